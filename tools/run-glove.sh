#!/usr/bin/env bash
# Set up, build and run the main job: a simulated five-finger glove grasp session with the host daemon.
# Usage: tools/run-glove.sh [extra `phalanx run` options]
set -euo pipefail
cd "$(dirname "$0")/.."

tools/setup.sh
# A first configure leaves the tests out (their libraries are in the test set, `tools/setup.sh --test`);
# tools/run-tests.sh turns them on. Only the three programs the session runs are built.
tests=()
if [ ! -f build/host/CMakeCache.txt ]; then tests=(-DPHALANX_BUILD_TESTS=OFF); fi
cmake --preset host "${tests[@]}" >/dev/null
cmake --build --preset host --target phalanx phalanxd firmware-sim
live=()
if [ -t 2 ]; then live=(--live); fi
exec build/host/bin/phalanx run --device sim:glove5 --seconds 10 --record build/glove-session.csv "${live[@]}" "$@"
