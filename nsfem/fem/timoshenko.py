"""Timoshenko beam element: shear deformation with the interdependent interpolation.

Per bending plane the element has the nodal displacement v and the section's rotation psi (the
second dof of every node, a rotor engineer's theta; psi = v' when shear is left out) at both ends. The
displacement is cubic, the rotation quadratic, both from the static solution of the Timoshenko beam
with end values (Friedman & Kosmatka 1993; Nelson 1980), parametrised by

    Phi = 12 E I / (kappa G A h^2)         (per element and per bending plane),

so the shear strain gamma = v' - psi is constant on an element and the element is exact for end loads.
With Phi = 0 the displacement functions are the cubic Hermite ones and psi their derivative
(:mod:`nsfem.fem.hermite`). The matrices per unit coefficient are

    mass        int N_v N_v dx             (x rho A)
    rotary      int N_psi N_psi dx         (x rho I; x rho I_p for the spin's gyroscopic couple)
    stiffness   int N_psi' N_psi' dx + (kappa G A / E I) int (N_v' - N_psi)(N_v' - N_psi) dx    (x E I)

the first two by Gauss-Legendre quadrature of the explicit polynomials in local xi (exact: degree 6 with
4 points), the stiffness in closed form 1 / (h^3 (1 + Phi)) [[12, 6h, -12, 6h], [6h, (4 + Phi) h^2, -6h,
(2 - Phi) h^2], ...] (tests/test_timoshenko.py checks it against the quadrature of its definition).

The shear coefficient kappa (:func:`shear_coefficient`): Cowper's (1966), as ROSS 2.3.0's default
``ShaftElement(shear_method_calc="cowper")`` evaluates it for solid and hollow circles (Hutchinson's 2001
form, ROSS's other choice, is available: Hutchinson's own, with (1 + nu)^2 where ROSS has (1 + nu)), and Cowper's 10 (1 + nu) / (12 + 11 nu) for rectangles, with
nu = E / (2 G) - 1.

>>> import numpy as np
>>> from nsfem.fem import hermite
>>> h = np.array([0.1, 0.25])
>>> bool(np.allclose(element_mass(h, np.zeros(2)), hermite.element_mass(h), rtol=0, atol=1e-16))
True
>>> bool(np.allclose(element_stiffness(h, np.zeros(2)), hermite.element_bend(h), rtol=1e-15, atol=0))
True
"""

from __future__ import annotations

import numpy as np

#: Gauss-Legendre points on [0, 1]: exact for products of two cubics (degree 6)
_XI, _WEIGHT = (np.polynomial.legendre.leggauss(4)[0] + 1) / 2, np.polynomial.legendre.leggauss(4)[1] / 2


def poisson(E: float, G: float) -> float:
    """Poisson's ratio nu = E / (2 G) - 1 of an isotropic material."""
    return E / (2.0 * G) - 1.0


def shear_coefficient(section: str, nu: float, outer: float = 1.0, inner: float = 0.0,
                      method: str = "cowper") -> float:
    """kappa of a section with Poisson's ratio ``nu``.

    Circle of diameters ``outer`` and ``inner`` (r = inner / outer): Cowper (1966, ROSS 2.3.0's default, the
    form ROSS evaluates) 6 (1 + r^2)^2 (1 + nu) / ((1 + r^2)^2 (7 + 6 nu) + r^2 (20 + 12 nu)), or Hutchinson
    (2001) 6 (1 + r^2)^2 (1 + nu)^2 / ((1 + r^2)^2 (7 + 12 nu + 4 nu^2) + 4 r^2 (5 + 6 nu + 2 nu^2)), solid
    6 (1 + nu)^2 / (7 + 12 nu + 4 nu^2). ROSS 2.3.0's ``shear_method_calc="hutchinson"`` has (1 + nu) in
    place of (1 + nu)^2 (0.71 instead of 0.925 for a solid circle at nu = 0.3): not Hutchinson's.
    Rectangle: Cowper's 10 (1 + nu) / (12 + 11 nu) (either method).

    >>> round(shear_coefficient("circle", 0.3), 12) == round(6 * 1.3 / (7 + 1.8), 12)
    True
    """
    if section != "circle":
        return 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)
    r2 = (inner / outer) ** 2
    r12 = (1.0 + r2) ** 2
    if method == "hutchinson":
        return 6.0 * r12 * (1.0 + nu) ** 2 / (r12 * (7.0 + 12.0 * nu + 4.0 * nu * nu)
                                             + 4.0 * r2 * (5.0 + 6.0 * nu + 2.0 * nu * nu))
    return 6.0 * r12 * (1.0 + nu) / (r12 * (7.0 + 6.0 * nu) + r2 * (20.0 + 12.0 * nu))


def shear_parameter(E: float, I: float, kappa: float, G: float, A: float, h: np.ndarray) -> np.ndarray:
    """Phi = 12 E I / (kappa G A h^2) of elements of lengths h."""
    return 12.0 * E * I / (kappa * G * A * np.asarray(h, dtype=float) ** 2)


def shape(xi: np.ndarray, h: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Displacement N_v and rotation N_psi functions at local points ``xi`` in [0, 1] of elements of lengths
    ``h`` and shear parameters ``phi``: two arrays (len(h), 4, len(xi)), dofs (v, psi) left then right."""
    xi = np.asarray(xi, dtype=float)[None, :]
    h = np.asarray(h, dtype=float)[:, None]
    p = np.asarray(phi, dtype=float)[:, None] * np.ones_like(h)
    d = 1.0 + p
    x2, x3 = xi * xi, xi**3
    value = np.stack([(1 + p - p * xi - 3 * x2 + 2 * x3) / d,
                      h * ((1 + p / 2) * xi - (2 + p / 2) * x2 + x3) / d,
                      (p * xi + 3 * x2 - 2 * x3) / d,
                      h * (-(p / 2) * xi - (1 - p / 2) * x2 + x3) / d], axis=1)
    rotation = np.stack([6 * (x2 - xi) / (h * d),
                         (1 + p - (4 + p) * xi + 3 * x2) / d,
                         -6 * (x2 - xi) / (h * d),
                         (-(2 - p) * xi + 3 * x2) / d], axis=1)
    return value, rotation


def _gram(h: np.ndarray, f: np.ndarray, g: np.ndarray | None = None) -> np.ndarray:
    """int f_i g_j dx (g = f by default) over each element from f, g (elements, 4, points) at the Gauss points."""
    return np.einsum("eiq,ejq,q,e->eij", f, f if g is None else g, _WEIGHT, np.asarray(h, dtype=float))


def element_mass(h: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """int N_v N_v dx: (len(h), 4, 4)."""
    return _gram(h, shape(_XI, h, phi)[0])


def element_rotary(h: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """int N_psi N_psi dx: (len(h), 4, 4)."""
    return _gram(h, shape(_XI, h, phi)[1])


def element_cross(h: np.ndarray, phi_a: np.ndarray, phi_b: np.ndarray, rotation: bool = False) -> np.ndarray:
    """int N^a N^b dx of two planes' functions with their own Phi (displacement N_v, or with ``rotation``
    N_psi): the integral of a coupling of the planes, e.g. a rectangle's Coriolis term. (len(h), 4, 4)."""
    k = 1 if rotation else 0
    return _gram(h, shape(_XI, h, phi_a)[k], shape(_XI, h, phi_b)[k])


def element_stiffness(h: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """(int N_psi' N_psi' + (kappa G A / E I) int (N_v' - N_psi)^2) dx in closed form: (len(h), 4, 4)."""
    h = np.asarray(h, dtype=float)[:, None, None]
    p = np.asarray(phi, dtype=float)[:, None, None] * np.ones_like(h)
    one = np.array([[12, 0, -12, 0], [0, 0, 0, 0], [-12, 0, 12, 0], [0, 0, 0, 0]], dtype=float)
    lin = np.array([[0, 6, 0, 6], [6, 0, -6, 0], [0, -6, 0, -6], [6, 0, -6, 0]], dtype=float)
    sq = np.array([[0, 0, 0, 0], [0, 4, 0, 2], [0, 0, 0, 0], [0, 2, 0, 4]], dtype=float)
    shear = np.array([[0, 0, 0, 0], [0, 1, 0, -1], [0, 0, 0, 0], [0, -1, 0, 1]], dtype=float)
    return (one + h * lin + h * h * (sq + p * shear)) / (h**3 * (1 + p))


def section_phi(segment, h: np.ndarray, method: str = "cowper") -> dict[str, np.ndarray]:
    """Phi per element of a segment for V (bending with I_z) and W (with I_y)."""
    G, kappa = segment.shear_modulus, kappa_of(segment, method)
    return {"V": shear_parameter(segment.E, segment.I_z, kappa, G, segment.area, h),
            "W": shear_parameter(segment.E, segment.I_y, kappa, G, segment.area, h)}


def kappa_of(segment, method: str = "cowper") -> float:
    """The shear coefficient of a segment's section and material."""
    return shear_coefficient(segment.section, poisson(segment.E, segment.shear_modulus), segment.width,
                             segment.inner, method)

