#!/usr/bin/env python3
"""An independent ROS 2-style DDS peer for phalanxd's bridge (docs/dds.md), on the Cyclone DDS Python binding.

  listen: subscribe to every topic of one device (QoS as a ROS 2 node would use for them), check the writers' QoS
          and type names from discovery, and store what arrived with its receipt time.
  check:  compare what arrived with the daemon's own --record CSV and --json summary; print the latency.
Exit status 1 with the reason on any mismatch."""
import argparse
import csv
import json
import math
import pickle
import sys
import time

sys.path.insert(0, __import__("os").path.dirname(__file__))
import ros2_types as R  # noqa: E402

FINGERS = ["thumb", "index", "middle", "ring", "little"]
# Default glove geometry (common/include/phalanx/glove/kinematics.h defaultModel, Table 2/3), mm:
#          p1    p2    p3    l1     l2     l_p    x_B0   y_B0
GLOVE = {"thumb": (49.4, 38.6, 31.1, 92.08, 58.87, -14.0, -16.0, 21.0),
         "index": (48.3, 28.2, 19.1, 73.88, 47.23, -12.5, -10.0, 14.0),
         "middle": (52.4, 33.5, 21.3, 82.84, 52.96, -14.0, -10.5, 17.5),
         "ring": (48.1, 32.5, 21.1, 78.58, 50.24, -13.5, -11.0, 17.5),
         "little": (40.2, 23.0, 18.3, 63.02, 40.29, -12.0, -9.5, 12.0)}


def fail(msg):
    print("ros2_peer: FAIL: " + msg, flush=True)
    sys.exit(1)


def topics(device, ns):
    base = "rt/" + ns + "/"
    out = {"joint_states": (base + "joint_states", R.JointState, "state")}
    bodies = FINGERS if device == "glove5" else ["pen"]
    for b in bodies:
        out[b + "/pose"] = (base + b + "/pose", R.PoseStamped, "state")
        out[b + "/wrench"] = (base + b + "/wrench", R.WrenchStamped, "state")
    out["diagnostics"] = (base + "diagnostics", R.DiagnosticArray, "event")
    return out


def listen(a):
    from cyclonedds.core import Policy, Qos, ReadCondition, SampleState, ViewState, InstanceState, WaitSet
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from cyclonedds.util import duration

    dp = DomainParticipant(a.domain)
    # As documented: state best-effort (a ROS 2 sensor-data subscription), events reliable (ROS 2's default).
    qos = {"state": Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(4096), Policy.Durability.Volatile),
           "event": Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(100),
                        Policy.Durability.Volatile)}
    ws = WaitSet(dp)
    readers, got = {}, {}
    for key, (name, typ, kind) in topics(a.device, a.ns).items():
        tp = Topic(dp, name, typ)
        r = DataReader(dp, tp, qos=qos[kind])
        ws.attach(ReadCondition(r, SampleState.Any | ViewState.Any | InstanceState.Any))
        readers[key] = (r, name, typ, kind, tp)
        got[key] = []
    # A reliable reader (ROS 2's default QoS) must NOT match the best-effort state writer.
    strict = DataReader(dp, readers["joint_states"][4], qos=qos["event"])
    open(a.ready, "w").write("ready\n")
    matched = {}
    end = time.monotonic() + a.seconds
    stop_at = None  # the daemon has ended (a.until exists): drain for another second, then stop
    while time.monotonic() < end and (stop_at is None or time.monotonic() < stop_at):
        if stop_at is None and __import__("os").path.exists(a.until):
            stop_at = time.monotonic() + 1.0
        ws.wait(duration(milliseconds=20))
        for key, (r, name, typ, kind, _) in readers.items():
            while True:
                batch = r.take(N=512)
                if not batch:
                    break
                now = time.time_ns()
                for m in batch:
                    if isinstance(m, typ):  # not the invalid sample of a writer that went away
                        got[key].append((now, m))
            if key not in matched:
                for h in r.get_matched_publications():
                    ep = r.get_matched_publication_data(h)
                    if ep is not None:
                        matched[key] = {"topic": ep.topic_name, "type": ep.type_name, "qos": repr(ep.qos)}
        if "strict" not in matched and got["joint_states"]:
            matched["strict"] = strict.get_subscription_matched_status().current_count
    with open(a.out, "wb") as f:
        pickle.dump({"got": got, "matched": matched, "device": a.device, "ns": a.ns}, f)
    print("ros2_peer: received %s" % (", ".join("%s %d" % (k, len(v)) for k, v in got.items())))


def near(x, y, tol):
    return abs(x - y) <= tol


def check(a):
    data = pickle.load(open(a.peer, "rb"))
    got, matched, device = data["got"], data["matched"], data["device"]
    summary = json.load(open(a.summary))
    reader = csv.DictReader(open(a.csv))
    rows = list(reader)
    if not rows:
        fail("the daemon's recording is empty")
    tops = topics(device, data["ns"])
    # 1. every topic arrived, from a writer of the documented type and QoS.
    for key, (name, typ, kind) in tops.items():
        if not got[key]:
            fail("nothing received on " + name)
        m = matched.get(key)
        if m is None:
            fail("no matched writer seen for " + name)
        if m["topic"] != name or m["type"] != typ.__idl_typename__:
            fail("writer of %s: topic %s type %s" % (name, m["topic"], m["type"]))
        want = "BestEffort" if kind == "state" else "Reliable"
        if want not in m["qos"] or "Volatile" not in m["qos"]:
            fail("writer of %s: QoS %s, documented %s volatile" % (name, m["qos"], want))
        depth = "KeepLast(depth=1)" if kind == "state" else "KeepLast(depth=10)"
        if depth not in m["qos"]:
            fail("writer of %s: QoS %s, documented %s" % (name, m["qos"], depth))
    if matched.get("strict", 1) != 0:
        fail("a reliable reader matched the best-effort joint_states writer")
    print("ros2_peer: every topic received; writers' type names and QoS as documented "
          "(state best-effort keep-last 1, diagnostics reliable keep-last 10, volatile); a reliable reader does not "
          "match a state topic")

    # 2. values against the daemon's recording. Telemetry rows by their raw samples (the CSV keeps 5 digits).
    nsamp = 25 if device == "glove5" else 12
    # The samples are the named columns right after fault_bits (docs/records.md, the --record CSV).
    first = reader.fieldnames.index("fault_bits") + 1
    sample_cols = reader.fieldnames[first:first + nsamp]
    table = [(r, [float(r[c]) for c in sample_cols]) for r in rows]

    def rel_close(x, y):
        return abs(x - y) <= 1e-4 * max(abs(y), 1e-3) + 1e-9

    hint = [0]  # messages and rows are both in time order: search on from the last match first

    def find_row(raw_idx, raw_vals):
        n = len(table)
        for k in list(range(hint[0], n)) + list(range(0, hint[0])):
            r, s = table[k]
            if all(rel_close(v, s[i]) for i, v in zip(raw_idx, raw_vals)):
                hint[0] = k
                return r, s
        return None, None

    by_stamp = {}
    for key in tops:
        if key == "diagnostics":
            continue
        for recv, m in got[key]:
            by_stamp.setdefault((m.header.stamp.sec, m.header.stamp.nanosec), {})[key] = m
    checked, lat = 0, []
    for recv, js in got["joint_states"]:
        st = js.header.stamp
        lat.append((recv - (st.sec * 10**9 + st.nanosec)) / 1000.0)
    step = max(1, len(got["joint_states"]) // 300)  # a few hundred samples spread over the run
    for recv, js in got["joint_states"][::step]:
        group = by_stamp[(js.header.stamp.sec, js.header.stamp.nanosec)]
        if device == "glove5":
            if len(js.name) != 30 or js.name[0] != "thumb_mcp" or js.name[15] != "thumb_mech1":
                fail("glove5 joint names: %s" % js.name[:4])
            alpha = js.position[15:30]
            r, s = find_row(range(15), alpha)
            if r is None:
                fail("joint_states mechanism angles %s match no row of the recording" % alpha[:3])
            for f, fn in enumerate(FINGERS):
                p1, p2, p3, l1, l2, lp, xb, yb = [v / 1000.0 for v in GLOVE[fn]]
                a1, a2, a3 = alpha[3 * f:3 * f + 3]
                # Fingertip pose from the mechanism angles (eq 3-4), recomputed here.
                c = a1 + a2 + a3
                x = xb + l1 * math.cos(a1) + l2 * math.cos(a1 + a2) + p3 * math.cos(c) - lp * math.sin(c)
                y = yb + l1 * math.sin(a1) + l2 * math.sin(a1 + a2) + p3 * math.sin(c) + lp * math.cos(c)
                pose = group.get(fn + "/pose")
                if pose is not None:
                    q = pose.pose.orientation
                    phi = 2.0 * math.atan2(q.z, q.w)
                    if not (near(pose.pose.position.x, x, 1e-9) and near(pose.pose.position.y, y, 1e-9)
                            and near(math.remainder(phi - c, 2 * math.pi), 0.0, 1e-9)):
                        fail("%s pose (%g, %g) != forward kinematics (%g, %g)" % (fn, pose.pose.position.x,
                                                                                 pose.pose.position.y, x, y))
                    # Flexion: the finger chain with θ = -flexion reaches the same fingertip (IK closes).
                    th = [-v for v in js.position[3 * f:3 * f + 3]]
                    if not any(math.isnan(v) for v in th):
                        xt = p1 * math.cos(th[0]) + p2 * math.cos(th[0] + th[1]) + p3 * math.cos(sum(th))
                        yt = p1 * math.sin(th[0]) + p2 * math.sin(th[0] + th[1]) + p3 * math.sin(sum(th))
                        if not (near(xt, x, 2.5e-3) and near(yt, y, 2.5e-3)):
                            fail("%s flexion %s does not reach the fingertip (%g, %g) vs (%g, %g)" % (fn, th, xt, yt, x, y))
                wr = group.get(fn + "/wrench")
                if wr is not None and not rel_close(wr.wrench.force.y, s[15 + f]):
                    fail("%s pad force %g != recorded %g" % (fn, wr.wrench.force.y, s[15 + f]))
        else:
            if len(js.position) != 6 or len(js.effort) != 6:
                fail("pantograph joint_states sizes %d/%d" % (len(js.position), len(js.effort)))
            r, s = find_row(range(6, 12), js.effort)
            if r is None:
                fail("joint_states efforts %s match no row of the recording" % js.effort)
            pose = group.get("pen/pose")
            wr = group.get("pen/wrench")
            if pose is not None and not any(math.isnan(v) for v in (pose.pose.position.x,)):
                q = pose.pose.orientation
                n = math.sqrt(q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2)
                if not near(n, 1.0, 1e-9):
                    fail("pen orientation is not a unit quaternion (%g)" % n)
                if wr is not None:
                    # Pen axis = R·y_B; the moment of two end forces about the centre is normal to the axis.
                    ax = (2 * (q.x * q.y - q.w * q.z), 1 - 2 * (q.x ** 2 + q.z ** 2), 2 * (q.y * q.z + q.w * q.x))
                    t = wr.wrench.torque
                    if abs(ax[0] * t.x + ax[1] * t.y + ax[2] * t.z) > 1e-9 + 1e-6 * math.sqrt(t.x**2 + t.y**2 + t.z**2):
                        fail("pen wrench torque has a component along the pen axis")
        checked += 1
    # The home offset: joint position - recorded relative angle is one constant per joint (pantograph). A message is
    # matched to the rows with its efforts; the offset is the median over messages with one such row, and every
    # message must have a matching row at that offset.
    if device == "pantograph":
        def rows_for(js):  # the rows with these efforts, near the message's time (its first match on)
            find_row(range(6, 12), js.effort)
            near_rows = table[max(0, hint[0] - 50):hint[0] + 200]
            return [s for _, s in near_rows if all(rel_close(v, s[6 + i]) for i, v in enumerate(js.effort))]
        sampled = [js for _, js in got["joint_states"][::step]]
        unique = [rows_for(js) for js in sampled]
        offs = [[js.position[i] - c[0][i] for i in range(6)] for js, c in zip(sampled, unique) if len(c) == 1]
        if not offs:
            fail("no pantograph joint_states matched exactly one recorded row")
        home = [sorted(o[i] for o in offs)[len(offs) // 2] for i in range(6)]
        for js, cands in zip(sampled, unique):
            if not any(all(abs(js.position[i] - c[i] - home[i]) < 2e-4 for i in range(6)) for c in cands):
                fail("joint_states %s: no recorded row at the home offset %s" % (js.position, home))
        print("ros2_peer: pantograph joint angles = recorded angles + one home offset per joint (%s rad)" %
              ", ".join("%.4f" % h for h in home))
    # 3. diagnostics: their telemetry seq and device time name a recorded row; mode and faults match it.
    rec = {(r["seq"], r["device_time_us"]): r for r in rows}
    diag_ok = 0
    for recv, d in got["diagnostics"]:
        kv = {v.key: v.value for v in d.status[0].values}
        r = rec.get((kv["telemetry_seq"], kv["device_time_us"]))
        if r is None:
            continue  # the last status can be of a cycle after the recording closed
        if int(kv["fault_bits"]) != int(r["fault_bits"]):
            fail("diagnostics fault_bits %s != recorded %s" % (kv["fault_bits"], r["fault_bits"]))
        diag_ok += 1
    if diag_ok == 0:
        fail("no diagnostics status names a recorded telemetry frame")
    # 4. counts: what the daemon published and what arrived (best-effort: losses are counted, not hidden).
    dds = summary["dds"]
    pub = dds["state_samples"]
    rx = len(got["joint_states"])
    lat.sort()
    p = lambda q: lat[min(len(lat) - 1, int(q * len(lat)))]  # noqa: E731
    print("ros2_peer: %d joint_states checked against the recording (pose, flexion, forces), %d diagnostics" %
          (checked, diag_ok))
    print("ros2_peer: published %d state samples, received %d joint_states (%.2f %% lost), ring drops %d" %
          (pub, rx, 100.0 * (pub - rx) / max(pub, 1), dds["dropped_full"]))
    print("ros2_peer: latency telemetry arrival -> peer receipt: p50 %.0f us, p99 %.0f us, max %.0f us (n=%d)" %
          (p(0.5), p(0.99), lat[-1], len(lat)))
    if rx > pub:
        fail("more joint_states received than published")


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    li = sub.add_parser("listen")
    li.add_argument("--domain", type=int, required=True)
    li.add_argument("--device", choices=["glove5", "pantograph"], required=True)
    li.add_argument("--ns", required=True)
    li.add_argument("--seconds", type=float, required=True, help="at most this long")
    li.add_argument("--until", required=True, help="stop one second after this file appears")
    li.add_argument("--ready", required=True)
    li.add_argument("--out", required=True)
    ch = sub.add_parser("check")
    ch.add_argument("--peer", required=True)
    ch.add_argument("--csv", required=True)
    ch.add_argument("--summary", required=True)
    a = ap.parse_args()
    listen(a) if a.cmd == "listen" else check(a)


if __name__ == "__main__":
    main()
