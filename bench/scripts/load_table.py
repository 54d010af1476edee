#!/usr/bin/python3
"""The table of bench/scripts/load_table.sh from its runs' files in OUT:
    load_table.py OUT ROOT STEAL_TICKS [--update-doc]
writes OUT/load_table.{md,json} and prints the markdown; --update-doc replaces the
"## Current figures" section at the top of ROOT/docs/PERFORMANCE.md with it."""
import datetime
import json
import os
import subprocess
import sys


def load(out, name):
    try:
        with open(os.path.join(out, name + ".json")) as f:
            return json.load(f)
    except (OSError, ValueError):
        return None


def threads(out, name):
    try:
        with open(os.path.join(out, name + ".threads")) as f:
            rows = [line.split() for line in f if line.strip()]
    except OSError:
        return "-"
    return ", ".join(f"{r[0]}{'×' + r[1] if r[1] != '1' else ''} {r[2]}%" for r in rows[:6])


def cpu(j):
    xs = [s["cpu_percent"] for s in j.get("per_second", []) if s.get("cpu_percent") is not None]
    xs = xs[10:-3] if len(xs) > 20 else xs
    return sum(xs) / len(xs) if xs else 0.0


def ok(value, goal):
    return "**met**" if value <= goal else "**missed**"


def replace_section(doc, heading, text):
    """`doc` with the section `heading` (its title followed by " (") replaced by `text`, or,
    when it has none, `text` inserted after the other current-figures section (else before
    the first section); a blank line between sections either way."""
    # The fast and the slowed host's tables are kept apart: "## Current figures (" is not
    # "## Current figures, ...".
    start = doc.find(heading + " (")
    if start >= 0:
        end = doc.find("\n## ", start + 1)
        if end < 0:
            return doc[:start] + text
        return doc[:start] + text.rstrip("\n") + "\n\n" + doc[end + 1:]
    other = doc.find("## Current figures")
    at = doc.find("\n## ", other + 1) if other >= 0 else doc.find("\n## ")
    return doc[:at + 1].rstrip("\n") + "\n\n" + text.rstrip("\n") + "\n\n" + doc[at + 1:]


def main():
    out, root, steal_ticks = sys.argv[1], sys.argv[2], int(sys.argv[3])
    update = "--update-doc" in sys.argv[4:]
    rows, data = [], {}

    # Only the scenarios this table ran (ONLY=...): the files of the others are older runs.
    only = set((os.environ.get("ONLY") or "lod200,p500,p1000,attack,storm").split(","))

    def add(name, scenario, goal, figure, verdict, run):
        if name not in only:
            return
        j = load(out, run) if run else None
        extra = ""
        if j:
            extra = f"{cpu(j):.0f} % ({threads(out, run)})"
        rows.append((scenario, goal, figure, verdict, extra))
        data[name] = {"scenario": scenario, "goal": goal, "figure": figure, "verdict": verdict}

    j = load(out, "lt_lod200")
    if j:
        d, fv, b = j["edit_to_delta_ms"]["p99"], j["first_view_ms"]["p99"], j["bytes_per_player_per_s"]
        add("lod200", "200 players, LOD views to 2,048 voxels (`--lod-level 6`, `--io-threads 2`)",
            "edit→delta p99 ≤ 50 ms; first view p99 ≤ 3 s; ≤ 45 KB/s per player",
            f"{d:.1f} ms; {fv / 1000:.1f} s; {b / 1000:.1f} KB/s",
            " / ".join([ok(d, 50), ok(fv, 3000), ok(b, 45000)]), "lt_lod200")
    for name, players, limit, view in (("p500", 500, 50, 1000), ("p1000", 1000, 100, 2000)):
        j = load(out, "lt_" + name)
        if not j:
            continue
        d, fv = j["edit_to_delta_ms"]["p99"], j["first_view_ms"]["p99"]
        busy = j.get("refused_by_status", {}).get("SERVER_BUSY", 0)
        rss = j.get("server_rss", {}).get("max_kib", 0) / 1024
        add(name, f"{players:,} players, default store",
            f"p99 ≤ {limit} ms; first view p99 ≤ {view / 1000:g} s; no SERVER_BUSY; RSS ≤ 1 GiB",
            f"{d:.1f} ms; {fv / 1000:.2f} s; {busy} SERVER_BUSY; RSS {rss:.0f} MiB",
            " / ".join([ok(d, limit), ok(fv, view), ok(busy, 0), ok(rss, 1024)]), "lt_" + name)
    base, atk = load(out, "lt_base200"), load(out, "lt_atk200")
    if base and atk:
        b, a = base["edit_to_delta_ms"]["p99"], atk["edit_to_delta_ms"]["p99"]
        rss = atk.get("server_rss", {}).get("max_kib", 0) / 1024
        ratio = a / b if b else float("inf")
        add("attack", "200 players with the attack mix against 200 without",
            "≤ 2×; RSS ≤ 1 GiB + 5 %", f"{a:.1f} against {b:.1f} ms: {ratio:.2f}×; RSS {rss:.0f} MiB",
            " / ".join([ok(ratio, 2), ok(rss, 1075)]), "lt_atk200")
    storm, steady = load(out, "lt_storm"), load(out, "lt_storm.steady")
    if storm and steady:
        fv = storm["first_view_ms"]["p99"]
        during = [s["p99_ms"] for s in steady.get("per_second", []) if 20 <= s["t"] < 50 and s.get("p99_ms")]
        worst = max(during) if during else 0.0
        add("storm", "login storm: 500 join within 5 s beside 100 playing",
            "first view p99 ≤ 2 s; players in: worst second's p99 ≤ 100 ms",
            f"{fv / 1000:.2f} s; {worst:.1f} ms", " / ".join([ok(fv, 2000), ok(worst, 100)]),
            "lt_storm")

    model = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
    model = next((l.split(":", 1)[1].strip() for l in model.splitlines() if l.startswith("Model name")), "?")
    commit = subprocess.run(["git", "-C", root, "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True).stdout.strip()
    date = datetime.date.today().isoformat()
    steal_s = steal_ticks / os.sysconf("SC_CLK_TCK")
    slow = os.environ.get("SLOW", "")
    heading = "## Current figures, slowed host" if slow else "## Current figures"
    slowed = (f" A slower host made of this one: `stress-ng --cpu 2 --cpu-load {slow}` ran beside "
              f"the whole table (`SLOW={slow} bench/scripts/load_table.sh`)." if slow else "")
    md = [f"{heading} ({date}, commit {commit})", "",
          f"`bench/scripts/load_table.sh` on {model}, {os.cpu_count()} cores; steal over the "
          f"whole run {steal_s:.1f} s of CPU.{slowed} Load tester on the same machine "
          "(`--spread-addresses`, 0.5 edits/s per player); voxeld's CPU is the mean of its "
          "per-second samples while the players play, with each thread's share. A goal met "
          "on one host is met only once it also holds on a slower one (the same 2-core size "
          "measured 1.5–9× apart between hosts, and one AMD EPYC host 2× apart within a "
          "day): take CPU away (`stress-ng` beside the run, or `taskset`) before calling it "
          "met.", "",
          "| scenario | goal | measured | verdict | voxeld CPU (threads) |", "|---|---|---|---|---|"]
    md += [f"| {' | '.join(r)} |" for r in rows]
    md.append("")
    text = "\n".join(md)
    with open(os.path.join(out, "load_table.md"), "w") as f:
        f.write(text)
    with open(os.path.join(out, "load_table.json"), "w") as f:
        json.dump({"date": date, "commit": commit, "cpu": model, "steal_s": steal_s, "rows": data}, f,
                  indent=1)
    print(text)
    if update:
        path = os.path.join(root, "docs", "PERFORMANCE.md")
        with open(path) as f:
            doc = f.read()
        with open(path, "w") as f:
            f.write(replace_section(doc, heading, text))
    return 0


if __name__ == "__main__":
    sys.exit(main())
