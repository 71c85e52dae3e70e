# phalanxd's e-stop input, drive-enable output and sync pulse output on gpio-sim lines (built out of tree by
# tools/vm/gpio-sim.sh), with gpiomon as an independent peer. The checks are in gpio_session.py (its docstring).
exec /usr/bin/python3 tests/vm/gpio_session.py "$@"
