"""A scene's periodic orbit (``nsfem periodic``): the layer between a scene and the shooting of
:mod:`nsfem.periodic.shooting`.

The scene's system is built and checked as ``nsfem run`` builds it (:func:`nsfem.simulate.prepare_scene`:
its frame, reduction, damping and the exact method's requirements); the forcing period is one revolution,
T = 1 / rotation.speed_hz (the unbalance turns at the speed in the inertial frame, gravity in the rotating
one); the orbit's period is K T (``multiple`` K: a subharmonic). The shooting starts from the last state of a
transient of ``transient_periods`` orbit periods with the exact method from the scene's ``[initial]`` state, or
from a saved state (``start``: a run's ``result.npz``, its last output; or an ``orbit.npz`` of this command).

>>> from nsfem import load_scene
>>> from nsfem.periodic.scene import orbit_of_scene
>>> so = orbit_of_scene(load_scene("crack"))              # doctest: +SKIP
>>> so.orbit.stable, so.amplitudes["disk_z"]              # doctest: +SKIP
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterator

import numpy as np

from ..errors import NsfemError, SceneError

if TYPE_CHECKING:
    from ..integrate import ContactSystem
    from ..scene import Scene

#: orbit periods of the transient before the shooting, by default (without ``start``): on the shipped crack scene
#: (a sharp 2x resonance, 1.6 % damping) the shooting converges from a transient of 2, 10 or 50 periods in 6, 6
#: and 4 Newton steps, from the initial state itself in 9 (the shooting lets a transient go on where Newton
#: fails); the transient costs about 6 ms a period there
TRANSIENT_PERIODS = 10
#: where the shooting's section lies after a transient (``orbit_of_scene``'s ``section``)
SECTIONS = ("quiet", "start")
#: at most this many orbit periods of transient (the search cost of the exact method is checked besides)
TRANSIENT_PERIODS_MAX = 100_000
#: the largest subharmonic order K of ``multiple``
MULTIPLE_MAX = 64
#: samples per forcing period at least over the orbit (histories, amplitudes, figures)
SAMPLES_PER_REVOLUTION = 256
#: VTU frames per forcing period of the orbit's series
FRAMES_PER_REVOLUTION = 32
#: a multiplier this close to the unit circle in modulus is on it (the tolerance of
#: :func:`nsfem.periodic.shooting.classify`'s verdict)
UNIT_CIRCLE_TOL = 1e-6
#: the shooting's tolerance on |phi(x0) - x0| / |x0| (dimensionless): from round-off (1e-14) to a coarse 1e-3
TOL_RANGE = (1e-14, 1e-3)


@dataclass
class SceneOrbit:
    """A scene's periodic orbit and what ``nsfem periodic`` reports of it.

    ``orbit``: the shooting's :class:`~nsfem.periodic.shooting.PeriodicOrbit`; ``t`` (K,) the output times
    over one period [s], from the section t0; ``signals`` (K, sensors) the scene's sensors over it [m];
    ``amplitudes`` {sensor: half the peak-to-peak over the period [m]}; ``contact_sequence`` the events over
    one period in order ({"t_s": time after t0, "kinds", "contacts" (labels), "closed": the closed contacts
    after it}); ``start`` what the shooting started from; ``warnings`` the results outside the model's validity
    or the shooting's (not converged, grazing)."""

    orbit: object
    system: "ContactSystem"
    multiple: int
    forcing_period_s: float
    transient_periods: int
    start: str
    t: np.ndarray
    signals: np.ndarray
    sensors: tuple
    amplitudes: dict[str, float]
    contact_sequence: list[dict]
    grazing: list[dict]
    approximations: list[dict] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    wall_s: float = 0.0

    @property
    def period_s(self) -> float:
        return float(self.orbit.period_s)

    def verdict(self) -> str:
        """'stable' or 'unstable (<kind of loss>)' in words."""
        if not self.orbit.converged:
            return "none: the shooting did not converge (the multipliers are the last iterate's)"
        neutral = len(getattr(self.orbit, "neutral", None) or ())
        also = (f"; {neutral} multiplier(s) +1 neutral (a continuum of stick positions: a contact sticks all period)"
                if neutral else "")
        if self.orbit.stable:
            k = self.on_unit_circle() - neutral
            return (f"stable, marginally: {k} multiplier(s) on the unit circle (|mu| within {UNIT_CIRCLE_TOL:g} of 1: "
                    "motions that neither grow nor decay, e.g. undamped modes)" + also) if k else "stable" + also
        kind = {"fold": "fold (a multiplier through +1)", "period-doubling": "period doubling (a multiplier "
                "through -1)", "neimark-sacker": "Neimark-Sacker (a complex pair outside the unit circle)"}
        return (f"unstable: {kind.get(self.orbit.loss, self.orbit.loss or 'a multiplier outside the unit circle')}"
                + also)

    def on_unit_circle(self) -> int:
        """How many multipliers lie on the unit circle (| |mu| - 1 | <= :data:`UNIT_CIRCLE_TOL`)."""
        return int(np.sum(np.abs(np.abs(np.asarray(self.orbit.multipliers, dtype=complex)) - 1.0) <= UNIT_CIRCLE_TOL))

    def to_json(self) -> dict:
        """The ``nsfem periodic`` JSON keys (design section 9, and the additions of issue 36)."""
        o = self.orbit
        mu = np.asarray(o.multipliers, dtype=complex)
        return {"period_s": float(o.period_s), "converged": bool(o.converged), "residual": float(o.residual),
                "multipliers": [[float(z.real), float(z.imag)] for z in mu],
                "multiplier_moduli": [float(abs(z)) for z in mu],
                # no orbit, no verdict: a shooting that did not converge has null stability (its iterate's
                # multipliers are kept, for what they are)
                "stable": bool(o.stable) if o.converged else None, "loss": o.loss if o.converged else None,
                "on_unit_circle": self.on_unit_circle(), "events_per_period": int(o.events_per_period),
                "amplitudes": {k: float(v) for k, v in self.amplitudes.items()},
                "iterations": int(o.iterations), "t0_s": float(o.t0), "multiple": self.multiple,
                "forcing_period_s": self.forcing_period_s, "transient_periods": self.transient_periods,
                "start": self.start, "grazing": self.grazing, "contact_sequence": self.contact_sequence,
                "approximations": self.approximations, "ndof": int(self.system.n),
                "neutral": list(getattr(o, "neutral", None) or []),
                "warnings": list(self.warnings), "notes": list(self.notes)}


def check_options(multiple, transient_periods, tol, output_dt) -> None:
    """Refuse bad orbit options before any computation (one line naming the option, its value, the reason)."""
    if isinstance(multiple, bool) or not isinstance(multiple, (int, np.integer)) or not 1 <= multiple <= MULTIPLE_MAX:
        raise NsfemError(f"--multiple must be an integer from 1 to {MULTIPLE_MAX} (the orbit's period in forcing "
                         f"periods), got {multiple!r}")
    if transient_periods is not None and (isinstance(transient_periods, bool) or not isinstance(
            transient_periods, (int, np.integer)) or not 0 <= transient_periods <= TRANSIENT_PERIODS_MAX):
        raise NsfemError(f"--transient must be an integer from 0 to {TRANSIENT_PERIODS_MAX} (orbit periods "
                         f"integrated before the shooting), got {transient_periods!r}")
    lo, hi = TOL_RANGE
    if not (isinstance(tol, (int, float)) and math.isfinite(tol) and lo <= tol <= hi):
        raise NsfemError(f"--tol must lie in [{lo:g}, {hi:g}] (the shooting's residual |phi(x0) - x0| / |x0|), "
                         f"got {tol!r}")
    if output_dt is not None and not (isinstance(output_dt, (int, float)) and math.isfinite(output_dt)
                                      and output_dt > 0):
        raise NsfemError(f"periodic: output_dt must be a finite time step > 0 s, got {output_dt!r}")


def check_scene(scene: "Scene") -> float:
    """The forcing period T = 1 / rotation.speed_hz [s] of a scene that can have a periodic orbit; a run-up
    or a rotor at rest refused (one line naming the key)."""
    rot = scene.rotation
    if rot.ramped:
        key = "rotation.speed_table_s" if rot.speed_table_s else "rotation.ramp_to_hz"
        raise SceneError(key, "a run-up changes the speed, so its response is not periodic; a periodic orbit is at "
                         "one speed: remove the ramp (nsfem periodic reads rotation.speed_hz)")
    if not rot.speed_hz > 0:
        raise SceneError("rotation.speed_hz", f"{rot.speed_hz:g} Hz: a rotor at rest has no periodic forcing, its "
                         "steady state is an equilibrium: nsfem stationary answers that one")
    return 1.0 / rot.speed_hz


def orbit_of_scene(scene: "Scene", multiple: int = 1, start: str | Path | None = None,
                   transient_periods: int | None = None, tol: float = 1e-9, output_dt: float | None = None,
                   warn: Callable[[str], None] | None = None, progress: bool | None = False,
                   shoot: Callable | None = None, model=None, reduction=None, section: str = "quiet") -> SceneOrbit:
    """The periodic orbit of ``scene`` of period ``multiple`` forcing periods (see the module's docstring).

    ``transient_periods`` (default :data:`TRANSIENT_PERIODS` without ``start``, 0 with it; a transient from a
    saved state is refused: the state is a starting guess already); ``tol`` the shooting's tolerance;
    ``output_dt`` the sampling of the period's histories (default: at least :data:`SAMPLES_PER_REVOLUTION`
    samples per forcing period, finer when the scene's simulation.output_dt is); ``warn(text)`` receives the
    warnings (a run's checks, not converged, grazing, an unstable orbit's meaning). ``shoot``: the shooting
    function (default :func:`nsfem.periodic.shooting.periodic_orbit`). ``model``, ``reduction``: the scene's, when
    built already (a sweep shares them between its values). ``section``: after a transient, ``"quiet"`` (default)
    shoots at the phase of its last period farthest from events (:func:`.flow.quiet_phase`: the map is smooth
    there and, on the shipped crack, far better conditioned: 4 Newton steps instead of 6), ``"start"`` at the
    transient's end (a whole number of periods: t0 = 0)."""
    import time

    from ..simulate import integrate_prepared, prepare_scene

    check_options(multiple, transient_periods, tol, output_dt)
    if section not in SECTIONS:
        raise NsfemError(f"--section: {str(section)[:40]!r} is not one of {', '.join(SECTIONS)}")
    if start is not None and transient_periods:
        raise NsfemError("--transient with --start: the saved state is the shooting's starting guess already; "
                         "give one of them")
    default_transient = transient_periods is None and start is None
    transient_periods = (0 if start is not None else TRANSIENT_PERIODS) if transient_periods is None \
        else int(transient_periods)
    forcing = check_scene(scene)
    period = multiple * forcing
    if output_dt is not None and output_dt > period:
        raise NsfemError(f"periodic: output_dt {output_dt:g} s exceeds the orbit's period {period:g} s")
    dt = period / orbit_samples(scene, multiple, output_dt)
    saved = _saved_state(start) if start is not None else None
    warnings: list[str] = []

    def say(text: str) -> None:
        warnings.append(text)
        if warn is not None:
            warn(text)

    t_wall = time.perf_counter()
    # the run's checks (search cost, output size, damping) on the transient's span (or one period), sampled once a
    # period as the transient is (the orbit's own samples, one period of them, are few)
    sized = _with_simulation(scene, max(transient_periods, 1) * period, period)
    system, info, q0, v0 = prepare_scene(sized, "exact", model=model, reduction=reduction, warn=say)
    if shoot is None:   # the shooting's own refusals (a round ring, ...) before the transient: its map's checks
        from .flow import FlowMap

        FlowMap(system, 0.0, period)
    t0, lead = 0.0, None   # (lead: the transient's configurations)
    if saved is not None:
        q0, v0, t_saved, what = saved
        if q0.shape != (system.n,):
            raise NsfemError(f"--start: {start} holds states of {q0.size} coordinates, this scene's system has "
                             f"{system.n} (another scene, mesh or reduction)")
        t0 = math.fmod(t_saved, forcing)   # the forcing's phase at the saved time
        origin = f"{what} {start} (t = {t_saved:.6g} s)"
    elif default_transient and not system.harmonic and (stationary := _stationary_start(scene, system)) is not None:
        # no periodic forcing in the scene's frame (a rotating frame without gravity): the orbit is its stationary
        # state, which LCP 28 gives directly (the shipped rub: 16 Newton steps from a 3-period transient, 0 from it)
        q0, v0 = stationary, np.zeros(system.n)
        transient_periods = 0
        origin = "the stationary state (LCP 28) of the scene"
    elif transient_periods:
        # (its configurations kept for the shooting, FlowMap.share; no energy balance: the same states, unread)
        lead = {}
        res, _ = integrate_prepared(sized, system, info, "exact", q0, v0, t_end=transient_periods * period,
                                    output_dt=period, progress=progress,
                                    options={"configurations": lead, "energy_balance": False})
        if not res.completed:   # interrupted (Ctrl-C, SIGTERM): its last state is not at the section's phase
            raise KeyboardInterrupt
        q0, v0 = res.q[:, -1].copy(), res.v[:, -1].copy()
        origin = f"a transient of {transient_periods} periods from the scene's initial state"
        if section == "quiet" and (t0 := _quiet_section(res, transient_periods, period)):
            q0, v0 = _flowed(system, q0, v0, t0, lead)
            origin += f" and on to its quiet phase t0 = {t0:.6g} s"
    else:
        origin = "the scene's initial state"
    options = {}
    if shoot is None:
        try:
            from .shooting import periodic_orbit as shoot
        except ImportError:
            raise NsfemError("nsfem periodic: not yet: the shooting on the exact flow (nsfem.periodic.shooting) "
                             "is not in this version") from None
        options["lead"] = lead   # the transient's configurations: the shooting does not build them again
    import warnings as python_warnings

    with python_warnings.catch_warnings(), interrupts_end_flows():   # (non-convergence: said once, by describe())
        python_warnings.simplefilter("ignore")
        orbit = shoot(system, period, q0, v0, t0, tol=tol, output_dt=dt, **options)
    if not getattr(orbit.result, "completed", True):   # a flow cut short by an interrupt is no period
        raise KeyboardInterrupt
    orbit.result.info.update(info)
    so = describe(scene, system, orbit, multiple, forcing, transient_periods, origin, say)
    so.wall_s = time.perf_counter() - t_wall
    return so


def _quiet_section(res, periods: int, period: float) -> float:
    """The phase of the transient's last period farthest from its events (:func:`.flow.quiet_phase`), 0.0 without
    events."""
    from .flow import quiet_phase

    return quiet_phase([e["t"] for e in res.events + res.impacts if e["t"] >= (periods - 1) * period], period)


def _flowed(system, q, v, t: float, lead: dict):
    """The state t [s] after a whole number of periods (the forcing's phase 0) by the exact flow, with the
    transient's configurations (:meth:`.flow.FlowMap.share`)."""
    from .flow import FlowMap

    with interrupts_end_flows():
        to_section = FlowMap(system, 0.0, t)
        to_section.share(lead)
        f = to_section(q, v, jacobian=False)
    if not getattr(f.result, "completed", True):   # cut short by an interrupt: not at the section
        raise KeyboardInterrupt
    return f.q, f.v


class _Interrupted(BaseException):
    """Ctrl-C or SIGTERM within :func:`interrupts_end_flows` (no KeyboardInterrupt: the integrator would catch it)."""


@contextlib.contextmanager
def interrupts_end_flows() -> Iterator[None]:
    """Ctrl-C (SIGINT) and SIGTERM within the block end it with KeyboardInterrupt, even inside a flow: the exact
    integrator ends a run cleanly on KeyboardInterrupt (completed = False), which a shooting or a continuation
    would take for a failed step of theirs and go on. A signal whose handler is SIG_IGN stays ignored; outside
    the main thread (a sweep's worker) the block runs as it is."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, frame):
        raise _Interrupted

    sigs = [s for s in (signal.SIGINT, signal.SIGTERM) if signal.getsignal(s) is not signal.SIG_IGN]
    previous = {sig: signal.signal(sig, stop) for sig in sigs}
    try:
        yield
    except _Interrupted:
        raise KeyboardInterrupt from None
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _stationary_start(scene: "Scene", system: "ContactSystem") -> np.ndarray | None:
    """The scene's stationary state (LCP 28) in the system's coordinates as a start for the shooting, or None where
    it has none (a contact model it does not cover, no solution, a state the exact flow's contacts refuse): the
    transient then starts the shooting.

    With rigid contacts only, LCP 28 is solved on the system's own Q, f0 and contacts
    (:func:`nsfem.analysis.stationary.stationary`: the same matrices :func:`~nsfem.analysis.stationary.rotor_stationary`
    assembles again, without its report of the rotor's parts: 6 ms of CPU on the shipped rub against 45 ms); elastic
    rings (their compliance) go through :func:`~nsfem.analysis.stationary.rotor_stationary`."""
    from ..analysis.stationary import rotor_stationary, stationary
    from ..integrate.base import initial_state, single_threaded_blas

    model, reduction = system.info.get("model"), system.info.get("reduction")
    if model is None or reduction is None:
        return None
    try:
        with single_threaded_blas():   # (small solves: a second BLAS thread only waits for a core)
            q = rotor_stationary(model, reduction, scene.rotation, scene.damping).q if system.rings else \
                stationary(system.Q, system.f0, system.contacts).q
        q = np.asarray(q, dtype=float)
        if q.shape != (system.n,) or not np.all(np.isfinite(q)):
            return None
        initial_state(system, q, np.zeros(system.n))   # on or above every contact
    except NsfemError:
        return None
    return q


def orbit_samples(scene: "Scene", multiple: int, output_dt: float | None = None) -> int:
    """Output intervals over the orbit's period K T: ``output_dt`` rounded to a whole number of them, by
    default at least :data:`SAMPLES_PER_REVOLUTION` per forcing period, finer where the scene's
    simulation.output_dt is."""
    period = multiple / scene.rotation.speed_hz
    if output_dt is not None:
        return max(1, math.ceil(period / output_dt - 1e-9))
    return max(SAMPLES_PER_REVOLUTION * multiple, math.ceil(period / scene.simulation.output_dt - 1e-9))


def vtu_every(samples: int, multiple: int) -> int:
    """Every how many outputs of the orbit a VTU frame is written: :data:`FRAMES_PER_REVOLUTION` a forcing
    period (more where the outputs are fewer)."""
    return max(1, samples // (FRAMES_PER_REVOLUTION * multiple))


def _with_simulation(scene: "Scene", t_end: float, output_dt: float) -> "Scene":
    """``scene`` with simulation.t_end and output_dt replaced (the typed part only; the tree is the user's)."""
    import copy
    from dataclasses import replace

    out = copy.copy(scene)
    out.simulation = replace(scene.simulation, t_end=t_end, output_dt=min(output_dt, t_end))
    return out


def _saved_state(path) -> tuple[np.ndarray, np.ndarray, float, str]:
    """(q, v, t, what) of a saved state: an orbit.npz's section state (q0, v0, t0) or a results file's last
    output (q[:, -1], v[:, -1], t[-1]); any other file refused in one line."""
    import zipfile

    path = Path(path)
    if path.is_dir():
        raise NsfemError(f"--start: {path} is a folder; give its result.npz or orbit.npz")
    if not path.is_file():
        raise NsfemError(f"--start: {path} does not exist")
    try:
        with np.load(path, allow_pickle=False) as r:
            if "q0" in r.files and "v0" in r.files:
                if r["q0"].ndim != 1:
                    raise NsfemError(f"--start: {path} is a branch.npz (the section states of {len(r['q0'])} "
                                     "orbits along a branch); give an orbit.npz of nsfem periodic or a run's "
                                     "result.npz")
                q, v, t, what = r["q0"], r["v0"], float(np.ravel(r["t0"])[0]), "the orbit in"
            else:
                q, v, t, what = r["q"][:, -1], r["v"][:, -1], float(r["t"][-1]), "the last output of"
    except (OSError, ValueError, KeyError, IndexError, EOFError, zipfile.BadZipFile):
        raise NsfemError(f"--start: {path} is not a results file of nsfem run nor an orbit.npz of nsfem "
                         "periodic") from None
    q, v = np.asarray(q, dtype=float).ravel(), np.asarray(v, dtype=float).ravel()
    if q.shape != v.shape or not (np.all(np.isfinite(q)) and np.all(np.isfinite(v)) and math.isfinite(t)):
        raise NsfemError(f"--start: {path} holds a state that is not finite or whose q and v differ in size")
    return q, v, t, what


def describe(scene: "Scene", system: "ContactSystem", orbit, multiple: int, forcing: float,
             transient_periods: int, start: str, warn: Callable[[str], None]) -> SceneOrbit:
    """The report of an orbit of ``scene``'s ``system``: sensor signals and amplitudes over the period, the
    contact sequence, grazing by label; warnings for a shooting that did not converge and for grazing."""
    from ..fem.constraints import dense
    from ..sensors import read

    res = orbit.result
    t = np.asarray(res.t, dtype=float)
    t0 = float(orbit.t0)
    # a flow's times counted from its start (0) rather than from t0: shifted to the forcing's time
    offset = t0 if t.size and abs(t[0] - t0) > 1e-9 * orbit.period_s else 0.0
    t = t + offset
    rot = scene.rotation
    sensors = tuple(scene.sensors)
    if sensors:
        signals = read(sensors, system.info["model"], dense(system.info["reduction"].T), t, res.q, rot.frame,
                       rot.speed_hz, rot.phase_deg)
    else:
        signals = np.zeros((t.size, 0))
    where, kinks = impact_readings(system, sensors, t, res, offset, rot.frame, rot.speed_hz, rot.phase_deg)
    amplitudes = {s.name: half_peak_to_peak(signals[:, k], kinks=(where, kinks[:, k])) for k, s in enumerate(sensors)}
    labels = list(system.model_contacts.labels)
    sequence = contact_sequence(res.events, labels, t0 - offset)
    grazing = [_named_grazing(g, labels, t0 - offset) for g in (orbit.grazing or [])]
    if not orbit.converged:
        warn(f"the shooting did not converge in {orbit.iterations} iterations (residual {orbit.residual:.2e}): "
             "the state is not a periodic orbit; a longer transient (--transient) or a start nearer to it may help")
    approximations = [{"t_s": float(a.get("t", t0 - offset)) - (t0 - offset), "why": str(a.get("why", ""))}
                      for a in (getattr(orbit, "approximations", None) or [])]
    if approximations:
        whys = sorted({a["why"] for a in approximations})
        warn(f"the monodromy matrix is approximate at {len(approximations)} event(s) of the period ("
             + "; ".join(whys) + "): the multipliers near the unit circle are uncertain there")
    if grazing:
        g = grazing[0]
        near = f" within {g['gap_min_m']:.3g} m" if "gap_min_m" in g else ""
        warn(f"grazing: the gap of {', '.join(g['contacts'])} comes{near} to zero without closing "
             f"({1e3 * g['t_s']:.4g} ms after the section): the orbit is at a grazing bifurcation, where its "
             "multipliers jump: they hold on this side of it only" + (f" ({len(grazing)} grazings per period)"
                                                                     if len(grazing) > 1 else ""))
    for ring, facets in polygon_corners(labels, res.normal_force, orbit.events_per_period):
        warn(f"{ring}: the orbit rests on a corner of its polygon (facets {', '.join(facets)} closed all period, "
             "no event): a corner holds the rotor in every direction of the plane, so the multipliers are the "
             "corner's, not those of the round ring the polygon stands for (more facets move the corner; they do "
             "not remove it); in the inertial frame the corners pass by as events (docs/validation.md, the rub on "
             "an elastic ring)")
    notes = []
    if not system.harmonic:
        notes.append(f"no time-dependent load in the {rot.frame} frame (the unbalance and gravity are constant "
                     "there): the period of one revolution is kept, and an orbit through an equilibrium is that "
                     "equilibrium (nsfem stationary), a whirl of another period is not found")
    return SceneOrbit(orbit, system, multiple, forcing, transient_periods, start, t, signals, sensors, amplitudes,
                      sequence, grazing, approximations, notes=notes)


def polygon_corners(labels: list[str], normal_force, events_per_period: int) -> list[tuple[str, list[str]]]:
    """The stator rings (``stator.K``) whose orbit rests on a corner of their polygon: two or more of the ring's
    facets (contacts ``stator.K.I``) carry a normal force at every sample of an orbit without events. A round
    ring's rub touches at one point; the polygon's corner also pins the rotor along the ring."""
    if events_per_period or normal_force is None:
        return []
    force = np.asarray(normal_force, dtype=float)
    if force.ndim != 2 or force.shape[0] != len(labels) or force.shape[1] == 0:
        return []
    from ..contact.tally import parts_of_labels

    loaded = (force > 0).all(axis=1)
    corners = []
    for part in parts_of_labels(labels):
        facets = [labels[k].rpartition(".")[2] for k in part.rows if loaded[k]]
        if part.kind == "ring" and len(facets) >= 2:
            corners.append((part.name, facets))
    return corners


def _named_grazing(g: dict, labels: list[str], t0: float) -> dict:
    """A grazing record of the shooting ({"t", "contacts" or "contact", maybe "gap_min"}) as the JSON has it:
    {"t_s": time after the section, "contacts": labels, "gap_min_m" where known}."""
    ks = g.get("contacts", [g["contact"]] if "contact" in g else [])
    out = {"t_s": float(g.get("t", t0)) - t0,
           "contacts": [labels[int(k)] if isinstance(k, (int, np.integer)) and 0 <= k < len(labels) else str(k)
                        for k in ks]}
    if g.get("gap_min") is not None:
        out["gap_min_m"] = float(g["gap_min"])
    return out


def impact_readings(system: "ContactSystem", sensors, t: np.ndarray, res, offset: float, frame: str,
                    speed_hz: float, phase_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(where (impacts,): the sample before each impact; (impacts, sensors) the probes' readings at them) of the
    impacts of ``res`` (a flow of ``system`` sampled at the times ``t`` = res.t + ``offset``, the forcing's
    clock): the positions there, each by the exact flow from the sample before it. An impact's velocity jump is
    a kink of the signal, often its extreme (a probe at a stop), which the samples straddle
    (:func:`half_peak_to_peak`)."""
    from ..fem.constraints import dense
    from ..sensors import read
    from .flow import flow

    times = [float(e["t"]) + offset for e in res.events if e.get("impact")]
    if not sensors or not times or t.size < 2:
        return np.zeros(0, dtype=int), np.zeros((0, len(sensors)))
    Q = np.empty((system.n, len(times)))
    where = np.empty(len(times), dtype=int)
    for j, te in enumerate(times):
        k = where[j] = max(0, min(int(np.searchsorted(t, te, side="right")) - 1, t.size - 1))
        span = te - t[k]
        if span <= 1e-12 * (t[-1] - t[0]):   # a sample at the impact (position continuous through it)
            Q[:, j] = res.q[:, k]
        else:
            Q[:, j] = flow(system, float(t[k]), res.q[:, k], res.v[:, k], span, jacobian=False, output_dt=span).q
    return where, read(sensors, system.info["model"], dense(system.info["reduction"].T), np.array(times), Q, frame,
                       speed_hz, phase_deg)


def half_peak_to_peak(y: np.ndarray, closed: bool = True, kinks: tuple | None = None) -> float:
    """Half the peak-to-peak of a periodic signal sampled uniformly over one period, ``closed``: its first
    sample repeated at the end (an orbit's outputs from t0 to t0 + T; the end is left out: it is the start
    again up to the shooting's residual) or not (``closed=False``): its extremes refined by a parabola through
    the extreme sample and its two neighbours (periodic), kept when its vertex lies between them: a smooth peak
    sampled 256 times a revolution is then found to about (2 pi / 256)^4 / 24 = 1.5e-8 of its amplitude
    instead of (pi / 256)^2 / 2 = 7.5e-5. A kink (an impact) is missed by the samples either side of it (by
    the velocity times the sample interval), and a parabola through samples either side of it is no peak's:
    ``kinks`` = (where, values): the sample before each of the period's impacts and the signal's value there
    (:func:`impact_readings`): those values are extremes where they exceed the samples', and no parabola
    spans an impact."""
    y = np.asarray(y, dtype=float)
    where, values = (np.zeros(0, dtype=int), np.zeros(0)) if kinks is None else (
        np.asarray(kinks[0], dtype=int).ravel(), np.asarray(kinks[1], dtype=float).ravel())
    if closed and y.size > 1:
        y = y[:-1]
    if y.size < 3:
        y = np.concatenate([y, values])
        return float(0.5 * (y.max(initial=0.0) - y.min(initial=0.0))) if y.size else 0.0
    where = where % y.size
    high, low = _extreme(y, 1.0, where), -_extreme(y, -1.0, where)
    if values.size:
        high, low = max(high, float(values.max())), min(low, float(values.min()))
    return 0.5 * (high - low)


def _extreme(y: np.ndarray, sign: float, kinks: np.ndarray = np.zeros(0, dtype=int)) -> float:
    """sign * (the maximum of sign * y), refined (:func:`half_peak_to_peak`) unless a kink lies between the
    samples k - 1 and k + 1 (``kinks``: the samples before them)."""
    s = sign * y
    k = int(np.argmax(s))
    if np.any((kinks == k) | (kinks == (k - 1) % s.size)):
        return float(s[k])
    a, b, c = s[k - 1], s[k], s[(k + 1) % s.size]
    curvature = a - 2.0 * b + c
    if curvature < 0.0:
        offset = 0.5 * (a - c) / curvature
        if abs(offset) <= 1.0:
            return float(b - 0.25 * (a - c) * offset)
    return float(b)


def contact_sequence(events: list[dict], labels: list[str], t0: float) -> list[dict]:
    """The events of one period in order: time after the section ``t0`` (in the events' clock), kinds,
    contacts (by label), whether it is an impact, and the contacts closed and sticking after it (labels)."""
    def named(ks) -> list[str]:
        return [labels[int(k)] if 0 <= int(k) < len(labels) else str(k) for k in ks]

    out = []
    for e in events:
        after = e.get("after", {})
        out.append({"t_s": float(e["t"]) - t0,
                    "kinds": list(e.get("kinds", [])), "contacts": named(e.get("contacts", [])),
                    "impact": bool(e.get("impact", False)), "closed": named(after.get("closed", [])),
                    "stick": named(k for k in after.get("stick", []) if isinstance(k, (int, np.integer)))})
    return out


def parse_continuation(text: str) -> tuple[str, float, float]:
    """(key, low, high) of ``--continue KEY=LOW:HIGH``: two finite ends that differ (either order: the
    branch is followed from LOW towards HIGH); one line naming the problem otherwise.

    >>> parse_continuation("rotation.speed_hz=30:20")
    ('rotation.speed_hz', 30.0, 20.0)
    """
    key, sep, rng = text.partition("=")
    lo, colon, hi = rng.partition(":")
    key = key.strip()
    if not sep or not colon or not key or ":" in hi:
        raise NsfemError(f"--continue {text.strip()!r}: give KEY=LOW:HIGH (e.g. rotation.speed_hz=20:30)")
    from ..scene.overrides import range_ends

    ends = range_ends("--continue", key, lo, hi)
    if ends[0] == ends[1]:
        raise NsfemError(f"--continue {key}: LOW and HIGH are the same value ({lo.strip()}); a branch needs a range")
    return key, ends[0], ends[1]


def check_continuation(scene: "Scene", key: str, low: float, high: float, load) -> None:
    """Refuse a continuation key that is not a number of ``scene`` (a missing item, a string, a list, a
    switch) and ends at which the scene is not valid: ``load(overrides)`` loads the scene with extra
    ``--set`` overrides (each end is loaded once; its error is the line)."""
    from ..scene.overrides import missing_item

    item = missing_item(scene, key)
    if item is not None:
        raise NsfemError(f"--continue {key}: the scene has no {item} (continue a key of an item the scene has)")
    node = dict(scene)
    for part in key.split("."):
        if isinstance(node, list) and part.isdigit() and int(part) < len(node):
            node = node[int(part)]
        elif isinstance(node, dict) and part in node:
            node = node[part]
        else:
            raise NsfemError(f"--continue {key}: not a key of the scene (give a dotted key such as "
                             "rotation.speed_hz or stator.0.friction)")
    if isinstance(node, bool) or not isinstance(node, (int, float)):
        what = "a table" if isinstance(node, dict) else "a list" if isinstance(node, list) else repr(node)
        raise NsfemError(f"--continue {key}: its value is {what}, not a number; a branch follows a numeric key")
    for end in (low, high):
        try:
            load([f"{key}={end!r}"])
        except NsfemError as exc:
            raise NsfemError(f"--continue {key}={low!r}:{high!r}: at {end!r}: {exc}") from None
