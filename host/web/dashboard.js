// Phalanx live dashboard: polls /api/samples (50 Hz samples, batched), draws strip charts on canvases (no
// libraries), and sends start/stop/exercise/reset as control-API requests to /api/request. docs/dashboard.md.
'use strict';

const WINDOW_S = 10;          // plotted time window
const POLL_MS = 100;          // poll period: 5 samples per answer at 50 Hz
// One colour per finger (channel), shared by its joints, its flexion, its target and its efforts.
const COLORS = ['#1f77b4', '#d62728', '#2ca02c', '#9467bd', '#ff7f0e', '#8c564b', '#17becf', '#7f7f7f'];
// Line styles: the channel's own trace solid, its target/command dashed; joints by position in the finger.
const DASH = { solid: [], dashed: [6, 4], dotted: [2, 3] };

// "Nice" axis ticks: a step of 1, 2 or 5 × 10^k giving about `count` intervals over [lo, hi].
function niceTicks(lo, hi, count) {
  const raw = (hi - lo) / Math.max(1, count);
  const mag = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= raw) || 10 * mag;
  const first = Math.floor(lo / step) * step, last = Math.ceil(hi / step) * step;
  const ticks = [];
  for (let v = first; v <= last + step / 2; v += step) ticks.push(Math.abs(v) < step / 1e6 ? 0 : v);
  const decimals = Math.max(0, -Math.floor(Math.log10(step) + 1e-9));
  return { lo: first, hi: last, ticks, label: (v) => v.toFixed(decimals) };
}

function tokenFromUrl() {
  const m = /token=([0-9a-f]+)/.exec(window.location.hash);
  if (m) {
    sessionStorage.setItem('phalanx-token', m[1]);
    history.replaceState(null, '', window.location.pathname);  // keep the token out of the address bar
    return m[1];
  }
  return sessionStorage.getItem('phalanx-token') || '';
}
const TOKEN = tokenFromUrl();

// A strip chart: named series of (t, y) over the last WINDOW_S seconds, auto-scaled.
class StripChart {
  constructor(canvas, title) {
    this.canvas = canvas;
    this.ctx = canvas.getContext('2d');
    this.title = title;
    this.reset([], '');
  }
  // styles[i]: {color, dash} of series i (a finger's colour, a dash pattern by role).
  reset(names, unit, styles) {
    this.names = names;
    this.unit = unit;
    this.styles = styles || [];
    this.t = [];
    this.y = names.map(() => []);
  }
  push(t, values) {
    this.t.push(t);
    for (let i = 0; i < this.y.length; ++i) {
      const v = values[i];
      this.y[i].push(typeof v === 'number' && isFinite(v) ? v : NaN);
    }
    const t0 = t - WINDOW_S;
    let drop = 0;
    while (drop < this.t.length && this.t[drop] < t0) ++drop;
    if (drop > 0) {
      this.t.splice(0, drop);
      for (const s of this.y) s.splice(0, drop);
    }
  }
  draw() {
    const c = this.ctx, W = this.canvas.width, H = this.canvas.height;
    const L = 60, R = 150, T = 22, B = 26;
    c.clearRect(0, 0, W, H);
    c.fillStyle = '#222';
    c.font = '13px sans-serif';
    c.fillText(this.title + (this.unit ? ' (' + this.unit + ')' : ''), L, 15);
    if (this.t.length < 2) {
      c.fillStyle = '#888';
      c.fillText('no data', L + 10, T + 30);
      return;
    }
    const t1 = this.t[this.t.length - 1], t0 = t1 - WINDOW_S;
    let lo = Infinity, hi = -Infinity;
    for (const s of this.y) for (const v of s) if (!isNaN(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    if (!isFinite(lo)) { lo = -1; hi = 1; }
    if (hi - lo < 1e-6) { lo -= 1; hi += 1; }
    const axis = niceTicks(lo, hi, 4);
    lo = axis.lo; hi = axis.hi;
    const X = (t) => L + (t - t0) / WINDOW_S * (W - L - R);
    const Y = (v) => T + (hi - v) / (hi - lo) * (H - T - B);
    // grid and axes
    c.strokeStyle = '#e4e4e4';
    c.lineWidth = 1;
    c.fillStyle = '#555';
    c.font = '11px sans-serif';
    for (const v of axis.ticks) {
      c.beginPath(); c.moveTo(L, Y(v)); c.lineTo(W - R, Y(v)); c.stroke();
      c.fillText(axis.label(v), 4, Y(v) + 4);
    }
    for (let s = Math.ceil(t0); s <= t1; s += 2) {
      c.beginPath(); c.moveTo(X(s), T); c.lineTo(X(s), H - B); c.stroke();
      c.fillText(s.toFixed(0) + ' s', X(s) - 8, H - 8);
    }
    c.strokeStyle = '#999';
    c.strokeRect(L, T, W - L - R, H - T - B);
    // series
    for (let i = 0; i < this.y.length; ++i) {
      const style = this.styles[i] || { color: COLORS[i % COLORS.length], dash: DASH.solid };
      const color = style.color;
      c.strokeStyle = color;
      c.lineWidth = 1.6;
      c.setLineDash(style.dash);
      c.beginPath();
      let pen = false;
      for (let k = 0; k < this.t.length; ++k) {
        const v = this.y[i][k];
        if (isNaN(v)) { pen = false; continue; }
        if (pen) c.lineTo(X(this.t[k]), Y(v)); else c.moveTo(X(this.t[k]), Y(v));
        pen = true;
      }
      c.stroke();
      c.setLineDash([]);
      c.fillStyle = color;
      const ly = T + 8 + 12 * i;
      c.setLineDash(style.dash);
      c.beginPath(); c.moveTo(W - R + 6, ly); c.lineTo(W - R + 24, ly); c.stroke();
      c.setLineDash([]);
      c.fillText(this.names[i], W - R + 28, ly + 4);
    }
  }
}

const charts = {
  joints: new StripChart(document.getElementById('plot-joints'), 'joint flexion'),
  channels: new StripChart(document.getElementById('plot-channels'), 'channel flexion q (solid) and target (dashed)'),
  efforts: new StripChart(document.getElementById('plot-efforts'), 'effort measured (solid) and commanded (dashed)'),
};
let lastSeq = 0;
let session = null;
let running = false;

function setField(id, text, bad) {
  const el = document.getElementById(id);
  el.textContent = text;
  el.className = bad === undefined ? '' : (bad ? 'bad' : 'ok');
}

function message(text, isError) {
  const el = document.getElementById('message');
  el.textContent = text;
  el.className = isError ? 'error' : '';
}

function showStatus(st) {
  running = !!st.session_running;
  setField('phase', st.phase || (running ? 'running' : 'none'));
  setField('patient', st.patient || '–');
  setField('device', st.device || '–');
  setField('exercise', st.exercise || '–');
  followExercise(running ? st.exercise : null);
  showGuidance(running ? st.fault_guidance : null);
  setField('mode', st.device_mode || '–');
  // The API gives the latched faults as one comma-separated string ("none" when none).
  let faults = Array.isArray(st.faults) ? st.faults.join(', ') : String(st.faults || '');
  if (faults === 'none') faults = '';
  setField('faults', st.faults === undefined ? '–' : (faults ? faults : 'none'),
           st.faults === undefined ? undefined : faults.length > 0);
  setField('estop', st.estop === undefined ? '–' : (st.estop ? 'PRESSED' : 'released'),
           st.estop === undefined ? undefined : !!st.estop);
  setField('time', typeof st.t_s === 'number' ? st.t_s.toFixed(1) + ' s' : '–');
  setField('limited', st.limited_cycles === undefined ? '–' : String(st.limited_cycles));
  showReplay(st.replay);
  document.getElementById('stop').disabled = !running;
  document.getElementById('reset').disabled = !running;
  document.getElementById('start').disabled = running;
  document.getElementById('pause').disabled = !running || !!st.paused;
  document.getElementById('resume').disabled = !running || !st.paused;
  showPlan(running ? st.plan : null, !!st.paused);
}

// The session plan: where it is (countdown, repetitions) and every step.
function planStepText(s) {
  let t = s.exercise + (s.preset ? ' (preset ' + s.preset + ')' : '') + ', ' + s.duration_s + ' s';
  if (s.target_repetitions > 0) t += ', ' + s.target_repetitions + ' repetitions';
  t += ': ' + s.state;
  if (s.state === 'done') {
    t += ', ' + s.repetitions + ' repetitions in ' + s.counted_s.toFixed(1) + ' s (' +
         (s.ended_by === 'repetitions' ? 'target reached' : 'its duration') + ')';
  }
  return t;
}
function showPlan(p, paused) {
  const box = document.getElementById('plan');
  if (!p || typeof p !== 'object') { box.style.display = 'none'; return; }
  box.style.display = 'block';
  document.getElementById('plan-name').textContent = p.name || '';
  document.getElementById('plan-step').textContent = String(p.step);
  document.getElementById('plan-steps').textContent = String(p.steps);
  document.getElementById('plan-exercise').textContent = p.exercise + (p.preset ? ' (preset ' + p.preset + ')' : '');
  document.getElementById('plan-remaining').textContent = p.finished ? 'no time' : p.remaining_s.toFixed(1);
  document.getElementById('plan-reps').textContent =
      String(p.repetitions) + (p.target_repetitions > 0 ? ' of ' + p.target_repetitions : '');
  document.getElementById('plan-paused').hidden = !paused;
  const list = document.getElementById('plan-list');
  const items = (p.list || []).map(planStepText);
  const key = JSON.stringify(items);
  if (list.dataset.key === key) return;
  list.textContent = '';
  (p.list || []).forEach((s, i) => {
    const li = document.createElement('li');
    li.className = s.state === 'to do' ? 'todo' : s.state;
    li.textContent = items[i];
    list.append(li);
  });
  list.dataset.key = key;
}

// `phalanx record replay FILE --dashboard`: the file, its speed and the replay time over the total; its
// controls are refused by the replay (there is no device).
function showReplay(r) {
  const box = document.getElementById('replay-field');
  box.hidden = !r;
  if (!r) return;
  const t = (v) => (typeof v === 'number' ? v.toFixed(1) : '–');
  document.getElementById('replay').textContent = r.file + ' at ' + r.speed + '× — ' + t(r.t_s) + ' / ' +
    t(r.total_s) + ' s' + (r.finished ? ' (end)' : '');
}

function startSession(meta) {
  session = meta.session;
  const unit = meta.effort_unit || '';
  const ch = meta.channels || [];
  const colorOf = (name) => COLORS[Math.max(0, ch.indexOf(name)) % COLORS.length];
  // Joints take their finger's colour; within a finger the first joint is solid, the next dashed, then dotted.
  const joints = meta.joints || [], jch = meta.joint_channels || [];
  const seen = {};
  const jointStyles = joints.map((j, i) => {
    const c = jch[i] || '';
    const k = seen[c] = (seen[c] === undefined ? 0 : seen[c] + 1);
    return { color: colorOf(c), dash: [DASH.solid, DASH.dashed, DASH.dotted][k % 3] };
  });
  charts.joints.reset(joints, 'deg', jointStyles);
  const own = ch.map((c) => ({ color: colorOf(c), dash: DASH.solid }));
  const paired = ch.map((c) => ({ color: colorOf(c), dash: DASH.dashed }));
  charts.channels.reset(ch.concat(ch.map((c) => c + ' target')), 'deg', own.concat(paired));
  charts.efforts.reset(ch.concat(ch.map((c) => c + ' cmd')), unit, own.concat(paired));
}

// Fault guidance (the daemon's one table: what happened, whether the patient is safe, what to do).
function showGuidance(list) {
  const box = document.getElementById('guidance'), out = document.getElementById('guidance-list');
  if (!Array.isArray(list) || list.length === 0) { box.style.display = 'none'; out.textContent = ''; return; }
  const key = JSON.stringify(list);
  if (out.dataset.key !== key) {
    out.textContent = '';
    for (const g of list) {
      const dl = document.createElement('dl');
      dl.className = 'fault';
      for (const [label, text] of [['fault', g.fault], ['what happened', g.what], ['is the patient safe', g.safe],
                                   ['what to do', g.action]]) {
        const dt = document.createElement('dt'); dt.textContent = label;
        const dd = document.createElement('dd'); dd.textContent = text;
        dl.append(dt, dd);
      }
      out.append(dl);
    }
    out.dataset.key = key;
  }
  box.style.display = 'block';
}

// The presets of the chosen patient, listed in the exercise choice as "preset:<name>".
let profilesById = {};
function showPresets() {
  const sel = document.getElementById('exercise-select');
  const old = document.getElementById('preset-group');
  if (old) old.remove();
  const p = profilesById[document.getElementById('patient-select').value];
  const names = p && p.presets ? Object.keys(p.presets) : [];
  if (names.length === 0) return;
  const g = document.createElement('optgroup');
  g.id = 'preset-group';
  g.label = 'presets of ' + p.patient;
  for (const n of names) {
    const o = document.createElement('option');
    o.value = 'preset:' + n;
    o.textContent = n + ' (' + p.presets[n].exercise + ')';
    g.append(o);
  }
  sel.prepend(g);
}
// The session plans of the chosen patient's profile: "name — N steps, T s".
function showPlans() {
  const sel = document.getElementById('plan-select');
  const keep = sel.value;
  while (sel.options.length > 1) sel.remove(1);
  const p = profilesById[document.getElementById('patient-select').value];
  const plans = p && p.plans ? p.plans : {};
  for (const [n, pl] of Object.entries(plans)) {
    const o = document.createElement('option');
    o.value = n;
    o.textContent = n + ' \u2014 ' + pl.steps + (pl.steps === 1 ? ' step, ' : ' steps, ') + pl.duration_s + ' s';
    sel.append(o);
  }
  if ([...sel.options].some((o) => o.value === keep)) sel.value = keep;
}
/// The exercise choice as request fields: {preset} or {exercise}.
function chosenExercise() {
  const v = document.getElementById('exercise-select').value;
  return v.startsWith('preset:') ? { preset: v.slice(7) } : { exercise: v };
}

// The exercise list shows the running exercise unless the therapist picked another one to change to.
let shownExercise = null;
let exercisePicked = false;
function followExercise(running) {
  const sel = document.getElementById('exercise-select');
  if (running && running !== shownExercise) {
    shownExercise = running;
    exercisePicked = false;
  }
  if (running && !exercisePicked && sel.value !== running) sel.value = running;
}

// The patient picker: the valid profiles of the daemon's --profiles-dir (an invalid one is listed, disabled,
// with its error as the tooltip).
async function loadProfiles() {
  const a = await request({ cmd: 'profiles' }, true);
  if (!a || !a.ok) return;
  const sel = document.getElementById('patient-select');
  const keep = sel.value;
  while (sel.options.length > 1) sel.remove(1);
  profilesById = {};
  for (const p of a.result) {
    const o = document.createElement('option');
    if (p.valid) {
      profilesById[p.patient] = p;
      o.value = p.patient;
      o.textContent = p.patient + ' (' + p.device + ')';
    } else {
      o.value = '';
      o.disabled = true;
      o.textContent = p.file + ' — invalid';
      o.title = p.error;
    }
    sel.append(o);
  }
  if ([...sel.options].some((o) => o.value === keep && !o.disabled)) sel.value = keep;
  showPresets();
  showPlans();
}

async function poll() {
  let full = false;  // a full answer (a fast replay, or a page that was hidden): fetch the rest at once
  try {
    const r = await fetch('api/samples?after=' + lastSeq, { headers: { 'X-Phalanx-Token': TOKEN }, cache: 'no-store' });
    const a = await r.json();
    if (!r.ok) {
      message(a.error || ('HTTP ' + r.status), true);
      return;
    }
    showStatus(a.status || {});
    if (a.meta && a.meta.session && a.meta.session !== session) startSession(a.meta);
    full = a.samples.length >= 500;
    for (const s of a.samples) {
      lastSeq = Math.max(lastSeq, s.seq);
      charts.joints.push(s.t, s.j);
      charts.channels.push(s.t, s.q.concat(s.tg));
      charts.efforts.push(s.t, s.em.concat(s.ec));
    }
    if (a.last_seq < lastSeq) lastSeq = 0;  // the daemon restarted
    for (const c of Object.values(charts)) c.draw();
  } catch (e) {
    message('dashboard: ' + e, true);
  } finally {
    setTimeout(poll, full ? 0 : POLL_MS);
  }
}

// Every control is one control-API request, validated by the daemon exactly as on its UNIX socket.
async function request(body, quiet) {
  try {
    const r = await fetch('api/request', {
      method: 'POST',
      headers: { 'X-Phalanx-Token': TOKEN, 'Content-Type': 'application/json' },
      body: JSON.stringify(body),
    });
    const a = await r.json();
    if (quiet && a.ok) return a;
    if (a.ok) message(body.cmd + ': ok' + (a.result && a.result.record ? ' (' + a.result.record + ')' : ''), false);
    else message(body.cmd + ': ' + (a.error || 'refused'), true);
    return a;
  } catch (e) {
    message(body.cmd + ': ' + e, true);
    return null;
  }
}

document.getElementById('stop').addEventListener('click', () => request({ cmd: 'stop' }));
document.getElementById('reset').addEventListener('click', () => request({ cmd: 'reset' }));
document.getElementById('exercise-select').addEventListener('change', () => { exercisePicked = true; });
document.getElementById('patient-select').addEventListener('focus', loadProfiles);
document.getElementById('patient-select').addEventListener('change', () => { showPresets(); showPlans(); });
document.getElementById('change').addEventListener('click',
  () => request(Object.assign({ cmd: 'exercise' }, chosenExercise())));
document.getElementById('pause').addEventListener('click', () => request({ cmd: 'pause' }));
document.getElementById('resume').addEventListener('click', () => request({ cmd: 'resume' }));
document.getElementById('start').addEventListener('click', () => {
  const body = { cmd: 'start' };
  const named = document.getElementById('plan-select').value;
  const text = document.getElementById('plan-input').value.trim();
  if (named && text) {
    message('start: a plan is chosen and another typed under advanced: clear one of them', true);
    return;
  }
  if (named) {
    body.plan = named;  // the daemon takes the plan from the patient's profile
  } else if (text) {
    try { body.plan = JSON.parse(text); } catch (e) { message('plan: not valid JSON: ' + e.message, true); return; }
  } else {
    Object.assign(body, chosenExercise());
  }
  const p = document.getElementById('patient-select').value;
  if (p) body.patient = p;
  if (document.getElementById('self-training').checked) body.self_training = true;
  request(body);
});
if (!TOKEN) message('no access token: open the URL phalanxd printed (…/#token=…)', true);
else loadProfiles();
poll();
