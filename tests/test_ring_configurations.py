"""Configurations of elastic rings keyed by what sets their matrices (issue 33, elastic rings).

A ring's law adds Kr = k_s P^T G S P and Cr = c_s P^T G D P to the equations and fr = k_s P^T G a to the load
(nsfem.contact.ring): a facet alone at a corner (laws 2F + k, 3F + k) is that facet's edge law (S, D and a
alike) and the corners' laws of both facets (S = D = I) differ in a alone. Such configurations share one
eigen-decomposition (``Configuration.with_load``). The sharing is exact, not approximate: the shared
configuration's arrays are formed from bit-identical inputs by the same operations, so every comparison here
is equality, and a run with sharing is the run without it, event for event and bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nsfem.contact.ring import PARALLEL, Ring
from nsfem.integrate import core, integrate
from nsfem.integrate.configuration import Configuration, Mode, Phase, matrix_key
from nsfem.integrate.event_driven import EventDriven
from nsfem.integrate.problem import ContactSystem


def _ring(facets: int, mu: float, n: int = 3, seed: int = 0, cs: float = 30.0) -> Ring:
    P = np.random.default_rng(seed).normal(size=(2, n))
    return Ring("ring", P, 2 * np.pi * np.arange(facets) / facets, 1e-4, 1e5, cs, mu, 0.01, 120.0, False)


@settings(max_examples=25, deadline=None)
@given(facets=st.sampled_from([3, 4, 12, 64]), mu=st.sampled_from([0.0, 0.3]), seed=st.integers(0, 2**31 - 1))
def test_laws_of_one_matrix_key_have_the_same_matrices(facets, mu, seed):
    """Over all 4F laws and both slip signs: one key, the same Kr and Cr (bit for bit); the same facets pushing,
    also the same load. (The key may be finer than the matrices: an S differing in a round-off entry that Kr
    rounds away costs one decomposition more, never a wrong one.)"""
    ring = _ring(facets, mu, seed=seed)
    groups: dict = {}
    for law in range(4 * facets):
        for s in (-1, 1):
            groups.setdefault(ring.matrix_key(law, s), []).append((law, ring.terms(law, s)))
    for key, terms in groups.items():
        _, (Kr, Cr, fr) = terms[0]
        for law, (K2, C2, f2) in terms[1:]:
            assert np.array_equal(K2, Kr) and np.array_equal(C2, Cr)
            same = [(m, f) for m, (_, _, f) in terms if set(ring.pushing(m)) == set(ring.pushing(law))]
            assert all(np.array_equal(f, same[0][1]) for _, f in same)
    # the shares the key is for: a facet alone at corner k is its edge's law, every corner's law of both facets one
    for k in range(facets):
        for s in (-1, 1):
            key = ring.matrix_key
            assert key(2 * facets + k, s) == key(k, s) and key(3 * facets + k, s) == key((k + 1) % facets, s)
            assert key(facets + k, s) == key(facets, s) != key(k, s)
            if facets % 2 == 0:     # opposite facets: one line, one spring (Ring.springs)
                assert key(k, s) == key((k + facets // 2) % facets, s)
    # at most F single facets and the corners' one key per slip sign; without friction the sign does not count
    assert len(groups) <= (facets + 1) * (2 if mu else 1)
    assert (mu == 0.0) == all(k[1] == 0 for k in groups)


def _jeffcott(mu: float, facets: int = 12, cs: float = 30.0):
    """test_elastic_ring's Jeffcott rotor (1 kg, 1e4 N/m) in an elastic ring of 1e5 N/m, with a turning 2 N load."""
    w = 120.0
    ring = Ring("ring", np.eye(2), 2 * np.pi * np.arange(facets) / facets, 1e-4, 1e5, cs, mu, 0.01, w, False)
    return ContactSystem.from_arrays(np.eye(2), 1e4 * np.eye(2), 2.0 * np.eye(2), fc=np.array([2.0, 0.0]),
                                     fs=np.array([0.0, 2.0]), omega=w, rings=(ring,))


def _same_configuration(a: Configuration, b: Configuration) -> None:
    for name in ("A", "B", "f0", "Q", "C", "N", "L", "Rx", "Rphi", "eigenvalues", "A_aug_base", "harmonic_b"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    for x, y in zip(a.eig, b.eig):
        assert np.array_equal(x, y)
    for key, arr in a.kernel_arrays.items():
        assert np.array_equal(arr, b.kernel_arrays[key]), key


@pytest.mark.parametrize("mu", [0.0, 0.2])
def test_a_shared_configuration_is_the_fresh_one(mu):
    """with_load of a configuration of the same key gives the arrays, and the motion, of a configuration built
    afresh, for every corner law from any other of the same key (kernel arrays formed before or after)."""
    sysm = _jeffcott(mu)
    F, s = 12, 1
    rng = np.random.default_rng(1)
    for law in range(4 * F):
        mode = Mode(ring=((0, law, s),))
        fresh = Configuration(sysm, mode)
        key = sysm.rings[0].matrix_key(law, s)
        other = next(m for m in range(4 * F) if m != law and sysm.rings[0].matrix_key(m, s) == key)
        base = Configuration(sysm, Mode(ring=((0, other, s),)))
        if law % 2:
            base.kernel_arrays   # noqa: B018 (formed before the share: with_load replaces its f0)
        shared = base.with_load(mode)
        assert shared.mode == mode and shared.eig[0] is base.eig[0]
        _same_configuration(shared, fresh)
        q0, v0 = rng.normal(scale=1e-4, size=2), rng.normal(scale=1e-2, size=2)
        t = np.linspace(0.0, 0.01, 7)
        assert np.array_equal(Phase(shared, 0.0, q0, v0, np.zeros(0)).xi(t), Phase(fresh, 0.0, q0, v0, np.zeros(0)).xi(t))


@pytest.mark.parametrize("mu", [0.0, 0.2])
def test_a_ring_run_decomposes_once_per_matrix_key_and_is_the_unshared_run(mu, monkeypatch):
    """A run through edges, corners and releases: one decomposition per matrix key met (fewer than its
    configurations), and the same run as with a decomposition per configuration, bit for bit."""
    sysm = _jeffcott(mu)
    shared = integrate(sysm, 0.2, "exact", 1e-3)
    keys = {matrix_key(sysm, Mode(ring=tuple(tuple(r) for r in e["after"].get("ring", []))))
            for e in shared.events} | {matrix_key(sysm, Mode())}
    assert {"ring_engage", "ring_release", "ring_exit"} <= {k for e in shared.events for k in e["kinds"]}
    assert shared.info["decompositions"] == len(keys) < shared.info["configurations"]
    monkeypatch.setattr(EventDriven, "_build", lambda self, mode, turn: Configuration(self.system, mode))
    alone = integrate(sysm, 0.2, "exact", 1e-3)
    assert alone.info["decompositions"] == alone.info["configurations"] == shared.info["configurations"]
    assert shared.events == alone.events
    assert np.array_equal(shared.q, alone.q) and shared.energy == alone.energy


def test_compiled_phase_reads_the_shared_load():
    """The compiled phase set-up reads f0 from kernel_arrays: a configuration shared after its kernel arrays were
    formed starts its phases from its own load (the compiled and the reference phase agree)."""
    if core.compiled("phase") is None:
        pytest.skip("the compiled event core is not installed or not active (NSFEM_PURE_PYTHON=1)")
    sysm = _jeffcott(0.2)
    F = 12
    base = Configuration(sysm, Mode(ring=((0, F, 1),)))
    base.kernel_arrays   # noqa: B018
    shared = base.with_load(Mode(ring=((0, F + 5, 1),)))
    q0, v0 = np.array([1.2e-4, 0.3e-4]), np.array([0.0, 1e-2])
    t = np.linspace(0.0, 0.01, 5)
    compiled = Phase(shared, 0.0, q0, v0, np.zeros(0)).xi(t)
    with core.reference():
        ref = Phase(shared, 0.0, q0, v0, np.zeros(0)).xi(t)
    # the kernel's loops round as the reference's BLAS products only to the last bits of the state (its size
    # 1e-4 m, 1e-2 m/s: 1e-12 of the largest component is a few hundred ulps of headroom)
    np.testing.assert_allclose(compiled, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert not np.allclose(shared.f0, base.f0)


@settings(max_examples=25, deadline=None)
@given(facets=st.integers(3, 256), turn=st.floats(-np.pi, np.pi), seed=st.integers(0, 2**31 - 1))
def test_a_facet_spring_is_its_normal_to_round_off(facets, turn, seed):
    """S_k is n_k n_k^T of its own normal, or of the first parallel facet's (opposite, |n_j x n_k| within the
    tolerance tol of PARALLEL, so |n_j + n_k| <= tol to first order): the entries (at most 1) then differ by at
    most 2 tol, and 4 eps more for their own rounding. Regular polygons of even F pair every facet with its
    opposite; random angles have no parallel facets and keep their own n n^T bit for bit."""
    ring = Ring("ring", np.eye(2), turn + 2 * np.pi * np.arange(facets) / facets, 1e-4, 1e5)
    own = np.einsum("ki,kj->kij", ring.normals, ring.normals)
    tol = PARALLEL * (1.0 + np.abs(ring.angles).max())
    assert np.abs(ring.springs - own).max() <= 2 * tol + 4 * np.finfo(float).eps
    # the definition, all pairs at once (Ring.springs finds them among neighbours in the lines' angle order)
    n = ring.normals
    cross = np.abs(n[:, None, 0] * n[None, :, 1] - n[:, None, 1] * n[None, :, 0])
    line = np.argmax(cross <= tol, axis=1)
    assert np.array_equal(ring.springs, np.einsum("ki,kj->kij", n[line], n[line]))
    shared = {ring.springs[k].tobytes() for k in range(facets)}
    assert len(shared) == (facets // 2 if facets % 2 == 0 else facets)
    angles = np.sort(np.random.default_rng(seed).uniform(0.0, 2 * np.pi, facets))
    if np.min(np.abs(np.sin(angles[:, None] - angles[None, :])) + np.eye(facets)) > 1e-9:
        odd = Ring("ring", np.eye(2), angles, 1e-4, 1e5)
        assert np.array_equal(odd.springs, np.einsum("ki,kj->kij", odd.normals, odd.normals))
    with pytest.raises(ValueError):
        ring.parts(0)[0][0, 0] = 1.0      # formed once per law and shared: read-only


@settings(max_examples=60, deadline=None)
@given(facets=st.sampled_from([3, 4, 5, 12, 64]), turn=st.floats(-np.pi, np.pi), region=st.integers(0, 10**6),
       u=st.tuples(st.floats(-3e-4, 3e-4), st.floats(-3e-4, 3e-4)), scale=st.floats(-8, 2),
       du=st.tuples(st.floats(-1, 1), st.floats(-1, 1)), cs=st.sampled_from([0.0, 30.0]),
       on=st.sampled_from([None, "n0", "n1", "t0", "zero"]))
def test_law_at_one_point_decides_as_laws(facets, turn, region, u, scale, du, cs, on):
    """Ring.law (scalars, once per ring event) and Ring.laws (arrays, the outputs) are one function: the same
    case for any X, also with X on a switch's line (along a facet's normal or tangent, or zero), where only
    the same products and sums in the same order decide alike."""
    ring = Ring("ring", np.eye(2), turn + 2 * np.pi * np.arange(facets) / facets, 1e-4, 1e5, cs)
    reg = region % (2 * facets)
    u, du = np.array(u), 10.0 ** scale * np.array(du)
    if on is not None and cs:       # u' that puts X = k_s d + c_s u' on a line of the cone's cases
        k = reg % facets
        line = {"n0": ring.normals[k], "n1": ring.normals[(k + 1) % facets],
                "t0": np.array([-ring.normals[k][1], ring.normals[k][0]]), "zero": np.zeros(2)}[on]
        d = ring.push(reg, u, np.zeros(2))
        du = (du[0] * line - d) / cs
    X = ring.push(reg, u, du)
    ref = int(ring.laws(np.array([reg]), X[:, None])[0])
    assert ring.law(reg, u, du) == (None if ref < 0 else ref)
