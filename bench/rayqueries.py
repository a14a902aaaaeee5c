#!/usr/bin/env python3
"""Ray queries from Python: prism.RayScene against embreex (Embree 4) and
Open3D's RaycastingScene, on the same meshes and the same rays, in one run.

Meshes: the Stanford bunny (npm package `bunny`, 3,674 triangles, as
bench/meshes.py gets it) and the 1M-triangle terrain of bench/meshes.py.
Rays: 1M coherent (a 1000x1000 pinhole camera, row by row) and 1M
incoherent (origins uniform in the mesh's box, directions uniform). For each
mesh: build time (to a first answer: Embree and Open3D build lazily), peak
memory per triangle (ru_maxrss growth over the build, each engine in a
process of its own), and rays/s for the nearest hit, any hit and counting
on 1 and 2 threads (embreex has no thread count: it traces on the calling
thread, so its 2-thread cells are empty; Embree has no counting query),
from wall time, and the CPU time of all the process's threads per 1M rays
(on two threads the work a query costs, whatever its threads waited).
Then the closest-point query (--points, 20,000 by default: uniform in the
mesh's box, and near its surface) against Open3D's compute_closest_points
(embreex has none), on 1 and 2 threads, with the largest difference in
distance between the two (Open3D works in float32).
Each measurement is taken in rounds that alternate the engines, after an
untimed warm-up round of every engine and query; the tables give the range
over the rounds.

Then pbrt-v4's watertightness test: 10M rays (a third per mesh) from
random points inside a randomly perturbed icosphere, the bunny (closed:
every edge on two triangles) and a torus, aimed at random directions, at
vertices and at points on edges; a ray that finds no hit has escaped. The
same rays (float32, as the others take them) go to each engine.

Set-up: bench/.venv (benchenv) with embreex, numpy and open3d-cpu from
PyPI; this tree's package is installed there with `pip install ./python`
(--no-install skips that).
Usage: python3 bench/rayqueries.py [--rounds N] [--warmup 0|1] [--rays N] [--points N] [--no-install]
           [--meshes bunny,bunny940k,terrain] [--watertight-rays N (0: none)]
       python3 bench/rayqueries.py --dump DIR   (the meshes and rays as raw
       f64/u32 files for examples/rayquerybench.rs, Prism's side in Rust)
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import benchenv  # noqa: E402

benchenv.ensure(extra=("open3d-cpu",))
# Open3D's wheel loads libusb, which a bare Debian lacks.
benchenv.ensure_library("usb-1.0", "libusb-1.0-0")
# NumPy's BLAS threads would spin in the CPU times measured below.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
import numpy as np  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ENGINES = ("prism", "embree", "open3d")


def install_prism():
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--disable-pip-version-check",
                    "--force-reinstall", "--no-deps", os.path.join(ROOT, "python")], check=True)


def read_ply(path):
    """bench/meshes.py's binary PLY, as (float32 vertices, int32 faces)."""
    import meshes as m  # bench/meshes.py, imported when first needed
    return m.read_ply(path)


def meshes():
    import meshes as m  # bench/meshes.py: fetches the bunny, writes the terrain
    os.makedirs(m.DATA, exist_ok=True)
    return [("bunny", read_ply(m.bunny())), ("bunny940k", read_ply(m.bunny_940k())),
            ("terrain 1M", read_ply(m.terrain()))]


def camera_rays(v, n):
    side = int(round(n ** 0.5))
    lo, hi = v.min(0), v.max(0)
    centre, size = (lo + hi) / 2, np.linalg.norm(hi - lo)
    eye = centre + size * np.array([0.3, 0.6, 1.0]) / np.linalg.norm([0.3, 0.6, 1.0]) * 1.2
    forward = (centre - eye) / np.linalg.norm(centre - eye)
    right = np.cross(forward, [0, 1, 0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    s = (np.arange(side) + 0.5) / side * 2 - 1
    x, y = np.meshgrid(s * 0.45, -s * 0.45)
    d = forward + x[..., None] * right + y[..., None] * up
    d = (d / np.linalg.norm(d, axis=-1, keepdims=True)).reshape(-1, 3)
    o = np.broadcast_to(eye, d.shape)
    return np.ascontiguousarray(o, dtype=np.float32), np.ascontiguousarray(d, dtype=np.float32)


def random_rays(v, n, seed):
    """Origins uniform in the box of `v`, directions uniform; `seed` (the
    mesh's index) keeps each mesh's rays whichever meshes are run."""
    rng = np.random.default_rng([1, seed])
    lo, hi = v.min(0), v.max(0)
    o = rng.uniform(lo, hi, size=(n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o.astype(np.float32), d.astype(np.float32)


def query_points(v, n, seed):
    """Points for the closest-point query: uniform in the mesh's box, and
    near its surface (a vertex moved by up to 1% of the box's diagonal)."""
    rng = np.random.default_rng(seed + 100)
    lo, hi = v.min(0), v.max(0)
    size = np.linalg.norm(hi - lo)
    near = v[rng.integers(0, len(v), n)] + rng.uniform(-0.01, 0.01, size=(n, 3)) * size / np.sqrt(3)
    return {"scattered": rng.uniform(lo, hi, size=(n, 3)), "near": near}


class Prism:
    name = "prism"

    def __init__(self, v, f):
        import prism
        self.scene = prism.RayScene(v.astype(np.float64), f.astype(np.int64))
        self.scene.intersect(v[:1] + 1e3, -v[:1] - 1e3)

    def prepare(self, o, d):
        return o.astype(np.float64), d.astype(np.float64)

    def closest(self, rays, threads):
        return self.scene.intersect(*rays, threads=threads)["triangle_id"]

    def any(self, rays, threads):
        return self.scene.occluded(*rays, threads=threads)

    def count(self, rays, threads):
        return self.scene.count_intersections(*rays, threads=threads)

    def closest_point(self, points, threads):
        return self.scene.closest_point(points.astype(np.float64), threads=threads)["point"]

    def memory(self):
        return self.scene.memory_bytes


class Embree:
    name = "embree"

    def __init__(self, v, f):
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
        self.scene = rtcs.EmbreeScene()
        TriangleMesh(self.scene, v.astype(np.float32), f.astype(np.int32))
        self.scene.run(v[:1] + np.float32(1e3), -v[:1] - np.float32(1e3))

    def prepare(self, o, d):
        return o, d

    def closest(self, rays, threads):
        if threads != 1:
            return None
        return self.scene.run(*rays, output=1)["primID"]

    def any(self, rays, threads):
        if threads != 1:
            return None
        return self.scene.run(*rays, query="OCCLUDED")

    def count(self, rays, threads):
        return None

    def closest_point(self, points, threads):
        return None  # embreex has no point queries


class Open3D:
    name = "open3d"

    def __init__(self, v, f):
        import open3d as o3d
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
        self.scene.cast_rays(o3d.core.Tensor(np.concatenate([v[:1] + 1e3, -v[:1] - 1e3], 1).astype(np.float32)))

    def prepare(self, o, d):
        import open3d as o3d
        return o3d.core.Tensor(np.ascontiguousarray(np.concatenate([o, d], 1), dtype=np.float32))

    def closest(self, rays, threads):
        return self.scene.cast_rays(rays, nthreads=threads)["primitive_ids"].numpy()

    def any(self, rays, threads):
        return self.scene.test_occlusions(rays, nthreads=threads).numpy()

    def count(self, rays, threads):
        return self.scene.count_intersections(rays, nthreads=threads).numpy()

    def closest_point(self, points, threads):
        import open3d as o3d
        p = o3d.core.Tensor(points.astype(np.float32))
        return self.scene.compute_closest_points(p, nthreads=threads)["points"].numpy()


CLASSES = {"prism": Prism, "embree": Embree, "open3d": Open3D}


def peak_memory(engine, path_v, path_f):
    """Bytes of peak resident-memory growth while building `engine` in a
    fresh process (the RSS sampled every millisecond), and of the growth
    left when the build is done."""
    code = f"""
import sys, threading, time, numpy as np
sys.path.insert(0, {os.path.dirname(os.path.abspath(__file__))!r})
import rayqueries as rq
def rss():
    return int(open("/proc/self/statm").read().split()[1]) * 4096
v, f = np.load({path_v!r}), np.load({path_f!r})
if {engine!r} == "open3d":
    import open3d
if {engine!r} == "prism":
    import prism
if {engine!r} == "embree":
    import embreex.rtcore_scene
before = rss()
peak = [before]
done = threading.Event()
def watch():
    while not done.is_set():
        peak[0] = max(peak[0], rss())
        time.sleep(0.001)
w = threading.Thread(target=watch)
w.start()
e = rq.CLASSES[{engine!r}](v, f)
done.set()
w.join()
after = rss()
print(max(peak[0], after) - before, after - before)
"""
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True,
                         env=dict(os.environ, RAYQUERIES_CHILD="1"))
    peak, steady = out.stdout.split()[-2:]
    return int(peak), int(steady)


def rng_range(xs, scale=1.0, fmt="{:.2f}"):
    if not xs:
        return "-"
    lo, hi = min(xs) * scale, max(xs) * scale
    return fmt.format(lo) if fmt.format(lo) == fmt.format(hi) else f"{fmt.format(lo)}-{fmt.format(hi)}"


def icosphere(levels, jitter, rng):
    t = (1 + 5 ** 0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    v = [np.asarray(p, float) / np.linalg.norm(p) for p in v]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    for _ in range(levels):
        mid = {}

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = (v[a] + v[b]) / 2
                v.append(p / np.linalg.norm(p))
                mid[key] = len(v) - 1
            return mid[key]

        nf = []
        for a, b, c in f:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    v = np.asarray(v) * rng.uniform(1 - jitter, 1 + jitter, size=(len(v), 1))
    return v.astype(np.float32), np.asarray(f, dtype=np.int64)


def torus(n, m, jitter, rng):
    i, j = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    u, w = 2 * np.pi * i / n, 2 * np.pi * j / m
    v = np.stack([(1 + 0.4 * np.cos(w)) * np.cos(u), (1 + 0.4 * np.cos(w)) * np.sin(u), 0.4 * np.sin(w)], -1)
    v = v.reshape(-1, 3) + jitter * rng.uniform(-1, 1, size=(n * m, 3))
    idx = lambda a, b: (a % n) * m + (b % m)
    a, b = i.ravel(), j.ravel()
    f = np.concatenate([np.stack([idx(a, b), idx(a + 1, b), idx(a + 1, b + 1)], 1),
                        np.stack([idx(a, b), idx(a + 1, b + 1), idx(a, b + 1)], 1)])
    return v.astype(np.float32), f.astype(np.int64)


def watertight_rays(v, f, inside, n, rng):
    o = inside(n)
    k = rng.integers(0, len(f), size=n)
    a, b = v[f[k, 0]].astype(np.float64), v[f[k, 1]].astype(np.float64)
    kind = np.arange(n) % 3
    s = rng.uniform(0, 1, size=(n, 1))
    target = np.where(kind[:, None] == 0, o + rng.normal(size=(n, 3)),
                      np.where(kind[:, None] == 1, a, a + s * (b - a)))
    return o.astype(np.float32), (target - o).astype(np.float32)


def dump(out, n):
    """Writes MESH.v (f64), MESH.f (u32) and MESH.KIND.o / .d (f64) for the
    bunny and the terrain: the rays main() times, as Prism receives them."""
    os.makedirs(out, exist_ok=True)
    for seed, (name, (v, f)) in enumerate(meshes()):
        tag = name.split()[0]
        v.astype(np.float64).tofile(os.path.join(out, f"{tag}.v"))
        f.astype(np.uint32).tofile(os.path.join(out, f"{tag}.f"))
        for kind, (o, d) in (("coherent", camera_rays(v, n)), ("incoherent", random_rays(v, n, seed))):
            o.astype(np.float64).tofile(os.path.join(out, f"{tag}.{kind}.o"))
            d.astype(np.float64).tofile(os.path.join(out, f"{tag}.{kind}.d"))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--rays", type=int, default=1_000_000)
    parser.add_argument("--points", type=int, default=20_000,
                        help="points per closest-point query (0: none)")
    parser.add_argument("--warmup", type=int, default=1, choices=(0, 1),
                        help="an untimed round first (1) or not (0)")
    parser.add_argument("--watertight-rays", type=int, default=10_000_000,
                        help="in all, a third per mesh")
    parser.add_argument("--no-install", action="store_true")
    parser.add_argument("--dump", metavar="DIR")
    parser.add_argument("--meshes", default="bunny,bunny940k,terrain",
                        help="comma-separated: which of bunny, bunny940k, terrain to time")
    args = parser.parse_args()
    if args.dump:
        dump(args.dump, args.rays)
        return
    if not args.no_install:
        install_prism()
    import open3d  # noqa: F401 (imported once, outside the timings)
    import prism  # noqa: F401
    rng = np.random.default_rng(1)
    print(f"rays per query: {args.rays:,}; rounds: {args.rounds}; CPUs: {os.cpu_count()}")
    results = []
    tmp = os.path.join(ROOT, "target", "rayqueries")
    os.makedirs(tmp, exist_ok=True)
    for seed, (name, (v, f)) in enumerate(meshes()):
        if name.split()[0] not in args.meshes.split(","):
            continue
        np.save(os.path.join(tmp, "v.npy"), v)
        np.save(os.path.join(tmp, "f.npy"), f)
        mem = {e: [b / len(f) for b in peak_memory(e, os.path.join(tmp, "v.npy"), os.path.join(tmp, "f.npy"))]
               for e in ENGINES}
        rays = {"coherent": camera_rays(v, args.rays), "incoherent": random_rays(v, args.rays, seed)}
        points = query_points(v, args.points, seed) if args.points else {}
        build = {e: [] for e in ENGINES}
        times = {}
        cpu = {}
        answers = {}
        # Round -1 is a warm-up, untimed: a process's first query of a kind
        # faults in its answers' memory and its code (Prism's first 1M-ray
        # nearest-hit query took 65-140 ms where later ones took 53), and
        # would charge that to whichever engine happens to go first.
        for r in range(-args.warmup, args.rounds):
            order = ENGINES if r % 2 == 0 else ENGINES[::-1]
            built = {}
            for e in order:
                start = time.perf_counter()
                built[e] = CLASSES[e](v, f)
                if r >= 0:
                    build[e].append(time.perf_counter() - start)
            for kind, (o, d) in rays.items():
                prepared = {e: built[e].prepare(o, d) for e in ENGINES}
                for query in ("closest", "any", "count"):
                    for threads in (1, 2):
                        for e in order:
                            start, start_cpu = time.perf_counter(), time.process_time()
                            out = getattr(built[e], query)(prepared[e], threads)
                            elapsed = time.perf_counter() - start
                            used = time.process_time() - start_cpu
                            if out is None or r < 0:
                                continue
                            times.setdefault((kind, query, threads, e), []).append(elapsed)
                            cpu.setdefault((kind, query, threads, e), []).append(used)
                            answers[(kind, query, e)] = out
            for kind, p in points.items():
                for threads in (1, 2):
                    for e in order:
                        start = time.perf_counter()
                        out = built[e].closest_point(p, threads)
                        elapsed = time.perf_counter() - start
                        if out is None or r < 0:
                            continue
                        times.setdefault((kind, "closest point", threads, e), []).append(elapsed)
                        answers[(kind, "closest point", e)] = np.linalg.norm(out - p, axis=1)
            del built
        # How far the engines agree (float32 engines see the same mesh and rays).
        agree = {}
        for kind in rays:
            p = answers[(kind, "closest", "prism")] >= 0
            for e, miss in (("embree", lambda x: x >= 0), ("open3d", lambda x: x != 4294967295)):
                if (kind, "closest", e) in answers:
                    agree[(kind, e)] = float(np.mean(miss(answers[(kind, "closest", e)]) == p))
        near = {kind: float(np.max(np.abs(answers[(kind, "closest point", "open3d")]
                                          - answers[(kind, "closest point", "prism")])))
                for kind in points}
        results.append((name, len(f), build, mem, times, cpu, agree, points, near))
    print()
    print("| mesh | triangles | engine | build s | bytes/tri peak, kept | ray kind | query | Mrays/s 1 thread | Mrays/s 2 threads "
          "| prism/engine 1 thread | prism/engine 2 threads | CPU s per 1M rays, 1 thread | CPU s per 1M rays, 2 threads "
          "| prism/engine by CPU, 2 threads |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, tris, build, mem, times, cpu, agree, _, _ in results:
        for kind in ("coherent", "incoherent"):
            for query in ("closest", "any", "count"):
                for e in ENGINES:
                    cells, ratios, cpu_cells = [], [], []
                    for threads in (1, 2):
                        ts = times.get((kind, query, threads, e), [])
                        cells.append(rng_range([args.rays / t / 1e6 for t in ts]))
                        # Prism's rate over this engine's, round by round
                        # (each pair measured back to back).
                        ps = times.get((kind, query, threads, "prism"), [])
                        ratios.append("-" if e == "prism" or not ts else
                                      rng_range([t / p for p, t in zip(ps, ts)]) + "x")
                        # CPU time of every thread of the process, per 1M rays.
                        cs = cpu.get((kind, query, threads, e), [])
                        cpu_cells.append(rng_range([c * 1e6 / args.rays for c in cs], fmt="{:.3f}"))
                    if cells == ["-", "-"]:
                        continue
                    # Two threads at equal work: this engine's CPU over Prism's.
                    cs, ps = cpu.get((kind, query, 2, e), []), cpu.get((kind, query, 2, "prism"), [])
                    cpu_ratio = "-" if e == "prism" or not cs else rng_range([c / p for p, c in zip(ps, cs)]) + "x"
                    print(f"| {name} | {tris:,} | {e} | {rng_range(build[e], fmt='{:.3f}')} | "
                          f"{mem[e][0]:.0f}, {mem[e][1]:.0f} | {kind} | {query} | {cells[0]} | {cells[1]} "
                          f"| {ratios[0]} | {ratios[1]} | {cpu_cells[0]} | {cpu_cells[1]} | {cpu_ratio} |")
        print(f"hit/miss agreement with prism on {name}: " +
              ", ".join(f"{k[1]} {k[0]} {v:.6f}" for k, v in agree.items()))
    if args.points:
        print()
        print(f"Closest point: {args.points:,} points a query ('scattered': uniform in the mesh's box; "
              "'near': within 1% of its size from a vertex), Prism against Open3D's compute_closest_points")
        print("| mesh | points | Prism Mpoints/s 1 thread | Prism/Open3D 1 thread | Prism Mpoints/s 2 threads "
              "| Prism/Open3D 2 threads | largest distance difference |")
        print("|---|---|---|---|---|---|---|")
        for name, _, _, _, times, _, _, points, near in results:
            for kind in points:
                cells = []
                for threads in (1, 2):
                    ps = times[(kind, "closest point", threads, "prism")]
                    os_ = times[(kind, "closest point", threads, "open3d")]
                    cells += [rng_range([args.points / t / 1e6 for t in ps]),
                              rng_range([o / p for p, o in zip(ps, os_)]) + "x"]
                print(f"| {name} | {kind} | {' | '.join(cells)} | {near[kind]:.1e} |")
    if args.watertight_rays == 0:
        return
    print()
    print("Watertightness (pbrt-v4): rays from inside perturbed closed meshes; escapes (no hit)")
    print("| mesh | triangles | rays | prism | embree | open3d |")
    print("|---|---|---|---|---|---|")
    def in_ball(n):
        d = rng.normal(size=(n, 3))
        return d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0, 0.5, size=(n, 1))

    def in_tube(n):
        u = rng.uniform(0, 2 * np.pi, n)
        return np.stack([np.cos(u), np.sin(u), np.zeros(n)], 1) + rng.uniform(-0.1, 0.1, size=(n, 3))

    def bunny(jitter):
        import meshes as m
        v, f = read_ply(m.bunny())
        return (v + rng.uniform(-jitter, jitter, size=v.shape)).astype(np.float32), f.astype(np.int64)

    def in_mesh(v, f):
        """Points of the mesh's box that Prism's exact `contains` puts
        inside (float32, as every engine gets them)."""
        import prism
        scene = prism.RayScene(v.astype(np.float64), f)

        def inside(n):
            found = []
            while sum(map(len, found)) < n:
                p = rng.uniform(v.min(0), v.max(0), size=(n, 3)).astype(np.float32)
                found.append(p[scene.contains(p.astype(np.float64))])
            return np.concatenate(found)[:n].astype(np.float64)
        return inside

    per_mesh = args.watertight_rays // 3
    bunny_mesh = bunny(0.02)
    for label, (v, f), inside in [
        ("icosphere (5 levels, radii +-10%)", icosphere(5, 0.1, rng), in_ball),
        ("bunny (closed, vertices +-0.02)", bunny_mesh, in_mesh(*bunny_mesh)),
        ("torus 256x128 (vertices +-0.004)", torus(256, 128, 0.004, rng), in_tube),
    ]:
        o, d = watertight_rays(v, f, inside, per_mesh, rng)
        escapes = {}
        for e in ENGINES:
            eng = CLASSES[e](v, f)
            ids = eng.closest(eng.prepare(o, d), 1)
            escapes[e] = int(np.sum(ids < 0)) if e != "open3d" else int(np.sum(ids == 4294967295))
        print(f"| {label} | {len(f):,} | {len(o):,} | {escapes['prism']} | {escapes['embree']} | {escapes['open3d']} |")


if __name__ == "__main__" and not os.environ.get("RAYQUERIES_CHILD"):
    main()
