"""The LCP set-up cached per structure (nsfem.lcp.builders.LCPCache) gives the same problems and
solutions as building it anew; Lemke with precomputed scalings solves bitwise alike."""

from __future__ import annotations

import numpy as np
import pytest

from nsfem.contact.set import ContactSet
from nsfem.lcp import impact_lcp, transition_lcp
from nsfem.lcp.builders import LCPCache
from nsfem.lcp.pivoting import equilibrate, lemke
from nsfem.linalg import factorize


def _system(seed: int, n: int = 6, m: int = 3, mu: float = 0.4):
    rng = np.random.default_rng(seed)
    B = rng.standard_normal((n, n))
    M = B @ B.T + n * np.eye(n)
    JN = rng.standard_normal((n, m))
    JS = [rng.standard_normal((n, 2)) for _ in range(m)]
    cs = ContactSet.from_arrays(JN, np.zeros(m), mu=mu, eps=0.5, JS=JS, r=4)
    return cs, factorize(M), rng


@pytest.mark.parametrize("seed", range(4))
def test_cached_impact_and_transition_lcps_equal_fresh_ones(seed):
    cs, Mf, rng = _system(seed)
    cache = LCPCache()
    for _ in range(3):  # the first call fills the cache, the others read it
        v = rng.standard_normal(cs.n)
        fresh = impact_lcp(cs, Mf, v, [0, 2])
        cached = impact_lcp(cs, Mf, v, [0, 2], cache, ("impact", (0, 2)))
        assert np.array_equal(fresh.A, cached.A) and np.array_equal(fresh.b, cached.b)
        assert np.array_equal(fresh.solve().x, cached.solve().x)
        f = rng.standard_normal(cs.n)
        fresh = transition_lcp(cs, Mf, f, [0, 1], [1], {0: cs.generators(0)[:, 1]})
        cached = transition_lcp(cs, Mf, f, [0, 1], [1], {0: cs.generators(0)[:, 1]}, cache=cache,
                                key=("transition", (0, 1), (1,), ((0, 1),)))
        assert np.array_equal(fresh.A, cached.A) and np.array_equal(fresh.b, cached.b)
        assert np.array_equal(fresh.motion(fresh.solve().x), cached.motion(cached.solve().x))
    assert len(cache) == 2
    assert not cached.A.flags.writeable and not cached.Y.flags.writeable


def test_impact_lcp_eps_argument_equals_a_contact_set_with_those_restitutions():
    from dataclasses import replace

    cs, Mf, rng = _system(7)
    v = rng.standard_normal(cs.n)
    eps = np.array([0.0, 0.3, 1.0])
    a = impact_lcp(replace(cs, eps=eps), Mf, v, [0, 1, 2])
    b = impact_lcp(cs, Mf, v, [0, 1, 2], eps=eps)
    assert np.array_equal(a.b, b.b) and np.array_equal(a.A, b.A)


def test_cache_drops_the_oldest_beyond_its_byte_budget():
    cache = LCPCache(entries=10, nbytes=1000)
    for k in range(4):
        cache.put(k, ("entry", k), 400)
    assert len(cache) == 2 and cache.get(0) is None and cache.get(3) == ("entry", 3)
    cache.put("big", ("too big",), 2000)          # larger than the budget: not kept
    assert cache.get("big") is None and len(cache) == 2


@pytest.mark.parametrize("seed", range(20))
def test_lemke_with_precomputed_scales_is_bitwise_the_same(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 8))
    B = rng.standard_normal((n, n))
    A = B @ B.T + 0.1 * np.eye(n) if seed % 2 else rng.standard_normal((n, n)) + n * np.eye(n)
    A = A * 10.0 ** rng.uniform(-6, 6, (n, 1))
    b = rng.standard_normal(n)
    ref, fast = lemke(A, b), lemke(A, b, scales=equilibrate(A))
    assert ref.status == fast.status and ref.pivots == fast.pivots
    assert np.array_equal(ref.x, fast.x) and ref.residual == fast.residual
