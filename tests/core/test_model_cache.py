"""Compiled models kept on disk: the model read back is the model compiled, and any change to the spec is a new key."""

from __future__ import annotations

import pathlib

import mujoco
import numpy as np
import pytest

from robot_models import g1
from robot_models.g1_tables import add_tables_and_objects
from robot_models.model_cache import CACHE_VARIABLE, compile_cached, spec_fingerprint


def _model_bytes(model: mujoco.MjModel) -> bytes:
    buffer = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


@pytest.fixture(scope="module")
def spec() -> mujoco.MjSpec:
    built = g1.build_spec()
    add_tables_and_objects(built)
    return built


def test_a_model_read_from_the_cache_is_the_model_compiled(spec, tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_VARIABLE, str(tmp_path))
    compiled = compile_cached(spec.copy())  # compiled and written
    files = list(tmp_path.glob("*.mjb"))
    assert len(files) == 1 and files[0].stat().st_size > 10_000_000  # the G1's meshes and their trees
    read = compile_cached(spec.copy())
    assert read is not compiled
    assert _model_bytes(read) == _model_bytes(compiled) == _model_bytes(spec.copy().compile())
    assert read.nmesh > 0 and read.nq == compiled.nq


def test_any_change_that_the_compile_reads_is_another_key(spec):
    key = spec_fingerprint(spec)
    assert spec_fingerprint(spec.copy()) == key  # a copy is the same spec

    def changed(edit) -> str:
        copy = spec.copy()
        edit(copy)
        return spec_fingerprint(copy)

    visual_geom = next(i for i, geom in enumerate(spec.geoms) if geom.contype == 0 and geom.conaffinity == 0)
    edits = {
        "a body's mass": lambda s: setattr(s.bodies[3], "mass", s.bodies[3].mass + 0.01),
        "a geom's friction": lambda s: setattr(s.geoms[5], "friction", [0.55, 0.005, 0.0001]),
        "a visual mesh made to collide": lambda s: setattr(s.geoms[visual_geom], "contype", 1),
        "a geom's colour": lambda s: setattr(s.geoms[visual_geom], "rgba", [1.0, 0.0, 0.0, 1.0]),
        "the physics step": lambda s: setattr(s.option, "timestep", 0.001),
        "visual-only geoms dropped": lambda s: setattr(s.compiler, "discardvisual", True),
        "a joint's range": lambda s: setattr(s.joints[2], "range", [-0.1, 0.1]),
        "a new keyframe": lambda s: s.add_key(name="another", time=1.0),
        "a mesh's scale": lambda s: setattr(s.meshes[0], "scale", [1.01, 1.0, 1.0]),
        "a body moved": lambda s: setattr(s.bodies[4], "pos", np.add(s.bodies[4].pos, (0.0, 0.0, 0.001))),
    }
    keys = {what: changed(edit) for what, edit in edits.items()}
    assert all(other != key for other in keys.values()), [what for what, other in keys.items() if other == key]
    assert len(set(keys.values())) == len(keys)


def test_a_damaged_file_is_compiled_again_and_caching_can_be_turned_off(spec, tmp_path, monkeypatch):
    monkeypatch.setenv(CACHE_VARIABLE, str(tmp_path))
    path = pathlib.Path(tmp_path) / f"{spec_fingerprint(spec)}.mjb"
    path.write_bytes(b"not a model")
    model = compile_cached(spec.copy())
    assert model.nmesh > 0 and path.stat().st_size > 10_000_000  # written again, whole
    monkeypatch.setenv(CACHE_VARIABLE, "off")
    path.unlink()
    assert compile_cached(spec.copy()).nmesh == model.nmesh
    assert not list(tmp_path.glob("*.mjb"))
