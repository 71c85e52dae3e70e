#!/usr/bin/env python3
"""Run the Phalanx firmware image for the emulated Cortex-M4F board (QEMU mps2-an386) and drive it with the host
daemon over a pseudo-terminal, exactly as a real board on a serial port.

  qemu_board.py session   -- the CI check: handshake + several-second 1 kHz session with `phalanx run`, then the
                             daemon killed with SIGKILL: the firmware must report its outputs safe (debug console)
                             within two ticks of the command deadline, and a reconnecting session must see the
                             latched command-timeout in the telemetry fault bits.
  qemu_board.py bench     -- the cycle benchmark: the same session under `-icount shift=N` (deterministic
                             instruction counting); prints the control tick's worst case and median in instructions.
  qemu_board.py run       -- start the board and print the pty path (for manual use with phalanxd).
  qemu_board.py flash     -- `phalanx flash` through QEMU's gdbstub into a blank board (no image loaded, core
                             halted): wrong-device, wrong-board and corrupt images are refused with nothing written;
                             the good image is written and the board answers the handshake with its build id.
  qemu_board.py blank     -- start a blank board waiting for a debugger (print its pty and gdbstub port).
  qemu_board.py settings  -- the board's settings flash kept in a host file (semihosting): `phalanx param set --save`
                             over the link, QEMU restarted (a power cycle), the saved value read back; twice, so
                             both pages of the store are written.
  qemu_board.py plan      -- a bench plan in real time on the emulated SEA rig board (docs/bench-runner.md): the
                             board writes its load cell's true torque on its instrument UART, this script serves it
                             as a Modbus TCP amplifier (pymodbus), and `phalanx bench run` drives the board over its
                             link and polls the amplifier, as on a lab's bench.

The protocol link is the CMSDK UART0 exposed with `-serial pty`; the debug console (UART1) is QEMU's stdout.
QEMU's CMSDK UART model takes one received byte per guest read (docs/firmware-mcu.md: about 25-30 kB/s), so the
host loop runs at 100 Hz (the daemon's minimum) here while the firmware ticks and sends telemetry at 1 kHz. QEMU
runs under SCHED_FIFO when permitted (realtime_prefix below).
"""
import argparse
import json
import os
import re
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import zlib

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
APPS = ("glove5", "sea_finger", "pantograph")
# Default plant period of session/run (ms between plant steps, docs/firmware-mcu.md "The simulated plant on the
# emulated board"): the glove and pen plants capped near the rate they reach, the SEA plant every millisecond.
SESSION_PLANT_PERIOD_MS = {"glove5": 1, "sea_finger": 1, "pantograph": 8}


# Emulated boards: QEMU machine -> (build directory, image name prefix). Both take the link UART as the first
# -serial and the debug console as the second (docs/firmware-mcu.md "Emulated boards").
BOARDS = {"mps2-an386": ("mcu-mps2-an386", "phalanx-mps2_an386"), "ast1030-evb": ("mcu-ast1030", "phalanx-ast1030")}


def app_elf(app, board="mps2-an386"):
    build, prefix = BOARDS[board]
    return os.path.join(ROOT, "build", build, f"{prefix}-{app}.elf")
BIN = os.path.join(ROOT, "build", "host", "bin")


# QEMU emulates a 1 kHz real-time device: its main-loop thread (timers, UART bytes) and its vCPU thread wake each
# other thousands of times a second, and each wake-up must come within a fraction of a millisecond. Under the
# default scheduler on a loaded 2-core machine (load 10-12 from other builds and VMs) a wake-up waits milliseconds
# for a time slice: SysTick expiries coalesce (the firmware's clock ran at 0.5x wall time) and received bytes queue
# in the pty (command round trip 0.5-2 s). So QEMU runs under SCHED_FIFO (docs/firmware-mcu.md, "Real-time
# scheduling of the emulator"; nice -15 did not help). PHALANX_QEMU_RT_PRIORITY=0 turns it off.
RT_PRIORITY = int(os.environ.get("PHALANX_QEMU_RT_PRIORITY", "10"))
_rt_prefix = None


def realtime_prefix():
    """`chrt -f N` if this process may use SCHED_FIFO (root or CAP_SYS_NICE), else nothing (with a warning)."""
    global _rt_prefix
    if _rt_prefix is None:
        _rt_prefix = []
        if RT_PRIORITY > 0:
            try:
                ok = subprocess.run(["chrt", "-f", str(RT_PRIORITY), "true"], capture_output=True).returncode == 0
            except FileNotFoundError:
                ok = False
            if ok:
                _rt_prefix = ["chrt", "-f", str(RT_PRIORITY)]
            else:
                print(f"WARNING: cannot run QEMU under SCHED_FIFO {RT_PRIORITY} (needs CAP_SYS_NICE): the emulated "
                      "board keeps real time only on a lightly loaded machine", file=sys.stderr)
    return _rt_prefix


class Board:
    """One QEMU process; collects its stdout (debug console + QEMU's own messages) in a background thread."""

    def __init__(self, elf, seconds=0, icount=None, extra=(), machine="mps2-an386", gdb_port=None, instrument=False):
        # UART0 (the protocol link) on a pty, UART1 (debug console) on stdout; semihosting only for the
        # command line and the exit status. elf=None with a gdb_port: a blank board (nothing loaded; the core
        # halted until a debugger lets it run: -S), the image to be written through the gdbstub (`phalanx flash`).
        # instrument: the board's instrument UART (the third -serial) on a pty of its own (self.instrument_pty).
        args = ["qemu-system-arm", "-M", machine, "-nographic", "-monitor", "none",
                "-serial", "pty", "-serial", "stdio"] + (["-serial", "pty"] if instrument else [])
        if instrument:
            extra = list(extra) + ["instrument=1"]
        if gdb_port is not None:
            args += ["-gdb", f"tcp:127.0.0.1:{gdb_port}"] + (["-S"] if elf is None else [])
        sh = ["enable=on", "target=native", "arg=fw", f"arg=seconds={seconds}"] + [f"arg={e}" for e in extra]
        if icount is not None:
            args += ["-icount", f"shift={icount}"]
            sh.append(f"arg=icount_shift={icount}")
        args += ["-semihosting-config", ",".join(sh)]
        if elf is not None:
            args += ["-kernel", elf]
        args = realtime_prefix() + args
        self.cmd = args
        self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, bufsize=1)
        self.lines = []
        self.lock = threading.Lock()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()
        self.pty = self.instrument_pty = None
        m = self.wait_for(r"char device redirected to (/dev/pts/\d+) \(label serial0\)", 10)
        if m:
            self.pty = m.group(1)
        if instrument:
            m = self.wait_for(r"char device redirected to (/dev/pts/\d+) \(label serial2\)", 10)
            self.instrument_pty = m.group(1) if m else None
        if elf is not None and not self.wait_for(r"^BOOT ", 30):
            raise RuntimeError("firmware did not boot:\n" + self.text())

    def _read(self):
        for line in self.proc.stdout:
            with self.lock:
                self.lines.append(line.rstrip("\n"))

    def text(self):
        with self.lock:
            return "\n".join(self.lines)

    def wait_for(self, pattern, timeout_s, start=0):
        rx = re.compile(pattern)
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            with self.lock:
                for line in self.lines[start:]:
                    m = rx.search(line)
                    if m:
                        return m
            if self.proc.poll() is not None and not self.reader.is_alive():
                break
            time.sleep(0.02)
        return None

    def line_count(self):
        with self.lock:
            return len(self.lines)

    def stop(self):
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.reader.join(2)


# Each command's own timeout. 200 ms rides out the emulator's stalls on a loaded 2-core machine (QEMU's main loop
# and vCPU threads compete with the host daemon and any parallel build); the watchdog check below measures the
# device's reaction relative to the deadline, whatever its length.
COMMAND_TIMEOUT_MS = 200


HOST_REALTIME = False  # --host-realtime: the host tools in their own real-time mode (SCHED_FIFO 80, mlockall)


def relaxed_hand(args):
    """The glove's simulated hand for the session and bench tests: still and relaxed. The board's plant runs from
    boot, seconds before the first session, with the glove's worm locked; in the grasp scenario (the board's
    default) the hand has by then closed onto the pads at about 5 N, the firmware refuses that loaded tare
    (glove5_param::kTare) and the glove then pushes against a clenched fist until current-limit latches
    (docs/glove-firmware.md). These tests are about the link, the watchdog and the tick, not that start."""
    return ["scenario=still"] if args.app == "glove5" else []


def host_scene(args):
    """The host's glove scene for these tests: none. The emulated plant computes 0.55-0.70 of real time during a
    session, and a still hand resting in the rendered rigid ball then latched current-limit on ast1030-evb at 1 kHz
    (CI, 2026-11-24): contact rendering against a plant in slow motion, which firmware-sim in real time does not show
    (docs/firmware-mcu.md). The link, watchdog and tick checks need no contact."""
    return ["--scene", "none"] if args.app == "glove5" else []


def host_rt_args():
    return [] if HOST_REALTIME else ["--no-realtime"]


def run_phalanx(pty, seconds, rate_hz, timeout_s, command_timeout_ms=COMMAND_TIMEOUT_MS, extra=()):
    cmd = [os.path.join(BIN, "phalanx"), "run", "--device", f"serial:{pty}", "--seconds", str(seconds),
           "--rate-hz", str(rate_hz), "--command-timeout-ms", str(command_timeout_ms), "--json"] + host_rt_args() + list(extra)
    r = subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=timeout_s)
    try:
        summary = json.loads(r.stdout) if r.stdout.strip() else {}
    except json.JSONDecodeError:
        summary = {"unparsed_stdout": r.stdout}
    return r.returncode, summary, r.stderr


class Checks:
    def __init__(self):
        self.passed = 0
        self.failed = 0

    def check(self, ok, what, detail=""):
        if ok:
            self.passed += 1
            print(f"  ok   {what}")
        else:
            self.failed += 1
            print(f"  FAIL {what} {detail}")
        return ok


def parse_kv(line):
    return {k: v for k, v in re.findall(r"(\w+)=(\S+)", line)}


def unsent_by_device(board, mark):
    """Frames the firmware could not send during the first session after line `mark`: the difference of the
    tx_dropped counts its SESSION lines report at that session's start and the next one's (None without both)."""
    counts = [int(m.group(1)) for m in re.finditer(r"^SESSION opened .*tx_dropped=(\d+)", "\n".join(
        board.text().splitlines()[mark:]), re.M)]
    return counts[1] - counts[0] if len(counts) >= 2 else None


def session(args):
    c = Checks()
    board = Board(args.elf, extra=[f"plant_period_ms={args.plant_period_ms}"] + relaxed_hand(args) + args.extra,
                  machine=args.board)
    try:
        print(f"board up: pty={board.pty}; {board.wait_for(r'^BOOT .*', 1).group(0)}")
        c.check(board.pty is not None, "QEMU exposed the protocol link as a pty")
        run_mark = board.line_count()
        rc, s, err = run_phalanx(board.pty, args.seconds, args.rate_hz, args.seconds + 30, extra=host_scene(args))
        expected_cycles = int(args.seconds * args.rate_hz)
        print(f"phalanx run: rc={rc} cycles={s.get('cycles')} telemetry={s.get('telemetry')} "
              f"commands={s.get('commands')} rtt={s.get('round_trip', {}).get('p50_us')}us "
              f"faults_seen={s.get('faults_seen')} final_mode={s.get('final_mode')}")
        c.check(rc == 0, "handshake and session completed (phalanx run exit 0)", err.strip()[-400:])
        c.check(s.get("device_type") == args.app, f"device answered the handshake as {args.app}", s.get("device_type"))
        c.check(s.get("firmware_tick_hz") == 1000, "firmware reports a 1 kHz tick", s.get("firmware_tick_hz"))
        c.check(s.get("cycles", 0) >= expected_cycles - 10, f"host ran {expected_cycles} cycles at {args.rate_hz} Hz",
                s.get("cycles"))
        tel = s.get("telemetry", {})
        # The device numbers one telemetry frame per 1 kHz tick; the host counts gaps in that sequence (checked
        # below, once the firmware's own count of frames it could not send is known).
        c.check(tel.get("received", 0) + tel.get("lost", 0) >= 0.8 * args.seconds * 1000,
                "telemetry numbered at ~1 kHz", tel)
        c.check(s.get("faults_seen") == "none", "no fault during the session", s.get("faults_seen"))
        # Round trip is reported, not judged: it measures the emulated UART's queueing (see the module doc).
        cmds = s.get("commands", {})
        c.check(cmds.get("rejected_by_device", 1) == 0, "device rejected no command", cmds)
        c.check(cmds.get("lost_seen_by_device", 1) == 0, "device saw no gap in the command sequence", cmds)
        c.check(cmds.get("unsent_link_full", 1) == 0, "host never found the link full", cmds)
        rx = s.get("host_rx_errors", {})
        c.check(rx.get("crc", 1) == 0 and rx.get("framing", 1) == 0, "no CRC or framing error on the host", rx)

        if args.kill_test:
            start_mark = board.line_count()
            daemon = subprocess.Popen([os.path.join(BIN, "phalanxd"), "--device", f"serial:{board.pty}",
                                       "--rate-hz", str(args.rate_hz), "--command-timeout-ms", str(COMMAND_TIMEOUT_MS)]
                                      + host_rt_args() + host_scene(args), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.PIPE, text=True)
            # Kill only once the device reports its power stage driven by this daemon's commands, and after a
            # while of steady commanding.
            active = board.wait_for(r"^ACTIVE ", 15, start=start_mark) is not None
            time.sleep(1.5)
            alive = daemon.poll() is None
            c.check(alive and active, "phalanxd drives the device (outputs active)",
                    "" if alive else daemon.stderr.read()[-400:])
            mark = board.line_count()  # only what the device reports after the kill counts
            daemon.send_signal(signal.SIGKILL)
            daemon.wait()
            # Commands the daemon wrote before dying may still be queued in the pty; the device goes safe one
            # command timeout after the last of them, so allow for the queue to drain.
            m = board.wait_for(r"^SAFE .*", 15, start=mark)
            c.check(m is not None, "firmware reported its outputs safe after the daemon was killed")
            if m is None:  # what the board said while phalanxd drove it (a fault latched before the kill?)
                print("\n".join("  board: " + l for l in board.text().splitlines()[start_mark:][-12:]))
            if m:
                kv = parse_kv(m.group(0))
                t_us, dl_us, per_us = int(kv["t_us"]), int(kv["deadline_us"]), int(kv["period_us"])
                faults = int(kv["faults"], 16)
                print(f"  device: {m.group(0)}")
                c.check(t_us > dl_us, "safe state came from the command watchdog (after the deadline)")
                c.check(t_us - dl_us <= 2 * per_us, "safe within two ticks of the command deadline",
                        f"{t_us - dl_us} us")
                c.check(faults & 0x1, "command-timeout fault latched on the device", hex(faults))
                # How much of the session's physics the plant computed: steps per (firmware ms / plant period).
                if "plant_steps" in kv:
                    due = int(kv["ms"]) / args.plant_period_ms
                    share = int(kv["plant_steps"]) / due if due > 0 else 0.0
                    print(f"  plant: {kv['plant_steps']} steps in {kv['ms']} firmware ms at a {args.plant_period_ms} ms "
                          f"period ({share:.3f} of real time, plant_ms={kv['plant_ms']})")
                    if args.require_plant_realtime:
                        c.check(share >= 0.95, "the plant kept real time (>= 95 % of its steps computed)",
                                f"{share:.3f}")
            # Reconnect: the latched fault is visible in the telemetry fault bits before the host clears it.
            rc2, s2, err2 = run_phalanx(board.pty, 1, args.rate_hz, 30, extra=host_scene(args))
            print(f"reconnect: rc={rc2} faults_at_start={s2.get('faults_at_start')}")
            c.check(rc2 == 0 and "command-timeout" in str(s2.get("faults_at_start", "")),
                    "reconnecting host reads the latched command-timeout in telemetry", err2.strip()[-300:])
        # A telemetry gap is a frame lost on the link, or one the firmware could not queue because its transmit
        # ring was full (the emulated UART or the host fell behind on a loaded machine; the emulator did not keep
        # real time): the firmware counts those, and reports the count since boot at each session's start.
        unsent = unsent_by_device(board, run_mark)
        if unsent:
            print(f"  note: the firmware could not send {unsent} frames during the session (its transmit ring was "
                  "full: the emulated UART or the host did not keep real time)")
        c.check(tel.get("lost", 1) <= (unsent or 0),
                "no telemetry frame lost on the link (a gap only where the firmware counted a frame it could not send)",
                f"{tel} unsent_by_device={unsent}")
    finally:
        board.stop()
    print(f"qemu session {args.app}: {c.passed} passed, {c.failed} failed")
    return 0 if c.failed == 0 else 1


DIAG_MARGIN_S = 6


def bench(args):
    plant_period_ms = args.plant_period_ms if args.plant_period_ms_given else 1
    # The firmware stops (STATS line) DIAG_MARGIN_S after the host session's length: the protocol read below must
    # get its own handshake in before that. 3 s was not always enough (CI, load 12: the session ran 3.8 s of device
    # time for 3 s, and QEMU 7.2's pty backend, as we read char-pty.c, re-checks for a client about once a second
    # after the previous one closed).
    board = Board(args.elf, seconds=args.seconds + DIAG_MARGIN_S, icount=args.shift,
                  extra=[f"plant_period_ms={plant_period_ms}"] + relaxed_hand(args) + args.extra, machine=args.board)
    try:
        boot = parse_kv(board.wait_for(r"^BOOT .*", 5).group(0))
        rc, s, err = run_phalanx(board.pty, args.seconds, args.rate_hz, args.seconds * 20 + 60, extra=host_scene(args))
        # The same statistics through the wire protocol (ParamGet 0x0080..), while the firmware still runs.
        d = subprocess.run([os.path.join(BIN, "phalanx"), "mcu-diag", "--device", f"serial:{board.pty}",
                            "--timeout", "10"], stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=120)
        try:
            diag = json.loads(d.stdout) if d.returncode == 0 else {"error": d.stderr.strip()}
        except json.JSONDecodeError:
            diag = {"error": "unparsed: " + d.stdout[-200:]}
        m = board.wait_for(r"^STATS .*", args.seconds * 20 + 60)
    finally:
        board.stop()
    if not m:
        print("no STATS line from the firmware:\n" + board.text())
        return 1
    kv = parse_kv(m.group(0))
    result = {
        "app": args.app,
        "image": os.path.relpath(args.elf, ROOT),
        "qemu": " ".join(board.cmd),
        "ns_per_instruction": int(boot.get("ns_per_insn", 0)),
        "host_rate_hz": args.rate_hz,
        "host_session": {"rc": rc, "cycles": s.get("cycles"), "telemetry": s.get("telemetry"),
                         "commands_sent": s.get("commands", {}).get("sent")},
        "tick_instructions": {"count": int(kv["ticks"]), "worst": int(kv["worst"]), "median": int(kv["median"]),
                              "p99": int(kv["p99"])},
        "budget_instructions": args.budget,
        "commands_applied": int(kv["commands"]),
        "stack_used_bytes": int(kv["stack_used"]),
        "worst_by_receive_work": {"no_bytes": int(kv["worst_no_rx"]), "up_to_one_frame": int(kv["worst_rx_le_frame"]),
                                  "more": int(kv["worst_rx_more"])},
        "overruns": int(kv["overruns"]),
        "plant_period_ms": plant_period_ms,
        "plant_ms_simulated": int(kv["plant_ms"]),
        "plant_steps_computed": int(kv["plant_steps"]),
        "firmware_stats_line": m.group(0),
        "through_protocol": diag,
    }
    print(json.dumps(result, indent=2))
    ok = result["tick_instructions"]["worst"] <= args.budget and result["commands_applied"] > 0
    # The protocol read happens before the firmware's final STATS line: its worst case and tick count can only be
    # smaller or equal, and the unit must be the instruction count the bench was started with.
    dp = diag.get("params", {})
    proto_ok = (diag.get("device_type") == args.app and 0 < dp.get("tick_count", 0) <= result["tick_instructions"]["count"]
                and 0 < dp.get("tick_worst", 0) <= result["tick_instructions"]["worst"]
                and dp.get("tick_unit_ns") == result["ns_per_instruction"] and result["ns_per_instruction"] > 0)
    print(f"through the protocol (phalanx mcu-diag): worst {dp.get('tick_worst')} median {dp.get('tick_median')} "
          f"after {dp.get('tick_count')} ticks, {dp.get('tick_unit_ns')} ns per unit: "
          f"{'consistent' if proto_ok else 'NOT consistent: ' + json.dumps(diag)}")
    ok = ok and proto_ok
    print(f"cycle bench {args.app}: worst {result['tick_instructions']['worst']} / median "
          f"{result['tick_instructions']['median']} instructions per tick (budget {args.budget}): "
          f"{'1 passed, 0 failed' if ok else '0 passed, 1 failed'}")
    return 0 if ok else 1


# ---- flash: `phalanx flash` through QEMU's gdbstub ----------------------------------------------------------------
# The image-info block (common/include/phalanx/image_info.h), read here independently of phalanx's own reader.
INFO_OFFSET = 0x200
INFO_FMT = "<IHHBBHIIIII"
INFO_FIELDS = ("magic", "layout_version", "info_size", "device_type", "board", "reserved0", "build_id", "load_address",
               "image_size", "image_crc32", "reserved1")
CRC_AT = INFO_OFFSET + 24


def image_info(data):
    return dict(zip(INFO_FIELDS, struct.unpack_from(INFO_FMT, data, INFO_OFFSET)))


def with_info(data, **fields):
    """A copy of a raw image with image-info fields replaced and its CRC recomputed (so only those fields differ)."""
    info = image_info(data)
    info.update(fields, image_crc32=0)
    out = bytearray(data)
    struct.pack_into(INFO_FMT, out, INFO_OFFSET, *(info[k] for k in INFO_FIELDS))
    struct.pack_into("<I", out, CRC_AT, zlib.crc32(bytes(out)) & 0xFFFFFFFF)
    return bytes(out)


class Amplifier:
    """The emulated board's load cell as a Modbus TCP amplifier on pymodbus (PyPI), outside the host: reads the
    board's instrument lines ("I <plant_ms> <micro-units>", board_main.cpp) from its pty and serves the newest as
    int32 counts of `scale` SI units, big-endian words, input registers from 0, unit 1 (the bench plans' map).
    Its two threads run under SCHED_FIFO 70 when permitted, as firmware-sim's amplifier does: an amplifier has a CPU
    of its own, and beside a loaded machine's other work pymodbus answered too late for 5.8 % of a plan's polls
    (50 ms timeout)."""

    def __init__(self, pty, scale=1e-5):
        import termios
        import tty
        self.scale = scale
        self.counts = 0
        self.lines = 0
        self.bad = 0
        self.fd = os.open(pty, os.O_RDONLY | os.O_NOCTTY)
        tty.setraw(self.fd, termios.TCSANOW)
        threading.Thread(target=self._read, daemon=True).start()
        self.port = free_port()
        threading.Thread(target=self._serve, daemon=True).start()
        for _ in range(250):  # until it accepts connections
            time.sleep(0.02)
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=0.2):
                    return
            except OSError:
                continue
        raise RuntimeError("the amplifier did not start listening")

    @staticmethod
    def _realtime():
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(70))  # this thread only
        except (PermissionError, OSError):
            pass

    def _read(self):
        self._realtime()
        buf = b""
        synced = False
        while True:
            try:
                chunk = os.read(self.fd, 4096)
            except OSError:
                return
            if not chunk:
                return
            buf += chunk
            *whole, buf = buf.split(b"\n")
            if not synced and whole:
                # The pty delivers from when it was opened, perhaps mid-line: the first piece is not a line.
                whole, synced = whole[1:], True
            for line in whole:
                f = line.split()
                if len(f) == 3 and f[0] == b"I":
                    self.counts = round(int(f[2]) * 1e-6 / self.scale)
                    self.lines += 1
                else:
                    self.bad += 1

    def _serve(self):
        self._realtime()
        import asyncio
        from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
        from pymodbus.server import StartAsyncTcpServer
        amp = self

        class Block(ModbusSequentialDataBlock):
            def __init__(self):
                super().__init__(1, [0] * 4)  # pymodbus numbers registers from 1 (PDU address 0 is its 1)

            def getValues(self, address, count=1):
                c = amp.counts & 0xFFFFFFFF
                return [c >> 16, c & 0xFFFF, 0, 0][address - 1:address - 1 + count]

        context = ModbusServerContext(slaves={1: ModbusSlaveContext(ir=Block(), hr=Block())}, single=False)
        asyncio.run(StartAsyncTcpServer(context=context, address=("127.0.0.1", self.port)))


# The device type of the plan each app's emulated board serves an instrument for, and the hand scenario it runs.
PLAN_DEVICE = {"sea_finger": ("sea_rig", []), "glove5": ("glove5", ["scenario=close-open"])}


def plan(args):
    """A bench plan in real time against the emulated board and its amplifier (tests/vm/vmlib.py realtime_bench, as
    the VM lane runs it over CAN and USB): the SEA rig's sine against its load cell, or the glove's free motion
    against the index fingertip's force sensor. Gated: the plan ran through the session runner over the board's
    link, the session ended cleanly, the amplifier served the board's lines and was read. Printed, not gated: the
    limits' verdict and the alignment (an emulator's timing)."""
    sys.path.insert(0, os.path.join(ROOT, "tests", "vm"))
    from vmlib import realtime_bench
    c = Checks()
    if args.app not in PLAN_DEVICE:
        print("plan: the emulated board serves an instrument for the SEA rig and the glove only (--app sea_finger or "
              "glove5; the pen's plant cannot keep real time on the emulated core)", file=sys.stderr)
        return 2
    device_type, scenario = PLAN_DEVICE[args.app]
    board = Board(args.elf, extra=[f"plant_period_ms={args.plant_period_ms}"] + scenario + args.extra,
                  machine=args.board, instrument=True)
    out = tempfile.mkdtemp(prefix="phalanx-qemu-plan-")
    try:
        print(f"board up: pty={board.pty} instrument={board.instrument_pty}; {board.wait_for(r'^BOOT .*', 1).group(0)}")
        c.check(board.instrument_pty is not None, "QEMU exposed the board's instrument UART as a pty")
        amp = Amplifier(board.instrument_pty)
        time.sleep(0.2)
        c.check(amp.lines > 0 and amp.bad == 0, "the board writes its instrument's truth on its instrument UART",
                f"lines={amp.lines} unreadable={amp.bad}")

        def check(ok, why):  # vmlib's convention: why is the failure's description
            if ok:
                c.passed += 1
            else:
                c.check(False, why)

        def fail(why):
            c.check(False, why)
            raise RuntimeError(why)

        line = realtime_bench("qemu-plan", f"serial:{board.pty}", amp.port, BIN, out, check, fail, device_type)
        print(f"RESULT qemu-plan {args.board}: {line} (amplifier: {amp.lines} board lines)")
    except RuntimeError:
        pass
    finally:
        board.stop()
        print(f"  the plan's JSON summary and the runner's stderr: {out}/qemu-plan.*; its report: /tmp/qemu-plan.html")
    print(f"qemu plan {args.app}: {c.passed} passed, {c.failed} failed")
    return 0 if c.failed == 0 else 1


SETTINGS_PARAM = {"glove5": "force_kp", "sea_finger": "kp_mcp", "pantograph": "torque_limit_j0_Nm"}


def settings(args):
    """`phalanx param` against the cross-compiled image's settings store (docs/params.md), its flash a host file."""
    c = Checks()
    name = SETTINGS_PARAM[args.app]
    path = os.path.join(tempfile.mkdtemp(prefix="phalanx-qemu-settings-"), "settings.bin")

    def param(board, *argv):
        r = subprocess.run([os.path.join(BIN, "phalanx"), "param", *argv, "--device", f"serial:{board.pty}"],
                           stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
        return r.returncode, r.stdout + r.stderr

    def boot():
        board = Board(args.elf, extra=[f"plant_period_ms={args.plant_period_ms}", f"settings={path}"]
                      + relaxed_hand(args) + args.extra, machine=args.board)
        return board, parse_kv(board.wait_for(r"^BOOT .*", 1).group(0)).get("settings")

    value = None
    for i, new in enumerate(("0.75", "1.25")):
        board, loaded = boot()
        try:
            c.check(loaded == ("nothing-stored" if i == 0 else "loaded"),
                    f"power-up {i + 1}: the board found {'an erased' if i == 0 else 'its kept'} settings flash", loaded)
            if value is not None:
                rc, out = param(board, "get", name)
                c.check(rc == 0 and f"{name} = " in out and abs(float(out.split("=")[1].split()[0]) - float(value)) < 1e-6,
                        f"power-up {i + 1}: {name} is the value saved before the power cycle ({value})", out.strip())
            rc, out = param(board, "set", name, new, "--save")
            c.check(rc == 0 and "saved: settings record" in out, f"power-up {i + 1}: param set {name} {new} --save", out.strip())
            value = new
        finally:
            board.stop()
    board, loaded = boot()
    try:
        c.check(loaded == "loaded", "power-up 3: the board loaded its kept settings", loaded)
        rc, out = param(board, "get", name)
        c.check(rc == 0 and abs(float(out.split("=")[1].split()[0]) - float(value)) < 1e-6,
                f"power-up 3: {name} is the second saved value ({value}): the store's other page", out.strip())
    finally:
        board.stop()
    shutil.rmtree(os.path.dirname(path), ignore_errors=True)
    print(f"qemu settings {args.app}: {c.passed} passed, {c.failed} failed")
    return 0 if c.failed == 0 else 1


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def gdb_read(port, addr, size, path):
    """Reads the board's memory through the gdbstub with gdb itself (not through phalanx). `disconnect`, not
    `detach`: the core stays halted (QEMU resumes it on a detach)."""
    r = subprocess.run(["gdb-multiarch", "-nx", "-batch", "-ex", f"target remote 127.0.0.1:{port}",
                        "-ex", f"dump binary memory {path} {addr:#x} {addr + size:#x}", "-ex", "disconnect"],
                       stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError:
        return r.stdout + r.stderr


def phalanx_flash(argv, timeout_s=120):
    r = subprocess.run([os.path.join(BIN, "phalanx"), "flash"] + argv, cwd=ROOT, stdin=subprocess.DEVNULL,
                       capture_output=True, text=True, timeout=timeout_s)
    return r.returncode, r.stdout, r.stderr


def documented_dry_runs():
    """The `--dry-run` examples of docs/firmware-mcu.md "Flashing": ($ command, [command lines it prints])."""
    out, cur = [], None
    for line in open(os.path.join(ROOT, "docs", "firmware-mcu.md")):
        line = line.rstrip("\n")
        if line.startswith("$ phalanx flash ") and "--dry-run" in line:
            cur = (line[2:], [])
            out.append(cur)
        elif cur is not None and line and not line.startswith("```") and not line.startswith("$ "):
            if not line.startswith("image "):
                cur[1].append(line)
        else:
            cur = None
    return out


def flash(args):
    c = Checks()
    board_name = BOARDS[args.board][1].split("-", 1)[1]  # "mps2_an386" / "ast1030": the build's board name
    good_path = app_elf(args.app, args.board)[:-4] + ".bin"
    other_app = next(a for a in APPS if a != args.app)
    wrong_device_path = app_elf(other_app, args.board)[:-4] + ".bin"
    stm32_path = os.path.join(ROOT, "build", "mcu-stm32g474", f"phalanx-stm32g474-{args.app}.bin")
    for p in (good_path, wrong_device_path, stm32_path):
        if not os.path.exists(p):
            print(f"missing image {p}: build the images first (tools/mcu/build.sh)")
            return 1
    good = open(good_path, "rb").read()
    info = image_info(good)
    build_hex = f"{info['build_id']:08x}"
    work = tempfile.mkdtemp(prefix="phalanx-flash-test-")
    corrupt_path = os.path.join(work, "corrupt.bin")
    corrupt = bytearray(good)
    corrupt[len(corrupt) // 2] ^= 0x5A  # one byte of code
    open(corrupt_path, "wb").write(corrupt)
    oversized_path = os.path.join(work, "oversized.bin")  # consistent (size, CRC), one word over the part's code memory
    part_bytes = {"mps2-an386": 4 << 20, "ast1030-evb": 512 << 10}[args.board]
    padded = good + bytes(part_bytes + 4 - len(good))
    open(oversized_path, "wb").write(with_info(padded, image_size=len(padded)))
    other_build_path = os.path.join(work, "other-build.bin")  # a consistent image that claims another build id
    open(other_build_path, "wb").write(with_info(good, build_id=info["build_id"] ^ 0x00FF00FF))

    port = free_port()
    board = Board(None, extra=[f"plant_period_ms={args.plant_period_ms}"] + relaxed_hand(args) + args.extra,
                  machine=args.board, gdb_port=port)
    common = ["--via", "gdb", "--target", f"127.0.0.1:{port}", "--board", board_name, "--device-type", args.app,
              "--device", f"serial:{board.pty}", "--timeout", "30"]
    readback = os.path.join(work, "memory.bin")
    try:
        print(f"blank board up: pty={board.pty} gdbstub=127.0.0.1:{port}; image {os.path.relpath(good_path, ROOT)} "
              f"build {build_hex}, {len(good)} bytes")
        blank = gdb_read(port, info["load_address"], len(good), readback)
        c.check(blank == bytes(len(good)), "the blank board's code memory reads as zeros through the gdbstub",
                blank[:200] if isinstance(blank, str) else "")
        refusals = [("wrong-device image", wrong_device_path, "wrong device"),
                    ("corrupt image (one byte flipped)", corrupt_path, "CRC mismatch"),
                    ("wrong-board image (the STM32G474's)", stm32_path, "wrong board"),
                    ("oversized image (one word over the part)", oversized_path, "too large"),
                    ("ELF instead of the raw image", app_elf(args.app, args.board), "ELF")]
        for what, path, expected in refusals:
            rc, out, err = phalanx_flash([path] + common)
            c.check(rc == 3 and expected in err and "nothing was written" in err,
                    f"{what} refused before writing (exit 3, '{expected}')", f"rc={rc} {err.strip()[-300:]}")
            print(f"    {err.strip()}")
            after = gdb_read(port, info["load_address"], len(good), readback)
            c.check(after == bytes(len(good)), f"  nothing was written (memory still zero after the {what})")
        t0 = time.monotonic()
        rc, out, err = phalanx_flash([good_path] + common)
        print("\n".join("    " + l for l in out.strip().splitlines()))
        c.check(rc == 0, f"the {args.app} image written through the gdbstub (exit 0, {time.monotonic() - t0:.1f} s "
                "with the handshake)", f"rc={rc} {err.strip()[-400:]}")
        c.check("read back: " in out and "equal to the image" in out, "phalanx read the image back equal")
        c.check(f"build {build_hex}: matches the image" in out,
                f"the board answered the handshake as {args.app} with the image's build id {build_hex}")
        boot = board.wait_for(rf"^BOOT .*app={args.app}\b", 10)
        c.check(boot is not None, "the board booted the written image (debug console BOOT line)")
        d = subprocess.run([os.path.join(BIN, "phalanx"), "mcu-diag", "--device", f"serial:{board.pty}",
                            "--timeout", "10"], stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=120)
        try:
            diag = json.loads(d.stdout)
        except json.JSONDecodeError:
            diag = {}
        c.check(diag.get("device_type") == args.app and diag.get("firmware", {}).get("build_id") == build_hex,
                f"an independent handshake (phalanx mcu-diag) reads {args.app} build {build_hex}",
                d.stdout[-200:] + d.stderr[-200:])
        rc, out, err = phalanx_flash([other_build_path] + common)
        c.check(rc == 5 and "build id mismatch" in err,
                "an image whose block claims another build id: written, then the handshake's mismatch is an error "
                "(exit 5)", f"rc={rc} {err.strip()[-300:]}")
        print(f"    {err.strip()}")
    finally:
        board.stop()
        shutil.rmtree(work, ignore_errors=True)

    docs = documented_dry_runs()
    vias = {v for cmd, _ in docs for v in ("openocd", "dfu", "gdb") if f"--via {v}" in cmd}
    c.check({"openocd", "dfu"} <= vias, "docs/firmware-mcu.md shows the --dry-run output of --via openocd and dfu",
            sorted(vias))
    for cmd, expected in docs:
        if "--via gdb" in cmd:
            continue  # its read-back file name carries the process id
        argv = cmd.split()[2:]
        rc, out, err = phalanx_flash(argv)
        got = [l for l in out.splitlines() if not l.startswith("image ")]
        c.check(rc == 0 and got == expected, f"`{cmd}` prints what the docs say",
                f"rc={rc} got {got} docs {expected} {err.strip()}")
    print(f"flash test {args.app} on {args.board}: {c.passed} passed, {c.failed} failed")
    return 0 if c.failed == 0 else 1


def blank(args):
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    port = args.gdb_port or free_port()
    board = Board(None, extra=[f"plant_period_ms={args.plant_period_ms}"] + args.extra, machine=args.board,
                  gdb_port=port)
    print(f"PTY {board.pty}\nGDB 127.0.0.1:{port}", flush=True)
    return serve(board)


def run(args):
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    board = Board(args.elf, seconds=0, icount=args.shift,
                  extra=[f"plant_period_ms={args.plant_period_ms}"] + args.extra,
                  machine=args.board)
    print(f"PTY {board.pty}", flush=True)
    return serve(board)


def serve(board):
    """Keeps a started board running until QEMU exits or we are interrupted (run, blank); prints its console."""
    try:
        while board.proc.poll() is None:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        board.stop()
        print(board.text())
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["session", "bench", "run", "flash", "blank", "plan", "settings"])
    ap.add_argument("--app", default="glove5", choices=APPS, help="device app of the image (default glove5)")
    ap.add_argument("--board", default="mps2-an386", choices=sorted(BOARDS),
                    help="emulated board (QEMU machine): mps2-an386 (CMSDK UART, host 100 Hz) or ast1030-evb "
                         "(16550 UART with FIFO: carries a 1 kHz host loop)")
    ap.add_argument("--elf", default=None, help="image (default: the board's build directory, <app> image)")
    ap.add_argument("--seconds", type=int, default=4)
    ap.add_argument("--rate-hz", type=int, default=100, help="host loop rate (the firmware always ticks at 1 kHz)")
    ap.add_argument("--plant-period-ms", type=int, default=None,
                    help="at most one plant step (1 ms of physics) per this many ms (default: session/run "
                         "glove5 16, sea_finger 1, pantograph 8; bench 1)")
    ap.add_argument("--shift", type=int, default=None,
                    help="-icount shift (2^shift ns per instruction); bench default 2, run default real time")
    ap.add_argument("--budget", type=int, default=17000, help="bench: worst-case tick instructions allowed")
    ap.add_argument("--no-kill-test", dest="kill_test", action="store_false")
    ap.add_argument("--require-plant-realtime", action="store_true",
                    help="session: fail unless the plant computed >= 95 %% of its steps (kept real time)")
    ap.add_argument("--host-realtime", action="store_true",
                    help="run phalanx/phalanxd in their real-time mode (SCHED_FIFO 80 + mlockall) instead of "
                         "--no-realtime; needed for a 1 kHz host loop on a loaded machine")
    ap.add_argument("--extra", action="append", default=[], help="extra firmware option key=value")
    ap.add_argument("--gdb-port", type=int, default=None, help="blank: the gdbstub's TCP port (default: a free one)")
    args = ap.parse_args()
    if args.elf is None:
        args.elf = app_elf(args.app, args.board)
    args.plant_period_ms_given = args.plant_period_ms is not None
    global HOST_REALTIME
    HOST_REALTIME = args.host_realtime
    if args.plant_period_ms is None:
        args.plant_period_ms = SESSION_PLANT_PERIOD_MS[args.app]
    if args.mode == "bench" and args.shift is None:
        args.shift = 2
    return {"session": session, "bench": bench, "run": run, "flash": flash, "blank": blank, "plan": plan,
            "settings": settings}[args.mode](args)


if __name__ == "__main__":
    sys.exit(main())
