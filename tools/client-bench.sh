#!/usr/bin/env bash
# The client channel's latency benchmarks (docs/sdk.md "Benchmarks"): phalanxd on sim:pantograph at 1 kHz with a
# C++ servo-callback client, then a Python client; printed, not gated. Real-time scheduling is used when the
# daemon may (root or RLIMIT_RTPRIO); the clients run at ordinary priority unless started with chrt.
#   tools/client-bench.sh [BUILD_DIR] [CPP_SECONDS] [PY_SECONDS]      (defaults build/host 60 20)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
build="${1:-$root/build/host}"
cpp_s="${2:-60}"
py_s="${3:-20}"
dir="$(mktemp -d /tmp/phalanx_client_bench.XXXXXX)"
trap 'rm -rf "$dir"' EXIT
run() {  # what, seconds, client command...
  local what="$1" secs="$2"
  shift 2
  "$build/bin/phalanxd" --device sim:pantograph --seconds "$((${secs%.*} + 4))" --mode transparent --scene none \
    --scenario still --client-socket "$dir/$what.sock" --json > "$dir/$what.json" 2> "$dir/$what.err" &
  local pid=$!
  for _ in $(seq 100); do grep -q "client: serving on" "$dir/$what.err" 2>/dev/null && break; sleep 0.05; done
  "$@" "$dir/$what.sock" "$secs"
  wait "$pid" || true
  python3 - "$dir/$what.json" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
c = j.get("client", {})
print("  daemon: cycles commanded %s, held cycles without a fresh command (missed) %s: %s on the daemon's schedule, "
      "%s off it (the daemon itself late or catching up); fallback cycles %s, force-offs %s"
      % (c.get("cycles_commanded"), c.get("cycles_without_fresh_command"), c.get("missed_on_schedule"),
         c.get("missed_off_schedule"), c.get("fallback_cycles"), c.get("force_offs")))
PY
}
# The C++ client at SCHED_FIFO 70 (below the daemon's loop) when allowed: the documented real-time set-up.
rt=()
if [ "$(id -u)" -eq 0 ] && command -v chrt > /dev/null; then rt=(chrt -f 70); fi
echo "== C++ callback client, ${cpp_s} s ${rt[*]}"
# The machine's own baseline in the same interval: cyclictest (rt-tests) at a priority below the client's counts the
# 1 ms periods in which this machine woke a real-time thread more than half a period late.
if [ ${#rt[@]} -gt 0 ] && command -v cyclictest > /dev/null; then
  cyclictest -q -m -p 60 -t1 -i 1000 -D "${cpp_s}s" -h 2000 > "$dir/cyclictest.txt" 2>&1 &
fi
run cpp "$cpp_s" "${rt[@]}" "$build/bin/phalanx_client_latency"
wait
if [ -s "$dir/cyclictest.txt" ]; then
  awk '/^[0-9]/ { if ($1 + 0 > 500) late += $2 } /Max Latencies/ { max = $4 } /Histogram Overflows/ { late += $4 }
       END { printf "  machine (cyclictest -p 60, same %s s): %d periods woke > 500 us late; max %d us\n", secs, late, max }' \
      secs="$cpp_s" "$dir/cyclictest.txt"
fi
echo "== Python client, ${py_s} s"
run py "$py_s" env PYTHONPATH="$root/python" python3 "$root/tools/client_latency.py"
