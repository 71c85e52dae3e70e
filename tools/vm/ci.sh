#!/usr/bin/env bash
# The VM lane of CI: boot Debian's kernel under QEMU and run every tests/vm/*_test.sh inside it against real kernel
# interfaces (vcan/SocketCAN, ...), with the host build tree (build/host) shared in. One boot runs the short tests
# (480 s for all of them); a test whose script has a line `# vm-lane: own boot, timeout SECONDS` runs in a boot of
# its own with that timeout (the teleoperation sweep: 10 cases of half a minute), so that neither budget is shared
# with a long test.
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

if [ $# -gt 0 ]; then tests=("$@"); else
  tests=(); for f in tests/vm/*_test.sh; do t=${f##*/}; tests+=("${t%_test.sh}"); done
fi
own_boot_timeout() {  # test name -> its own boot's timeout, or nothing
  [ -f "tests/vm/$1_test.sh" ] || return 0
  sed -n 's/^# vm-lane: own boot, timeout \([0-9][0-9]*\)$/\1/p' "tests/vm/$1_test.sh" | head -1
}
shared=()
own=()
for t in "${tests[@]}"; do
  if [ -n "$(own_boot_timeout "$t")" ]; then own+=("$t"); else shared+=("$t"); fi
done

start=$(date +%s)
failed=0
boot() {  # name timeout tests...
  local name=$1 timeout=$2 rc=0 t0
  shift 2
  t0=$(date +%s)
  tools/vm/run.sh --timeout "$timeout" --name "$name" -- sh tests/vm/run-all.sh "$@" || rc=$?
  echo "vm lane: boot '$name' ($*) exit $rc in $(( $(date +%s) - t0 )) s of its $timeout s"
  [ $rc -eq 0 ] || failed=$((failed + 1))
}
[ ${#shared[@]} -eq 0 ] || boot vm-tests 480 "${shared[@]}"
for t in "${own[@]}"; do boot "vm-$t" "$(own_boot_timeout "$t")" "$t"; done
echo "vm lane: finished in $(( $(date +%s) - start )) s"
[ $failed -eq 0 ]
