#!/usr/bin/env python3
"""Soak with fault injection (issue 21, item 2; docs/soak.md).

Runs the real phalanxd and firmware-sim on all three simulated devices (sim:glove5, sim:sea_finger,
sim:pantograph) episode after episode for --minutes, each episode with one fault from a seeded schedule, and
keeps every piece of evidence in OUT/epNNNN/: the daemon's --json summary, its stderr, the --record file (CSV or
MCAP), the plant truth (--sim-truth / firmware-sim --truth), the firmware's log and meta.json (what was injected,
when, exit codes). tests/soak/check.py then reads all of it and fails on any broken invariant.

Usage: soak.py --bin BUILD/bin --minutes M --seed S --out DIR [--kinds a,b,...]
Exit: 0 when every episode ran and the checker found no violation, 1 otherwise.
"""

import argparse
import json
import os
import random
import select
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import tty

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
import check  # noqa: E402

DEVICES = ("glove5", "sea_finger", "pantograph")
KINDS = ("clean", "kill9_daemon", "kill9_firmware", "corrupt_frames", "truncate_frames", "flood_frames",
         "link_stall_short", "link_stall_long", "disk_full", "client_bad", "api_garbage", "dashboard_garbage",
         "modbus_garbage", "link_replug", "sensor_range", "sensor_stuck", "estop_press")
# Every daemon runs without real-time priority (the machine is shared) and with a 100 ms command timeout, so a
# busy machine's scheduling hiccup is not mistaken for a fault (the watchdog then still trips within 100 ms).
COMMON = ["--no-realtime", "--command-timeout-ms", "100"]


class Episode:
    def __init__(self, root, n, kind, device, rng):
        self.dir = os.path.join(root, f"ep{n:04d}")
        os.makedirs(self.dir, exist_ok=True)
        self.meta = {"episode": n, "kind": kind, "device": device, "daemons": [], "injected": {}, "notes": []}
        self.rng = rng

    def path(self, name):
        return os.path.join(self.dir, name)

    def inject(self, what, n=1):
        self.meta["injected"][what] = self.meta["injected"].get(what, 0) + n

    def save(self):
        with open(self.path("meta.json"), "w") as f:
            json.dump(self.meta, f, indent=1)


def children(pid):
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            return [int(x) for x in f.read().split()]
    except OSError:
        return []


class Daemon:
    """One phalanxd process; its record in meta['daemons'] is what the checker reads."""

    def __init__(self, ep, bin_dir, args, name, expect, record=None, truth=None):
        self.ep, self.name = ep, name
        self.out = open(ep.path(f"{name}.json"), "w")
        self.err = open(ep.path(f"{name}.stderr"), "w")
        self.info = {"name": name, "args": args, "expect_exit": expect, "record": record, "truth": truth,
                     "summary": f"{name}.json", "stderr": f"{name}.stderr", "start_wall_ns": time.time_ns()}
        ep.meta["daemons"].append(self.info)
        self.p = subprocess.Popen([os.path.join(bin_dir, "phalanxd"), *args], stdout=self.out, stderr=self.err)

    def wait_for_loop(self, timeout):
        """Until the daemon says its control loop started (stderr), it exited, or timeout seconds."""
        end = time.monotonic() + timeout
        while time.monotonic() < end and self.p.poll() is None:
            with open(self.ep.path(f"{self.name}.stderr"), errors="replace") as f:
                if "control loop started" in f.read():
                    return
            time.sleep(0.02)

    def kill9(self):
        self.info["kill_wall_ns"] = time.time_ns()
        self.p.send_signal(signal.SIGKILL)

    def wait(self, timeout):
        try:
            rc = self.p.wait(timeout)
        except subprocess.TimeoutExpired:
            self.info["hung"] = True
            self.p.send_signal(signal.SIGKILL)
            rc = self.p.wait()
        self.info["exit"] = rc
        self.info["end_wall_ns"] = time.time_ns()
        self.out.close()
        self.err.close()
        return rc


class Firmware:
    """A standalone firmware-sim on its own pseudo-terminal (the daemon then opens it as serial:PATH)."""

    def __init__(self, ep, bin_dir, device, seed, extra=()):
        self.log = open(ep.path("firmware.stderr"), "w")
        truth = ep.path("truth.csv")
        self.p = subprocess.Popen([os.path.join(bin_dir, "firmware-sim"), "--device", device, "--scenario", "random",
                                   "--seed", str(seed), "--seconds", "300", "--truth", truth, *extra],
                                  stdout=subprocess.PIPE, stderr=self.log, text=True)
        line = self.p.stdout.readline().strip()
        if not line.startswith("PTY "):
            raise RuntimeError(f"firmware-sim said {line!r}")
        self.pty = line[4:]
        ep.meta["firmware"] = {"stderr": "firmware.stderr", "truth": "truth.csv"}
        self.ep = ep

    def stop(self):
        self.p.send_signal(signal.SIGTERM)
        try:
            rc = self.p.wait(10)
        except subprocess.TimeoutExpired:
            self.p.kill()
            rc = self.p.wait()
        self.ep.meta["firmware"]["exit"] = rc
        self.log.close()


class Proxy(threading.Thread):
    """A pseudo-terminal between firmware-sim and the daemon that forwards bytes and, on request, damages the
    device-to-host stream frame by frame (frames end with 0x00: COBS, docs/protocol.md) or holds all traffic."""

    def __init__(self, fw_pty, link_path=None):
        super().__init__(daemon=True)
        self.fw = os.open(fw_pty, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fw)
        self._open_host_side()
        self.link_path = link_path  # a stable name (a symlink to the pty) for a link that is unplugged and back
        self.replugs = 0
        self.plug = None  # "unplug" | "replug", done by the proxy thread
        if link_path:
            os.symlink(self.slave_path, link_path)
        self.lock = threading.Lock()
        self.damage = None  # (kind, frames left, rng)
        self.stall_until = 0.0
        self.injected = {}
        self.stop_flag = False
        self.buf = b""
        self.watch()

    def request(self, kind, frames, rng):
        with self.lock:
            self.damage = [kind, frames, rng]

    def stall(self, seconds):
        self.stall_until = time.monotonic() + seconds

    def _damage(self, frame):
        with self.lock:
            d = self.damage
            if d is None or d[1] <= 0:
                return frame
            kind, rng = d[0], d[2]
            d[1] -= 1
        self.injected[kind] = self.injected.get(kind, 0) + 1
        body = bytearray(frame[:-1])
        if kind == "corrupt" and body:
            i = rng.randrange(len(body))
            body[i] ^= 1 << rng.randrange(8)
            if body[i] == 0:
                body[i] = 0x55  # keep it one frame: a new delimiter would make two
        elif kind == "truncate" and len(body) > 2:
            body = body[: rng.randrange(1, len(body) - 1)]
        elif kind == "flood":
            # A burst of 64 garbage frames (no zero byte inside), then the real frame.
            junk = b"".join(bytes(rng.randrange(1, 256) for _ in range(rng.randrange(3, 40))) + b"\0"
                            for _ in range(64))
            self.injected["flood_garbage_frames"] = self.injected.get("flood_garbage_frames", 0) + 64
            return junk + bytes(body) + b"\0"
        return bytes(body) + b"\0"

    def _open_host_side(self):
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.slave_path = os.ttyname(slave)
        self.slave = slave  # kept open so the daemon's close does not hang the master up

    def unplug(self):
        """The host's port goes away (the daemon's descriptor hangs up), as a USB serial adapter pulled out."""
        self.plug = "unplug"

    def replug(self):
        """A new port under the same name (the symlink moved atomically to a new pty)."""
        self.plug = "replug"

    def _replug(self):
        """The proxy thread's side of unplug()/replug(): only it touches the descriptors."""
        if self.plug == "unplug" and self.master is not None:
            os.close(self.master)
            os.close(self.slave)
            self.master = self.slave = None
        elif self.plug == "replug" and self.master is None:
            self._open_host_side()
            tmp = self.link_path + ".new"
            os.symlink(self.slave_path, tmp)
            os.replace(tmp, self.link_path)
            self.replugs += 1
        self.plug = None

    def watch(self):
        """From now on (the daemon's start) keep the longest time the host was sent nothing."""
        self.last_to_host = self.last_from_host = time.monotonic()
        self.longest_silence = 0.0

    def silence_ms(self):
        """The longest time the host got no frame while it ran: between two forwards, or from the last forward to
        the host's last command (the daemon sends one every cycle until it exits). On a loaded machine this is
        also how long the proxy or firmware-sim went unscheduled: a silence the daemon had to take as a lost
        link if it exceeded the telemetry timeout."""
        return round(1000.0 * max(self.longest_silence, self.last_from_host - self.last_to_host), 1)

    def run(self):
        while not self.stop_flag:
            if self.plug:
                self._replug()
            if self.master is None:  # unplugged: the device's bytes go nowhere
                if select.select([self.fw], [], [], 0.05)[0]:
                    os.read(self.fw, 4096)
                continue
            r, _, _ = select.select([self.fw, self.master], [], [], 0.05)
            now = time.monotonic()
            stalled = now < self.stall_until
            for fd in r:
                try:
                    data = os.read(fd, 4096)
                except OSError:
                    return
                if fd == self.master:
                    self.last_from_host = now
                if not data or stalled:
                    continue  # a held link: the bytes are lost, as on a cable pulled for a while
                if fd == self.master:
                    os.write(self.fw, data)
                    continue
                self.buf += data
                out = []
                while b"\0" in self.buf:
                    i = self.buf.index(b"\0") + 1
                    out.append(self._damage(self.buf[:i]))
                    self.buf = self.buf[i:]
                if out:
                    try:
                        os.write(self.master, b"".join(out))
                    except OSError:
                        continue
                    self.longest_silence = max(self.longest_silence, now - self.last_to_host)
                    self.last_to_host = now

    def close(self):
        self.stop_flag = True
        self.join(2)
        for fd in (self.fw, self.master, self.slave):
            if fd is not None:
                os.close(fd)


def sim_args(ep, device, seconds, record_ext="csv", truth=True):
    a = ["--device", f"sim:{device}", "--seconds", str(seconds), "--json", "--seed", str(ep.rng.randrange(1, 10000)),
         "--record", ep.path(f"record.{record_ext}")]
    if truth:
        a += ["--sim-truth", ep.path("truth.csv")]
    return COMMON + a


def ep_clean(ep, b, device):
    d = Daemon(ep, b, sim_args(ep, device, round(ep.rng.uniform(2, 5), 2)), "daemon", [0],
               record="record.csv", truth="truth.csv")
    d.wait(90)


def ep_kill9_daemon(ep, b, device):
    """kill -9 of a recording daemon on a standalone firmware: the firmware's watchdog makes the device safe, the
    MCAP record holds data to within 100 ms of the kill, and a new daemon on the same port takes over."""
    fw = Firmware(ep, b, device, ep.rng.randrange(1, 10000))
    d = Daemon(ep, b, COMMON + ["--device", f"serial:{fw.pty}", "--json", "--mode", "transparent", "--seconds", "0",
                                "--record", ep.path("record.mcap")], "daemon", ["SIGKILL"], record="record.mcap",
               truth="truth.csv")
    time.sleep(ep.rng.uniform(1.5, 4.0))
    if d.p.poll() is None:
        ep.meta["firmware"]["log_offset_at_kill"] = os.path.getsize(ep.path("firmware.stderr"))
        d.kill9()
        ep.inject("kill9_daemon")
    d.wait(10)
    time.sleep(0.4)  # the watchdog trips 100 ms after the last command; the firmware logs it
    ep.meta["firmware"]["log_offset_at_restart"] = os.path.getsize(ep.path("firmware.stderr"))
    ep.inject("restart_daemon")
    d2 = Daemon(ep, b, COMMON + ["--device", f"serial:{fw.pty}", "--json", "--mode", "transparent", "--seconds", "1.5",
                                 "--record", ep.path("record2.csv")], "daemon2", [0], record="record2.csv",
                truth="truth.csv")
    d2.wait(60)
    fw.stop()


def ep_kill9_firmware(ep, b, device):
    d = Daemon(ep, b, sim_args(ep, device, 0), "daemon", [6], record="record.csv", truth="truth.csv")
    time.sleep(ep.rng.uniform(1.0, 3.0))
    kids = children(d.p.pid)
    if kids:
        for k in kids:
            os.kill(k, signal.SIGKILL)
        ep.inject("kill9_firmware")
        d.info["firmware_kill_wall_ns"] = time.time_ns()
    else:
        ep.meta["notes"].append("no firmware-sim child found")
    d.wait(10)
    ep.inject("restart_after_firmware_kill")
    d2 = Daemon(ep, b, COMMON + ["--device", f"sim:{device}", "--seconds", "1", "--json",
                                 "--record", ep.path("record2.csv")], "daemon2", [0], record="record2.csv")
    d2.wait(60)


def ep_link(ep, b, device, kind):
    """Frames damaged on their way to the host, or the link held (short: the session goes on; long: link lost)."""
    fw = Firmware(ep, b, device, ep.rng.randrange(1, 10000))
    px = Proxy(fw.pty)
    px.start()
    stall_long = kind == "link_stall_long"
    seconds = round(ep.rng.uniform(3, 5), 2)
    # Exit 6 only for the long stall, or for a link that went silent past the telemetry timeout anyway (a loaded
    # machine starving the proxy or firmware-sim): the checker then holds the daemon's claim against the silence
    # the proxy measured (check.py, link_silence_ms).
    px.watch()
    d = Daemon(ep, b, COMMON + ["--device", f"serial:{px.slave_path}", "--json", "--mode", "transparent",
                                "--seconds", str(seconds), "--record", ep.path("record.csv")], "daemon",
               [6] if stall_long else [0, 6], record="record.csv", truth="truth.csv")
    # Faults go in once the daemon's control loop runs (a loaded machine can take seconds to start it: a stall
    # during its start-up is not the outage this episode is about), until 0.8 s before its end.
    d.wait_for_loop(30)
    t_end = time.monotonic() + seconds - 0.8
    while time.monotonic() < t_end and d.p.poll() is None:
        if kind in ("corrupt_frames", "truncate_frames", "flood_frames"):
            px.request(kind.split("_")[0], ep.rng.randrange(1, 6), ep.rng)
        elif kind == "link_stall_short":
            px.stall(ep.rng.uniform(0.03, 0.25))
            ep.inject("link_stall_short")
        else:
            px.stall(1.2)
            ep.inject("link_stall_long")
            break
        time.sleep(ep.rng.uniform(0.15, 0.5))
    d.wait(60)
    d.info["link_silence_ms"] = px.silence_ms()
    px.close()
    for k, v in px.injected.items():
        ep.inject(k, v)
    fw.stop()


def ep_link_replug(ep, b, device):
    """The host's serial port unplugged for 0.3–1.5 s and back under the same name: the daemon reports the lost
    link, sends nothing, reconnects (a new handshake, its start-up parameters, the faults the outage latched read
    and cleared) and ends its session normally (exit 0), connected."""
    fw = Firmware(ep, b, device, ep.rng.randrange(1, 10000))
    px = Proxy(fw.pty, link_path=ep.path("ttyPHALANX"))
    px.start()
    d = Daemon(ep, b, COMMON + ["--device", f"serial:{px.link_path}", "--json", "--mode", "transparent",
                                "--seconds", "6", "--record", ep.path("record.csv")], "daemon", [0],
               record="record.csv", truth="truth.csv")
    d.info["expect_reconnects"] = 1
    time.sleep(ep.rng.uniform(1.5, 2.5))
    if d.p.poll() is None:
        px.unplug()
        ep.inject("link_unplug")
        time.sleep(ep.rng.uniform(0.3, 1.5))
        px.replug()
    d.wait(60)
    px.close()
    fw.stop()


# protocol::fault bits (common/include/phalanx/protocol/messages.h) each input fault must latch.
INPUT_FAULTS = {"sensor_range": ("sensor-range", 1 << 3), "sensor_stuck": ("sensor-stuck", 1 << 4),
                "estop_press": ("estop", 1 << 2)}


def ep_input_fault(ep, b, device, kind):
    """A sensor that fails (open or frozen) or the e-stop pressed on the board (firmware-sim --inject), while the
    daemon drives the device: the firmware must find it itself and latch its safe state; the session runs on to
    its end with the device safe (exit 0)."""
    what, bit = INPUT_FAULTS[kind]
    at = round(ep.rng.uniform(2.0, 3.0), 2)
    spec = f"{what}@{at}" + (f"+{round(ep.rng.uniform(0.1, 1.0), 2)}" if what == "estop" else "")
    fw = Firmware(ep, b, device, ep.rng.randrange(1, 10000), ["--inject", spec])
    ep.meta["expect_fault"] = bit
    ep.meta["firmware"]["inject"] = spec
    d = Daemon(ep, b, COMMON + ["--device", f"serial:{fw.pty}", "--json", "--mode", "transparent", "--seconds", "5",
                                "--record", ep.path("record.csv")], "daemon", [0], record="record.csv",
               truth="truth.csv")
    ep.inject(kind)
    d.wait(60)
    fw.stop()


def ep_disk_full(ep, b, device):
    """The records directory on a 256 KiB tmpfs: the recording fails, the session stops safe, exit 7."""
    mnt = ep.path("full")
    os.makedirs(mnt, exist_ok=True)
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", mnt]).returncode != 0:
        ep.meta["notes"].append("tmpfs mount failed (not root?): disk_full skipped")
        ep.meta["skipped"] = True
        return
    try:
        # Fill most of it first so the failure comes at a random point of the session.
        with open(os.path.join(mnt, "ballast"), "wb") as f:
            f.write(b"\0" * ep.rng.randrange(0, 200 * 1024))
        args = COMMON + ["--device", f"sim:{device}", "--seconds", "30", "--json", "--record",
                         os.path.join(mnt, "record.csv")]
        d = Daemon(ep, b, args, "daemon", [7], record="full/record.csv")
        ep.inject("disk_full")
        d.wait(60)
        # Keep the evidence: copy the record out before the tmpfs goes.
        with open(os.path.join(mnt, "record.csv"), "rb") as src, open(ep.path("record.csv"), "wb") as dst:
            dst.write(src.read())
        d.info["record"] = "record.csv"
        d.info["disk_full"] = True
    finally:
        subprocess.run(["umount", mnt])


def ep_client_bad(ep, b, device):
    """A libphalanx Python client that sends NaN, infinities, setpoints far beyond every limit, and stalls."""
    sock = ep.path("client.sock")
    args = sim_args(ep, device, 4) + ["--client-socket", sock]
    d = Daemon(ep, b, args, "daemon", [0], record="record.csv", truth="truth.csv")
    log = open(ep.path("client.log"), "w")
    code = CLIENT_CODE.format(repo=REPO, sock=sock, seed=ep.rng.randrange(1, 10000))
    c = subprocess.run([sys.executable, "-c", code], stdout=log, stderr=subprocess.STDOUT, timeout=60)
    log.close()
    ep.meta["client_exit"] = c.returncode
    try:
        with open(ep.path("client.log")) as f:
            for line in f:
                if line.startswith("INJECTED "):
                    k, v = line.split()[1:3]
                    ep.inject(k, int(v))
    except OSError:
        pass
    d.wait(60)


CLIENT_CODE = r"""
import math, os, random, sys, time
sys.path.insert(0, os.path.join({repo!r}, "python"))
import phalanx
rng = random.Random({seed})
for _ in range(200):
    if os.path.exists({sock!r}): break
    time.sleep(0.05)
c = phalanx.Client({sock!r}, deadline_ms=100, fallback="safe")
n = int(c.device["setpoint_count"]); lim = float(c.device["setpoint_limit"])
count = {{}}
def note(k): count[k] = count.get(k, 0) + 1
bad = [float("nan"), float("inf"), -float("inf"), 1e9, -1e9, lim * 3.0, -lim * 1.5]
t_end = time.monotonic() + 2.5
while time.monotonic() < t_end:
    s = c.wait_state(100)
    r = rng.random()
    try:
        if r < 0.3:
            c.set_setpoints([rng.choice(bad) for _ in range(n)], "setpoint"); note("client_bad_setpoint")
        elif r < 0.35:
            time.sleep(rng.uniform(0.05, 0.3)); note("client_stall")
        else:
            c.set_setpoints([rng.uniform(-lim, lim) * 0.5 for _ in range(n)], "setpoint"); note("client_ok_setpoint")
    except phalanx.Error as e:
        note("client_refused_by_sdk")
c.release()
for k, v in count.items(): print("INJECTED", k, v)
"""


def api_send(path, payload, timeout=3.0):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    s.settimeout(timeout)
    try:
        s.connect(path)
        s.sendall(payload)
        try:
            return s.recv(65536)
        except socket.timeout:
            return b""
    finally:
        s.close()


def api_status_ok(path):
    try:
        a = json.loads(api_send(path, b'{"cmd":"status","id":9}\n').split(b"\n")[0])
        return a.get("ok") is True
    except (OSError, ValueError):
        return False


def api_daemon(ep, b, device, extra=()):
    sock = ep.path("api.sock")
    rec = ep.path("records")
    args = ["--no-realtime", "--device", f"sim:{device}", "--api", sock, "--records-dir", rec, "--profiles-dir",
            os.path.join(REPO, "config", "profiles"), "--json", *extra]
    d = Daemon(ep, b, args, "daemon", [0], record=None)
    d.info["summary"] = None  # with --api each session's summary is the stop answer (meta["stop"])
    for _ in range(200):
        if os.path.exists(sock):
            break
        time.sleep(0.05)
    return d, sock


def phalanx_cli(b, sock, *args):
    return subprocess.run([os.path.join(b, "phalanx"), *args, "--socket", sock, "--json"], capture_output=True,
                          text=True, timeout=60)


def start_session(ep, b, sock, device):
    patient = ["--patient", "demo-001"] if device == "glove5" else []
    exercise = "resistance" if device in ("glove5", "sea_finger") else None
    if device == "pantograph":
        return None  # the pen has no therapy adapter: the daemon serves it without sessions
    p = phalanx_cli(b, sock, "start", *patient, "--exercise", exercise, "--scenario", "random", "--seconds", "0")
    ep.meta["start"] = {"exit": p.returncode, "stdout": p.stdout[-2000:], "stderr": p.stderr[-2000:]}
    if device == "glove5":
        ep.meta["patient_profile"] = os.path.join(REPO, "config", "profiles", "demo-001.yaml")
    return p


def finish_api(ep, b, d, sock, started):
    if started is not None and started.returncode == 0:
        p = phalanx_cli(b, sock, "stop")
        with open(ep.path("stop.json"), "w") as f:
            f.write(p.stdout)
        ep.meta["stop"] = {"exit": p.returncode, "answer": "stop.json", "stderr": p.stderr[-2000:]}
        recs = sorted(f for f in os.listdir(ep.path("records")) if f.endswith(".phrec"))
        if recs:
            d.info["record"] = os.path.join("records", recs[-1])
    d.p.send_signal(signal.SIGTERM)
    d.wait(30)


def ep_api_garbage(ep, b, device):
    d, sock = api_daemon(ep, b, device)
    started = start_session(ep, b, sock, device)
    bad = [b"\x00\xff\xfe garbage\n", b'{"cmd":\n', b'{"cmd":"status","id":1,"verbose":true}\n',
           b'{"cmd":"limits","effort_max":{"index":50}}\n', b'{"cmd":"limits","effort_max":{"index":NaN}}\n',
           b'{"cmd":"limits","effort_max":{"index":-1}}\n', b'{"cmd":"start","seconds":-3}\n',
           b'{"cmd":"exercise","exercise":"../../etc/passwd"}\n', b'[1,2,3]\n', b'{"cmd":"nope"}\n',
           b"x" * 70000 + b"\n", b'{"cmd":"status"', b'{"cmd":"status","id":' + b"9" * 400 + b"}\n"]
    ok_after = 0
    for i in range(ep.rng.randrange(8, 16)):
        payload = ep.rng.choice(bad)
        try:
            api_send(sock, payload, timeout=1.0)
        except OSError as e:
            ep.meta["notes"].append(f"api send: {e}")
        ep.inject("api_garbage")
        if api_status_ok(sock):
            ok_after += 1
        time.sleep(ep.rng.uniform(0.05, 0.3))
    ep.meta["api_status_ok_after_garbage"] = ok_after
    ep.meta["api_garbage_sent"] = ep.meta["injected"].get("api_garbage", 0)
    finish_api(ep, b, d, sock, started)


def ep_dashboard_garbage(ep, b, device):
    port = free_port()
    d, sock = api_daemon(ep, b, device, extra=["--dashboard", f"127.0.0.1:{port}"])
    started = start_session(ep, b, sock, device)
    bad = [b"GARBAGE\r\n\r\n", b"GET / HTTP/1.1\r\n" + b"X-Long: " + b"a" * 100000 + b"\r\n\r\n",
           b"GET /../../../etc/passwd HTTP/1.1\r\nHost: x\r\n\r\n", b"POST /api HTTP/1.1\r\nContent-Length: 99999999\r\n\r\n{",
           b"GET /api/status?token=wrong HTTP/1.1\r\n\r\n", b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03",
           b"GET / HTTP/1.1\r\n", b"POST /api/stop HTTP/1.1\r\nContent-Length: 5\r\n\r\nxxxxx"]
    ok_after = 0
    for _ in range(ep.rng.randrange(8, 16)):
        try:
            s = socket.create_connection(("127.0.0.1", port), timeout=1.0)
            s.sendall(ep.rng.choice(bad))
            try:
                s.recv(4096)
            except OSError:
                pass
            s.close()
        except OSError as e:
            ep.meta["notes"].append(f"dashboard: {e}")
        ep.inject("dashboard_garbage")
        if api_status_ok(sock):
            ok_after += 1
    ep.meta["api_status_ok_after_garbage"] = ok_after
    ep.meta["api_garbage_sent"] = ep.meta["injected"].get("dashboard_garbage", 0)
    finish_api(ep, b, d, sock, started)


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def ep_modbus_garbage(ep, b, device):
    """A Modbus TCP server with writes allowed: malformed frames and writes out of range from a client."""
    port = free_port()
    cfg = ep.path("phalanxd.yaml")
    with open(cfg, "w") as f:
        f.write(f"device: sim:{device}\nmodbus:\n  enabled: true\n  port: {port}\n  writes_enabled: true\n")
    d = Daemon(ep, b, COMMON + ["--config", cfg, "--seconds", "4", "--json", "--record", ep.path("record.csv"),
                                "--sim-truth", ep.path("truth.csv")], "daemon", [0], record="record.csv",
               truth="truth.csv")
    time.sleep(1.0)

    def f32(x):
        return struct.pack(">f", x)

    def write_regs(addr, data):
        return bytes([0x10]) + addr.to_bytes(2, "big") + (len(data) // 2).to_bytes(2, "big") + bytes([len(data)]) + data

    # Take control in setpoint mode (a valid write), then a client that misbehaves.
    frames = [write_regs(0, b"\0\1\0\2")]
    extreme = [float("nan"), float("inf"), -float("inf"), 1e9, -1e9, 3.0 * 10.0, 1e-3]
    for _ in range(40):
        r = ep.rng.random()
        if r < 0.4:  # setpoints 0..3 at extreme values (one bad value must refuse the whole block)
            pdu = write_regs(2, b"".join(f32(ep.rng.choice(extreme)) for _ in range(4)))
        elif r < 0.55:  # write single register, random address and value
            pdu = bytes([0x06]) + ep.rng.randrange(0, 65536).to_bytes(2, "big") + \
                ep.rng.randrange(0, 65536).to_bytes(2, "big")
        elif r < 0.7:  # a read whose count is out of range
            pdu = bytes([0x03, 0, 0, 0xff, 0xff])
        else:  # random bytes
            pdu = bytes(ep.rng.randrange(256) for _ in range(ep.rng.randrange(1, 20)))
        frames.append(pdu)
    frames = [(i + 1).to_bytes(2, "big") + b"\0\0" +
              (len(pdu) + 1 + (ep.rng.random() < 0.1) * 7).to_bytes(2, "big") + b"\x01" + pdu
              for i, pdu in enumerate(frames)]
    try:
        s = socket.create_connection(("127.0.0.1", port), timeout=1.0)
        for fr in frames:
            try:
                s.sendall(fr)
                ep.inject("modbus_garbage")
                s.settimeout(0.05)
                try:
                    s.recv(512)
                except socket.timeout:
                    pass
            except OSError:
                s.close()
                s = socket.create_connection(("127.0.0.1", port), timeout=1.0)
        s.close()
    except OSError as e:
        ep.meta["notes"].append(f"modbus connect: {e}")
    d.wait(60)


RUNNERS = {
    "clean": ep_clean, "kill9_daemon": ep_kill9_daemon, "kill9_firmware": ep_kill9_firmware,
    "corrupt_frames": lambda e, b, dv: ep_link(e, b, dv, "corrupt_frames"),
    "truncate_frames": lambda e, b, dv: ep_link(e, b, dv, "truncate_frames"),
    "flood_frames": lambda e, b, dv: ep_link(e, b, dv, "flood_frames"),
    "link_stall_short": lambda e, b, dv: ep_link(e, b, dv, "link_stall_short"),
    "link_stall_long": lambda e, b, dv: ep_link(e, b, dv, "link_stall_long"),
    "disk_full": ep_disk_full, "client_bad": ep_client_bad, "api_garbage": ep_api_garbage,
    "dashboard_garbage": ep_dashboard_garbage, "modbus_garbage": ep_modbus_garbage,
    "link_replug": ep_link_replug,
    "sensor_range": lambda e, b, dv: ep_input_fault(e, b, dv, "sensor_range"),
    "sensor_stuck": lambda e, b, dv: ep_input_fault(e, b, dv, "sensor_stuck"),
    "estop_press": lambda e, b, dv: ep_input_fault(e, b, dv, "estop_press"),
}


def prune(ep_dir, limits):
    """Check the episode now; without a violation keep its result (checked.json) and drop the bulky evidence."""
    result = check.episode_result(ep_dir, limits)
    if result["violations"]:
        return
    with open(os.path.join(ep_dir, "checked.json"), "w") as f:
        json.dump(result, f)
    for root, _, files in os.walk(ep_dir):
        for name in files:
            if name.endswith((".csv", ".mcap", ".phrec", ".html")):
                os.remove(os.path.join(root, name))


def schedule(rng, kinds):
    """Rounds of every (kind, device) pair in a seeded order: a short run still covers every kind early."""
    while True:
        order = list(kinds)
        rng.shuffle(order)
        for k in order:
            yield k, rng.choice(DEVICES)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bin", default=os.path.join(REPO, "build", "host", "bin"))
    ap.add_argument("--minutes", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", default=None)
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--prune", action="store_true",
                    help="check each episode as it ends and delete the records of those without a violation "
                         "(summaries, logs and meta kept): an hours-long soak then keeps ~30 KB per episode")
    a = ap.parse_args()
    kinds = [k for k in a.kinds.split(",") if k]
    for k in kinds:
        if k not in RUNNERS:
            ap.error(f"--kinds: unknown fault kind '{k}' (known: {', '.join(KINDS)})")
    out = a.out or tempfile.mkdtemp(prefix="phalanx-soak-")
    os.makedirs(out, exist_ok=True)
    if any(e.startswith("ep") for e in os.listdir(out)):
        ap.error(f"--out {out}: holds another soak's episodes (the checker would read them too); use a new directory")
    limits = check.device_limits()
    rng = random.Random(a.seed)
    t_end = time.monotonic() + a.minutes * 60.0
    t0 = time.monotonic()
    n = 0
    print(f"soak: seed {a.seed}, {a.minutes} min, evidence in {out}; load average {os.getloadavg()}", flush=True)
    for kind, device in schedule(rng, kinds):
        if time.monotonic() >= t_end:
            break
        ep = Episode(out, n, kind, device, random.Random(rng.randrange(1 << 30)))
        t = time.monotonic()
        try:
            RUNNERS[kind](ep, a.bin, device)
        except Exception as e:  # the harness's own failure is evidence too: the checker counts it
            ep.meta["harness_error"] = repr(e)
        ep.meta["wall_s"] = round(time.monotonic() - t, 2)
        ep.save()
        if a.prune:
            prune(ep.dir, limits)
        print(f"  ep{n:04d} {kind:18s} {ep.meta['device']:10s} {ep.meta['wall_s']:6.1f} s  exits "
              f"{[x.get('exit') for x in ep.meta['daemons']]}  injected {ep.meta['injected']}", flush=True)
        n += 1
    print(f"soak: {n} episodes in {(time.monotonic() - t0) / 60:.1f} min; load average {os.getloadavg()}", flush=True)
    return check.main([out])


if __name__ == "__main__":
    sys.exit(main())
