"""Campbell diagram, gravity resonances and divergence speeds of a rotating beam stack (the inertial
frame's whirl senses, critical speeds and instability onsets: :mod:`.whirl`).

Rotating-frame natural frequencies come from the first-order form of eq. (22),

    [I 0; 0 M] z' = [0 I; -Q -C] z,   z = (q, q'),

solved for the eigenvalues nearest zero by shift-invert Arnoldi (sparse, exact model).

Gravity resonances: in the rotating frame gravity is a load at the rotation frequency,
f_g(t) = Re(F e^{i Omega t}) with F = g e^{i phi} (i Fy - Fz). The undamped response
X e^{i Omega t} solves [K0 + Omega^2 (Kc1 - M + i G1)] X = F, which is singular where

    K0 x = mu H x,   H = M - Kc1 - i G1   (Hermitian: G1 is real skew),   mu = Omega^2,

a generalized Hermitian eigenproblem solved directly (no scan over speed). A root
is a resonance only if gravity excites it: x^H F != 0 (measured in energy norms, so
the full and the reduced models agree). (An isotropic shaft has roots at
half its critical speeds that gravity cannot excite.) For a uniform shaft whose two
bending planes have squared frequencies a and b for one mode shape, the pair decouples
into q_v'' - 2 Omega q_w' + (a - Omega^2) q_v = f_v, q_w'' + 2 Omega q_v' +
(b - Omega^2) q_w = f_w; at forcing frequency Omega the determinant is
(a - 2 Omega^2)(b - 2 Omega^2) - 4 Omega^4 = a b - 2 Omega^2 (a + b), so the gravity
resonance is Omega^2 = a b / (2 (a + b)), i.e. near half the critical speed.

Divergence (supercritical) speeds: the symmetric part K0 + Omega^2 Kc1 of Q loses
definiteness where K0 x = Omega^2 (-Kc1) x; the number of its negative eigenvalues is
the number of such speeds below Omega, and where it is odd the rotor diverges whatever
its gyroscopic coupling (Kelvin-Tait-Chetaev): the bands between consecutive speeds,
e.g. between the two critical speeds of a shaft with unequal bending stiffnesses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..errors import NsfemError
from ..fem.constraints import dense as _dense
from ..fem.rotating import RotorOperators
from ..system import LinearSystem, check_damping, linear_system

if TYPE_CHECKING:
    from ..scene import Scene
    from .branches import Branches

#: A root counts as a gravity resonance when its excitation (see gravity_resonances, 0 for an
#: isotropic shaft, 0.05-0.2 for the shipped scene's real ones) exceeds this. Roots of the
#: shipped scene's nearly isotropic mode pairs sit at 1e-9 to 1e-6 and differ between full and
#: reduced models: practically unexcitable, dropped.
EXCITATION = 1e-4
#: Dense eigen solvers below this many dofs.
DENSE_LIMIT = 60
#: Resonances and divergence speeds of a reduced model are reported up to this fraction of
#: its highest kept mode's frequency (Craig-Bampton 16 modes: above it, roots were 17 % off).
VALID_FRACTION = 0.5
#: Dense fallback when Arnoldi fails, up to this many dofs.
DENSE_FALLBACK = 1500
#: Two computed roots are one defective root split by round-off when they lie closer than
#: RESOLUTION sqrt(eps) omega_max (omega_max: the model's fastest frequency, rad/s) and
#: their unit eigenvectors are nearly parallel (1 - |cos| < DEFECTIVE, an angle under 2.6
#: degrees). A Jordan block of the first-order form perturbed by round-off, eps |K| / m ~ eps
#: omega_max^2 in its stiffness entry, splits into lambda_0 +- sqrt(eps) omega_max c with c of
#: order one, its eigenvectors by an angle of the same order. Measured (20 elements, omega_max
#: 3.9e5 rad/s, sqrt(eps) omega_max = 5.8e-3 1/s): splits of 1e-3 to 4e-3 1/s (a free rotor's
#: rigid translations whirling at Omega, its axial drift at 0, a double root at 0 on a
#: divergence speed) with 1 - |cos| from 6e-15 to 6e-6; physical pairs nearest to them, a
#: free Euler-Bernoulli rotor's tilts at i Omega +- 2.05 and +- 3.77 1/s, lie 35 times the
#: threshold away.
RESOLUTION = 10.0
DEFECTIVE = 1e-3
#: Eigenvalues computed beyond 2 x count, so real (overdamped, divergent) ones do not crowd
#: out oscillating modes.
EXTRA = 12


@dataclass(frozen=True)
class CampbellResult:
    """Rotating-frame frequencies [Hz] per speed (rows) and the largest real part [1/s]."""

    speeds_hz: np.ndarray
    frequencies_hz: np.ndarray  # (speeds, count); nan where fewer modes exist
    growth_per_s: np.ndarray  # (speeds,): max Re(lambda) over the reported and real roots (growth_rate)
    whirl: np.ndarray | None = None  # inertial frame: (speeds, count) +1 forward, -1 backward, 0 planar
    branches: Branches | None = None  # the roots followed in speed (one mode per branch)
    log_decrements: np.ndarray | None = None  # (speeds, count) -2 pi Re / Im of each frequency's root; nan as it
    resolution_per_s: float = 0.0  # real parts below this are round-off (sqrt(eps) omega_max, :func:`growth_rate`)


def state_eigenvalues(system: LinearSystem, count: int, vectors: bool = False):
    """Eigenvalues (complex, rad/s) of the first-order form nearest zero, enough for ``count``
    oscillating modes (real, overdamped or divergent ones come along), sorted by modulus; with
    ``vectors``, also the displacement parts of their eigenvectors (n x k)."""
    n = system.n
    k = min(2 * count + EXTRA, 2 * n - 2)
    M, Q = system.M, system.Q
    C = system.C if system.C is not None else sp.csr_matrix((n, n))
    if n <= DENSE_LIMIT or k >= n:
        return _dense_state(M, C, Q, vectors)
    A = sp.bmat([[None, sp.identity(n)], [-Q, -C]], format="csr")
    B = sp.block_diag([sp.identity(n), M], format="csr")
    scale = _omega_max(M, Q)
    # a small negative shift keeps A - sigma B regular at divergence boundaries, where Q is
    # singular; a factor with a pivot at round-off means sigma hit an eigenvalue: next shift
    for sigma in (-1e-6 * scale, -1.3e-5 * scale, 1.7e-5 * scale):
        # (A - sigma B) x = b:  x2 = b1 + sigma x1,  -(Q + sigma C + sigma^2 M) x1 = b2 + (C + sigma M) b1
        try:
            lu = spla.splu(sp.csc_matrix(Q + sigma * C + sigma**2 * M))
        except RuntimeError:
            continue
        piv = np.abs(lu.U.diagonal())
        if piv.min() <= 1e-13 * piv.max():
            continue
        CsM = C + sigma * M
        held = [lu]  # ARPACK's parameter object keeps a reference cycle to this closure:
        # clearing the list frees the factor now instead of at the next cyclic collection

        def solve(b, held=held, CsM=CsM, sigma=sigma):
            b1, b2 = b[:n], b[n:]
            x1 = -held[0].solve(b2 + CsM @ b1)
            return np.concatenate([x1, b1 + sigma * x1])

        op = spla.LinearOperator((2 * n, 2 * n), matvec=solve, dtype=float)
        v0 = np.random.default_rng(0).standard_normal(2 * n)
        try:
            # heavy damping clusters overdamped roots near -1/beta, which stalls Arnoldi: give
            # up early and solve densely instead
            lam, V = spla.eigs(A, k=k, M=B, sigma=sigma, OPinv=op, which="LM", v0=v0, maxiter=300)
            lam = merge_defective(lam, V, scale)
        except spla.ArpackNoConvergence:
            break
        finally:
            held.clear()
            del lu
        order = np.argsort(np.abs(lam))
        return (lam[order], V[:n, order]) if vectors else lam[order]
    if n <= DENSE_FALLBACK:
        return _dense_state(M, C, Q, vectors)
    raise NsfemError(f"the rotating-frame eigenproblem of {n} dofs did not converge; reduce the model "
                     "([reduction] method = craig-bampton)")


def _omega_max(M, Q) -> float:
    """The fastest frequency [rad/s] as the largest diagonal ratio sqrt(Q_ii / M_ii) (an
    estimate within a small factor for FE matrices, the scale of round-off in the roots)."""
    d = np.abs(np.asarray(Q.diagonal(), dtype=float)) / np.asarray(M.diagonal(), dtype=float)
    return math.sqrt(float(np.max(d, initial=0.0)))


def _dense_state(M, C, Q, vectors: bool = False):
    """All eigenvalues of the first-order form, from the standard form with M^-1 (M is pd)."""
    n = M.shape[0]
    cho = sla.cho_factor(M.toarray())
    A = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-sla.cho_solve(cho, Q.toarray()), -sla.cho_solve(cho, C.toarray())]])
    lam, V = sla.eig(A)
    lam = merge_defective(lam, V, _omega_max(M, Q))
    order = np.argsort(np.abs(lam))
    return (lam[order], V[:n, order]) if vectors else lam[order]


def merge_defective(lam: np.ndarray, V: np.ndarray, omega_max: float) -> np.ndarray:
    """Eigenvalues with each round-off split of a defective root replaced by its mean.

    A defective root (a Jordan block: the rigid translations of a free rotor whirl at
    exactly Omega in the rotating frame with a uniform drift; a double root at 0 on a
    divergence speed) is ill-conditioned: any eigen solver returns it split by about
    sqrt(eps |A|) (measured 2e-6 relative, +-1.4e-3 1/s of spurious growth), by an amount
    that depends on the BLAS's order of summation. The mean of the split roots is the trace of
    the block over its size, which is well-conditioned (Kato), so it is the same on every
    machine to round-off. Split roots are recognized by their distance (below the resolution
    RESOLUTION sqrt(eps) ``omega_max``) and their nearly parallel eigenvectors (:data:`DEFECTIVE`);
    ``V`` holds one eigenvector per column.
    """
    lam = np.array(lam, dtype=complex)
    m = lam.size
    if m < 2:
        return lam
    U = V / np.maximum(np.linalg.norm(V, axis=0), 1e-300)
    tol = RESOLUTION * math.sqrt(np.finfo(float).eps) * omega_max
    order = np.argsort(lam.imag)
    parent = np.arange(m)

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a in range(m):
        i = order[a]
        for b in range(a + 1, m):
            j = order[b]
            if lam[j].imag - lam[i].imag > tol:
                break
            if abs(lam[j] - lam[i]) > tol or lam[i].imag * lam[j].imag < 0:  # (a conjugate is another root)
                continue
            if 1.0 - abs(np.vdot(U[:, i], U[:, j])) < DEFECTIVE:
                parent[root(j)] = root(i)
    roots = np.array([root(i) for i in range(m)])
    for r in np.unique(roots):
        group = roots == r
        if np.count_nonzero(group) > 1:
            lam[group] = lam[group].mean()
    return lam


def frequencies_of(lam: np.ndarray, count: int) -> np.ndarray:
    """Natural frequencies [Hz]: one per complex-conjugate pair, ascending by frequency.

    Real eigenvalues (overdamped or divergent motion) have no frequency and are left to the
    growth rate; so are roots within 1e-5 of the ``count``-th oscillating root's modulus of
    zero, where a double root at a divergence speed splits at round-off into a real or a
    complex pair. Missing entries are nan.
    """
    f = lam[_oscillating(lam, count)].imag / (2 * math.pi)
    out = np.full(count, np.nan)
    out[: f.size] = f
    return out


def log_decrements_of(lam: np.ndarray, count: int, resolution: float = 0.0) -> np.ndarray:
    """Logarithmic decrements -2 pi Re(lambda) / Im(lambda) of the roots :func:`frequencies_of` reports, aligned
    with its frequencies (negative: the mode grows); nan where it has none. A real part within ``resolution`` (the
    roots' round-off, sqrt(eps) omega_max: :func:`growth_rate`) is 0, as in :func:`.damped.damped_modes`."""
    pick = lam[_oscillating(lam, count)]
    re = np.where(np.abs(pick.real) <= resolution, 0.0, pick.real)
    out = np.full(count, np.nan)
    out[: pick.size] = -2 * math.pi * re / pick.imag + 0.0  # (no -0.0)
    return out


def campbell(ops: RotorOperators, speeds_hz, count: int = 6, rayleigh=(0.0, 0.0), external: float = 0.0,
             frame: str = "rotating", turn: sp.spmatrix | None = None) -> CampbellResult:
    """Natural frequencies at each speed (damping as given, no gravity needed): in the rotating frame,
    those a frame turning with the shaft sees; in the inertial frame, whirl frequencies, each marked
    forward or backward by :func:`.whirl.whirl_sense` (``turn``: the quarter turn J in full coordinates,
    :func:`nsfem.fem.components.lateral_turn`; ops.basis maps to them). The roots are also followed in
    speed as branches (:mod:`.branches`), :data:`TRACKED` x ``count`` of them per speed, so that a branch
    leaving the lowest ``count`` is not cut short (on a grid refined where the shapes change fast,
    :func:`.branches.refine`)."""
    from .branches import track

    speeds = np.asarray(speeds_hz, dtype=float)
    F = np.full((len(speeds), count), np.nan)
    W = np.zeros((len(speeds), count)) if frame == "inertial" else None
    growth = np.zeros(len(speeds))
    D = np.full((len(speeds), count), np.nan)
    resolution = 0.0
    roots = []
    for i, s in enumerate(speeds):
        system = linear_system(ops, s, 0.0, 0.0, rayleigh, external, frame)
        lam, X = state_eigenvalues(system, TRACKED * count, vectors=True)
        pick = _oscillating(lam, count)
        if W is not None and turn is not None and len(pick):
            W[i, : len(pick)] = _whirl(X[:, pick], ops, turn, s)
        roots.append(_tracked_roots(lam, X, TRACKED * count, ops, turn, s))
        F[i] = frequencies_of(lam, count)
        omega_max = _omega_max(system.M, system.Q)
        resolution = max(resolution, math.sqrt(np.finfo(float).eps) * omega_max)
        D[i] = log_decrements_of(lam, count, math.sqrt(np.finfo(float).eps) * omega_max)
        growth[i] = growth_rate(lam, count, omega_max)
    follow = root_function(ops, count, rayleigh, external, frame, turn)
    return CampbellResult(speeds, F, growth, W, track(speeds, roots, ops.M, follow), D, resolution)


#: campbell follows this many times ``count`` roots per speed as branches
TRACKED = 2


def _whirl(X: np.ndarray, ops: RotorOperators, turn, speed_hz: float) -> np.ndarray:
    """Whirl codes of eigenvector columns X (:func:`.whirl.whirl_sense`); at rest no mode whirls (an
    isotropic pair's eigenvectors are any combination): 0 there, but for axial modes."""
    from .whirl import AXIAL, whirl_sense

    sense = whirl_sense(X, ops.basis, turn)
    return sense if speed_hz > 0 else np.where(sense == AXIAL, AXIAL, 0)


def _tracked_roots(lam, X, m: int, ops: RotorOperators, turn, speed_hz: float):
    """(eigenvalues, vectors, whirl codes) of the lowest ``m`` oscillating roots (input of :func:`.branches.track`)."""
    pick = _oscillating(lam, m)
    W = _whirl(X[:, pick], ops, turn, speed_hz) if turn is not None and len(pick) else np.zeros(len(pick), dtype=int)
    return lam[pick], X[:, pick], W


def root_function(ops: RotorOperators, count: int, rayleigh=(0.0, 0.0), external: float = 0.0,
                  frame: str = "rotating", turn: sp.spmatrix | None = None):
    """speed [Hz] -> the roots :func:`campbell` tracks there (for :func:`.branches.crossings`)."""
    def roots(speed_hz: float):
        system = linear_system(ops, speed_hz, 0.0, 0.0, rayleigh, external, frame)
        lam, X = state_eigenvalues(system, TRACKED * count, vectors=True)
        return _tracked_roots(lam, X, TRACKED * count, ops, turn, speed_hz)
    return roots


def shown_branches(res: CampbellResult) -> np.ndarray:
    """Indices of the diagram's branches: those among the lowest ``count`` frequencies at some speed,
    and those that cross the 1x line within the speeds (a critical speed; the branches are followed
    among the lowest :data:`TRACKED` x ``count`` roots)."""
    B = res.branches
    F = B.frequencies_hz[:, B.reported]
    known = np.isfinite(res.frequencies_hz)
    # the count-th frequency per speed (every root is among the lowest count when fewer exist)
    ceiling = np.where(known.all(axis=1), np.where(known, res.frequencies_hz, -np.inf).max(axis=1, initial=-np.inf),
                       np.inf)
    inside = np.isfinite(F) & (F <= ceiling[None, :] * (1 + 1e-12))
    g = B.frequencies_hz - B.speeds_hz[None, :]
    crosses = np.any(np.isfinite(g[:, :-1]) & np.isfinite(g[:, 1:]) & (g[:, :-1] * g[:, 1:] <= 0.0)
                     & (B.speeds_hz[None, 1:] > 0), axis=1)
    return np.flatnonzero(inside.any(axis=1) | crosses)


def branches_json(res: CampbellResult, whirl_names: dict | None = None) -> list[dict]:
    """The diagram's branches (:func:`shown_branches`) for the JSON: damped frequency [Hz], damping ratio
    and logarithmic decrement per speed (null where the branch does not exist), and with ``whirl_names`` (inertial frame) the
    branch's whirl label."""
    B = res.branches
    out = []
    for b in shown_branches(res):
        f, z = B.frequencies_hz[b, B.reported], B.damping_ratios[b, B.reported]
        row = {"whirl": whirl_names[int(B.label[b])]} if whirl_names else {}
        row["frequencies_hz"] = [float(x) if np.isfinite(x) else None for x in f]
        row["damping_ratio"] = [float(x) if np.isfinite(x) else None for x in z]
        # 2 pi zeta / sqrt(1 - zeta^2) (:func:`.damped.log_decrement`); a branch root has zeta < 1 (it oscillates)
        row["log_decrement"] = [float(2 * math.pi * x / math.sqrt(1 - x * x)) if np.isfinite(x) and abs(x) < 1 else None
                                for x in z]
        out.append(row)
    return out


def _oscillating(lam: np.ndarray, count: int) -> np.ndarray:
    """Indices of the roots :func:`frequencies_of` reports (at most ``count``), by ascending frequency."""
    idx = np.flatnonzero(lam.imag > 1e-9 * np.maximum(np.abs(lam), 1.0))
    if len(idx):
        ref = np.sort(np.abs(lam[idx]))[min(count, len(idx)) - 1]
        idx = idx[np.abs(lam[idx]) > 1e-5 * ref]
    return idx[np.argsort(lam[idx].imag, kind="stable")][:count]


def growth_rate(lam: np.ndarray, count: int, omega_max: float) -> float:
    """Largest real part [1/s] of the real roots and of the first ``count`` oscillating ones,
    0 when below the round-off resolution sqrt(eps) ``omega_max`` of a root.

    The extra roots beyond ``count`` that Arnoldi computes sit at the edge of its window and
    carry errors of 1e-3 1/s in their real parts (measured at 2748 rad/s), and no root is
    resolved better than sqrt(eps) omega_max where it is, or is near, a defective one
    (:func:`merge_defective`): a smaller growth cannot be told from round-off.
    """
    if not len(lam):
        return 0.0
    osc = lam.imag > 1e-9 * np.maximum(np.abs(lam), 1.0)
    ref = np.sort(np.abs(lam[osc]))[min(count, int(np.count_nonzero(osc))) - 1] if np.any(osc) else np.inf
    seen = lam[~osc | (np.abs(lam) <= ref * (1 + 1e-9))]
    g = float(seen.real.max())
    return g if abs(g) > math.sqrt(np.finfo(float).eps) * omega_max else 0.0


def gravity_resonances(ops: RotorOperators, phase_deg: float = 0.0, max_hz: float | None = None
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Speeds [Hz] where the undamped gravity response is unbounded, and their excitation.

    Returns (speeds, excitation) with the energy-normalized excitation in (EXCITATION, 1];
    roots gravity cannot excite are dropped. A free structure (rigid motions) has none: it
    falls rigidly, undeformed by a uniform gravity field.
    """
    K0 = _dense(ops.K0)
    H = _dense(ops.M) - _dense(ops.Kc1) - 1j * _dense(ops.G1)
    F = np.exp(1j * math.radians(phase_deg)) * (1j * ops.Fy - ops.Fz)
    nu, X, free = _pencil(H, K0)  # H x = nu K0 x, nu = 1 / Omega^2
    if free:
        # a free structure falls rigidly: in the falling frame no load remains, so gravity
        # deforms it at no speed (and the pencil's roots would be spurious)
        return np.zeros(0), np.zeros(0)
    speeds = 1.0 / np.sqrt(nu) / (2 * math.pi)
    order = np.argsort(speeds)
    speeds, X = speeds[order], X[:, order]
    # group (near-)repeated roots and measure the excitation of their eigenspace
    # excitation |x^H F| / sqrt((x^H K0 x) (F^H K0^-1 F)), maximized over a root's eigenspace:
    # in the K0 energy norm (K0 = L L^H) it is |Q^H G| / |G| with Q an orthonormal basis of
    # L^H X and G = L^-1 F. Energy norms make it the same in full and reduced coordinates: the
    # work of the load on the mode against the mode's strain energy and the load's compliance.
    L = np.linalg.cholesky(K0)
    Y = L.conj().T @ X
    G = sla.solve_triangular(L, F, lower=True)
    g = max(np.linalg.norm(G), 1e-300)
    out_s, out_e = [], []
    i = 0
    while i < len(speeds):
        j = i + 1
        while j < len(speeds) and speeds[j] - speeds[i] <= 1e-9 * speeds[i]:
            j += 1
        Qy, _ = np.linalg.qr(Y[:, i:j])
        e = float(np.linalg.norm(Qy.conj().T @ G) / g)
        if e > EXCITATION:
            out_s.append(speeds[i])
            out_e.append(e)
        i = j
    s, e = np.array(out_s), np.array(out_e)
    if max_hz is not None:
        s, e = s[s <= max_hz], e[s <= max_hz]
    return s, e


def divergence_speeds(ops: RotorOperators, count: int | None = None) -> np.ndarray:
    """Speeds [Hz] where K0 + Omega^2 Kc1 becomes singular (all, or the lowest ``count``)."""
    nu, _, _ = _pencil(-_dense(ops.Kc1), _dense(ops.K0))  # -Kc1 x = nu K0 x, nu = 1 / Omega^2
    return np.sort(1.0 / np.sqrt(nu) / (2 * math.pi))[:count]


def _pencil(H: np.ndarray, K0: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """Positive eigenvalues nu of H x = nu K0 x (H Hermitian, K0 psd) and their vectors.

    With K0 positive definite this is a Hermitian-definite problem. A free structure (rigid
    motions in K0's null space, nu infinite there) goes to the general QZ solver instead.
    """
    # 1/nu must lie above round-off of the largest eigenvalue, max(K0_ii / |H_ii|) roughly:
    # rigid motions (nu = inf) otherwise show up as huge finite nu
    d = np.abs(np.diag(H))
    ok = d > 1e-12 * d.max(initial=0.0)  # reduced coordinates can hold round-off-sized entries
    lam_max = float(np.max(np.diag(K0).real[ok] / d[ok], initial=1.0))
    big = 1e12 / lam_max
    try:
        nu, X = sla.eigh(H, K0)
        rigid = np.abs(nu).max(initial=0.0) >= big  # Cholesky of a singular K0 can succeed
    except np.linalg.LinAlgError:
        rigid = True
    if rigid:
        w, X = sla.eig(H, K0)
        real = np.isfinite(w) & (np.abs(w.imag) <= 1e-8 * np.abs(w[np.isfinite(w)]).max(initial=1e-300))
        nu, X = w[real].real, X[:, real]
    nu_max = np.abs(nu[np.abs(nu) < big]).max(initial=0.0)
    # nu at round-off of the largest finite one: H x = 0 directions (infinite speed)
    keep = (nu > 1e-12 * nu_max) & (nu < big)
    return nu[keep], X[:, keep], bool(rigid)


def divergence_bands(speeds_hz: np.ndarray) -> list[tuple[float, float]]:
    """Intervals with an odd number of negative eigenvalues of K0 + Omega^2 Kc1."""
    s = list(speeds_hz)
    bands = [(s[k], s[k + 1]) for k in range(0, len(s) - 1, 2)]
    if len(s) % 2:
        bands.append((s[-1], math.inf))
    return bands


def default_speeds(ops_open: RotorOperators, scene_speed_hz: float = 0.0, n: int = 61) -> np.ndarray:
    """0 to 1.23 times the second divergence speed (both first critical speeds), or 2x the scene's.

    (1.23, not 1.2: with 61 points 1.2 puts a grid point exactly on the divergence speed.)
    """
    d = divergence_speeds(ops_open, 2)
    stop = 1.23 * (d[-1] if len(d) else 0.0)
    stop = max(stop, 2.0 * scene_speed_hz, 1.0)
    return np.linspace(0.0, stop, n)


#: Models up to this many dofs have their Rayleigh damping checked by a dense eigen solve
DAMPING_CHECK_MAX_DOF = 2000


def standstill_frequencies(ops: RotorOperators) -> np.ndarray:
    """Circular frequencies [rad/s] of the undamped structure at rest, sqrt|eig(K0, M)| (dense)."""
    lam = sla.eigh(_dense(ops.K0), _dense(ops.M), eigvals_only=True)
    return np.sqrt(np.abs(lam))


def parse_speeds(text: str) -> np.ndarray:
    """``START:STOP:N`` -> N speeds [Hz]."""
    try:
        a, b, n = text.split(":")
        a, b, n = float(a), float(b), int(n)
    except ValueError:
        raise NsfemError(f"--speeds must look like START:STOP:N (e.g. 0:60:61), got {text!r}") from None
    if not (math.isfinite(a) and math.isfinite(b)) or a < 0 or b < a or n < 1 or n > 100_000:
        raise NsfemError(f"--speeds {text!r}: need 0 <= START <= STOP and 1 <= N <= 100000")
    return np.linspace(a, b, n)


def campbell_report(scene: Scene, model, speeds_hz=None, count: int = 6, reduction=None) -> dict:
    """Everything ``nsfem campbell`` prints: frequencies open/closed, resonances, divergence (of the
    scene's ``[rotation]`` and ``[damping]``).

    ``reduction`` (:func:`nsfem.reduce.reduce`) works on the reduced model; operators are
    reduced once and reused for every speed.
    """
    from ..fem.rotating import rotor_operators
    from ..scene import check_frame_at_speed
    from .modes import contact_basis

    rot, damp = scene.rotation, scene.damping
    check_frame_at_speed(rot.frame, model.stack)     # the diagram spins a scene given at rest too
    if model.stack.speed_dependent:
        speeds_hz = table_speeds(model.stack) if speeds_hz is None else speeds_hz
        model.stack.check_speeds(speeds_hz)
    ops = {c: rotor_operators(model, contact_basis(model, c, reduction)) for c in ("open", "closed")}
    if not model.stack.contacts:
        ops["closed"] = ops["open"]
    if ops["open"].n <= DAMPING_CHECK_MAX_DOF:  # as nsfem run: damping double precision cannot hold
        check_damping(damp.rayleigh, standstill_frequencies(ops["open"]), damp.external,
                      min(seg.rho * seg.area for seg in model.stack.segments))
    if rot.frame == "inertial":
        from .whirl import inertial_report

        rep = with_log_decrements(inertial_report(model, ops, rot, damp, speeds_hz, count, reduction))
        return table_warning(rep, model.stack, rot, "undamped_critical_speeds_hz")
    # (a run-up's diagram spans its ramp too)
    top = getattr(rot, "max_speed_hz", rot.speed_hz)
    speeds = default_speeds(ops["open"], top) if speeds_hz is None else np.asarray(speeds_hz)
    res = {c: campbell(o, speeds, count, damp.rayleigh, damp.external) for c, o in ops.items()}
    grav = {c: gravity_resonances(o, rot.phase_deg) for c, o in ops.items()}
    div = {c: divergence_speeds(o) for c, o in ops.items()}  # all: bands need every root
    # a reduced model is trusted up to half its highest kept mode: drop what lies beyond
    top = None if reduction is None else reduction.info.get("max_frequency_hz")
    valid = VALID_FRACTION * top if top else math.inf
    grav = {c: (g[0][g[0] <= valid], g[1][g[0] <= valid]) for c, g in grav.items()}
    div = {c: d[d <= valid] for c, d in div.items()}

    def clean(a):
        return [None if not np.isfinite(x) else float(x) for x in np.ravel(a)]

    out = {
        "frame": "rotating",
        "speeds_hz": clean(speeds),
        "frequencies_hz": [clean(row) for row in res["open"].frequencies_hz],
        "frequencies_closed_hz": [clean(row) for row in res["closed"].frequencies_hz],
        "growth_rate_per_s": {c: clean(r.growth_per_s) for c, r in res.items()},
        "branches": {c: branches_json(r) for c, r in res.items()},
        "gravity_resonances_hz": {c: clean(g[0][:count]) for c, g in grav.items()},
        "gravity_excitation": {c: clean(g[1][:count]) for c, g in grav.items()},
        "instability_hz": {c: clean(d[:count]) for c, d in div.items()},
        "instability_bands_hz": {c: [[float(a), float(b) if math.isfinite(b) else None]
                                     for a, b in divergence_bands(d) if len(d) and a <= d[:count][-1]]
                                 for c, d in div.items()},
        "ndof_full": model.n, "ndof": model.n if reduction is None else reduction.ndof,
        "valid_up_to_hz": None if math.isinf(valid) else valid,
        "warnings": [],
        "_results": res, "_bands": divergence_bands(div["open"]), "_critical": {c: [] for c in res},
    }
    return table_warning(with_log_decrements(out), model.stack, rot, "gravity_resonances_hz and instability_hz")


def crossing_log_decrement(crossing, resolution: float = 0.0) -> float:
    """The log decrement of a damped critical speed (:class:`.branches.Crossing`): -2 pi Re / Im of its root, 0 for a
    real part within ``resolution`` (round-off)."""
    lam = crossing.eigenvalue
    return float(-2 * math.pi * (0.0 if abs(lam.real) <= resolution else lam.real) / lam.imag) + 0.0


def with_log_decrements(report: dict) -> dict:
    """``report`` (:func:`campbell_report`, its "_results" and "_critical" still in it) with ``log_decrements`` and
    ``log_decrements_closed`` aligned with ``frequencies_hz`` and ``frequencies_closed_hz`` (speeds x count,
    -2 pi Re(lambda) / Im(lambda) of each frequency's root, null where the frequency is), and each damped critical
    speed's ``log_decrement`` (of the crossing root)."""
    def clean(row):
        return [float(x) if np.isfinite(x) else None for x in row]

    for key, c in (("log_decrements", "open"), ("log_decrements_closed", "closed")):
        report[key] = [clean(row) for row in report["_results"][c].log_decrements]
    for c, found in report.get("critical_speeds", {}).items():
        res = report["_results"][c].resolution_per_s
        for entry, x in zip(found, report["_critical"][c]):
            entry["log_decrement"] = crossing_log_decrement(x, res)
    return report


def table_speeds(stack, n: int = 61) -> np.ndarray:
    """The default speeds of a diagram with speed-dependent bearings: ``n`` over the span every table covers."""
    lo = max(b.table[0][0] for b in stack.bearings if b.table)
    hi = min(b.table[0][-1] for b in stack.bearings if b.table)
    return np.linspace(lo, hi, n) if hi > lo else np.array([lo])


def table_warning(report: dict, stack, rot, keys: str) -> dict:
    """``report`` with a warning that ``keys`` (solved for the speed, not followed in it) hold the bearings'
    coefficients at the scene's speed, when the bearings have speed tables."""
    if stack.speed_dependent:
        report["warnings"].append(f"{keys} take the speed-dependent bearings' coefficients at rotation.speed_hz = "
                                  f"{rot.speed_hz:g} Hz (they are solved for the speed, not followed in it); the "
                                  "frequencies and branches read the tables at each speed")
    return report


def supercritical_warning(speed_hz: float, divergence_hz) -> str | None:
    """A warning when ``speed_hz`` lies beyond the first divergence speed, else None."""
    d = np.asarray(divergence_hz, dtype=float)
    if len(d) == 0 or speed_hz <= d[0]:
        return None
    inside = [(a, b) for a, b in divergence_bands(d) if a < speed_hz < b]
    where = (f"inside the divergence band {inside[0][0]:.3f}-{inside[0][1]:.3f} Hz, where the static response "
             "diverges" if inside else "past a divergence band, where only gyroscopic coupling can keep it stable")
    return f"rotation.speed_hz = {speed_hz:g} Hz is supercritical (first divergence speed {d[0]:.3f} Hz), {where}"
