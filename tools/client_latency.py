#!/usr/bin/env python3
"""Latency benchmark for a Python client (docs/sdk.md "Benchmarks"; printed, not gated): the same figures as
sdk/tools/client_latency.cpp - telemetry arrival of the state a command was computed from → the wake-up of the
daemon cycle that sent it, beside the built-in path (that cycle's wake-up minus its own telemetry's arrival) -
and the achieved rate. The client renders a gentle spring on the pen.

  client_latency.py SOCKET SECONDS
"""
import sys
import time

import numpy as np

import phalanx


def main():
    sock, seconds = sys.argv[1], float(sys.argv[2])
    c = phalanx.Client(sock, deadline_ms=250)
    rate = c.device["rate_hz"]
    n = int(seconds * rate) + 16
    rx_of_seq = np.zeros(n + 2, dtype=np.uint64)
    client_us, builtin_us = [], []
    seq = 0
    c0 = None
    first = last = None
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end and seq + 1 < len(rx_of_seq):
        s = c.wait_state(100)
        if s is None:
            continue
        if s.control == "forced-off":
            print("forced off:", s.force_off_cause)
            break
        first = s.cycle if first is None else first
        last = s.cycle
        used = s.command_seq_used
        if 0 < used <= seq and rx_of_seq[used] != 0:
            client_us.append((s.daemon_time_ns - int(rx_of_seq[used])) * 1e-3)
        if 0 < s.telemetry_rx_ns <= s.daemon_time_ns:
            builtin_us.append((s.daemon_time_ns - s.telemetry_rx_ns) * 1e-3)
        if c0 is None and s.pen_valid:
            c0 = s.pen_centre
        f = 100.0 * (c0 - s.pen_centre) if c0 is not None else np.zeros(3)
        c.set_pen_wrench(f, (0.0, 0.0, 0.0), fallback=[(s.pen_centre + f / 100.0, 100.0, 0.0)])
        seq += 1
        rx_of_seq[seq] = s.telemetry_rx_ns
    st = c.get_state()
    cycles = (last - first + 1) if first is not None else 0
    print("Python client: %d commands over %d daemon cycles (%.1f %%), achieved %.1f Hz, fallback cycles %d" %
          (seq, cycles, 100.0 * seq / max(cycles, 1), st.achieved_rate_hz, st.fallback_cycles))
    for name, v in (("client (telemetry arrival -> the daemon cycle that sent its command)", client_us),
                    ("built-in (telemetry arrival -> the daemon cycle that computed from it)", builtin_us)):
        if v:
            a = np.sort(np.array(v))
            print("%s: n=%d p50=%.1f us p99=%.1f us max=%.1f us" %
                  (name, len(a), a[len(a) // 2], a[int(0.99 * (len(a) - 1))], a[-1]))
    c.release()


if __name__ == "__main__":
    main()
