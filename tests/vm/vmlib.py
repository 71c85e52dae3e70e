"""Shared by the VM lane's session scripts (tests/vm/*_session.py): guest set-up and timing reports.

Why the VM can miss 1 kHz, and what each setting here is for: docs/vm-lane.md ("Why the VM missed 1 kHz").
"""
import re

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
