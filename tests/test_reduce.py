"""Model reduction: Craig-Bampton and modal truncation against the full model."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from nsfem import NsfemError, build_model, load_scene, natural_frequencies
from nsfem.analysis.campbell import gravity_resonances
from nsfem.analysis.modes import contact_basis
from nsfem.contact.kinematics import gap_jacobian
from nsfem.fem.rotating import rotor_operators
from nsfem.reduce import reduce


@pytest.fixture(scope="module")
def model():
    return build_model(load_scene(None))  # the shipped scene, 40 elements, 355 dofs


@pytest.fixture(scope="module")
def full(model):
    return {c: natural_frequencies(model, c, 6).frequencies_hz for c in ("open", "closed")}


def max_error(model, full, red, contact):
    f = natural_frequencies(model, contact, 6, red).frequencies_hz
    return float(np.abs(f / full[contact] - 1).max())


def test_craig_bampton_reproduces_the_full_model(model, full):
    # shipped scene, first six frequencies. Open: truncation errors, the same on every BLAS
    # kernel to 1e-11, bounded by the measured ones with ~3x margin (N = 16: 3.5e-5, N = 64:
    # 7.2e-7). Closed: exact in exact arithmetic (the boundary coordinates are the gaps: closing
    # them leaves the closed structure's own fixed-interface modes), so only the eigensolvers'
    # round-off remains, eps x the componentwise condition |v|^T |K| |v| / v^T K v of the full
    # model's first six modes (<= 1.4e6) = 3e-10 (measured 4e-12 to 9e-12 over four kernels)
    red = reduce(model, "craig-bampton", 16)
    assert red.ndof == 25 < model.n  # 9 gaps + 16 modes
    assert max_error(model, full, red, "open") < 1e-4
    assert max_error(model, full, red, "closed") < 1e-9
    fine = reduce(model, "craig-bampton", 64)
    assert max_error(model, full, fine, "open") < 2e-6
    # gravity resonances, N = 16: truncation errors again (kernel spread 1e-11), measured
    # 6.8e-9 / 2.9e-5 open, 5.7e-10 / 1.2e-6 closed; bounds 3x the open ones
    for c in ("open", "closed"):
        ref = gravity_resonances(rotor_operators(model, contact_basis(model, c)))[0][:2]
        got = gravity_resonances(rotor_operators(model, contact_basis(model, c, red)))[0][:2]
        assert got[0] == pytest.approx(ref[0], rel=2e-8)
        assert got[1] == pytest.approx(ref[1], rel=1e-4)


def test_craig_bampton_error_falls_as_modes_are_added(model, full):
    errs = [max_error(model, full, reduce(model, "craig-bampton", n), "open")
            for n in (6, 16, 64, 128)]
    # measured 3.58e-5, 3.55e-5, 7.2e-7, 1.4e-7: the smallest step (3.6e-7) is far above the 1e-11
    # round-off of either side
    assert all(b < a for a, b in zip(errs, errs[1:])), errs


def test_modal_truncation_open_is_exact_closed_is_too_stiff(model, full):
    # the basis holds the open eigenvectors themselves: open frequencies exact to round-off,
    # eps x the componentwise condition of the Rayleigh quotient (<= 1.4e6) = 3e-10 (measured
    # 2e-12 to 1.3e-11 over four kernels)
    assert max_error(model, full, reduce(model, "modal", 16), "open") < 1e-9
    # closing 9 Dirac contacts over-constrains the kept shapes ("artificial rigidity"):
    # the first closed z-bending frequency converges from above as modes are added
    # (measured 43.7573, 43.6655, 43.6584, 43.6574 Hz for 20-32 modes; full 43.6574)
    first_w = []
    for n in (20, 24, 28, 32):
        m = natural_frequencies(model, "closed", 6, reduce(model, "modal", n))
        first_w.append(next(f for f, k in zip(m.frequencies_hz, m.fields) if k == "W"))
    assert all(b < a for a, b in zip(first_w, first_w[1:])), first_w
    assert all(f > full["closed"][0] for f in first_w)
    # truncation errors (kernel-independent to 1e-11): measured 2.3e-3 at 20 modes, 3.6e-7 at 32
    assert first_w[0] / full["closed"][0] - 1 > 1e-3 and first_w[-1] / full["closed"][0] - 1 < 1e-6
    # with 16 modes (the paper's model) no z-bending shape survives the closure at all
    m16 = natural_frequencies(model, "closed", 6, reduce(model, "modal", 16))
    assert "W" not in m16.fields


def test_projection_keeps_symmetry_skewness_and_definiteness(model):
    full_ops = rotor_operators(model, basis=sp.identity(model.n_full, format="csr"))
    for method in ("modal", "craig-bampton"):
        red = reduce(model, method, 16)
        for contact in ("open", "closed"):
            T = contact_basis(model, contact, red)
            # the raw products, before project() enforces exact (skew-)symmetry: sums over the 355
            # full dofs, off by at most n eps |T|^T |G1| |T| <= 355 x 2.2e-16 x 1.8 max|G| = 1.4e-13
            # max|G| (measured <= 1.1e-15)
            G = T.T @ (full_ops.G1 @ T)
            assert np.abs(G + G.T).max() <= 1e-12 * np.abs(G).max()
            ops = rotor_operators(model, T)
            # smallest eigenvalues 3e-2 (M) and 2.3e-4 (K0) of the largest: far from 25 eps
            assert np.linalg.eigvalsh(ops.M.toarray()).min() > 0
            assert np.linalg.eigvalsh(ops.K0.toarray()).min() > 0
            # eigvalsh: n eps ||Kc1||; the projection: 355 eps |T|^T |Kc1| |T| <= 355 x 2.2e-16 x 7.5
            # ||Kc1|| = 6e-13 ||Kc1|| (measured <= 2.2e-16)
            w = np.linalg.eigvalsh(ops.Kc1.toarray())
            assert w.max() <= 1e-12 * abs(w).max()


def test_static_contact_load_gives_the_same_gaps(model):
    # Craig-Bampton's constraint modes make the static response to boundary loads exact
    J, j = gap_jacobian(model)
    lam = np.linspace(1.0, 2.0, J.shape[1])  # normal forces at the 9 contact points [N]
    f = model.T.T @ (J @ lam)
    q = spla.spsolve(model.K.tocsc(), f)
    gaps_full = J.T @ (model.T @ q)
    red = reduce(model, "craig-bampton", 4)
    V = red.V
    eta = np.linalg.solve(V.T @ (model.K @ V), V.T @ f)
    gaps_cb = J.T @ (model.T @ (V @ eta))
    # the full solve is good to eps x cond(D K D) = 2.2e-16 x 1.6e6 = 3.5e-10 of the largest gap
    # (K Jacobi-scaled: LU does not see the scaling); the 25-dof reduced solve's cond is 900.
    # Measured 9e-13 to 1.8e-12 over four kernels
    assert np.allclose(gaps_cb, gaps_full, rtol=0.0, atol=1e-9 * np.abs(gaps_full).max())
    # modal truncation with as many modes is far off (no static completeness; measured 2.2e-2)
    Vm = reduce(model, "modal", red.ndof).V
    eta = np.linalg.solve(Vm.T @ (model.K @ Vm), Vm.T @ f)
    assert np.abs(J.T @ (model.T @ (Vm @ eta)) / gaps_full - 1).max() > 1e-3


def test_free_structure_reduces_too():
    model = build_model(load_scene(None, ['shaft.supports="free-free"', "mesh.elements=20"]))
    red = reduce(model, "craig-bampton", 24)
    assert red.info["boundary_dofs"] == 9 + 5  # one dof per rigid motion the gaps leave free
    ref = natural_frequencies(model, "open", 9).frequencies_hz
    got = natural_frequencies(model, "open", 9, red).frequencies_hz
    assert np.count_nonzero(got == 0) == 5  # rigid modes are set to exactly 0 Hz
    # truncation error, kernel-independent: measured 3.7e-5, bound 2.7x that
    assert got[5:] == pytest.approx(ref[5:], rel=1e-4)


def test_bad_reduction_requests():
    model = build_model(load_scene(None, ["mesh.elements=20"]))
    with pytest.raises(NsfemError, match="exceeds"):
        reduce(model, "modal", 10_000)
    with pytest.raises(NsfemError, match="unknown reduction"):
        reduce(model, "svd", 4)


def test_scene_and_set_select_the_reduction(capsys):
    import json

    from nsfem import cli

    for method, ndof in (("none", 175), ("modal", 12), ("craig-bampton", 21)):
        assert cli.main(["modes", "--json", "--set", "mesh.elements=20", "--set", f"reduction.method={method}",
                         "--set", "reduction.modes=12"]) == 0
        d = json.loads(capsys.readouterr().out)
        assert d["reduction"]["method"] == method and d["ndof"] == ndof and d["ndof_full"] == 175


@pytest.mark.parametrize("overrides", [[], ["delamination.0.friction=0.3"], ["delamination.0.weighting=hat"]])
def test_craig_bampton_coordinates_are_the_gaps_and_slips(overrides):
    # C V = [I 0]: the first b reduced coordinates are the gaps (and slips), the modal ones
    # move none of them; so gaps are exact and closing contacts removes coordinates exactly
    m = build_model(load_scene(None, overrides + ["mesh.elements=20"]))
    red = reduce(m, "craig-bampton", 8)
    JN, jN, JS = red.jacobians()
    C = np.hstack([JN, JS]).T  # (gaps + slips) x ndof
    b = red.info["boundary_dofs"]
    assert b == C.shape[0] == 9 + (18 if "friction" in str(overrides) else 0)
    # C V - [I 0] is a residual (of the bordered LU solve for the constraint modes, of the exact
    # elimination C Tc = 0 for the others), not a forward error, so cond does not enter: measured
    # 2e-14 to 3.8e-12 over four kernels and these three scenes (|C| |V| <= 8.7); 1e-10 keeps 25x
    assert np.allclose(C[:, :b], np.eye(b), atol=1e-10) and np.abs(C[:, b:]).max() < 1e-10
    assert red.jacobians()[0] is JN  # projected once


def test_hat_weighted_reduction_does_not_grow_with_the_mesh():
    # a hat-weighted gap is one functional however many dofs it spans
    sizes = [reduce(build_model(load_scene(None, ["delamination.0.weighting=hat", f"mesh.elements={n}"])),
                    "craig-bampton", 16).ndof for n in (20, 80)]
    assert sizes == [25, 25]
