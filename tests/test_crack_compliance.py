"""The open crack's local flexibility (nsfem.fem.crack) against independent routes to the same integrals."""

import math

import pytest
from scipy.integrate import dblquad

from nsfem.fem.crack import (circle_compliance, rectangle_compliance, rizos_J, strip_over_rizos, tada_bending,
                             tada_tension)

E = 2.1e11


@pytest.mark.parametrize("depth", [1e-3, 1e-4, 1e-6, 1e-7, 2e-8])
def test_circle_small_crack_limit(depth):
    """A shallow crack in a circle: alpha_max = a - y^2 / 2R, beta = sqrt(2 R a), F = F(0), so
    c_open -> 16/15 pi F_b(0)^2 R^2 a^2 beta / (E I^2) and c_other -> 16/105 pi F_t(0)^2 a^2 beta^3 / (E I^2)
    (the strip integrals in closed form). The first neglected terms are O(a / D) (F's slope at 0, the strip
    height's curvature): the error must be below 4 a/D and fall with a. The scaled strip integrals keep their
    tolerance however shallow the crack (down to 2e-8, where the closed form takes over; they used to warn
    and lose it near 1e-10)."""
    D = 0.05
    R, a = D / 2, depth * D
    beta, inertia = math.sqrt(a * (2 * R - a)), math.pi * R ** 4 / 4
    c_open, c_other = circle_compliance(E, D, depth)
    open_limit = 16 / 15 * math.pi * tada_bending(0.0) ** 2 * R ** 2 * a ** 2 * beta / (E * inertia ** 2)
    other_limit = 16 / 105 * math.pi * tada_tension(0.0) ** 2 * a ** 2 * beta ** 3 / (E * inertia ** 2)
    assert c_open == pytest.approx(open_limit, rel=4 * depth)
    assert c_other == pytest.approx(other_limit, rel=4 * depth)


def test_circle_limit_error_is_first_order():
    """The limit's error shrinks tenfold with the depth (first order): a wrong strip geometry (beta, the
    local depth) would leave an O(1) error that does not shrink."""
    D, errs = 0.05, []
    for depth in (1e-3, 1e-4):
        R, a = D / 2, depth * D
        beta, inertia = math.sqrt(a * (2 * R - a)), math.pi * R ** 4 / 4
        limit = 16 / 15 * math.pi * tada_bending(0.0) ** 2 * R ** 2 * a ** 2 * beta / (E * inertia ** 2)
        errs.append(abs(circle_compliance(E, D, depth)[0] / limit - 1))
    assert 7 < errs[0] / errs[1] < 13


def test_rectangle_other_axis_from_its_definition():
    """c_other = (2/E) int_{-b/2}^{b/2} dy int_0^a (y / I')^2 pi alpha F_t(alpha / h)^2 dalpha, integrated
    as it stands (a 2-D quadrature, no reduction to one integral): to the quadrature's 1e-8."""
    h, b, depth = 0.02, 0.01, 0.35
    inertia = h * b ** 3 / 12
    val = dblquad(lambda alpha, y: (y / inertia) ** 2 * math.pi * alpha * tada_tension(alpha / h) ** 2,
                  -b / 2, b / 2, 0.0, depth * h, epsabs=0.0, epsrel=1e-10)[0]
    assert rectangle_compliance(E, h, b, depth)[1] == pytest.approx(2 / E * val, rel=1e-8)


def test_rectangle_opening_axis_is_rizos():
    """The design's formula, c = 5.346 h J(a/h) / (E I), with J's small-crack term 1.8624 (a/h)^2 (the
    polynomial's higher terms are 4 % of it at a/h = 0.01)."""
    h, b, depth = 0.02, 0.01, 0.3
    assert rectangle_compliance(E, h, b, depth)[0] == pytest.approx(5.346 * h * rizos_J(depth) / (E * b * h ** 3 / 12),
                                                                   rel=1e-14)
    assert rizos_J(0.01) == pytest.approx(1.8624e-4, rel=0.04)


def test_sources_agree_within_the_stated_spread():
    """The module states the strip integration gives 1.22 to 1.31 times Rizos's compliance (a/h 0.05 to 0.7)."""
    ratios = [strip_over_rizos(s) for s in (0.05, 0.2, 0.4, 0.7)]
    assert all(1.22 <= r <= 1.32 for r in ratios)


def test_circle_symmetric_cross_section_numbers_increase_with_depth():
    """Deeper is softer on both axes, and the opening axis is the softer one (the crack's own bending)."""
    prev = (0.0, 0.0)
    for depth in (0.1, 0.2, 0.3, 0.4, 0.5):
        c = circle_compliance(E, 0.05, depth)
        assert c[0] > prev[0] and c[1] > prev[1] and c[0] > c[1]
        prev = c


@pytest.mark.parametrize("depth", [0.0, -0.1, 0.9, float("nan")])
def test_depth_outside_the_fits(depth):
    with pytest.raises(ValueError, match="crack depth"):
        circle_compliance(E, 0.05, depth)


# --- issue 32: shallow cracks ------------------------------------------------------------------------------
def test_shallow_cracks_need_no_quadrature_warning():
    """From 1e-300 to 0.5 no quadrature warning, finite non-negative compliances, and a centroid of the
    ligament that tends to the section's (the old acos(1 - a/R) was 0/0 below a = 1e-16 R)."""
    import warnings

    from nsfem.fem.crack import ligament_centroid

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for depth in (1e-300, 1e-200, 1e-17, 1e-10, 1e-3, 0.5):
            assert all(math.isfinite(c) and c >= 0.0 for c in circle_compliance(E, 0.02, depth))
            assert all(math.isfinite(c) and c >= 0.0 for c in rectangle_compliance(E, 0.02, 0.01, depth))
            assert -0.01 < ligament_centroid("circle", 0.02, depth) <= 0.0


@pytest.mark.parametrize("depth", [0.05, 0.3, 0.5])
def test_ligament_centroid_against_its_definition(depth):
    """The centroid of the disc minus the segment of height a, from the segment's area and centroid in their
    textbook form (fine for these depths): the rewritten, cancellation-free form agrees to round-off."""
    from nsfem.fem.crack import ligament_centroid

    R = 0.01
    psi = math.acos(1 - depth * 2 * R / R)
    area = R * R * (psi - math.sin(psi) * math.cos(psi))
    dist = 2 * R * math.sin(psi) ** 3 / (3 * (psi - math.sin(psi) * math.cos(psi)))
    assert ligament_centroid("circle", 2 * R, depth) == pytest.approx(-area * dist / (math.pi * R * R - area),
                                                                      rel=1e-12)


def test_hinge_compliance_floor():
    """A compliance below l / (MAX_HINGE_STIFFNESS E I) is raised to it, per slope with its own I; larger
    ones are kept exactly."""
    from nsfem.fem.crack import MAX_HINGE_STIFFNESS, hinge_compliance

    EI_z, EI_y, le = 2.0, 8.0, 0.05
    floor_v, floor_w = le / (MAX_HINGE_STIFFNESS * EI_z), le / (MAX_HINGE_STIFFNESS * EI_y)
    assert hinge_compliance((0.0, 1e-300), 1.0, EI_z, EI_y, le) == (floor_v, floor_w)
    assert hinge_compliance((3e-3, 4e-3), 1.0, EI_z, EI_y, le) == (3e-3, 4e-3)


@pytest.mark.parametrize("elements", [10, 20, 100, 200])
def test_hinge_floor_leaves_engineering_cracks_alone(elements):
    """The floor is mesh-dependent (l / (1e4 E I)), so it must stay below the design's compliances for the
    depths one models: the shipped cracked rotor (solid circle D = 20 mm, L = 0.8 m) from a/D = 0.1 to 0.5
    and a square shaft of that size with the design's Rizos J(a) from a/h = 0.05 to 0.8, on 10 to 200
    elements, keep their compliances bit for bit (measured margins: 9.3 at a/D = 0.1 on 10 elements, the
    non-opening axis; at a/D = 0.05 the floor raises that axis by 20 %, its first frequency by 2e-6). A cap
    100 times lower (1e2 x an element) would raise the a/D = 0.1 crack's and fail here."""
    from nsfem.fem.crack import hinge_compliance, slope_compliance

    D, L = 0.02, 0.8
    le = L / elements
    I_circle, I_square = math.pi * D ** 4 / 64, D ** 4 / 12
    for section, inertia, depths in (("circle", I_circle, (0.1, 0.2, 0.3, 0.4, 0.5)),
                                     ("rectangle", I_square, (0.05, 0.1, 0.3, 0.5, 0.8))):
        for depth in depths:
            for side in ("-z", "+y"):
                c = slope_compliance(section, E, D, D, depth, side)
                assert hinge_compliance(c, E, inertia, inertia, le) == c, (section, depth, side)
