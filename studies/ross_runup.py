"""Reference run-up for nsfem's variable-speed integrators (issue 35, item 7): ROSS 2.3.0 integrates a small rotor
run up linearly through its first critical speed; this script writes tests/data/ross_runup.json (the rotor, the ramp,
the unbalance and its conventions, the integrator and its settings, the disk's y and z every 1 ms, ROSS's
angular-acceleration matrices) and prints the convergence and Kst checks. Run it with ROSS's own interpreter:

    /work/rossvenv/bin/python studies/ross_runup.py

The same rotor in nsfem's format is tests/data/ross_runup.toml. Axes: ROSS's x (horizontal) is nsfem's y, its y
nsfem's z, its shaft axis z nsfem's x (a cyclic permutation: both right-handed, the spin turns from y towards z).

Rotor: 1.0 m steel shaft of 40 mm in 10 Rayleigh elements (shear_effects=False, rotary_inertia=True,
gyroscopic=True: nsfem's [beam] theory = "rayleigh"), a disk from geometry (outer 0.24 m, bore 0.04 m, width
0.04 m, steel) at node 3 (x = 0.3 m: off centre, so that it tilts in the first mode and its gyroscopic and
angular-acceleration terms act), isotropic bearings k = 2e6 N/m, c = 600 N s/m at both ends. First critical
speed about 38.2 Hz (log dec about 0.08). Ramp: 20 -> 60 Hz linearly in 1.5 s (alpha = 167.6 rad/s^2).
"""
import json
import sys
import time
from pathlib import Path

import numpy as np
import ross as rs

OUT = Path(__file__).resolve().parents[1] / "tests" / "data" / "ross_runup.json"

E, RHO, POISSON = 2.11e11, 7810.0, 0.3
L, D, N_EL = 1.0, 0.04, 10
DISK_NODE, DISK_OD, DISK_ID, DISK_W = 3, 0.24, 0.04, 0.04
K_B, C_B = 2e6, 600.0
F0_HZ, F1_HZ, RAMP_S = 20.0, 60.0, 1.5
UNBALANCE = 1e-4        # kg m, at the disk node
PHASE = 0.0             # rad: at t = 0 the unbalance points along ROSS's +x (nsfem's +y)
DT_OUT = 1e-3           # recorded every 1 ms
DT = 2.5e-5             # integration step (40 per recorded sample); DT / 2 checks convergence
NEWMARK = {"gamma": 0.5, "beta": 0.25, "tol": 1e-9}   # average acceleration (trapezoidal), unconditionally stable


def build():
    steel = rs.Material(name="steel_runup", rho=RHO, E=E, Poisson=POISSON)
    shaft = [rs.ShaftElement(L=L / N_EL, idl=0.0, odl=D, material=steel, shear_effects=False, rotary_inertia=True,
                             gyroscopic=True) for _ in range(N_EL)]
    disk = rs.DiskElement.from_geometry(n=DISK_NODE, material=steel, width=DISK_W, i_d=DISK_ID, o_d=DISK_OD)
    brg = [rs.BearingElement(n=n, kxx=K_B, kyy=K_B, cxx=C_B, cyy=C_B) for n in (0, N_EL)]
    return rs.Rotor(shaft, [disk], brg), shaft, disk


def run(rotor, dt, zero_kst=False):
    """(t, y, z) of the disk node, sampled every DT_OUT, integrated with step ``dt``."""
    n = int(round(RAMP_S / dt))
    t = np.linspace(0.0, RAMP_S, n + 1)
    speed = 2 * np.pi * (F0_HZ + (F1_HZ - F0_HZ) * t / RAMP_S)        # rad/s
    F = rotor.unbalance_force_over_time([DISK_NODE], [UNBALANCE], [PHASE], speed, t).T
    extra = {"Ksdt": np.zeros((rotor.ndof, rotor.ndof))} if zero_kst else {}
    _, y, _ = rotor.time_response(speed, F, t, method="newmark", **NEWMARK, **extra)
    every = int(round(DT_OUT / dt))
    i = rotor.number_dof * DISK_NODE
    return t[::every], y[::every, i], y[::every, i + 1]


def pattern(A, ross_names, names):
    """Nonzero entries of a local matrix as [ROSS row dof, ROSS column dof, nsfem row dof, nsfem column dof, value]."""
    return [[ross_names[i], ross_names[j], names[i], names[j], float(A[i, j])] for i, j in zip(*np.nonzero(A))]


def steady_peak(rotor):
    """The constant-speed unbalance response's largest disk orbit radius over 20-60 Hz (0.01 Hz grid) and its speed:
    the slow limit of the run-up (ROSS's run_unbalance_response, same rotor and unbalance)."""
    f = np.arange(F0_HZ, F1_HZ + 1e-9, 0.01)
    r = rotor.run_unbalance_response(node=DISK_NODE, unbalance_magnitude=UNBALANCE, unbalance_phase=PHASE,
                                     frequency=2 * np.pi * f)
    i = rotor.number_dof * DISK_NODE
    a, b = r.forced_resp[i], r.forced_resp[i + 1]
    # the orbit's semi-major axis: sqrt((|a|^2 + |b|^2 + |a^2 + b^2|) / 2)
    major = np.sqrt(0.5 * (np.abs(a) ** 2 + np.abs(b) ** 2 + np.abs(a * a + b * b)))
    k = int(np.argmax(major))
    return {"amplitude_m": float(major[k]), "speed_hz": float(f[k]), "grid_hz": 0.01,
            "what": "the largest semi-major axis of the disk's steady 1x orbit over 20-60 Hz (constant speed)"}


def steady_response(rotor, speeds_hz=(20.0, 38.5, 60.0)):
    """ROSS's steady unbalance response of the disk (run_unbalance_response) at a few constant speeds: complex
    amplitudes Z of y and z with y(t) = Re(Z_y e^{i Omega t}) (the unbalance along +y at t = 0, turning towards +z:
    the force m e Omega^2 (cos Omega t, sin Omega t) of the run's phi at constant speed)."""
    f = np.asarray(speeds_hz)
    r = rotor.run_unbalance_response(node=DISK_NODE, unbalance_magnitude=UNBALANCE, unbalance_phase=PHASE,
                                     frequency=2 * np.pi * f)
    i = rotor.number_dof * DISK_NODE
    a, b = r.forced_resp[i], r.forced_resp[i + 1]
    return {"speeds_hz": f.tolist(), "y_re": a.real.tolist(), "y_im": a.imag.tolist(), "z_re": b.real.tolist(),
            "z_im": b.imag.tolist(), "convention": "y(t) = Re(Z_y e^{i Omega t}), z(t) = Re(Z_z e^{i Omega t})"}


def main():
    rotor, shaft, disk = build()
    modal = rotor.run_modal(speed=0.0)
    t0 = time.time()
    t, y, z = run(rotor, DT)
    t_fine, y_fine, z_fine = run(rotor, DT / 2)
    _, y_nokst, z_nokst = run(rotor, DT, zero_kst=True)
    elapsed = time.time() - t0
    amp = np.hypot(y, z)
    peak = float(np.max(amp))
    conv = float(np.max(np.hypot(y - y_fine, z - z_fine)))
    kst = float(np.max(np.hypot(y - y_nokst, z - z_nokst)))
    ipk = int(np.argmax(amp))
    crit = rotor.run_critical_speed()
    local = ["y_0", "z_0", "x_0", "rot_y_0", "rot_z_0", "rot_x_0", "y_1", "z_1", "x_1", "rot_y_1", "rot_z_1", "rot_x_1"]
    ross_names = list(shaft[0].dof_mapping().keys())
    data = {
        "source": "ROSS 2.3.0 (ross-rotordynamics), studies/ross_runup.py, run with /work/rossvenv/bin/python",
        "axes": "ROSS x (horizontal) = nsfem y, ROSS y = nsfem z, ROSS z (shaft axis) = nsfem x; the spin turns "
                "from +y towards +z (nsfem names below)",
        "rotor": {"shaft": {"length_m": L, "diameter_m": D, "elements": N_EL, "E_Pa": E, "rho_kg_m3": RHO,
                            "poisson": POISSON, "beam": "rayleigh (shear_effects=False, rotary_inertia=True, "
                            "gyroscopic=True)"},
                  "disk": {"x_m": DISK_NODE * L / N_EL, "node": DISK_NODE, "outer_diameter_m": DISK_OD,
                           "inner_diameter_m": DISK_ID, "width_m": DISK_W, "rho_kg_m3": RHO, "mass_kg": disk.m,
                           "polar_inertia_kg_m2": disk.Ip, "diametral_inertia_kg_m2": disk.Id},
                  "bearings": [{"x_m": 0.0, "kyy": K_B, "kzz": K_B, "cyy": C_B, "czz": C_B},
                               {"x_m": L, "kyy": K_B, "kzz": K_B, "cyy": C_B, "czz": C_B}],
                  "first_critical_speeds_hz": [float(x) for x in crit.wd()[:2] / (2 * np.pi)],
                  "natural_frequencies_at_rest_hz": [float(x) for x in modal.wd[:4] / (2 * np.pi)]},
        "ramp": {"speed_hz": F0_HZ, "ramp_to_hz": F1_HZ, "ramp_s": RAMP_S, "law": "Omega(t) = 2 pi (speed_hz + "
                 "(ramp_to_hz - speed_hz) t / ramp_s), angle phi(t) = phase + integral of Omega (cumulative trapezoid, "
                 "exact for the ramp)", "alpha_rad_s2": 2 * np.pi * (F1_HZ - F0_HZ) / RAMP_S},
        "unbalance": {"x_m": DISK_NODE * L / N_EL, "magnitude_kg_m": UNBALANCE, "phase_rad": PHASE,
                      "force": "F_y = m e (Omega^2 cos phi + alpha sin phi), F_z = m e (Omega^2 sin phi - alpha cos "
                               "phi): the reaction of the unbalance mass at angle phi from +y towards +z (ROSS's "
                               "unbalance_force_over_time)"},
        "initial": "rest: zero displacement, velocity and acceleration at t = 0 (ROSS's newmark starts there, even "
                   "though the unbalance force is not zero at t = 0)",
        "integrator": {"method": "ross.utils.newmark via Rotor.time_response(speed array, method='newmark'): M y'' "
                       "+ (C + Omega(t) G) y' + (K + alpha(t) Ksdt) y = F(t)", **NEWMARK, "dt_s": DT},
        "gravity": 0.0,
        "dt_out_s": DT_OUT,
        "t_s": [round(float(x), 9) for x in t],
        "disk_y_m": [float(f"{x:.9e}") for x in y],
        "disk_z_m": [float(f"{x:.9e}") for x in z],
        "steady_peak": steady_peak(rotor),
        "steady_response": steady_response(rotor),
        "peak": {"amplitude_m": peak, "t_s": float(t[ipk]),
                 "speed_hz": F0_HZ + (F1_HZ - F0_HZ) * float(t[ipk]) / RAMP_S,
                 "what": "the largest sqrt(y^2 + z^2) of the recorded samples in the run-up"},
        "convergence": {"max_difference_dt_half_m": conv, "relative_to_peak": conv / peak},
        "kst_effect": {"max_difference_without_Ksdt_m": kst, "relative_to_peak": kst / peak},
        "kst": {"note": "the angular-acceleration stiffness, K += alpha(t) Kst (ROSS: Rotor.Ksdt, DiskElement.Kdt, "
                        "ShaftElement.Kst); entries [ROSS row, ROSS column, nsfem row, nsfem column, value]: ROSS's "
                        "x, y, z, alpha (about x), beta (about y), theta (about z, torsion) are nsfem's y, z, x, "
                        "rot_y, rot_z, rot_x",
                "ross_local_dofs": ross_names, "nsfem_local_dofs": local,
                "disk": pattern(disk.Kdt(), ross_names[:6], local[:6]), "disk_Ip": disk.Ip,
                "shaft_element": pattern(shaft[0].Kst(), ross_names, local),
                "shaft_element_formula": "rho Ie / (15 L) x [[0,-36,0,3L,...]] (ROSS ShaftElement.Kst), Ie the "
                                         "area moment, L the element length",
                "shaft_element_L_m": L / N_EL},
    }
    OUT.write_text(json.dumps(data, separators=(",", ":")) + "\n")
    print(json.dumps({k: data[k] for k in ("peak", "steady_peak", "convergence", "kst_effect")}), f"{elapsed:.1f} s",
          file=sys.stderr)


if __name__ == "__main__":
    main()
