"""Issue 33's goals, one table: collected from the JSON the goal studies wrote (no run of its own).

Reads, from ``--out`` (default studies/out): work_precision/work_precision.json, paper_figure3/paper_figure3.json,
scaling/scaling.json, rub/rub.json, unreduced/unreduced.json, cli_time/cli_time.json and
profile_exact/profile_exact.json (each
written by its study, e.g. ``python studies/work_precision.py --quick --json``), and writes goals33.md there:
per goal the case, what was measured side by side in one run, the ratio, met or not, and where exact's
time goes (studies/profile_exact.py's split, ms per event). A study not run is reported as missing.

    python studies/goals33.py [--out DIR]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path


def load(out: Path, name: str) -> dict | None:
    path = out / name / f"{name}.json"
    return json.loads(path.read_text()) if path.is_file() else None


def split(prof: dict | None, case: str) -> str:
    """'search a, lcp b, ...' ms per event of the compiled run of ``case``, largest first."""
    if not prof or case not in prof or "compiled" not in prof[case]:
        return "not profiled"
    parts = prof[case]["compiled"]["parts_ms_per_event"]
    return ", ".join(f"{k} {v:.3g}" for k, v in sorted(parts.items(), key=lambda kv: -kv[1]))


def yes(flag: bool | None) -> str:
    return "missing" if flag is None else ("met" if flag else "**not met**")


def rows(out: Path) -> list[tuple]:
    wp, f3, sc = load(out, "work_precision"), load(out, "paper_figure3"), load(out, "scaling")
    rub, un, prof = load(out, "rub"), load(out, "unreduced"), load(out, "profile_exact")
    table = []
    if prof and "stop" in prof and "compiled" in prof["stop"]:
        c, p = prof["stop"]["compiled"], prof["stop"]["python"]
        ratio = p["ms_per_event"] / c["ms_per_event"]
        table.append(("stop scene: compiled core vs pure Python, per event (>= 8x, <= 0.1 ms)",
                      f"{c['ms_per_event']:.3f} vs {p['ms_per_event']:.3f} ms/event ({c['events']} events, best of "
                      f"{c.get('repeat', prof.get('repeat'))})", f"{ratio:.2f}x", yes(ratio >= 8 and c["ms_per_event"] <= 0.1),
                      split(prof, "stop")))
    for case in ("shipped", "rub", "fig3-modal16", "fig3-cb16"):
        if prof and case in prof and "compiled" in prof[case]:
            c, p = prof[case]["compiled"], prof[case]["python"]
            table.append((f"{case}: compiled vs pure Python, per event (no goal of its own)",
                          f"{c['ms_per_event']:.3f} vs {p['ms_per_event']:.3f} ms/event ({c['events']} events)",
                          f"{p['ms_per_event'] / c['ms_per_event']:.2f}x", "-", split(prof, case)))
    if wp:
        for name, p in (("shipped", wp), ("stop", wp.get("stop"))):
            if not p:
                continue
            rk = p["speedup_at_equal_error"].get("rk")
            own = p["speedup_at_own_best_error"].get("rk")
            if name == "stop":
                if rk is not None:
                    table.append(("stop scene: rk at exact's error over exact (>= 10x)", f"exact error "
                                  f"{p['exact_error_bound']:.2g}", f"{rk:.3g}x", yes(rk >= 10), split(prof, "stop")))
                else:
                    table.append(("stop scene: rk at exact's error over exact (>= 10x)",
                                  f"rk never reaches exact's error {p['exact_error_bound']:.2g} (rtol down to 1e-10); "
                                  f"its best {own['best_error']:.2g} takes {own['wall_s']:.3g} s vs exact "
                                  f"{p['exact_wall_s']:.3g} s", f"{own['speedup']:.3g}x at rk's best error",
                                  "met at equal error (rk never gets there); not met at rk's best", split(prof, "stop")))
            f = p["fastest_any_answer"]
            table.append((f"{name} scene ({p['t_end']:g} s): no other method answers faster than exact",
                          f"fastest other: {f['method']} {f['setting']} {f['wall_s']:.3g} s (gap error "
                          f"{f['error']:.2g}) vs exact {f['exact_wall_s']:.3g} s ({p['exact_events']} events)",
                          f"{f['speedup']:.3g}x exact's time", yes(f["exact_is_fastest"]), split(prof, name)))
    if f3:
        for name, g in f3.get("goals", {}).items():
            case = "fig3-modal16" if name.startswith("modal") else "fig3-cb16"
            run = next(c for c in f3["cost"]["runs"] if f"{c['reduction']} {c['ndof']}" == name)
            rk = run["rk"]
            table.append((f"figure 3, {name}: rk rtol 1e-6 over exact (>= 10x)",
                          f"exact {run['exact']['wall_s']:.3g} s ({run['exact']['events']} events), rk "
                          + (f"{rk['wall_s']:.3g} s" if rk.get("error") is not None else "failed")
                          + f"; {f3['cost']['t_end']:g} s, best of {f3['cost']['repeat']} interleaved",
                          "-" if g["rk_over_exact"] is None else f"{g['rk_over_exact']:.3g}x", yes(g["rk_goal_met"]),
                          split(prof, case)))
            first = g["fastest_other"]
            table.append((f"figure 3, {name}: no other method answers faster than exact",
                          "no other answer" if first is None else
                          f"fastest other: {first} {run[first]['wall_s']:.3g} s (gap error {run[first]['error']:.2g})",
                          "-" if first is None else f"{g['fastest_other_over_exact']:.3g}x exact's time",
                          yes(g["exact_is_fastest"]), ""))
    if rub:
        m = rub["methods"]
        ex = m[0]
        others = "; ".join(f"{x['method']} " + (f"{x['wall_s']:.3g} s" if x["wall_s"] is not None else "no answer")
                           for x in m[1:])
        fo = rub.get("fastest_other")
        table.append((f"shipped rub ({rub['t_end']:g} s): no other method answers faster than exact",
                      f"exact {ex['wall_s']:.3g} s; {others}",
                      "-" if fo is None else f"{fo['over_exact_wall']:.3g}x exact's time ({fo['method']})",
                      yes(rub.get("exact_is_fastest")), split(prof, "rub")))
        for r in rub.get("round_vs_baseline", []):
            label = f"{r['scene']} {r['overrides']}" + (f" + {r['this_commit_adds']} now" if r.get("this_commit_adds")
                                                        else "")
            sp = r.get("speedup")
            table.append((f"{label}: integration vs {rub['baseline_commit']} (>= 10x)",
                          f"{r.get('baseline_wall_s', float('nan')):.3g} s -> {r.get('round_wall_s', float('nan')):.3g} s"
                          f"; events {r.get('baseline_events')} -> {r.get('round_events')}",
                          "-" if sp is None else f"{sp:.3g}x", yes(None if sp is None else sp >= 10), ""))
    if un:
        fo = un["fastest_other"]
        per = "; ".join(f"{r['method']} {r['setting']}: " + (f"{r['wall_over_exact']:.3g}x (gap error {r['gap_error']:.2g})"
                                                             if "wall_over_exact" in r else
                                                             f"> {r['wall_over_exact_at_least']:.3g}x (no answer in "
                                                             f"{r['budget_s']:g} s)" if "wall_over_exact_at_least" in r
                                                             else r["status"]) for r in un["runs"][1:])
        table.append((f"unreduced shipped scene ({un['ndof']} dofs, {un['t_end']:g} s from rest): exact first of the four",
                      f"exact {un['exact_wall_s']:.3g} s ({un['exact_events']} events); {per}",
                      "-" if fo is None else f"{fo['wall_over_exact']:.3g}x exact's time ({fo['method']} {fo['setting']})",
                      yes(un["exact_is_fastest"]), split(prof, "unreduced")))
    if sc:
        g = sc.get("search_per_sample_term_goal")
        if g and g.get("reference"):
            per = "; ".join(f"{k} ({v['ndof']} dofs) {v['search_ns_per_sample_term']:.3g} ns: {v['over_cb16']:.3g}x"
                            for k, v in g["unreduced"].items())
            worst = max((v["over_cb16"] for v in g["unreduced"].values()), default=None)
            table.append(("scaling: unreduced search cost per row-term-sample within 2x of Craig-Bampton 16's",
                          f"CB 16 {g['reference']['search_ns_per_sample_term']:.3g} ns; {per}",
                          "-" if worst is None else f"up to {worst:.3g}x", yes(g["met"]), ""))
    ct = load(out, "cli_time")
    if ct and ct.get("base_over_this") is not None:
        table.append((f"nsfem run, shipped scene, whole command: not slower than {ct['base_commit']}",
                      f"{ct['base']['command_s']:.3g} s -> {ct['this']['command_s']:.3g} s (integration "
                      f"{ct['base']['integration_s']:.3g} -> {ct['this']['integration_s']:.3g} s), best of {ct['repeat']}",
                      f"{ct['base_over_this']:.3g}x", yes(ct["not_slower"]), ""))
    return table


def markdown(table: list[tuple]) -> str:
    head = "| goal | measured side by side (one run) | ratio | | where exact's time goes (compiled, ms/event) |\n" \
           "|---|---|---|---|---|\n"
    return head + "".join("| " + " | ".join(str(c).replace("|", "/") for c in row) + " |\n" for row in table)


def main(argv=None) -> str:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "out")
    args = ap.parse_args(argv)
    text = "# Issue 33's goals, measured\n\n" + markdown(rows(args.out))
    missing = [n for n in ("work_precision", "paper_figure3", "scaling", "rub", "unreduced", "profile_exact", "cli_time")
               if load(args.out, n) is None]
    if missing:
        text += "\nNot run: " + ", ".join(missing) + "\n"
    tmp = args.out / "goals33.md.tmp"
    tmp.write_text(text)
    tmp.replace(args.out / "goals33.md")
    print(text)
    return text


if __name__ == "__main__":
    main()
