// Prism's preview page: draws the linear radiance the server streams (with
// the exposure applied and the sRGB transfer function, as `prism render`
// writes PNG), follows the render, shows errors and explains pixels. The
// exposure starts at the scene's and follows it while the slider is left
// there; "Save PNG" writes what the page shows, at the slider's exposure.
"use strict";

const state = {
  generation: 0, width: 0, height: 0, radiance: null, phase: "connecting",
  exposure: 0, sceneExposure: null, exposureMoved: false, status: null, explanation: null, dirty: false, coarseAt: null,
  view: "", viewGeneration: 0, viewTop: null, notice: "", loading: null,
};
window.prism = state; // for the browser test

const $ = (id) => document.getElementById(id);
const canvas = $("picture"), ctx = canvas.getContext("2d");
const rays = $("rays"), rctx = rays.getContext("2d");

function decode(b64) {
  const bytes = Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
  return new Float32Array(bytes.buffer);
}

function resize(w, h) {
  if (state.width === w && state.height === h && state.radiance) return;
  state.width = w; state.height = h;
  state.radiance = new Float32Array(w * h * 3);
  for (const c of [canvas, rays]) { c.width = w; c.height = h; }
  applyZoom();
}

// The same encoding as the PNG writer: clamp, sRGB, round to 8 bits.
function srgb8(v) {
  if (!(v > 0)) return 0;
  if (v >= 1) return 255;
  const s = v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055;
  return Math.round(s * 255);
}

function draw() {
  state.dirty = false;
  const { width: w, height: h, radiance } = state;
  if (!radiance || !w) return;
  const scale = Math.pow(2, state.exposure);
  const img = ctx.createImageData(w, h);
  for (let i = 0, j = 0; i < w * h * 3; i += 3, j += 4) {
    img.data[j] = srgb8(radiance[i] * scale);
    img.data[j + 1] = srgb8(radiance[i + 1] * scale);
    img.data[j + 2] = srgb8(radiance[i + 2] * scale);
    img.data[j + 3] = 255;
  }
  ctx.putImageData(img, 0, 0);
}

function redraw() {
  if (!state.dirty) { state.dirty = true; requestAnimationFrame(draw); }
}

function putTile(x0, y0, w, h, data) {
  // Tiles that come while the picture loads are put over it afterwards.
  if (state.loading) { state.loading.push([x0, y0, w, h, data]); return; }
  const W = state.width;
  for (let y = 0; y < h; y++) {
    state.radiance.set(data.subarray(y * w * 3, (y + 1) * w * 3), ((y0 + y) * W + x0) * 3);
  }
  redraw();
}

function putCoarse(cw, ch, data) {
  // Each coarse pixel covers an 8×8 block of the full picture.
  const { width: W, height: H, radiance } = state;
  for (let y = 0; y < H; y++) {
    for (let x = 0; x < W; x++) {
      const s = ((y >> 3) * cw + (x >> 3)) * 3, d = (y * W + x) * 3;
      radiance[d] = data[s]; radiance[d + 1] = data[s + 1]; radiance[d + 2] = data[s + 2];
    }
  }
  redraw();
}

// The picture as it is now: binary f32 RGB, its size in the headers.
async function loadPicture() {
  if (state.loading) return;
  state.loading = [];
  try {
    for (;;) {
      const r = await fetch("/picture");
      if (r.ok) {
        const w = +r.headers.get("x-prism-width"), h = +r.headers.get("x-prism-height");
        const data = new Float32Array(await r.arrayBuffer());
        if (w && h && data.length === w * h * 3) {
          resize(w, h);
          state.radiance.set(data);
          redraw();
        }
        break;
      }
      // Busy (503): try again shortly.
      await new Promise((ok) => setTimeout(ok, 1000));
    }
  } catch (e) {
    // The stream's error handler reconnects.
  } finally {
    const queued = state.loading;
    state.loading = null;
    for (const t of queued) putTile(...t);
  }
}

function showStatus(s) {
  state.status = s;
  state.phase = s.phase;
  if (s.generation !== state.generation) {
    state.generation = s.generation;
  }
  if (s.scene) {
    $("scene").textContent = s.scene;
    document.title = `${s.scene} — Prism preview`;
  }
  // A debug view follows the scene once it has loaded.
  if (state.view && s.generation !== state.viewGeneration && s.phase !== "loading" && s.phase !== "error") {
    showView();
  }
  if (s.exposure != null && s.exposure !== state.sceneExposure) sceneExposure(s.exposure);
  if (s.width && s.height) resize(s.width, s.height);
  const phase = $("phase");
  phase.textContent = s.phase;
  phase.className = "phase " + s.phase;
  $("progress").value = s.total ? s.done / s.total : 0;
  $("eta").textContent = s.phase === "done" ? `done in ${s.elapsed_s.toFixed(2)} s`
    : s.eta_s != null ? `ETA ${s.eta_s.toFixed(1)} s` : "";
  $("summary").textContent = s.summary || "";
  const errors = $("errors");
  errors.hidden = !s.errors.length;
  errors.textContent = s.errors.map((e) =>
    `${e.file}:${e.line}:${e.column}: error: ${e.message}`).join("\n");
}

function notice(text) {
  state.notice = text;
  $("notice").textContent = text;
  $("notice").hidden = !text;
}

let retry = 1;
function connect() {
  const events = new EventSource("/events");
  events.onerror = async () => {
    if (events.readyState !== EventSource.CLOSED) {
      notice("connection lost; reconnecting …");
      return;
    }
    // Refused (the browser does not retry that): say why, try again.
    let why = "the preview server cannot be reached";
    try {
      const r = await fetch("/events");
      why = r.ok ? "" : (await r.text()).trim();
      if (r.body) r.body.cancel();
    } catch (e) { /* not reachable */ }
    const wait = retry;
    retry = Math.min(retry * 2, 10);
    notice(`${why || "disconnected"}; retrying in ${wait} s`);
    setTimeout(connect, wait * 1000);
  };
  events.addEventListener("status", (e) => showStatus(JSON.parse(e.data)));
  events.addEventListener("frame", (e) => {
    const f = JSON.parse(e.data);
    state.coarseAt = performance.now();
    putCoarse(f.width, f.height, decode(f.data));
  });
  events.addEventListener("tile", (e) => {
    const t = JSON.parse(e.data);
    if (state.radiance) putTile(t.x0, t.y0, t.w, t.h, decode(t.data));
  });
  events.addEventListener("lagged", loadPicture);
  events.onopen = () => { retry = 1; notice(""); loadPicture(); };
}

// Exposure: the scene's, until the slider moves away from it; the saved
// PNG is written at the exposure shown.
function evText(ev) {
  const tenths = Math.abs(ev * 10 - Math.round(ev * 10)) < 1e-9;
  return `${tenths ? ev.toFixed(1) : String(+ev.toFixed(4))} EV`;
}
function setExposure(ev, moved) {
  state.exposure = ev;
  state.exposureMoved = moved;
  const slider = $("exposure");
  if (!moved) {
    // The scene's value, even beyond the slider's range or between its steps.
    slider.min = Math.min(-6, Math.floor(ev));
    slider.max = Math.max(6, Math.ceil(ev));
    slider.value = ev;
  }
  $("ev").textContent = evText(ev);
  const save = $("save-png");
  save.href = `/save.png?ev=${encodeURIComponent(ev)}`;
  $("save-ev").textContent = `at ${evText(ev)}` +
    (moved ? "" : " (the scene's)");
  const back = $("exposure-scene");
  back.hidden = !moved || state.sceneExposure === null;
  if (state.sceneExposure !== null) back.textContent = `scene's ${evText(state.sceneExposure)}`;
  redraw();
}
// The scene file's exposure changed (or is first known): followed unless
// the user chose another; then only the button back to it changes.
function sceneExposure(ev) {
  state.sceneExposure = ev;
  if (!state.exposureMoved) setExposure(ev, false);
  else setExposure(state.exposure, Math.abs(state.exposure - ev) > 1e-9);
}
$("exposure").oninput = (e) => {
  const ev = parseFloat(e.target.value);
  setExposure(ev, state.sceneExposure === null || Math.abs(ev - state.sceneExposure) > 1e-9);
};
$("exposure-scene").onclick = () => setExposure(state.sceneExposure, false);
function applyZoom() {
  const z = parseInt($("zoom").value, 10);
  $("zoomv").textContent = `${z}×`;
  $("stage").style.transform = `scale(${z})`;
  $("stage").style.width = `${state.width}px`;
}
$("zoom").oninput = applyZoom;

function pixelAt(ev) {
  const r = canvas.getBoundingClientRect();
  const x = Math.floor((ev.clientX - r.left) / r.width * state.width);
  const y = Math.floor((ev.clientY - r.top) / r.height * state.height);
  return x >= 0 && y >= 0 && x < state.width && y < state.height ? [x, y] : null;
}
$("stage").onmousemove = (ev) => {
  const p = pixelAt(ev);
  if (!p || !state.radiance) return;
  const i = (p[1] * state.width + p[0]) * 3, v = state.radiance;
  $("cursor").textContent = `(${p[0]}, ${p[1]}) linear RGB ${v[i].toFixed(5)} ${v[i + 1].toFixed(5)} ${v[i + 2].toFixed(5)}`;
};
$("stage").onclick = (ev) => {
  const p = pixelAt(ev);
  if (p) explain(p[0], p[1]);
};

// Debug views: fetched (so that a view no longer wanted is abandoned, and
// the server stops rendering it), shown over the picture, renewed when the
// scene changes; the heat ramps get a legend.
const RAMPS = { bounces: "depth of the deepest ray", feelers: "shadow feelers per pixel",
  time: "nanoseconds per pixel" };
let viewRequest = null;
async function showView() {
  if (viewRequest) viewRequest.abort();
  const name = state.view, img = $("aov");
  if (!name) {
    img.hidden = true; $("legend").hidden = true;
    state.viewGeneration = 0;
    return;
  }
  const request = viewRequest = new AbortController();
  state.viewGeneration = state.generation;
  try {
    const r = await fetch(`/aov.png?name=${name}&g=${state.generation}`, { signal: request.signal });
    if (r.status === 503) {
      // Busy: ask again shortly, unless another view was chosen meanwhile.
      setTimeout(() => { if (request === viewRequest) showView(); }, 1000);
      return;
    }
    if (!r.ok) { notice(`${name}: ${(await r.text()).trim()}`); return; }
    const top = r.headers.get("x-prism-ramp-top");
    const blob = await r.blob();
    if (request !== viewRequest) return;
    if (img.src.startsWith("blob:")) URL.revokeObjectURL(img.src);
    img.src = URL.createObjectURL(blob);
    img.dataset.generation = r.headers.get("x-prism-generation") || "";
    img.dataset.view = name;
    img.hidden = false;
    state.viewTop = top === null ? null : +top;
    $("legend").hidden = top === null;
    if (top !== null) {
      $("legend-top").textContent = (+top).toPrecision(4).replace(/\.?0+$/, "") + " or more";
      $("legend-what").textContent = `${name}: ${RAMPS[name]}, black to white`;
    }
  } catch (e) {
    if (e.name !== "AbortError") notice(`${name}: ${e}`);
  }
}
$("view-select").onchange = (e) => {
  state.view = e.target.value;
  showView();
};

// The inspector: the ray tree of one sample.
const fmt = (v) => v.map((x) => x.toFixed(6)).join(", ");
function nodeHtml(n) {
  const rows = [];
  const row = (k, v) => rows.push(`<tr><td>${k}</td><td>${v}</td></tr>`);
  row("ray", `${n.kind}, depth ${n.depth}, weight (${fmt(n.weight)})`);
  if (!n.hit) {
    row("hit", "nothing: the background");
  } else {
    const h = n.hit;
    row("hit", `<b>${escapeHtml(h.object)}</b> (material ${escapeHtml(h.material)}) at distance ${h.distance.toFixed(6)}`);
    row("point / normal", `(${fmt(h.point)}) / (${fmt(h.normal)})`);
    row("side", (h.entering ? "entering" : "leaving") +
      (h.eta_incoming != null ? `, η ${h.eta_incoming} → ${h.eta_beyond}` : ""));
    row("ka·Od·Ia", fmt(n.ambient));
    for (const l of n.lights) {
      row(`light ${escapeHtml(l.light)}`, `visible (${fmt(l.visible_fraction)}) of ${l.samples} samples, ${l.feelers} feelers`);
      row("&nbsp; kd·Od·max(0,N·L)", fmt(l.diffuse));
      row("&nbsp; ks·max(0,R·V)ⁿ", fmt(l.specular));
    }
    row("kr / kt", `(${fmt(n.kr)}) / (${fmt(n.kt)})` + (n.total_internal_reflection ? " — total internal reflection" : ""));
    if (n.reflected) row("kr·I_reflected", fmt(n.reflected_term));
    if (n.refracted) row("kt·I_refracted", fmt(n.refracted_term));
  }
  for (const s of n.stopped) rows.push(`<tr class="stop"><td>stops</td><td>${s}</td></tr>`);
  row("= radiance", `<b>${fmt(n.radiance)}</b>`);
  const kids = [n.reflected, n.refracted].filter(Boolean).map(nodeHtml).join("");
  return `<div class="node ${n.kind}" data-kind="${n.kind}"><table>${rows.join("")}</table>${kids}</div>`;
}
function escapeHtml(s) {
  return s.replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" })[c]);
}

async function explain(x, y) {
  const r = await fetch(`/explain?x=${x}&y=${y}&sample=0`);
  if (!r.ok) { $("inspector").textContent = await r.text(); return; }
  const e = await r.json();
  state.explanation = e;
  $("inspector").innerHTML =
    `<p>Pixel (${x}, ${y}), sample ${e.sample} of ${e.samples}: radiance <b id="inspect-radiance">${fmt(e.radiance)}</b></p>` +
    (e.lens_point ? `<p>Through the lens at ${fmt(e.lens_point)} (right, up from its centre)</p>` : "") +
    (e.time != null ? `<p>At the shutter's instant ${e.time.toFixed(4)} frames after the frame's start</p>` : "") +
    nodeHtml(e.tree);
  // The sample's rays over the picture.
  rctx.clearRect(0, 0, rays.width, rays.height);
  const colours = { camera: "#ffd54f", reflected: "#4fc3f7", refracted: "#81c784" };
  rctx.lineWidth = 1.5;
  for (const s of e.segments) {
    rctx.strokeStyle = colours[s.kind];
    rctx.beginPath();
    rctx.moveTo(s.screen[0], s.screen[1]);
    rctx.lineTo(s.screen[2], s.screen[3]);
    rctx.stroke();
  }
}

// The token is kept in a cookie now: out of the address bar.
if (new URLSearchParams(location.search).has("token")) history.replaceState(null, "", "/");
connect();
