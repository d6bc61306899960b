"""Stationary contact states (LCP 28) against closed-form beam solutions and physics.

Euler-Bernoulli beams with Hermite cubic elements and consistent loads are nodally exact
(the static Green's function is cubic between nodes), so a pinned-pinned beam sagging
onto stops placed at nodes must reproduce the superposition solution to round-off.

Round-off: Q of the 20-element beam has condition 2.3e7, but the forward error of its LU
solve at a stop follows the componentwise condition (|Q^-1| |Q| |x|)_stop / |x_stop|, 8.3e4
(1.3e6 for the 40 elements of the shipped mesh): the free sag d0 and the influence w each
carry ~8.3e4 eps = 1.8e-11 (2.9e-10), and a stop force (d0 - c) / w that times
1 + d0 / (d0 - c). Measured under four BLAS kernels: at most 1.6e-11 (20 elements, c = 0.9 d0).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import RHO, E, L, beam_tree

from nsfem import cli
from nsfem.analysis.stationary import existence, scene_stationary, stationary
from nsfem.contact.set import ContactSet
from nsfem.errors import NsfemError
from nsfem.scene import load_scene, scene_from_tree

B, H, G = 0.03, 0.01, 9.81
EI = E * B * H**3 / 12
Q_LOAD = RHO * B * H * G  # N/m


def free_sag(a):
    """Deflection (downward, > 0) of the pinned-pinned beam at x = a under its weight."""
    return Q_LOAD * a * (L**3 - 2 * L * a**2 + a**3) / (24 * EI)


def influence(a, b):
    """Deflection at a per unit point load at b (same direction), pinned-pinned."""
    a, b = min(a, b), max(a, b)
    bb = L - b
    return bb * a * (L**2 - bb**2 - a**2) / (6 * L * EI)


def sag_scene(stops, elements=20, method="none", **extra):
    tree = beam_tree(width=B, height=H, elements=elements, rotation={"speed_hz": 0.0, "gravity": G},
                     obstacle=[{"x": x, "normal": "-z", "clearance": c, **extra} for x, c in stops])
    tree["reduction"] = {"method": method, "modes": 8}
    return scene_from_tree(tree)


@pytest.mark.parametrize("fraction", [0.25, 0.5, 0.9])
def test_beam_sagging_onto_a_midspan_stop(fraction):
    d0 = free_sag(0.5)
    c = fraction * d0
    st = scene_stationary(sag_scene([(0.5, c)]))
    P = (d0 - c) / influence(0.5, 0.5)  # closed form: 48 EI (d0 - c) / L^3
    assert P == pytest.approx(48 * EI * (d0 - c) / L**3, rel=1e-12)  # two closed forms: a few eps
    # 1.8e-11 x (1 + 1 / (1 - fraction)) = 2e-10 at fraction 0.9 (module docstring; measured 1.6e-11)
    assert st.normal_force[0] == pytest.approx(P, rel=1e-9)
    # a closed gap carries a few eps of the terms J^T q ~ c that cancel in it (reported as 0 below
    # 1e-12 of the free gap)
    assert abs(st.gap[0]) <= 1e-12 * c
    assert st.state == ["slip"]  # frictionless and closed: nothing holds it tangentially


def test_a_stop_out_of_reach_carries_nothing_and_shows_the_free_gap():
    d0 = free_sag(0.5)
    st = scene_stationary(sag_scene([(0.5, 2.5 * d0)]))
    assert st.normal_force[0] == 0.0 and st.state == ["open"]
    assert st.gap[0] == pytest.approx(1.5 * d0, rel=1e-9)  # 1.8e-11 x 2.5 / 1.5 (measured 1.2e-12)


def test_two_stops_superposition():
    """Symmetric stops at L/4 and 3L/4: P (w(a,a) + w(a,L-a)) = free sag - clearance."""
    a = 0.25
    c = 0.3 * free_sag(a)
    st = scene_stationary(sag_scene([(a, c), (L - a, c)]))
    P = (free_sag(a) - c) / (influence(a, a) + influence(a, L - a))
    # 20 elements, c = 0.3 d0: ~1.8e-11 x (1 + 1 / 0.7) (module docstring; measured 1.6e-12)
    np.testing.assert_allclose(st.normal_force, [P, P], rtol=1e-9)
    # the midspan deflection is then the free sag minus both stops' relief: check one stop open
    c_far = 0.3 * free_sag(a)
    st2 = scene_stationary(sag_scene([(a, c), (0.5, 10 * free_sag(0.5))]))
    assert st2.state[1] == "open" and st2.normal_force[1] == 0.0
    P1 = (free_sag(a) - c_far) / influence(a, a)
    gap_mid = 10 * free_sag(0.5) - (free_sag(0.5) - P1 * influence(0.5, a))
    assert st2.normal_force[0] == pytest.approx(P1, rel=1e-9)  # as above (measured 1.6e-12)
    assert st2.gap[1] == pytest.approx(gap_mid, rel=1e-9)  # an open gap of 9 d0: measured 3e-14


def test_craig_bampton_keeps_the_stop_force_close():
    """CB keeps the gap functional exactly, and its static constraint mode is K-orthogonal to
    the fixed-interface modes, so the reduced gap under any load (the distributed weight too)
    is the full model's C K^-1 f: the stop force agrees to round-off, not to the truncation
    of the 8 modes (module docstring: 1.8e-11 x 3 for each; measured 1.7e-12)."""
    d0 = free_sag(0.5)
    full = scene_stationary(sag_scene([(0.5, 0.5 * d0)]))
    cb = scene_stationary(sag_scene([(0.5, 0.5 * d0)], method="craig-bampton"))
    assert cb.info["ndof"] < full.info["ndof"]
    assert cb.normal_force[0] == pytest.approx(full.normal_force[0], rel=1e-9)


def _friction_case(mu, x=0.25):
    d0 = free_sag(x)
    return scene_stationary(sag_scene([(x, 0.5 * d0)], friction=mu, friction_directions=4))


def test_friction_sticks_below_and_slides_above_the_coulomb_limit():
    """A stop off midspan: the bottom fibre there moves axially (u1 = U + h/2 W') as the beam sags.

    With a large mu the contact sticks: its slip is zero and it needs |lam_T| / lam_N = mu*.
    Just above mu* it still sticks; just below it slides with |lam_T| = mu lam_N, slip
    opposing the friction force. (mu* is large, ~230: the friction force acts at the
    fibre h/2 below the axis, and its moment lifts the beam off the stop.)

    A sticking slip is Lemke's componentwise residual, n eps ||A|| ||x|| with ||x|| ~ mu* lam_N:
    6 x 2.2e-16 x 230 d0 = 3e-13 d0 (measured <= 3e-18 d0 after the final refinement).
    """
    stick = _friction_case(1e4)
    assert stick.state == ["stick"]
    assert np.abs(stick.slip[0]).max() <= 1e-12 * free_sag(0.25)
    lamT = np.linalg.norm(stick.tangential_force[0])
    mu_star = lamT / stick.normal_force[0]
    assert 1.0 < mu_star < 1e4  # a real tangential load
    assert _friction_case(0.3).state == ["slip"]
    above = _friction_case(1.05 * mu_star)
    assert above.state == ["stick"]
    assert np.abs(above.slip[0]).max() <= 1e-12 * free_sag(0.25)
    below = _friction_case(0.95 * mu_star)
    assert below.state == ["slip"]
    t = below.tangential_force[0]
    # the saturated cone row mu lam_N - sum beta = 0 to n eps of its terms (2 mu lam_N): 2.6e-15
    # relative (measured 2.2e-16); allowed 1e-12
    assert np.linalg.norm(t) == pytest.approx(0.95 * mu_star * below.normal_force[0], rel=1e-12)
    s = below.slip[0]
    assert np.linalg.norm(s) > 0 and float(t @ s) < 0  # friction opposes the slip
    # zero friction: the stop's force is the frictionless one
    free = _friction_case(0.0)
    assert free.state == ["slip"] and len(free.tangential_force[0]) == 0


def test_delaminated_shaft_at_speed_opens_every_gap():
    """The centrifugal load pushes the sub-beams apart: no contact force, gaps > 0 and ~ Omega^2."""
    gaps = {}
    for speed in (2.0, 4.0, 21.0):
        st = scene_stationary(load_scene(None, [f"rotation.speed_hz={speed}", "mesh.elements=20"]))
        assert st.state == ["open"] * 9
        assert np.all(st.normal_force == 0.0) and np.all(st.gap > 0)
        # symmetric shaft: the gaps mirror to 2.0e-10, 7.9e-10, 2.4e-8 at 2, 4, 21 Hz, with the same
        # digits under four BLAS kernels and with clamped ends too: an asymmetry of the model growing
        # as Omega^2, not round-off (cond(Q) eps = 4.7e3 x 2.2e-16 = 1e-12); allowed 4x the 21 Hz value
        np.testing.assert_allclose(st.gap, st.gap[::-1], rtol=1e-7)
        gaps[speed] = st.gap
    # K0 + Omega^2 Kc1 softens by (Omega / Omega_div)^2: the ratio exceeds 4 by at most
    # (1 - (2 / 43.4)^2) / (1 - (4 / 43.4)^2) - 1 = 0.64 % (lowest divergence speed; measured 0.17-0.18 %)
    ratio = gaps[4.0] / gaps[2.0]
    np.testing.assert_allclose(ratio, 4.0, rtol=0.01)
    assert np.all(ratio > 4.0)  # softening: slightly more than quadratic


def test_thin_upper_layer_rests_on_the_lower_at_rest():
    """At rest under gravity the thinner sub-beam sags more (w ~ 1/h^2): a thin upper layer
    lies on the lower one (contacts closed); a thin lower layer hangs away from it (open)."""
    base = ["rotation.speed_hz=0", "mesh.elements=20", "reduction.method=none"]
    thick_up = scene_stationary(load_scene(None, base))
    assert thick_up.state == ["open"] * 9 and np.all(thick_up.gap > 0)
    thin_up = scene_stationary(load_scene(None, base + ["delamination.0.upper_height=0.006"]))
    closed = [k for k, s in enumerate(thin_up.state) if s != "open"]
    assert closed and np.all(thin_up.normal_force >= 0)
    # gaps against the layers' free separation at rest (1.8e-5 m; every thin_up gap may be closed,
    # so its own largest gap is no scale): closed gaps are Lemke's residual, ~n eps |b| =
    # 9 x 2.2e-16 x 1e-4 m = 2e-19 m (measured 3e-20 m before stationary() rounds them to 0)
    scale = np.abs(thick_up.gap).max()
    assert np.all(thin_up.gap >= -1e-12 * scale)
    assert np.all(np.abs(thin_up.gap[closed]) <= 1e-12 * scale)
    # the contact forces carry at most the weight difference the upper layer would add
    seg = 0.8 * 0.02 * 0.006 * 7500.0 * G
    assert thin_up.normal_force.sum() < seg


def test_existence_statement_follows_the_paper():
    Q = np.array([[2.0, 0.0], [0.0, 1.0]])
    assert existence(Q, frictionless=False)["guaranteed"]
    P = np.array([[0.0, 0.5], [-0.5, 0.0]])  # circulatory, from external damping
    assert not existence(Q + P, frictionless=False)["guaranteed"]
    assert existence(Q + P, frictionless=True)["guaranteed"]
    ind = np.diag([1.0, -1.0])
    rep = existence(ind, frictionless=True)
    assert not rep["guaranteed"] and "positive definite" in rep["reason"]


def test_singular_stiffness_is_named():
    cs = ContactSet.from_arrays(np.array([[1.0], [0.0]]), [0.0])
    with pytest.raises(NsfemError, match="singular"):
        stationary(np.diag([1.0, 0.0]), np.array([-1.0, 0.0]), cs)


def test_infeasible_stationary_problem_reports_lemke_diagnosis():
    """A negative stiffness whose load pulls the gap shut has no stationary state:
    w = -lam - 1 >= 0 is infeasible; Lemke must say so, not return a wrong answer."""
    cs = ContactSet.from_arrays(np.array([[1.0]]), [0.0])
    with pytest.raises(NsfemError, match="secondary ray.*not guaranteed"):
        stationary(np.array([[-1.0]]), np.array([1.0]), cs)


def test_cli_stationary_json_contract(capsys):
    assert cli.main(["stationary", "--json", "--set", "mesh.elements=20"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("gap_m", "normal_force_N", "tangential_force_N", "state"):
        assert len(out[key]) == 9
    assert out["state"] == ["open"] * 9 and out["existence"]["guaranteed"]
    assert out["loads"] == ["centrifugal"] and "note" in out


def test_cli_stationary_with_stops_and_friction(capsys):
    d0 = free_sag(0.5)
    args = ["stationary", "--json", "--set", "delamination=[]", "--set", "rotation.speed_hz=0",
            "--set", "shaft.width=0.03", "--set", "shaft.height=0.01", "--set", f"shaft.rho={RHO}",
            "--set", f'obstacle=[{{x=0.5, normal="-z", clearance={0.5 * d0}, friction=0.3}}]',
            "--set", "reduction.method=none"]
    assert cli.main(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["contacts"] == ["obstacle.0"] and out["state"] == ["stick"]
    # the shipped 40-element mesh: 2.9e-10 x (1 + 2) = 8.7e-10 (module docstring; measured <= 1.5e-11)
    assert out["normal_force_N"][0] == pytest.approx(48 * EI * 0.5 * d0 / L**3, rel=3e-9)
    # at midspan the free slip is round-off, which the LCP sets to 0: no tangential load at all
    assert out["tangent_directions"] == [["x", "y"]] and out["tangential_force_N"] == [0.0]


def test_cli_warns_when_existence_is_not_guaranteed(capsys):
    assert cli.main(["stationary", "--set", "rotation.speed_hz=45", "--set", "mesh.elements=20"]) in (0, 2)
    err = capsys.readouterr().err
    assert "existence not guaranteed" in err and "positive definite" in err


# --- issue 34: a rotor's parts in its stationary state -----------------------------------------------
# A free-free circular Euler-Bernoulli shaft on two end bearings of stiffness k (kzz), a disk given by
# its mass at midspan, gravity at rest: its sag at midspan is the bearings' W / (2 k) plus the simply
# supported beam's P L^3 / (48 EI) + 5 q L^4 / (384 EI). Hermite elements with consistent loads are
# nodally exact (the static Green's function is cubic between nodes), so the model reproduces both to
# round-off: Q's componentwise condition at midspan is ~1e5 for 12 elements (module docstring: 8.3e4 for
# 20), 1e5 eps = 2e-11; 1e-9 leaves a factor 50. The reactions are -k u at the bearings' nodes (the same
# round-off) and their sum is the weight by the equilibrium of the exact solution (rigid translation in the
# basis): 1e-9 as well.
ROTOR_L, ROTOR_D, ROTOR_E, ROTOR_RHO, DISK_M, K_BEARING = 0.8, 0.03, 2.1e11, 7850.0, 3.0, 2e6


def rotor_scene(bearings=True, **overrides):
    tree = {"shaft": {"length": ROTOR_L, "section": "circle", "diameter": ROTOR_D, "E": ROTOR_E, "rho": ROTOR_RHO,
                      "supports": "free-free" if bearings else "pinned-pinned"},
            "disk": [{"x": ROTOR_L / 2, "mass": DISK_M}],
            "rotation": {"speed_hz": 0.0, "gravity": G, "frame": "inertial"},
            "mesh": {"elements": 12}, "reduction": {"method": "none"}}
    if bearings:
        tree["bearing"] = [{"x": 0.0, "kyy": K_BEARING, "kzz": K_BEARING, "kxx": K_BEARING},
                           {"x": ROTOR_L, "kyy": K_BEARING, "kzz": K_BEARING}]
    tree.update(overrides)
    return scene_from_tree(tree)


def rotor_sag(bearings: bool) -> tuple[float, float]:
    """(weight [N], midspan sag [m], downward > 0) in closed form."""
    area, inertia = np.pi * ROTOR_D**2 / 4, np.pi * ROTOR_D**4 / 64
    q, P = ROTOR_RHO * area * G, DISK_M * G
    W = q * ROTOR_L + P
    beam = P * ROTOR_L**3 / (48 * ROTOR_E * inertia) + 5 * q * ROTOR_L**4 / (384 * ROTOR_E * inertia)
    return W, beam + (W / (2 * K_BEARING) if bearings else 0.0)


@pytest.mark.parametrize("bearings", [True, False])
def test_rotor_sag_and_reactions_against_the_closed_form(bearings):
    W, sag = rotor_sag(bearings)
    parts = scene_stationary(rotor_scene(bearings)).parts
    assert parts["load_N"][1] == pytest.approx(-W, rel=1e-12)   # the loads' sum: a few eps per node
    disk = parts["disks"][0]
    assert disk["deflection_m"][1] == pytest.approx(-sag, rel=1e-9)
    assert abs(disk["deflection_m"][0]) <= 1e-12 * sag            # no load along y: round-off
    top = parts["max_deflection"]
    assert top["x_m"] == pytest.approx(ROTOR_L / 2) and top["magnitude_m"] == pytest.approx(sag, rel=1e-9)
    carriers = parts["bearings"] if bearings else parts["supports"]
    assert len(carriers) == 2 and not (parts["supports"] if bearings else parts["bearings"])
    for c in carriers:   # symmetric: each end carries half the weight, upwards on the shaft
        assert c["reaction_N"][1] == pytest.approx(W / 2, rel=1e-9)
        assert abs(c["reaction_N"][0]) <= 1e-9 * W
    total = np.sum([c["reaction_N"] for c in carriers], axis=0) + parts["load_N"]
    assert np.all(np.abs(total) <= 1e-9 * W)


def test_bearing_reactions_of_a_speed_free_static_load_and_cross_coupling():
    """An asymmetric rotor (disk at 0.3 L) on cross-coupled bearings: the reactions are -K u at the nodes and
    still balance the weight (no other static load: the unbalance is harmonic in the inertial frame)."""
    from nsfem.analysis.reactions import bearing_reactions
    from nsfem.fem.assemble import build_model

    scene = rotor_scene(disk=[{"x": 0.3 * ROTOR_L, "mass": DISK_M}], unbalance=[{"x": 0.3 * ROTOR_L, "magnitude": 1e-3}],
                        bearing=[{"x": 0.0, "kyy": 2e6, "kzz": 1e6, "kyz": 3e5, "kzy": -2e5, "kxx": 1e6},
                                 {"x": ROTOR_L, "kyy": 1.5e6, "kzz": 3e6}],
                        rotation={"speed_hz": 30.0, "gravity": G, "frame": "inertial"})
    st = scene_stationary(scene)
    W, _ = rotor_sag(True)
    R = np.array([b["reaction_N"] for b in st.parts["bearings"]])
    # the split follows the lever rule of a rigid beam: 0.7 of the disk and half the shaft at x = 0
    assert R[0, 1] == pytest.approx(W - DISK_M * G * 0.3 - (W - DISK_M * G) / 2, rel=1e-9)
    assert np.all(np.abs(R.sum(axis=0) + st.parts["load_N"]) <= 1e-9 * W)
    model = build_model(scene)
    u = np.asarray(st.q).ravel()   # no reduction: q holds the constrained coordinates
    assert np.allclose(bearing_reactions(model, np.asarray(model.T @ u).ravel()), R, rtol=1e-12, atol=0)
    # the cross-coupled bearing pushes along y too: -(kyz w) with v ~ 0 would not do; check -K u itself
    b = model.stack.bearings[0]
    vw = np.array([model.T[model.dof(model.stack.carrier(0.0), f, 0.0)] @ u for f in ("V", "W")]).ravel()
    assert R[0] == pytest.approx(-(np.asarray(b.K) @ vw), rel=1e-12)


RUB_FAST = ["--set", "mesh.elements=8", "--set", "reduction.modes=6"]


def test_ring_is_one_line_whose_force_sums_its_facets_along_the_whirl(capsys):
    """rub: the ring's resultant is the vector sum of its facets' forces (lam_N n + mu lam_N t on the ring,
    friction dragging it forwards), its normal part points along the whirl to within a facet's angle
    (the shaft sits in a corner of the 64-gon: 5.6 deg), the friction part is mu times the normal one
    where every touching facet slides; one text line for the ring, none per facet."""
    assert cli.main(["stationary", "rub", "--json", *RUB_FAST]) == 0
    out = json.loads(capsys.readouterr().out)
    scene = load_scene("rub", RUB_FAST[1::2])
    ring, = out["rings"]
    contacts = [c for c in scene.stack.contacts if c.table_key == "stator.0"]
    n = np.array([[np.cos(c.angle), np.sin(c.angle)] for c in contacts])
    lamN = np.array(out["normal_force_N"][:len(contacts)])
    lamT = np.array([t[0] if t else 0.0 for t in out["tangential_force_components_N"][:len(contacts)]])
    t = np.column_stack([-n[:, 1], n[:, 0]])
    F = lamN @ n - lamT @ t
    # sums of 64 terms of one sign: 64 eps relative
    assert np.allclose(ring["force_yz_N"], F, rtol=1e-13, atol=1e-13 * np.abs(F).max())
    assert ring["force_N"] == pytest.approx(np.hypot(*F), rel=1e-13)
    normal = lamN @ n
    whirl = np.radians(ring["whirl_angle_deg"])
    facet = 2 * np.pi / len(contacts)
    assert abs(np.angle(np.exp(1j * (np.arctan2(normal[1], normal[0]) - whirl)))) <= facet
    assert ring["state"] == "slip" and ring["facets"] and ring["min_clearance_m"] == 0.0
    assert np.all(lamN[[i for i in range(len(contacts)) if i not in ring["facets"]]] == 0.0)
    mu = scene.stack.contacts[0].friction
    # sliding facets: friction mu lam_N t_k with t_k = J n_k, so the friction part is mu J (normal part): 1e-13
    assert ring["friction_N"] == pytest.approx(mu * ring["normal_N"], rel=1e-13)
    assert ring["normal_N"] == pytest.approx(np.hypot(*normal), rel=1e-13)
    assert ring["radius_m"] == pytest.approx(np.hypot(*ring["whirl_yz_m"]), rel=1e-15)
    assert ring["radius_m"] >= 0.99 * 1e-4   # the whirl reaches the 0.1 mm clearance (within the polygon's cos)
    # the damper at the disk, fixed in space, sees the synchronous whirl's velocity Omega J u: -Omega c J u on the
    # shaft (round-off of a 2-vector product)
    (v, w), omega, c = ring["whirl_yz_m"], 2 * np.pi * scene.rotation.speed_hz, scene.stack.bearings[0].C[0][0]
    assert out["bearings"][0]["reaction_N"] == pytest.approx([omega * c * w, -omega * c * v], rel=1e-13)
    capsys.readouterr()
    assert cli.main(["stationary", "rub", *RUB_FAST]) == 0
    text = capsys.readouterr().out
    assert "stator.0.1 " not in text and len([line for line in text.splitlines() if "stator.0" in line]) == 1


def test_existence_caveat_is_said_once_and_names_its_cause(capsys):
    """rub has no external damping: the caveat names the bearing damper's circulatory term, once."""
    assert cli.main(["stationary", "rub", *RUB_FAST]) == 0
    cap = capsys.readouterr()
    both = cap.out + cap.err
    assert both.count("existence not guaranteed") == 1 and "bearing.0's damping" in both
    assert "external" not in both
    assert cli.main(["stationary", "rub", *RUB_FAST, "--set", "damping.external=0.5"]) == 0
    both = "".join(capsys.readouterr())
    assert both.count("existence not guaranteed") == 1 and "damping.external" in both


def test_axial_rigid_motion_is_named_with_the_key_that_restrains_it(capsys):
    args = ["ross_example", "--set", "bearing.2.kxx=0", "--set", "mesh.elements=8", "--set", "reduction.modes=8"]
    assert cli.main(["stationary", *args]) == cli.EXIT_ERROR
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "axial rigid motion" in err and "kxx" in err and "singular" in err
    assert cli.main(["modes", *args, "--count", "3", "--json"]) == 0
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    assert out["rigid_motions"] == ["axial rigid motion (U)"] and out["frequencies_hz"][0] == 0.0
    assert cap.err.count("warning") == 1 and "kxx" in cap.err
    assert cli.main(["modes", *args, "--count", "3"]) == 0
    assert "rigid axial motion (U)" in capsys.readouterr().out.splitlines()[3]
    # restrained (the shipped scene's thrust bearing): no warning, no rigid motion
    assert cli.main(["modes", "ross_example", "--set", "mesh.elements=8", "--set", "reduction.modes=8", "--json"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["rigid_motions"] == [] and "warning" not in cap.err


def test_free_lateral_motions_are_named_per_plane():
    from nsfem.analysis.rigid_motion import free_motions
    from nsfem.fem.assemble import build_model

    names = free_motions(build_model(rotor_scene(bearing=[{"x": 0.0, "kyy": 1e6, "kzz": 1e6, "kxx": 1e6}])))
    # one bearing: each plane keeps the tilt about it
    assert names == ["rigid tilt in the x-y plane about x = 0 m", "rigid tilt in the x-z plane about x = 0 m"]
    assert free_motions(build_model(rotor_scene())) == []


def test_ross_example_statics_match_ross_run_static():
    """ROSS 2.3.0's ``Rotor.run_static`` on its example rotor (6 shaft elements, shear_effects=False: the same
    Hermite beam as the scene's Rayleigh model in statics; g = 9.8065, ROSS's): bearing forces 432.3774305443126 N
    each, shaft sag at the disk (node 2) 6.473626038799438e-4 m and at midspan 7.445426152804584e-4 m. ROSS's
    deformation holds the shaft at the bearings (zero there), so ours less the bearings' own W / (2 kzz) is
    compared. Both discretizations are nodally exact for this load: round-off only (1e-10)."""
    st = scene_stationary(load_scene("ross_example", ["rotation.gravity=9.8065", "mesh.elements=6",
                                                      "reduction.method=none"]))
    R = [b["reaction_N"][1] for b in st.parts["bearings"][:2]]   # bearing.2 is the thrust bearing (no lateral load)
    assert R == pytest.approx([432.3774305443126] * 2, rel=1e-10)
    assert st.parts["bearings"][2]["reaction_N"] == [0.0, 0.0]
    settle = R[0] / 8e5   # kzz of both bearings
    assert st.parts["disks"][0]["deflection_m"][1] + settle == pytest.approx(-6.473626038799438e-4, rel=1e-10)
    assert st.parts["max_deflection"]["x_m"] == pytest.approx(0.75)
    assert st.parts["max_deflection"]["deflection_m"][1] + settle == pytest.approx(-7.445426152804584e-4, rel=1e-10)


def test_spinning_free_rotor_is_refused_for_its_axial_motion_only():
    """Free-free at 21 Hz in the rotating frame: the centrifugal term -Omega^2 m makes the lateral rigid motions a
    negative stiffness, not a singular one, so only the axial travel (no speed term acts on U) is named; at rest
    all three are."""
    base = ["shaft.supports=free-free", "mesh.elements=12"]
    with pytest.raises(NsfemError) as spinning:
        scene_stationary(load_scene(None, base))
    assert "axial rigid motion" in str(spinning.value) and "lateral" not in str(spinning.value)
    with pytest.raises(NsfemError) as rest:
        scene_stationary(load_scene(None, [*base, "rotation.speed_hz=0"]))
    assert all(k in str(rest.value) for k in ("axial rigid motion", "x-y plane", "x-z plane", "kyy and kzz"))


# --- issue 34 review (r2): reactions of reduced models, rotating frame, supports with bearings ---

@pytest.mark.parametrize("name", ["crack", "default"])
def test_support_reactions_of_a_reduced_scene_balance_its_weight(name):
    """A shipped scene with supports and its own Craig-Bampton reduction, at rest under its weight: the
    supports carry the weight (with the contacts' forces, internal to the structure). The residual of the
    reduced state holds the reduction's error on every dof (crack: the supports summed to 68.12 N of 68.40,
    default: 28.17 of 29.43); the reactions are the full model's under the same loads and contact forces, so
    the balance is round-off of one sparse solve: 1e-9 of the weight (measured 1e-12)."""
    st = scene_stationary(load_scene(name, ["rotation.speed_hz=0", "rotation.gravity=9.81"]))
    parts = st.parts
    W = -parts["load_N"][1]
    total = np.sum([s["reaction_N"] for s in parts["supports"] + parts["bearings"]], axis=0) + parts["load_N"]
    assert W > 0 and np.all(np.abs(total) <= 1e-9 * W), total


def test_supports_with_bearings_share_the_weight_by_the_closed_form():
    """A shaft clamped at x = 0 and on a bearing (k) at x = L, under its own weight q per length (Euler-
    Bernoulli): the propped cantilever on a spring carries R = (3/8) q L / (1 + 3 E I / (k L^3)) at the
    bearing, the rest at the clamp; with the scene's Craig-Bampton reduction too. Nodally exact elements:
    round-off (1e-9). A reduction's state is off by its truncation, but the clamp's force is still exact."""
    k, D, Lr = 2e5, 0.02, 0.8
    tree = {"shaft": {"length": Lr, "section": "circle", "diameter": D, "E": E, "rho": RHO,
                      "supports": "clamped-free"},
            "bearing": [{"x": Lr, "kyy": k, "kzz": k}], "mesh": {"elements": 8},
            "rotation": {"speed_hz": 0.0, "gravity": 9.81}, "beam": {"theory": "euler-bernoulli"}}
    q = RHO * np.pi * D**2 / 4 * 9.81
    EI = E * np.pi * D**4 / 64
    R = 3 / 8 * q * Lr / (1 + 3 * EI / (k * Lr**3))
    parts = scene_stationary(scene_from_tree({**tree, "reduction": {"method": "none"}})).parts
    assert parts["bearings"][0]["reaction_N"][1] == pytest.approx(R, rel=1e-9)
    assert parts["supports"][0]["reaction_N"][1] == pytest.approx(q * Lr - R, rel=1e-9)
    # four modes: the state (and so the bearing's -K u) is 2 % off, the clamp's force is the full model's
    # (it was 9.70 N of 12.35: the residual of the reduced state held the reduction's error)
    parts = scene_stationary(scene_from_tree({**tree, "reduction": {"method": "craig-bampton", "modes": 4}})).parts
    assert parts["supports"][0]["reaction_N"][1] == pytest.approx(q * Lr - R, rel=1e-9)


def test_rotating_frame_bearing_reactions_are_the_inertial_harmonic_forces():
    """A Jeffcott rotor (tests/test_sweep.py's) stationary in the rotating frame at 40 Hz: each bearing's force
    in that frame has the size of the inertial frame's steady unbalance force |(k + i w c) z_b| on it, z_b the
    bearing's motion from the closed form (shaft stiffness ks in series with the bearings k = 2 x 5e5, c = 2 x
    200). The closed form lumps the shaft's mass (1.6e-3 of the disk's) into the disk: 1e-5 relative bounds it
    (measured 2.5e-7)."""
    import cmath  # noqa: F401
    import math

    from test_sweep import JEFFCOTT

    from nsfem.scene.load import scene_from_tree as from_tree
    import tomllib

    raw = tomllib.loads(JEFFCOTT)
    scene = from_tree(raw, ["rotation.frame=rotating", "rotation.speed_hz=40", "rotation.gravity=0"])
    bearings = scene_stationary(scene).parts["bearings"]
    mass = 10.0 + 10.0 * math.pi * 0.05**2 * 0.2
    ks = 48 * 2.1e11 * (math.pi * 0.1**4 / 64) / 0.2**3
    w = 2 * math.pi * 40.0
    z = 1e-4 * w**2 / (ks - ks**2 / (ks + 1e6 + 1j * w * 400.0) - mass * w**2)
    zb = ks * z / (ks + 1e6 + 1j * w * 400.0)
    for b in bearings[:2]:
        assert b["magnitude_N"] == pytest.approx(abs((5e5 + 1j * w * 200.0) * zb), rel=1e-5)


def test_rotating_frame_reactions_balance_the_load_with_the_deflections_centrifugal_force():
    """In the rotating frame the bearings also carry the centrifugal force of the deflected rotor, which is in
    Q (Omega^2 Kc1 q), not in the constant load: the parts report it (``deflection_load_N``) so that the load,
    it and the reactions balance (the Jeffcott rotor of tests/test_sweep.py at 40 Hz, unreduced: round-off,
    1e-9 of the load). It is Omega^2 m u of the disk and the shaft: the closed form lumps the shaft's mass
    (1.6e-3 of the disk's), whose deflection differs from the disk's by 1.6e-4 of it: 1e-6 relative bounds
    it (measured 1.2e-7; the balance 2e-11). At rest it is zero."""
    import math

    import tomllib
    from test_sweep import JEFFCOTT

    raw = tomllib.loads(JEFFCOTT)
    parts = scene_stationary(scene_from_tree(raw, ["rotation.frame=rotating", "rotation.speed_hz=40",
                                                   "rotation.gravity=0"])).parts
    load, extra = np.array(parts["load_N"]), np.array(parts["deflection_load_N"])
    total = load + extra + np.sum([b["reaction_N"] for b in parts["bearings"]], axis=0)
    assert np.all(np.abs(total) <= 1e-9 * np.abs(load).max()), total
    mass = 10.0 + 10.0 * math.pi * 0.05**2 * 0.2
    u = np.array(parts["disks"][0]["deflection_m"])
    assert extra == pytest.approx((2 * math.pi * 40.0) ** 2 * mass * u, rel=1e-6)
    rest = scene_stationary(scene_from_tree(raw, ["rotation.speed_hz=0"])).parts
    assert rest["deflection_load_N"] == [0.0, 0.0]
