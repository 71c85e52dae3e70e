#!/bin/sh
# Runs "$@" with the host CPU weight of the VM lane raised (tools/vm/run.sh; docs/vm-lane.md): the caller has
# started a new session (setsid), so this process heads a new autogroup; its nice value becomes NICE, and so does
# the process's own (for hosts without autogroup scheduling). Never fails: without the right to raise priority
# the command runs unchanged and a note says so.
# Usage: setsid tools/vm/vm-nice.sh NICE COMMAND...
nice=$1; shift
if [ -w /proc/self/autogroup ] && echo "$nice" 2>/dev/null > /proc/self/autogroup; then :; else
  [ -e /proc/self/autogroup ] && echo "vm-nice: cannot set the autogroup's nice to $nice (not root?): the VM runs at the host's normal weight" >&2
fi
renice -n "$nice" -p $$ >/dev/null 2>&1 || echo "vm-nice: cannot renice to $nice: the VM runs at the host's normal priority" >&2
exec "$@"
