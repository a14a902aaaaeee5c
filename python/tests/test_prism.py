"""The Python package against the command: the same pixels, the same
trees, the same errors; the GIL released; Ctrl-C obeyed."""

import _thread
import os
import subprocess
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import prism

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"
PRISM = os.environ.get("PRISM_BIN", str(ROOT / "target" / "release" / "prism"))


def cli(*args, cwd=None):
    out = subprocess.run([PRISM, *map(str, args)], capture_output=True, text=True, cwd=cwd)
    assert out.returncode == 0, out.stderr
    return out


@pytest.mark.parametrize(
    "name, extra",
    [
        ("whitted", {}),
        ("soft-shadows", {}),
        ("nested-glass", {}),
        ("models", {}),
        ("rolling", {"frame": 30}),
    ],
)
def test_array_equals_the_cli_exr_bit_for_bit(tmp_path, name, extra):
    scene = prism.load(SCENES / f"{name}.toml")
    img = scene.render(width=96, height=72, spp=2, progress=False, **extra)
    assert isinstance(img, np.ndarray) and img.dtype == np.float32 and img.shape == (72, 96, 3)
    args = ["render", SCENES / f"{name}.toml", "--width", 96, "--height", 72, "--spp", 2, "-q"]
    if "frame" in extra:
        args += ["--frame", extra["frame"]]
    cli(*args, "-o", tmp_path / "cli.exr")
    exr, region = prism.read_exr(tmp_path / "cli.exr")
    assert region == (0, 96, 0, 72)
    assert img.tobytes() == np.asarray(exr).tobytes()
    # And the written files are the command's, byte for byte, in 8 bits.
    cli(*args, "-o", tmp_path / "cli.png")
    prism.write(tmp_path / "py.png", img)
    assert (tmp_path / "py.png").read_bytes() == (tmp_path / "cli.png").read_bytes()


def test_crop_and_debug_views_match_the_cli(tmp_path):
    scene = prism.load(SCENES / "whitted.toml")
    part = scene.render(width=64, height=48, spp=1, crop=(10, 30, 5, 25), progress=False)
    assert part.shape == (20, 20, 3)
    whole = scene.render(width=64, height=48, spp=1, progress=False)
    assert part.tobytes() == np.ascontiguousarray(whole[5:25, 10:30]).tobytes()
    normal = scene.render(width=64, height=48, spp=1, aov="normal", progress=False)
    cli("render", SCENES / "whitted.toml", "--width", 64, "--height", 48, "--spp", 1,
        "--aov", "normal", "-q", "-o", tmp_path / "n.exr")
    exr, _ = prism.read_exr(tmp_path / "n.exr")
    assert normal.tobytes() == np.asarray(exr).tobytes()
    assert set(prism.AOVS) >= {"normal", "depth", "object", "time"}


def test_explain_is_the_cli_tree_and_the_pixel(tmp_path):
    scene = prism.load(SCENES / "whitted.toml")
    img = scene.render(width=80, height=60, spp=1, progress=False)
    for x, y in [(40, 30), (10, 50), (70, 5)]:
        tree = prism.explain(scene, x, y, width=80, height=60, spp=1)
        assert np.array_equal(np.float32(tree["radiance"]), img[y, x]), (x, y)
        import json
        out = cli("explain", SCENES / "whitted.toml", "--pixel", f"{x},{y}", "--json",
                  "--width", 80, "--height", 60, "--spp", 1)
        assert json.loads(out.stdout) == tree


def test_the_gil_is_released_while_rendering():
    scene = prism.load(SCENES / "soft-shadows.toml")
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    start = time.perf_counter()
    scene.render(width=160, height=120, spp=4, progress=False)
    end = time.perf_counter()
    stop.set()
    t.join()
    during = [x for x in ticks if start < x < end]
    # A thread blocked by the GIL would tick at most once or twice.
    assert len(during) > 10, (len(during), end - start)


def test_keyboard_interrupt_cancels_the_render():
    scene = prism.load(SCENES / "soft-shadows.toml")
    # Python's own Ctrl-C handler, which a process started in the
    # background without job control (SIGINT ignored) does not install,
    # and without which interrupt_main does nothing.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.3, _thread.interrupt_main)
    timer.start()
    start = time.perf_counter()
    try:
        with pytest.raises(KeyboardInterrupt):
            # Minutes of work if not stopped.
            scene.render(width=1280, height=960, spp=64, threads=1, progress=False)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    assert time.perf_counter() - start < 10


def test_progress_callback_sees_every_pixel():
    scene = prism.load(SCENES / "whitted.toml")
    seen = []
    scene.render(width=64, height=48, spp=1, progress=lambda done, total: seen.append((done, total)))
    assert seen[-1] == (64 * 48, 64 * 48)
    assert all(d <= t for d, t in seen)
    # An exception in the callback stops the render and propagates.
    def boom(done, total):
        raise RuntimeError("stop here")
    with pytest.raises(RuntimeError, match="stop here"):
        prism.load(SCENES / "soft-shadows.toml").render(width=640, height=480, spp=16, progress=boom)


def test_scene_errors_carry_their_location(tmp_path):
    bad = tmp_path / "bad.toml"
    text = (SCENES / "whitted.toml").read_text().replace("radius = ", "radius = -", 1)
    bad.write_text(text)
    with pytest.raises(prism.SceneError) as e:
        prism.load(bad)
    err = e.value
    line = next(i for i, l in enumerate(text.splitlines(), 1) if "radius = -" in l)
    assert err.file.endswith("bad.toml") and err.line == line and err.column > 1
    assert "radius" in err.message and err.problems[0][0] == line
    # Syntax errors, a missing file, unknown keys.
    with pytest.raises(prism.SceneError) as e:
        prism.loads("[camera\n", origin="broken")
    assert e.value.file == "broken" and e.value.line == 1
    with pytest.raises(prism.SceneError) as e:
        prism.load(tmp_path / "missing.toml")
    assert e.value.line is None and "cannot read" in e.value.message
    with pytest.raises(prism.SceneError) as e:
        prism.loads((SCENES / "whitted.toml").read_text().replace("spp = 4", "sppp = 4"))
    assert e.value.line == 8 and "sppp" in e.value.message
    # A model outside the allowed folders is refused by the read policy.
    outside = tmp_path / "outside.toml"
    outside.write_text((SCENES / "models.toml").read_text().replace('file = "models/', f'file = "{SCENES}/models/'))
    with pytest.raises(prism.SceneError) as e:
        prism.load(outside)
    assert "allow-read" in str(e.value) or "outside" in str(e.value), str(e.value)
    assert prism.load(outside, allow_read=[SCENES]).frames == 1


def test_bad_arguments_are_value_errors():
    scene = prism.load(SCENES / "whitted.toml")
    for kwargs in [
        {"width": 0},
        {"spp": 0},
        {"crop": (5, 5, 0, 1)},
        {"crop": (0, 10_000, 0, 1)},
        {"aov": "nope"},
        {"threads": 0},
        {"max_depth": 100000},
    ]:
        with pytest.raises(ValueError):
            scene.render(progress=False, **kwargs)
    with pytest.raises(ValueError):
        prism.explain(scene, 10_000, 0)
    with pytest.raises(ValueError):
        prism.write("x.png", np.zeros((4, 4)))
    with pytest.raises(OSError):
        prism.write("/nonexistent-folder/x.png", np.zeros((4, 4, 3)))
    with pytest.raises(ValueError):
        prism.load(SCENES / "rolling.toml").render(frame=48, progress=False)


def test_dict_scenes_and_their_errors():
    d = {
        "render": {"width": 48, "height": 36, "spp": 1},
        "camera": {"position": [0, 1, -5], "look_at": [0, 1, 0], "fov": 40},
        "lights": {"key": {"type": "point", "position": [2, 5, -3], "intensity": 1.0}},
        "materials": {"red": {"color": [0.8, 0.1, 0.1]}},
        "objects": [
            {"type": "sphere", "center": [0, 1, 0], "radius": 1.0, "material": "red"},
        ],
    }
    text = """
[render]
width = 48
height = 36
spp = 1
[camera]
position = [0, 1, -5]
look_at = [0, 1, 0]
fov = 40
[lights.key]
type = "point"
position = [2, 5, -3]
intensity = 1.0
[materials.red]
color = [0.8, 0.1, 0.1]
[[objects]]
type = "sphere"
center = [0, 1, 0]
radius = 1.0
material = "red"
"""
    a = prism.Scene.from_dict(d).render(progress=False)
    b = prism.loads(text).render(progress=False)
    assert a.tobytes() == b.tobytes() and a.max() > 0
    d["objects"][0]["radius"] = -1.0
    with pytest.raises(prism.SceneError) as e:
        prism.Scene.from_dict(d)
    assert e.value.key_path == "objects[0].radius", e.value.key_path
    assert "objects[0].radius" in str(e.value)


def test_write_encodings_and_srgb(tmp_path):
    img = np.zeros((2, 3, 3), np.float32)
    img[0, 0] = [0.5, 1.0, 2.0]
    rgb8 = prism.to_srgb8(img)
    assert rgb8.dtype == np.uint8 and rgb8.shape == (2, 3, 3)
    assert list(rgb8[0, 0]) == [188, 255, 255]
    for ext in ["png", "exr", "hdr", "ppm"]:
        prism.write(tmp_path / f"a.{ext}", img)
        assert (tmp_path / f"a.{ext}").stat().st_size > 0
    png = prism.Image._repr_png_(img.view(prism.Image))
    assert png.startswith(b"\x89PNG")
    brighter = img.view(prism.Image).with_exposure(1)
    assert brighter._repr_png_() != png and brighter.base is not None


def test_default_progress_is_a_tqdm_bar_when_tqdm_is_installed(capsys):
    pytest.importorskip("tqdm")
    prism.load(SCENES / "whitted.toml").render(width=64, height=48, spp=1)
    assert "px" in capsys.readouterr().err


def test_interact_re_renders_when_a_slider_moves():
    widgets = pytest.importorskip("ipywidgets")
    shown = []
    import IPython.display

    real = IPython.display.display
    IPython.display.display = lambda *objs, **kw: shown.extend(objs)
    try:
        d = {
            "render": {"width": 32, "height": 24, "spp": 1},
            "camera": {"position": [0, 1, -5], "look_at": [0, 1, 0], "fov": 40},
            "lights": {"key": {"type": "point", "position": [2, 5, -3], "intensity": 1.0}},
            "materials": {"red": {"color": [0.8, 0.1, 0.1]}},
            "objects": [{"type": "sphere", "center": [0, 1, 0], "radius": 1.0, "material": "red"}],
        }
        slider = widgets.FloatSlider(value=1.0, min=0.5, max=2.0)
        prism.interact(d, objects__0__radius=slider)
        slider.value = 0.5
    finally:
        IPython.display.display = real
    assert len(shown) >= 2 and all(isinstance(s, prism.Image) for s in shown)
    # The smaller ball covers fewer pixels.
    assert (shown[-1] > 0.05).sum() < (shown[0] > 0.05).sum()


def test_help_reads_well():
    doc = prism.Scene.render.__doc__
    assert "float32" in doc and "KeyboardInterrupt" in doc and "crop" in doc
