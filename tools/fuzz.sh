#!/usr/bin/env bash
# Build every libFuzzer target (tests/fuzz/<name>_fuzz.cpp: clang, ASan + UBSan, the fuzz CMake preset), replay
# the committed crash inputs (tests/fuzz/regressions/<name>/), then fuzz each target for SECONDS from its seed
# corpus (tests/fuzz/corpus/<name>/, read only; new inputs go to build/fuzz/corpus/<name>/, kept between runs).
# Prints one line per target: executions, edge coverage (libFuzzer's cov:), corpus size. Fails on any crash,
# leak, sanitizer report or timeout; the input is saved in build/fuzz/artifacts/<name>/.
# Usage: tools/fuzz.sh [SECONDS=6] [TARGET...]        (CI: 6 s each; a report: tools/fuzz.sh 600)
#        PHALANX_FUZZ_RUNS=10000000 tools/fuzz.sh 7200 can   (stop at N executions, SECONDS at most)
set -euo pipefail
cd "$(dirname "$0")/.."
secs="${1:-6}"
shift || true
out=build/fuzz

launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi
cmake --preset fuzz "${launcher[@]}" >/dev/null
cmake --build --preset fuzz --target fuzz_targets -- -j"${PHALANX_FUZZ_JOBS:-2}" >/dev/null

if [ $# -gt 0 ]; then
  targets=("$@")
else
  targets=()
  for src in tests/fuzz/*_fuzz.cpp; do
    n=$(basename "$src" .cpp)
    targets+=("${n%_fuzz}")
  done
fi

runs=()
if [ -n "${PHALANX_FUZZ_RUNS:-}" ]; then runs=(-runs="$PHALANX_FUZZ_RUNS"); fi
status=0
printf '%-16s %12s %8s %8s %8s %s\n' target executions exec/s cov corpus result
for t in "${targets[@]}"; do
  bin="$out/bin/${t}_fuzz"
  seeds="tests/fuzz/corpus/$t"
  work="$out/corpus/$t"
  art="$out/artifacts/$t"
  mkdir -p "$work" "$art"
  log="$out/$t.log"
  # Every committed crash input first: each must now pass (a fixed finding stays fixed).
  if [ -d "tests/fuzz/regressions/$t" ] && [ -n "$(ls -A "tests/fuzz/regressions/$t")" ]; then
    if ! "$bin" -runs=1 tests/fuzz/regressions/"$t"/* >"$out/$t.replay.log" 2>&1; then
      echo "$t: a committed crash input fails again (see $out/$t.replay.log)"
      status=1
      continue
    fi
  fi
  dirs=("$work")
  if [ -d "$seeds" ]; then dirs+=("$seeds"); fi
  rc=0
  nice "$bin" -max_total_time="$secs" "${runs[@]}" -max_len=4096 -timeout=10 -print_final_stats=1 \
    -artifact_prefix="$art/" "${dirs[@]}" >"$log" 2>&1 || rc=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n1)
  eps=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -n1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -n1 | cut -d' ' -f2)
  corpus=$(find "$work" -type f | wc -l)
  result=ok
  if [ "$rc" -ne 0 ]; then
    result="FAIL (rc $rc, $log)"
    status=1
    grep -m3 -E 'ERROR|SUMMARY|runtime error' "$log" || true
  fi
  printf '%-16s %12s %8s %8s %8s %s\n' "$t" "${execs:-?}" "${eps:-?}" "${cov:-?}" "$corpus" "$result"
done
exit "$status"
