#!/usr/bin/env bash
# Set up, build and run the main job: a simulated five-finger glove grasp session with the host daemon.
# Usage: tools/run-glove.sh [extra phalanxd options, e.g. --json, --scenario close-open, --seconds 30]
set -euo pipefail
cd "$(dirname "$0")/.."

tools/setup.sh
# A first configure leaves the tests out (their libraries are in the test set, `tools/setup.sh --test`);
# tools/run-tests.sh turns them on. Only the two programs the session runs are built: the daemon and the simulated
# board (`cmake --build --preset host` builds the rest, the `phalanx` CLI among them).
tests=()
if [ ! -f build/host/CMakeCache.txt ]; then tests=(-DPHALANX_BUILD_TESTS=OFF); fi
cmake --preset host "${tests[@]}" >/dev/null
cmake --build --preset host --target phalanxd firmware-sim
live=()
if [ -t 2 ]; then live=(--live); fi
exec build/host/bin/phalanxd --device sim:glove5 --seconds 10 --record build/glove-session.csv "${live[@]}" "$@"
