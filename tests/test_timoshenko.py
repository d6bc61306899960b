"""Timoshenko beam elements (issue 35 item 1): closed forms, ROSS 2.3.0 with shear on, the pipeline."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg as sl

from nsfem.fem import hermite, timoshenko
from nsfem.fem.assemble import assemble
from nsfem.mesh import generate
from nsfem.stack import BeamStack, Segment, Support

E, RHO = 2.1e11, 7850.0
G = E / 2.6                                   # the default shear modulus: nu = 0.3
KAPPA = 6 * 1.3 / (7 + 6 * 0.3)            # Cowper's for a solid circle (ROSS's default)
THEORIES = ("euler-bernoulli", "rayleigh", "timoshenko")


def pinned_beam(theory: str, diameter: float, length: float = 1.0) -> BeamStack:
    seg = Segment("s", 0.0, length, diameter, diameter, E=E, rho=RHO, section="circle")
    return BeamStack((seg,), supports=(Support("s", 0.0, ("U", "V", "W")), Support("s", length, ("V", "W"))),
                     theory=theory).validate()


def plane_frequencies(theory: str, diameter: float, elements: int, count: int = 3) -> np.ndarray:
    """The lowest circular frequencies of the V plane of a pinned-pinned shaft (the W plane repeats them)."""
    stack = pinned_beam(theory, diameter)
    model = assemble(stack, generate(stack, elements))
    held = {model.dof("s", "V", 0.0), model.dof("s", "V", 1.0)}
    keep = np.array([i for i in model.spaces["s"].dofs["V"] if i not in held])
    K, M = (A[keep][:, keep].toarray() for A in (model.K_full, model.M_full))
    return np.sqrt(sl.eigh(K, M, eigvals_only=True)[:count])


def exact_frequencies(theory: str, diameter: float, count: int = 3, length: float = 1.0) -> np.ndarray:
    """The pinned-pinned spectrum in closed form. With v = V sin(k x), psi = Psi cos(k x), k = n pi / L,
    Timoshenko's equations give the quadratic in w^2
        rho^2 I / (kappa G) w^4 - (rho A + rho I (1 + E / (kappa G)) k^2) w^2 + E I k^4 = 0,
    both of whose roots are modes, and n = 0 gives the thickness-shear mode v = 0, psi = const at
    w^2 = kappa G A / (rho I). Rayleigh: w^2 = E I k^4 / (rho A + rho I k^2); Euler-Bernoulli:
    w^2 = E I k^4 / (rho A)."""
    A, I = math.pi * diameter**2 / 4, math.pi * diameter**4 / 64
    out = []
    for n in range(1, count + 1):
        k = n * math.pi / length
        if theory == "euler-bernoulli":
            out.append(E * I * k**4 / (RHO * A))
        elif theory == "rayleigh":
            out.append(E * I * k**4 / (RHO * A + RHO * I * k**2))
        else:
            a, b, c = RHO**2 * I / (KAPPA * G), -(RHO * A + RHO * I * (1 + E / (KAPPA * G)) * k**2), E * I * k**4
            d = math.sqrt(b * b - 4 * a * c)
            out += [2 * c / (-b + d), (-b + d) / (2 * a)]     # the lower root written without cancellation
    if theory == "timoshenko":
        out.append(KAPPA * G * A / (RHO * I))
    return np.sqrt(np.sort(out)[:count])


def lower_branch(theory: str, diameter: float, n: int) -> float:
    """The n-th flexural (lower-branch) frequency alone."""
    A, I = math.pi * diameter**2 / 4, math.pi * diameter**4 / 64
    k = n * math.pi
    if theory != "timoshenko":
        return math.sqrt(E * I * k**4 / (RHO * A + (RHO * I * k**2 if theory == "rayleigh" else 0.0)))
    a, b, c = RHO**2 * I / (KAPPA * G), -(RHO * A + RHO * I * (1 + E / (KAPPA * G)) * k**2), E * I * k**4
    return math.sqrt(2 * c / (-b + math.sqrt(b * b - 4 * a * c)))


@pytest.mark.parametrize("slenderness", [5, 10, 20, 50])
def test_pinned_pinned_frequencies_converge_to_the_closed_forms(slenderness):
    """L / r = 5 ... 50 (r = D / 4, the solid circle's radius of gyration), modes 1 to 3 of each theory.

    Ritz: each finite-element frequency lies above the exact one (to round-off, 1e-12 relative). The
    cubic Hermite element's frequency error falls as h^4; the interdependent Timoshenko element's as h^2
    wherever shear matters (its shear strain is constant on an element: the shear energy's error is
    O(h^2)), towards h^4 for a slender shaft where bending dominates. So the observed order between 8, 16
    and 32 elements lies in [1.9, 4.2], and the error at 32 elements is within the Richardson estimate
    (f16 - f32) / (2^p - 1) of order p >= 1.9 (slack 1.3 for the pre-asymptotic terms)."""
    D = 4.0 / slenderness
    for theory in THEORIES:
        exact = exact_frequencies(theory, D)
        f8, f16, f32 = (plane_frequencies(theory, D, n) for n in (8, 16, 32))
        assert np.all(f32 >= exact * (1 - 1e-12)), (theory, f32 / exact - 1)
        order = np.log2((f8 - f16) / (f16 - f32))
        assert np.all((order > 1.9) & (order < 4.2)), (theory, order)
        assert np.all(f32 - exact <= 1.3 * (f16 - f32) / (2**1.9 - 1)), (theory, f32 / exact - 1)
    # a pre-set rate: the Timoshenko element converges at h^2 on the stubby shaft, its error quartering
    if slenderness <= 20:
        e16, e32 = (plane_frequencies("timoshenko", D, n)[0] / exact_frequencies("timoshenko", D)[0] - 1
                    for n in (16, 32))
        assert 3.6 < e16 / e32 < 4.4


@pytest.mark.parametrize("slenderness", [5, 10, 20, 50])
def test_shear_and_rotary_inertia_lower_each_flexural_mode(slenderness):
    """EB > Rayleigh > Timoshenko for each flexural mode, in closed form and in the model (64 elements:
    each model frequency within 1e-3 of its closed form, far below the gaps: rotary inertia lowers mode n
    by (n pi r / L)^2 / 2, 2e-5 for n = 1 at L / r = 50; shear by about E / (kappa G) as much again)."""
    D = 4.0 / slenderness
    for n in (1, 2, 3):
        eb, ra, ti = (lower_branch(t, D, n) for t in THEORIES)
        assert eb > ra > ti
    fe = {t: plane_frequencies(t, D, 64) for t in ("euler-bernoulli", "rayleigh")}
    assert np.all(fe["euler-bernoulli"] > fe["rayleigh"])
    if slenderness > 5:          # at L / r = 5 the thickness-shear mode lies below the second flexural one
        fe_t = plane_frequencies("timoshenko", D, 64)
        assert np.all(fe["rayleigh"] > fe_t)
        assert fe_t == pytest.approx([lower_branch("timoshenko", D, n) for n in (1, 2, 3)], rel=1e-3)


def test_element_matrices_are_their_definitions_and_hermites_without_shear():
    """The closed-form stiffness is the quadrature of E I int psi'^2 + kappa G A int (v' - psi)^2 (per E I,
    with kappa G A / (E I) = 12 / (Phi h^2)), to round-off; Phi = 0 gives the Hermite element (mass and
    stiffness to a few eps of their entries)."""
    h, phi = np.array([0.05, 0.3, 1.7]), np.array([0.01, 0.4, 3.0])
    g, wg = np.polynomial.legendre.leggauss(6)
    xi, wg = (g + 1) / 2, wg / 2
    eps = 1e-7
    v, psi = timoshenko.shape(xi, h, phi)
    # derivatives of the explicit polynomials: d/dx = (1/h) d/dxi, by the exact difference of a cubic
    vp = (timoshenko.shape(xi + eps, h, phi)[0] - timoshenko.shape(xi - eps, h, phi)[0]) / (2 * eps * h[:, None, None])
    pp = (timoshenko.shape(xi + eps, h, phi)[1] - timoshenko.shape(xi - eps, h, phi)[1]) / (2 * eps * h[:, None, None])
    gamma = vp - psi
    bend = np.einsum("eiq,ejq,q,e->eij", pp, pp, wg, h)
    shear = np.einsum("eiq,ejq,q,e->eij", gamma, gamma, wg, h) * (12 / (phi * h**2))[:, None, None]
    K = timoshenko.element_stiffness(h, phi)
    # central differences of polynomials of degree <= 3 carry eps^2 |f'''| ~ 1e-14 of truncation plus
    # 1e-16 / 1e-7 = 1e-9 of round-off relative to the entries
    np.testing.assert_allclose(bend + shear, K, rtol=1e-7, atol=1e-7 * np.abs(K).max())
    # the shear strain is constant on each element: the element solves the static beam exactly
    assert np.ptp(gamma, axis=2).max() < 1e-6
    # the planes' cross integral is the plane's own when their Phi agree, and symmetric under exchange
    np.testing.assert_allclose(timoshenko.element_cross(h, phi, phi), timoshenko.element_mass(h, phi), rtol=1e-15)
    np.testing.assert_allclose(timoshenko.element_cross(h, phi, 2 * phi, rotation=True),
                               np.swapaxes(timoshenko.element_cross(h, 2 * phi, phi, rotation=True), 1, 2), rtol=1e-15)
    z = np.zeros(3)
    np.testing.assert_allclose(timoshenko.element_mass(h, z), hermite.element_mass(h), rtol=1e-14, atol=1e-17)
    np.testing.assert_allclose(timoshenko.element_rotary(h, z), hermite.element_stretch(h), rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(timoshenko.element_stiffness(h, z), hermite.element_bend(h), rtol=1e-14)


@pytest.mark.parametrize("nu", [0.0, 0.25, 0.3, 0.5])
def test_shear_coefficients_are_the_literatures(nu):
    """Cowper (1966): a solid circle 6 (1 + nu) / (7 + 6 nu), a thin tube 2 (1 + nu) / (4 + 3 nu), a rectangle
    10 (1 + nu) / (12 + 11 nu). Hutchinson (2001; the value "most authors have considered best", Stephen's
    discussion, J. Appl. Mech. 68, 959): a solid circle 6 (1 + nu)^2 / (7 + 12 nu + 4 nu^2), a hollow one of
    radii a, b 6 (a^2 + b^2)^2 (1 + nu)^2 / (7 a^4 + 34 a^2 b^2 + 7 b^4 + nu (12 a^4 + 48 a^2 b^2 + 12 b^4) +
    nu^2 (4 a^4 + 16 a^2 b^2 + 4 b^4)), whose thin-walled limit is 1/2 at nu = 0 like Cowper's. (ROSS 2.3.0's
    "hutchinson" has (1 + nu) where Hutchinson has (1 + nu)^2: 0.71 instead of 0.925 at nu = 0.3.) Closed
    forms evaluated the same way: round-off, 1e-14."""
    k = timoshenko.shear_coefficient
    assert k("circle", nu) == pytest.approx(6 * (1 + nu) / (7 + 6 * nu), rel=1e-14)
    assert k("circle", nu, 1.0, 1.0 - 1e-9) == pytest.approx(2 * (1 + nu) / (4 + 3 * nu), rel=1e-8)
    assert k("rectangle", nu) == pytest.approx(10 * (1 + nu) / (12 + 11 * nu), rel=1e-14)
    assert k("circle", nu, method="hutchinson") == pytest.approx(6 * (1 + nu)**2 / (7 + 12 * nu + 4 * nu**2), rel=1e-14)
    a, b = 0.05, 0.03
    want = 6 * (a * a + b * b)**2 * (1 + nu)**2 / (7 * a**4 + 34 * a * a * b * b + 7 * b**4
                                                   + nu * (12 * a**4 + 48 * a * a * b * b + 12 * b**4)
                                                   + nu**2 * (4 * a**4 + 16 * a * a * b * b + 4 * b**4))
    assert k("circle", nu, 2 * a, 2 * b, method="hutchinson") == pytest.approx(want, rel=1e-14)
    if nu == 0.0:
        assert k("circle", nu, 1.0, 1.0 - 1e-9, method="hutchinson") == pytest.approx(0.5, rel=1e-8)


@pytest.mark.parametrize("section", ["circle", "rectangle"])
def test_one_element_cantilever_tip_deflection_is_exact(section):
    """A cantilever under a tip force P: w = P L^3 / (3 E I) + P L / (kappa G A), bending and shear, with ONE
    element (the interdependent element is the static solution for end loads): to round-off (the 2 x 2
    solve's condition ~ (L / h_section)^2 ~ 1e3, times eps: 1e-12 relative). The rectangle bends W with I_y
    and V with I_z, kappa Cowper's 10 (1 + nu) / (12 + 11 nu)."""
    L, P, Gs = 0.4, 1e3, 7.9e10
    seg = (Segment("s", 0.0, L, 0.08, 0.08, E=E, rho=RHO, section="circle", G=Gs) if section == "circle" else
           Segment("s", 0.0, L, 0.06, 0.1, E=E, rho=RHO, G=Gs))
    stack = BeamStack((seg,), supports=(Support("s", 0.0, ("U", "V", "W", "V'", "W'")),),
                      theory="timoshenko").validate()
    model = assemble(stack, generate(stack, 1))
    nu = E / (2 * Gs) - 1
    kappa = 10 * (1 + nu) / (12 + 11 * nu) if section == "rectangle" else 6 * (1 + nu) / (7 + 6 * nu)
    for fld, I in (("V", seg.I_z), ("W", seg.I_y)):
        f = np.zeros(model.n_full)
        f[model.dof("s", fld, L)] = P
        K = (model.T.T @ model.K_full @ model.T).toarray()
        q = model.T @ np.linalg.solve(K, model.T.T @ f)
        want = P * L**3 / (3 * E * I) + P * L / (kappa * Gs * seg.area)
        assert q[model.dof("s", fld, L)] == pytest.approx(want, rel=1e-12)
        # the tip rotation: bending alone, P L^2 / (2 E I) (shear does not turn the sections)
        assert q[model.dof("s", fld + "'", L)] == pytest.approx(P * L**2 / (2 * E * I), rel=1e-12)


# ---------------------------------------------------------------- ROSS 2.3.0 with shear on
#: ROSS 2.3.0's rotor3 of ross/tests/test_rotor_assembly.py (6 ShaftElements of 0.25 m with its defaults: shear
#: on with Cowper's kappa = 0.886306356763, phi = 0.0879556650246; disks from geometry at nodes 2 (outer 0.28 m)
#: and 4 (outer 0.35 m), bearings kxx = 1e6, kyy = 8e5 N/m at nodes 0 and 6, steel E 211e9, G_s 81.2e9, rho
#: 7810): the lowest 8 lateral wd [rad/s] of run_modal at each speed, and the speeds where a root's wd equals
#: the speed (brentq). How: /work/rossvenv/bin/python studies/ross_timoshenko.py (printed with repr).
ROSS_ROTOR3_WD = {
    0.0: [82.65303733556736, 86.65811435148956, 254.52047828237409, 274.3128539134222, 679.4890323815636,
          716.7863122127058, 1032.3915317624628, 1066.1562003864751],
    100.0: [82.63352553572449, 86.67069274911151, 253.18588892543863, 275.5338486568403, 664.9017383992654,
            731.0115791131321, 1031.403702799227, 1066.870278983818],
    300.0: [82.4813272311157, 86.76734307323554, 245.4909284380595, 282.33294698788984, 614.055362770479,
            779.0777833453193, 1024.5776213193353, 1071.517438161316],
    1000.0: [81.03348804246193, 87.57329570388161, 208.04894105692776, 311.0646853482717, 457.9966828374221,
             913.4156819295066, 978.9693924212336, 1093.8325576186828],
}
ROSS_ROTOR3_CRITICAL = [82.63969961116351, 86.6675733115961, 247.85538666106342, 281.59892942150486]
#: ross.rotor_example() as shipped (shear on, the same element; both disks 0.28 m), wd at 0 and 500 rad/s
ROSS_EXAMPLE_WD = {
    0.0: [91.79655317547751, 96.28899976985788, 274.5659451261476, 296.50048531755726, 722.8978749492842,
          765.0004291608805, 1069.6595997887705, 1103.628982710992],
    500.0: [91.56035074098234, 96.45663974846025, 265.40599986987934, 305.3534547593894, 658.346552303948,
            821.3253588409547, 1062.9206562893698, 1107.6454643694356],
}
#: ross_example on ROSS's mesh with its shear: theory = "timoshenko" is the only change (the scene has G_s)
ROSS_MESH = ["mesh.elements=6", "reduction.method=none", "beam.theory=timoshenko"]


def _whirl(overrides, speeds_rad):
    from nsfem.analysis.campbell import campbell
    from nsfem.fem.assemble import build_model
    from nsfem.fem.components import lateral_turn
    from nsfem.fem.rotating import rotor_operators
    from nsfem.scene import load_scene

    model = build_model(load_scene("ross_example", overrides))
    ops = rotor_operators(model)
    turn = lateral_turn(model.spaces, model.n_full)
    res = campbell(ops, np.asarray(speeds_rad) / (2 * math.pi), 9, frame="inertial", turn=turn)
    lateral = [w != 2 for w in res.whirl]                # our model has the thrust bearing's axial mode too
    return [2 * math.pi * f[k][:8] for f, k in zip(res.frequencies_hz, lateral)], ops, turn


@pytest.mark.parametrize("rotor, overrides, table", [
    ("rotor3", ["disk.1.outer_diameter=0.35"], ROSS_ROTOR3_WD),
    ("rotor_example", [], ROSS_EXAMPLE_WD)])
def test_whirl_frequencies_match_ross_with_shear(rotor, overrides, table):
    """The same element (interdependent Timoshenko, Cowper's kappa, consistent mass) on ROSS's mesh: the
    whirl frequencies agree to the eigen solvers' round-off (measured 1.5e-11 over the 8 modes and speeds; two
    runs of ROSS's script differ by up to 2.6e-11; 1e-9 leaves room for other BLAS kernels); Hutchinson's kappa instead of Cowper's moves them by up to 3.3e-4,
    shear left out (rayleigh) by up to 8e-3."""
    speeds = sorted(table)
    got, _, _ = _whirl(ROSS_MESH + overrides, speeds)
    for s, g in zip(speeds, got):
        np.testing.assert_allclose(g, table[s], rtol=1e-9)
    other, _, _ = _whirl(ROSS_MESH + overrides + ["beam.shear_coefficient=hutchinson"], speeds[:1])
    assert np.abs(other[0] / table[speeds[0]] - 1).max() > 1e-4     # the comparison can tell kappas apart


def test_critical_speeds_match_ross_with_shear():
    """Undamped critical speeds (the Hermitian pencil K0 x = Omega^2 (M - i Gp1) x) against ROSS's crossings of
    wd with the speed (brentq to 1e-12 rad/s): both exact for the same model, so round-off, 1e-9."""
    from nsfem.analysis.whirl import critical_speeds

    _, ops, turn = _whirl(ROSS_MESH + ["disk.1.outer_diameter=0.35"], [0.0])
    speeds, whirl = critical_speeds(ops, turn, max_hz=60.0)
    np.testing.assert_allclose(2 * math.pi * speeds, ROSS_ROTOR3_CRITICAL, rtol=1e-9)
    assert list(whirl) == [-1, 1, -1, 1]                 # anisotropic bearings: backward and forward alike


# ---------------------------------------------------------------- between the nodes: sensors and hat weights
def _tip_loaded_cantilever(L: float, P: float, elements: int, contacts=()):
    """(model, segment, full displacement) of a clamped 80 mm Timoshenko rod of length L under a tip force P along z."""
    seg = Segment("s", 0.0, L, 0.08, 0.08, E=E, rho=RHO, section="circle")
    stack = BeamStack((seg,), supports=(Support("s", 0.0, ("U", "V", "W", "V'", "W'")),), contacts=tuple(contacts),
                      theory="timoshenko").validate()
    model = assemble(stack, generate(stack, elements))
    f = np.zeros(model.n_full)
    f[model.dof("s", "W", L)] = P
    K = (model.T.T @ model.K_full @ model.T).toarray()
    return model, seg, model.T @ np.linalg.solve(K, model.T.T @ f)


def test_sensor_between_nodes_reads_the_static_solution():
    """A sensor reads the element's displacement functions N_v between nodes; on the one-element cantilever
    under a tip force they are the exact static solution w(x) = P x^2 (3 L - x) / (6 E I) + P x / (kappa G A)
    (a Hermite cubic of the nodal values would miss the shear part's linear growth): to round-off."""
    from nsfem.sensors import hermite_row

    L, P = 0.4, 1e3
    model, seg, q = _tip_loaded_cantilever(L, P, 1)
    for x in (0.05, 0.17, 0.33):
        want = P * x**2 * (3 * L - x) / (6 * E * seg.I_y) + P * x / (KAPPA * G * seg.area)
        assert float((hermite_row(model, "s", "W", x) @ q)[0]) == pytest.approx(want, rel=1e-12)


def test_hat_weights_reproduce_rigid_motions_with_shear():
    """The hat-weighted average of a rigid motion (v = a + b x, psi = b: no shear strain) is its value at the
    hat's centroid; the interdependent functions reproduce rigid motions exactly, so to round-off."""
    x = np.linspace(0.0, 1.0, 11)
    phi = np.full(10, 0.7)
    a, b, lo, mid, hi = 0.3, -1.2, 0.2, 0.5, 0.8

    def hat(s):
        return np.where((s >= lo) & (s <= hi), np.minimum((s - lo) / (mid - lo), (hi - s) / (hi - mid)), 0.0) / 0.3

    q = np.empty(22)
    q[0::2], q[1::2] = a + b * x, b
    assert hermite.assemble_weighted(x, hat, phi=phi) @ q == pytest.approx(a + b * mid, rel=1e-14)
    assert hermite.assemble_weighted(x, hat, slope=True, phi=phi) @ q == pytest.approx(b, rel=1e-14)


def test_hat_weighted_contact_reads_the_sheared_static_solution():
    """A hat-weighted contact row (eq. 19) averages the element's displacement functions N_v (and, for a
    slope, the rotation's N_psi) of their Phi: on a 4-element cantilever under a tip force, whose elements
    are the exact static solution w(x) = P x^2 (3 L - x) / (6 E I) + P x / (kappa G A), psi(x) = P x (2 L - x)
    / (2 E I), the rows give int hat w dx and int hat psi dx to round-off (1e-12; the integrals by Gauss on each
    linear piece of the hat, exact). Hermite cubics of the nodal values would miss the shear part of w between
    the nodes (the hat here spans 1.4 elements: 1.1e-4 relative, measured)."""
    from nsfem.contact.kinematics import point_row
    from nsfem.stack import Contact

    L, P = 0.4, 1e3
    a, mid, b = 0.13, 0.21, 0.27
    contact = Contact("obstacle", mid, ("s",), "hat", (a, b), clearance=1.0)
    model, seg, q = _tip_loaded_cantilever(L, P, 4, (contact,))
    g, wg = np.polynomial.legendre.leggauss(4)
    x = np.concatenate([lo + (hi - lo) * (g + 1) / 2 for lo, hi in ((a, mid), (mid, b))])
    w8 = np.concatenate([(hi - lo) * wg / 2 for lo, hi in ((a, mid), (mid, b))])
    hat = np.minimum((x - a) / (mid - a), (b - x) / (b - mid)) * 2 / (b - a)
    exact_w = P * x**2 * (3 * L - x) / (6 * E * seg.I_y) + P * x / (KAPPA * G * seg.area)
    exact_psi = P * x * (2 * L - x) / (2 * E * seg.I_y)
    for fld, exact in (("W", exact_w), ("W'", exact_psi)):
        row = point_row(model, "s", fld, contact)
        got = sum(v * q[i] for i, v in row.items())
        assert got == pytest.approx(float(np.sum(hat * exact * w8)), rel=1e-12), fld


# ---------------------------------------------------------------- the pipeline
def _cli(argv, tmp_path):
    """``nsfem argv`` in ``tmp_path`` through test_fuzz's invocation check, which must succeed: (JSON or None, stderr)."""
    import json

    from test_fuzz import check_invocation

    code, out, err = check_invocation(argv, tmp_path)
    assert code == 0, err
    return json.loads(out) if "--json" in argv else None, err


SS_SCENE = """
[shaft]
length = 0.5
section = "circle"
diameter = 0.1
supports = "pinned-pinned"
[beam]
theory = "{theory}"
[rotation]
gravity = 9.81
[reduction]
method = "none"
[mesh]
elements = 10
"""


def test_stationary_sag_of_a_stubby_shaft_has_its_shear_part(tmp_path):
    """nsfem stationary on a pinned-pinned shaft (L / D = 5) under its weight q = rho A g: the midspan sag is
    5 q L^4 / (384 E I) + q L^2 / (8 kappa G A) (shear adds 7 % here). The interdependent element with its
    consistent load is exact at the nodes for a uniform load: round-off (1e-10). Without shear the scene gets
    the stubby-rotor note, and its sag is the bending part alone."""
    scene = tmp_path / "ss.toml"
    L, D = 0.5, 0.1
    A, I = math.pi * D**2 / 4, math.pi * D**4 / 64
    q = 7850.0 * A * 9.81                                # the shaft's default rho and E
    bending, shear = 5 * q * L**4 / (384 * E * I), q * L**2 / (8 * KAPPA * G * A)
    for theory, want in (("timoshenko", bending + shear), ("euler-bernoulli", bending)):
        scene.write_text(SS_SCENE.format(theory=theory))
        out, err = _cli(["stationary", str(scene), "--json"], tmp_path)
        sag = out["max_deflection"]
        assert sag["x_m"] == pytest.approx(L / 2) and sag["deflection_m"][1] == pytest.approx(-want, rel=1e-10)
        stubby = [n for n in out["notes"] if "stubby" in n]
        assert bool(stubby) == (theory != "timoshenko"), out["notes"]
    assert shear / bending > 0.05


TINY = ["--set", "simulation.t_end=0.004", "--set", "simulation.output_dt=0.001", "--set", "output.plots=[]"]
SHEAR = ["--set", "beam.theory=\"timoshenko\""]


@pytest.mark.parametrize("argv", [
    ["run", "rub", "--method", "exact", "--set", "mesh.elements=8", "--set", "reduction.modes=6",
     "--set", "output.vtu_every=1"],
    ["run", "rub", "--method", "rk", "--set", "mesh.elements=8", "--set", "reduction.modes=6",
     "--set", "output.vtu_every=0"],
    ["run", "crack", "--method", "exact", "--set", "mesh.elements=10", "--set", "output.vtu_every=1"],
], ids=["rub-exact-vtu", "rub-rk", "crack-exact-vtu"])
def test_runs_with_shear_write_sensors_and_vtu(argv, tmp_path):
    """A ring contact (rub) with the exact and rk integrators and a breathing crack, with Timoshenko elements:
    each run finishes, its sensors.csv has finite readings and its VTU frames (when asked) exist."""
    _, err = _cli([*argv, *SHEAR, *TINY, "--out", "out"], tmp_path)
    csv = np.loadtxt(tmp_path / "out" / "sensors.csv", delimiter=",", skiprows=1, ndmin=2)
    assert csv.shape[0] >= 4 and np.all(np.isfinite(csv))
    if "output.vtu_every=1" in argv:
        assert (tmp_path / "out" / "nsfem.pvd").exists() and any((tmp_path / "out" / "vtu").iterdir())


def test_modes_campbell_response_with_shear(tmp_path):
    """modes (at rest and at speed), campbell and response of ross_example with shear on its own mesh: the
    modes and Campbell's frequencies at rest are ROSS's with shear (rotor_example, 1e-9: round-off), the
    first undamped critical speed is a whirl frequency at that speed (1e-9: both solves' round-off), and the
    1x response peaks near the first critical speeds (the first two wd at rest: 14.6 and 15.3 Hz)."""
    base = ["ross_example", *SHEAR, "--set", "mesh.elements=6", "--set", "reduction.method=\"none\""]
    out, _ = _cli(["modes", *base, "--json", "--count", "9"], tmp_path)
    f = np.array(out["frequencies_hz"])
    lateral = np.sort(2 * math.pi * f)
    assert any(abs(w / ROSS_EXAMPLE_WD[0.0][0] - 1) < 1e-9 for w in lateral)
    out, _ = _cli(["modes", *base, "--json", "--speed", str(500 / (2 * math.pi)), "--count", "9"], tmp_path)
    got = 2 * math.pi * np.array(out["frequencies_hz"])
    assert any(abs(w / ROSS_EXAMPLE_WD[500.0][0] - 1) < 1e-9 for w in got)
    out, _ = _cli(["campbell", *base, "--json", "--speeds", "0:30:4", "--count", "9"], tmp_path)
    at_rest = [f for f, w in zip(out["frequencies_hz"][0], out["whirl"][0]) if w != "axial"]
    np.testing.assert_allclose(2 * math.pi * np.array(at_rest[:6]), ROSS_EXAMPLE_WD[0.0][:6], rtol=1e-9)
    # each undamped critical speed is a whirl frequency of the rotor spinning at it (its own 1x crossing)
    crit = out["undamped_critical_speeds_hz"]["open"][0]
    spun, _ = _cli(["modes", *base, "--json", "--speed", repr(crit), "--count", "4"], tmp_path)
    assert min(abs(f / crit - 1) for f in spun["frequencies_hz"]) < 1e-9
    out, _ = _cli(["response", *base, "--json", "--speeds", "10:20:41"], tmp_path)
    peak = max(out["peaks"], key=lambda p: p["amplitude_m"])
    assert 14.0 < peak["speed_hz"] < 16.0


# ---------------------------------------------------------------- spinning: both frames, rigid motions
def _stubby_rotor(theory="timoshenko", supports="free-free", **extra):
    """A hollow stubby shaft (L / D = 7.5, shear lowers its bending modes by percents) on two isotropic damped
    cross-coupled bearings with a disk, internal and external damping."""
    from nsfem.fem.assemble import build_model
    from nsfem.scene import scene_from_tree

    tree = {"shaft": {"length": 0.6, "section": "circle", "diameter": 0.08, "inner_diameter": 0.03, "E": E,
                      "rho": RHO, "G": 7.9e10, "supports": supports},
            "beam": {"theory": theory}, "mesh": {"elements": 8}, "reduction": {"method": "none"},
            "rotation": {"speed_hz": 0.0, "gravity": 0.0},
            "disk": [{"x": 0.2, "outer_diameter": 0.3, "width": 0.03}],
            "bearing": [{"x": 0.0, "kyy": 5e7, "kzz": 5e7, "kyz": 4e6, "kzy": -4e6, "cyy": 900.0, "czz": 900.0,
                         "kxx": 1e8}, {"x": 0.6, "kyy": 6e7, "kzz": 6e7, "cyy": 700.0, "czz": 700.0}],
            "damping": {"rayleigh": [0.4, 1e-6], "external": 2.0}}
    tree.update(extra)
    return build_model(scene_from_tree(tree))


@pytest.mark.parametrize("speed_hz", [40.0, 300.0])
def test_rotating_and_inertial_frames_agree_with_shear(speed_hz):
    """The same spinning rotor seen from both frames: each inertial root lambda is a rotating-frame root
    lambda - i Omega s (s = +1 forward, -1 backward, 0 axial). This ties the Timoshenko element's Coriolis
    (int N_v N_v), centrifugal and rotary (int N_psi N_psi) terms to its spin couple (rho I_p int N_psi N_psi)
    and the damping seen from each frame. Two 76 x 76 state matrices whose roots span 1e5: dense eigen
    solvers hold simple roots to a few hundred ulps of the matrix norm, 1e-11 of the largest root."""
    from nsfem.analysis.whirl import AXIAL, whirl_sense
    from nsfem.fem.components import lateral_turn
    from nsfem.fem.rotating import rotor_operators
    from nsfem.system import linear_system

    model = _stubby_rotor()
    ops = rotor_operators(model)
    damping = dict(rayleigh=(0.4, 1e-6), external=2.0)
    sys_i = linear_system(ops, speed_hz, frame="inertial", **damping)
    sys_r = linear_system(ops, speed_hz, frame="rotating", **damping)

    def state(s):
        M, C, Q = (A.toarray() for A in (s.M, s.C, s.Q))
        n = M.shape[0]
        return np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, Q), -np.linalg.solve(M, C)]]), n

    Ai, n = state(sys_i)
    lam_i, X = np.linalg.eig(Ai)
    senses = whirl_sense(X[:n], ops.basis, lateral_turn(model.spaces, model.n_full))
    lam_r = np.linalg.eigvals(state(sys_r)[0])
    w = 2 * math.pi * speed_hz
    scale = np.abs(lam_i).max()
    used = np.zeros(lam_r.size, dtype=bool)
    for lam, sense in zip(lam_i, senses):
        d = np.abs(lam_r - (lam - 1j * w * (0 if sense == AXIAL else sense)))
        d[used] = np.inf
        k = int(np.argmin(d))
        assert d[k] < 1e-11 * scale, (lam, d[k] / scale)
        used[k] = True


def test_free_rigid_tilt_whirls_at_the_rotation_frequency_with_shear():
    """A free-free Timoshenko shaft's rigid motions carry no shear (psi = v'), so in the rotating frame two
    translations and one tilt sit at Omega and the other tilt is the spinning rod's nutation
    Omega (1 - I_p / I_d), I_p / I_d = 2 I / (A L^2 / 12 + I) of the uniform shaft, to campbell's
    resolution of defective rigid roots (sqrt(eps) omega_max: 1e-5 of Omega here, 4e-5 allowed)."""
    from nsfem.analysis.campbell import campbell
    from nsfem.fem.rotating import rotor_operators

    model = _stubby_rotor(disk=[], bearing=[{"x": 0.0, "kxx": 1e8}], damping={"rayleigh": [0.0, 0.0]})
    res = campbell(rotor_operators(model), [30.0], 6)
    f = np.sort(res.frequencies_hz[0])
    D, d, L = 0.08, 0.03, 0.6
    A, I = math.pi * (D**2 - d**2) / 4, math.pi * (D**4 - d**4) / 64
    nutation = 30.0 * (1 - 2 * I / (A * L**2 / 12 + I))
    assert np.count_nonzero(np.abs(f - 30.0) < 4e-5 * 30) == 3
    assert np.any(np.abs(f - nutation) < 4e-5 * 30), (f, nutation)
    assert abs(res.growth_per_s[0]) < 0.05


def test_rectangle_bends_each_plane_with_its_own_phi():
    """A pinned-pinned rectangle 0.1 m (y) x 0.05 m (z), L = 0.5 m: V bends with I_z = h b^3 / 12, W with
    I_y = b h^3 / 12, each with its Phi and Cowper's kappa 10 (1 + nu) / (12 + 11 nu). Each plane's first
    frequency against Timoshenko's closed form with that plane's I: from above (Ritz) and within 2e-4 with 64
    elements (the element's h^2 error: 1e-4 at 32 elements for L / r = 10 to 20 in the circle test, L / r =
    17 and 35 here)."""
    from nsfem.stack import Segment as Seg

    L, b, h = 0.5, 0.1, 0.05
    seg = Seg("s", 0.0, L, b, h, E=E, rho=RHO)
    stack = BeamStack((seg,), supports=(Support("s", 0.0, ("U", "V", "W")), Support("s", L, ("V", "W"))),
                      theory="timoshenko").validate()
    model = assemble(stack, generate(stack, 64))
    kappa = 10 * 1.3 / (12 + 11 * 0.3)
    A = b * h
    for fld, I in (("V", h * b**3 / 12), ("W", b * h**3 / 12)):
        held = {model.dof("s", fld, 0.0), model.dof("s", fld, L)}
        keep = np.array([i for i in model.spaces["s"].dofs[fld] if i not in held])
        K, M = (X[keep][:, keep].toarray() for X in (model.K_full, model.M_full))
        w = math.sqrt(sl.eigh(K, M, eigvals_only=True)[0])
        k = math.pi / L
        a_, b_, c_ = RHO**2 * I / (kappa * G), -(RHO * A + RHO * I * (1 + E / (kappa * G)) * k**2), E * I * k**4
        exact = math.sqrt(2 * c_ / (-b_ + math.sqrt(b_ * b_ - 4 * a_ * c_)))
        assert 0 <= w / exact - 1 < 2e-4, (fld, w / exact - 1)


def test_rectangle_plane_couplings_integrate_each_planes_own_functions():
    """A spinning rectangle couples V and W through its Coriolis (-2 rho A int v w), circulatory (-int v w)
    and the spin's couple (rho I_p int psi_V psi_W): v and psi_V of V's functions with Phi_V = 12 E I_z /
    (kappa G A h^2), w and psi_W of W's with Phi_W (I_y), 4 times Phi_V here. For random nodal values the
    assembled operators give these integrals (8 Gauss points per element, exact for the cubics' products) to
    round-off (1e-12 of the product of the norms); V's functions for both planes are off by 1.7e-2 in int v w
    and by a factor 2.7 in int psi_V psi_W here (measured)."""
    from nsfem.fem.rotating import full_operators

    L, b, h, n = 0.5, 0.1, 0.05, 6
    seg = Segment("s", 0.0, L, b, h, E=E, rho=RHO)
    stack = BeamStack((seg,), supports=(Support("s", 0.0, ("U",)),), theory="timoshenko").validate()
    model = assemble(stack, generate(stack, n))
    ops = full_operators(model)
    space = model.spaces["s"]
    kappa = 10 * 1.3 / (12 + 11 * 0.3)
    x = np.asarray(space.x, dtype=float)
    he = np.diff(x)
    phi = {"V": 12 * E * seg.I_z / (kappa * G * seg.area * he**2), "W": 12 * E * seg.I_y / (kappa * G * seg.area * he**2)}
    assert phi["V"][0] == pytest.approx(4 * phi["W"][0], rel=1e-12)
    g, wg = np.polynomial.legendre.leggauss(8)
    xi, wg = (g + 1) / 2, wg / 2
    rng = np.random.default_rng(35)
    nd = space.bending.nodal_dofs

    def fields(q, fld):
        """(value, rotation) at the Gauss points of every element, (elements, points) each."""
        d = space.dofs[fld]
        local = np.stack([q[d[nd[0, :-1]]], q[d[nd[1, :-1]]], q[d[nd[0, 1:]]], q[d[nd[1, 1:]]]], axis=1)
        value, rotation = timoshenko.shape(xi, he, phi[fld])
        return np.einsum("eiq,ei->eq", value, local), np.einsum("eiq,ei->eq", rotation, local)

    for _ in range(3):
        a, c = np.zeros(model.n_full), np.zeros(model.n_full)
        a[space.dofs["V"]] = rng.standard_normal(space.dofs["V"].size)
        c[space.dofs["W"]] = rng.standard_normal(space.dofs["W"].size)
        (v, pv), (w, pw) = fields(a, "V"), fields(c, "W")
        vw = float(np.einsum("eq,eq,q,e->", v, w, wg, he))
        pp = float(np.einsum("eq,eq,q,e->", pv, pw, wg, he))
        tol = 1e-12 * np.linalg.norm(a) * np.linalg.norm(c)
        assert a @ ops.G1 @ c == pytest.approx(-2 * RHO * seg.area * vw, abs=tol * RHO * seg.area)
        assert c @ ops.G1 @ a == pytest.approx(2 * RHO * seg.area * vw, abs=tol * RHO * seg.area)
        assert a @ ops.P1 @ c == pytest.approx(-vw, abs=tol)
        assert a @ ops.Gp1 @ c == pytest.approx(RHO * (seg.I_y + seg.I_z) * pp, abs=tol * RHO * seg.I_z)
        assert c @ ops.Gp1 @ a == pytest.approx(-RHO * (seg.I_y + seg.I_z) * pp, abs=tol * RHO * seg.I_z)


@pytest.mark.parametrize("diameter, theory, noted", [(0.2, "rayleigh", True), (0.2, "euler-bernoulli", True),
                                                     (0.2, "timoshenko", False), (0.14, "rayleigh", False)])
def test_a_stubby_span_without_shear_gets_a_note(diameter, theory, noted):
    """ross_example's bearing span of 1.5 m: 7.5 diameters of 0.2 m is stubby (< 10) and gets the note
    without shear; 10.7 diameters of 0.14 m is not; timoshenko has the shear."""
    from nsfem.scene import load_scene

    notes = load_scene("ross_example", [f"shaft.diameter={diameter}", f"beam.theory=\"{theory}\""]).notes
    stubby = [n for n in notes if "stubby" in n]
    assert bool(stubby) == noted, notes
    if noted:
        assert "x = 0 to 1.5 m is 7.5 section depths" in stubby[0] and "timoshenko" in stubby[0]
