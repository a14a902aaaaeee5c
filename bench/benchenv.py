"""Makes sure the benchmark scripts run inside bench/.venv with embreex and
numpy, creating it on first use (pip, from PyPI) and re-running the calling
script there."""

import os
import subprocess
import sys

BENCH = os.path.dirname(os.path.abspath(__file__))
VENV = os.path.join(BENCH, ".venv")
PYTHON = os.path.join(VENV, "bin", "python")


def ensure(extra=()):
    """Call before importing embreex or numpy. `extra`: further PyPI
    packages the caller needs, installed into the venv when missing."""
    if os.path.realpath(sys.prefix) == os.path.realpath(VENV):
        from importlib import metadata
        missing = []
        for name in extra:
            try:
                metadata.version(name)
            except metadata.PackageNotFoundError:
                missing.append(name)
        if missing:
            print(f"adding {', '.join(missing)} to bench/.venv ...", file=sys.stderr)
            subprocess.run([PYTHON, "-m", "pip", "install", "-q", "--disable-pip-version-check", *missing],
                           check=True)
        return
    if not os.path.exists(PYTHON):
        print("creating bench/.venv with embreex and numpy ...", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "venv", VENV], check=True)
        subprocess.run([PYTHON, "-m", "pip", "install", "-q", "--disable-pip-version-check", "embreex", "numpy"],
                       check=True)
    os.execv(PYTHON, [PYTHON] + sys.argv)
