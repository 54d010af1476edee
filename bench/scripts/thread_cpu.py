#!/usr/bin/python3
"""Each thread's share of a CPU over a window, by thread name (threads of one name summed):
    thread_cpu.py PID [DELAY_S] [WINDOW_S]
waits DELAY_S (default 10), reads /proc/PID/task/*/stat, waits WINDOW_S (default 60), reads
again and prints "name count percent" per line, busiest first. Beside a latency figure it
says where the process's time went (docs/PERFORMANCE.md)."""
import os
import sys
import time


def sample(pid):
    out = {}
    for tid in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{tid}/stat") as f:
                stat = f.read()
        except OSError:
            continue  # the thread ended
        name = stat[stat.index("(") + 1:stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2:].split()
        out[tid] = (name, int(fields[11]) + int(fields[12]))  # utime + stime
    return out


def main():
    pid = int(sys.argv[1])
    delay = float(sys.argv[2]) if len(sys.argv) > 2 else 10
    window = float(sys.argv[3]) if len(sys.argv) > 3 else 60
    time.sleep(delay)
    try:
        first = sample(pid)
        t0 = time.monotonic()
        time.sleep(window)
        second = sample(pid)
        elapsed = time.monotonic() - t0
    except FileNotFoundError:
        print(f"thread_cpu: process {pid} ended", file=sys.stderr)
        return 1
    for name, count, percent in shares(first, second, elapsed):
        print(f"{name} {count} {percent:.1f}")
    return 0


def shares(first, second, elapsed):
    """[(thread name, threads, percent of a CPU)] between two samples, busiest first."""
    hz = os.sysconf("SC_CLK_TCK")
    by_name = {}
    for tid, (name, ticks) in second.items():
        used = ticks - first.get(tid, (name, 0))[1]
        count, total = by_name.get(name, (0, 0))
        by_name[name] = (count + 1, total + used)
    return [(name, count, 100.0 * ticks / hz / elapsed)
            for name, (count, ticks) in sorted(by_name.items(), key=lambda kv: -kv[1][1])]


def steal_seconds():
    """CPU time stolen by the hypervisor since boot, all CPUs (/proc/stat)."""
    with open("/proc/stat") as f:
        return int(f.readline().split()[8]) / os.sysconf("SC_CLK_TCK")


def cpu_model():
    """The CPU model /proc/cpuinfo names."""
    model = [line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
             if line.startswith("model name")]
    return model[0] if model else "CPU model unknown"


if __name__ == "__main__":
    sys.exit(main())
