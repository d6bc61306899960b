"""Bilinear forms of the beam stack (unit coefficients; segment constants multiply outside).

Per segment (design section 3), with U axial (Lagrange) and V, W bending (Hermite):

- kinetic energy   rhoA (U'^2 + V'^2 + W'^2)   [+ rho I_z Vdot'^2 + rho I_y Wdot'^2 for Rayleigh beams]
- strain energy    EA U'^2 + E I_z V''^2 + E I_y W''^2     (paper eq. 34-35)

so three forms suffice: :func:`mass` (int u v), :func:`stretch` (int u' v') and
:func:`bend` (int u'' v'').

>>> import numpy as np
>>> from skfem import Basis, MeshLine, ElementLineHermite, asm
>>> basis = Basis(MeshLine(np.linspace(0.0, 2.0, 5)), ElementLineHermite())
>>> w = basis.project(lambda x: x[0] ** 2)           # W = x^2, W'' = 2
>>> round(float(w @ asm(bend, basis) @ w), 10)       # int_0^2 (W'')^2 dx = 8
8.0
"""

from skfem import BilinearForm
from skfem.helpers import dd, dot, grad


@BilinearForm
def mass(u, v, _):
    """int u v dx: translational inertia, and N N^T blocks of later operators (G1, Kc1, D_e)."""
    return u * v


@BilinearForm
def stretch(u, v, _):
    """int u' v' dx: axial stiffness (times EA) and rotary inertia (times rho I)."""
    return dot(grad(u), grad(v))


@BilinearForm
def bend(u, v, _):
    """int u'' v'' dx: bending stiffness (times E I) on Hermite elements."""
    return dd(u)[0, 0] * dd(v)[0, 0]
