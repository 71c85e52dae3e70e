#!/usr/bin/env bash
# Install exactly what is missing for building and testing Phalanx on Debian 12. Idempotent: a second run
# installs nothing.
# Usage: tools/setup.sh          the main-job set: what building and running phalanxd/phalanx/firmware-sim needs
#        tools/setup.sh --test   everything: the main-job set plus what the tests, CI lanes and packaging need
#        tools/setup.sh PKG…     only those packages
set -euo pipefail

# The main-job set (tools/run-glove.sh): build tools and the libraries the host build links. Keep it small.
MAIN_PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libcli11-dev libyaml-cpp-dev zlib1g-dev nlohmann-json3-dev libceres-dev libusb-1.0-0-dev
  libgpiod-dev libmodbus-dev libnlopt-dev libcpp-httplib-dev libaio-dev libzstd-dev
)

set_name=main
if [ "${1:-}" = "--test" ]; then set_name=test; shift; fi
if [ $# -gt 0 ]; then set_name=requested
  PACKAGES=("$@")
elif [ "$set_name" = main ]; then
  PACKAGES=("${MAIN_PACKAGES[@]}")
else
# The test set (tools/run-tests.sh, CI): a superset of the main-job set. Append new test/CI packages here.
PACKAGES=(
  build-essential cmake ninja-build pkg-config git python3
  libeigen3-dev libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev libspdlog-dev libfmt-dev libyaml-cpp-dev
  zlib1g-dev
  nlohmann-json3-dev libceres-dev libusb-1.0-0-dev libgpiod-dev gpiod libmodbus-dev mbpoll libnlopt-dev rt-tests
  clang libclang-rt-14-dev valgrind
  qemu-system-x86 busybox-static kmod cpio can-utils bc libaio-dev usbutils rt-tests
  linux-source-6.1 linux-headers-amd64
  libcpp-httplib-dev chromium poppler-utils
  debootstrap lintian help2man libcap2-bin
  cyclonedds-dev cyclonedds-tools iproute2
  nanopb libnanopb-dev
  pybind11-dev python3-dev python3-numpy python3-venv
  gdb-multiarch openocd dfu-util   # phalanx flash --via gdb|openocd|dfu (docs/firmware-mcu.md "Flashing")
)
fi
# Python tools of the test set, pinned, from PyPI (independent peers and readers in the tests). Append here.
PIP_PACKAGES=(
  cyclonedds==11.0.1
  fhir.resources==8.1.0 fhir-core==1.1.12   # the FHIR export's validator (docs/fhir.md)
  mcap==1.6.0 zstandard==0.25.0 lz4==4.4.5 numpy==2.4.6   # the MCAP files' reader; phalanx.records' arrays
  pymodbus==3.6.9    # an independent load-cell amplifier for the real-time bench (tests/integration/bench_realtime_test.cpp)
)

if [ "$set_name" = test ] && [ $# -eq 0 ]; then PACKAGES+=("${MAIN_PACKAGES[@]}"); fi
PACKAGES=($(printf '%s\n' "${PACKAGES[@]}" | sort -u))

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

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present ($set_name set)"
else
  echo "setup: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The test set's Python tools: pip installs only those whose pinned version is not present.
if [ "$set_name" = test ]; then
  pip_missing=()
  for spec in "${PIP_PACKAGES[@]}"; do
    python3 -c "import importlib.metadata as m, sys; n, v = sys.argv[1].split('=='); sys.exit(m.version(n) != v)" \
      "$spec" 2>/dev/null || pip_missing+=("$spec")
  done
  if [ ${#pip_missing[@]} -gt 0 ]; then
    echo "setup: pip installing ${pip_missing[*]}"
    python3 -m pip install --break-system-packages -q "${pip_missing[@]}"
  fi
fi
# The DDS commander of tests/dds (docs/dds.md §"Commands"): the Cyclone DDS Python binding 0.10.2, built against
# Debian's libddsc 0.10.2, in a venv of its own (the test set's 11.0.1 stays for the subscriber). Why: Debian's
# libddsc 0.10.2 crashes in its type lookup when a reader of its resolves the type of a writer from the 11.x
# binding; a 0.10.x writer's types are the reader's own. CYCLONEDDS_HOME must look like an install prefix.
DDS_PY010=/opt/phalanx/dds-py010
if [ "$set_name" = test ] && [ $# -eq 0 ] && ! "$DDS_PY010/bin/python" -c "import cyclonedds" 2>/dev/null; then
  echo "setup: building the cyclonedds 0.10.2 Python binding into $DDS_PY010"
  home=$(mktemp -d)
  ln -s /usr/include "$home/include"
  ln -s "/usr/lib/$(dpkg-architecture -qDEB_HOST_MULTIARCH 2>/dev/null || echo x86_64-linux-gnu)" "$home/lib"
  ln -s /usr/bin "$home/bin"
  $SUDO mkdir -p "$(dirname "$DDS_PY010")"
  $SUDO python3 -m venv "$DDS_PY010"
  $SUDO env CYCLONEDDS_HOME="$home" "$DDS_PY010/bin/pip" install -q cyclonedds==0.10.2
  rm -rf "$home"
fi
link_python_package "$@"
