# The kernel's SocketCAN works in the VM lane with independent peers (can-utils): classic and CAN-FD frames
# round-trip over vcan, error frames reach sockets that ask for them, and a downed interface refuses writes.
. tests/vm/lib.sh
vcan_up vcan9 fd
timeout 30 candump -n 3 -L vcan9,0:0,#FFFFFFFF > /tmp/dump.txt &
sleep 3  # candump must be listening; starting it in the emulated VM can take seconds
cansend vcan9 123#DEADBEEF || fail "cansend classic"
cansend vcan9 456##1$(printf '%0128d' 0) || fail "cansend CAN-FD 64 bytes"
cansend vcan9 20000040#0000000000000000 || fail "cansend error frame"
wait
grep -q 'vcan9 123#DEADBEEF' /tmp/dump.txt || fail "classic frame not seen: $(cat /tmp/dump.txt)"
grep -q "vcan9 456##" /tmp/dump.txt || fail "CAN-FD frame not seen: $(cat /tmp/dump.txt)"
grep -q '20000040#' /tmp/dump.txt || fail "error frame not seen"
$IP link set vcan9 down
if cansend vcan9 123#00 2>/dev/null; then fail "write on a downed interface succeeded"; fi
$IP link del vcan9
echo "RESULT socketcan: classic, CAN-FD and error frames round-trip on vcan; writes to a downed link fail"
