# Teleoperation over DDS between two network namespaces with tc netem's delay and loss on their veth pair, under
# Debian's kernel (this build machine's has no netem): every case of tests/dds/teleop_netns_test.sh, whose checks
# are in tests/dds/teleop_check.py. TELEOP_CASES overrides the cases (scheme:delay_ms:loss_pct ...).
# shellcheck disable=SC2086
# Under TCG the device's clock runs at 0.3 to 2/3 of real time and the master takes seconds to start: a case runs
# until the device's clock has passed its hold phase, at most 40 s of master. phalanxd without mlockall (it would fault in every page of the binaries over 9p: docs/vm-lane.md).
# The stable/unstable verdicts are printed, not gated, here: the device clock's speed varies with the host's load,
# so the pen's dynamics against the real-time network delay differ from run to run (a loaded CI run lost the contact
# for 7 % of a passive 10 ms hold that an unloaded run held throughout). Gated: the channel's energy bound, no sample
# refused, the pen's force gone after the remote is killed.
# Its 12 cases and the remote-killed case take 9-12 min under TCG (a case whose device stalled runs again), so it boots on its own (tools/vm/ci.sh):
# vm-lane: own boot, timeout 1200
TELEOP_STABILITY_PRINTED_ONLY=1 TELEOP_SECONDS=${TELEOP_SECONDS:-40} TELEOP_DAEMON_ARGS=${TELEOP_DAEMON_ARGS:---no-realtime} exec bash tests/dds/teleop_netns_test.sh build/host/bin ${TELEOP_CASES:-}
