"""A rigid stator ring (polygon of facets) around a Jeffcott rotor: full annular rub, with and without
friction against the sliding shaft surface, against its closed form, from `stationary` and as the limit
of a damped transient, in both frames; energy with restitution 1 and with friction."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_rotor_components import E, rotor_tree

from nsfem.analysis.stationary import scene_stationary
from nsfem.errors import SceneError
from nsfem.integrate import core
from nsfem.scene import scene_from_tree
from nsfem.simulate import run_scene

D, L, M, ME, C_E, CLEARANCE = 0.02, 0.8, 5.0, 1e-3, 40.0, 1e-4
K = 48 * E * (math.pi * D**4 / 64) / L**3      # midspan stiffness of the shaft
WN = math.sqrt(K / M)


def rub_tree(facets, frame="rotating", speed_ratio=0.8, restitution=0.0, damper=C_E, beta=0.0, friction=0.0,
             shape="polygon", **extra):
    """The Jeffcott rub scene; ``shape`` polygon by default: these tests hold the polygon's closed forms
    (the round ring's: tests/test_round_ring.py)."""
    tree = rotor_tree(10, D, rho=1.0, length=L, disk=[{"x": L / 2, "mass": M}],
                      bearing=[{"x": L / 2, "cyy": damper, "czz": damper}] if damper else [],
                      unbalance=[{"x": L / 2, "magnitude": ME}],
                      stator=[{"x": L / 2, "clearance": CLEARANCE, "facets": facets, "restitution": restitution,
                               "friction": friction, "shape": shape}],
                      rotation={"speed_hz": speed_ratio * WN / (2 * math.pi), "gravity": 0.0, "frame": frame},
                      damping={"rayleigh": [0.0, beta]}, reduction={"method": "craig-bampton", "modes": 4})
    tree.update(extra)
    return tree


def ring_force(r, w, mu=0.0):
    """Full annular rub of a Jeffcott rotor on a rigid circle of radius r, synchronous: the ring force
    N from ((k - m w^2) r + N)^2 + (c w r + mu N)^2 = (m e w^2)^2 (the larger root)."""
    a, b, f = (K - M * w * w) * r, C_E * w * r, ME * w * w
    p = a + mu * b
    return (-p + math.sqrt(p * p - (1 + mu * mu) * (a * a + b * b - f * f))) / (1 + mu * mu)


def polygon_forces(closed, facets, w, mu=0.0):
    """The same on the polygon: the disk rests on the closed facets (one: anywhere on it; two: at
    their vertex); (k - m w^2 + i c w) z + sum N_j (1 + i mu) n_j = m e w^2 in the rotating frame
    (complex y + i z; the friction force -mu N_j i n_j on the shaft opposes the surface sliding forward
    past the ring), solved for the facets' forces (and the position along a single facet). Returns
    the forces and the condition number of that solve (its columns scaled to unit length: the unknowns
    are in N and m)."""
    A = K - M * w * w + 1j * C_E * w
    n = [np.exp(2j * math.pi * j / facets) for j in closed]
    if len(closed) == 1:
        rhs = ME * w * w / n[0] - A * CLEARANCE        # A i s + (1 + i mu) N = rhs, s along the facet
        G = np.array([[(1j * A).real, 1.0], [(1j * A).imag, mu]])
        return np.linalg.solve(G, [rhs.real, rhs.imag])[1:], np.linalg.cond(G / np.linalg.norm(G, axis=0))
    z = CLEARANCE / math.cos(math.pi / facets) * (n[0] + n[1]) / abs(n[0] + n[1])   # adjacent facets' vertex
    rhs = ME * w * w - A * z
    m = [(1 + 1j * mu) * x for x in n]
    G = np.array([[m[0].real, m[1].real], [m[0].imag, m[1].imag]])
    return np.linalg.solve(G, [rhs.real, rhs.imag]), np.linalg.cond(G / np.linalg.norm(G, axis=0))


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
    np.testing.assert_allclose(st.normal_force[closed], polygon_forces(list(closed), facets, w)[0], rtol=1e-4)
    # the polygon lies within CLEARANCE (1 / cos(pi / facets) - 1) of the circle; the ring force moves by
    # about 0.4 of that relative change (|k - m w^2| r / N) plus the turn of the force at a vertex: twice
    # the relative distance bounds it (measured 3.4e-3 of 3.9e-2 at 16 facets, 1.15e-3 of 2.4e-3 at 64)
    total = abs(sum(st.normal_force[j] * np.exp(2j * math.pi * j / facets) for j in closed))
    assert abs(total / ring_force(CLEARANCE, w) - 1) <= 2 * (1 / math.cos(math.pi / facets) - 1)


def test_a_damped_transient_from_rest_ends_in_the_stationary_rub():
    # beta damps the shaft's own modes (zeta about 0.5 at 1e5 rad/s); a larger beta overdamps them (the test
    # below: the search samples at their decay rate only until they have died out)
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
    for key, value, match in (("damping", 10.0, "stator.0.damping: damping belongs to an elastic ring"),
                              ("x", 5.0, "stator.0.x: x=5.0 must lie on the intact shaft"),
                              ("facets", 2, "stator.0.facets: must lie in"),
                              ("x", 0.0, "stator.0.x: x=0.0 is a support")):
        tree = rub_tree(16)
        tree["stator"][0][key] = value
        with pytest.raises(SceneError, match=match):
            scene_from_tree(tree)


def test_two_stators_too_close_name_the_stator():
    """Two rings at one x, or too close for the mesh: the error names the second ring's x (not a facet's label)."""
    tree = rub_tree(8)
    tree["stator"].append(dict(tree["stator"][0]))
    with pytest.raises(SceneError, match=r"^stator\.1\.x: duplicate contact point"):
        scene_from_tree(tree)
    tree["stator"][1]["x"] = tree["stator"][0]["x"] + 1e-7
    with pytest.raises(SceneError, match=r"^stator\.[01]\.x: nodes at x="):
        scene_from_tree(tree)


def test_shipped_rub_scene_is_the_closed_form():
    """`nsfem stationary rub`: the shipped Jeffcott rub against the circle's closed form with friction, read
    off its own keys (disk, damper, unbalance, ring), within the polygon's distance from the circle."""
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
    mu = ring["friction"]
    a_, b_, f_ = (k - m_eff * w * w) * r, c * w * r, me * w * w
    N = (-(a_ + mu * b_) + math.sqrt((a_ + mu * b_) ** 2 - (1 + mu * mu) * (a_ * a_ + b_ * b_ - f_ * f_))) / (1 + mu * mu)
    assert mu > 0
    st = scene_stationary(scene)
    closed = np.flatnonzero(st.normal_force > 0)
    total = abs(sum(st.normal_force[j] * np.exp(2j * math.pi * j / ring["facets"]) for j in closed))
    # Rayleigh's 17/35 is itself within 1e-3 of the shaft's true share at this mass ratio (0.4)
    assert total == pytest.approx(N, rel=2 * (1 / math.cos(math.pi / ring["facets"]) - 1) + 1e-3)


@pytest.mark.parametrize("name", ["default", "ross_example", "rub", "critical_speed", "retainer_drop", "crack",
                                  "stepped_rotor", "runup"])
def test_shipped_scenes_run(name, tmp_path):
    from nsfem import load_scene

    scene = load_scene(name, ["simulation.t_end=0.02", "simulation.output_dt=1e-3"])
    # a run-up is refused by exact (constant speeds only): it runs rk, whose energy balance holds to its
    # solver tolerance (rtol 1e-8, accumulated over the run: 1e-7), exact's to round-off (1e-9)
    method, bound = ("rk", 1e-7) if scene.rotation.ramp_to_hz is not None else ("exact", 1e-9)
    res, _ = run_scene(scene, method)
    assert res.completed and abs(res.energy["relative_residual"]) < bound


def test_review_fixes_critical_speed_of_an_unsplit_pair_gap_panel_and_radius(tmp_path):
    """A disk at midspan on isotropic supports: the spin does not split its pair, the solver returns
    two planar vectors, and the critical speed is still listed, once (the rotating frame's divergence
    speed of the same rotor); a stator's facets share one panel of the gap plot."""
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


# --- friction against the sliding shaft surface ----------------------------------------------------

@pytest.mark.parametrize("mu", [0.1, 0.3])
def test_frictional_full_annular_rub_is_a_stationary_state(mu):
    """Rotating frame: LCP (28) with the friction's direction known (the shaft surface slides forward past
    the ring at Omega (R + clearance)): the facets' forces are the polygon's closed form with friction.
    The model differs from it by the light shaft's mass (ratio 5e-5), which the solve for the forces
    amplifies by its condition number (about 20 at a vertex of 64 facets): the tolerance is twice
    their product. The resultant tends to the circle's closed form with mu N in the tangential balance."""
    scene = scene_from_tree(rub_tree(64, friction=mu))
    w = 2 * math.pi * scene["rotation"]["speed_hz"]
    st = scene_stationary(scene)
    closed = np.flatnonzero(st.normal_force > 0)
    assert 1 <= len(closed) <= 2 and all(st.state[k] == "slip" for k in closed)
    forces, cond = polygon_forces(list(closed), 64, w, mu)
    np.testing.assert_allclose(st.normal_force[closed], forces, rtol=2 * 5e-5 * cond)
    # the friction force on the shaft opposes the surface's motion (along -t) and is mu N
    for k in closed:
        assert st.tangential_force[k][0] == pytest.approx(-mu * st.normal_force[k], rel=1e-12)
    total = abs(sum(st.normal_force[j] * np.exp(2j * math.pi * j / 64) for j in closed))
    assert abs(total / ring_force(CLEARANCE, w, mu) - 1) <= 2 * (1 / math.cos(math.pi / 64) - 1)
    # friction matters here: without it the ring force differs by more than that tolerance
    assert abs(ring_force(CLEARANCE, w, mu) / ring_force(CLEARANCE, w) - 1) > 4 * (1 / math.cos(math.pi / 64) - 1)


def test_frictional_rub_from_rest_ends_in_the_stationary_state_and_friction_dissipates():
    """Rotating frame, exact: the damped transient from rest (impacts with frictional impulses against the
    moving surface, then sliding) ends in LCP (28)'s state; the work balance, in which the spin does the
    work that friction dissipates, closes to round-off; moreau reaches the same state within its step's
    first-order error."""
    scene = scene_from_tree(rub_tree(16, beta=1e-5, friction=0.1, simulation={"t_end": 4.0, "output_dt": 1e-3}))
    st = scene_stationary(scene)
    closed = np.flatnonzero(st.normal_force > 0)
    res, _ = run_scene(scene, "exact")
    assert np.flatnonzero(res.normal_force[:, -1] > 0).tolist() == closed.tolist()
    # the slowest mode in contact decays as e^-4t (c / 2m): 1e-7 of the force is left after 4 s
    np.testing.assert_allclose(res.normal_force[closed, -1], st.normal_force[closed], rtol=1e-6)
    e = res.energy
    assert len(res.impacts) > 3 and e["dissipated_friction_J"] > 0 and e["work_spin_J"] > 0
    # the spin's work (8 J) and the friction's dissipation cancel to the rotor's energy (1e-3 J): the residual
    # is round-off of the larger terms (measured 3e-15 J)
    assert abs(e["residual_J"]) < 1e-12 * e["work_spin_J"]
    mor, _ = run_scene(scene, "moreau")
    # moreau's step (1e-3 / 10 = 1e-4 s) against the slowest contact mode's 0.25 s time constant and the
    # 45 ms period: first-order errors of a few 1e-4 (measured 9e-5 and 4e-4)
    np.testing.assert_allclose(mor.normal_force[closed, -1], st.normal_force[closed], rtol=2e-3)
    assert mor.energy["dissipated_friction_J"] > 0


def test_inertial_frame_ring_load_with_friction_is_the_closed_form():
    """Inertial frame: the rotor whirls round the polygon fixed in space, delivering the centripetal part
    of the ring load at the corners as plastic impacts (9.9 N of 14 N as impulses). The ring's load
    averaged over whole revolutions, forces and impulses, is the circle's closed form with friction to the
    polygon's distance from the circle (measured 1.5e-3 at 32 facets); the tangential force on the shaft
    is -mu N throughout (the surface slides forward at Omega R)."""
    mu, facets = 0.3, 32
    scene = scene_from_tree(rub_tree(facets, frame="inertial", beta=1e-5, friction=mu,
                                     simulation={"t_end": 1.5, "output_dt": 1e-4}))
    w = 2 * math.pi * scene["rotation"]["speed_hz"]
    res, _ = run_scene(scene, "exact")
    t1 = res.t[-1]
    t0 = t1 - 20 * 2 * math.pi / w          # 20 whole revolutions, after the start has died out (e^-4t)
    late = res.t >= t0
    force = np.trapezoid(res.normal_force[:, late].sum(axis=0), res.t[late]) / (t1 - t0)
    impulses = sum(sum(i["impulse_Ns"]) for i in res.impacts if i["t"] >= t0) / (t1 - t0)
    assert abs((force + impulses) / ring_force(CLEARANCE, w, mu) - 1) <= 2 * (1 / math.cos(math.pi / facets) - 1)
    on = res.normal_force > 0
    np.testing.assert_allclose(res.tangential_force[:, 0][on], -mu * res.normal_force[on], rtol=1e-12)
    e = res.energy
    assert e["dissipated_friction_J"] > 0 and abs(e["relative_residual"]) < 1e-9


def test_friction_never_adds_energy_and_elastic_impacts_keep_the_balance():
    """Restitution 1 with friction, inertial frame, no damping: every contact is an impact (no sliding
    phase), whose frictional impulse against the moving surface dissipates (never a gain) while the spin
    does work through it; the balance closes to round-off."""
    scene = scene_from_tree(rub_tree(32, frame="inertial", restitution=1.0, damper=0.0, friction=0.2,
                                     simulation={"t_end": 0.3, "output_dt": 1e-3}))
    res, _ = run_scene(scene, "exact")
    e = res.energy
    assert len(res.impacts) > 10 and e["work_spin_J"] != 0.0 and e["lost_in_impacts_J"] > 0
    # the spin pumps the whirl up (backward whirl: 10 J after 0.3 s); round-off per event over some 3000
    # impacts (measured 7e-13 of the largest energy)
    assert abs(e["relative_residual"]) < 1e-9
    # per impact: the loss (kinetic energy removed less the spin's work through the impulse) is never negative
    for imp in res.impacts:
        loss = imp["kinetic_before_J"] - imp["kinetic_after_J"] + imp.get("work_spin_J", 0.0)
        assert loss >= -1e-12 * e["max_J"]


def test_a_block_dragged_by_a_moving_surface_until_it_rolls_with_it():
    """A unit mass pressed by F onto a surface moving at w (slip velocity y' + w): friction -mu F along y
    accelerates it until y' = -w at t = w / (mu F), in closed form; there it would stick to (move with) the
    surface, which the event-driven methods refuse with a clear error at that instant, and moreau holds."""
    from nsfem.contact.set import ContactSet
    from nsfem.errors import IntegrationError
    from nsfem.integrate import ContactSystem, integrate

    F, mu, w, clearance = 2.0, 0.5, 0.3, 1e-3
    cs = ContactSet.from_arrays([[0.0], [-1.0]], [clearance], mu=mu, JS=[np.array([[1.0], [0.0]])], r=2,
                                wS=[np.array([w])])
    system = ContactSystem.from_arrays(M=np.eye(2), Q=np.zeros((2, 2)), f0=[0.0, F], contacts=cs)
    t_roll = w / (mu * F)
    with pytest.raises(IntegrationError, match="stick to the stator's moving surface") as err:
        integrate(system, 1.0, "exact", 1e-3, q0=[0.0, clearance], v0=[0.0, 0.0])
    part = err.value.result
    assert float(str(err.value).split("t = ")[1].split(" s")[0]) == pytest.approx(t_roll, rel=1e-12)
    # sliding before it: y' = -mu F t exactly
    np.testing.assert_allclose(part.v[0], -mu * F * part.t, rtol=1e-12, atol=1e-15)
    mor = integrate(system, 1.0, "moreau", 1e-3, q0=[0.0, clearance], v0=[0.0, 0.0])
    after = mor.t > t_roll + 2e-3
    # moreau: implicit steps of 1e-4 s; the velocity settles on -w to the LCP's round-off once it sticks
    np.testing.assert_allclose(mor.v[0, after], -w, rtol=1e-9)
    assert np.all(mor.state[0, after] == 1)


def test_retainer_drop_falls_freely_then_friction_pushes_it_up_the_side_the_surface_leaves():
    """The shipped retainer drop: until the first impact the rotor's vertical momentum is -m g t exactly (no
    lateral support is left; the reduced basis carries the rigid translation, so the momentum r^T M T v of
    the model is that of its rigid body to round-off); the first impact comes after the rigid fall time
    through the clearance (the elastic rotor's ends lag behind its centre of mass at first); friction then
    drives the shaft towards -y at the bottom (the surface there moves towards +y); the work balance,
    with the spin's work through friction, closes to round-off and friction only dissipates."""
    from nsfem import build_model, load_scene
    from nsfem.fem.constraints import dense

    scene = load_scene("retainer_drop", ["unbalance.0.magnitude=0.0", "simulation.t_end=0.05",
                                         "simulation.output_dt=1e-4"])
    res, system = run_scene(scene, "exact")
    model, T = system.info["model"], dense(system.info["reduction"].T)      # q_full = T q
    r = np.zeros(model.n_full)
    for seg in model.stack.segments:   # a rigid vertical translation: W = 1 at every node, slopes 0
        space = model.spaces[seg.name]
        r[space.dofs["W"][space.bending.nodal_dofs[0]]] = 1.0
    Mr = T.T @ (model.M_full @ r)
    mass = float(r @ (model.M_full @ r))
    assert mass == pytest.approx(10.0 + 7850.0 * math.pi / 4 * 0.05**2 * 0.6, rel=1e-12)   # disk and shaft
    g = scene["rotation"]["gravity"]
    t_hit = res.impacts[0]["t"]
    before = res.t < t_hit
    # round-off of the closed form: the momentum is a sum of terms of the size of the elastic swing's
    # momentum, about the rigid one's, to 1e-12 each
    np.testing.assert_allclose(Mr @ res.v[:, before], -mass * g * res.t[before], rtol=0, atol=1e-10 * mass * g * t_hit)
    assert t_hit > math.sqrt(2 * scene["stator"][0]["clearance"] / g)
    # friction against the spin at the bottom of the rings: the shaft is pushed towards -y first
    bottom = [k for k, lab in enumerate(system.contacts.labels) if lab.endswith(".24")]   # 24 of 32: angle -90 deg
    on = np.flatnonzero(np.any(res.normal_force[bottom] > 0, axis=0))
    assert on.size and np.all(res.tangential_force[bottom, 0][:, on] <= 0.0)
    e = res.energy
    assert e["dissipated_friction_J"] > 0 and e["lost_in_impacts_J"] > 0 and e["work_spin_J"] > 0
    # the balance is a sum over ~240 phases of closed-form work integrals (friction and the spin's work, 35 J each,
    # cancel to an E of 0.05 J): each phase's integral carries round-off of a few hundred eps of that phase's
    # turnover (rigid-body phases sum divided-difference terms larger than the state they make), so the balance
    # is bounded by 1e-11 of the run's turnover, not by E (measured 1e-13 to 2e-12 of it across BLAS kernels
    # and both cores; Gauss quadrature of the same phases, before issue 33, 1e-13)
    turnover = sum(abs(e[k]) for k in ("work_external_J", "dissipated_damping_J", "work_circulatory_J",
                                       "dissipated_friction_J", "work_spin_J", "lost_in_impacts_J"))
    assert abs(e["residual_J"]) < 1e-11 * turnover


def test_review_fixes_moving_surfaces():
    """A moving surface on a two-dimensional friction cone is refused (a force on a polygon facet is held by a
    fixed slip); a model with a frictional stator needs its speed to build its contact set; LCP (29) with a
    moving surface needs the velocity; the stationary loop accepts a state whose slip rates all vanish."""
    from nsfem import build_model, load_scene
    from nsfem.contact.set import ContactSet
    from nsfem.errors import NsfemError
    from nsfem.lcp.builders import transition_lcp
    from nsfem.linalg import factorize

    with pytest.raises(NsfemError, match="two-dimensional friction cone"):
        ContactSet.from_arrays([[0.0], [0.0], [-1.0]], [0.0], mu=0.5, JS=[np.eye(3)[:, :2]], r=4,
                               wS=[np.array([1.0, 0.0])])
    with pytest.raises(NsfemError, match="pass omega"):
        ContactSet.from_model(build_model(load_scene("rub")))
    cs = ContactSet.from_arrays([[0.0], [-1.0]], [0.0], mu=0.5, JS=[np.array([[1.0], [0.0]])], r=2,
                                wS=[np.array([0.3])])
    with pytest.raises(NsfemError, match="needs the velocity"):
        transition_lcp(cs, factorize(np.eye(2)), np.array([0.0, 1.0]), [0], [0])
    # Sq^T q + w = 0 at the stationary state: no direction, the contact sticks (a surface at rest there)
    from nsfem.analysis.stationary import stationary
    still = ContactSet.from_arrays([[0.0], [-1.0]], [1e-3], mu=0.5, JS=[np.array([[1.0], [0.0]])], r=2,
                                   JSq=[np.array([[0.0], [-1.0]])], wS=[np.array([1e-3])])
    st = stationary(np.eye(2), np.array([0.0, 1.0]), still)
    # lam_N = 1 - clearance exactly (Q = I, unit load); Lemke's polish leaves round-off, far below pytest's 1e-6
    assert st.state == ["stick"] and st.normal_force[0] == pytest.approx(1.0 - 1e-3)


def test_overdamped_stiff_modes_stop_setting_the_search_step(monkeypatch):
    """Rayleigh beta 1e-4 overdamps the shaft's stiff modes (real roots near -1e4 (two), -2e6 and -4.9e6 1/s
    next to the rub's 35 and 316 rad/s): once such a term has decayed into its row's budget the search
    no longer samples at its rate (issue 33: 72 000 search chunks for 4 s before). Counted: the samples
    the search evaluates per phase (``Phase.search_samples``) against what the oscillating modes need."""
    import nsfem.integrate.configuration as configuration
    import nsfem.integrate.event_driven as event_driven

    searched = []

    def counted(phase, rows, t0, t1, report=None):
        ev = first_event(phase, rows, t0, t1, report)
        searched.append((t1 if ev is None else ev.t) - t0)
        searched.append(phase.search_samples)
        searched.append(phase.config.eigenvalues)
        return ev

    first_event = event_driven.first_event
    monkeypatch.setattr(event_driven, "first_event", counted)
    scene = scene_from_tree(rub_tree(16, beta=1e-4, simulation={"t_end": 0.1, "output_dt": 1e-3}))
    res, _ = run_scene(scene, "exact")
    spans, samples, spectra = searched[0::3], searched[1::3], searched[2::3]
    # what the oscillating modes (|Im| > |Re|) need: a step of 1/8 of the fastest one's period
    need = sum(dt * 4 * max(abs(x) for x in lam if abs(x.imag) > abs(x.real)) / math.pi
               for dt, lam in zip(spans, spectra))
    overdamped = [x for x in spectra[0] if abs(x.imag) < abs(x.real) and x.imag >= 0]
    assert len(overdamped) == 4 and max(abs(x) for x in overdamped) > 1e6
    # each overdamped pair sets the step until it has decayed by at most 1e16 (its size against a band of
    # 1e-11 of the row, down to round-off terms): (4 / pi) ln(1e16) |lam| / |Re lam| = 47 samples at its own
    # step, 50 with the chunks' shared ends, for each of the 4 per phase (measured: 691 in all, the
    # oscillating modes needing 731; 435 000 when the decayed terms set the step)
    assert 0 < sum(samples) <= need + 200 * len(spans), (sum(samples), need)
    # the same run with the old bound (a decaying term at its initial size over the whole horizon), on the
    # reference path: the compiled search forms its renewals in C (configuration._renewal is its reference)
    monkeypatch.setattr(configuration, "_renewal", lambda *args: math.inf)
    with core.reference():
        ref, _ = run_scene(scene, "exact")
    assert [(e["kinds"], e["contacts"], e["impact"]) for e in res.events] == \
        [(e["kinds"], e["contacts"], e["impact"]) for e in ref.events]
    # both locate each root to its row's band (1e-11 of its terms): with slopes of the terms' size
    # times the rub's 35..316 rad/s that is below 3e-13 s per root; the next phase starts from that
    # state, so the differences compound over the 19 events (measured 8e-13 relative at most)
    np.testing.assert_allclose([e["t"] for e in res.events], [e["t"] for e in ref.events], rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.normal_force, ref.normal_force, rtol=0, atol=1e-9 * np.abs(ref.normal_force).max())
