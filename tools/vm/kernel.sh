#!/usr/bin/env bash
# Fetch Debian's kernel package (download and unpack only: installing linux-image-* would pull in
# initramfs-tools and rewrite the host's boot files) and index its modules. Idempotent: cached in build/vm/.
# Prints the kernel version (e.g. 6.1.0-56-amd64) on stdout; logs go to stderr.
# Usage: tools/vm/kernel.sh
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
CACHE="$ROOT/build/vm"
mkdir -p "$CACHE"

# The package the linux-image-amd64 metapackage points at now; fall back to what is cached when apt knows nothing.
KPKG=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/{print $2; exit}' || true)
if [ -z "$KPKG" ]; then
  cached=$(ls -d "$CACHE"/kroot-* 2>/dev/null | tail -1 || true)
  [ -n "$cached" ] || { echo "kernel.sh: apt-cache knows no linux-image-amd64 and nothing is cached" >&2; exit 1; }
  basename "$cached" | sed 's/^kroot-//'
  exit 0
fi
KV=${KPKG#linux-image-}
KROOT="$CACHE/kroot-$KV"
if [ ! -f "$KROOT/.complete" ]; then
  echo "kernel.sh: fetching $KPKG (apt-get download, not install)" >&2
  rm -rf "$KROOT" "$CACHE/deb"
  mkdir -p "$CACHE/deb"
  (cd "$CACHE/deb" && apt-get download "$KPKG" >&2)
  dpkg-deb -x "$CACHE"/deb/"${KPKG}"_*.deb "$KROOT"
  depmod -b "$KROOT" "$KV"
  rm -rf "$CACHE/deb"
  touch "$KROOT/.complete"
fi
echo "$KV"
