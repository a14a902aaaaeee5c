#!/usr/bin/env python3
"""What a scattered ray's unpredictable branches cost, Prism against embreex
(Embree 4), on the Stanford bunny of bench/rayqueries.py.

The same nearest-hit query of 1M rays, on one thread, made of the bench's
scattered rays that hit the bunny, taken in pairs, each pair repeated R
times in a row (a b a b ..., R = 1, 2, 4, 16, 64). A pair traced again
takes the same paths: the CPU's branch predictor learns them after a few
repeats, and the rays' nodes and triangles are in the L1 cache from their
second trace. So where a row's time falls as R grows, the fall is what the
branches the predictor had not learnt (and, at R = 1, lines not yet in L1)
cost the engine. This machine (a VM) exposes no counters of mispredicted
branches; this comparison stands in for them.

Pairs, not one ray repeated: eight copies of one ray in a row are a group
Prism's query traces as one packet (`coherent` in src/query/trace.rs),
which would time its packets rather than its single-ray search. The two
rays of a pair are more than 8 degrees apart, so no group of eight is
coherent; the script checks that and stops otherwise.

Rounds alternate the engines; the table gives the range over the rounds of
the CPU time per 1M rays and Prism's rate over Embree's.

Usage: python3 bench/predictability.py [--rounds N] [--no-install]
"""

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import rayqueries  # noqa: E402  (its set-up: the bench venv, numpy)

np = rayqueries.np
REPEATS = (1, 2, 4, 16, 64)
RAYS = 1_000_000


def cosine(a, b):
    """The cosine of the angle between directions a and b, row by row."""
    dot = (a * b).sum(axis=-1)
    return dot / np.sqrt((a * a).sum(axis=-1) * (b * b).sum(axis=-1))


def cpu_ms(query):
    start = time.process_time()
    query()
    return 1e3 * (time.process_time() - start)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--no-install", action="store_true")
    args = parser.parse_args()
    if not args.no_install:
        rayqueries.install_prism()
    import prism
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    import meshes  # bench/meshes.py: fetches the bunny
    os.makedirs(meshes.DATA, exist_ok=True)
    v, f = rayqueries.read_ply(meshes.bunny())
    # The bench's scattered rays of the bunny (its mesh index, 0, seeds them).
    o, d = rayqueries.random_rays(v, RAYS, 0)
    scene = prism.RayScene(v.astype(np.float64), f.astype(np.int64))
    embree = rtcs.EmbreeScene()
    TriangleMesh(embree, v.astype(np.float32), f.astype(np.int32))
    hits = np.nonzero(scene.intersect(o, d, threads=1)["triangle_id"] >= 0)[0]
    pairs = hits[: len(hits) // 2 * 2].reshape(-1, 2)
    pairs = pairs[cosine(d[pairs[:, 0]], d[pairs[:, 1]]) < 0.99]
    print(f"bunny: {len(hits):,} of {RAYS:,} scattered rays hit; "
          f"each query {RAYS:,} of those, in {len(pairs):,} pairs")
    sets = {}
    for r in REPEATS:
        # Each pair r times in a row (a b a b ...), RAYS in all.
        idx = np.resize(np.tile(pairs, (1, r)).reshape(-1), RAYS)
        groups = idx[: RAYS // 8 * 8].reshape(-1, 8)
        # Prism's query tests groups of eight from every multiple of 8.
        if (cosine(d[groups], d[groups[:, :1]]) >= 0.99).all(axis=1).any():
            sys.exit(f"{r}x: a group of eight rays would be traced as a packet")
        sets[r] = (np.ascontiguousarray(o[idx]), np.ascontiguousarray(d[idx]))
    engines = {
        "prism": lambda rays: scene.intersect(*rays, threads=1),
        "embree": lambda rays: embree.run(*rays, output=1),
    }
    times = {(e, r): [] for e in engines for r in REPEATS}
    for e in engines:  # untimed warm-up: answers' memory, code
        for r in REPEATS:
            engines[e](sets[r])
    for _ in range(args.rounds):
        for r in REPEATS:
            for e, query in engines.items():
                times[(e, r)].append(cpu_ms(lambda: query(sets[r])))
    print("| each pair in a row | Prism ms per 1M | Embree ms per 1M | Prism/Embree |")
    print("|---|---|---|---|")
    for r in REPEATS:
        p, e = times[("prism", r)], times[("embree", r)]
        ratio = [b / a for a, b in zip(p, e)]
        print(f"| {r}x | {min(p):.1f}-{max(p):.1f} | {min(e):.1f}-{max(e):.1f} "
              f"| {min(ratio):.2f}-{max(ratio):.2f}x |")


if __name__ == "__main__":
    main()
