"""Element refinement of the shipped scene: what the mesh, the reduction and the contact ansatz change.

Quantities, each against the number of elements (shipped scene otherwise unchanged):

- natural frequencies 1-6 of the non-rotating structure, gap open and gap closed (full model);
- the first gravity resonance (open linearization) of the full model (Rayleigh-quotient iteration
  on the sparse pencil K0 x = Omega^2 (M - Kc1 - i G1) x, seeded by the Craig-Bampton root) and of
  the scene's Craig-Bampton model (what ``nsfem campbell`` reports);
- the stationary gap at 21 Hz (centrifugal load; all contacts open) at midspan and its maximum,
  full and Craig-Bampton; the stationary state of the shaft at rest turned upside down (0 Hz,
  gravity along +z: every contact closed), midspan and total normal force (a non-trivial LCP 28);
- the transient from rest (exact method, Craig-Bampton 16): the gap history at all contacts, the
  impacts (count, times, impulses); separately the number of Craig-Bampton modes at a fixed mesh.

Errors are relative. Frequencies and the resonance: against Richardson extrapolation (order 4)
of the nested uniform meshes 100 and 200, below the round-off floor; the rest: against the
finest mesh of its series. Orders: least-squares slope of log(error) against log(elements) on
the pre-asymptotic-to-floor range 12-100 elements (meshes 12, 24, 48 are nested with 1 : 2 : 4
elements per interval; 50, 100, 200, ... are uniform). Heavy refinement (to 3200 elements,
4800 in full mode) shows the round-off floor of Hermite elements and its h^-4 growth.

A second series varies the contact ansatz at a fixed mesh: 3 to 33 (65 in full mode) contact
points, Dirac and hat weighting: closed frequency, stationary gaps and forces, transient closed
fraction, impacts, impulse and the midspan gap history.

    python studies/refinement.py [--quick] [--json] [--out DIR]

Writes refinement.csv/.json and refinement_elements.png, refinement_transient.png,
refinement_contacts.png into studies/out/refinement (copies of the PNGs to docs/figures);
``--json`` prints one summary object (measured orders, reference values, floor, transient
horizon, contact-ansatz findings).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from study_io import machine, write_outputs

from nsfem import build_model, load_scene, natural_frequencies
from nsfem.analysis.campbell import gravity_resonances
from nsfem.analysis.modes import contact_basis
from nsfem.analysis.stationary import scene_stationary
from nsfem.errors import IntegrationError
from nsfem.fem.rotating import rotor_operators
from nsfem.reduce import reduce, scene_reduction
from nsfem.result import json_default
from nsfem.simulate import run_scene

ROOT = Path(__file__).resolve().parent.parent
NMODES = 6
MID = 4  # midspan contact (x = 0.5) of the shipped 9 points
FIT = (12, 100)  # elements range of the order fits
RICH = (100, 200)  # nested uniform pair for the Richardson reference
UPSIDE_DOWN = ["rotation.speed_hz=0", "rotation.phase_deg=180"]  # gravity along +z: contacts close
FULL = ["reduction.method=none"]


def scene(elements: int, extra=()):
    return load_scene(None, [f"mesh.elements={elements}", *extra])


def resonance_rqi(ops, f0_hz: float, phase_deg: float = 0.0, iterations: int = 8) -> tuple[float, float]:
    """First gravity resonance [Hz] of the full (sparse) open model by Rayleigh-quotient iteration.

    Start: the gravity response at the seed speed (dominated by the resonant shape); the pencil
    K0 x = mu H x is Hermitian, so the Rayleigh quotient converges cubically. Returns the last
    iterate and the spread of the last three (its round-off noise)."""
    K0 = sp.csc_matrix(ops.K0)
    H = sp.csc_matrix(ops.M - ops.Kc1 - 1j * ops.G1)
    F = (np.exp(1j * math.radians(phase_deg)) * (1j * ops.Fy - ops.Fz)).astype(complex)
    mu = (2 * math.pi * f0_hz) ** 2
    x = spla.splu(sp.csc_matrix(K0 - mu * H)).solve(F)
    hist = []
    for _ in range(iterations):
        x /= np.linalg.norm(x)
        mu = float(np.real(np.vdot(x, K0 @ x) / np.vdot(x, H @ x)))
        hist.append(math.sqrt(mu) / (2 * math.pi))
        try:
            x = spla.splu(sp.csc_matrix(K0 - mu * H)).solve(H @ x)
        except RuntimeError:  # exactly singular: mu is the root
            break
    tail = hist[-3:]
    return hist[-1], float(max(tail) - min(tail))


def mesh_row(n: int, static_full: bool) -> dict:
    """Every steady quantity of the shipped scene on ``n`` elements, with wall times."""
    sc = scene(n)
    t0 = time.perf_counter()
    model = build_model(sc)
    red = scene_reduction(sc, model)
    t1 = time.perf_counter()
    fo = natural_frequencies(model, "open", NMODES).frequencies_hz
    fc = natural_frequencies(model, "closed", NMODES).frequencies_hz
    t2 = time.perf_counter()
    fo_cb = natural_frequencies(model, "open", NMODES, reduction=red).frequencies_hz
    g_red = gravity_resonances(rotor_operators(model, contact_basis(model, "open", red)))[0][0]
    g_full, g_noise = resonance_rqi(rotor_operators(model, contact_basis(model, "open", None)), g_red)
    t3 = time.perf_counter()
    st_red = scene_stationary(sc, model, red)
    row = {"elements": n, "ndof_full": model.n, "ndof_cb": red.ndof, "wall_build_s": t1 - t0,
           "wall_modes_s": t2 - t1, "wall_resonance_s": t3 - t2,
           **{f"open{k + 1}": float(fo[k]) for k in range(NMODES)},
           **{f"closed{k + 1}": float(fc[k]) for k in range(NMODES)},
           "resonance_full": g_full, "resonance_full_noise": g_noise, "resonance_cb": float(g_red),
           "cb_open_freq_error_max": float(np.max(np.abs(fo_cb / fo - 1))),
           "gap_mid_cb": float(st_red.gap[MID]), "gap_max_cb": float(st_red.gap.max())}
    if static_full:
        t4 = time.perf_counter()
        st = scene_stationary(scene(n, FULL), model)
        up = scene_stationary(scene(n, FULL + UPSIDE_DOWN), model)
        row.update({"wall_stationary_s": time.perf_counter() - t4, "gap_mid": float(st.gap[MID]),
                    "gap_max": float(st.gap.max()), "cb_gap_mid_error": abs(row["gap_mid_cb"] / float(st.gap[MID]) - 1),
                    "open_contacts": int(sum(s == "open" for s in st.state)),
                    "upside_force_mid": float(up.normal_force[MID]),
                    "upside_force_total": float(up.normal_force.sum()),
                    "upside_closed": int(sum(s != "open" for s in up.state))})
    return row


def transient(extra, t_end: float) -> dict:
    sc = load_scene(None, [*extra, f"simulation.t_end={t_end}"])
    t0 = time.perf_counter()
    failure = None
    try:
        res, _ = run_scene(sc, "exact")
    except IntegrationError as exc:  # a failed run is a finding: keep what it computed
        res, failure = exc.result, str(exc)
    wall = time.perf_counter() - t0
    s = res.summary()
    imp = [(float(i["t"]), float(np.sum(i["impulse_Ns"]))) for i in res.impacts]
    return {"t": res.t, "gap": res.gap, "impacts": imp, "wall_s": wall, "failure": failure,
            "ndof": int(res.q.shape[0]), "events": s["events"], "closed_fraction": s["closed_fraction"],
            "max_normal_force_N": s["max_normal_force_N"], "min_gap_m": s["min_gap_m"],
            "max_gap_m": s["max_gap_m"], "t_reached": float(res.t[-1]) if res.t.size else 0.0}


def horizon(t, err_t, tol) -> float:
    """Last output time up to which the running error stays below ``tol``."""
    bad = np.nonzero(err_t > tol)[0]
    return float(t[-1]) if len(bad) == 0 else float(t[max(bad[0] - 1, 0)])


def compare(run: dict, ref: dict) -> dict:
    """Gap-history and impact errors of ``run`` against ``ref`` (same output times and contacts)."""
    scale = float(np.abs(ref["gap"]).max())
    err_t = np.abs(run["gap"] - ref["gap"]).max(axis=0) / scale
    out = {"gap_error": float(err_t.max()), "gap_error_t": err_t,
           "horizon_1e-3": horizon(ref["t"], err_t, 1e-3), "horizon_1e-2": horizon(ref["t"], err_t, 1e-2),
           "impacts": len(run["impacts"]), "impulse_sum": float(sum(p for _, p in run["impacts"]))}
    if run["impacts"] and ref["impacts"]:
        out["first_impact_t_error_s"] = abs(run["impacts"][0][0] - ref["impacts"][0][0])
        out["first_impulse_error"] = abs(run["impacts"][0][1] / ref["impacts"][0][1] - 1)
        # impacts matched one-to-one in order, within 1 ms, before the first mismatch
        k = 0
        for (ta, pa), (tb, pb) in zip(run["impacts"], ref["impacts"]):
            if abs(ta - tb) > 1e-3:
                break
            k += 1
        out["impacts_matched"] = k
    return out


def fit_order(ns, errs, lo=FIT[0], hi=FIT[1]) -> float | None:
    """-slope of log(error) against log(elements) on [lo, hi] (order in h)."""
    pts = [(n, e) for n, e in zip(ns, errs) if lo <= n <= hi and e is not None and e > 0 and math.isfinite(e)]
    if len(pts) < 2:
        return None
    x, y = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(-np.polyfit(x, y, 1)[0])


def local_orders(ns, errs) -> list:
    """Order between successive meshes, log(e_i / e_{i+1}) / log(n_{i+1} / n_i)."""
    out = []
    for (n0, e0), (n1, e1) in zip(zip(ns, errs), zip(ns[1:], errs[1:])):
        out.append(None if not (e0 and e1) else float(np.log(e0 / e1) / np.log(n1 / n0)))
    return out


def elements_study(sizes, static_max, trans_sizes, t_end, cb_modes, cb_elements) -> tuple[dict, list[dict]]:
    rows, data = [], []
    for n in sizes:
        r = mesh_row(n, static_full=n <= static_max)
        data.append(r)
        print(f"  {n:5d} elements, {r['ndof_full']:6d} dofs: f_open1 {r['open1']:.10f} Hz, resonance "
              f"{r['resonance_full']:.10f} Hz, gap_mid(CB) {r['gap_mid_cb']:.12e} m  "
              f"[{r['wall_build_s'] + r['wall_modes_s'] + r['wall_resonance_s']:.2f} s]", flush=True)
    ns = [r["elements"] for r in data]
    by_n = {r["elements"]: r for r in data}
    a, b = by_n[RICH[0]], by_n[RICH[1]]
    summary: dict = {"reference": {}, "orders": {}, "local_orders": {}, "floor": {}}
    series = {}
    # eigenvalue-type quantities: Richardson reference, order 4
    for q in [f"open{k + 1}" for k in range(NMODES)] + [f"closed{k + 1}" for k in range(NMODES)] + \
            ["resonance_full", "resonance_cb"]:
        ref = b[q] + (b[q] - a[q]) / 15.0
        errs = [abs(r[q] / ref - 1) for r in data]
        series[q] = errs
        summary["reference"][q] = ref
        summary["orders"][q] = fit_order(ns, errs)
        summary["local_orders"][q] = local_orders(ns, errs)
        k = int(np.argmin(errs))
        rise = [(n, e) for n, e in zip(ns, errs) if n >= 4 * ns[k]]
        slope = float(np.polyfit(np.log([p[0] for p in rise]), np.log([p[1] for p in rise]), 1)[0]) \
            if len(rise) >= 2 else None
        summary["floor"][q] = {"elements": ns[k], "error": errs[k], "growth_order_beyond": slope}
        for r, e in zip(data, errs):
            rows.append({"group": "elements", "quantity": q, "elements": r["elements"], "value": r[q], "error": e,
                         "reference": ref, "wall_s": r["wall_modes_s"] if q[0] in "oc" else r["wall_resonance_s"]})
    # the Craig-Bampton resonance against the full one on the same mesh (reduction error)
    summary["resonance_cb_vs_full"] = {r["elements"]: abs(r["resonance_cb"] / r["resonance_full"] - 1) for r in data}
    # statics. 21 Hz gap: centrifugal softening breaks the nodal exactness of Hermite elements for
    # Euler-Bernoulli statics: Richardson reference as for the frequencies. 0 Hz upside down: the
    # static problem is nodally exact on every mesh: reference = the coarsest mesh (least round-off)
    for q in ("gap_mid", "gap_max", "gap_mid_cb", "upside_force_mid", "upside_force_total"):
        have = [r for r in data if q in r]
        hn = [r["elements"] for r in have]
        if q.startswith("upside"):
            ref = have[0][q]
        else:
            ref = by_n[RICH[1]][q] + (by_n[RICH[1]][q] - by_n[RICH[0]][q]) / 15.0
        errs = [abs(r[q] / ref - 1) for r in have]
        series[q] = errs
        summary["reference"][q] = ref
        summary["orders"][q] = None if q.startswith("upside") else fit_order(hn, errs)
        k = int(np.argmin(errs[1:])) + 1 if q.startswith("upside") else int(np.argmin(errs))
        summary["floor"][q] = {"elements": hn[k], "error": errs[k], "max_error": max(errs),
                               "max_error_elements": hn[int(np.argmax(errs))],
                               "error_at_shipped_40": errs[hn.index(40)] if 40 in hn else None}
        for r, e in zip(have, errs):
            rows.append({"group": "elements", "quantity": q, "elements": r["elements"], "value": r[q], "error": e,
                         "reference": ref, "wall_s": r.get("wall_stationary_s")})
    summary["cb16_vs_full"] = {r["elements"]: {"open_freq_max": r["cb_open_freq_error_max"],
                                               "gap_mid": r.get("cb_gap_mid_error")} for r in data}
    summary["stationary_open_contacts_21hz"] = data[0].get("open_contacts")
    summary["upside_down_closed_contacts"] = data[0].get("upside_closed")
    # transient against elements (Craig-Bampton 16)
    runs = {}
    for n in trans_sizes:
        runs[n] = transient([f"mesh.elements={n}"], t_end)
        print(f"  transient {n:5d} elements: {len(runs[n]['impacts'])} impacts, wall {runs[n]['wall_s']:.2f} s",
              flush=True)
    ref_n = trans_sizes[-1]
    tr = {"t_end": t_end, "reference_elements": ref_n, "per_mesh": {}}
    for n, run in runs.items():
        c = compare(run, runs[ref_n])
        tr["per_mesh"][n] = {k: v for k, v in c.items() if k != "gap_error_t"}
        tr["per_mesh"][n].update(wall_s=run["wall_s"], closed_fraction=run["closed_fraction"], ndof=run["ndof"])
        rows.append({"group": "transient_elements", "quantity": "gap_history", "elements": n, "modes": 16,
                     "value": run["max_gap_m"], "error": c["gap_error"] if n != ref_n else None,
                     "wall_s": run["wall_s"], "impacts": c["impacts"], "impulse_sum": c["impulse_sum"],
                     "first_impact_t_error_s": c.get("first_impact_t_error_s"),
                     "first_impulse_error": c.get("first_impulse_error"), "horizon_1e-3_s": c["horizon_1e-3"],
                     "closed_fraction": run["closed_fraction"]})
    tr["order_gap"] = fit_order(trans_sizes[:-1], [tr["per_mesh"][n]["gap_error"] for n in trans_sizes[:-1]],
                                lo=0, hi=10**9)
    tr["reference_impacts"] = runs[ref_n]["impacts"][:12]
    # transient against Craig-Bampton modes at a fixed mesh
    cb = {}
    for m in cb_modes:
        cb[m] = transient([f"mesh.elements={cb_elements}", f"reduction.modes={m}"], t_end)
        print(f"  transient CB {m:3d} modes ({cb[m]['ndof']} dofs): {len(cb[m]['impacts'])} impacts, "
              f"wall {cb[m]['wall_s']:.2f} s", flush=True)
    cb_ref = cb_modes[-1]
    tr["cb"] = {"elements": cb_elements, "reference_modes": cb_ref, "per_modes": {}}
    model = build_model(scene(cb_elements))
    for m, run in cb.items():
        c = compare(run, cb[cb_ref])
        red = reduce(model, "craig-bampton", m)
        g = gravity_resonances(rotor_operators(model, contact_basis(model, "open", red)))[0][0]
        c["resonance_error"] = abs(g / by_n[cb_elements]["resonance_full"] - 1) if cb_elements in by_n else None
        tr["cb"]["per_modes"][m] = {k: v for k, v in c.items() if k != "gap_error_t"}
        tr["cb"]["per_modes"][m].update(wall_s=run["wall_s"], ndof=run["ndof"])
        rows.append({"group": "transient_modes", "quantity": "gap_history", "elements": cb_elements, "modes": m,
                     "ndof": run["ndof"], "value": run["max_gap_m"], "error": c["gap_error"] if m != cb_ref else None,
                     "wall_s": run["wall_s"], "impacts": c["impacts"], "impulse_sum": c["impulse_sum"],
                     "first_impulse_error": c.get("first_impulse_error"), "horizon_1e-3_s": c["horizon_1e-3"],
                     "resonance_error": c["resonance_error"]})
    summary["transient"] = tr
    plot_data = {"ns": ns, "series": series, "data": data, "runs": runs, "ref_n": ref_n, "cb": cb, "cb_ref": cb_ref}
    return summary, rows, plot_data


def contacts_study(counts, elements, t_end) -> tuple[dict, list[dict], dict]:
    rows, res = [], {}
    for w in ("dirac", "hat"):
        for c in counts:
            extra = [f"mesh.elements={elements}", f"delamination.0.contact_points={c}",
                     f'delamination.0.weighting="{w}"']
            t0 = time.perf_counter()
            sc = load_scene(None, extra + FULL)
            model = build_model(sc)
            fc = natural_frequencies(model, "closed", 3).frequencies_hz
            st = scene_stationary(sc, model)
            up = scene_stationary(load_scene(None, extra + FULL + UPSIDE_DOWN), model)
            x = np.asarray(st.contacts.x)
            mid = int(np.argmin(np.abs(x - 0.5)))
            wall_static = time.perf_counter() - t0
            run = transient(extra, t_end)
            ok = run["failure"] is None
            r = {"weighting": w, "contact_points": c, "closed1": float(fc[0]), "closed3": float(fc[2]),
                 "gap_mid": float(st.gap[mid]), "gap_max": float(st.gap.max()),
                 "upside_force_total": float(up.normal_force.sum()),
                 "upside_force_max": float(up.normal_force.max()),
                 "upside_closed": int(sum(s != "open" for s in up.state)), "ndof_cb": run["ndof"],
                 "closed_fraction": run["closed_fraction"] if ok else None,
                 "impacts": len(run["impacts"]) if ok else None,
                 "impulse_sum": float(sum(p for _, p in run["impacts"])) if ok else None,
                 "max_normal_force_N": run["max_normal_force_N"] if ok else None,
                 "max_gap_m": run["max_gap_m"] if ok else None,
                 "wall_static_s": wall_static, "wall_transient_s": run["wall_s"],
                 "transient_failure": run["failure"], "transient_t_reached": run["t_reached"]}
            res[(w, c)] = (r, run, mid)
            tail = (f"transient: {r['impacts']} impacts, closed {r['closed_fraction']:.3f}, impulse sum "
                    f"{r['impulse_sum']:.4e} N s" if ok else f"transient FAILED at t = {run['t_reached']:g} s")
            print(f"  {w:5s} {c:3d} points: closed f1 {r['closed1']:.6f} Hz, gap_mid {r['gap_mid']:.6e} m, "
                  f"upside total {r['upside_force_total']:.5f} N, {tail} [{run['wall_s']:.2f} s]", flush=True)
    good = [k for k in res if res[k][0]["impacts"] is not None]
    ref_key = max(good, key=lambda k: (k[1], k[0] == "hat"))
    ref_r, ref_run, ref_mid = res[ref_key]
    summary = {"elements": elements, "t_end": t_end, "reference": f"{ref_key[0]}, {ref_key[1]} points",
               "static_reference": f"hat, {counts[-1]} points", "rows": [],
               "failures": {f"{w} {c}": res[(w, c)][0]["transient_failure"] for (w, c) in res
                            if res[(w, c)][0]["transient_failure"]}}
    sref = res[("hat", counts[-1])][0]
    hat = [(c, abs(res[("hat", c)][0]["gap_mid"] / res[("dirac", c)][0]["gap_mid"] - 1)) for c in counts]
    summary["hat_gap_averaging_error"] = dict(hat)
    summary["hat_gap_averaging_order"] = fit_order([c + 1 for c, _ in hat], [e for _, e in hat], lo=0, hi=10**9)
    for (w, c), (r, run, mid) in res.items():
        if r["impacts"] is not None:
            g = run["gap"][mid]
            gr = ref_run["gap"][ref_mid]
            r["mid_gap_history_error"] = float(np.abs(g - gr).max() / np.abs(gr).max())
        else:
            r["mid_gap_history_error"] = None
        for q in ("closed1", "gap_mid", "upside_force_total"):
            r[f"{q}_rel_to_ref"] = r[q] / sref[q] - 1
        r["gap_mid_rel_to_dirac"] = r["gap_mid"] / res[("dirac", c)][0]["gap_mid"] - 1
        for q in ("impulse_sum", "closed_fraction"):
            r[f"{q}_rel_to_ref"] = (r[q] / ref_r[q] - 1) if (r[q] is not None and ref_r[q]) else None
        summary["rows"].append(r)
        rows.append({"group": "contacts", **r})
    return summary, rows, {"res": res, "counts": counts}


# ---------------------------------------------------------------------------------------------- plots


def _save(fig, path: Path) -> None:
    """PNG at dpi 100, palette-quantized (line plots lose nothing visible; files stay small)."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    fig.savefig(buf, dpi=100, format="png")
    img = Image.open(buf).convert("RGB").quantize(colors=128)
    tmp = path.with_name(path.stem + ".tmp.png")
    img.save(tmp, optimize=True)
    tmp.replace(path)


def _counts_axis(ax, counts) -> None:
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    ax.set_xticks(counts)
    ax.xaxis.set_major_formatter(ScalarFormatter())
    ax.xaxis.set_minor_formatter(NullFormatter())


def plot_elements(pd: dict, summary: dict, path: Path) -> None:
    import matplotlib.pyplot as plt

    ns, s, data = np.array(pd["ns"]), pd["series"], pd["data"]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10.5, 4.4))
    cmap = plt.get_cmap("viridis")
    for k in range(NMODES):
        ax.loglog(ns, s[f"open{k + 1}"], "-", color=cmap(k / NMODES), lw=1, marker="o", ms=3,
                  label=f"open {k + 1}" if k in (0, NMODES - 1) else None)
        ax.loglog(ns, s[f"closed{k + 1}"], "--", color=cmap(k / NMODES), lw=1, marker="s", ms=3,
                  label=f"closed {k + 1}" if k in (0, NMODES - 1) else None)
    ax.loglog(ns, s["resonance_full"], "r-", lw=2, marker="D", ms=4, label="gravity resonance (full)")
    ax.loglog(ns, [r["cb_open_freq_error_max"] for r in data], color="gray", lw=1.5, ls=(0, (5, 2)),
              label="CB 16 vs full, same mesh (max open 1-6)")
    ax.loglog(ns[ns <= 400], 3e-6 * (12 / ns[ns <= 400]) ** 4, "k:", lw=1, label=r"$h^4$")
    ax.loglog(ns[ns >= 400], 3e-9 * (ns[ns >= 400] / 400.0) ** 4, "k-.", lw=1, label=r"$h^{-4}$ (round-off)")
    ax.axvline(40, color="gray", lw=0.8, alpha=0.6)
    ax.set_xlabel("elements over the length (shipped: 40)")
    ax.set_ylabel("relative error (Richardson reference, 100/200)")
    ax.set_title("frequencies 1-6 (open, closed), gravity resonance", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)

    def pos(n, e):
        return [(a, b) for a, b in zip(n, e) if b > 0]

    for q, st, lab in (("gap_mid", "o-", "stationary gap, midspan, 21 Hz (full)"),
                       ("gap_mid_cb", "x:", "stationary gap, midspan, 21 Hz (CB 16)"),
                       ("upside_force_mid", "^-", "contact force midspan, 0 Hz upside down (vs 12)"),
                       ("upside_force_total", "v--", "contact force total, 0 Hz upside down (vs 12)")):
        n_q = [r["elements"] for r in data if q in r]
        bx.loglog(*zip(*pos(n_q, s[q])), st, ms=4, label=lab)
    cbg = [(r["elements"], r["cb_gap_mid_error"]) for r in data if "cb_gap_mid_error" in r]
    bx.loglog(*zip(*cbg), color="gray", lw=1.5, ls=(0, (5, 2)), label="CB 16 vs full, stationary gap, same mesh")
    tr = summary["transient"]["per_mesh"]
    nt = [n for n in tr if n != summary["transient"]["reference_elements"]]
    bx.loglog(nt, [tr[n]["gap_error"] for n in nt], "ko-", lw=2,
              label=f"transient gap history, {summary['transient']['t_end']:g} s (vs {max(tr)})")
    fi = [(n, tr[n].get("first_impulse_error")) for n in nt if tr[n].get("first_impulse_error")]
    if fi:
        bx.loglog(*zip(*fi), "kd--", label="first impact impulse")
    bx.axvline(40, color="gray", lw=0.8, alpha=0.6)
    bx.set_xlabel("elements over the length (shipped: 40)")
    bx.set_ylabel("relative error")
    bx.set_title("stationary states, transient (exact, CB 16)", fontsize=10)
    bx.grid(True, which="both", alpha=0.3)
    bx.legend(fontsize=7)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def plot_transient(pd: dict, summary: dict, path: Path) -> None:
    import matplotlib.pyplot as plt

    runs, ref_n, cb, cb_ref = pd["runs"], pd["ref_n"], pd["cb"], pd["cb_ref"]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10.5, 4.0))
    ref = runs[ref_n]
    win = ref["t"] <= min(0.2, ref["t"][-1])
    ax.plot(ref["t"][win], ref["gap"][MID][win] * 1e3, "k-", lw=1.5, label=f"{ref_n} elements, CB 16")
    ax.plot(runs[min(runs)]["t"][win], runs[min(runs)]["gap"][MID][win] * 1e3, "b:", lw=1.2,
            label=f"{min(runs)} elements, CB 16")
    for m, st in ((min(cb), "g--"), (cb_ref, "r-")):
        ax.plot(cb[m]["t"][win], cb[m]["gap"][MID][win] * 1e3, st, lw=0.9,
                label=f"{summary['transient']['cb']['elements']} elements, CB {m}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("gap at midspan [mm]")
    ax.set_title("gap history from rest (exact), first 0.2 s", fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    scale = np.abs(ref["gap"]).max()
    for n, run in runs.items():
        if n != ref_n:
            err = np.maximum.accumulate(np.abs(run["gap"] - ref["gap"]).max(axis=0) / scale)
            bx.semilogy(run["t"], np.maximum(err, 1e-16), label=f"{n} elements (vs {ref_n})")
    rcb = cb[cb_ref]
    scale = np.abs(rcb["gap"]).max()
    for m, run in cb.items():
        if m != cb_ref:
            err = np.maximum.accumulate(np.abs(run["gap"] - rcb["gap"]).max(axis=0) / scale)
            bx.semilogy(run["t"], np.maximum(err, 1e-16), "--", label=f"CB {m} modes (vs {cb_ref})")
    bx.set_xlabel("t [s]")
    bx.set_ylabel("running max of |g - g_ref| / max |g_ref|")
    bx.set_title("error growth: mesh (solid, CB 16) and reduction (dashed)", fontsize=10)
    bx.set_ylim(1e-9, 1)
    bx.legend(fontsize=7, ncol=2)
    bx.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def plot_contacts(cd: dict, csum: dict, path: Path) -> None:
    import matplotlib.pyplot as plt

    counts, res = cd["counts"], cd["res"]
    fig, axs = plt.subplots(1, 3, figsize=(13, 4.0))
    ax2 = axs[2].twinx()
    for w, st in (("dirac", "o-"), ("hat", "s--")):
        rs = [res[(w, c)][0] for c in counts]
        for q, col, lab in (("closed1_rel_to_ref", "C0", "closed-gap f1"),
                            ("upside_force_total_rel_to_ref", "C1", "total contact force, 0 Hz upside down")):
            pts = [(c, abs(r[q])) for c, r in zip(counts, rs) if r[q]]
            if pts:
                axs[0].loglog(*zip(*pts), st, color=col, label=f"{lab}, {w}")
        if w == "hat":
            pts = [(c, abs(r["gap_mid_rel_to_dirac"])) for c, r in zip(counts, rs)]
            axs[0].loglog(*zip(*pts), st, color="C2", label="hat-averaged stationary gap vs point value")
        pts = [(c, r["mid_gap_history_error"]) for c, r in zip(counts, rs) if r["mid_gap_history_error"]]
        if pts:
            axs[1].loglog(*zip(*pts), st, label=f"midspan gap history, {w}")
        ok = [(c, r) for c, r in zip(counts, rs) if r["impacts"] is not None]
        axs[2].semilogx([c for c, _ in ok], [r["impulse_sum"] * 1e3 for _, r in ok], st, color="C0",
                        label=f"impulse sum, {w}")
        ax2.loglog([c for c, _ in ok], [r["impacts"] for _, r in ok], st, color="C3", alpha=0.7,
                   label=f"impacts, {w}")
        for c, r in zip(counts, rs):
            if r["impacts"] is None:
                for ax in axs[1:]:
                    ax.axvline(c, color="red", lw=0.8, ls=st[1:])
                axs[1].text(c, 0.5, f" {w} {c}: exact failed at t=0", color="red", fontsize=7, rotation=90,
                            va="center", transform=axs[1].get_xaxis_transform())
    axs[0].set_ylabel("relative deviation")
    axs[0].set_title(f"statics / modes vs {csum['static_reference']}", fontsize=10)
    axs[1].set_ylabel("max |g - g_ref| / max |g_ref| at midspan")
    axs[1].set_title(f"transient {csum['t_end']:g} s vs {csum['reference']}", fontsize=10)
    axs[2].set_ylabel("sum of impact impulses [mN s] (blue)")
    ax2.set_ylabel("number of impacts (red)")
    axs[2].set_title(f"impacts, exact, CB 16, {csum['elements']} elements", fontsize=10)
    for ax in axs:
        ax.set_xlabel("contact points")
        ax.grid(True, which="both", alpha=0.3)
        _counts_axis(ax, counts)
        ax.legend(fontsize=7, loc="upper right" if ax is not axs[2] else "lower right")
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------- main


def fmt(x, spec=".2e"):
    return "-" if x is None else format(x, spec)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer meshes, 0.5 s transients (about 1-2 min)")
    ap.add_argument("--json", action="store_true", help="print one JSON summary object")
    ap.add_argument("--out", default=str(Path(__file__).parent / "out" / "refinement"))
    ap.add_argument("--no-docs", action="store_true", help="do not copy the PNGs to docs/figures")
    args = ap.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    if args.quick:
        sizes = [12, 24, 40, 48, 50, 100, 200, 400, 800, 1600, 3200]
        static_max, trans = 800, [12, 24, 48, 100, 200]
        t_end, cb_modes, counts, c_elements = 0.5, [8, 16, 32, 64], [3, 5, 9, 17, 33], 100
    else:
        sizes = [12, 24, 40, 48, 50, 100, 200, 400, 800, 1600, 3200, 4800]
        static_max, trans = 3200, [12, 24, 48, 100, 200, 400, 800]
        t_end, cb_modes, counts, c_elements = 1.0, [8, 12, 16, 24, 32, 64, 128], [3, 5, 9, 17, 33, 65], 200
    # with --json, progress goes to stderr: stdout holds exactly one JSON object
    with contextlib.redirect_stdout(sys.stderr if args.json else sys.stdout):
        print(f"refinement of the shipped scene ({'quick' if args.quick else 'full'}): elements", flush=True)
        summary, rows, pd = elements_study(sizes, static_max, trans, t_end, cb_modes, 100)
        print("contact points and weighting", flush=True)
        csum, crow, cd = contacts_study(counts, c_elements, t_end)
    rows += crow
    wall = time.perf_counter() - t_start
    figs = [out / "refinement_elements.png", out / "refinement_transient.png", out / "refinement_contacts.png"]
    plot_elements(pd, summary, figs[0])
    plot_transient(pd, summary, figs[1])
    plot_contacts(cd, csum, figs[2])
    if not args.no_docs:
        for f in figs:
            shutil.copyfile(f, ROOT / "docs" / "figures" / f.name)
    payload = {"mode": "quick" if args.quick else "full", "wall_s": wall, "machine": machine(),
               "elements": sizes, "fit_range_elements": list(FIT), "richardson_pair": list(RICH), **summary,
               "contacts": csum, "per_mesh": pd["data"], "outputs": [str(f) for f in figs]}
    write_outputs(out, "refinement", rows, json.loads(json.dumps(payload, default=json_default)))
    compact = {
        "mode": payload["mode"], "wall_s": round(wall, 1),
        "orders": {k: None if v is None else round(v, 2) for k, v in summary["orders"].items()},
        "reference": {k: summary["reference"][k] for k in ("open1", "closed1", "resonance_full", "gap_mid",
                                                          "upside_force_total")},
        "floor": {k: summary["floor"][k] for k in ("open1", "closed1", "resonance_full")},
        "stationary_max_error": {k: summary["floor"][k]["max_error"] for k in ("gap_mid", "upside_force_total")},
        "resonance_cb16_vs_full_at_100": summary["resonance_cb_vs_full"].get(100),
        "transient": {"t_end": t_end, "reference_elements": summary["transient"]["reference_elements"],
                      "gap_error": {n: v["gap_error"] for n, v in summary["transient"]["per_mesh"].items()},
                      "horizon_1e-3_s": {n: v["horizon_1e-3"] for n, v in summary["transient"]["per_mesh"].items()},
                      "cb_gap_error": {m: v["gap_error"] for m, v in summary["transient"]["cb"]["per_modes"].items()}},
        "contacts": [{k: r[k] for k in ("weighting", "contact_points", "closed1", "gap_mid", "impacts",
                                        "impulse_sum", "closed_fraction", "mid_gap_history_error")}
                     for r in csum["rows"]],
    }
    if args.json:
        print(json.dumps(json.loads(json.dumps(compact, default=json_default))))
    else:
        report(summary, csum, wall)
    return payload



def report(summary: dict, csum: dict, wall: float) -> None:
    print("\nquantity              reference          order(12-100)  floor at   floor error  growth beyond")
    for q, ref in summary["reference"].items():
        fl = summary["floor"][q]
        if "growth_order_beyond" in fl:
            print(f"{q:20s} {ref:18.12g}  {fmt(summary['orders'].get(q), '6.2f'):>12s}  {fl['elements']:7d}   "
                  f"{fl['error']:10.2e}  {fmt(fl['growth_order_beyond'], '+.2f')}")
        else:
            print(f"{q:20s} {ref:18.12g}  {fmt(summary['orders'].get(q), '6.2f'):>12s}  {fl['elements']:7d}   "
                  f"{fl['error']:10.2e}  (max {fmt(fl['max_error'])} at {fl['max_error_elements']}; "
                  f"{fmt(fl['error_at_shipped_40'])} at 40)")
    tr = summary["transient"]
    print(f"\ntransient, exact, CB 16, {tr['t_end']:g} s, reference {tr['reference_elements']} elements")
    print("elements  gap error  horizon(1e-3)  impacts  matched  first impulse err  wall [s]")
    for n, v in tr["per_mesh"].items():
        print(f"{n:8d}  {v['gap_error']:9.2e}  {v['horizon_1e-3']:12.4f}  {v['impacts']:7d}  "
              f"{fmt(v.get('impacts_matched'), 'd'):>7s}  {fmt(v.get('first_impulse_error')):>17s}  {v['wall_s']:7.2f}")
    print(f"Craig-Bampton modes at {tr['cb']['elements']} elements, reference {tr['cb']['reference_modes']} modes")
    print("modes  gap error  horizon(1e-3)  impacts  first impulse err  resonance err  wall [s]")
    for m, v in tr["cb"]["per_modes"].items():
        print(f"{m:5d}  {v['gap_error']:9.2e}  {v['horizon_1e-3']:12.4f}  {v['impacts']:7d}  "
              f"{fmt(v.get('first_impulse_error')):>17s}  {fmt(v.get('resonance_error')):>13s}  {v['wall_s']:7.2f}")
    print(f"\ncontact ansatz at {csum['elements']} elements (reference {csum['reference']})")
    print("weighting points  closed f1 [Hz]   gap_mid [m]     upside total [N]  impacts  impulse sum [N s]  "
          "closed frac  mid gap hist err")
    for r in csum["rows"]:
        if r["impacts"] is None:
            tail = f"transient failed: {r['transient_failure'][:70]}"
        else:
            tail = (f"{r['impacts']:7d}  {r['impulse_sum']:17.6e}  {r['closed_fraction']:11.3f}  "
                    f"{r['mid_gap_history_error']:.2e}")
        print(f"{r['weighting']:9s} {r['contact_points']:6d}  {r['closed1']:14.8f}  {r['gap_mid']:.8e}  "
              f"{r['upside_force_total']:14.8f}  {tail}")
    print(f"\nwall {wall:.1f} s")


if __name__ == "__main__":
    main()
