"""The delaminated shaft (shipped ``default`` scene) near its gravity resonance: the orbit stays open (issue 36).

In the rotating frame each layer's centrifugal force on its offset from the axis holds the interface open; with
damping the synchronous orbit at 22 Hz never touches, so it is the orbit of a linear system, and Liouville's formula
gives its multipliers' product in closed form: det(monodromy) = exp(-trace(M^-1 C) T) = exp(-alpha n T) for
C = alpha M (the gyroscopic matrix is skew, M^-1 G has zero trace), n the reduced coordinates.
studies/delamination_resonance.py follows it through the resonance (docs/validation.md).
"""

import numpy as np
import pytest

from nsfem.fem.assemble import build_model
from nsfem.integrate.problem import ContactSystem
from nsfem.periodic import periodic_orbit
from nsfem.periodic.flow import FlowMap
from nsfem.reduce import scene_reduction
from nsfem.scene.load import load_scene
from nsfem.simulate import initial_state


def _orbit(alpha: float, speed_hz: float, lead: int = 3):
    scene = load_scene("default", [f"damping.rayleigh=[{alpha},0.0]", f"rotation.speed_hz={speed_hz}"])
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    q, v = initial_state(scene, model, red, system)
    T = 1.0 / speed_hz
    phi = FlowMap(system, 0.0, T)
    for _ in range(lead):
        f = phi(q, v, jacobian=False)
        q, v = f.q, f.v
    return system, T, periodic_orbit(system, T, q, v, tol=1e-10)


def test_open_orbit_below_resonance_obeys_liouville():
    alpha = 2.0
    system, T, o = _orbit(alpha, 22.0)
    r = o.result
    assert o.converged and o.events_per_period == 0
    # open all period: no contact force, the smallest gap well above the integrator's event tolerance (its size,
    # 1e-4 m measured by the study, is the centrifugal mean opening minus gravity's oscillation)
    assert r.normal_force.max() == 0.0
    assert r.gap.min() > 1e-6
    n = system.n
    assert o.multipliers.size == 2 * n            # no contact closed: every direction admissible
    log_det = float(np.sum(np.log(np.abs(o.multipliers))))
    # Liouville: exact for the linear open flow; the transition matrix is a matrix exponential (round-off ~1e-13 per
    # entry), the sum of 50 logs then carries ~1e-12 absolute (1e-13 measured); 1e-10 relative of alpha n T (= 2.3) covers it
    assert log_det == pytest.approx(-alpha * n * T, rel=1e-10)
    assert o.stable and np.abs(o.multipliers).max() < 1.0
