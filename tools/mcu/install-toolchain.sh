#!/usr/bin/env bash
# Install the Cortex-M cross toolchain, QEMU and gdb-multiarch for the MCU images (Debian 12). Idempotent: installs only what is
# missing, and nothing at all on a second run. About 420 MB to download on a fresh machine.
# Usage: tools/mcu/install-toolchain.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
# gdb-multiarch: tools/mcu/flash-test.sh writes an image into an emulated board through QEMU's gdbstub.
tools/setup.sh gcc-arm-none-eabi libnewlib-arm-none-eabi libstdc++-arm-none-eabi-newlib qemu-system-arm gdb-multiarch
echo "mcu toolchain: $(arm-none-eabi-gcc -dumpversion), $(qemu-system-arm --version | head -1)"
