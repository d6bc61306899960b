"""The rub's orbit from its stationary state: what the fast start must keep (issue 36, goal 1).

The shipped ``rub`` scene in its rotating frame has no periodic forcing: its orbit is its stationary state, which
:func:`nsfem.periodic.scene._stationary_start` takes from LCP 28 solved on the system's own matrices (not from
:func:`~nsfem.analysis.stationary.rotor_stationary`, which assembles them again and reports the rotor's parts).
Checked: the same state as rotor_stationary's, and a shooting from it that needs exactly one flow (with its
monodromy) and no Newton step.
"""

from __future__ import annotations

import functools
import sys

import numpy as np

from nsfem import load_scene
from nsfem.analysis.stationary import rotor_stationary
from nsfem.fem.assemble import build_model
from nsfem.integrate import ContactSystem
from nsfem.periodic import periodic_orbit
from nsfem.periodic.scene import _stationary_start
from nsfem.reduce import scene_reduction


@functools.lru_cache(maxsize=1)
def _rub():
    scene = load_scene("rub")
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    system.info.update(model=model, reduction=red)
    return scene, model, red, system


def test_stationary_start_is_rotor_stationary():
    """LCP 28 on the system's Q, f0 and contacts gives rotor_stationary's state: both factor the same reduced
    matrices (rotor_operators = full_operators projected), so they agree to round-off (cond(Q) eps ~ 1e-13; 1e-11
    of the state's size leaves a factor 100)."""
    scene, model, red, system = _rub()
    q = _stationary_start(scene, system)
    ref = rotor_stationary(model, red, scene.rotation, scene.damping).q
    assert q is not None
    assert np.abs(q - ref).max() <= 1e-11 * np.abs(ref).max()
    # the disk rests on the ring: a facet's gap closed (to round-off of the clearance), none negative
    gaps = system.contacts.gaps(q)
    clearance = np.abs(system.contacts.jN).max()
    assert gaps.min() >= -1e-12 * clearance and np.abs(gaps).min() <= 1e-12 * clearance


def test_stationary_start_needs_one_flow(monkeypatch):
    """From the stationary state the shooting converges at once: one flow over the period (with its monodromy
    matrix) gives the residual, no Newton step follows, and the state is phi_T's fixed point to round-off. The
    residual's tolerance 1e-12: an equilibrium's flow over a period is constant up to the closed form's
    round-off (measured 7e-15)."""
    scene, model, red, system = _rub()
    q = _stationary_start(scene, system)
    flows = sys.modules["nsfem.periodic.flow"].FlowMap
    calls = []
    call = flows.__call__

    def counted(self, q0, v0, jacobian=True):
        calls.append(jacobian)
        return call(self, q0, v0, jacobian)

    monkeypatch.setattr(flows, "__call__", counted)
    orbit = periodic_orbit(system, 1.0 / scene.rotation.speed_hz, q, np.zeros(system.n), tol=1e-12)
    assert calls == [True]
    assert orbit.converged and orbit.iterations == 0 and orbit.residual <= 1e-12
    assert orbit.events_per_period == 0
    # the state comes back: the flow's end state is the start
    assert np.abs(orbit.result.q[:, -1] - q).max() <= 1e-12 * np.abs(q).max()


def test_nested_single_threaded_blas_blocks():
    """An inner single_threaded_blas block (a flow inside a shooting) keeps one thread and leaves the outer block's
    limit in place; the outermost restores the counts before it, also when its body raises."""
    from threadpoolctl import threadpool_info

    from nsfem.integrate.base import single_threaded_blas

    def counts():
        return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]

    before = counts()
    try:
        with single_threaded_blas():
            with single_threaded_blas():
                assert set(counts()) <= {1}
            assert set(counts()) <= {1}   # the inner block did not restore the outer's counts
            raise KeyError("body")
    except KeyError:
        pass
    assert counts() == before
    with single_threaded_blas():   # and a block after a raising one limits again
        assert set(counts()) <= {1}
    assert counts() == before


def test_inner_blas_block_skips_the_library_scan(monkeypatch):
    """Only the outermost block limits the threads (threadpoolctl's scan of the loaded libraries): a shooting's
    flows inside it pay no scan of their own."""
    from nsfem.integrate import blas

    calls = []
    limits = blas.threadpool_limits

    def counted(*args, **kwargs):
        calls.append(kwargs)
        return limits(*args, **kwargs)

    monkeypatch.setattr(blas, "threadpool_limits", counted)
    with blas.single_threaded_blas():
        for _ in range(3):
            with blas.single_threaded_blas():
                pass
    assert len(calls) == 1
