"""Cost and accuracy of the reductions on the shipped scene at increasing mesh sizes.

For each mesh: the full model's assembly and eigen time, then for modal truncation and
Craig-Bampton with several mode counts: reduction time, ndof, and the largest relative
error of the first six open and closed frequencies and of the first gravity resonance
(open) against the full model. Prints one JSON object (``--json``) or a table; writes
``reduction_benchmark.json`` and ``.csv`` into ``--out``.

    python studies/reduction_benchmark.py [--quick] [--json] [--out DIR]
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np

import nsfem
from nsfem.analysis.campbell import gravity_resonances
from nsfem.analysis.modes import contact_basis
from nsfem.fem.rotating import rotor_operators
from nsfem.reduce import reduce


def errors(model, full, red):
    out = {}
    for c in ("open", "closed"):
        try:
            m = nsfem.natural_frequencies(model, c, 6, red)
            f = m.frequencies_hz
            if len(f) < len(full[c]) or m.fields.count("W") < full[c + "_w"]:
                out[c] = "frozen"  # shapes missing: closure left too few coordinates
            else:
                mask = full[c] > 0
                out[c] = float(np.abs(f[mask] / full[c][mask] - 1).max())
        except nsfem.NsfemError:
            out[c] = "frozen"
    g = gravity_resonances(rotor_operators(model, contact_basis(model, "open", red)))[0]
    out["gravity"] = float(abs(g[0] / full["gravity"] - 1)) if len(g) else None
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two meshes, fewer mode counts (under a minute)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--out", default="studies/out/reduction_benchmark")
    args = ap.parse_args(argv)
    meshes = [20, 40] if args.quick else [20, 40, 80, 160, 320]
    counts = [8, 16, 32] if args.quick else [8, 16, 32, 64]
    rows = []
    for elements in meshes:
        t0 = time.perf_counter()
        model = nsfem.build_model(nsfem.load_scene(None, [f"mesh.elements={elements}"]))
        t_build = time.perf_counter() - t0
        t0 = time.perf_counter()
        full = {}
        for c in ("open", "closed"):
            m = nsfem.natural_frequencies(model, c, 6)
            full[c], full[c + "_w"] = m.frequencies_hz, m.fields.count("W")
        t_eig = time.perf_counter() - t0
        full["gravity"] = gravity_resonances(rotor_operators(model))[0][0]
        rows.append({"elements": elements, "method": "none", "modes": None, "ndof": model.n,
                     "reduce_s": 0.0, "build_s": t_build, "eigen_s": t_eig,
                     "err_open": 0.0, "err_closed": 0.0, "err_gravity": 0.0})
        for method in ("modal", "craig-bampton"):
            for n in counts:
                if method == "modal" and n >= model.n:
                    continue
                t0 = time.perf_counter()
                red = reduce(model, method, n)
                t_red = time.perf_counter() - t0
                t0 = time.perf_counter()
                e = errors(model, full, red)
                rows.append({"elements": elements, "method": method, "modes": n, "ndof": red.ndof,
                             "reduce_s": t_red, "build_s": t_build, "eigen_s": time.perf_counter() - t0,
                             "err_open": e["open"], "err_closed": e["closed"], "err_gravity": e["gravity"]})
        if not args.json:
            for r in rows[-(1 + 2 * len(counts)):]:
                print(f"{r['elements']:5d} {r['method']:14s} {str(r['modes']):>4s} ndof {r['ndof']:5d} "
                      f"reduce {r['reduce_s']:7.3f} s  err open {_fmt(r['err_open'])} closed "
                      f"{_fmt(r['err_closed'])} gravity {_fmt(r['err_gravity'])}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result = {"scene": "shipped", "frequencies": 6, "rows": rows}
    (out / "reduction_benchmark.json").write_text(json.dumps(result, indent=1))
    with open(out / "reduction_benchmark.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    if args.json:
        print(json.dumps(result))
    return result


def _fmt(x):
    return f"{x:>8s}" if isinstance(x, str) else ("   n/a  " if x is None else f"{x:8.1e}")


if __name__ == "__main__":
    main()
