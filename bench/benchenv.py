"""Makes sure the benchmark scripts run inside bench/.venv with embreex and
numpy, creating it on first use (pip, from PyPI) and re-running the calling
script there."""

import ctypes.util
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


def ensure_library(library, package):
    """Installs Debian's `package` when the shared library `library` (as
    ctypes names it: "usb-1.0") is missing: a wheel's system dependency,
    such as Open3D's libusb, which pip cannot install."""
    if ctypes.util.find_library(library):
        return
    print(f"installing {package} (for lib{library}) ...", file=sys.stderr)
    sudo = [] if os.geteuid() == 0 else ["sudo"]
    env = dict(os.environ, DEBIAN_FRONTEND="noninteractive")
    subprocess.run(sudo + ["apt-get", "update", "-qq"], check=True, env=env)
    subprocess.run(sudo + ["apt-get", "install", "-y", "-qq", package], check=True, env=env,
                   stdout=subprocess.DEVNULL)
