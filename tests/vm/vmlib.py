"""Shared by the VM lane's session scripts (tests/vm/*_session.py): guest set-up and timing reports.

Why the VM can miss 1 kHz, and what each setting here is for: docs/vm-lane.md ("Why the VM missed 1 kHz").
"""
import json
import os
import random
import re
import struct
import subprocess
import time
import zlib

# Socket receive buffers of the guest (bytes). The emulated machine sometimes stops for a few hundred ms as a whole
# (the host descheduled QEMU); the default 208 KB holds about 240 CAN-FD frames, and a 0.3 s stall at 1 kHz
# overflowed firmware-sim's socket (37 commands dropped by the kernel, measured 2026-11-24). 4 MB holds several
# seconds of either direction. This is a property of the VM, not of the link: on a bench the device is an MCU
# whose CAN FIFO is read every tick.
RMEM_BYTES = 4 * 1024 * 1024


def raise_socket_buffers():
    for key in ("rmem_default", "rmem_max"):
        with open("/proc/sys/net/core/" + key, "w") as f:
            f.write(str(RMEM_BYTES))


def device_timing(fw_log, rate):
    """firmware-sim's own view of its 1 kHz: ticks, whole periods missed, its wake lateness and work per tick (us).
    Returns a dict (empty when the log has no summary) with kept_hz = ticks / (ticks + overruns) * rate."""
    m = re.search(r"stopped ticks=(\d+) overruns=(\d+)", fw_log)
    t = re.search(r"tick timing \(us\) wake_late p50=(\d+) p99=(\d+) max=(\d+); work p50=(\d+) p99=(\d+) max=(\d+)", fw_log)
    if not m:
        return {}
    ticks, over = int(m.group(1)), int(m.group(2))
    d = {"ticks": ticks, "overruns": over, "kept_hz": rate * ticks / max(1, ticks + over)}
    if t:
        v = [int(x) for x in t.groups()]
        d.update(late_p50=v[0], late_p99=v[1], late_max=v[2], work_p50=v[3], work_p99=v[4], work_max=v[5])
    return d


def timing_line(name, s, rate, fw_log=None):
    """One line with the rate each end kept and the host's wake jitter, and whether these are <rate> figures:
    STRICT when both ends kept at least 99 % of the rate (fewer than 1 % of periods missed), else NOT-STRICT."""
    host_hz = s["cycles"] / s["seconds"]
    host_missed = s["overruns"] / max(1, s["cycles"] + s["overruns"])
    j = s.get("period_jitter", {})
    dev = device_timing(fw_log, rate) if fw_log else {}
    dev_missed = dev["overruns"] / max(1, dev["ticks"] + dev["overruns"]) if dev else 0.0
    strict = host_missed < 0.01 and dev_missed < 0.01
    txt = "TIMING %s: %s - host loop kept %.0f Hz of %d (%.1f %% of periods missed, wake late p50 %.0f us p99 %.0f us max %.0f us)" % (
        name, "STRICT %d Hz figures" % rate if strict else "NOT-STRICT (not %d Hz figures)" % rate, host_hz, rate,
        100 * host_missed, j.get("p50_us", 0), j.get("p99_us", 0), j.get("max_us", 0))
    if dev:
        txt += "; device kept %.0f Hz (%.1f %% missed, own work per tick p50 %s us p99 %s us, wake late p50 %s us p99 %s us)" % (
            dev["kept_hz"], 100 * dev_missed, dev.get("work_p50", "?"), dev.get("work_p99", "?"), dev.get("late_p50", "?"),
            dev.get("late_p99", "?"))
    return txt, strict


# The plans realtime_bench runs, per device type: the instrument's scale and unit, the safety stage, and one step
# as the shipped plans in bench/ write it (sea-rig.yaml, glove-free-motion.yaml).
BENCH_PLANS = {
    "sea_rig": ("""instrument: {transport: tcp, host: 127.0.0.1, port: %(port)s, type: int32, scale: 1.0e-5, unit: N*m, poll_hz: 500,
             timeout_ms: 50, stale_ms: 50}
max_stale_percent: 5
safety: {effort_max: 0.4, instrument_silence_ms: 200, disagreement_max: 0.05, disagreement_ms: 100}
steps:
  - name: sine 0.3 N*m over %(link)s
    kind: sea-rig-sine
    peak_Nm: 0.3
    hz: 0.5
    seconds: 6
    settle_s: 2
    limits:
      setpoint_vs_instrument: {nrmse_percent_max: 11.59, fidelity_percent_min: 97.7}
      estimate_vs_instrument: {nrmse_percent_max: 6.0}
""", "load cell", 1e3, "mN*m"),
    "glove5": ("""instrument: {transport: tcp, host: 127.0.0.1, port: %(port)s, type: int32, scale: 1.0e-5, unit: N, poll_hz: 500,
             timeout_ms: 50, stale_ms: 50}
max_stale_percent: 5
safety: {effort_max: 1.0, instrument_silence_ms: 200, disagreement_max: 0.5, disagreement_ms: 100}
steps:
  - name: free motion, index finger, over %(link)s
    kind: glove-free-motion
    finger: 1
    seconds: 6
    settle_s: 0.5
    limits:
      setpoint_vs_instrument: {rmse_max: 0.05}
      estimate_vs_instrument: {rmse_max: 0.05}
""", "fingertip sensor", 1e3, "mN"),
}


def realtime_bench(name, device, instrument_port, bin_dir, out_dir, check, fail, device_type="sea_rig"):
    """A bench plan (docs/bench-runner.md "Real time") over a real link: `phalanx bench run` drives the firmware on
    DEVICE (the sea_rig's sine, or the glove's free motion: BENCH_PLANS) while its instrument (the rig's load cell,
    the index fingertip's force sensor) is served over Modbus TCP on 127.0.0.1:INSTRUMENT_PORT (by firmware-sim in
    the VM lane, by the emulated board's amplifier in tools/mcu/qemu_board.py plan), as a lab's board and amplifier.
    Checked (through check/fail): the plan ran through the session runner on that link (the session ended cleanly)
    and its instrument was read. The limits' verdict, the alignment, any step error and what the link kept
    (telemetry rate, ticks unseen, the device clock's rate) are returned as one line, not gated: the emulated VM
    keeps neither 1 kHz nor a steady delay (measured over CAN: the instrument's delay wandered 8-24 ms within one
    6 s step, so the alignment refused it)."""
    plan_path, report = "/tmp/%s.yaml" % name, "/tmp/%s.html" % name
    steps, what, to_unit, unit = BENCH_PLANS[device_type]
    with open(plan_path, "w") as f:
        f.write("version: 1\ndevice: %s\ndevice_type: %s\n" % (device, device_type)
                + steps % {"port": instrument_port, "link": device.split(":")[0].upper()})
    # SCHED_FIFO from chrt, without the runner's mlockall (slow over 9p in the VM).
    r = subprocess.run(["chrt", "-f", "80", bin_dir + "/phalanx", "bench", "run", plan_path, "--report", report,
                        "--no-realtime"], capture_output=True, text=True, timeout=240)
    with open(os.path.join(out_dir, "%s.stderr.log" % name), "w") as f:
        f.write(r.stderr)
    try:
        res = json.loads(r.stdout)
    except ValueError:
        fail("%s: no JSON summary (rc %d): %s" % (name, r.returncode, r.stderr[-800:]))
    with open(os.path.join(out_dir, "%s.json" % name), "w") as f:
        json.dump(res, f, indent=2)
    check(r.returncode in (0, 1), "%s: exit %d: %s" % (name, r.returncode, r.stderr[-800:]))
    check(res.get("mode") == "realtime" and res["session"].get("exit_code") == 0, "%s: session %s" % (name, res.get("session")))
    step = res["steps"][0]
    a, link = step.get("alignment", {}), step.get("link", {})
    check(link.get("device") == device and link.get("frames", 0) > 0, "%s: the step did not run over the link: %s" % (name, step))
    check(step["instrument"].get("polls_ok", 0) > 0, "%s: the instrument was never read: %s" % (name, step["instrument"]))
    # What the emulated VM's erratic timing causes is reported, not gated: an alignment it does not allow, stale
    # instrument samples, a command-timeout the firmware latched when the host's commands came late.
    error = step.get("error", "")
    aligned = ("instrument delay %.2f +- %.2f ms (correlation %.4f), estimate vs %s RMSE %.2f %s"
               % (a["delay_ms"], a["uncertainty_ms"], a["correlation"], what,
                  step["estimate_vs_instrument"]["rmse"] * to_unit, unit)
               if a.get("ok") and not error else "not scored (%s)" % error)
    return ("plan over %s, %s; device kept %.0f Hz telemetry (%d of %d ticks unseen, its clock %.0f ppm off the "
            "host's), %d instrument polls; %s"
            % (link["device"], "limits PASS" if step["pass"] else "not passed", link["telemetry_hz"],
               link["ticks_unseen"], link["device_ticks"], a.get("clock_drift_ppm", 0), step["instrument"]["polls_ok"],
               aligned))


def test_image(path, build_id, size, device_type=2):
    """A firmware image for the update (docs/firmware-update.md): random bytes with a valid image-info block
    (common/include/phalanx/image_info.h) for the stm32g474 board, its CRC-32 over the image with the CRC field 0."""
    rnd = random.Random(build_id)
    b = bytearray(rnd.getrandbits(8) for _ in range(size))
    b[0x200:0x220] = struct.pack("<IHHBBHIIIII", 0x49584850, 1, 32, device_type, 1, 0, build_id, 0x08000000, size, 0, 0)
    b[0x218:0x21C] = struct.pack("<I", zlib.crc32(bytes(b)))
    with open(path, "wb") as f:
        f.write(b)


def update_images(prefix):
    """The update scenarios' files: an old image (the board's factory image, build 0a11ce01), a new one
    (0b0b0b02) and the path of a code flash file that does not exist yet. Returns (old, new, flash)."""
    old, new, flash = "/tmp/%s-old.bin" % prefix, "/tmp/%s-new.bin" % prefix, "/tmp/%s-code.flash" % prefix
    test_image(old, 0x0a11ce01, 30011)
    test_image(new, 0x0b0b0b02, 45007)
    if os.path.exists(flash):
        os.remove(flash)
    return old, new, flash


def run_update(launch, bin_dir, image, device, log_path):
    """`phalanx update IMAGE --device DEVICE` without reconnects, its output appended to LOG_PATH; LAUNCH prefixes
    the command (chrt). Returns (CompletedProcess, wall seconds)."""
    t0 = time.monotonic()
    r = subprocess.run(list(launch) + [bin_dir + "/phalanx", "update", image, "--device", device, "--timeout", "5",
                       "--reconnects", "0"], capture_output=True, text=True, timeout=240)
    with open(log_path, "a") as f:
        f.write(r.stdout + r.stderr)
    return r, time.monotonic() - t0
