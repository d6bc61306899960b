"""Command line: a thin shell over the library (design section 5).

``--json`` prints exactly one JSON object on stdout; errors print one line on stderr
and exit non-zero (a traceback only with ``--debug``).
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import time
from typing import NoReturn, Sequence

from . import __version__
from .errors import IntegrationError, NsfemError

EXIT_ERROR = 2
FIELD_NAMES = {"U": "U (axial)", "V": "V (bending x-y)", "W": "W (bending x-z)"}
RIGID_NAMES = {"U": "rigid axial motion (U)", "V": "rigid lateral motion in x-y (V)",
               "W": "rigid lateral motion in x-z (W)"}
#: the scenes shipped in nsfem/scenes, by the name a SCENE argument takes, in a few words (``run --help``)
SHIPPED_SCENES = {
    "default": "the paper's rotating shaft with a through-width delamination (Waltersberger & Wauer)",
    "critical_speed": "20 kg disk on anisotropic damped bearings: unbalance response near the critical speeds",
    "ross_example": "ROSS's example rotor (rotor_example()): two disks, two anisotropic bearings",
    "rub": "Jeffcott rotor rubbing a rigid stator ring with friction (full annular rub)",
    "crack": "Jeffcott rotor with a breathing transverse crack under its weight (2x response)",
    "retainer_drop": "spinning rotor dropping onto its retainer bearings (two rings, friction, impacts)",
    "stepped_rotor": "stepped compressor rotor, three impellers, plain journal bearings tabled against speed",
    "runup": "Jeffcott rotor run up through its critical speed, rubbing an elastic seal on the way",
}


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, no usage dump
        raise NsfemError(f"{self.prog}: {message}")


def _scene_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", nargs="?", default=None, help="scene TOML file, or the name of a shipped scene "
                   "(default: the shipped scene `default`; `nsfem run --help` lists them)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene key, e.g. delamination.0.friction=0.3 (repeatable)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")


def parser() -> argparse.ArgumentParser:
    top = _Parser(prog="nsfem", description="Non-smooth dynamics of rotating beam stacks with frictional contacts.")
    top.add_argument("--version", action="version", version=f"nsfem {__version__}")
    sub = top.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("run", help="transient simulation of a scene",
                       formatter_class=argparse.RawDescriptionHelpFormatter, epilog="shipped scenes (give the name as SCENE, e.g. `nsfem run rub`):\n" + "\n".join(
                           f"  {name:15s} {what}" for name, what in SHIPPED_SCENES.items()))
    _scene_args(p)
    p.add_argument("--method", choices=("exact", "rk", "penalty", "moreau"),
                   help="integrator (default: the scene's simulation.method): exact (event-driven, closed form), rk "
                   "(event-driven, Runge-Kutta), penalty (stiff springs), moreau (time stepping)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: the scene's output.dir): result.npz, the "
                   "PNG plots, nsfem.pvd for ParaView with its VTU frames in DIR/vtu/")

    p = sub.add_parser("modes", help="natural frequencies of the non-rotating structure; damped modes at a speed")
    _scene_args(p)
    p.add_argument("--contact", choices=("open", "closed"), default="open",
                   help="contact points open (free sub-beams) or closed (gap held at zero, frictionless)")
    p.add_argument("--count", type=int, default=10, help="number of frequencies (default 10)")
    p.add_argument("--speed", type=float, metavar="HZ", help="damped modes of the rotor spinning at HZ in the scene's "
                   "frame (damped frequencies, damping ratios, log decrements, whirl); without it, the undamped "
                   "modes at rest")
    p.add_argument("--png", metavar="FILE", help="with --speed: write the whirl orbits of the first modes along "
                   "the shaft to this PNG")

    p = sub.add_parser("campbell", help="frequencies against speed, critical speeds, gravity resonances")
    _scene_args(p)
    p.add_argument("--speeds", metavar="START:STOP:N", help="speeds in Hz (default: 61 values from 0 to 1.23 x "
                   "the second divergence (rotating frame) or forward critical (inertial) speed, at least 2 x "
                   "rotation.speed_hz; with speed-dependent bearings, 61 over their tables)")
    p.add_argument("--count", type=int, default=6, help="frequencies per speed and resonances listed (default 6)")
    p.add_argument("--png", metavar="FILE", help="write the Campbell diagram to this file only (without --png: "
                   "to <output.dir>/campbell.png when the scene's output.plots lists campbell)")

    p = sub.add_parser("response", help="steady unbalance response against speed by a harmonic solve (linear scenes)")
    _scene_args(p)
    p.add_argument("--speeds", metavar="START:STOP:N", required=True,
                   help="speeds in Hz, START > 0 (e.g. 10:45:1000)")
    p.add_argument("--png", metavar="FILE", help="write the Bode plot (left) and the polar plot (right) to this "
                   "one file")

    # (the numbers of nsfem.periodic.scene, not imported here: the parser is built by every command; test_cli
    # checks that they agree)
    p = sub.add_parser("periodic", help="periodic orbit by shooting on the exact flow: Floquet multipliers, "
                       "stability, amplitudes")
    _scene_args(p)
    p.add_argument("--multiple", type=int, default=1, metavar="K", help="the orbit's period in forcing periods "
                   "(one forcing period is 1 / rotation.speed_hz): 1 (default) a synchronous orbit, K > 1 a "
                   "subharmonic of order K")
    p.add_argument("--continue", dest="continuation", metavar="KEY=LOW:HIGH", help="follow the orbit's branch "
                   "over a numeric scene key by pseudo-arclength, e.g. rotation.speed_hz=20:30, from the orbit at the "
                   "scene's value (or at the nearer end): stability and bifurcations along it; writes branch.json, "
                   "branch.npz and branch.png")
    p.add_argument("--steps", type=int, default=100, metavar="N", help="with --continue: at most N continuation "
                   "steps in each direction (default 100, at most 10000)")
    p.add_argument("--step", type=float, metavar="DP", help="with --continue: the first step, in the key's unit "
                   "(default a fiftieth of the range; the steps then adapt)")
    p.add_argument("--workers", type=int, metavar="N", help="with --continue: run the branch's independent pieces "
                   "(the two sides of a start inside the range, the period-doubled branches) on a local Dask "
                   "cluster of N worker processes (at most one per side, 4 per core; default and 1: in this process)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="with --continue: run them on a running Dask scheduler, "
                   "e.g. tcp://127.0.0.1:8786")
    p.add_argument("--start", metavar="FILE", help="start the shooting from a saved state: a run's result.npz "
                   "(its last output) or an orbit.npz of nsfem periodic (default: the last state of a transient "
                   "from the scene's initial state)")
    p.add_argument("--transient", type=int, metavar="N", help="orbit periods integrated with the exact method "
                   "before the shooting (default 10; 0: shoot from the scene's initial state; not with --start)")
    p.add_argument("--section", choices=("quiet", "start"), help="where the shooting's Poincare section lies after "
                   "the transient: quiet (default) the phase of its last period farthest from events (the map is "
                   "smooth and better conditioned there), start its end (t0 = 0); not with --start or --transient 0")
    p.add_argument("--tol", type=float, default=1e-9, help="the shooting's tolerance on |phi_T(x0) - x0| / |x0| "
                   "(default 1e-9, from 1e-14 to 0.001)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: <output.dir>/periodic): periodic.json, "
                   "orbit.npz, orbit.png and floquet.png (unless output.plots is empty), nsfem.pvd with the VTU "
                   "frames of one period in DIR/vtu/ (unless output.vtu_every = 0)")

    p = sub.add_parser("stationary", help="stationary contact state (LCP 28)")
    _scene_args(p)

    p = sub.add_parser("sweep", help="one run per parameter value (--set KEY=START:STOP:N), on a Dask cluster")
    _scene_args(p)
    p.add_argument("--method", choices=("exact", "rk", "penalty", "moreau"),
                   help="integrator of every run (default: the scene's simulation.method)")
    p.add_argument("--workers", type=int, help="local worker processes (default: one per core; never more than the runs, at "
                   "most 4 per core)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="use a running Dask scheduler, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--out", metavar="DIR", help="sweep folder (default: <output.dir>/sweep-<swept keys>); a rerun "
                   "resumes it")
    p.add_argument("--steady", choices=("transient", "periodic"), default="transient", help="the steady state each "
                   "value records: transient (default: a run, the 1x fit over its last half) or periodic (the "
                   "periodic orbit by shooting on the exact flow, the 1x fit over its period, plus its stability: "
                   "columns stable, largest_multiplier, events_per_period, converged)")

    p = sub.add_parser("fit", help="estimate scene keys from measured sensor signals (--vary KEY=LOW:HIGH)")
    _scene_args(p)
    p.add_argument("--data", metavar="CSV", required=True, help="measured signals: a column t [s] and one per sensor")
    p.add_argument("--vary", action="append", default=[], metavar="KEY=LOW:HIGH",
                   help="a scene key to estimate and its range (repeatable)")
    p.add_argument("--misfit", choices=("time", "spectrum"), default="time",
                   help="compare the samples (default) or their amplitude spectra")
    p.add_argument("--workers", type=int, help="local worker processes (default: one per core, at most 4 per core)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="use a running Dask scheduler, e.g. tcp://127.0.0.1:8786")
    p.add_argument("--out", metavar="DIR", help="output folder (default: <output.dir>/fit-<varied keys>)")
    p.add_argument("--no-refine", dest="refine", action="store_false",
                   help="skip the refined runs at the estimate (the intervals then leave out the model's "
                        "discretization error)")

    p = sub.add_parser("export", help="re-export a saved result as a VTU/PVD series (ParaView)")
    p.add_argument("result", help="a results file (result.npz) written by nsfem run")
    p.add_argument("--vtu", metavar="DIR", required=True, help="folder to write DIR/nsfem.pvd into (open it in "
                   "ParaView), with its VTU frames in DIR/vtu/")
    p.add_argument("--every", type=int, metavar="N", help="every N-th output time (default: the run's "
                   "output.vtu_every, else 1)")
    p.add_argument("--frame", choices=("rotating", "inertial"), help="coordinates of the series (default: the "
                   "frame the run was computed in); inertial turns a rotating-frame run about x by Omega t + phase")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")

    p = sub.add_parser("render", help="off-screen picture of a saved result")
    p.add_argument("result", help="a results file (result.npz) written by nsfem run")
    p.add_argument("--time", type=float, metavar="T", help="output time to draw, in s (the nearest one "
                   "saved; default: the last)")
    p.add_argument("--png", metavar="FILE", help="picture to write (default: render.png next to RESULT)")
    p.add_argument("--exaggeration", type=float, metavar="X",
                   help="displacement scale (default: 10 %% of the stack's length over the largest displacement)")
    p.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    return top


def printable(text: str) -> str:
    r"""``text`` with control characters (terminal escape codes from a scene's title, say) shown
    as escapes, line breaks kept: what a user wrote is echoed, never executed by the terminal.

    >>> printable("shaft \x1b[31mred\x1b[0m\nnext")
    'shaft \\x1b[31mred\\x1b[0m\nnext'
    """
    return "".join(c if c == "\n" or c.isprintable() else repr(c)[1:-1] for c in text)


@contextlib.contextmanager
def sigterm_as_interrupt():
    """A scheduler's SIGTERM ends a command like Ctrl-C (what was computed is kept), within the block
    (in the main thread; elsewhere signal handlers cannot be set)."""
    def terminate(signum, frame):
        raise KeyboardInterrupt

    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


class _Stderr:
    """sys.stderr that drops what it cannot write (a reader that went away: ``nsfem run 2>&1 | head``):
    a warning or a progress line must never cost the run its results file."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text: str) -> int:
        try:
            return self.stream.write(text)
        except (BrokenPipeError, ValueError):  # a closed pipe, a closed file
            return len(text)

    def flush(self) -> None:
        try:
            self.stream.flush()
        except (BrokenPipeError, ValueError):
            pass

    def __getattr__(self, name):
        return getattr(self.stream, name)


def _scene(args, command: str, overrides: Sequence[str] | None = None):
    """The command's scene (``args.scene`` with ``overrides``, default ``args.overrides``); its notes, the
    defaults that shape its model without the scene saying so, printed once on stderr as
    ``nsfem <command>: note: ...`` (a JSON payload lists them as ``notes``)."""
    from .scene import load_scene

    scene = load_scene(args.scene, args.overrides if overrides is None else overrides)
    for note in scene.notes:
        print(printable(f"nsfem {command}: note: {note}"), file=sys.stderr)
    return scene


def _emit(args, payload: dict, text: str) -> None:
    if args.json:
        from .jsonio import as_text, dumps

        sys.stdout.write(dumps(payload, as_text) + "\n")
    else:
        print(printable(text))


def cmd_modes(args) -> int:
    from .analysis.modes import natural_frequencies
    from .fem.assemble import build_model
    from .reduce import scene_reduction

    if args.count < 1:
        raise NsfemError(f"--count must be a positive integer, got {args.count}")
    if args.speed is None and args.png is not None:
        raise NsfemError("--png draws the whirl orbits of damped modes: give --speed HZ too")
    if args.speed is not None:
        return _damped_modes(args)
    scene = _scene(args, "modes")
    t0 = time.perf_counter()
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    modes = natural_frequencies(model, args.contact, args.count, red)
    wall = time.perf_counter() - t0
    from .analysis.rigid_motion import caught_by_contacts, free_motions, rigid_warning

    rigid = free_motions(model)
    warning = rigid_warning(model, caught_by_contacts(model), rigid)
    if warning:
        print(f"nsfem modes: warning: {warning}", file=sys.stderr)
    payload = {"title": scene.title, **modes.to_json(), "reduction": red.info,
               "elements": model.mesh.elements, "wall_s": wall, "rigid_motions": rigid,
               "warnings": [warning] if warning else [], "notes": list(scene.notes)}
    lines = [scene.title, f"contact {modes.contact}: {modes.ndof} dofs ({red.name}; full model "
             f"{modes.ndof_full}), {model.mesh.elements} elements",
             "  mode  frequency [Hz]  field"]
    # 4 decimals for Hz-sized frequencies; 5 significant digits for tiny or huge ones (a
    # nondimensional E = rho = 1 shaft's first frequency is 8.2e-3, which .4f would show as 0.0082)
    # a rigid-body mode (exactly 0 Hz from the kinematics, nsfem.fem.rigid) is named as the motion it is
    lines += [f"  {k + 1:4d}  {f:14.4f}  {RIGID_NAMES[fld] if f == 0.0 else FIELD_NAMES[fld]}" if 0.1 <= f < 1e9
              or f == 0.0 else f"  {k + 1:4d}  {f:14.5g}  {FIELD_NAMES[fld]}"
              for k, (f, fld) in enumerate(zip(modes.frequencies_hz, modes.fields))]
    _emit(args, payload, "\n".join(lines))
    return 0


def _damped_modes(args) -> int:
    """``nsfem modes --speed HZ``: the damped modes at the speed (:func:`nsfem.analysis.damped.damped_modes`)."""
    import math

    from .analysis.damped import scene_damped_modes
    from .fem.assemble import build_model
    from .reduce import scene_reduction

    if not (math.isfinite(args.speed) and args.speed >= 0):
        raise NsfemError(f"--speed must be a finite speed >= 0 Hz, got {args.speed:g}")
    _check_png(args.png)
    if args.png:
        from .atomic import check_file
        from pathlib import Path

        check_file(Path(args.png), "--png")
    scene = _scene(args, "modes")
    from .scene import check_speed

    check_speed(args.speed, scene.stack, "--speed")
    t0 = time.perf_counter()
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    modes = scene_damped_modes(scene, model, args.speed, args.count, red, args.contact)
    from .analysis.rigid_motion import caught_by_contacts, free_motions, rigid_warning

    rigid = free_motions(model)
    warnings = [w for w in [rigid_warning(model, caught_by_contacts(model), rigid)] if w]
    top = red.info.get("max_frequency_hz")
    if top and len(modes.frequencies_hz) and modes.frequencies_hz[-1] > 0.5 * top:
        warnings.append(f"modes above {0.5 * top:.4g} Hz (half the reduction's highest kept mode, {top:.4g} Hz) are "
                        "not converged in the reduction; raise reduction.modes or use reduction.method = none")
    unstable = [k + 1 for k, z in enumerate(modes.damping_ratios) if z < 0]
    if unstable:
        warnings.append(f"mode(s) {', '.join(map(str, unstable))} grow (negative damping ratio): the rotor is unstable "
                        f"at {args.speed:g} Hz")
    for w in warnings:
        print(printable(f"nsfem modes: warning: {w}"), file=sys.stderr)
    outputs = []
    if args.png:
        from .plot.modes import whirl_orbits_plot

        outputs.append(str(whirl_orbits_plot(args.png, modes, scene.title)))
    payload = {"title": scene.title, **modes.to_json(), "contact": args.contact, "ndof": red.ndof,
               "ndof_full": model.n, "reduction": red.info, "elements": model.mesh.elements,
               "wall_s": time.perf_counter() - t0, "rigid_motions": rigid, "outputs": outputs, "warnings": warnings,
               "notes": list(scene.notes)}
    lines = [scene.title, f"damped modes at {args.speed:g} Hz ({modes.frame} frame), contact {args.contact}: "
             f"{red.ndof} dofs ({red.name}; full model {model.n})",
             "  mode  frequency [Hz]  damping ratio  log dec  whirl"]
    lines += [f"  {k + 1:4d}  {f:14.5g}  {z:13.4g}  {d:7.4g}  {w}" for k, (f, z, d, w) in
              enumerate(zip(modes.frequencies_hz, modes.damping_ratios, modes.log_decrements, modes.whirl))]
    if outputs:
        lines.append("wrote " + ", ".join(outputs))
    _emit(args, payload, "\n".join(lines))
    return 0


def cmd_sweep(args) -> int:
    """One run per value of the swept keys; the table, JSON and resonance curve in the sweep folder."""
    from .sweep import SweepInterrupted, run_sweep, table_lines

    if args.workers is not None and args.scheduler:
        raise NsfemError("--workers cannot be combined with --scheduler (the cluster has its own workers)")

    def progress(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    from .sweep import parse_ranges

    notes = _scene(args, "sweep", parse_ranges(args.overrides)[0]).notes   # the scene with its fixed --set
    interrupted = False
    try:
        with sigterm_as_interrupt():   # finished rows kept
            res = run_sweep(args.scene, args.overrides, args.out, method=args.method, workers=args.workers,
                            scheduler=args.scheduler, progress=progress, steady=args.steady)
    except SweepInterrupted as exc:
        res, interrupted = exc.result, True
    payload = {**res.to_json(), "notes": list(notes)}
    keys = [a.key for a in res.axes]
    shown = [r for r in res.runs if r is not None]
    lines = [f"{len(shown)} runs in the folder ({res.info['executed']} run now, {res.info['resumed']} already done) "
             f"in {res.info['wall_s']:.3g} s on {res.info['workers']} workers; {res.info['models_built']} model(s) "
             "built", *table_lines(keys, shown)]
    lines.append(f"wrote {res.table}" + (f", {res.figure}" if res.figure else ""))
    _emit(args, payload, "\n".join(lines))
    if interrupted:
        print(f"nsfem: interrupted: the finished runs are in {res.out_dir}; run the same command again to "
              "resume", file=sys.stderr)
        return 130
    failed = res.failed
    if failed:
        first = failed[0]
        print(f"nsfem: error: {len(failed)} of {len(res.current)} runs failed (first: "
              + ", ".join(f"{k}={first[k]}" for k in keys) + f": {' '.join(first['error'].split())}); see {res.table}",
              file=sys.stderr)
        return EXIT_ERROR
    return 0


def cmd_fit(args) -> int:
    """The estimates with their 95 % intervals; fit.json, evaluations.csv and the plots in the output folder."""
    from .fit import FitInterrupted, fit

    def progress(line: str) -> None:
        print(printable(line), file=sys.stderr, flush=True)

    notes = _scene(args, "fit").notes   # the scene with its fixed --set
    interrupted = False
    try:
        with sigterm_as_interrupt():   # the runs so far kept; fit() refuses --workers with --scheduler
            res = fit(args.scene, args.data, args.vary, misfit=args.misfit, workers=args.workers,
                      scheduler=args.scheduler, overrides=args.overrides, out_dir=args.out, progress=progress,
                      refine=args.refine)
    except FitInterrupted as exc:
        res, interrupted = exc.result, True
    payload = {**res.to_json(), "notes": list(notes)}
    width = max(len(k) for k in res.keys)
    lines = [f"  {'key':{width}s}  {'estimate':>12s}  {'95 % interval':>27s}  note"]
    for key, p in payload["parameters"].items():
        lo, hi = p["interval"]
        interval = f"[{lo:.6g}, {hi:.6g}]" if lo is not None and hi is not None else "-"
        shift = p["discretization_shift"]
        notes = ((["at bound"] if p["at_bound"] else [])
                 + ([f"discretization shift {shift:+.3g}"] if shift is not None else []) + ([] if p["identified"] else ["not identified"])
                 + (["ambiguous: a second minimum"] if p["ambiguous"] else []))
        est = f"{p['estimate']:12.6g}" if p["estimate"] is not None else f"{'-':>12s}"
        lines.append(f"  {key:{width}s}  {est}  {interval:>27s}  {', '.join(notes)}")
    ident = payload["identifiability"]
    for d in (ident or {}).get("directions", []):
        why = ("the data do not see it" if d["reason"] == "rank" else "its interval exceeds the ranges")
        lines.append(f"  not identifiable: a combination of {', '.join(d['keys'])} ({why})")
    for alt in payload["alternatives"]:
        if alt["indistinguishable"]:
            lines.append(f"  not identifiable: {', '.join(f'{k}={v:.6g}' for k, v in alt['parameters'].items())} "
                         f"explains the data as well (misfit {100 * alt['misfit']:.4g} %, F-test p = "
                         f"{alt['p_value']:.3g}); the intervals of {', '.join(alt['differs'])} are not confident")
    misfit = payload["misfit"]
    lines.append(f"misfit {100 * misfit:.4g} % (relative RMS, {res.kind}), {payload['runs']} runs in "
                 f"{payload['wall_s']:.3g} s on {res.info.get('workers', 0)} workers" if misfit is not None
                 else f"no successful run; {payload['runs']} runs")
    lines.append("wrote " + ", ".join(res.outputs))
    _emit(args, payload, "\n".join(lines))
    if interrupted:
        print(f"nsfem: interrupted: the runs so far are in {res.out_dir}", file=sys.stderr)
        return 130
    return 0


def cmd_campbell(args) -> int:
    from pathlib import Path

    from .analysis.campbell import campbell_report, parse_speeds
    from .fem.assemble import build_model
    from .plot.campbell import report_plot
    from .reduce import scene_reduction

    if args.count < 1:
        raise NsfemError(f"--count must be a positive integer, got {args.count}")
    speeds = parse_speeds(args.speeds) if args.speeds else None
    _check_png(args.png)
    scene = _scene(args, "campbell")
    from .atomic import check_file

    # --png names the one file written; without it, output.dir/campbell.png when output.plots lists campbell
    if args.png:
        targets, what = [Path(args.png)], "--png"
    else:
        targets = [scene.output.dir / "campbell.png"] if "campbell" in scene.output.plots else []
        what = "output.dir"
    for t in targets:
        check_file(t, what)
    if speeds is not None:
        from .scene import check_speed

        check_speed(float(speeds.max()), scene.stack, "--speeds")
    t0 = time.perf_counter()
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    rep = campbell_report(scene, model, speeds, args.count, red)
    from .analysis.campbell import supercritical_warning
    from .analysis.whirl import unstable_warning

    inertial = rep["frame"] == "inertial"
    speed = scene.rotation.speed_hz
    warning = (unstable_warning(speed, rep["instability_hz"]["open"], rep["instability_bands_hz"]["open"])
               if inertial else supercritical_warning(speed, rep["instability_hz"]["open"]))
    if warning:
        print(f"nsfem campbell: warning: {warning}", file=sys.stderr)
    for text in rep.get("warnings", []):
        print(f"nsfem campbell: warning: {text}", file=sys.stderr)

    outputs = [str(report_plot(t, rep, scene.title, speed)) for t in targets]
    for key in ("_results", "_bands", "_critical"):
        rep.pop(key)
    payload = {"title": scene.title, **rep, "reduction": red.info, "wall_s": time.perf_counter() - t0,
               "outputs": outputs, "notes": list(scene.notes)}
    def fmt(items) -> str:
        return ", ".join(items) or "none"

    def rows(head: str, what) -> list[str]:
        """``head`` with its open list, and the closed one below it: a rotor without contacts has one set of
        branches, so its "closed" row would repeat the open one."""
        out = [f"{head} open: " + fmt(what("open"))]
        if model.stack.contacts:
            out.append(" " * (len(head) - 1) + "closed: " + fmt(what("closed")))
        return out

    lines = [scene.title, f"{rep['ndof']} dofs ({red.name}; full model {model.n}), speeds "
             f"{rep['speeds_hz'][0]:g} to {rep['speeds_hz'][-1]:g} Hz, {rep['frame']} frame"]
    if inertial:
        lines += ["critical speeds [Hz] (1x crossings of the damped branches; b backward, f forward, p planar, "
                  "b/p: branch backward, planar at that speed; log dec; damping ratio zeta)",
                  *rows(" " * 24, lambda c: map(_crossing, rep["critical_speeds"][c])),
                  "undamped critical speeds open: " + fmt(f"{x:.3f} ({w[0]})" for x, w in zip(
                      rep["undamped_critical_speeds_hz"]["open"], rep["undamped_critical_whirl"]["open"])),
                  *rows("instability onsets [Hz] ", lambda c: (f"{x:.3f}" for x in rep["instability_hz"][c]))]
    else:
        lines += [*rows("gravity resonances [Hz] ", lambda c: (f"{x:.3f}" for x in rep["gravity_resonances_hz"][c])),
                  *rows("divergence speeds [Hz]  ", lambda c: (f"{x:.3f}" for x in rep["instability_hz"][c]))]
    lines += [f"wrote {o}" for o in outputs]
    _emit(args, payload, "\n".join(lines))
    return 0


def _crossing(c: dict) -> str:
    """A damped critical speed for the text output: speed, branch label (/ the crossing's own whirl where it
    differs), log decrement to three significant digits (as the figure's legend; 0, never -0, for a round-off-sized
    one) and damping ratio to two decimals (0.00, never -0.00)."""
    whirl = c["whirl"][0] + ("" if c["whirl_at_speed"] == c["whirl"] else "/" + c["whirl_at_speed"][0])
    ratio = f"{c['damping_ratio'] + 0.0:.2f}".replace("-0.00", "0.00")
    dec = f"log dec {c['log_decrement'] + 0.0:.3g}" if "log_decrement" in c else None
    return f"{c['speed_hz']:.3f} ({whirl}, {dec + ', ' if dec else ''}zeta {ratio})"


def cmd_stationary(args) -> int:
    from .analysis.stationary import scene_stationary

    scene = _scene(args, "stationary")
    st = scene_stationary(scene)
    info = st.info
    payload = {"title": scene.title, **st.to_json(), "speed_hz": info["speed_hz"], "loads": info["loads"],
               "ndof_full": info["ndof_full"], "ndof": info["ndof"], "reduction": info["reduction"],
               "wall_s": st.wall_s}
    if "note" in info:
        payload["note"] = info["note"]
    # the existence caveat is said once: a warning on stderr when it is one, else on the LCP line
    if not st.existence["guaranteed"]:
        print(f"nsfem stationary: warning: {st.existence['reason']}", file=sys.stderr)
    for w in info["warnings"]:
        print(f"nsfem stationary: warning: {w}", file=sys.stderr)
    payload["warnings"] = info["warnings"]
    payload["notes"] = list(scene.notes)
    rot = scene.rotation
    if rot.ramped:   # one speed: the ramp's start, said
        ramp = (f"a run-up scene ({rot.describe()}): the stationary "
                f"state at rotation.speed_hz = {rot.speed_hz:g} Hz, the ramp's start")
        payload["notes"].append(ramp)
        print(f"nsfem stationary: note: {ramp}", file=sys.stderr)
    loads = " + ".join(info["loads"]) or "none"
    lines = [scene.title, f"speed {info['speed_hz']:g} Hz, constant loads: {loads}; {info['ndof']} dofs "
             f"({info['reduction']['method']}; full model {info['ndof_full']})",
             f"LCP (28): {st.lcp.x.size} unknowns, {st.lcp.pivots} pivots, residual {st.lcp.residual:.1e}"
             + (f"; {st.existence['reason']}" if st.existence["guaranteed"] else "")]
    if "note" in info:
        lines.append(f"note: {info['note']}")
    lines += _stationary_parts(st.parts)
    grouped = {r["key"] for r in st.parts["rings"] + st.parts["cracks"]}
    rows = [k for k, c in enumerate(st.contacts.labels) if c.rpartition(".")[0] not in grouped]
    if rows:
        lines.append("  contact              x [m]      gap [m]   normal [N]  tangential [N]  state")
        for k in rows:
            lines.append(f"  {st.contacts.labels[k]:18s} {st.contacts.x[k]:7.4f}  {st.gap[k]:11.4e}  "
                         f"{st.normal_force[k]:11.4e}  {payload['tangential_force_N'][k]:14.4e}  {st.state[k]}")
    if not st.contacts.m:
        lines.append("no contacts: the stationary state is Q^-1 f0")
    _emit(args, payload, "\n".join(lines))
    return 0


def _angle(deg) -> str:
    return "-" if deg is None else f"{deg:.2f}"


def _shown(values, scale: float) -> list[float]:
    """``values`` with round-off (below 1e-9 of ``scale``, the table's largest size) shown as 0."""
    return [0.0 if abs(v) <= 1e-9 * scale else v for v in values]


def _stationary_parts(parts: dict) -> list[str]:
    """The text lines of a stationary state's parts (:func:`nsfem.analysis.stationary.rotor_parts`)."""
    frame = parts["frame"]
    force = max([abs(v) for v in parts["load_N"] + parts.get("deflection_load_N", [])]
                + [r["magnitude_N"] for r in parts["bearings"] + parts["supports"]])
    top = parts["max_deflection"]
    parts = {**parts, "load_N": _shown(parts["load_N"], force),
             "bearings": [{**b, "reaction_N": _shown(b["reaction_N"], force)} for b in parts["bearings"]],
             "supports": [{**b, "reaction_N": _shown(b["reaction_N"], force)} for b in parts["supports"]],
             "disks": [{**d, "deflection_m": _shown(d["deflection_m"], top["magnitude_m"])} for d in parts["disks"]],
             "max_deflection": {**top, "deflection_m": _shown(top["deflection_m"], top["magnitude_m"])}}
    fy, fz = parts["load_N"]
    out = [f"constant load {fy:.6g} N along y, {fz:.6g} N along z ({frame} frame); forces on the shaft:"
           if parts["bearings"] or parts["supports"] else f"constant load {fy:.6g} N along y, {fz:.6g} N along z "
           f"({frame} frame)"]
    dy, dz = _shown(parts.get("deflection_load_N", [0.0, 0.0]), force)
    if dy or dz:   # the reactions balance it too
        out.insert(1, f"  and on the deflected rotor, from the speed (centrifugal Omega^2 m u, damping drag): "
                      f"{dy:.6g} N along y, {dz:.6g} N along z")
    if parts["bearings"] or parts["supports"]:
        out.append("  reaction             x [m]       y [N]        z [N]      |F| [N]")
        for b in parts["bearings"]:
            out.append(f"  {b['label']:18s} {b['x_m']:7.4f}  {b['reaction_N'][0]:11.5g}  {b['reaction_N'][1]:11.5g}  "
                       f"{b['magnitude_N']:11.5g}")
        for i, s in enumerate(parts["supports"]):
            out.append(f"  {'support ' + '+'.join(s['fix']):18s} {s['x_m']:7.4f}  {s['reaction_N'][0]:11.5g}  "
                       f"{s['reaction_N'][1]:11.5g}  {s['magnitude_N']:11.5g}")
    if parts["disks"]:
        out.append("  deflection           x [m]       y [m]        z [m]      |u| [m]")
        for d in parts["disks"]:
            out.append(f"  {d['label']:18s} {d['x_m']:7.4f}  {d['deflection_m'][0]:11.4e}  "
                       f"{d['deflection_m'][1]:11.4e}  {d['magnitude_m']:11.4e}")
    top = parts["max_deflection"]
    out.append(f"largest shaft deflection {top['magnitude_m']:.4e} m at x = {top['x_m']:.4f} m "
               f"(y {top['deflection_m'][0]:.4e}, z {top['deflection_m'][1]:.4e} m)")
    if parts["rings"]:
        out.append("  ring           x [m]  force on ring [N]  angle [deg]  whirl radius [m]  angle [deg]  "
                   "min gap [m]  state")
        for r in parts["rings"]:
            state = r["state"] + (f" on facet{'s' * (len(r['facets']) > 1)} {', '.join(map(str, r['facets']))}"
                                  if r["facets"] else "")
            out.append(f"  {r['key']:12s} {r['x_m']:7.4f}  {r['force_N']:17.5g}  {_angle(r['angle_deg']):>11s}  "
                       f"{r['radius_m']:16.4e}  {_angle(r['whirl_angle_deg']):>11s}  {r['min_clearance_m']:11.4e}  "
                       f"{state}")
    if parts["cracks"]:
        out.append("  crack          x [m]  opening [m]  face force [N]  state")
        for c in parts["cracks"]:
            out.append(f"  {c['key']:12s} {c['x_m']:7.4f}  {c['opening_m']:11.4e}  {c['face_force_N']:14.5g}  "
                       f"{c['state']}")
    return out


def cmd_run(args) -> int:
    from pathlib import Path

    from .outdir import claim

    scene = _scene(args, "run")
    out_dir = Path(args.out or scene.output.dir)
    what = "--out" if args.out else "output.dir"
    files = _run_files(scene)
    _check_run_targets(out_dir, scene.output, scene.sensors, what, files["series"], bool(scene.stack.bearings),
                       scene.rotation.ramped)
    with claim(out_dir, "run", files, what) as written:
        return _run(args, scene, out_dir, written)


def _run_files(scene) -> dict[str, list[str]]:
    """The names ``nsfem run`` may write for ``scene`` (:func:`nsfem.outdir.claim`)."""
    from .export.vtu import series_files
    from .integrate.base import output_times
    from .simulate import FILES_MAX

    out = scene.output
    run = ["result.npz"] + [f"{n}.png" for n in out.plots]
    if scene.sensors:
        run += ["sensors.csv", "sensors.png"] + (["runup.png"] if scene.rotation.ramped else [])
    if scene.stack.bearings:
        run += ["bearings.csv", "bearings.png"]
    sim = scene.simulation
    n_times = output_times(sim.t_end, sim.output_dt).size
    # more than FILES_MAX in 2 files a frame: refused by run_scene's size check before any write
    few = out.vtu_every and 2 * -(-n_times // out.vtu_every) + 2 <= FILES_MAX
    return {"run": run, "series": series_files(n_times, out.vtu_every) if few else []}


def _run(args, scene, out_dir, written: set) -> int:
    """``nsfem run`` in its claimed folder ``out_dir`` (``written``: the files written there so far)."""
    from pathlib import Path

    from .analysis.campbell import supercritical_warning
    from .atomic import signals_deferred
    from .fem.constraints import dense
    from .integrate import core as event_core
    from .scene import default_scene_path
    from .simulate import run_scene

    method = args.method or scene.simulation.method
    t0 = time.perf_counter()
    text_path = Path(scene.path) if scene.path else default_scene_path()
    scene_text = text_path.read_text() if text_path.exists() else ""
    if args.overrides:
        scene_text += "\n# overrides: " + " ".join(args.overrides) + "\n"
    warnings: list[str] = []

    def warn(text):
        warnings.append(text)
        print(f"nsfem run: warning: {text}", file=sys.stderr)

    try:
        with sigterm_as_interrupt():   # results kept
            result, system = run_scene(scene, method, progress=True, warn=warn, out_dir=out_dir)  # on stderr after 5 s
    except IntegrationError as exc:  # keep what was computed, then report the error
        res, sysm = exc.result, exc.system
        with signals_deferred():  # the results file is finished, not cut short
            path = res.save(out_dir / "result.npz", scene_text, dense(sysm.info["reduction"].T),
                            sysm.model_contacts.x, scene.record())
        raise NsfemError(f"{exc} (the run up to t = {res.t_end:g} s is in {path})") from exc
    red = system.info["reduction"]
    top = red.info.get("max_frequency_hz")
    if scene.rotation.speed_hz and top and scene.rotation.frame == "rotating":
        from .analysis.campbell import divergence_speeds
        from .fem.rotating import rotor_operators

        div = divergence_speeds(rotor_operators(system.info["model"], red.T))
        warning = supercritical_warning(scene.rotation.speed_hz, div[div <= 0.5 * top])
        if warning:
            warn(warning)
    path = out_dir / "result.npz"
    outputs, extra = [str(path)], {}
    try:
        with signals_deferred():  # the results file is finished, not cut short
            result.save(path, scene_text, dense(red.T), system.model_contacts.x, scene.record())
        if result.completed:
            from .plot.results import write_plots

            outputs += [str(p) for p in write_plots(result, system, out_dir, scene.output.plots, warn=warn,
                                                        listed=scene.plots_listed)]
            if "campbell" in scene.output.plots:
                from .plot.campbell import scene_campbell

                try:
                    outputs.append(str(scene_campbell(out_dir / "campbell.png", scene, system.info["model"], red,
                                                              warn=warn)))
                except NsfemError as exc:  # a diagram this scene cannot have (e.g. spun in the wrong frame)
                    warn(f"plot 'campbell' skipped: {exc}")
        if scene.sensors:
            from .sensors import write_csv
            from .simulate import sensor_signals

            values = sensor_signals(result, system)
            extra["sensors"] = str(write_csv(out_dir / "sensors.csv", result.t, scene.sensors, values))
            outputs.append(extra["sensors"])
            if scene.output.plots and result.t.size > 1:
                from .plot.sensors import sensors_plot, stator_rings

                outputs.append(str(sensors_plot(out_dir / "sensors.png", result.t, values, scene.sensors,
                                                scene.rotation.speed_hz, scene.title, stator_rings(system),
                                                scene.rotation.speed_at if scene.rotation.ramped else None)))
            if scene.rotation.ramped and result.t.size > 1:   # a run-up: amplitude against speed, steady beside
                from .plot.runup import scene_runup_plot

                outputs.append(str(scene_runup_plot(out_dir / "runup.png", scene, result, system, values)))
        if scene.stack.bearings:
            outputs += _bearing_outputs(result, system, scene, out_dir, extra)
        if result.completed and scene.output.vtu_every:   # last: the longest to write (Ctrl-C there keeps the rest)
            from .export.vtu import write_series

            outputs.append(str(write_series(result, system, out_dir, every=scene.output.vtu_every)))
    except KeyboardInterrupt:  # what was written stays valid; say so, and still print the JSON
        from .outdir import MANIFEST

        done = sorted(str(p) for p in written if Path(p).name != MANIFEST and Path(p).suffix not in (".vtu", ".vtm"))
        outputs[:] = [str(path)] * (str(path) in done) + [p for p in done if p != str(path)]
        interrupted = "nsfem: interrupted while writing the outputs; written: " + (", ".join(outputs) or "nothing")
        if str(out_dir / "nsfem.pvd") in outputs:
            interrupted += " (nsfem.pvd indexes the VTU frames written)"
    else:
        interrupted = ("" if result.completed else
                       f"nsfem: interrupted at t = {result.t_end:g} s: {path} holds the run up to there")
    summary = result.summary()
    payload = {"title": scene.title, **summary, **extra, "wall_s": time.perf_counter() - t0,
               "integration_wall_s": result.wall_s, "outputs": outputs,
               "energy_terms": result.energy, "speed_hz": scene.rotation.speed_hz, "warnings": warnings,
               "interrupted": bool(interrupted), "core": event_core.name(), "notes": list(scene.notes)}
    if scene.rotation.ramped:   # a run-up: speed_hz is its start
        payload.update(scene.rotation.record())
    lines = [scene.title, f"{method}: {result.t_end:g} s simulated in {result.wall_s:.3g} s "
             f"({system.n} dofs; full model {summary['ndof_full']}), {summary['events']} events, "
             f"{summary['impacts']} impacts"
             + (f" ({summary['shared_impacts']} on more than one part at once)" if summary["shared_impacts"] else "")
             + f"; event core: {event_core.name()}",
             f"gap {summary['min_gap_m']:.4e} .. {summary['max_gap_m']:.4e} m, closed "
             f"{100 * summary['closed_fraction']:.2f} % of the time, {_force_words(summary)} at one contact point, "
             f"energy residual {summary['energy']:.1e}" if summary["min_gap_m"] is not None
             else "no contacts",
             *_part_lines(summary["parts"]),
             "wrote " + ", ".join(outputs)]
    if not result.completed:
        lines.append(f"interrupted at t = {result.t_end:g} s: the results file holds the run up to there")
    with signals_deferred():  # the report is printed whole
        _emit(args, payload, "\n".join(lines))
    if interrupted:
        print(printable(interrupted), file=sys.stderr)
        return 130
    return 0


def _bearing_outputs(result, system, scene, out_dir, extra: dict) -> list[str]:
    """bearings.csv (the force of each bearing on the shaft over time, N, inertial frame) and, when the scene
    draws plots, bearings.png; ``extra["bearings"]`` names the CSV (the run JSON's ``bearings``)."""
    from .analysis.reactions import bearing_columns, bearing_force_histories, bearing_names, write_bearings_csv
    from .fem.constraints import dense

    model = system.info["model"]
    info = result.info
    forces = bearing_force_histories(model, dense(system.info["reduction"].T), result.t, result.q, result.v,
                                     info.get("frame", "rotating"), info.get("speed_hz", 0.0),
                                     info.get("phase_deg", 0.0))
    columns, index = bearing_columns(model)
    extra["bearings"] = str(write_bearings_csv(out_dir / "bearings.csv", result.t, columns, index, forces))
    written = [extra["bearings"]]
    if scene.output.plots and result.t.size > 1:
        from .plot.bearings import bearings_plot

        written.append(str(bearings_plot(out_dir / "bearings.png", result.t, forces, bearing_names(model), index,
                                         scene.rotation.speed_hz, scene.title)))
    return written


def _force_words(summary: dict) -> str:
    """The run's largest contact force and impulse in words: an impact-only run has no sustained force."""
    force = (f"max normal force {summary['max_normal_force_N']:.4g} N" if summary["max_normal_force_N"] > 0
             else "no sustained normal force")
    return force + (f", largest impulse {summary['max_impulse_Ns']:.3g} N s" if summary["impacts"] else "")


def _part_lines(parts: list[dict]) -> list[str]:
    """One line per contact part of the run summary (:func:`nsfem.contact.tally.tally`'s numbers)."""
    lines = []
    for p in parts:
        what = {"ring": "facet", "crack": "front point"}.get(p["kind"], "contact point") + "s" * (p["contacts"] != 1)
        force = (f"max normal force {p['max_normal_force_N']:.4g} N (resultant"
                 + (f" at {p['force_angle_deg']:.0f} deg" if p.get("force_angle_deg") is not None else "")
                 + (f"; {p['max_point_force_N']:.4g} N at one point)" if p["contacts"] > 1 else ")")
                 if p["max_normal_force_N"] > 0 else "no sustained normal force")
        impacts = (f"{p['impacts']} impacts (largest impulse {p['max_impulse_Ns']:.3g} N s)" if p["impacts"]
                   else "no impacts")
        gap = "" if p["min_gap_m"] is None else f", min gap {p['min_gap_m']:.4e} m"
        lines.append(f"  {p['name']} ({p['kind']}, {p['contacts']} {what}): {impacts}, {force}{gap}, closed "
                     f"{100 * p['closed_fraction']:.2f} % of the time")
    return lines


def _check_png(png: str | None) -> None:
    """``--png`` names a PNG picture: any other name (the results file, a scene, data) is a slip
    that would overwrite that file with a picture."""
    from pathlib import Path

    if png is not None and Path(png).suffix.lower() != ".png" and not Path(png).is_dir():  # a folder: its own line
        raise NsfemError(f"--png: {png} does not end in .png; give the picture a name ending in .png (a results "
                         "file, scene or data named there would be replaced by it)")


def _check_run_targets(out_dir, output, sensors, what: str, frames=(), bearings: bool = False,
                       ramp: bool = False) -> None:
    """Refuse, before the run, an output folder or file that cannot be written (``output``: the
    scene's :class:`~nsfem.scene.Output`, ``sensors`` its sensors, ``frames`` the series' names,
    ``bearings``: the scene has bearings, whose forces go to bearings.csv; ``ramp``: a run-up, whose
    sensors go to runup.png too)."""
    from .atomic import check_file, check_folder

    check_folder(out_dir, what)
    names = ["result.npz"] + [f"{n}.png" for n in output.plots]
    if output.vtu_every:
        names.append("nsfem.pvd")
        _check_frames_folder(out_dir, what, frames)
    if sensors:
        names += ["sensors.csv", "sensors.png"] + (["runup.png"] if ramp else [])
    if bearings:
        names += ["bearings.csv", "bearings.png"]
    for name in names:
        check_file(out_dir / name, what)


def _check_frames_folder(out_dir, what: str, frames=()) -> None:
    """The subfolder a VTU series' frames go into (:data:`nsfem.export.vtu.SUBFOLDER`) is a folder or can be
    one: a file of that name is refused, as is a folder in it named like one of ``frames`` (the series'
    names, :func:`nsfem.export.vtu.series_files`), where a frame file goes (the folder itself is checked
    by the caller; nothing is written)."""
    import os

    from .export.vtu import SUBFOLDER

    sub = out_dir / SUBFOLDER
    if sub.is_symlink() and not sub.exists():
        raise NsfemError(f"{what}: {sub} is a link to {os.readlink(sub)}, which does not exist (nsfem writes the VTU "
                         f"frames of nsfem.pvd into {SUBFOLDER}/); create that folder, remove the link or choose "
                         "another folder")
    if sub.exists() and not sub.is_dir():
        raise NsfemError(f"{what}: {sub} is a file, not a folder (nsfem writes the VTU frames of nsfem.pvd into "
                         f"{SUBFOLDER}/); move it away or choose another folder")
    names = {n for n in frames if n.startswith(f"{SUBFOLDER}/")}
    if names and sub.is_dir():   # through a link too (frames kept on another disk): the writes go there
        with os.scandir(sub) as entries:
            folders = sorted(e.name for e in entries if f"{SUBFOLDER}/{e.name}" in names
                             and e.is_dir(follow_symlinks=False))
        if folders:
            raise NsfemError(f"{what}: {sub / folders[0]} is a folder, where nsfem writes a VTU frame of nsfem.pvd; "
                             "move it away or choose another folder")


def _saved(path_text: str, command: str):
    """(Result, extra arrays, model, scene) of a results file, the model rebuilt from its stored
    scene; every inconsistency of the file with that model is a one-line error."""
    import hashlib
    from pathlib import Path

    import numpy as np

    from .fem.assemble import build_model
    from .result import Result, check_times
    from .scene import HIGH_LEVEL, LOW_LEVEL, SceneError, scene_from_tree

    path = Path(path_text)
    if path.is_dir():
        raise NsfemError(f"nsfem {command}: {path} is a folder; give its result.npz")
    if not path.is_file():
        raise NsfemError(f"nsfem {command}: {path} does not exist")
    try:
        res, meta, extra = Result.load(path)
        tree = meta["scene_tree"]
    except Exception:  # noqa: BLE001 - any unreadable file gets the same message
        raise NsfemError(f"nsfem {command}: {path} is not an nsfem results file (the result.npz that nsfem run "
                         "writes)") from None
    # the resolved tree (every default filled in, overrides applied) holds one of the two forms;
    # the other is empty
    form = HIGH_LEVEL if any(tree.get(k) for k in LOW_LEVEL) else LOW_LEVEL
    tree = {k: v for k, v in tree.items() if k not in form}
    mesh = dict(tree.get("mesh") or {})
    digest = mesh.pop("sha256", None)
    if mesh.get("file"):
        f = Path(mesh["file"])
        if not f.is_file():
            raise NsfemError(f"nsfem {command}: the mesh file {f} of the run that wrote {path} is missing")
        if digest is not None and hashlib.sha256(f.read_bytes()).hexdigest() != digest:
            raise NsfemError(f"nsfem {command}: the mesh file {f} has changed since the run that wrote {path}")
        tree["mesh"] = mesh
    try:
        t_end = float(meta["t_end"])
    except (KeyError, TypeError, ValueError):
        raise NsfemError(f"nsfem {command}: {path} has no valid t_end in its meta (a damaged or edited file)") from None
    check_times(res.t, t_end, f"nsfem {command}: {path}")
    try:
        scene = scene_from_tree(tree)
    except SceneError as exc:
        raise NsfemError(f"nsfem {command}: the scene stored in {path} is not valid: {exc}") from None
    model = build_model(scene)
    n, k = res.q.shape if res.q.ndim == 2 else (-1, -1)
    m = len(model.stack.contacts)
    want = {"basis": (extra["basis"].shape, (model.n_full, n)), "t": (res.t.shape, (k,)),
            "v": (res.v.shape, (n, k)), "gap": (res.gap.shape, (m, k)), "state": (res.state.shape, (m, k)),
            "normal_force": (res.normal_force.shape, (m, k)), "contact_x": (extra["contact_x"].shape, (m,))}
    bad = [f"{name} is {got}, expected {exp}" for name, (got, exp) in want.items() if tuple(got) != exp]
    if n < 0 or bad:
        raise NsfemError(f"nsfem {command}: {path} does not match the model of its own scene ("
                         + ("q is not a matrix" if n < 0 else "; ".join(bad)) + ")")
    finite = np.all(np.isfinite(res.q), axis=0) & np.isfinite(res.t)
    if not np.all(finite):
        first = int(np.argmin(finite))
        raise NsfemError(f"nsfem {command}: {path} holds non-finite displacements from output {first} on "
                         f"(t = {res.t[first]:g} s): the run it comes from diverged")
    return res, extra, model, scene


def cmd_render(args) -> int:
    """Off-screen picture of the deformed stack at one output time."""
    from pathlib import Path

    import math

    from .export.render import render

    if args.exaggeration is not None and not (math.isfinite(args.exaggeration) and args.exaggeration > 0):
        raise NsfemError(f"nsfem render: --exaggeration must be a finite positive number, got {args.exaggeration}")
    from .atomic import check_file

    _check_png(args.png)
    res, extra, model, _ = _saved(args.result, "render")  # a folder or a missing file: one line first
    png = Path(args.png) if args.png else Path(args.result).resolve().with_name("render.png")
    check_file(png, "--png")
    if png.resolve().parent == Path(args.result).resolve().parent:  # into the run's folder: one of its files
        from .outdir import claim

        with claim(png.parent, "render", {"run": [png.name]}, "--png"):
            path = render(res, model, extra["basis"], png, time=args.time, exaggeration=args.exaggeration)
    else:
        path = render(res, model, extra["basis"], png, time=args.time, exaggeration=args.exaggeration)
    print(f"wrote {path}")
    return 0


def cmd_export(args) -> int:
    """Re-export a saved results file as a VTU/PVD series (ParaView)."""
    from pathlib import Path

    from .atomic import check_folder
    from .export.vtu import SUBFOLDER, frame_size, series_files, series_frame, write_series
    from .outdir import claim, replaced_bytes
    from .simulate import FILES_MAX, free_bytes

    res, extra, model, scene = _saved(args.result, "export")
    every = args.every if args.every is not None else scene.output.vtu_every or 1
    if every < 1:
        raise NsfemError(f"--every must be a positive integer, got {every}")
    rot = scene.rotation   # the run's frame, speed and phase, as run_scene records them
    res.info = {"frame": rot.frame, "speed_hz": rot.speed_hz, "phase_deg": rot.phase_deg, **res.info}
    try:
        frame, _ = series_frame(res, args.frame)
    except NsfemError as exc:
        raise NsfemError(f"--frame: {str(exc).removeprefix('export: ')}") from None
    out = Path(args.vtu)
    check_folder(out, "--vtu")
    _check_frames_folder(out, "--vtu")
    frames = -(-res.t.size // every)
    per_frame, frame_bytes = frame_size(model)
    files, nbytes, free = 1 + frames * per_frame, frames * frame_bytes, free_bytes(out)
    free = free + replaced_bytes(out, "export") if free is not None else None  # the series it replaces too
    what = f"{files} files ({frames} of the {res.t.size} output times) and up to {nbytes / 1e9:.3g} GB"
    if files > FILES_MAX:
        raise NsfemError(f"--every: {what} exceed the limit of {FILES_MAX} files; raise --every")
    if free is not None and nbytes > free:
        raise NsfemError(f"--every: {what} exceed the {free / 1e9:.3g} GB free in {out} (with the series it "
                         "replaces); raise --every")
    names = series_files(res.t.size, every)
    _check_frames_folder(out, "--vtu", names)
    with claim(out, "export", {"series": names}, "--vtu"):
        try:
            pvd = write_series(res, (model, extra["basis"]), out, every=every, frame=frame, phase_deg=rot.phase_deg)
        except KeyboardInterrupt:
            print(printable(f"nsfem: interrupted: {out / 'nsfem.pvd'} indexes the VTU frames written so far"),
                  file=sys.stderr)
            return 130
    print(printable(f"wrote {pvd} ({frames} times, {frame} frame; the frames in {out / SUBFOLDER})"))
    return 0


def cmd_response(args) -> int:
    from pathlib import Path

    from .analysis.campbell import parse_speeds
    from .analysis.response import check_linear, response_report
    from .atomic import check_file
    from .fem.assemble import build_model
    from .reduce import scene_reduction
    from .scene import check_speed

    import numpy as np

    speeds = parse_speeds(args.speeds)
    if not speeds[0] > 0:
        raise NsfemError(f"--speeds {args.speeds!r}: START must be above 0 Hz (at rest an unbalance has no force, "
                         "no 1x response)")
    _check_png(args.png)
    scene = _scene(args, "response")
    check_linear(scene.stack)
    if not scene.sensors:
        raise NsfemError("response: the scene has no [[sensor]]: add one where the response is read")
    check_speed(float(speeds.max()), scene.stack, "--speeds")
    if args.png:
        check_file(Path(args.png), "--png")
    t0 = time.perf_counter()
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    rep = response_report(scene, model, speeds, red)
    rep.pop("_response")
    for text in rep["warnings"]:
        print(printable(f"nsfem response: warning: {text}"), file=sys.stderr)
    outputs = []
    if args.png:
        from .plot.response import plot_response

        outputs.append(str(plot_response(args.png, rep, scene.title, scene.rotation.speed_hz)))
    payload = {"title": scene.title, **rep, "reduction": red.info, "wall_s": time.perf_counter() - t0,
               "outputs": outputs, "notes": list(scene.notes)}
    lines = [scene.title, f"{rep['ndof']} dofs ({red.name}; full model {model.n}), {speeds.size} speeds "
             f"{speeds[0]:g} to {speeds[-1]:g} Hz, {rep['frame']} frame, harmonic solve"]
    for name, v in rep["sensors"].items():
        k = int(np.argmax(v["amplitude_m"]))
        lines.append(f"  {name}: largest 1x amplitude {v['amplitude_m'][k]:.4e} m at {speeds[k]:.6g} Hz "
                     f"(phase lag {round(v['phase_deg'][k], 1) % 360.0:.1f} deg)"
                     + (" where the structure is unstable: no steady state" if rep["unstable"][k] else ""))
    for p in rep["peaks"]:
        sm = "" if p["separation_margin"] is None else f", separation margin {p['separation_margin']:.1f} %"
        lines.append(f"  peak {p['sensor']}: {p['speed_hz']:.6g} Hz, {p['amplitude_m']:.4e} m, amplification "
                     f"factor {p['amplification_factor']:.3g} (half-power band {p['band_hz'][0]:.6g}-"
                     f"{p['band_hz'][1]:.6g} Hz){sm}"
                     + (" [structure unstable there: no steady state, not a resonance]" if p["unstable"] else ""))
    if not rep["peaks"]:
        lines.append("  no peak with its half-power band inside the speeds")
    if rep["unstable_ranges_hz"]:
        lines.append("  structure unstable (no steady state) " + ", ".join(
            f"{a:.6g}-{b:.6g} Hz" if b is not None else f"from {a:.6g} Hz on" for a, b in rep["unstable_ranges_hz"]))
    lines += [f"wrote {o}" for o in outputs]
    _emit(args, payload, "\n".join(lines))
    return 0


def cmd_periodic(args) -> int:
    """``nsfem periodic``: the scene's periodic orbit (:func:`nsfem.periodic.scene.orbit_of_scene`); its JSON,
    orbit.npz, figures and VTU series of one period in the output folder."""
    from pathlib import Path

    from .outdir import claim
    from .periodic.scene import check_continuation, check_options, check_scene, parse_continuation

    check_options(args.multiple, args.transient, args.tol, None)
    if args.start is not None and args.transient:
        raise NsfemError("--transient with --start: the saved state is the shooting's starting guess already; "
                         "give one of them")
    if args.section is not None and (args.start is not None or args.transient == 0 or args.continuation is not None):
        why = ("the saved state's time is the section" if args.start is not None else
               "there is no transient to choose it from" if args.transient == 0 else
               "a branch chooses and moves its sections itself")
        raise NsfemError(f"--section with {'--start' if args.start is not None else '--transient 0' if args.transient == 0 else '--continue'}: {why}")
    continuation = parse_continuation(args.continuation) if args.continuation is not None else None
    scene = _scene(args, "periodic")
    check_scene(scene)
    if continuation is not None:
        from .periodic.scene_branch import SPEED_KEY, check_branch_options, check_key, check_speeds
        from .scene import load_scene

        key, low, high = continuation
        check_branch_options(args.steps, args.step, low, high)
        from .periodic.branch_cluster import check_cluster_options

        check_cluster_options(None, args.workers, args.scheduler)
        check_key(key)
        check_continuation(scene, key, low, high, lambda extra: load_scene(args.scene, [*args.overrides, *extra]))
        if key == SPEED_KEY:
            check_speeds(scene, *sorted((low, high)))
    else:
        from .periodic.scene_branch import STEPS

        if args.steps != STEPS or args.step is not None:
            raise NsfemError(f"{'--steps' if args.steps != STEPS else '--step'} is an option of --continue "
                             "KEY=LOW:HIGH (the continuation's steps); a single orbit has none")
        if args.workers is not None or args.scheduler is not None:
            raise NsfemError(f"{'--workers' if args.workers is not None else '--scheduler'} is an option of "
                             "--continue KEY=LOW:HIGH (its sides and doubled branches run as tasks); a single orbit "
                             "is one computation")
    if args.start is not None:
        from .periodic.scene import _saved_state

        _saved_state(args.start)   # a missing or foreign file: one line before anything is built
    out_dir = Path(args.out) if args.out else scene.output.dir / "periodic"
    what = "--out" if args.out else "output.dir"
    if continuation is not None:
        names = list(BRANCH_FILES) + (["branch.png"] if scene.output.plots else [])
        _check_periodic_targets(out_dir, {"periodic": names, "series": []}, what)
        with claim(out_dir, "branch", {"branch": names}, what, inputs=[args.start] if args.start else ()):
            return _periodic_branch(args, scene, continuation, out_dir)
    files = _periodic_files(scene, args.multiple)
    _check_periodic_targets(out_dir, files, what)
    with claim(out_dir, "periodic", files, what, inputs=[args.start] if args.start else ()):
        return _periodic(args, scene, out_dir)


#: the files of nsfem periodic besides the VTU series
PERIODIC_FILES = ("periodic.json", "orbit.npz")
PERIODIC_PLOTS = ("orbit.png", "floquet.png")


def _periodic_files(scene, multiple: int) -> dict[str, list[str]]:
    """The names ``nsfem periodic`` may write for ``scene`` (:func:`nsfem.outdir.claim`)."""
    from .export.vtu import series_files
    from .periodic.scene import orbit_samples, vtu_every

    names = list(PERIODIC_FILES) + (list(PERIODIC_PLOTS) if scene.output.plots else [])
    series = []
    if scene.output.vtu_every:
        samples = orbit_samples(scene, multiple)
        series = series_files(samples + 1, vtu_every(samples, multiple))
    return {"periodic": names, "series": series}


def _check_periodic_targets(out_dir, files: dict, what: str) -> None:
    """Refuse, before any computation, an output folder or file of ``nsfem periodic`` that cannot be written."""
    from .atomic import check_file, check_folder

    check_folder(out_dir, what)
    for name in files["periodic"]:
        check_file(out_dir / name, what)
    if files["series"]:
        check_file(out_dir / "nsfem.pvd", what)
        _check_frames_folder(out_dir, what, files["series"])


def _periodic(args, scene, out_dir) -> int:
    """``nsfem periodic`` in its claimed folder ``out_dir``."""
    from .periodic.output import write_orbit
    from .periodic.scene import orbit_of_scene

    t0 = time.perf_counter()
    warnings: list[str] = []

    def warn(text: str) -> None:
        warnings.append(text)
        print(printable(f"nsfem periodic: warning: {text}"), file=sys.stderr)

    so = orbit_of_scene(scene, args.multiple, args.start, args.transient, args.tol, warn=warn, progress=True,
                        section=args.section or "quiet")
    for note in so.notes:
        print(printable(f"nsfem periodic: note: {note}"), file=sys.stderr)
    o = so.orbit
    payload = {"title": scene.title, **so.to_json(), "speed_hz": scene.rotation.speed_hz,
               "frame": scene.rotation.frame, "warnings": warnings, "notes": list(scene.notes) + so.notes}
    outputs = [str(out_dir / "periodic.json")] + [str(p) for p in write_orbit(so, scene, out_dir, payload)]
    from .atomic import write_text_atomic
    from .jsonio import as_text, dumps

    payload.update(outputs=outputs, wall_s=time.perf_counter() - t0)   # periodic.json last: it lists the others
    write_text_atomic(out_dir / "periodic.json", dumps(payload, as_text) + "\n")
    import numpy as np

    mu = np.asarray(o.multipliers, dtype=complex)
    impacts = sum(1 for e in so.contact_sequence if e["impact"])
    lines = [scene.title,
             f"orbit of period {o.period_s:.6g} s ({so.multiple} x the forcing period 1 / {scene.rotation.speed_hz:g} "
             f"Hz, {scene.rotation.frame} frame; {so.system.n} dofs), section t0 = {o.t0:.6g} s, from {so.start}",
             f"shooting {'converged' if o.converged else 'NOT converged'} in {o.iterations} iterations, residual "
             f"{o.residual:.2e}",
             f"events per period {o.events_per_period} ({impacts} impacts)"
             + (": " + ", ".join(f"{'+'.join(e['kinds'])} {','.join(e['contacts'])} at {1e3 * e['t_s']:.4g} ms"
                                 for e in so.contact_sequence[:6]) + (" ..." if len(so.contact_sequence) > 6 else "")
                if so.contact_sequence else ""),
             f"Floquet multipliers ({mu.size}, largest modulus first):"]
    lines += [f"  {z.real:+.6f} {z.imag:+.6f}i   |mu| {abs(z):.6f}" for z in mu[:6]]
    if mu.size > 6:
        lines.append(f"  ... {mu.size - 6} more, |mu| <= {abs(mu[6]):.6f}")
    lines.append(f"verdict: {so.verdict()}")
    if so.amplitudes:
        lines.append("amplitudes (half the peak-to-peak over the period): " + ", ".join(
            f"{k} {v:.4e} m" for k, v in so.amplitudes.items()))
    lines.append("wrote " + ", ".join(outputs))
    _emit(args, payload, "\n".join(lines))
    return 0


#: the files of nsfem periodic --continue besides branch.png
BRANCH_FILES = ("branch.json", "branch.npz")
#: branch.json is rewritten at most this often [s] while a branch is followed (each point's flows take longer)
BRANCH_WRITE_EVERY = 1.0


def _periodic_branch(args, scene, continuation, out_dir) -> int:
    """``nsfem periodic --continue KEY=LOW:HIGH`` in its claimed folder ``out_dir``: the branch
    (:func:`nsfem.periodic.scene_branch.branch_of_scene`), branch.json rewritten as points come (an interrupt
    leaves the points so far), then branch.npz, branch.png and branch.json."""
    from .atomic import write_text_atomic
    from .jsonio import as_text, dumps
    from .periodic.output import save_branch
    from .periodic.scene_branch import branch_of_scene
    from .scene import load_scene

    key, low, high = continuation
    t0 = time.perf_counter()
    warnings: list[str] = []
    last = [0.0]

    def warn(text: str) -> None:
        warnings.append(text)
        print(printable(f"nsfem periodic: warning: {text}"), file=sys.stderr)

    def progress(text: str) -> None:
        print(printable(f"nsfem periodic: {text}"), file=sys.stderr)

    def payload_of(sb) -> dict:
        return {"title": scene.title, **sb.to_json(), "frame": scene.rotation.frame,
                "start": sb.start.start if sb.start is not None else None, "warnings": warnings,
                "notes": list(scene.notes), "wall_s": time.perf_counter() - t0}

    def on_point(sb) -> None:   # the points so far, at most once a BRANCH_WRITE_EVERY
        if time.perf_counter() - last[0] >= BRANCH_WRITE_EVERY:
            write_text_atomic(out_dir / "branch.json", dumps({**payload_of(sb), "stop": "running"}, as_text) + "\n")
            last[0] = time.perf_counter()

    sb = branch_of_scene(scene, key, low, high, multiple=args.multiple, start=args.start,
                         transient_periods=args.transient, tol=args.tol, steps=args.steps, step=args.step,
                         load=lambda extra: load_scene(args.scene, [*args.overrides, *extra]), warn=warn,
                         progress=progress, on_point=on_point, workers=args.workers, scheduler=args.scheduler)
    payload = payload_of(sb)
    outputs = [str(out_dir / "branch.json"), str(save_branch(out_dir / "branch.npz", sb, payload))]
    if scene.output.plots and sb.points:
        from .plot.periodic import branch_plot

        outputs.append(str(branch_plot(out_dir / "branch.png", key, sb.points, [s.name for s in sb.sensors],
                                       sb.bifurcations, sb.doubled, scene.title)))
    payload.update(outputs=outputs, wall_s=time.perf_counter() - t0)   # branch.json last: it lists the others
    write_text_atomic(out_dir / "branch.json", dumps(payload, as_text) + "\n")
    _emit(args, payload, "\n".join(branch_lines(scene.title, sb, outputs)))
    if sb.interrupted:
        print("nsfem: interrupted (the points so far are written)", file=sys.stderr)
        return 130
    return 0


def branch_lines(title: str, sb, outputs) -> list[str]:
    """The text report of a branch: a table of its points (value, period, stability, largest |mu|, events,
    amplitudes in µm), its bifurcations and the doubled branches, why each side stopped, the files."""
    names = [s.name for s in sb.sensors]
    lines = [title, f"branch of period-{sb.multiple} orbits over {sb.key} from {sb.start_value:g} "
             f"(the scene's value {sb.scene_value:g}) towards {sb.low:g} and {sb.high:g}: {len(sb.points)} points"]
    head = f"{sb.key:>20} {'period [s]':>11} {'stable':>8} {'max|mu|':>9} {'events':>6}" + "".join(
        f" {n + ' [um]':>14}" for n in names)
    lines.append(head)

    def row(p: dict) -> str:
        return (f"{p['value']:>20.10g} {p['period_s']:>11.6g} {('yes' if p['stable'] else 'NO'):>8} "
                f"{p['largest_multiplier']:>9.6f} {p['events_per_period']:>6d}"
                + "".join(f" {1e6 * p['amplitudes'][n]:>14.6g}" for n in names)
                + ("" if p["converged"] else "  (not converged)"))

    lines += [row(p) for p in sb.points]
    if sb.bifurcations:
        lines.append("bifurcations: " + ", ".join(f"{b['kind']} at {sb.key} = {b['value']:.10g}"
                                                  for b in sb.bifurcations))
    else:
        lines.append("bifurcations: none found")
    for d in sb.doubled:
        lines.append(f"period-{d['multiple']} (doubled) branch: {len(d['points'])} points")
        lines += [row(p) for p in d["points"]]
    lines += [f"towards {s['towards']:g}: {s['reason']}" for s in sb.sides]
    if sb.interrupted:
        lines.append("interrupted: the points so far are written")
    lines.append("wrote " + ", ".join(outputs))
    return lines


COMMANDS = {"modes": cmd_modes, "campbell": cmd_campbell, "stationary": cmd_stationary, "run": cmd_run,
            "sweep": cmd_sweep, "response": cmd_response, "fit": cmd_fit, "export": cmd_export, "render": cmd_render,
            "periodic": cmd_periodic}


#: the variables by which a user sets the BLAS threads (OpenBLAS reads the first it finds; MKL its own)
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread() -> None:
    """One BLAS thread for a command whose environment sets none: nsfem's dense products and eigenproblems have
    tens to hundreds of rows, where a second thread costs more than it gives (the shipped scene's reduction:
    0.03 s with one thread, 0.26-0.33 s with two on two busy cores; the integrators run with one anyway, see
    :mod:`nsfem.integrate.blas`). Only before NumPy is loaded (OpenBLAS reads the variable once, at load): a
    fresh command, not a call from Python."""
    import os

    if "numpy" not in sys.modules and not any(v in os.environ for v in BLAS_THREAD_VARIABLES):
        os.environ["OPENBLAS_NUM_THREADS"] = "1"


#: container objects a command allocates (less those freed) between two passes of Python's cyclic garbage
#: collector over the young ones (Python's default: 700)
YOUNG_OBJECTS_PER_COLLECTION = 7000


def command() -> NoReturn:
    """The ``nsfem`` command (``python -m nsfem`` and the installed script): :func:`main` on ``sys.argv``, then
    exit with its status.

    The cyclic garbage collector is tuned for a command, whose objects are mostly the imports' (they live to
    the end) or freed by reference counting: it passes over the young objects every
    :data:`YOUNG_OBJECTS_PER_COLLECTION` allocations instead of every 700 (the shipped run: 29 instead of 300
    passes, and no full pass over everything imported instead of two: 0.09 -> 0.05 s; the memory it may hold
    back is a few thousand objects more). Before the interpreter is torn down, every object still alive is moved
    out of its reach (``gc.freeze``): the collections of the shutdown would otherwise walk all of NumPy's,
    SciPy's and matplotlib's objects once more, 0.12 s of the run, to free memory the process hands back to the
    system anyway. Exit handlers, flushing and closing run as usual."""
    import gc

    gc.set_threshold(YOUNG_OBJECTS_PER_COLLECTION, *gc.get_threshold()[1:])
    status = main()
    gc.freeze()
    sys.exit(status)


def main(argv: Sequence[str] | None = None) -> int:
    one_blas_thread()
    stderr = sys.stderr
    sys.stderr = _Stderr(stderr)
    try:
        return _main(argv)
    finally:
        sys.stderr = stderr


def _main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    try:
        args = parser().parse_args(argv)
        with sigterm_as_interrupt():  # whatever the command is doing: its outputs stay valid
            return COMMANDS[args.command](args)
    except NsfemError as exc:
        if debug:
            raise
        print(printable(f"nsfem: error: {' '.join(str(exc).splitlines())}"), file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        print("nsfem: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # e.g. piped into head: not an error of ours
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # a write that failed after the checks (disk full, a target that changed)
        if debug:
            raise
        where = f" {exc.filename}" if getattr(exc, "filename", None) else ""
        print(f"nsfem: error: cannot write{where}: {exc.strerror or exc}", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":  # pragma: no cover
    command()
