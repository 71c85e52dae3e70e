#!/usr/bin/env bash
# A clean Debian 12 root for the package tests (tools/pkg/ci.sh) and the first-run measurement: `debootstrap
# --variant=minbase bookworm` from the mirror this machine's apt uses, made once and kept as a tarball in the cache
# directory, so that later runs only unpack it (a few seconds). Needs root (debootstrap, chroot).
# Usage: tools/pkg/base-root.sh DIR        (DIR: created, must not exist; prints the seconds it took)
# Cache: $PHALANX_ROOT_CACHE (default /var/cache/phalanx-ci); delete bookworm-minbase.tar there to rebuild.
set -euo pipefail
dir=${1:?usage: base-root.sh DIR}
[ ! -e "$dir" ] || { echo "base-root: $dir exists" >&2; exit 2; }
cache=${PHALANX_ROOT_CACHE:-/var/cache/phalanx-ci}
tarball=$cache/bookworm-minbase.tar
start=$(date +%s)
if [ ! -s "$tarball" ]; then
  command -v debootstrap >/dev/null || { echo "base-root: debootstrap missing (tools/setup.sh --test)" >&2; exit 2; }
  # The mirror of the first deb.debian.org-style source apt uses (sources.list or deb822 .sources).
  mirror=$(grep -hoE '(URIs:|deb) +https?://[^ ]+/debian/?( |$)' /etc/apt/sources.list /etc/apt/sources.list.d/*.list \
             /etc/apt/sources.list.d/*.sources 2>/dev/null | grep -oE 'https?://[^ ]+' | head -1 || true)
  mirror=${mirror:-http://deb.debian.org/debian}
  mkdir -p "$cache"
  tmp=$(mktemp -d "$cache/debootstrap.XXXXXX")
  echo "base-root: debootstrap bookworm from $mirror (once; cached in $tarball)"
  debootstrap --variant=minbase bookworm "$tmp/root" "$mirror" > "$tmp/log" 2>&1 || { tail -20 "$tmp/log" >&2; exit 1; }
  tar -C "$tmp/root" -cf "$tarball.part" . && mv "$tarball.part" "$tarball"
  rm -rf "$tmp"
fi
mkdir -p "$dir"
tar -C "$dir" -xf "$tarball"
cp /etc/resolv.conf "$dir/etc/resolv.conf" 2>/dev/null || true
echo "base-root: $dir ready in $(( $(date +%s) - start )) s"
