#!/usr/bin/python3
"""deploy/: the systemd unit passes `systemd-analyze verify` (with no warning), the
Grafana dashboard is valid JSON, the alert rules have what Prometheus needs, and every
metric either names (with each label value it matches) is one a running voxeld exports.
  deploy_check.py ROOT BIN_DIR"""
import json
import os
import re
import shutil
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
    """/metrics of a fresh voxeld: {name: [label dicts of its samples]}."""
    tmp = tempfile.mkdtemp(prefix="voxeld_deploy_")
    port_file = os.path.join(tmp, "mport")
    server = subprocess.Popen(
        [os.path.join(BIN, "voxeld"), "--in-memory", "--port", "0", "--http-port", "0",
         "--metrics-port", "0", "--metrics-port-file", port_file],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
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
    finally:
        server.terminate()
        server.wait(timeout=30)
        shutil.rmtree(tmp, ignore_errors=True)
    series = {}
    for line in text.splitlines():
        m = re.match(r"([a-zA-Z_:][a-zA-Z0-9_:]*)(\{[^}]*\})? ", line)
        if not m or line.startswith("#"):
            continue
        labels = dict(re.findall(r'(\w+)="([^"]*)"', m.group(2) or ""))
        series.setdefault(m.group(1), []).append(labels)
    return series


class Deploy(unittest.TestCase):
    series = None

    @classmethod
    def setUpClass(cls):
        cls.series = scrape()

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
                          "VoxeldRefusedEditsRising"})
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
