"""One interface, several methods (as scipy's ``solve_ivp(method=...)``).

A method subclasses :class:`Integrator` and must

- take the :class:`~nsfem.integrate.problem.ContactSystem` and its own keyword options in
  ``__init__`` and validate them there (clear NsfemError, before any computation);
- implement ``run(t_end, output_dt, q0, v0) -> Result`` returning a
  :class:`~nsfem.result.Result` with outputs at the times 0, output_dt, ..., t_end;
- stop cleanly on KeyboardInterrupt, returning the result up to the last completed step
  with ``completed = False``.

:func:`integrate` maps ``[simulation] method`` names to the classes in :data:`METHODS`.
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from ..errors import IntegrationError, NsfemError
from ..result import Result
from .blas import single_threaded_blas
from .problem import ContactSystem


class Integrator:
    """Base class (see the module docstring for the contract)."""

    name = "base"

    def __init__(self, system: ContactSystem, **options):
        self.system = system
        self.options = options

    def run(self, t_end: float, output_dt: float, q0=None, v0=None) -> Result:  # pragma: no cover - abstract
        raise NotImplementedError


def initial_state(system: ContactSystem, q0=None, v0=None) -> tuple[np.ndarray, np.ndarray]:
    """(q, v) from q0, v0 (default rest), validated: n finite entries each, no contact penetrated
    (beyond 1e-8 of the terms that make its gap)."""
    n, cs = system.n, system.contacts
    q = np.zeros(n) if q0 is None else np.asarray(q0, dtype=float).copy()
    v = np.zeros(n) if v0 is None else np.asarray(v0, dtype=float).copy()
    if q.shape != (n,) or v.shape != (n,):
        raise NsfemError(f"initial q0 and v0 must have {n} entries")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
        raise NsfemError("initial q0 and v0 must be finite")
    if cs.m:
        g0 = cs.gaps(q)
        size = np.abs(cs.JN).T @ np.abs(q) + np.abs(cs.jN)
        bad = np.flatnonzero(g0 < -1e-8 * (size + float(size.max(initial=0.0))))
        if bad.size:
            k = int(bad[0])
            raise NsfemError(f"the initial state penetrates {cs.labels[k]} "
                             f"(gap {g0[k]:.6g} m < 0); start on or above every contact")
    return q, v


def close_energy(energy: dict, e_final: float, e_max: float) -> dict:
    """Complete an energy record: final_J, residual_J = E(T) - E(0) - W_ext - W_spin + W_diss (damping,
    circulatory, friction, impacts), max_J and relative_residual = |residual| / max E.

    ``work_spin_J`` is the work the drive holding Omega does on the lateral motion through friction at a
    moving surface: the friction force does lam_T . (S^T q') on the structure, the slip velocity is
    S^T q' + Sq^T q + w, so that work is -int lam_T . (Sq^T q + w) dt beside the dissipation
    -int lam_T . u_T' dt >= 0 (``dissipated_friction_J``)."""
    e_max = max(e_max, abs(e_final))
    energy.setdefault("work_spin_J", 0.0)
    balance = (e_final - energy["initial_J"] - energy["work_external_J"] - energy["work_spin_J"]
               + energy["dissipated_damping_J"] + energy["work_circulatory_J"] + energy["dissipated_friction_J"]
               + energy["lost_in_impacts_J"])
    energy.update(final_J=e_final, residual_J=float(balance), max_J=e_max,
                  relative_residual=abs(balance) / e_max if e_max > 0 else 0.0)
    return energy


def output_times(t_end: float, output_dt: float) -> np.ndarray:
    if not (math.isfinite(t_end) and t_end > 0):
        raise NsfemError(f"simulation.t_end must be a positive number, got {t_end}")
    if not (math.isfinite(output_dt) and 0 < output_dt <= t_end):
        raise NsfemError(f"simulation.output_dt must lie in (0, t_end = {t_end}], got {output_dt}")
    n = int(math.floor(t_end / output_dt + 1e-9))
    if n > 10_000_000:
        raise NsfemError(f"t_end / output_dt = {n} output steps exceeds the limit of 1e7")
    t = np.arange(n + 1) * output_dt
    if t_end - t[-1] > 1e-9 * output_dt:
        t = np.append(t, t_end)
    else:  # n dt may round a few ulps past t_end (0.7 = 700 x 1e-3 + 1.1e-16): the last output is t_end
        t[-1] = t_end
    return t


class Progress:
    """Progress of a long run on stderr (never stdout), silent for the first ``delay`` seconds.

    ``enabled``: None shows a one-line bar when stderr is a terminal (library default); True
    also reports on a pipe or a log file, one line every ``every`` seconds (``nsfem run``);
    False shows nothing.
    """

    def __init__(self, t_end: float, enabled: bool | None = None, delay: float = 2.0, stream=None,
                 every: float = 5.0):
        self.stream = stream or sys.stderr
        tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.enabled = tty if enabled is None else bool(enabled)
        self.bar = tty
        self.t_end, self.delay = t_end, delay if tty else max(delay, every)
        self.every = 0.2 if tty else every
        self.t0 = time.perf_counter()
        self.last = 0.0
        self.shown = False

    def __call__(self, t: float, events: int) -> None:
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self.t0 < self.delay or now - self.last < self.every:
            return
        self.last = now
        frac = min(1.0, t / self.t_end)
        text = f"t = {t:.4g} of {self.t_end:g} s ({100 * frac:.1f} %), events {events}, {now - self.t0:.1f} s"
        if self.bar:
            self.stream.write(f"\r  [{'#' * int(30 * frac):<30s}] {text}  ")
            self.shown = True
        else:
            self.stream.write(f"nsfem: progress: {text}\n")
        self.stream.flush()

    def close(self) -> None:
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()


def integrate(system: ContactSystem, t_end: float, method: str = "exact", output_dt: float | None = None,
              q0=None, v0=None, **options) -> Result:
    """Integrate ``system`` from (q0, v0) (default rest) to t_end with the named method."""
    from .event_driven import Exact, RungeKutta

    methods = {"exact": Exact, "rk": RungeKutta, **EXTRA_METHODS}
    if method not in methods:
        raise NsfemError(f"unknown integration method {method!r} (available: {', '.join(methods)})")
    dt = t_end / 1000 if output_dt is None else output_dt
    integrator = methods[method](system, **options)
    # floating-point overflow is not printed as RuntimeWarnings: the integrators check their
    # state, rates and energy and stop with an error naming it (nsfem.integrate.guard)
    with single_threaded_blas(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        if not system.rings:
            return integrator.run(t_end, dt, q0, v0)
        try:
            return with_ring_contacts(integrator.run(t_end, dt, q0, v0), system)
        except IntegrationError as exc:
            if exc.result is not None:
                with_ring_contacts(exc.result, system)
            raise


def with_ring_contacts(res: Result, system: ContactSystem) -> Result:
    """The contact outputs over the model's whole contact list (:attr:`ContactSystem.model_contacts`): the
    rigid contacts' from the run, an elastic ring's facets from its force law at the output states. A facet
    carries the part of the ring's normal force along it (both facets of a corner share it when both push;
    lam >= 0, the force lies in the facets' cone), its friction -mu s lam along its circumferential tangent,
    state 2 (sliding) while it pushes. In place; returns res."""
    from ..contact.ring import forces

    full = system.model_contacts
    index = system.info.get("contact_index")
    if index is None or full is system.contacts:
        return res
    K = res.t.size
    gap = full.gaps(res.q) if K else np.zeros((full.m, 0))
    normal, tang = np.zeros((full.m, K)), np.zeros((full.m, 2, K))
    state = np.zeros((full.m, K), dtype=res.state.dtype)
    normal[index], tang[index], state[index] = res.normal_force, res.tangential_force, res.state
    for ring in system.rings:
        N, _, regions, slip = forces(ring, res.q, res.v)
        on = np.flatnonzero(np.any(N != 0.0, axis=0))
        for j in on:
            ks = list(ring.pushing(int(regions[j])))
            if len(ks) == 1:
                lam = [float(ring.normals[ks[0]] @ N[:, j])]
            else:   # N = a n_k + b n_k+1 at corner k
                lam = list(np.linalg.solve(ring.normals[ks].T, N[:, j]))
            for kk, lm in zip(ks, lam):
                c = ring.facets[kk]
                normal[c, j] = lm
                tang[c, 0, j] = -ring.friction * np.sign(slip[j]) * lm
                state[c, j] = 2
    res.gap, res.normal_force, res.tangential_force, res.state = gap, normal, tang, state
    return res


#: methods registered by other modules (penalty, moreau) as name -> class
EXTRA_METHODS: dict = {}
