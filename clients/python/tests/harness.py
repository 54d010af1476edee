"""The shared voxeld of the end-to-end test and helpers to talk to it."""
import os
import socket
import sys
import time
import unittest

sys.path.insert(0, os.path.normpath(os.path.join(os.path.dirname(__file__), "..")))

from voxelclient import Client, load_table, proto  # noqa: E402
from voxelclient.server import Voxeld  # noqa: E402

HANDSHAKE_TIMEOUT_MS = 1500  # shorter than the default 5 s, to provoke HANDSHAKE_TIMEOUT
VIEW_TIMEOUT = 30            # seconds for a radius-3 view to be complete
TEST_BUDGET = 90             # the whole test


class Shared:
    server = None
    pb = None
    table = None
    started = None


def start():
    path = os.environ.get("VOXELD")
    if not path:
        raise unittest.SkipTest("set VOXELD to the voxeld binary")
    Shared.started = time.monotonic()
    Shared.pb = proto.load()
    Shared.table = load_table(proto.DEFAULT_TABLE)
    Shared.server = Voxeld(path, seed=1, extra_args=[
        "--threads", "2", "--handshake-timeout-ms", str(HANDSHAKE_TIMEOUT_MS)])


def stop():
    """Stops the server; returns (exit code, Error code the watcher got, elapsed seconds)."""
    watcher = connect("watcher")
    code = Shared.server.stop()
    try:
        watcher.wait_closed(10)
    except socket.timeout:
        pass
    watcher.close()
    got = [e.code for e in watcher.errors]
    return code, got, time.monotonic() - Shared.started


def raw_client(**kw):
    return Client(Shared.server.host, Shared.server.port, pb=Shared.pb, table=Shared.table, **kw)


def connect(name, **kw):
    client = raw_client(**kw)
    client.hello(name)
    return client


def load_view(client, position, radius, view_id):
    client.set_view(position, radius, view_id)
    return client.wait_view_ready(view_id, VIEW_TIMEOUT)


def fresh_view(position, radius, name="fresh"):
    """What a new client receives for this view: (client, ViewReady)."""
    client = connect(name)
    ready = load_view(client, position, radius, 1)
    return client, ready


def sync(client, nonce):
    """Pings and waits for the Pong: everything the server sent before is then read."""
    client.ping(nonce)
    client.wait_pong(nonce)


def wait_newer(client, before, timeout=10):
    """Pumps until every chunk of `before` (coord -> version) is held at a newer version."""
    def done():
        return all(c in client.chunks and client.chunks[c].version > v
                   for c, v in before.items())
    client.pump(done, timeout)


def surface_point(client, coord):
    """A vertex of the held chunk `coord` near the middle of its x-z square, in world voxels."""
    mesh = client.chunks[coord].mesh
    best, point = None, None
    for i in range(mesh.vertex_count):
        x, y, z = mesh.positions[3 * i:3 * i + 3]
        d = (x - 16) ** 2 + (z - 16) ** 2
        if best is None or d < best:
            best, point = d, (x + 32 * coord[0], y + 32 * coord[1], z + 32 * coord[2])
    return point
