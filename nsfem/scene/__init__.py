"""Scene files (TOML): defaults, ``--set`` overrides, validation, translation to a BeamStack.

A scene is read, overridden, checked against :data:`SCHEMA` (unknown keys, types,
ranges, NaN/inf) and cross-checked (delaminations inside the shaft, contact points
inside their delamination, ...) before anything is computed. The high-level tables
(``[shaft]``, ``[[delamination]]``, ``[[obstacle]]``) are translated into the
low-level :class:`~nsfem.stack.BeamStack`; a scene may also give the low-level
``[[segment]]``, ``[[junction]]``, ``[[support]]`` and ``[[contact]]`` tables directly.

The package splits these jobs: :mod:`~nsfem.scene.schema` (the keys, their defaults and value
checks), :mod:`~nsfem.scene.validate` (a raw tree against the schema), :mod:`~nsfem.scene.overrides`
(``--set``), :mod:`~nsfem.scene.translate` (tables to a BeamStack), :mod:`~nsfem.scene.checks`
(cross-checks of the translated scene), :mod:`~nsfem.scene.parts` (the option tables as typed
parts), :mod:`~nsfem.scene.notes` (one line per default that shapes a rotor's model unsaid),
:mod:`~nsfem.scene.load` (the :class:`Scene`) and :mod:`~nsfem.scene.reference` (``docs/scene.md``).

>>> scene = load_scene(None, ["delamination.0.friction=0.3", "mesh.elements=20"])
>>> scene["delamination"][0]["friction"], scene["mesh"]["elements"]
(0.3, 20)
>>> [s.name for s in scene.stack.segments]
['intact_0', 'delamination_0_upper', 'delamination_0_lower', 'intact_1']
>>> len(scene.stack.contacts)
9
"""

from ..errors import SceneError
from .checks import (COMPONENT_RANGE, check_components, check_frame, check_frame_at_speed, check_mesh, check_scales,
                     check_speed, check_times, speed_limit_hz)
from .load import Scene, default_scene_path, load_scene, scene_file, scene_from_tree, shipped_scenes
from .notes import scene_notes
from .overrides import apply_override, nesting_depth, parse_value
from .parts import Damping, Initial, MeshOptions, Output, ReductionOptions, Rotation, Simulation
from .reference import scene_reference
from .schema import (AXES, AXIAL, FRAMES, HIGH_LEVEL, INITIAL_STATES, LCP_BYTES_PER_ENTRY, LOW_LEVEL, MATERIAL_RANGE,
                     MAX_CONTACT_POINTS, MAX_ELEMENTS, MAX_FRICTION_DIRECTIONS, MAX_NESTING, METHODS, MIN_LAYER,
                     MIN_SPACING, PATH_KEYS, PLOTS, REDUCTIONS, RK_SOLVERS, SCHEMA, STIFF_SOLVERS, SUPPORT_DOFS_BY_NAME,
                     SUPPORTS, Key)
from .translate import (contact_positions, disk_inertia, high_level_stack, low_level_stack, point_components, section,
                        stator_contacts)
from .validate import defaults, implied_defaults, section_of, validate_tree

__all__ = [
    "AXES", "AXIAL", "COMPONENT_RANGE", "FRAMES", "HIGH_LEVEL", "INITIAL_STATES", "LCP_BYTES_PER_ENTRY", "LOW_LEVEL",
    "MATERIAL_RANGE", "MAX_CONTACT_POINTS", "MAX_ELEMENTS", "MAX_FRICTION_DIRECTIONS", "MAX_NESTING", "METHODS",
    "MIN_LAYER", "MIN_SPACING", "PATH_KEYS", "PLOTS", "REDUCTIONS", "RK_SOLVERS", "SCHEMA", "STIFF_SOLVERS",
    "SUPPORTS", "SUPPORT_DOFS_BY_NAME", "Damping", "Initial", "Key", "MeshOptions", "Output", "ReductionOptions",
    "Rotation", "Scene", "SceneError", "Simulation", "apply_override", "check_components", "check_frame",
    "check_frame_at_speed", "check_mesh", "check_scales", "check_speed", "check_times", "contact_positions",
    "default_scene_path", "defaults", "disk_inertia", "high_level_stack", "load_scene", "low_level_stack",
    "implied_defaults", "nesting_depth", "parse_value", "point_components", "scene_file", "scene_from_tree",
    "scene_notes", "scene_reference", "section", "section_of", "shipped_scenes", "speed_limit_hz", "stator_contacts",
    "validate_tree",
]
