"""ROSS 2.3.0 references of issue 35: the shipped stepped_rotor scene (damped modes at two speeds, damped critical
speeds; studies/ross_stepped_rotor.py) and the run-up reference pair tests/data/ross_runup.{json,toml} (studies/
ross_runup.py): the scene and the recorded rotor agree, and nsfem's constant-speed model of it is ROSS's."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from nsfem import build_model, load_scene
from nsfem.analysis.campbell import campbell_report
from nsfem.analysis.damped import scene_damped_modes
from nsfem.scene import scene_from_tree

DATA = Path(__file__).resolve().parent / "data"

# --- issue 35: ROSS references (stepped_rotor, run-up) ---
#: studies/ross_stepped_rotor.py (ROSS 2.3.0, /work/rossvenv/bin/python): run_modal(sparse=False) at 50 and 100 Hz of
#: the same 24 Timoshenko elements (shear_effects=True, shear_method_calc="cowper": ROSS's default and nsfem's; the
#: scene's E, G and rho), disks and bearings, the bearings' coefficients nsfem's linear interpolation of the table
#: (both are the table at these speeds): wd / 2 pi [Hz] and log_dec of the six lowest lateral modes (ROSS's
#: torsional mode and nsfem's axial one, each without counterpart, left out). ROSS's default sparse run_modal is
#: 3e-9 to 4e-9 off on the modes above 500 Hz: the dense solve of its own state matrix is the reference (see the
#: script).
ROSS_STEPPED = {
    50.0: ([28.40224012028, 32.12447487039, 115.8664997291, 123.5555297024, 491.9138529386, 501.1894361619],
           [4.574151877671, 3.651476098744, 2.142707311176, 0.5864638272774, 0.31213818443, 0.8014217211512]),
    100.0: ([53.64008405707, 58.59510964546, 117.2391507009, 121.6687544606, 483.1021639042, 511.3370738398],
            [2.847768767011, 1.03625202563, 3.028673153523, 0.8074124605811, 0.5599508795938, 0.7394833243671]),
}
#: the same rotor without shear (`--theory rayleigh`: shear_effects=False; nsfem: beam.theory = "rayleigh"), the
#: scene's numbers before it took shear (docs/validation.md: what shear moved)
ROSS_STEPPED_RAYLEIGH = {
    50.0: ([28.40215517653, 32.10914785787, 117.9194457791, 125.7419883844, 510.9746271365, 521.7693226558],
           [4.574139964044, 3.651842274416, 2.177638444246, 0.5971565605607, 0.320852747337, 0.8172216448494]),
    100.0: ([53.63871546485, 58.57911218032, 119.4112883995, 123.7593759063, 501.4167417993, 533.2393277418],
            [2.847844615918, 1.052543643518, 3.042886627024, 0.8245116221178, 0.5734208002367, 0.7538793984769]),
}
#: the speeds where a damped root of ROSS's run_modal whirls at the speed (bearings rebuilt at each trial speed,
#: Brent xtol 1e-10 Hz) and that root's log_dec
ROSS_STEPPED_CRITICAL = [(121.36835818963665, 0.8202378428950641), (122.70343239795695, 3.307183247533883)]


@pytest.fixture(scope="module")
def stepped():
    scene = load_scene("stepped_rotor")
    return scene, build_model(scene)


@pytest.mark.parametrize("theory, reference", [("timoshenko", ROSS_STEPPED), ("rayleigh", ROSS_STEPPED_RAYLEIGH)])
@pytest.mark.parametrize("speed", sorted(ROSS_STEPPED))
def test_stepped_rotor_damped_modes_match_ross_with_shear_on_and_off(stepped, speed, theory, reference):
    """Same elements, same bearings: the damped frequencies and log decs agree to the eigen solvers' round-off.
    ROSS's numbers are recorded to 13 digits (5e-13 relative); the two codes assemble and solve in different orders
    (ROSS: a dense eig of M^-1 [K, C]; nsfem: shift-invert Arnoldi of the pencil), and the mass matrix's condition
    (7.6e5) amplifies eps in both (measured: at most 6e-12 relative on the frequencies, 1.5e-11 on the log decs):
    1e-9 relative leaves room for other BLAS kernels. Shear moves these numbers by 3e-6 to 5e-4 (the modes of the
    rotor rocking on its bearings) to 4 % (the 500 Hz bending pair), far outside that: each theory matches only
    its own."""
    scene, model = stepped
    if theory != "timoshenko":  # the scene's
        scene = load_scene("stepped_rotor", [f"beam.theory={theory}"])
        model = build_model(scene)
    modes = scene_damped_modes(scene, model, speed, 12)
    lateral = np.array([w != "axial" for w in modes.whirl])
    f, d = modes.frequencies_hz[lateral], modes.log_decrements[lateral]
    ross_f, ross_d = reference[speed]
    np.testing.assert_allclose(f[: len(ross_f)], ross_f, rtol=1e-9)
    np.testing.assert_allclose(d[: len(ross_d)], ross_d, rtol=1e-9)


def test_stepped_rotor_damped_critical_speeds_match_ross(stepped):
    """The damped critical speeds (1x crossings of the tracked damped branches, the bearings read from their tables
    at each speed; what ``nsfem campbell`` reports) are ROSS's, with their log decs: both sides stop Brent within
    1e-10 Hz (nsfem: XTOL x the grid's 30 Hz span, 3e-10 Hz) and solve the same pencil (round-off as above;
    measured 1e-13 to 7e-13 on the speeds, 9e-12 on the log decs): 1e-9 relative. A grid of 5 Hz over 110-140 Hz
    brackets both: the crossings are refined on the tracked branches, not read off the grid."""
    from nsfem.analysis.campbell import campbell, crossing_log_decrement
    from nsfem.analysis.whirl import damped_critical_speeds
    from nsfem.fem.components import lateral_turn
    from nsfem.fem.rotating import rotor_operators

    scene, model = stepped
    ops, turn = rotor_operators(model), lateral_turn(model.spaces, model.n_full)
    rd = (scene.damping.rayleigh, scene.damping.external)
    res = campbell(ops, np.linspace(110.0, 140.0, 7), 4, *rd, frame="inertial", turn=turn)
    found = damped_critical_speeds(ops, res, 4, *rd, turn=turn)
    assert [c.speed_hz for c in found] == pytest.approx([s for s, _ in ROSS_STEPPED_CRITICAL], rel=1e-9)
    assert [crossing_log_decrement(c, res.resolution_per_s) for c in found] == pytest.approx(
        [d for _, d in ROSS_STEPPED_CRITICAL], rel=1e-9)


@pytest.mark.slow
def test_stepped_rotor_campbell_report_tells_the_scenes_story(stepped):
    """``nsfem campbell stepped_rotor``'s report over the table's span: the two damped critical speeds (ROSS's, as
    above) with their log decs in the JSON, above the 100 Hz operating speed, and the oil-whip onset where the
    half-speed forward branch turns unstable: between the critical speeds and the table's end."""
    scene, model = stepped
    rep = campbell_report(scene, model, np.linspace(10.0, 150.0, 29), 6)
    found = rep["critical_speeds"]["open"]
    assert [c["speed_hz"] for c in found] == pytest.approx([s for s, _ in ROSS_STEPPED_CRITICAL], rel=1e-9)
    assert [c["log_decrement"] for c in found] == pytest.approx([d for _, d in ROSS_STEPPED_CRITICAL], rel=1e-9)
    assert all(scene.rotation.speed_hz < c["speed_hz"] < 150.0 for c in found)
    onset = rep["instability_hz"]["open"]
    assert len(onset) == 1 and found[-1]["speed_hz"] < onset[0] < 150.0
    # past the onset the half-speed branch's log dec is negative in the JSON
    D = np.array(rep["log_decrements"], dtype=float)
    past = np.array(rep["speeds_hz"]) > onset[0]
    assert np.all(np.nanmin(D[past], axis=1) < 0) and np.all(np.nanmin(D[~past], axis=1) >= 0)  # (axial: 0)


def _runup():
    data = json.loads((DATA / "ross_runup.json").read_text())
    tree = tomllib.loads((DATA / "ross_runup.toml").read_text())
    return data, tree


def _constant_speed(tree):
    """The run-up scene without its ramp (nsfem's constant-speed model of the same rotor)."""
    rot = {k: v for k, v in tree["rotation"].items() if k not in ("ramp_to_hz", "ramp_s")}
    return scene_from_tree({**tree, "rotation": rot})


def test_runup_reference_scene_is_the_recorded_rotor():
    """tests/data/ross_runup.toml states the rotor, ramp and unbalance the JSON records (exactly: the same
    decimal numbers), and the JSON's samples are the recorded 1 ms grid over the ramp."""
    data, tree = _runup()
    rotor, sh = data["rotor"], tree["shaft"]
    assert (sh["length"], sh["diameter"], sh["E"], sh["rho"]) == (rotor["shaft"]["length_m"], rotor["shaft"][
        "diameter_m"], rotor["shaft"]["E_Pa"], rotor["shaft"]["rho_kg_m3"])
    assert tree["beam"]["theory"] == "rayleigh" and tree["mesh"]["elements"] == rotor["shaft"]["elements"]
    (disk,) = tree["disk"]
    d = rotor["disk"]
    assert (disk["x"], disk["outer_diameter"], disk["inner_diameter"], disk["width"], disk["rho"]) == (
        d["x_m"], d["outer_diameter_m"], d["inner_diameter_m"], d["width_m"], d["rho_kg_m3"])
    lateral = [b for b in tree["bearing"] if "kyy" in b]
    assert [{"x_m": b["x"], **{k: b[k] for k in ("kyy", "kzz", "cyy", "czz")}} for b in lateral] == rotor["bearings"]
    rot, ramp = tree["rotation"], data["ramp"]
    assert (rot["speed_hz"], rot["ramp_to_hz"], rot["ramp_s"], rot["gravity"]) == (
        ramp["speed_hz"], ramp["ramp_to_hz"], ramp["ramp_s"], data["gravity"])
    (u,) = tree["unbalance"]
    assert (u["x"], u["magnitude"], math.radians(u["phase_deg"])) == (
        data["unbalance"]["x_m"], data["unbalance"]["magnitude_kg_m"], data["unbalance"]["phase_rad"])
    t = np.array(data["t_s"])
    assert t[0] == 0.0 and t[-1] == pytest.approx(ramp["ramp_s"], abs=1e-12)
    assert np.diff(t) == pytest.approx(data["dt_out_s"], abs=1e-9)
    assert len(data["disk_y_m"]) == len(data["disk_z_m"]) == t.size


def test_runup_reference_rotor_at_constant_speed_is_rosss():
    """nsfem's constant-speed model of the run-up scene (the ramp keys left out) has ROSS's steady unbalance
    response, complex, with the same phase convention (y = Re(Z e^{i Omega t}), the unbalance along +y at t = 0):
    the same elements and loads solved by two codes, to round-off (a harmonic solve of a 55-dof system, amplified
    near the 38.5 Hz resonance by its 1 / (2 zeta) = 38: measured 2e-14 to 1.2e-11 relative, the largest at the
    resonance; 1e-9 leaves room for other BLAS kernels). This pins the pair's conventions (axes, unbalance phase,
    sense of rotation) for the run-up's check."""
    from nsfem.analysis.response import harmonic_response
    from nsfem.fem.rotating import rotor_operators

    data, tree = _runup()
    scene = _constant_speed(tree)
    model = build_model(scene)
    st = data["steady_response"]
    res = harmonic_response(rotor_operators(model), scene.sensors, model, st["speeds_hz"], scene.rotation,
                            scene.damping)
    Zy = np.array(st["y_re"]) + 1j * np.array(st["y_im"])
    Zz = np.array(st["z_re"]) + 1j * np.array(st["z_im"])
    np.testing.assert_allclose(res.Z[:, 0], Zy, rtol=1e-9, atol=1e-9 * np.abs(Zy).max())
    np.testing.assert_allclose(res.Z[:, 1], Zz, rtol=1e-9, atol=1e-9 * np.abs(Zz).max())


def test_runup_reference_shows_the_passage_through_the_critical_speed():
    """The recorded run-up (alpha = 167.6 rad/s^2 through 38.2/38.5 Hz, log dec 0.08) passes the critical speed as
    the classical closed forms say a fast passage does: its largest orbit radius is well below the steady peak and
    reached past it. With the dimensionless acceleration eta = alpha / omega_n^2 = 2.9e-3 and damping ratio 0.013,
    the undamped asymptotics of the passage (Lewis 1932; Markert & Seidler 2001) give a peak of about
    1 / sqrt(eta) ... 1.5 / sqrt(eta) = 19-28 static deflections against the steady 1 / (2 zeta) = 38 (a ratio
    0.45-0.75), reached 2-2.5 sqrt(eta) omega_n / 2 pi = 4-5 Hz past the critical speed; the recorded run has
    0.50 and +3.8 Hz. The bounds below are those asymptotics' spread widened for the damping (which lowers both)."""
    data, _ = _runup()
    y, z = np.array(data["disk_y_m"]), np.array(data["disk_z_m"])
    r = np.hypot(y, z)
    k = int(np.argmax(r))
    ramp = data["ramp"]
    speed_at_peak = ramp["speed_hz"] + (ramp["ramp_to_hz"] - ramp["speed_hz"]) * data["t_s"][k] / ramp["ramp_s"]
    steady = data["steady_peak"]
    assert 0.35 < r[k] / steady["amplitude_m"] < 0.8
    assert 1.5 < speed_at_peak - steady["speed_hz"] < 6.0
    # converged: halving ROSS's step moved the history by less than 1e-3 of its peak (recorded 8.3e-5)
    assert data["convergence"]["relative_to_peak"] < 1e-3
