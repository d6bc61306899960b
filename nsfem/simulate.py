"""A scene's transient run: system, initial state, integrator, results file (``nsfem run``).

>>> from nsfem import load_scene
>>> scene = load_scene(None, ["mesh.elements=20", "simulation.t_end=0.01"])
>>> result, system = run_scene(scene)
>>> result.summary()["method"], float(result.t[-1]), result.gap.shape
('exact', 0.01, (9, 11))
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .errors import IntegrationError, NsfemError, SceneError
from .integrate import ContactSystem, integrate
from .integrate.base import output_times
from .result import Result
from .system import ZETA_MAX, check_damping, damping_ratio  # noqa: F401 (public here too)

if TYPE_CHECKING:
    from .scene import Scene, Simulation


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


def initial_state(scene: Scene, model, reduction, system: ContactSystem) -> tuple[np.ndarray, np.ndarray]:
    """(q0, v0) of a scene's ``[initial]``: rest (undeformed) or the stationary state (LCP 28) of its
    ``[rotation]`` and ``[damping]``."""
    ini = scene.initial
    q0 = np.zeros(system.n)
    if ini.state == "stationary":
        from .analysis.stationary import rotor_stationary

        q0 = rotor_stationary(model, reduction, scene.rotation, scene.damping).q
    return q0, uniform_velocity(model, reduction, system, ini.velocity)


def integrator_options(sim: Simulation | Scene, method: str) -> dict:
    """The keyword arguments of ``method``'s integrator from ``[simulation]`` (``sim``, or a scene's)."""
    from .scene import Simulation

    if not isinstance(sim, Simulation):
        sim = sim.simulation
    if method == "rk":
        return {"solver": sim.rk_solver, "rtol": sim.rtol, "atol": sim.atol}
    if method == "penalty":
        return {"solver": sim.stiff_solver, "rtol": sim.rtol, "atol": sim.atol,
                "stiffness": sim.penalty_stiffness or None, "factor": sim.penalty_factor}
    if method == "moreau":
        return {"step": sim.moreau_step or sim.output_dt / 10.0, "theta": sim.moreau_theta}
    return {}


#: event-search samples per run above which :func:`run_scene` warns
SAMPLES_WARN = 2e6
#: event-search samples per run above which :func:`run_scene` refuses: ``exact`` and ``rk`` do
#: 1e4 to 3e4 samples per second (measured: 25 and 355 dofs), so 1e11 is a month or more of
#: computing; far below 1/eps = 4.5e15, where the step would vanish in the round-off of t.
SAMPLES_MAX = 1e11
#: Dense eigenvalue problems (the spectrum of :func:`spectrum`) up to this many dofs: a general (gyroscopic)
#: one; a symmetric one (eigh, 10x cheaper, and what ``exact`` decomposes anyway) up to twice as many.
SPECTRUM_MAX_DOF = 2000
#: a mode whose largest displacement in a contact direction is below this fraction of the largest mode's
#: (mass-normalized shapes) is not seen by the contacts: the event search leaves it out (it keeps terms
#: above events.ZERO = 1e-11 of a row's size, so 1e-12 is on the safe side)
UNSEEN = 1e-12


def spectrum(system: ContactSystem, seen: bool = False) -> np.ndarray:
    """Circular frequencies [rad/s] of the undamped open structure, sqrt|eig(Q, M)|, ascending; with
    ``seen``, of a symmetric structure only the modes that move some contact point in one of its
    directions (normal or tangential: the modes an event row can follow; an axial impact does not see
    the bending modes)."""
    return spectra(system)[1 if seen else 0]


def spectra(system: ContactSystem) -> tuple[np.ndarray, np.ndarray]:
    """(all, seen): :func:`spectrum` without and with ``seen``, from one eigen-decomposition."""
    import scipy.linalg as sla

    if system.n == 0:
        return np.zeros(0), np.zeros(0)
    if system.symmetric:
        w2, Phi = sla.eigh(0.5 * (system.Q + system.Q.T), 0.5 * (system.M + system.M.T))
        w = np.sqrt(np.abs(w2))
        cs = system.model_contacts   # elastic rings' facets too
        if not cs.m:
            return np.sort(w), np.sort(w)
        J = np.hstack([cs.JN] + [cs.JS[k] for k in range(cs.m)])
        reach = np.abs(J.T @ Phi).max(axis=0)
        return np.sort(w), np.sort(w[reach > UNSEEN * reach.max(initial=0.0)])
    lam = sla.eigvals(system.Q, system.M)
    w = np.sort(np.sqrt(np.abs(lam[np.isfinite(lam)])))
    return w, w


def fastest_frequency(system: ContactSystem) -> float:
    """The largest circular frequency [rad/s] of the undamped open structure, sqrt|eig(Q, M)|, for models
    beyond :data:`SPECTRUM_MAX_DOF` (ARPACK on M^-1 Q: a few matrix-vector products)."""
    import scipy.linalg as sla
    from scipy.sparse.linalg import LinearOperator, eigs

    n = system.n
    Mf = sla.cho_factor(0.5 * (system.M + system.M.T))
    op = LinearOperator((n, n), matvec=lambda x: sla.cho_solve(Mf, system.Q @ x), dtype=float)
    lam = eigs(op, k=1, which="LM", return_eigenvectors=False, tol=1e-3)
    return float(np.sqrt(np.abs(lam[0])))


def search_cost(system: ContactSystem, t_end: float, w: np.ndarray | None = None) -> tuple[float, float]:
    """(f_max [Hz], samples): the fastest free mode of the model that the contacts see (all modes of a
    gyroscopic model) and the number of event-search samples it implies over t_end (a step of 1/8 of
    its period, as ``exact`` samples when that mode is excited)."""
    if w is None:
        big = system.n > (2 if system.symmetric else 1) * SPECTRUM_MAX_DOF
        top = fastest_frequency(system) if big else float(np.max(spectra(system)[1], initial=0.0))
    else:
        top = float(np.max(w, initial=0.0))
    return top / (2 * np.pi), t_end * 4.0 * top / np.pi


def output_bytes(system: ContactSystem, t_end: float, output_dt: float) -> float:
    """Bytes of a Result's output arrays: per sample q and v (2 n), gap, normal force, state and two
    tangential components per contact (5 m) and t, 8 bytes each."""
    samples = math.floor(t_end / output_dt) + 1
    return 8.0 * samples * (2 * system.n + 5 * system.contacts.m + 1)


def memory_bytes() -> float | None:
    """Physical memory of this machine (None where the OS does not say)."""
    import os

    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        return None


def check_outputs(system: ContactSystem, t_end: float, output_dt: float, memory: float | None = None) -> None:
    """Refuse output arrays larger than the machine's memory (:func:`output_bytes`)."""
    need = output_bytes(system, t_end, output_dt)
    memory = memory_bytes() if memory is None else memory
    if memory is not None and need > memory:
        raise SceneError("simulation.output_dt", f"t_end / output_dt = {t_end / output_dt:.3g} output samples of "
                         f"{system.n} dofs and {system.contacts.m} contacts need {need / 2**30:.3g} GiB, more than "
                         f"this machine's {memory / 2**30:.3g} GiB; raise simulation.output_dt or shorten "
                         "simulation.t_end")


#: files a run may write into its folder. Refused above FILES_MAX: 1e5 files are 1.4e4 to 5e4 VTU frames
#: (2 to 7 files each: the parts and the .vtm), more than a viewer can step through, each written in 1 to 3 ms
#: (minutes of writing after the run), and past where listing, copying and removing the folder become slow;
#: warned above FILES_WARN. Bytes (an upper bound, see frame_size) are warned above BYTES_WARN and
#: refused beyond the free space of the folder's file system.
FILES_MAX = 100_000
FILES_WARN = 10_000
BYTES_WARN = 2.0**30


def output_size(model, system: ContactSystem, t_end: float, output_dt: float, vtu_every: int,
                n_times: int, sensors: int = 0, bearing_columns: int = 0) -> tuple[int, float]:
    """(files, bytes) a run writes into its folder: result.npz (:func:`output_bytes` and its basis)
    and, with ``vtu_every``, its VTU series (every ``vtu_every``-th output time a frame of
    :func:`nsfem.export.vtu.frame_size`, and the .pvd: 100 bytes a file) of ``n_times`` output times,
    and with ``sensors`` sensors.csv (t and each sensor as a float's repr and a separator: 25 bytes
    at most), and with ``bearing_columns`` force columns bearings.csv (likewise); the plots are a few files
    of 100 kB or less and left out."""
    nbytes = output_bytes(system, t_end, output_dt) + 8.0 * model.n_full * system.n
    files = 1
    for columns in (sensors, bearing_columns):
        if columns:
            files += 1
            nbytes += 25.0 * n_times * (columns + 1)
    if vtu_every:
        from .export.vtu import frame_size

        frames = -(-n_times // vtu_every)
        per_frame, frame_bytes = frame_size(model)
        files += 1 + frames * per_frame
        nbytes += frames * (frame_bytes + 100.0 * per_frame)
    return files, nbytes


def check_output_size(files: int, nbytes: float, free: float | None, vtu_every: int, n_times: int) -> str | None:
    """The warning text when a run's output is large (None when not); raises SceneError when it
    exceeds :data:`FILES_MAX` files or ``free`` bytes (the file system's free space, None: unknown)."""
    what = (f"{files} files (a VTU frame every {vtu_every} of {n_times} output times) and up to "
            f"{nbytes / 1e9:.3g} GB" if vtu_every else f"a results file of up to {nbytes / 1e9:.3g} GB")
    key = "output.vtu_every" if vtu_every else "simulation.output_dt"
    fix = ("raise output.vtu_every or simulation.output_dt, or set output.vtu_every = 0 (nsfem export writes "
           "the series later)" if vtu_every else "raise simulation.output_dt or shorten simulation.t_end")
    if files > FILES_MAX:
        raise SceneError(key, f"this run would write {what}, more than the limit of {FILES_MAX} files; {fix}")
    if free is not None and nbytes > free:
        raise SceneError(key, f"this run would write {what}, more than the {free / 1e9:.3g} GB free there "
                         f"(with the earlier run's files it replaces); {fix}")
    if files > FILES_WARN or nbytes > BYTES_WARN:
        return f"this run writes {what}; {fix} for less"
    return None


def free_bytes(folder) -> float | None:
    """Free bytes on the file system of ``folder`` (or of its nearest existing parent)."""
    import shutil
    from pathlib import Path

    p = Path(folder).absolute()
    while not p.exists() and p.parent != p:
        p = p.parent
    try:
        return float(shutil.disk_usage(p).free)
    except OSError:
        return None


def check_search_cost(system: ContactSystem, t_end: float, method: str, reduction: dict, f_max: float,
                      samples: float) -> str | None:
    """The advice text when an event-driven run needs many search samples (None when few); raises
    when it needs more than :data:`SAMPLES_MAX`. ``reduction``: the reduction's info (method,
    max_frequency_hz of the kept modes)."""
    if samples <= SAMPLES_WARN:
        return None
    kept = reduction.get("max_frequency_hz") or math.inf
    if reduction.get("method", "none") == "none":
        advice = "a reduced model (reduction.method = craig-bampton or modal) runs far faster"
    elif f_max <= 1.01 * kept:  # the highest kept mode sets it
        advice = "fewer kept modes (reduction.modes) or a shorter simulation.t_end lower it"
    else:  # Craig-Bampton: a constraint mode at a contact point, stiffer than every kept mode
        advice = ("its constraint modes at the contact points set it: fewer contact points or a shorter "
                  "simulation.t_end lower it")
    text = (f"the fastest mode of this {system.n}-dof model ({f_max:.4g} Hz) sets the time scale of '{method}' "
            f"wherever the contacts come within reach of its motion: up to about {samples:.2g} event-search "
            f"samples for t_end = {t_end:g} s; {advice}")
    if samples > SAMPLES_MAX:
        raise SceneError("simulation.t_end", f"{text}; more than {SAMPLES_MAX:.0e} samples (a month or more of "
                         "computing) are refused")
    return text


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
    from .analysis.campbell import merge_defective

    from .integrate.configuration import Configuration, Mode

    # the open configuration: its rigid-body coordinates split off (exactly zero roots, not the
    # +-sqrt(eps) omega_max of a defective pair), the rest in first-order form
    cfg = Configuration(system, Mode())
    lam, V = cfg.eig[:2] if cfg.eig is not None else sla.eig(cfg.A[cfg.k:, cfg.k:])
    keep = np.isfinite(lam)
    lam, V = lam[keep], V[:, keep]
    # a root is resolved to sqrt(eps) omega_max at best (a defective one, like the rigid drift
    # of a free structure, splits by that much: 2.8e-3 1/s for a free bar at 0 Hz); split
    # defective roots are merged to their mean, and smaller growth is round-off
    omega_max = float(np.max(np.abs(lam), initial=0.0))
    lam = merge_defective(lam, V, omega_max)
    g = float(np.max(lam.real, initial=0.0))
    return g if g > math.sqrt(np.finfo(float).eps) * omega_max else 0.0


def run_scene(scene: Scene, method: str | None = None, progress: bool | None = False, model=None, reduction=None,
              warn=None, out_dir=None) -> tuple[Result, ContactSystem]:
    """Integrate a scene with its (or the given) method; returns the Result and the system.

    The system, checks and initial state are :func:`prepare_scene`'s; then the integration and, with
    ``warn``, the check of the deflections. A run that stops early raises
    :class:`~nsfem.errors.IntegrationError` whose ``result`` holds it up to there."""
    sim = scene.simulation
    method = method or sim.method
    system, info, q0, v0 = prepare_scene(scene, method, model, reduction, warn, out_dir)
    return integrate_prepared(scene, system, info, method, q0, v0, progress=progress, warn=warn)


def integrate_prepared(scene: Scene, system: ContactSystem, info: dict, method: str, q0, v0,
                       t_end: float | None = None, output_dt: float | None = None, progress: bool | None = False,
                       warn=None, options: dict | None = None) -> tuple[Result, ContactSystem]:
    """Integrate a :func:`prepared <prepare_scene>` scene from (q0, v0) to ``t_end`` (default the scene's
    simulation.t_end), outputs every ``output_dt`` (default the scene's); ``info`` goes into the Result's.
    ``options``: further keyword arguments of the integrator (the periodic orbit's transient: its configurations'
    store, no energy balance)."""
    sim = scene.simulation
    t_end = sim.t_end if t_end is None else t_end
    output_dt = sim.output_dt if output_dt is None else output_dt
    try:
        result = integrate(system, t_end, method, output_dt, q0, v0, progress=progress,
                           **integrator_options(sim, method), **(options or {}))
    except IntegrationError as exc:
        exc.result.info.update(info)
        exc.system = system
        raise
    result.info.update(info)
    if warn is not None:
        from .analysis.deflection import result_warning

        text = result_warning(result, system.info["model"], system.info["reduction"].T)
        if text:
            warn(text)
    return result, system


def prepare_scene(scene: Scene, method: str, model=None, reduction=None, warn=None,
                  out_dir=None) -> tuple[ContactSystem, dict, np.ndarray, np.ndarray]:
    """(system, info, q0, v0) of a scene about to be integrated with ``method``: the checks of a run
    (:func:`run_scene`) before any integration, the ContactSystem of its model and reduction, the
    Result info a run records and the scene's initial state.

    ``warn(text)`` receives the warnings known before integrating (an unreduced model whose fastest mode
    makes the run long, a structure unstable without its contacts). ``out_dir``: the folder the caller
    writes the result and the scene's VTU series into; their size is checked (:func:`check_output_size`).
    Bad sample counts and damping raise SceneError first."""
    from .fem.assemble import build_model
    from .reduce import scene_reduction

    sim = scene.simulation
    from .integrate.base import EXTRA_METHODS

    known = ("exact", "rk", *EXTRA_METHODS)
    if method not in known:
        raise NsfemError(f"simulation.method {method!r} is not available in this version (available: "
                         f"{', '.join(known)})")
    output_times(sim.t_end, sim.output_dt)  # validate before building anything
    if scene.rotation.ramped and method == "exact":
        key = "rotation.speed_table_s" if scene.rotation.speed_table_s else "rotation.ramp_to_hz"
        raise SceneError(key, "the exact method integrates constant speeds (its phases are "
                         "closed-form exponentials); use method = rk, penalty or moreau")
    model = build_model(scene) if model is None else model
    red = scene_reduction(scene.reduction, model) if reduction is None else reduction
    rot, damp = scene.rotation, scene.damping
    system = ContactSystem.from_model(model, red, rot, damp)
    check_outputs(system, sim.t_end, sim.output_dt)
    w, w_seen = spectra(system) if system.n <= (2 if system.symmetric else 1) * SPECTRUM_MAX_DOF else (None, None)
    if w is not None:
        check_damping(damp.rayleigh, w, damp.external,
                      min(seg.rho * seg.area for seg in model.stack.segments))
    if method in ("exact", "rk"):
        f_max, samples = search_cost(system, sim.t_end, w_seen)
        text = check_search_cost(system, sim.t_end, method, red.info, f_max, samples)
        if text and warn is not None:
            warn(text)
    if out_dir is not None:  # after the refusals above: no warning for a run refused anyway
        n_times = output_times(sim.t_end, sim.output_dt).size
        from .analysis.reactions import bearing_columns

        files, nbytes = output_size(model, system, sim.t_end, sim.output_dt, scene.output.vtu_every, n_times,
                                    len(scene.sensors), len(bearing_columns(model)[0]))
        from .outdir import replaced_bytes

        free = free_bytes(out_dir)  # and the room of the earlier run's files this one replaces
        free = free + replaced_bytes(out_dir, "run") if free is not None else None
        text = check_output_size(files, nbytes, free, scene.output.vtu_every, n_times)
        if text and warn is not None:
            warn(text)
    if warn is not None:  # a free axial travel (a thrust bearing left out) is a 0 Hz mode: said once
        from .analysis.rigid_motion import caught_by_contacts, rigid_warning

        text = rigid_warning(model, caught_by_contacts(model))
        if text:
            warn(text)
    q0, v0 = initial_state(scene, model, red, system)
    if warn is not None and method == "penalty" and np.any(system.contacts.mu > 0):
        warn(f"penalty neglects friction, as in the paper: the friction coefficients of "
             f"{int(np.sum(system.contacts.mu > 0))} contacts are ignored (use exact, rk or moreau for friction)")
    if warn is not None and system.n <= GROWTH_CHECK_MAX_DOF:
        rate = growth_rate(system)
        if rate > 0.0:
            warn(f"the structure without contact forces is unstable at {rot.speed_hz:g} Hz"
                 f"{' (the run-up starts there)' if rot.ramped else ''}: its "
                 f"fastest-growing mode grows at {rate:.3g} 1/s (x10 every {math.log(10) / rate:.3g} s); unless the "
                 "contacts or damping hold it, displacements soon exceed the linear model's range")
        if rot.ramped and rate <= 0.0:   # a run-up into an unstable speed: said with the speed and when it comes
            top = rot.max_speed_hz
            end = growth_rate(ContactSystem.from_model(model, red, rot, damp, top))
            if end > 0.0:
                ts, hz = rot.knots
                key = "rotation.ramp_to_hz" if rot.ramp_to_hz is not None else "the speed table's top"
                warn(f"the run-up reaches speeds where the structure without contact forces is unstable: at "
                     f"{key} = {top:g} Hz (reached at t = {float(ts[int(hz.argmax())]):g} s) its "
                     f"fastest-growing mode grows at {end:.3g} 1/s; unless the contacts or damping hold it, "
                     "displacements soon exceed the linear model's range")
    from .contact.tally import system_parts

    info = {"ndof_full": model.n, "reduction": red.info, "title": scene.title,
            "speed_hz": rot.speed_hz, "contacts": list(system.model_contacts.labels),
            "frame": rot.frame, "phase_deg": rot.phase_deg,
            # a run-up: speed_hz stays the initial speed (nsfem.scene.parts.Rotation's profile)
            **rot.record(),
            # the contact parts and, with elastic rings, the rigid contacts' rows: read by nsfem.contact.tally
            "parts": [p.record() for p in system_parts(system)]}
    if system.info.get("contact_index") is not None:
        info["contact_index"] = [int(k) for k in system.info["contact_index"]]
    system.info["sensors"] = scene.sensors
    return system, info, q0, v0


def sensor_signals(result: Result, system: ContactSystem) -> np.ndarray:
    """The signals (len(result.t), sensors) of the sensors ``run_scene`` put on ``system``."""
    from .fem.constraints import dense
    from .sensors import read, speed_table

    sensors = system.info.get("sensors", ())
    if not sensors:
        return np.zeros((result.t.size, 0))
    return read(sensors, system.info["model"], dense(system.info["reduction"].T), result.t, result.q,
                result.info.get("frame", "rotating"), result.info.get("speed_hz", 0.0),
                result.info.get("phase_deg", 0.0), result.info.get("ramp_to_hz"), result.info.get("ramp_s", 0.0),
                speed_table(result.info))
