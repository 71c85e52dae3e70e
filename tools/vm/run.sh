#!/usr/bin/env bash
# Boot Debian's kernel under QEMU (TCG emulation: this machine's /dev/kvm cannot run it) with the host's root
# shared read-only and this repository read-write over 9p, run one command inside (from the repository
# directory, as root, in a chroot of the host's root), and exit with that command's exit code.
# The whole console log is kept in build/vm/logs/<name>.log.
# Usage: tools/vm/run.sh [--timeout SECONDS] [--name NAME] [--smp N] -- COMMAND...
# Exit codes: the command's, or 124 when the VM timed out, 125 when the VM gave no result line.
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
TIMEOUT=300
NAME=run
SMP=2
while [ $# -gt 0 ]; do
  case "$1" in
    --timeout) TIMEOUT="$2"; shift 2 ;;
    --name) NAME="$2"; shift 2 ;;
    --smp) SMP="$2"; shift 2 ;;
    --) shift; break ;;
    *) echo "run.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
[ $# -gt 0 ] || { echo "usage: tools/vm/run.sh [--timeout S] [--name N] -- COMMAND..." >&2; exit 2; }
CMD="$*"
# The kernel command line is capped at 2048 bytes and splits on spaces unless quoted; keep the command short
# and free of double quotes (wrap longer things in a script under tests/vm/).
case "$CMD" in *\"*) echo "run.sh: the command must not contain double quotes" >&2; exit 2 ;; esac
[ ${#CMD} -lt 1500 ] || { echo "run.sh: command too long for the kernel command line" >&2; exit 2; }

KV=$("$ROOT/tools/vm/kernel.sh")
# Out-of-tree gpio-sim for tests/vm/gpio_test.sh (cached; without its packages only that test fails).
"$ROOT/tools/vm/gpio-sim.sh" "$KV" || echo "run.sh: gpio-sim.ko not built (see above): tests/vm/gpio_test.sh will fail" >&2
INITRD=$("$ROOT/tools/vm/initramfs.sh" "$KV")
KERNEL="$ROOT/build/vm/kroot-$KV/boot/vmlinuz-$KV"
mkdir -p "$ROOT/build/vm/logs"
LOG="$ROOT/build/vm/logs/$NAME.log"

# clocksource=tsc: under TCG the kernel distrusts the TSC and falls back to the HPET, whose every read is an
# emulated MMIO access with no vDSO; QEMU derives the guest TSC from the host clock, so it is safe here. Measured
# on this machine: a 2 s firmware-sim run took 10.9 s of wall time with the HPET, 7.8 s with the TSC (host loaded).
# VM_KERNEL_ARGS adds kernel arguments; VM_QEMU_CPU replaces -cpu max (measurements only: docs/vm-lane.md).
# Host CPU share (docs/vm-lane.md "Why the VM missed 1 kHz"): with autogroup scheduling (Debian's default) the host
# splits its CPUs between sessions first, so on a machine shared by several jobs QEMU's threads got one session's
# share however many of them were busy, and the guest's 1 kHz timers fired late or not at all. QEMU therefore runs
# in a session of its own whose autogroup is raised to nice PHALANX_VM_NICE (default -10: about 9 times another
# session's weight; 0 leaves it as is). Needs root (CI and this machine); otherwise it runs unchanged, with a note.
VM_NICE=${PHALANX_VM_NICE:--10}
PRIO=()
if [ "$VM_NICE" != 0 ]; then
  PRIO=(setsid "$ROOT/tools/vm/vm-nice.sh" "$VM_NICE")
fi
start=$(date +%s.%N)
set +e
timeout --foreground -k 5 "$TIMEOUT" "${PRIO[@]}" qemu-system-x86_64 -accel tcg -cpu "${VM_QEMU_CPU:-max}" -smp "$SMP" -m 768 \
  -nographic -no-reboot -net none -monitor none -serial stdio \
  -kernel "$KERNEL" -initrd "$INITRD" \
  -virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on \
  -virtfs "local,path=$ROOT,mount_tag=work,security_model=none" \
  -append "console=ttyS0 quiet loglevel=3 panic=-1 clocksource=tsc tsc=reliable ${VM_KERNEL_ARGS:-} repo=$ROOT test=\"$CMD\"" </dev/null >"$LOG" 2>&1
qrc=$?
set -e
elapsed=$(echo "$(date +%s.%N) - $start" | bc)
grep -a '^vm-nice:' "$LOG" || true
# Show the test's own output (the console minus the boot noise before init's first line).
sed -n '/^init: /,$p' "$LOG" | tr -d '\r'
if [ $qrc -eq 124 ]; then
  echo "vm: '$NAME' timed out after ${TIMEOUT}s (log: $LOG)"; exit 124
fi
rc=$(tr -d '\r' < "$LOG" | sed -n 's/^VM-TEST-EXIT rc=\([0-9]*\)$/\1/p' | tail -1)
if [ -z "$rc" ]; then
  echo "vm: '$NAME' gave no VM-TEST-EXIT line (qemu exit $qrc; log: $LOG)"; tail -20 "$LOG"; exit 125
fi
printf 'vm: %s rc=%s in %.1f s\n' "$NAME" "$rc" "$elapsed"
exit "$rc"
