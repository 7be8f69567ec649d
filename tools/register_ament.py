"""Register the ament package ``sim`` in the venv, as colcon would.

``ros2 run sim EXE`` (on a full ROS 2 install with this venv on ``AMENT_PREFIX_PATH``) finds the
package through ``<prefix>/share/ament_index/resource_index/packages/sim`` and runs
``<prefix>/lib/sim/EXE``. pip's editable install skips data files, so this writes those few
files: the index entry, ``share/sim/package.xml`` and one small wrapper per console script.
"""

from __future__ import annotations

import pathlib
import shutil
import sys
import tomllib

ROOT = pathlib.Path(__file__).resolve().parent.parent
PACKAGE = "sim"


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
    print(f"registered ament package {PACKAGE!r} in {prefix} with executables: {', '.join(scripts)}")


if __name__ == "__main__":
    main()
