"""The reference sleeper of the jitter benchmarks (tools/modbus-load.sh, tools/jitter-load.py): a cyclictest run's
histogram file (`cyclictest -q -h 1000 ...` output) summarised as wakes, wakes later than the histogram's 1000 µs,
latency percentiles and the maximum."""
import os


def summary(path):
    """None when the file does not exist (cyclictest not installed)."""
    if not os.path.exists(path):
        return None
    hist, over, mx = {}, 0, None
    for line in open(path):
        p = line.split()
        if len(p) == 2 and p[0].isdigit() and p[1].isdigit():
            hist[int(p[0])] = int(p[1])
        elif line.startswith("# Histogram Overflows:"):
            over = int(p[3])
        elif line.startswith("# Max Latencies:"):
            mx = int(p[3])
    n = sum(hist.values()) + over

    def quantile(q):
        acc = 0
        for us in sorted(hist):
            acc += hist[us]
            if acc >= q * n:
                return us
        return ">1000"
    return {"wakes": n, "late_over_1ms": over, "latency_p50_us": quantile(0.5), "latency_p99_us": quantile(0.99),
            "latency_p999_us": quantile(0.999), "latency_max_us": mx}
