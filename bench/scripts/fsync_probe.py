#!/usr/bin/python3
"""How long the disk takes to make 4 KB durable, as the world store's appends need it.
   fsync_probe.py [COUNT] [DIR]   (defaults: 2000 writes, /tmp/voxeld_bench)
Writes 4 KB into a 1 MiB file and fdatasyncs it, COUNT times, 5 ms apart (about the pace of
the pipeline's batches at 500 players), and prints the fdatasync's p50/p90/p99/max. Run it
alone for the disk's own figure, and beside a load test (bench/scripts/attack_run.sh with
VOXELD_ARGS=--in-memory, so that the server writes nothing) for what a sync costs on a busy
machine: the floor under what the store's group commit can add to an edit."""
import os
import sys
import time

count = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
directory = sys.argv[2] if len(sys.argv) > 2 else "/tmp/voxeld_bench"
os.makedirs(directory, exist_ok=True)
path = os.path.join(directory, "fsync_probe")
fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
try:
    os.ftruncate(fd, 1 << 20)
    block = b"x" * 4096
    took = []
    for i in range(count):
        os.pwrite(fd, block, (i % 256) * 4096)
        start = time.perf_counter()
        os.fdatasync(fd)
        took.append((time.perf_counter() - start) * 1000)
        time.sleep(0.005)
finally:
    os.close(fd)
    os.unlink(path)
took.sort()
n = len(took)
print(f"fdatasync of 4 KB, {n} times: p50 {took[n // 2]:.2f} p90 {took[int(n * 0.9)]:.2f} "
      f"p99 {took[int(n * 0.99)]:.2f} max {took[-1]:.2f} ms")
