#!/usr/bin/env bash
# The Python packages the tests use, from PyPI, pinned. Idempotent. Usage: tools/setup-python.sh
#   fhir.resources 8.1.0 (+ its fhir-core): validates the FHIR export (docs/fhir.md, therapist_flow_test).
set -euo pipefail
PACKAGES=(fhir.resources==8.1.0 fhir-core==1.1.12)
missing=()
for spec in "${PACKAGES[@]}"; do
  name=${spec%%==*}
  want=${spec##*==}
  have=$(python3 -m pip show "$name" 2>/dev/null | sed -n 's/^Version: //p')
  [ "$have" = "$want" ] || missing+=("$spec")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup-python: all ${#PACKAGES[@]} packages present"
  exit 0
fi
echo "setup-python: installing ${missing[*]}"
python3 -m pip install --quiet --break-system-packages "${missing[@]}"
