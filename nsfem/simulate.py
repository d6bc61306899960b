"""A scene's transient run: system, initial state, integrator, results file (``nsfem run``).

>>> from nsfem import load_scene
>>> scene = load_scene(None, ["mesh.elements=20", "simulation.t_end=0.01"])
>>> result, system = run_scene(scene)
>>> result.summary()["method"], float(result.t[-1]), result.gap.shape
('exact', 0.01, (9, 11))
"""

from __future__ import annotations

import math

import numpy as np

from .errors import IntegrationError, NsfemError
from .integrate import ContactSystem, integrate
from .integrate.base import output_times
from .result import Result


def uniform_velocity(model, reduction, system: ContactSystem, velocity) -> np.ndarray:
    """Reduced velocities closest (in the kinetic-energy norm) to a uniform translation.

    The translation (u1, u2, u3) sets U = u1, V = u2, W = u3 and slopes 0 at every node;
    where supports forbid it, the admissible motion nearest to it is taken.
    """
    velocity = np.asarray(velocity, dtype=float)
    if not np.any(velocity):
        return np.zeros(system.n)
    vf = np.zeros(model.n_full)
    for space in model.spaces.values():
        vf[space.dofs["U"]] = velocity[0]
        for fld, val in (("V", velocity[1]), ("W", velocity[2])):
            vf[space.dofs[fld][space.bending.nodal_dofs[0]]] = val
    T = reduction.T
    rhs = T.T @ (model.M_full @ vf)
    return np.linalg.solve(system.M, np.asarray(rhs).ravel())


def initial_state(scene, model, reduction, system: ContactSystem) -> tuple[np.ndarray, np.ndarray]:
    """(q0, v0) of ``[initial]``: rest (undeformed) or the stationary state (LCP 28)."""
    ini = scene["initial"]
    q0 = np.zeros(system.n)
    if ini["state"] == "stationary":
        from .analysis.stationary import scene_stationary

        q0 = scene_stationary(scene, model, reduction).q
    return q0, uniform_velocity(model, reduction, system, ini["velocity"])


def integrator_options(scene, method: str) -> dict:
    sim = scene["simulation"]
    if method == "rk":
        return {"solver": sim["rk_solver"], "rtol": sim["rtol"], "atol": sim["atol"]}
    if method == "penalty":
        return {"solver": sim["stiff_solver"], "rtol": sim["rtol"], "atol": sim["atol"],
                "stiffness": sim["penalty_stiffness"] or None, "factor": sim["penalty_factor"]}
    if method == "moreau":
        return {"step": sim["moreau_step"] or sim["output_dt"] / 10.0, "theta": sim["moreau_theta"]}
    return {}


#: event-search samples per run above which :func:`run_scene` warns
SAMPLES_WARN = 2e6


def search_cost(system: ContactSystem, t_end: float) -> tuple[float, float]:
    """(f_max [Hz], samples): the fastest free mode of the model and the number of event-search
    samples it implies over t_end (a step of 1/8 of its period, as ``exact`` samples)."""
    import scipy.linalg as sla

    if system.n == 0:
        return 0.0, 0.0
    lam = sla.eigvals(system.Q, system.M)
    w = float(np.sqrt(np.max(np.abs(lam[np.isfinite(lam)]), initial=0.0)))
    return w / (2 * np.pi), t_end * 4.0 * w / np.pi


#: models larger than this skip the (dense) growth-rate check of :func:`growth_rate`
GROWTH_CHECK_MAX_DOF = 400


def growth_rate(system: ContactSystem) -> float:
    """Largest real part [1/s] of the eigenvalues of the contact-free linear system
    M q'' + C q' + Q q = 0 (positive: the open structure is unstable at this speed: divergence
    or flutter; the linear model then leaves its range unless contacts or damping hold it)."""
    import scipy.linalg as sla

    n = system.n
    if n == 0:
        return 0.0
    Mi = np.linalg.inv(system.M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ system.Q, -Mi @ system.C]])
    lam = sla.eigvals(A)
    lam = lam[np.isfinite(lam)]
    # round-off of the eigenvalues: eps times the largest one
    return float(np.max(lam.real, initial=0.0)) if np.max(lam.real, initial=0.0) > 1e-9 * np.max(
        np.abs(lam), initial=0.0) else 0.0


def run_scene(scene, method: str | None = None, progress: bool | None = False, model=None, reduction=None,
              warn=None) -> tuple[Result, ContactSystem]:
    """Integrate a scene with its (or the given) method; returns the Result and the system.

    ``warn(text)`` receives warnings before the integration starts (an unreduced model whose
    fastest mode makes the run long). A run that stops early raises
    :class:`~nsfem.errors.IntegrationError` whose ``result`` holds it up to there."""
    from .fem.assemble import build_model
    from .reduce import scene_reduction

    sim = scene["simulation"]
    method = method or sim["method"]
    from .integrate.base import EXTRA_METHODS

    known = ("exact", "rk", *EXTRA_METHODS)
    if method not in known:
        raise NsfemError(f"simulation.method {method!r} is not available in this version (available: "
                         f"{', '.join(known)})")
    output_times(sim["t_end"], sim["output_dt"])  # validate before building anything
    model = build_model(scene) if model is None else model
    red = scene_reduction(scene, model) if reduction is None else reduction
    system = ContactSystem.from_scene(scene, model, red)
    q0, v0 = initial_state(scene, model, red, system)
    if warn is not None and method == "penalty" and np.any(system.contacts.mu > 0):
        warn(f"penalty neglects friction, as in the paper: the friction coefficients of "
             f"{int(np.sum(system.contacts.mu > 0))} contacts are ignored (use exact, rk or moreau for friction)")
    if warn is not None and method in ("exact", "rk"):
        f_max, samples = search_cost(system, sim["t_end"])
        if samples > SAMPLES_WARN:
            warn(f"the fastest mode of this {system.n}-dof model ({f_max:.4g} Hz) sets the time scale of "
                 f"'{method}': about {samples:.2g} event-search samples for t_end = {sim['t_end']:g} s; a reduced "
                 "model (reduction.method = craig_bampton or modal) runs far faster")
    if warn is not None and system.n <= GROWTH_CHECK_MAX_DOF:
        rate = growth_rate(system)
        if rate > 0.0:
            warn(f"the structure without contact forces is unstable at {scene['rotation']['speed_hz']:g} Hz: its "
                 f"fastest-growing mode grows at {rate:.3g} 1/s (x10 every {math.log(10) / rate:.3g} s); unless the "
                 "contacts or damping hold it, displacements soon exceed the linear model's range")
    info = {"ndof_full": model.n, "reduction": red.info, "title": scene["title"],
            "speed_hz": scene["rotation"]["speed_hz"], "contacts": list(system.contacts.labels)}
    try:
        result = integrate(system, sim["t_end"], method, sim["output_dt"], q0, v0, progress=progress,
                           **integrator_options(scene, method))
    except IntegrationError as exc:
        exc.result.info.update(info)
        exc.system = system
        raise
    result.info.update(info)
    return result, system
