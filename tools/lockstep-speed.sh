#!/usr/bin/env bash
# Lockstep simulation speed of every device's benches, side by side in one run (docs/bench-runner.md
# "Lockstep speed"): virtual seconds the bench's rigs stepped / their wall-clock seconds. Printed, not judged.
# Usage: tools/lockstep-speed.sh [path/to/phalanx]   (default build/host/bin/phalanx)
set -euo pipefail
cd "$(dirname "$0")/.."
phalanx=${1:-build/host/bin/phalanx}
[ -x "$phalanx" ] || { echo "lockstep-speed: $phalanx not built (cmake --build --preset host --target phalanx)" >&2; exit 2; }
printf '%-11s %-18s %6s %12s %11s %11s %12s\n' device bench rigs simulated_s rig_wall_s x_real_time bench_wall_s
run() {
  local device=$1 bench=$2
  "$phalanx" bench "$bench" --json | python3 -c '
import json, sys
s = json.load(sys.stdin)["lockstep_speed"]
print("%-11s %-18s %6d %12.2f %11.3f %11.0f %12.3f" % (sys.argv[1], sys.argv[2], s["rigs"], s["simulated_s"],
      s["rig_wall_s"], s["x_real_time"], s["bench_wall_s"]))' "$device" "$bench"
}
run glove5 glove-free-motion
run glove5 glove-grasp
run sea_rig sea-rig-sine
run sea_rig sea-rig-chirp
run sea_finger sea-finger-torque
run sea_finger sea-transparency
run pantograph pen-wall
