"""Element refinement of Hermite beam frequencies: h^4 convergence and the round-off floor.

Pinned-pinned uniform beam (analytic (n pi)^2 sqrt(EI/rhoA) / L^2): relative error of the
first three bending frequencies against the number of elements, from the shift-invert
Lanczos solver nsfem uses and from dense LAPACK (for comparison), and the shipped scene's
first open and closed frequencies against the number of elements. Writes CSV and PNG.

    python studies/hermite_refinement.py [--quick] [--out DIR]
"""

from __future__ import annotations

import argparse
import csv
import json
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sla

import nsfem
from nsfem.scene import scene_from_tree

E, RHO, B, H = 2.1e11, 7800.0, 0.03, 0.01


def uniform(elements: int):
    tree = {"shaft": {"width": B, "height": H, "E": E, "rho": RHO, "supports": "pinned-pinned"},
            "mesh": {"elements": elements}, "reduction": {"method": "none"}}
    return nsfem.build_model(scene_from_tree(tree))


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer meshes (under a minute)")
    ap.add_argument("--out", default="studies/out/hermite_refinement")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    sizes = [5, 10, 20, 40, 80, 160, 320, 640] if args.quick else [5, 10, 20, 40, 80, 160, 320, 640, 1280, 2560]
    exact = (np.pi * np.arange(1, 4)) ** 2 * np.sqrt(E * B * H**3 / 12 / (RHO * B * H)) / (2 * np.pi)
    rows = []
    for n in sizes:
        model = uniform(n)
        t0 = time.perf_counter()
        modes = nsfem.natural_frequencies(model, "open", 12)
        wall = time.perf_counter() - t0
        w = np.array([f for f, fld in zip(modes.frequencies_hz, modes.fields) if fld == "W"])[:3]
        row = {"elements": n, "ndof": model.n, "wall_s": wall,
               **{f"err{k + 1}": abs(w[k] / exact[k] - 1) for k in range(3)}}
        if model.n <= 3500:  # dense for comparison
            lam = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True)
            f = np.sort(np.sqrt(np.abs(lam)) / (2 * np.pi))
            row["dense_err1"] = float(np.min(np.abs(f / exact[0] - 1)))
        rows.append(row)
        print(json.dumps(row))
    scene_rows = []
    for n in ([20, 40, 80, 160] if args.quick else [20, 40, 80, 160, 320, 640]):
        model = nsfem.build_model(nsfem.load_scene(None, [f"mesh.elements={n}"]))
        fo = nsfem.natural_frequencies(model, "open", 3).frequencies_hz
        fc = nsfem.natural_frequencies(model, "closed", 3).frequencies_hz
        scene_rows.append({"elements": n, "open1": fo[0], "open3": fo[2], "closed1": fc[0], "closed3": fc[2]})
        print(json.dumps(scene_rows[-1]))
    for name, data in (("uniform_beam.csv", rows), ("default_scene.csv", scene_rows)):
        keys = sorted({k for r in data for k in r}, key=lambda k: list(data[-1]).index(k) if k in data[-1] else 99)
        with open(out / name, "w", newline="") as fh:
            wr = csv.DictWriter(fh, keys)
            wr.writeheader()
            wr.writerows(data)
    plot(rows, out / "hermite_refinement.png")
    return {"uniform": rows, "scene": scene_rows}


def plot(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = np.array([r["elements"] for r in rows])
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for k, marker in zip(range(1, 4), "osd"):
        ax.loglog(n, [r[f"err{k}"] for r in rows], marker=marker, label=f"mode {k}, shift-invert (nsfem)")
    dn = [(r["elements"], r["dense_err1"]) for r in rows if "dense_err1" in r]
    ax.loglog(*zip(*dn), "k--x", label="mode 1, dense LAPACK")
    ax.loglog(n, (np.pi / n) ** 4 / 1440, ":", color="gray", label=r"$(\beta h)^4/1440$ (mode 1 estimate)")
    ax.set_xlabel("elements over the length")
    ax.set_ylabel("relative frequency error")
    ax.set_title("Pinned-pinned Hermite beam: h$^4$ convergence, round-off floor")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    tmp = path.with_name(path.stem + ".tmp.png")
    fig.savefig(tmp, dpi=120)
    tmp.replace(path)


if __name__ == "__main__":
    main()
