"""The Python face keeps the command's promises (issue 26, item 9): the
command's limits, ValueError for every bad argument (named), paths taken as
a careful user means them, messages in Python's names and without raw
control characters, files that read back, dict scenes built directly."""

import os
from pathlib import Path

import numpy as np
import pytest

import prism

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"

SMALL = {
    "render": {"width": 24, "height": 18, "spp": 1},
    "camera": {"position": [0, 1, -5], "look_at": [0, 1, 0], "fov": 40},
    "lights": {"key": {"type": "point", "position": [2, 5, -3], "intensity": 1.0}},
    "materials": {"red": {"color": [0.8, 0.1, 0.1]}},
    "objects": [{"type": "sphere", "center": [0, 1, 0], "radius": 1.0, "material": "red"}],
}


def small(**changes):
    import copy

    d = copy.deepcopy(SMALL)
    d.update(changes)
    return d


def test_threads_are_bounded_by_the_commands_limit():
    scene = prism.Scene.from_dict(SMALL)
    assert prism.LIMITS["MAX_THREADS"] == 1024
    # Refused before any thread starts (it started them at 50 a second).
    for threads in [1025, 10**6, 10**30]:
        with pytest.raises(ValueError, match=r"threads must be between 1 and 1024"):
            scene.render(threads=threads, progress=False)
    assert scene.render(threads=prism.LIMITS["MAX_THREADS"], progress=False).shape == (18, 24, 3)
    with pytest.raises(ValueError, match="spp"):
        scene.render(spp=prism.LIMITS["MAX_SPP"] + 1, progress=False)


@pytest.mark.parametrize(
    "name, value",
    [
        ("width", -1), ("height", -5), ("spp", -1), ("max_depth", -2), ("seed", -1),
        ("seed", 2**64), ("frame", -1), ("threads", -1), ("threads", 0), ("width", 2**40),
        ("spp", 10**30), ("max_depth", 2**70),
    ],
)
def test_integers_out_of_range_are_value_errors_naming_the_argument(name, value):
    scene = prism.Scene.from_dict(SMALL)
    with pytest.raises(ValueError) as e:
        scene.render(progress=False, **{name: value})
    assert not isinstance(e.value, OverflowError) and name in str(e.value), str(e.value)
    if name != "threads":
        with pytest.raises(ValueError) as e:
            scene.explain(1, 1, **{name: value})
        assert not isinstance(e.value, OverflowError) and name in str(e.value), str(e.value)


def test_other_integer_arguments_out_of_range():
    scene = prism.Scene.from_dict(SMALL)
    for call, name in [
        (lambda: scene.render(crop=(-1, 4, 0, 4), progress=False), "crop"),
        (lambda: scene.render(crop=(0, 2**33, 0, 4), progress=False), "crop"),
        (lambda: scene.explain(-1, 0), "x"),
        (lambda: scene.explain(0, 2**64), "y"),
        (lambda: scene.explain(0, 0, sample=-1), "sample"),
        (lambda: prism.load(SCENES / "whitted.toml", frame=-1), "frame"),
        (lambda: prism.loads("", frame=2**64), "frame"),
        (lambda: prism.Scene.from_dict(SMALL, frame=-3), "frame"),
    ]:
        with pytest.raises(ValueError) as e:
            call()
        assert not isinstance(e.value, OverflowError)
        if name:
            assert name in str(e.value), str(e.value)
    # A whole number of the wrong type is a TypeError, as in Python.
    with pytest.raises(TypeError):
        scene.render(width=1.5, progress=False)


def test_allow_read_takes_one_folder_as_a_path(tmp_path):
    outside = tmp_path / "outside.toml"
    outside.write_text((SCENES / "models.toml").read_text()
                       .replace('file = "models/', f'file = "{SCENES}/models/'))
    # One str or PathLike is one folder, not a sequence of one-letter ones.
    assert prism.load(outside, allow_read=str(SCENES)).frames == 1
    assert prism.load(outside, allow_read=SCENES).frames == 1
    assert prism.loads(outside.read_text(), allow_read=str(SCENES)).frames == 1
    assert prism.load(outside, allow_read=[SCENES]).frames == 1


def test_paths_that_name_no_folder_are_value_errors_naming_argument_and_path(tmp_path):
    missing = tmp_path / "nonexistent"
    with pytest.raises(ValueError) as e:
        prism.loads("", base_dir=missing)
    assert "base_dir" in str(e.value) and str(missing) in str(e.value)
    with pytest.raises(ValueError) as e:
        prism.Scene.from_dict(SMALL, base_dir=missing)
    assert "base_dir" in str(e.value) and str(missing) in str(e.value)
    with pytest.raises(ValueError) as e:
        prism.load(SCENES / "whitted.toml", allow_read=[""])
    assert "allow_read" in str(e.value)
    with pytest.raises(ValueError) as e:
        prism.load(SCENES / "whitted.toml", allow_read=[missing])
    assert "allow_read" in str(e.value) and str(missing) in str(e.value)
    assert "--allow-read" not in str(e.value)


def test_messages_use_the_python_names(tmp_path):
    outside = tmp_path / "outside.toml"
    outside.write_text((SCENES / "models.toml").read_text()
                       .replace('file = "models/', f'file = "{SCENES}/models/'))
    with pytest.raises(prism.SceneError) as e:
        prism.load(outside)
    text = str(e.value) + e.value.message
    assert "allow_read" in text and "--allow-read" not in text, text
    scene = prism.Scene.from_dict(SMALL)
    with pytest.raises(TypeError) as e:
        prism.explain(scene, 1, 1, spp_count=2)
    assert "explain_json" not in str(e.value) and "spp_count" in str(e.value)
    with pytest.raises(TypeError) as e:
        scene.explain(1, 1, spp_count=2)
    assert "explain_json" not in str(e.value)


def test_read_exr_reads_what_write_wrote(tmp_path):
    rng = np.random.default_rng(3)
    img = rng.normal(size=(7, 11, 3)).astype(np.float32) * 1e3   # negative values too
    prism.write(tmp_path / "a.exr", img)
    back, region = prism.read_exr(tmp_path / "a.exr")
    assert region == (0, 11, 0, 7)
    assert back.dtype == np.float32 and back.tobytes() == img.tobytes()
    render = prism.Scene.from_dict(SMALL).render(progress=False)
    prism.write(str(tmp_path / "r.exr"), render)
    assert prism.read_exr(tmp_path / "r.exr")[0].tobytes() == render.tobytes()


def test_from_dict_names_a_material_with_a_dot():
    d = small(materials={"glass.red": {"color": [0.8, 0.1, 0.1]}})
    d["objects"][0]["material"] = "glass.red"
    img = prism.Scene.from_dict(d).render(progress=False)
    text = (
        '[render]\nwidth = 24\nheight = 18\nspp = 1\n'
        '[camera]\nposition = [0, 1, -5]\nlook_at = [0, 1, 0]\nfov = 40\n'
        '[lights.key]\ntype = "point"\nposition = [2, 5, -3]\nintensity = 1.0\n'
        '[materials."glass.red"]\ncolor = [0.8, 0.1, 0.1]\n'
        '[[objects]]\ntype = "sphere"\ncenter = [0, 1, 0]\nradius = 1.0\nmaterial = "glass.red"\n'
    )
    assert img.tobytes() == prism.loads(text).render(progress=False).tobytes() and img.max() > 0
    d["materials"]["glass.red"]["ior"] = -1.0
    with pytest.raises(prism.SceneError) as e:
        prism.Scene.from_dict(d)
    assert e.value.key_path == 'materials."glass.red".ior', e.value.key_path


def test_from_dict_builds_without_toml_text_and_names_key_paths():
    d = small()
    d["objects"] = [dict(d["objects"][0], center=[i, 1, 0]) for i in range(5)]
    d["objects"][3]["radius"] = -2
    with pytest.raises(prism.SceneError) as e:
        prism.Scene.from_dict(d)
    # Located by key path, not by a line of generated text.
    assert e.value.key_path == "objects[3].radius" and e.value.line is None
    assert e.value.file == "<dict>" and str(e.value).startswith("<dict>: objects[3].radius: ")
    d["objects"][3]["radius"] = 1
    d["objects"][1]["radiuss"] = 1
    d["objects"][4]["center"] = [0, "one", 0]
    with pytest.raises(prism.SceneError) as e:
        prism.Scene.from_dict(d)
    paths = [p[2].split(":")[0] for p in e.value.problems]
    assert paths == ["objects[1].radiuss", "objects[4].center"], e.value.problems
    # Values no scene holds are ValueErrors with their path.
    d = small()
    d["objects"][0]["center"] = [0, {1, 2}, 0]
    with pytest.raises(ValueError, match=r"objects\[0\]\.center\[1\]: cannot put a set"):
        prism.Scene.from_dict(d)
    d["objects"][0]["center"] = [0, 2**70, 0]
    with pytest.raises(ValueError, match=r"objects\[0\]\.center\[1\]"):
        prism.Scene.from_dict(d)
    # NumPy values and paths are taken as they are.
    d = small()
    d["objects"][0]["center"] = np.array([0.0, 1.0, 0.0])
    d["objects"][0]["radius"] = np.float32(1.0)
    d["render"]["spp"] = np.int64(1)
    a = prism.Scene.from_dict(d).render(progress=False)
    assert a.tobytes() == prism.Scene.from_dict(SMALL).render(progress=False).tobytes()


def test_from_dict_builds_the_scene_loads_builds():
    # The same spheres as a dict and as TOML text: the same picture. (How
    # fast each is, bench/load_spheres_python.py measures; no timing here.)
    n = 2_000
    d = small()
    d["objects"] = [{"type": "sphere", "material": "red", "center": [i * 0.01, 1.0, (i % 7) * 0.1],
                     "radius": 0.01} for i in range(n)]
    lines = [f'[[objects]]\ntype = "sphere"\nmaterial = "red"\ncenter = [{i * 0.01}, 1.0, {(i % 7) * 0.1}]\n'
             f'radius = 0.01\n' for i in range(n)]
    head = (
        '[render]\nwidth = 24\nheight = 18\nspp = 1\n'
        '[camera]\nposition = [0, 1, -5]\nlook_at = [0, 1, 0]\nfov = 40\n'
        '[lights.key]\ntype = "point"\nposition = [2, 5, -3]\nintensity = 1.0\n'
        '[materials.red]\ncolor = [0.8, 0.1, 0.1]\n'
    )
    text = head + "".join(lines)
    a = prism.Scene.from_dict(d).render(progress=False)
    assert a.tobytes() == prism.loads(text).render(progress=False).tobytes()


def test_messages_carry_no_raw_control_characters(tmp_path):
    bad = "\x1b]0;owned\x07\x1b[2J\r\nFAKE"
    with pytest.raises(prism.SceneError) as e:
        prism.loads("[camera\n", origin=bad)
    for text in [str(e.value), e.value.message]:
        assert "\x1b" not in text and "\r" not in text and "\x07" not in text, repr(text)
    d = small()
    d["objects"][0]["material"] = bad
    with pytest.raises(prism.SceneError) as e:
        prism.Scene.from_dict(d)
    assert not any(c in str(e.value) for c in "\x1b\r\x07"), repr(str(e.value))
    d = small(**{bad: {}})
    with pytest.raises(prism.SceneError) as e:
        prism.Scene.from_dict(d)
    assert not any(c in str(e.value) + str(e.value.key_path) for c in "\x1b\r\n\x07"), repr(str(e.value))
    with pytest.raises(ValueError) as e:
        prism.read_exr(tmp_path / f"x{bad}.exr")
    assert not any(c in str(e.value) for c in "\x1b\r\n\x07"), repr(str(e.value))
    with pytest.raises(ValueError) as e:
        prism.loads("", base_dir=tmp_path / bad)
    assert not any(c in str(e.value) for c in "\x1b\r\n\x07"), repr(str(e.value))
    assert prism.escape_controls("a\nb\x1b") == "a\\nb\\u{1b}"


def test_from_dict_refuses_a_list_that_holds_itself():
    # Walked without a bound it overflowed the stack and killed Python.
    # Nesting past the bound is a scene problem, named by its key path
    # (test_csg_dict.py tests the bound itself).
    loop = []
    loop.append(loop)
    d = small()
    d["objects"] = [{"type": "sphere", "material": "red", "center": loop, "radius": 1}]
    with pytest.raises(prism.SceneError, match="nested more than") as e:
        prism.Scene.from_dict(d)
    assert e.value.key_path.startswith("objects[0].center[0][0]"), e.value.key_path
    deep = {"type": "sphere"}
    for _ in range(10_000):
        deep = {"x": deep}
    with pytest.raises(prism.SceneError, match="nested more than") as e:
        prism.Scene.from_dict(small(objects=[deep]))
    assert e.value.key_path.startswith("objects[0].x.x"), e.value.key_path


def test_only_regular_files_are_loaded(tmp_path):
    # /dev/zero was read until memory ran out; a FIFO with no writer
    # blocked for ever, past Ctrl-C. Both are refused at once, named.
    fifo = tmp_path / "pipe.toml"
    os.mkfifo(fifo)
    for path in ["/dev/zero", str(fifo), str(tmp_path)]:
        with pytest.raises(prism.SceneError) as e:
            prism.load(path)
        assert "not a regular file" in str(e.value) and path in str(e.value), str(e.value)


def test_from_dict_takes_a_box_filtered_checker():
    # A floor seen at a low angle: its far rows alias when point-sampled
    # (black or white) and turn to the mean grey when box-filtered.
    def floor(**checker):
        d = small()
        d["render"].update(width=48, height=24, ambient=[1, 1, 1], background=[0, 0, 0])
        d["camera"] = {"position": [0.3, 1.0, 6.0], "look_at": [0, 0.6, 0], "fov": 50}
        d["lights"] = {}
        d["materials"] = {"floor": {"color": [1, 1, 1], "ka": 1, "kd": 0,
                                    "checker": dict(color=[0, 0, 0], size=0.5, **checker)}}
        d["objects"] = [{"type": "plane", "normal": [0, 1, 0], "distance": 0, "material": "floor"}]
        return prism.Scene.from_dict(d)

    point = np.asarray(floor().render(progress=False))
    box = np.asarray(floor(filter="box").render(progress=False))
    rows = [y for y in range(24) if point[y].max() > 0]
    far = slice(rows[0] + 1, rows[0] + 3)
    assert set(np.unique(point[far])) <= {0.0, 1.0}
    assert np.abs(box[far] - 0.5).max() < 0.1
    with pytest.raises(prism.SceneError, match="world checker"):
        floor(filter="box", mapping="uv")
    with pytest.raises(prism.SceneError):
        floor(filter="gauss")
