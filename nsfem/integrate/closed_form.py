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
        # (the terms past _terms' count sum to below 1e-18 of tt^2 / 2, below half an ulp of the sum, which is at
        # least 0.19 tt^2 / 2 here (|d| tt <= 1: the integrand's real part is at least e^-1 cos 1): leaving them
        # out changes no bit; the nodes of rigid rows, 0 to round-off, need one or two)
        rho = float(np.max(np.maximum(np.abs(dd1), np.abs(dd2)) * tt, initial=0.0))
        for k in range(1, _terms(rho, 2)):
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

    def evaluate(self, tau: np.ndarray, H: np.ndarray | None = None, E: np.ndarray | None = None) -> np.ndarray:
        """H x(tau) (x itself without H), tau: (T,) -> (rows, T); ``E``: e^{nu tau} when formed."""
        U = self.U if H is None else H @ self.U
        out = np.real(U @ (exponentials(self.nu, tau) if E is None else E))
        for nodes, D in self.groups:
            DD = D if H is None else H @ D
            out += np.real(DD @ divided_exp(nodes, tau))
        return out

    def on_grid(self, tau0: float, dtau: float, n: int) -> np.ndarray:
        """x at the n times tau0 + j dtau, its exponentials by repeated products from e^{nu tau0} with the
        step e^{nu dtau} (relative error ~ j eps; :func:`exponentials` does the same on a grid it finds
        uniform)."""
        E = np.empty((self.nu.size, n), dtype=complex)
        E[:, 0] = np.exp(self.nu * tau0)
        E[:, 1:] = np.exp(self.nu * dtau)[:, None]
        return self.evaluate(tau0 + dtau * np.arange(n), E=np.cumprod(E, axis=1))

    def bound(self, H: np.ndarray | None, order: int, horizon: float, since: float = 0.0,
              HU: np.ndarray | None = None) -> np.ndarray:
        """Per row of H x (of x without H), a bound of its order-th derivative on [since, horizon]: a
        growing term at its size at the horizon, a decaying one at its size at ``since`` (a divided-
        difference group at its bound over [0, horizon]). ``HU``: H U when the caller has it."""
        with np.errstate(over="ignore"):
            grow = decay_factors(self.nu, horizon, since)
            HU = (self.U if H is None else H @ self.U) if HU is None else HU
            b = np.abs(HU) @ (power(np.abs(self.nu), order) * grow)
            for nodes, D in self.groups:
                b = b + np.abs(D if H is None else H @ D) @ divided_exp_bound(nodes, order, horizon)
        return b


def power(x, order: int):
    """x^order as repeated products, x * x * ... left to right (C's pow and NumPy's power round differently
    from each other: the compiled search forms the same products)."""
    out = 1.0
    for _ in range(order):
        out = out * x
    return out


def decay_factors(nu: np.ndarray, horizon: float, since: float = 0.0) -> np.ndarray:
    """max |e^{nu tau}| over tau in [since, horizon] per exponent: e^{Re(nu) horizon} for a growing
    term, e^{Re(nu) since} for a decaying one (1 for a steady one)."""
    with np.errstate(over="ignore"):
        re = nu.real
        return np.exp(np.where(re > 0.0, re * horizon, re * since))


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


class ModalPlan:
    """The motion of x = (a, w) from x(0) = (a0, w0) under w' = A_w w + sum_mu b_mu e^{mu tau}, a' = S w,
    with A_w = V diag(lam) V^-1, split into what the configuration fixes and what each phase adds.

    Every term of the motion is a modal coefficient, z0 = V^-1 w0 or beta_mu = V^-1 b_mu, times a factor
    that depends on the nodes only: the particular solutions' 1 / (mu - lam_j), the divided differences
    of resonant pairs and the rigid rows' partial fractions. They are found once here (which nodes are
    close, how the rigid rows split); :meth:`motion` is then a few products per phase.
    ``mus``: the forcing exponents, 0 (the constant load) first; ``floor``: absolute closeness of nodes
    (round-off of the eigenvalues)."""

    def __init__(self, lam: np.ndarray, V: np.ndarray, mus: list, k: int, S: np.ndarray, floor: float):
        m, nmu = lam.size, len(mus)
        self.V, self.k, self.mus = V, k, list(mus)
        self.nu = np.concatenate([lam, np.array(mus, dtype=complex)])   # of U's columns: modes, then the mus
        self.nu.flags.writeable = False                                  # shared by the phases' motions
        res = np.array([_close(lam, mu, floor) for mu in mus]).reshape(nmu, m)
        # the particular solutions' divisors mu - lam_j; a resonant pair has none (b / inf = 0): its term
        # is a divided difference
        self.den = np.where(res, np.inf, np.subtract.outer(np.array(mus, dtype=complex), lam))
        # divided-difference terms: (nodes, source (0: z0, 1 + i: beta of mus[i]), mode, factor, rigid row,
        # kept also with a zero coefficient); sources index the rows of (z0, beta)
        terms = [((lam[j], mu), 1 + i, j, 1.0, False, True) for i, mu in enumerate(mus) for j in np.flatnonzero(res[i])]
        self.SV = S @ V if k else np.zeros((0, m))
        if k:
            self.Fa = np.zeros((1 + nmu, m), dtype=complex)        # a-rows of the e^{lam_j tau} terms
            self.Fx = np.zeros((1 + nmu, m, nmu), dtype=complex)   # a-rows of the e^{mu tau} terms
            self._rigid(lam, mus, floor, terms)
        self.groups = [self._group([t for t in terms if len(t[0]) == n], m, nmu) for n in (2, 3)]
        self.groups = [g for g in self.groups if g is not None]

    def _rigid(self, lam, mus, floor, terms: list) -> None:
        """The factors of the rigid rows a(tau) = a0 + sum_j SV_j [z0_j F[0, lam_j] + sum_mu beta_mu,j
        F[0, lam_j, mu]]."""
        moved = np.any(self.SV != 0, axis=0)
        # modes far from 0 and from every forcing exponent (mu = 0 or far from 0): F[0, lam] = (e^{lam tau} - 1)
        # / lam; F[0, lam, mu] by partial fractions over its three nodes, and for mu = 0, F[0, 0, lam] =
        # (e^{lam tau} - 1 - lam tau) / lam^2 (the tau term a divided difference F[0, 0]): the terms
        # :func:`_split` gives, for all of them at once
        far = moved & ~_close(lam, 0j, floor)
        for mu in mus:
            far &= ~_close(lam, mu, floor)
        if any(mu != 0 and _close(mu, 0j, floor) for mu in mus):
            far[:] = False
        lf = lam[far]
        self.Fa[0, far] += 1.0 / lf
        self.Fx[0, far, 0] -= 1.0 / lf
        for i, mu in enumerate(mus):
            if mu == 0:
                self.Fa[1 + i, far] += 1.0 / lf / lf
                self.Fx[1 + i, far, 0] -= 1.0 / lf / lf
                terms += [((0j, 0j), 1 + i, j, -1.0 / lam[j], True, True) for j in np.flatnonzero(far)]
                continue
            self.Fa[1 + i, far] += 1.0 / (lf * (lf - mu))
            self.Fx[1 + i, far, 0] += 1.0 / (lf * mu)
            self.Fx[1 + i, far, i] += 1.0 / (mu * (mu - lf))
        for j in np.flatnonzero(moved & ~far):
            mode = (lam[j], "mode")
            nodes = [[(0j, 0j), mode]] + [[(0j, 0j), mode, (mu, mu)] for mu in mus]
            for src, nodes_ in enumerate(nodes):
                exps, dds = _split(nodes_, floor)
                for key, div in exps:   # a-rows of e^{x tau}: the mode's own column, or a forcing's
                    if key == "mode":
                        self.Fa[src, j] += _divide(1.0, div)
                    else:
                        self.Fx[src, j, mus.index(key)] += _divide(1.0, div)
                terms += [(dd_nodes, src, j, _divide(1.0, div), True, False) for dd_nodes, div in dds]

    @staticmethod
    def _group(terms: list, m: int, nmu: int):
        """(nodes (n, K), factors of the w-rows and of the a-rows (1 + nmu, m, K; None without any), the
        terms' sources ((1 + nmu) m, K), columns kept with zero coefficients (K,)) of the divided
        differences with n nodes, equal nodes one column (the F[0, 0] of a constant load is shared by
        every mode of a rigid body); None without any."""
        if not terms:
            return None
        index: dict = {}
        for t in terms:
            index.setdefault(tuple(t[0]), len(index))
        K = len(index)
        Fw, Fr = np.zeros((1 + nmu, m, K), dtype=complex), np.zeros((1 + nmu, m, K), dtype=complex)
        source, always = np.zeros((1 + nmu, m, K)), np.zeros(K, dtype=bool)
        for nodes, src, j, factor, rigid, keep in terms:
            c = index[tuple(nodes)]
            (Fr if rigid else Fw)[src, j, c] += factor
            source[src, j, c] = 1.0
            always[c] |= keep
        return (np.array(list(index), dtype=complex).T, Fw if Fw.any() else None, Fr if Fr.any() else None,
                source.reshape(-1, K), always)

    def motion(self, z0: np.ndarray, beta: np.ndarray, a0: np.ndarray) -> tuple[Motion, tuple]:
        """(Motion, (c, g)) from z0 = V^-1 w0, beta (len(mus), m) = V^-1 b_mu (e^{mu t0} folded in) and a0:
        w(tau) = V (c e^{lam tau} + sum_mu g_mu e^{mu tau}) plus the divided differences."""
        U, c, g = self.modes(z0, beta)
        return self.complete(U, z0, beta, a0), (c, g)

    def modes(self, z0: np.ndarray, beta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(U, c, g): the modes' and particular solutions' part of the motion, U[k:] = V [diag(c), g^T]
        (U[:k], the rigid rows, left to :meth:`complete`)."""
        k, V, m = self.k, self.V, z0.size
        g = beta / self.den                     # the particular solutions, modal
        c = z0
        U = np.empty((k + V.shape[0], self.nu.size), dtype=complex)
        for i, gi in enumerate(g):              # one mu at a time: the same round-off for any number of them
            c = c - gi
            U[k:, m + i] = V @ gi
        U[k:, :m] = V * c[None, :]
        return U, c, g

    def complete(self, U: np.ndarray, z0: np.ndarray, beta: np.ndarray, a0: np.ndarray) -> Motion:
        """The Motion of U (from :meth:`modes`) with its rigid rows and divided differences."""
        k, V, m = self.k, self.V, z0.size
        C = np.vstack([z0, beta]) if k or self.groups else None     # the coefficients by source
        if k:
            U[:k, :m] = self.SV * np.einsum("im,im->m", self.Fa, C)
            U[:k, m:] = self.SV @ np.einsum("imc,im->mc", self.Fx, C)
            U[:k, m] += a0
        groups = []
        for nodes, Fw, Fr, source, always in self.groups:
            D = np.zeros((U.shape[0], nodes.shape[1]), dtype=complex)
            if Fw is not None:      # resonant pairs
                D[k:] = V @ np.einsum("imK,im->mK", Fw, C)
            if Fr is None:
                groups.append((nodes, D))
                continue
            D[:k] = self.SV @ np.einsum("imK,im->mK", Fr, C)
            # a rigid row's term of a zero coefficient is no term (its nodes would set the search's rate)
            kept = always | (source.T @ (C != 0).ravel() > 0)
            if kept.any():
                groups.append((nodes, D) if kept.all() else (nodes[:, kept], D[:, kept]))
        return Motion(self.nu, U, groups)


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


# -- work integrals of a motion with divided-difference groups ------------------------------------------
#: terms of the Taylor series of a divided difference whose nodes lie within 1 / T of each other: the k-th is
#: at most C(k + N - 2, N - 2) / (k + N - 1)! of the size T^(N-1) / (N-1)!, below 1e-20 of it at k = 30
_TAYLOR_TERMS = 30


def _terms(rho: float, n: int) -> int:
    """Terms of the series sum_k rho^k C(k + n - 1, n - 1) n! / (k + n)! (the Taylor series of a divided
    difference over n + 1 nodes within rho / T of the first, relative to its size) that leave a remainder
    below 1e-18 (rho <= 1: at most :data:`_TAYLOR_TERMS`)."""
    if rho == 0.0:
        return 1
    t = 1.0
    for k in range(1, _TAYLOR_TERMS):
        t *= rho * (k + n - 1) / k / (k + n)
        if t <= 1e-18:
            return k
    return _TAYLOR_TERMS


def divided_exp_at(nodes: np.ndarray, T: float) -> np.ndarray:
    """F[x_0, .., x_{N-1}](T) of x -> e^{x T} for any number N >= 1 of nodes per column (``nodes`` (N, P)
    complex, T >= 0 one time); returns (P,).

    Nodes within 1 / T of each other: the Taylor series after a shift to the first node,
    F = e^{x_0 T} sum_k T^(k+N-1) / (k+N-1)! h_k(x_1 - x_0, ..), h_k the complete homogeneous symmetric
    polynomials; otherwise the recursion over the farthest pair (x_i, x_j), F = (F[nodes without x_i] -
    F[nodes without x_j]) / (x_j - x_i), whose divisor is then above 1 / T: the difference loses at most
    the size T^(N-1) e^{max Re x T} / (N-1)! times a few eps (Hermite-Genocchi bounds both terms)."""
    X = np.asarray(nodes, dtype=complex)
    N = X.shape[0]
    if N == 1:
        return np.exp(X[0] * T)
    if N == 2:
        return np.exp(X[0] * T) * T * _phi1((X[1] - X[0]) * T)
    gap = np.abs(X[:, None, :] - X[None, :, :]).reshape(N * N, -1)
    far = np.argmax(gap, axis=0)
    out = np.empty(X.shape[1], dtype=complex)
    small = gap[far, np.arange(X.shape[1])] * T <= 1.0
    if np.any(small):
        Xs = X[:, small]
        d = Xs[1:] - Xs[0]
        H = np.ones_like(d)                 # H[j]: h_k(d_0, .., d_j), here k = 0
        term = T ** (N - 1) / math.factorial(N - 1)
        acc = term * H[-1]
        for k in range(1, _terms(float(np.max(np.abs(d))) * T, N - 1)):
            H[0] = H[0] * d[0]
            for j in range(1, N - 1):
                H[j] = H[j - 1] + d[j] * H[j]
            term = term * T / (k + N - 1)
            acc = acc + term * H[-1]
        out[small] = np.exp(Xs[0] * T) * acc
    if not np.all(small):
        cols = np.flatnonzero(~small)
        i, j = far[cols] // N, far[cols] % N
        # the nodes reordered per column: x_i first, x_j last, the others between (their order is free)
        order = np.empty((N, cols.size), dtype=int)
        order[0], order[-1] = i, j
        rest = np.argsort((np.arange(N)[:, None] == i) | (np.arange(N)[:, None] == j), axis=0, kind="stable")
        order[1:-1] = rest[: N - 2]
        Xf = X[order, cols]
        out[cols] = (divided_exp_at(Xf[1:], T) - divided_exp_at(Xf[:-1], T)) / (Xf[-1] - Xf[0])
    return out


def _expm_triangular(Z: np.ndarray) -> np.ndarray:
    """exp(Z) of a stack of upper triangular (P, S, S) complex matrices whose diagonals have real parts
    <= 0: scaled by 2^s to a 1-norm of at most 1/2, the Taylor series (S - 1 terms and as many more as
    leave a remainder below 1e-18), squared s times."""
    S = Z.shape[-1]
    norm = float(np.max(np.sum(np.abs(Z), axis=-2), initial=0.0))
    s = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    Zs = Z / 2.0 ** s
    # terms: an entry k places above the diagonal starts at the k-th power (a path of k steps up); past
    # that, the remainder of sum_j |Z|^j / j! below 1e-18 (|Z| <= 1/2: at most 16 more)
    rho, j, t = norm / 2.0 ** s, 1, 1.0
    while j < 24 and t * rho > 1e-18:
        j += 1
        t *= rho / j
    n = S - 1 + j
    I = np.eye(S)
    E = I + Zs / n
    for k in range(n - 1, 0, -1):          # Horner: I + Z/1 (I + Z/2 (I + ...))
        E = Zs @ E
        E /= k
        E += I
    for _ in range(s):
        E = E @ E
    return E


def product_integrals(A: np.ndarray, B: np.ndarray, T: float) -> np.ndarray:
    """int_0^T F[A_p](s) F[B_p](s) ds per column p of the nodes A (m, P) and B (n, P).

    Opitz: F[X](s) is the corner entry of exp(s J_X), J_X bidiagonal with the nodes on its diagonal and
    ones above; the product of two is the corner entry of exp(s K), K = J_A (x) I + I (x) J_B, and its
    integral the corner of exp(T [[K, e], [0, 0]]) (e the last unit vector): one upper triangular
    exponential of size m n + 1 per column (:func:`_expm_triangular`, after a shift by the largest real
    part of its diagonal). Meant for the slow nodes of divided-difference groups (near 0 or a forcing
    exponent), whose spans T |x| are small."""
    A, B = np.asarray(A, dtype=complex), np.asarray(B, dtype=complex)
    m, n, P = A.shape[0], B.shape[0], A.shape[1]
    S = m * n + 1
    K = np.zeros((P, S, S), dtype=complex)
    idx = np.arange(m * n)
    a, b = idx // n, idx % n
    K[:, idx, idx] = (A[a] + B[b]).T
    for i in range(m * n):          # J_A (x) I: (a, b) -> (a + 1, b); I (x) J_B: (a, b) -> (a, b + 1)
        if a[i] + 1 < m:
            K[:, i, i + n] = 1.0
        if b[i] + 1 < n:
            K[:, i, i + 1] = 1.0
    K[:, m * n - 1, S - 1] = 1.0
    shift = np.maximum(np.max(np.real(A[a] + B[b]), axis=0), 0.0)       # (P,): e^{shift T} taken out
    Z = T * (K - shift[:, None, None] * np.eye(S))
    return np.exp(shift * T) * _expm_triangular(Z)[:, 0, S - 1]


def group_integrals(nu: np.ndarray, groups: list, T: float, pairs: bool = True):
    """The integrals over [0, T] of products of a motion's divided-difference columns (F[X_c], the
    groups' nodes (m, K) in order) with its exponentials e^{nu_j s} and with each other: (Pe (Kt, len(nu)),
    Pg (Kt, Kt) or None without ``pairs``).

    int e^{nu s} F[X](s) ds = F[0, X + nu](T) (e^{nu s} shifts the nodes; integrating from 0 adds the node
    0): :func:`divided_exp_at` with m + 1 nodes; the products of two columns by :func:`product_integrals`."""
    nu = np.asarray(nu, dtype=complex)
    cols = [nodes[:, c] for nodes, _ in groups for c in range(nodes.shape[1])]
    Kt, p = len(cols), nu.size
    Pe = np.empty((Kt, p), dtype=complex)
    start = 0
    for nodes, _ in groups:
        m, K = nodes.shape
        X = np.empty((m + 1, K, p), dtype=complex)
        X[0] = 0.0
        X[1:] = nodes[:, :, None] + nu[None, None, :]
        Pe[start: start + K] = divided_exp_at(X.reshape(m + 1, K * p), T).reshape(K, p)
        start += K
    if not pairs:
        return Pe, None
    Pg = np.empty((Kt, Kt), dtype=complex)
    sizes = np.array([c.size for c in cols])
    for ma in np.unique(sizes):
        for mb in np.unique(sizes):
            if ma > mb:     # (the pair (mb, ma) fills both triangles)
                continue
            I, J = np.meshgrid(np.flatnonzero(sizes == ma), np.flatnonzero(sizes == mb), indexing="ij")
            I, J = (I[I <= J], J[I <= J]) if ma == mb else (I.ravel(), J.ravel())
            A = np.array([cols[i] for i in I]).T
            B = np.array([cols[j] for j in J]).T
            v = product_integrals(A, B, T)
            Pg[I, J] = v
            Pg[J, I] = v
    return Pe, Pg
