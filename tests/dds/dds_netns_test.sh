#!/usr/bin/env bash
# phalanxd's DDS bridge between two "machines": two network namespaces joined by a veth pair (made here, with
# addresses of their own, removed on exit). phalanxd (sim:glove5, then sim:pantograph) publishes in one; an
# independent peer on the Cyclone DDS Python binding (tests/dds/ros2_peer.py, its own ROS 2 type definitions)
# subscribes in the other and checks topics, QoS and values against phalanxd's own --record CSV. Printed, not
# gated: ddsperf's round trip between the namespaces (the baseline), the publish latency telemetry → peer, and
# the loop's missed periods / jitter with the bridge publishing at 1 kHz vs without it (docs/dds.md). Then a
# commander in B (tests/dds/command_peer.py) drives the glove through rt/<ns>/command and is killed -9.
# Usage: dds_netns_test.sh BIN_DIR     (root; exit 77 = skipped)
set -euo pipefail
BIN=$1
HERE=$(cd "$(dirname "$0")" && pwd)
if [ "$(id -u)" != 0 ]; then echo "SKIP: network namespaces need root"; exit 77; fi
command -v ddsperf >/dev/null || { echo "FAIL: ddsperf missing (cyclonedds-tools; tools/setup.sh)"; exit 1; }
python3 -c "import cyclonedds" || { echo "FAIL: the cyclonedds Python binding is missing (tools/setup.sh)"; exit 1; }
# The commander runs on the binding 0.10.2 over Debian's libddsc (tools/setup.sh says why; docs/dds.md).
PY010=${PHALANX_DDS_PY010:-/opt/phalanx/dds-py010}/bin/python
"$PY010" -c "import cyclonedds" || { echo "FAIL: $PY010 has no cyclonedds 0.10.2 (tools/setup.sh --test)"; exit 1; }
[ -x "$BIN/glove_press" ] || { echo "FAIL: $BIN/glove_press missing (the SDK example; build the examples)"; exit 1; }
[ -x "$BIN/remote_press" ] || { echo "FAIL: $BIN/remote_press missing (the SDK's network example; build the examples)"; exit 1; }

TAG=$$
NA=phxddsA$TAG NB=phxddsB$TAG VA=vdA$TAG VB=vdB$TAG
WORK=$(mktemp -d /tmp/phx-dds.XXXXXX)
PIDS=()
cleanup() {
  for p in "${PIDS[@]:-}"; do [ -n "$p" ] && kill "$p" 2>/dev/null || true; done
  ip netns del "$NA" 2>/dev/null || true
  ip netns del "$NB" 2>/dev/null || true
  [ -n "${KEEP_WORK:-}" ] && echo "kept $WORK" || rm -rf "$WORK"
}
trap cleanup EXIT
ip netns add "$NA"
ip netns add "$NB"
ip link add "$VA" netns "$NA" type veth peer name "$VB" netns "$NB"
ip -n "$NA" addr add 192.168.233.1/24 dev "$VA"
ip -n "$NB" addr add 192.168.233.2/24 dev "$VB"
for n in "$NA" "$NB"; do ip -n "$n" link set lo up; done
ip -n "$NA" link set "$VA" up
ip -n "$NB" link set "$VB" up
uri() { echo "<CycloneDDS><Domain Id=\"any\"><General><Interfaces><NetworkInterface name=\"$1\"/></Interfaces></General></Domain></CycloneDDS>"; }
DOMAIN=17

echo "== ddsperf baseline: round trip between the namespaces (1 kHz pings, 3 s) =="
ip netns exec "$NB" env CYCLONEDDS_URI="$(uri "$VB")" ddsperf -i $DOMAIN -D 5 pong >"$WORK/pong.txt" 2>&1 &
PIDS+=($!)
sleep 1
ip netns exec "$NA" env CYCLONEDDS_URI="$(uri "$VA")" ddsperf -i $DOMAIN -D 3 ping 1000Hz >"$WORK/ping.txt" 2>&1 || true
grep " size " "$WORK/ping.txt" | sed 's/^\[[0-9]*\] */ddsperf round trip: /' || { cat "$WORK/ping.txt"; echo "FAIL: ddsperf measured nothing"; exit 1; }
wait "${PIDS[-1]}" 2>/dev/null || true

# One session: the peer listens in B, phalanxd publishes in A for SECONDS; then the peer checks.
run_session() {  # name device ns dds_args...
  local name=$1 device=$2 ns=$3
  shift 3
  local ready="$WORK/$name.ready"
  ip netns exec "$NB" env CYCLONEDDS_URI="$(uri "$VB")" python3 "$HERE/ros2_peer.py" listen --domain $DOMAIN \
    --device "$device" --ns "$ns" --seconds 60 --until "$WORK/$name.done" --ready "$ready" --out "$WORK/$name.pkl" &
  local peer=$!
  PIDS+=($peer)
  for _ in $(seq 300); do [ -f "$ready" ] && break; sleep 0.1; done
  [ -f "$ready" ] || { echo "FAIL: the peer did not start"; exit 1; }
  local rc=0
  ip netns exec "$NA" "$BIN/phalanxd" --device "sim:$device" --seconds 5 --record "$WORK/$name.csv" --json \
    --dds --dds-domain $DOMAIN --dds-interface "$VA" "$@" >"$WORK/$name.json" 2>"$WORK/$name.err" || rc=$?
  if [ $rc -ne 0 ]; then cat "$WORK/$name.err"; echo "FAIL: phalanxd exited $rc"; exit 1; fi
  touch "$WORK/$name.done"
  wait $peer
  python3 "$HERE/ros2_peer.py" check --peer "$WORK/$name.pkl" --csv "$WORK/$name.csv" --summary "$WORK/$name.json"
}

# The Python peer keeps up with the glove's 11 topics at 100 Hz (its receipt times are then the latency, not its
# backlog); the pantograph's 3 topics go at 1 kHz, and that session is compared with one without the bridge.
echo "== sim:glove5, bridge at 100 Hz =="
run_session glove glove5 phalanx/glove5 --dds-state-rate 100
echo "== sim:pantograph, bridge at 1 kHz, namespace lab/pen1 =="
run_session pen pantograph lab/pen1 --dds-state-rate 1000 --dds-namespace lab/pen1

# Commands over DDS (docs/dds.md §"Commands"): the peer in B commands the glove's index pad force through
# rt/lab/glove_cmd/command (enabled in a config file, like a deployment), then is killed -9 mid-command.
echo "== sim:glove5, commands from the peer: in limit, beyond it, NaN, then the peer killed =="
cmd_session() {  # attempt
  [ "$1" = 1 ] || echo "(attempt $1)"
  rm -f "$WORK/cmd.armed" "$WORK/cmd.sent"
  cat >"$WORK/cmd.yaml" <<EOF
dds:
    domain_id: $DOMAIN
    interface: $VA
    namespace: lab/glove_cmd
    state_rate_hz: 10
    commands: {enabled: true, deadline_ms: 250, fallback: safe}
EOF
  ip netns exec "$NB" env CYCLONEDDS_URI="$(uri "$VB")" "$PY010" "$HERE/command_peer.py" send --domain $DOMAIN \
    --ns lab/glove_cmd --log "$WORK/cmd.sent" --armed "$WORK/cmd.armed" >"$WORK/cmd.peer" 2>&1 &
  CMDPEER=$!
  PIDS+=($CMDPEER)
  rm -f "$WORK/c.sock"
  ip netns exec "$NA" "$BIN/phalanxd" --config "$WORK/cmd.yaml" --device sim:glove5 --seconds 10 --mode transparent \
    --scene none --scenario still --client-socket "$WORK/c.sock" --record "$WORK/cmd.csv" --json \
    >"$WORK/cmd.json" 2>"$WORK/cmd.err" &
  CMDD=$!
  PIDS+=($CMDD)
  for _ in $(seq 200); do [ -f "$WORK/cmd.armed" ] && break; sleep 0.05; done
  [ -f "$WORK/cmd.armed" ] || { cat "$WORK/cmd.peer" "$WORK/cmd.err"; echo "FAIL: the commander never got through its phases"; exit 1; }
  # One commander at a time: a local client (the SDK's glove_press) is refused while the DDS commander holds.
  rc=0
  "$BIN/glove_press" "$WORK/c.sock" 1 1 100 250 >"$WORK/press.out" 2>"$WORK/press.err" || rc=$?
  if [ $rc -ne 3 ] || ! grep -q "another client" "$WORK/press.err"; then
    cat "$WORK/press.out" "$WORK/press.err"; echo "FAIL: a local client was not refused (exit $rc) while DDS commanded"; exit 1
  fi
  echo "local client while the DDS commander holds: refused ($(head -c 120 "$WORK/press.err" | tr '\n' ' '))"
  sleep 0.3
  kill -9 $CMDPEER
  rc=0
  wait $CMDD || rc=$?
  if [ $rc -ne 0 ]; then cat "$WORK/cmd.err"; echo "FAIL: phalanxd exited $rc"; exit 1; fi
  python3 "$HERE/command_peer.py" check --log "$WORK/cmd.sent" --csv "$WORK/cmd.csv" --summary "$WORK/cmd.json"
}
# A session whose check exits 2 (the simulated device faulted: its current limit, or a command timeout when the
# loop starved on a loaded machine) is run again, at most 3 times.
retry3() {  # session function
  local attempt rc
  for attempt in 1 2 3; do
    rc=0
    "$1" $attempt || rc=$?
    [ $rc -eq 2 ] || break
  done
  [ $rc -ne 2 ] || { echo "FAIL: the simulated device faulted in all 3 attempts"; exit 1; }
  [ $rc -eq 0 ] || exit 1
}
retry3 cmd_session

echo "== sim:glove5, the commander hands the device back (disposes its writer) =="
rel_session() {  # attempt
  [ "$1" = 1 ] || echo "(attempt $1)"
  ip netns exec "$NB" env CYCLONEDDS_URI="$(uri "$VB")" "$PY010" "$HERE/command_peer.py" send --release \
    --domain $DOMAIN --ns lab/glove_cmd --log "$WORK/rel.sent" --armed "$WORK/rel.armed" >"$WORK/rel.peer" 2>&1 &
  PIDS+=($!)
  ip netns exec "$NA" "$BIN/phalanxd" --config "$WORK/cmd.yaml" --device sim:glove5 --seconds 5 --mode transparent \
    --scene none --scenario still --record "$WORK/rel.csv" --json >"$WORK/rel.json" 2>"$WORK/rel.err" ||
    { cat "$WORK/rel.err" "$WORK/rel.peer"; echo "FAIL: phalanxd (release session)"; exit 1; }
  python3 "$HERE/command_peer.py" check-release --csv "$WORK/rel.csv" --summary "$WORK/rel.json"
}
retry3 rel_session

# A client of libphalanx's network part (phalanx::RemoteDevice, the example remote_press) in B addresses the
# glove in A by the name its daemon announces, presses the index pad for 1 s and releases (docs/sdk.md §"Devices
# on the network"); the same check as the Python commander's hand-back.
echo "== sim:glove5 addressed by name from B: libphalanx's RemoteDevice (remote_press) =="
name_session() {  # attempt
  [ "$1" = 1 ] || echo "(attempt $1)"
  ip netns exec "$NA" "$BIN/phalanxd" --config "$WORK/cmd.yaml" --device sim:glove5 --seconds 9 --mode transparent \
    --scene none --scenario still --record "$WORK/name.csv" --json >"$WORK/name.json" 2>"$WORK/name.err" &
  local d=$!
  PIDS+=($d)
  sleep 0.5
  # Discovery 4 s: a daemon starting on a loaded machine announces late; the press then lasts 1 s.
  ip netns exec "$NB" "$BIN/remote_press" --device lab/glove_cmd --domain $DOMAIN --interface "$VB" --finger 1 \
    --force 0.75 --seconds 1 --discovery-s 4 >"$WORK/name.out" 2>&1 || { cat "$WORK/name.out"; echo "FAIL: remote_press"; exit 1; }
  wait $d || { cat "$WORK/name.err"; echo "FAIL: phalanxd (by-name session)"; exit 1; }
  cat "$WORK/name.out"
  python3 - "$WORK/name.out" "$WORK/name.json" <<'PY'
import json, sys
out, s = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
c = s["dds"]["commands"]
if c["received"] != out["commands_sent"] or c["passed_to_client_path"] != out["commands_sent"]:
    sys.exit("FAIL: remote_press sent %d commands, the daemon received %d and passed %d" %
             (out["commands_sent"], c["received"], c["passed_to_client_path"]))
if out["joint_states"] < 5:
    sys.exit("FAIL: remote_press received %d joint_states samples in 1 s at 10 Hz" % out["joint_states"])
print("by name: %d commands sent, %d received by the daemon, %d joint_states samples back" %
      (out["commands_sent"], c["received"], out["joint_states"]))
PY
  python3 "$HERE/command_peer.py" check-release --csv "$WORK/name.csv" --summary "$WORK/name.json"
}
retry3 name_session

# Several devices on several "machines" (docs/dds.md §"Devices on the network"): two daemons in A, one in B; from
# each namespace `phalanx devices` lists all three from their announcements on rt/phalanx/devices.
echo "== phalanx devices: glove5 and pantograph in A, sea_finger in B =="
DEVP=()
for spec in "$NA $VA glove5 lab/glove_a" "$NA $VA pantograph lab/pen1" "$NB $VB sea_finger lab/sea1"; do
  set -- $spec
  ip netns exec "$1" "$BIN/phalanxd" --device "sim:$3" --seconds 17 --dds --dds-domain $DOMAIN --dds-interface "$2" \
    --dds-namespace "$4" --dds-state-rate 10 --json >"$WORK/dev_$3.json" 2>"$WORK/dev_$3.err" &
  DEVP+=($!)
  PIDS+=($!)
done
sleep 3
ip netns exec "$NB" "$BIN/phalanx" devices --domain $DOMAIN --interface "$VB" --seconds 2 --json >"$WORK/devices_B.json"
ip netns exec "$NA" "$BIN/phalanx" devices --domain $DOMAIN --interface "$VA" --seconds 2 >"$WORK/devices_A.txt"
# Addressing by name what cannot be commanded: a name nobody announced, a device whose commands are off.
for bad in "lab/nobody:no daemon announced" "lab/pen1:does not take commands"; do
  rc=0
  ip netns exec "$NB" "$BIN/remote_press" --device "${bad%%:*}" --domain $DOMAIN --interface "$VB" --discovery-s 1 \
    >"$WORK/bad.out" 2>&1 || rc=$?
  if [ $rc -ne 3 ] || ! grep -q "${bad#*:}" "$WORK/bad.out"; then
    cat "$WORK/bad.out"; echo "FAIL: remote_press --device ${bad%%:*}: exit $rc, expected 3 and '${bad#*:}'"; exit 1
  fi
  echo "remote_press --device ${bad%%:*}: refused: $(cat "$WORK/bad.out")"
done
# The same from Python (the bindings of libphalanx's network part): the list, and a refusal naming its reason.
ip netns exec "$NB" env PYTHONPATH="$HERE/../../python" python3 - $DOMAIN "$VB" <<'PY' || { echo "FAIL: Python's network_devices / RemoteDevice"; exit 1; }
import sys
import phalanx
domain, iface = int(sys.argv[1]), sys.argv[2]
names = sorted(d["name"] for d in phalanx.network_devices(domain=domain, interface=iface, seconds=1))
if names != ["lab/glove_a", "lab/pen1", "lab/sea1"]:
    sys.exit("FAIL: phalanx.network_devices listed %s" % names)
try:
    phalanx.RemoteDevice("lab/sea1", domain=domain, interface=iface, discovery_s=1)
    sys.exit("FAIL: RemoteDevice('lab/sea1') accepted a device whose commands are off")
except phalanx.Error as e:
    reason = str(e)
if "does not take commands" not in reason:
    sys.exit("FAIL: RemoteDevice('lab/sea1') refused for another reason: %s" % reason)
print("python: network_devices lists %s; RemoteDevice('lab/sea1') refused: %s" % (", ".join(names), reason))
PY
for p in "${DEVP[@]}"; do wait "$p" || { cat "$WORK"/dev_*.err; echo "FAIL: a daemon of the devices session failed"; exit 1; }; done
cat "$WORK/devices_A.txt"
python3 - "$WORK/devices_B.json" "$WORK/devices_A.txt" "$WORK" <<'PY'
import json, socket, sys
seen = {d["name"]: d for d in json.load(open(sys.argv[1]))}
want = {"lab/glove_a": "glove5", "lab/pen1": "pantograph", "lab/sea1": "sea_finger"}
if set(seen) != set(want):
    sys.exit("FAIL: phalanx devices in B listed %s, expected %s" % (sorted(seen), sorted(want)))
for name, typ in want.items():
    d = seen[name]
    if d["type"] != typ or d["device"] != "sim:" + typ or d["rate_hz"] != 1000.0 or d["commands"]:
        sys.exit("FAIL: %s announced as %s" % (name, d))
    # The state announced is the daemon's own: running, or a fault it latched (a starved loop on a loaded machine
    # can latch command-timeout); a fault named must be one the daemon's summary saw.
    faults_seen = json.load(open("%s/dev_%s.json" % (sys.argv[3], typ)))["faults_seen"].split("|")
    st = d["state"]
    own = st.startswith("running") or (st.startswith("fault: ") and set(st[7:].split("|")) <= set(faults_seen))
    if not own or d["host"] != socket.gethostname():
        sys.exit("FAIL: %s: state %r (daemon saw faults %s) host %r" % (name, st, faults_seen, d["host"]))
table = open(sys.argv[2]).read()
if not all(n in table for n in want):
    sys.exit("FAIL: phalanx devices in A did not list all three:\n" + table)
print("phalanx devices: from B and from A, all three devices (type, device, rate, state, host) as the daemons run them:",
      ", ".join("%s %s" % (n, seen[n]["state"]) for n in sorted(seen)))
PY

echo "== the same pantograph session without the bridge (loop figures only) =="
ip netns exec "$NA" "$BIN/phalanxd" --device sim:pantograph --seconds 5 --json >"$WORK/nodds.json" 2>"$WORK/nodds.err" ||
  { cat "$WORK/nodds.err"; echo "FAIL: phalanxd without the bridge"; exit 1; }
python3 - "$WORK/pen.json" "$WORK/nodds.json" <<'PY'
import json, sys
w, n = (json.load(open(p)) for p in sys.argv[1:3])
for label, s in (("with the bridge at 1 kHz", w), ("without the bridge     ", n)):
    j = s["period_jitter"]
    print("loop %s: %d cycles, %d missed periods, period jitter p50 %.0f us, p99 %.0f us, max %.0f us"
          % (label, s["cycles"], s["overruns"], j["p50_us"], j["p99_us"], j["max_us"]))
d = w["dds"]["telemetry_to_written"]
print("bridge: telemetry arrival -> dds_write returned: p50 %.0f us, p99 %.0f us (n=%d)" % (d["p50_us"], d["p99_us"], d["count"]))
PY
echo "PASS"
