"""Build the ROS 2 interface packages in ``interfaces/`` into the active venv.

Usage: ``.venv/bin/python tools/build_interfaces.py``. Idempotent (CMake rebuilds what changed).

Two fixes are needed before the wheels' CMake files can build anything (see the project notes):
1. their exported CMake files name the build farm's Python include and numpy include paths;
   these are rewritten to this interpreter's paths;
2. the generators run with this venv's Python, so the build runs with the wheels' start-up hook
   marked as done and ``LD_LIBRARY_PATH`` already set, so nothing re-executes mid-build.

The installed libraries carry a RUNPATH to ``<venv>/lib``, so the libraries they link to are found
without help; ``<venv>/setup.sh`` (tools/register_ament.py) adds the library path rosidl searches.

Only what Python loads is built: rosidl's C code, the C type supports (the dispatch, Fast DDS's and the
introspection one) and the Python bindings. The C++ generators are skipped (``SIM_SKIP_GENERATORS``;
rclpy on rmw_fastrtps_cpp and ros2cli never load them). The three packages depend on none of each
other, so they build at the same time, with Ninja (from requirements.txt).
"""

from __future__ import annotations

import glob
import os
import pathlib
import shutil
import subprocess
import sys
import sysconfig
from concurrent.futures import ThreadPoolExecutor

import numpy

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGES = ("simulation_interfaces", "sim_interfaces", "tf2_msgs")  # independent of each other; largest first
# rosidl generators for C++ users only: their headers, type support dispatch, Fast DDS and introspection code.
SKIPPED_GENERATORS = (
    "rosidl_generator_cpp", "rosidl_typesupport_cpp",
    "rosidl_typesupport_fastrtps_cpp", "rosidl_typesupport_introspection_cpp",
)
GENERATOR = "Ninja"
FARM_PYTHON_INCLUDE = "/opt/python/cp311-cp311/include/python3.11"
FARM_NUMPY_INCLUDE = "/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include"


def venv_prefix() -> pathlib.Path:
    return pathlib.Path(sys.prefix)


def fix_exported_cmake_paths(prefix: pathlib.Path) -> int:
    """Point the wheels' CMake files at this interpreter's include directories. Returns files changed."""
    replacements = {
        FARM_PYTHON_INCLUDE: sysconfig.get_paths()["include"],
        FARM_NUMPY_INCLUDE: numpy.get_include(),
    }
    changed = 0
    for path in glob.glob(str(prefix / "share" / "*" / "cmake" / "*.cmake")):
        text = pathlib.Path(path).read_text()
        new = text
        for old, replacement in replacements.items():
            new = new.replace(old, replacement)
        if new != text:
            pathlib.Path(path).write_text(new)
            changed += 1
    return changed


def build_environment(prefix: pathlib.Path) -> dict[str, str]:
    site = pathlib.Path(sysconfig.get_paths()["purelib"])
    libs = [str(prefix / "lib"), *sorted(glob.glob(str(site / "ros_*.libs")))]
    env = dict(os.environ)
    env["LD_LIBRARY_PATH"] = os.pathsep.join([*libs, env.get("LD_LIBRARY_PATH", "")]).rstrip(os.pathsep)
    env["_ROS_WHEELS_BOOTSTRAP_COMPLETE"] = "1"
    env["AMENT_PREFIX_PATH"] = str(prefix)
    env["CMAKE_PREFIX_PATH"] = str(prefix)
    env["PATH"] = f"{prefix / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    return env


def build_package(name: str, prefix: pathlib.Path, env: dict[str, str]) -> str:
    """Configure, build and install one package; returns its name. Raises SystemExit with CMake's output."""
    source = ROOT / "interfaces" / name
    build = ROOT / "build" / name
    cache = build / "CMakeCache.txt"
    if cache.exists() and f"CMAKE_GENERATOR:INTERNAL={GENERATOR}\n" not in cache.read_text():
        shutil.rmtree(build)  # configured by an earlier set-up with another generator: CMake refuses to switch
    build.mkdir(parents=True, exist_ok=True)
    configure = [
        "cmake", "-G", GENERATOR, "-S", str(source), "-B", str(build),
        f"-DCMAKE_PREFIX_PATH={prefix}", f"-DCMAKE_INSTALL_PREFIX={prefix}",
        f"-DPython3_EXECUTABLE={prefix / 'bin' / 'python'}", "-DBUILD_TESTING=OFF",
        "-DCMAKE_BUILD_TYPE=Release", "-Wno-dev", f"-DSIM_SKIP_GENERATORS={';'.join(SKIPPED_GENERATORS)}",
        # Every installed library and Python extension finds the generated libraries it links to in
        # <prefix>/lib by itself (RUNPATH). The type support libraries rosidl opens at run time are
        # searched on LD_LIBRARY_PATH only: <venv>/setup.sh exports it for tools of other set-ups.
        f"-DCMAKE_INSTALL_RPATH={prefix / 'lib'}",
    ]
    # Each build may use every core: the packages' serial steps (configure, the generators) leave them idle.
    jobs = str(os.cpu_count() or 2)
    for command in (configure, ["cmake", "--build", str(build), "-j", jobs], ["cmake", "--install", str(build)]):
        result = subprocess.run(command, env=env, cwd=build, capture_output=True, text=True)
        if result.returncode != 0:
            sys.stderr.write(result.stdout[-4000:] + result.stderr[-4000:])
            raise SystemExit(f"building interface package {name} failed: {' '.join(command[:2])}")
    return name


def main() -> None:
    prefix = venv_prefix()
    if prefix == pathlib.Path(sys.base_prefix):
        raise SystemExit("run this with the project's venv Python (.venv/bin/python)")
    fix_exported_cmake_paths(prefix)
    env = build_environment(prefix)
    with ThreadPoolExecutor(max_workers=len(PACKAGES)) as pool:
        futures = [pool.submit(build_package, name, prefix, env) for name in PACKAGES]
        for future in futures:
            print(f"built and installed interface package {future.result()} into {prefix}")


if __name__ == "__main__":
    main()
