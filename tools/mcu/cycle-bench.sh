#!/usr/bin/env bash
# Cycle budget of the control tick on the emulated Cortex-M4F: the firmware under `qemu -icount shift=N` (each
# instruction 2^N ns of virtual time, so SysTick deltas count instructions deterministically), a host session
# over the emulated UART, the plant running below the tick (at most one 1 ms step per --plant-period-ms). Prints
# the tick's worst case, median and p99 in
# instructions and fails if the worst case exceeds the budget (CI gates per app: tools/mcu/ci.sh).
# Usage: tools/mcu/cycle-bench.sh [--app glove5|sea_finger|pantograph] [--seconds 5] [--shift 2] [--rate-hz 100]
#        [--plant-period-ms 1] [--budget 17000]
set -euo pipefail
cd "$(dirname "$0")/../.."
exec python3 tools/mcu/qemu_board.py bench "$@"
