"""Rigid-body motions of a beam stack and the ones its constraints admit.

A rigid motion of the stack (no torsion field) is u0 along x, translations v0, w0 and
small rotations tv (about z), tw (about y): V = v0 + tv x, W = w0 + tw x and, on a
segment with centroid offset (y_c, z_c), U = u0 - y_c tv - z_c tw (design section 3).
They carry zero strain energy; the constraints (supports, closed contacts) admit a
subspace of them, which :func:`admissible` finds.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla


def components(stack) -> list[list[str]]:
    """Segment names grouped into the parts that junctions and cracks connect."""
    parent = {s.name: s.name for s in stack.segments}

    def root(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for j in stack.junctions:
        for s in j.slaves:
            parent[root(s)] = root(j.master)
    for k in stack.cracks:   # a crack's hinge spring resists a relative rotation: one rigid part
        parent[root(k.segments[1])] = root(k.segments[0])
    groups: dict[str, list[str]] = {}
    for s in stack.segments:
        groups.setdefault(root(s.name), []).append(s.name)
    return list(groups.values())


def rigid_fields(model) -> np.ndarray:
    """Rigid motions (u0, v0, tv, w0, tw) of every connected part, in full coordinates.

    n_full x 5 p for p parts (a full-length delamination leaves two unconnected sub-beams).
    """
    parts = components(model.stack)
    R = np.zeros((model.n_full, 5 * len(parts)))
    for p, names in enumerate(parts):
        R[:, 5 * p:5 * p + 5] = _rigid_part(model, names)
    return R


def _rigid_part(model, names) -> np.ndarray:
    R = np.zeros((model.n_full, 5))
    for s in (model.stack.segment(n) for n in names):
        space = model.spaces[s.name]
        ud = space.dofs["U"]
        R[ud, 0] = 1.0
        R[ud, 2] = -s.offset[0]
        R[ud, 4] = -s.offset[1]
        xb = space.bending.doflocs[0] + space.x[0]
        value = np.zeros(space.bending.N, dtype=bool)
        value[space.bending.nodal_dofs[0]] = True
        for fld, (c_t, c_r) in (("V", (1, 2)), ("W", (3, 4))):
            d = space.dofs[fld]
            R[d[value], c_t] = 1.0
            R[d[value], c_r] = xb[value]
            R[d[~value], c_r] = 1.0  # slopes of the rotation
    return R


def admissible(T: sp.spmatrix, R: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Basis (in reduced coordinates q, q_full = T q) of the rigid motions span(R) in range(T)."""
    TtT = sp.csc_matrix(T.T @ T)
    Q = spla.splu(TtT).solve(np.asarray(T.T @ R))
    E = T @ Q - R
    # combinations c with E c = 0 relative to |R c|: generalized SVD via R's QR
    Rq, Rr = np.linalg.qr(R)
    s, Vt = np.linalg.svd(E @ np.linalg.inv(Rr), full_matrices=False)[1:]
    keep = s < tol
    C = np.linalg.solve(Rr, Vt[keep].T)
    return Q @ C


def rigid_modes(model, T: sp.spmatrix) -> np.ndarray:
    """Basis (in q, q_full = T q) of the rigid motions the constraints admit and the bearings leave free
    of strain energy (a shaft on bearings keeps only the motions they do not resist, e.g. axial travel
    without a thrust bearing)."""
    A = admissible(T, rigid_fields(model))
    Kb = getattr(model, "K_bearing", None)
    if A.shape[1] == 0 or Kb is None or Kb.nnz == 0:
        return A
    B = np.asarray(T @ A)
    E = B.T @ (Kb @ B)
    w, V = np.linalg.eigh((E + E.T) / 2)
    scale = float(abs(Kb).max()) * float(np.abs(B).max()) ** 2
    return A @ V[:, w <= 1e-12 * scale]
