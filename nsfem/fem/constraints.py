"""Exact elimination of linear constraints: q_full = T q with C T = 0.

Supports, junctions (design section 3) and, for the closed linearization, contact
closures are homogeneous linear constraints C q_full = 0 on few dofs. Gauss-Jordan
elimination on the columns they touch picks one slave dof per independent row (a
preferred one when given and well-conditioned, else the largest pivot) and expresses it
through the remaining masters. T is sparse (identity on masters), so T^T M T and
T^T K T stay symmetric; redundant rows (a dof fixed twice) are dropped.

>>> import numpy as np, scipy.sparse as sp
>>> C = sp.csr_matrix(np.array([[1.0, -1.0, 0.0]]))    # q0 = q1
>>> T, slaves = constraint_basis(C, 3, prefer=[0])
>>> T.toarray().tolist(), slaves.tolist()
([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]], [0])
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
import scipy.sparse as sp

#: A row whose largest entry after elimination is below this fraction of its original
#: size depends on earlier rows and is dropped.
REDUNDANT = 1e-10
#: A preferred slave is used while its pivot is at least this fraction of the row's largest.
PREFER = 0.1


def constraint_basis(C: sp.spmatrix, n: int, prefer: Sequence[int | None] | None = None,
                     row_scale: np.ndarray | None = None) -> tuple[sp.csr_matrix, np.ndarray]:
    """Null-space basis T (n x (n - rank)) of the sparse constraint rows C, and the slave dofs.

    ``row_scale`` is the size each row is judged against for redundancy (default: its own
    largest entry). Pass it when C = C0 T0 is a projection: a row that cancels to round-off
    there (a tie between two dofs T0 already equates) must count as redundant.
    """
    C = sp.csr_matrix(C, shape=(C.shape[0], n))
    if C.shape[0] == 0 or C.nnz == 0:
        return sp.identity(n, format="csr"), np.zeros(0, dtype=int)
    cols = np.unique(C.indices)
    local = {c: i for i, c in enumerate(cols)}
    R = C[:, cols].toarray()
    size = np.abs(R).max(axis=1) if row_scale is None else np.asarray(row_scale, dtype=float)
    pivots: list[tuple[int, int]] = []
    for i in range(R.shape[0]):
        row = R[i]
        amax = np.abs(row).max()
        if amax <= REDUNDANT * size[i]:
            continue
        p = int(np.argmax(np.abs(row)))
        want = prefer[i] if prefer is not None else None
        if want is not None and want in local and abs(row[local[want]]) >= PREFER * amax:
            p = local[want]
        R[i] /= row[p]
        others = np.abs(R[:, p]) > 0
        others[i] = False
        R[others] -= np.outer(R[others, p], R[i])
        pivots.append((i, p))
    prow = np.array([i for i, _ in pivots], dtype=int)
    pcol = np.array([p for _, p in pivots], dtype=int)
    slaves = cols[pcol]
    is_master = np.ones(n, dtype=bool)
    is_master[slaves] = False
    masters = np.flatnonzero(is_master)
    position = -np.ones(n, dtype=int)
    position[masters] = np.arange(len(masters))
    rows, cc, vals = [masters], [np.arange(len(masters))], [np.ones(len(masters))]
    free = np.setdiff1d(np.arange(len(cols)), pcol)
    for r, s in zip(prow, slaves):
        coef = -R[r, free]
        keep = coef != 0.0
        rows.append(np.full(keep.sum(), s))
        cc.append(position[cols[free[keep]]])
        vals.append(coef[keep])
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cc))),
                      shape=(n, len(masters)))
    return T, np.sort(slaves)


def project(T, A: sp.spmatrix) -> sp.csr_matrix:
    """T^T A T; exactly symmetric (skew) when A is, removing round-off asymmetry.

    T may be sparse (constraints) or a dense basis (a reduction); A @ T is formed first,
    so a dense T never sits inside a sparse product.
    """
    A = sp.csr_matrix(A)
    B = sp.csr_matrix(T.T @ (A @ T))
    if A.nnz and abs(A - A.T).max() == 0.0:
        B = ((B + B.T) * 0.5).tocsr()
    elif A.nnz and abs(A + A.T).max() == 0.0:
        B = ((B - B.T) * 0.5).tocsr()
    return B


def dense(A) -> np.ndarray:
    """A sparse matrix or array as a dense ndarray."""
    return A.toarray() if sp.issparse(A) else np.asarray(A)
