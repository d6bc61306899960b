"""Critical speeds of rotors on cross-coupled bearings (issue 32: they used to ignore the skew stiffness)."""

from __future__ import annotations

import math

import numpy as np

from nsfem.analysis.whirl import critical_speeds
from nsfem.fem import build_model
from nsfem.fem.components import lateral_turn
from nsfem.fem.rotating import rotor_operators
from nsfem.scene import load_scene, scene_from_tree
from nsfem.system import linear_system
from nsfem.analysis.campbell import state_eigenvalues

E, D, L, M_DISK = 2.1e11, 0.02, 0.8, 5.0


def jeffcott_model(q: float):
    """A 5 kg disk (no rotary inertia) at the middle of a pinned-pinned shaft of density 1 (mass 5e-5 of the
    disk's), a bearing at the disk with only cross coupling: K = [[0, q], [-q, 0]]."""
    tree = {"shaft": {"length": L, "section": "circle", "diameter": D, "E": E, "rho": 1.0,
                      "supports": "pinned-pinned"},
            "mesh": {"elements": 4}, "reduction": {"method": "none"},
            "disk": [{"x": L / 2, "mass": M_DISK}],
            "bearing": [{"x": L / 2, "kyz": q, "kzy": -q}],
            "rotation": {"speed_hz": 0.0, "gravity": 0.0, "frame": "inertial"}}
    return build_model(scene_from_tree(tree))


def test_jeffcott_critical_speed_with_cross_coupling_closed_form():
    """The disk's motion r = v + i w obeys m r'' + (k - i q) r = 0 (k = 48 E I / L^3), so it whirls at
    w = Re sqrt((k - i q) / m) whatever the speed (no gyroscopic couple at midspan): the crossing of that
    whirl frequency with the 1x line is the critical speed, above sqrt(k / m) by the factor
    Re sqrt(1 - i q / k). The shaft's mass (ratio 5e-5) shifts it by about 1e-5, the brentq refinement
    by 1e-10: rtol 1e-4. The coupling here raises it by 5.9 %, far beyond that tolerance."""
    k = 48 * E * (math.pi * D**4 / 64) / L**3
    q = 0.7 * k
    model = jeffcott_model(q)
    crit, _ = critical_speeds(rotor_operators(model), lateral_turn(model.spaces, model.n_full), max_hz=40.0)
    exact = (np.sqrt((k - 1j * q) / M_DISK)).real / (2 * math.pi)
    assert exact > 1.05 * math.sqrt(k / M_DISK) / (2 * math.pi)
    np.testing.assert_allclose(crit[:2], exact, rtol=1e-4)
    # the bearing is isotropic ([[k, q], [-q, k]] commutes with a turn): an unbalance drives the forward
    # root alone, one critical speed, forward (the backward root crosses at the same speed)
    fwd, sense = critical_speeds(rotor_operators(model), lateral_turn(model.spaces, model.n_full), max_hz=40.0,
                                 forward_only=True)
    np.testing.assert_allclose(fwd, [exact], rtol=1e-4)
    assert sense.tolist() == [1]


def test_cross_coupled_critical_speeds_are_synchronous_roots():
    """ROSS's rotor with a cross-coupled bearing (gyroscopic, anisotropic): at each critical speed the
    undamped rotor has a whirl root whose frequency equals the speed (Brent to 1e-10 of the speed, the
    eigenvalues to round-off of the 48-state problem: 1e-8), and the coupling moves the first ones by more
    than 1 % (the cross-coupling-free speeds would fail the first assertion).

    Independent reference: ROSS 2.3.0 (ross-rotordynamics, in a separate venv) on rotor_example() rebuilt with
    ShaftElement(shear_effects=False) (the Rayleigh beam, whose matrices equal ours to 1e-12) and
    BearingElement(0, kxx=1e6, kyy=8e5, kxy=1e7, kyx=-1e7): brentq to 1e-13 on s - run_modal(s).wd[j], the
    crossing its run_critical_speed finds by Newton to 0.5 %. Agreement 1e-8 measured; rtol 1e-7 allows
    ROSS's and our eigen solvers' round-off on roots of growth rates 0.02-0.15 log dec."""
    scene = load_scene("ross_example", ["mesh.elements=6", "reduction.method=\"none\"", "bearing.0.kyz=1e7",
                                        "bearing.0.kzy=-1e7"])
    model = build_model(scene)
    ops = rotor_operators(model)
    crit, whirl = critical_speeds(ops, lateral_turn(model.spaces, model.n_full), max_hz=70.0, count=4)
    ross = (16.524382901678308, 16.970405767360283, 56.11158162707585, 60.64412270768715)
    np.testing.assert_allclose(crit, ross, rtol=1e-7)
    assert whirl.tolist() == [-1, 1, -1, 1]   # ROSS: Backward, Forward, Backward, Forward
    for speed in crit:
        lam = state_eigenvalues(linear_system(ops, speed, frame="inertial"), 12)
        assert np.min(np.abs(lam.imag / (2 * math.pi) - speed)) < 1e-8 * speed
    free = (14.617, 15.336, 43.222, 47.880)   # the same rotor without the coupling
    assert all(np.min(np.abs(crit - f)) > 0.01 * f for f in free[:2])


def test_vanishing_cross_coupling_leaves_the_critical_speeds_of_a_damped_rotor():
    """Critical speeds are those of the undamped rotor with or without cross coupling: a coupling of 1e-3 N/m
    (1e-9 of the bearings' stiffness) on bearings damped with 1e4 N s/m (about 0.8 of critical on the rigid
    modes) moves them by O(1e-9), well inside rtol 1e-7 (Brent's 1e-10 of the speed plus that). The crossing
    path once kept the bearing damping (16.75 / 16.80 Hz, two speeds instead of four) and, the thrust
    bearing's axial root taking one of the count places, lost the fourth speed (47.88 Hz)."""
    damped = ["mesh.elements=6", "reduction.method=\"none\""] + [f"bearing.{i}.c{a}={1e4}" for i in (0, 1)
                                                                 for a in ("yy", "zz")]
    found = []
    for q in (0.0, 1e-3):
        model = build_model(load_scene("ross_example", damped + [f"bearing.0.kyz={q}", f"bearing.0.kzy={-q}"]))
        found.append(critical_speeds(rotor_operators(model), lateral_turn(model.spaces, model.n_full), max_hz=70.0,
                                     count=4))
    (plain, w0), (coupled, w1) = found
    assert plain.size == 4 and coupled.size == 4
    np.testing.assert_allclose(coupled, plain, rtol=1e-7)
    assert w0.tolist() == w1.tolist()
