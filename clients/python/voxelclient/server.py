"""Starting and stopping a local voxeld for tests and benchmarks."""
import queue
import re
import shutil
import signal
import subprocess
import tempfile
import threading
import time

_LISTENING = re.compile(r"listening on ([0-9.]+):(\d+)")


class Voxeld:
    """A voxeld on 127.0.0.1 with port 0, in a temporary working directory. The port is the
    one the server prints in its "listening on HOST:PORT" log line."""

    def __init__(self, path, seed=1, extra_args=(), timeout=15):
        self.workdir = tempfile.mkdtemp(prefix="voxeld_")
        args = [path, "--port", "0", "--bind", "127.0.0.1", "--seed", str(seed),
                "--stats-interval", "0", *extra_args]
        self.proc = subprocess.Popen(args, cwd=self.workdir, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True)
        self.lines = []
        self._queue = queue.Queue()
        threading.Thread(target=self._drain, daemon=True).start()
        self.host, self.port = self._wait_port(timeout)

    def _drain(self):
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))
            self._queue.put(line)
        self._queue.put(None)

    def _wait_port(self, timeout):
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                self.stop()
                raise TimeoutError("voxeld printed no 'listening on' line in %ss" % timeout)
            try:
                line = self._queue.get(timeout=remaining)
            except queue.Empty:
                continue
            if line is None:
                raise RuntimeError("voxeld exited: %s" % "\n".join(self.lines))
            match = _LISTENING.search(line)
            if match:
                return match.group(1), int(match.group(2))

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
