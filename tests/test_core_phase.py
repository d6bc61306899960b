"""The compiled phase set-up and closed-form energy (core part "phase", issue 33) against their
Python references: configuration.Phase (set-up: q_p, the constant load, x0, the modal coefficients and
the motion's U) and event_driven._exp_integrals / EventDriven._energy_modal / _end_energy.

Tolerances. The kernels form every elementwise operation (complex products, Smith's quotient, exp,
expm1) as numpy writes it, but numpy may fuse a complex product's multiply-add (its SIMD loops on FMA
CPUs), so an entry may differ in its last bits: 8 eps of the operands' size. The matrix-vector products
are plain loops where numpy calls BLAS, whose summation order and fused multiply-adds depend on the CPU:
both obey the dot product's forward error bound |fl(a.x) - a.x| <= n eps |a|.|x|, so they differ by at
most twice that, propagated through the few steps after it as the test's ``bound`` says (componentwise,
on absolute values: a bound, not an estimate).

Skipped where the compiled core is not installed (no C compiler at install time) or NSFEM_PURE_PYTHON=1.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nsfem import load_scene
from nsfem.integrate import core
from nsfem.integrate.closed_form import divided_exp
from nsfem.integrate.configuration import Configuration, Mode, Phase
from nsfem.integrate.event_driven import _exp_integrals

from test_event_search import KINDS, _phase

kernel = core.compiled("phase")
pytestmark = pytest.mark.skipif(kernel is None, reason="the compiled core part 'phase' is not active (not built, "
                                                       "or NSFEM_PURE_PYTHON=1): the reference runs")
EPS = np.finfo(float).eps


def _cv(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=complex).view(float)


def _both(config: Configuration, t0: float, q0: np.ndarray, v0: np.ndarray, g0: np.ndarray) -> tuple[Phase, Phase]:
    with core.reference():
        ref = Phase(config, t0, q0, v0, g0)
    return ref, Phase(config, t0, q0, v0, g0)


def _check_phase(ref: Phase, got: Phase, q0: np.ndarray, v0: np.ndarray) -> None:
    """The compiled phase against the reference, within the products' forward error bounds."""
    cfg = ref.config
    n, r = cfg.system.n, cfg.r
    g0 = np.abs(ref.g0)
    b_qp = 2 * max(g0.size, 1) * EPS * (np.abs(cfg.Gpinv) @ g0)
    assert np.all(np.abs(got.qp - ref.qp) <= b_qp)
    # f0 = f0_config - Q q_p: the product's bound plus the difference carried from q_p
    b_f0 = 2 * n * EPS * (np.abs(cfg.Q) @ np.abs(ref.qp)) + np.abs(cfg.Q) @ b_qp + EPS * np.abs(ref.forcing[0])
    assert np.all(np.abs(got.forcing[0] - ref.forcing[0]) <= b_f0)
    NT = np.abs(cfg.N.T)
    b_x0 = np.concatenate([2 * n * EPS * (NT @ (np.abs(q0) + np.abs(ref.qp))) + NT @ b_qp,
                           2 * n * EPS * (NT @ np.abs(v0))])
    assert np.all(np.abs(got.x0 - ref.x0) <= b_x0)
    b_Bf0 = 2 * n * EPS * (np.abs(cfg.B) @ np.abs(ref.forcing[0])) + np.abs(cfg.B) @ b_f0
    assert np.all(np.abs(got.A_aug[: 2 * r, 2 * r] - ref.A_aug[: 2 * r, 2 * r]) <= b_Bf0)
    assert np.array_equal(np.delete(got.A_aug, 2 * r, axis=1), np.delete(ref.A_aug, 2 * r, axis=1))
    assert (got._modal is None) == (ref._modal is None) and (got.amplitudes is None) == (ref.amplitudes is None)
    if ref._modal is None:
        return
    k, plan = cfg.k, cfg.plan
    Vi, V = np.abs(cfg.eig[2]), np.abs(plan.V)
    m, nmu = Vi.shape[0], len(plan.mus)
    # the modal coefficients: products of Vi (|Vi| |x| n eps each, 4 eps more for the complex products of
    # the harmonic load's phase), their inputs' differences through |Vi|
    xin = [np.abs(ref.A_aug[k: 2 * r, 2 * r])]
    bin_ = [b_Bf0[k:]]
    if nmu > 1:
        hb = np.abs(cfg.harmonic_b)
        xin += [hb, hb]
        bin_ += [4 * EPS * hb, 4 * EPS * hb]
    b_beta = np.array([4 * m * EPS * (Vi @ x) + Vi @ b for x, b in zip(xin, bin_)])
    b_z0 = 2 * m * EPS * (Vi @ np.abs(ref.x0[k:])) + Vi @ b_x0[k:]
    beta = np.abs(np.array([Vi @ x for x in xin]))
    den = np.abs(plan.den)
    # g = beta / den (4 eps for the quotient, the absolute quotient's bound), c = z0 - sum g
    b_g = (b_beta + 8 * EPS * beta) / den
    b_c = b_z0 + b_g.sum(axis=0) + (nmu + 1) * EPS * (np.abs(Vi) @ np.abs(ref.x0[k:]) + (beta / den).sum(axis=0))
    c_abs = np.abs(ref.amplitudes[0]) if ref.amplitudes is not None else None
    U_ref, U_got = ref._modal.U, got._modal.U
    b_U = np.empty(U_ref.shape)
    b_U[k:, :m] = V * b_c + 4 * EPS * np.abs(U_ref[k:, :m])
    b_U[k:, m:] = (V @ b_g.T) + 4 * m * EPS * (V @ (beta / den).T)
    assert np.all(np.abs(U_got[k:] - U_ref[k:]) <= b_U[k:])
    if c_abs is not None:
        assert np.all(np.abs(got.amplitudes[0] - ref.amplitudes[0]) <= b_c)
        assert np.all(np.abs(got.amplitudes[1] - ref.amplitudes[1]) <= b_g)
    # rigid rows and divided differences are the reference's own code (ModalPlan.complete) on these
    # coefficients: linear in (z0, beta), so they differ by at most that map on absolute values applied to
    # the coefficients' bounds, plus the map's own rounding (a few terms per entry: 16 eps of its
    # absolute value)
    assert len(got._modal.groups) == len(ref._modal.groups)
    if k or ref._modal.groups:
        C_abs = np.vstack([np.abs(cfg.eig[2] @ ref.x0[k:]), beta])
        b_C = np.vstack([b_z0, b_beta])
        (Ub, Dbs), (Ua, Das) = _complete_abs(plan, b_C, np.zeros(k)), _complete_abs(plan, C_abs, np.abs(ref.x0[:k]))
        assert np.all(np.abs(U_got[:k] - U_ref[:k]) <= Ub[:k] + 16 * EPS * Ua[:k])
        for (na, Da), (nb, Db), Db_, Da_ in zip(got._modal.groups, ref._modal.groups, Dbs, Das):
            assert np.array_equal(na, nb) and Da.shape == Db.shape
            assert np.all(np.abs(Da - Db) <= Db_ + 16 * EPS * Da_)


def _complete_abs(plan, C_abs: np.ndarray, a0_abs: np.ndarray):
    """(U, [D per group]) of ModalPlan.complete with every factor and coefficient by its absolute value (a
    bound of the map's values, or of their differences when C_abs bounds the coefficients')."""
    k = plan.k
    pa = copy.copy(plan)
    pa.V, pa.SV = np.abs(plan.V), np.abs(plan.SV)
    if k:
        pa.Fa, pa.Fx = np.abs(plan.Fa), np.abs(plan.Fx)
    pa.groups = [(nodes, None if Fw is None else np.abs(Fw), None if Fr is None else np.abs(Fr), source,
                  np.ones_like(always)) for nodes, Fw, Fr, source, always in plan.groups]
    U = np.zeros((k + plan.V.shape[0], plan.nu.size), dtype=complex)
    mot = pa.complete(U, C_abs[0].astype(complex), C_abs[1:].astype(complex), a0_abs)
    return np.abs(mot.U), [np.abs(D) for _, D in mot.groups]


@pytest.mark.parametrize("kind", KINDS)
def test_phase_setup_matches_the_reference_on_random_phases(kind):
    """Random phases of test_event_search's generator: modal, harmonic, gyroscopic, resonant (divided
    differences), rigid and defective (matrix exponential) configurations."""
    taken = set()
    for seed in range(40):
        rng = np.random.default_rng([33, KINDS.index(kind), seed])
        path = "expm" if rng.random() < 1 / 3 else "modal"
        with core.reference():
            phase, *_, info = _phase(rng, kind, path)
        cfg = phase.config
        q0 = cfg.N @ phase.x0[: cfg.r] + phase.qp
        v0 = cfg.N @ phase.x0[cfg.r:]
        ref, got = _both(cfg, phase.t0, q0, v0, phase.g0)
        _check_phase(ref, got, q0, v0)
        taken.add(info["path_taken"])
    assert "modal" in taken and (kind in ("stiff", "overdamped") or "divided" in taken)   # (modal only)


@pytest.fixture(scope="module")
def rotor():
    """The shipped scene's system with a stop (10 contacts, gyroscopic, an unbalance: harmonic load)."""
    from nsfem.fem.assemble import build_model
    from nsfem.integrate import ContactSystem
    from nsfem.reduce import scene_reduction

    scene = load_scene("default", ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]'])
    model = build_model(scene)
    return ContactSystem.from_model(model, scene_reduction(scene.reduction, model), scene.rotation, scene.damping)


def test_phase_setup_matches_the_reference_with_closed_contacts(rotor):
    """Random contact sets closed on the rotor (constraints: q_p from g0), random states, gaps and times,
    states from 1e-9 to 1e3 (the set-up is linear: scales must not matter), zeros included."""
    rng = np.random.default_rng(33)
    n, m = rotor.n, rotor.contacts.m
    for trial in range(40):
        closed = tuple(sorted(rng.choice(m, size=int(rng.integers(0, 4)), replace=False).tolist()))
        cfg = Configuration(rotor, Mode(closed=closed))
        scale = 10.0 ** rng.uniform(-9, 3)
        q0 = scale * rng.standard_normal(n) * (rng.random(n) < 0.8)
        v0 = scale * rng.standard_normal(n) * (rng.random() < 0.8)
        g0 = scale * rng.standard_normal(len(closed)) * (rng.random(len(closed)) < 0.7)
        t0 = float(rng.choice([0.0, rng.uniform(0, 10)]))
        ref, got = _both(cfg, t0, q0, v0, g0)
        _check_phase(ref, got, q0, v0)


def test_exp_integrals_kernel_matches_the_reference():
    """Random exponent pairs: conjugates (nearly cancelling sums), zeros, equal entries, the series,
    expm1 and quotient branches, scales 1e-6..1e4, horizons 1e-8..10 s, empty arrays."""
    rng = np.random.default_rng(5)
    seen = set()
    for trial in range(1500):
        na, nb = (int(x) for x in rng.integers(0, 7, 2))
        sc = 10.0 ** rng.uniform(-6, 4)
        re = rng.standard_normal(na) * rng.choice([0.0, 1e-12, 1e-3, 1.0], na)
        a = (re + 1j * rng.standard_normal(na) * rng.choice([0.0, 1.0], na, p=[0.2, 0.8])) * sc
        b = np.concatenate([-np.conj(a[: nb // 2]), a[: nb // 4] * 0.0,
                            (rng.standard_normal(nb) - 1j * rng.standard_normal(nb)) * sc])[:nb]
        T = 10.0 ** rng.uniform(-8, 1)
        with np.errstate(all="ignore"):
            ref = _exp_integrals(a, b, T)
            ea, eb = np.abs(np.exp(a * T)), np.abs(np.exp(b * T))
            s = np.abs(np.add.outer(a, b))
            # far (|s| T >= 1/2): the quotient's operands' size over |s|; near: the series' or
            # expm1(x T) / x's operands, e^{|x| T} + 2 <= 4, over |x| < 1 / (2 T)
            near = s * T < 0.5
            bound = 8 * EPS * np.where(near, 4.0 * 2.0 * T, (np.multiply.outer(ea, eb) + 2.0) / np.where(near, 1, s))
        got = np.empty((a.size, b.size), dtype=complex)
        kernel.exp_integrals(_cv(a), _cv(b), T, got.view(float))
        fin = np.isfinite(ref)
        assert np.array_equal(fin, np.isfinite(got))
        assert np.all(np.abs(got[fin] - ref[fin]) <= bound[fin])
        seen |= {("near" if x * T < 0.5 else "far") for x in s.ravel()}
    assert seen == {"near", "far"}


_part = st.one_of(st.just(0.0), st.floats(-1e6, 1e6, allow_nan=False), st.floats(-1e-9, 1e-9, allow_nan=False))
_exponents = st.lists(st.tuples(_part, _part).map(lambda z: complex(*z)), max_size=5)


@settings(max_examples=300, deadline=None, derandomize=True, database=None)
@given(a=_exponents, b=_exponents, T=st.floats(1e-12, 1e2), conjugate=st.booleans())
def test_exp_integrals_kernel_property(a, b, T, conjugate):
    """Any exponents (zeros, tiny and huge parts, equal and, with ``conjugate``, cancelling pairs) and
    horizons: the kernel's entries are finite where the reference's are and within the same bound as
    test_exp_integrals_kernel_matches_the_reference."""
    a = np.array(a, dtype=complex)
    b = np.concatenate([-np.conj(a), np.array(b, dtype=complex)]) if conjugate else np.array(b, dtype=complex)
    with np.errstate(all="ignore"):
        ref = _exp_integrals(a, b, T)
        s = np.abs(np.add.outer(a, b))
        near = s * T < 0.5
        big = np.multiply.outer(np.abs(np.exp(a * T)), np.abs(np.exp(b * T)))
        bound = 8 * EPS * np.where(near, 8.0 * T, (big + 2.0) / np.where(near, 1, s))
    got = np.empty((a.size, b.size), dtype=complex)
    kernel.exp_integrals(_cv(a), _cv(b), T, got.view(float))
    fin = np.isfinite(ref)
    assert np.array_equal(fin, np.isfinite(got))
    assert np.all(np.abs(got[fin] - ref[fin]) <= bound[fin])


def _random_modal(rng, m: int, nmu: int, nf: int):
    lam = (-np.abs(rng.standard_normal(m // 2)) * rng.choice([0.0, 1e-3, 1.0], m // 2)
           + 1j * np.abs(rng.standard_normal(m // 2))) * 10.0 ** rng.uniform(0, 3)
    lam = np.concatenate([lam, np.conj(lam)])
    w = abs(rng.standard_normal()) * 100.0
    mus = np.array([0j, -1j * w, 1j * w][:nmu])
    nu = np.concatenate([lam, mus])
    c = rng.standard_normal(m) + 1j * rng.standard_normal(m)
    g = (rng.standard_normal((nmu, m)) + 1j * rng.standard_normal((nmu, m))) * (rng.random((nmu, m)) < 0.9)
    E = rng.standard_normal((nmu, m)) + 1j * rng.standard_normal((nmu, m))
    S = rng.standard_normal((nf, m, m)) + 1j * rng.standard_normal((nf, m, m))
    return nu, c, g, E, S, mus


def _energy_reference(nu, c, g, E, S, mus, T, t0):
    """EventDriven._energy_modal's arithmetic (its lines, on arrays), and its absolute-value bound."""
    m, nf = c.size, S.shape[0]
    with np.errstate(all="ignore"):
        Phi = _exp_integrals(nu if nf else mus, nu, T)
    A = np.abs
    if nf:
        ZP = c[:, None] * Phi[:m] + g.T @ Phi[m:]
        ZPa = A(c)[:, None] * A(Phi[:m]) + A(g.T) @ A(Phi[m:])
        PZ, PZa = ZP[:, m:].T, ZPa[:, m:].T
    else:
        PZ = Phi[:, :m] * c + Phi[:, m:] @ g
        PZa = A(Phi[:, :m]) * A(c) + A(Phi[:, m:]) @ A(g)
    emu = np.exp(mus * t0)
    work = float(np.einsum("i,ij,ij->", emu, E, PZ).real)
    work_a = float(np.einsum("i,ij,ij->", A(emu), A(E), PZa))
    vals = np.einsum("fjk,jk->f", S, ZP[:, :m] * c + ZP[:, m:] @ g).real if nf else np.zeros(0)
    vals_a = np.einsum("fjk,jk->f", A(S), ZPa[:, :m] * A(c) + ZPa[:, m:] @ A(g)) if nf else np.zeros(0)
    return work, vals, PZ, work_a, vals_a, PZa


@pytest.mark.parametrize("nf", [0, 1, 2])
def test_energy_modal_kernel_matches_the_reference(nf):
    """The work integrals of random modal motions (conjugate pairs, undamped and damped modes, a constant
    and a harmonic load, zero coefficients), horizons 1e-7..1 s. Each value is a sum of up to 4 p^2
    products of entries of Phi, Z and the forms: the two orders of summation differ by at most
    2 (4 p^2) eps times the sum of the absolute values, plus Phi's own 8 eps per entry."""
    rng = np.random.default_rng(7 + nf)
    for trial in range(60):
        m, nmu = 2 * int(rng.integers(0, 8)), int(rng.choice([1, 3]))
        nu, c, g, E, S, mus = _random_modal(rng, m, nmu, nf)
        T, t0 = 10.0 ** rng.uniform(-7, 0), float(rng.uniform(0, 5))
        work, vals, PZ, work_a, vals_a, PZa = _energy_reference(nu, c, g, E, S, mus, T, t0)
        p = nu.size
        tol = 16 * (4 * p * p + 8) * EPS
        got_vals, got_PZ = np.empty(nf), np.empty((nmu, m), dtype=complex)
        got = kernel.energy_modal(_cv(nu), _cv(c), _cv(g), T, t0, _cv(E), _cv(S), got_vals, got_PZ.view(float))
        assert abs(got - work) <= tol * work_a
        assert np.all(np.abs(got_vals - vals) <= tol * vals_a)
        assert np.all(np.abs(got_PZ - PZ) <= tol * PZa)


def test_end_energy_kernel_matches_the_reference():
    """max_t |X_t^T H X_t| of random states and forms (zeros, scales 1e-9..1e3, a non-finite state): the
    double sum of (2n)^2 products differs from BLAS's by at most 2 (2n)^2 eps |X|^T |H| |X|."""
    rng = np.random.default_rng(11)
    for trial in range(200):
        n2 = 2 * int(rng.integers(0, 12))
        H = rng.standard_normal((n2, n2)) * (rng.random((n2, n2)) < 0.5)
        H = 0.5 * (H + H.T)
        X = 10.0 ** rng.uniform(-9, 3) * rng.standard_normal((2, n2)) * (rng.random((2, n2)) < 0.8)
        ref = float(np.abs(np.einsum("ti,ti->t", X @ H, X)).max()) if n2 else 0.0
        bound = 2 * max(n2, 1) ** 2 * EPS * float(np.max(np.einsum("ti,ti->t", np.abs(X) @ np.abs(H), np.abs(X))))
        assert abs(kernel.end_energy(H, X) - ref) <= bound
    X = np.ones((2, 4))
    X[1, 0] = np.nan
    assert np.isnan(kernel.end_energy(np.eye(4), X))


@pytest.mark.parametrize("kind", KINDS)
def test_state_at_one_time_matches_the_reference(kind):
    """Phase._xi_at (the root refinement's evaluation) compiled against the reference on random phases,
    at random times over 40 periods of the fastest mode: the same U (the reference phase's), so each row
    differs only by the order of its sum of 2 p rounded terms and the exponentials' last bits
    (numpy's exp may run its own SIMD loop): 4 (2 p + 4) eps |U| |e^{nu tau}|."""
    for seed in range(30):
        rng = np.random.default_rng([34, KINDS.index(kind), seed])
        path = "expm" if rng.random() < 1 / 3 else "modal"
        with core.reference():
            phase, *_ = _phase(rng, kind, path)
        if phase._modal is None:
            continue
        mot = phase._modal
        fast = float(np.max(np.abs(mot.nu), initial=1.0))
        for t in phase.t0 + rng.uniform(0.0, 40 * 2 * np.pi / fast, 5):
            tau = t - phase.t0
            ref = phase._xi_at(float(t))
            got = np.empty(phase.dim)
            kernel.xi_at(_cv(mot.U), _cv(mot.nu), tau, phase.w, float(t), got)
            d = mot.U.shape[0]
            for nodes, D in mot.groups:     # (the divided differences stay the reference's code)
                got[:d] += (D @ divided_exp(nodes, np.array([tau]))[:, 0]).real
            bound = 4 * (2 * mot.nu.size + 4) * EPS * (np.abs(mot.U) @ np.abs(np.exp(mot.nu * tau)))
            if mot.groups:
                bound = bound + 4 * EPS * np.abs(ref[:d])
            assert np.all(np.abs(got[:d] - ref[:d]) <= bound)
            assert np.array_equal(got[d:], ref[d:])


# -- the work integrals of divided-difference groups (kernel group_integrals) ------------------------------

def _groups(rng, kinds: str) -> list:
    """Divided-difference groups as ModalPlan forms them: clusters of 2 or 3 nodes at 0 (rigid rows) or at a
    forcing exponent +-i w (resonance), equal, 1e-9 or 1e-6 apart (the closeness floor), some columns exactly 0."""
    out = []
    for m in (2, 3):
        K = int(rng.integers(0 if kinds == "mixed" else 1, 4))
        if K == 0:
            continue
        c = 1j * rng.choice([-1, 1]) * 10 ** rng.uniform(-1, 3) if rng.random() < 0.5 else 0j
        spread = rng.choice([0.0, 1e-9, 1e-6]) * max(abs(c), 1.0)
        nodes = c + spread * (rng.normal(size=(m, K)) + 1j * rng.normal(size=(m, K)))
        nodes[:, rng.random(K) < 0.2] = 0.0
        out.append((nodes.astype(complex), None))
    return out


@pytest.mark.parametrize("seed", range(6))
def test_group_integrals_kernel_matches_the_reference(seed):
    """The kernel against closed_form.group_integrals on random groups and exponents (zero, slow, stiff up to
    1e5 1/s, ties), T from 1e-7 to 1 s. Both evaluate the same formulas but choose their Taylor lengths and
    scalings per column where the reference chooses them per batch, and the kernel's complex products
    and sums are C's: each is within a few eps of the entry's natural size (Hermite-Genocchi: T^N / N! for
    the exponential integrals of N + 1 nodes; the pair's T^(m+n-1) / ... for the products), so they agree to
    1e-13 of the largest entry of each block (the sizes of one block differ by at most their nodes' spread)."""
    from nsfem.integrate.closed_form import group_integrals
    from nsfem.integrate.event_driven import _compiled_group_integrals

    rng = np.random.default_rng(seed)
    for _ in range(40):
        groups = _groups(rng, "mixed")
        if not groups:
            continue
        p = int(rng.integers(0, 14))
        nu = -np.abs(rng.normal(size=p)) * 10 ** rng.uniform(-3, 4, p) \
            + 1j * rng.normal(size=p) * 10 ** rng.uniform(-3, 5, p)
        nu[: min(p, 2)] = 0.0
        if p > 3:
            nu[3] = nu[2]          # a tie
        T = 10 ** rng.uniform(-7, 0)
        pairs = bool(rng.random() < 0.7)
        Pe, Pg = group_integrals(nu, groups, T, pairs)
        Qe, Qg = _compiled_group_integrals(kernel, nu, groups, T, pairs)
        assert Qe.shape == Pe.shape and (Qg is None) == (Pg is None)
        if Pe.size:
            assert np.abs(Qe - Pe).max() <= 1e-13 * np.abs(Pe).max()
        if pairs:
            assert np.abs(Qg - Pg).max() <= 1e-13 * np.abs(Pg).max()


def _shorter(a: np.ndarray, axis: int = 0) -> np.ndarray:
    """a without its last entry along ``axis`` (C-contiguous, same dtype)."""
    return np.ascontiguousarray(np.delete(a, -1, axis=axis))


def test_kernels_refuse_arrays_of_the_wrong_shape(monkeypatch):
    """Review of issue 33: the phase kernels read and write without bounds checks, and had no shape checks (and
    no check of their work space's malloc): an output a row short was written past its end, an input a
    column short read past it, a divided difference of 4 or 0 nodes overflowed a stack array. Each such call
    is a ValueError now, before any access; the arguments of real calls (captured from a phase's set-up, and
    built as the energy's callers build them) are accepted."""
    import nsfem.integrate.core._phase as phase_kernels

    captured = {}

    class Setup:
        """PhaseSetup, its construction and its first start recorded (the arrays a phase's set-up passes)."""
        def __init__(self, *args, **kw):
            captured["init"] = (args, kw)
            self._real = phase_kernels.PhaseSetup(*args, **kw)
            self.layout = self._real.layout

        def start(self, *args):
            captured.setdefault("start", args)
            return self._real.start(*args)

        def state(self, *args):
            return self._real.state(*args)

    class Spy:
        def __getattr__(self, name):
            return Setup if name == "PhaseSetup" else getattr(phase_kernels, name)

    monkeypatch.setitem(core._active, "phase", Spy())
    rng = np.random.default_rng([33, 99])
    with core.reference():
        phase, *_ = _phase(rng, "generic", "modal")
    cfg = phase.config
    Phase(cfg, phase.t0, cfg.N @ phase.x0[: cfg.r] + phase.qp, cfg.N @ phase.x0[cfg.r:], phase.g0)
    assert {"init", "start"} <= set(captured)
    # phase_start's and phase_modal's arguments as PhaseSetup.start forms them from its arrays
    GpinvT, QT, f0, BT, N, ViT, harmonic, V, den, k, nmu, p = captured["init"][0]   # (a modal plan's set-up)
    g0, q0, v0, w, t0, _ = captured["start"]
    n, r, m, d = QT.shape[0], N.shape[1], ViT.shape[1] // 2, V.shape[0]
    qp, f0o, Bf0, x0 = np.empty(n), np.empty(n), np.empty(2 * r), np.empty(2 * r)
    phase_kernels.phase_start(GpinvT, g0, QT, f0, BT, N, q0, v0, qp, f0o, Bf0, x0)
    ph = np.exp(1j * w * t0) if w else 0.0
    z0, beta, c = np.empty(2 * m), np.empty((nmu, 2 * m)), np.empty(2 * m)
    g, U = np.empty((nmu, 2 * m)), np.zeros((k + d, 2 * p))
    captured["phase_start"] = (GpinvT, g0, QT, f0, BT, N, q0, v0, qp, f0o, Bf0, x0)
    captured["phase_modal"] = (ViT, Bf0, x0, harmonic, float(np.real(ph)), float(np.imag(ph)), k, V, den, z0, beta,
                               c, g, U)

    def refuses(name, args, spoilt: dict):
        fun = getattr(phase_kernels, name)
        fun(*args)                                     # the real call is accepted
        for j, value in spoilt.items():
            bad = list(args)
            bad[j] = value
            with pytest.raises(ValueError, match=name):   # (its message names the kernel)
                fun(*bad)

    a = captured["phase_start"]   # GpinvT, g0, QT, f0, BT, N, q0, v0, qp, f0, Bf0, x0
    refuses("phase_start", a, {2: _shorter(a[2], 1), 4: _shorter(a[4], 0), 5: _shorter(a[5], 0),
                               6: _shorter(a[6]), 8: _shorter(a[8]), 9: _shorter(a[9]), 10: _shorter(a[10]),
                               11: _shorter(a[11])})
    a = captured["phase_modal"]   # ViT, Bf0, x0, harmonic, re, im, k, V, den, z0, beta, c, g, U
    refuses("phase_modal", a, {1: _shorter(a[1]), 2: _shorter(a[2]), 3: _shorter(a[3], 0), 7: _shorter(a[7], 1),
                               9: _shorter(a[9]), 10: _shorter(a[10], 1), 11: _shorter(a[11]),
                               12: _shorter(a[12], 0), 13: _shorter(a[13], 0)})
    # the energy's kernels, their arrays as event_driven's callers form them
    nu, c, g, E, S, mus = _random_modal(rng, 4, 3, 2)
    vals, PZ = np.empty(2), np.empty((3, 4), dtype=complex)
    args = (_cv(nu), _cv(c), _cv(g), 0.3, 0.1, _cv(E), _cv(S), vals, PZ.view(float))
    refuses("energy_modal", args, {2: _cv(g[:2]), 5: _cv(E[:2]), 6: _cv(S[:, :3]), 7: np.empty(1),
                                   8: _shorter(PZ.view(float))})
    phi = np.empty((3, 4), dtype=complex)
    refuses("exp_integrals", (_cv(nu[:3]), _cv(nu[:4]), 0.2, phi.view(float)),
            {3: _shorter(phi.view(float)), 1: _cv(nu[:5])})   # (phi a column short; b one longer)
    X = rng.standard_normal((2, 4))
    refuses("end_energy", (np.eye(4), X), {0: np.eye(3)})
    mot = phase._modal
    out = np.empty(phase.dim)
    refuses("xi_at", (_cv(mot.U), _cv(mot.nu), 0.1, phase.w, 0.1, out),
            {5: out[: mot.U.shape[0]].copy(), 1: _cv(mot.nu[:-1])})
    cols, sizes = np.zeros((2, 3), dtype=complex), np.array([2, 3], dtype=np.int64)
    Pe, Pg = np.empty((2, 3), dtype=complex), np.empty((2, 2), dtype=complex)
    refuses("group_integrals", (nu[:3].copy(), cols, sizes, 0.5, Pe, Pg),
            {2: np.array([2, 4], dtype=np.int64), 5: np.empty((1, 2), dtype=complex), 4: Pe[:1].copy()})
    with pytest.raises(ValueError):
        phase_kernels.group_integrals(nu[:3].copy(), cols, np.array([0, 2], dtype=np.int64), 0.5, Pe, Pg)
