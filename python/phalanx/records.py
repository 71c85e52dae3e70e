"""Read Phalanx recordings into named numpy arrays (docs/records.md, "Python").

    from phalanx import records
    r = records.load("session.phrec")      # or a --record CSV, an export CSV, or an MCAP file
    r["t_s"], r["force_index_N"]            # numpy arrays by column name
    r.names                                  # column names, in file order
    r.header, r.events                       # the record's header and events (.phrec, MCAP)
    r.topics["/phalanx/joint_states"]        # MCAP: every topic's fields as arrays
    r.dataframe()                            # a pandas.DataFrame of the columns (pandas installed)

.phrec and CSV need only numpy and the standard library; MCAP needs the `mcap` package (pip install mcap).
A .phrec is checked as the daemon's own reader checks it: sync word, length and CRC-32 of every record; a torn
tail (the daemon killed mid-write) and damaged records are counted in r.integrity, never silently dropped.
"""

from __future__ import annotations

import csv
import json
import math
import struct
import zlib
from typing import Any, Dict, List, Optional

import numpy as np

__all__ = ["Record", "load", "load_phrec", "load_csv", "load_mcap"]

_PHREC_MAGIC = b"PHXREC1\n"
_SYNC = 0x43455250
_HEADER, _CYCLE, _EVENT, _FOOTER, _BLOCK = 1, 2, 3, 4, 5
_CYCLE_FIXED = struct.Struct("<QdQHHHHBBBBBB")  # host_ns t_s device_time_us tel_seq cmd_seq_echo cmd_seq
#                                                 fault_bits tel_mode cmd_mode state_flags n_samples n_setpoints n_aux
_CYCLE_FIELDS = ("host_ns", "t_s", "device_time_us", "tel_seq", "cmd_seq_echo", "cmd_seq", "fault_bits", "tel_mode",
                 "cmd_mode", "state_flags")


class Record:
    """Named columns (numpy arrays of equal length) plus what the file says about itself."""

    def __init__(self, fmt: str, columns: Dict[str, np.ndarray], header: Any = None,
                 events: Optional[List[Any]] = None, footer: Any = None,
                 topics: Optional[Dict[str, Dict[str, np.ndarray]]] = None,
                 integrity: Optional[Dict[str, Any]] = None):
        self.format = fmt
        self.columns = columns
        self.header = header
        self.events = events or []
        self.footer = footer
        self.topics = topics or {}
        self.integrity = integrity or {}

    @property
    def names(self) -> List[str]:
        return list(self.columns)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    def __len__(self) -> int:
        return len(next(iter(self.columns.values()))) if self.columns else 0

    def dataframe(self):
        """The columns as a pandas.DataFrame; ImportError when pandas is not installed."""
        import pandas as pd  # optional dependency

        return pd.DataFrame(self.columns)

    def __repr__(self) -> str:
        return f"<phalanx.records.Record {self.format}: {len(self)} rows, {len(self.columns)} columns>"


def load(path: str) -> Record:
    """A .phrec session record, a CSV (--record or record export) or an MCAP file, by its first bytes."""
    with open(path, "rb") as f:
        head = f.read(8)
    if head == _PHREC_MAGIC:
        return load_phrec(path)
    if head == b"\x89MCAP0\r\n":
        return load_mcap(path)
    return load_csv(path)


# ---------------------------------------------------------------------------------------------------------------
# .phrec

def _decode_cycle(payload: bytes):
    if len(payload) < _CYCLE_FIXED.size:
        return None
    fixed = _CYCLE_FIXED.unpack_from(payload, 0)
    ns, nc, na = fixed[10], fixed[11], fixed[12]
    if len(payload) != _CYCLE_FIXED.size + 4 * (ns + nc + na):
        return None
    values = struct.unpack_from(f"<{ns + nc + na}f", payload, _CYCLE_FIXED.size)
    return fixed[:10], values[:ns], values[ns:ns + nc], values[ns + nc:]


def _block_payloads(body: bytes) -> List[bytes]:
    """A cycle block (type 5): u16 count, u16 payload length L, then zlib of the count payloads of L bytes
    transposed byte-wise (every cycle's byte 0, then every byte 1, …)."""
    count, length = struct.unpack_from("<HH", body, 0)
    raw = zlib.decompress(body[4:])
    if len(raw) != count * length:
        raise ValueError("cycle block size mismatch")
    arr = np.frombuffer(raw, dtype=np.uint8).reshape(length, count).T
    return [arr[i].tobytes() for i in range(count)]


def load_phrec(path: str) -> Record:
    data = open(path, "rb").read()
    if data[:8] != _PHREC_MAGIC:
        raise ValueError(f"{path}: not a Phalanx session record (bad magic)")
    header = footer = None
    events: List[Any] = []
    fixed_rows, samples, setpoints, aux = [], [], [], []
    bad = skipped = 0
    torn = False
    in_bad = False
    pos = 8
    n = len(data)

    def add(payload: bytes) -> bool:
        c = _decode_cycle(payload)
        if c is None:
            return False
        fixed_rows.append(c[0])
        samples.append(c[1])
        setpoints.append(c[2])
        aux.append(c[3])
        return True

    while pos < n:
        left = n - pos
        if left < 12:
            sync = struct.pack("<I", _SYNC)
            if data[pos:pos + min(left, 4)] == sync[:min(left, 4)]:
                torn = True
                break
        if left >= 4 and struct.unpack_from("<I", data, pos)[0] == _SYNC:
            if left < 12:
                torn = True
                break
            length, rtype = struct.unpack_from("<HB", data, pos + 4)
            if left < 12 + length:
                torn = True
                break
            body = data[pos + 4:pos + 8 + length]
            (crc,) = struct.unpack_from("<I", data, pos + 8 + length)
            if zlib.crc32(body) == crc:
                in_bad = False
                payload = body[4:]
                if rtype == _HEADER:
                    header = json.loads(payload)
                elif rtype == _CYCLE:
                    if not add(payload):
                        bad += 1
                elif rtype == _BLOCK:
                    try:
                        for p in _block_payloads(payload):
                            if not add(p):
                                bad += 1
                    except (ValueError, zlib.error):
                        bad += 1
                elif rtype == _EVENT:
                    events.append(json.loads(payload))
                elif rtype == _FOOTER:
                    footer = json.loads(payload)
                else:
                    bad += 1
                pos += 12 + length
                continue
        skipped += 1
        if not in_bad:
            bad += 1
        in_bad = True
        pos += 1
    if torn:
        skipped += n - pos
    columns: Dict[str, np.ndarray] = {}
    f = np.array(fixed_rows, dtype=np.float64).reshape(len(fixed_rows), len(_CYCLE_FIELDS))
    for i, name in enumerate(_CYCLE_FIELDS):
        columns[name] = f[:, i] if name == "t_s" else f[:, i].astype(np.int64)
    # host_ns needs all 64 bits: take it again without the float round trip.
    columns["host_ns"] = np.array([r[0] for r in fixed_rows], dtype=np.uint64)
    columns["device_time_us"] = np.array([r[2] for r in fixed_rows], dtype=np.uint64)
    h = header if isinstance(header, dict) else {}
    for key, rows, prefix in (("samples", samples, "sample"), ("setpoints", setpoints, "setpoint"),
                              ("aux", aux, "aux")):
        width = len(rows[0]) if rows else 0
        names = list(h.get(key) or [])
        names += [f"{prefix}{i}" for i in range(len(names), width)]
        arr = np.array([r if len(r) == width else (list(r) + [math.nan] * width)[:width] for r in rows],
                       dtype=np.float32).reshape(len(rows), width)
        for i in range(width):
            columns[names[i]] = arr[:, i]
    return Record("phrec", columns, header=header, events=events, footer=footer,
                  integrity={"bad_records": bad, "bytes_skipped": skipped, "torn_tail": torn,
                             "complete": footer is not None})


# ---------------------------------------------------------------------------------------------------------------
# CSV

def load_csv(path: str) -> Record:
    """A CSV with a header row of column names; every value numeric (an empty cell is NaN)."""
    with open(path, newline="") as f:
        reader = csv.reader(f)
        names = next(reader)
        rows = [r for r in reader if r]
    cols: Dict[str, np.ndarray] = {}
    for i, name in enumerate(names):
        cols[name] = np.array([float(r[i]) if i < len(r) and r[i] != "" else math.nan for r in rows],
                              dtype=np.float64)
    return Record("csv", cols)


# ---------------------------------------------------------------------------------------------------------------
# MCAP

class _Cdr:
    """Just enough CDR (XCDR1, either byte order) for the ROS 2 messages the recordings carry."""

    def __init__(self, data: bytes):
        self.d = data
        self.le = data[1] == 1
        self.p = 4

    def _align(self, n: int) -> None:
        self.p += (-(self.p - 4)) % n

    def _get(self, fmt: str, size: int):
        self._align(size)
        v = struct.unpack_from(("<" if self.le else ">") + fmt, self.d, self.p)[0]
        self.p += size
        return v

    def u8(self) -> int:
        v = self.d[self.p]
        self.p += 1
        return v

    def u32(self) -> int:
        return self._get("I", 4)

    def i32(self) -> int:
        return self._get("i", 4)

    def f64(self) -> float:
        return self._get("d", 8)

    def string(self) -> str:
        n = self.u32()
        s = self.d[self.p:self.p + n - 1].decode()
        self.p += n
        return s

    def header(self) -> Dict[str, Any]:
        sec, nsec = self.i32(), self.u32()
        return {"stamp_ns": sec * 1_000_000_000 + nsec, "frame_id": self.string()}

    def f64seq(self) -> List[float]:
        return [self.f64() for _ in range(self.u32())]


def _decode_ros2(schema: str, data: bytes) -> Dict[str, Any]:
    r = _Cdr(data)
    h = r.header()
    if schema == "sensor_msgs/msg/JointState":
        names = [r.string() for _ in range(r.u32())]
        return {"header": h, "name": names, "position": r.f64seq(), "velocity": r.f64seq(), "effort": r.f64seq()}
    if schema == "geometry_msgs/msg/WrenchStamped":
        v = [r.f64() for _ in range(6)]
        return {"header": h, "force": v[:3], "torque": v[3:]}
    if schema == "geometry_msgs/msg/PoseStamped":
        v = [r.f64() for _ in range(7)]
        return {"header": h, "position": v[:3], "orientation": v[3:]}
    if schema == "diagnostic_msgs/msg/DiagnosticArray":
        status = []
        for _ in range(r.u32()):
            level = r.u8()
            name, message, hw = r.string(), r.string(), r.string()
            values = {}
            for _ in range(r.u32()):
                k = r.string()
                values[k] = r.string()
            status.append({"level": level, "name": name, "message": message, "hardware_id": hw, "values": values})
        return {"header": h, "status": status}
    raise ValueError(f"no decoder for {schema}")


def _flatten(msg: Dict[str, Any]) -> Dict[str, float]:
    """A decoded message as named numbers: JointState positions by joint name, wrench as force_x …"""
    out: Dict[str, float] = {}
    if "position" in msg and "name" in msg:
        for n, v in zip(msg["name"], msg["position"]):
            out[n] = v
    elif "force" in msg:
        for axis, v in zip("xyz", msg["force"]):
            out["force_" + axis] = v
        for axis, v in zip("xyz", msg["torque"]):
            out["torque_" + axis] = v
    elif "orientation" in msg:
        for k, v in zip(("x", "y", "z"), msg["position"]):
            out["position_" + k] = v
        for k, v in zip(("qx", "qy", "qz", "qw"), msg["orientation"]):
            out[k] = v
    elif "status" in msg:
        for s in msg["status"]:
            for k, v in s["values"].items():
                try:
                    out[k] = float(v)
                except ValueError:
                    pass
    return out


def load_mcap(path: str) -> Record:
    """Every topic of an MCAP file as named arrays (r.topics[topic][field], plus log_time_ns), and the columns of
    /phalanx/telemetry, /phalanx/command and /phalanx/therapy joined by cycle as r.columns (the CSV's names).
    A file that was never closed (the daemon killed) is read message by message up to its last whole chunk."""
    # The `mcap` package from PyPI: its StreamReader reads records in file order (CRCs validated), so a file the
    # daemon never closed is read up to its end.
    from mcap.exceptions import EndOfFile
    from mcap.records import Channel, Message, Schema
    from mcap.stream_reader import StreamReader

    per_topic: Dict[str, List[Dict[str, Any]]] = {}
    events: List[Any] = []
    header = None
    schemas: Dict[int, str] = {}
    channels: Dict[int, Any] = {}
    torn = False
    with open(path, "rb") as f:
        try:
            for rec in StreamReader(f, validate_crcs=True).records:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec.name
                    continue
                if isinstance(rec, Channel):
                    channels[rec.id] = rec
                    continue
                if not isinstance(rec, Message):
                    continue
                channel = channels[rec.channel_id]
                if channel.message_encoding == "json":
                    msg = json.loads(rec.data)
                    if channel.topic == "/phalanx/events":
                        events.append(msg)
                        continue
                    row = {k: (math.nan if v is None else v) for k, v in msg.items()
                           if v is None or isinstance(v, (int, float))}
                else:
                    row = _flatten(_decode_ros2(schemas.get(channel.schema_id, ""), rec.data))
                row["log_time_ns"] = rec.log_time
                per_topic.setdefault(channel.topic, []).append(row)
        except (EndOfFile, struct.error):
            # No footer: the recording was not closed (the daemon killed), or the file ends inside a record (cut
            # at any byte: a crash mid-write, a truncated copy; the mcap package then fails to unpack the
            # record's header): keep what was read.
            torn = True
    topics: Dict[str, Dict[str, np.ndarray]] = {}
    for topic, rows in per_topic.items():
        keys: List[str] = []
        for r in rows:
            for k in r:
                if k not in keys:
                    keys.append(k)
        topics[topic] = {k: np.array([r.get(k, math.nan) for r in rows],
                                     dtype=np.uint64 if k == "log_time_ns" else np.float64) for k in keys}
    columns: Dict[str, np.ndarray] = {}
    for topic, prefix in (("/phalanx/telemetry", ""), ("/phalanx/command", "cmd_"), ("/phalanx/therapy", "")):
        for k, v in topics.get(topic, {}).items():
            if k == "log_time_ns" or (k == "t_s" and "t_s" in columns):
                continue
            name = prefix + k if k in ("seq", "mode") else k
            columns[name] = v
    return Record("mcap", columns, header=header, events=events, topics=topics, integrity={"torn_tail": torn})
