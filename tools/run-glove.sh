#!/usr/bin/env bash
# Set up, build and run the main job: a simulated five-finger glove grasp session with the host daemon.
# Usage: tools/run-glove.sh [extra `phalanx run` options]
set -euo pipefail
cd "$(dirname "$0")/.."

tools/setup.sh
cmake --preset host >/dev/null
cmake --build --preset host
live=()
if [ -t 2 ]; then live=(--live); fi
exec build/host/bin/phalanx run --device sim:glove5 --seconds 10 --record build/glove-session.csv "${live[@]}" "$@"
