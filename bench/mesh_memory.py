#!/usr/bin/env python3
"""Load + build memory of a million-triangle mesh (issue 16's second goal).

Writes bench/meshes.py's 999,698-triangle terrain (binary PLY) and a scene
placing it, then runs `prism check` on it under GNU time three times and
prints the peak resident memory, in MB (GNU time's kilobytes / 1000) and in
bytes per triangle (goal: at most 150), and the mesh's steady memory from
examples/meshbench (`Mesh::memory_bytes`; goal: at most 66 bytes per
triangle).

Set-up: none beyond bench/meshes.py's (bench/.venv, made on first run) and
GNU time (bench/setup.sh installs it).
Usage: python3 bench/mesh_memory.py
"""

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import meshes  # noqa: E402  (re-runs this script inside bench/.venv)

ROOT = meshes.ROOT


def main():
    if not os.path.exists("/usr/bin/time"):
        subprocess.run([os.path.join(ROOT, "bench", "setup.sh")], check=True)
    os.makedirs(meshes.DATA, exist_ok=True)
    ply = meshes.terrain()
    subprocess.run(["cargo", "build", "--release", "--quiet", "--example", "meshbench"], cwd=ROOT, check=True)
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    prism = os.path.join(ROOT, "target", "release", "prism")
    with tempfile.TemporaryDirectory() as work:
        shutil.copy(ply, os.path.join(work, "terrain.ply"))
        scene = os.path.join(work, "terrain.toml")
        with open(scene, "w") as f:
            f.write('[render]\nwidth = 64\nheight = 64\n\n[camera]\nposition = [0, 3, 3]\nlook_at = [0, 0, 0]\n'
                    'fov = 40\n\n[lights.sun]\ntype = "point"\nposition = [0, 8, 0]\n\n'
                    '[[objects]]\ntype = "mesh"\nfile = "terrain.ply"\n')
        peaks = []
        for _ in range(3):
            out = subprocess.run(["/usr/bin/time", "-f", "PEAK %M", prism, "check", scene],
                                 capture_output=True, text=True, check=True)
            peaks.append(int(re.findall(r"PEAK (\d+)", out.stderr)[-1]) / 1000)
        bench = json.loads(subprocess.run(
            [os.path.join(ROOT, "target", "release", "examples", "meshbench"), ply, work, "4096"],
            capture_output=True, text=True, check=True).stdout)
    triangles = bench["triangles"]
    per = [p * 1e6 / triangles for p in peaks]
    print(f"terrain: {triangles} triangles")
    print(f"load + build peak (prism check): {min(peaks):.1f}–{max(peaks):.1f} MB, "
          f"{min(per):.0f}–{max(per):.0f} bytes per triangle (goal ≤ 150)")
    print(f"steady (Mesh::memory_bytes): {bench['mesh_mb']:.1f} MB, "
          f"{bench['mesh_mb'] * 1e6 / triangles:.0f} bytes per triangle (goal ≤ 66)")


if __name__ == "__main__":
    main()
