"""The loss of the synchronous full annular rub of the shipped ``rub`` (issue 36, goal 2b; studies/rub_whirl.py).

The reference (:mod:`rub_reference`: the round ring's stationary rub in the rotating frame and its linearization
with the contact held, reduced on the constraint's null spaces) loses stability at mu = 0.55 near 25.13 Hz through
a complex pair (a Hopf point in the rotating frame: a Neimark-Sacker point of the inertial orbit), the shaft's
second bending mode (380 Hz in the rotating frame) driven by the friction, while the disk's own motion along the
ring is damped the more the larger mu. The onset is checked against an independent form of the same
linearization: the bordered (descriptor) eigenproblem in (dq, dq', dN) with the constraint G^T dq = 0 kept as an
equation (scipy's QZ; its infinite eigenvalues dropped), not projected.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import brentq, linear_sum_assignment

from nsfem import load_scene
from nsfem.fem.assemble import build_model
from nsfem.fem.components import lateral_turn
from nsfem.integrate import ContactSystem
from nsfem.periodic import periodic_orbit
from nsfem.reduce import scene_reduction
from rub_reference import eigenvalues, geometric_stiffness, held_pencil, ring_rows, round_rub


@functools.lru_cache(maxsize=None)
def _parts(mu: float):
    scene = load_scene("rub", [f"stator.0.friction={mu}"])
    model = build_model(scene)
    return scene, model, scene_reduction(scene.reduction, model)


def _state(mu: float, speed_hz: float):
    """(system, D, c, the round ring's rub) at the speed (rotating frame)."""
    scene, model, red = _parts(mu)
    R = ContactSystem.from_scene(scene, model, red, speed_hz=speed_hz)
    D, c, _ = ring_rows(R.contacts.JN, R.contacts.jN)
    return R, D, c, round_rub(R.Q, R.f0, D, c, mu, math.copysign(1.0, R.omega))


def _held(mu: float, speed_hz: float) -> np.ndarray:
    R, D, c, rub = _state(mu, speed_hz)
    return eigenvalues(*held_pencil(R.M, R.C, R.Q, D, rub, c, mu))


def _bordered(mu: float, speed_hz: float) -> np.ndarray:
    """The finite eigenvalues of B x' = A x, x = (dq, dq', dN): M dq'' + C dq' + K dq + W dN = 0, G^T dq = 0."""
    R, D, c, rub = _state(mu, speed_hz)
    n = R.n
    K = R.Q + D.T @ geometric_stiffness(rub, c, mu) @ D
    G = D.T @ rub.n
    W = D.T @ (rub.n + mu * rub.s * rub.t)
    Z, I = np.zeros((n, n)), np.eye(n)
    A = np.block([[Z, I, np.zeros((n, 1))], [-K, -R.C, -W[:, None]], [G[None, :], np.zeros((1, n + 1))]])
    B = sla.block_diag(I, R.M, np.zeros((1, 1)))
    lam = sla.eig(A, B, right=False)
    return lam[np.isfinite(lam) & (np.abs(lam) < 1e8)]


def _onset(mu: float, lo: float, hi: float) -> float:
    return brentq(lambda f: _held(mu, f).real.max(), lo, hi, xtol=1e-7)


def test_bordered_eigenproblem_is_the_held_pencil():
    """Both forms give the same 2 (n - 1) eigenvalues (QZ and the projected eig, each to ~1e-12 of |lambda| ~ 3e3
    times the conditioning: 1e-8 relative with margin)."""
    held, bordered = _held(0.55, 25.0), _bordered(0.55, 25.0)
    assert held.size == bordered.size
    distance = np.abs(held[:, None] - bordered[None, :])
    i, j = linear_sum_assignment(distance)
    assert distance[i, j].max() <= 1e-8 * np.abs(held).max()


def test_onset_at_mu_055_is_a_hopf_of_the_second_bending_mode():
    """mu = 0.55: the largest real part crosses 0 between 24 and 28 Hz (near 25.13 Hz) through a complex pair
    (Hopf: the inertial orbit's Neimark-Sacker); the bordered form changes sign across the onset +- 0.01 Hz (the
    real part's slope there is about 0.2 1/s per Hz: +-2e-3 1/s, far above the eigenvalues' round-off ~1e-8 of
    |lambda| = 2.4e3 rad/s). Its frequency in the rotating frame is near the shaft's second bending mode (383 Hz,
    the disk at its node; the rotating frame and the held contact shift it by tens of Hz: 350 to 420 Hz), not the
    disk's (under 40 Hz)."""
    f = _onset(0.55, 24.0, 28.0)
    assert 24.0 < f < 28.0
    below, above = _bordered(0.55, f - 0.01), _bordered(0.55, f + 0.01)
    assert below.real.max() < 0.0 < above.real.max()
    k = int(np.argmax(above.real))
    assert abs(above[k].imag) > 1e3 * abs(above[k].real)       # a complex pair, not a real eigenvalue
    assert 350.0 < abs(above[k].imag) / (2 * math.pi) < 420.0
    assert np.any(np.abs(above - above[k].conj()) <= 1e-8 * abs(above[k]))


@pytest.mark.parametrize("mu", [0.1, 0.3, 0.5])
def test_no_onset_below_mu_05(mu):
    """mu 0.1, 0.3, 0.5: every eigenvalue of the held linearization decays at 16.5, 22.4, 30 and 40 Hz (the rub
    begins at 15.67 Hz, where the free whirl reaches the clearance): the synchronous rub stays stable."""
    for f in (16.5, 22.4, 30.0, 40.0):
        assert _bordered(mu, f).real.max() < 0.0


def test_friction_damps_the_disks_motion_along_the_ring():
    """The disk's mode along the ring (its frequency under 40 Hz in the rotating frame) decays faster with more
    friction at 25 Hz: a larger whirl speed presses harder (Coriolis) and the friction then opposes it; no backward
    whirl of the disk grows from the slipping rub (measured -17.5, -45.7, -87.8 1/s at mu 0.1, 0.3, 0.6)."""
    rates = []
    for mu in (0.1, 0.3, 0.6):
        lam = _bordered(mu, 25.0)
        disk = lam[np.abs(lam.imag) < 2 * math.pi * 40.0]
        assert disk.size == 2
        rates.append(disk.real.max())
    assert rates[0] < 0.0 and rates[1] < rates[0] and rates[2] < rates[1]


@pytest.mark.slow
def test_polygon_orbit_loses_stability_past_the_reference_onset():
    """The exact flow's orbit on 64 facets (inertial frame, shot from the round ring's state at a facet's middle):
    stable at 26.5 Hz and unstable at 27.0 Hz by a complex pair (Neimark-Sacker), so its onset lies in between:
    above the round ring's 25.13 Hz by the polygon's first-order error (the corners' plastic impacts damp the
    disk's motion along the ring, 2 pi m_eff Omega / F, corner_terms; studies/rub_whirl.py measures 26.763 Hz at 64
    facets and 26.023 Hz at 128: 1.63 and 0.89 Hz above, halving with 1 / F). The shooting's multipliers are exact
    to ~1e-9 (tests/test_periodic_rub.py), far below the |mu| - 1 of -2.5e-3 and +1.1e-3 here."""
    scene = load_scene("rub", ["stator.0.friction=0.55", "rotation.frame=inertial"])
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    T = np.asarray(red.T)
    J = np.linalg.lstsq(T, lateral_turn(model.spaces, T.shape[0]) @ T, rcond=None)[0]
    largest = {}
    for f in (26.5, 27.0):
        R, D, c, rub = _state(0.55, f)
        w = R.omega
        t0 = ((-math.atan2(rub.n[1], rub.n[0])) % (2.0 * math.pi / 64)) / w
        q = sla.expm(w * t0 * J) @ rub.q
        orbit = periodic_orbit(ContactSystem.from_scene(scene, model, red, speed_hz=f), 1.0 / f, q, w * J @ q, t0=t0)
        assert orbit.converged and orbit.events_per_period == 64
        largest[f] = orbit.multipliers[0]
        assert orbit.stable == (f == 26.5)
    assert abs(largest[26.5]) < 1.0 < abs(largest[27.0])
    assert abs(largest[27.0].imag) > 1e-3 and _onset(0.55, 24.0, 28.0) < 26.5

