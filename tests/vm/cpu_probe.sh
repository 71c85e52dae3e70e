#!/bin/sh
# Measurement, not a test (no _test.sh suffix): run one command inside the VM while sampling the guest's CPU use
# (/proc/stat every second, and `top -H` per thread), to tell a busy guest from late timers.
# Usage: tools/vm/run.sh --name cpuprobe -- sh tests/vm/cpu_probe.sh COMMAND...
OUT=build/vm/results
mkdir -p $OUT
( prev=""; while :; do set -- $(head -1 /proc/stat); shift; now="$*"
    if [ -n "$prev" ]; then
      echo "$prev $now" | awk '{n=NF/2; for(i=1;i<=n;i++){d=$(i+n)-$i; t+=d; if(i==4||i==5) idle+=d; if(i==6) irq+=d; if(i==7) sirq+=d}
        printf "guest-cpu: busy %5.1f%% (irq %4.1f%%, softirq %4.1f%%) of %d vCPUs\n", 100*(t-idle)/t, 100*irq/t, 100*sirq/t, '"$(nproc)"'}'
    fi; prev="$now"; sleep 1; done ) > /tmp/cpu_probe.stat 2>&1 &
SAMPLER=$!
top -b -H -d 2 -n 200 -w 160 > /tmp/cpu_probe.top 2>&1 &
TOP=$!
"$@"
rc=$?
kill $SAMPLER $TOP 2>/dev/null
cp /tmp/cpu_probe.stat $OUT/cpu_probe.stat; cp /tmp/cpu_probe.top $OUT/cpu_probe.top
echo "== guest CPU per second (see $OUT/cpu_probe.stat):"; cat /tmp/cpu_probe.stat | tr '\n' ';' | cut -c1-3000; echo
echo "== busiest threads (top -H, %CPU summed over the 2 s samples):"
awk '/^ *[0-9]+ /{c[$12]+=$9; n[$12]++} END{for(k in c) printf "%8.1f %s\n", c[k], k}' /tmp/cpu_probe.top | sort -rn | head -15
exit $rc
