#!/bin/sh
# Measurement, not a test (no _test.sh suffix, so tools/vm/ci.sh does not run it): how well does this VM keep
# a 1 kHz period, independent of Phalanx? Prints the guest's timer set-up and cyclictest (rt-tests) latencies.
# Usage: tools/vm/run.sh --name probe -- sh tests/vm/timer_probe.sh [LOOPS]   (cyclictest: Debian's rt-tests)
LOOPS=${1:-5000}
mkdir -p /dev/shm 2>/dev/null; mountpoint -q /dev/shm || mount -t tmpfs tmpfs /dev/shm
echo "== cpus: $(nproc); $(grep -m1 'model name' /proc/cpuinfo)"
echo "== clocksource: $(cat /sys/devices/system/clocksource/clocksource0/current_clocksource) (available: $(cat /sys/devices/system/clocksource/clocksource0/available_clocksource))"
echo "== clockevents: $(grep -h 'Clock Event Device' /proc/timer_list | sort | uniq -c | tr -s ' ')"
grep -m2 -E 'hres_active|event_handler' /proc/timer_list
echo "== sched_rt: runtime $(cat /proc/sys/kernel/sched_rt_runtime_us) period $(cat /proc/sys/kernel/sched_rt_period_us)"
echo "== timer_slack (this shell): $(grep -s timerslack /proc/self/status; cat /proc/self/timerslack_ns)"
echo "== cmdline: $(cat /proc/cmdline | cut -c1-200)"
echo "== loadavg: $(cat /proc/loadavg)"
for mode in "fifo80-1thread:-m -p 80 -t 1" "other-1thread:-m -t 1 --policy=other"; do
  name=${mode%%:*}; args=${mode#*:}
  echo "== cyclictest $name ($args -i 1000 -l $LOOPS)"
  cyclictest $args -i 1000 -l "$LOOPS" -q -h 2000 --histfile=/tmp/cyc.$name 2>&1 | tail -5
  # Overflows and the distribution: share of wakes later than 1 ms (a missed 1 kHz period for an absolute timer).
  # Histogram rows: latency in us, then one count per thread (latencies >= 2 ms are only in the overflow count).
  awk -v n="$name" '/^[0-9]/{for(i=2;i<=NF;i++){t[i]+=$i; if($1>=1000) late[i]+=$i; if($1>=200) l200[i]+=$i; if($1>=500) l500[i]+=$i}} END{for(i in t) printf "  %s thread%d: samples < 2 ms %d, >=200us %d, >=500us %d, >=1000us %d\n", n, i-2, t[i], l200[i], l500[i], late[i]}' /tmp/cyc.$name
  grep -E '^# (Max|Min|Avg|Histogram Overflows)' /tmp/cyc.$name
done
