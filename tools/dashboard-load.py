#!/usr/bin/env python3
# Loop figures of a simulated sea_finger session (phalanxd --api, --no-realtime) without and with the dashboard
# polled the way the page polls it (incremental, every 100 ms); two pairs. docs/dashboard.md "Measured".
# Usage: python3 tools/dashboard-load.py   (after building phalanxd)
import json, os, socket, subprocess, time, urllib.request
B=os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'build', 'host', 'bin') + '/'
def api(sock, req):
    s=socket.socket(socket.AF_UNIX); s.connect(sock); s.sendall((json.dumps(req)+'\n').encode())
    buf=b''
    while not buf.endswith(b'\n'): buf+=s.recv(65536)
    return json.loads(buf)
os.makedirs('/tmp/phalanx-dashload', exist_ok=True)
for dash in (False, True, False, True):
    sock='/tmp/phalanx-dashload/a%d.sock'%dash
    args=[B+'phalanxd','--api',sock,'--records-dir','/tmp/phalanx-dashload','--profiles-dir','/tmp/phalanx-dashload','--no-realtime','--device','sim:sea_finger','--scenario','close-open']
    if dash: args+=['--dashboard','127.0.0.1:0']
    p=subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    p.stdout.readline()
    url=p.stdout.readline().split()[1] if dash else None
    api(sock, {'cmd':'start','exercise':'assessment'})
    time.sleep(1.0)
    t0=time.time(); n=0; last=0
    while time.time()-t0 < 5:
        if dash:
            host=url.split('/')[2]; tok=url.split('token=')[1]
            r=urllib.request.Request('http://'+host+'/api/samples?after=%d'%last, headers={'X-Phalanx-Token':tok})
            a=json.loads(urllib.request.urlopen(r).read()); last=a['last_seq']; n+=1
            time.sleep(0.1)
        else:
            time.sleep(0.05)
    s=api(sock,{'cmd':'stop'})['result']
    print('dashboard' if dash else 'no dashboard', 'requests',n, 'cycles',s['cycles'],'seconds',round(s['seconds'],2),'overruns',s['overruns'],'jitter p50/p99/max us',s['period_jitter']['p50_us'],s['period_jitter']['p99_us'],s['period_jitter']['max_us'])
    p.terminate(); p.wait()
