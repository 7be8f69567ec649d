"""Every entry point runs numpy's and scipy's OpenBLAS on one thread, whatever its imports load first.

The project's matrices are small (the whole-body QP's, the IK's): spread over two threads on a busy 2-core machine
a solve waits for a thread the scheduler gave to another process. A walk in the core took 11.5 s of wall time
instead of 4.9 with two other busy processes beside it, and the G1 fetches of the test suite 50-85 s instead of
13-17. ``robot_models`` set OPENBLAS_NUM_THREADS, but a process that loaded numpy before it kept two threads:
``arm_server`` (rclpy's messages first), ``sim-demo``, a program that imports ``sim_bridge`` first, and every test
module (numpy, mujoco first). Each package a program starts from now sets it first: an entry point's first import
is its top-level package, so checking each package checks every entry point.
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import tomllib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

# Imports the module, then numpy and scipy's LAPACK (as the whole-body QP does), and prints each loaded
# OpenBLAS's thread count.
PROBE = """
import ctypes, importlib, json, sys
importlib.import_module(sys.argv[1])
import numpy, scipy.linalg
counts = []
for path in sorted({line.split()[-1] for line in open("/proc/self/maps") if "openblas" in line.lower()}):
    library = ctypes.CDLL(path)
    get = getattr(library, "scipy_openblas_get_num_threads64_", None) or getattr(library, "scipy_openblas_get_num_threads")
    counts.append(get())
print(json.dumps(counts))
"""


def _entry_packages() -> list[str]:
    """The top-level packages of the console scripts, and the core's (a user's program may start from either)."""
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    return sorted({target.split(".")[0] for target in scripts.values()} | {"sim_bridge", "robot_models"})


@pytest.mark.parametrize("module", _entry_packages())
def test_an_entry_point_runs_openblas_on_one_thread(module: str) -> None:
    env = {key: value for key, value in os.environ.items() if key != "OPENBLAS_NUM_THREADS"}  # a plain shell's
    done = subprocess.run([sys.executable, "-c", PROBE, module], capture_output=True, text=True, cwd=ROOT, env=env,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    counts = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(counts) == 2, f"numpy's and scipy's OpenBLAS expected loaded, found {counts}"
    assert counts == [1, 1], f"{module}: OpenBLAS threads {counts}"
