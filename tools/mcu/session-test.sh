#!/usr/bin/env bash
# The QEMU-hosted firmware against the host daemon over the emulated UART (needs the host build and the
# mps2-an386 image): handshake, a several-second session with the firmware ticking at 1 kHz, then phalanxd
# killed with SIGKILL — the firmware must report its outputs safe within two ticks of the command deadline, and
# a reconnecting host must read the latched command-timeout. Extra arguments go to qemu_board.py session.
# Usage: tools/mcu/session-test.sh [--app glove5|sea_finger|pantograph] [--seconds 4] [--rate-hz 100]
#        [--plant-period-ms N (default per app: glove5 16, sea_finger 1, pantograph 8)]
set -euo pipefail
cd "$(dirname "$0")/../.."
exec python3 tools/mcu/qemu_board.py session "$@"
