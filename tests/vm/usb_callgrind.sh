# Measurement, not a test (run-all.sh runs only *_test.sh): the host side's instructions per frame over USB bulk
# (libusb) and CDC-ACM, counted by valgrind's callgrind around a real phalanxd in the VM, at 100 Hz (a daemon under
# valgrind in TCG keeps 15-20 Hz; the device's 1 kHz telemetry would fill its IN pool and drop the answers to
# start-up parameters). Output: build/vm/results/{usb,acm}-quiet.callgrind.out; analysis in docs/usb.md.
# Usage (host): tools/vm/run.sh --timeout 900 --name usbcg -- sh tests/vm/usb_callgrind.sh
export PHALANX_VM_USB_WRAP="valgrind --tool=callgrind --callgrind-out-file=build/vm/results/NAME.callgrind.out"
export PHALANX_VM_USB_SECONDS=3
export PHALANX_VM_USB_HZ=100
exec /usr/bin/python3 tests/vm/usb_session.py usb acm
