"""Damped modes at speed (``nsfem modes --speed``, :mod:`nsfem.analysis.damped`): against a closed form, the
state-space eigenvalues they must be, and ROSS 2.3.0's ``run_modal``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from nsfem import build_model, load_scene
from nsfem.analysis.damped import damped_modes, log_decrement, scene_damped_modes
from nsfem.fem.rotating import rotor_operators

# a uniform stiff shaft (Rayleigh beam) on two equal isotropic damped bearings at its ends, a thrust bearing on x
RIGID = """
title = "stiff shaft on two damped bearings"
[shaft]
length = 1.0
section = "circle"
diameter = 0.05
E = {E}
rho = 7810.0
supports = "free-free"
[beam]
theory = "rayleigh"
[[bearing]]
x = 0.0
kyy = {k}
kzz = {k}
cyy = {c}
czz = {c}
[[bearing]]
x = 1.0
kyy = {k}
kzz = {k}
cyy = {c}
czz = {c}
[[bearing]]
x = 0.0
kxx = 1e9
[rotation]
frame = "inertial"
speed_hz = {speed}
[mesh]
elements = 8
[reduction]
method = "none"
"""


def _rigid_scene(tmp_path, speed, k=1e5, zeta=0.1, E=2.11e14):
    m = 7810.0 * math.pi * 0.025**2 * 1.0
    c = zeta * math.sqrt(2 * k * m)   # 2 c = 2 zeta sqrt(2 k m): the translation's damping ratio is zeta
    path = tmp_path / "rigid.toml"
    path.write_text(RIGID.format(E=E, k=k, c=c, speed=speed))
    return load_scene(str(path), []), m


@pytest.mark.parametrize("speed", [0.0, 10.0])
def test_translation_mode_of_a_stiff_rotor_on_damped_bearings_has_the_closed_form(tmp_path, speed):
    """m x'' + 2 c x' + 2 k x = 0: omega_n = sqrt(2 k / m), zeta = c / sqrt(2 k m), omega_d = omega_n
    sqrt(1 - zeta^2), delta = 2 pi zeta / sqrt(1 - zeta^2); the symmetric rotor's translation does not
    feel the gyroscopic moment, so at any speed. The shaft is 3e4 times stiffer than the bearings
    (48 E I / L^3 = 3e9 N/m against 2 k = 2e5 N/m): its bending shifts the translation by a relative
    O(2 k / k_shaft) = 7e-5, hence the tolerance 3e-4."""
    k, zeta = 1e5, 0.1
    scene, m = _rigid_scene(tmp_path, speed, k, zeta)
    model = build_model(scene)
    modes = scene_damped_modes(scene, model, speed, 2)
    wn = math.sqrt(2 * k / m)
    wd = wn * math.sqrt(1 - zeta**2)
    assert modes.frequencies_hz == pytest.approx([wd / (2 * math.pi)] * 2, rel=3e-4)
    assert modes.damping_ratios == pytest.approx([zeta] * 2, rel=3e-4)
    assert modes.log_decrements == pytest.approx(log_decrement([zeta] * 2), rel=3e-4)
    # a repeated root: at rest no whirl; spinning, its eigenspace splits into one forward, one backward circle
    assert sorted(modes.whirl) == (["planar"] * 2 if speed == 0 else ["backward", "forward"])


def test_damped_modes_are_roots_of_the_quadratic_pencil():
    """Every reported lambda makes lambda^2 M + lambda C + Q singular: its smallest singular value, relative to
    the largest, at round-off times the pencil's condition (1e-9: a backward-stable eigen solver's eps |P| /
    sigma_min in a 24-dof reduced model whose frequencies span 10 to 1e4 Hz); the reported numbers are the
    root's: f = Im / 2 pi, zeta = -Re / |lambda|, log dec = 2 pi zeta / sqrt(1 - zeta^2) (identities to
    round-off), whirl named as in the list."""
    from nsfem.reduce import scene_reduction
    from nsfem.system import linear_system

    scene = load_scene("ross_example", [f"bearing.{i}.c{a}=1000" for i in (0, 1) for a in ("yy", "zz")])
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    ops = rotor_operators(model, red.T)
    modes = damped_modes(model, ops, 50.0, 6, frame="inertial")
    system = linear_system(ops, 50.0, frame="inertial")
    M, C, Q = (A.toarray() for A in (system.M, system.C, system.Q))
    for lam in modes.eigenvalues:
        s = np.linalg.svd(lam**2 * M + lam * C + Q, compute_uv=False)
        assert s[-1] <= 1e-9 * s[0], lam
    assert np.all(np.diff(modes.frequencies_hz) >= 0)
    assert modes.frequencies_hz == pytest.approx(modes.eigenvalues.imag / (2 * math.pi), rel=1e-14)
    assert modes.log_decrements == pytest.approx(log_decrement(modes.damping_ratios), rel=1e-12, abs=1e-15)
    assert set(modes.whirl) <= {"forward", "backward", "planar", "axial"}


# ROSS 2.3.0 (/work/rossvenv, ross.Rotor of rotor_example()'s geometry: 6 ShaftElement of 0.25 m, odl 0.05,
# steel rho 7810 E 211e9, shear_effects=False, rotary_inertia and gyroscopic on; disks from_geometry at nodes 2
# and 4 (width 0.07, i_d 0.05, o_d 0.28); BearingElement at nodes 0 and 6 with kxx=1e6, kyy=8e5, cxx=cyy=1000),
# rotor.run_modal(speed=4000.0 rad/s, num_modes=12): wd / 2 pi and log_dec of the first five (lateral) modes,
# printed to 10 decimals, whirl_direction()
ROSS_WD_HZ = [13.3035551579, 15.9915383367, 26.3198713016, 45.0237787338, 63.7633650102]
ROSS_LOG_DEC = [0.0896073789, 0.1766675449, 0.6175741550, 0.5388872311, 0.4864076582]
ROSS_WHIRL = ["backward", "forward", "backward", "backward", "forward"]


def test_damped_modes_agree_with_ross_run_modal_without_shear():
    """The same Rayleigh-beam model (ROSS's x = our y, ROSS's y = our z): equal to ROSS's printed digits
    (1e-10 absolute; 1e-8 relative is the looser of both on these magnitudes) but for our extra axial mode."""
    speed_hz = 4000.0 / (2 * math.pi)
    scene = load_scene("ross_example", ["reduction.method=none", "mesh.elements=6"]
                       + [f"bearing.{i}.c{a}=1000" for i in (0, 1) for a in ("yy", "zz")])
    modes = scene_damped_modes(scene, build_model(scene), speed_hz, 6)
    lateral = [i for i, w in enumerate(modes.whirl) if w != "axial"]
    assert modes.frequencies_hz[lateral] == pytest.approx(ROSS_WD_HZ, rel=1e-8)
    assert modes.log_decrements[lateral] == pytest.approx(ROSS_LOG_DEC, rel=1e-8)
    assert [modes.whirl[i] for i in lateral] == ROSS_WHIRL


def test_modes_speed_json_lists_are_aligned_and_the_png_is_written(tmp_path, capsys):
    from nsfem import cli

    png = tmp_path / "orbits.png"
    assert cli.main(["modes", "ross_example", "--speed", "50", "--count", "5", "--json", "--png", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    keys = ("frequencies_hz", "damping_ratios", "log_decrements", "whirl")
    assert len({len(out[k]) for k in keys}) == 1 and len(out["frequencies_hz"]) == 5
    assert out["speed_hz"] == 50.0 and out["outputs"] == [str(png)]
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ------------------------------------------------------------------ bearing reactions (bearings.csv of nsfem run)
def test_bearing_forces_of_a_rotor_at_rest_under_gravity_carry_its_weight():
    """The static sag K q = f_gravity of ross_example: its bearings' vertical forces sum to the weight m g of the
    shaft (rho A L) and the two disks (rho pi/4 (D^2 - d^2) w each), the horizontal ones to 0. Tolerance 1e-9:
    the solve's round-off, cond(K) eps with cond(K) ~ 1e6 here."""
    from nsfem.analysis.reactions import bearing_force_histories
    from nsfem.fem.constraints import dense
    from nsfem.system import linear_system

    scene = load_scene("ross_example", ["reduction.method=none", "mesh.elements=12", "rotation.speed_hz=0"])
    model = build_model(scene)
    basis = dense(model.T)
    system = linear_system(rotor_operators(model, model.T), 0.0, 9.81, frame="inertial")
    q = np.linalg.solve(system.Q.toarray(), system.f0)
    F = bearing_force_histories(model, basis, np.zeros(1), q[:, None], np.zeros((q.size, 1)))
    rho, g = 7810.0, 9.81
    m = rho * math.pi / 4 * (0.05**2 * 1.5 + 2 * (0.28**2 - 0.05**2) * 0.07)
    assert F[0, :, 2].sum() == pytest.approx(m * g, rel=1e-9)
    assert abs(F[0, :, 1].sum()) <= 1e-9 * m * g


@pytest.mark.parametrize("frame", ["inertial", "rotating"])
def test_bearing_force_of_a_synchronous_circular_orbit_is_the_dynamic_stiffness_times_the_radius(frame):
    """A steady unbalance orbit u = r (cos Omega t, sin Omega t) at an isotropic bearing (k, c): the force's
    amplitude is |k + i Omega c| r, and it leads the displacement's opposite by atan(Omega c / k). In the
    rotating frame the same orbit is a constant u_r = (r, 0), u_r' = 0 (the damping then acts on Omega J u_r).
    Round-off only: 1e-12."""
    from nsfem.analysis.reactions import bearing_force_histories

    k, c, speed, r = 2e6, 3e3, 40.0, 1e-4
    scene = load_scene("rub", ["reduction.method=none", f"rotation.frame={frame}", f"rotation.speed_hz={speed}",
                               f"bearing.0.kyy={k}", f"bearing.0.kzz={k}", f"bearing.0.cyy={c}",
                               f"bearing.0.czz={c}", "rotation.phase_deg=0"])
    model = build_model(scene)
    b = model.stack.bearings[0]
    n = model.n_full
    seg = model.stack.carrier(b.x)
    iv, iw = model.dof(seg, "V", b.x), model.dof(seg, "W", b.x)
    W = 2 * math.pi * speed
    t = np.linspace(0.0, 0.05, 41)
    q, v = np.zeros((n, t.size)), np.zeros((n, t.size))
    if frame == "inertial":
        q[iv], q[iw] = r * np.cos(W * t), r * np.sin(W * t)
        v[iv], v[iw] = -r * W * np.sin(W * t), r * W * np.cos(W * t)
    else:
        q[iv] = r
    F = bearing_force_histories(model, np.eye(n), t, q, v, frame, speed, 0.0)[:, 0, 1:]
    assert np.hypot(F[:, 0], F[:, 1]) == pytest.approx(abs(k + 1j * W * c) * r, rel=1e-12)
    # F = -(k + i W c) u in complex notation u = r e^{i W t}
    assert F[:, 0] + 1j * F[:, 1] == pytest.approx(-(k + 1j * W * c) * r * np.exp(1j * W * t), rel=1e-12, abs=1e-9)


def test_run_writes_bearings_csv_with_the_run(tmp_path, capsys):
    """A scene with bearings: bearings.csv beside result.npz, named in the JSON as ``bearings``, a column per
    lateral force of each bearing and the axial one of the thrust bearing, a row per output time."""
    from nsfem import cli

    out = tmp_path / "run"
    assert cli.main(["run", "ross_example", "--json", "--out", str(out), "--set", "simulation.t_end=0.01",
                     "--set", "output.vtu_every=0", "--set", "output.plots=[]"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload["bearings"] == str(out / "bearings.csv") and payload["bearings"] in payload["outputs"]
    lines = (out / "bearings.csv").read_text().splitlines()
    assert lines[0] == "t,bearing.0.Fy,bearing.0.Fz,bearing.1.Fy,bearing.1.Fz,bearing.2.Fx"
    import nsfem.result

    res, _, _ = nsfem.result.Result.load(out / "result.npz")
    assert len(lines) == 1 + res.t.size and not (out / "bearings.png").exists()


def test_damped_modes_in_the_rotating_frame_are_the_inertial_ones_seen_from_the_shaft():
    """The rub rotor (axisymmetric, isotropic bearing) in both frames: a mode whirling with sense s at omega in
    space is seen from the shaft at |omega - s Omega| with the same decay rate Re(lambda) and the same whirl
    reported (at 40 Hz, above the first forward whirl at 26 Hz: seen from the shaft it turns backwards, and is
    still reported forward). Tolerance 1e-7 of the largest |lambda|: the eigen solvers' round-off on a
    10-element model."""
    speed = 40.0
    W = 2 * math.pi * speed
    base = ["reduction.method=none", "mesh.elements=10", f"rotation.speed_hz={speed}"]
    found = {}
    for frame in ("inertial", "rotating"):
        scene = load_scene("rub", base + [f"rotation.frame={frame}"])
        found[frame] = scene_damped_modes(scene, build_model(scene), speed, 8)
    ine, rot = found["inertial"], found["rotating"]
    scale = 1e-7 * np.abs(ine.eigenvalues).max()
    sign = {"forward": 1, "backward": -1}
    for lam, w in zip(ine.eigenvalues[:4], ine.whirl[:4]):
        seen = lam.real + 1j * abs(lam.imag - sign[w] * W)
        k = int(np.argmin(np.abs(rot.eigenvalues - seen)))
        assert abs(rot.eigenvalues[k] - seen) <= scale, (lam, w, rot.eigenvalues)
        assert rot.whirl[k] == w


def test_campbell_branches_carry_the_damped_modes_log_decrements(capsys):
    """campbell --json's branches at a speed of its grid are the damped modes of modes --speed there: each shown
    branch's frequency and log decrement are those of one mode (1e-8 relative: two eigen solves of one model,
    the shift-invert solver's round-off), and its log decrement is 2 pi zeta / sqrt(1 - zeta^2) of its ratio."""
    from nsfem import cli

    damped = [f"bearing.{i}.c{a}=1000" for i in (0, 1) for a in ("yy", "zz")]
    sets = [x for kv in ["mesh.elements=6", "reduction.method=none", *damped] for x in ("--set", kv)]
    assert cli.main(["campbell", "ross_example", *sets, "--speeds", "0:60:3", "--count", "4", "--json"]) == 0
    branches = json.loads(capsys.readouterr().out)["branches"]["open"]
    scene = load_scene("ross_example", ["mesh.elements=6", "reduction.method=none", *damped])
    modes = scene_damped_modes(scene, build_model(scene), 60.0, 12)
    assert branches
    for b in branches:
        f, z, d = b["frequencies_hz"][-1], b["damping_ratio"][-1], b["log_decrement"][-1]
        if f is None:
            continue
        k = int(np.argmin(np.abs(modes.frequencies_hz - f)))
        assert modes.frequencies_hz[k] == pytest.approx(f, rel=1e-8)
        assert modes.log_decrements[k] == pytest.approx(d, rel=1e-8, abs=1e-12)
        assert d == pytest.approx(float(log_decrement(z)), rel=1e-12, abs=1e-15)


_RUB = {}


def rub_model(frame: str):
    """The rub rotor's 6-element model in ``frame`` (built once)."""
    if frame not in _RUB:
        _RUB[frame] = build_model(load_scene("rub", ["reduction.method=none", "mesh.elements=6",
                                                     f"rotation.frame={frame}"]))
    return _RUB[frame]


from hypothesis import given, settings, strategies as st  # noqa: E402


@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(speed=st.floats(0.0, 300.0), phase=st.floats(-180.0, 180.0),
       amp=st.tuples(*[st.floats(-1e-3, 1e-3)] * 4), w=st.floats(0.0, 2000.0))
def test_bearing_forces_do_not_depend_on_the_frame_a_run_is_computed_in(speed, phase, amp, w):
    """One motion of the bearing's node, u(t) = Re(a e^{i w t}) in space, handed over in the inertial frame and
    in the rotating one (u_r = R(-theta) u, u_r' = R(-theta) (u' - Omega J u), theta = Omega t + phi): the
    same forces. Round-off: 1e-9 of the largest force (the turn's cos/sin at theta up to 2e3 rad), at least
    1e-12 N (a motion of round-off size)."""
    from nsfem.analysis.reactions import QUARTER_TURN, bearing_force_histories

    t = np.linspace(0.0, 0.1, 17)
    a = np.array([amp[0] + 1j * amp[1], amp[2] + 1j * amp[3]])
    u = np.real(a[:, None] * np.exp(1j * w * t))
    du = np.real(1j * w * a[:, None] * np.exp(1j * w * t))
    W = 2 * math.pi * speed
    th = W * t + math.radians(phase)
    c, s = np.cos(th), np.sin(th)
    ur = np.array([c * u[0] + s * u[1], -s * u[0] + c * u[1]])
    dd = du - W * (QUARTER_TURN @ u)
    dur = np.array([c * dd[0] + s * dd[1], -s * dd[0] + c * dd[1]])
    F = {}
    for frame, (uu, vv) in (("inertial", (u, du)), ("rotating", (ur, dur))):
        model = rub_model(frame)
        b = model.stack.bearings[0]
        seg = model.stack.carrier(b.x)
        iv, iw = model.dof(seg, "V", b.x), model.dof(seg, "W", b.x)
        q, v = np.zeros((model.n_full, t.size)), np.zeros((model.n_full, t.size))
        q[[iv, iw]], v[[iv, iw]] = uu, vv
        F[frame] = bearing_force_histories(model, np.eye(model.n_full), t, q, v, frame, speed, phase)
    assert np.abs(F["rotating"] - F["inertial"]).max() <= 1e-9 * np.abs(F["inertial"]).max() + 1e-12


def test_a_free_rotors_rigid_motions_are_not_listed_as_modes():
    """retainer_drop's rotor floats free (its magnetic bearings off, the retainer rings open): its rigid
    translations and precession are roots at 0, split by round-off into pairs of about sqrt(eps) omega_max
    (measured 1.8e-4 Hz); none is a mode. The first mode is the forward nutation, at a sizeable fraction of the
    speed (Ip / Id Omega for a rigid rotor), so every reported frequency is above 1 Hz."""
    scene = load_scene("retainer_drop", [])
    modes = scene_damped_modes(scene, build_model(scene), 100.0, 4)
    assert len(modes.whirl) == 4 and modes.frequencies_hz.min() > 1.0
    assert modes.whirl[0] == "forward"
