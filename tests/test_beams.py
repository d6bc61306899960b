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
ROUNDOFF = 1e-7  # measured round-off floor of the dense eigensolver at 40 elements is ~4e-8


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
    assert np.all((rel > 0) & (rel < 2 * (k * L / elements) ** 2 / 24)), rel


def test_free_free_has_five_rigid_body_modes():
    # axial translation, and translation + rotation in each bending plane (no torsion field)
    modes = natural_frequencies(beam_model("free-free"), "open", 8)
    assert np.count_nonzero(modes.frequencies_hz == 0.0) == 5
    assert modes.frequencies_hz[5] > 10.0


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
    assert np.all(np.abs(orders - want) < 0.15), orders


def _model_modes(supports, n, axial="P1"):
    m = beam_model(supports, elements=n, axial=axial)
    return m, natural_frequencies(m, "open", 40)


@pytest.mark.parametrize("supports", ["pinned-pinned", "clamped-free"])
def test_hermite_bending_converges_at_h4(supports):
    # eigenvalue error ~ C h^4: halving h divides it by 16; pre-asymptotic terms (beta h)^6 and the
    # round-off floor keep the measured orders within 0.2 of 4 on 8-16-32 elements (measured 3.93-4.00)
    beta_l = np.array(BETA_L[supports][:3])
    exact = bending_hz(beta_l, I_Y)
    errs = []
    for n in (8, 16, 32):
        m, modes = _model_modes(supports, n)
        errs.append(frequencies_by_field(m, modes)["W"][:3] / exact - 1)
    errs = np.array(errs)
    orders = np.log2(errs[:-1] / errs[1:])
    # only pairs well above the round-off floor (1e-9 measured at these sizes) are meaningful
    meaningful = errs[1:] > 1e-7
    assert meaningful.sum() >= 4
    assert np.all(np.abs(orders[meaningful] - 4.0) < 0.2), orders
