"""Defaults that never change a rotor's model silently (issue 34, points 2 and 3): no supports hidden under
bearings, steel's density, a diameter meaning a circle, and a note for every default left that shapes a
rotor's model (its section, its beam theory, a disk without inertias, kxx read in ROSS's axes, nothing holding
the axial motion)."""

import functools
import json
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from nsfem import cli
from nsfem.analysis.modes import natural_frequencies
from nsfem.fem.assemble import build_model
from nsfem.scene import AXES, LOW_LEVEL, SceneError, load_scene, scene_from_tree, shipped_scenes

# The issue's rotor: a 0.8 m steel shaft of 30 mm on two bearings at its ends, a 3 kg disk at the middle
E, D, L, M_DISK, K_BEARING = 2.1e11, 0.03, 0.8, 3.0, 1e7


def issue_rotor(**shaft) -> dict:
    """The rotor as a user writes it from the docs: no supports key, no density (steel's default)."""
    return {"shaft": {"length": L, "section": "circle", "diameter": D, **shaft},
            "disk": [{"x": L / 2, "mass": M_DISK, "polar_inertia": 0.0, "diametral_inertia": 0.0}],
            "bearing": [{"x": 0.0, "kyy": K_BEARING, "kzz": K_BEARING},
                        {"x": L, "kyy": K_BEARING, "kzz": K_BEARING},
                        {"x": 0.0, "kxx": 1e6}],   # the thrust bearing
            "unbalance": [{"x": L / 2, "magnitude": 1e-4}],
            "rotation": {"frame": "inertial", "speed_hz": 40.0},
            "mesh": {"elements": 40}, "reduction": {"method": "none"}}


@functools.lru_cache
def spring_supported_frequencies(rho: float, count: int) -> list[float]:
    """Bending frequencies [Hz] of the continuous Euler-Bernoulli beam of the issue's rotor: free ends on
    springs K_BEARING (EI w''(0) = 0, EI w'''(0) + k w(0) = 0, and mirrored at L), a point mass at L/2
    (w, w', w'' continuous, EI [w'''] = m omega^2 w). Roots of the 8 x 8 determinant of the two spans'
    cos/sin/cosh/sinh amplitudes (rows scaled to 1), bracketed on a 0.05 Hz grid up to 400 Hz (the roots lie
    60 and 330 Hz apart), refined by brentq to 1e-12."""
    EI, rA, a = E * math.pi * D**4 / 64, rho * math.pi * D**2 / 4, L / 2

    def rows(b, s):
        c, si, ch, sh = math.cos(b * s), math.sin(b * s), math.cosh(b * s), math.sinh(b * s)
        return np.array([[c, si, ch, sh], [-b * si, b * c, b * sh, b * ch], [-b * b * c, -b * b * si, b * b * ch,
                         b * b * sh], [b**3 * si, -b**3 * c, b**3 * sh, b**3 * ch]])

    def det(f):
        w = 2 * math.pi * f
        b = (rA * w * w / EI) ** 0.25
        A = np.zeros((8, 8))
        r0, ra, rL = rows(b, 0.0), rows(b, a), rows(b, L - a)
        A[0, :4], A[1, :4] = r0[2], EI * r0[3] + K_BEARING * r0[0]
        for i in range(3):                           # w, w', w'' continuous at the disk
            A[2 + i, :4], A[2 + i, 4:] = ra[i], -r0[i]
        A[5, :4], A[5, 4:] = -EI * ra[3] - M_DISK * w * w * ra[0], EI * r0[3]
        A[6, 4:], A[7, 4:] = rL[2], -EI * rL[3] + K_BEARING * rL[0]
        return np.linalg.det(A / np.abs(A).max(axis=1, keepdims=True))

    fs = np.arange(1.0, 400.0, 0.05)
    d = np.array([det(f) for f in fs])
    roots = [brentq(det, fs[i], fs[i + 1], xtol=1e-12) for i in np.flatnonzero(d[:-1] * d[1:] < 0)]
    return roots[:count]


def lateral(scene, count=2) -> np.ndarray:
    m = natural_frequencies(build_model(scene), "open", 2 * count + 2)
    return np.array([f for f, fld in zip(m.frequencies_hz, m.fields) if fld != "U"][:count])


def test_a_rotor_on_bearings_has_no_hidden_supports():
    """The issue's rotor without a supports key: the bearings alone hold it (free-free, recorded so), and its
    first bending pair is the spring-supported beam's 60.4584 Hz (ROSS 2.3.0, 40 Euler-Bernoulli elements,
    bearings kxx = kyy = 1e7 at nodes 0 and 40, DiskElement(m=3): 60.45842591 Hz; the old pinned supports
    under the bearings gave 62.52 Hz). Tolerance 3e-8: the Hermite error of the first mode at 40 elements,
    (beta h)^4 / 1440 = 1.1e-8 (beta h = 0.063; measured 4.5e-9), twice, plus the root's 1e-12."""
    scene = scene_from_tree(issue_rotor())
    assert scene["shaft"]["supports"] == "free-free" and scene.stack.supports == ()
    assert scene["shaft"]["rho"] == 7850.0   # steel, the disk's default too
    exact = spring_supported_frequencies(7850.0, 1)[0]
    assert exact == pytest.approx(60.4584, abs=1e-4)   # the ROSS number above, to its printed digits
    np.testing.assert_allclose(lateral(scene), [exact, exact], rtol=3e-8)
    # the record (what result.npz stores, read back as export does: the unused low-level form dropped)
    again = scene_from_tree({k: v for k, v in scene.record().items() if k not in LOW_LEVEL})
    assert again["shaft"]["supports"] == "free-free" and again.stack.supports == ()


def test_supports_given_beside_bearings_are_kept():
    """Saying pinned-pinned keeps the supports: the pinned ends make the bearings there idle, so the first
    pair is the pinned beam's, well above the spring-supported 60.46 Hz (62.52 Hz measured: 3.4 %)."""
    scene = scene_from_tree(issue_rotor(supports="pinned-pinned"))
    assert [s.fix for s in scene.stack.supports] == [("U", "V", "W"), ("V", "W")]
    assert lateral(scene)[0] > 1.02 * spring_supported_frequencies(7850.0, 1)[0]


def test_a_shaft_without_bearings_keeps_the_papers_supports():
    scene = scene_from_tree({"shaft": {"length": 1.0}})
    assert scene["shaft"]["supports"] == "pinned-pinned" and len(scene.stack.supports) == 2
    assert scene.notes == ()


def test_a_diameter_means_a_circle():
    scene = scene_from_tree({"shaft": {"diameter": 0.03}, "bearing": [{"x": 0.0, "kyy": 1e6, "kzz": 1e6}]})
    seg = scene.stack.segments[0]
    assert scene["shaft"]["section"] == "circle" and seg.section == "circle" and seg.width == 0.03
    assert scene_from_tree({"shaft": {"inner_diameter": 0.01}})["shaft"]["section"] == "circle"
    # width and diameter without a section: ambiguous, refused naming the key and the fix
    with pytest.raises(SceneError, match=r"shaft.diameter: a rectangular section does not use diameter.*no "
                                         r"section given"):
        scene_from_tree({"shaft": {"diameter": 0.03, "width": 0.02}})


# --- notes: each case, and only it ----------------------------------------------------------------------
BEARINGS = [{"x": 0.0, "kyy": 1e6, "kzz": 1e6}, {"x": 1.0, "kyy": 1e6, "kzz": 1e6}]


def rotor(bearings=None, disk=None, **shaft) -> dict:
    tree = {"shaft": {"section": "circle", "diameter": 0.03, "supports": "pinned-pinned", **shaft},
            "beam": {"theory": "euler-bernoulli"}, "bearing": BEARINGS if bearings is None else bearings,
            "rotation": {"frame": "inertial"}}
    if disk is not None:
        tree["disk"] = [disk]
    return tree


NOTE_CASES = [
    pytest.param(rotor(), [], id="states-everything"),
    pytest.param(rotor([{"x": 0.0, "kxx": 1e6, "kyy": 1e6}, BEARINGS[1]]), ["bearing.0: kxx = 1e+06 N/m with kyy and "
                 "no kzz: " + AXES], id="ross-way-kxx-kyy"),
    pytest.param(rotor([{"x": 0.0, "kxx": 1e6, "kyy": 1e6, "kzz": 8e5}, BEARINGS[1]]),
                 ["bearing.0: kxx = 1e+06 N/m as large as its lateral kzz = 800000 N/m: " + AXES], id="axial-as-large"),
    pytest.param(rotor([{"x": 0.0, "kxx": 1e5, "kyy": 1e6, "kzz": 8e5}, BEARINGS[1]]), [], id="axial-smaller"),
    pytest.param(rotor([*BEARINGS, {"x": 0.0, "kxx": 1e8}]), [], id="thrust-bearing-alone"),
    # free rigid motions are said by the model's check, not as notes (tests/test_stationary.py, test_fuzz.py)
    pytest.param(rotor(supports="free-free"), [], id="axial-free"),
    pytest.param(rotor([*BEARINGS, {"x": 0.0, "kxx": 1e6}], supports="free-free"), [], id="axial-held"),
    pytest.param(rotor([{"x": 0.5, "cyy": 40.0, "czz": 40.0, "kxx": 1e6}], supports="free-free"),
                 [], id="a-damper-holds-nothing"),
    pytest.param(rotor([{"x": 0.0, "kyy": 1e6}, {"x": 1.0, "kyy": 1e6}, {"x": 0.0, "kxx": 1e6}], supports="free-free"),
                 [], id="vertical-free"),
    pytest.param(rotor([{"x": 1.0, "kyy": 1e6, "kzz": 1e6}, {"x": 0.0, "kxx": 1e6}], supports="clamped-free"), [],
                 id="clamp-and-bearing-hold"),
    pytest.param(rotor(disk={"x": 0.5, "mass": 3.0}), ["disk.0: given by its mass, its polar_inertia and "
                 "diametral_inertia are 0 (no gyroscopic moment, no rotary inertia); give polar_inertia and "
                 "diametral_inertia in kg m^2, or the disk's outer_diameter and width instead of its mass"],
                 id="disk-mass-alone"),
    pytest.param(rotor(disk={"x": 0.5, "mass": 3.0, "polar_inertia": 0.01}), ["disk.0: given by its mass, its "
                 "diametral_inertia is 0 (no rotary inertia); give diametral_inertia in kg m^2, or the disk's "
                 "outer_diameter and width instead of its mass"], id="disk-without-diametral"),
    pytest.param(rotor(disk={"x": 0.5, "mass": 3.0, "polar_inertia": 0.0, "diametral_inertia": 0.0}), [],
                 id="disk-point-mass-said"),
    pytest.param(rotor(disk={"x": 0.5, "outer_diameter": 0.2, "width": 0.03}), [], id="disk-geometry"),
    pytest.param({"shaft": {"supports": "pinned-pinned"}, "beam": {"theory": "rayleigh"},
                  "disk": [{"x": 0.5, "mass": 1.0, "polar_inertia": 0.0, "diametral_inertia": 0.0}]},
                 ['shaft: no section given: the default rectangle, 0.02 m (y) x 0.02 m (z); a round shaft is '
                  'section = "circle" with its diameter'], id="rotor-without-section"),
    pytest.param({"shaft": {"length": 1.0}, "delamination": [{}]}, [], id="papers-beam-without-section"),
    pytest.param({**rotor(), "beam": {}}, ['beam.theory: euler-bernoulli by default: the shaft has no rotary inertia '
                                           'and no gyroscopic moments of its own (its disks keep theirs); theory = '
                                           '"rayleigh" adds them, "timoshenko" (ROSS\'s default) adds shear '
                                           'deformation too'],
                 id="rotor-without-beam-theory"),
]


@pytest.mark.parametrize("tree, notes", NOTE_CASES)
def test_notes_exactly_for_the_defaults_left(tree, notes):
    assert list(scene_from_tree(tree).notes) == notes


@pytest.mark.parametrize("name", sorted(shipped_scenes()))
def test_shipped_scenes_are_quiet(name):
    """Every shipped scene states what it means: no note."""
    assert load_scene(name).notes == ()


@pytest.mark.parametrize("key", ["cxx", "kxy", "kyx", "cxy", "czx"])
def test_bearing_keys_in_other_axes_are_refused_naming_the_axes(key):
    with pytest.raises(SceneError, match=rf"bearing.0.{key}: unknown key: x is the shaft axis: kxx is an axial"):
        scene_from_tree(rotor([{"x": 0.0, "kyy": 1e6, "kzz": 1e6, key: 1.0}, BEARINGS[1]]))


# --- the command line prints each note once, and the JSON lists them ----------------------------------
NOISY = """
[shaft]
length = 0.8
diameter = 0.03
supports = "pinned-pinned"
[beam]
theory = "rayleigh"
[[disk]]
x = 0.4
mass = 3.0
[[bearing]]
x = 0.0
kxx = 1e6
kyy = 1e6
[rotation]
frame = "inertial"
speed_hz = 10.0
gravity = 0.0
[mesh]
elements = 8
[reduction]
method = "none"
[simulation]
t_end = 0.002
output_dt = 0.001
[output]
vtu_every = 0
plots = []
"""


@pytest.mark.parametrize("command", [["modes", "--count", "2"], ["stationary"], ["campbell", "--speeds", "0:10:2"],
                                     ["run"]])
def test_every_command_prints_each_note_once(command, tmp_path, capsys, monkeypatch):
    path = tmp_path / "rotor.toml"
    path.write_text(NOISY)
    notes = load_scene(path).notes
    assert len(notes) == 2   # the disk's inertias and the ROSS-way bearing
    monkeypatch.chdir(tmp_path)
    assert cli.main([command[0], str(path), *command[1:], "--json"]) == 0
    out, err = capsys.readouterr()
    for note in notes:
        assert err.count(note) == 1 and f"nsfem {command[0]}: note: {note}\n" in err
    assert json.loads(out)["notes"] == list(notes)


def test_a_quiet_scene_prints_no_note(capsys):
    assert cli.main(["modes", "ross_example", "--count", "2", "--json"]) == 0
    out, err = capsys.readouterr()
    assert "note:" not in err and json.loads(out)["notes"] == []


@pytest.mark.parametrize("command, module, name", [(["sweep", "--set", "rotation.speed_hz=5:10:2"], "nsfem.sweep",
                                                     "run_sweep"),
                                                    (["fit", "--data", "m.csv", "--vary", "bearing.0.kyy=1e5:1e7"],
                                                     "nsfem.fit", "fit")])
def test_sweep_and_fit_print_the_notes_of_their_scene_before_any_run(command, module, name, tmp_path, capsys,
                                                                     monkeypatch):
    """sweep and fit load their scene with its fixed --set once for the notes, before the library's runs (stubbed
    here: the notes must already be out when it starts)."""
    import importlib

    from nsfem.errors import NsfemError

    path = tmp_path / "rotor.toml"
    path.write_text(NOISY)
    notes = load_scene(path).notes
    assert len(notes) == 2
    seen = []

    def stub(*args, **kwargs):
        seen.append(capsys.readouterr().err)
        raise NsfemError("stubbed")

    monkeypatch.setattr(importlib.import_module(module), name, stub)
    assert cli.main([command[0], str(path), *command[1:]]) == cli.EXIT_ERROR
    assert seen and all(seen[0].count(f"nsfem {command[0]}: note: {n}\n") == 1 for n in notes)


# --- issue 34 review (r2): a section given in part ---
@pytest.mark.parametrize("shaft, missing", [
    ({"width": 0.03}, ["height"]), ({"section": "rectangle", "height": 0.04}, ["width"]),
    ({"section": "rectangle"}, ["width", "height"]), ({"section": "circle"}, ["diameter"]),
    ({"width": 0.03, "height": 0.03}, []), ({"diameter": 0.05}, []), ({"section": "circle", "diameter": 0.05}, []),
])
def test_a_rotor_section_given_in_part_notes_the_dimension_left_at_its_default(shaft, missing):
    """A rotor's shaft with a width and no height was a 0.03 x 0.02 m rectangle without a word (the note fired
    only for a table with no section key at all): each dimension the section uses and the scene leaves out
    gets its default said, naming it (in the rotating frame: the inertial one refuses a non-square rectangle)."""
    tree = {**rotor(), "shaft": {"supports": "pinned-pinned", **shaft}, "rotation": {"frame": "rotating"}}
    notes = [n for n in scene_from_tree(tree).notes if n.startswith("shaft:")]
    assert len(notes) == (1 if missing else 0), notes
    if missing:
        assert all(f"{k} = 0.02 m" in notes[0] for k in missing) and "default" in notes[0]
