"""Cubic Hermite beam element matrices in closed form.

scikit-fem's ``ElementLineHermite`` builds its shape functions per element by inverting a
monomial Vandermonde matrix in the mesh's coordinates; with elements of length h at distance
x from the origin that matrix has a condition of order (x / h)^3 (4.5e6 on a 1 m segment of
40 elements), so its integrals carry round-off of 1e-11 to 1e-9 of their largest entry, and
which digits depends on the BLAS kernel. The element integrals of the cubic Hermite
polynomials are rational numbers times powers of h; assembled from these, the unit matrices
are exact to a few eps on any machine. Dof order per node: value, slope (d/dx), as in
scikit-fem, so the results replace ``asm(form, basis)`` one for one.

>>> import numpy as np
>>> from skfem import Basis, MeshLine, ElementLineHermite, asm
>>> from nsfem.fem import forms
>>> x = np.array([0.0, 0.3, 0.5, 1.0])
>>> basis = Basis(MeshLine(x), ElementLineHermite())
>>> all(np.allclose(assemble(x, m).toarray(), asm(f, basis).toarray(), rtol=0, atol=1e-9)
...     for m, f in ((element_mass, forms.mass), (element_stretch, forms.stretch), (element_bend, forms.bend)))
True
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from . import timoshenko


def element_mass(h: np.ndarray) -> np.ndarray:
    """int N_i N_j dx over elements of lengths h: (len(h), 4, 4)."""
    h = np.asarray(h, dtype=float)[:, None, None]
    one = np.array([[156, 0, 54, 0], [0, 0, 0, 0], [54, 0, 156, 0], [0, 0, 0, 0]], dtype=float)
    lin = np.array([[0, 22, 0, -13], [22, 0, 13, 0], [0, 13, 0, -22], [-13, 0, -22, 0]], dtype=float)
    sq = np.array([[0, 0, 0, 0], [0, 4, 0, -3], [0, 0, 0, 0], [0, -3, 0, 4]], dtype=float)
    return h / 420.0 * (one + h * lin + h * h * sq)


def element_stretch(h: np.ndarray) -> np.ndarray:
    """int N_i' N_j' dx over elements of lengths h: (len(h), 4, 4)."""
    h = np.asarray(h, dtype=float)[:, None, None]
    one = np.array([[36, 0, -36, 0], [0, 0, 0, 0], [-36, 0, 36, 0], [0, 0, 0, 0]], dtype=float)
    lin = np.array([[0, 3, 0, 3], [3, 0, -3, 0], [0, -3, 0, -3], [3, 0, -3, 0]], dtype=float)
    sq = np.array([[0, 0, 0, 0], [0, 4, 0, -1], [0, 0, 0, 0], [0, -1, 0, 4]], dtype=float)
    return (one + h * lin + h * h * sq) / (30.0 * h)


def element_bend(h: np.ndarray) -> np.ndarray:
    """int N_i'' N_j'' dx over elements of lengths h: (len(h), 4, 4)."""
    h = np.asarray(h, dtype=float)[:, None, None]
    one = np.array([[12, 0, -12, 0], [0, 0, 0, 0], [-12, 0, 12, 0], [0, 0, 0, 0]], dtype=float)
    lin = np.array([[0, 6, 0, 6], [6, 0, -6, 0], [0, -6, 0, -6], [6, 0, -6, 0]], dtype=float)
    sq = np.array([[0, 0, 0, 0], [0, 4, 0, 2], [0, 0, 0, 0], [0, 2, 0, 4]], dtype=float)
    return (one + h * lin + h * h * sq) / h**3


def _element_dofs(n_nodes: int) -> np.ndarray:
    """(elements, 4): value and slope of the left node, then of the right one."""
    left = 2 * np.arange(n_nodes - 1)
    return np.stack([left, left + 1, left + 2, left + 3], axis=1)


def assemble(x: np.ndarray, element) -> sp.csr_matrix:
    """The global matrix of ``element`` (:func:`element_mass`, :func:`element_stretch`, :func:`element_bend`) on nodes x."""
    x = np.asarray(x, dtype=float)
    return assemble_local(x, element(np.diff(x)))


def assemble_local(x: np.ndarray, Ke: np.ndarray) -> sp.csr_matrix:
    """The global matrix on nodes x of element matrices Ke (elements, 4, 4) in the dof order value, slope
    (or rotation) per node."""
    x = np.asarray(x, dtype=float)
    dofs = _element_dofs(x.size)
    rows = np.repeat(dofs, 4, axis=1).ravel()
    cols = np.tile(dofs, (1, 4)).ravel()
    n = 2 * x.size
    return sp.csr_matrix((Ke.ravel(), (rows, cols)), shape=(n, n))


def shape(xi: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values and x-derivatives of the four shape functions at local points ``xi`` in [0, 1] of
    elements of lengths ``h``: two arrays (len(h), 4, len(xi))."""
    xi = np.asarray(xi, dtype=float)[None, :]
    h = np.asarray(h, dtype=float)[:, None]
    one = np.ones_like(h)
    value = np.stack([one * (1 - 3 * xi**2 + 2 * xi**3), h * (xi - 2 * xi**2 + xi**3),
                      one * (3 * xi**2 - 2 * xi**3), h * (xi**3 - xi**2)], axis=1)
    slope = np.stack([(-6 * xi + 6 * xi**2) / h, one * (1 - 4 * xi + 3 * xi**2),
                      (6 * xi - 6 * xi**2) / h, one * (3 * xi**2 - 2 * xi)], axis=1)
    return value, slope


def assemble_weighted(x: np.ndarray, weight, slope: bool = False, points: int = 3,
                      phi: np.ndarray | None = None) -> np.ndarray:
    """int weight(x) N_i(x) dx (or N_i'(x) with ``slope``) over the nodes x by Gauss-Legendre
    quadrature on each element: exact for a weight that is a polynomial of degree up to
    2 points - 4 on every element (a hat whose kinks are nodes, with the default 3 points).

    With Timoshenko's shear parameters ``phi`` per element the functions are the interdependent ones
    (:func:`nsfem.fem.timoshenko.shape`): N_v, and with ``slope`` the rotation's N_psi."""
    x = np.asarray(x, dtype=float)
    h = np.diff(x)
    g, wg = np.polynomial.legendre.leggauss(points)
    xi, wg = (g + 1) / 2, wg / 2
    if phi is None or not np.any(phi):
        value, d = shape(xi, h)
    else:
        value, d = timoshenko.shape(xi, h, phi)
    at = x[:-1, None] + h[:, None] * xi[None, :]           # (elements, points)
    f = weight(at) * wg[None, :] * h[:, None]
    local = np.einsum("eiq,eq->ei", d if slope else value, f)
    out = np.zeros(2 * x.size)
    np.add.at(out, _element_dofs(x.size), local)
    return out
