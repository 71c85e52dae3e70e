# phalanxd <-> firmware-sim over vcan (CAN-FD and classic CAN), with injected bad frames, bus-off and link-down.
# The scenarios and their checks are in can_session.py (see its docstring).
exec /usr/bin/python3 tests/vm/can_session.py "$@"
