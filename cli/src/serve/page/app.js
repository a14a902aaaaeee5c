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
  return `<div class="node ${n.kind}" data-kind="${n.kind}"><table>${rows.join("")}</table>` +
    lectureHtml(n) + `${kids}</div>`;
}

// The lecture worked on the ray: the test of what it hit, step by step,
// with the notes' diagrams (the projected polygon and its crossings;
// Snell's construction), R = I − 2N(I·N), and what else it was tested
// against.
const num = (x, d = 6) => (x == null ? "–" : (+x).toFixed(d));
function lectureHtml(n) {
  const parts = [];
  if (n.intersection) parts.push(testHtml(n.intersection, true));
  if (n.reflection) {
    const r = n.reflection;
    parts.push(`<div class="step reflection">R = I − 2N(I·N): I·N = ${num(r.i_dot_n)}, ` +
      `R = (${fmt(r.r)}), angle ${num(r.theta, 2)}°</div>`);
  }
  if (n.refraction) parts.push(snellHtml(n.refraction));
  if (n.rejected && n.rejected.length) {
    const more = n.rejected_left_out ? ` (${n.rejected.length} nearest the ray of ` +
      `${n.rejected.length + n.rejected_left_out})` : "";
    const items = n.rejected.map((t) => `<li>${testHtml(t, false)}</li>`).join("");
    // Open at a camera ray that missed a polygon whose plane it met (a
    // click beside a polygon: why it was missed, in the picture).
    const hitPolygon = n.intersection && n.intersection.polygon;
    const open = n.depth === 1 && !hitPolygon && n.rejected.some((t) => t.polygon) ? " open" : "";
    parts.push(`<details class="rejected"${open}><summary>also tested${more}</summary><ul>${items}</ul></details>`);
  }
  return parts.join("");
}
function testHtml(t, open) {
  const lines = [`<b>${escapeHtml(t.object)}</b> (${t.shape}): ${escapeHtml(t.verdict)}`];
  if (t.plane) {
    const p = t.plane;
    lines.push(`n = (${fmt(p.normal)}), n·d = ${num(p.n_dot_d)} → <b>${p.verdict}</b>; ` +
      `t = (d − n·O)/(n·d) = ${num(p.t)}` + (p.point ? `; P = O + tD = (${fmt(p.point)})` : ""));
  }
  if (t.sphere) {
    const q = t.sphere;
    lines.push(`a t² + b t + c = 0${q.object_space ? " (unit sphere, object space)" : ""}: ` +
      `a = ${num(q.a)}, b = ${num(q.b)}, c = ${num(q.c)}; discriminant b² − 4ac = ` +
      `<b class="discriminant">${num(q.discriminant)}</b>; ` +
      (q.roots ? `roots t₀ = ${num(q.roots[0])}, t₁ = ${num(q.roots[1])}; ` +
        (q.taken ? `<b>${q.taken}</b> taken` : "both behind the ray") : "no real roots"));
  }
  if (t.triangle) {
    const w = t.triangle;
    lines.push(`watertight test of triangle ${w.triangle}${w.object_space ? " (mesh space)" : ""}: ` +
      `axes (kx, ky, kz) = (${w.axes.join(", ")}); edge functions U, V, W = (${fmt(w.edge_functions)}) ` +
      `<b>${w.signs}</b>, det = ${num(w.det)}, t = ${num(w.t)}, barycentrics (${w.barycentric ? fmt(w.barycentric) : "–"})`);
  }
  let diagram = "";
  if (t.polygon) diagram = polygonHtml(t.polygon, t.primitive);
  const body = lines.map((l) => `<div>${l}</div>`).join("") + diagram;
  return `<div class="step test" data-primitive="${t.primitive}">` +
    (open ? body : `<details${diagram ? " open" : ""}><summary>${lines[0]}</summary>${lines.slice(1).map((l) => `<div>${l}</div>`).join("")}${diagram}</details>`) +
    "</div>";
}

// The notes' point-in-polygon picture: the polygon projected along its
// principal axis, translated so the hit is the origin, the test ray along
// +x, each edge coloured by its case and each x_int marked.
const CASE_COLOURS = { "both z positive": "#777", "both z negative": "#777",
  "both x negative": "#a1887f", x_int: "#ffb74d" };
function polygonHtml(p, primitive) {
  const pts = p.translated_polygon;
  const xs = pts.map((q) => q[0]).concat([0]), zs = pts.map((q) => q[1]).concat([0]);
  const [x0, x1, z0, z1] = [Math.min(...xs), Math.max(...xs), Math.min(...zs), Math.max(...zs)];
  const W = 320, H = 240, pad = 18;
  const k = Math.min((W - 2 * pad) / (x1 - x0 || 1), (H - 2 * pad) / (z1 - z0 || 1));
  const X = (x) => pad + (x - x0) * k, Z = (z) => H - pad - (z - z0) * k;
  const svg = [];
  svg.push(`<polygon points="${pts.map((q) => `${X(q[0])},${Z(q[1])}`).join(" ")}" fill="rgba(255,255,255,0.08)" stroke="none"/>`);
  svg.push(`<line x1="${X(x0)}" y1="${Z(0)}" x2="${W}" y2="${Z(0)}" stroke="#555" stroke-dasharray="3 3"/>`);
  svg.push(`<line x1="${X(0)}" y1="${Z(0)}" x2="${W - 2}" y2="${Z(0)}" stroke="#ffd54f" stroke-width="1.5" class="test-ray"/>`);
  svg.push(`<line x1="${X(0)}" y1="${Z(z0)}" x2="${X(0)}" y2="${Z(z1)}" stroke="#555" stroke-dasharray="3 3"/>`);
  p.edges.forEach((e, i) => {
    const colour = e.crosses ? "#66bb6a" : CASE_COLOURS[e.case];
    svg.push(`<line class="edge" data-edge="${i}" data-case="${e.case}" data-crosses="${e.crosses}"` +
      (e.x_int != null ? ` data-x-int="${e.x_int}"` : "") +
      ` x1="${X(e.from[0])}" y1="${Z(e.from[1])}" x2="${X(e.to[0])}" y2="${Z(e.to[1])}"` +
      ` stroke="${colour}" stroke-width="${e.crosses ? 2.5 : 1.5}"/>`);
    if (e.x_int != null) {
      svg.push(`<circle class="x-int" cx="${X(e.x_int)}" cy="${Z(0)}" r="3.5" ` +
        `fill="${e.crosses ? "#66bb6a" : "none"}" stroke="${e.crosses ? "#66bb6a" : "#ef5350"}"/>`);
    }
  });
  svg.push(`<circle cx="${X(0)}" cy="${Z(0)}" r="3" fill="#fff"/>`);
  svg.push(`<text x="${W - 4}" y="${Z(0) - 4}" text-anchor="end" fill="#ffd54f" font-size="11">+x (${p.x_axis})</text>`);
  svg.push(`<text x="${X(0) + 4}" y="12" fill="#aaa" font-size="11">z (${p.z_axis})</text>`);
  const rows = p.edges.map((e, i) => `<tr><td>${i}</td><td>(${num(e.from[0], 3)}, ${num(e.from[1], 3)}) → ` +
    `(${num(e.to[0], 3)}, ${num(e.to[1], 3)})</td><td>${e.case}</td><td>${e.x_int == null ? "" : num(e.x_int, 4)}</td>` +
    `<td>${e.crosses ? "crosses" : ""}</td></tr>`).join("");
  const left = p.edges_left_out ? `<div>${p.edges_left_out} more edges not listed</div>` : "";
  return `<div class="polygon-diagram" data-primitive="${primitive}" data-principal-axis="${p.principal_axis}" ` +
    `data-crossings="${p.crossings}" data-parity="${p.parity}" data-inside="${p.inside}">` +
    `<div>principal axis <b>${p.principal_axis}</b> (largest |n| component): project onto the <b>${p.projected_onto}</b> plane; ` +
    `translate P = (${num(p.point[0], 4)}, ${num(p.point[1], 4)}) to the origin; count crossings of +x</div>` +
    `<svg width="${W}" height="${H}" viewBox="0 0 ${W} ${H}">${svg.join("")}</svg>` +
    `<div class="verdict"><b class="crossings">${p.crossings}</b> crossings: <b>${p.parity}</b> → ` +
    `${p.inside ? "inside" : "outside"}</div>` +
    `<details><summary>edges</summary><table><tr><td>#</td><td>from → to (x, z)</td><td>case</td><td>x_int</td><td></td></tr>${rows}</table>${left}</details></div>`;
}

// Snell's construction in the plane of I and N: N up, the surface across,
// I arriving, T = w + ηu leaving below (or, past the critical angle, no T
// and R instead), the angles marked.
function snellHtml(r) {
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const len = Math.hypot(...r.u);
  // The tangent: along u; at normal incidence any direction in the plane.
  const tan = len > 1e-12 ? r.u.map((c) => c / len) : [0, 0, 0];
  const W = 320, H = 220, cx = 160, cy = 110, L = 90;
  const to = (v) => [cx + L * dot(v, tan), cy - L * dot(v, r.n)];
  const svg = [];
  svg.push(`<rect x="0" y="${cy}" width="${W}" height="${H - cy}" fill="rgba(129,199,132,0.10)"/>`);
  svg.push(`<line x1="0" y1="${cy}" x2="${W}" y2="${cy}" stroke="#888"/>`);
  svg.push(`<line x1="${cx}" y1="${cy - L - 10}" x2="${cx}" y2="${cy + L + 10}" stroke="#777" stroke-dasharray="4 3"/>`);
  svg.push(`<text x="${cx + 4}" y="${cy - L}" fill="#ccc" font-size="11">N</text>`);
  svg.push(`<text x="4" y="${cy - 6}" fill="#aaa" font-size="11">η_i = ${r.eta_i}</text>`);
  svg.push(`<text x="4" y="${cy + 16}" fill="#aaa" font-size="11">η_t = ${r.eta_t}</text>`);
  const arrow = (from, tip, colour, label, cls) => {
    svg.push(`<line class="${cls}" x1="${from[0]}" y1="${from[1]}" x2="${tip[0]}" y2="${tip[1]}" stroke="${colour}" stroke-width="2"/>`);
    svg.push(`<circle cx="${tip[0]}" cy="${tip[1]}" r="3" fill="${colour}"/>`);
    svg.push(`<text x="${tip[0] + 5}" y="${tip[1] + 4}" fill="${colour}" font-size="12">${label}</text>`);
  };
  // I ends at the hit: drawn from −I.
  const start = to(r.i.map((c) => -c));
  arrow(start, [cx, cy], "#ffd54f", "", "ray-i");
  svg.push(`<text x="${start[0] - 12}" y="${start[1]}" fill="#ffd54f" font-size="12">I</text>`);
  if (r.critical_angle != null) {
    const c = r.critical_angle * Math.PI / 180, s = Math.sign(-dot(r.i, tan)) || -1;
    svg.push(`<line class="critical" x1="${cx}" y1="${cy}" x2="${cx + s * L * Math.sin(c)}" y2="${cy - L * Math.cos(c)}" stroke="#ef5350" stroke-dasharray="5 3"/>`);
    svg.push(`<text x="${cx + s * L * Math.sin(c) + (s < 0 ? -70 : 4)}" y="${cy - L * Math.cos(c) - 4}" fill="#ef5350" font-size="11">θc ${r.critical_angle.toFixed(1)}°</text>`);
  }
  if (r.t) {
    arrow([cx, cy], to(r.t), "#81c784", "T", "ray-t");
    if (r.w) svg.push(`<line x1="${cx}" y1="${cy}" x2="${to(r.w)[0]}" y2="${to(r.w)[1]}" stroke="#81c784" stroke-dasharray="2 2"/>`);
  } else {
    // All of it reflected: R = I − 2N(I·N).
    const nd = dot(r.i, r.n);
    const refl = r.i.map((c, k) => c - 2 * r.n[k] * nd);
    arrow([cx, cy], to(refl), "#4fc3f7", "R", "ray-r");
  }
  svg.push(`<text x="${cx - 60}" y="${cy - 30}" fill="#ffd54f" font-size="11">θi ${r.theta_i.toFixed(1)}°</text>`);
  if (r.theta_t != null) svg.push(`<text x="${cx + 8}" y="${cy + 40}" fill="#81c784" font-size="11">θt ${r.theta_t.toFixed(1)}°</text>`);
  const verdict = r.total_internal_reflection
    ? `θi = ${num(r.theta_i, 2)}° > θc = ${num(r.critical_angle, 2)}°: <b>total internal reflection</b> ` +
      `(1 − η²(1 − cos²θi) = ${num(r.radicand)} &lt; 0), no T`
    : `θt = ${num(r.theta_t, 2)}°, T = w + ηu = (${fmt(r.t)})`;
  return `<div class="snell-diagram" data-theta-i="${r.theta_i}" data-theta-t="${r.theta_t ?? ""}" ` +
    `data-critical-angle="${r.critical_angle ?? ""}" data-tir="${r.total_internal_reflection}">` +
    `<div>Snell: η = η_i/η_t = ${r.eta_i}/${r.eta_t} = ${num(r.eta, 4)}; cos θi = −I·N = ${num(r.cos_i)}, ` +
    `θi = <b>${num(r.theta_i, 2)}°</b>` + (r.critical_angle != null ? `, critical angle <b>${num(r.critical_angle, 2)}°</b>` : ", no critical angle (η_i ≤ η_t)") +
    `</div><svg width="${W}" height="${H}" viewBox="0 0 ${W} ${H}">${svg.join("")}</svg><div class="verdict">${verdict}</div></div>`;
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
    `<div class="space"><canvas id="space" width="440" height="280"></canvas>` +
    `<div>In space: drag to turn the view. Camera white, lights yellow, rays as over the picture.</div></div>` +
    nodeHtml(e.tree);
  drawSpace();
  spaceEvents();
  // The sample's rays over the picture, its shadow feelers too: a blocked
  // one red, ending in a cross where it was blocked.
  rctx.clearRect(0, 0, rays.width, rays.height);
  const colours = { camera: "#ffd54f", reflected: "#4fc3f7", refracted: "#81c784", feeler: "#fff59d" };
  for (const s of e.segments) {
    const [ax, ay, bx, by] = s.screen;
    rctx.strokeStyle = s.blocked ? "#ef5350" : colours[s.kind];
    rctx.lineWidth = s.kind === "feeler" ? 1 : 1.5;
    rctx.setLineDash(s.kind === "feeler" ? [3, 2] : []);
    rctx.beginPath();
    rctx.moveTo(ax, ay);
    rctx.lineTo(bx, by);
    rctx.stroke();
    if (s.blocked) {
      rctx.setLineDash([]);
      rctx.beginPath();
      rctx.moveTo(bx - 3, by - 3); rctx.lineTo(bx + 3, by + 3);
      rctx.moveTo(bx + 3, by - 3); rctx.lineTo(bx - 3, by + 3);
      rctx.stroke();
    }
  }
  rctx.setLineDash([]);
}

// The 3D view: the scene in outline (the server's `space`), the camera,
// the lights and the sample's ray tree with its feelers, seen from an
// orbiting eye (drag to turn it), drawn on a plain 2D canvas.
const orbit = { yaw: null, pitch: 0.35 };
const v3 = {
  add: (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]],
  sub: (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]],
  mul: (a, k) => [a[0] * k, a[1] * k, a[2] * k],
  dot: (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2],
  cross: (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]],
  unit: (a) => { const l = Math.hypot(...a) || 1; return [a[0] / l, a[1] / l, a[2] / l]; },
};
function treeNodes(n) {
  return [n].concat(...[n.reflected, n.refracted].filter(Boolean).map(treeNodes));
}
function drawSpace() {
  const e = state.explanation, cv = $("space");
  if (!e || !cv || !e.space) return;
  const g = cv.getContext("2d"), W = cv.width, H = cv.height;
  g.fillStyle = "#15161a"; g.fillRect(0, 0, W, H);
  const sp = e.space, nodes = treeNodes(e.tree);
  // The view holds the camera and the tree's points.
  const pts = [sp.camera.position];
  for (const n of nodes) { pts.push(n.origin); if (n.hit) pts.push(n.hit.point); }
  const centre = v3.mul(pts.reduce(v3.add, [0, 0, 0]), 1 / pts.length);
  const R = Math.max(1e-3, ...pts.map((p) => Math.hypot(...v3.sub(p, centre))));
  if (orbit.yaw === null) {
    // First seen from the scene's camera, turned 35° to show depth.
    const f = sp.camera.forward;
    orbit.yaw = Math.atan2(-f[0], -f[2]) + 0.6;
    orbit.pitch = Math.max(-1.4, Math.min(1.4, Math.asin(Math.max(-1, Math.min(1, -f[1]))) + 0.25));
  }
  const D = 2.6 * R;
  const eye = v3.add(centre, v3.mul([Math.cos(orbit.pitch) * Math.sin(orbit.yaw),
    Math.sin(orbit.pitch), Math.cos(orbit.pitch) * Math.cos(orbit.yaw)], D));
  const fw = v3.unit(v3.sub(centre, eye)), rt = v3.unit(v3.cross(fw, [0, 1, 0])), up = v3.cross(rt, fw);
  const focal = H / (2 * Math.tan(25 * Math.PI / 180));
  const project = (p) => {
    const d = v3.sub(p, eye), z = v3.dot(d, fw);
    return z > 1e-3 * D ? [W / 2 + focal * v3.dot(d, rt) / z, H / 2 - focal * v3.dot(d, up) / z] : null;
  };
  const line = (a, b, colour, width = 1, dash = []) => {
    const pa = project(a), pb = project(b);
    if (!pa || !pb) return false;
    g.strokeStyle = colour; g.lineWidth = width; g.setLineDash(dash);
    g.beginPath(); g.moveTo(...pa); g.lineTo(...pb); g.stroke();
    return true;
  };
  const loop = (ps, colour) => ps.forEach((p, i) => line(p, ps[(i + 1) % ps.length], colour));
  // Objects in outline.
  for (const o of sp.objects) {
    const colour = "#666";
    if (o.sphere) {
      const { center: c, radius: r } = o.sphere;
      for (const [a, b] of [[[1, 0, 0], [0, 1, 0]], [[0, 1, 0], [0, 0, 1]], [[1, 0, 0], [0, 0, 1]]]) {
        loop([...Array(32).keys()].map((k) => {
          const t = 2 * Math.PI * k / 32;
          return v3.add(c, v3.add(v3.mul(a, r * Math.cos(t)), v3.mul(b, r * Math.sin(t))));
        }), colour);
      }
    } else if (o.polygon) {
      loop(o.polygon, "#888");
    } else if (o.plane) {
      const n = o.plane.normal, foot = v3.sub(centre, v3.mul(n, v3.dot(n, centre) - o.plane.d));
      const a = v3.unit(v3.cross(n, Math.abs(n[0]) < 0.9 ? [1, 0, 0] : [0, 1, 0])), b = v3.cross(n, a);
      const S = 1.5 * R;
      for (let k = -4; k <= 4; k++) {
        const s = S * k / 4;
        line(v3.add(foot, v3.add(v3.mul(a, s), v3.mul(b, -S))), v3.add(foot, v3.add(v3.mul(a, s), v3.mul(b, S))), "#3a3a3a");
        line(v3.add(foot, v3.add(v3.mul(b, s), v3.mul(a, -S))), v3.add(foot, v3.add(v3.mul(b, s), v3.mul(a, S))), "#3a3a3a");
      }
    } else if (o.box) {
      const [lo, hi] = o.box;
      const c = (i) => [i & 1 ? hi[0] : lo[0], i & 2 ? hi[1] : lo[1], i & 4 ? hi[2] : lo[2]];
      for (let i = 0; i < 8; i++) for (const bit of [1, 2, 4]) if (!(i & bit)) line(c(i), c(i | bit), colour);
    }
  }
  // The camera and the lights.
  const cam = sp.camera.position;
  line(cam, v3.add(cam, v3.mul(sp.camera.forward, 0.15 * R)), "#fff", 2);
  const dot = (p, colour, r) => {
    const q = project(p);
    if (q) { g.fillStyle = colour; g.beginPath(); g.arc(q[0], q[1], r, 0, 2 * Math.PI); g.fill(); }
  };
  dot(cam, "#fff", 3);
  for (const l of sp.lights) if (l.position) dot(l.position, "#ffeb3b", 4);
  // The tree: rays to their hits (a miss: as far as the view reaches) and
  // the listed feelers, blocked ones red to their blocker.
  const colours = { camera: "#ffd54f", reflected: "#4fc3f7", refracted: "#81c784" };
  let rays = 0, feelers = 0;
  for (const n of nodes) {
    const end = n.hit ? n.hit.point : v3.add(n.origin, v3.mul(n.direction, 2 * R));
    if (line(n.origin, end, colours[n.kind], 2)) rays++;
    if (n.hit) dot(n.hit.point, colours[n.kind], 2.5);
    for (const l of n.lights) {
      for (const f of l.feeler_points) {
        const to = f.blocker_distance != null ? v3.add(f.origin, v3.mul(f.direction, f.blocker_distance))
          : f.on_light || v3.add(f.origin, v3.mul(f.direction, 2 * R));
        if (line(f.origin, to, f.blocked_by ? "#ef5350" : "#fff59d", 1, [3, 2])) feelers++;
      }
    }
  }
  g.setLineDash([]);
  state.space = { rays, feelers, objects: sp.objects.length, yaw: orbit.yaw, pitch: orbit.pitch };
}
function spaceEvents() {
  const cv = $("space");
  let from = null;
  cv.onmousedown = (ev) => { from = [ev.clientX, ev.clientY]; ev.preventDefault(); };
  cv.onmousemove = (ev) => {
    if (!from) return;
    orbit.yaw -= (ev.clientX - from[0]) * 0.01;
    orbit.pitch = Math.max(-1.5, Math.min(1.5, orbit.pitch + (ev.clientY - from[1]) * 0.01));
    from = [ev.clientX, ev.clientY];
    drawSpace();
  };
  cv.onmouseup = cv.onmouseleave = () => { from = null; };
}

// The token is kept in a cookie now: out of the address bar.
if (new URLSearchParams(location.search).has("token")) history.replaceState(null, "", "/");
connect();
