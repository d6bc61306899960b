"""ROSS 2.3.0 reference numbers for the shipped scene nsfem/scenes/stepped_rotor.toml (docs/validation.md, tests/
test_campbell_references.py). Run it with ROSS's own interpreter:

    /work/rossvenv/bin/python studies/ross_stepped_rotor.py

It reads the scene file itself (one source for both models) and builds ROSS's rotor of the same elements: 24
ShaftElements of 50 mm of the scene's material (rho, E and G: Material(rho, E, G_s), so nu = E / (2 G) - 1 on both
sides), shear_effects as the scene's [beam] theory says (timoshenko: True, with shear_method_calc = the scene's
shear_coefficient, cowper by default, ROSS's default too; rayleigh: False), rotary_inertia=True, gyroscopic=True, the
diameters of the [[shaft.step]] tables, DiskElement.from_geometry for each [[disk]], and per [[bearing]] a
BearingElement at its node. `--theory rayleigh` runs the same rotor without shear (shear_effects=False) whatever
the scene says: the numbers of the scene before it took shear (docs/validation.md compares the two). Axes: nsfem's
y, z are ROSS's x, y (kyz = ROSS's kxy, kzy = ROSS's kyx, likewise c).

Bearing tables: ROSS interpolates a coefficient table with a smoothing cubic spline (UnivariateSpline), nsfem
linearly; the two differ between the table's speeds. So every ROSS number here is computed with constant-coefficient
BearingElements holding nsfem's linear interpolation at the speed (np.interp of the scene's table): at the table's
own speeds (50 and 100 Hz below) both interpolations are the table. The thrust bearing (kxx) has no ROSS
counterpart (its axial motion is free); axial modes are not compared.

run_modal is called with sparse=False (a dense eig of ROSS's state matrix): its default shift-invert Arnoldi (sigma=1)
returns the bending modes above 500 Hz 3e-9 to 4e-9 off the dense eigenvalues of the same matrix (which nsfem's
dense and Arnoldi solvers both reproduce to 1e-12), the heavily damped bearings making those roots ill-conditioned
for it; the dense solve is the reference.

Prints one JSON object: damped frequencies [Hz] and log decrements of the lowest lateral modes at 50 and 100 Hz
(run_modal), and the damped critical speeds (speeds s where a damped root's wd / 2 pi = s, Brent on each sign change
of the ordered roots' wd / 2 pi - s over 10-150 Hz, rebuilding the bearings at each trial speed).

The table itself came from ROSS's CylindricalBearing (short-bearing closed form) at 900 N: CylindricalBearing(n, speed
= 2 pi [10, 25, 50, 75, 100, 125, 150] rad/s, weight=900, bearing_length=0.035, journal_diameter=0.07,
radial_clearance=70e-6, oil_viscosity=0.02), rounded to 4 digits (`--table` prints it again).
"""
import json
import sys
import tomllib
from pathlib import Path

import numpy as np
import ross as rs
from scipy.optimize import brentq

SCENE = Path(__file__).resolve().parents[1] / "nsfem" / "scenes" / "stepped_rotor.toml"
AXES = {"kyy": "kxx", "kzz": "kyy", "kyz": "kxy", "kzy": "kyx", "cyy": "cxx", "czz": "cyy", "cyz": "cxy", "czy": "cyx"}
SPEEDS_HZ = (50.0, 100.0)
MODES = 8       # lateral modes compared at each speed


def table():
    f = np.array([10, 25, 50, 75, 100, 125, 150.0])
    b = rs.CylindricalBearing(n=0, speed=2 * np.pi * f, weight=900, bearing_length=0.035, journal_diameter=0.07,
                              radial_clearance=70e-6, oil_viscosity=0.02)
    for k, r in AXES.items():
        print(f"{k} = [" + ", ".join(f"{x:.4g}" for x in getattr(b, r)) + "]")


def rotor_at(scene, speed_hz):
    """ROSS's rotor with the bearings' coefficients interpolated linearly at ``speed_hz``."""
    sh = scene["shaft"]
    n_el = scene["mesh"]["elements"]
    h = sh["length"] / n_el
    G = sh.get("G", sh["E"] / (2 * (1 + 0.3)))         # nsfem's default: nu = 0.3
    steel = rs.Material(name="steel_stepped", rho=sh["rho"], E=sh["E"], G_s=G)
    theory = scene.get("beam", {}).get("theory", "euler-bernoulli")
    if theory not in ("rayleigh", "timoshenko"):
        raise ValueError(f"beam.theory {theory!r}: ROSS's element has rotary inertia (rayleigh or timoshenko)")
    shear = theory == "timoshenko"
    method = scene.get("beam", {}).get("shear_coefficient", "cowper")

    def diameter(x):
        for st in sh.get("step", []):
            if st["start"] <= x <= st["end"]:
                return st["diameter"]
        return sh["diameter"]

    shaft = [rs.ShaftElement(L=h, idl=0.0, odl=diameter((i + 0.5) * h), material=steel, shear_effects=shear,
                             shear_method_calc=method, rotary_inertia=True, gyroscopic=True) for i in range(n_el)]
    disks = [rs.DiskElement.from_geometry(n=int(round(d["x"] / h)), material=rs.Material(
        name=f"disk_{i}", rho=d["rho"], E=sh["E"], Poisson=0.3), width=d["width"], i_d=d["inner_diameter"],
        o_d=d["outer_diameter"]) for i, d in enumerate(scene["disk"])]
    bearings = []
    for b in scene["bearing"]:
        if "kyy" not in b:
            continue  # the thrust bearing: no ROSS counterpart
        kw = {r: float(np.interp(speed_hz, b["speeds_hz"], b[k])) if k in b else 0.0 for k, r in AXES.items()}
        if not b["speeds_hz"][0] <= speed_hz <= b["speeds_hz"][-1]:
            raise ValueError(f"{speed_hz} Hz outside the table")
        bearings.append(rs.BearingElement(n=int(round(b["x"] / h)), **kw))
    return rs.Rotor(shaft, disks, bearings)


def lateral(scene, speed_hz, count=MODES + 6):
    """(wd [Hz], log dec) of the roots with wd > 0 at ``speed_hz``, ascending; ROSS's free axial and torsional
    motion (rigid: wd = 0) left out."""
    m = rotor_at(scene, speed_hz).run_modal(speed=2 * np.pi * speed_hz, sparse=False)
    wd, ld = np.asarray(m.wd) / (2 * np.pi), np.asarray(m.log_dec)
    keep = wd > 1.0
    order = np.argsort(wd[keep])
    return wd[keep][order], ld[keep][order]


def critical_speeds(scene, lo, hi, n=141):
    grid = np.linspace(lo, hi, n)
    k = 6
    table = np.array([lateral(scene, s)[0][:k] for s in grid]) - grid[:, None]
    out = []
    for j in range(k):
        g = table[:, j]
        for i in np.flatnonzero(np.sign(g[:-1]) != np.sign(g[1:])):
            s = brentq(lambda s: lateral(scene, s)[0][j] - s, grid[i], grid[i + 1], xtol=1e-10, rtol=1e-13)
            wd, ld = lateral(scene, s)
            out.append({"speed_hz": s, "log_decrement": float(ld[j]), "order": j})
    return sorted(out, key=lambda c: c["speed_hz"])


def main():
    if "--table" in sys.argv:
        return table()
    scene = tomllib.loads(SCENE.read_text())
    if "--theory" in sys.argv:
        scene["beam"] = {**scene.get("beam", {}), "theory": sys.argv[sys.argv.index("--theory") + 1]}
    out = {"source": "ROSS 2.3.0, studies/ross_stepped_rotor.py", "theory": scene["beam"]["theory"], "speeds": {}}
    for s in SPEEDS_HZ:
        wd, ld = lateral(scene, s)
        out["speeds"][f"{s:g}"] = {"frequencies_hz": wd[:MODES].tolist(), "log_decrements": ld[:MODES].tolist()}
    lo = max(b["speeds_hz"][0] for b in scene["bearing"] if "speeds_hz" in b)
    hi = min(b["speeds_hz"][-1] for b in scene["bearing"] if "speeds_hz" in b)
    out["critical_speeds"] = critical_speeds(scene, lo, hi)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
