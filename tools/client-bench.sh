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
print("  daemon: cycles commanded %s, held cycles without a fresh command (missed) %s, fallback cycles %s, force-offs %s"
      % (c.get("cycles_commanded"), c.get("cycles_without_fresh_command"), c.get("fallback_cycles"), c.get("force_offs")))
PY
}
# The C++ client at SCHED_FIFO 70 (below the daemon's loop) when allowed: the documented real-time set-up.
rt=()
if [ "$(id -u)" -eq 0 ] && command -v chrt > /dev/null; then rt=(chrt -f 70); fi
echo "== C++ callback client, ${cpp_s} s ${rt[*]}"
run cpp "$cpp_s" "${rt[@]}" "$build/bin/phalanx_client_latency"
echo "== Python client, ${py_s} s"
run py "$py_s" env PYTHONPATH="$root/python" python3 "$root/tools/client_latency.py"
