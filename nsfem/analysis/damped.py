"""Damped modes of the linearized rotor at one speed (``nsfem modes --speed``).

The roots lambda = -zeta omega_n +- i omega_d of the first-order form of eq. (22) at the speed (the
state eigenvalues of :mod:`.campbell`, damping of the scene: Rayleigh, external, bearings) give per
mode, one per conjugate pair with omega_d > 0:

    damped frequency  f_d = Im(lambda) / 2 pi,
    damping ratio     zeta = -Re(lambda) / |lambda|,
    log decrement     delta = -2 pi Re(lambda) / Im(lambda) = 2 pi zeta / sqrt(1 - zeta^2),

and its whirl (:func:`.whirl.whirl_sense`): forward when the orbits turn with the spin, backward
against it, planar (flat orbits, or at rest), axial (no lateral motion). In the rotating frame the
orbits are seen from the shaft; the whirl reported is the inertial one, sign(s omega_d + Omega) for a
mode turning with sense s in the rotating frame (exact for the circular orbits of an axisymmetric rotor
on isotropic bearings, the only one the rotating frame spins; :func:`nsfem.scene.check_frame_at_speed`).
Overdamped (real) roots have no frequency and are not listed; a real part within the roots' round-off
resolution sqrt(eps) omega_max (:func:`.campbell.growth_rate`) is reported as 0 (undamped), and a root
within it of 0 (a free rotor's rigid motion split by round-off) is not a mode.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import NsfemError
from ..system import linear_system
from .campbell import _omega_max, _oscillating, state_eigenvalues

#: roots beyond ``count`` looked at, so that dropping round-off roots at 0 leaves ``count`` modes
SPARE = 6
#: whirl codes (:func:`.whirl.whirl_sense`) to names
WHIRL_NAMES = {1: "forward", -1: "backward", 0: "planar", 2: "axial"}


@dataclass(frozen=True)
class DampedModes:
    """Damped modes at ``speed_hz``, ascending by damped frequency; ``shapes``: per mode the complex
    lateral amplitudes (V, W) at the shaft's nodes, (modes, nodes, 2), normalized to a largest orbit
    radius of 1, with the nodes' positions ``x_m``."""

    speed_hz: float
    frame: str
    eigenvalues: np.ndarray  # (modes,) complex, 1/s
    whirl: tuple[str, ...]
    x_m: np.ndarray
    shapes: np.ndarray

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.eigenvalues.imag / (2 * math.pi)

    @property
    def damping_ratios(self) -> np.ndarray:
        return -self.eigenvalues.real / np.abs(self.eigenvalues) + 0.0  # (no -0.0)

    @property
    def log_decrements(self) -> np.ndarray:
        return -2 * math.pi * self.eigenvalues.real / self.eigenvalues.imag + 0.0

    def to_json(self) -> dict:
        return {"speed_hz": self.speed_hz, "frame": self.frame,
                "frequencies_hz": self.frequencies_hz.tolist(), "damping_ratios": self.damping_ratios.tolist(),
                "log_decrements": self.log_decrements.tolist(), "whirl": list(self.whirl)}


def log_decrement(zeta: np.ndarray) -> np.ndarray:
    """The logarithmic decrement 2 pi zeta / sqrt(1 - zeta^2) of damping ratios below 1."""
    zeta = np.asarray(zeta, dtype=float)
    return 2 * math.pi * zeta / np.sqrt(1 - zeta**2)


def damped_modes(model, ops, speed_hz: float, count: int, rayleigh=(0.0, 0.0), external: float = 0.0,
                 frame: str = "inertial") -> DampedModes:
    """The lowest ``count`` damped modes of the rotor ``ops`` (:func:`nsfem.fem.rotating.rotor_operators`
    of ``model`` in any basis) spinning at ``speed_hz`` in ``frame``."""
    from ..fem.components import lateral_turn
    from .whirl import whirl_sense

    if not (math.isfinite(speed_hz) and speed_hz >= 0):
        raise NsfemError(f"--speed must be a finite speed >= 0 Hz, got {speed_hz}")
    if count < 1:
        raise NsfemError(f"--count must be a positive integer, got {count}")
    system = linear_system(ops, speed_hz, 0.0, 0.0, rayleigh, external, frame)
    lam, X = state_eigenvalues(system, count, vectors=True)
    pick = _oscillating(lam, count + SPARE)
    # a real part below the roots' round-off resolution (:func:`.campbell.growth_rate`) is no damping, and a
    # root within it of 0 no mode: a free rotor's rigid motions (a defective root at 0, split by round-off)
    resolution = math.sqrt(np.finfo(float).eps) * _omega_max(system.M, system.Q)
    pick = pick[np.abs(lam[pick]) > resolution][:count]
    lam, X = lam[pick], X[:, pick]
    lam = np.where(np.abs(lam.real) <= resolution, 1j * lam.imag, lam)
    turn = lateral_turn(model.spaces, model.n_full)
    xf = np.asarray(ops.basis @ X) if ops.basis is not None else X
    if speed_hz > 0:
        xf = _split_repeated(lam, xf, turn)
    sense = whirl_sense(xf, None, turn) if len(pick) else np.zeros(0, dtype=int)
    omega = 2 * math.pi * speed_hz
    if frame == "rotating" and omega:
        lateral = (sense == 1) | (sense == -1)
        sense = np.where(lateral, np.sign(sense * lam.imag + omega).astype(int), sense)
    elif omega == 0:
        sense = np.where(sense == 2, 2, 0)  # at rest no mode whirls: an isotropic pair is any combination
    x, shapes = _lateral_shapes(model, xf)
    return DampedModes(float(speed_hz), frame, lam, tuple(WHIRL_NAMES[int(s)] for s in sense), x, shapes)


#: roots closer than this share of their modulus are one repeated root (an isotropic rotor's translation
#: on isotropic bearings: its forward and backward whirl have one frequency; the solver returns any
#: combination of the two, e.g. two planar ones). Measured: such a pair split by round-off by 3e-8 of its
#: modulus (a shaft 3e4 times stiffer than its bearings); the gyroscopic split of a pair is larger than 1e-6
#: from speeds of about 1e-6 of its frequency on. Within a group the backward combination comes first.
REPEATED = 1e-6


def _split_repeated(lam: np.ndarray, xf: np.ndarray, turn) -> np.ndarray:
    """Eigenvectors (full coordinates, columns) with those of each repeated root replaced by the combinations
    that whirl purely forward and backward: the eigenvectors of the whirl measure x^H (-i J) x (Hermitian, J
    real skew) against the lateral amplitude x^H P x within the root's eigenspace."""
    import scipy.linalg as sla

    xf = np.array(xf, dtype=complex)
    lateral = np.asarray(abs(turn).sum(axis=1)).ravel() > 0
    done = np.zeros(lam.size, dtype=bool)
    for i in range(lam.size):
        group = np.flatnonzero(~done & (np.abs(lam - lam[i]) <= REPEATED * np.abs(lam[i])))
        done[group] = True
        if group.size < 2:
            continue
        Y = xf[:, group]
        A = Y.conj().T @ (-1j * (turn @ Y))
        B = Y[lateral].conj().T @ Y[lateral]
        try:
            _, V = sla.eigh(0.5 * (A + A.conj().T), 0.5 * (B + B.conj().T))
        except np.linalg.LinAlgError:   # no lateral motion to split (axial modes)
            continue
        xf[:, group] = Y @ V
    return xf


def _lateral_shapes(model, xf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, (modes, nodes, 2) complex (V, W)) at every segment's nodes, each mode scaled to a largest orbit
    radius (the ellipse's semi-major axis) of 1 and turned so that it is reached at phase 0."""
    xs, V, W = [], [], []
    for space in model.spaces.values():
        nod = space.bending.nodal_dofs[0]
        xs.append(np.asarray(space.x, dtype=float))
        V.append(xf[space.dofs["V"][nod]])
        W.append(xf[space.dofs["W"][nod]])
    x = np.concatenate(xs)
    S = np.stack([np.concatenate(V), np.concatenate(W)], axis=-1).transpose(1, 0, 2)  # (modes, nodes, 2)
    order = np.argsort(x, kind="stable")
    x, S = x[order], S[:, order]
    for k in range(S.shape[0]):
        major, phase = _semi_major(S[k])
        i = int(np.argmax(major))
        if major[i] > 0:
            S[k] *= np.exp(1j * phase[i]) / major[i]
    return x, S


def _semi_major(uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row (a, b) of complex amplitudes, the orbit Re((a, b) e^{i t})'s semi-major axis and the phase t
    where it is reached: |a|^2 + |b|^2 = p, a^2 + b^2 = c, r^2(t) = (p + Re(c e^{2 i t})) / 2."""
    p = (np.abs(uv) ** 2).sum(axis=1)
    c = (uv**2).sum(axis=1)
    return np.sqrt(0.5 * (p + np.abs(c))), -0.5 * np.angle(c)


def scene_damped_modes(scene, model, speed_hz: float, count: int, reduction=None, contact: str = "open"
                       ) -> DampedModes:
    """:func:`damped_modes` of the scene's rotor (its frame and damping; the contacts ``open`` or ``closed``)."""
    from ..fem.rotating import rotor_operators
    from ..scene import check_frame_at_speed
    from .modes import contact_basis

    if speed_hz > 0:
        check_frame_at_speed(scene.rotation.frame, model.stack)
    ops = rotor_operators(model, contact_basis(model, contact, reduction))
    return damped_modes(model, ops, speed_hz, count, scene.damping.rayleigh, scene.damping.external,
                        scene.rotation.frame)


__all__ = ["DampedModes", "WHIRL_NAMES", "damped_modes", "log_decrement", "scene_damped_modes"]
