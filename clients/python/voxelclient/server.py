"""Starting and stopping a local voxeld for tests and benchmarks."""
import os
import shutil
import signal
import subprocess
import tempfile
import threading
import time

class Voxeld:
    """A voxeld on 127.0.0.1 with port 0, in a temporary working directory. The port is the
    one it writes to its --port-file once it listens (README, "voxeld")."""

    def __init__(self, path, seed=1, extra_args=(), timeout=15):
        self.workdir = tempfile.mkdtemp(prefix="voxeld_")
        self.port_file = os.path.join(self.workdir, "port")
        args = [os.path.abspath(path), "--port", "0", "--bind", "127.0.0.1", "--port-file", self.port_file,
                "--seed", str(seed), "--stats-interval", "0", *extra_args]
        self.proc = subprocess.Popen(args, cwd=self.workdir, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True)
        self.lines = []
        threading.Thread(target=self._drain, daemon=True).start()
        self.host, self.port = "127.0.0.1", self._wait_port(timeout)

    def _drain(self):
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))

    def _wait_port(self, timeout):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError("voxeld exited: %s" % "\n".join(self.lines))
            try:
                with open(self.port_file) as f:
                    text = f.read().strip()
                if text:
                    return int(text)
            except (FileNotFoundError, ValueError):
                pass
            time.sleep(0.01)
        self.stop()
        raise TimeoutError("voxeld wrote no --port-file in %ss" % timeout)

    def stop(self, timeout=15):
        """SIGTERM, wait; returns the exit code (kills after `timeout`, then returns None)."""
        code = None
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(5)
        self.proc.stdout.close()
        shutil.rmtree(self.workdir, ignore_errors=True)
        return code
