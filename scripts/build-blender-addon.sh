#!/bin/bash
# The Blender add-on as an installable zip: target/prism_render.zip, holding
# the folder prism_render/ (Edit > Preferences > Add-ons > Install...).
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p target
python3 - <<'PY'
import pathlib, zipfile
src = pathlib.Path("blender/prism_render")
with zipfile.ZipFile("target/prism_render.zip", "w", zipfile.ZIP_DEFLATED) as z:
    for f in sorted(src.rglob("*.py")):
        if "__pycache__" not in f.parts:
            z.write(f, f.relative_to(src.parent))
PY
echo "target/prism_render.zip"
