#!/usr/bin/python3
"""phalanxd <-> firmware-sim over vcan in the VM lane (Debian's kernel, real SocketCAN).

Scenarios (each a fresh bus): a quiet CAN-FD session and a quiet classic-CAN session at 1 kHz (zero lost frames,
round-trip latency, bus load measured from candump -L and, for classic, by can-utils' canbusload); quiet sessions
of glove5, sea_finger and pantograph over the compact CAN-FD mapping (fd-compact: the same checks, no fault latched,
bus load per 1 kHz tick at 1/5 Mbit/s at most 20 %) and bad compact frames injected by cansend; frames with bad
identifiers, lengths and CRCs injected by cansend (rejected and counted on the side they reach); bus-off and
restart error frames injected by cansend (both ends stop sending, the device goes safe by itself, traffic resumes);
and the interface taken down and up mid-session (writes fail with ENETDOWN, traffic resumes); a bench plan run by
`phalanx bench run` over CAN-FD against firmware-sim's Modbus load cell (bench); and a firmware update over CAN-FD
and the compact mapping by `phalanx update`, with the power lost mid-transfer once (update).
Prints RESULT lines; exits non-zero on the first failed expectation.
Usage (inside the VM, from the repository root): python3 tests/vm/can_session.py [scenario...]
"""
import json
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import time

import vmlib

BIN = "build/host/bin"
IP = "/usr/sbin/ip"
OUT = "build/vm/results"
NODE = 1
# Tick and host loop rate. 1 kHz is the specification; PHALANX_VM_CAN_HZ lowers it only to check the link's
# behaviour where the emulated VM cannot keep 1 kHz (the RESULT lines state the rate used).
RATE = int(os.environ.get("PHALANX_VM_CAN_HZ", "1000"))
# The simulated device. glove5 (the default, and the device of the bus-load figures) costs firmware-sim about
# 0.9-1.2 ms of emulated CPU per 1 ms tick under TCG (its plant: docs/vm-lane.md "Why the VM missed 1 kHz"), so the
# device side cannot keep 1 kHz in this VM; sea_finger's plant costs a quarter of that and measures the link at 1 kHz.
DEVICE = os.environ.get("PHALANX_VM_DEVICE", "glove5")


def fail(msg):
    print("FAIL: " + msg, flush=True)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def sh(*args):
    subprocess.run(list(args), check=True)


def vcan(name, fd):
    subprocess.run([IP, "link", "del", name], stderr=subprocess.DEVNULL)
    sh(IP, "link", "add", name, "type", "vcan")
    if fd:
        sh(IP, "link", "set", name, "mtu", "72")
    sh(IP, "link", "set", name, "up")


def cansend(bus, frame):
    subprocess.run(["cansend", bus, frame], check=True)


def send_error_frame(bus, err_bits):
    """Write one error frame (CAN_ERR_FLAG | err_bits) from this process's own raw socket: starting cansend in
    the emulated VM can take longer than the interval being tested."""
    sock = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    sock.bind((bus,))
    sock.send(struct.pack("=IB3x8s", 0x20000000 | err_bits, 8, bytes(8)))
    sock.close()


class DumpCounter:
    """Counts the frames of one identifier in a growing candump -L log (read incrementally)."""

    def __init__(self, path, can_id):
        self.path, self.tag, self.pos, self.count = path, " %03X#" % can_id, 0, 0

    def update(self):
        with open(self.path) as f:
            f.seek(self.pos)
            data = f.read()
        complete = data[:data.rfind("\n") + 1]
        self.pos += len(complete)
        self.count += complete.count(self.tag)
        return self.count


def session(name, bus, mode, seconds, actions=(), extra_dev=(), monitor_classic_load=False, device=DEVICE,
            extra_host=(), expect_exit=0, tail_commands=0, end_when=None):
    """Run firmware-sim and phalanxd on bus; actions = [(t_s, callable)] run while the session runs.
    tail_commands > 0: the session is not bounded by `seconds` but ends (SIGINT, a clean stop) once the host has
    sent that many commands after the last action returned - so what an action sent is always inside the
    session, however slowly the emulated VM runs this script or cansend (a fixed-length session ended before the
    injected frames on a loaded machine: the host then counted none of them). end_when: likewise, the session ends
    (SIGINT) 0.5 s after end_when() first holds, once the actions have run.
    Returns (summary dict, firmware-sim stderr text, candump log path, canbusload output)."""
    if tail_commands > 0 or end_when is not None:
        seconds = 600  # an upper bound only: the session is ended by the script
    vcan(bus, mode != "classic")
    # The log goes to the VM's tmpfs: 2000 lines/s written over 9p would cost the VM more than the session.
    dump_path = "/tmp/%s.candump" % name
    dump = subprocess.Popen(["candump", "-L", bus], stdout=open(dump_path, "w"))
    load = None
    if monitor_classic_load:
        load = subprocess.Popen(["canbusload", "%s@1000000" % bus], stdout=subprocess.PIPE, text=True)
    fw_err = open(os.path.join(OUT, "%s.firmware.log" % name), "w+")
    # SCHED_FIFO inside the guest (phalanxd sets its own): candump and this script must not delay a tick.
    fw = subprocess.Popen(["chrt", "-f", "70", BIN + "/firmware-sim", "--device", device, "--can", bus, "--node", str(NODE),
                           "--can-mode", mode, "--scenario", "still", "--substeps", "2", "--tick-hz", str(RATE)] + list(extra_dev),
                          stdout=subprocess.PIPE, stderr=fw_err, text=True)
    line = fw.stdout.readline()
    check(line.startswith("CAN %s node %d %s" % (bus, NODE, mode)), "firmware-sim did not report its CAN link: %r" % line)
    # phalanxd under SCHED_FIFO but without its mlockall: locking every page of a binary served over 9p takes the
    # emulated VM many seconds, during which the bus backs up (measured: 12 s on a loaded machine).
    d = subprocess.Popen(["chrt", "-f", "80", BIN + "/phalanxd", "--no-realtime", "--device", "can:%s:%d@%s" % (bus, NODE, mode), "--seconds", str(seconds),
                          "--json", "--scene", "rigid-ball", "--rate-hz", str(RATE)] + list(extra_host),
                         stdout=subprocess.PIPE, stderr=open(os.path.join(OUT, "%s.phalanxd.log" % name), "w"),
                         text=True)
    # Actions are timed from the first command on the bus (the control loop's start), not from process start:
    # on a slow VM the daemon's start-up alone can take seconds.
    if actions:
        deadline = time.monotonic() + 60
        while "%03X#" % (1 << 6 | NODE) not in open(dump_path).read():
            check(time.monotonic() < deadline and d.poll() is None, "%s: the session never started" % name)
            time.sleep(0.05)
    t0 = time.monotonic()
    for at, act in sorted(actions, key=lambda a: a[0]):
        while time.monotonic() - t0 < at:
            time.sleep(0.01)
        act()
    if tail_commands > 0:
        commands = DumpCounter(dump_path, 1 << 6 | NODE)
        target = commands.update() + tail_commands
        deadline = time.monotonic() + 300
        while commands.update() < target:
            check(d.poll() is None, "%s: phalanxd ended before the session was stopped" % name)
            check(time.monotonic() < deadline, "%s: the host sent %d of %d commands after the last action in 300 s"
                  % (name, commands.count - target + tail_commands, tail_commands))
            time.sleep(0.05)
        d.send_signal(signal.SIGINT)
    elif end_when is not None:
        deadline = time.monotonic() + 300
        while not end_when():
            check(d.poll() is None, "%s: phalanxd ended before the session was stopped" % name)
            check(time.monotonic() < deadline, "%s: the session's end condition did not hold within 300 s" % name)
            time.sleep(0.05)
        time.sleep(0.5)
        d.send_signal(signal.SIGINT)
    # phalanxd runs seconds × RATE cycles: at the few hundred Hz a loaded VM keeps, that takes several times longer.
    out, _ = d.communicate(timeout=seconds + 180)
    fw.terminate()
    fw.wait(timeout=10)
    dump.terminate()
    dump.wait()
    load_out = ""
    if load is not None:
        load.terminate()
        load_out = load.communicate()[0]
    fw_err.seek(0)
    fw_text = fw_err.read()
    subprocess.run(["cp", dump_path, OUT])
    try:
        summary = json.loads(out)
    except ValueError:
        fail("%s: phalanxd printed no JSON summary (rc %d): %r" % (name, d.returncode, out[-500:]))
    with open(os.path.join(OUT, "%s.summary.json" % name), "w") as f:
        json.dump(summary, f, indent=2)
    check(d.returncode == expect_exit, "%s: phalanxd exit %d: %s" % (name, d.returncode, summary.get("error")))
    if expect_exit != 0:
        return summary, fw_text, dump_path, load_out
    # Under TCG on a loaded machine the VM may not keep the rate. The link's integrity is checked regardless (the
    # sequence numbers say whether anything was lost, however slow); timing figures are reported with the rate
    # the VM actually kept, and a WARNING when it did not keep the specified one.
    summary["achieved_hz"] = summary["cycles"] / summary["seconds"]
    print(vmlib.timing_line(name, summary, RATE, fw_text)[0], flush=True)
    if summary["overruns"] > 0.05 * summary["cycles"]:
        print("WARNING %s: the VM kept %.0f Hz, not %d Hz (%d overruns): timing figures of this run are not "
              "%d Hz figures" % (name, summary["achieved_hz"], RATE, summary["overruns"], RATE), flush=True)
    return summary, fw_text, dump_path, load_out


def outage(dump_path, can_id):
    """Longest gap between consecutive frames with this identifier in a candump -L log, and how many followed it."""
    times = []
    for line in open(dump_path):
        m = re.match(r"\((\d+\.\d+)\) \S+ ([0-9A-F]+)#", line)
        if m and int(m.group(2), 16) == can_id:
            times.append(float(m.group(1)))
    check(len(times) > 2, "no frames 0x%X in %s" % (can_id, dump_path))
    gaps = [(times[i + 1] - times[i], len(times) - i - 1) for i in range(len(times) - 1)]
    return max(gaps)


def split_by_direction(dump_path):
    """Host -> device and device -> host frames of a candump -L log into two logs; counts of commands (part 0)
    and telemetry status frames."""
    host_fns = {0x01, 0x02, 0x03, 0x0D, 0x0E, 0x11, 0x12}
    cmd_path, tel_path = dump_path + ".cmd", dump_path + ".tel"
    n_cmd = n_tel = 0
    with open(cmd_path, "w") as c, open(tel_path, "w") as t:
        for line in open(dump_path):
            m = re.match(r"\(\d+\.\d+\) \S+ ([0-9A-F]{3})#", line)
            if not m:
                continue
            cid = int(m.group(1), 16)
            fn = cid >> 6
            (c if fn in host_fns else t).write(line)
            n_cmd += fn == 0x01
            n_tel += fn == 0x04
    check(n_cmd > 0 and n_tel > 0, "no commands or telemetry in %s" % dump_path)
    return cmd_path, tel_path, n_cmd, n_tel


def count_frames(dump_path, can_id):
    n = 0
    for line in open(dump_path):
        m = re.match(r"\(\d+\.\d+\) \S+ ([0-9A-F]+)#", line)
        if m and int(m.group(1), 16) == can_id:
            n += 1
    return n


def fw_counter(text, key):
    m = re.findall(r"\b%s=(\d+)" % key, text)
    check(m, "firmware-sim did not report %s" % key)
    return int(m[-1])


def measured_load(dump_path, data_bps):
    r = subprocess.run([BIN + "/phalanx", "can", "load", "--log", dump_path, "--bitrate", "1000000",
                        "--data-bitrate", str(data_bps)], capture_output=True, text=True)
    check(r.returncode == 0, "phalanx can load failed: " + r.stdout + r.stderr)
    return json.loads(r.stdout)


def quiet(mode, device=DEVICE, seconds=5):
    name = "quiet-" + mode + ("" if device == "glove5" else "-" + device)
    # The compact sessions must also end with no fault latched. The emulated VM on a loaded machine stalls for tens
    # of milliseconds (round trip p99 85 ms measured) and a 20 ms command timeout then latches command-timeout,
    # which says nothing about the link: these sessions carry a 500 ms timeout (the link checks are unchanged).
    extra_host = ["--command-timeout-ms", "500"] if mode == "fd-compact" else []
    if mode == "classic" and device == "glove5":
        # Classic CAN carries no gain scales, and the glove's rendering sends one per finger in contact: phalanxd
        # refuses that pairing at start, naming the way out; the reduced classic session runs transparent.
        s, _, _, _ = session("classic-render", "vcan0", mode, 1, device=device, expect_exit=2)
        check("classic CAN does not carry" in s.get("error", ""), "classic + rendering not refused: %s" % s.get("error"))
        print("RESULT can-classic-render: refused at start (%s)" % s["error"], flush=True)
        extra_host = ["--mode", "transparent"]
    s, fw, dump, load_out = session(name, "vcan0", mode, seconds, monitor_classic_load=(mode == "classic"), device=device,
                                    extra_host=extra_host)
    tel, cmd, rx = s["telemetry"], s["commands"], s["host_rx_errors"]
    rt = s["round_trip"]
    print("%s: cycles=%d telemetry=%d lost=%d commands=%d unsent=%d lost_at_device=%d rejected_by_device=%d "
          "host_rx_errors=%s rtt_p50=%.0fus rtt_p99=%.0fus overruns=%d can=%s" % (
              mode, s["cycles"], tel["received"], tel["lost"], cmd["sent"], cmd["unsent_link_full"],
              cmd["lost_seen_by_device"], cmd["rejected_by_device"], rx, rt["p50_us"], rt["p99_us"], s["overruns"],
              json.dumps(s["can"])), flush=True)
    check(s["cycles"] >= (seconds - 0.1) * RATE, "%s: only %d cycles" % (mode, s["cycles"]))
    check(tel["lost"] == 0, "%s: %d telemetry frames lost" % (mode, tel["lost"]))
    check(tel["received"] >= 0.2 * s["cycles"], "%s: only %d telemetry frames" % (mode, tel["received"]))
    check(cmd["unsent_link_full"] == 0, "%s: %d commands not sent" % (mode, cmd["unsent_link_full"]))
    check(cmd["lost_seen_by_device"] == 0, "%s: device saw %d lost commands" % (mode, cmd["lost_seen_by_device"]))
    check(cmd["rejected_by_device"] == 0, "%s: device rejected %d frames" % (mode, cmd["rejected_by_device"]))
    check(all(v == 0 for v in rx.values()), "%s: host rejected frames: %s" % (mode, rx))
    check(s["can"]["rx_kernel_dropped"] == 0, "%s: kernel dropped frames" % mode)
    check(fw_counter(fw, "tx_dropped_full") == 0 and fw_counter(fw, "rx_kernel_dropped") == 0,
          "%s: firmware-sim dropped frames" % mode)
    check(rt["count"] >= 0.2 * s["cycles"], "%s: only %d round trips measured" % (mode, rt["count"]))
    # The VM may run the host loop and the firmware slower than 1 kHz, and not at the same rate: the bus time per
    # command (host -> device frames / commands) and per telemetry (device -> host frames / status frames) are what
    # the log measures; one 1 kHz tick carries one of each.
    cmd_log, tel_log, n_cmd, n_tel = split_by_direction(dump)
    loads = {}
    fd = mode != "classic"
    for data_bps in ([1000000, 5000000] if fd else [1000000]):
        mc, mt = measured_load(cmd_log, data_bps), measured_load(tel_log, data_bps)
        per_tick = {k: 1000.0 * (mc[k] * mc["seconds"] / n_cmd + mt[k] * mt["seconds"] / n_tel)
                    for k in ("load_pct_worst_stuffing", "load_pct_no_stuffing")}
        loads[data_bps] = per_tick
        print("%s bus time per tick @1M/%dM: %.2f frames per command, %.2f per telemetry; at 1 kHz %.1f %% "
              "worst-case stuffing, %.1f %% none" % (mode, data_bps // 1000000, mc["frames"] / n_cmd,
                                                   mt["frames"] / n_tel, per_tick["load_pct_worst_stuffing"],
                                                   per_tick["load_pct_no_stuffing"]), flush=True)
    ticks_per_s = n_tel / measured_load(tel_log, 1000000)["seconds"]
    extra = ""
    if mode == "classic":
        # canbusload (can-utils) prints one line per second: "<if>@<bitrate> <frames> <bits> <payload bits> <pct>%"
        pcts = [int(x) for x in re.findall(r"vcan0@1000000\s+\d+\s+\d+\s+\d+\s+(\d+)%", load_out)]
        busy = [p for p in pcts if p > 0][1:-1]  # whole seconds inside the session
        check(busy, "canbusload reported nothing: %r" % load_out[-300:])
        # canbusload sees both directions at their own (VM) rates; scaled by the telemetry rate it is comparable
        # to the per-tick figure only when host and device kept the same rate.
        scaled = sum(busy) / len(busy) * 1000.0 / ticks_per_s
        extra = " canbusload %s %% at %.0f ticks/s = %.0f %% at 1 kHz" % ("/".join(str(p) for p in busy), ticks_per_s,
                                                                       scaled)
        print("classic canbusload (worst-case stuffing, per second): %s; mean scaled to 1 kHz %.1f %%" % (busy, scaled))
    w = loads[5000000 if fd else 1000000]["load_pct_worst_stuffing"]
    if mode == "fd-compact":
        # The compact mapping exists for this budget (docs/protocol.md, "Bus load at 1 kHz"); and a clean session.
        check(w <= 20.0, "%s %s: bus load %.1f %% per 1 kHz tick at 1/5 Mbit/s exceeds 20 %%" % (mode, device, w))
        check(s["faults_seen"] == [] or s["faults_seen"] == "none",
              "%s %s: faults latched during the session: %s" % (mode, device, s["faults_seen"]))
        check(s["can"]["tx_not_representable"] == 0, "%s %s: commands refused: %s" % (mode, device, s["can"]["tx_refusal"]))
    print("RESULT can-%s: %s %d cycles at %d Hz (VM kept %.0f Hz), 0 lost, faults %s, rtt p50 %.0f us p99 %.0f us, bus load measured per tick, at 1 kHz %.1f %% "
          "(worst-case stuffing, %s)%s" % (mode, device, s["cycles"], RATE, s["achieved_hz"], s["faults_seen"] or "none",
                                         rt["p50_us"], rt["p99_us"], w,
                                         "1/5 Mbit/s" if fd else "1 Mbit/s", extra), flush=True)


def inject_session(name, bus, mode, frames):
    """A session with `frames` sent by cansend from 1.5 s on, ended after the host sent 1000 more commands; returns (summary, host rx_rejected, device rx counts).
    Always glove5, whatever PHALANX_VM_DEVICE says: the frames' lengths are glove5's (a right-length compact
    command for glove5 is a wrong-length one for the other devices)."""
    acts = [(1.5, lambda f=f: cansend(bus, f)) for f in frames]
    # Ended 1000 host commands after the last cansend returned: both ends have read every injected frame by then.
    s, fw, _, _ = session(name, bus, mode, 3, actions=acts, device="glove5", tail_commands=1000)
    host = s["can"]["rx_rejected"]
    dev = {k: fw_counter(fw, "rx_" + k) for k in ("bad_id", "bad_length", "crc", "sequence")}
    print("%s: host rejected %s, device rejected %s, rejected_by_device (telemetry) %d, telemetry lost %d" % (
        name, host, dev, s["commands"]["rejected_by_device"], s["telemetry"]["lost"]), flush=True)
    return s, host, dev


def inject():
    bus = "vcan0"
    zeros = "00" * 64
    # Node-1 identifiers: function << 6 | 1. Command = 0x041, Telemetry = 0x101, unknown function 0x1F = 0x7C1.
    frames = [
        "7C1##1" + "00" * 8,        # unknown function: both ends count bad_id
        "041##1" + "00" * 12,       # Command with 12 bytes instead of 64: device bad_length (host: wrong direction)
        "041##1" + zeros,           # Command of the right length whose CRC is wrong: device crc (host: wrong direction)
        "101##1" + "00" * 8,        # Telemetry 8 bytes instead of 64: host bad_length (device: wrong direction)
        "042##1" + zeros,           # addressed to node 2: filtered by the kernel, never seen
        "12345678#00",              # extended identifier, low bits = node 56: filtered
    ]
    s, host, dev = inject_session("inject-fd", bus, "fd", frames)
    check(dev == {"bad_id": 2, "bad_length": 1, "crc": 1, "sequence": 0}, "device counts %s" % dev)
    check(host == {"bad_id": 3, "bad_length": 1, "crc": 0, "sequence": 0}, "host counts %s" % host)
    check(s["commands"]["rejected_by_device"] == 4, "telemetry rx_errors reported %d" % s["commands"]["rejected_by_device"])
    check(s["telemetry"]["lost"] == 0 and s["commands"]["lost_seen_by_device"] == 0, "injection disturbed the session")
    # (No check on device faults here: a glove5 on a VM that cannot keep 1 kHz may latch current-limit or
    # command-timeout by itself; what the injected frames did is in the exact counts above.)
    print("RESULT can-inject: bad id/length/CRC frames from cansend rejected and counted (device %d, host %d), "
          "session undisturbed" % (sum(dev.values()), sum(host.values())), flush=True)


def busoff():
    bus = "vcan0"
    acts = [(1.5, lambda: send_error_frame(bus, 0x040)),   # CAN_ERR_BUSOFF
            (2.5, lambda: send_error_frame(bus, 0x100))]   # CAN_ERR_RESTARTED
    s, fw, dump, _ = session("busoff-fd", bus, "fd", 4, actions=acts, tail_commands=1000)
    c = s["can"]
    print("busoff: host can %s; faults %s; telemetry %d; firmware: bus_off=%d restarts=%d tx_dropped_bus_off=%d" % (
        json.dumps(c), s["faults_seen"], s["telemetry"]["received"], fw_counter(fw, "bus_off"),
        fw_counter(fw, "restarts"), fw_counter(fw, "tx_dropped_bus_off")), flush=True)
    check(c["bus_off_events"] == 1 and c["restarts"] == 1, "host did not see bus-off and restart")
    log = open(os.path.join(OUT, "busoff-fd.phalanxd.log")).read()
    check("CAN bus error-active -> bus-off" in log and "CAN bus bus-off -> error-active" in log,
          "phalanxd did not report bus-off and recovery: %r" % log[-400:])
    # One second of bus-off at the rate the VM kept: most of those cycles' commands must have been refused.
    check(c["tx_dropped_bus_off"] >= 0.5 * s["achieved_hz"],
          "host kept sending while bus-off (%d refused at %.0f Hz)" % (c["tx_dropped_bus_off"], s["achieved_hz"]))
    check(c["state"] == "error-active", "host link ends in state %s" % c["state"])
    check(fw_counter(fw, "bus_off") == 1 and fw_counter(fw, "restarts") == 1, "device did not see bus-off/restart")
    check("command-timeout" in s["faults_seen"], "device did not go safe on its own: faults %s" % s["faults_seen"])
    check("firmware-sim: SAFE" in fw, "firmware-sim never reported its outputs off")
    # On the bus (candump): telemetry stops for the bus-off second, then flows again after the restart.
    gap, after = outage(dump, 0x101)
    print("busoff: longest telemetry gap on the bus %.2f s, %d telemetry frames after it" % (gap, after), flush=True)
    check(gap >= 0.5, "telemetry did not stop during bus-off (longest gap %.2f s)" % gap)
    check(after >= 0.3 * s["achieved_hz"], "telemetry did not resume after the restart (%d frames)" % after)
    print("RESULT can-busoff: injected bus-off stops both ends (host refused %d commands), device safe by "
          "command timeout, traffic resumes after restart" % c["tx_dropped_bus_off"], flush=True)


def linkdown():
    bus = "vcan0"
    acts = [(1.5, lambda: sh(IP, "link", "set", bus, "down")), (2.0, lambda: sh(IP, "link", "set", bus, "up"))]
    # Ended once the daemon has reported the link back, not after a fixed length: on a loaded machine the fixed
    # 3.5 s session ended before the script's "up" (the daemon logged the link down at t=3.44 s and never saw it
    # return). candump exits when its interface goes down, so the commands after "up" cannot be counted there.
    log_path = os.path.join(OUT, "linkdown-fd.phalanxd.log")
    back = lambda: "CAN bus down -> error-active" in open(log_path).read()
    s, fw, dump, _ = session("linkdown-fd", bus, "fd", 3.5, actions=acts, end_when=back)
    c = s["can"]
    print("linkdown: host can %s; faults %s; telemetry %d" % (json.dumps(c), s["faults_seen"],
                                                              s["telemetry"]["received"]), flush=True)
    check(c["tx_link_down"] > 0, "writes on a downed interface were not refused")
    check(c["state"] == "error-active", "host link ends in state %s" % c["state"])
    # candump itself exits when its interface goes down; the daemon's log says what its link went through.
    log = open(os.path.join(OUT, "linkdown-fd.phalanxd.log")).read()
    check(re.search(r"CAN bus error-active -> down", log) and re.search(r"CAN bus down -> error-active", log),
          "phalanxd did not report the link going down and coming back: %r" % log[-400:])
    print("RESULT can-linkdown: ENETDOWN on %d writes while down, traffic resumes when up" % c["tx_link_down"],
          flush=True)


def inject_compact():
    """Bad frames of the compact CAN-FD mapping (glove5: command 24 bytes, telemetry 32 bytes with 25 samples)."""
    bus = "vcan0"
    frames = [
        "7C1##1" + "00" * 8,               # unknown function: both ends count bad_id
        "041##1" + "00" * 64,              # a whole-message (fd) Command on a compact link: device bad_length
        "041##1" + "00" * 24,              # compact Command of the right length whose CRC is wrong: device crc
        "101##1" + "00" * 9 + "19" + "00" * 22,  # Telemetry whose window starts at sample 25 of 25: host bad_length
        "101##1" + "00" * 64,              # Telemetry 64 bytes instead of 32: host bad_length
    ]
    s, host, dev = inject_session("inject-fd-compact", bus, "fd-compact", frames)
    # Device: the unknown function and the two telemetry frames are bad_id there (wrong direction).
    check(dev == {"bad_id": 3, "bad_length": 1, "crc": 1, "sequence": 0}, "device counts %s" % dev)
    # Host: the unknown function and the two commands (wrong direction) are bad_id, the two telemetry bad_length.
    check(host == {"bad_id": 3, "bad_length": 2, "crc": 0, "sequence": 0}, "host counts %s" % host)
    check(s["commands"]["rejected_by_device"] == 5, "telemetry rx_errors reported %d" % s["commands"]["rejected_by_device"])
    check(s["telemetry"]["lost"] == 0 and s["commands"]["lost_seen_by_device"] == 0, "injection disturbed the session")
    print("RESULT can-inject-compact: bad id/length/CRC/window frames from cansend rejected and counted (device %d, "
          "host %d), session undisturbed" % (sum(dev.values()), sum(host.values())), flush=True)


def bench(mode="fd"):
    """A bench plan over CAN (vmlib.realtime_bench): the sea_rig firmware on vcan, its load cell over Modbus TCP."""
    bus = "vcan0"
    vcan(bus, mode != "classic")
    sh(IP, "link", "set", "lo", "up")  # the amplifier is on 127.0.0.1; the VM's init leaves lo down
    fw_err = open(os.path.join(OUT, "bench-%s.firmware.log" % mode), "w+")
    fw = subprocess.Popen(["chrt", "-f", "70", BIN + "/firmware-sim", "--device", "sea_rig", "--can", bus, "--node",
                           str(NODE), "--can-mode", mode, "--substeps", "2", "--instrument", "tcp:0"],
                          stdout=subprocess.PIPE, stderr=fw_err, text=True)
    check(fw.stdout.readline().startswith("CAN %s" % bus), "firmware-sim did not report its CAN link")
    inst = fw.stdout.readline()
    m = re.search(r"tcp 127\.0\.0\.1:(\d+)", inst)
    check(m is not None, "firmware-sim did not report its instrument: %r" % inst)
    try:
        line = vmlib.realtime_bench("bench-" + mode, "can:%s:%d@%s" % (bus, NODE, mode), m.group(1), BIN, OUT, check, fail)
    finally:
        fw.terminate()
        fw.wait(timeout=10)
    print("RESULT can-bench-%s: %s" % (mode, line), flush=True)


def update():
    """`phalanx update` over SocketCAN (docs/firmware-update.md): firmware-sim (sea_finger) with a code flash file on
    vcan0, updated over CAN-FD, then over the compact mapping back to the first image; once the power is lost
    (firmware-sim ends at a byte of the transfer) and the board must come back on its old image. Gated: each
    update completes, the board reports the image's build id after its reset, and after the power loss it boots the
    old build and the retry completes. Printed: the transfer time and the resends."""
    bus = "vcan0"
    vcan(bus, True)
    old, new, flash = vmlib.update_images("update")

    def board(mode, cut=None):
        args = [BIN + "/firmware-sim", "--device", "sea_finger", "--can", bus, "--node", str(NODE), "--can-mode", mode,
                "--flash", flash, "--flash-provision", old, "--seconds", "300"]
        if cut is not None:
            args += ["--flash-power-cut-after", str(cut)]
        log = open(os.path.join(OUT, "update-%s.firmware.log" % mode), "a+")
        fw = subprocess.Popen(["chrt", "-f", "70"] + args, stdout=subprocess.PIPE, stderr=log, text=True)
        check(fw.stdout.readline().startswith("CAN %s" % bus), "firmware-sim did not report its CAN link")
        return fw

    def run_update(image, mode):
        return vmlib.run_update(["chrt", "-f", "80"], BIN, image, "can:%s:%d@%s" % (bus, NODE, mode),
                                os.path.join(OUT, "update-%s.log" % mode))

    for image, build, mode in ((new, "0b0b0b02", "fd"), (old, "0a11ce01", "fd-compact")):
        fw = board(mode)
        r, secs = run_update(image, mode)
        check(r.returncode == 0 and ("to build " + build) in r.stdout,
              "update over %s: exit %d: %s %s" % (mode, r.returncode, r.stdout, r.stderr[-600:]))
        fw.terminate()
        fw.wait(timeout=10)
        resent = re.search(r"resent (\d+) chunks", r.stdout)
        print("RESULT can-update-%s: %d bytes over CAN-FD (%s) in %.2f s wall, %s chunks resent, the board came back "
              "as build %s" % (mode, os.path.getsize(image), mode, secs, resent.group(1) if resent else "?", build),
              flush=True)
    # Power lost a third of the way through an update of the new image: the board must boot the old one again.
    fw = board("fd", cut=15000)
    r, _ = run_update(new, "fd")
    check(r.returncode != 0, "an update whose power was cut reported success")
    check(fw.wait(timeout=20) == 75, "firmware-sim did not end as a board losing power")
    fw = board("fd")
    r, _ = run_update(new, "fd")
    check(r.returncode == 0 and "from build 0a11ce01 to build 0b0b0b02" in r.stdout,
          "after the power loss: exit %d: %s %s" % (r.returncode, r.stdout, r.stderr[-600:]))
    fw.terminate()
    fw.wait(timeout=10)
    print("RESULT can-update-power-loss: power lost after 15000 programmed bytes; the board booted build 0a11ce01 "
          "again and the retry updated it to 0b0b0b02", flush=True)


SCENARIOS = {"fd": lambda: quiet("fd"), "classic": lambda: quiet("classic"),
             "fd-compact": lambda: [quiet("fd-compact", d, 3) for d in ("glove5", "sea_finger", "pantograph")],
             "inject-compact": inject_compact, "inject": inject, "busoff": busoff, "linkdown": linkdown, "bench": bench,
             "update": update}

if __name__ == "__main__":
    os.makedirs(OUT, exist_ok=True)
    vmlib.raise_socket_buffers()
    for name in sys.argv[1:] or list(SCENARIOS):
        SCENARIOS[name]()
