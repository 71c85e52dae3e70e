#!/usr/bin/env python3
"""A DDS commander for phalanxd (docs/dds.md §"Commands"), on the Cyclone DDS Python binding, in another network
namespace.

  send:  wait for the daemon's command reader, then command the simulated glove's index pad force (raw setpoints,
         200 Hz): IN N for 1 s, OVER N (beyond the device limit) for 50 ms, NaN for 0.1 s, IN N for 0.5 s; then
         write the `armed` file and go on commanding IN N until killed (the test kills it with -9).
  check: the daemon's --record CSV and --json summary: commanded = limited value, the saturation and the NaN
         refusal counted, and the killed commander forced off (client-timeout) in the first cycle past its
         deadline, the device safe within two telemetry frames of that.
Exit status 1 with the reason on any mismatch; 2 when the simulated device faulted (run the session again)."""
import argparse
import csv
import json
import math
import sys
import time

sys.path.insert(0, __import__("os").path.dirname(__file__))
import ros2_types as R  # noqa: E402

IN_N, OVER_N, LIMIT_N = 0.75, 25.0, 10.0  # glove5: |pad force setpoint| <= 10 N (protocol/devices.h)
INDEX = 1


def fail(msg):
    print("command_peer: FAIL: " + msg, flush=True)
    sys.exit(1)


def reader_seen(dp, w, topic):
    """Whether the daemon's command reader is known: the writer's matched status (binding 11.x), or a reader of
    the topic in the built-in subscription topic (0.10.x, which has no matched status)."""
    if hasattr(w, "get_publication_matched_status"):
        return w.get_publication_matched_status().current_count >= 1
    from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsSubscription
    if not hasattr(reader_seen, "r"):
        reader_seen.r = BuiltinDataReader(dp, BuiltinTopicDcpsSubscription)
    return any(getattr(s, "topic_name", None) == topic for s in reader_seen.r.read(N=64))


def send(a):
    from cyclonedds.core import Policy, Qos
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.pub import DataWriter
    from cyclonedds.topic import Topic
    from cyclonedds.util import duration

    dp = DomainParticipant(a.domain)
    # Reliable, as documented for commands (a best-effort writer would not match the daemon's reliable reader).
    qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(64),
              Policy.Durability.Volatile)
    w = DataWriter(dp, Topic(dp, "rt/" + a.ns + "/command", R.Command), qos=qos)
    end = time.monotonic() + 30
    while not reader_seen(dp, w, "rt/" + a.ns + "/command"):
        if time.monotonic() > end:
            fail("the daemon's command reader never matched")
        time.sleep(0.01)
    time.sleep(0.2)  # seen by discovery; the match on the writer's side follows
    sent = {"in": 0, "over": 0, "nan": 0}

    def phase(name, value, seconds):
        stop = time.monotonic() + seconds
        while time.monotonic() < stop:
            v = [0.0] * 5
            v[INDEX] = value
            now = time.time_ns()
            w.write(R.Command(header=R.Header(stamp=R.Time(now // 10**9, now % 10**9)), mode=2, kind=0, values=v))
            sent[name] += 1
            time.sleep(0.005)

    if a.release:  # a clean hand-back: command, then dispose and delete the writer
        phase("in", IN_N, 0.5)
        w.dispose(R.Command(mode=2, kind=0, values=[0.0] * 5))
        with open(a.log, "w") as f:
            json.dump(sent, f)
        time.sleep(1.0)  # the reliable dispose reaches the daemon; then the writer goes with the process
        return
    phase("in", IN_N, 1.0)
    phase("over", OVER_N, 0.05)
    phase("nan", float("nan"), 0.1)
    phase("in", IN_N, 0.5)
    with open(a.log, "w") as f:
        json.dump(sent, f)
    open(a.armed, "w").write("armed\n")
    while True:
        phase("in", IN_N, 1.0)


def check(a):
    sent = json.load(open(a.log))
    s = json.load(open(a.summary))
    rows = list(csv.DictReader(open(a.csv)))
    if not rows:
        fail("the daemon's recording is empty")
    cl, dc = s.get("client"), s.get("dds", {}).get("commands")
    if cl is None or dc is None or not dc.get("enabled"):
        fail("the summary has no client / dds.commands section: %s" % json.dumps(s)[:400])
    print("command_peer: daemon summary: client %s; dds.commands %s; faults %s" % (
        json.dumps({k: cl.get(k) for k in ("cycles_commanded", "limited", "refused_invalid", "force_off_records")}),
        json.dumps(dc), json.dumps(s.get("faults_seen"))))
    faulted = [r for r in cl["force_off_records"] if r["cause"] == "device-fault"]
    if faulted:  # the simulated motor's current limit under load, or a latched command timeout: not this test's
        print("command_peer: the simulated device faulted (%s); the session is run again" % faulted, flush=True)
        sys.exit(2)
    sp = ["setpoint_thumb", "setpoint_index", "setpoint_middle", "setpoint_ring", "setpoint_little"]
    val = lambda r, c: float(r[c])  # noqa: E731
    # 1. commanded = limited value: every setpoint sent is finite and within the limit; the in-limit command
    #    arrived as sent, the one beyond the limit as the limit; no other channel moved; no other value.
    n_in = n_lim = 0
    for r in rows:
        for c in sp:
            v = val(r, c)
            if not math.isfinite(v) or abs(v) > LIMIT_N:
                fail("row t_s %s: %s = %s (not finite or beyond %g N)" % (r["t_s"], c, r[c], LIMIT_N))
            if c != "setpoint_index" and v != 0.0:
                fail("row t_s %s: %s = %s, only the index was commanded" % (r["t_s"], c, r[c]))
        v = val(r, "setpoint_index")
        if abs(v - IN_N) < 1e-6:
            n_in += 1
        elif abs(v - LIMIT_N) < 1e-6:
            n_lim += 1
        elif v != 0.0:
            fail("row t_s %s: setpoint_index %g is neither the command %g, the limit %g nor 0" %
                 (r["t_s"], v, IN_N, LIMIT_N))
    if n_in == 0 or n_lim == 0:
        fail("cycles sent at %g N: %d, at the limit %g N: %d (both must occur)" % (IN_N, n_in, LIMIT_N, n_lim))
    # The device moved: its measured index pad force follows the command (median over the cycles commanded at IN_N
    # before the first at the limit: the 10 N push displaces the simulated mechanism, which the safe state's
    # worm drive then holds against the still hand, so later pad forces are not the command's).
    first_lim = next(i for i, r in enumerate(rows) if abs(val(r, "setpoint_index") - LIMIT_N) < 1e-6)
    measured = sorted(val(r, "force_index_N") for r in rows[:first_lim] if abs(val(r, "setpoint_index") - IN_N) < 1e-6)
    if not measured:
        fail("no cycle commanded at %g N before the one beyond the limit" % IN_N)
    pad = measured[len(measured) // 2]
    if abs(pad - IN_N) > 0.2:
        fail("measured index pad force %.3f N (median) while %g N was commanded" % (pad, IN_N))
    # 2. counted: the saturation (client path's `limited`), the NaN commands (refused by it; all passed by the
    #    bridge: reliable delivery, so exactly the number sent).
    if cl["limited"] < 1:
        fail("the saturated command was not counted (client.limited = %s)" % cl["limited"])
    if cl["refused_invalid"] < 1:
        fail("the NaN command was not refused (client.refused_invalid = %s)" % cl["refused_invalid"])
    if dc["nonfinite_passed"] != sent["nan"]:
        fail("the bridge passed %s NaN commands, the peer sent %d" % (dc["nonfinite_passed"], sent["nan"]))
    before_kill = sent["in"] + sent["over"] + sent["nan"]
    if dc["received"] < before_kill:
        fail("the bridge received %s commands, the peer had sent %d before it was armed" % (dc["received"], before_kill))
    if dc["refused_malformed"] or dc["refused_busy"] or dc["refused_other_writer"]:
        fail("commands refused by the bridge: %s" % dc)
    if cl["refused_busy"] != 1 or cl["connections"] != 0:
        fail("the local client's attempt: refused_busy %s, connections %s (1 and 0 expected)" %
             (cl["refused_busy"], cl["connections"]))
    # 3. the kill: one force-off, client-timeout, from DDS; the first cycle past the deadline; then safe.
    offs = cl["force_off_records"]
    if len(offs) != 1 or offs[0]["cause"] != "client-timeout" or offs[0]["source"] != "dds":
        fail("force-off records %s (one client-timeout from dds expected)" % offs)
    ts = [float(r["t_s"]) for r in rows]
    near = lambda t: min(range(len(ts)), key=lambda i: abs(ts[i] - t))  # noqa: E731
    last, forced = near(offs[0]["last_command_at_s"]), near(offs[0]["at_s"])
    deadline_s = dc["deadline_ms"] / 1000.0
    if forced + 3 >= len(rows):
        fail("the recording ends %d rows after the force-off" % (len(rows) - forced))
    if not (ts[forced] - ts[last] > deadline_s and ts[forced - 1] - ts[last] <= deadline_s):
        fail("forced at %.4f s, last command %.4f s: not the first cycle past the %g s deadline" %
             (ts[forced], ts[last], deadline_s))
    if abs(val(rows[last], "setpoint_index") - IN_N) > 1e-6:
        fail("the commander was not commanding %g N when it was killed" % IN_N)
    fresh, safe_row = 0, None
    for i in range(forced + 1, len(rows)):
        if rows[i]["seq"] != rows[i - 1]["seq"]:
            fresh += 1
        if int(rows[i]["mode"]) == 0:
            safe_row = i
            break
    if safe_row is None:
        fail("the device never reported safe after the force-off")
    if fresh > 2:
        fail("the device reported safe %d telemetry frames after the forced cycle (at most 2)" % fresh)
    for i in range(safe_row, len(rows)):
        if int(rows[i]["mode"]) != 0:
            fail("row t_s %s: the device left safe after the force-off" % rows[i]["t_s"])
    for i in range(forced, len(rows)):
        if val(rows[i], "setpoint_index") != 0.0:
            fail("row t_s %s: a force after the force-off" % rows[i]["t_s"])
    print("command_peer: sent %d in-limit, %d beyond-limit, %d NaN commands before arming; the bridge received %d "
          "(the rest of the run: killed mid-command)" % (sent["in"], sent["over"], sent["nan"], dc["received"]))
    print("command_peer: recorded setpoint_index: %d cycles at %g N (as commanded), %d at the %g N limit (%g N "
          "commanded); client path: %d cycles limited, %d refused (NaN), %d commanded; measured index pad force "
          "%.3f N (median) at %g N" % (n_in, IN_N, n_lim, LIMIT_N, OVER_N, cl["limited"], cl["refused_invalid"],
                                       cl["cycles_commanded"], pad, IN_N))
    print("command_peer: killed -> forced off (client-timeout, dds) %.1f ms after the last command (deadline %g ms), "
          "device safe %d telemetry frame(s) / %.1f ms later" %
          (1000 * (ts[forced] - ts[last]), dc["deadline_ms"], fresh, 1000 * (ts[safe_row] - ts[forced])))


def check_release(a):
    """The commander disposed its writer: a clean hand-back, no force-off, the built-in controller again."""
    s = json.load(open(a.summary))
    rows = list(csv.DictReader(open(a.csv)))
    cl = s["client"]
    if s.get("faults_seen", "none") != "none":  # e.g. command-timeout: the loop starved on a loaded machine
        print("command_peer: the simulated device faulted (%s); the session is run again" % s["faults_seen"], flush=True)
        sys.exit(2)
    if cl["releases"] != 1 or cl["force_off_records"] or cl["disconnects_without_release"] != 0:
        fail("release: releases %s, force-offs %s, disconnects %s (1, none, 0 expected)" %
             (cl["releases"], cl["force_off_records"], cl["disconnects_without_release"]))
    idx = [i for i, r in enumerate(rows) if abs(float(r["setpoint_index"]) - IN_N) < 1e-6]
    if not idx or s["command_sources"]["client"] < 1:
        fail("release: the commander never commanded")
    after = rows[idx[-1] + 1:len(rows) - 20]  # the last 20 ms can be the session's own stop (the safe command)
    if len(after) < 100:
        fail("release: the recording ends %d rows after the last command" % len(after))
    bad = [r for r in after[5:] if float(r["setpoint_index"]) != 0.0 or int(r["mode"]) == 0]
    if bad:
        fail("release: %d rows after the hand-back with a force or safe, first t_s %s mode %s setpoint %s fault_bits %s "
             "(last command row t_s %s); faults seen %s" % (len(bad), bad[0]["t_s"], bad[0]["mode"],
                                                             bad[0]["setpoint_index"], bad[0]["fault_bits"],
                                                             rows[idx[-1]]["t_s"], s.get("faults_seen")))
    if int(after[-1]["mode"]) != 1:
        fail("release: the device is in mode %s after the hand-back, not the built-in transparent" % after[-1]["mode"])
    print("command_peer: writer disposed -> released (no force-off); the built-in controller (transparent) commands "
          "again: %d cycles by the commander, %d by the controller" % (s["command_sources"]["client"],
                                                                    s["command_sources"]["controller"]))


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    se = sub.add_parser("send")
    se.add_argument("--domain", type=int, required=True)
    se.add_argument("--ns", required=True)
    se.add_argument("--log", required=True)
    se.add_argument("--armed", required=True)
    se.add_argument("--release", action="store_true", help="command 0.5 s, then hand the device back (dispose)")
    ch = sub.add_parser("check")
    ch.add_argument("--log", required=True)
    ch.add_argument("--csv", required=True)
    ch.add_argument("--summary", required=True)
    cr = sub.add_parser("check-release")
    cr.add_argument("--csv", required=True)
    cr.add_argument("--summary", required=True)
    a = ap.parse_args()
    {"send": send, "check": check, "check-release": check_release}[a.cmd](a)


if __name__ == "__main__":
    main()
