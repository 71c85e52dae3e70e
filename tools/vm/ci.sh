#!/usr/bin/env bash
# The VM lane of CI: boot Debian's kernel under QEMU once and run every tests/vm/*_test.sh inside it against
# real kernel interfaces (vcan/SocketCAN, ...), with the host build tree (build/host) shared in.
# Skipped, with a message, only when QEMU itself cannot run on this machine.
# Usage: tools/vm/ci.sh [TEST-NAME...]   (default: all tests/vm/*_test.sh; the host build must exist)
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
cd "$ROOT"
# QEMU can run when a bare TCG machine starts and keeps running (timeout ends it: exit 124).
qemu_ok=0
if command -v qemu-system-x86_64 >/dev/null; then
  set +e; timeout 3 qemu-system-x86_64 -accel tcg -machine none -nographic -monitor none </dev/null >/dev/null 2>&1
  [ $? -eq 124 ] && qemu_ok=1; set -e
fi
if [ $qemu_ok -ne 1 ]; then
  echo "vm lane: SKIPPED - qemu-system-x86_64 cannot run here (tools/setup.sh installs qemu-system-x86)"
  exit 0
fi
[ -x build/host/bin/phalanxd ] || { echo "vm lane: build/host is missing (cmake --preset host && cmake --build --preset host)"; exit 1; }
start=$(date +%s)
set +e
tools/vm/run.sh --timeout 420 --name vm-tests -- sh tests/vm/run-all.sh "$@"
rc=$?
set -e
echo "vm lane: finished in $(( $(date +%s) - start )) s"
exit $rc
