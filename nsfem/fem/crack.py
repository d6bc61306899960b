"""Local flexibility of an open transverse crack (design section 8, the ``[[crack]]`` hinge).

An open crack of depth ``a`` starting from one face of the section is a rotational spring between the
two sides of the shaft: the relative slope theta = c M for a bending moment M. The crack has two axes:
the moment that opens it (the face it starts from in tension) and the moment about the perpendicular
axis (stress varying along the crack front). Both compliances are diagonal in these axes (the crack is
symmetric about its depth direction, so the cross term integrates to zero). With Timoshenko elements the
hinge joins the second nodal dofs, the sections' rotations psi: the crack's energy release turns the
sections on either side against each other (theta is their relative rotation, the faces' tilt), while
the shear strain v' - psi stays each side's, so the same compliance applies unchanged.

Sources and what is taken from each:

- Rectangle, opening axis: c = 5.346 h J(a/h) / (E I) with the polynomial J of Dimarogonas (Rizos,
  Aspragathos & Dimarogonas, J. Sound Vib. 138 (1990) 381-388), as the design fixes it.
- Every other case by the strip integration of Dimarogonas & Papadopoulos (J. Sound Vib. 91 (1983)
  583-593): the section is cut into strips dy along the crack front; strip y is an edge-cracked strip of
  its own height h(y) with local crack depth alpha_max(y), loaded by the stress the moment puts on it,
  with the stress intensity K_I = sigma sqrt(pi alpha) F(alpha / h) of Tada, Paris & Irwin (The Stress
  Analysis of Cracks Handbook): F_b for the strip's bending (the opening moment, linear across the
  strip), F_t for uniform tension (the other moment, constant across the strip). The strain energy of
  the crack is U = int K_I^2 / E dA, so c = (2 / E) int dy int_0^alpha_max (K_I / M)^2 dalpha.

Plane stress (E) throughout, as in the design's formula (the scene has no Poisson ratio). The two
sources are not the same fit: for the rectangle's opening axis the strip integration gives 1.22 to 1.31
times Rizos's compliance for a/h = 0.05 to 0.7, 1.49 at 0.8 (:func:`strip_over_rizos`); docs/theory.md states this
spread as the model's uncertainty. Hollow sections are not covered (a strip then crosses the bore).
"""

from __future__ import annotations

import math

import numpy as np

#: Dimarogonas' J(a/h) coefficients of a^2 .. a^10 (Rizos et al. 1990)
J_COEFFICIENTS = (1.8624, -3.95, 16.375, -37.226, 76.81, -126.9, 172.0, -143.97, 66.56)
#: the range of relative depths the fits are meant for (rectangles)
MAX_DEPTH = 0.8
#: solid circles: beyond a = R the strips at the front's ends are cut through (local depth = strip height),
#: where F diverges and the strip integration has no meaning
MAX_CIRCLE_DEPTH = 0.5
#: below this relative depth a circle's compliance is the closed-form shallow limit (its relative error is
#: O(a / D), under 4e-8 here; the strip quadrature agrees with it to that at 1e-7, tests/test_crack_compliance.py)
SHALLOW_CIRCLE = 1e-8
#: The stiffest crack hinge, relative to the bending stiffness E I / l of a shaft element of the mean length l:
#: a shallower crack's compliance is raised to l / (MAX_HINGE_STIFFNESS E I). Stiffer, the hinge's row in the
#: stiffness matrix would dwarf the shaft's (a crack of 1e-3 D in the shipped cracked rotor is 5e9 times
#: stiffer than an element on its other axis: its two first frequencies split by 0.2 % from round-off alone;
#: at 1e5 times the mechanism check of a 10-element model already fails). The raised compliance adds at most
#: 1e-4 of one element's bending flexibility: the shipped cracked rotor with a crack of 1e-300 D lies 1.2e-5
#: (10 elements) and 5.9e-6 (20) below the intact shaft's first frequency, a crack of 0.4 D 4.3 % below.
MAX_HINGE_STIFFNESS = 1e4
#: A crack front narrower than this fraction of its distance from the hinge's centre is one face point
#: (a circle's shallower than 2.5e-5 D; :func:`face_points`)
NARROW_FRONT = 1e-2


def rizos_J(s: float) -> float:
    """Dimarogonas' dimensionless compliance J(a/h) of an edge crack in a rectangle, bending that opens it."""
    return float(sum(c * s ** (k + 2) for k, c in enumerate(J_COEFFICIENTS)))


def _tada_root(s):
    lam = 0.5 * math.pi * s
    return math.sqrt(math.tan(lam) / lam) / math.cos(lam) if lam > 1e-12 else 1.0


def tada_bending(s: float) -> float:
    """F(a/h) of an edge crack in a strip under pure bending (Tada: 0.923 + 0.199 (1 - sin)^4, 0.5 % for any a/h)."""
    lam = 0.5 * math.pi * s
    return _tada_root(s) * (0.923 + 0.199 * (1.0 - math.sin(lam)) ** 4)


def tada_tension(s: float) -> float:
    """F(a/h) of an edge crack in a strip under uniform tension (Tada: 0.752 + 2.02 s + 0.37 (1 - sin)^3, 0.5 %)."""
    lam = 0.5 * math.pi * s
    return _tada_root(s) * (0.752 + 2.02 * s + 0.37 * (1.0 - math.sin(lam)) ** 3)


def _check_depth(depth: float, limit: float = MAX_DEPTH) -> None:
    if not 0.0 < depth <= limit:
        raise ValueError(f"relative crack depth {depth} outside (0, {limit}]: the stress-intensity fits are "
                         "not meant for deeper cracks")


def _strip_integral(F, s_max: float) -> float:
    """int_0^s_max s F(s)^2 ds, as s_max^2 int_0^1 t F(s_max t)^2 dt: the integrand is of order one for any
    depth, so the relative tolerance holds down to the shallowest crack (the result underflows to 0 near
    s_max = 1e-154, where the hinge is far stiffer than :data:`MAX_HINGE_STIFFNESS` allows anyway)."""
    if not s_max > 0.0:
        return 0.0
    from scipy.integrate import quad

    return s_max * s_max * quad(lambda t: t * F(s_max * t) ** 2, 0.0, 1.0, limit=200, epsabs=0.0, epsrel=1e-12)[0]


def rectangle_compliance(E: float, depth_side: float, front_side: float, depth: float) -> tuple[float, float]:
    """(c_open, c_other) in rad / (N m) of a crack of relative depth ``depth`` = a / depth_side across the
    whole ``front_side`` of a rectangle: c_open = 5.346 h J(a/h) / (E I) about the axis along the crack front
    (I = front h^3 / 12), c_other = 2 pi h / (E I') int_0^{a/h} s F_t(s)^2 ds about the axis along the depth
    (I' = h front^3 / 12; strip integration: strip y carries the uniform stress M y / I')."""
    _check_depth(depth)
    h, b = depth_side, front_side
    c_open = 5.346 * h * rizos_J(depth) / (E * b * h ** 3 / 12.0)
    c_other = 2.0 * math.pi * h / (E * h * b ** 3 / 12.0) * _strip_integral(tada_tension, depth)
    return c_open, c_other


def strip_over_rizos(depth: float) -> float:
    """The rectangle's opening compliance by strip integration, 6 pi h / (E I) int s F_b^2, over Rizos's."""
    _check_depth(depth)
    return 6.0 * math.pi * _strip_integral(tada_bending, depth) / (5.346 * rizos_J(depth))


def circle_compliance(E: float, diameter: float, depth: float) -> tuple[float, float]:
    """(c_open, c_other) in rad / (N m) of a straight-fronted crack of depth a = depth * diameter in a solid
    circular section of radius R (Dimarogonas & Papadopoulos' strip integration): the crack face is the
    segment of the circle up to R - a from the centre, its front of half-width beta = sqrt(a (2R - a)); strip
    y (|y| < beta) has height h = 2 sqrt(R^2 - y^2) and local crack depth alpha_max = a - R + sqrt(R^2 - y^2);

        c_open  = (2 / E) int dy (R^2 - y^2) / I^2 int_0^alpha_max pi alpha F_b(alpha / h)^2 dalpha,
        c_other = (2 / E) int dy      y^2      / I^2 int_0^alpha_max pi alpha F_t(alpha / h)^2 dalpha,

    I = pi R^4 / 4: the opening moment bends each strip with its extreme fibre stress M sqrt(R^2 - y^2) / I,
    the other moment stresses strip y uniformly by M y / I."""
    _check_depth(depth, MAX_CIRCLE_DEPTH)
    R = 0.5 * diameter
    a = depth * diameter
    beta = math.sqrt(a * (2.0 * R - a))
    inertia = math.pi * R ** 4 / 4.0
    if depth < SHALLOW_CIRCLE:
        # the closed-form limit: alpha_max = a - y^2 / 2R, h = 2R, F = F(0); relative error O(a / D)
        scale = math.pi * a * a / (E * inertia ** 2)
        return (16.0 / 15.0 * scale * tada_bending(0.0) ** 2 * R * R * beta,
                16.0 / 105.0 * scale * tada_tension(0.0) ** 2 * beta ** 3)

    def inner(F, u):
        # strip y = beta u; R - sqrt(R^2 - y^2) = y^2 / (R + sqrt(R^2 - y^2)) keeps alpha_max exact for a << R
        half = math.sqrt(R * R - (beta * u) ** 2)
        h = 2.0 * half
        alpha_max = a * (1.0 - (2.0 * R - a) * u * u / (R + half))
        # int_0^alpha_max pi alpha F(alpha / h)^2 dalpha = pi h^2 int_0^s_max s F(s)^2 ds
        return math.pi * h * h * _strip_integral(F, alpha_max / h)

    from scipy.integrate import quad

    def outer(F, weight):
        # even in y, taken over u = y / beta in [0, 1]; it ends like (1 - u)^2 at the front's edge: smooth
        return 2.0 * beta * quad(lambda u: weight(beta * u) * inner(F, u), 0.0, 1.0, limit=200, epsabs=0.0,
                                 epsrel=1e-10)[0]

    c_open = 2.0 / E / inertia ** 2 * outer(tada_bending, lambda y: R * R - y * y)
    c_other = 2.0 / E / inertia ** 2 * outer(tada_tension, lambda y: y * y)
    return c_open, c_other


#: the unit vector (y, z) from the centroid towards the face a crack starts from
SIDE_DIRECTION = {"+y": (1.0, 0.0), "-y": (-1.0, 0.0), "+z": (0.0, 1.0), "-z": (0.0, -1.0)}
def ligament_centroid(section: str, depth_side: float, depth: float) -> float:
    """Position along the crack's depth direction (from the section's centroid towards the cracked face)
    of the uncracked ligament's centroid, the hinge's centre of rotation: -a / 2 for a rectangle; for a
    solid circle of radius R minus the segment of height a (half-angle psi, cos psi = 1 - a / R),
    -A_s d_s / (pi R^2 - A_s) with A_s = R^2 (psi - sin psi cos psi), d_s = 2 R sin^3 psi / (3 (psi - sin psi cos psi))."""
    a = depth * depth_side
    if section != "circle":
        return -a / 2.0
    R = depth_side / 2.0
    # cos psi = 1 - a / R, i.e. sin(psi / 2) = t = sqrt(a / 2R): exact for any a > 0 (acos(1 - a / R) is 0
    # below a = 1e-16 R); A_s d_s = (2/3) R^3 sin^3 psi needs no quotient of vanishing terms
    t = math.sqrt(a / (2.0 * R))
    psi = 2.0 * math.asin(t)
    sin_psi = 2.0 * t * math.sqrt(1.0 - t * t)
    area = 0.5 * R * R * _x_minus_sin(2.0 * psi)
    return -(2.0 / 3.0) * R ** 3 * sin_psi ** 3 / (math.pi * R * R - area)


def _x_minus_sin(x: float) -> float:
    """x - sin x without the cancellation of small x (the series to x^11: relative error below 1e-16 for x < 0.1)."""
    if x >= 0.1:
        return x - math.sin(x)
    x2 = x * x
    return x * x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0 * (1.0 - x2 / 110.0))))


def face_points(section: str, width: float, height: float, depth: float, side: str) -> np.ndarray:
    """The two ends (y, z) of a crack's front, measured from the ligament's centroid (rows; the hinge's arms).

    The faces' gap at a face point p is -p . (dV', dW') in the hinge's relative slopes: linear in p, so it
    is least at a vertex of the face, and the feasible slopes form a cone in the plane whose edges are
    set by the two vertices of extreme direction as seen from the hinge's centre. For a rectangle these
    are the front's corners (a cracked face's far corner (+-B/2, H/2) is a positive combination of
    (+B/2, H/2 - a) and (-B/2, H/2 - a) about the centre); for a circle the arc point at angle psi from
    the depth axis has direction sin psi / (cos psi + c), c = -centre / R in (0, 1), increasing in psi,
    so again the front's ends. Holding these two is holding the whole face: exact for rigid faces, and
    the contact set stays of full rank (the hinge has two rotations).

    A circle's front is only sqrt(a D) wide: below :data:`NARROW_FRONT` of the arm the two ends' gap rows are
    nearly parallel (the reduction's constraint modes would divide by their difference), and the front's middle
    is its one point, the cone then a half-plane (an error in the direction of its edges of that relative size,
    on a hinge at least that shallow crack's stiffness on either axis).

    >>> face_points("rectangle", 0.02, 0.01, 0.4, "-z").round(6).tolist()
    [[-0.01, -0.003], [0.01, -0.003]]
    >>> face_points("circle", 0.02, 0.02, 1e-9, "-z").round(6).tolist()
    [[0.0, -0.01]]
    """
    dy, dz = SIDE_DIRECTION[side]
    H, B = (width, height) if dy else (height, width)   # depth side, front side
    a = depth * H
    centre = ligament_centroid(section, H, depth)
    half = math.sqrt(a * (H - a)) if section == "circle" else B / 2.0   # the front's half-width
    along = np.full(2, H / 2.0 - a - centre)
    front = np.array([-half, half])
    if half < NARROW_FRONT * abs(along[0]):
        along, front = along[:1], np.zeros(1)
    # front axis: the depth direction turned by +90 degrees about x, (y, z) -> (-z, y)
    return np.column_stack([along * dy - front * dz, along * dz + front * dy]) + 0.0


def hinge_compliance(compliance: tuple[float, float], E: float, I_z: float, I_y: float,
                     element_length: float) -> tuple[float, float]:
    """(c_V', c_W') raised to at least l / (:data:`MAX_HINGE_STIFFNESS` E I) of the bending each slope belongs
    to (V': I_z, W': I_y): a crack too shallow for double precision beside the shaft is a hinge that stiff."""
    floors = (element_length / (MAX_HINGE_STIFFNESS * E * I_z), element_length / (MAX_HINGE_STIFFNESS * E * I_y))
    return tuple(max(c, f) for c, f in zip(compliance, floors))


def slope_compliance(section: str, E: float, width: float, height: float, depth: float, side: str) -> tuple[float, float]:
    """(c_V', c_W') [rad / (N m)] of an open crack: the compliance about the axis that opens it on the
    slope of the bending it opens under (W' for a crack from +-z), the other on the other slope."""
    dy, _ = SIDE_DIRECTION[side]
    H, B = (width, height) if dy else (height, width)
    c_open, c_other = circle_compliance(E, H, depth) if section == "circle" else rectangle_compliance(E, H, B, depth)
    return (c_open, c_other) if dy else (c_other, c_open)
