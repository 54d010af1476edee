"""A voxeld session (PROTOCOL.md section 4): handshake, views, edits, queries, held chunk
meshes."""
import itertools
import socket
import sys
import time
from array import array

from . import compression, mesh, proto
from .framing import FrameReader, encode_frame

PROTOCOL_VERSION = 1
VEC3_FIELDS = ("center", "min", "max")


class ServerError(Exception):
    """The server answered with an Error message where the caller expected something else."""

    def __init__(self, error, name):
        super().__init__("%s: %s" % (name, error.message))
        self.code, self.name, self.message = error.code, name, error.message


class Chunk:
    """What the client holds of one chunk: its newest version and decompressed encoding."""

    def __init__(self, version, encoding, decoded):
        self.version, self.encoding, self.mesh = version, encoding, decoded


def coord_of(c):
    return (c.x, c.y, c.z)


def xyz(v):
    return (v.x, v.y, v.z)


def volumes(edit_result):
    """An EditResult's material yield (section 4.4): {material: (removed, added)} in voxels,
    empty for a refused edit or a resend."""
    return {v.material: (v.removed, v.added) for v in edit_result.volumes}


class QueryAnswer:
    """A QueryResult (section 4.13), decoded. `result` is the message itself; `status` its
    status (compare with `pb.QueryResult.OK` etc.), `status_name` the name.

    raycast, ground: `hit`, and when it hit `point`, `normal` (x, y, z), `material`,
    `distance`. samples: `box` ((min_x, min_y, min_z), (max_x, max_y, max_z)), `size`
    (samples per axis), `densities` (array of int16, solid when > 0) and `materials`
    (bytes), x fastest, then y, then z; `sample(x, y, z)` reads one by world coordinates."""

    def __init__(self, result, pb):
        self.result = result
        self.request_id, self.status, self.reason = result.request_id, result.status, result.reason
        self.status_name = pb.QueryResult.Status.Name(result.status)
        self.ok = result.status == pb.QueryResult.OK
        self.retry_after_ms = result.retry_after_ms
        self.hit = result.hit
        self.point = xyz(result.point) if result.hit else None
        self.normal = xyz(result.normal) if result.hit else None
        self.material = result.material if result.hit else None
        self.distance = result.distance if result.hit else None
        self.box = self.size = None
        self.densities, self.materials = array("h"), b""
        if result.HasField("box"):
            b = result.box
            self.box = ((b.min_x, b.min_y, b.min_z), (b.max_x, b.max_y, b.max_z))
            self.size = tuple(hi - lo + 1 for lo, hi in zip(*self.box))
            count = self.size[0] * self.size[1] * self.size[2]
            if len(result.densities) != 2 * count or len(result.materials) != count:
                raise ValueError("QueryResult %d: %d density and %d material bytes for %d "
                                 "samples" % (result.request_id, len(result.densities),
                                              len(result.materials), count))
            self.densities = array("h", result.densities)  # little-endian int16
            if sys.byteorder == "big":
                self.densities.byteswap()
            self.materials = result.materials

    def index(self, x, y, z):
        """The position of world sample (x, y, z) in `densities` and `materials`."""
        (x0, y0, z0), (sx, sy, sz) = self.box[0], self.size
        i, j, k = x - x0, y - y0, z - z0
        if not (0 <= i < sx and 0 <= j < sy and 0 <= k < sz):
            raise IndexError("sample %s is outside the box %s" % ((x, y, z), self.box))
        return i + sx * (j + sy * k)

    def sample(self, x, y, z):
        """(density, material) of world sample (x, y, z)."""
        i = self.index(x, y, z)
        return self.densities[i], self.materials[i]

    def __repr__(self):
        if self.box:
            return "QueryAnswer(%d %s box=%s)" % (self.request_id, self.status_name, self.box)
        if self.hit:
            return "QueryAnswer(%d %s point=%s normal=%s material=%d distance=%g)" % (
                self.request_id, self.status_name, self.point, self.normal, self.material,
                self.distance)
        return "QueryAnswer(%d %s hit=False%s)" % (
            self.request_id, self.status_name, " " + self.reason if self.reason else "")


def _detail(kind, env):
    if kind == "chunk_mesh":
        m = env.chunk_mesh
        return coord_of(m.coord), m.version, m.base_version
    if kind == "view_ready":
        return env.view_ready.view_id
    if kind == "edit_result":
        return env.edit_result.request_id
    if kind == "query_result":
        return env.query_result.request_id
    if kind == "error":
        return env.error.code
    return None


class Client:
    """One connection. Incoming messages are handled in `pump`; everything the server sent
    is recorded in the attributes below for callers (and tests) to inspect."""

    def __init__(self, host, port, pb=None, table=None, decode=True, auto_resync=True):
        self.pb = pb or proto.load()
        self.table = table or mesh.load_table(proto.DEFAULT_TABLE)
        self.decode, self.auto_resync = decode, auto_resync
        self.sock = socket.create_connection((host, port), timeout=10)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.reader = FrameReader(self.sock)
        self.closed = False
        self.welcome = None
        self.chunks = {}          # coord -> Chunk (level 0)
        self.lod_chunks = {}      # (level, x, y, z) -> Chunk (levels >= 1, section 4.10)
        self.resyncing = set()    # coords dropped and asked for again
        self.failures = []        # (coord, reason) of payloads that did not apply
        self.received = []        # (coord, version, base_version, payload bytes, content bytes)
        self.unloaded = []        # coords of every ChunkUnload (level 0)
        self.lod_unloaded = []    # (level, x, y, z) of every ChunkUnload of a coarser level
        self.view_ready = {}      # view_id -> ViewReady
        self.results = {}         # request_id -> EditResult
        self.result_log = []      # request ids of every EditResult, in arrival order
        self.queries = {}         # request_id -> QueryAnswer
        self.query_log = []       # request ids of every QueryResult, in arrival order
        self.pongs = set()
        self.errors = []          # Error messages
        self.log = []             # (kind, detail) of every message, in arrival order
        self._ids = itertools.count(1)

    # ---- sending ----------------------------------------------------------------------

    def send(self, envelope):
        self.send_raw(envelope.SerializeToString())

    def send_raw(self, payload):
        self.sock.sendall(encode_frame(payload))

    def send_message(self, **body):
        self.send(self.pb.Envelope(**body))

    def hello(self, name="pyclient", version=PROTOCOL_VERSION, timeout=10, token=""):
        """Sends Hello and returns the Welcome (raises ServerError on an Error). `token`:
        a signed player token, for a server started with --auth-public-key (PROTOCOL 4.8)."""
        self.send_message(hello=self.pb.Hello(protocol_version=version, player_name=name,
                                              token=token))
        self.pump(lambda: self.welcome is not None or self.errors, timeout)
        if self.welcome is None:
            raise self.error_exception(self.errors[0])
        return self.welcome

    def set_view(self, position, radius, view_id=None, lod_level=0, lod_distance=0.0):
        """`lod_level` > 0: a level-of-detail view of levels 0 .. lod_level (section 4.10);
        coarse chunks land in `lod_chunks`."""
        view_id = next(self._ids) if view_id is None else view_id
        self.send_message(set_view=self.pb.SetView(
            position=self.vec3(position), radius=radius, view_id=view_id,
            lod_level=lod_level, lod_distance=lod_distance))
        return view_id

    def edit(self, kind, request_id=None, edit_id=0, **fields):
        """Sends an Edit of `kind` (brush, explosion, smooth, paint, stamp); returns its id.
        Vector fields take (x, y, z); a stamp's `shape` may be "box" or "sphere".
        `edit_id` (non-zero, unique among the player's edits) makes a resend of the same
        edit safe: the server answers it already_applied instead of applying it twice."""
        request_id = next(self._ids) if request_id is None else request_id
        msg = self.pb.Edit(request_id=request_id, edit_id=edit_id)
        if kind is not None:
            getattr(msg, kind).CopyFrom(self._edit_body(kind, fields))
        self.send_message(edit=msg)
        return request_id

    def _edit_body(self, kind, fields):
        cls = getattr(self.pb, kind.capitalize())
        args = {}
        for key, value in fields.items():
            if key in VEC3_FIELDS:
                value = self.vec3(value)
            elif key == "shape" and isinstance(value, str):
                value = getattr(self.pb.Stamp, value.upper())
            args[key] = value
        return cls(**args)

    def query(self, kind, request_id=None, **fields):
        """Sends a Query of `kind` (raycast, ground, samples; None: an empty one) without
        waiting; returns its request id (wait_query reads the answer). raycast: origin,
        direction (x, y, z), max_distance; ground: x, z, from_y, max_depth; samples: min,
        max (x, y, z), inclusive samples (or box, a VoxelBox)."""
        request_id = next(self._ids) if request_id is None else request_id
        msg = self.pb.Query(request_id=request_id)
        if kind == "raycast":
            msg.raycast.CopyFrom(self.pb.Raycast(
                origin=self.vec3(fields["origin"]), direction=self.vec3(fields["direction"]),
                max_distance=fields["max_distance"]))
        elif kind == "ground":
            msg.ground.CopyFrom(self.pb.GroundQuery(**fields))
        elif kind == "samples":
            box = fields.get("box") or self.voxel_box(fields["min"], fields["max"])
            msg.samples.CopyFrom(self.pb.SampleQuery(box=box))
        elif kind is not None:
            raise ValueError("unknown query kind %r" % kind)
        self.send_message(query=msg)
        return request_id

    def ask(self, kind, timeout=10, busy_retries=20, **fields):
        """Sends a query and waits for its answer (a QueryAnswer, whatever its status). A
        SERVER_BUSY answer (terrain still loading, section 4.13) is retried after its
        retry_after_ms, up to `busy_retries` times."""
        for attempt in range(busy_retries + 1):
            answer = self.wait_query(self.query(kind, **fields), timeout)
            if answer.status != self.pb.QueryResult.SERVER_BUSY or attempt == busy_retries:
                return answer
            self.pause(answer.retry_after_ms / 1000.0)

    def raycast(self, origin, direction, max_distance, **kw):
        """Where the ray from `origin` along `direction` first meets the surface within
        `max_distance` voxels: a QueryAnswer (hit, point, normal, material, distance)."""
        return self.ask("raycast", origin=origin, direction=direction,
                        max_distance=max_distance, **kw)

    def ground(self, x, z, from_y, max_depth, **kw):
        """The first surface below (x, from_y, z) within `max_depth` voxels."""
        return self.ask("ground", x=x, z=z, from_y=from_y, max_depth=max_depth, **kw)

    def samples(self, min, max, **kw):
        """The samples of the inclusive box `min`..`max`: a QueryAnswer with `densities`
        (int16) and `materials`, x fastest, then y, then z."""
        return self.ask("samples", min=min, max=max, **kw)

    def ping(self, nonce):
        self.send_message(ping=self.pb.Ping(nonce=nonce))

    def resync(self, coords, level=0):
        coords = list(coords)
        held = self.chunks if level == 0 else self.lod_chunks
        for c in coords:
            key = c if level == 0 else (level,) + tuple(c)
            held.pop(key, None)
            self.resyncing.add(key)
        self.send_message(resync=self.pb.Resync(coords=[self.chunk_coord(c) for c in coords],
                                                level=level))

    def vec3(self, v):
        return self.pb.Vec3(x=v[0], y=v[1], z=v[2])

    def chunk_coord(self, c):
        return self.pb.ChunkCoord(x=c[0], y=c[1], z=c[2])

    def voxel_box(self, lo, hi):
        return self.pb.VoxelBox(min_x=lo[0], min_y=lo[1], min_z=lo[2],
                                max_x=hi[0], max_y=hi[1], max_z=hi[2])

    # ---- waiting ----------------------------------------------------------------------

    def pump(self, until, timeout):
        """Handles incoming messages until `until()` is true; False when the connection
        closed first. Raises socket.timeout after `timeout` seconds."""
        deadline = time.monotonic() + timeout
        while not until():
            if self.closed:
                return False
            frame = self.reader.read(deadline)
            if frame is None:
                self.closed = True
                continue
            env = self.pb.Envelope()
            env.ParseFromString(frame)
            self.handle(env)
        return True

    def wait_view_ready(self, view_id, timeout=30):
        if not self.pump(lambda: view_id in self.view_ready, timeout):
            raise ConnectionError("closed before ViewReady %d" % view_id)
        return self.view_ready[view_id]

    def wait_result(self, request_id, timeout=10):
        if not self.pump(lambda: request_id in self.results, timeout):
            raise ConnectionError("closed before EditResult %d" % request_id)
        return self.results[request_id]

    def wait_query(self, request_id, timeout=10):
        if not self.pump(lambda: request_id in self.queries, timeout):
            raise ConnectionError("closed before QueryResult %d" % request_id)
        return self.queries[request_id]

    def pause(self, seconds):
        """Handles incoming messages for `seconds`."""
        try:
            self.pump(lambda: False, seconds)
        except socket.timeout:
            pass

    def wait_pong(self, nonce, timeout=10):
        if not self.pump(lambda: nonce in self.pongs, timeout):
            raise ConnectionError("closed before Pong %d" % nonce)

    def wait_error(self, timeout=10):
        """The first Error received (pumping until one comes)."""
        if not self.pump(lambda: self.errors, timeout):
            raise ConnectionError("closed without an Error")
        return self.errors[0]

    def wait_closed(self, timeout=10):
        self.pump(lambda: False, timeout)

    def error_exception(self, error):
        return ServerError(error, self.pb.Error.Code.Name(error.code))

    # ---- receiving --------------------------------------------------------------------

    def handle(self, env):
        kind = env.WhichOneof("body")
        self.log.append((kind, _detail(kind, env)))
        if kind == "welcome":
            revision = env.welcome.mesh_table_revision or 1
            if self.decode and revision != getattr(self.table, "revision", 1):
                raise mesh.MeshError(
                    "the server derives triangles with table revision %d, this client's "
                    "table is revision %d: take the server's docs/marching_cubes_tables.txt"
                    % (revision, getattr(self.table, "revision", 1)))
            self.welcome = env.welcome
        elif kind == "chunk_mesh":
            self.on_chunk_mesh(env.chunk_mesh)
        elif kind == "chunk_unload":
            level = env.chunk_unload.level
            for c in map(coord_of, env.chunk_unload.coords):
                key = c if level == 0 else (level,) + c
                (self.chunks if level == 0 else self.lod_chunks).pop(key, None)
                self.resyncing.discard(key)
                (self.unloaded if level == 0 else self.lod_unloaded).append(key)
        elif kind == "view_ready":
            self.view_ready[env.view_ready.view_id] = env.view_ready
        elif kind == "edit_result":
            self.results[env.edit_result.request_id] = env.edit_result
            self.result_log.append(env.edit_result.request_id)
        elif kind == "query_result":
            self.queries[env.query_result.request_id] = QueryAnswer(env.query_result, self.pb)
            self.query_log.append(env.query_result.request_id)
        elif kind == "pong":
            self.pongs.add(env.pong.nonce)
        elif kind == "error":
            self.errors.append(env.error)
        # anything else (None: a body this client does not know) is ignored, section 4.1

    def on_chunk_mesh(self, msg):
        # Level-k chunks (k >= 1) are keyed (k, x, y, z); versions are per key (4.10).
        c = coord_of(msg.coord) if msg.level == 0 else (msg.level,) + coord_of(msg.coord)
        store = self.chunks if msg.level == 0 else self.lod_chunks
        held = store.get(c)
        if msg.base_version != 0 and c in self.resyncing:
            return  # a delta for a chunk we hold no base of: wait for the full copy
        try:
            encoding = self._apply(msg, held)
            decoded = mesh.decode(encoding, self.table) if self.decode else None
            if not self.decode:
                mesh.check_crc(encoding)
        except (compression.CompressionError, mesh.MeshError) as e:
            self._failed(c, str(e))
            return
        self.received.append((c, msg.version, msg.base_version, len(msg.payload), len(encoding)))
        store[c] = Chunk(msg.version, encoding, decoded)
        self.resyncing.discard(c)

    def _apply(self, msg, held):
        # A full copy answering a Resync may repeat the held version (section 4.3).
        if held is not None and (msg.version < held.version or
                                 (msg.version == held.version and msg.base_version != 0)):
            raise mesh.MeshError("version %d is not newer than the held %d"
                                 % (msg.version, held.version))
        if msg.base_version == 0:
            return compression.decompress_full(msg.payload)
        if held is None or held.version != msg.base_version:
            raise mesh.MeshError("delta against version %d, held %s"
                                 % (msg.base_version, held and held.version))
        return compression.decompress_delta(msg.payload, held.encoding)

    def _failed(self, c, reason):
        self.failures.append((c, reason))
        level, coord = (0, c) if len(c) == 3 else (c[0], c[1:])
        (self.chunks if level == 0 else self.lod_chunks).pop(c, None)
        if self.auto_resync:
            self.resync([coord], level)
        else:
            self.resyncing.add(c)

    def close(self):
        try:
            self.sock.close()
        finally:
            self.closed = True
