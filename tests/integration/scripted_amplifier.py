#!/usr/bin/env python3
"""A scripted load-cell amplifier on pymodbus (PyPI), written apart from the project's own Modbus code: it serves a
signal this script decides, so the bench runner's instrument client is checked against a server it did not write
(tests/integration/bench_realtime_test.cpp). int32 counts, big-endian words, input registers from 0, unit 1, at
--scale SI units per count (docs/modbus.md's default map: 1e-5).

  scripted_amplifier.py --value 0.1234             a constant (a load cell that reads a fixed torque)
  scripted_amplifier.py --value 0 --hang-after-s 2 then, 2 s after the first request, stops answering (requests
                                                   accepted, never answered)

Prints "PORT <n>" once it listens on 127.0.0.1."""
import argparse
import asyncio
import socket
import sys
import time

from pymodbus.datastore import ModbusSlaveContext, ModbusSequentialDataBlock, ModbusServerContext
from pymodbus.server import StartAsyncTcpServer


class ScriptedBlock(ModbusSequentialDataBlock):
    def __init__(self, args):
        super().__init__(1, [0] * 4)  # pymodbus numbers registers from 1 (PDU address 0 is its 1)
        self.args = args
        self.t0 = None  # the first request's time: --hang-after-s counts from it

    def getValues(self, address, count=1):
        if self.t0 is None:
            self.t0 = time.monotonic()
        if self.args.hang_after_s >= 0 and time.monotonic() - self.t0 >= self.args.hang_after_s:
            time.sleep(3600)  # the amplifier hangs: the whole server stops answering
        counts = round(self.args.value / self.args.scale) & 0xFFFFFFFF
        words = [counts >> 16, counts & 0xFFFF, 0, 0]
        first = address - 1
        return words[first:first + count]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--value", type=float, required=True, help="the value served, SI units")
    ap.add_argument("--scale", type=float, default=1e-5)
    ap.add_argument("--hang-after-s", type=float, default=-1.0)
    args = ap.parse_args()
    block = ScriptedBlock(args)
    context = ModbusServerContext(slaves={1: ModbusSlaveContext(ir=block, hr=block)}, single=False)
    port = free_port()
    server = asyncio.ensure_future(StartAsyncTcpServer(context=context, address=("127.0.0.1", port)))
    for _ in range(200):  # until it accepts connections
        await asyncio.sleep(0.02)
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                break
        except OSError:
            continue
    print(f"PORT {port}", flush=True)
    await server


if __name__ == "__main__":
    asyncio.run(main())
