# A cluster on this machine for the bench scripts that drive it with the Python reference
# client (clients/python): PostgreSQL (initdb in DIR/pg, on a Unix socket; run as postgres
# when we are root) and nats-server (a user and password from its configuration file) on
# 127.0.0.1, and voxeld nodes started with --cluster. Files stay in DIR.
import atexit, glob, os, re, signal, subprocess, sys, time
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, ROOT + "/clients/python")
from voxelclient.client import Client  # noqa: E402  (re-exported for the scripts)


class Cluster:
    def __init__(self, directory, pg_port, zone_chunks=0):
        self.dir, self.pg_port, self.zone_chunks = directory, pg_port, zone_chunks
        self.procs, self.ports = {}, {}
        atexit.register(self.kill_all)  # a script that fails leaves nothing running
        subprocess.run(["rm", "-rf", directory])
        os.makedirs(directory + "/pg")
        os.chmod(directory, 0o755)
        self.pgbin = sorted(glob.glob("/usr/lib/postgresql/*/bin"))[-1]
        if os.getuid() == 0:
            subprocess.run(["chown", "postgres", directory, directory + "/pg"])
        self.pg(f"{self.pgbin}/initdb -D {directory}/pg -U postgres -A trust")
        self.pg(f"{self.pgbin}/pg_ctl -D {directory}/pg -l {directory}/pg.log -w -o "
                f"\"-k {directory} -p {pg_port} -c listen_addresses=''\" start")
        self.pg(f"{self.pgbin}/psql -q -h {directory} -p {pg_port} -U postgres "
                "-c 'CREATE DATABASE vox'")
        open(directory + "/nats.conf", "w").write(
            'host: 127.0.0.1\nport: -1\nauthorization { user: "u", password: "p-secret" }\n')
        os.makedirs(directory + "/ports")
        self.nats = subprocess.Popen(
            ["nats-server", "-c", directory + "/nats.conf", "--ports_file_dir",
             directory + "/ports"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        for _ in range(100):
            f = glob.glob(directory + "/ports/*")
            if f:
                break
            time.sleep(0.1)
        self.nats_url = re.search(r'nats://[^"]*', open(f[0]).read()).group(0)

    def pg(self, cmd):
        argv = ["runuser", "-u", "postgres", "--", "sh", "-c", cmd] if os.getuid() == 0 \
            else ["sh", "-c", cmd]
        subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)

    def start(self, node, args=(), more=""):
        """Starts node `node` (a, b, ...) with voxeld `args` (and `more`: more lines of its
        configuration file) and returns its TCP port."""
        d = self.dir
        conf = f"{d}/{node}.conf"
        text = (f"database = postgresql:///vox?host={d}&port={self.pg_port}&user=postgres\n"
                f"nats = {self.nats_url}\nnats_user = u\nnats_password = p-secret\n"
                f"node = {node}\n")
        if self.zone_chunks:
            text += f"zone_chunks = {self.zone_chunks}\n"
        text += more
        open(conf, "w").write(text)
        os.chmod(conf, 0o600)
        pf = f"{d}/{node}.port"
        self.procs[node] = subprocess.Popen(
            [os.environ.get("VOXELD", ROOT + "/build/bin/voxeld"), "--cluster", conf, "--port",
             "0", "--port-file", pf, "--http-port", "0", *args], stdout=open(f"{d}/{node}.log", "w"), stderr=subprocess.STDOUT)
        for _ in range(100):
            if os.path.exists(pf) and open(pf).read().strip():
                break
            time.sleep(0.1)
        self.ports[node] = int(open(pf).read())
        return self.ports[node]

    def holders(self):
        """{(zone x, zone z): node} from the nodes' logs: each zone's last take, unless its
        taker lost it since."""
        events = []
        for node in self.procs:
            for line in open(f"{self.dir}/{node}.log"):
                m = re.search(r"^\[([^\]]+)\].*(took|lost) zone \((-?\d+), (-?\d+)\)", line)
                if m:
                    events.append((m.group(1), m.group(2) == "took", (int(m.group(3)),
                                                                      int(m.group(4))), node))
        out = {}
        for _, took, zone, node in sorted(events):  # a loss before a take in one millisecond
            if took:
                out[zone] = node
            elif out.get(zone) == node:
                del out[zone]
        return out

    def kill(self, node):
        self.procs[node].send_signal(signal.SIGKILL)
        self.procs[node].wait()

    def kill_all(self):
        for p in list(self.procs.values()) + [getattr(self, "nats", None)]:
            if p is not None and p.poll() is None:
                p.kill()
                p.wait()
        if os.path.exists(self.dir + "/pg/postmaster.pid"):
            self.pg(f"{self.pgbin}/pg_ctl -D {self.dir}/pg -m immediate -w stop")

    def stop(self):
        for name, p in self.procs.items():
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
                print(name, "stopped with exit code", p.wait(timeout=15))
        self.nats.terminate()
        self.nats.wait()
        self.pg(f"{self.pgbin}/pg_ctl -D {self.dir}/pg -m fast -w stop")
