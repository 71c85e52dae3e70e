#!/usr/bin/env python3
"""Validates a FHIR Bundle (JSON) with the fhir.resources package (an independent implementation of the FHIR
schema, PyPI; tools/setup.sh --test pins it). fhir.resources 8 models FHIR R4B (4.3.0) in its R4B package, the
release it ships closest to R4 (4.0.1); Bundle, Observation and Patient references are the same in both.

Usage: fhir-validate.py BUNDLE.json   exit 0: valid (prints a summary line), 1: invalid (prints the errors),
2: fhir.resources is not installed.
"""
import json
import sys

try:
    from fhir.resources.R4B.bundle import Bundle
    from fhir.resources.R4B.observation import Observation
except ImportError as e:  # pragma: no cover
    print(f"fhir-validate: fhir.resources is not installed ({e}); run tools/setup.sh --test", file=sys.stderr)
    sys.exit(2)


def main() -> int:
    with open(sys.argv[1], encoding="utf-8") as f:
        text = f.read()
    try:
        bundle = Bundle.model_validate_json(text)
        observations = []
        for entry in bundle.entry or []:
            # The bundle model types its entries as generic resources: validate each as what it says it is.
            res = json.loads(entry.resource.model_dump_json()) if entry.resource is not None else None
            if res is None or res.get("resourceType") != "Observation":
                raise ValueError(f"entry {entry.fullUrl}: not an Observation")
            observations.append(Observation.model_validate(res))
    except Exception as e:  # pydantic.ValidationError and the checks above
        print(f"fhir-validate: {sys.argv[1]}: INVALID: {e}")
        return 1
    subjects = sorted({o.subject.reference or o.subject.identifier.value for o in observations})
    print(f"fhir-validate: {sys.argv[1]}: valid Bundle ({bundle.type}) of {len(observations)} Observations, "
          f"subjects {subjects}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
