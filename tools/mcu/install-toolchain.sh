#!/usr/bin/env bash
# Install the Cortex-M cross toolchain and QEMU for the MCU images (Debian 12). Idempotent: installs only what is
# missing, and nothing at all on a second run. About 420 MB to download on a fresh machine.
# Usage: tools/mcu/install-toolchain.sh
set -euo pipefail

PACKAGES=(gcc-arm-none-eabi libnewlib-arm-none-eabi libstdc++-arm-none-eabi-newlib qemu-system-arm)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "mcu toolchain: all ${#PACKAGES[@]} packages present ($(arm-none-eabi-gcc -dumpversion), $(qemu-system-arm --version | head -1))"
  exit 0
fi

echo "mcu toolchain: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
