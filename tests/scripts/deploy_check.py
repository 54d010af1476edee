#!/usr/bin/python3
"""deploy/: the systemd unit passes `systemd-analyze verify` (with no warning), the
Grafana dashboard is valid JSON, the alert rules have what Prometheus needs, and every
metric either names (with each label value it matches) is one a running voxeld exports.
  deploy_check.py ROOT BIN_DIR"""
import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import unittest
import urllib.request

ROOT, BIN = sys.argv.pop(1), sys.argv.pop(1)
DEPLOY = os.path.join(ROOT, "deploy")


def read(name):
    with open(os.path.join(DEPLOY, name), encoding="utf-8") as f:
        return f.read()


def dashboard_exprs():
    dash = json.loads(read("grafana-voxeld.json"))
    exprs = [t["expr"] for p in dash["panels"] for t in p["targets"]]
    exprs += [v["query"] for v in dash["templating"]["list"] if v["type"] == "query"]
    return exprs


def alert_rules():
    """The rules of voxeld-alerts.yml as dicts of their one-line fields (the file keeps
    each expression on one line, so no YAML library is needed)."""
    rules, rule = [], None
    for line in read("voxeld-alerts.yml").splitlines():
        m = re.match(r"\s*- alert: (\S+)$", line)
        if m:
            rule = {"alert": m.group(1)}
            rules.append(rule)
            continue
        m = re.match(r"\s+(expr|for|severity|summary): (.+)$", line)
        if m and rule is not None:
            rule[m.group(1)] = m.group(2)
    return rules


def scrape():
    """/metrics of a fresh voxeld started with --log-format json: ({name: [label dicts of
    its samples]}, its log's lines)."""
    tmp = tempfile.mkdtemp(prefix="voxeld_deploy_")
    port_file = os.path.join(tmp, "mport")
    log = open(os.path.join(tmp, "log"), "w+b")
    server = subprocess.Popen(
        [os.path.join(BIN, "voxeld"), "--in-memory", "--port", "0", "--http-port", "0",
         "--metrics-port", "0", "--metrics-port-file", port_file, "--log-format", "json",
         "--log-level", "debug"],
        stdout=log, stderr=subprocess.STDOUT)
    try:
        for _ in range(300):
            if os.path.exists(port_file) and os.path.getsize(port_file) > 0:
                break
            if server.poll() is not None:
                raise RuntimeError("voxeld exited")
            time.sleep(0.05)
        with open(port_file) as f:
            port = int(f.read().strip())
        text = urllib.request.urlopen(f"http://127.0.0.1:{port}/metrics", timeout=10).read().decode()
        # A hostile client's name in a log line: quotes, a backslash, a newline, bad UTF-8.
        game_port = None
        for line in open(os.path.join(tmp, "log"), "rb").read().decode(errors="replace").splitlines():
            m = re.search(r"listening on 127\.0\.0\.1:(\d+)", line)
            if m:
                game_port = int(m.group(1))
        if game_port:
            with socket.create_connection(("127.0.0.1", game_port), timeout=5) as sock:
                sock.sendall(b"\x00\x00\x00\x05\xff\xfe\"\\\n")  # a malformed frame
                try:
                    sock.recv(4096)
                except OSError:
                    pass
    finally:
        server.terminate()
        server.wait(timeout=30)
        log.seek(0)
        log_lines = log.read().splitlines()
        log.close()
        shutil.rmtree(tmp, ignore_errors=True)
    series = {}
    for line in text.splitlines():
        m = re.match(r"([a-zA-Z_:][a-zA-Z0-9_:]*)(\{[^}]*\})? ", line)
        if not m or line.startswith("#"):
            continue
        labels = dict(re.findall(r'(\w+)="([^"]*)"', m.group(2) or ""))
        series.setdefault(m.group(1), []).append(labels)
    return series, log_lines


class Deploy(unittest.TestCase):
    series = None
    log_lines = None

    @classmethod
    def setUpClass(cls):
        cls.series, cls.log_lines = scrape()

    def test_json_logs_are_one_object_per_line(self):
        self.assertGreaterEqual(len(self.log_lines), 3)
        messages = []
        for raw in self.log_lines:
            line = json.loads(raw.decode("utf-8"))  # valid UTF-8 and valid JSON
            self.assertEqual(set(line), {"time", "level", "thread", "msg"}, raw)
            self.assertIn(line["level"], ("trace", "debug", "info", "warning", "error", "critical"))
            messages.append(line["msg"])
        self.assertTrue(any("listening on" in m for m in messages), messages)
        self.assertTrue(any("stopped" in m or "shutting" in m or "stop" in m for m in messages),
                        messages)

    def check_names(self, where, expr):
        for name, selector in re.findall(r"\b(voxeld_[a-z0-9_]+)(\{[^}]*\})?", expr):
            self.assertTrue(name in self.series, f"{where}: {name} is not exported: {expr}")
            for label, value in re.findall(r'(\w+)="([^"]*)"', selector or ""):
                if label == "instance":
                    continue
                self.assertTrue(any(s.get(label) == value for s in self.series[name]),
                                f"{where}: {name} has no {label}=\"{value}\": {expr}")

    def test_every_dashboard_expression_names_exported_metrics(self):
        exprs = dashboard_exprs()
        self.assertGreaterEqual(len(exprs), 10)
        for e in exprs:
            self.assertIn("voxeld_", e)
            self.check_names("dashboard", e)

    def test_every_alert_is_complete_and_names_exported_metrics(self):
        rules = alert_rules()
        self.assertEqual({r["alert"] for r in rules},
                         {"VoxeldDown", "VoxeldEditLatencyHigh", "VoxeldMemoryNearBudget",
                          "VoxeldResidentOverBudget", "VoxeldStoreUnavailable",
                          "VoxeldRefusedEditsRising", "VoxeldCheckpointsFailing"})
        for r in rules:
            for field in ("expr", "for", "severity", "summary"):
                self.assertIn(field, r, f"{r['alert']} has no {field}")
            self.check_names(r["alert"], r["expr"])
            self.assertEqual(r["expr"].count("("), r["expr"].count(")"), r["alert"])

    def test_prometheus_scrapes_voxeld_with_the_rules(self):
        conf = read("prometheus.yml")
        self.assertIn("job_name: voxeld", conf)
        self.assertIn("- voxeld-alerts.yml", conf)

    def test_the_systemd_unit_verifies(self):
        analyze = shutil.which("systemd-analyze")
        if analyze is None:
            self.skipTest("no systemd-analyze on this machine")
        with tempfile.TemporaryDirectory() as tmp:
            unit = os.path.join(tmp, "voxeld.service")
            with open(unit, "w") as f:  # the built binary where the unit installs it
                f.write(read("voxeld.service").replace("/usr/local/bin/voxeld ",
                                                       os.path.join(BIN, "voxeld") + " "))
            r = subprocess.run([analyze, "verify", unit], capture_output=True, text=True,
                               timeout=60)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertEqual(r.stderr.strip(), "", "a warning: " + r.stderr)


if __name__ == "__main__":
    unittest.main()
