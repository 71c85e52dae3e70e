#!/usr/bin/env bash
# Build the protocol decoder fuzz target with clang + libFuzzer (+ ASan/UBSan) and run it for N seconds.
# Usage: tools/fuzz.sh [seconds=60]
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-60}"
out=build/fuzz
mkdir -p "$out/corpus"
clang++ -std=c++17 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all \
  -Icommon/include tests/fuzz/decoder_fuzz.cpp common/src/protocol/codec.cpp -o "$out/decoder_fuzz"
"$out/decoder_fuzz" -max_total_time="$secs" -max_len=512 -print_final_stats=1 "$out/corpus" 2>&1 | tail -n 12
