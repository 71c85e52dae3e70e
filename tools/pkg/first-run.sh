#!/usr/bin/env bash
# The new user's first run, measured (docs/install.md "Measured"): a fresh clone in a fresh Debian 12 root
# (debootstrap --variant=minbase, tools/pkg/base-root.sh), then the README's main-job command there —
# `tools/run-glove.sh --json` — timed from its start to the first session cycle, with each output line stamped, so
# that package installation, configuration, the build and the session can be told apart. Nothing is cached between
# runs except the debootstrap tarball (the fresh machine itself): apt downloads every package, the build starts
# from nothing.
# Usage: tools/pkg/first-run.sh [COMMIT]     (root; the clone is of COMMIT, default HEAD; prints the phase times)
# Needs: root (chroot, mounts), git, and debootstrap the first time (tools/setup.sh --test installs it).
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
commit=${1:-HEAD}
[ "$(id -u)" = 0 ] || { echo "first-run: needs root (chroot)" >&2; exit 2; }
out=$ROOT/build/first-run
root=$out/root
mounts=()
cleanup() {
  for ((i = ${#mounts[@]} - 1; i >= 0; i--)); do umount -l "${mounts[$i]}" 2>/dev/null || true; done
}
trap cleanup EXIT
if [ -e "$root" ]; then
  for m in $(awk -v r="$root" 'index($2, r) == 1 {print $2}' /proc/mounts | sort -r); do umount -l "$m"; done
  rm -rf "$root"
fi
mkdir -p "$out"
"$ROOT/tools/pkg/base-root.sh" "$root"
for m in proc dev dev/pts; do
  case $m in proc) mount -t proc proc "$root/proc" ;; *) mount --bind "/$m" "$root/$m" ;; esac
  mounts+=("$root/$m")
done
git clone --quiet --no-hardlinks "$ROOT" "$root/root/phalanx"
git -C "$root/root/phalanx" checkout --quiet "$(git -C "$ROOT" rev-parse "$commit")"
echo "first-run: $(git -C "$root/root/phalanx" log -1 --format='%h %s' | cut -c1-100)"
echo "first-run: machine $(nproc) CPUs, load average $(cut -d' ' -f1-3 /proc/loadavg) at the start"
start=$(date +%s.%N)
set +e
chroot "$root" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 HOME=/root \
  bash -c 'cd /root/phalanx && tools/run-glove.sh --json' 2>&1 | while IFS= read -r line; do
    printf '%7.1f %s\n' "$(echo "$(date +%s.%N) - $start" | bc)" "$line"
  done > "$out/run.log"
rc=${PIPESTATUS[0]}
set -e
end=$(date +%s.%N)
echo "first-run: load average $(cut -d' ' -f1-3 /proc/loadavg) at the end; log: $out/run.log"
# Phases, from the stamped lines: packages installed and the build configured (ninja's first step), built (its
# last link), the session's first output (firmware-sim's first line, or the summary).
t_of() { awk -v pat="$1" '$0 ~ pat {print $1; exit}' "$out/run.log"; }
t_build0=$(t_of '\[1/[0-9]+\]')
t_built=$(awk '/\[[0-9]+\/[0-9]+\] Linking/ {t = $1} END {print t}' "$out/run.log")
t_session=$(t_of 'firmware-sim:|"session"')
printf 'first-run: set up and configured at %s s, built at %s s, first session output at %s s; whole command %.1f s, exit %s\n' \
  "${t_build0:-?}" "${t_built:-?}" "${t_session:-?}" "$(echo "$end - $start" | bc)" "$rc"
awk 'match($2, /^\[[0-9]+\/[0-9]+\]$/) {n = substr($2, index($2, "/") + 1); sub(/\]/, "", n)} END {print "first-run: build steps: " n}' \
  "$out/run.log"
exit "$rc"
