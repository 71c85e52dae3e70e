#!/usr/bin/env bash
# Set up, build and run every Phalanx test: the host build (unit, closed-loop simulation and multi-process
# integration suites), the sanitizer build (unit suites under ASan + UBSan), a short fuzz run of the decoder and
# the VM lane (Debian's kernel under QEMU: SocketCAN tests against the real kernel, tools/vm/ci.sh).
# Usage: tools/run-tests.sh            (what CI runs)
set -euo pipefail
cd "$(dirname "$0")/.."

tools/setup.sh
tools/setup-records.sh  # pinned PyPI packages of the recordings' tests (mcap, numpy)

echo "== host build =="
cmake --preset host >/dev/null
cmake --build --preset host
ctest --preset host -j2

echo "== sanitizer build (ASan + UBSan), unit suites =="
cmake --preset sanitize >/dev/null
cmake --build --preset sanitize
ctest --preset sanitize -j2

if command -v clang++ >/dev/null; then
  echo "== decoder fuzz (libFuzzer, 60 s) =="
  tools/fuzz.sh 60
fi

echo "== MCU firmware: Cortex-M4F cross builds within budget + QEMU mps2-an386 session with phalanxd =="
tools/mcu/ci.sh

echo "== VM lane: Debian kernel under QEMU (TCG), real SocketCAN =="
tools/vm/ci.sh
