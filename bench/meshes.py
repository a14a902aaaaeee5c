#!/usr/bin/env python3
"""Prism's mesh ray queries against Embree (embreex) on the same meshes and
the same rays, in the same run.

Meshes: the Stanford bunny (npm package `bunny`, installed into bench/) and a
procedural terrain of about one million triangles written by this script.
For each: Prism (examples/meshbench.rs) loads, builds and times (a) primary
camera rays 1024x1024, (b) incoherent rays, (c) shadow any-hit rays, single
threaded and on all threads; then Embree builds and traces the very same
rays (embreex traces on one thread, so the single-threaded ratio is the
like-for-like one). Prism's primary and shadow rays are also traced in
packets of eight (camera rays in 4x2 tiles, shadow rays of neighbouring
hits), as Mitsuba traces its batches, and the incoherent rays in streams
(eight traced in turns, so one ray's cache misses wait while the others
step); those rows still divide by Embree's one-ray-at-a-time rate. Prints one table with Prism/Embree ratios, and the
obvhs crate's compressed wide BVH on the same rays (one thread), the
candidate replacement for Prism's own BVH, and Mitsuba 3 (its LLVM variant,
one thread: closest hits and any-hit `ray_test`) where it can run.

Set-up: none; the script makes bench/.venv (embreex, numpy) on first run,
and adds mitsuba to it (its LLVM variant needs Debian's libllvm; without it
the Mitsuba rows say why they are missing).
Usage: python3 bench/meshes.py [--incoherent N]
       MESHBENCH=path/to/meshbench python3 bench/meshes.py  (time that binary,
       e.g. a saved build of an earlier commit, instead of building this tree's)
"""

import argparse
import json
import os
import re
import struct
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import benchenv  # noqa: E402

benchenv.ensure()
import numpy as np  # noqa: E402
from embreex import rtcore_scene as rtcs  # noqa: E402
from embreex.mesh_construction import TriangleMesh  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BENCH = os.path.join(ROOT, "bench")
DATA = os.path.join(BENCH, "data")


def write_ply(path, vertices, faces):
    with open(path, "wb") as f:
        f.write(b"ply\nformat binary_little_endian 1.0\n")
        f.write(b"element vertex %d\nproperty float x\nproperty float y\nproperty float z\n" % len(vertices))
        f.write(b"element face %d\nproperty list uchar int vertex_indices\nend_header\n" % len(faces))
        f.write(np.asarray(vertices, dtype="<f4").tobytes())
        rec = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", 3)])
        rec["n"] = 3
        rec["i"] = faces
        f.write(rec.tobytes())


def read_ply(path):
    """What write_ply writes: float x, y, z; uchar count + 3 ints."""
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().split("\n")
    nv = int(next(l for l in header if l.startswith("element vertex")).split()[-1])
    nf = int(next(l for l in header if l.startswith("element face")).split()[-1])
    v = np.frombuffer(data, dtype="<f4", count=3 * nv, offset=end).reshape(nv, 3)
    rec = np.frombuffer(data, dtype=[("n", "u1"), ("i", "<i4", 3)], count=nf, offset=end + 12 * nv)
    return np.ascontiguousarray(v), np.ascontiguousarray(rec["i"])


def bunny():
    """The Stanford bunny from the npm package `bunny`, as binary PLY."""
    path = os.path.join(DATA, "bunny.ply")
    if os.path.exists(path):
        return path
    module = os.path.join(BENCH, "node_modules", "bunny", "index.js")
    if not os.path.exists(module):
        subprocess.run(["npm", "install", "--prefix", BENCH, "--no-save", "--silent", "bunny@1.0.1"], check=True)
    text = open(module).read()
    grab = lambda name: json.loads(re.search(r"exports\." + name + r"\s*=\s*(\[.*?\]\])", text, re.S).group(1))
    write_ply(path, grab("positions"), grab("cells"))
    return path


def subdivided(vertices, faces, levels):
    """Each triangle split into four at its edges' midpoints, `levels`
    times (the surface unchanged, 4**levels times the triangles; an edge's
    midpoint is shared by the two triangles on it, so a closed mesh stays
    closed)."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    for _ in range(levels):
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        unique, inverse = np.unique(np.sort(edges, axis=1), axis=0, return_inverse=True)
        mid = len(v) + inverse.reshape(3, -1)
        v = np.concatenate([v, (v[unique[:, 0]] + v[unique[:, 1]]) / 2])
        ab, bc, ca = mid
        a, b, c = f.T
        f = np.concatenate([np.stack(t, 1) for t in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))])
    return v, f


def bunny_940k():
    """The bunny's 3,674 triangles subdivided four times: 940,544."""
    path = os.path.join(DATA, "bunny940k.ply")
    if os.path.exists(path):
        return path
    write_ply(path, *subdivided(*read_ply(bunny()), 4))
    return path


def terrain(n=708):
    """A rolling heightfield of 2·(n−1)² ≈ 1M triangles, as binary PLY."""
    path = os.path.join(DATA, f"terrain{n}.ply")
    if os.path.exists(path):
        return path
    u = np.linspace(-1.0, 1.0, n)
    x, z = np.meshgrid(u, u)
    y = 0.08 * np.sin(9 * x) * np.cos(7 * z) + 0.05 * np.sin(23 * x + 11 * z) + 0.02 * np.cos(61 * z - 37 * x)
    vertices = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).reshape(-1)
    faces = np.concatenate([np.stack([a, a + n, a + 1], 1), np.stack([a + 1, a + n, a + n + 1], 1)])
    write_ply(path, vertices, faces)
    return path


def load_rays(path):
    r = np.fromfile(path, dtype="<f4").reshape(-1, 7)
    return np.ascontiguousarray(r[:, :3]), np.ascontiguousarray(r[:, 3:6]), np.ascontiguousarray(r[:, 6])


def mitsuba_rates(triangles, rays):
    """Mitsuba 3's single-threaded Mrays/s on the same triangles and rays:
    (primary closest hits, shadow any hits, their hit counts), or a reason."""
    try:
        subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--disable-pip-version-check", "mitsuba"],
                       check=True, capture_output=True)
        import drjit as dr
        import mitsuba as mi
        mi.set_variant("llvm_ad_rgb")
    except Exception as e:  # noqa: BLE001 - any failure means "not measured", with the reason
        return str(e).splitlines()[0] if str(e) else type(e).__name__
    dr.set_thread_count(1)
    n = len(triangles)
    v = triangles.reshape(-1, 3)
    mesh = mi.Mesh("m", vertex_count=3 * n, face_count=n, has_vertex_normals=False, has_vertex_texcoords=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = dr.ravel(mi.Point3f(v[:, 0], v[:, 1], v[:, 2]))
    params["faces"] = mi.UInt32(np.arange(3 * n, dtype=np.uint32))
    params.update()
    scene = mi.load_dict({"type": "scene", "m": mesh})
    out = {}
    for kind in ("primary", "shadow"):
        o, d, t = rays[kind]
        ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
        ray.maxt = mi.Float(np.minimum(t, 3e38))
        if kind == "shadow":
            run = lambda: int(dr.count(scene.ray_test(ray)).numpy()[0])  # noqa: E731
        else:
            run = lambda: int(dr.count(scene.ray_intersect_preliminary(ray).is_valid()).numpy()[0])  # noqa: E731
        secs, hits = best_of_3(run)
        out[kind] = (len(o) / secs / 1e6, hits)
    return out


def best_of_3(run):
    best, out = float("inf"), None
    for _ in range(3):
        start = time.perf_counter()
        out = run()
        best = min(best, time.perf_counter() - start)
    return best, out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--incoherent", type=int, default=1 << 20)
    args = parser.parse_args()
    os.makedirs(DATA, exist_ok=True)
    exe = os.environ.get("MESHBENCH")
    if not exe:
        subprocess.run(["cargo", "build", "--release", "--quiet", "--example", "meshbench"], cwd=ROOT, check=True)
        exe = os.path.join(ROOT, "target", "release", "examples", "meshbench")
    rows, notes = [], []
    for name, path in [("bunny", bunny()), ("terrain 1M", terrain())]:
        with tempfile.TemporaryDirectory() as out:
            prism = json.loads(subprocess.run([exe, path, out, str(args.incoherent)], check=True,
                                              capture_output=True, text=True).stdout)
            triangles = np.fromfile(os.path.join(out, "triangles.f32"), dtype="<f4").reshape(-1, 3, 3)
            rays = {k: load_rays(os.path.join(out, k + ".f32")) for k in ("primary", "incoherent", "shadow")}
        start = time.perf_counter()
        scene = rtcs.EmbreeScene()
        TriangleMesh(scene, triangles)
        scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))  # commit: build the BVH
        embree_build = time.perf_counter() - start
        rows.append((name, "triangles", prism["triangles"], None, None, None))
        ob = prism["obvhs"]
        rows.append((name, "obvhs CWBVH8 build s / primary / shadow", ob["build_s"], ob["primary_mrays_1"],
                     ob["shadow_mrays_1"], None))
        mi = mitsuba_rates(triangles, rays)
        if isinstance(mi, dict):
            notes.append(f"{name}: Mitsuba 3 (llvm_ad_rgb, 1 thread): " + ", ".join(
                f"{kind} {mi[kind][0]:.3f} Mrays/s (Prism/Mitsuba {prism[kind]['mrays_1'] / mi[kind][0]:.2f}x, "
                f"hits {mi[kind][1]} vs {prism[kind]['hits']})" for kind in ("primary", "shadow")))
        else:
            notes.append(f"{name}: Mitsuba 3 not measured: {mi}")
        rows.append((name, "build s (Prism load+build / Embree)", prism["load_s"] + prism["build_s"], None, embree_build, None))
        rows.append((name, "Prism mesh MB / peak RSS MB", prism["mesh_mb"], prism["peak_rss_mb"], None, None))
        for kind in ("primary", "incoherent", "shadow"):
            o, d, t = rays[kind]
            if kind == "shadow":
                secs, res = best_of_3(lambda: scene.run(o, d, query="OCCLUDED", dists=t))
                hits = int((res >= 0).sum())
            else:
                secs, res = best_of_3(lambda: scene.run(o, d))
                hits = int((res >= 0).sum())
            e_rate = len(o) / secs / 1e6
            p = prism[kind]
            agree = abs(hits - p["hits"]) <= max(2, len(o) * 1e-3)
            rows.append((name, f"{kind} Mrays/s (1 thread, all threads)", p["mrays_1"], p["mrays_n"], e_rate,
                         (p["mrays_1"] / e_rate, agree)))
            if kind == "incoherent" and "streams" in prism:
                # The same rays traced by Prism eight at a time in turns
                # (Mesh::intersect_stream), against Embree one at a time.
                st = prism["streams"]
                rows.append((name, "incoherent in streams of 8 Mrays/s", st["incoherent_mrays_1"],
                             st["incoherent_mrays_n"], e_rate, (st["incoherent_mrays_1"] / e_rate, agree)))
            if kind in ("primary", "shadow"):
                # The same rays traced by Prism in packets of eight (camera
                # rays in 4x2 tiles), against Embree one ray at a time.
                pk = prism["packets"]
                rows.append((name, f"{kind} in packets of 8 Mrays/s", pk[f"{kind}_mrays_1"], pk[f"{kind}_mrays_n"],
                             e_rate, (pk[f"{kind}_mrays_1"] / e_rate, agree)))
                if isinstance(mi, dict):
                    notes.append(f"{name}: {kind} in packets of 8, Prism/Mitsuba "
                                 f"{pk[kind + '_mrays_1'] / mi[kind][0]:.2f}x")
    print(f"{'mesh':<11} {'measure':<38} {'prism':>10} {'prism all':>10} {'embree':>10} {'prism/embree':>13} {'hits agree':>10}")
    for name, what, a, b, e, ratio in rows:
        fmt = lambda v: f"{v:>10.3f}" if isinstance(v, float) else (f"{v:>10}" if v is not None else " " * 10)
        r = f"{ratio[0]:>12.2f}x {str(ratio[1]):>10}" if ratio else ""
        print(f"{name:<11} {what:<38} {fmt(a)} {fmt(b)} {fmt(e)} {r}")
    for note in notes:
        print(note)


if __name__ == "__main__":
    main()
