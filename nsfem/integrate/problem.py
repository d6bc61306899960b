"""The contact system every integrator works on (paper eq. 22-24).

    M q'' + C q' + Q q = f0 + fc cos(omega t) + fs sin(omega t) + J_N lam_N + J_T lam_T

with the unilateral contacts and friction cones of a :class:`~nsfem.contact.set.ContactSet`.
Built from a scene (:meth:`ContactSystem.from_scene`, in the scene's reduced coordinates), a model
with its rotation and damping (:meth:`ContactSystem.from_model`) or directly from small arrays, so
that tests can use systems with closed-form answers.

>>> import numpy as np
>>> from nsfem.contact.set import ContactSet
>>> ball = ContactSystem.from_arrays(M=[[1.0]], Q=[[0.0]], f0=[-9.81],
...                                  contacts=ContactSet.from_arrays([[1.0]], [0.0], eps=0.5))
>>> ball.n, ball.contacts.m, ball.omega
(1, 1, 0.0)
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from ..contact.set import ContactSet
from ..errors import NsfemError, SceneError
from ..fem.constraints import dense

if TYPE_CHECKING:
    from ..scene import Damping, Rotation, Scene


@dataclass(frozen=True)
class ContactSystem:
    """M, C, Q (n x n, dense), load parts (n,) or None, omega [rad/s], contacts."""

    M: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    f0: np.ndarray
    fc: np.ndarray
    fs: np.ndarray
    omega: float
    contacts: ContactSet
    info: dict = field(default_factory=dict, compare=False)
    #: elastic stator rings (:mod:`nsfem.contact.ring`): force laws, not constraints; ``contacts`` holds the
    #: rigid contacts only (``info["contact_index"]``: their places in the model's contact list)
    rings: tuple = ()
    #: a run-up or coast-down (:class:`~nsfem.system.SpeedSchedule`): the time-varying C(t), Q(t), f(t) that the
    #: methods rk, penalty and moreau integrate; M, C, Q, f0, fc, fs are then the constant-speed values at t = 0
    schedule: object = None

    @property
    def n(self) -> int:
        return self.M.shape[0]

    @cached_property
    def symmetric(self) -> bool:
        """M, C and Q symmetric (to 1e-13 of their largest entries: assembly round-off): a structure
        without gyroscopic and circulatory terms, whose configurations have real modes (an engaged ring's
        friction is checked by its configuration)."""
        def sym(X):
            return bool(np.all(np.abs(X - X.T) <= 1e-13 * np.abs(X).max(initial=0.0)))

        return sym(self.M) and sym(self.C) and sym(self.Q)

    @property
    def model_contacts(self) -> ContactSet:
        """Every contact of the model in its order: the rigid ones and the facets of elastic rings (outputs)."""
        return self.info.get("all_contacts", self.contacts)

    @property
    def harmonic(self) -> bool:
        return self.omega != 0.0 and (np.any(self.fc) or np.any(self.fs))

    def load(self, t):
        """f(t) for a scalar t, shape (n,); for an array of times, shape (n, len(t)) (a run-up's schedule
        included)."""
        if self.schedule is not None:
            return self.schedule.load(t)
        return self.steady_load(t)

    def steady_load(self, t):
        """f0 + fc cos(omega t) + fs sin(omega t): the load at the constant speed omega (a run-up's at t = 0)."""
        t = np.asarray(t, dtype=float)
        out = np.multiply.outer(self.f0, np.ones_like(t))
        if self.harmonic:
            out = out + np.multiply.outer(self.fc, np.cos(self.omega * t)) + np.multiply.outer(
                self.fs, np.sin(self.omega * t))
        return out

    @classmethod
    def from_arrays(cls, M, Q, C=None, f0=None, fc=None, fs=None, omega: float = 0.0,
                    contacts: ContactSet | None = None, info=None, rings=(), schedule=None) -> ContactSystem:
        """Validate and build; missing parts are zero (C, loads) or no contacts; ``rings`` elastic stator
        rings (:class:`~nsfem.contact.ring.Ring`) in the same coordinates."""
        M = np.atleast_2d(np.asarray(dense(M), dtype=float))
        n = M.shape[0]

        def square(A, name):
            A = np.zeros((n, n)) if A is None else np.atleast_2d(np.asarray(dense(A), dtype=float))
            if A.shape != (n, n):
                raise NsfemError(f"contact system: {name} must be {n} x {n}, got {A.shape}")
            if not np.all(np.isfinite(A)):
                raise NsfemError(f"contact system: {name} has nan or inf entries")
            return A

        def vec(v, name):
            v = np.zeros(n) if v is None else np.asarray(v, dtype=float).ravel()
            if v.shape != (n,) or not np.all(np.isfinite(v)):
                raise NsfemError(f"contact system: {name} must be a finite vector of length {n}")
            return v

        M, Q, C = square(M, "M"), square(Q, "Q"), square(C, "C")
        if np.abs(M - M.T).max() > 1e-12 * np.abs(M).max():
            raise NsfemError("contact system: the mass matrix M must be symmetric")
        try:
            np.linalg.cholesky(M)
        except np.linalg.LinAlgError:
            raise NsfemError("contact system: the mass matrix M must be positive definite") from None
        if not np.isfinite(omega) or omega < 0:
            raise NsfemError(f"contact system: omega must be finite and >= 0, got {omega}")
        cs = ContactSet.from_arrays(np.zeros((n, 0)), np.zeros(0)) if contacts is None else contacts
        if cs.n != n:
            raise NsfemError(f"contact system: the contacts live in {cs.n} coordinates, the system in {n}")
        rings = tuple(rings)
        for ring in rings:
            if ring.P.shape != (2, n):
                raise NsfemError(f"contact system: ring {ring.label} maps {ring.P.shape[1]} coordinates, not {n}")
        if schedule is not None:
            for name in ("C1", "Q1", "Kst", "Q2"):
                if getattr(schedule, name) is not None:
                    square(getattr(schedule, name), f"schedule.{name}")
            for name in ("u", "w", "f_s", "f1", "f2", "fa", "gc", "gs"):
                if getattr(schedule, name) is not None:
                    vec(getattr(schedule, name), f"schedule.{name}")
        return cls(M, C, Q, vec(f0, "f0"), vec(fc, "fc"), vec(fs, "fs"), float(omega), cs, dict(info or {}), rings,
                   schedule)

    @classmethod
    def from_scene(cls, scene: Scene, model=None, reduction=None, speed_hz: float | None = None) -> ContactSystem:
        """The scene's system at its speed (or ``speed_hz``) in its reduced coordinates (its model and
        reduction unless given; :meth:`from_model`)."""
        from ..fem.assemble import build_model
        from ..reduce import scene_reduction

        model = build_model(scene) if model is None else model
        red = scene_reduction(scene.reduction, model) if reduction is None else reduction
        return cls.from_model(model, red, scene.rotation, scene.damping, speed_hz)

    @classmethod
    def from_model(cls, model, reduction, rotation: Rotation, damping: Damping,
                   speed_hz: float | None = None) -> ContactSystem:
        """The system of a model in ``reduction``'s coordinates with ``[rotation]`` and ``[damping]``, at
        ``rotation.speed_hz`` (or ``speed_hz``).

        ``info`` keeps the model, the reduction and the map T (q_full = T q) for outputs.
        """
        from ..fem.rotating import rotor_operators
        from ..system import rotor_system, speed_schedule

        ops = rotor_operators(model, reduction.T)
        lin = rotor_system(ops, rotation, damping, speed_hz)
        spin = 2.0 * np.pi * (rotation.speed_hz if speed_hz is None else speed_hz)
        full = ContactSet.from_model(model, reduction, omega=spin, frame=rotation.frame)
        rigid, rings = split_rings(full, model.stack.contacts, spin, rotation.frame == "rotating")
        schedule = None
        if speed_hz is None and getattr(rotation, "ramped", False):
            for c in model.stack.contacts:
                if rotation.frame == "rotating" and c.angle is not None and (c.stiffness > 0.0 or c.friction > 0.0):
                    what = "an elastic ring, whose law turns with the frame" if c.stiffness > 0.0 else \
                        "friction against a stator, whose surface slides at Omega(t) r and turns with the frame"
                    raise SceneError(f"{c.table_key}.{'stiffness' if c.stiffness > 0.0 else 'friction'}",
                                     f"a run-up in the rotating frame does not carry {what}; run it in the "
                                     "inertial frame (rotation.frame = \"inertial\", an axisymmetric rotor)")
                if c.friction > 0.0 and c.stiffness > 0.0:
                    raise SceneError(f"{c.table_key or c.label}.friction", "an elastic ring's friction against the "
                                     "shaft surface, which slides at Omega(t) r in a run-up, is not modelled for a "
                                     "changing speed; set it to 0, or make the stator rigid (stiffness = 0) and run "
                                     "method = moreau")
            schedule = speed_schedule(model, reduction.T, ops, rotation, damping, lin.f0)
            if any(c.friction > 0.0 for c in model.stack.contacts):   # the moving surfaces' speed per unit Omega
                unit = ContactSet.from_model(model, reduction, omega=1.0, frame=rotation.frame)
                schedule = replace(schedule, surface=(unit.subset(rigid) if rings else unit).wS)
        info = {"model": model, "reduction": reduction, "ndof_full": model.n,
                "omega2_ref": omega2_ref(model.K, model.M)}
        if rings:
            info.update(contact_index=rigid, all_contacts=full)
        # the rigid stators that the exact method makes round (:mod:`..integrate.round`)
        info["round_rings"] = tuple(sorted({c.table_key for c in model.stack.contacts if c.round}))
        return cls.from_arrays(lin.M, lin.Q, lin.C, lin.f0, lin.fc, lin.fs, lin.omega, full.subset(rigid) if rings
                               else full, info, rings, schedule)


def split_rings(cs: ContactSet, contacts, spin: float, rotating: bool) -> tuple[list[int], tuple]:
    """(rigid, rings): the indices of the rigid contacts in ``cs`` (the model's ``contacts``, in order) and
    the elastic stator rings their facets with stiffness > 0 make, one per ``[[stator]]``."""
    from ..contact.ring import from_facets

    groups: dict[str, list[int]] = {}
    rigid = []
    for k, c in enumerate(contacts):
        if c.stiffness > 0.0:
            groups.setdefault(c.label.rsplit(".", 1)[0], []).append(k)
        else:
            rigid.append(k)
    rings = tuple(from_facets(label, cs.JN[:, idx], contacts, idx, spin, rotating) for label, idx in groups.items())
    return rigid, rings


def omega2_ref(K, M) -> float:
    """max K_ii / M_ii [1/s^2]: the size of the full model's largest omega^2 (within a factor of a few),
    the scale against which a reduced model's rigid-body modes (omega^2 at round-off) are recognized."""
    k, m = np.abs(np.asarray(K.diagonal(), dtype=float)), np.abs(np.asarray(M.diagonal(), dtype=float))
    ok = m > 0
    return float(np.max(k[ok] / m[ok], initial=0.0))
