#!/usr/bin/env python3
"""Quantiles of voxeld's Prometheus histograms, interpolated within their buckets.
   metrics_quantile.py METRICS_FILE NAME [Q ...]   e.g. voxeld_edit_publish_seconds 0.99"""
import re
import sys


def buckets(path, name):
    out = []
    pattern = re.compile(r'^%s_bucket\{le="([^"]+)"\} (\S+)$' % re.escape(name))
    for line in open(path):
        m = pattern.match(line.strip())
        if m:
            out.append((float("inf") if m.group(1) == "+Inf" else float(m.group(1)), float(m.group(2))))
    return sorted(out)


def quantile(bs, q):
    """Linear within the bucket the q-th observation falls in (as PromQL's histogram_quantile)."""
    total = bs[-1][1] if bs else 0
    if total == 0:
        return float("nan")
    rank, lo, below = q * total, 0.0, 0.0
    for le, count in bs:
        if count >= rank:
            if le == float("inf"):
                return lo
            return lo + (le - lo) * (rank - below) / max(count - below, 1e-12)
        lo, below = le, count
    return lo


if __name__ == "__main__":
    path, name = sys.argv[1], sys.argv[2]
    bs = buckets(path, name)
    print(" ".join("%.1f" % (1000 * quantile(bs, float(q))) for q in (sys.argv[3:] or ["0.99"])))
