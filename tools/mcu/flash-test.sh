#!/usr/bin/env bash
# `phalanx flash` against an emulated board (issue 24 item 3; docs/firmware-mcu.md "Flashing"): a blank QEMU board
# (nothing loaded, core halted) takes the image through its gdbstub (gdb-multiarch); wrong-device, wrong-board,
# corrupt and ELF images are refused with nothing written (memory read back by gdb itself); the written board boots
# and answers the handshake with the image's build id; an image claiming another build id is written and then the
# mismatch is an error; the --dry-run output of --via openocd and dfu is what the docs show.
# Needs build/host (phalanx) and the images of tools/mcu/build.sh (the board's, and the STM32G474's).
# Usage: tools/mcu/flash-test.sh [--app glove5|sea_finger|pantograph] [--board mps2-an386|ast1030-evb]
set -euo pipefail
cd "$(dirname "$0")/../.."
exec python3 tools/mcu/qemu_board.py flash "$@"
