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
# Target (issue 6): worst-case glove tick ≤ 17000 instructions; measured 14,380–16,480 across runs. CI fails
# above 18000 (a regression guard) so run-to-run variation near the target does not turn CI red; the bench
# prints the worst case against both.
tools/mcu/cycle-bench.sh --seconds 3 --budget 18000
echo "mcu stage: $(( $(date +%s) - start )) s"
