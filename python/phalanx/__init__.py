"""Phalanx from Python: the client bindings (the servo-loop API, docs/sdk.md) and the record reader
(docs/records.md) share this package."""
