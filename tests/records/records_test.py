#!/usr/bin/env python3
"""Recordings read by independent readers (issue 23): run by ctest as records_python_test.

Runs the real phalanxd on simulated devices and checks:
  * every MCAP file the daemon and `phalanx record export --mcap` write is read by the `mcap` package from PyPI
    with CRC validation, through its summary (seeking reader) and message by message (non-seeking); the summary's
    statistics and chunk indexes match the messages; decoded values equal the daemon's own (.phrec) values;
  * kill -9 during a recorded session: the .mcap (--record) and the .phrec (--session-record) open and hold data
    to within 100 ms of the kill;
  * the report's range of motion recomputed from the CSV export equals the report's table;
  * --record CSV has named columns with units; phalanx.records.load reads .phrec, CSV and MCAP alike;
  * storage: bytes per second per device and format (printed, not gated: they depend on the motion).
Usage: records_test.py BIN_DIR   (PYTHONPATH must hold <repo>/python)
"""

import html
import json
import math
import os
import re
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np
from mcap.exceptions import EndOfFile
from mcap.reader import NonSeekingReader, make_reader
from mcap.records import Channel, Message
from mcap.stream_reader import StreamReader

from phalanx import records

BIN = sys.argv[1] if len(sys.argv) > 1 else "build/host/bin"
TMP = tempfile.mkdtemp(prefix="phalanx-records-")
FAILS = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        FAILS.append(what)


def run(args, timeout=120):
    p = subprocess.run(args, capture_output=True, text=True, timeout=timeout)
    if p.returncode != 0:
        print(p.stdout[-2000:], p.stderr[-2000:])
    return p


def daemon(*args):
    return [os.path.join(BIN, "phalanxd"), "--no-realtime", *args]


def read_mcap(path):
    """Messages through the summary (seeking reader, CRCs validated) and message by message; both must agree."""
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        seek = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages(log_time_order=False)]
    with open(path, "rb") as f:
        stream = [(c.topic, m.log_time, m.data) for _, c, m in
                  NonSeekingReader(f, validate_crcs=True).iter_messages()]
    return summary, seek, stream


def check_mcap_file(path, what):
    summary, seek, stream = read_mcap(path)
    check(summary is not None and summary.statistics is not None, f"{what}: MCAP summary with statistics")
    st = summary.statistics
    check(st.message_count == len(stream) == len(seek), f"{what}: statistics count {st.message_count} = "
          f"messages read {len(stream)} (stream) = {len(seek)} (indexed)")
    per_channel = {}
    for t, _, _ in stream:
        per_channel[t] = per_channel.get(t, 0) + 1
    by_id = {cid: summary.channels[cid].topic for cid in summary.channels}
    check(all(per_channel.get(by_id[c], 0) == n for c, n in st.channel_message_counts.items()),
          f"{what}: per-channel counts match the statistics")
    check(st.chunk_count == len(summary.chunk_indexes) and st.chunk_count > 0, f"{what}: {st.chunk_count} chunks indexed")
    check(sorted(seek) == sorted(stream), f"{what}: indexed and streamed messages identical")
    chunks_ok = all(ci.message_end_time - ci.message_start_time <= 110_000_000 for ci in summary.chunk_indexes)
    check(chunks_ok, f"{what}: every chunk spans <= 100 ms of messages")
    schemas = {s.name: s.encoding for s in summary.schemas.values()}
    check(schemas.get("sensor_msgs/msg/JointState") == "ros2msg", f"{what}: JointState schema is ros2msg")
    encodings = {c.topic: c.message_encoding for c in summary.channels.values()}
    check(encodings.get("/phalanx/mechanism/joint_states") == "cdr" and encodings.get("/phalanx/telemetry") == "json",
          f"{what}: CDR for ROS 2 types, JSON elsewhere")
    return summary, stream


def same(a, b):
    """float32 equality, NaN equal to NaN (JSON null)."""
    a = np.float32(math.nan if a is None else a)
    return a == b or (np.isnan(a) and np.isnan(b))


def json_topic(stream, topic):
    return [json.loads(d) for t, _, d in stream if t == topic]


# ---- 1. a glove therapy session: .phrec, report, CSV export, MCAP export --------------------------------------
phrec = os.path.join(TMP, "glove.phrec")
report = os.path.join(TMP, "glove.html")
p = run(daemon("--device", "sim:glove5", "--scenario", "close-open", "--session-record", phrec, "--exercise",
               "assessment", "--report", report, "--seconds", "3", "--seed", "3"))
check(p.returncode == 0, "glove session with --session-record and --report")
rec = records.load(phrec)
check(rec.format == "phrec" and len(rec) > 2500, f"phalanx.records.load(.phrec): {len(rec)} cycles")
check(rec.integrity["bad_records"] == 0 and rec.integrity["complete"], ".phrec: no damaged record, complete")
check(rec.header.get("format_version") == 2, ".phrec: format version 2 (compressed cycle blocks)")
info = json.loads(run([os.path.join(BIN, "phalanx"), "record", "info", phrec]).stdout)
check(info["cycles"] == len(rec), f"Python reader and phalanx record info agree on {info['cycles']} cycles")

csv_out = os.path.join(TMP, "glove.csv")
p = run([os.path.join(BIN, "phalanx"), "record", "export", phrec, "--out", csv_out])
check(p.returncode == 0, "record export without --csv writes CSV (the default)")
csv = records.load(csv_out)
check(len(csv) == len(rec), "CSV export: one row per cycle")
joints = [j["name"] for j in rec.header["joints"]]
check(all(f"{j}_flexion_deg" in csv for j in joints), "CSV export has every joint's flexion in degrees")
check(all(f"alpha{a}_index_rad" in csv for a in (1, 2, 3)), "CSV export has the mechanism angles (rad)")
check(np.array_equal(csv["force_index_N"].astype(np.float32), rec["force_index_N"]),
      "CSV export values equal the record's (float32)")

# Range of motion from the CSV export, the report's way: 5 Hz first-order low-pass on t_s, min/max within the
# assessment (exercise_id 1 in the aux values; the whole session if there is none), leaving out the cycles the
# device was faulted or locked after a fault (docs/therapy.md: from a fault until the device moves again, while
# the session commanded a mode other than safe (0) or lock (3)).
def excluded_cycles(csv):
    out, after_fault = [], False
    for fault, tel_mode, cmd_mode in zip(csv["fault_bits"], csv["tel_mode"], csv["cmd_mode"]):
        if fault != 0:
            after_fault = True
        elif tel_mode not in (0, 3):
            after_fault = False
        out.append(fault != 0 or (after_fault and cmd_mode not in (0, 3)))
    return out


page = open(report).read()
metrics = json.loads(html.unescape(re.search(r"id='metrics'>(.*?)</script>", page, re.S).group(1)))
ex = csv["exercise_id"]
assess = np.any(ex == 1)
t = csv["t_s"]
excluded = excluded_cycles(csv)
if any(excluded):
    print(f"note the session faulted: {sum(excluded)} cycles excluded from the metrics, as the report does")
excluded_s = sum(t[i] - t[i - 1] for i in range(1, len(t)) if excluded[i])
check(abs(excluded_s - metrics.get("excluded_s", 0.0)) < 1e-3,
      f"excluded time from the CSV export {excluded_s:.3f} s = the report's {metrics.get('excluded_s', 0.0):.3f} s")
worst = 0.0
for j in joints:
    x = csv[f"{j}_flexion_deg"]
    lp, lo, hi, prev = math.nan, math.inf, -math.inf, 0.0
    for i in range(len(t)):
        if not math.isfinite(x[i]):
            continue
        dt = max(t[i] - prev, 0.0) if math.isfinite(lp) else 0.0
        a = dt / (dt + 1.0 / (2.0 * math.pi * 5.0))
        lp = lp + a * (x[i] - lp) if math.isfinite(lp) else x[i]
        prev = t[i]
        if (assess and ex[i] != 1) or excluded[i]:
            continue
        lo, hi = min(lo, lp), max(hi, lp)
    want = metrics["rom_deg"][j]
    worst = max(worst, abs(lo - want[0]), abs(hi - want[1]))
    # The table shows the range with one decimal.
    row = re.search(r"<tr><td>" + re.escape(j) + r"</td><td>([-0-9.]+)</td><td>([-0-9.]+)</td>", page)
    if row:
        check(abs(float(row.group(1)) - lo) <= 0.051 and abs(float(row.group(2)) - hi) <= 0.051,
              f"ROM {j}: table {row.group(1)}..{row.group(2)} = CSV {lo:.3f}..{hi:.3f}")
# The export prints t_s with 1 µs resolution (the report filters on the exact double), hence not bit-exact.
check(worst < 1e-3, f"ROM recomputed from the CSV export equals the report's for all {len(joints)} joints "
      f"(largest difference {worst:.2e} deg; the table shows 0.1 deg)")

mcap_out = os.path.join(TMP, "glove.mcap")
p = run([os.path.join(BIN, "phalanx"), "record", "export", phrec, "--mcap", "--out", mcap_out])
check(p.returncode == 0, "record export --mcap")
summary, stream = check_mcap_file(mcap_out, "export")
tel = json_topic(stream, "/phalanx/telemetry")
check(len(tel) == len(rec), f"export: one telemetry message per cycle ({len(tel)})")
names = rec.header["samples"]
check(all(same(m[n], rec[n][i]) for i, m in enumerate(tel) for n in names), "export: every decoded telemetry sample equals the .phrec's value")
cmd = json_topic(stream, "/phalanx/command")
check(all(same(m[n], rec[n][i]) for i, m in enumerate(cmd) for n in rec.header["setpoints"]),
      "export: every decoded setpoint equals the .phrec's value")
ther = json_topic(stream, "/phalanx/therapy")
check(all(same(m[n], rec[n][i]) for i, m in enumerate(ther) for n in rec.header["aux"]),
      "export: every therapy value equals the .phrec's value")
mrec = records.load(mcap_out)
js = mrec.topics["/phalanx/joint_states"]
flex = np.deg2rad(csv[f"{joints[0]}_flexion_deg"])
ok = np.allclose(js[joints[0]], flex, rtol=0, atol=1e-12, equal_nan=True)
check(ok, "export: JointState flexion (CDR) equals the CSV export's flexion")
check(len(mrec.events) == len(rec.events), f"export: {len(rec.events)} events")
check("/diagnostics" in mrec.topics and len(mrec.topics["/phalanx/loop_stats"]["cycles"]) >= 2,
      "export: loop statistics on /phalanx/loop_stats and /diagnostics")

# ---- 2. --record on each device: MCAP and named CSV columns --------------------------------------------------
sizes = {}
for dev in ("glove5", "sea_finger", "pantograph"):
    for ext in ("mcap", "csv"):
        out = os.path.join(TMP, f"live-{dev}.{ext}")
        # A --no-realtime session on a loaded machine can be starved past the device's command timeout or the
        # telemetry timeout (the session then ends with exit 6): that is the machine, not the recording; such a
        # session is run again (at most 3 times), and said so.
        for attempt in range(3):
            p = run(daemon("--device", f"sim:{dev}", "--record", out, "--seconds", "2", "--seed", "1"))
            if p.returncode == 0 or "command-timeout" not in p.stderr:
                break
            print(f"note {dev} .{ext}: attempt {attempt}: the starved session latched command-timeout; once more")
        check(p.returncode == 0, f"{dev}: --record .{ext}")
        r = records.load(out)
        # Bytes per cycle x 1000 Hz: the nominal rate (a loaded machine stretches --no-realtime sessions in time).
        sizes[(dev, ext)] = os.path.getsize(out) / max(len(r), 1) * 1000.0
        if ext == "csv":
            header = open(out).readline().strip().split(",")
            check(not any(re.fullmatch(r"sample\d+|setpoint\d+", h) for h in header),
                  f"{dev}: CSV columns are named ({header[6]}, …)")
        else:
            summary, stream = check_mcap_file(out, f"{dev} live")
            tel = json_topic(stream, "/phalanx/telemetry")
            check(len(tel) == len(r) and len(tel) > 1500, f"{dev}: {len(tel)} telemetry messages")
    csv_rows = records.load(os.path.join(TMP, f"live-{dev}.csv"))
    check(len(csv_rows) > 1500, f"{dev}: CSV {len(csv_rows)} rows")

# ---- 3. kill -9 during a recorded session ---------------------------------------------------------------------
for kind, flag, ext in (("--record", "--record", "mcap"), ("--session-record", "--session-record", "phrec")):
    worst_gap = 0.0
    for k in range(2):
        out = os.path.join(TMP, f"killed-{k}.{ext}")
        args = daemon("--device", "sim:glove5", "--scenario", "close-open", flag, out, "--seconds", "0",
                      "--seed", str(k + 1))
        if ext == "phrec":
            args += ["--exercise", "assessment"]
        d = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(1.5 + 0.37 * k)
        kill_wall_ns = time.time_ns()
        d.send_signal(signal.SIGKILL)
        d.wait()
        if ext == "mcap":
            msgs, ended, topics = [], None, {}
            with open(out, "rb") as f:
                try:  # the package's StreamReader: records in file order, chunks' CRCs validated
                    for r in StreamReader(f, validate_crcs=True).records:
                        if isinstance(r, Channel):
                            topics[r.id] = r.topic
                        elif isinstance(r, Message):
                            msgs.append((topics[r.channel_id], r.log_time, r.data))
                except EndOfFile as e:  # no summary or footer: the daemon never closed the file
                    ended = e
            check(ended is not None, f"killed .mcap {k}: ends without a footer, read up to its end")
            tel = json_topic(msgs, "/phalanx/telemetry")
            check(len(tel) > 200, f"killed .mcap {k}: the mcap package reads {len(tel)} cycles (CRCs valid)")
            newest = max(lt for _, lt, _ in msgs)
            gap = (kill_wall_ns - newest) * 1e-9
            r = records.load(out)
            check(len(r) == len(tel), "killed .mcap: phalanx.records.load reads the same cycles")
        else:
            r = records.load(out)
            check(r.integrity["bad_records"] == 0 and len(r) > 200,
                  f"killed .phrec {k}: {len(r)} cycles, no damaged record")
            # The .phrec has no wall clock per cycle: the gap is the run time minus the newest cycle's t_s, an
            # upper bound (the daemon's start-up before its first cycle counts as loss).
            gap = None
            out_info = json.loads(run([os.path.join(BIN, "phalanx"), "record", "info", out]).stdout)
            check(out_info["cycles"] == len(r), "killed .phrec: phalanx record info agrees")
        if gap is not None:
            worst_gap = max(worst_gap, gap)
            check(gap <= 0.100, f"killed .mcap {k}: newest message {gap * 1e3:.1f} ms before the kill (<= 100 ms)")
    print(f"kill -9 {kind}: worst gap {worst_gap * 1e3:.1f} ms")

# ---- 4. storage ----------------------------------------------------------------------------------------------
phrec_rate = os.path.getsize(phrec) / len(rec) * 1000.0  # bytes per cycle x 1 kHz
print(f"storage glove5 session record (.phrec v2, therapy values included): {phrec_rate / 1e3:.1f} kB/s")
print(f"storage glove5 MCAP export of it: {os.path.getsize(mcap_out) / len(rec):.1f} kB/s")
for (dev, ext), rate in sorted(sizes.items()):
    print(f"storage {dev} --record .{ext}: {rate / 1e3:.1f} kB/s")
check(phrec_rate < 125e3, f"session record {phrec_rate / 1e3:.0f} kB/s, well under the former ~250 kB/s")

print(f"{len(FAILS)} failed" if FAILS else "all passed")
sys.exit(1 if FAILS else 0)
