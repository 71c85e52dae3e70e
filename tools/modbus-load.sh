#!/usr/bin/env bash
# The Modbus server's cost to the 1 kHz loop (issue #9 target): one phalanxd run in three phases of PHASE s each:
#   quiet1  no Modbus client
#   load    N mbpoll clients, each polling the whole input map every 10 ms (≈ 100 Hz)
#   quiet2  no client again (with quiet1: the run's own A/A variation, i.e. what the machine alone does)
# The loop's own per-cycle wake times (its CSV recording) give the period jitter and missed periods of each phase;
# the phase boundaries come from the loop clock read over Modbus (input register 12, uptime ms). In each phase a
# reference sleeper (`cyclictest`, one SCHED_FIFO thread one priority BELOW the loop, 1 kHz, no work) measures
# what the machine itself does to a periodic real-time thread at the same time: if it misses periods too, the
# machine (other processes, the hypervisor) is the cause, not the daemon.
#
# Usage: tools/modbus-load.sh [build/host/bin] [clients=16] [phase_s=10]
# Environment: DEVICE=sim:glove5|sim:sea_finger|sim:pantograph (default sim:glove5), PIN=<cpu> (pin the daemon, its
# simulated device and the reference sleeper to one CPU; the clients stay unpinned), PORT (default 15502).
set -euo pipefail
BIN=${1:-build/host/bin}
CLIENTS=${2:-16}
PHASE=${3:-10}
PORT=${PORT:-15502}
DEVICE=${DEVICE:-sim:glove5}
PIN=${PIN:-}
PRIO=80  # phalanxd's default realtime priority (config realtime.priority)
WORK=$(mktemp -d /tmp/phalanx-modbus-load.XXXXXX)
trap 'rm -rf "$WORK"' EXIT
command -v mbpoll >/dev/null || { echo "modbus-load: mbpoll is not installed (tools/setup.sh)" >&2; exit 2; }
HAVE_CT=0
command -v cyclictest >/dev/null && HAVE_CT=1
[ "$HAVE_CT" = 1 ] || echo "modbus-load: cyclictest (rt-tests) not installed: no reference sleeper" >&2
TASKSET=()
CT_PIN=()
if [ -n "$PIN" ]; then
  TASKSET=(taskset -c "$PIN")
  CT_PIN=(-a "$PIN")
fi

# cycle: timer — the analysis below measures each cycle's wake against the loop's absolute 1 kHz grid; the default
# telemetry-driven cycle starts on frame arrival and has no such grid (tools/jitter-load.py measures either).
cat > "$WORK/phalanxd.yaml" <<YAML
version: 1
device: $DEVICE
cycle: timer
seconds: $((3 * PHASE + 8))
record: $WORK/loop.csv
modbus:
  enabled: true
  port: $PORT
YAML

"${TASKSET[@]}" "$BIN/phalanxd" --config "$WORK/phalanxd.yaml" --json >"$WORK/summary.json" 2>"$WORK/phalanxd.err" &
DAEMON=$!
uptime_ms() {
  local v
  v=$(mbpoll -m tcp -p "$PORT" -0 -1 -B -t 3:int -r 12 127.0.0.1 | sed -n 's/^\[12\]: *//p' | tr -d '[:space:]') || true
  if [ -z "$v" ]; then
    echo "modbus-load: cannot read the loop clock over Modbus; phalanxd said:" >&2
    cat "$WORK/phalanxd.err" >&2
    exit 3
  fi
  echo "$v"
}
# One reference sleeper per phase: 1 kHz, histogram to 1000 µs (beyond: "overflows" = periods it would miss).
reference() {  # $1: phase name
  if [ "$HAVE_CT" = 1 ]; then
    cyclictest --default-system -m -q -p $((PRIO - 1)) -i 1000 -h 1000 -D "$PHASE" "${CT_PIN[@]}" >"$WORK/ct-$1.txt" 2>&1 &
  fi
}
for _ in $(seq 50); do grep -q "modbus: serving" "$WORK/phalanxd.err" 2>/dev/null && break; sleep 0.1; done
grep -q "modbus: serving" "$WORK/phalanxd.err" || { cat "$WORK/phalanxd.err" >&2; exit 3; }

sleep 2  # start-up transient excluded
T0=$(uptime_ms); reference quiet1
sleep "$PHASE"
T1=$(uptime_ms)
PIDS=()
for _ in $(seq "$CLIENTS"); do
  mbpoll -m tcp -p "$PORT" -0 -t 3 -r 0 -c 112 -l 10 -o 1 127.0.0.1 >/dev/null 2>&1 &
  PIDS+=($!)
done
sleep 1  # all clients connected and polling
T2=$(uptime_ms); reference load
sleep "$PHASE"
T3=$(uptime_ms)
if [ "${#PIDS[@]}" -gt 0 ]; then
  kill "${PIDS[@]}"
  wait "${PIDS[@]}" 2>/dev/null || true
fi
sleep 1
T4=$(uptime_ms); reference quiet2
sleep "$PHASE"
T5=$(uptime_ms)
wait "$DAEMON" || true
wait || true

PYTHONPATH="$(dirname "$0")" python3 - "$WORK" "$T0" "$T1" "$T2" "$T3" "$T4" "$T5" "$CLIENTS" "$DEVICE" "${PIN:--}" <<'PY'
import csv, json, math, os, sys
import cyclictest_summary
work = sys.argv[1]
t0, t1, t2, t3, t4, t5, clients = map(int, sys.argv[2:9])
device, pin = sys.argv[9], sys.argv[10]
summary = json.load(open(f"{work}/summary.json"))
T = 1.0 / summary["rate_hz"]
rows = []  # (t_s, jitter_us, missed)
missed_total = 0
with open(f"{work}/loop.csv") as f:
    for k, r in enumerate(csv.DictReader(f)):
        t = float(r["t_s"])
        # The daemon's deadline for cycle k is (k + 1 + periods missed so far) · T after its start (absolute timer).
        lat = t - (k + 1 + missed_total) * T
        missed = 0
        if lat >= T:
            missed = int(lat // T)
            missed_total += missed
            lat -= missed * T
        rows.append((t, abs(lat) * 1e6, missed))

def pct(v, p):
    v = sorted(v)
    return v[min(len(v) - 1, int(math.ceil(p * len(v))) - 1)] if v else float("nan")

def reference(name):
    """The reference sleeper's histogram of this phase (tools/cyclictest_summary.py)."""
    return cyclictest_summary.summary(f"{work}/ct-{name}.txt")

def phase(name, a_ms, b_ms):
    sel = [r for r in rows if a_ms / 1e3 <= r[0] < b_ms / 1e3]
    j = [r[1] for r in sel]
    return {"seconds": (b_ms - a_ms) / 1e3, "cycles": len(sel), "missed_periods": sum(r[2] for r in sel),
            "jitter_p50_us": pct(j, 0.5), "jitter_p99_us": pct(j, 0.99), "jitter_p999_us": pct(j, 0.999),
            "jitter_max_us": max(j) if j else float("nan"), "reference_sleeper": reference(name)}

out = {"device": device, "pinned_cpu": pin, "clients": clients, "poll_interval_ms": 10, "registers_per_request": 112,
       "realtime": summary.get("realtime"), "quiet1": phase("quiet1", t0, t1), "load": phase("load", t2, t3),
       "quiet2": phase("quiet2", t4, t5), "modbus": summary.get("modbus"), "recording": summary.get("recording"),
       "daemon_overruns_whole_run": summary.get("overruns"), "daemon_jitter_whole_run": summary.get("period_jitter"),
       "daemon_cycle_time_whole_run": summary.get("cycle_time")}
if (summary.get("recording") or {}).get("dropped_rows", 0):
    out["warning"] = "the recorder dropped rows: per-phase figures are not reliable"
req = (summary.get("modbus") or {}).get("requests", 0)
out["modbus_requests_per_s_during_load"] = round(req / ((t3 - t2) / 1e3 + 1.0), 1)  # whole run's requests / load time
try:
    out["loadavg_at_end"] = open("/proc/loadavg").read().split()[:3]
except OSError:
    pass
print(json.dumps(out, indent=2))
for name in ("quiet1", "load", "quiet2"):
    p = out[name]
    line = (f"{name:7s} cycles={p['cycles']:6d} missed={p['missed_periods']:4d} jitter p50={p['jitter_p50_us']:.0f} "
            f"p99={p['jitter_p99_us']:.0f} p99.9={p['jitter_p999_us']:.0f} max={p['jitter_max_us']:.0f} µs")
    ref = p["reference_sleeper"]
    if ref:
        line += (f" | reference sleeper: late>1ms={ref['late_over_1ms']:4d} p99={ref['latency_p99_us']} "
                 f"p99.9={ref['latency_p999_us']} max={ref['latency_max_us']} µs")
    print(line, file=sys.stderr)
PY
