"""Round rigid stator rings in the exact method (:mod:`nsfem.integrate.round`): a polygon that turns with
the contact point. The shipped rub started next to its stationary state, and the Jeffcott rub of
``tests/test_stator.py`` whirling round its ring in the inertial frame."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nsfem import load_scene
from nsfem.analysis.stationary import scene_stationary
from nsfem.integrate.base import integrate
from nsfem.integrate.problem import ContactSystem
from nsfem.integrate.round import DELTA
from nsfem.scene import scene_from_tree
from test_stator import CLEARANCE, rub_tree

F = 64


def ring_load(forces: np.ndarray, facets: int = F) -> np.ndarray:
    """|sum_j N_j n_j| per column (the turn of a round ring's polygon leaves it unchanged)."""
    return np.abs(np.exp(2j * math.pi * np.arange(facets) / facets) @ forces)


def near_stationary(shape: str, t_end: float):
    """The shipped rub (64 facets, mu 0.1) with beta 1e-5 (its sliding state is then stable; with 1e-6 the
    run ends on a bouncing limit cycle, docs/validation.md) from 0.999 of its stationary displacement, at
    rest in the rotating frame: the polygon's stationary state (at the corner of facets 62 and 63), its
    ring force, the run."""
    scene = load_scene("rub", ["damping.rayleigh=[0.0, 1e-5]", f"stator.0.shape={shape}"])
    st = scene_stationary(scene)
    system = ContactSystem.from_scene(scene)
    res = integrate(system, t_end, "exact", 1e-3, q0=0.999 * st.q, v0=np.zeros_like(st.q))
    return st, float(ring_load(st.normal_force[:, None])[0]), res


def test_a_round_ring_settles_to_a_steady_full_annular_rub():
    st, n_st, res = near_stationary("round", 0.6)
    late = res.t >= 0.4
    load = ring_load(res.normal_force[:, late])
    # the model's distance from LCP 28 on the 64-gon: the ring's radius within 2.4e-7 m (k - m w^2 = 5.6e4 N/m:
    # 0.013 N) and the held corner within its last wedge (3e-4 rad) of the facet's equilibrium, at
    # (k - m w^2) c + N = 22 N per radian (7e-3 N); the 64-gon itself is 5.6e-4 from the circle (1024-gon):
    # 2e-3 of 16 N in all, inside the 1 % (measured 7e-4, steady to 1e-12)
    assert np.max(np.abs(load / n_st - 1.0)) < 1e-2
    assert np.ptp(load) < 1e-6 * n_st                     # steady: no event in the last 0.2 s (4.5 turns)
    assert not [e for e in res.events if e["t"] >= 0.4]
    assert abs(res.energy["relative_residual"]) < 1e-10    # measured 3e-13
    info = res.info["round_rings"]["stator.0"]
    assert info["holds"] >= 1


def test_no_zeno_at_a_corner():
    """From the same state the fixed polygon slides into the corner of facets 62 and 63 and comes to rest
    there through an accumulation of impacts, each on one facet lifting the other; the round ring holds the
    point where it settles (two facets through it, one plastic impact on both) after a bounded number of
    events, none closer together than the accumulation's."""
    _, _, poly = near_stationary("polygon", 0.3)
    _, _, rnd = near_stationary("round", 0.3)
    alternating = sum(1 for a, b in zip(poly.impacts, poly.impacts[1:]) if a["contacts"] != b["contacts"])
    assert alternating > 100                                # measured 204 impacts alternating
    t_poly = np.diff([i["t"] for i in poly.impacts])
    t_rnd = np.diff([e["t"] for e in rnd.events])
    assert len(rnd.events) < 400                            # measured 244
    assert np.median(t_rnd) > 10 * np.median(t_poly)       # measured 1.6e-4 s against 3e-6 s
