"""Cost of the ``exact`` method against model size (dofs) and against the number of contact points.

Two series on the shipped scene (``nsfem/scenes/default.toml``, 21 Hz, from rest):

(a) dofs: modal and Craig-Bampton reductions with 8, 16, 32 and 64 modes of the shipped 40-element
    mesh (355 dofs unreduced), then unreduced models (``reduction.method = "none"``) of 12 to 80
    elements (715 dofs, ``--quick``) or 12 to 320 elements (about 2900 dofs);
(b) contact points: ``delamination.0.contact_points`` = 3, 9, 21 (``--quick``), 51, 101, each with
    Craig-Bampton 16 and modal 16 on a 120-element mesh (the mesh needs an interval per point).

Per case: the reduced size n, the simulated time (chosen per case so that a run takes seconds),
the set-up time (build_model, the reduction, ContactSystem and the initial state; timed apart from
the integration), the wall time of ``integrate(..., "exact")`` (best of 3 runs under 5 s), wall time per simulated second,
events, configurations met, wall time per event (all of it: sampling included), and the fastest rate w_max of the free configuration (the largest
|eigenvalue| of its state matrix, from the same ``Configuration`` the integrator builds, whose
build time is reported as ``config_s``; above ``RATE_CONFIG_MAX`` dofs, where that eigen-
decomposition is itself minutes, an undamped estimate sqrt(max eig(Q, M)) instead). Each case runs
in its own process with a time budget (60 s quick, 600 s full); a case over budget is killed and
recorded as ``timeout`` (its set-up and rate, when they finished, are kept, and the time its
integration ran over t_end is a lower bound of its wall time per simulated second).

The event search itself, per case: its wall time in the run (``search_s``, ``first_event``), the fine
samples it took (``samples``) and the row-term-samples it evaluated (``term_samples``: rows x modal terms
kept x times, over every evaluation of the rows inside the search: fine, coarse and subdivided samples,
roots), both counted on the pure-Python path (which takes the same chunks as the compiled loop; a second
run within the budget), and its cost per sample and modal term ``search_ns_per_sample_term`` = search_s /
term_samples (what a row-term-sample costs, the search's set-up per phase included). Issue 33's goal: the
unreduced cases' cost per sample and modal term within 2x of Craig-Bampton 16's
(``search_per_sample_term_goal``), i.e. the search's cost follows the model's content.

What the growth should be. Between events the motion is in closed form; the cost is the event
search, the events themselves and the set-up of each configuration met:

    wall per simulated second ~ (samples per second) x (cost per sample)
                                + (events per second) x (cost per event)
                                + (new configurations per second) x (set-up of a configuration)

- samples per second: the search samples every event row (a gap per open contact, a force per
  closed one, friction rows) at a step set by the fastest rate that the step rule takes into
  account: with the step a fixed fraction of the configuration's fastest period (pi / (4 w_max)
  when this study was written), samples per second are proportional to w_max. Since issue 17's
  third session a coarse pass lets only the modes that matter to the rows set the step away from
  a root (the modes a row barely sees are left out with their bound): far from contact the growth
  with w_max is gone; near roots and in impact bursts it stays.
- cost per sample: in a modal form of the configuration a row is a sum over its 2r modes,
  O(rows x r); a dense product with the 2n-state costs O(rows x n) to O(n^2).
- cost per event: an impact LCP and a transition LCP over the contacts involved (a few dozen
  unknowns at most); a new configuration costs an eigen-decomposition of its 2r x 2r state
  matrix, O(r^3), once (configurations are cached).

Hence, for a beam (bending frequencies grow as k^2 with the mode number and as h^-2 with the
element size):

- modal reduction with k modes: r = k and w_max ~ k^2, so the sampling cost per simulated
  second grows as rows x k^3 (slope about 3 in n), less while fixed overheads dominate;
- Craig-Bampton with k modes: r = k + one interface dof per contact point; w_max is set by the
  constraint modes (stiff, nearly independent of k), so the growth in k is the cost per sample;
- unreduced meshes of N elements: n ~ N and w_max ~ N^2, so the sampling cost per simulated
  second grows as n^3 (O(rows x n) per sample) to n^4 (O(n^2) per sample), plus the O(n^3)
  eigen-decomposition of every configuration;
- contact points m: rows ~ m; with modal 16, r and w_max stay fixed (slope about 1 plus events);
  with Craig-Bampton 16, r = 16 + m grows too and the interface stiffens (w_max grows), and more
  contacts give more events and more distinct configurations, each O(r^3).

The study fits the log-log slope of wall per simulated second against n (per series) and against
m, and splits it into the slope of w_max and the slope of the wall time per nominal sample
(wall, less the free configuration's set-up, over t_end x 4 w_max / pi samples; not given where
that set-up was not measured apart). The measured
numbers describe the code of the day; the explanation above is what they should be compared with.

    python studies/scaling.py [--quick] [--json] [--budget S] [--out DIR]

Writes scaling.csv/.json and scaling.png (log-log) into studies/out/scaling; ``--json`` prints one
object {"cases": [...], "fits": {...}, "machine": {...}, ...} (progress goes to stderr).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import multiprocessing as mp
import queue
import sys
import time
from pathlib import Path

import numpy as np
from study_io import machine, write_outputs

#: above this many (reduced) dofs the free configuration is not built a second time for its rate
RATE_CONFIG_MAX = 1500
#: runs of the integration per case, the fastest kept (wall time and search time apart), unless one takes
#: over REPEAT_MAX_S seconds
REPEAT, REPEAT_MAX_S = 3, 5.0
#: the mesh of the contact-point series (51 and 101 points need more than the shipped 40 elements)
CONTACT_ELEMENTS = 120


def cases(quick: bool) -> list[dict]:
    """Every case: series, label, scene overrides, simulated time."""
    t_red = 0.5 if quick else 2.0
    out = []
    for method in ("modal", "craig-bampton"):
        for k in (8, 16, 32, 64):
            out.append({"series": f"dofs {method}", "label": f"{method} {k}", "x_contacts": 9,
                        "overrides": [f'reduction.method="{method}"', f"reduction.modes={k}"], "t_end": t_red})
    # unreduced: the cost per simulated second grows steeply with the mesh; t_end keeps runs at seconds
    t_full = {12: 0.2, 20: 0.1, 40: 0.05, 80: 0.01, 160: 0.002, 320: 0.0005}
    for e in ((12, 20, 40, 80) if quick else (12, 20, 40, 80, 160, 320)):
        out.append({"series": "dofs none", "label": f"none {e} el.", "x_contacts": 9,
                    "overrides": ['reduction.method="none"', f"mesh.elements={e}"], "t_end": t_full[e]})
    t_con = 0.5 if quick else 1.0
    for method in ("craig-bampton", "modal"):
        for m in ((3, 9, 21) if quick else (3, 9, 21, 51, 101)):
            out.append({"series": f"contacts {method}", "label": f"{method} 16, {m} points", "x_contacts": m,
                        "overrides": [f'reduction.method="{method}"', "reduction.modes=16",
                                      f"mesh.elements={CONTACT_ELEMENTS}", f"delamination.0.contact_points={m}"],
                        "t_end": t_con})
    return out


# ---------------------------------------------------------------------------------------------
def _fastest_rate(system) -> tuple[float, str, float | None]:
    """(w_max of the free configuration, how it was found, seconds to build that configuration)."""
    n = system.n
    if n <= RATE_CONFIG_MAX:
        try:
            from nsfem.integrate.blas import single_threaded_blas
            from nsfem.integrate.configuration import Configuration, Mode

            t0 = time.perf_counter()
            with single_threaded_blas(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                cfg = Configuration(system, Mode())
            return float(cfg.fastest_rate()), "configuration", time.perf_counter() - t0
        except Exception:  # the configuration's interface may change under this study: estimate instead
            pass
    import scipy.linalg as sl

    Q, M = np.asarray(system.Q, dtype=float), np.asarray(system.M, dtype=float)
    lam = sl.eigh(0.5 * (Q + Q.T), 0.5 * (M + M.T), eigvals_only=True, subset_by_index=[n - 1, n - 1])
    return float(math.sqrt(max(lam[0], 0.0))), "undamped estimate", None


def _work(case: dict, channel) -> None:
    """One case in its own process; partial results go to ``channel`` as they come."""
    try:
        from nsfem import load_scene
        from nsfem.fem.assemble import build_model
        from nsfem.integrate import ContactSystem, integrate
        from nsfem.reduce import scene_reduction
        from nsfem.simulate import initial_state

        t_end = case["t_end"]
        dt = min(1e-3, t_end / 10)
        t0 = time.perf_counter()
        scene = load_scene(None, case["overrides"] + [f"simulation.t_end={t_end}", f"simulation.output_dt={dt}"])
        model = build_model(scene)
        t1 = time.perf_counter()
        red = scene_reduction(scene, model)
        t2 = time.perf_counter()
        system = ContactSystem.from_scene(scene, model, red)
        q0, v0 = initial_state(scene, model, red, system)
        t3 = time.perf_counter()
        channel.put({"ndof": system.n, "ndof_full": model.n, "contacts": system.contacts.m,
                     "setup_s": t3 - t0, "build_s": t1 - t0, "reduce_s": t2 - t1, "system_s": t3 - t2})
        rate, how, config_s = _fastest_rate(system)
        channel.put({"fastest_rate": rate, "fastest_rate_from": how, "config_s": config_s})
        channel.put({"integrate_started": time.time()})
        # best of REPEAT (the machine is shared), a run of over REPEAT_MAX_S once
        wall = search_s = math.inf
        for _ in range(REPEAT):
            with _SearchMeter() as search:
                t4 = time.perf_counter()
                res = integrate(system, t_end, "exact", dt, q0, v0)
                wall_i = time.perf_counter() - t4
            wall, search_s = min(wall, wall_i), min(search_s, search.spent)
            if wall_i > REPEAT_MAX_S:
                break
        channel.put({"wall_s": wall, "events": len(res.events), "impacts": len(res.impacts),
                     "configurations": res.info.get("configurations"), "completed": bool(res.completed),
                     "search_s": search_s})
        # the fine samples the search took: counted on the reference path (the compiled loop takes the same
        # chunks and does not count them); its search time beside the compiled one's
        from nsfem.integrate import core

        if core.name() == "compiled":
            with core.reference(), _SearchMeter(count=True) as ref:
                integrate(system, t_end, "exact", dt, q0, v0)
            channel.put({"samples": ref.samples, "term_samples": ref.term_samples, "search_s_python": ref.spent})
        channel.put({"status": "ok"})
    except BaseException as exc:  # noqa: BLE001 - a failing case is a data point
        channel.put({"status": "error", "error": f"{type(exc).__name__}: {exc}"[:300]})


class _SearchMeter:
    """Within the block: the wall time spent in the exact method's event search (``first_event``), the fine
    samples it took (``Phase.search_samples``) and, with ``count``, the row-term-samples it evaluated (rows x
    modal terms x times of every :meth:`~nsfem.integrate.closed_form.Motion.evaluate` inside the search: fine,
    coarse and subdivided samples and the roots' evaluations). Both counts on the pure-Python path only."""

    def __init__(self, count: bool = False):
        self.count = count

    def __enter__(self):
        from nsfem.integrate import closed_form, event_driven

        self.spent, self.samples, self.term_samples, self._inside = 0.0, 0, 0, 0
        self._owner, self._motion = event_driven, closed_form.Motion
        self._f = f = event_driven.first_event
        self._evaluate = evaluate = closed_form.Motion.evaluate

        def timed(phase, *a, **k):
            phase.search_samples = 0
            self._inside += 1
            t = time.perf_counter()
            try:
                return f(phase, *a, **k)
            finally:
                self.spent += time.perf_counter() - t
                self._inside -= 1
                self.samples += getattr(phase, "search_samples", 0)

        def counted(motion, tau, H=None):
            if self._inside:
                rows = motion.U.shape[0] if H is None else H.shape[0]
                self.term_samples += rows * motion.nu.size * np.atleast_1d(tau).size
            return evaluate(motion, tau, H)

        event_driven.first_event = timed
        if self.count:
            closed_form.Motion.evaluate = counted
        return self

    def __exit__(self, *exc):
        self._owner.first_event = self._f
        self._motion.evaluate = self._evaluate


def run_case(case: dict, budget: float) -> dict:
    """Run ``case`` in a fresh process; kill it after ``budget`` seconds (status ``timeout``)."""
    ctx = mp.get_context("spawn")
    channel = ctx.Queue()
    proc = ctx.Process(target=_work, args=(case, channel), daemon=True)
    row = {k: v for k, v in case.items() if k != "overrides"}
    row["overrides"] = " ".join(case["overrides"])
    start = time.perf_counter()
    proc.start()
    while "status" not in row:
        left = budget - (time.perf_counter() - start)
        if left <= 0:
            break
        try:
            row.update(channel.get(timeout=min(left, 1.0)))
        except queue.Empty:
            if not proc.is_alive():  # died without a word (killed, out of memory)
                with contextlib.suppress(queue.Empty):
                    row.update(channel.get(timeout=1.0))
                row.setdefault("status", "error")
                row.setdefault("error", f"process ended with exit code {proc.exitcode}")
    if "status" not in row and "wall_s" in row:   # the integration ended; counting its samples did not
        proc.kill()
        row["status"] = "ok"
    elif "status" not in row:
        proc.kill()
        row["status"] = "timeout"
        if "integrate_started" in row:  # how long the integration ran before it was stopped
            row["integrate_ran_s"] = time.time() - row["integrate_started"]
    row.pop("integrate_started", None)
    proc.join(10)
    channel.close()
    row["budget_s"] = budget
    row["case_s"] = time.perf_counter() - start
    return derive(row)


def derive(row: dict) -> dict:
    """Per simulated second, per event, per nominal sample."""
    t_end, wall = row["t_end"], row.get("wall_s")
    if row.get("status") == "ok":
        row["wall_per_sim_s"] = wall / t_end
        row["ms_per_event"] = 1e3 * wall / row["events"] if row["events"] else None
        rate = row.get("fastest_rate") or 0.0
        samples = t_end * 4.0 * rate / math.pi  # the step pi / (4 w_max)
        row["nominal_samples"] = samples
        # only where the free configuration's set-up was measured apart (above RATE_CONFIG_MAX it
        # is not, and it dominates such a run: a per-sample figure would be mostly set-up)
        net = wall - row["config_s"] if row.get("config_s") is not None else None
        row["us_per_nominal_sample"] = 1e6 * net / samples if samples > 0 and net and net > 0 else None
        # the search's own cost per fine sample it took, and per row-term-sample it evaluated
        if row.get("samples"):
            row["search_us_per_sample"] = 1e6 * row["search_s"] / row["samples"]
        if row.get("term_samples"):
            row["search_ns_per_sample_term"] = 1e9 * row["search_s"] / row["term_samples"]
    elif row.get("status") == "timeout" and row.get("integrate_ran_s"):
        # a lower bound: the integration ran this long without reaching t_end
        row["wall_per_sim_s_at_least"] = row["integrate_ran_s"] / t_end
    return row


def slope(x, y) -> float | None:
    """Least-squares slope of log y against log x (None with fewer than two usable points)."""
    pts = [(a, b) for a, b in zip(x, y) if a and b and a > 0 and b > 0]
    if len(pts) < 2 or len({a for a, _ in pts}) < 2:
        return None
    lx, ly = np.log([a for a, _ in pts]), np.log([b for _, b in pts])
    return float(np.polyfit(lx, ly, 1)[0])


def fits(rows: list[dict]) -> dict:
    out = {}
    for series in dict.fromkeys(r["series"] for r in rows):
        ok = [r for r in rows if r["series"] == series and r.get("status") == "ok"]
        x = [r["ndof"] if series.startswith("dofs") else r["contacts"] for r in ok]
        out[series] = {"against": "ndof" if series.startswith("dofs") else "contact points", "points": len(ok),
                       "wall_per_sim_s": slope(x, [r["wall_per_sim_s"] for r in ok]),
                       "fastest_rate": slope(x, [r.get("fastest_rate") for r in ok]),
                       "us_per_nominal_sample": slope(x, [r.get("us_per_nominal_sample") for r in ok]),
                       # not over a series where some runs met no event (a slope of the others would mislead)
                       "events_per_sim_s": slope(x, [r["events"] / r["t_end"] for r in ok])
                       if all(r["events"] for r in ok) else None}
    ok = [r for r in rows if r["series"].startswith("dofs") and r.get("status") == "ok"]
    out["dofs all"] = {"against": "ndof", "points": len(ok),
                       "wall_per_sim_s": slope([r["ndof"] for r in ok], [r["wall_per_sim_s"] for r in ok])}
    return out


def goal(rows: list[dict]) -> dict:
    """Issue 33: the unreduced search's cost per sample and modal term within 2x of Craig-Bampton 16's."""
    cb = next((r for r in rows if r["label"] == "craig-bampton 16" and r.get("search_ns_per_sample_term")), None)
    out = {"reference": None if cb is None else {"label": cb["label"], "ndof": cb["ndof"],
                                                 "search_ns_per_sample_term": cb["search_ns_per_sample_term"]},
           "unreduced": {}}
    for r in rows:
        if r["series"] == "dofs none" and cb is not None and r.get("search_ns_per_sample_term"):
            out["unreduced"][r["label"]] = {"ndof": r["ndof"], "search_ns_per_sample_term": r["search_ns_per_sample_term"],
                                            "over_cb16": r["search_ns_per_sample_term"] / cb["search_ns_per_sample_term"]}
    ratios = [v["over_cb16"] for v in out["unreduced"].values()]
    out["met"] = bool(ratios) and max(ratios) <= 2.0
    return out


def plot(rows: list[dict], fit: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6))
    for ax, prefix, key, xlabel in ((axes[0], "dofs", "ndof", "dofs n (reduced size)"),
                                    (axes[1], "contacts", "contacts", "contact points m")):
        for series in dict.fromkeys(r["series"] for r in rows if r["series"].startswith(prefix)):
            ok = sorted((r for r in rows if r["series"] == series and r.get("status") == "ok"), key=lambda r: r[key])
            s = fit.get(series, {}).get("wall_per_sim_s")
            label = series.split(" ", 1)[1] + ("" if s is None else f" (slope {s:.2f})")
            line = None
            if ok:
                (line,) = ax.loglog([r[key] for r in ok], [r["wall_per_sim_s"] for r in ok], "o-", label=label)
            late = [r for r in rows if r["series"] == series and r.get("wall_per_sim_s_at_least") and key in r]
            if late:
                ax.loglog([r[key] for r in late], [r["wall_per_sim_s_at_least"] for r in late], "^",
                          color=line.get_color() if line else None, ms=9,
                          label=f"{series.split(' ', 1)[1]}: timeout (at least)")
        ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel(xlabel)
        ax.set_ylabel("wall time per simulated second [s]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_title("exact: cost against model size")
    axes[1].set_title("exact: cost against contact points (16 modes)")
    fig.tight_layout()
    tmp = path.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=120)
    plt.close(fig)
    tmp.replace(path)


def fmt(x, spec: str) -> str:
    return "-" if x is None else format(x, spec)


def table(rows: list[dict]) -> str:
    head = (f"{'case':28s} {'n':>5s} {'m':>4s} {'t_end':>7s} {'setup':>7s} {'config':>7s} {'wall':>8s} "
            f"{'wall/sim s':>10s} {'events':>6s} {'confs':>5s} {'ms/event':>8s} {'w_max':>9s} {'us/sample':>9s} "
            f"{'samples':>8s} {'search':>7s} {'ns/s.term':>9s}  status")
    lines = [head]
    for r in rows:
        lines.append(f"{r['label']:28s} {fmt(r.get('ndof'), '5d'):>5s} {fmt(r.get('contacts'), '4d'):>4s} "
                     f"{r['t_end']:7.4g} {fmt(r.get('setup_s'), '7.3f'):>7s} {fmt(r.get('config_s'), '7.3f'):>7s} "
                     f"{fmt(r.get('wall_s'), '8.3f'):>8s} {fmt(r.get('wall_per_sim_s'), '10.4g'):>10s} "
                     f"{fmt(r.get('events'), '6d'):>6s} {fmt(r.get('configurations'), '5d'):>5s} "
                     f"{fmt(r.get('ms_per_event'), '8.3g'):>8s} {fmt(r.get('fastest_rate'), '9.3g'):>9s} "
                     f"{fmt(r.get('us_per_nominal_sample'), '9.3g'):>9s} {fmt(r.get('samples'), '8d'):>8s} "
                     f"{fmt(r.get('search_s'), '7.3f'):>7s} {fmt(r.get('search_ns_per_sample_term'), '9.3g'):>9s}"
                     f"  {r['status']}"
                     + (f" ({r['error']})" if r.get("error") else "")
                     + (f" (> {r['wall_per_sim_s_at_least']:.3g} s per simulated s)"
                        if r.get("wall_per_sim_s_at_least") else ""))
    return "\n".join(lines)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer and smaller cases (< 5 min on 2 cores)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--budget", type=float, default=None, help="seconds per case (60 quick, 600 full)")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "scaling"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    budget = args.budget or (60.0 if args.quick else 600.0)
    start = time.perf_counter()
    rows = []
    with contextlib.redirect_stdout(sys.stderr if args.json else sys.stdout):
        for case in cases(args.quick):
            print(f"{case['label']} ({case['t_end']:g} s simulated) ...", flush=True)
            rows.append(run_case(case, budget))
        fit = fits(rows)
        plot(rows, fit, out / "scaling.png")
        print(table(rows))
        g = goal(rows)
        if g["reference"] is not None:
            print(f"search per sample and modal term: craig-bampton 16 ({g['reference']['ndof']} dofs) "
                  f"{g['reference']['search_ns_per_sample_term']:.3g} ns; unreduced / craig-bampton 16 (goal <= 2): "
                  + ", ".join(f"{k} ({v['ndof']} dofs) {v['over_cb16']:.3g}" for k, v in g["unreduced"].items())
                  + (" -- met" if g["met"] else " -- NOT met"))
        print("log-log slopes (wall per simulated second = w_max x wall per sample):")
        for series, f in fit.items():
            print(f"  {series:24s} against {f['against']:14s} wall/sim s {fmt(f['wall_per_sim_s'], '.2f')}"
                  + (f", w_max {fmt(f['fastest_rate'], '.2f')}, per sample {fmt(f['us_per_nominal_sample'], '.2f')},"
                     f" events/sim s {fmt(f['events_per_sim_s'], '.2f')}" if "fastest_rate" in f else ""))
    payload = {"mode": "quick" if args.quick else "full", "budget_s": budget, "wall_s": time.perf_counter() - start,
               "cases": rows, "fits": fit, "search_per_sample_term_goal": g, "timeouts": [r["label"] for r in rows if r["status"] == "timeout"],
               "errors": [r["label"] for r in rows if r["status"] == "error"],
               "outputs": [str(out / "scaling.png")], "machine": machine()}
    write_outputs(out, "scaling", rows, payload)
    if args.json:
        print(json.dumps(payload))
    return payload


if __name__ == "__main__":
    main()
