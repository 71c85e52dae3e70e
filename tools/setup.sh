#!/usr/bin/env bash
# Install exactly what is missing for building and testing Phalanx on Debian 12. Idempotent: a second run
# installs nothing. Usage: tools/setup.sh [extra Debian packages…]   (with arguments: only those packages)
set -euo pipefail

if [ $# -gt 0 ]; then
  PACKAGES=("$@")
else
PACKAGES=(
  build-essential cmake ninja-build pkg-config git python3
  libeigen3-dev libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev libspdlog-dev libfmt-dev libyaml-cpp-dev
  zlib1g-dev
  nlohmann-json3-dev libceres-dev libusb-1.0-0-dev libgpiod-dev gpiod libmodbus-dev mbpoll libnlopt-dev rt-tests
  clang libclang-rt-14-dev valgrind
  qemu-system-x86 busybox-static kmod cpio can-utils bc libaio-dev usbutils rt-tests
  linux-source-6.1 linux-headers-amd64
  libcpp-httplib-dev chromium
  libzstd-dev
)
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "setup: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
