"""The preview in a real browser (headless Chromium over WebDriver):
the canvas shows what `prism render` writes, a click on the glass ball
shows the tree `prism explain --json` gives, a save moves the ball, a broken
save shows its located error and keeps the picture, a fix brings it back.
The page (issue 14, item 16): the header names the scene; heat-ramp views
have a legend; back to "picture", the view goes and exposure works; a
chosen view follows an edit; a page refused by the 16-stream cap says why
and connects once there is room. Network mode: without the token the page
asks for it; with it, the page works, the token leaves the address bar and
a reload works from the cookie.
Exposure (issue 26, item 4): the page starts at the scene's exposure and
follows it on a save while the slider is left there; the canvas, the PNG
"Save PNG" downloads and `prism render --exposure EV` agree at the scene's
exposure and at one set with the slider; a slider moved away stays when
the scene's exposure changes, until its button brings the scene's back.
The lecture (issue 31): clicks inside and outside the concave star of
star.toml and on the glass ball of nested-glass.toml, and checks the
drawn polygon diagram (axis, edge cases, crossings, parity) and Snell's
construction (theta_i, the critical angle, TIR) against `prism explain
--json`.
Keeps screenshots in target/preview-screens/ (and the README's in
docs/images/preview.png when asked). Run by scripts/test-preview-browser.sh.

Usage: python preview_browser_test.py PRISM SCENE_DIR SCREENS_DIR [README_SHOT]
"""

import json
import os
import re
import socket
import subprocess
import sys
import time
import urllib.request

from selenium import webdriver
from selenium.webdriver.chrome.options import Options
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.action_chains import ActionChains
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import Select

PRISM, WORK, SCREENS = sys.argv[1:4]
README_SHOT = sys.argv[4] if len(sys.argv) > 4 else None
SCENE = os.path.join(WORK, "whitted.toml")
os.makedirs(SCREENS, exist_ok=True)


def fail(message):
    print("FAIL:", message, file=sys.stderr)
    sys.exit(1)


def read_ppm(path):
    data = open(path, "rb").read()
    m = re.match(rb"P6\s+(\d+)\s+(\d+)\s+255\s", data)
    w, h = int(m.group(1)), int(m.group(2))
    return w, h, data[m.end():m.end() + w * h * 3]


def reference(name, *args):
    out = os.path.join(WORK, name + ".ppm")
    subprocess.run([PRISM, "render", SCENE, "-q", *args, "-o", out], check=True)
    return read_ppm(out)


def reference_png(name, *args):
    out = os.path.join(WORK, name + ".png")
    subprocess.run([PRISM, "render", SCENE, "-q", *args, "-o", out], check=True)
    return open(out, "rb").read()


def explain_json(x, y):
    out = subprocess.run([PRISM, "explain", SCENE, "--pixel", f"{x},{y}", "--json"],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out)


server = subprocess.Popen([PRISM, "serve", SCENE, "--port", "0"], stdout=subprocess.PIPE, text=True)
url = re.search(r"http://\S+", server.stdout.readline()).group(0)
options = Options()
for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1500,900"):
    options.add_argument(arg)
driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)


def save(text):
    """Saves the scene as an editor that writes a new file and renames it
    does: the server never reads it half written (a truncate, then a write,
    can be read in between under load)."""
    temp = SCENE + ".saving"
    with open(temp, "w") as f:
        f.write(text)
    os.replace(temp, SCENE)


def wait(condition, what, timeout=60):
    end = time.time() + timeout
    while time.time() < end:
        value = driver.execute_script(f"return {condition};")
        if value:
            return value
        time.sleep(0.02)
    fail(f"timed out waiting for {what}")


def canvas_rgb():
    b64 = driver.execute_script("""
        const c = document.getElementById('picture'), d = c.getContext('2d')
            .getImageData(0, 0, c.width, c.height).data;
        let s = '';
        for (let i = 0; i < d.length; i += 4) s += String.fromCharCode(d[i], d[i+1], d[i+2]);
        return btoa(s);""")
    import base64
    return base64.b64decode(b64)


# The picture is on the canvas: no /picture fetch under way (tiles wait for
# it) and no redraw pending (requestAnimationFrame).
DRAWN = ("window.prism.radiance !== null && window.prism.loading === null && "
         "!window.prism.dirty")


def wait_done(generation_above):
    wait(f"window.prism.generation > {generation_above} && window.prism.phase === 'done' && "
         + DRAWN, "the render to finish and be drawn")
    return driver.execute_script("return window.prism.generation;")


def compare(shown, ref, what):
    w, h, want = ref
    if len(shown) != len(want):
        fail(f"{what}: the canvas has {len(shown)} bytes, the render {len(want)}")
    diffs = [abs(a - b) for a, b in zip(shown, want) if a != b]
    if diffs and (max(diffs) > 1 or len(diffs) > len(want) * 0.001):
        fail(f"{what}: {len(diffs)} of {len(want)} channel values differ (max {max(diffs)})")
    print(f"ok: {what}: canvas equals prism render's picture "
          f"({len(diffs)} channel values off by one of {len(want)})")


def choose_view(name):
    Select(driver.find_element(By.ID, "view-select")).select_by_visible_text(name or "picture")
    if name:
        wait(f"document.getElementById('aov').dataset.view === '{name}' && "
             "!document.getElementById('aov').hidden && "
             "document.getElementById('aov').complete && "
             "document.getElementById('aov').naturalWidth > 0", f"the {name} view")


def on_top():
    """The id of what is seen at the middle of the picture."""
    return driver.execute_script("""
        const r = document.getElementById('picture').getBoundingClientRect();
        return document.elementFromPoint(r.left + r.width / 2, r.top + r.height / 2).id;""")


def set_exposure(ev):
    driver.execute_script(f"""
        const e = document.getElementById('exposure');
        e.value = '{ev}'; e.dispatchEvent(new Event('input'));""")
    wait(DRAWN, "the redraw at the new exposure")


try:
    driver.get(url)
    generation = wait_done(0)
    first = reference("first")
    compare(canvas_rgb(), first, "first render")
    driver.save_screenshot(os.path.join(SCREENS, "1-render.png"))

    # Click the glass ball: find one of its pixels with prism explain.
    w, h, _ = first
    target = None
    for y in range(h // 4, 3 * h // 4, 8):
        for x in range(w // 2, w, 8):
            e = explain_json(x, y)
            if e["tree"]["hit"] and e["tree"]["hit"]["object"] == "glass ball":
                target, expected = (x, y), e
                break
        if target:
            break
    if not target:
        fail("no pixel of the glass ball found")
    canvas = driver.find_element(By.ID, "picture")
    ActionChains(driver).move_to_element_with_offset(
        canvas, target[0] + 0.5 - w / 2, target[1] + 0.5 - h / 2).click().perform()
    wait("document.getElementById('inspect-radiance')", "the inspector")
    shown = driver.execute_script("return window.prism.explanation;")
    if shown["pixel"] != list(target):
        fail(f"clicked {target}, the inspector shows {shown['pixel']}")

    def close(a, b, path="tree"):
        if isinstance(a, dict):
            for k in b:
                if k != "segments":
                    close(a.get(k), b[k], f"{path}.{k}")
        elif isinstance(a, list) and a and isinstance(a[0], (int, float)):
            for u, v in zip(a, b):
                if abs(u - v) > 1e-12 * max(1.0, abs(v)):
                    fail(f"{path}: page {a} vs explain {b}")
        elif a != b and not (a is None and b is None):
            if isinstance(a, list):
                for u, v in zip(a, b):
                    close(u, v, path)
            elif a != b:
                fail(f"{path}: page {a!r} vs explain {b!r}")
    close(shown, expected)
    page_text = driver.find_element(By.ID, "inspector").text
    for term in ("glass ball", "ka·Od·Ia", "kd·Od·max(0,N·L)", "kt·I_refracted"):
        if term not in page_text:
            fail(f"the inspector does not show {term!r}")
    print(f"ok: the inspector at {target} shows prism explain's tree "
          f"({len(shown['segments'])} rays drawn)")
    driver.save_screenshot(os.path.join(SCREENS, "2-inspector.png"))
    if README_SHOT:
        driver.save_screenshot(README_SHOT)

    # The header names the scene.
    name = driver.find_element(By.ID, "scene").text
    if name != "whitted.toml" or "whitted.toml" not in driver.title:
        fail(f"the header shows {name!r}, the title {driver.title!r}")
    print(f"ok: the header and title name the scene ({driver.title!r})")

    # Heat-ramp views have a legend: black to white, 0 to the value shown white.
    choose_view("feelers")
    legend = driver.find_element(By.ID, "legend")
    top = driver.find_element(By.ID, "legend-top").text
    if not legend.is_displayed() or not re.match(r"[0-9.e+]+ or more", top):
        fail(f"no legend for the feelers view ({top!r})")
    if on_top() != "aov":
        fail(f"the feelers view is not shown over the picture ({on_top()!r})")
    driver.save_screenshot(os.path.join(SCREENS, "2b-feelers.png"))
    choose_view("normal")
    if legend.is_displayed():
        fail("the normal view has a heat-ramp legend")
    print(f"ok: the feelers view has a legend (0 to {top}); the normal view none")

    # Back to the picture: the view goes, and exposure changes what is seen.
    choose_view("")
    wait("getComputedStyle(document.getElementById('aov')).display === 'none'", "the view to go")
    if on_top() != "picture":
        fail(f"back to the picture, {on_top()!r} is on top")
    set_exposure(2)
    brighter = canvas_rgb()
    set_exposure(0)
    if brighter == canvas_rgb() or on_top() != "picture":
        fail("exposure does not change the picture after a debug view")
    compare(canvas_rgb(), first, "back to the picture at 0 EV")
    print("ok: after a debug view, picture is on top again and exposure works")

    # A chosen view follows the next edit (checked after the ball moves).
    choose_view("depth")
    view_generation = int(driver.execute_script(
        "return document.getElementById('aov').dataset.generation;"))

    # Move the glass ball: the picture follows the save.
    text = open(SCENE).read()
    moved = text.replace("center = [0.7, 1.0, 0.6]", "center = [-0.3, 1.0, 0.9]")
    if moved == text:
        fail("the scene has no glass ball centre to move")
    before = canvas_rgb()
    coarse_before = driver.execute_script("return window.prism.coarseAt;")
    saved = time.time()
    save(moved)
    wait(f"window.prism.coarseAt !== {json.dumps(coarse_before)}", "the coarse picture", 10)
    latency = time.time() - saved
    generation = wait_done(generation)
    after = canvas_rgb()
    changed = sum(1 for a, b in zip(before, after) if a != b)
    if changed < len(after) * 0.01:
        fail(f"only {changed} channel values changed after moving the ball")
    compare(after, reference("moved"), "after moving the ball")
    print(f"ok: save to first coarse picture: {latency * 1000:.0f} ms")
    wait(f"document.getElementById('aov').dataset.view === 'depth' && "
         f"+document.getElementById('aov').dataset.generation > {view_generation}",
         "the depth view to follow the edit")
    print("ok: the depth view follows the edit")
    choose_view("")
    driver.save_screenshot(os.path.join(SCREENS, "3-moved.png"))

    # A broken save: the located error, the picture kept.
    broken = moved.replace("radius = 0.8", 'radius = "big"')
    save(broken)
    wait("window.prism.phase === 'error'", "the error")
    line = next(i + 1 for i, l in enumerate(broken.splitlines()) if 'radius = "big"' in l)
    errors = driver.find_element(By.ID, "errors")
    if not errors.is_displayed() or f"whitted.toml:{line}:" not in errors.text:
        fail(f"the page does not show the error at line {line}: {errors.text!r}")
    if canvas_rgb() != after:
        fail("the picture changed while the scene was broken")
    print(f"ok: the broken scene shows {errors.text.splitlines()[0]!r}; the picture stays")
    driver.save_screenshot(os.path.join(SCREENS, "4-error.png"))

    # Fixed: the picture returns and the error goes.
    save(moved)
    wait_done(driver.execute_script("return window.prism.generation;") - 1)
    wait("document.getElementById('errors').hidden", "the error to go")
    compare(canvas_rgb(), reference("fixed"), "after the fix")
    driver.save_screenshot(os.path.join(SCREENS, "5-fixed.png"))

    # Exposure: what the page shows is what Save PNG writes, and what
    # `prism render --exposure EV` writes.
    def with_exposure(text, ev):
        return text.replace("[render]\n", f"[render]\nexposure = {ev}\n", 1)

    def page_exposure():
        return driver.execute_script(
            "return [window.prism.exposure, window.prism.exposureMoved, "
            "document.getElementById('exposure').value, "
            "document.getElementById('ev').textContent, "
            "document.getElementById('exposure-scene').hidden];")

    def saved_png():
        href = driver.find_element(By.ID, "save-png").get_attribute("href")
        return href, urllib.request.urlopen(href).read()

    def agree(what, *args):
        compare(canvas_rgb(), reference(what, *args), what)
        href, png = saved_png()
        command = " ".join(("prism render",) + args)
        if png != reference_png(what, *args):
            fail(f"{what}: Save PNG ({href}) is not {command}'s PNG")
        print(f"ok: {what}: Save PNG ({href}) equals {command}'s PNG")

    generation = driver.execute_script("return window.prism.generation;")
    save(with_exposure(moved, 1.5))
    generation = wait_done(generation)
    ev, was_moved, slider, label, button_hidden = page_exposure()
    if ev != 1.5 or was_moved or float(slider) != 1.5 or label != "1.5 EV" or not button_hidden:
        fail(f"the page does not start at the scene's 1.5 EV: {page_exposure()}")
    agree("the scene's 1.5 EV")
    driver.save_screenshot(os.path.join(SCREENS, "5b-exposure-scene.png"))
    # A page opened on that scene starts there too.
    driver.refresh()
    wait("window.prism && window.prism.phase === 'done' && window.prism.exposure === 1.5 && "
         + DRAWN, "the reloaded page at the scene's exposure")
    if page_exposure()[1:4] != [False, "1.5", "1.5 EV"]:
        fail(f"the reloaded page does not start at the scene's 1.5 EV: {page_exposure()}")
    agree("a new page at the scene's 1.5 EV")

    set_exposure(-1)
    agree("the slider's -1 EV", "--exposure", "-1")
    if driver.find_element(By.ID, "exposure-scene").text != "scene's 1.5 EV":
        fail("moved away, the slider offers no way back to the scene's exposure")

    # The scene's exposure changes while the slider is moved: it stays.
    save(with_exposure(moved, 0.5))
    generation = wait_done(generation)
    ev, was_moved, _, _, button_hidden = page_exposure()
    if ev != -1 or not was_moved or button_hidden:
        fail(f"the slider the user moved did not stay: {page_exposure()}")
    if driver.find_element(By.ID, "exposure-scene").text != "scene's 0.5 EV":
        fail("the button does not name the scene's new exposure")
    agree("the slider's -1 EV kept over a save", "--exposure", "-1")
    # Its button brings the scene's back, and the page follows it again.
    driver.find_element(By.ID, "exposure-scene").click()
    wait("window.prism.exposure === 0.5 && !window.prism.exposureMoved && " + DRAWN,
         "the scene's exposure back")
    agree("back to the scene's 0.5 EV")
    save(moved)
    generation = wait_done(generation)
    if page_exposure()[:2] != [0, False]:
        fail(f"the slider did not follow the scene's exposure to 0: {page_exposure()}")
    agree("the scene's exposure followed to 0")
    print("ok: exposure: the page starts at the scene's, follows it unless moved, "
          "and saves what it shows")

    # A page beyond the 16-stream cap says why and retries.
    addr = re.match(r"http://([^/]+)/", url).group(1)
    host, port = addr.rsplit(":", 1)
    pages = json.load(urllib.request.urlopen(f"http://{addr}/stats"))["pages"]
    held = []
    for _ in range(16 - pages):
        s = socket.create_connection((host, int(port)))
        s.sendall(f"GET /events HTTP/1.1\r\nHost: {addr}\r\n\r\n".encode())
        if b" 200 " not in s.recv(4096):
            fail("a stream below the cap was refused")
        held.append(s)
    driver.switch_to.new_window("tab")
    driver.get(url)
    wait("window.prism.notice.includes('too many') && window.prism.notice.includes('retrying')",
         "the page to say why it cannot connect")
    notice = driver.find_element(By.ID, "notice")
    if not notice.is_displayed():
        fail("the refusal is not shown")
    print(f"ok: a page beyond the cap says {notice.text!r}")
    driver.save_screenshot(os.path.join(SCREENS, "6-refused.png"))
    for s in held:
        s.close()
    wait("window.prism.phase === 'done' && window.prism.notice === '' && " + DRAWN,
         "the page to connect once there is room and draw the picture")
    compare(canvas_rgb(), reference("connected"), "the page that waited for room")

    # The lecture, live (issue 31): a click inside the concave star and one
    # in the notch between two of its points draw the projected polygon,
    # its crossings and their parity; a click on the glass ball of
    # nested-glass.toml draws Snell's construction with total internal
    # reflection at the air bubble. Each drawn value is prism explain's.
    lecture_server = None
    for scene_name, clicks in (("star.toml", ((330, 140), (314, 192))),
                               ("nested-glass.toml", ((210, 140),))):
        path = os.path.join(WORK, scene_name)
        lecture_server = subprocess.Popen([PRISM, "serve", path, "--port", "0"],
                                          stdout=subprocess.PIPE, text=True)
        driver.get(re.search(r"http://\S+", lecture_server.stdout.readline()).group(0))
        wait("window.prism.phase === 'done' && " + DRAWN, f"{scene_name} to render")
        for x, y in clicks:
            # The last screenshot scrolled the inspector's diagram into view.
            driver.execute_script("window.scrollTo(0, 0); window.prism.explanation = null;")
            canvas = driver.find_element(By.ID, "picture")
            cw, ch = driver.execute_script("return [window.prism.width, window.prism.height];")
            # WebDriver offsets are whole CSS pixels from the centre, which
            # may lie between pixels: a click that takes a neighbour is
            # moved by the difference and made again.
            dx, dy = 0, 0
            for _ in range(3):
                driver.execute_script("window.prism.explanation = null;")
                ActionChains(driver).move_to_element_with_offset(
                    canvas, x - cw // 2 + dx, y - ch // 2 + dy).click().perform()
                wait("window.prism.explanation && document.getElementById('inspect-radiance')",
                     f"the inspector near {x},{y}")
                shown = driver.execute_script("return window.prism.explanation;")
                if shown["pixel"] == [x, y]:
                    break
                dx += x - shown["pixel"][0]
                dy += y - shown["pixel"][1]
            # The pixel clicked, as the command explains it.
            x, y = shown["pixel"]
            out = subprocess.run([PRISM, "explain", path, "--pixel", f"{x},{y}", "--json"],
                                 check=True, capture_output=True, text=True).stdout
            expected = json.loads(out)
            close(shown, expected)
            tree = expected["tree"]
            if scene_name == "star.toml":
                # The star's test: the hit's, or among those rejected.
                tests = [tree["intersection"]] + tree["rejected"]
                star = next(t for t in tests if t and t["object"] == "standing star")
                drawn = driver.execute_script(f"""
                    const d = document.querySelector('.polygon-diagram[data-primitive="{star["primitive"]}"]');
                    return d && {{axis: d.dataset.principalAxis, crossings: +d.dataset.crossings,
                        parity: d.dataset.parity, inside: d.dataset.inside === 'true',
                        text: d.querySelector('.verdict').textContent,
                        edges: [...d.querySelectorAll('line.edge')].map((e) => [e.dataset.case,
                            e.dataset.xInt === undefined ? null : +e.dataset.xInt,
                            e.dataset.crosses === 'true'])}};""")
                p = star["polygon"]
                want = {"axis": p["principal_axis"], "crossings": p["crossings"],
                        "parity": p["parity"], "inside": p["inside"]}
                if not drawn or any(drawn[k] != v for k, v in want.items()):
                    fail(f"{x},{y}: the star's diagram shows {drawn}, explain {want}")
                edges = [[e["case"], e["x_int"], e["crosses"]] for e in p["edges"]]
                if drawn["edges"] != edges:
                    fail(f"{x},{y}: the edges drawn {drawn['edges']} are not explain's {edges}")
                if f"{p['crossings']} crossings: {p['parity']}" not in drawn["text"]:
                    fail(f"{x},{y}: the verdict reads {drawn['text']!r}")
                verdict = "inside" if p["inside"] else "outside"
                print(f"ok: {scene_name} at {x},{y}: the projected star (principal axis "
                      f"{p['principal_axis']}), {len(edges)} edges with their cases, "
                      f"{p['crossings']} crossings, {p['parity']}: {verdict}, as explain says")
                shot = f"lecture-star-{verdict}.png"
                driver.execute_script(f"""document.querySelector(
                    '.polygon-diagram[data-primitive="{star["primitive"]}"]')
                    .scrollIntoView({{block: "nearest"}});""")
            else:
                nodes, stack = [], [tree]
                while stack:
                    n = stack.pop()
                    nodes.append(n)
                    stack += [c for c in (n["reflected"], n["refracted"]) if c]
                tir = next(n for n in nodes if n["refraction"]
                           and n["refraction"]["total_internal_reflection"])
                r = tir["refraction"]
                drawn = driver.execute_script("""
                    const d = [...document.querySelectorAll('.snell-diagram')]
                        .find((d) => d.dataset.tir === 'true');
                    return d && {theta_i: +d.dataset.thetaI, critical: +d.dataset.criticalAngle,
                        text: d.textContent, r: !!d.querySelector('line.ray-r'),
                        t: !!d.querySelector('line.ray-t')};""")
                if (not drawn or drawn["theta_i"] != r["theta_i"]
                        or drawn["critical"] != r["critical_angle"]
                        or not drawn["r"] or drawn["t"]):
                    fail(f"the Snell diagram shows {drawn}, explain {r}")
                for words in (f"{r['theta_i']:.2f}°", f"{r['critical_angle']:.2f}°",
                              "total internal reflection"):
                    if words not in drawn["text"]:
                        fail(f"the Snell diagram does not read {words!r}")
                feelers = driver.execute_script(
                    "return window.prism.explanation.segments.filter((s) => s.kind === 'feeler').length;")
                print(f"ok: {scene_name} at {x},{y}: Snell's construction drawn, "
                      f"theta_i {r['theta_i']:.2f}° past the critical angle "
                      f"{r['critical_angle']:.2f}°: total internal reflection, R drawn, no T; "
                      f"{feelers} feelers drawn over the picture")
                # The 3D view: every ray of the tree and every listed feeler
                # drawn; a drag turns it.
                space = driver.execute_script("return window.prism.space;")
                listed = sum(len(l["feeler_points"]) for n in nodes for l in n["lights"])
                if not space or space["rays"] != len(nodes) or space["feelers"] != listed:
                    fail(f"the 3D view drew {space}, the tree has {len(nodes)} rays "
                         f"and {listed} feelers listed")
                view3d = driver.find_element(By.ID, "space")
                driver.execute_script("arguments[0].scrollIntoView({block: 'nearest'});", view3d)
                ActionChains(driver).move_to_element(view3d).click_and_hold().move_by_offset(
                    -60, 20).release().perform()
                turned = driver.execute_script("return window.prism.space;")
                if turned["yaw"] == space["yaw"] or turned["rays"] != len(nodes):
                    fail(f"dragging the 3D view did not turn it: {space} -> {turned}")
                driver.save_screenshot(os.path.join(SCREENS, "lecture-space.png"))
                if README_SHOT:
                    driver.save_screenshot(os.path.join(os.path.dirname(README_SHOT),
                                                        "lecture-space.png"))
                print(f"ok: the 3D view draws the {len(nodes)} rays and {listed} feelers "
                      f"of the tree among {space['objects']} objects, and turns when dragged")
                shot = "lecture-glass.png"
                driver.execute_script("""[...document.querySelectorAll('.snell-diagram')]
                    .find((d) => d.dataset.tir === 'true').scrollIntoView({block: "nearest"});""")
            driver.save_screenshot(os.path.join(SCREENS, shot))
            if README_SHOT:
                driver.save_screenshot(os.path.join(os.path.dirname(README_SHOT), shot))
        lecture_server.kill()
        lecture_server = None

    # Network mode: the token in the printed URL, then in a cookie.
    network = subprocess.Popen([PRISM, "serve", SCENE, "--port", "0", "--bind", "0.0.0.0"],
                               stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    token_url = re.search(r"http://\S+", network.stdout.readline()).group(0)
    bare = token_url.split("?")[0]
    driver.get(bare)
    if "needs the token" not in driver.find_element(By.TAG_NAME, "body").text:
        fail("without the token, the page does not ask for it")
    driver.get(token_url)
    wait("window.prism && window.prism.phase === 'done'", "the page opened with the token")
    if driver.current_url != bare:
        fail(f"the token stays in the address bar: {driver.current_url}")
    driver.refresh()
    wait("window.prism && window.prism.phase === 'done' && " + DRAWN,
         "the page reloaded with the cookie")
    compare(canvas_rgb(), reference("network"), "network mode, reloaded from the cookie")
    print("ok: network mode: the token is asked for, kept in a cookie and out of the address bar")
finally:
    driver.quit()
    server.kill()
    if globals().get("lecture_server"):
        lecture_server.kill()
    if "network" in globals():
        network.kill()
print("ok: the preview passes in Chromium")
