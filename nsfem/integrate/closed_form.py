"""Closed-form solution of x' = A x + B phi(t) with phi(t) = sum_mu f_mu e^{mu t}, valid at resonance.

With A = V diag(lam) V^-1 each modal coordinate obeys z_j' = lam_j z_j + sum_mu beta_mu,j e^{mu t},

    z_j(tau) = e^{lam_j tau} z_j(0) + sum_mu beta_mu,j F[lam_j, mu](tau),

where F[x_0, ..., x_m](tau) is the divided difference over the nodes x_i of x -> e^{x tau}
(F[a, b] = (e^{b tau} - e^{a tau}) / (b - a), and tau e^{a tau} when a = b). Nodes far apart are
split into exponentials (the usual particular solutions); nodes that nearly coincide (forcing at
a natural frequency, a constant load on a zero eigenvalue) are kept as divided differences and
evaluated without cancellation, so the exact resonance costs what its neighbourhood costs.

Rigid-body positions a (coordinates with no stiffness, split off by the configuration) are
integrals of velocity components of the modal part, a(tau) = a(0) + int_0^tau S w: divided
differences over {0, lam_j, mu}, i.e. polynomials in tau for a free body under a constant load
(no round-off exponential, no drift).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: nodes closer than RES times their size are evaluated together (a divided difference):
#: split into exponentials their terms would cancel by up to 1 / (|a - b| tau); RES = 1e-3 keeps
#: that loss below 1e3 eps relative to the steady amplitude |beta| / |a - b| of the pair
RES = 1e-3


def _close(a, b, floor: float) -> np.ndarray:
    return np.abs(a - b) <= RES * np.maximum(np.abs(a), np.abs(b)) + floor


def _phi1(z: np.ndarray) -> np.ndarray:
    """(e^z - 1) / z, 1 at z = 0 (complex, without cancellation)."""
    zs = np.where(z == 0, 1.0, z)
    return np.where(z == 0, 1.0, np.expm1(zs) / zs)


def divided_exp(nodes: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """F[x_0, .., x_{m-1}](tau) of x -> e^{x tau} for m = 2 or 3 nodes per column.

    ``nodes``: (m, K) complex, ``tau``: (T,) >= 0; returns (K, T). Shifted by the first node,
    F = e^{x_0 tau} F[0, x_1 - x_0, ..](tau): m = 2 is tau phi1(d tau) exactly; m = 3 is the
    Taylor series when all (x_i - x_0) tau are at most 1, else the recursion over the farthest
    pair (whose difference then is not small)."""
    nodes = np.asarray(nodes, dtype=complex)
    tau = np.asarray(tau, dtype=float)[None, :]
    x0 = nodes[0][:, None]
    base = np.exp(x0 * tau)
    if nodes.shape[0] == 2:
        d = (nodes[1] - nodes[0])[:, None]
        return base * tau * _phi1(d * tau)
    d1, d2 = (nodes[1] - nodes[0])[:, None], (nodes[2] - nodes[0])[:, None]
    size = np.maximum(np.maximum(np.abs(d1), np.abs(d2)), np.abs(d2 - d1)) * tau
    out = np.empty(np.broadcast_shapes(d1.shape, tau.shape), dtype=complex)
    small = size <= 1.0
    if np.any(small):
        # F[0, d1, d2](tau) = sum_k tau^(k+2) / (k+2)! h_k(0, d1, d2), h_k = sum_{i<=k} d1^i d2^(k-i)
        dd1, dd2, tt = np.broadcast_to(d1, out.shape)[small], np.broadcast_to(d2, out.shape)[small], \
            np.broadcast_to(tau, out.shape)[small]
        h = np.ones_like(dd1)        # h_0
        p2 = np.ones_like(dd1)       # d2^k
        term = tt * tt / 2.0
        acc = term * h
        for k in range(1, 30):
            p2 = p2 * dd2
            h = h * dd1 + p2          # h_k = d1 h_{k-1} + d2^k
            term = term * tt / (k + 2)
            acc = acc + term * h
        out[small] = acc
    if np.any(~small):
        # F[0, d1, d2] = (F[0, d2] - F[0, d1]) / (d2 - d1) when d2 - d1 is the largest difference,
        # else shift to the node that makes the farthest pair the outer one
        D1, D2, TT = (np.broadcast_to(v, out.shape)[~small] for v in (d1, d2, tau))
        g1, g2 = TT * _phi1(D1 * TT), TT * _phi1(D2 * TT)
        far = np.abs(D2 - D1) >= np.maximum(np.abs(D1), np.abs(D2)) * 0.5
        val = np.empty_like(D1)
        val[far] = (g2[far] - g1[far]) / (D2[far] - D1[far])
        # otherwise 0 is the outlier: F[0, d1, d2] = (F[d1, d2] - F[0, d1]) / d2 with F[d1, d2] close
        nf = ~far
        if np.any(nf):
            f12 = np.exp(D1[nf] * TT[nf]) * TT[nf] * _phi1((D2[nf] - D1[nf]) * TT[nf])
            val[nf] = (f12 - g1[nf]) / D2[nf]
        out[~small] = val
    return base * out


def divided_exp_bound(nodes: np.ndarray, order: int, horizon: float) -> np.ndarray:
    """Per column, a bound of |d^order/dtau^order F[nodes](tau)| on [0, horizon].

    Hermite-Genocchi: F[x_0..x_{m-1}] averages tau^(m-1) e^{xi tau} / (m-1)! over the nodes' hull;
    its derivatives are bounded with |xi| <= rho = max |x_i| and Re xi <= max Re x_i."""
    nodes = np.asarray(nodes, dtype=complex)
    m = nodes.shape[0]
    rho = np.max(np.abs(nodes), axis=0)
    with np.errstate(over="ignore"):
        grow = np.exp(np.maximum(np.max(nodes.real, axis=0), 0.0) * horizon)
    total = np.zeros_like(rho)
    for i in range(min(order, m - 1) + 1):
        total += math.comb(order, i) * math.perm(m - 1, i) * horizon ** (m - 1 - i) * rho ** (order - i)
    return total * grow / math.factorial(m - 1)


@dataclass
class Motion:
    """x(tau) = Re[U e^{nu tau} + sum over divided-difference groups D F[nodes](tau)]."""

    nu: np.ndarray          # (p,) exponents
    U: np.ndarray           # (d, p)
    groups: list            # [(nodes (m, K), D (d, K))]

    def evaluate(self, tau: np.ndarray, H: np.ndarray | None = None) -> np.ndarray:
        """H x(tau) (x itself without H), tau: (T,) -> (rows, T)."""
        U = self.U if H is None else H @ self.U
        out = np.real(U @ exponentials(self.nu, tau))
        for nodes, D in self.groups:
            DD = D if H is None else H @ D
            out += np.real(DD @ divided_exp(nodes, tau))
        return out

    def bound(self, H: np.ndarray | None, order: int, horizon: float) -> np.ndarray:
        """Per row of H x (of x without H), a bound of its order-th derivative on [0, horizon]."""
        with np.errstate(over="ignore"):
            grow = np.exp(np.maximum(self.nu.real, 0.0) * horizon)
            b = np.abs(self.U if H is None else H @ self.U) @ (np.abs(self.nu) ** order * grow)
            for nodes, D in self.groups:
                b = b + np.abs(D if H is None else H @ D) @ divided_exp_bound(nodes, order, horizon)
        return b


def exponentials(nu: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """e^{nu tau} (p x T); on a uniform grid by repeated multiplication (relative error ~ k eps)."""
    tau = np.atleast_1d(np.asarray(tau, dtype=float))
    d = np.diff(tau)
    if tau.size > 8 and np.all(np.abs(d - d[0]) <= 1e-12 * abs(d[0])):
        E = np.empty((nu.size, tau.size), dtype=complex)
        E[:, 0] = np.exp(nu * tau[0])
        E[:, 1:] = np.exp(nu * d[0])[:, None]
        return np.cumprod(E, axis=1)
    return np.exp(np.outer(nu, tau))


def modal_motion(lam, V, Vi, w0, forcing: dict, k: int, S: np.ndarray, a0: np.ndarray, floor: float) -> Motion:
    """The motion of x = (a, w) from x(0) = (a0, w0) under w' = A_w w + sum_mu b_mu e^{mu tau},
    a' = S w, with A_w = V diag(lam) Vi; ``forcing``: {mu: b_mu} (b_mu in w-space, e^{mu t0} folded
    in). ``floor``: absolute closeness of nodes (round-off of the eigenvalues)."""
    dw = V.shape[0]
    d = k + dw
    z0 = Vi @ w0
    mus = sorted(forcing, key=lambda m: (abs(m), m.imag))
    beta = {mu: Vi @ forcing[mu] for mu in mus}
    coef = z0.astype(complex).copy()            # of e^{lam_j tau}, modal
    X = {0j: np.zeros(d, dtype=complex)}        # of e^{mu tau}, x-space
    X[0j][:k] = a0
    Ua = np.zeros((k, lam.size), dtype=complex)  # a-rows of the e^{lam_j tau} terms
    dd2n, dd2c, dd3n, dd3c = [], [], [], []
    SV = S @ V if k else np.zeros((0, lam.size))

    for mu in mus:
        X.setdefault(mu, np.zeros(d, dtype=complex))
        b = beta[mu]
        res = _close(lam, mu, floor)
        far = ~res
        with np.errstate(divide="ignore", invalid="ignore"):
            g = np.where(far, b / np.where(far, mu - lam, 1.0), 0.0)
        coef -= g
        X[mu][k:] += V @ g
        for j in np.flatnonzero(res):
            col = np.zeros(d, dtype=complex)
            col[k:] = V[:, j] * b[j]
            dd2n.append((lam[j], mu))
            dd2c.append(col)
    if k:
        # a(tau) = a0 + sum_j SV_j [z0_j F[0, lam_j] + sum_mu beta_mu,j F[0, lam_j, mu]]
        moved = np.any(SV != 0, axis=0)
        # modes far from 0 and from every forcing exponent (mu = 0 or far from 0): their terms split
        # the same way for all of them, done at once (:func:`_far_rigid_terms`)
        far = moved & ~_close(lam, 0j, floor)
        for mu in mus:
            far &= ~_close(lam, mu, floor)
        if any(mu != 0 and _close(mu, 0j, floor) for mu in mus):
            far[:] = False
        if np.any(far):
            _far_rigid_terms(lam[far], SV[:, far], z0[far], {mu: beta[mu][far] for mu in mus}, k, Ua, far, X,
                             dd2n, dd2c)
        for j in np.flatnonzero(moved & ~far):
            s = SV[:, j]
            mode = (lam[j], "mode")
            terms = [(z0[j], [(0j, 0j), mode])] + [(beta[mu][j], [(0j, 0j), mode, (mu, mu)]) for mu in mus]
            for c, nodes in terms:
                if c == 0:
                    continue
                vec = c * s
                exps, dds = _split(nodes, floor)
                for key, div in exps:   # a-rows of e^{x tau}: the mode's own column, or a forcing's
                    if key == "mode":
                        Ua[:, j] += _divide(vec, div)
                    else:
                        X.setdefault(key, np.zeros(d, dtype=complex))[:k] += _divide(vec, div)
                for dd_nodes, div in dds:
                    col = np.zeros(d, dtype=complex)
                    col[:k] = _divide(vec, div)
                    (dd2n if len(dd_nodes) == 2 else dd3n).append(dd_nodes)
                    (dd2c if len(dd_nodes) == 2 else dd3c).append(col)
    U = np.zeros((d, lam.size), dtype=complex)
    U[k:] = V * coef[None, :]
    U[:k] = Ua
    nu = np.concatenate([lam, np.array(list(X), dtype=complex)])
    U = np.hstack([U, np.column_stack(list(X.values()))])
    groups = [_merged(nodes, cols) for nodes, cols in ((dd2n, dd2c), (dd3n, dd3c)) if nodes]
    return Motion(nu, U, groups)


def _merged(nodes: list, cols: list) -> tuple[np.ndarray, np.ndarray]:
    """A divided-difference group (nodes (m, K), D (d, K)) with the columns of equal nodes summed (the
    F[0, 0] of a constant load is shared by every mode of a rigid body)."""
    index: dict = {}
    for key in nodes:
        index.setdefault(tuple(key), len(index))
    D = np.zeros((cols[0].shape[0], len(index)), dtype=complex)
    for key, col in zip(nodes, cols):
        D[:, index[tuple(key)]] += col
    return np.array(list(index), dtype=complex).T, D


def _far_rigid_terms(lam, SV, z0, beta: dict, k: int, Ua, sel, X: dict, dd2n: list, dd2c: list) -> None:
    """The rigid rows of modes far from 0 and from every forcing exponent mu (each mu 0 or far from
    0), for all of them at once: F[0, lam] = (e^{lam tau} - 1) / lam; F[0, lam, mu] by partial
    fractions over its three nodes, and for mu = 0, F[0, 0, lam] = (e^{lam tau} - 1 - lam tau) / lam^2
    (the tau term a divided difference F[0, 0]). Same terms as :func:`_split` gives one mode at a time."""
    V0 = SV * z0[None, :] / lam[None, :]
    Ua[:, sel] += V0
    X[0j][:k] -= V0.sum(axis=1)
    for mu, b in beta.items():
        Vb = SV * b[None, :]
        if mu == 0:
            V1 = Vb / lam[None, :]
            V2 = V1 / lam[None, :]
            Ua[:, sel] += V2
            X[0j][:k] -= V2.sum(axis=1)
            col = np.zeros(X[0j].shape[0], dtype=complex)
            col[:k] = -V1.sum(axis=1)
            dd2n.append((0j, 0j))
            dd2c.append(col)
            continue
        Ua[:, sel] += Vb / (lam * (lam - mu))[None, :]
        X[0j][:k] += (Vb / (lam * mu)[None, :]).sum(axis=1)
        X[mu][:k] += (Vb / (mu * (mu - lam))[None, :]).sum(axis=1)


def _divide(vec: np.ndarray, div: tuple) -> np.ndarray:
    """sign * vec / d_1 / d_2 ... for div = (sign, d_1, d_2, ...)."""
    out = vec if div[0] > 0 else -vec
    for d in div[1:]:
        out = out / d
    return out


def _split(nodes: list, floor: float) -> tuple[list, list]:
    """F[x_0, .., x_m] (m = 1, 2) as exponentials where the nodes are far apart and divided
    differences where they are close: ([(key, divisors)], [(close nodes, divisors)]), each term
    :func:`_divide` of the coefficient by its divisors; ``nodes``: [(x, key)], the key naming the
    exponential a node's term belongs to."""
    x = [v for v, _ in nodes]
    if len(nodes) == 2:
        (p, kp), (q, kq) = nodes
        if _close(p, q, floor):
            return [], [((p, q), (1,))]
        return [(kq, (1, q - p)), (kp, (-1, q - p))], []
    pairs = [(a, b) for a in range(3) for b in range(a + 1, 3) if _close(x[a], x[b], floor)]
    if not pairs:   # partial fractions
        return [(nodes[i][1], (1, np.prod([x[i] - x[j] for j in range(3) if j != i]))) for i in range(3)], []
    if len(pairs) >= 2:
        return [], [(tuple(x), (1,))]
    # one close pair {p, q}, s far: F[p, q, s] = (F[q, s] - F[p, q]) / (s - p), F[q, s] split
    a, b = pairs[0]
    c = 3 - a - b
    (p, _), (q, kq), (s_, ks) = nodes[a], nodes[b], nodes[c]
    den = s_ - p
    return [(ks, (1, den, s_ - q)), (kq, (-1, den, s_ - q))], [((p, q), (-1, den))]
