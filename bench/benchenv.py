"""Makes sure the benchmark scripts run inside bench/.venv with embreex and
numpy, creating it on first use (pip, from PyPI) and re-running the calling
script there."""

import os
import subprocess
import sys

BENCH = os.path.dirname(os.path.abspath(__file__))
VENV = os.path.join(BENCH, ".venv")
PYTHON = os.path.join(VENV, "bin", "python")


def ensure():
    """Call before importing embreex or numpy."""
    if os.path.realpath(sys.prefix) == os.path.realpath(VENV):
        return
    if not os.path.exists(PYTHON):
        print("creating bench/.venv with embreex and numpy ...", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "venv", VENV], check=True)
        subprocess.run([PYTHON, "-m", "pip", "install", "-q", "--disable-pip-version-check", "embreex", "numpy"],
                       check=True)
    os.execv(PYTHON, [PYTHON] + sys.argv)
