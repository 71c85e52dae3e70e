#!/usr/bin/env python3
"""Receive throughput of the UART models of QEMU's Cortex-M4 boards (docs/firmware-mcu.md, "The emulated UART's
throughput"). Builds the probe guest (probe.cpp) for each board, floods its link UART from the host for a few
seconds (optionally while the guest sends 70 bytes per 1 ms tick back, like the firmware's telemetry) and prints the
bytes per second the guest received, per QEMU machine, chardev backend and UART configuration.

  python3 tools/mcu/uart_probe/uart_throughput.py [--seconds 3] [--only mps2-an386]

QEMU runs under SCHED_FIFO like the session tests when permitted (PHALANX_QEMU_RT_PRIORITY=0: default scheduler).
"""
import argparse
import os
import re
import select
import socket
import subprocess
import sys
import threading
import time
import tty

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", "..", ".."))
OUT = os.path.join(ROOT, "build", "mcu-uart-probe")
sys.path.insert(0, os.path.dirname(HERE))
import qemu_board  # noqa: E402  (realtime_prefix)

# board define -> (QEMU machine, code origin, data origin)
BOARDS = {"BOARD_MPS2": ("mps2-an386", 0x00000000, 0x20000000),
          "BOARD_STM32": ("netduinoplus2", 0x08000000, 0x20000000),
          "BOARD_AST": ("ast1030-evb", 0x00000000, 0x00080000)}
CFLAGS = ["-mcpu=cortex-m4", "-mthumb", "-O2", "-ffreestanding", "-nostdlib", "-fno-exceptions", "-fno-rtti",
          "-Wall", "-Wextra", "-Werror"]


def build(board, txload, trig=None):
    machine, code, data = BOARDS[board]
    os.makedirs(OUT, exist_ok=True)
    name = f"{machine}-tx{txload}" + (f"-trig{trig}" if trig is not None else "")
    ld = os.path.join(OUT, f"{machine}.ld")
    with open(ld, "w") as f:
        f.write(f"MEMORY {{ CODE (rwx) : ORIGIN = {code:#x}, LENGTH = 256K  DATA (rwx) : ORIGIN = {data:#x}, "
                "LENGTH = 64K }\nSECTIONS {\n  .text : { KEEP(*(.vectors)) *(.text*) *(.rodata*) } > CODE\n"
                "  .bss (NOLOAD) : { *(.bss*) *(COMMON) . = ALIGN(8); . += 4096; __stack_top__ = .; } > DATA\n}\n")
    elf = os.path.join(OUT, name + ".elf")
    defs = [f"-D{board}=1", f"-DTXLOAD={txload}"] + \
           ([f"-DFCRTRIG={trig}u"] if trig is not None else [])
    subprocess.run(["arm-none-eabi-g++"] + CFLAGS + defs + ["-T", ld, os.path.join(HERE, "probe.cpp"), "-o", elf],
                   check=True)
    return machine, elf


def measure(machine, elf, backend, seconds, extra=()):
    link = {"pty": ["-serial", "pty"],
            "socket": ["-chardev", f"socket,id=l,path={OUT}/l.sock,server=on,wait=off", "-serial", "chardev:l"],
            "pipe": ["-chardev", f"pipe,id=l,path={OUT}/l", "-serial", "chardev:l"]}[backend]
    if backend == "pipe":
        for s in ("in", "out"):
            if not os.path.exists(f"{OUT}/l.{s}"):
                os.mkfifo(f"{OUT}/l.{s}")
    args = qemu_board.realtime_prefix() + ["qemu-system-arm", "-M", machine, "-nographic", "-monitor", "none"] + \
        link + ["-serial", "stdio"] + list(extra) + ["-kernel", elf]
    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, text=True)
    lines = []
    threading.Thread(target=lambda: [lines.append((time.monotonic(), ln.strip())) for ln in p.stdout],
                     daemon=True).start()
    deadline = time.monotonic() + 10
    while not any("BOOT probe" in ln for _, ln in lines) and time.monotonic() < deadline:
        time.sleep(0.05)
    if backend == "pty":
        pty = next(m.group(1) for _, ln in lines for m in [re.search(r"(/dev/pts/\d+)", ln)] if m)
        wfd = rfd = os.open(pty, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(wfd)
    elif backend == "socket":
        s = socket.socket(socket.AF_UNIX)
        s.connect(f"{OUT}/l.sock")
        wfd = rfd = s.fileno()
    else:
        wfd = os.open(f"{OUT}/l.in", os.O_WRONLY)
        rfd = os.open(f"{OUT}/l.out", os.O_RDONLY | os.O_NONBLOCK)
    os.set_blocking(wfd, False)
    os.set_blocking(rfd, False)
    data = b"\xAA" * 4096
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        r, w, _ = select.select([rfd], [wfd], [], 0.05)
        try:
            if rfd in r:
                os.read(rfd, 65536)
            if wfd in w:
                os.write(wfd, data)
        except BlockingIOError:
            pass
    p.terminate()
    p.wait()
    t = [(tm, list(map(int, ln.split()[1:4]))) for tm, ln in lines if ln.startswith("T ")]
    if len(t) < 3:
        return None
    (ta, a), (tb, b) = t[1], t[-1]
    return {"rx_kBps": (b[1] - a[1]) / (tb - ta) / 1000, "tx_kBps": (b[2] - a[2]) / (tb - ta) / 1000,
            "guest_ms_per_wall_ms": (b[0] - a[0]) / 1000 / (tb - ta)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=3)
    ap.add_argument("--only", default=None, help="one QEMU machine")
    a = ap.parse_args()
    runs = []
    for tx in (0, 70):
        runs.append(("BOARD_MPS2", tx, None, "pty", ()))
    runs += [("BOARD_MPS2", 70, None, "socket", ()), ("BOARD_MPS2", 70, None, "pipe", ()),
             ("BOARD_MPS2", 70, None, "pty", ("-icount", "shift=2")),
             ("BOARD_STM32", 0, None, "pty", ()), ("BOARD_STM32", 70, None, "pty", ())]
    runs += [("BOARD_AST", 70, trig, "pty", ()) for trig in (0, 1, 2, 3)]
    print(f"{'machine':14s} {'backend':7s} {'UART setting':22s} {'TX/ms':>5s} {'RX kB/s':>8s} {'TX kB/s':>8s} "
          f"{'guest ms/wall ms':>16s}")
    for board, tx, trig, backend, extra in runs:
        machine, elf = build(board, tx, trig)
        if a.only and machine != a.only:
            continue
        r = measure(machine, elf, backend, a.seconds, extra)
        setting = ({"BOARD_MPS2": "CMSDK, 1-byte RX", "BOARD_STM32": "STM32 USART, 1-byte DR"}[board]
                   if trig is None else f"16550 FIFO trigger {(1, 4, 8, 14)[trig]}") + (" icount2" if extra else "")
        if r is None:
            print(f"{machine:14s} {backend:7s} {setting:22s} no result")
            continue
        print(f"{machine:14s} {backend:7s} {setting:22s} {tx:5d} {r['rx_kBps']:8.1f} {r['tx_kBps']:8.1f} "
              f"{r['guest_ms_per_wall_ms']:16.2f}", flush=True)


if __name__ == "__main__":
    main()
