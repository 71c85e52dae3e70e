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
  pybind11-dev python3-dev python3-numpy
)
fi

# `import phalanx` for a plain python3 (docs/sdk.md "Python"): a .pth file in each python3's site directory that
# puts this tree's python/ on the path; the build puts the extension module (_phalanx*.so) into python/phalanx/.
# Skipped when only extra packages were asked for, or when the site directory is not writable.
link_python_package() {
  [ $# -gt 0 ] && return 0
  local repo py site
  repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
  for py in $(command -v python3) /usr/bin/python3; do
    [ -x "$py" ] || continue
    site="$("$py" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])' 2>/dev/null)" || continue
    mkdir -p "$site" 2>/dev/null || true
    if [ -w "$site" ]; then
      echo "$repo/python" > "$site/phalanx-tree.pth"
      echo "setup: $py imports phalanx from $repo/python ($site/phalanx-tree.pth)"
    fi
  done
}

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present"
  link_python_package "$@"
  exit 0
fi

echo "setup: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
link_python_package "$@"
