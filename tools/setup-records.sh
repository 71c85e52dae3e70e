#!/usr/bin/env bash
# Python packages the recordings' tests use (tests/records/records_test.py), pinned, from PyPI: the `mcap`
# reader (an independent reader of the MCAP files the daemon writes; it brings zstandard and lz4) and numpy (the
# phalanx.records reader's arrays). Idempotent: installs nothing when the pinned versions are present.
set -euo pipefail
PINNED=(mcap==1.6.0 zstandard==0.25.0 lz4==4.4.5 numpy==2.4.6)
missing=()
for spec in "${PINNED[@]}"; do
  name=${spec%%==*}
  want=${spec#*==}
  have=$(python3 -c "import importlib.metadata as m; print(m.version('$name'))" 2>/dev/null || true)
  [ "$have" = "$want" ] || missing+=("$spec")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup-records: python packages present"
  exit 0
fi
echo "setup-records: pip installing ${missing[*]}"
python3 -m pip install --quiet --break-system-packages "${missing[@]}"
