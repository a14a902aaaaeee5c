"""The lecture worked on a pixel, in a notebook: ``prism.explain`` returns an
:class:`Explanation`, the dict ``prism explain --json`` gives, which Jupyter
draws through ``_repr_html_`` (no server): each ray of the tree with its
intersection test step by step, the notes' picture of a polygon's crossing
count, Snell's construction with the critical angle, R = I − 2N(I·N), and
why the other objects were rejected. The values drawn are the renderer's own
(see docs/teaching.md)."""

from __future__ import annotations

import html
import math
from typing import Any, Dict, List, Optional

__all__ = ["Explanation"]


def _num(x: Optional[float], digits: int = 6) -> str:
    return "–" if x is None else f"{x:.{digits}f}"


def _vec(v: Optional[List[float]], digits: int = 4) -> str:
    return "–" if v is None else "(" + ", ".join(f"{c:.{digits}f}" for c in v) + ")"


_CASE_COLOURS = {"both z positive": "#999", "both z negative": "#999",
                 "both x negative": "#a1887f", "x_int": "#fb8c00"}


def polygon_svg(p: Dict[str, Any], width: int = 320, height: int = 240) -> str:
    """The notes' point-in-polygon picture: the polygon projected along its
    principal axis and translated so the hit is the origin, the test ray
    along +x, each edge coloured by its case, each x_int marked."""
    pts = p["translated_polygon"]
    xs = [q[0] for q in pts] + [0.0]
    zs = [q[1] for q in pts] + [0.0]
    x0, x1, z0, z1 = min(xs), max(xs), min(zs), max(zs)
    pad = 18
    k = min((width - 2 * pad) / ((x1 - x0) or 1), (height - 2 * pad) / ((z1 - z0) or 1))

    def X(x: float) -> float:
        return pad + (x - x0) * k

    def Z(z: float) -> float:
        return height - pad - (z - z0) * k

    out = [f'<polygon points="{" ".join(f"{X(q[0]):.2f},{Z(q[1]):.2f}" for q in pts)}" '
           'fill="rgba(0,0,0,0.06)" stroke="none"/>',
           f'<line x1="{X(0):.2f}" y1="{Z(0):.2f}" x2="{width - 2}" y2="{Z(0):.2f}" '
           'stroke="#f9a825" stroke-width="1.5"/>']
    for i, e in enumerate(p["edges"]):
        colour = "#2e7d32" if e["crosses"] else _CASE_COLOURS.get(e["case"], "#999")
        out.append(f'<line class="edge" data-edge="{i}" data-case="{e["case"]}" '
                   f'x1="{X(e["from"][0]):.2f}" y1="{Z(e["from"][1]):.2f}" '
                   f'x2="{X(e["to"][0]):.2f}" y2="{Z(e["to"][1]):.2f}" stroke="{colour}" '
                   f'stroke-width="{2.5 if e["crosses"] else 1.5}"/>')
        if e["x_int"] is not None:
            fill = "#2e7d32" if e["crosses"] else "none"
            stroke = "#2e7d32" if e["crosses"] else "#e53935"
            out.append(f'<circle cx="{X(e["x_int"]):.2f}" cy="{Z(0):.2f}" r="3.5" '
                       f'fill="{fill}" stroke="{stroke}"/>')
    out.append(f'<circle cx="{X(0):.2f}" cy="{Z(0):.2f}" r="3" fill="#000"/>')
    out.append(f'<text x="{width - 4}" y="{Z(0) - 4:.2f}" text-anchor="end" font-size="11" '
               f'fill="#f57f17">+x ({p["x_axis"]})</text>')
    return (f'<svg class="polygon-diagram" width="{width}" height="{height}" '
            f'viewBox="0 0 {width} {height}" style="background:#fafafa;border:1px solid #ccc">'
            + "".join(out) + "</svg>")


def snell_svg(r: Dict[str, Any], width: int = 320, height: int = 220) -> str:
    """Snell's construction in the plane of I and N: the surface across, N
    up, I arriving, T leaving below (or R under total internal reflection),
    the critical angle dashed."""
    dot = lambda a, b: sum(x * y for x, y in zip(a, b))  # noqa: E731
    length = math.hypot(*r["u"])
    tangent = [c / length for c in r["u"]] if length > 1e-12 else [0.0, 0.0, 0.0]
    cx, cy, L = width / 2, height / 2, 90

    def to(v: List[float]) -> List[float]:
        return [cx + L * dot(v, tangent), cy - L * dot(v, r["n"])]

    out = [f'<rect x="0" y="{cy}" width="{width}" height="{height - cy}" fill="#e8f5e9"/>',
           f'<line x1="0" y1="{cy}" x2="{width}" y2="{cy}" stroke="#888"/>',
           f'<line x1="{cx}" y1="{cy - L - 8}" x2="{cx}" y2="{cy + L + 8}" stroke="#999" '
           'stroke-dasharray="4 3"/>',
           f'<text x="{cx + 4}" y="{cy - L}" font-size="11">N</text>',
           f'<text x="4" y="{cy - 6}" font-size="11">η_i = {r["eta_i"]}</text>',
           f'<text x="4" y="{cy + 16}" font-size="11">η_t = {r["eta_t"]}</text>']

    def arrow(a: List[float], b: List[float], colour: str, label: str) -> None:
        out.append(f'<line x1="{a[0]:.2f}" y1="{a[1]:.2f}" x2="{b[0]:.2f}" y2="{b[1]:.2f}" '
                   f'stroke="{colour}" stroke-width="2"/>')
        out.append(f'<text x="{b[0] + 5:.2f}" y="{b[1] + 4:.2f}" font-size="12" '
                   f'fill="{colour}">{label}</text>')

    arrow(to([-c for c in r["i"]]), [cx, cy], "#f9a825", "")
    start = to([-c for c in r["i"]])
    out.append(f'<text x="{start[0] - 12:.2f}" y="{start[1]:.2f}" font-size="12" '
               'fill="#f9a825">I</text>')
    if r["critical_angle"] is not None:
        c = math.radians(r["critical_angle"])
        s = -1.0 if dot(r["i"], tangent) >= 0 else 1.0
        out.append(f'<line x1="{cx}" y1="{cy}" x2="{cx + s * L * math.sin(c):.2f}" '
                   f'y2="{cy - L * math.cos(c):.2f}" stroke="#e53935" stroke-dasharray="5 3"/>')
        out.append(f'<text x="{cx + s * L * math.sin(c) + (-70 if s < 0 else 4):.2f}" '
                   f'y="{cy - L * math.cos(c) - 4:.2f}" font-size="11" fill="#e53935">'
                   f'θc {r["critical_angle"]:.1f}°</text>')
    if r["t"] is not None:
        arrow([cx, cy], to(r["t"]), "#2e7d32", "T")
    else:
        nd = dot(r["i"], r["n"])
        arrow([cx, cy], to([c - 2 * nc * nd for c, nc in zip(r["i"], r["n"])]), "#0277bd", "R")
    return (f'<svg class="snell-diagram" width="{width}" height="{height}" '
            f'viewBox="0 0 {width} {height}" style="background:#fafafa;border:1px solid #ccc">'
            + "".join(out) + "</svg>")


def _test_html(t: Dict[str, Any]) -> str:
    lines = [f'<b>{html.escape(t["object"])}</b> ({t["shape"]}): {html.escape(t["verdict"])}']
    if t.get("plane"):
        p = t["plane"]
        lines.append(f'n = {_vec(p["normal"])}, n·d = {_num(p["n_dot_d"])} → <b>{p["verdict"]}</b>; '
                     f't = (d − n·O)/(n·d) = {_num(p["t"])}'
                     + (f'; P = O + tD = {_vec(p["point"])}' if p["point"] else ""))
    diagram = ""
    if t.get("polygon"):
        p = t["polygon"]
        lines.append(f'principal axis <b>{p["principal_axis"]}</b> → project onto the '
                     f'<b>{p["projected_onto"]}</b> plane; <b>{p["crossings"]}</b> crossings of +x: '
                     f'<b>{p["parity"]}</b> → {"inside" if p["inside"] else "outside"}')
        diagram = polygon_svg(p)
    if t.get("sphere"):
        q = t["sphere"]
        roots = ("no real roots" if q["roots"] is None else
                 f'roots t₀ = {_num(q["roots"][0])}, t₁ = {_num(q["roots"][1])}; '
                 + (f'<b>{q["taken"]}</b> taken' if q["taken"] else "both behind the ray"))
        lines.append(f'a = {_num(q["a"])}, b = {_num(q["b"])}, c = {_num(q["c"])}; '
                     f'discriminant b² − 4ac = <b>{_num(q["discriminant"])}</b>; {roots}')
    if t.get("triangle"):
        w = t["triangle"]
        lines.append(f'watertight test of triangle {w["triangle"]}: U, V, W = '
                     f'{_vec(w["edge_functions"])} ({w["signs"]}), t = {_num(w["t"])}, '
                     f'barycentrics {_vec(w["barycentric"])}')
    return "<div>" + "<br>".join(lines) + "</div>" + diagram


def _node_html(n: Dict[str, Any]) -> str:
    colour = {"camera": "#f9a825", "reflected": "#0277bd", "refracted": "#2e7d32"}[n["kind"]]
    parts = [f'<div style="border-left:3px solid {colour};margin:4px 0 4px 6px;padding-left:8px">',
             f'<div><b>{n["kind"]}</b> ray, depth {n["depth"]}: radiance {_vec(n["radiance"])}</div>']
    if n["hit"] is None:
        parts.append("<div>misses everything: the background</div>")
    if n.get("intersection"):
        parts.append(_test_html(n["intersection"]))
    if n.get("reflection"):
        r = n["reflection"]
        parts.append(f'<div>R = I − 2N(I·N): I·N = {_num(r["i_dot_n"])}, R = {_vec(r["r"])}, '
                     f'angle {r["theta"]:.2f}°</div>')
    if n.get("refraction"):
        r = n["refraction"]
        crit = ("no critical angle (η_i ≤ η_t)" if r["critical_angle"] is None
                else f'critical angle <b>{r["critical_angle"]:.2f}°</b>')
        verdict = (f'<b>total internal reflection</b>: 1 − η²(1 − cos²θi) = {_num(r["radicand"])} &lt; 0, no T'
                   if r["total_internal_reflection"]
                   else f'θt = {r["theta_t"]:.2f}°, T = w + ηu = {_vec(r["t"])}')
        parts.append(f'<div>Snell: η = {r["eta_i"]}/{r["eta_t"]}, θi = <b>{r["theta_i"]:.2f}°</b>, '
                     f'{crit}; {verdict}</div>' + snell_svg(r))
    for light in n.get("lights", []):
        blocked = sum(1 for f in light["feeler_points"] if f["blocked_by"])
        parts.append(f'<div>light {html.escape(light["light"])}: {light["feelers"]} feelers, '
                     f'{blocked} of those listed blocked; visible {_vec(light["visible_fraction"], 3)}</div>')
    if n.get("rejected"):
        more = n.get("rejected_left_out", 0)
        items = "".join(f"<li>{_test_html(t)}</li>" for t in n["rejected"])
        parts.append(f"<details><summary>also tested ({len(n['rejected']) + more})</summary>"
                     f"<ul>{items}</ul></details>")
    for child in (n.get("reflected"), n.get("refracted")):
        if child:
            parts.append(_node_html(child))
    parts.append("</div>")
    return "".join(parts)


class Explanation(dict):
    """The ray tree of one sample of a pixel, as ``prism explain --json``
    gives it (a dict), drawn in Jupyter by :meth:`_repr_html_`."""

    def nodes(self) -> List[Dict[str, Any]]:
        """Every ray of the tree, depth first."""
        out: List[Dict[str, Any]] = []
        stack = [self["tree"]]
        while stack:
            n = stack.pop()
            out.append(n)
            stack += [c for c in (n.get("refracted"), n.get("reflected")) if c]
        return out

    def _repr_html_(self) -> str:
        x, y = self["pixel"]
        return (f'<div class="prism-explanation" style="font:13px sans-serif">'
                f'<div>Pixel ({x}, {y}), sample {self["sample"]} of {self["samples"]}: '
                f'radiance {_vec(self["radiance"])}</div>' + _node_html(self["tree"]) + "</div>")
