#!/usr/bin/env python3
"""The 1 kHz loop's period jitter while a browser shows the dashboard and Modbus clients poll (issue #20, item 6).

One phalanxd in API mode (control API, dashboard, Modbus server, the documented real-time set-up: SCHED_FIFO 80 and
locked memory for the loop, the simulated firmware under SCHED_FIFO --sim-fifo) runs three therapy sessions of
--phase seconds one after the other on the same device:
  quiet1  nothing else
  load    headless Chromium showing the dashboard (its page polls /api/samples every 100 ms and draws the plots)
          and --clients mbpoll processes each reading the whole Modbus input map every 10 ms
  quiet2  nothing else again (with quiet1: what the machine alone does in this run)
Each session's own summary gives the figures (period_jitter, overruns, cycle_time, round_trip). In each phase a
reference sleeper (cyclictest, SCHED_FIFO one priority below the loop, 1 kHz, no work) shows what the machine does
to any periodic real-time thread at the same time. Nothing is gated: the figures are printed (a benchmark).

Usage: tools/jitter-load.py [--bin build/host/bin] [--clients 16] [--phase 10] [--cycle telemetry|timer]
                            [--sim-fifo 70] [--pin CPU] [--device sim:glove5] [--no-browser]
"""
import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time

import cyclictest_summary

LOOP_PRIORITY = 80  # phalanxd's default realtime.priority


def api(bin_dir, sock, request):
    r = subprocess.run([os.path.join(bin_dir, "phalanx"), "api", "--socket", sock, json.dumps(request)],
                       capture_output=True, text=True, timeout=30)
    answer = json.loads(r.stdout) if r.stdout.strip() else {}
    if not answer.get("ok"):
        sys.exit(f"jitter-load: {request['cmd']} refused: {answer.get('error') or r.stderr.strip()}")
    return answer["result"]


def wait_port(port, timeout_s=5.0):
    """The session's Modbus server accepts connections (it starts with the session, after `start` answered)."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        try:
            socket.create_connection(("127.0.0.1", port), 0.2).close()
            return
        except OSError:
            time.sleep(0.05)
    sys.exit(f"jitter-load: the Modbus server did not accept connections on port {port}")


def tree_cpu_s(pid):
    """CPU seconds (user + system) of a process and its children still alive (Chromium's renderer, GPU process)."""
    total, tick = 0.0, os.sysconf("SC_CLK_TCK")
    pids, seen = [pid], set()
    while pids:
        p = pids.pop()
        if p in seen:
            continue
        seen.add(p)
        try:
            f = open(f"/proc/{p}/stat").read().rsplit(")", 1)[1].split()
            total += (int(f[11]) + int(f[12])) / tick
            for t in os.listdir(f"/proc/{p}/task"):
                pids += [int(c) for c in open(f"/proc/{p}/task/{t}/children").read().split()]
        except (OSError, IndexError, ValueError):
            pass
    return total


def reference_sleeper(work, name, seconds, pin):
    if shutil.which("cyclictest") is None:
        return None
    cmd = ["cyclictest", "--default-system", "-m", "-q", "-p", str(LOOP_PRIORITY - 1), "-i", "1000", "-h", "1000",
           "-D", str(seconds)] + (["-a", str(pin)] if pin is not None else [])
    return subprocess.Popen(cmd, stdout=open(os.path.join(work, f"ct-{name}.txt"), "w"), stderr=subprocess.STDOUT)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="build/host/bin")
    ap.add_argument("--clients", type=int, default=16)
    ap.add_argument("--phase", type=int, default=10, help="seconds per session")
    ap.add_argument("--cycle", choices=["telemetry", "timer"], default="telemetry")
    ap.add_argument("--sim-fifo", type=int, default=70, help="SCHED_FIFO priority of firmware-sim (0: default policy)")
    ap.add_argument("--pin", type=int, default=None, help="pin phalanxd, firmware-sim and the sleeper to this CPU")
    ap.add_argument("--device", default="sim:glove5")
    ap.add_argument("--port", type=int, default=15504, help="Modbus TCP port")
    ap.add_argument("--no-browser", dest="browser", action="store_false")
    a = ap.parse_args()
    if a.phase < 3:
        ap.error("--phase: at least 3 s")
    for tool in ["mbpoll"] + (["chromium"] if a.browser else []):
        if shutil.which(tool) is None:
            sys.exit(f"jitter-load: {tool} is not installed (tools/setup.sh --test installs it)")
    work = tempfile.mkdtemp(prefix="phalanx-jitter-load.")
    os.makedirs(os.path.join(work, "records"))
    os.makedirs(os.path.join(work, "profiles"))
    sock = os.path.join(work, "api.sock")
    with open(os.path.join(work, "phalanxd.yaml"), "w") as f:
        f.write(f"version: 1\ndevice: {a.device}\ncycle: {a.cycle}\nmodbus:\n  enabled: true\n  port: {a.port}\n"
                "dashboard:\n  listen: 127.0.0.1:0\n")
    pin = ["taskset", "-c", str(a.pin)] if a.pin is not None else []
    extra = []
    if a.sim_fifo > 0:
        wrapper = os.path.join(work, "firmware-sim")
        with open(wrapper, "w") as f:
            f.write(f"#!/bin/sh\nexec {shutil.which('chrt')} -f {a.sim_fifo} "
                    f"{os.path.abspath(os.path.join(a.bin, 'firmware-sim'))} \"$@\"\n")
        os.chmod(wrapper, 0o755)
        extra = ["--firmware-sim", wrapper]
    daemon = subprocess.Popen(pin + [os.path.join(a.bin, "phalanxd"), "--config", os.path.join(work, "phalanxd.yaml"),
                                     "--api", sock, "--records-dir", os.path.join(work, "records"),
                                     "--profiles-dir", os.path.join(work, "profiles")] + extra,
                              stdout=subprocess.PIPE, stderr=open(os.path.join(work, "phalanxd.err"), "w"), text=True)
    url = None
    for line in daemon.stdout:
        if line.startswith("DASHBOARD "):
            url = line.split(None, 1)[1].strip()
            break
    if url is None:
        sys.exit("jitter-load: phalanxd printed no dashboard URL:\n" + open(os.path.join(work, "phalanxd.err")).read())
    browser = None
    results = {}
    try:
        for name in ("quiet1", "load", "quiet2"):
            clients = []
            cpu0 = 0.0
            if name == "load" and a.browser:
                browser = subprocess.Popen(["chromium", "--headless=new", "--no-sandbox", "--disable-gpu",
                                            "--disable-dev-shm-usage", "--no-first-run", "--window-size=1100,900",
                                            f"--user-data-dir={work}/chromium", url],
                                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                time.sleep(3)  # the page loaded and polling before the session starts
                cpu0 = tree_cpu_s(browser.pid)
            ref = reference_sleeper(work, name, a.phase, a.pin)
            api(a.bin, sock, {"cmd": "start", "seconds": a.phase})
            if name == "load":
                wait_port(a.port)
                clients = [subprocess.Popen(["mbpoll", "-m", "tcp", "-p", str(a.port), "-0", "-t", "3", "-r", "0",
                                             "-c", "112", "-l", "10", "-o", "1", "127.0.0.1"],
                                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                           for _ in range(a.clients)]
            while api(a.bin, sock, {"cmd": "status"}).get("session_running"):
                time.sleep(0.5)
            s = api(a.bin, sock, {"cmd": "status"})["last_session"]
            for c in clients:
                c.terminate()
                c.wait()
            if ref is not None:
                ref.wait()
            r = {k: s.get(k) for k in ("cycles", "overruns", "period_jitter", "cycle_time", "round_trip", "realtime",
                                       "exit_code", "faults_seen")}
            r["modbus_requests"] = (s.get("modbus") or {}).get("requests")
            r["reference_sleeper"] = cyclictest_summary.summary(os.path.join(work, f"ct-{name}.txt"))
            if name == "load" and browser is not None:
                r["browser_cpu_s"] = round(tree_cpu_s(browser.pid) - cpu0, 2)
                browser.terminate()
                browser.wait()
                browser = None
            results[name] = r
    finally:
        if browser is not None:
            browser.kill()
        daemon.terminate()
        daemon.wait()
    out = {"device": a.device, "cycle": a.cycle, "sim_fifo": a.sim_fifo, "pinned_cpu": a.pin, "clients": a.clients,
           "browser": a.browser, "phase_s": a.phase, "loadavg_at_end": open("/proc/loadavg").read().split()[:3],
           "phases": results}
    print(json.dumps(out, indent=2))
    for name, r in results.items():
        j, c, rt = r["period_jitter"] or {}, r["cycle_time"] or {}, r["round_trip"] or {}
        line = (f"{name:6s} cycles={r['cycles']} overruns={r['overruns']} jitter p50={j.get('p50_us')} "
                f"p99={j.get('p99_us')} p99.9={j.get('p999_us')} max={j.get('max_us', 0):.0f} µs | cycle time "
                f"p99.9={c.get('p999_us')} | round trip p50={rt.get('p50_us')} | modbus requests={r['modbus_requests']}")
        if "browser_cpu_s" in r:
            line += f" | browser CPU {r['browser_cpu_s']} s"
        ref = r["reference_sleeper"]
        if ref:
            line += (f" | sleeper p99.9={ref['latency_p999_us']} max={ref['latency_max_us']} µs "
                     f"late>1ms={ref['late_over_1ms']}")
        print(line, file=sys.stderr)
    shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
