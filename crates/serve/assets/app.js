// vfxgraph studio: the page. Plain ES2020, no build step, no network beyond this server.
// State comes from GET /api/state; live changes from the server-sent events of /api/events.
'use strict';

const $ = (id) => document.getElementById(id);
const studio = {
  state: null,        // the last /api/state
  live: {},           // node id -> live counts (updated by events)
  running: false,
  selected: null,     // node id in the panel
  frameIdx: 0,        // index into the graph's frames (shared by the viewers)
  latencies: [],      // ms from the engine's event to its DOM update
  readyAt: null,      // performance.now() when the first state was drawn
  marks: { frames: [] },
  marksNode: null,
  tri: null,
  images: new Map(),  // url -> loaded HTMLImageElement
  seenStates: {},     // node id -> the states it showed, in order
  frames: [],         // the graph's frames, or (without a `frames:` range) its outputs'
  paramUndo: [],      // param edits to undo: {node, param, value before}
  paramRedo: [],
  defUndo: [],        // the definer's marks before each change (JSON)
  defRedo: [],
};
window.studio = studio;
// Script errors, kept for the page's own tests (and shown in the status line).
studio.errors = [];
window.addEventListener('error', (e) => studio.errors.push(String(e.message)));
window.addEventListener('unhandledrejection', (e) => studio.errors.push(String(e.reason && e.reason.stack || e.reason)));

async function api(method, url, body) {
  const opt = { method, headers: {} };
  // Every change carries a JSON body: the server refuses any other (a cross-site page cannot
  // send one without a preflight).
  if (body === undefined && method !== 'GET') body = {};
  if (body !== undefined) {
    opt.headers['Content-Type'] = 'application/json';
    opt.body = JSON.stringify(body);
  }
  const r = await fetch(url, opt);
  const ct = r.headers.get('Content-Type') || '';
  const data = ct.includes('json') ? await r.json() : await r.text();
  if (!r.ok) {
    const e = new Error((data && data.error) || r.statusText);
    e.data = data;
    e.status = r.status;
    throw e;
  }
  return data;
}

const esc = (s) => String(s ?? '').replace(/[&<>"]/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;' }[c]));
const nodes = () => (studio.state && studio.state.graph ? studio.state.graph.nodes : []);
const frames = () => studio.frames;
const nodeById = (id) => nodes().find((n) => n.id === id);

// ----------------------------------------------------------------------------- state & events

async function refresh() {
  const s = await api('GET', '/api/state');
  if (studio.state && s.runs !== studio.state.runs) studio.trackErr = null;
  studio.state = s;
  studio.running = s.running;
  studio.live = s.live || {};
  if (s.running && s.run_started_at) studio.runStart = s.run_started_at;
  renderAll();
  if (studio.readyAt === null) studio.readyAt = performance.now();
  if (!studio.displays) loadDisplays();
}

// The display/view transforms of the graph's OpenColorIO config, offered beside the sRGB
// curve: the previews then come through the chosen view (GET /api/colour, /api/image?display=).
async function loadDisplays() {
  studio.displays = [];
  let c;
  try { c = await api('GET', '/api/colour'); } catch (e) { studio.displays = null; return; }
  const sel = $('display');
  sel.title = `OpenColorIO: ${c.config}; the values are ${c.working_space}`;
  for (const d of c.displays) {
    for (const v of d.views) {
      const o = document.createElement('option');
      o.value = JSON.stringify([d.display, v]);
      o.textContent = `${d.display} / ${v}`;
      sel.appendChild(o);
      studio.displays.push([d.display, v]);
    }
  }
}

function connect() {
  const es = new EventSource('/api/events');
  es.onmessage = (m) => {
    const ev = JSON.parse(m.data);
    handle(ev);
  };
  es.onerror = () => { $('status').textContent = 'disconnected — retrying'; };
  es.onopen = () => refresh();
}

const emptyLive = () => ({ running: 0, ran: 0, cached: 0, failed: 0, skipped: 0, progress: 0 });

function handle(ev) {
  const k = ev.kind;
  if (k === 'state') { refresh(); return; }
  if (k === 'run_started') {
    studio.running = true;
    studio.runStart = ev.started_at || ev.t;
    studio.live = {};
    studio.failureShownFor = null;
    $('failure').hidden = true;
    for (const n of nodes()) studio.live[n.id] = emptyLive();
    renderStatus();
    for (const n of nodes()) renderNode(n.id);
  } else if (k === 'run_done') {
    studio.running = false;
    studio.stopped = !!ev.stopped;
    renderStatus();
  } else if (k === 'run_error') {
    $('status').textContent = 'run failed to start: ' + ev.error;
  } else if (k === 'started' || k === 'progress' || k === 'finished') {
    const l = studio.live[ev.node] || (studio.live[ev.node] = emptyLive());
    if (k === 'started') l.running += 1;
    if (k === 'progress' && ev.frame === null) l.progress = ev.fraction;
    if (k === 'finished') {
      if (ev.status !== 'cached' && ev.status !== 'skipped') l.running = Math.max(0, l.running - 1);
      l[ev.status] += 1;
      if (ev.status === 'ran' && ev.frame === null) l.progress = 1;
    }
    renderNode(ev.node);
    if (k === 'started') followNode(ev.node);
    renderProgress();
  }
  // The DOM now shows the event: how long since the engine reported it.
  const lat = Date.now() - ev.t;
  studio.latencies.push(lat);
  document.body.dataset.lastEvent = ev.seq;
}

function renderAll() {
  const s = studio.state;
  $('file').textContent = s.file.split(/[\\/]/).pop();
  $('file').title = s.file;
  $('sets').textContent = s.sets.length ? s.sets.map((x) => '--set ' + x).join(' ') : '';
  $('sets').title = $('sets').textContent;
  const diag = $('diagnostics');
  if (s.diagnostics.length) {
    diag.hidden = false;
    $('diag-list').innerHTML = s.diagnostics.map((d) => `<li class="diag">${esc(d.text)}${d.help ? '\n  help: ' + esc(d.help) : ''}</li>`).join('');
  } else {
    diag.hidden = true;
  }
  renderStatus();
  renderGraph();
  renderPanel();
  renderFailure();
  deriveFrames().then(() => {
    if (!studio.selected) renderPanel();
    fillOutputs();
    fillDefiner();
    fillSolve();
  });
}

// The instances of the graph, and those done, failed or running now (from the live counts).
function runCounts() {
  let total = 0, done = 0, failed = 0;
  const running = [];
  for (const n of nodes()) {
    total += n.instances;
    const l = studio.live[n.id];
    if (!l) continue;
    done += l.ran + l.cached + l.failed + l.skipped;
    failed += l.failed;
    if (l.running > 0) running.push(n.id);
  }
  return { total, done, failed, running };
}

const secs = (ms) => (ms < 60000 ? (ms / 1000).toFixed(1) + ' s' : Math.floor(ms / 60000) + ' min ' + Math.round((ms % 60000) / 1000) + ' s');

// The header's progress while a run goes: instances done / total, the running nodes, the
// elapsed time and an estimate of the time left (elapsed × left / done).
function renderProgress() {
  const p = $('progress');
  if (!studio.running) { p.hidden = true; return; }
  p.hidden = false;
  const c = runCounts();
  const el = Date.now() - (studio.runStart || Date.now());
  const left = c.done > 0 && c.done < c.total ? (el * (c.total - c.done)) / c.done : null;
  $('progress-bar').firstElementChild.style.width = `${(100 * c.done) / Math.max(1, c.total)}%`;
  const names = c.running.length > 3 ? c.running.slice(0, 3).join(', ') + ` +${c.running.length - 3}` : c.running.join(', ');
  $('progress-text').textContent = `${c.done}/${c.total} instances · ${names ? 'running ' + names + ' · ' : ''}${secs(el)}${left !== null ? ' · ~' + secs(left) + ' left' : ''}${c.failed ? ` · ${c.failed} failed` : ''}`;
  p.dataset.done = c.done;
  p.dataset.total = c.total;
  p.dataset.running = c.running.join(',');
}
setInterval(() => { if (studio.running) renderProgress(); }, 250);

function renderStatus() {
  const s = studio.state;
  let t, outcome = '';
  if (!s.graph) t = 'graph does not load';
  else if (studio.running) t = 'running…';
  else {
    const c = { cached: 0, run: 0, blocked: 0 };
    for (const p of s.plan) c[p.status] += 1;
    t = `plan: ${c.cached} cached, ${c.run} to run, ${c.blocked} waiting`;
    const r = s.last_run;
    if (r) {
      if (r.stopped && !r.failures.length) { outcome = 'stopped'; t = `stopped after ${r.wall_seconds.toFixed(2)} s, ${r.ran} ran · ` + t; }
      else if (r.failed) {
        outcome = 'failed';
        const ids = [...new Set(r.failures.map((f) => f.id))];
        t = `failed: ${ids.join(', ') || 'an input'} · ` + t;
      } else { outcome = 'ok'; t += ` · last run ${r.wall_seconds.toFixed(2)} s, ${r.ran} ran`; }
    }
  }
  $('status').textContent = t;
  $('status').title = t;
  $('status').dataset.outcome = outcome;
  $('status').dataset.running = studio.running ? '1' : '0';
  $('run').disabled = studio.running || !s.graph;
  $('cancel').disabled = !studio.running;
  renderProgress();
}

// The failure panel: opens by itself after a run with failed instances, names each failed
// node with its message (the engine's reason); a click on a name shows the node.
function renderFailure() {
  const r = studio.state.last_run;
  const box = $('failure');
  if (!r || !r.failures || !r.failures.length || studio.running) { box.hidden = true; return; }
  if (studio.failureShownFor === studio.state.runs) return;
  studio.failureShownFor = studio.state.runs;
  const byNode = {};
  for (const f of r.failures) (byNode[f.id] = byNode[f.id] || []).push(f);
  $('failure-title').textContent = `The run failed: ${Object.keys(byNode).join(', ')}`;
  $('failure-body').innerHTML = Object.entries(byNode).map(([id, fs]) => {
    const msgs = [...new Set(fs.map((f) => f.message))];
    const fr = fs[0].frame === null ? '' : ` — frame${fs.length > 1 ? 's' : ''} ${fs.slice(0, 8).map((f) => f.frame).join(', ')}${fs.length > 8 ? ', …' : ''}`;
    return `<div class="failed-node" data-id="${esc(id)}"><a href="#" data-show="${esc(id)}"><b>${esc(id)}</b></a> <small>(${esc(fs[0].type)})${fr}</small>${msgs.map((m) => `<pre>${esc(m)}</pre>`).join('')}</div>`;
  }).join('');
  box.hidden = false;
  box.querySelectorAll('a[data-show]').forEach((a) => a.addEventListener('click', (e) => {
    e.preventDefault();
    showView('graph');
    select(a.dataset.show);
    followNode(a.dataset.show, true);
  }));
}

// ----------------------------------------------------------------------------- graph view

const NW = 176, NH = 50, GX = 74, GY = 20, DH = 12;

// A layered layout of our own (Sugiyama): rank = longest path from a source; an edge that
// spans several ranks gets a waypoint in each rank between (so it runs between the nodes of
// those ranks, never through one); the order in each rank comes from barycentre sweeps
// down and up; nodes and waypoints are stacked in their column, columns centred.
function layout(ns) {
  const rank = {};
  const byId = Object.fromEntries(ns.map((n) => [n.id, n]));
  const rankOf = (id, seen = new Set()) => {
    if (rank[id] !== undefined) return rank[id];
    if (seen.has(id)) return 0;
    seen.add(id);
    const ins = byId[id].inputs.filter((e) => byId[e.from]).map((e) => rankOf(e.from, seen) + 1);
    return (rank[id] = ins.length ? Math.max(...ins) : 0);
  };
  ns.forEach((n) => rankOf(n.id));
  const cols = [];
  const items = {}; // id -> {id, rank, ins: [ids], outs: [ids], dummy}
  const add = (id, r, dummy) => { items[id] = { id, rank: r, ins: [], outs: [], dummy }; (cols[r] = cols[r] || []).push(id); };
  ns.forEach((n) => add(n.id, rank[n.id], false));
  const chains = []; // per edge: the ids from source to target
  let k = 0;
  for (const n of ns) {
    n.inputs.forEach((e, ei) => {
      if (!byId[e.from]) return;
      const chain = [e.from];
      for (let r = rank[e.from] + 1; r < rank[n.id]; r++) {
        const d = `~${k++}`;
        add(d, r, true);
        chain.push(d);
      }
      chain.push(n.id);
      for (let i = 0; i + 1 < chain.length; i++) { items[chain[i]].outs.push(chain[i + 1]); items[chain[i + 1]].ins.push(chain[i]); }
      chains.push({ from: e.from, to: n.id, e, ei, chain });
    });
  }
  for (let c = 0; c < cols.length; c++) cols[c] = cols[c] || [];
  const order = {};
  cols.forEach((col) => col.forEach((id, i) => (order[id] = i)));
  const sweep = (down) => {
    const rs = [...cols.keys()];
    if (!down) rs.reverse();
    for (const r of rs) {
      const col = cols[r];
      const bary = (id) => {
        const nb = down ? items[id].ins : items[id].outs;
        return nb.length ? nb.reduce((a, b) => a + order[b], 0) / nb.length : order[id];
      };
      const b = Object.fromEntries(col.map((id) => [id, bary(id)]));
      col.sort((x, y) => b[x] - b[y] || order[x] - order[y]);
      col.forEach((id, i) => (order[id] = i));
    }
  };
  for (let it = 0; it < 6; it++) sweep(it % 2 === 0);
  const hOf = (id) => (items[id].dummy ? DH : NH);
  const colH = cols.map((col) => col.reduce((a, id) => a + hOf(id) + GY, -GY));
  const maxH = Math.max(NH, ...colH);
  const pos = {};
  cols.forEach((col, r) => {
    let y = 10 + (maxH - colH[r]) / 2;
    for (const id of col) {
      pos[id] = { x: 10 + r * (NW + GX), y, w: NW, h: hOf(id), dummy: items[id].dummy };
      y += hOf(id) + GY;
    }
  });
  return { pos, chains, width: 20 + cols.length * (NW + GX) - GX, height: 20 + maxH };
}

function planOf(id) {
  return studio.state.plan.filter((p) => p.id === id);
}

// A node's state: live during (and after) a run, else the plan's.
function nodeState(id) {
  const n = nodeById(id);
  const plan = planOf(id);
  const total = n.instances;
  const l = studio.live[id];
  if (studio.running && l) {
    const done = l.ran + l.cached;
    let st = 'run';
    if (l.failed) st = 'failed';
    else if (l.running > 0) st = 'running';
    else if (done === total) st = l.ran ? 'ran' : 'cached';
    else if (l.skipped) st = 'failed';
    return { st, done, total, progress: total > 1 ? done / total : l.progress };
  }
  const lastFailed = studio.state.last_run && studio.state.last_run.nodes.some((x) => x.id === id && x.status === 'failed');
  const cached = plan.filter((p) => p.status === 'cached').length;
  let st = 'cached';
  if (plan.some((p) => p.status === 'run')) st = 'run';
  else if (plan.some((p) => p.status === 'blocked')) st = 'blocked';
  if (lastFailed && st !== 'cached') st = 'failed';
  return { st, done: cached, total, progress: cached / Math.max(1, total) };
}

// Where a port sits on its node's box: inputs on the left edge, outputs on the right.
function portY(p, i, count) { return p.y + ((i + 1) * p.h) / (count + 1); }

function renderGraph() {
  const root = $('graph-root');
  const ns = nodes();
  if (!ns.length) { root.innerHTML = ''; return; }
  const key = JSON.stringify(ns.map((n) => [n.id, n.type, n.inputs.map((e) => e.from + '.' + e.from_port + '>' + e.port)]));
  const L = layout(ns);
  studio.pos = L.pos;
  studio.graphSize = { w: L.width, h: L.height };
  const { pos } = L;
  let h = '';
  const pts = [];
  for (const c of L.chains) {
    const a = pos[c.from], b = pos[c.to];
    const src = nodeById(c.from), dst = nodeById(c.to);
    const oi = Math.max(0, src.outputs.findIndex((p) => p.name === c.e.from_port));
    const ii = Math.max(0, dst.input_ports.findIndex((p) => p.name === c.e.port));
    const p = [[a.x + a.w, portY(a, oi, src.outputs.length)]];
    for (const d of c.chain.slice(1, -1)) { const q = pos[d]; p.push([q.x, q.y + q.h / 2], [q.x + q.w, q.y + q.h / 2]); }
    p.push([b.x, portY(b, ii, dst.input_ports.length)]);
    let d = `M${p[0][0]},${p[0][1]}`;
    for (let i = 1; i < p.length; i++) {
      const [x0, y0] = p[i - 1], [x1, y1] = p[i];
      if (y0 === y1 || i % 2 === 0) d += ` L${x1},${y1}`; // along a waypoint: straight
      else { const mx = (x0 + x1) / 2; d += ` C${mx},${y0} ${mx},${y1} ${x1},${y1}`; }
    }
    pts.push(p);
    h += `<path class="edge" data-from="${esc(c.from)}" data-to="${esc(c.to)}" d="${d}"><title>${esc(c.from + '.' + c.e.from_port + ' → ' + c.to + '.' + c.e.port)}</title></path>`;
  }
  studio.edgePoints = pts;
  for (const n of ns) {
    const p = pos[n.id];
    const ports = n.input_ports.map((q, i) => {
      const y = portY(p, i, n.input_ports.length) - p.y;
      return `<circle class="port in" cx="0" cy="${y}" r="3.5"><title>input ${esc(q.name)}: ${esc(q.type)}</title></circle><text class="port-label" x="-6" y="${y + 3}" text-anchor="end">${esc(q.name)}</text>`;
    }).join('') + n.outputs.map((q, i) => {
      const y = portY(p, i, n.outputs.length) - p.y;
      return `<circle class="port out" cx="${p.w}" cy="${y}" r="3.5"><title>output ${esc(q.name)}: ${esc(q.type)}</title></circle><text class="port-label" x="${p.w + 6}" y="${y + 3}">${esc(q.name)}</text>`;
    }).join('');
    h += `<g class="node" id="node-${esc(n.id)}" data-id="${esc(n.id)}" transform="translate(${p.x},${p.y})">
      <rect class="box" width="${p.w}" height="${p.h}"></rect>
      <text x="9" y="17">${esc(n.id)}</text><text x="9" y="31" opacity=".75">${esc(n.type)}</text>
      <text class="count" x="${p.w - 8}" y="17" text-anchor="end"></text>
      ${n.instances > 1 ? `<rect class="track" x="6" y="${p.h - 9}" height="4" width="${p.w - 12}"></rect>` : ''}
      <rect class="bar" x="6" y="${p.h - 9}" height="4" width="0"></rect>${ports}</g>`;
  }
  root.innerHTML = h;
  root.querySelectorAll('.node').forEach((g) => g.addEventListener('click', () => select(g.dataset.id)));
  for (const n of ns) renderNode(n.id);
  // A new graph (or the first): fit it to the view; a re-render keeps the user's view.
  if (studio.graphKey !== key) { studio.graphKey = key; fitGraph(); } else applyGraphView();
}

function renderNode(id) {
  const g = document.getElementById('node-' + id);
  if (!g || !studio.state) return;
  const s = nodeState(id);
  if (g.dataset.state !== s.st) (studio.seenStates[id] = studio.seenStates[id] || []).push(s.st);
  g.dataset.state = s.st;
  g.classList.toggle('selected', studio.selected === id);
  g.querySelector('.count').textContent = s.total > 1 ? `${s.done}/${s.total}` : '';
  g.querySelector('.bar').setAttribute('width', String(Math.round((NW - 12) * Math.min(1, s.progress || 0))));
  g.dataset.progress = (s.progress || 0).toFixed(3);
}

// The graph's view: translate (x, y) then scale k, on the SVG's root group.
const gview = { x: 0, y: 0, k: 1 };
studio.gview = gview;
function applyGraphView() {
  $('graph-root').setAttribute('transform', `translate(${gview.x},${gview.y}) scale(${gview.k})`);
}
function fitGraph() {
  const svg = $('graph'), r = svg.getBoundingClientRect(), sz = studio.graphSize;
  if (!sz || r.width < 10 || r.height < 10) { studio.needFit = true; return; }
  studio.needFit = false;
  // Room for the toolbar above and the legend below.
  const top = 36, bottom = 34, side = 16;
  const k = Math.min((r.width - 2 * side) / sz.w, (r.height - top - bottom) / sz.h, 1.6);
  gview.k = Math.max(0.05, k);
  gview.x = (r.width - sz.w * gview.k) / 2;
  gview.y = top + (r.height - top - bottom - sz.h * gview.k) / 2;
  applyGraphView();
}
studio.fitGraph = fitGraph;
function zoomGraph(f, cx, cy) {
  const r = $('graph').getBoundingClientRect();
  if (cx === undefined) { cx = r.width / 2; cy = r.height / 2; }
  const k = Math.min(8, Math.max(0.05, gview.k * f));
  gview.x = cx - ((cx - gview.x) * k) / gview.k;
  gview.y = cy - ((cy - gview.y) * k) / gview.k;
  gview.k = k;
  applyGraphView();
}
// Brings node `id` into view (centred) when it is outside it; `force`: centre it anyway.
function followNode(id, force) {
  if (!force && !$('g-follow').checked) return;
  const p = studio.pos && studio.pos[id];
  if (!p) return;
  const r = $('graph').getBoundingClientRect();
  if (r.width < 10) return;
  const x0 = gview.x + p.x * gview.k, y0 = gview.y + p.y * gview.k;
  const x1 = x0 + p.w * gview.k, y1 = y0 + p.h * gview.k;
  if (!force && x0 >= 0 && y0 >= 30 && x1 <= r.width && y1 <= r.height - 30) return;
  gview.x = r.width / 2 - (p.x + p.w / 2) * gview.k;
  gview.y = r.height / 2 - (p.y + p.h / 2) * gview.k;
  applyGraphView();
}

function graphEvents() {
  const svg = $('graph');
  let drag = null;
  svg.addEventListener('mousedown', (e) => {
    if (e.button !== 0 || e.target.closest('.node')) return;
    drag = { x: e.clientX, y: e.clientY, gx: gview.x, gy: gview.y };
    svg.classList.add('panning');
  });
  window.addEventListener('mousemove', (e) => {
    if (!drag) return;
    gview.x = drag.gx + e.clientX - drag.x;
    gview.y = drag.gy + e.clientY - drag.y;
    applyGraphView();
  });
  window.addEventListener('mouseup', () => { drag = null; svg.classList.remove('panning'); });
  svg.addEventListener('wheel', (e) => {
    e.preventDefault();
    const r = svg.getBoundingClientRect();
    zoomGraph(e.deltaY > 0 ? 1 / 1.15 : 1.15, e.clientX - r.left, e.clientY - r.top);
  }, { passive: false });
  $('g-fit').addEventListener('click', fitGraph);
  $('g-in').addEventListener('click', () => zoomGraph(1.25));
  $('g-out').addEventListener('click', () => zoomGraph(1 / 1.25));
  $('g-one').addEventListener('click', () => { const k = 1 / gview.k; zoomGraph(k); });
  window.addEventListener('resize', () => { if (!$('view-graph').hidden) fitGraph(); });
}

function select(id) {
  studio.selected = id;
  nodes().forEach((n) => renderNode(n.id));
  document.querySelectorAll('.edge').forEach((e) => e.classList.toggle('hl', e.dataset.from === id || e.dataset.to === id));
  renderPanel();
}

// The param's input: a slider and a number for a bounded int/float, a menu for a choice, a
// checkbox for a bool, else text. A change applies on Enter (text, number), on release
// (slider) or at once (menu, checkbox).
function paramInput(p) {
  const v = p.value ?? '';
  const name = esc(p.name);
  if (p.choices) {
    return `<select data-param="${name}">${p.choices.map((c) => `<option ${v === c || v === JSON.stringify(c) ? 'selected' : ''}>${esc(c)}</option>`).join('')}</select>`;
  }
  if (p.kind === 'bool') return `<input type="checkbox" data-param="${name}" ${v === 'true' ? 'checked' : ''}>`;
  if ((p.kind === 'int' || p.kind === 'float') && p.min !== null && p.max !== null && p.max - p.min <= 1e6) {
    const step = p.kind === 'int' ? 1 : (p.max - p.min) / 200;
    return `<input type="range" data-slider="${name}" min="${p.min}" max="${p.max}" step="${step}" value="${esc(v)}"> <input type="text" inputmode="decimal" data-param="${name}" value="${esc(v)}">`;
  }
  if (p.kind === 'int' || p.kind === 'float') return `<input type="text" inputmode="decimal" data-param="${name}" value="${esc(v)}" placeholder="${esc(p.default ?? '')}">`;
  return `<input type="text" data-param="${name}" value="${esc(v)}" placeholder="${esc(p.default ?? '')}">`;
}

const overrideOf = (node, param) => {
  const pre = `${node}.${param}=`;
  const s = (studio.state.sets || []).find((x) => x.startsWith(pre));
  return s === undefined ? null : s.slice(pre.length);
};

// Sets (or with null resets) an override; records the previous one for undo.
async function setParam(node, param, value, record = true) {
  const prev = overrideOf(node, param);
  try {
    await api('POST', '/api/params', { node, param, value });
    if (record) { studio.paramUndo.push({ node, param, value: prev }); studio.paramRedo = []; }
    paramMsg(node, esc(value === null ? `${param} reset to the file's value` : `${param} = ${value} (not in the file yet: "save to file")`));
    return true;
  } catch (e) {
    paramMsg(node, `<span class="err">${esc(e.message)}</span>`);
    return false;
  }
}
// The panel's message about the last edit; kept over the panel's re-renders (each state).
function paramMsg(node, html, saved) {
  studio.paramMsg = { node, html, saved: saved || '' };
  const m = $('param-msg');
  if (m) { m.innerHTML = html; m.dataset.saved = saved || ''; }
}

async function undoParam(redo) {
  const from = redo ? studio.paramRedo : studio.paramUndo;
  const to = redo ? studio.paramUndo : studio.paramRedo;
  const u = from.pop();
  if (!u) return;
  const cur = overrideOf(u.node, u.param);
  if (await setParam(u.node, u.param, u.value, false)) to.push({ node: u.node, param: u.param, value: cur });
}
studio.undoParam = undoParam;

function renderPanel() {
  const el = $('panel');
  const n = studio.selected && nodeById(studio.selected);
  if (!n) { el.innerHTML = overviewPanel(); return; }
  const reasons = {};
  for (const p of planOf(n.id)) (reasons[p.status + ': ' + p.reason] = reasons[p.status + ': ' + p.reason] || []).push(p.frame);
  const last = studio.state.last_run ? studio.state.last_run.nodes.filter((x) => x.id === n.id) : [];
  const lastReasons = {};
  for (const p of last) (lastReasons[p.status + ': ' + p.reason] = lastReasons[p.status + ': ' + p.reason] || []).push(p.frame);
  const fr = (l) => (l[0] === null ? '' : ` (frames ${l.length > 6 ? l.slice(0, 6).join(', ') + ', …' : l.join(', ')})`);
  const params = n.params.map((p) => {
    const edited = overrideOf(n.id, p.name) !== null;
    return `<tr class="${edited ? 'edited' : ''}" data-row="${esc(p.name)}"><td title="${esc(p.doc)}"><b>${esc(p.name)}</b><br><small>${esc(p.type)}${p.affects_output ? '' : ' · cosmetic'}</small></td>
      <td class="pv">${paramInput(p)}${edited ? ` <button data-reset="${esc(p.name)}" title="back to the file's value">×</button> <button data-save="${esc(p.name)}" title="write this value into the graph file (only this value changes; comments kept)">save to file</button>` : ''}<br><small class="hint">${esc(p.doc)}</small></td></tr>`;
  }).join('');
  el.innerHTML = `<h3>${esc(n.id)} <small>${esc(n.type)} v${n.version}</small></h3>
    <p>${esc(n.doc)}</p>
    <p>${n.per_frame ? `per frame: ${n.instances} instances` : 'runs once'} · line ${n.line}</p>
    <h4>Params <button id="param-undo" title="undo the last param edit (Ctrl+Z)" ${studio.paramUndo.length ? '' : 'disabled'}>Undo</button> <button id="param-redo" ${studio.paramRedo.length ? '' : 'disabled'}>Redo</button></h4>
    <p class="hint">Enter applies; sliders apply on release.</p>
    <table>${params}</table><p id="param-msg"></p>
    <h4>Plan</h4><ul id="reasons">${Object.entries(reasons).map(([r, l]) => `<li>${esc(r)}${fr(l)}</li>`).join('')}</ul>
    <h4>Last run</h4><ul>${Object.entries(lastReasons).map(([r, l]) => `<li>${esc(r)}${fr(l)}</li>`).join('') || '<li>not run here yet</li>'}</ul>
    <h4>Inputs</h4><ul>${n.input_ports.map((p) => {
      const e = n.inputs.find((x) => x.port === p.name);
      return `<li><b>${esc(p.name)}</b>: ${esc(p.type)} ← ${e ? esc(e.from + '.' + e.from_port) : '<i>not connected</i>'}</li>`;
    }).join('') || '<li>none</li>'}</ul>
    <h4>Outputs</h4><ul>${n.outputs.map((p) => `<li><b>${esc(p.name)}</b>: ${esc(p.type)} — ${esc(p.doc)}</li>`).join('') || '<li>none</li>'}</ul>`;
  const apply = (name, value) => setParam(n.id, name, value);
  el.querySelectorAll('[data-param]').forEach((inp) => {
    const name = inp.dataset.param;
    if (inp.tagName === 'SELECT') inp.addEventListener('change', () => apply(name, inp.value));
    else if (inp.type === 'checkbox') inp.addEventListener('change', () => apply(name, inp.checked ? 'true' : 'false'));
    else inp.addEventListener('keydown', (e) => { if (e.key === 'Enter') { e.preventDefault(); apply(name, inp.value.trim() === '' ? null : inp.value.trim()); } });
  });
  el.querySelectorAll('[data-slider]').forEach((sl) => {
    const num = el.querySelector(`[data-param="${sl.dataset.slider}"]`);
    sl.addEventListener('input', () => { num.value = sl.value; });
    sl.addEventListener('change', () => apply(sl.dataset.slider, sl.value));
  });
  el.querySelectorAll('[data-reset]').forEach((b) => b.addEventListener('click', () => apply(b.dataset.reset, null)));
  el.querySelectorAll('[data-save]').forEach((b) => b.addEventListener('click', async () => {
    try {
      const r = await api('POST', '/api/params/save', { node: n.id, param: b.dataset.save });
      studio.paramUndo = studio.paramUndo.filter((u) => !(u.node === n.id && u.param === b.dataset.save));
      paramMsg(n.id, esc(`saved ${b.dataset.save}: ${r.saved} into ${studio.state.file}`), b.dataset.save);
    } catch (e) {
      paramMsg(n.id, `<span class="err">${esc(e.message)}</span>`);
    }
  }));
  if (studio.paramMsg && studio.paramMsg.node === n.id) paramMsg(n.id, studio.paramMsg.html, studio.paramMsg.saved);
  $('param-undo').addEventListener('click', () => undoParam(false));
  $('param-redo').addEventListener('click', () => undoParam(true));
}

// With no node selected: what the graph is, and the first frame of its first image output.
function overviewPanel() {
  const s = studio.state;
  if (!s || !s.graph) return '<p class="hint">Click a node.</p>';
  const ns = nodes();
  const imgs = outputsOfType(['image', 'layers']);
  const per = ns.filter((n) => n.instances > 1).length;
  let h = `<p class="hint">Click a node for its docs, params and plan.</p><p>${ns.length} nodes, ${per} per frame, ${frames().length} frames${s.graph.frames.length ? '' : ' (from the graph\'s outputs: no <code>frames:</code> range)'}.</p>`;
  if (imgs.length && frames().length) {
    const sel = imgs[0].node + '.' + imgs[0].port;
    h += `<h4>${esc(sel)}, frame ${frames()[0]}</h4><img class="first-frame" id="first-frame" alt="" src="${imageUrl(sel, frames()[0], { png: true })}" onerror="this.replaceWith(Object.assign(document.createElement('p'), {className: 'hint', textContent: 'no preview yet: run the graph'}))">`;
  }
  return h;
}

// ----------------------------------------------------------------------------- frame viewer

function outputsOfType(types) {
  const out = [];
  for (const n of nodes()) for (const p of n.outputs) if (types.includes(p.type)) out.push({ node: n.id, port: p.name, type: p.type, per_frame: n.per_frame });
  return out;
}

function fillSelect(sel, items, keepEmpty) {
  const old = sel.value;
  const head = keepEmpty ? '<option value="">(none)</option>' : '';
  sel.innerHTML = head + items.map((o) => `<option value="${esc(o.node + '.' + o.port)}">${esc(o.node + '.' + o.port)}</option>`).join('');
  if ([...sel.options].some((o) => o.value === old)) sel.value = old;
}

// The frames the viewers step through: the graph's `frames:` range, else (the book's
// matchmove reads tracks and solves cameras without one) the frames of its camera paths, else
// of its tracks, else of its marks.
async function deriveFrames() {
  const g = studio.state && studio.state.graph;
  if (!g) { studio.frames = []; return; }
  if (g.frames.length) { studio.frames = g.frames; studio.framesFrom = 'graph'; return; }
  const key = studio.state.runs + '|' + studio.graphKey;
  if (studio.framesKey === key) return;
  const found = new Set();
  let from = '';
  for (const [types, pick] of [
    [['camera_path'], (a) => (a.frames || []).map((f) => f.frame)],
    [['tracks'], (a) => a.frames || []],
    [['marked_points', 'marks'], (a) => (a.frames || []).map((f) => f.frame)],
  ]) {
    for (const o of outputsOfType(types)) {
      const a = await artifactJson(o.node + '.' + o.port);
      if (a) for (const f of pick(a)) if (Number.isFinite(f)) found.add(f);
      if (found.size && !from) from = o.node + '.' + o.port;
    }
    if (found.size) break;
  }
  studio.frames = [...found].sort((a, b) => a - b);
  studio.framesFrom = from;
  studio.framesKey = key;
}

function fillOutputs() {
  const imgs = outputsOfType(['image', 'layers']);
  fillSelect($('out-a'), imgs, false);
  fillSelect($('out-b'), imgs, true);
  const tracks = outputsOfType(['tracks']);
  fillSelect($('tracks'), tracks, true);
  // A graph of tracks and cameras only: show the tracks (on black) rather than nothing.
  if (!imgs.length && tracks.length && !$('tracks').value && !studio.tracksPicked) {
    $('tracks').value = tracks[0].node + '.' + tracks[0].port;
    studio.tracksPicked = true;
  }
  frameSizeFromIntrinsics();
  const f = frames();
  for (const id of ['scrub', 'def-scrub', 'solve-scrub']) $(id).max = Math.max(0, f.length - 1);
  studio.frameIdx = Math.min(studio.frameIdx, Math.max(0, f.length - 1));
  loadLayers().then(drawViewer);
}

const frameNow = () => frames()[studio.frameIdx];

// The frame size of a graph without images: the intrinsics' (their width and height when
// recorded, else twice the principal point), for drawing tracks and marks on black.
async function frameSizeFromIntrinsics() {
  if (studio.frameSize !== undefined) return;
  studio.frameSize = null;
  for (const o of outputsOfType(['intrinsics', 'camera_path'])) {
    const a = await artifactJson(o.node + '.' + o.port);
    const k = a && (a.K ? a : a.intrinsics);
    if (!k) continue;
    // A principal point at (w − 1)/2 (pixel centres at integers) or at w/2.
    const dim = (c) => (Math.abs(c - Math.floor(c) - 0.5) < 1e-6 ? 2 * c + 1 : Math.round(2 * c));
    const w = k.width || (k.K ? dim(k.K[0][2]) : 0), h = k.height || (k.K ? dim(k.K[1][2]) : 0);
    if (w > 16 && h > 16 && w < 20000 && h < 20000) { studio.frameSize = { w, h }; return; }
  }
}

// Tracks on black at frame `f` (no image output to show them over).
async function drawTracksOnBlack(c, f, tok) {
  const tr = await tracksData().catch(() => null);
  if (!tr || tok !== drawToken) return false;
  const sz = studio.frameSize || { w: 1280, h: 720 };
  if (c.width !== sz.w || c.height !== sz.h) { c.width = sz.w; c.height = sz.h; layoutViewer(); }
  const ctx = c.getContext('2d');
  ctx.fillStyle = '#000'; ctx.fillRect(0, 0, c.width, c.height);
  const ov = drawTracks(ctx, tr, f);
  studio.overlay = { tracks: ov.tracks, lost: ov.lost, reproj: [] };
  c.dataset.tracks = ov.tracks;
  c.dataset.lost = ov.lost;
  c.dataset.frame = f ?? '';
  $('frame-label').textContent = f ?? '–';
  $('viewer-msg').textContent = 'no image output in this graph: the tracks on black';
  return true;
}

function imageUrl(sel, frame, opts = {}) {
  const [node, port] = sel.split('.');
  const q = new URLSearchParams({ node, port, exposure: $('exposure').value, srgb: $('srgb').checked });
  if ($('display').value) {
    const [display, view] = JSON.parse($('display').value);
    q.set('display', display);
    q.set('view', view);
  }
  if (frame !== undefined) q.set('frame', frame);
  if ($('jpeg').checked && !opts.png) q.set('fmt', 'jpg');
  const layer = $('layer').value;
  if (layer && opts.layer !== false) q.set('layer', layer);
  // The run number: a rerun's previews are new URLs, never the page's cached images of the
  // last run (the server ignores it). studio.bust: a scrub benchmark's pass (the same).
  q.set('run', studio.state ? studio.state.runs : 0);
  if (studio.bust) q.set('b', studio.bust);
  return '/api/image?' + q;
}

function loadImage(url) {
  const hit = studio.images.get(url);
  if (hit) return Promise.resolve(hit);
  return new Promise((ok, fail) => {
    const im = new Image();
    im.onload = () => {
      studio.images.set(url, im);
      if (studio.images.size > 400) studio.images.delete(studio.images.keys().next().value);
      ok(im);
    };
    im.onerror = () => fail(new Error('no image for ' + url));
    im.src = url;
  });
}

async function loadLayers() {
  const a = $('out-a').value;
  const sel = $('layer');
  if (!a) { sel.innerHTML = ''; return; }
  const [node, port] = a.split('.');
  try {
    const info = await api('GET', `/api/artifact?node=${encodeURIComponent(node)}&port=${encodeURIComponent(port)}&frame=${frameNow() ?? ''}`);
    const old = sel.value;
    sel.innerHTML = (info.layers || []).map((l) => `<option>${esc(l)}</option>`).join('');
    if ([...sel.options].some((o) => o.value === old)) sel.value = old;
  } catch (e) { sel.innerHTML = ''; }
}

let tracksCache = { key: null, data: null };
async function tracksData() {
  const t = $('tracks').value;
  if (!t) return null;
  if (tracksCache.key === t) return tracksCache.data;
  const [node, port] = t.split('.');
  const data = await api('GET', `/api/artifact?node=${encodeURIComponent(node)}&port=${encodeURIComponent(port)}`);
  tracksCache = { key: t, data };
  return data;
}

// The frame viewer's view: the canvas holds the image at its own size; a CSS transform
// (translate then scale k) places it in the stage. Modes: fit (the default: the whole image,
// as large as the stage allows), 1:1, or free (after a zoom or a pan).
const vview = { k: 1, x: 0, y: 0, mode: 'fit' };
studio.vview = vview;
function layoutViewer() {
  const c = $('viewer'), w = $('viewer-wrap').getBoundingClientRect();
  if (w.width < 2 || w.height < 2) return;
  if (vview.mode === 'fit') {
    vview.k = Math.min(w.width / c.width, w.height / c.height);
    if (c.width <= 1) vview.k = 1;
  } else if (vview.mode === 'one') vview.k = 1;
  if (vview.mode !== 'free') {
    vview.x = (w.width - c.width * vview.k) / 2;
    vview.y = (w.height - c.height * vview.k) / 2;
  }
  c.style.transform = `translate(${vview.x}px, ${vview.y}px) scale(${vview.k})`;
  c.classList.toggle('smooth', vview.k < 1);
  $('v-zoom-label').textContent = `${Math.round(vview.k * 100)} %${vview.mode === 'fit' ? ' (fit)' : ''}`;
  $('viewer').dataset.zoom = vview.k.toFixed(4);
  placeLabels();
}
function zoomViewer(f, cx, cy) {
  const w = $('viewer-wrap').getBoundingClientRect();
  if (cx === undefined) { cx = w.width / 2; cy = w.height / 2; }
  const k = Math.min(64, Math.max(0.02, vview.k * f));
  vview.x = cx - ((cx - vview.x) * k) / vview.k;
  vview.y = cy - ((cy - vview.y) * k) / vview.k;
  vview.k = k;
  vview.mode = 'free';
  layoutViewer();
}
function setViewerMode(m) { vview.mode = m; layoutViewer(); }
// The A and B labels: A at the image's top left, B just right of the wipe line.
function placeLabels() {
  const a = $('out-a').value, b = $('out-b').value, la = $('label-a'), lb = $('label-b');
  la.hidden = !a || !b;
  lb.hidden = !b;
  if (!b) return;
  const c = $('viewer');
  const wx = vview.x + Number($('wipe').value) * c.width * vview.k;
  la.textContent = 'A: ' + a;
  lb.textContent = 'B: ' + b;
  la.style.left = Math.max(4, vview.x + 6) + 'px';
  la.style.top = lb.style.top = Math.max(4, vview.y + 6) + 'px';
  lb.style.left = wx + 6 + 'px';
}
function toggleFull(on) {
  const w = $('viewer-wrap');
  w.classList.toggle('fullwin', on === undefined ? !w.classList.contains('fullwin') : on);
  layoutViewer();
}
function viewerEvents() {
  const w = $('viewer-wrap');
  let drag = null;
  w.addEventListener('mousedown', (e) => {
    if (e.button !== 0) return;
    const r = w.getBoundingClientRect();
    const wx = vview.x + Number($('wipe').value) * $('viewer').width * vview.k;
    if ($('out-b').value && Math.abs(e.clientX - r.left - wx) < 10) drag = { wipe: true };
    else drag = { x: e.clientX, y: e.clientY, vx: vview.x, vy: vview.y };
    e.preventDefault();
  });
  window.addEventListener('mousemove', (e) => {
    if (!drag) return;
    if (drag.wipe) {
      const r = w.getBoundingClientRect();
      const v = (e.clientX - r.left - vview.x) / ($('viewer').width * vview.k);
      $('wipe').value = Math.min(1, Math.max(0, v));
      drawViewer();
      return;
    }
    vview.x = drag.vx + e.clientX - drag.x;
    vview.y = drag.vy + e.clientY - drag.y;
    vview.mode = 'free';
    layoutViewer();
  });
  window.addEventListener('mouseup', () => (drag = null));
  w.addEventListener('wheel', (e) => {
    e.preventDefault();
    const r = w.getBoundingClientRect();
    zoomViewer(e.deltaY > 0 ? 1 / 1.2 : 1.2, e.clientX - r.left, e.clientY - r.top);
  }, { passive: false });
  w.addEventListener('dblclick', () => setViewerMode(vview.mode === 'fit' ? 'one' : 'fit'));
  $('v-fit').addEventListener('click', () => setViewerMode('fit'));
  $('v-one').addEventListener('click', () => setViewerMode('one'));
  $('v-in').addEventListener('click', () => zoomViewer(1.25));
  $('v-out').addEventListener('click', () => zoomViewer(1 / 1.25));
  $('v-full').addEventListener('click', () => toggleFull());
  window.addEventListener('resize', layoutViewer);
}

let warmTimer = null;
function warmSoon() {
  clearTimeout(warmTimer);
  warmTimer = setTimeout(() => { if (!$('view-frames').hidden) warmPreviews(); }, 100);
}

let drawToken = 0;
async function drawViewer() {
  const a = $('out-a').value;
  const f = frameNow();
  const tok = ++drawToken;
  const c = $('viewer');
  if (!a) {
    if (!(await drawTracksOnBlack(c, f, tok)) && tok === drawToken) $('viewer-msg').textContent = 'no image output in this graph';
    return;
  }
  try {
    const b = $('out-b').value;
    const [ia, ib] = await Promise.all([loadImage(imageUrl(a, f)), b ? loadImage(imageUrl(b, f, { layer: false })) : null]);
    if (tok !== drawToken) return;
    if (c.width !== ia.width || c.height !== ia.height) { c.width = ia.width; c.height = ia.height; layoutViewer(); }
    const ctx = c.getContext('2d');
    ctx.drawImage(ia, 0, 0);
    if (ib) {
      const x = Math.round($('wipe').value * c.width);
      ctx.save();
      ctx.beginPath(); ctx.rect(x, 0, c.width - x, c.height); ctx.clip();
      ctx.drawImage(ib, 0, 0, c.width, c.height);
      ctx.restore();
      ctx.strokeStyle = '#ff0'; ctx.lineWidth = Math.max(1, 1.5 / vview.k); ctx.beginPath(); ctx.moveTo(x + 0.5, 0); ctx.lineTo(x + 0.5, c.height); ctx.stroke();
    }
    placeLabels();
    const tr = await tracksData().catch(() => null);
    const ov = { tracks: 0, lost: 0, reproj: [] };
    if (tr && tok === drawToken) Object.assign(ov, drawTracks(ctx, tr, f));
    const rp = await reprojData().catch(() => null);
    if (rp && tok === drawToken) ov.reproj = drawReprojection(ctx, rp, f);
    studio.overlay = ov;
    c.dataset.tracks = ov.tracks;
    c.dataset.lost = ov.lost;
    c.dataset.reproj = ov.reproj.length;
    $('viewer-msg').textContent = '';
    $('frame-label').textContent = f ?? '–';
    c.dataset.frame = f ?? '';
  } catch (e) {
    if (tok === drawToken) {
      $('viewer-msg').textContent = 'no preview for frame ' + f + ' (has the graph run?)';
      $('frame-label').textContent = f ?? '–';
      c.dataset.frame = '';
    }
  }
  prefetch();
}

// Each track's trail (the last `trail` frames) up to this frame, coloured by its age (yellow:
// new, blue: 50 frames or older) or by its error: the solve's RMS reprojection error of the
// track when a report gives one per track (green up to the median track's, red from the 95th
// percentile's: the worst tracks stand out), else how far
// the point is from the middle of its neighbours on the track (green under 0.25 px, red from
// 2 px); a track lost at this frame is marked with a red x.
let trackErrCache = { key: null, data: null };
async function trackErrors() {
  const key = (studio.state ? studio.state.runs : 0) + '|' + studio.graphKey;
  if (trackErrCache.key === key) return trackErrCache.data;
  let data = null;
  for (const o of outputsOfType(['report'])) {
    const r = await artifactJson(o.node + '.' + o.port);
    if (r && Array.isArray(r.tracks) && r.tracks.length && r.tracks[0].id !== undefined && r.tracks[0].rms !== undefined) {
      const v = r.tracks.map((t) => t.rms).filter(Number.isFinite).sort((a, b) => a - b);
      const med = v[Math.floor(v.length / 2)] || 0, p95 = v[Math.floor(0.95 * (v.length - 1))] || 1;
      data = { from: o.node + '.' + o.port, rms: new Map(r.tracks.map((t) => [t.id, t.rms])), med, p95: Math.max(p95, med + 1e-6) };
      break;
    }
  }
  trackErrCache = { key, data };
  return data;
}

function trackColour(t, upto) {
  if ($('track-colour').value === 'error') {
    const te = studio.trackErr;
    if (te && te.rms.has(t.id)) {
      const a = Math.min(1, Math.max(0, (te.rms.get(t.id) - te.med) / (te.p95 - te.med)));
      return `hsl(${Math.round(120 * (1 - a))}, 90%, 55%)`;
    }
    const p = t.points, i = upto;
    let e = 0;
    if (i > 0 && i + 1 < p.length) e = Math.hypot(p[i][0] - (p[i - 1][0] + p[i + 1][0]) / 2, p[i][1] - (p[i - 1][1] + p[i + 1][1]) / 2);
    else if (i > 0) e = Math.hypot(p[i][0] - p[i - 1][0], p[i][1] - p[i - 1][1]) / 4;
    const a = Math.min(1, Math.max(0, (e - 0.25) / 1.75));
    return `hsl(${Math.round(120 * (1 - a))}, 90%, 55%)`;
  }
  const age = Math.min(1, upto / 50);
  return `hsl(${Math.round(55 + 160 * age)}, 95%, 58%)`;
}

function drawTracks(ctx, tr, f) {
  const fi = tr.frames.indexOf(f);
  if ($('track-colour').value === 'error' && !studio.trackErr) {
    // Fetched once, then the frame is drawn again with it.
    trackErrors().then((d) => { if (d) { studio.trackErr = d; drawViewer(); } });
  }
  const n = { tracks: 0, lost: 0 };
  if (fi < 0) return n;
  const trail = Math.max(0, Math.min(500, Number($('trail').value) || 0));
  ctx.lineWidth = Math.max(1, 1.2 / vview.k);
  const dot = Math.max(3, 3 / vview.k);
  for (const t of tr.tracks) {
    const last = t.first + t.points.length - 1;
    if (fi < t.first || fi > last + 1) continue;
    const upto = Math.min(fi, last) - t.first;
    const col = trackColour(t, upto);
    ctx.strokeStyle = col;
    ctx.beginPath();
    const from = Math.max(0, upto - trail);
    for (let i = from; i <= upto; i++) {
      const [x, y] = t.points[i];
      if (i === from) ctx.moveTo(x + 0.5, y + 0.5); else ctx.lineTo(x + 0.5, y + 0.5);
    }
    ctx.stroke();
    const [x, y] = t.points[upto];
    if (fi > last && t.lost) {
      ctx.strokeStyle = '#f44';
      ctx.beginPath(); ctx.moveTo(x - 3, y - 3); ctx.lineTo(x + 4, y + 4); ctx.moveTo(x + 4, y - 3); ctx.lineTo(x - 3, y + 4); ctx.stroke();
      n.lost += 1;
    } else if (fi <= last) {
      ctx.fillStyle = col; ctx.fillRect(x + 0.5 - dot / 2, y + 0.5 - dot / 2, dot, dot);
      n.tracks += 1;
    }
  }
  return n;
}

// The solved points (a points3d/point_cloud output) through this frame's solved camera (the
// Solve tab's camera path; K from the path, else the graph's first intrinsics output).
let reprojCache = { key: null, data: null };
async function reprojData() {
  const p = $('reproj').value, c = $('solve-cams').value;
  if (!p || !c) return null;
  const key = p + '|' + c + '|' + (studio.state ? studio.state.runs : 0);
  if (reprojCache.key === key) return reprojCache.data;
  const cams = await artifactJson(c);
  const pts = pointsOf(await artifactJson(p));
  let K = cams && cams.intrinsics ? cams.intrinsics.K : null;
  if (!K) for (const o of outputsOfType(['intrinsics'])) { const k = await artifactJson(o.node + '.' + o.port); if (k && k.K) { K = k.K; break; } }
  const data = cams && pts && K ? { cams, pts, K } : null;
  reprojCache = { key, data };
  return data;
}

function projectPoint(K, pose, X) {
  const R = pose.R, t = pose.t;
  const xc = [0, 1, 2].map((i) => R[i][0] * X[0] + R[i][1] * X[1] + R[i][2] * X[2] + t[i]);
  if (xc[2] <= 1e-9) return null;
  const x = xc[0] / xc[2], y = xc[1] / xc[2];
  return [K[0][0] * x + K[0][1] * y + K[0][2], K[1][1] * y + K[1][2]];
}

function drawReprojection(ctx, rp, f) {
  const pose = rp.cams.frames.find((p) => p.frame === f);
  if (!pose) return [];
  const out = [];
  ctx.strokeStyle = '#f0f'; ctx.lineWidth = 1.5;
  for (const X of rp.pts) {
    const uv = projectPoint(rp.K, pose, X);
    if (!uv) continue;
    const [u, v] = [uv[0] + 0.5, uv[1] + 0.5];
    ctx.beginPath(); ctx.arc(u, v, 4, 0, 2 * Math.PI); ctx.moveTo(u - 6, v); ctx.lineTo(u + 6, v); ctx.moveTo(u, v - 6); ctx.lineTo(u, v + 6); ctx.stroke();
    out.push(uv);
  }
  return out;
}

// The neighbouring frames (3 ahead, 1 behind) are fetched while this one shows, so a scrub or
// play finds them decoded in the page.
function prefetch() {
  const a = $('out-a').value, f = frames();
  if (!a || f.length < 2) return;
  for (const k of [1, 2, 3, -1]) {
    const fr = f[(((studio.frameIdx + k) % f.length) + f.length) % f.length];
    loadImage(imageUrl(a, fr)).catch(() => {});
  }
}

// Asks the server to encode every frame's preview of output A under the current view
// (GET /api/warm, one background thread); resolves with its progress.
async function warmPreviews() {
  const a = $('out-a').value;
  if (!a || !studio.state || !studio.state.graph) return null;
  const u = imageUrl(a, frameNow()).replace('/api/image?', '/api/warm?').replace(/&(run|b)=[^&]*/g, '');
  try { return await api('GET', u); } catch (e) { return null; }
}
studio.warmPreviews = warmPreviews;
// Resolves once every preview of output A is encoded on the server.
studio.warmed = async function () {
  for (;;) {
    const w = await warmPreviews();
    if (!w || w.done + w.failed >= w.total) return w;
    await new Promise((r) => setTimeout(r, 50));
  }
};

function setFrameIdx(i, opts = {}) {
  const n = frames().length;
  if (!n) return;
  studio.frameIdx = ((i % n) + n) % n;
  for (const id of ['scrub', 'def-scrub', 'solve-scrub']) $(id).value = studio.frameIdx;
  renderSolve();
  if (opts.viewerOnly) return;
  if (!$('view-frames').hidden) drawViewer();
  if (!$('view-definer').hidden) drawDefiner();
}

// Scrubs `count` frames as fast as they can be shown; returns frames per second (the browser
// test prints it).
// Each step shows the next frame (fetched from the server unless prefetched, decoded, drawn)
// and checks that the frame label then names it; studio.scrubMisses counts labels that did not.
studio.benchScrub = async function (count) {
  studio.scrubMisses = 0;
  studio.bust = String(performance.now()); // new URLs: nothing from the browser's caches
  const t0 = performance.now();
  for (let k = 1; k <= count; k++) {
    setFrameIdx(studio.frameIdx + 1, { viewerOnly: true });
    await drawViewer();
    if ($('frame-label').textContent !== String(frameNow())) studio.scrubMisses += 1;
  }
  return (count * 1000) / (performance.now() - t0);
};

function play() {
  if (studio.playing) {
    studio.playing = false;
    $('play').textContent = 'Play';
    return;
  }
  studio.playing = true;
  $('play').textContent = 'Pause';
  const step = async () => {
    if (!studio.playing) return;
    const t0 = performance.now();
    setFrameIdx(studio.frameIdx + 1);
    const wait = 1000 / Math.max(1, Number($('fps').value) || 24) - (performance.now() - t0);
    setTimeout(step, Math.max(0, wait));
  };
  step();
}

let pixelTimer = null;
function hoverPixel(ev) {
  const c = $('viewer');
  const r = c.getBoundingClientRect();
  const x = Math.floor(((ev.clientX - r.left) * c.width) / r.width);
  const y = Math.floor(((ev.clientY - r.top) * c.height) / r.height);
  clearTimeout(pixelTimer);
  pixelTimer = setTimeout(async () => {
    const [node, port] = $('out-a').value.split('.');
    const q = new URLSearchParams({ node, port, x, y });
    if (frameNow() !== undefined) q.set('frame', frameNow());
    if ($('layer').value) q.set('layer', $('layer').value);
    try {
      const p = await api('GET', '/api/pixel?' + q);
      $('pixel-readout').textContent = `(${x}, ${y}) = ${p.value.map((v) => v.toFixed(4)).join(' ')}`;
    } catch (e) { $('pixel-readout').textContent = ''; }
  }, 30);
}

// ----------------------------------------------------------------------------- definer (§8.3)

function fillDefiner() {
  const marksNodes = nodes().filter((n) => n.type === 'read_marks');
  const sel = $('marks-node');
  const old = sel.value;
  sel.innerHTML = marksNodes.map((n) => `<option>${esc(n.id)}</option>`).join('');
  if ([...sel.options].some((o) => o.value === old)) sel.value = old;
  fillSelect($('def-image'), outputsOfType(['image', 'layers']), false);
  if (sel.value && sel.value !== studio.marksNode) loadMarks(sel.value);
  else if (!$('view-definer').hidden) drawDefiner();
}

// Unsaved marks are kept in the browser (localStorage) under the graph file and node, with
// the file's marks they were made from; a reload restores them.
const draftKey = () => `vfxgraph-marks|${studio.state ? studio.state.file : ''}|${studio.marksNode}`;
const pointCount = (m) => (m && m.frames && m.frames.length ? m.frames[0].points.length : 0);

// The marks as compared and kept: frames without a point left out.
const marksText = (m) => JSON.stringify({ frames: (m.frames || []).filter((f) => f.points.length) });

// Marks the marks as changed from the file's (or not, when they are back to them).
function setDirty(on) {
  if (on && marksText(studio.marks) === studio.marksBase) on = false;
  studio.defDirty = on;
  $('def-dirty').hidden = !on;
  $('def-canvas').dataset.dirty = on ? '1' : '0';
  try {
    if (on) localStorage.setItem(draftKey(), JSON.stringify({ marks: studio.marks, base: studio.marksBase }));
    else localStorage.removeItem(draftKey());
  } catch (e) { /* storage full or off: the marks stay in the page */ }
}

// Call before each change of the marks: the state before it goes on the undo stack.
function defPush() {
  studio.defUndo.push(JSON.stringify(studio.marks));
  if (studio.defUndo.length > 200) studio.defUndo.shift();
  studio.defRedo = [];
}
function defUndo(redo) {
  const from = redo ? studio.defRedo : studio.defUndo, to = redo ? studio.defUndo : studio.defRedo;
  const m = from.pop();
  if (m === undefined) return;
  to.push(JSON.stringify(studio.marks));
  studio.marks = JSON.parse(m);
  setDirty(true);
  drawDefiner();
  triangulateSoon();
}
studio.defUndoFn = defUndo;

async function loadMarks(id) {
  studio.marksNode = id;
  studio.defUndo = []; studio.defRedo = [];
  studio.defConfirm = false;
  $('def-warn').innerHTML = '';
  try {
    const r = await api('GET', '/api/marks?node=' + encodeURIComponent(id));
    studio.marks = r.marks;
    studio.marksBase = marksText(r.marks);
    studio.marksFileCount = pointCount(r.marks);
    $('def-msg').textContent = r.path;
  } catch (e) {
    studio.marks = { frames: [] };
    studio.marksBase = marksText(studio.marks);
    studio.marksFileCount = 0;
    $('def-msg').textContent = e.message;
  }
  let draft = null;
  try { draft = JSON.parse(localStorage.getItem(draftKey()) || 'null'); } catch (e) { draft = null; }
  if (draft && draft.marks && marksText(draft.marks) !== studio.marksBase) {
    studio.marks = draft.marks;
    setDirty(true);
    const changed = draft.base !== studio.marksBase ? ' (the file changed since they were made)' : '';
    $('def-msg').innerHTML = `<span class="warn" id="def-restored">restored unsaved marks from this browser${changed}</span> <button id="def-discard">Discard them</button>`;
    $('def-discard').addEventListener('click', () => {
      defPush();
      studio.marks = JSON.parse(studio.marksBase);
      setDirty(false);
      $('def-msg').textContent = 'unsaved marks discarded';
      drawDefiner();
      triangulateSoon();
    });
  } else setDirty(false);
  drawDefiner();
  triangulateSoon();
}

function marksOf(frame, create) {
  let m = studio.marks.frames.find((x) => x.frame === frame);
  if (!m && create) {
    m = { frame, points: [] };
    studio.marks.frames.push(m);
    studio.marks.frames.sort((a, b) => a.frame - b.frame);
  }
  return m;
}

const ZOOMS = [16, 12, 8, 6, 4, 3, 2, 1.5, 1, 0.75, 0.5, 0.25];
// The definer's zoom: the menu's, or at "fit" the largest that shows the whole image.
const zoom = () => studio.defZoom || 1;
function pickZoom(w, h) {
  const v = $('def-zoom').value;
  if (v !== 'fit') return Number(v);
  const r = $('def-wrap').getBoundingClientRect();
  const f = Math.min((r.width - 4) / w, (r.height - 4) / h);
  return ZOOMS.find((z) => z <= f) || 0.25;
}

// The size to mark on without an image (a graph of tracks and cameras only): what holds the
// marks and their projections, at least 640×360.
function blankSize() {
  if (studio.frameSize) return studio.frameSize;
  let w = 640, h = 360;
  for (const f of studio.marks.frames) for (const [x, y] of f.points) { w = Math.max(w, x + 1); h = Math.max(h, y + 1); }
  const pr = studio.tri && studio.tri.projected;
  if (pr) for (const uv of Object.values(pr)) for (const p of uv) if (p && p[0] < 8192 && p[1] < 8192) { w = Math.max(w, p[0] + 1); h = Math.max(h, p[1] + 1); }
  return { w: Math.ceil(w / 16) * 16, h: Math.ceil(h / 9) * 9 };
}

// Draws the definer; a draw started later (another frame) wins over one still loading.
let defDrawToken = 0;
async function drawDefiner() {
  const c = $('def-canvas');
  const f = frameNow();
  const tok = ++defDrawToken;
  $('def-frame-label').textContent = f ?? '–';
  const src = $('def-image').value;
  const ctx = c.getContext('2d');
  let im = null;
  if (src && f !== undefined) {
    try { im = await loadImage(imageUrl(src, f, { png: true })); } catch (e) { im = null; }
  }
  if (tok !== defDrawToken) return;
  const blank = im ? null : blankSize();
  const w = im ? im.width : blank.w, h = im ? im.height : blank.h;
  studio.defSize = { w, h };
  studio.defImage = im;
  const z = pickZoom(w, h);
  studio.defZoom = z;
  const cw = Math.round(w * z), ch = Math.round(h * z);
  if (c.width !== cw || c.height !== ch) { c.width = cw; c.height = ch; }
  ctx.imageSmoothingEnabled = z < 1;
  ctx.fillStyle = '#000'; ctx.fillRect(0, 0, c.width, c.height);
  if (im) ctx.drawImage(im, 0, 0, cw, ch);
  else {
    // No image: this frame's tracks, dimmed, to mark on.
    const tr = $('tracks').value ? await tracksData().catch(() => null) : null;
    if (tok !== defDrawToken) return;
    const fi = tr ? tr.frames.indexOf(f) : -1;
    if (fi >= 0) {
      ctx.fillStyle = '#4a7';
      for (const t of tr.tracks) {
        const i = fi - t.first;
        if (i < 0 || i >= t.points.length) continue;
        ctx.fillRect((t.points[i][0] + 0.5) * z - 1.5, (t.points[i][1] + 0.5) * z - 1.5, 3, 3);
      }
    }
    ctx.fillStyle = '#888'; ctx.font = '13px sans-serif';
    ctx.fillText(`no image: ${w}×${h} black${fi >= 0 ? `, this frame's ${$('tracks').value} shown` : ''}`, 10, 20);
  }
  const m = marksOf(f, false);
  ctx.font = '12px sans-serif';
  // The triangulated points through this frame's camera: solid where the frame is marked
  // (the point drawn back), dashed where it is not (the prediction of where to click).
  const pr = studio.tri && studio.tri.projected ? studio.tri.projected[String(f)] : null;
  let nproj = 0;
  if (pr) {
    ctx.setLineDash(m ? [] : [4, 3]);
    ctx.font = 'bold 12px sans-serif';
    pr.forEach((p, i) => {
      if (!p) return;
      const cx = (p[0] + 0.5) * z, cy = (p[1] + 0.5) * z;
      // A dark outline under the cyan: visible on bright plates too.
      for (const [col, lw] of [['#000', 3.5], ['#3ef', 1.6]]) {
        ctx.strokeStyle = col; ctx.lineWidth = lw;
        ctx.beginPath(); ctx.arc(cx, cy, 7, 0, 2 * Math.PI); ctx.stroke();
      }
      ctx.lineWidth = 3; ctx.strokeStyle = '#000';
      ctx.strokeText((m ? '' : '?') + (i + 1), cx + 8, cy + 15);
      ctx.fillStyle = '#3ef'; ctx.fillText((m ? '' : '?') + (i + 1), cx + 8, cy + 15);
      nproj += 1;
    });
    ctx.font = '12px sans-serif';
    ctx.setLineDash([]);
  }
  (m ? m.points : []).forEach(([x, y], i) => {
    const cx = (x + 0.5) * z, cy = (y + 0.5) * z;
    for (const [col, lw] of [['#000', 3.5], ['#ff0', 1.5]]) {
      ctx.strokeStyle = col; ctx.lineWidth = lw;
      ctx.beginPath(); ctx.moveTo(cx - 6, cy); ctx.lineTo(cx + 6, cy); ctx.moveTo(cx, cy - 6); ctx.lineTo(cx, cy + 6); ctx.stroke();
    }
    ctx.lineWidth = 3; ctx.strokeStyle = '#000'; ctx.strokeText(String(i + 1), cx + 5, cy - 5);
    ctx.fillStyle = '#ff0'; ctx.fillText(String(i + 1), cx + 5, cy - 5);
  });
  // Until the mouse moves over the image, the loupe shows the first mark (or the middle).
  if (!studio.loupeUsed) {
    const p0 = m && m.points.length ? m.points[0] : [w / 2, h / 2];
    loupeAt(p0[0] + 0.5, p0[1] + 0.5);
  }
  c.dataset.frame = f ?? '';
  c.dataset.src = src;
  c.dataset.marks = m ? m.points.length : 0;
  c.dataset.projected = nproj;
  c.dataset.predicted = pr && !m ? nproj : 0;
  c.dataset.zoom = z;
  studio.defProjected = pr ? pr.map((p) => p && [p[0], p[1]]) : null;
  renderMarksTable();
}

// Image coordinates (pixel centres at integers) of a mouse event: at 1/zoom pixel precision
// when zoomed in, whole pixels when zoomed out.
function defCoords(ev) {
  const c = $('def-canvas');
  const r = c.getBoundingClientRect();
  const z = zoom();
  // The canvas pixel hit, then the nearest 1/zoom step to its centre.
  const i = Math.floor(((ev.clientX - r.left) * c.width) / r.width);
  const j = Math.floor(((ev.clientY - r.top) * c.height) / r.height);
  if (z < 1 || !Number.isInteger(z)) return [Math.round((i + 0.5) / z - 0.5), Math.round((j + 0.5) / z - 0.5)];
  return [Math.round(i + 0.5 - z / 2) / z, Math.round(j + 0.5 - z / 2) / z];
}
// Sub-pixel refinement of a new mark (POST /api/refine: the corner within the window, on the
// server, in the linear image); the mark stays where clicked when there is no corner there.
// studio.snaps records each (from, to, refined) for the browser test.
async function snapMark(frame, pt) {
  const src = $('def-image').value;
  if (!src) { triangulateSoon(); return; }
  const [node, port] = src.split('.');
  const body = { node, port, x: pt[0], y: pt[1], radius: Number($('def-snap-r').value) || 5 };
  if (frame !== undefined) body.frame = frame;
  const from = pt.slice();
  try {
    const r = await api('POST', '/api/refine', body);
    if (r.refined) {
      // 1/1000 px is far below any click's precision and keeps the text file short.
      pt[0] = Math.round(r.x * 1000) / 1000;
      pt[1] = Math.round(r.y * 1000) / 1000;
    }
    (studio.snaps = studio.snaps || []).push({ frame, from, to: pt.slice(), refined: r.refined });
    if (studio.defDirty) setDirty(true);
  } catch (e) {
    (studio.snaps = studio.snaps || []).push({ frame, from, to: pt.slice(), refined: false, error: e.message });
  }
  drawDefiner();
  triangulateSoon();
}

function nearestMark(x, y) {
  const m = marksOf(frameNow(), false);
  if (!m) return -1;
  const tol = Math.max(6 / zoom(), 1);
  let best = -1, bd = tol;
  m.points.forEach(([px, py], i) => { const d = Math.hypot(px - x, py - y); if (d <= bd) { bd = d; best = i; } });
  return best;
}

function definerEvents() {
  const c = $('def-canvas');
  let drag = -1, moved = false;
  c.addEventListener('mousedown', (ev) => {
    if (ev.button !== 0) return;
    const [x, y] = defCoords(ev);
    drag = nearestMark(x, y);
    moved = false;
    ev.preventDefault();
  });
  c.addEventListener('mousemove', (ev) => {
    drawLoupe(ev);
    if (drag < 0) return;
    const [x, y] = defCoords(ev);
    const m = marksOf(frameNow(), false);
    if (!moved) defPush();
    m.points[drag] = [x, y];
    moved = true;
    drawDefiner();
  });
  c.addEventListener('mouseup', (ev) => {
    if (ev.button !== 0) return;
    const [x, y] = defCoords(ev);
    if (drag >= 0) {
      if (moved) { setDirty(true); triangulateSoon(); }
    } else {
      if (frameNow() === undefined) return;
      defPush();
      const m = marksOf(frameNow(), true);
      const pt = [x, y];
      m.points.push(pt);
      setDirty(true);
      if ($('def-snap').checked) snapMark(frameNow(), pt);
      else triangulateSoon();
    }
    drag = -1;
    drawDefiner();
  });
  c.addEventListener('contextmenu', (ev) => {
    ev.preventDefault();
    const [x, y] = defCoords(ev);
    const i = nearestMark(x, y);
    if (i < 0) return;
    defPush();
    const m = marksOf(frameNow(), false);
    m.points.splice(i, 1);
    setDirty(true);
    if (!m.points.length) studio.marks.frames = studio.marks.frames.filter((q) => q !== m);
    drawDefiner();
    triangulateSoon();
  });
}

// The loupe: 8× the image around the cursor (20 image pixels across), with the marks.
function drawLoupe(ev) {
  const c = $('def-canvas');
  const r = c.getBoundingClientRect();
  const z = zoom();
  studio.loupeUsed = true;
  loupeAt(((ev.clientX - r.left) * c.width) / r.width / z, ((ev.clientY - r.top) * c.height) / r.height / z);
}

// The loupe around image point (u, v) (pixel edges at integers).
function loupeAt(u, v) {
  const l = $('loupe');
  const ctx = l.getContext('2d');
  ctx.imageSmoothingEnabled = false;
  const s = 20, k = l.width / s;
  ctx.fillStyle = '#000'; ctx.fillRect(0, 0, l.width, l.height);
  if (studio.defImage) ctx.drawImage(studio.defImage, u - s / 2, v - s / 2, s, s, 0, 0, l.width, l.height);
  const m = marksOf(frameNow(), false);
  ctx.strokeStyle = '#ff0';
  for (const [x, y] of m ? m.points : []) {
    const px = (x + 0.5 - (u - s / 2)) * k, py = (y + 0.5 - (v - s / 2)) * k;
    ctx.beginPath(); ctx.moveTo(px - 8, py); ctx.lineTo(px + 8, py); ctx.moveTo(px, py - 8); ctx.lineTo(px, py + 8); ctx.stroke();
  }
  ctx.strokeStyle = '#f0f'; ctx.beginPath(); ctx.moveTo(80, 70); ctx.lineTo(80, 90); ctx.moveTo(70, 80); ctx.lineTo(90, 80); ctx.stroke();
}

function renderMarksTable() {
  const fs = studio.marks.frames;
  const n = Math.max(0, ...fs.map((f) => f.points.length));
  const tri = studio.tri;
  let h = '<tr><th>frame</th>' + [...Array(n).keys()].map((i) => `<th>#${i + 1}</th>`).join('') + '</tr>';
  for (const f of fs) {
    const fi = tri && tri.report ? tri.report.frames.indexOf(f.frame) : -1;
    h += `<tr data-frame="${f.frame}"><td>${f.frame}</td>` + f.points.map(([x, y], i) => {
      const e = fi >= 0 && tri.report.errors[i] ? ` <small>${tri.report.errors[i][fi].toFixed(2)} px</small>` : '';
      return `<td>${x} ${y}${e}</td>`;
    }).join('') + '</tr>';
  }
  $('marks-table').innerHTML = h;
  if (tri && tri.points) {
    $('tri').innerHTML = '<h4>Triangulated (from the solved cameras)</h4>' + tri.points.map((p, i) =>
      `<div>#${i + 1}: (${p.map((v) => v.toFixed(3)).join(', ')}) rms ${tri.report.rms[i].toFixed(2)} px</div>`).join('');
  } else if (tri && tri.error) {
    $('tri').innerHTML = `<p class="hint">${esc(tri.error)}</p>`;
  }
}

let triTimer = null;
function triangulateSoon() {
  clearTimeout(triTimer);
  triTimer = setTimeout(async () => {
    if (!studio.marksNode || !studio.marks.frames.length) return;
    // The most points marked on at least two frames, on the frames that have them (a frame
    // being marked, or a point marked on one frame so far, waits for its second frame).
    const counts = studio.marks.frames.map((f) => f.points.length).sort((a, b) => b - a);
    const n = counts.length > 1 ? counts[1] : counts[0] || 0;
    const full = { frames: studio.marks.frames.filter((f) => f.points.length >= n).map((f) => ({ frame: f.frame, points: f.points.slice(0, n) })) };
    try {
      studio.tri = await api('POST', '/api/triangulate', { node: studio.marksNode, marks: full });
    } catch (e) {
      studio.tri = { error: e.message };
    }
    if (!$('view-definer').hidden) drawDefiner(); else renderMarksTable();
  }, 150);
}

// Saves the marks. When the number of points a frame differs from the file's, the first
// click only warns (the nodes reading the marks, e.g. a calibration whose points a later node
// uses by index, get another count); a second click saves.
async function saveMarks() {
  const n = pointCount(studio.marks), was = studio.marksFileCount || 0;
  if (was && n !== was && !studio.defConfirm) {
    const users = nodes().filter((x) => x.inputs.some((e) => e.from === studio.marksNode)).map((x) => `${x.id} (${x.type})`);
    $('def-warn').innerHTML = `<p class="warn" id="def-count-warn">The marks file has ${was} points a frame; this saves ${n}. ${users.length ? 'Downstream, ' + esc(users.join(', ')) + ' and what follows will get ' + n + ' points instead of ' + was + '.' : ''} Click Save again to save anyway.</p>`;
    studio.defConfirm = true;
    return;
  }
  try {
    const r = await api('POST', '/api/marks', { node: studio.marksNode, marks: studio.marks });
    $('def-msg').textContent = 'saved ' + r.written.join(', ');
    $('def-msg').dataset.saved = String(Date.now());
    studio.marksBase = marksText(studio.marks);
    studio.marksFileCount = n;
    studio.defConfirm = false;
    $('def-warn').innerHTML = '';
    setDirty(false);
  } catch (e) {
    $('def-msg').innerHTML = `<span class="err">${esc(e.message)}</span>`;
  }
}

// ----------------------------------------------------------------------------- solve viewer

// three.js (vendored, assets/vendor/) draws the solve: the camera path as a line, each solved
// camera as a small frustum (the current frame's larger and yellow), the point cloud as points.
// Orbit of our own (drag, wheel) around the centre of what is drawn.
const solve = { yaw: 0.6, pitch: 0.35, dist: 1, cams: null, points: null, errors: null, gl: null, highlighted: null, info: null, error: null };
window.solve = solve;

let threeLib = null;
const loadThree = async () => (threeLib = threeLib || (await import('/assets/three.module.min.js')));

function fillSolve() {
  fillSelect($('solve-cams'), outputsOfType(['camera_path']), false);
  const pts = outputsOfType(['points3d', 'point_cloud']);
  fillSelect($('solve-points'), pts, true);
  fillSelect($('reproj'), pts, true);
  if (!$('view-solve').hidden) loadSolve();
}

async function artifactJson(sel) {
  if (!sel) return null;
  const [node, port] = sel.split('.');
  try { return await api('GET', `/api/artifact?node=${encodeURIComponent(node)}&port=${encodeURIComponent(port)}`); } catch (e) { return null; }
}

// [x, y, z] of a points3d (a list) or a point cloud ({points: [{position}]}).
function pointsOf(pts) {
  if (!pts) return null;
  return Array.isArray(pts) ? pts : (pts.points || []).map((p) => p.position || p.x || p);
}

// Per-frame RMS of a report: a solve's ({frames: [{frame, rms}]}), else a point-cloud
// calibration's ({frames: [f], errors: [point][frame]}, RMS over the points).
function perFrameErrors(r) {
  if (!r || !Array.isArray(r.frames) || !r.frames.length) return null;
  if (r.frames[0] && r.frames[0].rms !== undefined) return { kind: 'solve', frames: r.frames.map((f) => ({ frame: f.frame, rms: f.rms })) };
  if (Array.isArray(r.errors) && r.errors.length && typeof r.frames[0] === 'number') {
    return { kind: 'marks', frames: r.frames.map((f, fi) => ({ frame: f, rms: Math.sqrt(r.errors.reduce((a, e) => a + e[fi] * e[fi], 0) / r.errors.length) })) };
  }
  return null;
}

async function loadSolve() {
  solve.cams = await artifactJson($('solve-cams').value);
  solve.points = pointsOf(await artifactJson($('solve-points').value));
  solve.errors = null;
  let fallback = null;
  for (const o of outputsOfType(['report'])) {
    const e = perFrameErrors(await artifactJson(o.node + '.' + o.port));
    if (e && e.kind === 'solve') { solve.errors = e.frames; break; }
    if (e && !fallback) fallback = e.frames;
  }
  solve.errors = solve.errors || fallback;
  await buildSolve();
  renderSolve();
}

// Camera centre C = -Rᵀt.
function centre(p) {
  const R = p.R, t = p.t;
  return [0, 1, 2].map((j) => -(R[0][j] * t[0] + R[1][j] * t[1] + R[2][j] * t[2]));
}

// A robust framing of the solve: the centre is the per-axis median of the points and camera
// centres, the radius the 95th percentile of their distances to it, so one far point (a
// badly triangulated track) does not shrink the rest to a dot.
function robustFrame(all) {
  if (!all.length) return { centre: [0, 0, 0], r95: 1, rmax: 1 };
  const med = (a) => { const b = a.slice().sort((x, y) => x - y); return b[Math.floor(b.length / 2)]; };
  const centre = [0, 1, 2].map((k) => med(all.map((p) => p[k])));
  const d = all.map((p) => Math.hypot(p[0] - centre[0], p[1] - centre[1], p[2] - centre[2])).sort((x, y) => x - y);
  const r95 = Math.max(1e-6, d[Math.min(d.length - 1, Math.floor(0.95 * (d.length - 1)))]);
  return { centre, r95, rmax: Math.max(r95, d[d.length - 1]) };
}
// 1, 2 or 5 × 10^k: the grid's step.
const niceStep = (x) => { const e = Math.pow(10, Math.floor(Math.log10(x))); const m = x / e; return (m < 2 ? 1 : m < 5 ? 2 : 5) * e; };

function sizeSolve() {
  const c = $('solve3d'), r = c.getBoundingClientRect();
  const w = Math.max(200, Math.round(r.width)), h = Math.max(150, Math.round(r.height));
  if (solve.gl && (c.width !== w || c.height !== h)) {
    solve.gl.renderer.setSize(w, h, false);
    solve.gl.camera.aspect = w / h;
    solve.gl.camera.updateProjectionMatrix();
  }
}

async function buildSolve() {
  let T;
  try { T = await loadThree(); } catch (e) { solve.error = 'three.js did not load: ' + e.message; return; }
  const c = $('solve3d');
  if (!solve.gl) {
    try {
      const renderer = new T.WebGLRenderer({ canvas: c, antialias: true, preserveDrawingBuffer: true });
      renderer.setSize(c.width, c.height, false);
      solve.gl = { T, renderer, camera: new T.PerspectiveCamera(45, c.width / c.height, 1e-3, 1e4) };
    } catch (e) { solve.error = 'no WebGL: ' + e.message; $('solve-msg').textContent = solve.error; return; }
  }
  sizeSolve();
  const scene = new T.Scene();
  scene.background = new T.Color(0x111111);
  const cams = solve.cams && solve.cams.frames ? solve.cams.frames : [];
  const cs = cams.map((p) => ({ frame: p.frame, c: centre(p), R: p.R }));
  const pts = solve.points || [];
  const fr = robustFrame(pts.length >= 4 ? pts.concat(cs.map((x) => x.c)) : cs.map((x) => x.c).concat(pts));
  solve.mean = fr.centre; solve.rad = fr.r95; solve.framing = fr;
  solve.gl.camera.near = fr.r95 * 1e-3; solve.gl.camera.far = fr.rmax * 20 + fr.r95 * 100;
  solve.gl.camera.updateProjectionMatrix();
  const v3 = (p) => new T.Vector3(p[0], p[1], p[2]);
  // The ground grid through the centre (x–z plane), 20 steps across, and the world axes
  // (x red, y green, z blue) at the origin.
  const step = niceStep(fr.r95 / 4);
  const grid = new T.GridHelper(step * 20, 20, 0x555555, 0x2c2c2c);
  grid.position.set(fr.centre[0], fr.centre[1], fr.centre[2]);
  scene.add(grid);
  const axes = new T.AxesHelper(step * 2);
  scene.add(axes);
  solve.step = step;
  if (cs.length > 1) {
    scene.add(new T.Line(new T.BufferGeometry().setFromPoints(cs.map((x) => v3(x.c))), new T.LineBasicMaterial({ color: 0x44aa88 })));
  }
  // Frustums: apex at the centre, image rectangle along the viewing axis (3rd row of R), x and
  // y the camera's (1st and 2nd rows). Past 60 cameras only every k-th is drawn (the path
  // line shows the rest) unless "every frustum" is ticked; the current camera's is drawn
  // on its own, larger and yellow.
  const s = 0.06 * fr.r95;
  const frustum = (R, size) => {
    const [ax, ay, az] = R;
    const corner = (u, v) => [0, 1, 2].map((k) => size * (az[k] + 0.6 * u * ax[k] + 0.4 * v * ay[k]));
    const q = [corner(-1, -1), corner(1, -1), corner(1, 1), corner(-1, 1)];
    const seg = [];
    for (let i = 0; i < 4; i++) { seg.push([0, 0, 0], q[i], q[i], q[(i + 1) % 4]); }
    seg.push(q[0], q[1].map((v, k) => (v + q[0][k]) / 2 - 0.6 * size * ay[k]));
    return new T.BufferGeometry().setFromPoints(seg.map(v3));
  };
  const every = $('solve-all').checked || cs.length <= 60 ? 1 : Math.ceil(cs.length / 40);
  const mat = new T.LineBasicMaterial({ color: 0x44aa88 });
  solve.camObjs = cs.filter((x, i) => i % every === 0).map((x) => {
    const o = new T.LineSegments(frustum(x.R, s), mat);
    o.position.copy(v3(x.c));
    o.userData.frame = x.frame;
    scene.add(o);
    return o;
  });
  solve.camByFrame = new Map(cs.map((x) => [x.frame, x]));
  solve.current = new T.LineSegments(new T.BufferGeometry(), new T.LineBasicMaterial({ color: 0xffff00 }));
  solve.current.visible = false;
  solve.currentSize = 2.5 * s;
  scene.add(solve.current);
  solve.every = every;
  if (pts.length) {
    const g = new T.BufferGeometry().setFromPoints(pts.map(v3));
    solve.pointObj = new T.Points(g, new T.PointsMaterial({ color: 0xdddddd, size: 3, sizeAttenuation: false }));
    scene.add(solve.pointObj);
  } else solve.pointObj = null;
  solve.gl.scene = scene;
  solve.error = null;
  const far = pts.length ? pts.filter((p) => Math.hypot(p[0] - fr.centre[0], p[1] - fr.centre[1], p[2] - fr.centre[2]) > 3 * fr.r95).length : 0;
  $('solve-scale').textContent = `grid ${step} units a square · axes ${2 * step} long · 95 % within ${fr.r95.toPrecision(3)} of the centre${far ? ` · ${far} far point${far > 1 ? 's' : ''} (up to ${fr.rmax.toPrecision(3)}) not framed` : ''}${every > 1 ? ` · every ${every}th frustum` : ''}`;
  $('solve-msg').textContent = cs.length ? '' : 'no solved cameras yet (run the graph)';
}

// Highlights the current frame's camera and draws; cheap (called on every frame change).
function renderSolve() {
  $('solve-frame').textContent = frameNow() ?? '–';
  drawErrors();
  const gl = solve.gl;
  if (!gl || !gl.scene) return;
  sizeSolve();
  const f = frameNow();
  const cur = solve.camByFrame && solve.camByFrame.get(f);
  (solve.camObjs || []).forEach((o) => { o.visible = o.userData.frame !== f; });
  if (cur) {
    const [ax, ay, az] = cur.R, size = solve.currentSize;
    const corner = (u, v) => [0, 1, 2].map((k) => size * (az[k] + 0.6 * u * ax[k] + 0.4 * v * ay[k]));
    const q = [corner(-1, -1), corner(1, -1), corner(1, 1), corner(-1, 1)];
    const seg = [];
    for (let i = 0; i < 4; i++) seg.push([0, 0, 0], q[i], q[i], q[(i + 1) % 4]);
    seg.push(q[0], q[1].map((v, k) => (v + q[0][k]) / 2 - 0.6 * size * ay[k]));
    solve.current.geometry.dispose();
    solve.current.geometry = new gl.T.BufferGeometry().setFromPoints(seg.map((p) => new gl.T.Vector3(p[0], p[1], p[2])));
    solve.current.position.set(cur.c[0], cur.c[1], cur.c[2]);
    solve.current.visible = true;
  } else solve.current.visible = false;
  const hi = cur ? f : null;
  solve.highlighted = hi;
  const m = solve.mean, d = 3 * solve.rad * solve.dist;
  gl.camera.position.set(m[0] + d * Math.sin(solve.yaw) * Math.cos(solve.pitch), m[1] - d * Math.sin(solve.pitch), m[2] - d * Math.cos(solve.yaw) * Math.cos(solve.pitch));
  gl.camera.up.set(0, -1, 0);
  gl.camera.lookAt(m[0], m[1], m[2]);
  gl.renderer.render(gl.scene, gl.camera);
  solve.info = {
    cameras: solve.camByFrame ? solve.camByFrame.size : 0,
    frustums: (solve.camObjs || []).length,
    points: solve.pointObj ? solve.pointObj.geometry.attributes.position.count : 0,
    objects: gl.scene.children.length,
    highlighted: hi,
    framingRadius: solve.rad,
    viewDistance: d,
    farthest: solve.framing ? solve.framing.rmax : 0,
    grid: solve.step,
  };
  $('solve3d').dataset.highlighted = hi ?? '';
}

function drawErrors() {
  const svg = $('error-plot');
  const e = solve.errors;
  if (!e) { svg.innerHTML = '<text x="10" y="20" fill="#888">no per-frame solve report</text>'; return; }
  const W = Math.max(300, svg.clientWidth || 800), H = 120, max = Math.max(1e-9, ...e.map((x) => x.rms));
  svg.setAttribute('viewBox', `0 0 ${W} ${H}`);
  const x = (i) => 30 + (i * (W - 40)) / Math.max(1, e.length - 1), y = (v) => H - 20 - (v / max) * (H - 40);
  let h = `<text x="4" y="14" fill="#888">RMS px per frame (max ${max.toFixed(2)}); click a frame</text><polyline fill="none" stroke="#f0c674" points="${e.map((f, i) => x(i) + ',' + y(f.rms)).join(' ')}"/>`;
  h += e.map((f, i) => `<circle data-frame="${f.frame}" cx="${x(i)}" cy="${y(f.rms)}" r="${e.length > 100 ? 2 : 4}" fill="${f.frame === frameNow() ? '#ff0' : '#f0c674'}"><title>frame ${f.frame}: ${f.rms.toFixed(3)} px</title></circle>`).join('');
  svg.innerHTML = h;
  svg.querySelectorAll('circle').forEach((el) => el.addEventListener('click', () => {
    const i = frames().indexOf(Number(el.dataset.frame));
    if (i >= 0) setFrameIdx(i);
  }));
}

function solveEvents() {
  const c = $('solve3d');
  let last = null;
  c.addEventListener('mousedown', (e) => (last = [e.clientX, e.clientY]));
  window.addEventListener('mouseup', () => (last = null));
  c.addEventListener('mousemove', (e) => {
    if (!last) return;
    solve.yaw += (e.clientX - last[0]) * 0.01;
    solve.pitch += (e.clientY - last[1]) * 0.01;
    last = [e.clientX, e.clientY];
    renderSolve();
  });
  c.addEventListener('wheel', (e) => { e.preventDefault(); solve.dist *= e.deltaY > 0 ? 1.1 : 0.9; renderSolve(); }, { passive: false });
  $('solve-scrub').addEventListener('input', () => setFrameIdx(Number($('solve-scrub').value)));
  $('solve-all').addEventListener('input', () => buildSolve().then(renderSolve));
  $('solve-fit').addEventListener('click', () => { solve.dist = 1; solve.yaw = 0.6; solve.pitch = 0.35; renderSolve(); });
  window.addEventListener('resize', () => { if (!$('view-solve').hidden) renderSolve(); });
}

// ----------------------------------------------------------------------------- wiring

function showView(v) {
  document.querySelectorAll('.view').forEach((el) => (el.hidden = el.id !== 'view-' + v));
  document.querySelectorAll('.tab').forEach((b) => b.classList.toggle('active', b.dataset.view === v));
  if (v === 'definer') drawDefiner();
  if (v === 'solve') loadSolve();
  if (v === 'frames') { layoutViewer(); drawViewer(); warmSoon(); }
  if (v === 'graph' && studio.needFit) fitGraph();
  studio.view = v;
}

// Keys: Space play / pause, ← → a frame, Home / End (frames, definer, solve); F fit, + −
// zoom, 0 or 1 for 1:1, W full window (frames), Esc leaves it or closes the failure panel;
// Ctrl+Z / Ctrl+Shift+Z undo / redo (the definer's marks, the graph's param edits).
function keys(e) {
  const t = e.target;
  if (e.key === 'Escape') { $('failure').hidden = true; toggleFull(false); return; }
  if (t && (t.tagName === 'INPUT' || t.tagName === 'SELECT' || t.tagName === 'TEXTAREA')) return;
  const v = studio.view;
  const undo = (e.ctrlKey || e.metaKey) && (e.key === 'z' || e.key === 'Z' || e.key === 'y');
  if (undo) {
    const redo = e.shiftKey || e.key === 'y';
    if (v === 'definer') defUndo(redo); else if (v === 'graph') undoParam(redo);
    e.preventDefault();
    return;
  }
  if (e.ctrlKey || e.metaKey || e.altKey) return;
  if (v === 'graph') {
    if (e.key === 'f') fitGraph();
    else if (e.key === '+' || e.key === '=') zoomGraph(1.25);
    else if (e.key === '-') zoomGraph(1 / 1.25);
    else if (e.key === '0') zoomGraph(1 / gview.k);
    else return;
    e.preventDefault();
    return;
  }
  if (v === 'frames') {
    if (e.key === 'f') { setViewerMode('fit'); e.preventDefault(); return; }
    if (e.key === '1' || e.key === '0') { setViewerMode('one'); e.preventDefault(); return; }
    if (e.key === '+' || e.key === '=') { zoomViewer(1.25); e.preventDefault(); return; }
    if (e.key === '-') { zoomViewer(1 / 1.25); e.preventDefault(); return; }
    if (e.key === 'w') { toggleFull(); e.preventDefault(); return; }
  }
  if (v === 'solve' && e.key === 'f') { $('solve-fit').click(); return; }
  const n = frames().length;
  if (!n) return;
  if (e.key === ' ') play();
  else if (e.key === 'ArrowRight') setFrameIdx(studio.frameIdx + 1);
  else if (e.key === 'ArrowLeft') setFrameIdx(studio.frameIdx - 1);
  else if (e.key === 'Home') setFrameIdx(0);
  else if (e.key === 'End') setFrameIdx(n - 1);
  else return;
  e.preventDefault();
}

function wire() {
  document.querySelectorAll('.tab').forEach((b) => b.addEventListener('click', () => showView(b.dataset.view)));
  $('run').addEventListener('click', async () => {
    try { await api('POST', '/api/run'); } catch (e) { $('status').textContent = e.message; }
  });
  $('cancel').addEventListener('click', () => api('POST', '/api/cancel').catch(() => {}));
  $('reload').addEventListener('click', () => api('POST', '/api/reload').catch((e) => ($('status').textContent = e.message)));
  $('scrub').addEventListener('input', () => setFrameIdx(Number($('scrub').value)));
  $('def-scrub').addEventListener('input', () => setFrameIdx(Number($('def-scrub').value)));
  for (const id of ['exposure', 'srgb', 'display', 'jpeg', 'layer', 'wipe', 'out-b', 'tracks', 'reproj', 'track-colour', 'trail']) $(id).addEventListener('input', () => { $('exposure-label').textContent = $('exposure').value; drawViewer(); warmSoon(); });
  $('out-a').addEventListener('input', () => loadLayers().then(drawViewer).then(warmSoon));
  $('play').addEventListener('click', play);
  $('viewer').addEventListener('mousemove', hoverPixel);
  $('marks-node').addEventListener('input', () => loadMarks($('marks-node').value));
  $('def-image').addEventListener('input', drawDefiner);
  $('def-zoom').addEventListener('input', drawDefiner);
  $('def-save').addEventListener('click', saveMarks);
  $('solve-cams').addEventListener('input', loadSolve);
  $('solve-points').addEventListener('input', loadSolve);
  $('def-undo').addEventListener('click', () => defUndo(false));
  $('def-redo').addEventListener('click', () => defUndo(true));
  $('failure-close').addEventListener('click', () => ($('failure').hidden = true));
  definerEvents();
  solveEvents();
  graphEvents();
  viewerEvents();
  document.addEventListener('keydown', keys);
  showView('graph');
}

wire();
connect();
