#!/usr/bin/env python3
"""Post-link step of every MCU image: fill in the image-info block's size and CRC and write the .bin and .hex.

The block (common/include/phalanx/image_info.h, 32 bytes at offset 0x200 of the image) is compiled in with its
magic, layout version, device type, board, build id and load address; this step checks those against what the
build says the image is, then sets image_size (bytes of the raw image) and image_crc32 (zlib's CRC-32 of the raw
image with the CRC field read as zero), writes the block back into the ELF (objcopy --update-section) and derives the
.bin and .hex from that ELF, so that all three carry the same block. Fails the build on any mismatch.
  image_info.py --objcopy OBJCOPY --elf E --bin B --hex H --device-type N --board N --build-id 0xHEX
"""
import argparse
import os
import struct
import subprocess
import sys
import tempfile
import zlib

MAGIC = 0x49584850
LAYOUT_VERSION = 1
OFFSET = 0x200
FMT = "<IHHBBHIIIII"  # magic, layout, info_size, device, board, reserved0, build_id, load, size, crc, reserved1
SIZE = struct.calcsize(FMT)
CRC_AT = OFFSET + 24


def crc_of(image):
    """CRC-32 of the image with its CRC field read as zero (what `phalanx flash` recomputes)."""
    return zlib.crc32(image[:CRC_AT] + b"\0\0\0\0" + image[CRC_AT + 4:]) & 0xFFFFFFFF


def main():
    ap = argparse.ArgumentParser()
    for a in ("--objcopy", "--elf", "--bin", "--hex", "--device-type", "--board", "--build-id"):
        ap.add_argument(a, required=True)
    args = ap.parse_args()
    name = os.path.basename(args.elf)

    def fail(why):
        sys.exit(f"image_info.py: {name}: {why}")

    def objcopy(*a):
        r = subprocess.run([args.objcopy, *a], capture_output=True, text=True)
        if r.returncode != 0:
            fail(f"{args.objcopy} {' '.join(a)}: {r.stderr.strip()}")

    objcopy("-O", "binary", args.elf, args.bin)
    image = bytearray(open(args.bin, "rb").read())
    if len(image) < OFFSET + SIZE:
        fail(f"image of {len(image)} bytes has no room for the image-info block at 0x{OFFSET:x}")
    f = list(struct.unpack_from(FMT, image, OFFSET))
    expect = {"magic": (0, MAGIC), "layout version": (1, LAYOUT_VERSION), "info size": (2, SIZE),
              "device type": (3, int(args.device_type, 0)), "board": (4, int(args.board, 0)),
              "build id": (6, int(args.build_id, 0))}
    for what, (i, want) in expect.items():
        if f[i] != want:
            fail(f"image-info {what} is 0x{f[i]:x}, the build says 0x{want:x} (block not at 0x{OFFSET:x}?)")
    f[8] = len(image)
    f[9] = 0
    struct.pack_into(FMT, image, OFFSET, *f)
    f[9] = crc_of(image)
    block = struct.pack(FMT, *f)
    with tempfile.NamedTemporaryFile(suffix=".image_info", delete=False) as t:
        t.write(block)
    try:
        objcopy("--update-section", f".image_info={t.name}", args.elf)
    finally:
        os.unlink(t.name)
    objcopy("-O", "binary", args.elf, args.bin)
    objcopy("-O", "ihex", args.elf, args.hex)
    final = open(args.bin, "rb").read()
    if len(final) != f[8] or final[OFFSET:OFFSET + SIZE] != block or crc_of(final) != f[9]:
        fail("the .bin written from the updated ELF does not carry the block just computed")
    print(f"{name}: image-info device {f[3]} board {f[4]} build {f[6]:08x} at 0x{f[7]:08x}, "
          f"{f[8]} bytes, crc32 {f[9]:08x}")


if __name__ == "__main__":
    main()
