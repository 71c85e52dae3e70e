#!/usr/bin/env bash
# The MCU stage of tools/run-tests.sh: toolchain (installed only if missing), cross builds within budget with
# -Werror and no allocator in the link, then the QEMU session test and the cycle benchmark. Needs build/host
# (phalanx, phalanxd) from the host stage.
set -euo pipefail
cd "$(dirname "$0")/../.."
start=$(date +%s)
tools/mcu/install-toolchain.sh
tools/mcu/build.sh
tools/mcu/session-test.sh --seconds 4
tools/mcu/cycle-bench.sh --seconds 3
echo "mcu stage: $(( $(date +%s) - start )) s"
