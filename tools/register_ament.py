"""Register the ament package ``sim`` in the venv, as colcon would.

``ros2 run sim EXE`` (on a full ROS 2 install with this venv on ``AMENT_PREFIX_PATH``) finds the
package through ``<prefix>/share/ament_index/resource_index/packages/sim`` and runs
``<prefix>/lib/sim/EXE``. pip's editable install skips data files, so this writes those few
files: the index entry, ``share/sim/package.xml`` and one small wrapper per console script.

It also writes ``<venv>/setup.sh``, the venv's answer to a ROS workspace's ``setup.bash``: sourced
in a shell where a ROS 2 Jazzy ros2cli runs (on the same Python version as the venv), it puts the
package on the ament path and the project's interface packages on the Python and library paths.
"""

from __future__ import annotations

import pathlib
import shutil
import sys
import sysconfig
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGE = "sim"
# Python packages the set-up builds (tools/build_interfaces.py)
INTERFACE_PACKAGES = ("sim_interfaces", "simulation_interfaces", "tf2_msgs")

SETUP_SH = """\
# Source this file (`. {prefix}/setup.sh`) in a shell where a ROS 2 Jazzy ros2cli runs, as you
# would source a workspace's setup.bash. Written by tools/register_ament.py during the set-up.
# It puts the package `sim` on the ament path and the project's interface packages
# ({packages}) on the Python path, and {prefix}/lib on the library path: rosidl opens
# their type support libraries by searching LD_LIBRARY_PATH (required; a RUNPATH does not help there).
# The interface modules are built for Python {python}: run ros2cli on that version.
_sim_prefix="{prefix}"
export AMENT_PREFIX_PATH="$_sim_prefix${{AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}}"
export PYTHONPATH="$_sim_prefix/share/sim/python${{PYTHONPATH:+:$PYTHONPATH}}"
export LD_LIBRARY_PATH="${{LD_LIBRARY_PATH:+$LD_LIBRARY_PATH:}}$_sim_prefix/lib"
unset _sim_prefix
"""


def main() -> None:
    prefix = pathlib.Path(sys.prefix)
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    index = prefix / "share" / "ament_index" / "resource_index" / "packages"
    index.mkdir(parents=True, exist_ok=True)
    (index / PACKAGE).write_text("")
    share = prefix / "share" / PACKAGE
    share.mkdir(parents=True, exist_ok=True)
    shutil.copy(ROOT / "package.xml", share / "package.xml")
    lib = prefix / "lib" / PACKAGE
    if lib.exists():
        shutil.rmtree(lib)
    lib.mkdir(parents=True)
    for name in scripts:
        wrapper = lib / name
        wrapper.write_text(f'#!/bin/sh\nexec "{prefix / "bin" / name}" "$@"\n')
        wrapper.chmod(0o755)
    write_setup_script(prefix)
    print(f"registered ament package {PACKAGE!r} in {prefix} with executables: {', '.join(scripts)}")


def write_setup_script(prefix: pathlib.Path) -> None:
    """Write ``<prefix>/setup.sh`` and ``share/sim/python``: links to just the interface packages.

    Only those packages go on a ROS tool's ``PYTHONPATH``: the venv's whole site-packages would put a
    second rclpy, numpy and MuJoCo in front of the tool's own.
    """
    site = pathlib.Path(sysconfig.get_paths()["purelib"])
    python_dir = prefix / "share" / PACKAGE / "python"
    if python_dir.exists():
        shutil.rmtree(python_dir)
    python_dir.mkdir(parents=True)
    for name in INTERFACE_PACKAGES:
        if (site / name).is_dir():
            (python_dir / name).symlink_to(site / name, target_is_directory=True)
    python = f"{sys.version_info.major}.{sys.version_info.minor}"
    text = SETUP_SH.format(prefix=prefix, packages=", ".join(INTERFACE_PACKAGES), python=python)
    (prefix / "setup.sh").write_text(text)


if __name__ == "__main__":
    main()
