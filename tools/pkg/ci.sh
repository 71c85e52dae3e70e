#!/usr/bin/env bash
# The package stage of tools/run-tests.sh (issue 24): the Debian packages of the host build (CPack, with the MCU
# images when tools/mcu has built them), lintian on them, then a clean Debian 12 root (chroot) they are installed
# into with apt (with systemd, for the unit's check), where
#   - phalanxd runs from the installed tree as an unprivileged member of group `phalanx` against sim:glove5 and must
#     get SCHED_FIFO and mlockall (its summary, and the scheduling policy in /proc while it runs);
#   - a user outside the group cannot start it;
#   - the systemd unit's own command line runs as the `phalanx` system user and serves the API socket in its
#     runtime directory to a member of the group (`phalanx status`); `systemd-analyze verify` checks the unit;
#   - the group's limits.d file is applied by a PAM login (runuser -l) where this machine lets a login raise
#     RLIMIT_RTPRIO (printed, not gated, where it cannot: a container without CAP_SYS_RESOURCE).
# Needs root (chroot, mounts) and build/host built. The clean root is unpacked from a cached debootstrap tarball
# (tools/pkg/base-root.sh); downloaded .debs are kept in $PHALANX_ROOT_CACHE/apt-archives for the next run.
# Usage: tools/pkg/ci.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
start=$(date +%s)
build=build/host
out=build/pkg
cache=${PHALANX_ROOT_CACHE:-/var/cache/phalanx-ci}
root=$PWD/build/pkg-root
[ "$(id -u)" -eq 0 ] || { echo "pkg: needs root (chroot)"; exit 2; }
fail() { echo "pkg: FAIL: $*" >&2; exit 1; }

umount_root() {
  for m in var/cache/apt/archives dev/pts dev proc; do
    if mountpoint -q "$root/$m" 2>/dev/null; then umount -l "$root/$m" || true; fi
  done
}
cleanup() { kill_ours; umount_root; rm -rf "$root"; }
pids=()
kill_ours() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT
umount_root
rm -rf "$root" "$out"
mkdir -p "$out"

echo "== packages (cpack) =="
cmake "$build" >/dev/null  # picks up MCU images built since the last configure
cmake --build "$build" --target phalanx phalanxd firmware-sim libphalanx man-pages deb-changelog >/dev/null
rm -rf "$build/packages"
(cd "$build" && cpack -G DEB) > "$out/cpack.log" 2>&1 || { tail -30 "$out/cpack.log"; fail "cpack"; }
mapfile -t debs < <(ls "$build"/packages/*.deb)
for d in "${debs[@]}"; do echo "  $(basename "$d") $(du -k "$d" | cut -f1) KiB"; done
t_pack=$(date +%s)

echo "== lintian =="
# Reported in full; gated on errors only (docs/install.md lists the warnings and why they stay).
lint_rc=0
lintian "${debs[@]}" > "$out/lintian.txt" 2>&1 || lint_rc=$?
cat "$out/lintian.txt"
[ "$lint_rc" -le 1 ] || fail "lintian did not run (exit $lint_rc)"
errors=$(grep -c '^E: ' "$out/lintian.txt" || true)
warnings=$(grep -c '^W: ' "$out/lintian.txt" || true)
echo "lintian: $errors errors, $warnings warnings"
[ "$errors" -eq 0 ] || fail "lintian reports $errors errors"
t_lint=$(date +%s)

echo "== clean Debian 12 root =="
tools/pkg/base-root.sh "$root"
mount -t proc proc "$root/proc"
mount --bind /dev "$root/dev"
mount --bind /dev/pts "$root/dev/pts"
mkdir -p "$cache/apt-archives/partial" "$root/tmp/debs"
mount --bind "$cache/apt-archives" "$root/var/cache/apt/archives"
cp "${debs[@]}" "$root/tmp/debs/"
in_root_debs=()
for d in "${debs[@]}"; do in_root_debs+=("/tmp/debs/$(basename "$d")"); done
in_root() { chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 "$@"; }
in_root apt-get update -qq > "$out/apt.log" 2>&1 || { tail "$out/apt.log"; fail "apt-get update in the clean root"; }
if ! in_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
     -o APT::Keep-Downloaded-Packages=true "${in_root_debs[@]}" systemd >> "$out/apt.log" 2>&1; then
  tail -30 "$out/apt.log"; fail "apt-get install of the packages"
fi
echo "installed: $(in_root dpkg-query -W -f '${Package} ' 'phalanx*' 'libphalanx*' 'python3-phalanx')"
t_inst=$(date +%s)

echo "== phalanxd as an unprivileged member of group phalanx =="
in_root useradd --create-home --groups phalanx tester
in_root useradd --create-home outsider
echo "  $(in_root stat -c '%n %U:%G %a' /usr/bin/phalanxd), capabilities: $(in_root getcap /usr/bin/phalanxd)"
in_root runuser -u tester -- phalanxd --device sim:glove5 --seconds 3 --json > "$out/session.json" 2> "$out/session.err" &
pids+=($!)
# The scheduling policy of the running daemon, from /proc (field 41 of stat: 1 = SCHED_FIFO), read once the
# session runs (its summary says the same at the end).
policy=""
for _ in $(seq 1 100); do
  pid=""
  for p in $(pgrep -x phalanxd || true); do  # the one inside this root (other phalanxd may run on the machine)
    [ "$(readlink "/proc/$p/root" 2>/dev/null)" = "$root" ] && pid=$p
  done
  if [ -n "$pid" ]; then
    policy=$(awk '{print $41}' "/proc/$pid/stat" 2>/dev/null || true)
    [ "$policy" = 1 ] && break
  fi
  sleep 0.05
done
wait "${pids[-1]}" || { cat "$out/session.err"; fail "phalanxd session as tester"; }
python3 - "$out/session.json" "$policy" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
rt = s["realtime"]
print(f"  summary: realtime {rt}, /proc policy while running: {sys.argv[2] or '?'} (1 = SCHED_FIFO)")
assert rt["sched_fifo"] is True, "no SCHED_FIFO for the group member"
assert rt["memory_locked"] is True, "no mlockall for the group member"
assert sys.argv[2] == "1", "the running daemon's policy was not SCHED_FIFO"
PY
if in_root runuser -u outsider -- phalanxd --device sim:glove5 --seconds 1 > "$out/outsider.txt" 2>&1; then
  fail "a user outside group phalanx ran phalanxd"
fi
echo "  outside the group: refused ($(head -1 "$out/outsider.txt"))"

echo "== limits.d through a PAM login =="
rtprio=$(in_root runuser -l tester -c 'ulimit -r' 2>&1 | tail -1 || true)
if [ "$(ulimit -Hr)" = unlimited ] || [ "$(ulimit -Hr)" -ge 90 ] 2>/dev/null || capsh --has-p=cap_sys_resource 2>/dev/null; then
  [ "$rtprio" = 90 ] || fail "runuser -l: RLIMIT_RTPRIO $rtprio, limits.d/phalanx.conf says 90"
  echo "  runuser -l tester: ulimit -r = $rtprio"
else
  echo "  not checked here: this machine's hard RLIMIT_RTPRIO is $(ulimit -Hr) and no CAP_SYS_RESOURCE, so no login" \
       "can raise it (runuser -l tester: ulimit -r = $rtprio); the file capabilities above gave SCHED_FIFO"
fi

echo "== the systemd unit =="
unit=$root/usr/lib/systemd/system/phalanxd.service
[ -f "$unit" ] || fail "no unit in the installed tree"
systemd-analyze verify --man=no --root="$root" phalanxd.service > "$out/verify.txt" 2>&1 || { cat "$out/verify.txt"; fail "systemd-analyze verify"; }
grep -v '^$' "$out/verify.txt" | sed 's/^/  /' || true
echo "  systemd-analyze verify: ok"
# The unit's ExecStart as its User, with the directories systemd would make (RuntimeDirectory, StateDirectory).
exec_start=$(sed -n 's/^ExecStart=//p' "$unit")
in_root install -d -o phalanx -g phalanx -m 0750 /run/phalanx /var/lib/phalanx /var/lib/phalanx/records
# shellcheck disable=SC2086
in_root runuser -u phalanx -- $exec_start > "$out/service.log" 2>&1 &
pids+=($!)
for _ in $(seq 1 100); do [ -S "$root/run/phalanx/phalanxd.sock" ] && break; sleep 0.05; done
[ -S "$root/run/phalanx/phalanxd.sock" ] || { cat "$out/service.log"; fail "the unit's command served no socket"; }
in_root runuser -u tester -- phalanx status --socket /run/phalanx/phalanxd.sock \
  --daemon-uid "$(in_root id -u phalanx)" --json > "$out/status.json" 2>&1 || { cat "$out/status.json"; fail "phalanx status"; }
echo "  phalanx status (as tester): $(head -c 200 "$out/status.json")"
kill -TERM "${pids[-1]}"; wait "${pids[-1]}" || true
end=$(date +%s)
echo "pkg stage: $((end - start)) s (packages $((t_pack - start)), lintian $((t_lint - t_pack)), root+install $((t_inst - t_lint)), checks $((end - t_inst)))"
