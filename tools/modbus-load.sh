#!/usr/bin/env bash
# The Modbus server's cost to the 1 kHz loop (issue #9 target): one phalanxd run, first without Modbus clients,
# then with N mbpoll clients each polling the whole input map every 10 ms (≈ 100 Hz), then quiet again. The loop's
# own per-cycle wake times (its CSV recording) give the period jitter and missed periods of each phase; the phase
# boundaries come from the loop clock read over Modbus (input register 12, uptime ms).
#
# Usage: tools/modbus-load.sh [build/host/bin] [clients=16] [phase_s=10]
set -euo pipefail
BIN=${1:-build/host/bin}
CLIENTS=${2:-16}
PHASE=${3:-10}
PORT=${PORT:-15502}
WORK=$(mktemp -d /tmp/phalanx-modbus-load.XXXXXX)
command -v mbpoll >/dev/null || { echo "modbus-load: mbpoll is not installed (tools/setup.sh)" >&2; exit 2; }

cat > "$WORK/phalanxd.yaml" <<YAML
version: 1
device: sim:glove5
seconds: $((3 * PHASE + 4))
record: $WORK/loop.csv
modbus:
  enabled: true
  port: $PORT
YAML

"$BIN/phalanxd" --config "$WORK/phalanxd.yaml" --json >"$WORK/summary.json" 2>"$WORK/phalanxd.err" &
DAEMON=$!
uptime_ms() {
  mbpoll -m tcp -p "$PORT" -0 -1 -B -t 3:int -r 12 127.0.0.1 | sed -n 's/^\[12\]: *//p' | tr -d '[:space:]'
}
for _ in $(seq 50); do grep -q "modbus: serving" "$WORK/phalanxd.err" 2>/dev/null && break; sleep 0.1; done
grep -q "modbus: serving" "$WORK/phalanxd.err" || { cat "$WORK/phalanxd.err" >&2; exit 3; }

sleep 2  # start-up transient excluded
T0=$(uptime_ms)
sleep "$PHASE"
T1=$(uptime_ms)
PIDS=()
for _ in $(seq "$CLIENTS"); do
  mbpoll -m tcp -p "$PORT" -0 -t 3 -r 0 -c 112 -l 10 -o 1 127.0.0.1 >/dev/null 2>&1 &
  PIDS+=($!)
done
sleep 1  # all clients connected and polling
T2=$(uptime_ms)
sleep "$PHASE"
T3=$(uptime_ms)
if [ "${#PIDS[@]}" -gt 0 ]; then
  kill "${PIDS[@]}"
  wait "${PIDS[@]}" 2>/dev/null || true
fi
wait "$DAEMON" || true

python3 - "$WORK" "$T0" "$T1" "$T2" "$T3" "$CLIENTS" <<'PY'
import csv, json, math, sys
work, t0, t1, t2, t3, clients = sys.argv[1], *map(int, sys.argv[2:6]), int(sys.argv[6])
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

def phase(a_ms, b_ms):
    sel = [r for r in rows if a_ms / 1e3 <= r[0] < b_ms / 1e3]
    j = [r[1] for r in sel]
    return {"seconds": (b_ms - a_ms) / 1e3, "cycles": len(sel), "missed_periods": sum(r[2] for r in sel),
            "jitter_p50_us": pct(j, 0.5), "jitter_p99_us": pct(j, 0.99), "jitter_p999_us": pct(j, 0.999),
            "jitter_max_us": max(j) if j else float("nan")}

out = {"clients": clients, "poll_interval_ms": 10, "registers_per_request": 112,
       "realtime": summary.get("realtime"), "no_load": phase(t0, t1), "load": phase(t2, t3),
       "modbus": summary.get("modbus"), "daemon_overruns_whole_run": summary.get("overruns"),
       "daemon_jitter_whole_run": summary.get("period_jitter")}
req = summary.get("modbus", {}).get("requests", 0)
out["modbus_requests_per_s_during_load"] = round(req / ((t3 - t2) / 1e3 + 1.0), 1)  # whole run's requests / load time
print(json.dumps(out, indent=2))
for name in ("no_load", "load"):
    p = out[name]
    print(f"{name:8s} cycles={p['cycles']:6d} missed={p['missed_periods']:3d} jitter p50={p['jitter_p50_us']:.0f} "
          f"p99={p['jitter_p99_us']:.0f} p99.9={p['jitter_p999_us']:.0f} max={p['jitter_max_us']:.0f} µs", file=sys.stderr)
PY
rm -rf "$WORK"
