"""The compiled impact path of transitions.resolve (core part "resolve", issue 33: ``_impact_fast`` with
_resolve.pyx's ``ImpactPath``) against resolve's full path, which is its specification.

The fast path takes an event when it is an impact after which every contact is open (frictionless, or
with Coulomb friction on fixed surfaces); otherwise it must hand the event back before changing anything.
Replayed on random contact systems near contact (gaps at zero, inside and outside their bands;
approaching, resting and separating contacts; restitutions 0..1; Zeno memories that make some impacts
plastic; settled, touching and closed-before contacts; friction on some), both paths on the compiled core:

- identical decisions: whether the result is the all-open configuration, the impact record's contacts,
  plastic contacts and keys, and the Zeno memory (impact counts, largest approach speeds: bitwise, both
  read the same compiled gap rates);
- when the fast path declines, the memory is bitwise what it was;
- impulses, the velocity after and the kinetic energies within round-off bounds. The two paths solve the
  same LCP on right-hand sides (normal rows (1 + e) J_N^T q'^-, friction rows J_T^T q'^-, limits 0) that
  differ only in how J^T q'^- is summed (a loop here, BLAS there): at most 2 n eps |J|^T |q'^-| per entry
  (the dot product's forward error bound, twice: one per path), times (1 + e) <= 2. With the same basis
  the unknowns x_S > 0 solve A_SS x_S = -b_S, so they move by at most ||A_SS^-1|| ||db_S||, plus the
  solvers' own rounding (refined to a few eps of |x|, 16 eps allowed per unknown). The velocity
  q'^- + Y x then moves by |Y| |dx| plus its own sums' rounding (2 (p + 1) eps of |q'^-| + |Y||x|, p terms);
  the kinetic energies (sums of n^2 products) by 2 n^2 eps of |q'| |M| |q'| plus what dv moves them.
  Everything is asserted with a margin of 4 on these bounds.

Skipped where the compiled part "resolve" is not active (not built, or NSFEM_PURE_PYTHON=1).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nsfem.contact.set import ContactSet
from nsfem.integrate import ContactSystem, core
from nsfem.integrate import transitions as tr
from nsfem.integrate.configuration import Mode
from nsfem.lcp.builders import impact_lcp
from nsfem.linalg import factorize

kernel = core.compiled("resolve")
pytestmark = pytest.mark.skipif(kernel is None, reason="the compiled core part 'resolve' is not active (not "
                                                       "built, or NSFEM_PURE_PYTHON=1): the reference runs")
EPS = np.finfo(float).eps


def _case(seed: int):
    """A random frictionless system near contact and the arguments of one resolve call."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 12))
    m = int(rng.integers(1, min(6, n + 1)))   # independent normals: one impact LCP solution
    B = rng.standard_normal((n, n))
    M = B @ B.T + n * np.eye(n) * 10.0 ** rng.uniform(-2, 2)
    JN = rng.standard_normal((n, m)) * 10.0 ** rng.uniform(-1, 1)
    q = rng.standard_normal(n) * 1e-3
    # gaps: zero (touching), inside the band, or open
    kind = rng.choice([0, 1, 2], m, p=[0.3, 0.2, 0.5])
    g = np.where(kind == 0, 0.0, np.where(kind == 1, 1e-14 * rng.random(m), 1e-4 * (1 + rng.random(m))))
    jN = g - JN.T @ q
    # rates: approaching, at rest or separating, set through the minimum-norm change of a random velocity
    rate = rng.choice([-1.0, 0.0, 1.0], m, p=[0.7, 0.1, 0.2]) * 10.0 ** rng.uniform(-3, 0, m)
    v0 = rng.standard_normal(n)
    v = v0 + JN @ np.linalg.lstsq(JN.T @ JN, rate - JN.T @ v0, rcond=None)[0]
    eps = rng.choice([0.0, 0.5, 1.0, 0.05 + 0.95 * float(rng.random())], m, p=[0.1, 0.3, 0.3, 0.3])
    friction = {}
    if rng.random() < 0.5 and n >= 3:   # Coulomb friction on some contacts (1 or 2 tangent directions)
        d = rng.integers(1, 3, m)
        JS = [rng.standard_normal((n, int(d[k]))) if rng.random() < 0.6 else None for k in range(m)]
        friction = {"mu": rng.choice([0.1, 0.3, 1.0], m), "JS": JS, "r": np.where(d == 1, 2, 4)}
    system = ContactSystem.from_arrays(M=M, Q=np.eye(n), contacts=ContactSet.from_arrays(JN, jN, eps=eps, **friction))
    memory = tr.Memory(10.0 ** rng.uniform(-4, 1, m) * (rng.random(m) < 0.7), rng.integers(0, 3, m),
                       zeno=float(rng.choice([1e-8, 0.3, 0.9])))
    memory.observe(system.contacts, q, v)
    close = [k for k in range(m) if kind[k] < 2]
    pick = lambda: {k for k in close if rng.random() < 0.4}   # noqa: E731
    before = Mode(closed=tuple(sorted(pick()))) if rng.random() < 0.3 else Mode()
    return system, factorize(M), q, v, before, memory, pick(), pick()


def _resolve(system, Mf, q, v, before, memory, touching, settled, fast: bool):
    if fast:
        return tr.resolve(system, Mf, 0.1, q, v, before, memory, touching, None, None, settled)
    saved = tr._impact_fast
    tr._impact_fast = lambda *a, **k: None
    try:
        return tr.resolve(system, Mf, 0.1, q, v, before, memory, touching, None, None, settled)
    finally:
        tr._impact_fast = saved


def _memory_state(memory: tr.Memory) -> list:
    return [np.array(getattr(memory, f), copy=True) for f in ("max_approach", "impacts", "gap_scale", "rate_scale")] \
        + [list(memory.degenerate)]


def _same(a: list, b: list) -> bool:
    return all(np.array_equal(x, y) for x, y in zip(a, b))


def check_case(seed: int) -> bool:
    """Both paths on one case; whether the fast path took it."""
    return check_args(*_case(seed))


def check_args(system, Mf, q, v, before, memory, touching, settled) -> bool:
    """Both paths on one set of resolve's arguments; whether the fast path took it."""
    start = _memory_state(memory)
    probe = copy.deepcopy(memory)
    took = tr._impact_fast(kernel, system, Mf, 0.1, q, v, before, probe, touching, None, settled) is not None
    if not took:   # handed back before changing anything
        assert _same(_memory_state(probe), start)
    mem_f, mem_p = copy.deepcopy(memory), copy.deepcopy(memory)
    try:
        full = _resolve(system, Mf, q, v, before, mem_p, touching, settled, fast=False)
    except tr.NsfemError:   # (a failed LCP: the fast path must not have taken it either)
        assert not took
        return False
    fast = _resolve(system, Mf, q, v, before, mem_f, touching, settled, fast=True)
    if not took:
        return False
    mode, v_f, imp_f = fast
    mode_p, v_p, imp_p = full
    # identical decisions
    assert mode == mode_p == Mode()
    assert imp_f.keys() == imp_p.keys()
    for key in ("t", "contacts", "plastic", "approach_m_s"):
        assert imp_f[key] == imp_p[key], key
    assert _same(_memory_state(mem_f), _memory_state(mem_p))
    # results within the round-off bounds of the module docstring: the full path's LCP (its restitutions:
    # plastic ones 0) and its solution x; on the unknowns x_S > 0 it solves A_SS x_S = -b_S
    cs, n = system.contacts, system.n
    act = imp_f["contacts"]
    e_used = cs.eps.copy()
    e_used[imp_p["plastic"]] = 0.0
    lcp = impact_lcp(cs, Mf, v, act, eps=e_used)
    x = lcp.solve().x
    na, nw = len(act), lcp.Y.shape[1]
    rows = np.hstack([cs.JN[:, act], lcp.W[:, na:]])   # [J_N, J_T]: the right-hand side's products
    db = np.zeros(x.size)
    db[:nw] = 2 * 2 * n * EPS * (np.abs(rows).T @ np.abs(v))
    S = np.flatnonzero(x > 0.0)
    # (A_SS is singular where a friction limit's multiplier z > 0 belongs to a contact without a normal impulse:
    # that z is free, and enters neither the impulses nor the velocity; the pseudo-inverse bounds the rest)
    inv = np.linalg.norm(np.linalg.pinv(lcp.A[np.ix_(S, S)], rcond=1e-12), 2) if S.size else 0.0
    dx = np.zeros(x.size)
    dx[S] = inv * np.linalg.norm(db[S])
    dx += 16 * EPS * np.abs(x)
    x_f, x_p = np.array(imp_f["impulse_Ns"]), np.array(imp_p["impulse_Ns"])
    assert np.all(np.abs(x_f - x_p) <= 4 * dx[:na])
    Y = np.abs(lcp.Y)
    dv = Y @ (4 * dx[:nw]) + 2 * (nw + 1) * EPS * (np.abs(v) + Y @ np.abs(x[:nw]))
    assert np.all(np.abs(v_f - v_p) <= 4 * dv)
    for key, w, dw in (("kinetic_before_J", v, np.zeros(n)), ("kinetic_after_J", v_p, 4 * dv)):
        size = np.abs(w) @ np.abs(system.M) @ np.abs(w)
        bound = 2 * n * n * EPS * size + (np.abs(w) @ np.abs(system.M) @ dw + 0.5 * dw @ np.abs(system.M) @ dw)
        assert abs(imp_f[key] - imp_p[key]) <= 4 * bound, key
    # what the answer must satisfy (Newton's law on the active contacts, q'^+ = q'^- + M^-1 J x)
    assert np.all(x_f >= 0.0)
    return True


def test_fast_path_takes_impacts_and_agrees_with_the_full_path():
    """200 random cases: both outcomes occur (the path is exercised and declines), and each agrees."""
    took = [check_case(seed) for seed in range(200)]
    assert 10 <= sum(took) <= 190   # (24 of 200 taken, 12 of them with friction or more than one contact)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(200, 2 ** 32 - 1))
def test_fast_path_property(seed):
    check_case(seed)


def test_declines_what_is_not_its_own():
    """Hand-made cases the path must hand back, memory untouched: a contact on a moving surface among the
    candidates, a plastic impact (the contact stays closed: the transition LCP decides), no approach."""
    M = np.diag([2.0, 3.0])
    JN = np.array([[1.0], [0.5]])
    v = np.array([-1.0, 0.0])
    cases = [
        ContactSet.from_arrays(JN, [0.0], eps=0.5, mu=0.3, JS=[np.array([[0.0], [1.0]])], r=2,
                               wS=[np.array([0.5])]),                                        # a moving surface
        ContactSet.from_arrays(JN, [0.0], eps=0.0),                                          # plastic: closed after
    ]
    for cs in cases:
        system = ContactSystem.from_arrays(M=M, Q=np.eye(2), contacts=cs)
        memory = tr.Memory(np.zeros(1), np.zeros(1, dtype=int))
        memory.observe(cs, np.zeros(2), v)
        start = _memory_state(memory)
        assert tr._impact_fast(kernel, system, factorize(M), 0.0, np.zeros(2), v, Mode(), memory, {0}, None,
                               set()) is None
        assert _same(_memory_state(memory), start)
    # no approach (separating): nothing to do here
    cs = ContactSet.from_arrays(JN, [0.0], eps=0.5)
    system = ContactSystem.from_arrays(M=M, Q=np.eye(2), contacts=cs)
    memory = tr.Memory(np.zeros(1), np.zeros(1, dtype=int))
    memory.observe(cs, np.zeros(2), -v)
    assert tr._impact_fast(kernel, system, factorize(M), 0.0, np.zeros(2), -v, Mode(), memory, {0}, None,
                           set()) is None


def test_one_contact_impact_is_newtons():
    """A point mass m on a stop, restitution e, Zeno memory off: q'^+ = -e q'^-, impulse m (1 + e) |q'^-|,
    kinetic energy e^2 of what it was (to a few ulp: one division, a few products)."""
    for e in (0.25, 0.5, 1.0):
        cs = ContactSet.from_arrays([[1.0]], [0.0], eps=e)
        system = ContactSystem.from_arrays(M=[[2.0]], Q=[[0.0]], contacts=cs)
        memory = tr.Memory(np.zeros(1), np.zeros(1, dtype=int))
        v = np.array([-3.0])
        memory.observe(cs, np.zeros(1), v)
        out = tr._impact_fast(kernel, system, factorize(system.M), 0.0, np.zeros(1), v, Mode(), memory, {0}, None,
                              set())
        assert out is not None
        v_new, imp = out
        assert abs(v_new[0] - 3.0 * e) <= 8 * EPS * 3.0
        assert abs(imp["impulse_Ns"][0] - 2.0 * (1 + e) * 3.0) <= 8 * EPS * 12.0
        assert abs(imp["kinetic_after_J"] - e * e * imp["kinetic_before_J"]) <= 16 * EPS * imp["kinetic_before_J"]
        assert memory.impacts[0] == 1 and memory.max_approach[0] == 3.0 and imp["plastic"] == []


def test_a_memory_with_its_impact_path_copies():
    """A Memory that has met an impact copies (the path is a cache its copies share) and the copy resolves as
    the original: the same velocity and Zeno memory."""
    for seed in range(200):   # a case the path takes
        system, Mf, q, v, before, memory, touching, settled = _case(seed)
        probe = copy.deepcopy(memory)
        if tr._impact_fast(kernel, system, Mf, 0.1, q, v, before, probe, touching, None, settled) is not None:
            break
    assert probe._impact is not None
    twin = copy.deepcopy(probe)
    assert twin._impact[2] is probe._impact[2]
    a = tr._impact_fast(kernel, system, Mf, 0.1, q, v, before, probe, touching, None, settled)
    b = tr._impact_fast(kernel, system, Mf, 0.1, q, v, before, twin, touching, None, settled)
    assert np.array_equal(a[0], b[0]) and a[1] == b[1]
    assert _same(_memory_state(probe), _memory_state(twin))


def _three_stops(eps: float = 0.5):
    """Three independent stops 1e-6 m away, each approached at 1 m/s (M diagonal, J_N = I)."""
    M = np.diag([1.0, 2.0, 3.0])
    cs = ContactSet.from_arrays(np.eye(3), [1e-6, 1e-6, 1e-6], eps=eps)
    return ContactSystem.from_arrays(M=M, Q=np.eye(3), contacts=cs), factorize(M), np.zeros(3), -np.ones(3)


def test_a_gap_tolerance_given_as_one_number_is_the_references():
    """resolve's ``gap_tol`` given as one number (numpy broadcasts it: every gap below it is zero): the impact path
    read it as a one-entry array and the other contacts' tolerances from memory beyond it (review-c: an impact on
    contact 0 alone, contacts 1 and 2 left approaching at -1 m/s, where the reference impacts all three). Each
    stop is independent (M diagonal, J_N = I): q'+ = -e q'- exactly on each, to a few ulp of 1 m/s."""
    system, Mf, q, v = _three_stops()
    for gap_tol in (1e-3, np.float64(1e-3), [1e-3] * 3):
        memory = tr.Memory(np.zeros(3), np.zeros(3, dtype=np.int64))
        memory.observe(system.contacts, q, v)
        mode, v_new, imp = tr.resolve(system, Mf, 0.0, q, v, Mode(), memory, (), gap_tol)
        assert mode == Mode() and imp["contacts"] == [0, 1, 2]
        assert np.all(np.abs(v_new - 0.5) <= 8 * EPS)
        assert memory.impacts.tolist() == [1, 1, 1]


def test_states_and_memories_of_other_shapes_take_the_full_path():
    """q, q' or a Zeno memory of another length than the system's (the kernels would read and write past them):
    the full path's answer (numpy's ValueError or IndexError), the memory's arrays unchanged in length."""
    system, Mf, q, v = _three_stops()
    for q_, v_, size in ((q[:2], v, 3), (q, v[:2], 3), (q, v, 2)):
        memory = tr.Memory(np.zeros(3), np.zeros(3, dtype=np.int64))
        memory.observe(system.contacts, q, v)
        memory.max_approach, memory.impacts = np.zeros(size), np.zeros(size, dtype=np.int64)
        assert tr._impact_fast(kernel, system, Mf, 0.0, q_, v_, Mode(), memory, {0, 1, 2}, None, set()) is None
        with pytest.raises((ValueError, IndexError)):
            tr.resolve(system, Mf, 0.0, q_, v_, Mode(), memory, {0, 1, 2})


def test_the_kernels_refuse_arrays_of_other_shapes():
    """ImpactPath.classify and .open read and write without bounds checks: called with an array of another shape
    (one entry short, or one row of state short) they decline (-1, 0) before reading it, and leave the Zeno
    memory as it was; with the right shapes the same call is taken (so the refusals are the shapes')."""
    system, Mf, q, v = _three_stops()
    cs = system.contacts
    memory = tr.Memory(np.zeros(3), np.zeros(3, dtype=np.int64))
    memory.observe(cs, q, v)
    path = memory.impact_path(system, Mf, kernel)
    good = dict(q=q, v=v, gap_scale=memory.gap_scale, rate_scale=memory.rate_scale, gap_tol=np.zeros(0),
                state=np.empty((6, 3)))
    def args(a):
        return a["q"], a["v"], a["gap_scale"], a["rate_scale"], a["gap_tol"], 0.0, (), (0, 1, 2), (), a["state"]
    for key, bad in (("q", q[:2]), ("v", v[:2]), ("gap_scale", memory.gap_scale[:2]),
                     ("rate_scale", memory.rate_scale[:2]), ("gap_tol", np.zeros(1)), ("state", np.empty((5, 3))),
                     ("state", np.empty((6, 2)))):
        assert path.classify(*args({**good, key: bad})) == -1, key
    assert path.classify(*args(good)) == 3
    state = good["state"]
    active = path.active()
    entry = tr._impact_parts(Mf, cs, active, tr.LCPCache(), ("impact", active))[0]   # (kept: equilibrated)
    mat = kernel.Matrix(entry[0], entry[2], entry[7], 3, entry[5], entry[8])
    general = lambda: tr.lemke(mat.A, x.copy(), groups=mat.groups, scales=mat.scales).x  # noqa: E731
    x = np.empty(3)
    good = dict(v=v, state=state, max_approach=np.zeros(3), impacts=np.zeros(3, dtype=np.int64), x=x,
                v_new=np.empty(3), ke=np.empty(2))
    def args(a):   # noqa: F811 - open's arguments
        return mat, general, a["v"], a["state"], a["max_approach"], a["impacts"], 1e-8, a["x"], a["v_new"], a["ke"]
    for key, bad in (("v", v[:2]), ("state", state[:5]), ("max_approach", np.zeros(2)),
                     ("impacts", np.zeros(2, dtype=np.int64)), ("x", np.empty(2)), ("v_new", np.empty(2)),
                     ("ke", np.empty(1))):
        a = {**good, key: bad}
        assert path.open(*args(a)) == 0, key
        assert not a["max_approach"].any() and not a["impacts"].any()
    assert path.open(*args(good)) == 1
    assert good["impacts"].tolist() == [1, 1, 1]


def _boundary_case(seed: int):
    """resolve's arguments at the path's decision boundaries: two contacts at one point (equal or nearly equal
    normals), approach rates at the CREEP boundary (-1e-7 of the speed and one ulp-scale beyond), at +-1e-300,
    resting and separating; restitutions 0, 1/2 and 1; Zeno memories exactly at their threshold (zeno a power of
    two: zeno * max_approach == the speed, not plastic by the strict test); friction with mu up to 10 on 4-8
    generators, some with no slip at all; speeds from 1e-120 to 1e120. None on a contact set the set refuses."""
    rng = np.random.default_rng([77, seed])
    n, m = int(rng.integers(2, 6)), int(rng.integers(2, 5))
    B = rng.standard_normal((n, n))
    M = B @ B.T + n * np.eye(n)
    JN = rng.standard_normal((n, m))
    if rng.random() < 0.3:
        JN[:, 1] = JN[:, 0] * (1 + (0 if rng.random() < 0.5 else 1e-12))
    q, jN = np.zeros(n), np.where(rng.random(m) < 0.7, 0.0, 1e-3)
    rate = rng.choice([-1.0, 0.0, 1.0, -1e-7, -1e-7 * (1 + 1e-15), 1e-300, -1e-300], m) * 10.0 ** rng.uniform(-120, 120)
    v0 = rng.standard_normal(n)
    v = v0 + np.linalg.lstsq(JN.T, rate - JN.T @ v0, rcond=None)[0]
    friction = {}
    if rng.random() < 0.5 and n >= 3:
        JS = [rng.standard_normal((n, int(rng.integers(1, 3)))) for _ in range(m)]
        if rng.random() < 0.5:   # no slip: S^T q' = 0
            JS = [S - np.outer(v, v @ S) / (v @ v) for S in JS]
        friction = {"mu": rng.choice([0.1, 1.0, 10.0], m), "JS": JS,
                    "r": [2 if S.shape[1] == 1 else int(rng.choice([4, 6, 8])) for S in JS]}
    try:
        cs = ContactSet.from_arrays(JN, jN, eps=rng.choice([0.0, 1.0, 0.5], m), **friction)
    except tr.NsfemError:
        return None
    system = ContactSystem.from_arrays(M=M, Q=np.eye(n), contacts=cs)
    zeno = float(rng.choice([0.5, 0.25]))
    maxa = np.maximum(np.where(rng.random(m) < 0.5, -(JN.T @ v) / zeno, 0.0), 0.0)
    memory = tr.Memory(maxa, (maxa > 0).astype(np.int64), zeno=zeno)
    memory.observe(cs, q, v)
    touching = {k for k in range(m) if jN[k] == 0.0 and rng.random() < 0.5}
    before = Mode(closed=tuple(k for k in range(m) if jN[k] == 0.0 and rng.random() < 0.3))
    return system, factorize(M), q, v, before, memory, touching, {k for k in range(m) if rng.random() < 0.2}


def test_fast_path_at_its_decision_boundaries():
    """200 boundary cases (review-c; 3000 checked once, 256 taken, all agree): each agrees with the full path
    (check_args: identical decisions and Zeno memory, results within their round-off bounds) or is handed back
    untouched; the path takes some of them."""
    took = [check_args(*args) for args in map(_boundary_case, range(200)) if args is not None]
    assert sum(took) >= 3   # (9 of 200 taken: the boundaries reach the path, not only its hand-backs)


def test_an_interrupt_inside_the_general_lcp_leaves_the_memory(monkeypatch):
    """A KeyboardInterrupt (Ctrl-C) or error raised by the general Lemke solve the kernel calls back into
    propagates out of ImpactPath.open (not swallowed in the C code), with the Zeno memory and the scales as they
    were; the same path then resolves the event (its work arrays are not left half-used)."""
    system, Mf, q, v = _three_stops()
    memory = tr.Memory(np.zeros(3), np.zeros(3, dtype=np.int64))
    memory.observe(system.contacts, q, v)
    start = _memory_state(memory)
    for exc in (KeyboardInterrupt, MemoryError):
        def interrupted(*args, **kw):
            raise exc
        monkeypatch.setattr(tr, "lemke", interrupted)
        with pytest.raises(exc):
            tr._impact_fast(kernel, system, Mf, 0.0, q, v, Mode(), memory, {0, 1, 2}, None, set())
        assert _same(_memory_state(memory), start)
    monkeypatch.undo()
    v_new, imp = tr._impact_fast(kernel, system, Mf, 0.0, q, v, Mode(), memory, {0, 1, 2}, None, set())
    assert imp["contacts"] == [0, 1, 2] and np.all(np.abs(v_new - 0.5) <= 8 * EPS)


def test_a_pushed_contact_is_handed_back():
    """Two touching stops on a coupled mass (M = [[1, .9], [.9, 1]], J_N = I): contact 0 approaches at 1 m/s,
    contact 1 separates at 1 mm/s; the impulse on 0 drives 1 into approach (M^-1 e_0 = [1, -.9] / .19), a set
    closure: the path hands it back untouched, and resolve's full path closes the set (both contacts in the
    impact, ``set_closure`` from 1 on) as on the reference core."""
    M = np.array([[1.0, 0.9], [0.9, 1.0]])
    cs = ContactSet.from_arrays(np.eye(2), [0.0, 0.0], eps=0.5)
    system, Mf = ContactSystem.from_arrays(M=M, Q=np.eye(2), contacts=cs), factorize(M)
    q, v = np.zeros(2), np.array([-1.0, 1e-3])
    records = []
    for reference in (False, True):
        memory = tr.Memory(np.zeros(2), np.zeros(2, dtype=np.int64))
        memory.observe(cs, q, v)
        if not reference:
            start = _memory_state(memory)
            assert tr._impact_fast(kernel, system, Mf, 0.0, q, v, Mode(), memory, {0, 1}, None, set()) is None
            assert _same(_memory_state(memory), start)
            records.append(tr.resolve(system, Mf, 0.0, q, v, Mode(), memory, {0, 1})[2])
        else:
            with core.reference():
                records.append(tr.resolve(system, Mf, 0.0, q, v, Mode(), memory, {0, 1})[2])
    assert records[0]["contacts"] == records[1]["contacts"] == [0, 1]
    assert records[0]["set_closure"] == records[1]["set_closure"] and records[0]["set_closure"][0] == 1


def test_the_paths_matrices_are_bounded_as_the_lcp_cache():
    """ImpactPath.matrices keeps the impact LCPs' matrix parts it meets: no more of them than the Memory's LCP cache
    keeps (its entries, the oldest dropped first), none the cache declined as too large (review-c: they grew
    without bound beside the cache's byte budget). Six stops, impacts on six different active sets, a cache of 2
    entries; then a cache of 0 bytes. Each impact is still resolved (q'+ = -e q'- on each stop, a few ulp)."""
    M = np.diag(np.arange(1.0, 7.0))
    cs = ContactSet.from_arrays(np.eye(6), np.zeros(6), eps=0.5)
    system, Mf = ContactSystem.from_arrays(M=M, Q=np.eye(6), contacts=cs), factorize(M)
    for entries, nbytes, kept in ((2, 2 ** 27, 2), (256, 0, 0)):
        memory = tr.Memory(np.zeros(6), np.zeros(6, dtype=np.int64))
        memory.lcp_cache = tr.LCPCache(entries, nbytes)
        for k in range(6):
            q, v = np.full(6, 1e-3), np.ones(6)
            q[k], v[k] = 0.0, -1.0   # contact k touches and approaches, the others are open and separate
            memory.observe(cs, q, v)
            v_new, imp = tr._impact_fast(kernel, system, Mf, 0.0, q, v, Mode(), memory, {k}, None, set())
            assert imp["contacts"] == [k] and abs(v_new[k] - 0.5) <= 8 * EPS
        assert len(memory._impact[2].matrices) == kept
