#!/usr/bin/env bash
# Instructions per operation of the telemetry path on this host (callgrind: deterministic, load-independent):
# Phalanx's framed encode and decode (payload + CRC-16 + COBS; decode = StreamDecoder::feed + decodePayload),
# the payload codec alone, and nanopb encoding/decoding the same fields and values (when protocol_bench was built
# with nanopb), all from one run of build/host/bin/protocol_bench's BM_Fixed10k (10 000 calls of each).
# A benchmark, not a test: it prints figures and fails only if the binary or a function is missing.
# Usage: tools/bench/protocol-instructions.sh [path/to/protocol_bench]
set -euo pipefail
cd "$(dirname "$0")/../.."
bin=${1:-build/host/bin/protocol_bench}
out=$(mktemp /tmp/protocol-instructions.XXXXXX)
trap 'rm -f "$out"' EXIT
valgrind --tool=callgrind --callgrind-out-file="$out" "$bin" --benchmark_filter='^BM_Fixed10k' >/dev/null 2>&1
callgrind_annotate --inclusive=yes --threshold=100 "$out" 2>/dev/null | python3 -c '
import re, sys
calls = 10000
names = ["phxFrameEncode", "phxFrameDecode", "phxPayloadEncode", "phxPayloadDecode", "nanopbEncode", "nanopbDecode"]
best = {}
for line in sys.stdin:
    m = re.match(r"\s*([\d,]+) \([^)]*\)\s+\S*?:(\w+)\(.*\[.*\]\s*$", line)
    if m and m.group(2) in names:
        best[m.group(2)] = max(best.get(m.group(2), 0), int(m.group(1).replace(",", "")))
per = {k: v / calls for k, v in best.items()}
missing = [n for n in names[:4] if n not in per]
if missing:
    sys.exit("protocol-instructions: not found in the profile: " + ", ".join(missing))
print("telemetry (64-byte payload, 69-byte frame), instructions per call, callgrind, %d calls each:" % calls)
print("  framed encode (encodeFrame)              %7.0f" % per["phxFrameEncode"])
print("  framed decode (feed + decodePayload)     %7.0f" % per["phxFrameDecode"])
print("  framed encode + decode                   %7.0f" % (per["phxFrameEncode"] + per["phxFrameDecode"]))
print("  payload encode (encodePayload)           %7.0f" % per["phxPayloadEncode"])
print("  payload decode (decodePayload)           %7.0f" % per["phxPayloadDecode"])
if "nanopbEncode" in per and "nanopbDecode" in per:
    print("  nanopb encode (pb_encode)                %7.0f   %.0fx the payload encode" % (per["nanopbEncode"], per["nanopbEncode"] / per["phxPayloadEncode"]))
    print("  nanopb decode (pb_decode)                %7.0f   %.0fx the payload decode" % (per["nanopbDecode"], per["nanopbDecode"] / per["phxPayloadDecode"]))
    print("  nanopb encode + decode vs framed encode + decode: %.1fx" % ((per["nanopbEncode"] + per["nanopbDecode"]) / (per["phxFrameEncode"] + per["phxFrameDecode"])))
else:
    print("  nanopb: not built in (install nanopb and libnanopb-dev, reconfigure)")
'
