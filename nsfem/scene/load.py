"""Loading a scene: the file, its overrides, validation, translation and checks, into a :class:`Scene`."""

from __future__ import annotations

import copy
import tomllib
from importlib import resources
from pathlib import Path
from typing import Iterable

from ..errors import SceneError
from ..stack import BeamStack
from .checks import check_components, check_frame, check_mesh, check_scales, check_speed, check_times
from .cracks import crack_stack
from .notes import scene_notes
from .overrides import _check_nesting, apply_override
from .parts import Damping, Initial, MeshOptions, Output, ReductionOptions, Rotation, Simulation, parts
from .schema import HIGH_LEVEL, LOW_LEVEL, MAX_NESTING
from .translate import _check_section_keys, high_level_stack, low_level_stack, point_components
from .validate import implied_defaults, validate_tree


class Scene(dict):
    """A validated scene: the full key tree (with defaults) plus its typed parts.

    The mapping is the scene as its file and overrides give it, every default filled in (what a
    results file records and ``--set`` addresses). The parts are built from it once, here, and are
    what the library reads: ``stack`` (the low-level :class:`~nsfem.stack.BeamStack`), ``sensors``,
    ``title``, ``rotation``, ``damping``, ``mesh_options``, ``reduction``, ``initial``, ``simulation``
    and ``output`` (:mod:`nsfem.scene.parts`). Like the stack, they do not follow later changes to
    the mapping: load the scene again with overrides instead.

    ``scene.path`` is the file it came from (None for the shipped default), ``scene.base``
    the directory relative paths in it refer to. ``scene.notes``: one line for each default that shapes
    the model without the scene saying so (:mod:`nsfem.scene.notes`; empty for a scene that states it).
    ``scene.plots_listed``: the scene (or an override) gave ``output.plots`` (False: the default list).
    """

    title: str
    rotation: Rotation
    damping: Damping
    mesh_options: MeshOptions
    reduction: ReductionOptions
    initial: Initial
    simulation: Simulation
    output: Output

    def __init__(self, tree: dict, stack: BeamStack, path: Path | None, base: Path, sensors: tuple = (),
                 notes: tuple[str, ...] = (), plots_listed: bool = True):
        super().__init__(tree)
        self.stack = stack
        self.path = path
        self.base = base
        self.sensors = sensors
        self.notes = notes
        self.plots_listed = plots_listed
        for name, part in parts(tree, base).items():
            setattr(self, name, part)

    @property
    def mesh_file(self) -> Path | None:
        """The mesh file, resolved against :attr:`base` (None: the mesh is generated)."""
        return self.mesh_options.file

    def record(self) -> dict:
        """The validated tree as a results file stores it: ``mesh.file`` resolved to the absolute
        path this scene read (a relative one means nothing to a later ``export`` run from another
        folder), and its SHA-256 under ``mesh.sha256`` so that a changed mesh is noticed."""
        tree = copy.deepcopy(dict(self))
        if self.mesh_file is not None:
            import hashlib

            path = self.mesh_file.resolve()
            tree["mesh"]["file"] = str(path)
            tree["mesh"]["sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
        return tree


def default_scene_path() -> Path:
    """Path of the scene shipped with the package (the paper's delaminated shaft)."""
    return Path(str(resources.files("nsfem.scenes").joinpath("default.toml")))


def shipped_scenes() -> dict[str, Path]:
    """The scenes shipped in the package, by name (``nsfem run ross_example``)."""
    root = resources.files("nsfem.scenes")
    return {Path(str(f)).stem: Path(str(f)) for f in root.iterdir() if str(f).endswith(".toml")}


def scene_file(path: str | Path | None) -> Path:
    """The file a SCENE argument names: the path itself, or a shipped scene's file when the path is no
    file but a shipped scene's name (``None``: the default scene)."""
    p = Path(path) if path is not None else default_scene_path()
    if not p.is_file() and path is not None and str(path) in shipped_scenes():
        p = shipped_scenes()[str(path)]
    return p


def load_scene(path: str | Path | None = None, overrides: Iterable[str] = (),
               cwd: Path | None = None) -> Scene:
    """Read, override and validate a scene; ``path=None`` is the shipped default scene, and a name
    that is no file but a shipped scene's (:func:`shipped_scenes`) is that scene."""
    p = scene_file(path)
    if not p.exists():
        raise SceneError("scene", f"file not found: {p} (shipped scenes: {', '.join(sorted(shipped_scenes()))})")
    if not p.is_file():
        raise SceneError("scene", f"not a file: {p}")
    try:
        raw = tomllib.loads(p.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise SceneError("scene", f"{p.name} is not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise SceneError("scene", f"{p.name} is not a UTF-8 text file") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise SceneError("scene", f"{p.name} is nested too deeply to parse (a scene needs at most "
                         f"{MAX_NESTING} levels of tables and lists)") from None
    _check_nesting(raw, "scene", p.name)
    return scene_from_tree(raw, overrides, path=p if path is not None else None, base=p.parent, cwd=cwd)


def scene_from_tree(raw: dict, overrides: Iterable[str] = (), path: Path | None = None,
                    base: Path | None = None, cwd: Path | None = None) -> Scene:
    """Validate a raw scene tree (e.g. from ``tomllib``) after applying ``overrides``."""
    raw = copy.deepcopy(raw)
    for o in overrides:
        apply_override(raw, o, cwd)
    tree = implied_defaults(raw, validate_tree(raw))
    check_times(tree["simulation"])
    _check_section_keys(raw)
    if any(t in raw for t in LOW_LEVEL):
        mixed = [t for t in HIGH_LEVEL if t in raw]
        if mixed:
            raise SceneError(mixed[0], "the low-level form ([[segment]] ...) cannot be mixed with "
                             "[shaft], [[delamination]] or [[obstacle]]")
        stack = low_level_stack(tree)
    else:
        stack = high_level_stack(tree)
    base = base or Path.cwd()
    stack = point_components(tree, crack_stack(tree, stack, bool(tree["mesh"]["file"]))).validate()
    check_scales(tree, stack)
    check_components(tree, stack)
    check_frame(tree, stack)
    check_speed(tree["rotation"]["speed_hz"], stack)
    if tree["rotation"].get("ramp_to_hz") is not None:
        check_speed(tree["rotation"]["ramp_to_hz"], stack, "rotation.ramp_to_hz")
    for k, v in enumerate(tree["rotation"].get("speed_table_hz") or ()):
        check_speed(v, stack, f"rotation.speed_table_hz.{k}")
    check_mesh(tree["mesh"], stack, base)
    from ..sensors import sensors_from_scene

    listed = isinstance(raw.get("output"), dict) and "plots" in raw["output"]
    return Scene(tree, stack, path, base, sensors_from_scene(tree, stack), scene_notes(raw, tree, stack), listed)
