"""Typed scene parts: built once at load from the validated tree, frozen, and what the library reads."""

from __future__ import annotations

import dataclasses
import pickle
from pathlib import Path

import numpy as np
import pytest

from nsfem import build_model, load_scene
from nsfem import mesh as nsmesh
from nsfem.fem.rotating import rotor_operators
from nsfem.integrate import ContactSystem
from nsfem.reduce import scene_reduction
from nsfem.scene import (SCHEMA, Damping, Initial, MeshOptions, Output, ReductionOptions, Rotation, Simulation,
                         scene_from_tree)
from nsfem.simulate import integrator_options
from nsfem.system import rotor_system, scene_system

#: attribute of the Scene, its table, its class
PARTS = [("rotation", "rotation", Rotation), ("damping", "damping", Damping), ("mesh_options", "mesh", MeshOptions),
         ("reduction", "reduction", ReductionOptions), ("initial", "initial", Initial),
         ("simulation", "simulation", Simulation), ("output", "output", Output)]

#: one override in every option table (lists, a path-free string, ints, floats)
OVERRIDES = ["title=\"parts\"", "rotation.speed_hz=12.5", "rotation.gravity=0", "rotation.phase_deg=30",
             "damping.rayleigh=[0.5, 1e-6]", "damping.external=2.0", "mesh.elements=24", "mesh.axial=\"P2\"",
             "reduction.method=modal", "reduction.modes=6", "initial.state=stationary",
             "initial.velocity=[0.0, 0.1, 0.0]", "simulation.method=rk", "simulation.t_end=0.5",
             "simulation.output_dt=0.01", "simulation.rtol=1e-6", "simulation.moreau_step=0.001",
             "output.dir=elsewhere", "output.vtu_every=0", "output.plots=[\"gap\"]"]


def assert_parts_match(scene) -> None:
    """Every part holds its table's values (lists as tuples, ``mesh.file`` resolved), key for key."""
    assert scene.title == scene["title"]
    for attr, table, cls in PARTS:
        part = getattr(scene, attr)
        assert type(part) is cls
        assert [f.name for f in dataclasses.fields(cls)] == list(SCHEMA[table]), "a part has a field per key"
        for key, value in scene[table].items():
            got = getattr(part, key)
            if table == "mesh" and key == "file":
                assert got == (scene.base / value if value else None)
            elif table == "output" and key == "dir":
                assert got == Path(value)
            elif isinstance(value, list):
                assert isinstance(got, tuple) and list(got) == value
            else:
                assert got == value and type(got) is type(value), (table, key)


def test_parts_match_the_defaults():
    scene = load_scene(None)
    assert_parts_match(scene)
    assert scene.rotation == Rotation(21.0, 9.81, 0.0, "rotating")
    assert scene.reduction == ReductionOptions("craig-bampton", 16)


def test_parts_match_the_overrides():
    scene = load_scene(None, OVERRIDES)
    assert_parts_match(scene)
    assert scene.title == "parts"
    assert scene.rotation == Rotation(12.5, 0.0, 30.0, "rotating")
    assert scene.damping == Damping((0.5, 1e-6), 2.0)
    assert scene.mesh_options == MeshOptions(24, None, "P2")
    assert scene.reduction == ReductionOptions("modal", 6)
    assert scene.initial == Initial("stationary", (0.0, 0.1, 0.0))
    assert (scene.simulation.method, scene.simulation.t_end, scene.simulation.rtol) == ("rk", 0.5, 1e-6)
    assert scene.output == Output(Path("elsewhere"), 0, ("gap",))


def test_parts_of_a_tree_without_option_tables_take_the_defaults():
    """A low-level tree: the option tables left out, their parts the schema's defaults."""
    tree = {"segment": [{"name": "s", "start": 0.0, "end": 1.0}],
            "support": [{"segment": "s", "x": 0.0, "fix": ["U", "V", "W", "V'", "W'"]}]}
    scene = scene_from_tree(tree)
    assert_parts_match(scene)
    assert scene.rotation.speed_hz == SCHEMA["rotation"]["speed_hz"].default


def test_mesh_file_is_resolved_against_the_scene_folder(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text("[mesh]\nelements = 20\n")
    generated = load_scene(path)
    nsmesh.write(tmp_path / "stack.msh", generated.stack, nsmesh.generate(generated.stack, 20))
    path.write_text('[mesh]\nelements = 20\nfile = "stack.msh"\n')
    scene = load_scene(path)
    assert scene["mesh"]["file"] == "stack.msh"
    assert scene.mesh_options.file == tmp_path / "stack.msh" == scene.mesh_file
    assert generated.mesh_options.file is None
    assert build_model(scene).n == build_model(generated).n


def test_parts_are_frozen():
    scene = load_scene(None)
    for attr, table, _ in PARTS:
        part = getattr(scene, attr)
        name = dataclasses.fields(part)[0].name
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(part, name, getattr(part, name))
        hash(part)  # frozen and of tuples: hashable


def test_parts_survive_pickling():
    """Sweeps send scenes to worker processes: the parts travel with the mapping."""
    scene = load_scene(None, OVERRIDES)
    back = pickle.loads(pickle.dumps(scene))
    assert dict(back) == dict(scene) and back.stack == scene.stack
    for attr, _, _ in PARTS:
        assert getattr(back, attr) == getattr(scene, attr)


def test_reduction_reads_its_part():
    """An override of reduction.modes reaches the reduced model through scene.reduction."""
    small = load_scene(None, ["mesh.elements=20", "reduction.modes=4"])
    large = load_scene(None, ["mesh.elements=20", "reduction.modes=10"])
    model = build_model(small)
    assert scene_reduction(small, model).ndof + 6 == scene_reduction(large, model).ndof
    # the part alone does the same as the scene
    assert scene_reduction(large.reduction, model).ndof == scene_reduction(large, model).ndof
    assert scene_reduction(ReductionOptions("modal", 3), model).ndof == 3
    assert ContactSystem.from_scene(large, model).n == scene_reduction(large, model).ndof


def test_assembly_reads_the_mesh_part():
    coarse = load_scene(None, ["mesh.elements=20"])
    fine = load_scene(None, ["mesh.elements=30", "mesh.axial=P2"])
    m20, m30 = build_model(coarse), build_model(fine)
    assert (m20.mesh.elements, m30.mesh.elements) == (20, 30)
    assert m30.axial == "P2" and m20.axial == "P1"


def test_system_reads_rotation_and_damping():
    scene = load_scene(None, ["mesh.elements=20", "rotation.speed_hz=7", "damping.external=3.0"])
    ops = rotor_operators(build_model(scene))
    lin = scene_system(scene, ops)
    assert lin.omega == pytest.approx(2 * np.pi * 7.0, rel=1e-15)
    again = rotor_system(ops, scene.rotation, scene.damping)
    for a, b in ((lin.M, again.M), (lin.Q, again.Q), (lin.C, again.C)):
        assert abs(a - b).max() == 0.0
    faster = rotor_system(ops, dataclasses.replace(scene.rotation, speed_hz=9.0), scene.damping)
    assert faster.omega == pytest.approx(2 * np.pi * 9.0, rel=1e-15)


def test_integrator_options_read_the_simulation_part():
    scene = load_scene(None, ["simulation.output_dt=0.002", "simulation.moreau_theta=0.75"])
    assert integrator_options(scene.simulation, "moreau") == {"step": 0.0002, "theta": 0.75}
    assert integrator_options(scene, "moreau") == integrator_options(scene.simulation, "moreau")
    assert integrator_options(scene.simulation, "exact") == {}
