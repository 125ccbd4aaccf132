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
};
window.studio = studio;

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
const frames = () => (studio.state && studio.state.graph ? studio.state.graph.frames : []);
const nodeById = (id) => nodes().find((n) => n.id === id);

// ----------------------------------------------------------------------------- state & events

async function refresh() {
  const s = await api('GET', '/api/state');
  studio.state = s;
  studio.running = s.running;
  studio.live = s.live || {};
  renderAll();
  if (studio.readyAt === null) studio.readyAt = performance.now();
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

function handle(ev) {
  const k = ev.kind;
  if (k === 'state') { refresh(); return; }
  if (k === 'run_started') {
    studio.running = true;
    studio.live = {};
    for (const n of nodes()) studio.live[n.id] = { running: 0, ran: 0, cached: 0, failed: 0, skipped: 0, progress: 0 };
    renderStatus();
    for (const n of nodes()) renderNode(n.id);
  } else if (k === 'run_done') {
    studio.running = false;
    renderStatus();
  } else if (k === 'run_error') {
    $('status').textContent = 'run failed to start: ' + ev.error;
  } else if (k === 'started' || k === 'progress' || k === 'finished') {
    const l = studio.live[ev.node] || (studio.live[ev.node] = { running: 0, ran: 0, cached: 0, failed: 0, skipped: 0, progress: 0 });
    if (k === 'started') l.running += 1;
    if (k === 'progress' && ev.frame === null) l.progress = ev.fraction;
    if (k === 'finished') {
      if (ev.status !== 'cached' && ev.status !== 'skipped') l.running = Math.max(0, l.running - 1);
      l[ev.status] += 1;
      if (ev.status === 'ran' && ev.frame === null) l.progress = 1;
    }
    renderNode(ev.node);
  }
  // The DOM now shows the event: how long since the engine reported it.
  const lat = Date.now() - ev.t;
  studio.latencies.push(lat);
  document.body.dataset.lastEvent = ev.seq;
}

function renderAll() {
  const s = studio.state;
  $('file').textContent = s.file;
  $('sets').textContent = s.sets.length ? s.sets.map((x) => '--set ' + x).join(' ') : '';
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
  fillOutputs();
  fillDefiner();
  fillSolve();
}

function renderStatus() {
  const s = studio.state;
  let t;
  if (!s.graph) t = 'graph does not load';
  else if (studio.running) t = 'running…';
  else {
    const c = { cached: 0, run: 0, blocked: 0 };
    for (const p of s.plan) c[p.status] += 1;
    t = `plan: ${c.cached} cached, ${c.run} to run, ${c.blocked} waiting`;
    if (s.last_run) t += ` · last run ${s.last_run.wall_seconds.toFixed(2)} s, ${s.last_run.ran} ran${s.last_run.failed ? ', FAILED' : ''}`;
  }
  $('status').textContent = t;
  $('status').dataset.running = studio.running ? '1' : '0';
  $('run').disabled = studio.running || !s.graph;
}

// ----------------------------------------------------------------------------- graph view

// A layered layout of our own: rank = longest path from a source, order in a rank by the mean
// order of the inputs (one sweep), nodes left to right.
function layout(ns) {
  const rank = {};
  const byId = Object.fromEntries(ns.map((n) => [n.id, n]));
  const rankOf = (id, seen = new Set()) => {
    if (rank[id] !== undefined) return rank[id];
    if (seen.has(id)) return 0;
    seen.add(id);
    const ins = byId[id].inputs.map((e) => rankOf(e.from, seen) + 1);
    return (rank[id] = ins.length ? Math.max(...ins) : 0);
  };
  ns.forEach((n) => rankOf(n.id));
  const cols = [];
  ns.forEach((n) => (cols[rank[n.id]] = cols[rank[n.id]] || []).push(n.id));
  const order = {};
  cols.forEach((col, r) => {
    if (r > 0) {
      const bary = (id) => {
        const ins = byId[id].inputs.map((e) => order[e.from]);
        return ins.length ? ins.reduce((a, b) => a + b, 0) / ins.length : 0;
      };
      col.sort((a, b) => bary(a) - bary(b));
    }
    col.forEach((id, i) => (order[id] = i));
  });
  const W = 170, H = 48, GX = 60, GY = 22;
  const pos = {};
  cols.forEach((col, r) => col.forEach((id, i) => (pos[id] = { x: 10 + r * (W + GX), y: 10 + i * (H + GY), w: W, h: H })));
  const width = 20 + cols.length * (W + GX);
  const height = 20 + Math.max(...cols.map((c) => c.length)) * (H + GY);
  return { pos, width, height };
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

function renderGraph() {
  const svg = $('graph');
  const ns = nodes();
  if (!ns.length) { svg.innerHTML = ''; return; }
  const { pos, width, height } = layout(ns);
  studio.pos = pos;
  svg.setAttribute('width', width);
  svg.setAttribute('height', height);
  let h = '';
  for (const n of ns) {
    for (const e of n.inputs) {
      const a = pos[e.from], b = pos[n.id];
      const x1 = a.x + a.w, y1 = a.y + a.h / 2, x2 = b.x, y2 = b.y + b.h / 2, mx = (x1 + x2) / 2;
      h += `<path class="edge" d="M${x1},${y1} C${mx},${y1} ${mx},${y2} ${x2},${y2}"><title>${esc(e.from + '.' + e.from_port + ' → ' + n.id + '.' + e.port)}</title></path>`;
    }
  }
  for (const n of ns) {
    const p = pos[n.id];
    h += `<g class="node" id="node-${esc(n.id)}" data-id="${esc(n.id)}" transform="translate(${p.x},${p.y})">
      <rect class="box" width="${p.w}" height="${p.h}"></rect>
      <text x="8" y="16">${esc(n.id)}</text><text x="8" y="30" opacity=".75">${esc(n.type)}</text>
      <text class="count" x="${p.w - 8}" y="30" text-anchor="end"></text>
      <rect class="bar" x="0" y="${p.h - 4}" height="4" width="0"></rect></g>`;
  }
  svg.innerHTML = h;
  svg.querySelectorAll('.node').forEach((g) => g.addEventListener('click', () => select(g.dataset.id)));
  ns.forEach((n) => renderNode(n.id));
}

function renderNode(id) {
  const g = document.getElementById('node-' + id);
  if (!g) return;
  const s = nodeState(id);
  if (g.dataset.state !== s.st) {
    // Every state a node showed (the browser test reads it).
    (studio.seenStates[id] = studio.seenStates[id] || []).push(s.st);
  }
  g.dataset.state = s.st;
  g.classList.toggle('selected', studio.selected === id);
  g.querySelector('.count').textContent = s.total > 1 ? `${s.done}/${s.total}` : '';
  g.querySelector('.bar').setAttribute('width', String(Math.round(170 * Math.min(1, s.progress || 0))));
}

function select(id) {
  studio.selected = id;
  nodes().forEach((n) => renderNode(n.id));
  renderPanel();
}

function renderPanel() {
  const el = $('panel');
  const n = studio.selected && nodeById(studio.selected);
  if (!n) { el.innerHTML = '<p class="hint">Click a node.</p>'; return; }
  const reasons = {};
  for (const p of planOf(n.id)) (reasons[p.status + ': ' + p.reason] = reasons[p.status + ': ' + p.reason] || []).push(p.frame);
  const last = studio.state.last_run ? studio.state.last_run.nodes.filter((x) => x.id === n.id) : [];
  const lastReasons = {};
  for (const p of last) (lastReasons[p.status + ': ' + p.reason] = lastReasons[p.status + ': ' + p.reason] || []).push(p.frame);
  const fr = (l) => (l[0] === null ? '' : ` (frames ${l.length > 6 ? l.slice(0, 6).join(', ') + ', …' : l.join(', ')})`);
  const params = n.params.map((p) => {
    const range = ''; // the type's text already says the range
    const input = p.choices
      ? `<select data-param="${esc(p.name)}">${p.choices.map((c) => `<option ${p.value === JSON.stringify(c) ? 'selected' : ''}>${esc(c)}</option>`).join('')}</select>`
      : `<input data-param="${esc(p.name)}" value="${esc(p.value ?? '')}" placeholder="${esc(p.default ?? '')}">`;
    return `<tr><td title="${esc(p.doc)}"><b>${esc(p.name)}</b><br><small>${esc(p.type)}${esc(range)}${p.affects_output ? '' : ' · cosmetic'}</small></td>
      <td>${input} <button data-set="${esc(p.name)}">set</button><br><small class="hint">${esc(p.doc)}</small></td></tr>`;
  }).join('');
  el.innerHTML = `<h3>${esc(n.id)} <small>${esc(n.type)} v${n.version}</small></h3>
    <p>${esc(n.doc)}</p>
    <p>${n.per_frame ? `per frame: ${n.instances} instances` : 'runs once'} · line ${n.line}</p>
    <h4>Inputs</h4><ul>${n.input_ports.map((p) => {
      const e = n.inputs.find((x) => x.port === p.name);
      return `<li><b>${esc(p.name)}</b>: ${esc(p.type)} ← ${e ? esc(e.from + '.' + e.from_port) : '<i>not connected</i>'}</li>`;
    }).join('') || '<li>none</li>'}</ul>
    <h4>Outputs</h4><ul>${n.outputs.map((p) => `<li><b>${esc(p.name)}</b>: ${esc(p.type)} — ${esc(p.doc)}</li>`).join('') || '<li>none</li>'}</ul>
    <h4>Params</h4><table>${params}</table><p id="param-msg"></p>
    <h4>Plan</h4><ul id="reasons">${Object.entries(reasons).map(([r, l]) => `<li>${esc(r)}${fr(l)}</li>`).join('')}</ul>
    <h4>Last run</h4><ul>${Object.entries(lastReasons).map(([r, l]) => `<li>${esc(r)}${fr(l)}</li>`).join('') || '<li>not run here yet</li>'}</ul>`;
  el.querySelectorAll('button[data-set]').forEach((b) => b.addEventListener('click', async () => {
    const name = b.dataset.set;
    const inp = el.querySelector(`[data-param="${name}"]`);
    const value = inp.value.trim() === '' ? null : inp.value;
    try {
      await api('POST', '/api/params', { node: n.id, param: name, value });
      $('param-msg').textContent = 'set';
    } catch (e) {
      $('param-msg').innerHTML = `<span class="err">${esc(e.message)}</span>`;
    }
  }));
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

function fillOutputs() {
  const imgs = outputsOfType(['image', 'layers']);
  fillSelect($('out-a'), imgs, false);
  fillSelect($('out-b'), imgs, true);
  fillSelect($('tracks'), outputsOfType(['tracks']), true);
  const f = frames();
  $('scrub').max = Math.max(0, f.length - 1);
  $('def-scrub').max = Math.max(0, f.length - 1);
  studio.frameIdx = Math.min(studio.frameIdx, Math.max(0, f.length - 1));
  loadLayers().then(drawViewer);
}

const frameNow = () => frames()[studio.frameIdx];

function imageUrl(sel, frame, opts = {}) {
  const [node, port] = sel.split('.');
  const q = new URLSearchParams({ node, port, exposure: $('exposure').value, srgb: $('srgb').checked });
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
  if (!a) { $('viewer-msg').textContent = 'no image output in this graph'; return; }
  try {
    const b = $('out-b').value;
    const [ia, ib] = await Promise.all([loadImage(imageUrl(a, f)), b ? loadImage(imageUrl(b, f, { layer: false })) : null]);
    if (tok !== drawToken) return;
    if (c.width !== ia.width || c.height !== ia.height) { c.width = ia.width; c.height = ia.height; }
    const ctx = c.getContext('2d');
    ctx.drawImage(ia, 0, 0);
    if (ib) {
      const x = Math.round($('wipe').value * c.width);
      ctx.save();
      ctx.beginPath(); ctx.rect(x, 0, c.width - x, c.height); ctx.clip();
      ctx.drawImage(ib, 0, 0, c.width, c.height);
      ctx.restore();
      ctx.strokeStyle = '#ff0'; ctx.beginPath(); ctx.moveTo(x + 0.5, 0); ctx.lineTo(x + 0.5, c.height); ctx.stroke();
    }
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

// Each track's trail up to this frame; a track lost at this frame is marked with a red x.
function drawTracks(ctx, tr, f) {
  const fi = tr.frames.indexOf(f);
  const n = { tracks: 0, lost: 0 };
  if (fi < 0) return n;
  ctx.lineWidth = 1;
  for (const t of tr.tracks) {
    const last = t.first + t.points.length - 1;
    if (fi < t.first || fi > last + 1) continue;
    const upto = Math.min(fi, last) - t.first;
    ctx.strokeStyle = '#4f4';
    ctx.beginPath();
    for (let i = Math.max(0, upto - 10); i <= upto; i++) {
      const [x, y] = t.points[i];
      if (i === Math.max(0, upto - 10)) ctx.moveTo(x + 0.5, y + 0.5); else ctx.lineTo(x + 0.5, y + 0.5);
    }
    ctx.stroke();
    const [x, y] = t.points[upto];
    if (fi > last && t.lost) {
      ctx.strokeStyle = '#f44';
      ctx.beginPath(); ctx.moveTo(x - 3, y - 3); ctx.lineTo(x + 4, y + 4); ctx.moveTo(x + 4, y - 3); ctx.lineTo(x - 3, y + 4); ctx.stroke();
      n.lost += 1;
    } else if (fi <= last) {
      ctx.fillStyle = '#4f4'; ctx.fillRect(x - 1, y - 1, 3, 3);
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
  $('scrub').value = studio.frameIdx;
  $('def-scrub').value = studio.frameIdx;
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
}

async function loadMarks(id) {
  studio.marksNode = id;
  try {
    const r = await api('GET', '/api/marks?node=' + encodeURIComponent(id));
    studio.marks = r.marks;
    $('def-msg').textContent = r.path;
  } catch (e) {
    studio.marks = { frames: [] };
    $('def-msg').textContent = e.message;
  }
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

const zoom = () => Number($('def-zoom').value);

async function drawDefiner() {
  const c = $('def-canvas');
  const f = frameNow();
  $('def-frame-label').textContent = f ?? '–';
  const src = $('def-image').value;
  const z = zoom();
  const ctx = c.getContext('2d');
  let im = null;
  if (src) {
    try { im = await loadImage(imageUrl(src, f, { png: true })); } catch (e) { im = null; }
  }
  const w = im ? im.width : 640, h = im ? im.height : 360;
  if (c.width !== w * z || c.height !== h * z) { c.width = w * z; c.height = h * z; }
  studio.defSize = { w, h };
  ctx.imageSmoothingEnabled = false;
  ctx.fillStyle = '#000'; ctx.fillRect(0, 0, c.width, c.height);
  if (im) ctx.drawImage(im, 0, 0, w * z, h * z);
  const m = marksOf(f, false);
  ctx.font = '12px sans-serif';
  (m ? m.points : []).forEach(([x, y], i) => {
    const cx = (x + 0.5) * z, cy = (y + 0.5) * z;
    ctx.strokeStyle = '#ff0'; ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.moveTo(cx - 6, cy); ctx.lineTo(cx + 6, cy); ctx.moveTo(cx, cy - 6); ctx.lineTo(cx, cy + 6); ctx.stroke();
    ctx.fillStyle = '#ff0'; ctx.fillText(String(i + 1), cx + 5, cy - 5);
  });
  c.dataset.frame = f ?? '';
  c.dataset.src = src;
  c.dataset.marks = m ? m.points.length : 0;
  renderMarksTable();
}

// Image coordinates (pixel centres at integers) of a mouse event, at 1/zoom pixel precision.
function defCoords(ev) {
  const c = $('def-canvas');
  const r = c.getBoundingClientRect();
  const z = zoom();
  // The canvas pixel hit, then the nearest 1/zoom step to its centre.
  const i = Math.floor(((ev.clientX - r.left) * c.width) / r.width);
  const j = Math.floor(((ev.clientY - r.top) * c.height) / r.height);
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
  } catch (e) {
    (studio.snaps = studio.snaps || []).push({ frame, from, to: pt.slice(), refined: false, error: e.message });
  }
  drawDefiner();
  triangulateSoon();
}

function nearestMark(x, y) {
  const m = marksOf(frameNow(), false);
  if (!m) return -1;
  const tol = 6 / zoom();
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
  });
  c.addEventListener('mousemove', (ev) => {
    drawLoupe(ev);
    if (drag < 0) return;
    const [x, y] = defCoords(ev);
    const m = marksOf(frameNow(), false);
    m.points[drag] = [x, y];
    moved = true;
    drawDefiner();
  });
  c.addEventListener('mouseup', (ev) => {
    if (ev.button !== 0) return;
    const [x, y] = defCoords(ev);
    if (drag >= 0) {
      if (moved) triangulateSoon();
    } else {
      const m = marksOf(frameNow(), true);
      const pt = [x, y];
      m.points.push(pt);
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
    const m = marksOf(frameNow(), false);
    m.points.splice(i, 1);
    if (!m.points.length) studio.marks.frames = studio.marks.frames.filter((q) => q !== m);
    drawDefiner();
    triangulateSoon();
  });
}

function drawLoupe(ev) {
  const c = $('def-canvas'), l = $('loupe');
  const r = c.getBoundingClientRect();
  const px = ((ev.clientX - r.left) * c.width) / r.width, py = ((ev.clientY - r.top) * c.height) / r.height;
  const ctx = l.getContext('2d');
  ctx.imageSmoothingEnabled = false;
  const s = 20; // source size in canvas pixels → 8× at zoom 1
  ctx.fillStyle = '#000'; ctx.fillRect(0, 0, l.width, l.height);
  ctx.drawImage(c, px - s / 2, py - s / 2, s, s, 0, 0, l.width, l.height);
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
    try {
      studio.tri = await api('POST', '/api/triangulate', { node: studio.marksNode, marks: studio.marks });
    } catch (e) {
      studio.tri = { error: e.message };
    }
    renderMarksTable();
  }, 150);
}

async function saveMarks() {
  try {
    const r = await api('POST', '/api/marks', { node: studio.marksNode, marks: studio.marks });
    $('def-msg').textContent = 'saved ' + r.written.join(', ');
    $('def-msg').dataset.saved = String(Date.now());
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
  const scene = new T.Scene();
  scene.background = new T.Color(0x111111);
  const cams = solve.cams && solve.cams.frames ? solve.cams.frames : [];
  const cs = cams.map((p) => ({ frame: p.frame, c: centre(p), R: p.R }));
  const all = cs.map((x) => x.c).concat(solve.points || []);
  const mean = all.length ? [0, 1, 2].map((k) => all.reduce((a, p) => a + p[k], 0) / all.length) : [0, 0, 0];
  const rad = Math.max(1e-6, ...all.map((p) => Math.hypot(p[0] - mean[0], p[1] - mean[1], p[2] - mean[2])));
  solve.mean = mean; solve.rad = rad;
  const v3 = (p) => new T.Vector3(p[0], p[1], p[2]);
  if (cs.length > 1) {
    scene.add(new T.Line(new T.BufferGeometry().setFromPoints(cs.map((x) => v3(x.c))), new T.LineBasicMaterial({ color: 0x44aa88 })));
  }
  // A frustum per camera: apex at the centre, image rectangle along the viewing axis (3rd row
  // of R), x and y the camera's (1st and 2nd rows).
  const s = 0.06 * rad;
  solve.camObjs = cs.map((x) => {
    const [ax, ay, az] = x.R;
    const corner = (u, v) => [0, 1, 2].map((k) => s * (az[k] + 0.6 * u * ax[k] + 0.4 * v * ay[k]));
    const q = [corner(-1, -1), corner(1, -1), corner(1, 1), corner(-1, 1)];
    const seg = [];
    for (let i = 0; i < 4; i++) { seg.push([0, 0, 0], q[i], q[i], q[(i + 1) % 4]); }
    seg.push(q[0], q[1].map((v, k) => (v + q[0][k]) / 2 - 0.6 * s * ay[k]));
    const g = new T.BufferGeometry().setFromPoints(seg.map(v3));
    const o = new T.LineSegments(g, new T.LineBasicMaterial({ color: 0x44aa88 }));
    o.position.copy(v3(x.c));
    o.userData.frame = x.frame;
    scene.add(o);
    return o;
  });
  if (solve.points && solve.points.length) {
    const g = new T.BufferGeometry().setFromPoints(solve.points.map(v3));
    solve.pointObj = new T.Points(g, new T.PointsMaterial({ color: 0xdddddd, size: 4, sizeAttenuation: false }));
    scene.add(solve.pointObj);
  } else solve.pointObj = null;
  solve.gl.scene = scene;
  solve.error = null;
  $('solve-msg').textContent = cs.length ? '' : 'no solved cameras yet (run the graph)';
}

// Highlights the current frame's camera and draws; cheap (called on every frame change).
function renderSolve() {
  $('solve-frame').textContent = frameNow() ?? '–';
  drawErrors();
  const gl = solve.gl;
  if (!gl || !gl.scene) return;
  const f = frameNow();
  let hi = null;
  (solve.camObjs || []).forEach((o) => {
    const cur = o.userData.frame === f;
    o.material.color.set(cur ? 0xffff00 : 0x44aa88);
    o.scale.setScalar(cur ? 2.5 : 1);
    if (cur) hi = f;
  });
  solve.highlighted = hi;
  const m = solve.mean, d = 3 * solve.rad * solve.dist;
  gl.camera.position.set(m[0] + d * Math.sin(solve.yaw) * Math.cos(solve.pitch), m[1] - d * Math.sin(solve.pitch), m[2] - d * Math.cos(solve.yaw) * Math.cos(solve.pitch));
  gl.camera.up.set(0, -1, 0);
  gl.camera.lookAt(m[0], m[1], m[2]);
  gl.renderer.render(gl.scene, gl.camera);
  solve.info = {
    cameras: (solve.camObjs || []).length,
    points: solve.pointObj ? solve.pointObj.geometry.attributes.position.count : 0,
    objects: gl.scene.children.length,
    highlighted: hi,
  };
  $('solve3d').dataset.highlighted = hi ?? '';
}

function drawErrors() {
  const svg = $('error-plot');
  const e = solve.errors;
  if (!e) { svg.innerHTML = '<text x="10" y="20" fill="#888">no per-frame solve report</text>'; return; }
  const W = 800, H = 140, max = Math.max(1e-9, ...e.map((x) => x.rms));
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
  c.addEventListener('wheel', (e) => { e.preventDefault(); solve.dist *= e.deltaY > 0 ? 1.1 : 0.9; renderSolve(); });
}

// ----------------------------------------------------------------------------- wiring

function showView(v) {
  document.querySelectorAll('.view').forEach((el) => (el.hidden = el.id !== 'view-' + v));
  document.querySelectorAll('.tab').forEach((b) => b.classList.toggle('active', b.dataset.view === v));
  if (v === 'definer') drawDefiner();
  if (v === 'solve') loadSolve();
  if (v === 'frames') { drawViewer(); warmSoon(); }
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
  for (const id of ['exposure', 'srgb', 'jpeg', 'layer', 'wipe', 'out-b', 'tracks', 'reproj']) $(id).addEventListener('input', () => { $('exposure-label').textContent = $('exposure').value; drawViewer(); warmSoon(); });
  $('out-a').addEventListener('input', () => loadLayers().then(drawViewer).then(warmSoon));
  $('play').addEventListener('click', play);
  $('viewer').addEventListener('mousemove', hoverPixel);
  $('marks-node').addEventListener('input', () => loadMarks($('marks-node').value));
  $('def-image').addEventListener('input', drawDefiner);
  $('def-zoom').addEventListener('input', drawDefiner);
  $('def-save').addEventListener('click', saveMarks);
  $('solve-cams').addEventListener('input', loadSolve);
  $('solve-points').addEventListener('input', loadSolve);
  definerEvents();
  solveEvents();
  showView('graph');
}

wire();
connect();
