"""Every bad scene input is rejected before any computation, with one clear line.

Each case is checked twice:

* through the Python API: :func:`nsfem.scene.load_scene` (or :func:`nsfem.build_model`
  for mesh-file contents) raises :class:`nsfem.errors.SceneError` whose ``key`` names
  the offending key, whose ``reason`` says why, and whose text is ``"key: reason"`` on
  one line;
* through the CLI: ``nsfem modes ...`` exits with status 2, prints exactly one line
  ``nsfem: error: <key>: <reason>`` on stderr, nothing on stdout and no traceback.

"Before any computation" is enforced by replacing the model builder (scene errors) or
the finite-element assembly (mesh-file errors) with a function that fails the test.
"""

from __future__ import annotations

import importlib

import pytest

import nsfem
from nsfem import cli
from nsfem import mesh as nsmesh
from nsfem.errors import SceneError
from nsfem.scene import SCHEMA, Key, load_scene
from nsfem.stack import BeamStack

ASSEMBLE = importlib.import_module("nsfem.fem.assemble")  # the module, not the function


# --------------------------------------------------------------------------- helpers
def _forbidden(what):
    def boom(*args, **kwargs):
        raise AssertionError(f"{what} was called: the bad input was not rejected before computation")

    return boom


@pytest.fixture
def no_model(monkeypatch):
    """Building the FE model (meshing + assembly) must not start for a bad scene."""
    # nsfem's public names load on first use: patch (and so resolve) nsfem.build_model before the module's
    # function, or its first lookup would find the stand-in, which the undo would then leave in place
    monkeypatch.setattr(nsfem, "build_model", _forbidden("build_model"))
    monkeypatch.setattr(ASSEMBLE, "build_model", _forbidden("build_model"))


@pytest.fixture
def no_assembly(monkeypatch):
    """Mesh files are read inside build_model; assembly must not start for a bad mesh."""
    monkeypatch.setattr(ASSEMBLE, "assemble", _forbidden("assemble"))


def expect_scene_error(fn, *args, **kwargs) -> SceneError:
    """Call ``fn`` and return the SceneError it raises; fail on acceptance or any other exception."""
    try:
        fn(*args, **kwargs)
    except SceneError as exc:
        return exc
    except (Exception, SystemExit) as exc:  # SystemExit: a library calling sys.exit()
        pytest.fail(f"raised {type(exc).__name__}: {exc!r} instead of SceneError")
    pytest.fail("the input was accepted")


def check_error(exc: SceneError, key: str, word: str) -> None:
    assert exc.key == key, f"key {exc.key!r} != {key!r} ({exc})"
    assert word.lower() in exc.reason.lower(), f"{word!r} not in reason {exc.reason!r}"
    text = str(exc)
    assert text == f"{key}: {exc.reason}"
    assert "\n" not in text and text.strip() == text


def run_cli(argv, capsys):
    try:
        code = cli.main(list(argv))
    except SystemExit as exc:  # nsfem must not let anything call sys.exit behind its back
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def check_cli_error(argv, capsys, key: str, word: str, clean_stdout: bool = True) -> str:
    """One line ``nsfem: error: <key>: <reason>`` on stderr, exit 2, no traceback.

    ``clean_stdout=False`` only where a mesh file is read: meshio's own stray stdout output is
    checked separately (test_cli_mesh_read_error_keeps_stdout_clean), not hidden.
    """
    code, out, err = run_cli(argv, capsys)
    assert "Traceback" not in err and "Traceback" not in out
    lines = err.splitlines()
    assert len(lines) == 1, f"expected one line on stderr, got {err!r}"
    line = lines[0]
    assert line.startswith(f"nsfem: error: {key}: "), line
    assert word.lower() in line.lower(), line
    if clean_stdout:
        assert out == "", f"nothing may be printed on stdout for a rejected scene, got {out!r}"
    assert code == cli.EXIT_ERROR, f"exit code {code!r}, stderr {err!r}"
    return line


# --------------------------------------------------------------------------- override cases
# (overrides applied to the shipped default scene, expected SceneError.key, a word of the reason)
CASES = [
    # unknown keys, top-level and nested
    pytest.param(["bogus=1"], "bogus", "unknown key", id="unknown-top-level"),
    pytest.param(["shaft.bogus=1"], "shaft.bogus", "unknown key", id="unknown-shaft.bogus"),
    pytest.param(["mesh.bogus=1"], "mesh.bogus", "unknown key", id="unknown-mesh.bogus"),
    pytest.param(["delamination.0.bogus=1"], "delamination.0.bogus", "unknown key", id="unknown-delamination.0.bogus"),
    pytest.param(["obstacle.0.bogus=1"], "obstacle.0.bogus", "unknown key", id="unknown-obstacle.0.bogus"),
    pytest.param(["shaft.0=1"], "shaft.0", "unknown key", id="unknown-numeric-key-in-table"),
    # wrong types
    pytest.param(["shaft.E=abc"], "shaft.E", "number", id="type-bare-string-for-number"),
    pytest.param(['shaft.length="1.0"'], "shaft.length", "number", id="type-quoted-string-for-number"),
    pytest.param(['delamination.0.start="0.1"'], "delamination.0.start", "number", id="type-string-for-start"),
    pytest.param(["mesh.elements=40.5"], "mesh.elements", "integer", id="type-float-for-elements"),
    pytest.param(["mesh.elements=40.0"], "mesh.elements", "integer", id="type-integral-float-for-elements"),
    pytest.param(["delamination.0.friction_directions=4.0"], "delamination.0.friction_directions", "integer",
                 id="type-float-for-friction_directions"),
    pytest.param(["shaft.E=true"], "shaft.E", "number", id="type-bool-for-number"),
    pytest.param(["rotation.speed_hz=false"], "rotation.speed_hz", "number", id="type-bool-for-speed"),
    pytest.param(["mesh.elements=true"], "mesh.elements", "integer", id="type-bool-for-elements"),
    pytest.param(["delamination.0.contact_points=true"], "delamination.0.contact_points", "count",
                 id="type-bool-for-contact_points"),
    pytest.param(['shaft.supports=["pinned-pinned"]'], "shaft.supports", "string", id="type-list-for-supports"),
    pytest.param(["title=[1]"], "title", "string", id="type-list-for-title"),
    pytest.param(['delamination.0.weighting=["dirac"]'], "delamination.0.weighting", "string",
                 id="type-list-for-weighting"),
    pytest.param(["shaft=3"], "shaft", "table", id="type-scalar-for-shaft-table"),
    pytest.param(["mesh=5"], "mesh", "table", id="type-scalar-for-mesh-table"),
    pytest.param(["delamination=3"], "delamination", "array of tables", id="type-scalar-for-delamination-array"),
    pytest.param(["delamination.0=3"], "delamination.0", "table", id="type-scalar-for-delamination-item"),
    pytest.param(["damping.rayleigh=0.5"], "damping.rayleigh", "list", id="type-scalar-for-list"),
    pytest.param(["damping.rayleigh=[0.0, 'a']"], "damping.rayleigh.1", "number", id="type-string-in-number-list"),
    pytest.param(["delamination.0.contact_points=2.5"], "delamination.0.contact_points", "count",
                 id="type-float-for-contact-count"),
    pytest.param(["delamination.0.contact_points=[0.5, 'a']"], "delamination.0.contact_points.1", "number",
                 id="type-string-in-contact-list"),
    # non-positive material / geometry / mesh
    pytest.param(["shaft.E=0"], "shaft.E", "positive", id="E-zero"),
    pytest.param(["shaft.E=-2.1e11"], "shaft.E", "positive", id="E-negative"),
    pytest.param(["shaft.rho=0"], "shaft.rho", "positive", id="rho-zero"),
    pytest.param(["shaft.rho=-7500"], "shaft.rho", "positive", id="rho-negative"),
    pytest.param(["shaft.length=0"], "shaft.length", "positive", id="length-zero"),
    pytest.param(["shaft.length=-1"], "shaft.length", "positive", id="length-negative"),
    pytest.param(["shaft.width=0"], "shaft.width", "positive", id="width-zero"),
    pytest.param(["shaft.width=-0.02"], "shaft.width", "positive", id="width-negative"),
    pytest.param(["shaft.height=0"], "shaft.height", "positive", id="height-zero"),
    pytest.param(["shaft.height=-0.02"], "shaft.height", "positive", id="height-negative"),
    pytest.param(["mesh.elements=0"], "mesh.elements", "must lie in [1,", id="elements-zero"),
    pytest.param(["mesh.elements=-5"], "mesh.elements", "must lie in [1,", id="elements-negative"),
    pytest.param(["mesh.elements=100000"], "mesh.elements", "round-off", id="elements-too-many"),
    pytest.param(["delamination.0.contact_points=[0.5, 0.5001]"], "delamination.0.contact_points", "apart",
                 id="contact-points-too-close"),
    pytest.param(["delamination.0.contact_points=[0.1000000001]"], "delamination.0.contact_points", "apart",
                 id="contact-point-at-delamination-end"),
    pytest.param(["delamination.0.upper_height=1e-300"], "delamination.0.upper_height", "thinner",
                 id="upper-height-vanishing"),
    pytest.param(["delamination.².start=0.2"], "delamination.².start", "index", id="non-ascii-index"),
    # a delamination outside the shaft, or with start >= end
    pytest.param(["delamination.0.end=1.5"], "delamination.0.end", "outside the shaft", id="delam-end-past-shaft"),
    pytest.param(["delamination.0.start=-0.1"], "delamination.0.start", "outside the shaft", id="delam-start-negative"),
    pytest.param(["shaft.length=0.5"], "delamination.0.end", "outside the shaft", id="delam-past-shortened-shaft"),
    pytest.param(["delamination.1.start=1.2", "delamination.1.end=1.4"], "delamination.1.start", "outside the shaft",
                 id="delam-added-beyond-shaft"),
    pytest.param(["delamination.0.start=0.9", "delamination.0.end=0.1"], "delamination.0.end", "exceed start",
                 id="delam-start-after-end"),
    pytest.param(["delamination.0.start=0.5", "delamination.0.end=0.5"], "delamination.0.end", "exceed start",
                 id="delam-start-equals-end"),
    # overlapping delaminations (index == len appends a second one)
    pytest.param(["delamination.1.start=0.5", "delamination.1.end=0.95"], "delamination.1", "overlaps",
                 id="overlap-partial"),
    pytest.param(["delamination.1.start=0.3", "delamination.1.end=0.4"], "delamination.1", "overlaps",
                 id="overlap-contained"),
    pytest.param(["delamination.1.start=0.9", "delamination.1.end=0.95"], "delamination.1", "touches",
                 id="overlap-touching"),
    pytest.param(["delamination.1.start=0.05", "delamination.1.end=0.2"], "delamination.0", "overlaps",
                 id="overlap-new-one-first"),
    # upper_height not strictly between 0 and height
    pytest.param(["delamination.0.upper_height=0"], "delamination.0.upper_height", "strictly between",
                 id="upper_height-zero"),
    pytest.param(["delamination.0.upper_height=-0.005"], "delamination.0.upper_height", "strictly between",
                 id="upper_height-negative"),
    pytest.param(["delamination.0.upper_height=0.02"], "delamination.0.upper_height", "strictly between",
                 id="upper_height-equals-height"),
    pytest.param(["delamination.0.upper_height=0.03"], "delamination.0.upper_height", "strictly between",
                 id="upper_height-above-height"),
    pytest.param(["shaft.height=0.01"], "delamination.0.upper_height", "strictly between",
                 id="upper_height-above-reduced-height"),
    # contact points outside their delamination, duplicated, or a zero count
    pytest.param(["delamination.0.contact_points=[0.05, 0.5]"], "delamination.0.contact_points",
                 "outside the delamination", id="contacts-before-start"),
    pytest.param(["delamination.0.contact_points=[0.5, 0.95]"], "delamination.0.contact_points",
                 "outside the delamination", id="contacts-after-end"),
    pytest.param(["delamination.0.contact_points=[0.1, 0.5]"], "delamination.0.contact_points",
                 "outside the delamination", id="contacts-on-the-edge"),
    pytest.param(["delamination.0.contact_points=[0.3, 0.3]"], "delamination.0.contact_points", "duplicate",
                 id="contacts-duplicated"),
    pytest.param(["delamination.0.contact_points=0"], "delamination.0.contact_points", ">= 1",
                 id="contacts-zero-count"),
    pytest.param(["delamination.0.contact_points=-3"], "delamination.0.contact_points", ">= 1",
                 id="contacts-negative-count"),
    pytest.param(["delamination.0.contact_points=[]"], "delamination.0.contact_points", "empty",
                 id="contacts-empty-list"),
    # restitution outside [0, 1]
    pytest.param(["delamination.0.restitution=-0.1"], "delamination.0.restitution", "[0, 1]",
                 id="restitution-negative"),
    pytest.param(["delamination.0.restitution=1.5"], "delamination.0.restitution", "[0, 1]",
                 id="restitution-above-one"),
    pytest.param(["obstacle.0.restitution=2"], "obstacle.0.restitution", "[0, 1]", id="obstacle-restitution"),
    # negative friction
    pytest.param(["delamination.0.friction=-0.1"], "delamination.0.friction", ">= 0", id="friction-negative"),
    pytest.param(["obstacle.0.friction=-1"], "obstacle.0.friction", ">= 0", id="obstacle-friction-negative"),
    # odd or < 2 friction directions
    pytest.param(["delamination.0.friction_directions=3"], "delamination.0.friction_directions", "even",
                 id="friction_directions-odd"),
    pytest.param(["delamination.0.friction_directions=0"], "delamination.0.friction_directions", "even",
                 id="friction_directions-zero"),
    pytest.param(["delamination.0.friction_directions=1"], "delamination.0.friction_directions", "even",
                 id="friction_directions-one"),
    pytest.param(["delamination.0.friction_directions=-2"], "delamination.0.friction_directions", "even",
                 id="friction_directions-negative"),
    pytest.param(["obstacle.0.friction_directions=3"], "obstacle.0.friction_directions", "even",
                 id="obstacle-friction_directions-odd"),
    # obstacles
    pytest.param(["obstacle.0.x=1.5"], "obstacle.0.x", "outside the shaft", id="obstacle-past-end"),
    pytest.param(["obstacle.0.x=-0.5"], "obstacle.0.x", "outside the shaft", id="obstacle-before-start"),
    pytest.param(["obstacle.0.normal=+w"], "obstacle.0.normal", "unknown value", id="obstacle-normal-+w"),
    pytest.param(['obstacle.0.normal="z"'], "obstacle.0.normal", "unknown value", id="obstacle-normal-unsigned"),
    pytest.param(["obstacle.0.x=0.5", "obstacle.0.normal=+y"], "obstacle.0.normal", "both sub-beams",
                 id="obstacle-in-delamination-sideways"),
    pytest.param(["obstacle.0.clearance=-0.001"], "obstacle.0.clearance", ">= 0", id="obstacle-clearance-negative"),
    # unknown names
    pytest.param(["shaft.supports=pinned-clamped-free"], "shaft.supports", "unknown value", id="name-supports"),
    pytest.param(["reduction.method=svd"], "reduction.method", "unknown value", id="name-reduction.method"),
    pytest.param(["simulation.method=euler"], "simulation.method", "unknown value", id="name-simulation.method"),
    pytest.param(["mesh.axial=P3"], "mesh.axial", "unknown value", id="name-mesh.axial"),
    pytest.param(["delamination.0.weighting=gauss"], "delamination.0.weighting", "unknown value",
                 id="name-weighting"),
    pytest.param(["beam.theory=timoshenk"], "beam.theory", "unknown value", id="name-beam.theory"),
    pytest.param(["initial.state=moving"], "initial.state", "unknown value", id="name-initial.state"),
    pytest.param(['output.plots=["phase", "bode"]'], "output.plots", "unknown entry", id="name-output.plots"),
    # NaN / inf examples named in the contract (every numeric key is covered below too)
    pytest.param(["shaft.E=nan"], "shaft.E", "finite", id="nan-shaft.E"),
    pytest.param(["rotation.speed_hz=inf"], "rotation.speed_hz", "finite", id="inf-rotation.speed_hz"),
    pytest.param(["damping.rayleigh=[0.0, nan]"], "damping.rayleigh.1", "finite", id="nan-in-damping.rayleigh"),
    pytest.param(["delamination.0.contact_points=[0.5, inf]"], "delamination.0.contact_points.1", "finite",
                 id="inf-in-contact_points"),
    pytest.param(["shaft.E=1e400"], "shaft.E", "finite", id="overflow-literal-is-inf"),
    # bad override syntax
    pytest.param(["shaft.E"], "shaft.E", "KEY=VALUE", id="override-no-equals"),
    pytest.param(["mesh.elements:20"], "mesh.elements:20", "KEY=VALUE", id="override-colon-instead-of-equals"),
    pytest.param(["=3"], "=3", "empty key", id="override-empty-key"),
    pytest.param(["shaft..E=3"], "shaft..E", "empty key", id="override-empty-key-part"),
    pytest.param(["delamination.5.start=0.3"], "delamination.5.start", "past the end", id="override-index-past-end"),
    pytest.param(["delamination.x.start=0.3"], "delamination.x.start", "list index", id="override-non-index"),
    pytest.param(["shaft.E.x=3"], "shaft.E.x", "not a table", id="override-into-scalar"),
]


def _nonfinite_cases(prefix: str, table: dict, list_len: dict[str, int] | None = None):
    """NaN, +inf and -inf for every numeric key of a schema table (list keys: in the last entry)."""
    out = []
    for name, spec in table.items():
        key = f"{prefix}.{name}"
        if isinstance(spec, list):   # an array of tables inside a table ([[shaft.step]]): its first entry
            out += _nonfinite_cases(f"{key}.0", spec[0], list_len)
            continue
        for lit in ("nan", "inf", "-inf"):
            if spec.kind in ("float", "float?", "int", "coef"):
                out.append(pytest.param([f"{key}={lit}"], key, "finite", id=f"{lit}-{key}"))
            elif spec.kind == "floats":
                n = spec.length or (list_len or {}).get(name, 2)
                vals = ["0.5"] * (n - 1) + [lit]
                out.append(pytest.param([f"{key}=[{', '.join(vals)}]"], f"{key}.{n - 1}", "finite",
                                        id=f"{lit}-in-{key}"))
            elif spec.kind == "points":
                out.append(pytest.param([f"{key}=[0.5, {lit}]"], f"{key}.1", "finite", id=f"{lit}-in-{key}"))
    return out


HIGH_LEVEL_NONFINITE = []
for _name, _spec in SCHEMA.items():
    if _name in ("segment", "junction", "support", "contact"):
        continue
    if isinstance(_spec, dict):
        HIGH_LEVEL_NONFINITE += _nonfinite_cases(_name, _spec)
    elif isinstance(_spec, list):  # delamination.0 exists in the default scene; obstacle.0 is created
        HIGH_LEVEL_NONFINITE += _nonfinite_cases(f"{_name}.0", _spec[0])
    else:
        assert isinstance(_spec, Key) and _spec.kind == "str"

LOW_LEVEL_NONFINITE = []
for _name in ("segment", "junction", "support", "contact"):
    LOW_LEVEL_NONFINITE += _nonfinite_cases(f"{_name}.0", SCHEMA[_name][0], {"extent": 2})

LOW_LEVEL_SCENE = """\
title = "two bars and a stop"

[[segment]]
name = "a"
start = 0.0
end = 0.5

[[segment]]
name = "b"
start = 0.5
end = 1.0

[[junction]]
x = 0.5
master = "a"
slaves = ["b"]

[[support]]
segment = "a"
x = 0.0
fix = ["U", "V", "W"]

[[contact]]
kind = "obstacle"
x = 0.9
segments = ["b"]
weighting = "hat"
extent = [0.8, 1.0]
"""


@pytest.fixture(scope="module")
def low_level_scene(tmp_path_factory):
    path = tmp_path_factory.mktemp("lowlevel") / "low.toml"
    path.write_text(LOW_LEVEL_SCENE, encoding="utf-8")
    load_scene(path)  # the base itself is valid
    return path


def test_schema_nonfinite_cases_cover_every_numeric_key():
    """Guard against the generated NaN/inf lists silently becoming empty."""
    assert len(HIGH_LEVEL_NONFINITE) >= 3 * 25
    assert len(LOW_LEVEL_NONFINITE) >= 3 * 15
    ids = {p.id for p in HIGH_LEVEL_NONFINITE}
    for expected in ("nan-shaft.E", "inf-mesh.elements", "-inf-obstacle.0.x", "nan-in-damping.rayleigh",
                     "inf-in-delamination.0.contact_points", "nan-in-initial.velocity"):
        assert expected in ids


def test_default_scene_and_low_level_base_are_valid(low_level_scene):
    """Positive controls: the bases the cases modify are accepted as they are."""
    assert len(load_scene(None).stack.contacts) == 9
    assert [s.name for s in load_scene(low_level_scene).stack.segments] == ["a", "b"]


@pytest.mark.parametrize("overrides, key, word", CASES + HIGH_LEVEL_NONFINITE)
def test_api_rejects_bad_override(overrides, key, word):
    check_error(expect_scene_error(load_scene, None, overrides), key, word)


@pytest.mark.parametrize("overrides, key, word", CASES + HIGH_LEVEL_NONFINITE)
def test_cli_rejects_bad_override(overrides, key, word, capsys, no_model):
    argv = ["modes"]
    for o in overrides:
        argv += ["--set", o]
    check_cli_error(argv, capsys, key, word)


@pytest.mark.parametrize("overrides, key, word", LOW_LEVEL_NONFINITE)
def test_api_rejects_nonfinite_in_low_level_scene(overrides, key, word, low_level_scene):
    check_error(expect_scene_error(load_scene, low_level_scene, overrides), key, word)


@pytest.mark.parametrize("overrides, key, word", LOW_LEVEL_NONFINITE)
def test_cli_rejects_nonfinite_in_low_level_scene(overrides, key, word, low_level_scene, capsys, no_model):
    argv = ["modes", str(low_level_scene)]
    for o in overrides:
        argv += ["--set", o]
    check_cli_error(argv, capsys, key, word)


@pytest.mark.parametrize("command", ["run", "campbell", "stationary", "sweep"])
def test_cli_other_commands_validate_the_scene_first(command, capsys, no_model):
    check_cli_error([command, "--set", "shaft.E=nan"], capsys, "shaft.E", "finite")


# --------------------------------------------------------------------------- scene files
SCENE_FILE_CASES = [
    pytest.param("[shaft]\nbogus = 1\n", "shaft.bogus", "unknown key", id="file-unknown-nested-key"),
    pytest.param("[[delamination]]\nstart = 0.1\nend = 0.9\ncolour = 'red'\n", "delamination.0.colour",
                 "unknown key", id="file-unknown-delamination-key"),
    pytest.param("[bogus]\nx = 1\n", "bogus", "unknown key", id="file-unknown-table"),
    pytest.param("[shaft]\nE = 'steel'\n", "shaft.E", "number", id="file-string-for-number"),
    pytest.param("shaft = 1.0\n", "shaft", "table", id="file-scalar-for-table"),
    pytest.param("[shaft]\nE = nan\n", "shaft.E", "finite", id="file-nan"),
    pytest.param("[shaft]\nlength = -inf\n", "shaft.length", "finite", id="file-minus-inf"),
    pytest.param("[[delamination]]\nstart = 0.1\nend = 0.9\ncontact_points = [0.5, nan]\n",
                 "delamination.0.contact_points.1", "finite", id="file-nan-contact-point"),
    pytest.param("[[delamination]]\nstart = 0.2\nend = 0.4\n[[delamination]]\nstart = 0.3\nend = 0.6\n",
                 "delamination.1", "overlaps", id="file-overlapping-delaminations"),
    pytest.param("[[obstacle]]\nx = 2.0\n", "obstacle.0.x", "outside the shaft", id="file-obstacle-outside"),
    pytest.param("[mesh]\nfile = \"missing.msh\"\n", "mesh.file", "file not found", id="file-missing-mesh"),
    pytest.param("[shaft]\nE = \n", "scene", "not valid TOML", id="file-toml-missing-value"),
    pytest.param("[shaft\nE = 1.0\n", "scene", "not valid TOML", id="file-toml-unclosed-table"),
    pytest.param("[shaft]\nE = 1.0\nE = 2.0\n", "scene", "not valid TOML", id="file-toml-duplicate-key"),
    pytest.param("title = \"unterminated\n", "scene", "not valid TOML", id="file-toml-unterminated-string"),
    pytest.param(b"\xff\xfe[shaft]\n", "scene", "UTF-8", id="file-not-utf8"),
]


def _write(path, content):
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


@pytest.mark.parametrize("content, key, word", SCENE_FILE_CASES)
def test_api_rejects_bad_scene_file(content, key, word, tmp_path):
    path = _write(tmp_path / "scene.toml", content)
    exc = expect_scene_error(load_scene, path)
    check_error(exc, key, word)
    if key == "scene":
        assert "scene.toml" in exc.reason


@pytest.mark.parametrize("content, key, word", SCENE_FILE_CASES)
def test_cli_rejects_bad_scene_file(content, key, word, tmp_path, capsys, no_model):
    path = _write(tmp_path / "scene.toml", content)
    line = check_cli_error(["modes", str(path)], capsys, key, word)
    if key == "scene":
        assert "scene.toml" in line


def test_api_rejects_missing_scene_file(tmp_path):
    missing = tmp_path / "nope.toml"
    exc = expect_scene_error(load_scene, missing, [])
    check_error(exc, "scene", "file not found")
    assert str(missing) in exc.reason


def test_cli_rejects_missing_scene_file(tmp_path, capsys, no_model):
    missing = tmp_path / "nope.toml"
    line = check_cli_error(["modes", str(missing)], capsys, "scene", "file not found")
    assert str(missing) in line


def test_api_rejects_directory_as_scene_file(tmp_path):
    check_error(expect_scene_error(load_scene, tmp_path), "scene", "not a file")


def test_relative_mesh_path_is_relative_to_the_scene_file(tmp_path, monkeypatch):
    sub = tmp_path / "scenes"
    sub.mkdir()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    path = _write(sub / "scene.toml", "[mesh]\nfile = \"beam.msh\"\n")
    exc = expect_scene_error(load_scene, path)
    check_error(exc, "mesh.file", "file not found")
    assert str(sub / "beam.msh") in exc.reason


def test_set_mesh_path_is_relative_to_the_cwd(tmp_path, monkeypatch, capsys, no_model):
    monkeypatch.chdir(tmp_path)
    exc = expect_scene_error(load_scene, None, ["mesh.file=beam.msh"])
    check_error(exc, "mesh.file", "file not found")
    assert str(tmp_path / "beam.msh") in exc.reason
    line = check_cli_error(["modes", "--set", "mesh.file=beam.msh"], capsys, "mesh.file", "file not found")
    assert str(tmp_path / "beam.msh") in line


# --------------------------------------------------------------------------- mesh files
MESH_OVERRIDES = ["mesh.elements=20"]


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    """A full gmsh22 mesh of the default scene and one lacking the lower sub-beam and intact_1."""
    d = tmp_path_factory.mktemp("meshes")
    scene = load_scene(None, MESH_OVERRIDES)
    m = nsmesh.generate(scene.stack, 20)
    full = nsmesh.write(d / "full.msh", scene.stack, m)

    # the same writer, given a stack of only two of the four segments
    keep = tuple(s for s in scene.stack.segments if s.name in ("intact_0", "delamination_0_upper"))
    partial = nsmesh.write(d / "partial.msh", BeamStack(keep), m)
    text = partial.read_text()
    assert '"intact_0"' in text and '"delamination_0_upper"' in text and '"intact_1"' not in text
    return {"full": full, "partial": partial, "scene": scene}


def test_full_mesh_file_is_read(meshes):
    """Positive control: the complete file (same writer as the partial one) is accepted."""
    scene = load_scene(None, [*MESH_OVERRIDES, f"mesh.file={meshes['full']}"])
    m = nsmesh.read(scene.mesh_file, scene.stack)
    assert sorted(m.nodes) == sorted(s.name for s in scene.stack.segments)


def test_api_rejects_missing_mesh_file(tmp_path):
    missing = tmp_path / "nope.msh"
    exc = expect_scene_error(load_scene, None, [f"mesh.file={missing}"])
    check_error(exc, "mesh.file", "file not found")
    assert str(missing) in exc.reason


def test_cli_rejects_missing_mesh_file(tmp_path, capsys, no_model):
    missing = tmp_path / "nope.msh"
    line = check_cli_error(["modes", "--set", f"mesh.file={missing}"], capsys, "mesh.file", "file not found")
    assert str(missing) in line


def test_api_rejects_mesh_lacking_a_cell_set(meshes, no_assembly):
    scene = load_scene(None, [*MESH_OVERRIDES, f"mesh.file={meshes['partial']}"])
    exc = expect_scene_error(nsfem.build_model, scene)
    check_error(exc, "mesh.file", "no cell set")
    assert "delamination_0_lower" in exc.reason and "partial.msh" in exc.reason


def test_cli_rejects_mesh_lacking_a_cell_set(meshes, capsys, no_assembly):
    line = check_cli_error(["modes", "--set", f"mesh.file={meshes['partial']}", *sum(
        (["--set", o] for o in MESH_OVERRIDES), [])], capsys, "mesh.file", "no cell set", clean_stdout=False)
    assert "delamination_0_lower" in line


def test_cli_mesh_read_error_keeps_stdout_clean(meshes, capsys, no_assembly):
    code, out, err = run_cli(["modes", "--set", f"mesh.file={meshes['partial']}", "--set", "mesh.elements=20"],
                             capsys)
    assert code == cli.EXIT_ERROR and "no cell set" in err
    assert out == ""


def test_relative_partial_mesh_in_scene_file(meshes, tmp_path, monkeypatch, capsys, no_assembly):
    """A relative mesh.file in a scene file resolves next to the scene, and its contents are checked."""
    (tmp_path / "m.msh").write_bytes(meshes["partial"].read_bytes())
    scene_file = _write(tmp_path / "scene.toml", "[[delamination]]\nstart = 0.1\nend = 0.9\n"
                        "[mesh]\nelements = 20\nfile = \"m.msh\"\n")
    monkeypatch.chdir(tmp_path.parent)
    exc = expect_scene_error(nsfem.build_model, load_scene(scene_file))
    check_error(exc, "mesh.file", "no cell set")
    check_cli_error(["modes", str(scene_file)], capsys, "mesh.file", "no cell set", clean_stdout=False)


def test_api_rejects_mesh_without_a_contact_node(meshes, no_assembly):
    """The full mesh has nodes at the 9 default contact points, not at x = 0.123."""
    scene = load_scene(None, [*MESH_OVERRIDES, "delamination.0.contact_points=[0.123]",
                              f"mesh.file={meshes['full']}"])
    check_error(expect_scene_error(nsfem.build_model, scene), "mesh.file", "no node at x=0.123")


def test_too_few_elements_rejected_before_assembly(capsys, no_assembly):
    check_error(expect_scene_error(load_scene, None, ["mesh.elements=3"]), "mesh.elements", "fewer than")
    check_cli_error(["modes", "--set", "mesh.elements=3"], capsys, "mesh.elements", "fewer than")


UNREADABLE_MESHES = [
    pytest.param("garbage.msh", bytes(range(256)) * 4, id="garbage-bytes-msh"),
    pytest.param("text.msh", b"this is not a mesh\n", id="plain-text-msh"),
    pytest.param("garbage.vtu", b"\x00\xff" * 100, id="garbage-bytes-vtu"),
    pytest.param("empty.msh", b"", id="empty-msh"),
    pytest.param("mesh.unknownext", b"\x00\xff" * 100, id="unknown-extension"),
]


@pytest.mark.parametrize("name, content", UNREADABLE_MESHES)
def test_api_rejects_unreadable_mesh_file(name, content, tmp_path, no_assembly):
    path = _write(tmp_path / name, content)
    scene = load_scene(None, [f"mesh.file={path}"])
    exc = expect_scene_error(nsfem.build_model, scene)
    check_error(exc, "mesh.file", "cannot read")
    assert name in exc.reason


@pytest.mark.parametrize("name, content", UNREADABLE_MESHES)
def test_cli_rejects_unreadable_mesh_file(name, content, tmp_path, capsys, no_assembly):
    path = _write(tmp_path / name, content)
    line = check_cli_error(["modes", "--set", f"mesh.file={path}"], capsys, "mesh.file", "cannot read",
                           clean_stdout=False)
    assert name in line


@pytest.mark.parametrize("segments, word", [(["upper", "upper"], "two different"),
                                            (["lower", "upper"], "must sit on")])
def test_low_level_interface_geometry_is_checked(segments, word):
    from nsfem.scene import scene_from_tree

    tree = {"segment": [{"name": "upper", "start": 0.0, "end": 1.0, "height": 0.01, "offset": [0.0, 0.005]},
                        {"name": "lower", "start": 0.0, "end": 1.0, "height": 0.01, "offset": [0.0, -0.005]}],
            "contact": [{"kind": "interface", "x": 0.5, "segments": segments}]}
    check_error(expect_scene_error(scene_from_tree, tree), "contact.0.segments", word)
