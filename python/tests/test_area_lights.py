"""Distributed ray tracing (issue 28) through Scene.from_dict: a rectangle
and a disk light, one- and two-sided, a rough (glossy) material, a thin
lens, adaptive anti-aliasing and an open shutter (motion blur) give the
picture their TOML text gives,
pixel for pixel; a bad key raises SceneError naming it."""

import numpy as np
import pytest

import prism

FLOOR = {
    "render": {"width": 48, "height": 36, "spp": 1, "ambient": [0, 0, 0]},
    "camera": {"position": [0, 3, 5], "look_at": [0, 0, 0], "fov": 45},
    "materials": {"white": {"color": [1, 1, 1], "ka": 0, "kd": 1, "ks": 0}},
    "objects": [
        {"type": "plane", "material": "white", "normal": [0, 1, 0], "distance": 0},
        {"type": "sphere", "material": "white", "center": [0, 0.6, 0], "radius": 0.5},
    ],
}

LIGHTS = {
    "rectangle": {"type": "rectangle", "position": [0.3, 2.5, 0.2], "edge_u": [1.5, 0, 0],
                  "edge_v": [0, 0, 0.8], "intensity": 4.0, "samples": 9},
    "two-sided rectangle": {"type": "rectangle", "position": [0.3, 2.5, 0.2],
                            "edge_u": [1.5, 0, 0], "edge_v": [0, 0, -0.8],
                            "two_sided": True, "intensity": 4.0, "samples": 9},
    "disk": {"type": "disk", "position": [-0.4, 2.0, 0.5], "normal": [0.2, -1, 0],
             "radius": 0.6, "color": [1, 0.9, 0.8], "intensity": 3.0, "samples": 16},
}


def toml_value(v):
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, str):
        return '"' + v + '"'
    return repr(v)


def toml_of(d):
    out = []
    for section in ["render", "animation", "camera"]:
        if section not in d:
            continue
        out.append(f"[{section}]")
        out.extend(f"{k} = {toml_value(v)}" for k, v in d[section].items())
    for section in ["lights", "materials"]:
        for name, table in d[section].items():
            out.append(f"[{section}.{name}]")
            out.extend(f"{k} = {toml_value(v)}" for k, v in table.items())
    for obj in d["objects"]:
        out.append("[[objects]]")
        out.extend(f"{k} = {toml_value(v)}" for k, v in obj.items())
    return "\n".join(out) + "\n"


@pytest.mark.parametrize("kind", sorted(LIGHTS))
def test_an_area_light_from_a_dict_is_its_toml(kind):
    d = dict(FLOOR, lights={"area": LIGHTS[kind]})
    a = prism.Scene.from_dict(d).render(progress=False)
    b = prism.loads(toml_of(d)).render(progress=False)
    assert a.tobytes() == b.tobytes(), toml_of(d)
    # Lit, and the sphere's shadow is on the floor: a dark and a bright part.
    assert a.max() > 0.1
    assert (a.max(axis=2) < 0.02).sum() > 0


def test_a_one_sided_light_facing_away_lights_nothing():
    up = dict(LIGHTS["rectangle"], edge_v=[0, 0, -0.8])
    a = prism.Scene.from_dict(dict(FLOOR, lights={"area": up})).render(progress=False)
    assert np.asarray(a).max() == 0


def test_a_bad_area_light_key_names_it():
    bad = dict(LIGHTS["disk"], edge_u=[1, 0, 0])
    with pytest.raises(prism.SceneError, match="edge_u"):
        prism.Scene.from_dict(dict(FLOOR, lights={"area": bad}))


def test_glossy_lens_and_adaptive_from_a_dict_are_their_toml():
    d = dict(FLOOR, lights={"area": LIGHTS["rectangle"]})
    d["render"] = dict(d["render"], adaptive={"threshold": 0.1, "depth": 2, "jitter": True})
    d["camera"] = dict(d["camera"], aperture=0.1, focus_on=[0, 0.6, 0])
    d["materials"] = dict(d["materials"], mirror={"kd": 0.1, "kr": 0.8, "roughness": 0.3, "samples": 4})
    d["objects"] = d["objects"] + [{"type": "sphere", "material": "mirror",
                                    "center": [1.2, 0.5, 0.4], "radius": 0.5}]
    a = prism.Scene.from_dict(d).render(progress=False)
    b = prism.loads(toml_of(d)).render(progress=False)
    assert a.tobytes() == b.tobytes(), toml_of(d)
    # The same picture on one thread as on all.
    c = prism.Scene.from_dict(d).render(progress=False, threads=1)
    assert a.tobytes() == c.tobytes()


def test_an_open_shutter_from_a_dict_is_its_toml():
    d = dict(FLOOR, lights={"area": LIGHTS["disk"]})
    d["render"] = dict(d["render"], spp=4, shutter=[0, 1], shutter_samples=4)
    d["animation"] = {"frames": 1}
    moving = {"type": "sphere", "material": "white", "radius": 0.3,
              "transform": [{"translate": [{"frame": 0, "value": [-1, 0.3, 0.5]},
                                           {"frame": 1, "value": [1, 0.3, 0.5]}]}]}
    d["objects"] = d["objects"] + [moving]
    a = prism.Scene.from_dict(d).render(progress=False)
    b = prism.loads(toml_of(d)).render(progress=False)
    assert a.tobytes() == b.tobytes(), toml_of(d)
    # The streak differs from the ball at rest at either end.
    still = dict(d, render=dict(d["render"]))
    del still["render"]["shutter"], still["render"]["shutter_samples"]
    c = prism.Scene.from_dict(still).render(progress=False)
    assert a.tobytes() != c.tobytes()
