"""The Jeffcott rub on an ELASTIC ring through the onset of backward whirl (issue 36, goal 2b).

The shipped ``rub`` (5 kg disk at midspan of a light pinned-pinned shaft, 40 N s/m damper at the disk, beta = 1e-5)
with its ring on a radial mount of stiffness k_s (``stator.0.stiffness``, undamped) at friction mu. On the rigid
ring the synchronous full annular rub loses stability only by a Hopf point of the shaft's second bending mode
(``studies/rub_whirl.py``); on a compliant ring the classical mechanism appears (Black 1968; Crandall 1990): the
friction mu N along the ring, with N = k_s (r - c0), acts as a cross-coupled stiffness that feeds a BACKWARD whirl
near the rotor-on-ring frequency sqrt((k + k_s) / m) against the damping.

1. **Closed form** (``tests/rub_reference.py``: :class:`Jeffcott`, :func:`hurwitz`, :func:`jeffcott_onset`): the
   Jeffcott rotor (the model's first mode: modal mass and stiffness with the disk's displacement as coordinate,
   c_e the damper, c_i = beta k the shaft's internal damping) in the rotating frame: the synchronous rub's radius,
   the 4 x 4 linearization (slip, N = k_s (r - c0), the force turning with the contact point), its Routh-Hurwitz
   condition D3 > 0, the onset speed per mu, the whirl frequency w = sqrt(a1 / a3) and its sense in space.
2. **Reduced model's round ring** (``elastic_rub``, ``elastic_ring_operators``: every mode of the 13-coordinate
   Craig-Bampton model): the same onset with the shaft's mass distribution, gyroscopics and second mode.
3. **Exact flow** on the 64-gon (and 128-gon) elastic ring, inertial frame (the polygon turns past the disk, so
   its facets' and corners' laws average to the round ring's, the error second order in 1 / F; in the rotating
   frame the equilibrium rests on one facet (tangential stiffness 0) or in one corner (k_s), neither the round
   ring's N / r: that frame's equilibrium does not converge to the round ring's stability): the onset by Brent's
   method on single orbits' largest multiplier, and a transient past the onset: its growth rate and whirl
   frequency in space (FFT of the disk's deviation, y + i z: negative = backward).

    python studies/rub_backward_whirl.py [--quick] [--json] [--stiffness 2e6] [--mu 0.03] [--facets 64 128]
                                         [--transient-hz F] [--periods 400]

``--quick``: the closed-form and reduced maps only. Writes studies/out/rub_backward_whirl/rub_backward_whirl.json/.csv
and docs/figures/rub_backward_whirl.png.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sla
from scipy.optimize import brentq

from study_io import machine, save_figure, write_outputs

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from nsfem.fem.assemble import build_model  # noqa: E402
from nsfem.fem.components import lateral_turn  # noqa: E402
from nsfem.integrate import ContactSystem  # noqa: E402
from nsfem.reduce import scene_reduction  # noqa: E402
from nsfem.scene.load import load_scene  # noqa: E402
from rub_reference import (Jeffcott, elastic_ring_operators, elastic_rub, jeffcott_onset)  # noqa: E402

OUT = ROOT / "studies" / "out" / "rub_backward_whirl"
FIGURE = ROOT / "docs" / "figures" / "rub_backward_whirl.png"


class ElasticRub:
    """The shipped rub on an undamped elastic ring (k_s, mu, facets, frame): one model and reduction."""

    def __init__(self, stiffness: float, mu: float, facets: int = 64, frame: str = "rotating"):
        self.stiffness, self.mu, self.facets = float(stiffness), float(mu), int(facets)
        self.scene = load_scene("rub", [f"stator.0.stiffness={stiffness}", "stator.0.damping=0",
                                        f"stator.0.friction={mu}", f"stator.0.facets={facets}",
                                        f"rotation.frame={frame}"])
        self.model = build_model(self.scene)
        self.red = scene_reduction(self.scene.reduction, self.model)
        T = np.asarray(self.red.T)
        self.J = np.linalg.lstsq(T, lateral_turn(self.model.spaces, T.shape[0]) @ T, rcond=None)[0]

    def system(self, speed_hz: float) -> ContactSystem:
        return ContactSystem.from_scene(self.scene, self.model, self.red, speed_hz=float(speed_hz))


def modal_jeffcott(rub: ElasticRub) -> Jeffcott:
    """The Jeffcott rotor of the model's first bending mode, the disk's displacement its coordinate: m = phi^T M phi,
    k = phi^T K phi with D phi = (1, 0) (D the ring's rows), c_e = phi^T C_b phi (the damper), c_i = beta k (Rayleigh's
    beta on the shaft alone), the unbalance m_u e at the disk (its modal force, phi = 1 there)."""
    T = np.asarray(rub.red.T)
    M, K = T.T @ rub.model.M_full @ T, T.T @ rub.model.K_full @ T
    lam, V = sla.eigh(K, M)
    R = rub.system(20.0)
    D = np.asarray(R.rings[0].P)
    # the first mode's pair spans a plane; take the combination that moves the disk along D's first row
    pair = V[:, :2]
    phi = pair @ np.linalg.solve(D @ pair, np.array([1.0, 0.0]))
    alpha, beta = rub.scene.damping.rayleigh
    k = float(phi @ K @ phi)
    return Jeffcott(m=float(phi @ M @ phi), k=k, c_e=float(phi @ T.T @ rub.model.C_bearing @ T @ phi),
                    c_i=beta * k + alpha * float(phi @ M @ phi), unbalance=float(rub.model.stack.unbalances[0].magnitude),
                    k_s=rub.stiffness, clearance=float(R.rings[0].clearance), mu=rub.mu)


def reduced_reference(rub: ElasticRub, speed_hz: float) -> dict | None:
    """The reduced model's rub on the elastic ROUND ring at the speed (rotating frame) and the eigenvalue of largest
    real part of its linearization, with the disk's whirl in space (None: no rub)."""
    R = rub.system(speed_hz)
    ring = R.rings[0]
    D = np.asarray(ring.P)
    s = math.copysign(1.0, R.omega)
    try:
        st = elastic_rub(R.Q, R.f0, D, float(ring.clearance), rub.mu, s, rub.stiffness)
    except ValueError:
        return None
    r = float(np.linalg.norm(D @ st.q))
    K, C = elastic_ring_operators(st, r, rub.mu, rub.stiffness, 0.0)
    n = R.n
    A = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-np.linalg.solve(R.M, R.Q + D.T @ K @ D), -np.linalg.solve(R.M, R.C + D.T @ C @ D)]])
    lam, V = np.linalg.eig(A)
    k = int(np.argmax(lam.real + 1e-9 * lam.imag))         # of a conjugate pair, the one with Im > 0
    u = D @ V[:n, k]                                         # the disk's motion, rotating frame, e^{i w t}
    x = u if lam[k].imag >= 0 else u.conj()
    fwd, bwd = abs(x[0] + 1j * x[1]) / 2.0, abs(x[0] - 1j * x[1]) / 2.0
    w = abs(lam[k].imag)
    return {"speed_hz": float(speed_hz), "N": st.N, "radius": r, "state": st, "system": R, "D": D,
            "lam": complex(lam[k]), "forward_hz": (w + R.omega) / (2 * math.pi),
            "backward_hz": (w - R.omega) / (2 * math.pi), "backward_share": float(bwd / (fwd + bwd))}


def reduced_onset(rub: ElasticRub, lo: float, hi: float) -> dict | None:
    """The speed in [lo, hi] Hz where the reduced model's largest real part crosses 0 (None: no sign change)."""
    def g(f: float) -> float:
        ref = reduced_reference(rub, f)
        return -1.0 if ref is None else ref["lam"].real

    if g(lo) * g(hi) > 0:
        return None
    f = float(brentq(g, lo, hi, xtol=1e-9))
    ref = reduced_reference(rub, f)
    return {"speed_hz": f, "N": ref["N"], "radius": ref["radius"], "w_rotating": abs(ref["lam"].imag),
            "forward_hz": ref["forward_hz"], "backward_hz": ref["backward_hz"],
            "backward_share": ref["backward_share"]}


def rub_start(jeff: Jeffcott) -> float:
    """The speed [Hz] where the free whirl reaches the clearance (the rub begins), below the critical speed."""
    def excess(f: float) -> float:
        w = 2 * math.pi * f
        return jeff.unbalance * w ** 2 - abs(complex(jeff.k - jeff.m * w ** 2, jeff.c_e * w)) * jeff.clearance

    return float(brentq(excess, 1.0, math.sqrt(jeff.k / jeff.m) / (2 * math.pi), xtol=1e-10))


def inertial_section(rub_i: ElasticRub, ref: dict) -> tuple[float, np.ndarray, np.ndarray]:
    """(t0, q, q'): the round ring's rotating-frame state turned into the inertial frame at the first t0 >= 0 with
    the disk at a facet's middle (away from the corner laws' switches; as tests/test_periodic_rub.py)."""
    st, w = ref["state"], ref["system"].omega
    t0 = ((-math.atan2(st.n[1], st.n[0])) % (2.0 * math.pi / rub_i.facets)) / w
    q = sla.expm(w * t0 * rub_i.J) @ st.q
    return t0, q, w * rub_i.J @ q


def exact_orbit(rub_r: ElasticRub, rub_i: ElasticRub, speed_hz: float, **kw):
    """The inertial-frame periodic orbit on the polygon at the speed, shot from the round ring's state."""
    from nsfem.periodic import periodic_orbit

    ref = reduced_reference(rub_r, speed_hz)
    t0, q, v = inertial_section(rub_i, ref)
    return periodic_orbit(rub_i.system(speed_hz), 1.0 / speed_hz, q, v, t0=t0, **kw), ref


def exact_onset(stiffness: float, mu: float, facets: int, lo: float, hi: float, say) -> dict:
    """The speed in [lo, hi] Hz where the polygon orbit's largest multiplier reaches the unit circle (Brent's method
    on ln|mu_max|, each value a shooting from the round ring's state), with the multiplier there."""
    rub_r, rub_i = ElasticRub(stiffness, mu, facets), ElasticRub(stiffness, mu, facets, "inertial")
    t = time.perf_counter()
    seen = []

    def g(f: float) -> float:
        orbit, _ = exact_orbit(rub_r, rub_i, f)
        if not orbit.converged:
            raise RuntimeError(f"no orbit at {f} Hz ({facets} facets): residual {orbit.residual:.3g}")
        k = int(np.argmax(np.abs(orbit.multipliers)))
        seen.append((f, orbit.multipliers[k], orbit.events_per_period))
        say(f"  {facets} facets, {f:.6f} Hz: largest multiplier {orbit.multipliers[k]:.6f}, "
            f"{orbit.events_per_period} events [{time.perf_counter() - t:.0f} s]")
        return float(np.log(abs(orbit.multipliers[k])))

    f = float(brentq(g, lo, hi, xtol=1e-5))
    _, m, events = min(seen, key=lambda x: abs(x[0] - f))
    # the multiplier's argument is w T mod 2 pi: the whirl frequency in space up to multiples of the speed
    return {"mu": mu, "facets": facets, "onset_hz": f, "multiplier": [m.real, m.imag],
            "argument_rad": float(np.angle(m)), "events_per_period": int(events), "orbits": len(seen),
            "wall_s": time.perf_counter() - t}
