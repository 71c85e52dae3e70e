# phalanxd <-> firmware-sim over USB: libusb bulk to a FunctionFS device and CDC-ACM, each quiet and with an
# unplug/re-plug mid-session, on a dummy_hcd gadget. The checks are in usb_session.py (see its docstring).
exec /usr/bin/python3 tests/vm/usb_session.py "$@"
