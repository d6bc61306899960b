"""The result of a transient run, the same for every integrator, and its results file.

The file is a NumPy ``.npz`` archive readable with numpy alone::

    import json, numpy as np
    r = np.load("out/result.npz")
    r["t"], r["gap"], r["normal_force"]        # (K,), (m, K), (m, K)
    q_full = r["basis"] @ r["q"]                # finite-element dofs (n_full, K)
    meta = json.loads(str(r["meta"]))           # method, scene text, events, impacts, energy

Arrays: ``t`` output times; ``q``, ``v`` reduced coordinates and velocities (n, K);
``gap`` (m, K); ``normal_force`` (m, K); ``tangential_force`` (m, 2, K) in each contact's
tangent directions; ``state`` (m, K) 0 open, 1 stick, 2 slip; ``basis`` (n_full, n) with
q_full = basis q; ``contact_x`` (m,). ``meta`` is a JSON string. Written atomically
(temporary file, then rename), so an interrupted run never leaves a broken file.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .atomic import write_atomic
from .errors import NsfemError
from .jsonio import dumps

STATES = ("open", "stick", "slip")


@dataclass
class Result:
    method: str
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    gap: np.ndarray
    normal_force: np.ndarray
    tangential_force: np.ndarray
    state: np.ndarray
    events: list = field(default_factory=list)
    impacts: list = field(default_factory=list)
    energy: dict = field(default_factory=dict)
    wall_s: float = 0.0
    t_end: float = 0.0
    completed: bool = True
    info: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """The ``nsfem run`` JSON keys (design section 5). The contact counts and maxima come from
        :func:`nsfem.contact.tally.tally`, their one definition: ``impacts`` the impact records with a positive
        impulse, ``max_normal_force_N`` and ``max_impulse_Ns`` the largest force and impulse at one contact
        point, ``parts`` one entry per delamination, ring, crack and stop (its resultant's maxima)."""
        from .contact.tally import tally

        m = self.gap.shape[0]
        closed_any = (self.state != 0).any(axis=0) if m else np.zeros(self.t.size, bool)
        counts = tally(self)
        return {
            "method": self.method, "t_end": self.t_end, "completed": self.completed, "wall_s": self.wall_s,
            "ndof_full": self.info.get("ndof_full"), "ndof": int(self.q.shape[0]),
            "events": len(self.events), "impacts": counts.impacts, "shared_impacts": counts.shared_impacts,
            "min_gap_m": float(self.gap.min()) if m and self.t.size else None,
            "max_gap_m": float(self.gap.max()) if m and self.t.size else None,
            # event-driven runs know it between events; the others sample their outputs
            "closed_fraction": float(self.info["closed_fraction"]) if "closed_fraction" in self.info
            else float(closed_any.mean()) if self.t.size else 0.0,
            "max_normal_force_N": counts.max_normal_force_N,
            "max_impulse_Ns": counts.max_impulse_Ns,
            "parts": [p.record() for p in counts.parts],
            "energy": self.energy.get("relative_residual"),
        }

    def save(self, path, scene_text: str = "", basis: np.ndarray | None = None, contact_x=None,
             scene_tree: dict | None = None) -> Path:
        """Write the results file atomically; returns its path.

        ``scene_text`` is the scene file as written (plus overrides), ``scene_tree`` the
        validated scene with every default filled in.
        """
        meta = {"method": self.method, "t_end": self.t_end, "completed": self.completed, "wall_s": self.wall_s,
                "events": self.events, "impacts": self.impacts, "energy": self.energy, "scene": scene_text,
                "scene_tree": scene_tree or {},
                "states": list(STATES), "summary": self.summary(),
                "info": {k: v for k, v in self.info.items() if _jsonable(v)}}
        arrays = dict(t=self.t, q=self.q, v=self.v, gap=self.gap, normal_force=self.normal_force,
                      tangential_force=self.tangential_force, state=self.state,
                      basis=np.zeros((0, self.q.shape[0])) if basis is None else np.asarray(basis),
                      contact_x=np.zeros(self.gap.shape[0]) if contact_x is None else np.asarray(contact_x),
                      meta=np.array(dumps(meta)))

        def write(tmp):
            with open(tmp, "wb") as fh:  # a file object: numpy would append .npz to a name
                np.savez_compressed(fh, **arrays)

        return write_atomic(path, write)

    @classmethod
    def load(cls, path) -> tuple[Result, dict, dict]:
        """(Result, meta, extra arrays basis/contact_x) from a results file."""
        with np.load(path, allow_pickle=False) as r:
            meta = json.loads(str(r["meta"]))
            res = cls(meta["method"], r["t"], r["q"], r["v"], r["gap"], r["normal_force"], r["tangential_force"],
                      r["state"], meta["events"], meta["impacts"], meta["energy"], meta["wall_s"], meta["t_end"],
                      meta["completed"], meta.get("info", {}))
            extra = {"basis": r["basis"], "contact_x": r["contact_x"]}
        return res, meta, extra


def _jsonable(v) -> bool:
    try:
        json.dumps(v, default=json_default)
        return True
    except TypeError:
        return False


def json_default(o):
    """``json.dumps(..., default=json_default)``: numpy scalars and arrays as Python values."""
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def check_times(t: np.ndarray, t_end: float, what: str) -> None:
    """Refuse the output times ``t`` of a results file (``what`` names it) that hold no sample, are not
    finite, do not increase, or lie outside [0, ``t_end``] (its stored end, to round-off): a file
    truncated or edited by hand, whose export would be an empty or meaningless series.

    >>> check_times(np.array([0.0, 0.5, 1.0]), 1.0, "r.npz")
    >>> check_times(np.array([0.0, 1.0, 0.5]), 1.0, "r.npz")
    Traceback (most recent call last):
    nsfem.errors.NsfemError: r.npz: its output times do not increase (t = 1 s is followed by 0.5 s, outputs 1 and 2)
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise NsfemError(f"{what}: holds no output time (zero samples)")
    bad = ~np.isfinite(t)
    if np.any(bad):
        raise NsfemError(f"{what}: its output time {int(np.argmax(bad))} is {t[np.argmax(bad)]} (not finite)")
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.argmax(steps <= 0))
        raise NsfemError(f"{what}: its output times do not increase (t = {t[i]:g} s is followed by {t[i + 1]:g} s, "
                         f"outputs {i} and {i + 1})")
    # round-off of the integrator's clock: a few ulps of t_end
    slack = 1e-9 * max(abs(float(t_end)), 1e-300)
    if not (math.isfinite(t_end) and t[0] >= -slack and t[-1] <= t_end + slack):
        raise NsfemError(f"{what}: its output times {t[0]:g}..{t[-1]:g} s lie outside the run's span 0..{t_end:g} s "
                         "(a damaged or edited file)")

