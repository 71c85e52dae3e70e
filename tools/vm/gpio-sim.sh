#!/usr/bin/env bash
# Build the gpio-sim kernel module out of tree for the VM lane's kernel (Debian's kernel does not build
# CONFIG_GPIO_SIM). Sources: drivers/gpio/gpio-sim.c, drivers/gpio/gpiolib.h and kernel/irq/irq_sim.c from Debian's
# linux-source-6.1 package (irq_sim is not built into Debian's kernel either, so it is linked into the module),
# patched by tools/vm/gpio-sim.patch (irq_to_desc() is not exported: generic_handle_irq() instead; a "wire"
# parameter joining an output line to an input line, docs/gpio.md). Built against linux-headers-$KV.
# Cached: rebuilt only when this script, the patch or the kernel version change. On success the module is
# build/vm/extra-modules/$KV/gpio-sim.ko and is listed in extra.load (tools/vm/initramfs.sh loads it at boot).
# Usage: tools/vm/gpio-sim.sh KERNEL_VERSION      (packages: tools/setup.sh installs linux-source-6.1 and
#        linux-headers-amd64; for another kernel version: bash tools/setup.sh linux-headers-$KV)
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
KV="$1"
CACHE="$ROOT/build/vm"
EXTRA="$CACHE/extra-modules/$KV"
KO="$EXTRA/gpio-sim.ko"
HEADERS="/usr/src/linux-headers-$KV"
SRC_TAR=/usr/src/linux-source-6.1.tar.xz
PATCH="$ROOT/tools/vm/gpio-sim.patch"

[ -d "$HEADERS" ] || { echo "gpio-sim.sh: $HEADERS missing: bash tools/setup.sh linux-headers-$KV" >&2; exit 1; }
[ -f "$SRC_TAR" ] || { echo "gpio-sim.sh: $SRC_TAR missing: bash tools/setup.sh linux-source-6.1" >&2; exit 1; }
# The driver reaches into gpiolib's private structures (gpiolib.h): its source must be the booted kernel's.
src_ver=$(dpkg-query -W -f '${Version}' linux-source-6.1)
hdr_ver=$(dpkg-query -W -f '${Version}' "linux-headers-$KV" 2>/dev/null || echo none)
# The image's changelog starts "linux-signed-amd64 (6.1.192+2) ...": its upstream part must match.
img_ver=""
cl="$CACHE/kroot-$KV/usr/share/doc/linux-image-$KV/changelog.gz"
[ -f "$cl" ] && img_ver=$( (zcat "$cl" || true) | sed -n '1s/^[^(]*(\([^)]*\)).*/\1/p')
upstream() { echo "$1" | sed 's/[-+].*//'; }
if [ "$(upstream "$src_ver")" != "$(upstream "$hdr_ver")" ] || { [ -n "$img_ver" ] && [ "$(upstream "$src_ver")" != "$(upstream "$img_ver")" ]; }; then
  echo "gpio-sim.sh: version mismatch: linux-source-6.1 $src_ver, linux-headers-$KV $hdr_ver, kernel image ${img_ver:-?}" >&2
  echo "gpio-sim.sh: update both: bash tools/setup.sh linux-source-6.1 linux-headers-$KV" >&2
  exit 1
fi

stamp=$({ cat "$0" "$PATCH"; echo "$KV $src_ver $hdr_ver"; } | sha256sum | cut -c1-16)
if [ -f "$KO" ] && [ "$(cat "$KO.stamp" 2>/dev/null)" = "$stamp" ]; then
  exit 0
fi
WORK="$CACHE/gpio-sim-build"
rm -rf "$WORK"
mkdir -p "$WORK" "$EXTRA"
echo "gpio-sim.sh: extracting gpio-sim from $SRC_TAR ($src_ver)" >&2
tar -xJf "$SRC_TAR" -C "$WORK" --strip-components=1 linux-source-6.1/drivers/gpio/gpio-sim.c \
  linux-source-6.1/drivers/gpio/gpiolib.h linux-source-6.1/kernel/irq/irq_sim.c
(cd "$WORK" && patch -s -p1 < "$PATCH")
# One module from two objects: the driver (renamed so the module can keep the name gpio-sim) and irq_sim.
mv "$WORK/drivers/gpio/gpio-sim.c" "$WORK/drivers/gpio/gpio-sim-drv.c"
cp "$WORK/kernel/irq/irq_sim.c" "$WORK/drivers/gpio/"
cat > "$WORK/drivers/gpio/Kbuild" <<'KBUILD'
obj-m := gpio-sim.o
gpio-sim-y := gpio-sim-drv.o irq_sim.o
KBUILD
echo "gpio-sim.sh: building against $HEADERS" >&2
make -s -C "$HEADERS" M="$WORK/drivers/gpio" modules >&2
cp "$WORK/drivers/gpio/gpio-sim.ko" "$KO"
grep -qxF gpio-sim.ko "$EXTRA/extra.load" 2>/dev/null || echo gpio-sim.ko >> "$EXTRA/extra.load"
echo "$stamp" > "$KO.stamp"
rm -rf "$WORK"
echo "gpio-sim.sh: built $KO" >&2
