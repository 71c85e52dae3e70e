#!/usr/bin/env python3
"""A force field on the Twin-Pantograph pen from Python (docs/sdk.md "Python"): a virtual horizontal plane plus a
magnet point, both acting on the pen centre, rendered as a pen wrench that phalanxd converts through its
redundant-actuator force split (seeds/004 Fig. 18) and checks against the device's and the patient's limits.

  plane:   F_y = k_plane (y_plane - y) - b v_y      while the centre is below y_plane (y is up)
  magnet:  F   = k_magnet (p_m - p)                   while |p_m - p| < radius

With each command the example hands the daemon a compliant fallback: a spring of stiffness k_fallback whose
target is chosen so that it exerts this very force at the current pose (target = p + F / k_fallback). If this
client misses a cycle, the daemon renders that spring at the newest state instead of a stale force, until the
deadline (then force off, as always).

  pen_field.py --socket PATH [--seconds 2] [--plane-mm 5] [--magnet-mm 10,0,0] [--k-plane 400] [--k-magnet 150]
               [--radius-mm 30] [--damping 2] [--k-fallback 400] [--deadline-ms 250] [--log FILE]
               [--slow-every 0 --slow-ms 5]      (--k-fallback 0: no fallback, a missed cycle repeats the command)
The plane and the magnet are placed relative to the first pen centre seen (plane that many mm ABOVE it, so the
field engages at once). --log writes per command: telemetry_seq, rendered force (3), measured force (3) of the
state it was computed from, rendered kind (command / fallback-spring / ...).
"""
import argparse
import sys
import time

import numpy as np

import phalanx


def parse():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--socket", required=True)
    ap.add_argument("--seconds", type=float, default=2.0)
    ap.add_argument("--plane-mm", type=float, default=5.0)
    ap.add_argument("--magnet-mm", default="10,0,0")
    ap.add_argument("--k-plane", type=float, default=400.0)
    ap.add_argument("--k-magnet", type=float, default=150.0)
    ap.add_argument("--radius-mm", type=float, default=30.0)
    ap.add_argument("--damping", type=float, default=2.0)
    ap.add_argument("--k-fallback", type=float, default=400.0)
    ap.add_argument("--deadline-ms", type=int, default=250)
    ap.add_argument("--log")
    ap.add_argument("--slow-every", type=int, default=0, help="sleep --slow-ms every this many cycles (0: never)")
    ap.add_argument("--slow-ms", type=float, default=5.0)
    return ap.parse_args()


def field(p, v, plane_y, magnet, a):
    f = np.zeros(3)
    depth = plane_y - p[1]
    if depth > 0.0:
        f[1] = max(0.0, a.k_plane * depth - a.damping * v[1])  # a plane pushes, never pulls
    r = magnet - p
    if np.linalg.norm(r) < a.radius_mm * 1e-3:
        f += a.k_magnet * r
    return f


def main():
    a = parse()
    try:
        client = phalanx.Client(a.socket, deadline_ms=a.deadline_ms, fallback="safe")
    except phalanx.Error as e:
        print("pen_field: " + str(e), file=sys.stderr)
        return 3
    if client.device["name"] != "pantograph":
        print("pen_field: the device is %s, not the pantograph" % client.device["name"], file=sys.stderr)
        return 2
    s = None
    while s is None or not s.pen_valid:
        s = client.wait_state(1000)
    plane_y = s.pen_centre[1] + a.plane_mm * 1e-3
    magnet = s.pen_centre + np.array([float(x) for x in a.magnet_mm.split(",")]) * 1e-3
    log = open(a.log, "w") if a.log else None
    cycles = 0
    end = time.monotonic() + a.seconds
    rc = 0
    while time.monotonic() < end:
        s = client.wait_state(100)
        if s is None:
            continue
        if s.control == "forced-off":
            print("pen_field: forced off, cause %s" % s.force_off_cause, file=sys.stderr)
            rc = 4
            break
        p, v = s.pen_centre, s.pen_velocity
        f = field(p, v, plane_y, magnet, a) if s.pen_valid else np.zeros(3)
        fallback = [(p + f / a.k_fallback, a.k_fallback, 0.0)] if a.k_fallback > 0 else None
        client.set_pen_wrench(f, (0.0, 0.0, 0.0), fallback=fallback)
        if log:
            m = s.pen_force
            log.write("%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%s\n" % (s.telemetry_seq, f[0], f[1], f[2], m[0], m[1], m[2],
                                                                 s.rendered))
        cycles += 1
        if a.slow_every > 0 and cycles % a.slow_every == 0:
            time.sleep(a.slow_ms * 1e-3)
    last = client.get_state()
    if last is not None:
        print("pen_field: %d commands, achieved %.0f Hz, fallback cycles %d, model saturated %d, limited %d" %
              (cycles, last.achieved_rate_hz, last.fallback_cycles, last.model_saturated, last.limited))
    client.release()
    if log:
        log.close()
    return rc


if __name__ == "__main__":
    sys.exit(main())
