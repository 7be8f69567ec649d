"""Compiled models kept on disk: the G1 with its meshes compiles in ~0.6 s and loads from its ``.mjb`` in ~0.1 s.

Most of a mesh model's compile is building its meshes' convex hulls and bounding volume trees, the same at
every start of ``/sim`` (and of every test that loads the robot). A compiled model is saved once
(``mj_saveModel``) under a key of everything it was compiled from: MuJoCo's version, every attribute of
every element of the spec (bodies, joints, geoms, actuators, sensors, keyframes, meshes, materials, the
options and compiler flags: :func:`spec_fingerprint`, ~40 ms for the G1) and the size and modification
time of each mesh file it reads. Any change to one of them is another key, so a stale model is never
loaded; the least recently used files beyond :data:`KEEP_FILES` are removed. (``MjSpec.to_xml`` would
describe the spec too, but it compiles it first: as slow as what the cache saves.)

``SIM_MODEL_CACHE`` names the folder (default ``$XDG_CACHE_HOME/sim/models``, else ``~/.cache/sim/models``);
``SIM_MODEL_CACHE=off`` compiles every time. A folder that cannot be written costs nothing but the speed.
"""

from __future__ import annotations

import hashlib
import os
import pathlib

import mujoco
import numpy as np

CACHE_VARIABLE = "SIM_MODEL_CACHE"
KEEP_FILES = 12  # the G1 with meshes is ~85 MB on disk: at most ~1 GB


def cache_folder() -> pathlib.Path | None:
    """Where compiled models are kept, or None when caching is off."""
    value = os.environ.get(CACHE_VARIABLE, "")
    if value.lower() in ("off", "0", "no", "false"):
        return None
    if value:
        return pathlib.Path(value).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or str(pathlib.Path.home() / ".cache")
    return pathlib.Path(base) / "sim" / "models"


# The spec's element lists and single settings (MuJoCo 3.3-4.0's MjSpec). An element's own attributes are read
# generically: whatever MuJoCo adds to an element is in the key without a change here.
_ELEMENT_LISTS = ("bodies", "frames", "joints", "geoms", "sites", "cameras", "lights", "actuators", "sensors", "tendons",
                  "equalities", "excludes", "pairs", "keys", "meshes", "materials", "textures", "hfields", "skins",
                  "numerics", "texts", "tuples", "flexes")
_SETTINGS = ("option", "compiler", "visual", "stat")
_BY_NAME = frozenset(("parent", "frame"))  # the element it hangs from: its name (the element is hashed in its list)
# Not read: an element's id and signature (bookkeeping), info (a source line), default (its values are the
# element's own), and plugin and compiler, whose reading crashed MuJoCo 4.0 (the spec's compiler flags are read).
_SKIPPED = frozenset(("id", "signature", "info", "default", "plugin", "compiler"))


def _feed(digest: hashlib._Hash, element: object, nested: bool = False) -> None:
    """Every plain attribute of an element (numbers, text, arrays; other elements by their names) into ``digest``."""
    for name in dir(element):
        if name.startswith("_") or name in _SKIPPED:
            continue
        try:
            value = getattr(element, name)
        except Exception:  # noqa: BLE001  (an attribute that cannot be read here is not one the compile uses)
            continue
        if callable(value):
            continue
        if value is None or isinstance(value, (bool, int, float, str, bytes)):
            digest.update(f"{name}={value!r};".encode())
        elif isinstance(value, np.ndarray):
            digest.update(f"{name}{value.dtype}{value.shape}=".encode() + np.ascontiguousarray(value).tobytes())
        elif isinstance(value, (list, tuple)):
            items = [item if isinstance(item, (bool, int, float, str)) else (type(item).__name__, getattr(item, "name", None))
                     for item in value]
            digest.update(f"{name}={items!r};".encode())
        elif name in _BY_NAME:
            digest.update(f"{name}={type(value).__name__}:{getattr(value, 'name', None)!r};".encode())
        elif not nested:  # e.g. a geom's alternative orientation
            digest.update(f"{name}:".encode())
            _feed(digest, value, nested=True)


def spec_fingerprint(spec: mujoco.MjSpec) -> str:
    """A digest of what compiling ``spec`` depends on: the MuJoCo version, its elements, its mesh files' stats."""
    digest = hashlib.sha256(mujoco.__version__.encode())
    for setting in _SETTINGS:
        digest.update(setting.encode())
        _feed(digest, getattr(spec, setting))
    for kind in _ELEMENT_LISTS:
        for element in getattr(spec, kind):
            digest.update(kind.encode())
            _feed(digest, element)
    for mesh in spec.meshes:
        path = pathlib.Path(mesh.file)
        if not path.is_absolute():
            path = pathlib.Path(spec.modelfiledir or ".") / (spec.meshdir or "") / path
        try:
            stat = path.stat()
            digest.update(f"{path}:{stat.st_size}:{stat.st_mtime_ns};".encode())
        except OSError:
            digest.update(f"{path}:unreadable;".encode())  # the compile says why
    return digest.hexdigest()[:32]


def compile_cached(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """``spec.compile()``, or the model compiled from an identical spec before (read from the cache).

    Worth it for models with meshes to process (the key costs ~40 ms for the G1); a model without them
    compiles faster than that.
    """
    folder = cache_folder()
    if folder is None:
        return spec.compile()
    path = folder / f"{spec_fingerprint(spec)}.mjb"
    if path.is_file():
        try:
            model = mujoco.MjModel.from_binary_path(str(path))
            os.utime(path)  # recently used: kept by the pruning
            return model
        except (OSError, ValueError):  # a file cut short or from elsewhere: compiled and written again
            pass
    model = spec.compile()
    _save(model, folder, path)
    return model


def _save(model: mujoco.MjModel, folder: pathlib.Path, path: pathlib.Path) -> None:
    """Write the model atomically (processes compiling the same model at once each write a whole file), then prune."""
    partial = path.with_name(f"{path.stem}.{os.getpid()}.partial")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        mujoco.mj_saveModel(model, str(partial), None)
        os.replace(partial, path)
        kept = sorted(folder.glob("*.mjb"), key=lambda file: file.stat().st_mtime, reverse=True)
        for old in kept[KEEP_FILES:]:
            old.unlink(missing_ok=True)
    except OSError:
        partial.unlink(missing_ok=True)
