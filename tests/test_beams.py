"""Uniform beams against analytic Euler-Bernoulli and bar frequencies; convergence orders.

Analytic values: omega_n = (beta_n L)^2 / L^2 sqrt(E I / rho A) with the classical
roots beta_n L (Blevins, Formulas for Natural Frequency and Mode Shape, table 8-1);
axial bars omega_n = k_n sqrt(E / rho). Cubic Hermite elements with consistent mass
overestimate a bending frequency by about (beta h)^4 / 1440 (eigenvalue error
(beta h)^4 / 720), and P1 bars by (k h)^2 / 24; the tolerances below are those
leading-order estimates with a factor of 2 (or a round-off allowance where smaller).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import RHO, E, L, beam_model, frequencies_by_field

from nsfem import natural_frequencies

B, H = 0.03, 0.01  # non-square: V (x-y, I_z = h b^3/12) and W (x-z, I_y = b h^3/12) differ
A, I_Y, I_Z = B * H, B * H**3 / 12, H * B**3 / 12
CC = [4.73004074, 7.85320462, 10.99560784, 14.13716549]
BETA_L = {
    "pinned-pinned": list(np.pi * np.arange(1, 5)),
    "clamped-free": [1.87510407, 4.69409113, 7.85475744, 10.99554073],
    "clamped-clamped": CC,
    "clamped-pinned": [3.92660231, 7.06858275, 10.21017612, 13.35176878],
    "free-free": CC,  # elastic modes of the free-free beam share the clamped-clamped roots
}
# axial wave numbers k_n L: U is held at x = 0 only for pinned-pinned, clamped-free, clamped-pinned
AXIAL_KL = {
    "pinned-pinned": [np.pi / 2, 3 * np.pi / 2],
    "clamped-free": [np.pi / 2, 3 * np.pi / 2],
    "clamped-pinned": [np.pi / 2, 3 * np.pi / 2],
    "clamped-clamped": [np.pi, 2 * np.pi],
    "free-free": [np.pi, 2 * np.pi],
}
# Allowance for what is not discretization error: the tabulated roots carry 9 significant digits
# (f ~ (beta L)^2: up to 1e-8 / (beta L) = 5.3e-9, for 1.87510407); the shift-invert Lanczos
# solution, eps x the componentwise condition |v|^T |K| |v| / v^T K v (1.3e6 at 40 elements) =
# 2.9e-10 (the element matrices are closed-form in h: a few eps). Sum 5.6e-9. Measured: every first
# mode differs from the leading-order estimate by its root's rounding alone (-1.4e-9 clamped-free,
# +2.0e-9 clamped-clamped), the same to 2e-10 over four OpenBLAS kernels.
ROUNDOFF = 1e-8


def bending_hz(beta_l, inertia):
    return np.asarray(beta_l) ** 2 / L**2 * np.sqrt(E * inertia / (RHO * A)) / (2 * np.pi)


@pytest.mark.parametrize("supports", list(BETA_L))
def test_bending_and_axial_frequencies(supports):
    elements = 40
    model = beam_model(supports, width=B, height=H, elements=elements)
    modes = natural_frequencies(model, "open", 30)
    by = frequencies_by_field(model, modes)
    beta_l = np.array(BETA_L[supports])
    bound = 2 * (beta_l / elements) ** 4 / 1440 + ROUNDOFF
    for fld, inertia in (("W", I_Y), ("V", I_Z)):
        f = by[fld][by[fld] > 0][:4]
        exact = bending_hz(beta_l, inertia)
        rel = f / exact - 1
        assert np.all(rel > -ROUNDOFF), (fld, rel)  # Rayleigh-Ritz bounds from above
        assert np.all(rel < bound), (fld, rel, bound)
    k = np.array(AXIAL_KL[supports]) / L
    fa = by["U"][by["U"] > 0][:2]
    rel = fa / (k * np.sqrt(E / RHO) / (2 * np.pi)) - 1
    # measured 1.0000 to 1.0003 x the leading term (>= 6.4e-5), far above round-off
    assert np.all((rel > 0) & (rel < 2 * (k * L / elements) ** 2 / 24)), rel


def test_free_free_has_five_rigid_body_modes():
    # axial translation, and translation + rotation in each bending plane (no torsion field)
    modes = natural_frequencies(beam_model("free-free"), "open", 8)
    assert np.count_nonzero(modes.frequencies_hz == 0.0) == 5  # rigid modes are set to exactly 0 Hz
    assert modes.frequencies_hz[5] > 10.0  # the first elastic mode: 53.3 Hz


@pytest.mark.parametrize("axial", ["P1", "P2"])
def test_axial_convergence_order(axial):
    # P1 bar frequencies converge at h^2, P2 at h^4 (eigenvalue error twice the interpolation order)
    errs = []
    k = 3 * np.pi / 2 / L  # second mode of the fixed-free bar
    exact = k * np.sqrt(E / RHO) / (2 * np.pi)
    for n in (8, 16, 32):
        by = frequencies_by_field(*_model_modes("clamped-free", n, axial))
        errs.append(by["U"][1] / exact - 1)
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    want = 2.0 if axial == "P1" else 4.0
    # pre-asymptotic terms only (errors >= 3e-7 against round-off <= 1e-10): measured 2.004, 2.001
    # (P1) and 3.981, 3.995 (P2) on every kernel; 0.05 = 2.5x the largest deviation
    assert np.all(np.abs(orders - want) < 0.05), orders


def _model_modes(supports, n, axial="P1"):
    m = beam_model(supports, elements=n, axial=axial)
    return m, natural_frequencies(m, "open", 40)


@pytest.mark.parametrize("supports", ["pinned-pinned", "clamped-free"])
def test_hermite_bending_converges_at_h4(supports):
    # eigenvalue error ~ C h^4: halving h divides it by 16; pre-asymptotic terms (beta h)^6 and the
    # error floor keep the measured orders within 0.2 of 4 on 8-16-32 elements (measured 3.935 to
    # 4.012 on every kernel: 3x margin)
    beta_l = np.array(BETA_L[supports][:3])
    exact = bending_hz(beta_l, I_Y)
    errs = []
    for n in (8, 16, 32):
        m, modes = _model_modes(supports, n)
        errs.append(frequencies_by_field(m, modes)["W"][:3] / exact - 1)
    errs = np.array(errs)
    orders = np.log2(errs[:-1] / errs[1:])
    # only pairs well above the floor are meaningful: the roots' digits (1.4e-9 for clamped-free's
    # first) and round-off (<= 1e-9, see ROUNDOFF) move an order by <= 2.4e-9 / (1e-7 ln 2) = 0.035
    meaningful = errs[1:] > 1e-7
    assert meaningful.sum() >= 4
    assert np.all(np.abs(orders[meaningful] - 4.0) < 0.2), orders
