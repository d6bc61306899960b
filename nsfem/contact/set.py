"""The contact set of a (reduced) model: everything the LCPs and integrators need.

For m contact points in n generalized coordinates q (paper eq. 17-24):

- normal gaps g = J_N^T q + j_N (``JN`` n x m, ``jN``),
- tangential relative displacements s_k = S_k^T q of contact k (``JS[k]`` n x d_k,
  d_k = 2 tangent directions, 1 when one is frozen in the model, 0 when mu_k = 0),
- the polygonal friction cone of contact k: r_k unit generators e_i in its tangent
  plane (eq. 20, 21), the columns of B_k; the tangential force is lam_T = B_k beta_k,
  beta_k >= 0, mu_k lam_N,k - 1^T beta_k >= 0, and J_T = [S_k B_k] (eq. 24),
- Coulomb mu and Newton restitution eps per contact,
- a moving surface (a stator's facet, which the shaft surface slides past): the slip velocity is
  affine in (q', q), u_T' = S_k^T q' + Sq_k^T q + w_k (paper eq. 27 and 32: g_T^T q' + g_0T'),
  ``JSq[k]`` n x d_k and ``wS[k]`` (d_k,); zero elsewhere.

With r_k generators on a two-dimensional tangent plane e_i = (cos, sin)(2 pi i / r_k);
r_k = 2 there gives friction along the first tangent only (the shaft axis for a
delamination). Where one tangent direction exists, r_k = 2 (+-t).

>>> import numpy as np
>>> cs = ContactSet.from_arrays(np.eye(2)[:, :1], [0.0], mu=[0.3], JS=[np.eye(2)[:, 1:]])
>>> cs.generators(0).tolist(), cs.JT([0]).tolist(), cs.E([0]).tolist()
([[1.0, -1.0]], [[0.0, 0.0], [1.0, -1.0]], [[1.0], [1.0]])
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import NsfemError

#: names of the tangent directions per contact kind/normal, in the order of slip_rows
TANGENTS = {"interface": ("x", "y"), "x": ("y", "z"), "y": ("x", "z"), "z": ("x", "y"),
             "stator": ("circumferential", "x")}


def tangent_names(contact) -> tuple[str, ...]:
    """The names of a model contact's tangent directions, in the order of its slip rows."""
    kind = "interface" if contact.kind == "interface" else "stator" if contact.angle is not None else contact.normal[1]
    return TANGENTS[kind]


@dataclass(frozen=True)
class ContactSet:
    """Contacts in n generalized coordinates (see the module docstring)."""

    JN: np.ndarray
    jN: np.ndarray
    mu: np.ndarray
    eps: np.ndarray
    JS: tuple[np.ndarray, ...]
    r: np.ndarray
    labels: tuple[str, ...]
    tangents: tuple[tuple[str, ...], ...]
    x: np.ndarray
    JSq: tuple[np.ndarray, ...] | None = None
    wS: tuple[np.ndarray, ...] | None = None

    def __post_init__(self):
        if self.JSq is None:
            object.__setattr__(self, "JSq", tuple(np.zeros_like(S) for S in self.JS))
        if self.wS is None:
            object.__setattr__(self, "wS", tuple(np.zeros(S.shape[1]) for S in self.JS))

    @cached_property
    def moving(self) -> np.ndarray:
        """Per contact: whether its surface moves (a slip velocity with a part besides S_k^T q')."""
        return np.array([bool(np.any(w) or np.any(Sq)) for w, Sq in zip(self.wS, self.JSq)], dtype=bool)

    @property
    def m(self) -> int:
        return self.jN.size

    @property
    def n(self) -> int:
        return self.JN.shape[0]

    @property
    def gap_floor(self) -> float:
        """The smallest gap [m] that means anything: positions in space of points up to max |x|
        from the origin carry a few ulps of it (4 eps max |x|, 9e-16 m on a 1 m shaft); a gap or
        a rebound below that is not resolved by any representation of the configuration. 0 when
        the positions are unknown (sets built from arrays without ``x``)."""
        x = self.x[np.isfinite(self.x)]
        return 4.0 * np.finfo(float).eps * float(np.abs(x).max(initial=0.0))

    @property
    def frictional(self) -> np.ndarray:
        """Indices of the contacts with friction rows (mu > 0 and a tangent direction)."""
        return np.flatnonzero(self.r > 0)

    @classmethod
    def from_arrays(cls, JN, jN, mu=0.0, eps=0.0, JS=None, r=4, labels=None, x=None, JSq=None,
                    wS=None) -> ContactSet:
        """A contact set from plain arrays (validated), e.g. for systems with closed-form answers.

        ``JS`` is a list with one (n x d_k) array (d_k in 0, 1, 2) per contact, or None;
        a contact without tangent directions is frictionless whatever its mu. ``JSq``, ``wS``:
        per contact the moving surface's parts of the slip velocity (shaped like JS[k] and its
        columns), or None.
        ``mu``, ``eps``, ``r`` are scalars or one value per contact.
        """
        JN = np.atleast_2d(np.asarray(JN, dtype=float))
        jN = np.atleast_1d(np.asarray(jN, dtype=float))
        n, m = JN.shape
        if jN.shape != (m,):
            raise NsfemError(f"contact set: j_N needs one entry per column of J_N ({m}), got {jN.size}")
        def per(v, name):
            v = np.asarray(v, dtype=float)
            if v.ndim > 1 or (v.ndim == 1 and v.size != m):
                raise NsfemError(f"contact set: {name} needs one value or one per contact ({m}), got shape {v.shape}")
            if not np.all(np.isfinite(v)):
                raise NsfemError(f"contact set: {name} must be finite")
            return np.broadcast_to(v, (m,)).copy()

        mu, eps = per(mu, "mu"), per(eps, "eps")
        rr = per(r, "r").astype(int)
        if JS is not None and len(JS) != m:
            raise NsfemError(f"contact set: JS needs one entry per contact ({m}), got {len(JS)}")
        if np.any(mu < 0) or np.any((eps < 0) | (eps > 1)):
            raise NsfemError("contact set: mu must be >= 0 and eps in [0, 1]")
        if np.any(rr < 2) or np.any(rr % 2):
            raise NsfemError("contact set: the number of friction generators r must be even and >= 2")
        if not (np.all(np.isfinite(JN)) and np.all(np.isfinite(jN))):
            raise NsfemError("contact set: J_N and j_N must be finite")
        blocks = []
        for k in range(m):
            S = np.zeros((n, 0)) if JS is None or mu[k] == 0 or JS[k] is None else np.asarray(JS[k], dtype=float)
            if S.ndim == 1:
                S = S[:, None]
            if S.ndim != 2 or S.shape[0] != n or not np.all(np.isfinite(S)):
                raise NsfemError(f"contact set: JS[{k}] must be a finite n x d array (n = {n}), got shape {S.shape}")
            if S.shape[1] > 2:
                raise NsfemError(f"contact set: contact {k} has {S.shape[1]} tangent directions (at most 2)")
            if S.shape[1]:
                sv = np.linalg.svd(np.column_stack([JN[:, k], S]), compute_uv=False)
                if sv.size < 1 + S.shape[1] or sv[-1] <= 1e-10 * sv[0]:
                    raise NsfemError(f"contact set: the tangent directions JS[{k}] of contact {k} are dependent on "
                                     "each other or on its normal J_N (a slip that moves the gap)")
            blocks.append(S)
        sq, ws = [], []
        for k, S in enumerate(blocks):
            d = S.shape[1]
            a = np.zeros((n, d)) if JSq is None or JSq[k] is None or not d else np.asarray(JSq[k], dtype=float)
            b = np.zeros(d) if wS is None or wS[k] is None or not d else np.asarray(wS[k], dtype=float).ravel()
            if a.ndim == 1:
                a = a[:, None]
            if a.shape != (n, d) or b.shape != (d,) or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
                raise NsfemError(f"contact set: the moving surface of contact {k} needs a finite JSq[{k}] of shape "
                                 f"{(n, d)} and wS[{k}] of {d} entries")
            sq.append(a)
            ws.append(b)
        # r = 2 on a plane: friction along the first tangent only (the second is frictionless)
        cut = [b.shape[1] == 2 and rr[k] == 2 for k, b in enumerate(blocks)]
        blocks = [b[:, :1] if c else b for b, c in zip(blocks, cut)]
        sq = [a[:, :1] if c else a for a, c in zip(sq, cut)]
        ws = [b[:1] if c else b for b, c in zip(ws, cut)]
        dims = np.array([b.shape[1] for b in blocks])
        rr = np.where(dims == 0, 0, np.where(dims == 1, 2, rr))
        for k in range(m):
            if dims[k] == 2 and (np.any(sq[k]) or np.any(ws[k])):
                raise NsfemError(f"contact set: contact {k} has a moving surface and a two-dimensional friction cone; "
                                 "a moving surface needs one tangent direction (r = 2) in this version (the "
                                 "event-driven methods hold a force on a polygon facet by a fixed slip)")
        labels = tuple(labels) if labels is not None else tuple(f"contact {k}" for k in range(m))
        tangents = tuple(("t1", "t2")[: d] for d in dims)
        xs = np.full(m, np.nan) if x is None else np.asarray(x, dtype=float)
        return cls(JN, jN, mu, eps, tuple(blocks), rr, labels, tangents, xs, tuple(sq), tuple(ws))

    @classmethod
    def from_model(cls, model, reduction=None, frozen_tol: float = 1e-10, omega: float | None = None,
                   frame: str = "rotating") -> ContactSet:
        """The contacts of ``model`` in the coordinates of ``reduction`` (default: no reduction).

        A tangent direction whose slip row vanishes in these coordinates (nothing can slip
        that way) is dropped; a contact left with one direction gets r = 2. A stator's facet at
        the speed ``omega`` [rad/s] gets its moving surface (:func:`surface_velocity`); ``omega`` is required
        when there is one (with friction), and ``frame`` says in which frame the coordinates are.
        """
        from ..reduce import NoReduction

        red = NoReduction(model) if reduction is None else reduction
        contacts = model.stack.contacts
        if omega is None:
            if any(c.angle is not None and c.friction > 0 for c in contacts):
                raise NsfemError("contact set: the model has a stator with friction, whose surface slides past at "
                                 "Omega r: pass omega [rad/s] and frame to ContactSet.from_model")
            omega = 0.0
        if frame not in ("rotating", "inertial"):
            raise NsfemError(f"contact set: frame must be 'rotating' or 'inertial', got {frame!r}")
        JN, jN, JS_all = red.jacobians()
        JN = np.asarray(JN, dtype=float)
        blocks, tangents, r, sq, ws = [], [], [], [], []
        col = 0
        for k, c in enumerate(contacts):
            names = tangent_names(c)
            if c.friction > 0:
                S = JS_all[:, col:col + 2]
                col += 2
                Sq, w = surface_velocity(c, JN[:, k], omega, frame)
                norms = np.linalg.norm(S, axis=0)
                keep = norms > frozen_tol * max(float(norms.max()), np.linalg.norm(JN[:, k]), 1e-300)
                S, Sq, w = S[:, keep], Sq[:, keep], w[keep]
                names = tuple(nm for nm, kp in zip(names, keep) if kp)
                rk = 0 if S.shape[1] == 0 else (2 if S.shape[1] == 1 else c.friction_directions)
            else:
                S, names, rk = np.zeros((JN.shape[0], 0)), (), 0
                Sq, w = S, np.zeros(0)
            if rk == 2 and S.shape[1] == 2:   # r = 2 on a plane: friction along the first tangent
                S, Sq, w, names = S[:, :1], Sq[:, :1], w[:1], names[:1]
            blocks.append(S)
            sq.append(Sq)
            ws.append(w)
            tangents.append(names)
            r.append(rk)
        return cls(JN, np.asarray(jN, dtype=float),
                   np.array([c.friction for c in contacts]), np.array([c.restitution for c in contacts]),
                   tuple(blocks), np.array(r, dtype=int), tuple(c.label for c in contacts), tuple(tangents),
                   np.array([c.x for c in contacts]), tuple(sq), tuple(ws))

    # --- friction cone -------------------------------------------------------------
    def generators(self, k: int) -> np.ndarray:
        """B_k: the r_k unit generators of contact k's cone (d_k x r_k), in pairs e_i = -e_j."""
        d, r = self.JS[k].shape[1], int(self.r[k])
        if r == 0:
            return np.zeros((d, 0))
        if d == 1:
            return np.array([[1.0, -1.0]])
        a = 2.0 * np.pi * np.arange(r) / r
        B = np.vstack([np.cos(a), np.sin(a)])
        B[np.abs(B) < 1e-15] = 0.0
        return B

    def facet(self, k: int, i: int) -> tuple[np.ndarray, np.ndarray, float, float]:
        """Facet i of contact k's friction polygon (d_k = 2), between generators i and i + 1:
        its outward unit normal n_f, unit tangent t_f (from e_i to e_i+1), cos(pi/r), sin(pi/r).
        A force on it is mu lam_N (cos(pi/r) n_f + s t_f) with |s| <= sin(pi/r)."""
        r = int(self.r[k])
        if self.JS[k].shape[1] != 2 or r < 3:
            raise NsfemError(f"contact {k} has no polygon facets (needs 2 tangent directions and r >= 3)")
        a = (2 * (i % r) + 1) * np.pi / r
        n_f = np.array([np.cos(a), np.sin(a)])
        return n_f, np.array([-n_f[1], n_f[0]]), float(np.cos(np.pi / r)), float(np.sin(np.pi / r))

    def JT(self, contacts) -> np.ndarray:
        """J_T = [S_k B_k] for the listed contacts (n x sum r_k), eq. (24)."""
        cols = [self.JS[k] @ self.generators(k) for k in contacts]
        return np.hstack(cols) if cols else np.zeros((self.n, 0))

    def E(self, contacts) -> np.ndarray:
        """Block-diagonal E = diag(1_k) (sum r_k x len(contacts)), eq. (24)."""
        r = [int(self.r[k]) for k in contacts]
        E = np.zeros((sum(r), len(r)))
        row = 0
        for j, rk in enumerate(r):
            E[row:row + rk, j] = 1.0
            row += rk
        return E

    # --- evaluation ----------------------------------------------------------------
    def gaps(self, q: np.ndarray) -> np.ndarray:
        """g = J_N^T q + j_N (for q of shape (n,) or (n, t))."""
        g = self.JN.T @ q
        return g + (self.jN if g.ndim == 1 else self.jN[:, None])

    def slip(self, k: int, q: np.ndarray) -> np.ndarray:
        """Tangential relative displacement (or velocity, given q', of a contact without a moving
        surface) of contact k (d_k,)."""
        return self.JS[k].T @ q

    def slip_rate(self, k: int, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The slip velocity of contact k, S_k^T q' + Sq_k^T q + w_k (d_k,), eq. (27, 32)."""
        return self.JS[k].T @ v + (self.JSq[k].T @ q + self.wS[k] if self.moving[k] else 0.0)

    def surface_offsets(self, contacts, q: np.ndarray) -> np.ndarray:
        """B_k^T (Sq_k^T q + w_k) for the listed contacts, stacked (sum r_k,): what a moving surface adds to
        the slip velocity along each cone generator (the right-hand side of LCP 30-32)."""
        parts = [self.generators(k).T @ (self.JSq[k].T @ q + self.wS[k]) if self.moving[k]
                 else np.zeros(int(self.r[k])) for k in contacts]
        return np.concatenate(parts) if parts else np.zeros(0)

    def surface_drifts(self, contacts, v: np.ndarray) -> np.ndarray:
        """B_k^T Sq_k^T q' for the listed contacts, stacked: what a moving surface adds to the slip
        acceleration (the right-hand side of LCP 29)."""
        parts = [self.generators(k).T @ (self.JSq[k].T @ v) if self.moving[k] else np.zeros(int(self.r[k]))
                 for k in contacts]
        return np.concatenate(parts) if parts else np.zeros(0)

    def slip_rate_rows(self, k: int, Pq: np.ndarray, Pv: np.ndarray, const: int) -> np.ndarray:
        """Rows (d_k x dim) mapping an augmented state xi (q = Pq xi, q' = Pv xi, xi[const] = 1) to the slip
        velocity of contact k."""
        rows = self.JS[k].T @ Pv
        if self.moving[k]:
            rows = rows + self.JSq[k].T @ Pq
            rows[:, const] += self.wS[k]
        return rows

    def subset(self, keep) -> ContactSet:
        """The contacts with indices ``keep``, in that order."""
        keep = [int(k) for k in keep]
        return ContactSet(self.JN[:, keep], self.jN[keep], self.mu[keep], self.eps[keep],
                          tuple(self.JS[k] for k in keep), self.r[keep], tuple(self.labels[k] for k in keep),
                          tuple(self.tangents[k] for k in keep), self.x[keep],
                          tuple(self.JSq[k] for k in keep), tuple(self.wS[k] for k in keep))


def surface_velocity(contact, jn: np.ndarray, omega: float, frame: str) -> tuple[np.ndarray, np.ndarray]:
    """(Sq, w): the moving surface's part of the slip velocity of a stator facet (Sq n x 2, w (2,), for the
    circumferential and axial slips of :func:`~nsfem.contact.kinematics.slip_rows`); zeros elsewhere.

    The shaft surface point at radius R on the facet normal n slides past the ring, fixed in space,
    with the relative velocity (v', w') + Omega e_x x ((v, w) + R n) in the rotating frame, whose
    circumferential part is t.(v', w') + Omega n.(v, w) + Omega R, and n.(v, w) = -J_N^T q (the gap
    is clearance - n.(v, w)): Sq = -Omega J_N. In the inertial frame the coordinates are the
    displacements in space: t.(v', w') + Omega R. The axial slip has no moving part."""
    n = jn.size
    if contact.angle is None or omega == 0.0:
        return np.zeros((n, 2)), np.zeros(2)
    Sq = np.zeros((n, 2))
    if frame == "rotating":
        Sq[:, 0] = -omega * jn
    return Sq, np.array([omega * contact.radius, 0.0])

