"""A rigid stator ring (polygon of facets) around a Jeffcott rotor: full annular rub against its
closed form, from `stationary` and as the limit of a damped transient; energy with restitution 1."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_rotor_components import E, rotor_tree

from nsfem.analysis.stationary import scene_stationary
from nsfem.errors import SceneError
from nsfem.scene import scene_from_tree
from nsfem.simulate import run_scene

D, L, M, ME, C_E, CLEARANCE = 0.02, 0.8, 5.0, 1e-3, 40.0, 1e-4
K = 48 * E * (math.pi * D**4 / 64) / L**3      # midspan stiffness of the shaft
WN = math.sqrt(K / M)


def rub_tree(facets, frame="rotating", speed_ratio=0.8, restitution=0.0, damper=C_E, beta=0.0, **extra):
    tree = rotor_tree(10, D, rho=1.0, length=L, disk=[{"x": L / 2, "mass": M}],
                      bearing=[{"x": L / 2, "cyy": damper, "czz": damper}] if damper else [],
                      unbalance=[{"x": L / 2, "magnitude": ME}],
                      stator=[{"x": L / 2, "clearance": CLEARANCE, "facets": facets, "restitution": restitution}],
                      rotation={"speed_hz": speed_ratio * WN / (2 * math.pi), "gravity": 0.0, "frame": frame},
                      damping={"rayleigh": [0.0, beta]}, reduction={"method": "craig-bampton", "modes": 4})
    tree.update(extra)
    return tree


def ring_force(r, w):
    """Full annular rub of a Jeffcott rotor on a rigid circle of radius r, synchronous: the ring force
    N from ((k - m w^2) r + N)^2 + (c w r)^2 = (m e w^2)^2."""
    return -(K - M * w * w) * r + math.sqrt((ME * w * w) ** 2 - (C_E * w * r) ** 2)


def polygon_forces(closed, facets, w):
    """The same on the polygon: the disk rests on the closed facets (one: anywhere on it; two: at
    their vertex); (k - m w^2 + i c w) z + sum N_j n_j = m e w^2 in the rotating frame (complex
    y + i z), solved for the facets' forces (and the position along a single facet)."""
    A = K - M * w * w + 1j * C_E * w
    n = [np.exp(2j * math.pi * j / facets) for j in closed]
    if len(closed) == 1:
        rhs = ME * w * w / n[0] - A * CLEARANCE        # A i s + N = rhs, s along the facet
        s = rhs.imag / (1j * A).imag
        return np.array([rhs.real - (1j * A).real * s])
    z = CLEARANCE / math.cos(math.pi / facets) * (n[0] + n[1]) / abs(n[0] + n[1])   # adjacent facets' vertex
    rhs = ME * w * w - A * z
    G = np.array([[n[0].real, n[1].real], [n[0].imag, n[1].imag]])
    return np.linalg.solve(G, [rhs.real, rhs.imag])


@pytest.mark.parametrize("facets", [16, 64])
def test_full_annular_rub_is_a_stationary_state(facets):
    """Rotating frame: the synchronous rub is a stationary state (LCP 28). On the polygon the forces are
    the polygon's closed form to the light shaft's mass (ratio 5e-5: measured 1.7e-5); its resultant
    tends to the circle's closed form as the facets multiply."""
    scene = scene_from_tree(rub_tree(facets))
    w = 2 * math.pi * scene["rotation"]["speed_hz"]
    assert ME * w * w / math.hypot(K - M * w * w, C_E * w) > 3 * CLEARANCE      # free, it would whirl wider
    st = scene_stationary(scene)
    closed = np.flatnonzero(st.normal_force > 0)
    assert 1 <= len(closed) <= 2 and np.all(st.gap[closed] == pytest.approx(0.0, abs=1e-12 * CLEARANCE))
    assert np.all(st.gap >= -1e-12 * CLEARANCE)
    np.testing.assert_allclose(st.normal_force[closed], polygon_forces(list(closed), facets, w), rtol=1e-4)
    # the polygon lies within CLEARANCE (1 / cos(pi / facets) - 1) of the circle; the ring force moves by
    # about 0.4 of that relative change (|k - m w^2| r / N) plus the turn of the force at a vertex: twice
    # the relative distance bounds it (measured 3.4e-3 of 3.9e-2 at 16 facets, 1.15e-3 of 2.4e-3 at 64)
    total = abs(sum(st.normal_force[j] * np.exp(2j * math.pi * j / facets) for j in closed))
    assert abs(total / ring_force(CLEARANCE, w) - 1) <= 2 * (1 / math.cos(math.pi / facets) - 1)


def test_a_damped_transient_from_rest_ends_in_the_stationary_rub():
    # beta damps the shaft's own modes (zeta about 0.5 at 1e5 rad/s); a larger beta overdamps them, and the
    # search then samples at their decay rate (1e6 1/s and more) long after they have died out
    scene = scene_from_tree(rub_tree(16, beta=1e-5, simulation={"t_end": 4.0, "output_dt": 1e-3}))
    st = scene_stationary(scene)
    res, _ = run_scene(scene, "exact")
    closed = np.flatnonzero(st.normal_force > 0)
    assert np.flatnonzero(res.normal_force[:, -1] > 0).tolist() == closed.tolist()
    # decay: the slowest mode in contact (the damper along the facet, about c / 2m = 4 1/s) leaves
    # e^-16 = 1e-7 of the 14 N after 4 s
    np.testing.assert_allclose(res.normal_force[closed, -1], st.normal_force[closed], rtol=1e-6)
    assert len(res.impacts) > 3
    assert abs(res.energy["relative_residual"]) < 1e-10      # measured 5e-13


def test_elastic_impacts_on_a_rigid_ring_keep_the_energy():
    """Inertial frame, no damping, restitution 1, frictionless: the work balance closes to round-off
    and no energy is lost in the impacts."""
    scene = scene_from_tree(rub_tree(32, frame="inertial", restitution=1.0, damper=0.0,
                                     simulation={"t_end": 0.5, "output_dt": 1e-3}))
    res, _ = run_scene(scene, "exact")
    assert len(res.impacts) > 20
    e = res.energy
    # round-off per event of the closed form and the impact LCP, over some 50 events: measured 3e-11
    assert abs(e["relative_residual"]) < 1e-9
    assert abs(e["lost_in_impacts_J"]) < 1e-12 * e["max_J"]


def test_stator_inputs_refused():
    for key, value, match in (("friction", 0.3, "stator.0.friction: friction at a stator"),
                              ("stiffness", 1e6, "stator.0.stiffness: an elastic stator"),
                              ("x", 5.0, "stator.0.x: x=5.0 must lie on the intact shaft"),
                              ("facets", 2, "stator.0.facets: must lie in")):
        tree = rub_tree(16)
        tree["stator"][0][key] = value
        with pytest.raises(SceneError, match=match):
            scene_from_tree(tree)


def test_shipped_rub_scene_is_the_closed_form():
    """`nsfem stationary rub`: the shipped Jeffcott rub against the circle's closed form, read off its
    own keys (disk, damper, unbalance, ring), within the polygon's distance from the circle."""
    from nsfem import load_scene

    scene = load_scene("rub")
    disk, damper, ring = scene["disk"][0], scene["bearing"][0], scene["stator"][0]
    sh = scene["shaft"]
    k = 48 * sh["E"] * math.pi * sh["diameter"] ** 4 / 64 / sh["length"] ** 3
    m, c, me, w = disk["mass"], damper["cyy"], scene["unbalance"][0]["magnitude"], 2 * math.pi * scene["rotation"]["speed_hz"]
    r = ring["clearance"]
    # the shaft's own mass (7850 kg/m^3, 2 kg: about 1 kg moves with the disk) is part of the model, not of
    # the closed form: compare with the disk's mass plus the shaft's modal share 17/35 rho A L
    m_eff = m + 17 / 35 * sh["rho"] * math.pi * sh["diameter"] ** 2 / 4 * sh["length"]
    N = -(k - m_eff * w * w) * r + math.sqrt((me * w * w) ** 2 - (c * w * r) ** 2)
    st = scene_stationary(scene)
    closed = np.flatnonzero(st.normal_force > 0)
    total = abs(sum(st.normal_force[j] * np.exp(2j * math.pi * j / ring["facets"]) for j in closed))
    # Rayleigh's 17/35 is itself within 1e-3 of the shaft's true share at this mass ratio (0.4)
    assert total == pytest.approx(N, rel=2 * (1 / math.cos(math.pi / ring["facets"]) - 1) + 1e-3)


@pytest.mark.parametrize("name", ["default", "ross_example", "rub", "critical_speed"])
def test_shipped_scenes_run(name, tmp_path):
    from nsfem import load_scene

    scene = load_scene(name, ["simulation.t_end=0.02", "simulation.output_dt=1e-3"])
    res, _ = run_scene(scene, "exact")
    assert res.completed and abs(res.energy["relative_residual"]) < 1e-9


def test_review_fixes_critical_speed_of_an_unsplit_pair_gap_panel_and_radius(tmp_path):
    """A disk at midspan on isotropic supports: the spin does not split its pair, the solver returns
    two planar vectors, and the critical speed is still listed, once (the rotating frame's divergence
    speed of the same rotor); a stator's facets share one panel of the gap plot; an unused radius is
    refused."""
    from nsfem import build_model, load_scene
    from nsfem.analysis.campbell import divergence_speeds
    from nsfem.analysis.whirl import critical_speeds
    from nsfem.fem.components import lateral_turn
    from nsfem.fem.rotating import rotor_operators
    from nsfem.plot.results import delamination_middles

    scene = load_scene("rub", ['rotation.frame="inertial"', "reduction.method=none"])
    model = build_model(scene)
    ops = rotor_operators(model)
    crit, sense = critical_speeds(ops, lateral_turn(model.spaces, model.n_full), forward_only=True)
    # divergence speeds come in pairs for an isotropic rotor (one per plane); the same eigenproblem at rest
    assert crit[0] == pytest.approx(divergence_speeds(ops)[0], rel=1e-9) and crit[1] > 2 * crit[0]
    assert np.all(sense == 1)
    _, system = run_scene(load_scene("rub", ["simulation.t_end=0.001"]), "exact")
    groups = delamination_middles(system)
    assert [g["name"] for g in groups] == ["stator.0"] and len(groups[0]["indices"]) == 64
    with pytest.raises(SceneError, match="stator.0.radius"):
        load_scene("rub", ["stator.0.radius=0.5"])
