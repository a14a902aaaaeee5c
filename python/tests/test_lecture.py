"""prism.explain's result draws the lecture in Jupyter (_repr_html_): the
same tree as `prism explain --json`, and the drawn values are its own."""

import json
import os
import pathlib
import subprocess

import prism

ROOT = pathlib.Path(__file__).resolve().parents[2]
PRISM = os.environ.get("PRISM_BIN", str(ROOT / "target" / "release" / "prism"))


def command(scene, x, y):
    out = subprocess.run([PRISM, "explain", str(ROOT / "scenes" / scene), "--pixel", f"{x},{y}",
                          "--json"], check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def explained(scene, x, y):
    return prism.explain(prism.load(str(ROOT / "scenes" / scene)), x, y)


def test_the_star_is_drawn_as_the_command_explains_it():
    for (x, y), parity in (((330, 140), "odd"), ((314, 192), "even")):
        e = explained("star.toml", x, y)
        assert isinstance(e, prism.Explanation) and isinstance(e, dict)
        assert e == command("star.toml", x, y)
        tests = [e["tree"]["intersection"]] + e["tree"]["rejected"]
        star = next(t for t in tests if t["object"] == "standing star")
        p = star["polygon"]
        assert p["parity"] == parity and p["principal_axis"] == "z"
        page = e._repr_html_()
        assert f"<b>{p['crossings']}</b> crossings of +x: <b>{parity}</b>" in page
        cases = [line.split('data-case="')[1].split('"')[0]
                 for line in page.split("<line")[1:] if 'class="edge"' in line]
        # Both stars' diagrams: the standing star's ten edges come first.
        assert cases[:10] == [edge["case"] for edge in p["edges"]]


def test_total_internal_reflection_is_drawn():
    e = explained("nested-glass.toml", 210, 140)
    tir = next(n for n in e.nodes()
               if n["refraction"] and n["refraction"]["total_internal_reflection"])
    r = tir["refraction"]
    assert abs(r["theta_i"] - 59.5) < 0.05 and abs(r["critical_angle"] - 41.81) < 0.01
    page = e._repr_html_()
    assert f"θi = <b>{r['theta_i']:.2f}°</b>" in page
    assert f"critical angle <b>{r['critical_angle']:.2f}°</b>" in page
    assert "<b>total internal reflection</b>" in page
    assert page.count('class="snell-diagram"') == sum(1 for n in e.nodes() if n["refraction"])
