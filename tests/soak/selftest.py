#!/usr/bin/env python3
"""Self-test of the soak's invariant checker (docs/soak.md): every invariant must be able to fail.

Runs two real episodes (a clean glove5 session with --record CSV and --sim-truth, and a kill -9 of a recording
daemon on a standalone firmware-sim), checks that the checker passes them, then feeds the checker doctored copies
of that evidence, one damage each, and expects a violation of exactly the invariant the damage breaks:
setpoint beyond the device's limit, beyond the patient's effort_max, a fault without the safe state, a motor
driven while faulted, the firmware's watchdog late, a kill -9 record cut short (> 100 ms lost), rows missing
from a record, an undocumented exit code, an unexpected exit code.
Usage: selftest.py BIN_DIR      exit 0 when every doctored case is caught and the real ones pass
"""
import csv
import json
import os
import random
import re
import shutil
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import check  # noqa: E402
import soak  # noqa: E402

BIN = sys.argv[1] if len(sys.argv) > 1 else os.path.join(soak.REPO, "build", "host", "bin")
TMP = tempfile.mkdtemp(prefix="phalanx-soak-selftest-")
FAILS = []


def expect(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        FAILS.append(what)


def real(kind, device, seed):
    root = os.path.join(TMP, "real-" + kind)
    ep = soak.Episode(root, 0, kind, device, random.Random(seed))
    soak.RUNNERS[kind](ep, BIN, device)
    ep.save()
    return root


def violations(root):
    res = check.run(root)
    return res, sorted(set(v[0] for v in res.violations))


def doctored(src, name, fn):
    dst = os.path.join(TMP, name)
    shutil.copytree(src, dst)
    fn(os.path.join(dst, "ep0000"))
    return dst


def edit_csv(path, fn):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    body = fn(header, body)
    with open(path, "w", newline="") as f:
        csv.writer(f).writerows([header] + body)


def set_cells(changes, rows=range(100, 110)):
    def fn(header, body):
        for i in rows:
            for col, v in changes.items():
                body[i][header.index(col)] = str(v)
        return body
    return fn


def edit_meta(ep_dir, fn):
    p = os.path.join(ep_dir, "meta.json")
    m = json.load(open(p))
    fn(m)
    json.dump(m, open(p, "w"))


clean = real("clean", "glove5", 5)
res, v = violations(clean)
expect(not v, f"a real clean glove5 episode passes ({res.checks}; {res.violations[:3]})")
killed = real("kill9_daemon", "pantograph", 6)
res, v = violations(killed)
expect(not v, f"a real kill -9 episode passes (worst gap {res.worst_kill_gap_ms:.1f} ms; {res.violations[:3]})")

rec = lambda d: os.path.join(d, "record.csv")  # noqa: E731


def patient_case(header, body):
    """Every setpoint 0 (a session within every limit) but the thumb at 3.5 N for 10 rows: only the patient's
    thumb limit (3 N in demo-001) is broken."""
    for r in body:
        for i, h in enumerate(header):
            if h.startswith("setpoint"):
                r[i] = "0"
    return set_cells({"setpoint_thumb": 3.5})(header, body)


def late_watchdog(d):
    """The first SAFE line after the kill: outputs safe three ticks after the command's deadline."""
    off = json.load(open(os.path.join(d, "meta.json")))["firmware"]["log_offset_at_kill"]
    p = os.path.join(d, "firmware.stderr")
    text = open(p).read()
    tail = re.sub(r"SAFE t_us=(\d+) deadline_us=(\d+)", lambda m: f"SAFE t_us={int(m[2]) + 3000} deadline_us={m[2]}",
                  text[off:], count=1)
    open(p, "w").write(text[:off] + tail)
def no_watchdog(d):
    """The SAFE line after the kill removed: the killed daemon's record shows a driven device at the kill."""
    off = json.load(open(os.path.join(d, "meta.json")))["firmware"]["log_offset_at_kill"]
    p = os.path.join(d, "firmware.stderr")
    text = open(p).read()
    tail = re.sub(r"[^\n]*SAFE t_us=[^\n]*\n", "", text[off:], count=1)
    open(p, "w").write(text[:off] + tail)


cases = [
    ("setpoint beyond the device's 10 N", clean, "setpoint-limit",
     lambda d: edit_csv(rec(d), set_cells({"setpoint_index": 10.5}))),
    ("setpoint NaN", clean, "setpoint-limit", lambda d: edit_csv(rec(d), set_cells({"setpoint_ring": "nan"}))),
    ("thumb 3.5 N beyond the patient's 3 N (within the device's 10 N)", clean, "setpoint-limit",
     lambda d: (edit_csv(rec(d), patient_case),
                edit_meta(d, lambda m: m.update(patient_profile_for_records=os.path.join(
                    soak.REPO, "config", "profiles", "demo-001.yaml"))))),
    ("fault latched, mode left in setpoint for 10 ticks", clean, "fault-safe",
     lambda d: edit_csv(rec(d), set_cells({"fault_bits": 1, "mode": 2}))),
    ("fault latched, mode safe but a motor still driven", clean, "fault-safe",
     lambda d: edit_csv(rec(d), set_cells({"fault_bits": 1, "mode": 0, "duty_index": 0.3}))),
    ("rows missing from a record", clean, "record-loss", lambda d: edit_csv(rec(d), lambda h, b: b[:-50])),
    ("undocumented exit code", clean, "exit-report",
     lambda d: edit_meta(d, lambda m: (m["daemons"][0].update(exit=9), m["daemons"][0].update(expect_exit=[9])))),
    ("exit 6 where 0 was expected", clean, "exit-report", lambda d: edit_meta(d, lambda m: m["daemons"][0].update(exit=6))),
    ("kill -9 record cut to its first half (> 100 ms lost)", killed, "record-loss",
     lambda d: os.truncate(os.path.join(d, "record.mcap"), os.path.getsize(os.path.join(d, "record.mcap")) // 2)),
    ("the firmware's watchdog three ticks late", killed, "fault-safe",
     late_watchdog),
    ("no SAFE logged after the kill of a daemon that was driving", killed, "fault-safe",
     no_watchdog),
]
for i, (what, src, inv, fn) in enumerate(cases):
    res, v = violations(doctored(src, f"case{i}", fn))
    expect(v == [inv], f"doctored: {what}: violations of {v} (expected [{inv}]) {res.violations[:1]}")
    if "patient" in what:
        expect(all("setpoint_thumb" in x[2] and "patient" in x[2] for x in res.violations),
               f"doctored: only the thumb's patient limit is reported ({[x[2] for x in res.violations]})")

# The pen's safe state is also checked against the plant's truth: a motor torque in the truth while faulted.
def pen_truth(d):
    edit_csv(rec(d), set_cells({"fault_bits": 1, "mode": 0}))
    with open(rec(d)) as f:
        t = [r.split(",")[1] for r in f.readlines()[101:111]]
    def fn(header, body):
        for r in body:
            if r[0] in t:
                r[header.index("truth_motor_torque0_Nm")] = "0.5"
        return body
    edit_csv(os.path.join(d, "truth.csv"), fn)
pen = real("clean", "pantograph", 7)
res, v = violations(pen)
expect(not v, f"a real clean pantograph episode passes ({res.violations[:2]})")
res, v = violations(doctored(pen, "case-pen-truth", pen_truth))
expect(v == ["fault-safe"], f"doctored: pen faulted, safe mode, but the plant truth has motor torque: {v}")

# An input fault injected into the board (firmware-sim --inject): detected, and the outputs off within two ticks.
def late_detection(d):
    """The firmware's SAFE line after the injection moved three ticks later."""
    p = os.path.join(d, "firmware.stderr")
    text = open(p).read()
    m = re.search(r"INJECT \S+ started t_us=(\d+)", text)
    tail = re.sub(r"SAFE t_us=\d+", f"SAFE t_us={int(m[1]) + 3000}", text[m.end():], count=1)
    open(p, "w").write(text[:m.end()] + tail)


def never_latched(d):
    """The record's fault bits all cleared: the injected fault never shows."""
    edit_csv(rec(d), lambda h, b: [r[:h.index("fault_bits")] + ["0"] + r[h.index("fault_bits") + 1:] for r in b])


sensor = real("sensor_range", "sea_finger", 8)
res, v = violations(sensor)
expect(not v, f"a real sensor-range episode on the SEA passes ({res.violations[:2]})")
for what, fn in (("outputs safe three ticks after the injected sensor fault", late_detection),
                 ("the injected sensor fault never latched in the record", never_latched)):
    res, v = violations(doctored(sensor, "case-" + fn.__name__, fn))
    expect(v == ["fault-safe"], f"doctored: {what}: violations of {v} (expected ['fault-safe']) {res.violations[:1]}")

# A daemon behind the proxy may end on a lost link only after the proxy really sent it nothing for longer than the
# telemetry timeout.
def claims_lost_link(d):
    p = os.path.join(d, "daemon.json")
    summary = json.load(open(p))
    summary["link_error"] = "no telemetry from the device for 501 ms (telemetry_timeout_ms 500)"
    json.dump(summary, open(p, "w"))
    edit_meta(d, lambda m: m["daemons"][0].update(exit=6, link_silence_ms=min(m["daemons"][0]["link_silence_ms"], 300)))


stall = real("link_stall_short", "glove5", 9)
res, v = violations(stall)
expect(not v, f"a real short-stall episode passes ({res.violations[:2]})")
res, v = violations(doctored(stall, "case-claims-lost-link", claims_lost_link))
expect(v == ["exit-report"], f"doctored: exit 6 for no telemetry although the proxy's longest silence was 300 ms: {v}")

print(f"selftest: {len(FAILS)} failures; evidence in {TMP}")
if not FAILS:
    shutil.rmtree(TMP, ignore_errors=True)
sys.exit(1 if FAILS else 0)
