#!/usr/bin/env python3
"""Invariant checker of the soak (docs/soak.md): reads every episode's evidence in a soak's output directory and
fails on any broken invariant.

  setpoint-limit   every recorded setpoint is finite and within the device's limit (the layouts in
                   common/include/phalanx/protocol/devices.h) and, for a patient's session, within the profile's
                   effort_max (config/profiles/<patient>.yaml)
  fault-safe       from two device ticks after a fault appears (fault_bits != 0) for as long as it is latched, the
                   telemetry's mode is safe and the device drives nothing (duty 0 on the glove and the SEA, the
                   plant's motor torque 0 on the pen in the plant truth); the firmware's watchdog after a kill -9
                   of the daemon reports its outputs safe within two ticks of the command's deadline
  record-loss      a kill -9 of a recording daemon leaves a record whose newest message is at most 100 ms older
                   than the kill; every daemon that ended by itself has exactly the rows its summary reports
  exit-report      every daemon exits with a code of the README's "Exit codes" (or by the harness's own kill -9),
                   the one its fault calls for, with a parsable summary whose final_mode is safe and which names
                   the cause (link_error for 6, the recording's error for 7); damaged frames are all counted;
                   the API answers after every bad request

Usage: check.py OUT_DIR      exit 0: no violation; 1: violations (listed); 2: no episode found
"""

import csv
import json
import math
import os
import re
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(REPO, "python"))

DOCUMENTED_EXITS = {0, 2, 3, 4, 5, 6, 7}
TICK_US = 1000  # firmware-sim's default tick (1 kHz)
INVARIANTS = ("setpoint-limit", "fault-safe", "record-loss", "exit-report")


def device_limits():
    """|setpoint| limit per device name, read from the layouts in devices.h (the firmware's and host's source)."""
    text = open(os.path.join(REPO, "common", "include", "phalanx", "protocol", "devices.h")).read()
    pat = re.compile(r'constexpr DeviceLayout k\w+Layout\{\s*DeviceType::\w+,\s*"(\w+)",\s*(\d+),\s*([0-9.]+)f')
    return {m.group(1): float(m.group(3)) for m in pat.finditer(text)}


def patient_effort_max(profile):
    """effort_max per channel of a profile (default + named channels). A small reader for the one block."""
    out, block = {}, False
    for line in open(profile):
        s = line.split("#")[0].rstrip()
        if re.match(r"^\s+effort_max:\s*$", s):
            block = True
            continue
        if block:
            m = re.match(r"^\s{4,}(\w+):\s*([-0-9.eE+]+)\s*$", s)
            if not m:
                break
            out[m.group(1)] = float(m.group(2))
    return out


class Result:
    def __init__(self):
        self.checks = {k: 0 for k in INVARIANTS}
        self.violations = []
        self.injected = {}
        self.episodes = 0
        self.kinds = {}
        self.worst_kill_gap_ms = 0.0
        self.counted = {}  # what the daemons themselves counted (their summaries), beside what was injected

    def count(self, k, v):
        if isinstance(v, (int, float)) and v:
            self.counted[k] = self.counted.get(k, 0) + v

    def check(self, inv, ok, where, what):
        self.checks[inv] += 1
        if not ok:
            self.violations.append((inv, where, what))


def load_record(path):
    """Columns (name -> list of floats) of a --record CSV, or via phalanx.records for .mcap / .phrec."""
    if path.endswith(".csv"):
        with open(path, newline="") as f:
            r = csv.reader(f)
            header = next(r, None)
            if header is None:
                return {}, 0
            cols = {h: [] for h in header}
            n = 0
            for row in r:
                if len(row) != len(header):
                    cols.setdefault("__torn_rows", []).append(n)
                    continue
                for h, v in zip(header, row):
                    cols[h].append(float(v) if v not in ("", "nan", "NaN") else math.nan)
                n += 1
            return cols, n
    from phalanx import records
    rec = records.load(path)
    cols = {k: list(map(float, rec[k])) for k in rec.columns}
    if rec.format == "mcap":
        times = [t for topic in rec.topics.values() for t in topic.get("log_time_ns", [])]
        cols["__log_time_ns"] = [max(times)] if times else []
    if rec.format == "phrec":
        cols["__setpoint_names"] = list(rec.header.get("setpoints", []))
    return cols, len(rec)


def check_setpoints(res, where, cols, device, limits, effort):
    lim = limits.get(device)
    names = [c for c in cols if c.startswith("setpoint")] + list(cols.get("__setpoint_names", []))
    names = sorted(set(n for n in names if n in cols))
    res.check("setpoint-limit", lim is not None and bool(names), where,
              f"device {device}: limit known ({lim}) and setpoint columns recorded ({len(names)})")
    if lim is None:
        return
    for n in names:
        vals = cols[n]
        bad = [v for v in vals if not math.isfinite(v) or abs(v) > lim * (1 + 1e-6)]
        res.check("setpoint-limit", not bad, where, f"{n}: {len(bad)} of {len(vals)} setpoints not finite or beyond "
                  f"the device's {lim} (first {bad[:1]})")
        if effort:
            ch = next((c for c in effort if c != "default" and (n.endswith("_" + c) or n.endswith("_" + c + "_N"))), None)
            cap = effort.get(ch, effort.get("default"))
            if cap is not None:
                badp = [v for v in vals if math.isfinite(v) and abs(v) > cap * (1 + 1e-6)]
                res.check("setpoint-limit", not badp, where, f"{n}: {len(badp)} setpoints beyond the patient's "
                          f"effort_max {cap} (first {badp[:1]})")


def load_truth(path):
    cols, _ = load_record(path)
    if "device_time_us" not in cols:
        return {}
    torque = [c for c in cols if c.startswith("truth_motor_torque")]
    return {int(t): max(abs(cols[c][i]) for c in torque) if torque else 0.0
            for i, t in enumerate(cols["device_time_us"])}


def check_fault_safe(res, where, cols, truth):
    if "fault_bits" not in cols or "mode" not in cols:
        return
    t, fb, mode = cols["device_time_us"], cols["fault_bits"], cols["mode"]
    duty = [c for c in cols if c.startswith("duty")]
    onset = None
    bad = []
    faulted_rows = 0
    for i in range(len(t)):
        if fb[i] == 0 or math.isnan(fb[i]):
            onset = None
            continue
        faulted_rows += 1
        if onset is None:
            onset = t[i]
        if t[i] < onset + 2 * TICK_US:
            continue
        driving = [c for c in duty if abs(cols[c][i]) > 1e-6]
        torque = truth.get(int(t[i]), 0.0) if truth else 0.0
        if mode[i] != 0 or driving or torque > 1e-6:
            bad.append((int(t[i]), int(fb[i]), int(mode[i]), driving[:2], torque))
    res.check("fault-safe", not bad, where, f"{len(bad)} faulted rows (of {faulted_rows}) two ticks after the fault "
              f"not safe (first: device_time_us, fault_bits, mode, driving, truth torque = {bad[:1]})")


def check_watchdog_log(res, where, log_path, offset, end, killed_record):
    """The firmware's outputs after a kill -9 of the daemon: the first SAFE line between the kill and the next
    daemon's start is the watchdog's. With none there, the outputs were already off at the kill (a fault latched
    before it), which the killed daemon's last recorded cycle must show."""
    log = open(log_path, errors="replace").read()[offset:end]
    m = re.search(r"SAFE t_us=(\d+) deadline_us=(\d+) period_us=(\d+) faults=0x([0-9a-f]+)", log)
    if m:
        t, dl, per, faults = int(m[1]), int(m[2]), int(m[3]), int(m[4], 16)
        res.check("fault-safe", t > dl and t - dl <= 2 * per and faults & 1, where,
                  f"watchdog: outputs safe {t - dl} us after the deadline (<= {2 * per}), faults 0x{faults:04x} "
                  "with command-timeout")
        return
    cols, n = load_record(killed_record) if os.path.exists(killed_record) else ({}, 0)
    driving = [c for c in cols if c.startswith("duty") and n and abs(cols[c][-1]) > 1e-6]
    undriven = n > 0 and cols["fault_bits"][-1] != 0 and cols["mode"][-1] == 0 and not driving
    res.check("fault-safe", undriven, where,
              "no SAFE logged after the kill -9, so the outputs must have been off already: the killed daemon's "
              f"last recorded cycle has a fault latched, mode safe and no duty ({n} cycles recorded)")


def summary_of(path):
    try:
        text = open(path).read()
    except OSError:
        return None, "no summary file"
    if not text.strip():
        return None, "empty summary"
    try:
        return json.loads(text), None
    except ValueError as e:
        return None, f"summary is not JSON: {e}"


TELEMETRY_TIMEOUT_MS = 500  # phalanxd's default telemetry_timeout_ms (host/include/phalanx/host/daemon.h)


def check_silence_claim(res, where, link_error, silence_ms):
    """A daemon behind the soak's proxy that ended on a lost link: true only if the proxy sent it nothing for
    longer than the telemetry timeout, and the silence it reports is no longer than the one the proxy measured
    (5 ms allowed for the two processes' clock reads)."""
    m = re.match(r"no telemetry from the device for (\d+(?:\.\d+)?) ms", link_error)
    res.count("link.silent_past_timeout", 1)
    res.check("exit-report", bool(m) and float(m[1]) > TELEMETRY_TIMEOUT_MS and float(m[1]) <= silence_ms + 5, where,
              f"exit 6 ({link_error!r}) only after a silence past the {TELEMETRY_TIMEOUT_MS} ms telemetry timeout, "
              f"no longer than the proxy's longest: {silence_ms} ms")


def check_daemon(res, ep_dir, meta, d, limits):
    where = f"{os.path.basename(ep_dir)} {meta['kind']} {meta['device']} {d['name']}"
    rc = d.get("exit")
    killed = rc == -9 and "kill_wall_ns" in d
    expect = d.get("expect_exit", [])
    res.check("exit-report", not d.get("hung"), where, "the daemon ended within its time (not hung)")
    res.check("exit-report", killed or rc in DOCUMENTED_EXITS, where, f"exit {rc} is a documented code")
    res.check("exit-report", (killed and "SIGKILL" in expect) or rc in expect, where, f"exit {rc}, expected {expect}")
    summary = None
    if not killed and d.get("summary"):
        summary, err = summary_of(os.path.join(ep_dir, d["summary"]))
        res.check("exit-report", summary is not None, where, f"a summary on stdout ({err})")
    # A lost link's final_mode is the last frame before the loss (the device's own watchdog makes it safe).
    if summary is not None and "final_mode" in summary and rc != 6:
        res.check("exit-report", summary["final_mode"] == "safe", where,
                  f"device left safe (final_mode {summary.get('final_mode')})")
    if summary is not None:
        for k, v in (summary.get("host_rx_errors") or {}).items():
            res.count("host_rx_errors." + k, v)
        for k in ("refused_by_host_limits", "limited_by_device_limits", "limited_by_patient_limits",
                  "rejected_by_device"):
            res.count("commands." + k, (summary.get("commands") or {}).get(k))
        for k in ("refused_invalid", "force_offs"):
            res.count("client." + k, (summary.get("client") or {}).get(k))
        for k in ("exceptions", "writes_accepted", "command_timeouts"):
            res.count("modbus." + k, (summary.get("modbus") or {}).get(k))
        res.count("daemon_exit." + str(rc), 1)
    elif killed:
        res.count("daemon_exit.SIGKILL", 1)
    if summary is not None and rc == 6:
        res.check("exit-report", bool(summary.get("link_error")), where, "exit 6 names the link error")
    if summary is not None and "expect_reconnects" in d:
        o = summary.get("outages") or {}
        res.check("exit-report", o.get("count") == o.get("reconnects") == d["expect_reconnects"] and
                  o.get("connected_at_end") is True, where,
                  f"the unplugged port: {d['expect_reconnects']} outage reported, reconnected, connected at the end "
                  f"(outages {o})")
    if summary is not None and rc == 6 and "link_silence_ms" in d:
        check_silence_claim(res, where, summary.get("link_error") or "", d["link_silence_ms"])
    if summary is not None and rc == 7:
        rec_err = (summary.get("recording") or {}).get("error") or summary.get("error")
        res.check("exit-report", bool(rec_err), where, "exit 7 names the recording's error")
    if summary is not None and meta.get("injected"):
        inj = meta["injected"]
        damaged = inj.get("corrupt", 0) + inj.get("truncate", 0) + inj.get("flood_garbage_frames", 0)
        # After a lost link (exit 6) the frames damaged once the daemon had stopped reading were never offered to
        # it: only a daemon that ended by itself must have counted them all.
        if damaged and rc != 6:
            counted = sum((summary.get("host_rx_errors") or {}).values())
            res.check("exit-report", counted >= damaged, where,
                      f"every damaged frame counted: host_rx_errors {counted} >= {damaged} injected")

    rec = d.get("record")
    if not rec:
        return
    path = os.path.join(ep_dir, rec)
    if not os.path.exists(path):
        res.check("record-loss", False, where, f"record {rec} missing")
        return
    try:
        cols, rows = load_record(path)
    except Exception as e:  # an unreadable record is lost data
        res.check("record-loss", False, where, f"record {rec} unreadable: {e!r}")
        return
    res.check("record-loss", "__torn_rows" not in cols, where, f"{rec}: no torn row "
              f"({len(cols.get('__torn_rows', []))})")
    effort = None
    if meta.get("patient_profile") and rec.endswith(".phrec") or meta.get("patient_profile_for_records"):
        effort = patient_effort_max(meta.get("patient_profile") or meta["patient_profile_for_records"])
    check_setpoints(res, where, cols, meta["device"], limits, effort)
    truth = {}
    if d.get("truth") and os.path.exists(os.path.join(ep_dir, d["truth"])):
        truth = load_truth(os.path.join(ep_dir, d["truth"]))
    check_fault_safe(res, where, cols, truth)
    if killed and "__log_time_ns" in cols:
        newest = cols["__log_time_ns"][0] if cols["__log_time_ns"] else 0
        gap_ms = (d["kill_wall_ns"] - newest) / 1e6
        res.worst_kill_gap_ms = max(res.worst_kill_gap_ms, gap_ms)
        res.check("record-loss", gap_ms <= 100.0, where, f"kill -9: newest recorded message {gap_ms:.1f} ms "
                  "before the kill (<= 100 ms)")
    if summary is not None and isinstance(summary.get("recording"), dict) and "rows" in summary["recording"]:
        want = summary["recording"]["rows"]
        res.check("record-loss", want == rows, where, f"{rec}: {rows} rows in the file, the summary says {want}")


def merge_pruned(res, ep_dir):
    """An episode checked during the soak and pruned (soak.py --prune): its records are gone, its result kept."""
    done = json.load(open(os.path.join(ep_dir, "checked.json")))
    res.episodes += 1
    res.kinds[done["kind"]] = res.kinds.get(done["kind"], 0) + 1
    for table, src in ((res.checks, done["checks"]), (res.injected, done["injected"]), (res.counted, done["counted"])):
        for k, v in src.items():
            table[k] = table.get(k, 0) + v
    res.violations += [tuple(v) for v in done["violations"]]
    res.worst_kill_gap_ms = max(res.worst_kill_gap_ms, done["worst_kill_gap_ms"])


def episode_result(ep_dir, limits):
    """One episode checked on its own (soak.py --prune stores it as checked.json before deleting the records)."""
    r = Result()
    check_episode(r, ep_dir, limits)
    kind = next(iter(r.kinds))
    return {"kind": kind, "checks": r.checks, "injected": r.injected, "counted": r.counted,
            "violations": r.violations, "worst_kill_gap_ms": r.worst_kill_gap_ms}


# Ticks from an injected input fault to the outputs off: the e-stop and a sensor's plausibility are read every
# tick (detected in the tick after the injection, outputs off in that tick); a frozen glove sensor needs
# FrozenSensorLimits::stuck_ticks (250, firmware/apps/include/phalanx/apps/frozen_sensor.h) unchanged ticks first.
# A frozen pen encoder is seen once the pen has moved ~2 mm in a way that encoder should have measured (the rigid-pen
# watch, firmware/apps/include/phalanx/apps/pantograph.h): that depends on the hand's motion, 51-691 ticks for the
# first encoder over 60 seeds of the random hand (lockstep), so its bound is a generous 1500.
INJECT_TICKS = {"sensor-range": 2, "estop": 2, "sensor-stuck": 250 + 2}
PEN_STUCK_TICKS = 1500 + 2


def check_injected_input(res, where, meta, ep_dir):
    """An input fault injected by firmware-sim --inject: the record shows its fault bit latched, and the firmware's
    outputs went off within INJECT_TICKS of the injection (its SAFE line after the INJECT line), or were already
    off then (no SAFE line after it: then no recorded cycle from the injection on drives anything)."""
    spec, bit = meta["firmware"]["inject"], meta["expect_fault"]
    d = next((x for x in meta["daemons"] if x["name"] == "daemon"), {})
    path = os.path.join(ep_dir, d.get("record") or "")
    cols, n = load_record(path) if os.path.exists(path) else ({}, 0)
    latched = any(not math.isnan(v) and int(v) & bit for v in cols.get("fault_bits", []))
    res.check("fault-safe", latched, where, f"{spec}: fault bit 0x{bit:04x} latched in the record ({n} cycles)")
    log = open(os.path.join(ep_dir, meta["firmware"]["stderr"]), errors="replace").read()
    m = re.search(r"INJECT (\S+) started t_us=(\d+)", log)
    if not m:
        res.check("fault-safe", False, where, f"{spec}: the firmware logged no INJECT line")
        return
    t_inj, per = int(m[2]), TICK_US
    safe = re.search(r"SAFE t_us=(\d+) deadline_us=\d+ period_us=(\d+) faults=0x([0-9a-f]+)", log[m.end():])
    if safe:
        t, per, faults = int(safe[1]), int(safe[2]), int(safe[3], 16)
        ticks = PEN_STUCK_TICKS if m[1] == "sensor-stuck" and meta["device"] == "pantograph" else INJECT_TICKS[m[1]]
        bound = ticks * per
        res.check("fault-safe", t - t_inj <= bound and faults & bit, where,
                  f"{spec}: outputs safe {t - t_inj} us after the injection (<= {bound}), faults 0x{faults:04x}")
        return
    duty = [c for c in cols if c.startswith("duty")]
    t = cols.get("device_time_us", [])
    driving = [int(t[i]) for i in range(n) if t[i] >= t_inj and any(abs(cols[c][i]) > 1e-6 for c in duty)]
    res.check("fault-safe", n > 0 and not driving, where, f"{spec}: no SAFE logged after the injection, so nothing "
              f"may be driven from it on ({len(driving)} recorded cycles drive; first {driving[:1]})")


def check_episode(res, ep_dir, limits):
    if os.path.exists(os.path.join(ep_dir, "checked.json")):
        merge_pruned(res, ep_dir)
        return
    meta = json.load(open(os.path.join(ep_dir, "meta.json")))
    res.episodes += 1
    res.kinds[meta["kind"]] = res.kinds.get(meta["kind"], 0) + 1
    for k, v in meta.get("injected", {}).items():
        res.injected[k] = res.injected.get(k, 0) + v
    where = f"{os.path.basename(ep_dir)} {meta['kind']} {meta['device']}"
    res.check("exit-report", "harness_error" not in meta, where, f"harness ran the episode ({meta.get('harness_error')})")
    if meta.get("skipped"):
        return
    for d in meta.get("daemons", []):
        check_daemon(res, ep_dir, meta, d, limits)
    fw = meta.get("firmware")
    if fw and "log_offset_at_kill" in fw:
        killed = next((d for d in meta.get("daemons", []) if d.get("exit") == -9), {})
        check_watchdog_log(res, where, os.path.join(ep_dir, fw["stderr"]), fw["log_offset_at_kill"],
                           fw.get("log_offset_at_restart"), os.path.join(ep_dir, killed.get("record", "")))
    if fw and "inject" in fw:
        check_injected_input(res, where, meta, ep_dir)
    if fw and "exit" in fw:
        res.check("exit-report", fw["exit"] == 0, where, f"firmware-sim exited 0 on SIGTERM (got {fw['exit']})")
    if "api_garbage_sent" in meta:
        res.check("exit-report", meta["api_status_ok_after_garbage"] == meta["api_garbage_sent"], where,
                  f"the API answered status after each bad request ({meta['api_status_ok_after_garbage']} of "
                  f"{meta['api_garbage_sent']})")
    if "start" in meta:
        res.check("exit-report", meta["start"]["exit"] == 0, where, f"phalanx start exit {meta['start']['exit']}: "
                  f"{meta['start']['stderr'][-300:]}")
    if "stop" in meta:
        res.check("exit-report", meta["stop"]["exit"] == 0, where, f"phalanx stop exit {meta['stop']['exit']}")
        try:
            ans = json.load(open(os.path.join(ep_dir, meta["stop"]["answer"])))
            ans = ans.get("result", ans)
        except (OSError, KeyError, ValueError):
            ans = None
        res.check("exit-report", isinstance(ans, dict) and ans.get("final_mode") == "safe", where,
                  "the stop answer is a summary with the device left safe (final_mode "
                  f"{ans.get('final_mode') if isinstance(ans, dict) else None})")
    if "client_exit" in meta:
        res.check("exit-report", meta["client_exit"] == 0, where, f"the misbehaving client ran (exit "
                  f"{meta['client_exit']})")


def run(out_dir):
    res = Result()
    limits = device_limits()
    eps = sorted(e for e in os.listdir(out_dir) if e.startswith("ep") and
                 os.path.exists(os.path.join(out_dir, e, "meta.json")))
    for e in eps:
        check_episode(res, os.path.join(out_dir, e), limits)
    return res


def main(argv):
    out_dir = argv[0]
    res = run(out_dir)
    if res.episodes == 0:
        print(f"check: no episode in {out_dir}")
        return 2
    print(f"check: {res.episodes} episodes, kinds {json.dumps(res.kinds, sort_keys=True)}")
    print(f"check: faults injected {json.dumps(res.injected, sort_keys=True)}")
    print(f"check: daemons counted {json.dumps(res.counted, sort_keys=True)}")
    for inv in INVARIANTS:
        nv = sum(1 for v in res.violations if v[0] == inv)
        print(f"check: {inv:15s} {res.checks[inv]:6d} checks, {nv} violations")
    print(f"check: worst kill -9 record gap {res.worst_kill_gap_ms:.1f} ms")
    for inv, where, what in res.violations:
        print(f"VIOLATION {inv}: {where}: {what}")
    with open(os.path.join(out_dir, "report.json"), "w") as f:
        json.dump({"episodes": res.episodes, "kinds": res.kinds, "injected": res.injected, "counted": res.counted, "checks": res.checks,
                   "violations": res.violations, "worst_kill_gap_ms": res.worst_kill_gap_ms}, f, indent=1)
    return 1 if res.violations else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
