"""prism.RayScene: every query against brute force on small meshes, every
class of bad argument, the GIL released during a query, Ctrl-C stopping one."""

import _thread
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import prism

ROOT = Path(__file__).resolve().parents[2]


def icosphere(levels=2, jitter=0.0, seed=0):
    """A closed, outward-wound icosphere (radius 1, each vertex's radius
    scaled by 1 +- jitter)."""
    t = (1 + 5 ** 0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    v = [list(np.asarray(p, float) / np.linalg.norm(p)) for p in v]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    for _ in range(levels):
        mid = {}

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = (np.asarray(v[a]) + np.asarray(v[b])) / 2
                v.append(list(p / np.linalg.norm(p)))
                mid[key] = len(v) - 1
            return mid[key]

        nf = []
        for a, b, c in f:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nf += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
        f = nf
    v = np.asarray(v)
    rng = np.random.default_rng(seed)
    v = v * rng.uniform(1 - jitter, 1 + jitter, size=(len(v), 1))
    return v, np.asarray(f, dtype=np.int64)


def random_soup(n, seed):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-1, 1, size=(n, 1, 3))
    v = (centres + 0.3 * rng.normal(size=(n, 3, 3))).reshape(-1, 3)
    return v, np.arange(3 * n, dtype=np.int64).reshape(n, 3)


def brute(v, f, o, d, tmin=0.0, tmax=np.inf):
    """Every (t, triangle, u, v) of each ray by Moller-Trumbore over every
    triangle, in float64 (rays near an edge differ from the watertight test
    only in the last bits)."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    e1, e2 = b - a, c - a
    out = []
    for oi, di in zip(o, d):
        p = np.cross(di, e2)
        det = np.einsum("ij,ij->i", e1, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            s = oi - a
            u = np.einsum("ij,ij->i", s, p) * inv
            q = np.cross(s, e1)
            w = (q @ di) * inv
            t = np.einsum("ij,ij->i", e2, q) * inv
        ok = (det != 0) & (u >= 0) & (w >= 0) & (u + w <= 1) & (t > tmin) & (t < tmax)
        idx = np.nonzero(ok)[0]
        order = np.argsort(t[idx], kind="stable")
        out.append([(t[i], i, u[i], w[i]) for i in idx[order]])
    return out


def rays(n, seed):
    rng = np.random.default_rng(seed)
    o = rng.uniform(-2, 2, size=(n, 3))
    d = rng.normal(size=(n, 3))
    return o, d


def test_queries_equal_brute_force():
    v, f = random_soup(200, 1)
    scene = prism.RayScene(v, f)
    o, d = rays(600, 2)
    for tmin, tmax in [(0.0, np.inf), (0.3, 1.5)]:
        ref = brute(v, f, o, d, tmin, tmax)
        hits = scene.intersect(o, d, tmin=tmin, tmax=tmax, threads=2)
        assert set(hits) == {"t", "mesh_id", "triangle_id", "u", "v", "normal"}
        assert hits["t"].dtype == np.float64 and hits["triangle_id"].dtype == np.int64
        assert hits["normal"].shape == (600, 3)
        occluded = scene.occluded(o, d, tmin=tmin, tmax=tmax)
        counts = scene.count_intersections(o, d, tmin=tmin, tmax=tmax)
        allx = scene.all_intersections(o, d, tmin=tmin, tmax=tmax)
        assert allx["offsets"].shape == (601,)
        hit = 0
        for k, r in enumerate(ref):
            assert occluded[k] == bool(r)
            assert counts[k] == len(r)
            s, e = allx["offsets"][k], allx["offsets"][k + 1]
            assert list(allx["triangle_id"][s:e]) == [x[1] for x in r]
            np.testing.assert_allclose(allx["t"][s:e], [x[0] for x in r], rtol=1e-12)
            if not r:
                assert hits["triangle_id"][k] == -1 and hits["mesh_id"][k] == -1
                assert hits["t"][k] == np.inf
                continue
            hit += 1
            t, tri, u, w = r[0]
            assert hits["triangle_id"][k] == tri and hits["mesh_id"][k] == 0
            assert hits["t"][k] == pytest.approx(t, rel=1e-12)
            assert hits["u"][k] == pytest.approx(u, abs=1e-9)
            assert hits["v"][k] == pytest.approx(w, abs=1e-9)
            a, b, c = v[f[tri]]
            n = np.cross(b - a, c - a)
            np.testing.assert_allclose(hits["normal"][k], n / np.linalg.norm(n), atol=1e-12)
        assert hit > 50


def test_answers_let_go_are_written_again_and_kept_ones_never():
    """A query writes its answers into the arrays of an earlier one that
    nothing holds any more (so a loop of large queries does not fault in
    new memory each time), whichever scene made them; arrays the caller
    keeps, or views of them, are never written."""
    v, f = random_soup(200, 3)
    scene = prism.RayScene(v, f)
    # A number of rays no other test uses: kept arrays of other tests'
    # queries are of other shapes.
    (o1, d1), (o2, d2) = rays(517, 4), rays(517, 5)
    fresh = prism.RayScene(v, f)
    first = scene.intersect(o1, d1)
    kept = {k: a.copy() for k, a in first.items()}
    address = {k: a.__array_interface__["data"][0] for k, a in first.items()}
    # Held by the caller: not written.
    second = scene.intersect(o2, d2)
    for k, a in first.items():
        np.testing.assert_array_equal(a, kept[k])
        assert second[k].__array_interface__["data"][0] != address[k]
    del a  # the loop's name for the last array holds it too
    # Let go: written again, every entry (misses included) the answer of
    # the new rays.
    del first
    third = prism.RayScene(v, f).intersect(o1[::-1].copy(), d1[::-1].copy())
    assert {k: a.__array_interface__["data"][0] for k, a in third.items()} == address
    want = fresh.intersect(o1[::-1].copy(), d1[::-1].copy())
    assert np.isinf(want["t"]).any() and np.isfinite(want["t"]).any()
    for k in want:
        np.testing.assert_array_equal(third[k], want[k])
    # A view keeps its array from being written.
    view = third["t"][::2]
    snapshot = view.copy()
    del third
    scene.intersect(o2, d2)
    np.testing.assert_array_equal(view, snapshot)
    # Read-only arrays let go are left alone too.
    second["u"].flags.writeable = False
    del second
    again = scene.intersect(o2, d2)
    for k, a in fresh.intersect(o2, d2).items():
        np.testing.assert_array_equal(again[k], a)


def test_meshes_ids_and_transforms():
    v, f = random_soup(100, 3)
    m = np.array([[0, -2, 0, 0.5], [1, 0, 0, 0.1], [0, 0, 1.5, -0.2], [0, 0, 0, 1]], float)
    moved = v @ m[:3, :3].T + m[:3, 3]
    a = prism.RayScene()
    assert a.add_mesh(v, f) == 0
    assert a.add_mesh(v, f, transform=m) == 1
    b = prism.RayScene()
    b.add_mesh(v, f)
    b.add_mesh(moved, f)
    assert a.mesh_count == 2 and a.triangle_count == 200
    assert a.memory_per_triangle > 0
    o, d = rays(500, 4)
    ha, hb = a.intersect(o, d), b.intersect(o, d)
    np.testing.assert_array_equal(ha["mesh_id"], hb["mesh_id"])
    np.testing.assert_array_equal(ha["triangle_id"], hb["triangle_id"])
    np.testing.assert_allclose(ha["t"], hb["t"], rtol=1e-9)
    np.testing.assert_allclose(ha["normal"], hb["normal"], atol=1e-9)
    assert (ha["mesh_id"] == 1).sum() > 20


def brute_distance(v, f, p):
    """Distance from each point to the nearest triangle, by a formulation
    of its own: the projection onto each triangle's plane where it falls
    inside, else the nearest of the three edges (segments)."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    n = np.cross(b - a, c - a)
    n2 = np.einsum("ij,ij->i", n, n)

    def segment(p, x, y):
        e = y - x
        s = np.clip(np.einsum("ij,ij->i", p - x, e) / np.einsum("ij,ij->i", e, e), 0, 1)
        return np.linalg.norm(p - (x + s[:, None] * e), axis=1)

    out = []
    for q in p:
        w = q - a
        h = np.einsum("ij,ij->i", w, n) / n2
        x = q - h[:, None] * n
        inside = np.ones(len(f), bool)
        for p0, p1 in ((a, b), (b, c), (c, a)):
            inside &= np.einsum("ij,ij->i", np.cross(p1 - p0, x - p0), n) >= 0
        plane = np.where(inside, np.abs(h) * np.sqrt(n2), np.inf)
        edges = np.minimum(np.minimum(segment(q, a, b), segment(q, b, c)), segment(q, c, a))
        out.append(np.minimum(plane, edges).min())
    return np.array(out)


def test_closest_point_equals_brute_force():
    v, f = random_soup(150, 11)
    m = np.array([[0, -2, 0, 0.5], [1, 0, 0, 0.1], [0, 0, 1.5, -0.2], [0, 0, 0, 1]], float)
    scene = prism.RayScene()
    scene.add_mesh(v, f)
    scene.add_mesh(v, f, transform=m)
    moved = v @ m[:3, :3].T + m[:3, 3]
    rng = np.random.default_rng(12)
    p = np.concatenate([rng.uniform(-3, 3, size=(300, 3)), v[:20] + 1e-9])
    near = scene.closest_point(p)
    assert near["point"].shape == (len(p), 3) and near["distance"].shape == (len(p),)
    both = np.concatenate([v, moved]), np.concatenate([f, f + len(v)])
    np.testing.assert_allclose(near["distance"], brute_distance(*both, p), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(p - near["point"], axis=1), near["distance"],
                               rtol=1e-12, atol=1e-15)
    # The point lies on the triangle named, at its barycentric weights.
    corners = np.where(near["mesh_id"][:, None, None] == 0, v[f[near["triangle_id"]]],
                       moved[f[near["triangle_id"]]])
    u, w = near["u"][:, None], near["v"][:, None]
    np.testing.assert_allclose((1 - u - w) * corners[:, 0] + u * corners[:, 1] + w * corners[:, 2],
                               near["point"], atol=1e-12)
    assert set(np.unique(near["mesh_id"])) == {0, 1}
    # The normal: unit, at right angles to the named triangle's edges.
    n = near["normal"]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1, atol=1e-12)
    for e in (corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]):
        np.testing.assert_allclose(np.einsum("ij,ij->i", n, e), 0, atol=1e-12)
    # The same on any thread count, and from float32 points as from
    # their float64 values.
    again = scene.closest_point(p, threads=2)
    for k in near:
        np.testing.assert_array_equal(near[k], again[k])
    single = p.astype(np.float32)
    a, b = scene.closest_point(single), scene.closest_point(single.astype(np.float64))
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])


def test_contains_and_watertightness():
    v, f = icosphere(3, jitter=0.1, seed=5)
    scene = prism.RayScene(v, f)
    assert scene.is_closed(0)
    rng = np.random.default_rng(6)
    inside = rng.normal(size=(2000, 3))
    inside *= (rng.uniform(0, 0.5, size=(2000, 1)) / np.linalg.norm(inside, axis=1, keepdims=True))
    assert scene.contains(inside).all()
    assert not scene.contains(3 * inside / np.linalg.norm(inside, axis=1, keepdims=True)).any()
    # Rays from inside at random directions, at vertices and at edges: none escapes.
    targets = np.concatenate([inside + rng.normal(size=inside.shape), v[f[:, 0]][:2000 // 2].repeat(2, 0),
                              (v[f[:, 0]] + v[f[:, 1]])[:1000].repeat(2, 0) / 2])
    origins = np.concatenate([inside] * 3)
    hits = scene.intersect(origins, targets - origins)
    assert (hits["triangle_id"] >= 0).all()
    assert scene.occluded(origins, targets - origins).all()
    # Points a trillionth inside and outside the faces along their normals.
    a, b, c = (v[f[:, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    centre = (a + b + c) / 3
    assert scene.contains(centre - 1e-12 * n).all()
    assert not scene.contains(centre + 1e-12 * n).any()


def bunny(jitter, seed):
    """The Stanford bunny of tests/data/bunny.ply (3,674 triangles, closed),
    each vertex moved by up to `jitter` along each axis."""
    data = (ROOT / "tests" / "data" / "bunny.ply").read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().split("\n")
    nv = int(next(line for line in header if line.startswith("element vertex")).split()[-1])
    nf = int(next(line for line in header if line.startswith("element face")).split()[-1])
    v = np.frombuffer(data, dtype="<f4", count=3 * nv, offset=end).reshape(nv, 3).astype(np.float64)
    rec = np.frombuffer(data, dtype=[("n", "u1"), ("i", "<i4", 3)], count=nf, offset=end + 12 * nv)
    rng = np.random.default_rng(seed)
    return v + rng.uniform(-jitter, jitter, size=v.shape), rec["i"].astype(np.int64)


def test_no_ray_escapes_the_bunny():
    v, f = bunny(0.02, seed=10)
    scene = prism.RayScene(v, f)
    assert scene.is_closed(0)
    rng = np.random.default_rng(11)
    points = rng.uniform(v.min(0), v.max(0), size=(4000, 3))
    inside = scene.contains(points)
    assert 400 < inside.sum() < 3600
    # Along random directions (through no edge, almost surely) the
    # crossings' parity is inside or outside.
    d = rng.normal(size=points.shape)
    assert ((scene.count_intersections(points, d) % 2 == 1) == inside).all()
    # From inside, at random directions, at vertices and at points on
    # edges: every ray hits.
    o = points[inside]
    k = rng.integers(0, len(f), size=len(o))
    a, b = v[f[k, 0]], v[f[k, 1]]
    targets = np.concatenate([o + rng.normal(size=o.shape), a, a + rng.uniform(0, 1, (len(o), 1)) * (b - a)])
    origins = np.concatenate([o] * 3)
    for threads in (1, 2):
        assert (scene.intersect(origins, targets - origins, threads=threads)["triangle_id"] >= 0).all()
        assert scene.occluded(origins, targets - origins, threads=threads).all()


def test_float32_and_noncontiguous_inputs():
    v, f = icosphere(1)
    o, d = rays(300, 7)
    ref = prism.RayScene(v.astype(np.float32).astype(np.float64), f).intersect(o, d)
    got = prism.RayScene(v.astype(np.float32), f.astype(np.int32)).intersect(o, d)
    np.testing.assert_array_equal(ref["t"], got["t"])
    wide = np.zeros((300, 6))
    wide[:, ::2] = o
    strided = prism.RayScene(v, f).intersect(wide[:, ::2], d.astype(np.float32))
    plain = prism.RayScene(v, f).intersect(o, d.astype(np.float32).astype(np.float64))
    np.testing.assert_array_equal(strided["t"], plain["t"])
    assert prism.RayScene(v, f).intersect(o.tolist(), d.tolist())["t"].shape == (300,)


def test_float32_rays_answer_as_their_float64_values():
    # Read in place and widened as they are traced: every query gives the
    # answers of the widened values, for scattered rays and a camera's rows.
    v, f = random_soup(400, 21)
    scene = prism.RayScene(v, f)
    o, d = rays(5000, 22)
    y, x = np.mgrid[0:48, 0:128]
    cam_d = np.stack([(x - 64) / 40.0, (y - 24) / 40.0, np.full(x.shape, -1.5)], -1).reshape(-1, 3)
    cam_o = np.broadcast_to([0.1, 0.2, 4.0], cam_d.shape)
    for o, d in ((o, d), (cam_o, cam_d)):
        o32, d32 = np.ascontiguousarray(o, np.float32), np.ascontiguousarray(d, np.float32)
        o64, d64 = o32.astype(np.float64), d32.astype(np.float64)
        for threads in (1, 2):
            ref, got = scene.intersect(o64, d64, threads=threads), scene.intersect(o32, d32, threads=threads)
            assert set(ref) == set(got)
            for key in ref:
                np.testing.assert_array_equal(ref[key], got[key])
            assert 0 < (ref["triangle_id"] >= 0).sum() < len(o)
            np.testing.assert_array_equal(scene.occluded(o64, d64, threads=threads), scene.occluded(o32, d32, threads=threads))
            np.testing.assert_array_equal(scene.count_intersections(o64, d64, threads=threads),
                                          scene.count_intersections(o32, d32, threads=threads))
            ref, got = scene.all_intersections(o64, d64, threads=threads), scene.all_intersections(o32, d32, threads=threads)
            for key in ref:
                np.testing.assert_array_equal(ref[key], got[key])
    with pytest.raises(ValueError, match="directions: row 1"):
        scene.intersect(np.zeros((2, 3), np.float32), np.array([[0, 0, 1], [np.nan, 0, 1]], np.float32))
    # Vertices and contains' points in float32, read in place too.
    v, f = icosphere(2)
    points = np.random.default_rng(23).uniform(-1.2, 1.2, size=(2000, 3)).astype(np.float32)
    single = prism.RayScene(v.astype(np.float32), f)
    double = prism.RayScene(v.astype(np.float32).astype(np.float64), f)
    inside = double.contains(points.astype(np.float64))
    np.testing.assert_array_equal(single.contains(points), inside)
    assert 0 < inside.sum() < len(points)


def test_from_file_reads_a_model():
    scene = prism.RayScene.from_file(ROOT / "scenes" / "models" / "icosphere.ply")
    assert scene.triangle_count > 0 and scene.mesh_count == 1
    hits = scene.intersect(np.zeros((1, 3)) + [0, 0, 10], [[0, 0, -1]])
    assert hits["triangle_id"][0] >= 0
    with pytest.raises(ValueError, match="missing.obj"):
        prism.RayScene.from_file(ROOT / "scenes" / "models" / "missing.obj")


def test_threads_give_the_same_answers():
    v, f = random_soup(300, 8)
    scene = prism.RayScene(v, f)
    o, d = rays(20000, 9)
    one = scene.intersect(o, d, threads=1)
    for n in (2, 3):
        other = scene.intersect(o, d, threads=n)
        for key in one:
            np.testing.assert_array_equal(one[key], other[key])
        np.testing.assert_array_equal(scene.count_intersections(o, d, threads=1),
                                      scene.count_intersections(o, d, threads=n))


BAD = [
    # (what, call, argument named)
    ("vertices 2 columns", lambda s, v, f, o, d: prism.RayScene(v[:, :2], f), "vertices"),
    ("vertices 1-D", lambda s, v, f, o, d: prism.RayScene(v.ravel(), f), "vertices"),
    ("vertices complex", lambda s, v, f, o, d: prism.RayScene(v.astype(complex), f), "vertices"),
    ("vertices strings", lambda s, v, f, o, d: prism.RayScene(v.astype(str), f), "vertices"),
    ("vertices bool", lambda s, v, f, o, d: prism.RayScene(v > 0, f), "vertices"),
    ("vertices NaN", lambda s, v, f, o, d: prism.RayScene(np.where(v > 0.9, np.nan, v), f), "vertices"),
    ("vertices inf", lambda s, v, f, o, d: prism.RayScene(np.where(v > 0.9, np.inf, v), f), "vertices"),
    ("vertices empty", lambda s, v, f, o, d: prism.RayScene(v[:0], f), "vertices"),
    ("faces float", lambda s, v, f, o, d: prism.RayScene(v, f.astype(float)), "faces"),
    ("faces shape", lambda s, v, f, o, d: prism.RayScene(v, f[:, :2]), "faces"),
    ("faces empty", lambda s, v, f, o, d: prism.RayScene(v, f[:0]), "faces"),
    ("faces negative", lambda s, v, f, o, d: prism.RayScene(v, f - 1), "faces"),
    ("faces past the end", lambda s, v, f, o, d: prism.RayScene(v, f + len(v)), "faces"),
    ("faces uint64 huge", lambda s, v, f, o, d: prism.RayScene(v, f.astype(np.uint64) + 2**63), "faces"),
    ("transform shape", lambda s, v, f, o, d: s.add_mesh(v, f, np.eye(3)), "transform"),
    ("transform singular", lambda s, v, f, o, d: s.add_mesh(v, f, np.zeros((4, 4))), "transform"),
    ("transform projective", lambda s, v, f, o, d: s.add_mesh(v, f, np.eye(4) + np.eye(4)[::-1]), "transform"),
    ("origins shape", lambda s, v, f, o, d: s.intersect(o[:, :2], d), "origins"),
    ("origins NaN", lambda s, v, f, o, d: s.intersect(o * np.nan, d), "origins"),
    ("origins empty", lambda s, v, f, o, d: s.occluded(o[:0], d[:0]), "origins"),
    ("origins object", lambda s, v, f, o, d: s.intersect(o.astype(object), d), "origins"),
    ("directions inf", lambda s, v, f, o, d: s.count_intersections(o, d * np.inf), "directions"),
    ("directions zero", lambda s, v, f, o, d: s.intersect(o, d * 0), "directions"),
    ("directions count", lambda s, v, f, o, d: s.all_intersections(o, d[:-1]), "directions"),
    ("tmin NaN", lambda s, v, f, o, d: s.intersect(o, d, tmin=np.nan), "tmin"),
    ("tmin text", lambda s, v, f, o, d: s.intersect(o, d, tmin="a"), "tmin"),
    ("tmin negative", lambda s, v, f, o, d: s.intersect(o, d, tmin=-1), "tmin"),
    ("tmax below tmin", lambda s, v, f, o, d: s.intersect(o, d, tmin=2, tmax=1), "tmax"),
    ("threads zero", lambda s, v, f, o, d: s.intersect(o, d, threads=0), "threads"),
    ("threads huge", lambda s, v, f, o, d: s.contains(o, threads=10**6), "threads"),
    ("threads text", lambda s, v, f, o, d: s.occluded(o, d, threads="2"), "threads"),
    ("points NaN", lambda s, v, f, o, d: s.contains(o * np.nan), "points"),
    ("points empty", lambda s, v, f, o, d: s.contains(o[:0]), "points"),
    ("contains open mesh", lambda s, v, f, o, d: prism.RayScene(v, f[1:]).contains(o), "contains"),
    ("closest points NaN", lambda s, v, f, o, d: s.closest_point(o * np.nan), "points"),
    ("closest points shape", lambda s, v, f, o, d: s.closest_point(o[:, :2]), "points"),
    ("closest points empty", lambda s, v, f, o, d: s.closest_point(o[:0]), "points"),
    ("closest threads", lambda s, v, f, o, d: s.closest_point(o, threads=0), "threads"),
    # The extension itself, past the package's conversions.
    ("raw strided origins", lambda s, v, f, o, d: s._scene.intersect(np.asfortranarray(o), d, 0.0,
                                                                      np.inf, None), "origins"),
    ("raw int faces", lambda s, v, f, o, d: s._scene.add_mesh(v, f.astype(np.int32), None), "faces"),
    ("raw list points", lambda s, v, f, o, d: s._scene.contains(o.tolist(), None), "points"),
]


@pytest.mark.parametrize("what,call,name", BAD, ids=[b[0] for b in BAD])
def test_bad_arguments_raise_value_error_naming_them(what, call, name):
    v, f = icosphere(1)
    scene = prism.RayScene(v, f)
    o, d = rays(10, 10)
    with pytest.raises(ValueError, match=name):
        call(scene, v, f, o, d)
    # The scene still answers.
    assert scene.intersect(o, d)["t"].shape == (10,)


def long_query():
    """A scene and rays that take seconds to count: 3000 stacked squares,
    every ray through all of them."""
    n = 3000
    z = np.linspace(0, 1, n)
    quad = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], float)
    v = np.concatenate([np.column_stack([quad, np.full(4, zi)]) for zi in z])
    base = np.arange(n)[:, None] * 4
    f = np.concatenate([base + [0, 1, 2], base + [0, 2, 3]]).astype(np.int64)
    rng = np.random.default_rng(11)
    o = np.column_stack([rng.uniform(-0.9, 0.9, (1000000, 2)), np.full(1000000, -1.0)])
    d = np.tile([0.0, 0.0, 1.0], (1000000, 1))
    return prism.RayScene(v, f), o, d


def test_the_gil_is_released_during_a_query():
    scene, o, d = long_query()
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.005)

    ticker = threading.Thread(target=tick)
    start = time.perf_counter()
    ticker.start()
    counts = scene.count_intersections(o[:30000], d[:30000], threads=1)
    end = time.perf_counter()
    stop.set()
    ticker.join()
    assert (counts == 3000).all()
    during = [t for t in ticks if start < t < end]
    # At least one tick every 50 ms on average while the query ran.
    assert end - start > 0.1, "the query was too short to tell"
    assert len(during) >= (end - start) / 0.05, (len(during), end - start)


def test_ctrl_c_stops_a_long_query():
    scene, o, d = long_query()
    # Python's own Ctrl-C handler, which a process started in the
    # background without job control (SIGINT ignored) does not install,
    # and without which interrupt_main does nothing (as in test_prism).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.3, _thread.interrupt_main)
    start = time.perf_counter()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            scene.count_intersections(o, d, threads=1)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    elapsed = time.perf_counter() - start
    # The whole query takes far longer (about 3e9 triangle tests).
    assert elapsed < 3.0, elapsed
    small = scene.count_intersections(o[:10], d[:10])
    assert (small == 3000).all()
