# Helpers for tests/vm/*_test.sh (sourced; POSIX sh). Runs inside the VM lane as root.
IP=/usr/sbin/ip
BIN=build/host/bin
fail() { echo "FAIL: $*"; exit 1; }
# vcan_up NAME [fd]: a fresh virtual CAN bus (mtu 72 = CAN-FD capable with "fd").
vcan_up() {
  $IP link del "$1" 2>/dev/null
  $IP link add "$1" type vcan || fail "cannot create $1"
  [ "$2" = fd ] && { $IP link set "$1" mtu 72 || fail "cannot set CAN-FD mtu on $1"; }
  $IP link set "$1" up || fail "cannot bring $1 up"
}
