"""Rotors as engineers build them: circular sections, disks, bearings, unbalance, both frames.

Each check is against a closed form or an independent model (design section 8, docs/theory.md).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sla

from nsfem import build_model, natural_frequencies
from nsfem.errors import SceneError
from nsfem.fem.rotating import rotor_operators
from nsfem.scene import scene_from_tree
from nsfem.system import linear_system

E, RHO = 2.1e11, 7850.0


def rotor_tree(elements=40, diameter=0.05, inner=0.0, supports="pinned-pinned", length=1.0, rho=RHO, **extra):
    tree = {"shaft": {"length": length, "section": "circle", "diameter": diameter, "inner_diameter": inner,
                      "E": E, "rho": rho, "supports": supports},
            "mesh": {"elements": elements}, "reduction": {"method": "none"},
            "rotation": {"speed_hz": 0.0, "gravity": 0.0}}
    tree.update(extra)
    return tree


def model_of(tree):
    return build_model(scene_from_tree(tree))


def state_eigs(sys_) -> np.ndarray:
    M, C, Q = (A.toarray() if A is not None else None for A in (sys_.M, sys_.C, sys_.Q))
    n = M.shape[0]
    C = np.zeros((n, n)) if C is None else C
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, Q), -np.linalg.solve(M, C)]])
    return np.linalg.eigvals(A)


@pytest.mark.parametrize("inner", [0.0, 0.03])
def test_circular_shaft_against_euler_bernoulli(inner):
    D, L, n_el = 0.05, 1.0, 40
    model = model_of(rotor_tree(n_el, D, inner))
    A, I = math.pi / 4 * (D**2 - inner**2), math.pi / 64 * (D**4 - inner**4)
    f = natural_frequencies(model, count=8).frequencies_hz
    lateral = np.sort(f)[:6]                       # three bending pairs (V and W alike); axial modes are higher
    for k in range(3):
        exact = (k + 1) ** 2 * math.pi / (2 * L**2) * math.sqrt(E * I / (RHO * A))
        # Hermite cubics: relative error of w^2 about (k h)^4 / 720 (k = n pi / L, h = L / n_el); 2x margin
        tol = 2 * ((k + 1) * math.pi / n_el) ** 4 / 720
        assert lateral[2 * k] == pytest.approx(exact, rel=tol)
        # y and z alike, up to the shift-invert Lanczos's own accuracy on a repeated pair (1e-9: it holds
        # eigenvalues to about 1e-10 of the spectrum's bottom, analysis/modes.py)
        assert lateral[2 * k + 1] == pytest.approx(lateral[2 * k], rel=1e-9)


def test_disk_on_a_light_shaft_is_the_jeffcott_rotor():
    D, L, m = 0.02, 0.8, 5.0
    rho = 1e-3   # shaft mass 2e-7 of the disk's: its effect on the frequency ~ 17/35 of that ratio
    tree = rotor_tree(20, D, rho=rho, length=L, disk=[{"x": L / 2, "mass": m, "polar_inertia": 0.01,
                                                         "diametral_inertia": 0.005}])
    f = natural_frequencies(model_of(tree), count=2).frequencies_hz
    k = 48 * E * (math.pi * D**4 / 64) / L**3      # midspan stiffness; the mode's slope there is zero
    exact = math.sqrt(k / m) / (2 * math.pi)
    # a point load's deflection is cubic per element, so Hermite elements hold k exactly; the residue is
    # the shaft's mass (ratio 2e-7) and round-off
    np.testing.assert_allclose(f, exact, rtol=1e-6)


def tip_disk(elements, D, rho, L, m, Id, Ip):
    """A disk on the tip of a cantilever of density rho, inertial frame, not spinning (the speed is
    given to linear_system)."""
    return model_of(rotor_tree(elements, D, rho=rho, length=L, supports="clamped-free",
                               disk=[{"x": L, "mass": m, "polar_inertia": Ip, "diametral_inertia": Id}],
                               rotation={"speed_hz": 0.0, "gravity": 0.0, "frame": "inertial"}))


def disk_tip_closed_form(m, Id, Ip, k11, k12, k22, spin):
    """Whirl frequencies of a disk on a massless cantilever tip, gyroscopic (inertial frame): with
    z = v + i w and theta = V' + i W' ~ e^{i w t}, det [[k11 - m w^2, k12], [k12, k22 - Id w^2 + Ip Omega w]]
    = 0; w > 0 whirls forwards (the sense of the spin), w < 0 backwards."""
    poly = np.polymul([-m, 0, k11], [-Id, Ip * spin, k22])
    poly = np.polysub(poly, [k12 * k12])
    w = np.roots(poly).real
    return np.sort(w[w > 0]), np.sort(-w[w < 0])


def test_gyroscopic_splitting_of_a_disk_on_a_cantilever():
    D, L, m, Id, Ip = 0.02, 0.5, 4.0, 0.02, 0.04
    model = tip_disk(16, D, 1e-3, L, m, Id, Ip)
    ops = rotor_operators(model)
    EI = E * math.pi * D**4 / 64
    # tip (w, w') of a clamped beam: EI / L^3 [[12, -6 L], [-6 L, 4 L^2]]
    k11, k12, k22 = 12 * EI / L**3, -6 * EI / L**2, 4 * EI / L
    for spin in (0.0, 300.0, 3000.0):
        lam = state_eigs(linear_system(ops, spin / (2 * math.pi), frame="inertial"))
        w = np.abs(lam.imag[lam.imag > 0])
        fwd, bwd = disk_tip_closed_form(m, Id, Ip, k11, k12, k22, spin)
        ref = np.sort(np.concatenate([fwd, bwd]))
        # the disk's axial mode on the shaft's axial stiffness, sqrt(E A / (L m)), lies among them: each
        # closed-form whirl frequency has its own root (nearest), to the light shaft (mass 1e-6 of the
        # disk's) and round-off of the 1e6-wide spectrum: 1e-5
        got = np.array([w[np.argmin(np.abs(w - r))] for r in ref])
        np.testing.assert_allclose(got, ref, rtol=1e-5)
        axial = math.sqrt(E * math.pi * D**2 / 4 / L / m)
        assert np.min(np.abs(w - axial)) < 1e-4 * axial      # the disk's mass is on U too


def test_free_disk_nutates_forwards():
    # the whirl sense of the inertial gyroscopic term: a disk on a soft cantilever at high spin nutates
    # at Ip Omega / Id in the sense of the spin (+y towards +z)
    D, L, m, Id, Ip = 0.01, 0.5, 4.0, 0.02, 0.04
    model = tip_disk(8, D, 1e-3, L, m, Id, Ip)
    ops = rotor_operators(model)
    spin = 2e4
    sys_ = linear_system(ops, spin / (2 * math.pi), frame="inertial")
    M, C, Q = sys_.M.toarray(), sys_.C.toarray(), sys_.Q.toarray()
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, Q), -np.linalg.solve(M, C)]])
    lam, X = np.linalg.eig(A)
    j = int(np.argmin(np.abs(lam - 1j * Ip * spin / Id)))
    assert lam[j].imag == pytest.approx(Ip * spin / Id, rel=1e-3)   # the tip's stiffness shifts it by ~1e-4
    vs, ws = model.dof("intact_0", "V'", L), model.dof("intact_0", "W'", L)
    col = np.asarray(model.T.T @ np.eye(model.n_full)[:, [vs, ws]])   # full dof -> q via T^T (T picks dofs)
    v, w = col[:, 0] @ X[:n, j], col[:, 1] @ X[:n, j]
    # z = V' + i W' ~ e^{+i w t}: w = -i v for a forward whirl (V' = cos, W' = sin)
    assert abs(w + 1j * v) < 1e-6 * abs(v)


def equivalent_rotor(elements=8):
    """An axisymmetric rotor with everything both frames can carry: disks with I_p != 2 I_d, isotropic
    bearings with cross-coupling and damping, internal Rayleigh and external damping."""
    return rotor_tree(elements, 0.04, supports="free-free", length=1.2,
                      disk=[{"x": 0.4, "mass": 12.0, "polar_inertia": 0.2, "diametral_inertia": 0.12},
                            {"x": 0.9, "outer_diameter": 0.25, "width": 0.04}],
                      bearing=[{"x": 0.0, "kyy": 2e6, "kzz": 2e6, "kyz": 3e5, "kzy": -3e5, "cyy": 400.0,
                                "czz": 400.0, "cyz": 50.0, "czy": -50.0, "kxx": 1e7},
                               {"x": 1.2, "kyy": 3e6, "kzz": 3e6, "cyy": 300.0, "czz": 300.0}],
                      damping={"rayleigh": [0.5, 2e-5], "external": 3.0},
                      beam={"theory": "rayleigh"})


@pytest.mark.parametrize("speed_hz", [7.0, 55.0])
def test_rotating_and_inertial_frames_agree(speed_hz):
    """An axisymmetric rotor seen from both frames: every inertial eigenvalue lambda appears in the
    rotating frame as lambda - i Omega s, s = +1 for a forward lateral mode, -1 backward, 0 axial.
    This ties together the disks' Coriolis, centrifugal and gyroscopic terms, the bearings' damping
    seen from the rotating frame and the internal damping seen from the inertial one."""
    from nsfem.analysis.whirl import AXIAL, whirl_sense
    from nsfem.fem.components import lateral_turn

    model = model_of(equivalent_rotor())
    ops = rotor_operators(model)
    rd = ((0.5, 2e-5), 3.0)
    sys_i = linear_system(ops, speed_hz, rayleigh=rd[0], external=rd[1], frame="inertial")
    M, C, Q = sys_i.M.toarray(), sys_i.C.toarray(), sys_i.Q.toarray()
    n = M.shape[0]
    lam_i, X = np.linalg.eig(np.block([[np.zeros((n, n)), np.eye(n)],
                                       [-np.linalg.solve(M, Q), -np.linalg.solve(M, C)]]))
    # each inertial root's own whirl sense says which shift it must take: forward -1 i Omega, ...
    senses = whirl_sense(X[:n], ops.basis, lateral_turn(model.spaces, model.n_full))
    lam_r = state_eigs(linear_system(ops, speed_hz, rayleigh=rd[0], external=rd[1], frame="rotating"))
    w = 2 * math.pi * speed_hz
    scale = np.abs(lam_i).max()
    used = np.zeros(lam_r.size, dtype=bool)
    for lam, sense in zip(lam_i, senses):
        assert sense != 0                                # no planar mode on an isotropic spinning rotor
        cand = np.array([lam - 1j * w * (0 if sense == AXIAL else sense)])
        d = np.abs(lam_r[None, :] - cand[:, None])
        d[:, used] = np.inf
        best = np.unravel_index(np.argmin(d), d.shape)
        # eigenvalues of two 108 x 108 state matrices spanning 1e5: measured 4e-15 of the largest, and
        # dense eigen solvers hold simple roots to a few hundred ulps of the matrix norm on any BLAS
        assert d[best] < 1e-11 * scale, (lam, d[best])
        used[best[1]] = True


def jeffcott(frame, speed_hz, beta, c_e, unbalance=(), rho=1e-3, phase_deg=0.0):
    """A disk of 5 kg at the middle of a light pinned-pinned shaft, a damper c_e to ground at the disk."""
    D, L, m = 0.02, 0.8, 5.0
    tree = rotor_tree(10, D, rho=rho, length=L,
                      disk=[{"x": L / 2, "mass": m}],
                      bearing=[{"x": L / 2, "cyy": c_e, "czz": c_e}],
                      unbalance=list(unbalance),
                      rotation={"speed_hz": speed_hz, "gravity": 0.0, "frame": frame, "phase_deg": phase_deg},
                      damping={"rayleigh": [0.0, beta]})
    model = model_of(tree)
    k = 48 * E * (math.pi * D**4 / 64) / L**3
    return model, rotor_operators(model), k, m


@pytest.mark.parametrize("frame", ["inertial", "rotating"])
def test_internal_damping_destabilizes_beyond_the_jeffcott_threshold(frame):
    """Jeffcott rotor with internal (rotating) damping c_i = beta k and external c_e: stable below
    Omega = w_n (1 + c_e / c_i), unstable above (a closed form)."""
    beta, c_e = 1e-4, 20.0
    model, ops, k, m = jeffcott(frame, 0.0, beta, c_e)
    wn = math.sqrt(k / m)
    threshold = wn * (1 + c_e / (beta * k))
    growth = []
    for f in (0.98, 1.02):
        w = f * threshold
        lam = state_eigs(linear_system(ops, w / (2 * math.pi), rayleigh=(0.0, beta), frame=frame))
        growth.append(lam.real.max())
    # the light shaft's own modes (1e7 rad/s) are damped by beta; 2 % off the threshold the disk's
    # growth rate is about 1e-2 (c_i / 2 m) w_n, far beyond the shaft's effect (mass ratio 2e-7)
    assert growth[0] < 0 < growth[1]


def test_unbalance_response_in_both_frames():
    """Jeffcott rotor with an unbalance and a damper: |z| = m e Omega^2 / sqrt((k - m Omega^2)^2 +
    (c Omega)^2); in the rotating frame a stationary deflection, in the inertial one a forward circle."""
    me, c_e, speed_hz, phase, turned = 1e-4, 40.0, 30.0, 30.0, 50.0   # turned: the rotor's angle at t = 0
    w = 2 * math.pi * speed_hz
    for frame in ("rotating", "inertial"):
        model, ops, k, m = jeffcott(frame, speed_hz, 0.0, c_e, [{"x": 0.4, "magnitude": me, "phase_deg": phase}])
        sys_ = linear_system(ops, speed_hz, phase_deg=turned, frame=frame)
        exact = me * w**2 / math.hypot(k - m * w**2, c_e * w)
        lag = math.atan2(c_e * w, k - m * w**2)        # the response trails the force by this angle
        v, wd = model.dof("intact_0", "V", 0.4), model.dof("intact_0", "W", 0.4)
        pick = np.asarray(model.T.T @ np.eye(model.n_full)[:, [v, wd]])
        if frame == "rotating":
            y, z = pick.T @ np.linalg.solve(sys_.Q.toarray(), sys_.f0)
            r, angle = math.hypot(y, z), math.atan2(z, y) + math.radians(turned)   # the frame's angle added
        else:
            # the harmonic response Re(X e^{i w t}) to f = fc cos + fs sin = Re((fc - i fs) e^{i w t})
            H = -w**2 * sys_.M.toarray() + 1j * w * sys_.C.toarray() + sys_.Q.toarray()
            y, z = pick.T @ np.linalg.solve(H, sys_.fc - 1j * sys_.fs)
            r, angle = abs(y), float(np.angle(y))     # at t = 0: (Re y, Re z) = r (cos, sin) of the angle
            assert abs(z + 1j * y) < 1e-9 * r          # z = -i y: a forward circle
        # mass ratio 2e-7, and the point load's static deflection is exact on Hermite elements
        assert r == pytest.approx(exact, rel=1e-5)
        assert math.remainder(angle - (math.radians(phase + turned) - lag), 2 * math.pi) == pytest.approx(0.0, abs=1e-5)


def test_frames_refuse_what_they_cannot_carry():
    aniso = [{"x": 0.0, "kyy": 1e6, "kzz": 2e6}, {"x": 1.0, "kyy": 1e6, "kzz": 1e6}]
    spin = {"speed_hz": 10.0, "gravity": 0.0}
    with pytest.raises(SceneError, match="rotation.frame.*bearing.0 is not isotropic.*use rotation.frame"):
        scene_from_tree(rotor_tree(bearing=aniso, supports="free-free", rotation=spin))
    rect = rotor_tree(bearing=aniso, supports="free-free", rotation=spin)
    with pytest.raises(SceneError, match="shaft.diameter: a rectangular section does not use diameter"):
        rect["shaft"].update(section="rectangle", width=0.03, height=0.02)
        scene_from_tree(rect)
    del rect["shaft"]["diameter"], rect["shaft"]["inner_diameter"]
    with pytest.raises(SceneError, match="periodic coefficients in both frames"):
        scene_from_tree(rect)
    rect["rotation"]["frame"] = "inertial"
    with pytest.raises(SceneError, match="needs an axisymmetric rotor"):
        scene_from_tree(rect)
    # not spinning: the frames coincide and any bearing is fine
    scene_from_tree(rotor_tree(bearing=aniso, supports="free-free"))
    with pytest.raises(SceneError, match="disk.0.mass: a disk needs a mass"):
        scene_from_tree(rotor_tree(disk=[{"x": 0.5}]))
    with pytest.raises(SceneError, match="disk.0.x: x=2.0 lies outside"):
        scene_from_tree(rotor_tree(disk=[{"x": 2.0, "mass": 1.0}]))
    with pytest.raises(SceneError, match="bearing.0.kyy: the symmetric part"):
        scene_from_tree(rotor_tree(bearing=[{"x": 0.0, "kyy": -1.0}]))
    with pytest.raises(SceneError, match="shaft.inner_diameter"):
        scene_from_tree(rotor_tree(inner=0.05))


def test_disk_from_geometry():
    tree = rotor_tree(disk=[{"x": 0.5, "outer_diameter": 0.3, "inner_diameter": 0.05, "width": 0.04, "rho": 7800.0}])
    d = scene_from_tree(tree).stack.disks[0]
    m = 7800.0 * math.pi / 4 * (0.3**2 - 0.05**2) * 0.04
    assert d.mass == pytest.approx(m, rel=1e-14)
    assert d.polar == pytest.approx(m * (0.3**2 + 0.05**2) / 8, rel=1e-14)
    assert d.diametral == pytest.approx(d.polar / 2 + m * 0.04**2 / 12, rel=1e-14)


#: ross.rotor_example() rebuilt with ShaftElement(shear_effects=False, rotary_inertia=True, gyroscopic=True),
#: ROSS 2.3.0 (pip ross-rotordynamics with plotly<6), rotor.run_modal(speed, num_modes=16).wd, the lowest
#: 8 lateral whirl frequencies [rad/s] (its torsional mode at 774.35 rad/s left out); whirl senses from
#: ROSS's own rule on each mode's node orbits. How: docs/validation.md, "ROSS's example rotor".
ROSS_WD = {
    0.0: [91.8492060360, 96.3499118862, 274.9147854489, 296.9516346243, 723.2783736375, 765.3844447649,
          1075.7316346736, 1109.7058610250],
    200.0: [91.8101438341, 96.3779790148, 272.9984468013, 298.8227944899, 705.3499098300, 781.9692372490,
            1074.6224854335, 1110.4003216187],
    500.0: [91.6123493171, 96.5180583638, 265.7141976607, 305.8725781451, 658.5167860192, 822.0463482465,
            1069.3440596147, 1113.4973043892],
    1000.0: [90.9804405140, 96.9439707375, 250.3497522099, 320.4354592869, 577.0132627755, 882.8651850937,
             1054.1043657953, 1120.8990868498],
}


def test_ross_example_rotor_whirl_frequencies():
    """The shipped ross_example scene on ROSS's own mesh (6 Rayleigh elements): the same element, so
    the same numbers up to the eigen solvers' round-off (ROSS's printed to 1e-10 rad/s; the 8 x 8 tables
    agree to 3e-12 here, 1e-9 leaves room for other BLAS kernels; a physics change, or 60 elements
    instead of ROSS's 6, moves them by 1e-6 to 5e-4)."""
    from nsfem.analysis.campbell import campbell
    from nsfem.fem.components import lateral_turn
    from nsfem.scene import load_scene

    scene = load_scene("ross_example", ["mesh.elements=6", "reduction.method=none"])
    model = build_model(scene)
    ops = rotor_operators(model)
    speeds = np.array(sorted(ROSS_WD)) / (2 * math.pi)
    res = campbell(ops, speeds, 9, frame="inertial", turn=lateral_turn(model.spaces, model.n_full))
    for i, w in enumerate(sorted(ROSS_WD)):
        lateral = res.whirl[i] != 2                      # our model has the axial mode (thrust bearing) too
        got = 2 * math.pi * res.frequencies_hz[i][lateral][:8]
        np.testing.assert_allclose(got, ROSS_WD[w], rtol=1e-9)
        senses = res.whirl[i][lateral][:8]
        # at rest every mode is planar; spinning, each pair splits into backward (lower) and forward
        assert list(senses) == ([0] * 8 if w == 0 else [-1, 1] * 4)


def test_instability_onset_and_critical_speed_of_the_jeffcott_rotor():
    from nsfem.analysis.campbell import campbell
    from nsfem.analysis.whirl import critical_speeds, instability_onsets
    from nsfem.fem.components import lateral_turn

    beta, c_e = 1e-4, 20.0
    # a shaft of density 1 (mass 5e-5 of the disk's): a lighter one's stiff modes (3e8 rad/s) would put
    # the growth rates' round-off resolution sqrt(eps) w_max above the 0.7 1/s measured here
    model, ops, k, m = jeffcott("inertial", 0.0, beta, c_e, rho=1.0)
    wn = math.sqrt(k / m)
    threshold_hz = wn * (1 + c_e / (beta * k)) / (2 * math.pi)
    speeds = np.linspace(0.0, 2 * threshold_hz, 9)
    res = campbell(ops, speeds, 2, (0.0, beta), 0.0, frame="inertial")
    onsets = instability_onsets(ops, speeds, res.growth_per_s, 2, (0.0, beta), 0.0)
    # bisection to 1e-6 of the speed; the shaft's mass (ratio 5e-5, about 17/35 of it moving with the
    # disk) shifts w_n and the closed form by about 1e-5
    np.testing.assert_allclose(onsets, [threshold_hz], rtol=1e-4)
    crit, whirl = critical_speeds(ops, lateral_turn(model.spaces, model.n_full))
    # the disk sits at midspan (no tilt): both whirl senses at w_n; the shaft's own modes far above
    np.testing.assert_allclose(crit[:2], wn / (2 * math.pi), rtol=1e-4)
    assert sorted(whirl[:2]) in ([-1, 1], [0, 0])


def test_shipped_scene_by_name_and_the_inertial_campbell_json(tmp_path, capsys):
    import json

    from nsfem import cli

    assert cli.main(["campbell", "ross_example", "--speeds", "0:100:3", "--json",
                     "--png", str(tmp_path / "c.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["frame"] == "inertial" and out["gravity_resonances_hz"] == {"open": [], "closed": []}
    assert out["whirl"][0] == ["planar", "planar", "axial", "planar", "planar", "planar"]
    assert out["whirl"][1][:2] == ["backward", "forward"]
    # the first critical speeds lie near the lowest whirl frequencies (15-16 Hz, ROSS: 91.8 and 96.3 rad/s)
    assert out["critical_speeds_hz"]["open"][0] == pytest.approx(14.62, abs=0.01)
    with pytest.raises(SceneError, match="shipped scenes: .*ross_example"):
        from nsfem.scene import load_scene
        load_scene("no_such_scene")


def test_a_disk_moves_axially_with_the_shaft():
    """The axial rigid translation carries the shaft's and the disks' mass (r^T M r, exact), and on a
    thrust spring the rotor's axial mode is sqrt(k / m_total) up to the shaft's own axial flexibility
    (k L / E A = 3.6e-3: it lowers the frequency by about a sixth of that)."""
    from nsfem.scene import load_scene

    scene = load_scene("ross_example", ["reduction.method=none"])
    model = build_model(scene)
    r = np.zeros(model.n_full)
    r[model.field_dofs("U")] = 1.0
    shaft = 7810.0 * math.pi * 0.05**2 / 4 * 1.5
    disks = sum(d.mass for d in scene.stack.disks)
    assert float(r @ model.M_full @ r) == pytest.approx(shaft + disks, rel=1e-12)
    f = natural_frequencies(model, count=6)
    axial = [fr for fr, fld in zip(f.frequencies_hz, f.fields) if fld == "U"]
    assert axial[0] == pytest.approx(math.sqrt(1e6 / (shaft + disks)) / (2 * math.pi), rel=1e-3)


def test_cross_coupled_bearings_are_circulatory():
    """A bearing's skew stiffness kyz = -kzy is no potential: K0 stays symmetric (modes, reductions and
    the symmetric solvers see the conservative rotor), the skew part acts in Q only; undamped, a rotor
    on such bearings is unstable at rest (Campbell: an onset at 0)."""
    from nsfem.analysis.campbell import campbell_report
    from nsfem.scene import load_scene

    plain = build_model(load_scene("ross_example", ["reduction.method=none"]))
    cross = build_model(load_scene("ross_example", ["reduction.method=none", "bearing.0.kyz=5e5",
                                                    "bearing.0.kzy=-5e5"]))
    assert abs(cross.K - cross.K.T).max() == 0.0
    np.testing.assert_array_equal(cross.K.toarray(), plain.K.toarray())
    ops = rotor_operators(cross)
    Q = linear_system(ops, 10.0, frame="inertial").Q
    assert abs(Q - Q.T).max() == pytest.approx(2 * 5e5, rel=1e-12)      # the skew pair, doubled in Q - Q^T
    scene = load_scene("ross_example", ["reduction.method=none", "bearing.0.kyz=1e6", "bearing.0.kzy=-1e6",
                                        "mesh.elements=10"])
    rep = campbell_report(scene, build_model(scene), [10.0, 20.0, 30.0], 4)
    assert rep["instability_hz"]["open"] == [0.0]


def test_instability_below_the_speed_grid_is_found():
    """A Jeffcott rotor with internal damping, asked on a grid that starts above its threshold: the
    onset is found below the grid (closed form w_n (1 + c_e / c_i))."""
    from nsfem.analysis.campbell import campbell
    from nsfem.analysis.whirl import instability_onsets

    beta, c_e = 1e-4, 20.0
    model, ops, k, m = jeffcott("inertial", 0.0, beta, c_e, rho=1.0)
    threshold_hz = math.sqrt(k / m) * (1 + c_e / (beta * k)) / (2 * math.pi)
    speeds = np.linspace(1.5 * threshold_hz, 3 * threshold_hz, 4)
    res = campbell(ops, speeds, 2, (0.0, beta), 0.0, frame="inertial")
    assert res.growth_per_s[0] > 0
    onsets = instability_onsets(ops, speeds, res.growth_per_s, 2, (0.0, beta), 0.0)
    np.testing.assert_allclose(onsets, [threshold_hz], rtol=1e-4)      # as the on-grid test


def test_forward_critical_speeds_of_a_gyroscopic_disk():
    """Isotropic supports: only forward whirl is driven by an unbalance; the disk on a light cantilever's
    tip whirls synchronously forwards where (k11 - m w^2)(k22 - (I_d - I_p) w^2) = k12^2 (the 2-dof tip
    model of test_gyroscopic_splitting with whirl = spin = w)."""
    from nsfem.analysis.whirl import critical_speeds
    from nsfem.fem.components import lateral_turn

    D, L, m, Id, Ip = 0.02, 0.5, 4.0, 0.02, 0.04
    # shaft density 1 (mass 4e-5 of the disk's): the critical-speed pencil drops roots more than 1e12
    # below its largest one (in w^2) as rigid, and a lighter shaft's spectrum is that wide
    model = tip_disk(16, D, 1.0, L, m, Id, Ip)
    EI = E * math.pi * D**4 / 64
    k11, k12, k22 = 12 * EI / L**3, -6 * EI / L**2, 4 * EI / L
    # (k11 - m x)(k22 - (Id - Ip) x) - k12^2 = 0 in x = w^2: with Ip > Id one positive root only (the
    # disk's spin stiffens its tilt without bound)
    a, b, c = m * (Id - Ip), -(k11 * (Id - Ip) + m * k22), k11 * k22 - k12**2
    x = np.roots([a, b, c])
    exact = np.sort(np.sqrt(x[x > 0].real)) / (2 * math.pi)
    crit, sense = critical_speeds(rotor_operators(model), lateral_turn(model.spaces, model.n_full),
                                  forward_only=True)
    # the shaft's mass (ratio 4e-5, about a quarter of it moving with the tip) shifts the root by about 1e-5
    np.testing.assert_allclose(crit[: exact.size], exact, rtol=1e-4)
    assert np.all(sense == 1)
    both, senses = critical_speeds(rotor_operators(model), lateral_turn(model.spaces, model.n_full))
    assert -1 in senses.tolist()                                       # backward crossings exist


def test_rotating_frame_campbell_refuses_anisotropic_bearings_even_at_rest():
    from nsfem.analysis.campbell import campbell_report
    from nsfem.scene import load_scene, scene_file
    from nsfem.sweep import scene_source

    scene = load_scene("ross_example", ["rotation.speed_hz=0", 'rotation.frame="rotating"'])
    with pytest.raises(SceneError, match="rotation.frame: bearing.0 is not isotropic"):
        campbell_report(scene, build_model(scene), [0.0, 10.0], 4)
    # a sweep reads the shipped scene's text by its name too
    assert scene_source("ross_example") == scene_file("ross_example").read_text(encoding="utf-8")
