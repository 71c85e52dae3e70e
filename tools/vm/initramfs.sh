#!/usr/bin/env bash
# Build the VM lane's initramfs from Debian's kernel package (tools/vm/kernel.sh): static busybox, the .ko files
# of the modules below with their dependencies, and tools/vm/init. Idempotent: rebuilt only when this script,
# the init or the kernel changed. Prints the path of the gzip'ed cpio archive on stdout.
# Usage: tools/vm/initramfs.sh KERNEL_VERSION
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
KV="$1"
CACHE="$ROOT/build/vm"
KROOT="$CACHE/kroot-$KV"
OUT="$CACHE/initramfs-$KV.cpio.gz"
# 9p (host root and repository), CAN (vcan, vxcan pairs, raw sockets), configfs (gadgets, gpio-sim), veth and
# netem (the teleoperation test's two namespaces and their delay).
MODULES=(virtio_pci 9pnet_virtio 9p vcan vxcan can-raw can-bcm configfs veth sch_netem)

EXTRA="$CACHE/extra-modules/$KV"
stamp=$({ cat "$0" "$ROOT/tools/vm/init" "$EXTRA"/extra.load "$EXTRA"/*.ko 2>/dev/null || true; } | sha256sum | cut -c1-16)
if [ -f "$OUT" ] && [ "$(cat "$OUT.stamp" 2>/dev/null)" = "$stamp" ]; then
  echo "$OUT"; exit 0
fi
BUSYBOX=$(command -v busybox || true)
[ -n "$BUSYBOX" ] && file -L "$BUSYBOX" 2>/dev/null | grep -q 'statically linked' || BUSYBOX=/bin/busybox
[ -x "$BUSYBOX" ] || { echo "initramfs.sh: static busybox missing (tools/setup.sh installs busybox-static)" >&2; exit 1; }

STAGE=$(mktemp -d "$CACHE/initramfs.XXXXXX")
trap 'rm -rf "$STAGE"' EXIT
mkdir -p "$STAGE"/{bin,sbin,etc,proc,sys,dev,tmp,mnt,run,usr/bin,usr/sbin,lib/modules/$KV}
cp "$BUSYBOX" "$STAGE/bin/busybox"
: > "$STAGE/etc/modules.load"
for m in "${MODULES[@]}"; do
  # modprobe prints the insmod lines in load order (dependencies first); builtin modules print nothing.
  modprobe -d "$KROOT" -S "$KV" --show-depends "$m" | awk '$1=="insmod"{print $2}' | while read -r ko; do
    rel=${ko#"$KROOT"}
    mkdir -p "$STAGE$(dirname "$rel")"
    cp "$ko" "$STAGE$rel"
    grep -qxF "$rel" "$STAGE/etc/modules.load" || echo "$rel" >> "$STAGE/etc/modules.load"
  done
done
# Out-of-tree modules built by the lane (e.g. gpio-sim) are appended by their build script via extra.load.
if [ -f "$EXTRA/extra.load" ]; then
  while read -r ko; do
    mkdir -p "$STAGE/lib/modules/$KV/extra"; cp "$EXTRA/$ko" "$STAGE/lib/modules/$KV/extra/"
    echo "/lib/modules/$KV/extra/$ko" >> "$STAGE/etc/modules.load"
  done < "$EXTRA/extra.load"
fi
for f in modules.order modules.builtin modules.builtin.modinfo; do cp "$KROOT/lib/modules/$KV/$f" "$STAGE/lib/modules/$KV/"; done
depmod -b "$STAGE" "$KV"
install -m 0755 "$ROOT/tools/vm/init" "$STAGE/init"
# Applet links last, and only where no file exists.
for applet in $("$STAGE/bin/busybox" --list-full); do
  [ -e "$STAGE/$applet" ] || { mkdir -p "$STAGE/$(dirname "$applet")"; ln -s /bin/busybox "$STAGE/$applet"; }
done
(cd "$STAGE" && find . | LC_ALL=C sort | cpio -o -H newc --quiet | gzip -1) > "$OUT.tmp"
mv "$OUT.tmp" "$OUT"
echo "$stamp" > "$OUT.stamp"
echo "$OUT"
