#!/bin/sh
# Runs inside the VM lane (tools/vm/ci.sh), from the repository root, as root in a chroot of the host's root.
# Runs each tests/vm/<name>_test.sh (or only the names given), prints one PASS/FAIL line per test, and exits
# non-zero if any failed. Results and logs go to build/vm/results/.
cd "$(dirname "$0")/../.." || exit 2
mkdir -p build/vm/results
if [ $# -gt 0 ]; then tests="$*"; else tests=$(ls tests/vm/*_test.sh | sed 's#.*/##; s#_test\.sh$##'); fi
failed=0
for t in $tests; do
  t0=$(date +%s.%N)
  if sh "tests/vm/${t}_test.sh" > "build/vm/results/$t.log" 2>&1; then r=PASS; else r=FAIL; failed=$((failed + 1)); fi
  dt=$(echo "$(date +%s.%N) - $t0" | bc)
  echo "vm-test: $r $t (${dt} s)"
  if [ $r = FAIL ]; then tail -40 "build/vm/results/$t.log" | sed 's/^/  | /'; else grep '^RESULT' "build/vm/results/$t.log" | sed 's/^/  /'; fi
done
exit $failed
