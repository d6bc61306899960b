"""ROSS 2.3.0 reference numbers with shear on (its default ShaftElement) for tests/test_timoshenko.py.

Run with ROSS's interpreter: /work/rossvenv/bin/python studies/ross_timoshenko.py
rotor3 of ross/tests/test_rotor_assembly.py: 6 Timoshenko elements of 0.25 m, 50 mm steel shaft (E 211e9,
G_s 81.2e9, rho 7810), disks from geometry at nodes 2 (outer 0.28 m) and 4 (outer 0.35 m), bore 0.05 m,
width 0.07 m, bearings kxx = 1e6, kyy = 8e5 N/m at nodes 0 and 6. Prints the lowest 8 lateral damped
frequencies wd [rad/s] of run_modal at a few speeds, the element's kappa and phi, and the critical speeds
(speeds where a root of run_modal has wd equal to the speed, brentq on wd(Omega) - Omega).
"""

import numpy as np
import ross as rs
from ross.materials import steel
from scipy.optimize import brentq


def rotor3(shear=True):
    elems = [rs.ShaftElement(0.25, 0.0, 0.05, material=steel, shear_effects=shear, rotary_inertia=True,
                             gyroscopic=True) for _ in range(6)]
    d0 = rs.DiskElement.from_geometry(2, steel, 0.07, 0.05, 0.28)
    d1 = rs.DiskElement.from_geometry(4, steel, 0.07, 0.05, 0.35)
    b0 = rs.BearingElement(0, kxx=1e6, kyy=0.8e6, cxx=0)
    b1 = rs.BearingElement(6, kxx=1e6, kyy=0.8e6, cxx=0)
    return rs.Rotor(elems, [d0, d1], [b0, b1])


def lateral_wd(rotor, speed, count=8):
    """The lowest ``count`` damped frequencies [rad/s] of run_modal whose mode moves a node laterally (ROSS's
    6 dofs per node: x, y, z, alpha, beta, theta; its axial and torsional modes left out)."""
    m = rotor.run_modal(speed, num_modes=2 * count + 8)
    nodes = rotor.nodes[-1] + 1
    lateral = np.r_[[6 * n + k for n in range(nodes) for k in (0, 1)]]
    keep = [w for i, w in enumerate(np.asarray(m.wd))
            if np.linalg.norm(m.evectors[lateral, i]) > 1e-6 * np.linalg.norm(m.evectors[:, i])]
    return np.array(keep[:count])


if __name__ == "__main__":
    np.set_printoptions(precision=10, linewidth=150)
    r = rotor3()
    e = r.shaft_elements[0]
    print("kappa", repr(e.kappa), "phi", repr(e.phi), "Poisson", repr(steel.Poisson))
    for speed in (0.0, 100.0, 300.0, 1000.0):
        print(speed, repr(lateral_wd(r, speed).tolist()))
    for k in range(4):
        print("critical", k, repr(brentq(lambda s, k=k: lateral_wd(r, s)[k] - s, 50.0, 400.0, xtol=1e-12)))
    example = rs.rotor_example()               # as shipped: shear on, the same element
    for speed in (0.0, 500.0):
        print("rotor_example", speed, repr(lateral_wd(example, speed).tolist()))
