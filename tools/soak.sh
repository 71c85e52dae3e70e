#!/usr/bin/env bash
# Soak with fault injection and the invariant checker (docs/soak.md): all three simulated devices, a seeded
# schedule of faults, every recording and log checked afterwards.
# Usage: tools/soak.sh [--minutes N] [--seed S] [--out DIR] [--bin BUILD/bin] [--kinds a,b,...] [--prune]
#   e.g. tools/soak.sh --minutes 60 --seed 7 --out /var/tmp/soak-7     (a lab's hour; evidence kept in --out)
#        tools/soak.sh --minutes 1440 --prune --out /var/tmp/soak-day   (records of passing episodes deleted)
# Root is needed for the disk-full fault (a 256 KiB tmpfs is mounted per episode); without it that kind is
# skipped and said so. Exit 0: no invariant broken; 1: violations (listed at the end, and in OUT/report.json).
set -euo pipefail
cd "$(dirname "$0")/.."
exec python3 tests/soak/soak.py "$@"
