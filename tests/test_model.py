"""The assembled model: constraint basis T, rigid-body motions, symmetry, definiteness, meshes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.linalg as sla

from nsfem import build_model, load_scene, natural_frequencies
from nsfem.fem.constraints import project
from nsfem.fem.rigid import admissible, rigid_fields
from nsfem.mesh import generate, read, write

MESHES = Path(__file__).resolve().parents[1] / "meshes"


def model_of(*overrides):
    return build_model(load_scene(None, list(overrides)))


def test_rigid_motions_carry_no_strain_energy_and_are_admitted_free_free():
    model = model_of('shaft.supports="free-free"', "mesh.elements=20")
    R = rigid_fields(model)
    K = model.K_full
    # strain energy of a unit rigid motion: the elements reproduce rigid motions, so only the
    # product's round-off remains, <= 6 eps |r|^T |K| |r| (6 entries a row; |r|^T |K| |r| =
    # 1.08 max|K| |r|^2) = 1.4e-15 max|K| |r|^2 (measured 1.3e-18)
    energy = np.einsum("ij,ij->j", R, K @ R)
    assert np.all(np.abs(energy) < 1e-14 * abs(K).max() * (R**2).sum(axis=0))
    # all five pass through the junctions: they lie in range(T)
    Q = admissible(model.T, R)
    assert Q.shape[1] == 5
    # likewise K Q is round-off: 6 eps |K| |Q| <= 6 x 2.2e-16 x 0.32 max|K| = 4e-16 max|K| (|Q| <=
    # 0.16; measured 2.4e-17)
    assert np.abs(model.K @ Q).max() < 5e-15 * abs(model.K).max()
    modes = natural_frequencies(model, "open", 7)
    assert np.count_nonzero(modes.frequencies_hz == 0) == 5
    # the shapes reported at 0 Hz really carry no strain energy, the next one does
    phi = modes.shapes
    energy = np.einsum("ij,ij->j", phi, K @ phi)  # = omega^2 for mass-normalized shapes
    # round-off: eps |phi|^T |K| |phi| = 2.2e-16 x 1.9e5 omega_6^2 = 4e-11 omega_6^2 (measured 1.5e-12
    # to 3.2e-12 over four kernels)
    assert np.all(np.abs(energy[:5]) < 1e-9 * energy[5])
    closed = natural_frequencies(model, "closed", 7)
    assert np.count_nonzero(closed.frequencies_hz == 0) == 5  # closing gaps keeps rigid motions


def test_unconnected_parts_each_have_rigid_motions():
    # a delamination over the whole free-free shaft leaves two separate beams: 10 rigid motions;
    # closing the gaps ties their W translation and rotation: 8 remain
    model = model_of("delamination.0.start=0.0", "delamination.0.end=1.0", 'shaft.supports="free-free"')
    f = natural_frequencies(model, "open", 12).frequencies_hz
    assert np.count_nonzero(f == 0) == 10 and f[10] > 10
    fc = natural_frequencies(model, "closed", 10).frequencies_hz
    assert np.count_nonzero(fc == 0) == 8 and fc[8] > 10
    # independent check: dense eigenvalues of the constrained pencil, 10 at round-off. A dense
    # symmetric eigensolver is good to about n eps lambda_max = 410 x 2.2e-16 = 9e-14 lambda_max
    # (measured 1e-17 to 2.6e-17); the first elastic one is (f_1 / f_max)^2 = 1.1e-8 of lambda_max
    w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True)
    assert np.all(np.abs(w[:10]) < 1e-12 * w[-1]) and w[10] > 1e-10 * w[-1]


def test_frequencies_do_not_depend_on_where_the_shaft_sits():
    # the same stack shifted 1000 m along x: segments use local coordinates
    from conftest import beam_tree

    from nsfem.scene import scene_from_tree

    base = beam_tree("pinned-pinned", elements=40)
    low = {"segment": [{"name": "s", "start": 1000.0, "end": 1001.0, "width": 0.03, "height": 0.01,
                        "E": 2.1e11, "rho": 7800.0}],
           "support": [{"segment": "s", "x": 1000.0, "fix": ["U", "V", "W"]},
                       {"segment": "s", "x": 1001.0, "fix": ["V", "W"]}],
           "mesh": {"elements": 40}, "reduction": {"method": "none"}}
    f0 = natural_frequencies(build_model(scene_from_tree(base)), "open", 4).frequencies_hz
    f1 = natural_frequencies(build_model(scene_from_tree(low)), "open", 4).frequencies_hz
    # the nodes at 1000 m are off by ulp(1000) = 1.1e-13 (4.5e-12 of an element; the element
    # matrices, closed form in h (fem/hermite.py), move by 3x that at most through h^-3); the
    # eigensolver adds eps x the componentwise condition of the Rayleigh quotient (1.3e6) = 2.9e-10.
    # Sum 3.1e-10. Measured 1.2e-11 to 1.7e-11 over the kernels
    assert np.allclose(f0, f1, rtol=1e-9)


@pytest.mark.parametrize("supports, rigid", [("pinned-pinned", 0), ("clamped-free", 0), ("free-free", 5)])
def test_supports_admit_the_right_rigid_motions(supports, rigid):
    model = model_of(f'shaft.supports="{supports}"', "mesh.elements=20")
    assert admissible(model.T, rigid_fields(model)).shape[1] == rigid


def test_constrained_matrices_symmetric_and_definite():
    model = model_of("mesh.elements=20")
    for A in (model.M, model.K):
        assert abs(A - A.T).max() == 0.0  # exactly symmetric (project() symmetrizes)
    sla.cholesky(model.M.toarray())  # M positive definite
    sla.cholesky(model.K.toarray())  # pinned-pinned, axial fixed: K positive definite
    free = model_of('shaft.supports="free-free"', "mesh.elements=20")
    w = np.linalg.eigvalsh(free.K.toarray())
    # psd with a five-dimensional null space: the smallest five at round-off of the largest,
    # n eps = 180 x 2.2e-16 = 4e-14 (measured 3.8e-17); the first elastic one at 9.2e-8 of it
    assert np.all(w[:5] < 1e-12 * w[-1]) and w[5] > 1e-8 * w[-1] and w[0] > -1e-12 * w[-1]


def test_junction_constraints_hold_exactly():
    model = model_of("mesh.elements=20")
    rng = np.random.default_rng(0)
    q = model.T @ rng.standard_normal(model.n)
    # a slave's row of T copies its master's (entries 1, or 1 and -z): a sparse product (no BLAS)
    # of values |q| <= 2.4 differs by at most 2 ulp = 9e-16 (measured 0)
    up, lo, m = "delamination_0_upper", "delamination_0_lower", "intact_0"
    for s, z in ((up, 0.0045), (lo, -0.0055)):
        for name in ("V", "V'", "W", "W'"):
            assert q[model.dof(s, name, 0.1)] == pytest.approx(q[model.dof(m, name, 0.1)], abs=1e-14)
        # U_s = U_m - z_s W_m' (design section 3)
        want = q[model.dof(m, "U", 0.1)] - z * q[model.dof(m, "W'", 0.1)]
        assert q[model.dof(s, "U", 0.1)] == pytest.approx(want, abs=1e-14)
    assert q[model.dof(m, "U", 0.0)] == 0.0 and q[model.dof(m, "W", 0.0)] == 0.0


def test_closed_contact_holds_gaps_at_zero():
    from nsfem.analysis.modes import contact_basis
    from nsfem.contact.kinematics import gap_jacobian

    model = model_of("mesh.elements=20")
    J, j = gap_jacobian(model)
    T = contact_basis(model, "closed")
    assert T.shape[1] == model.n - 9
    # entries +-1 against T's rows: sums of two products of size <= 1, <= 2 ulp (measured 0)
    assert abs(J.T @ T).max() < 1e-14


@pytest.mark.parametrize("points", [9, [0.2, 0.3, 0.7]])
def test_hat_weighting_averages_the_gap(points):
    # hats of unit integral on (a, b) peaking at c: a gap growing linearly in x averages to
    # the hat's centroid (a + b + c) / 3, the peak itself when the hat is symmetric
    from nsfem.contact.kinematics import gap_jacobian

    model = model_of("delamination.0.weighting=hat", f"delamination.0.contact_points={points}",
                     "mesh.elements=40")
    q = np.zeros(model.n_full)
    up = model.spaces["delamination_0_upper"]
    q[up.dofs["W"][up.bending.nodal_dofs[0]]] = up.x
    q[up.dofs["W"][up.bending.nodal_dofs[1]]] = 1.0
    J, _ = gap_jacobian(model)
    want = [sum(c.extent) / 3 + c.x / 3 for c in model.stack.contacts]
    # exact quadrature (the hat's kinks are nodes) of closed-form shape functions (fem/hermite.py):
    # a sum of about 20 terms of one sign, 20 eps = 4.4e-15 (measured 6.7e-16 on every kernel; the
    # Vandermonde-built scikit-fem shape functions gave 3e-14 to 4e-13, by kernel)
    assert np.allclose(J.T @ q, want, rtol=1e-14, atol=0.0)


@pytest.mark.parametrize("elements", [20, 40, 80])
def test_shipped_mesh_files_give_the_generated_model(elements):
    scene = load_scene(None, [f"mesh.elements={elements}"])
    generated = build_model(scene)
    from_file = build_model(load_scene(None, [f"mesh.file={MESHES / f'paper_stack_{elements}.msh'}"]))
    assert from_file.n == generated.n
    for name in ("M", "K", "T"):
        a, b = getattr(generated, name), getattr(from_file, name)
        # the file holds the generated coordinates to the last bit, so the same assembly follows
        # (measured 0); 1e-12 still flags any node moved by more than ~1e-12 of an element
        assert abs(a - b).max() <= 1e-12 * abs(a).max()


def test_mesh_roundtrip_with_nonuniform_nodes(tmp_path):
    stack = load_scene(None).stack
    mesh = generate(stack, 33)  # contact points force uneven spacing
    path = write(tmp_path / "m.msh", stack, mesh)
    back = read(path, stack)
    for name, x in mesh.nodes.items():
        assert np.array_equal(back.nodes[name], x)


def test_mesh_generation_places_required_nodes_and_counts_elements():
    stack = load_scene(None).stack
    for n in (12, 37, 200):
        mesh = generate(stack, n)
        assert mesh.elements == n
        for s in stack.segments:
            for x in stack.required_nodes(s.name):
                assert x in mesh.nodes[s.name]


def test_project_symmetric_and_skew():
    import scipy.sparse as sp

    rng = np.random.default_rng(1)
    A = sp.csr_matrix(rng.standard_normal((6, 6)))
    T = sp.csr_matrix(rng.standard_normal((6, 3)))
    S = project(T, A + A.T)
    W = project(T, A - A.T)
    assert abs(S - S.T).max() == 0 and abs(W + W.T).max() == 0


def test_slip_rows_vanish_for_rigid_and_bonded_motion_and_measure_sliding():
    from nsfem.contact.kinematics import slip_jacobian

    model = model_of("delamination.0.friction=0.3", 'shaft.supports="free-free"', "mesh.elements=20")
    S = slip_jacobian(model)
    assert S.shape[1] == 18  # 9 contacts x (s_x, s_y)
    R = rigid_fields(model)
    # rigid motions do not slide the faces: entries +-1 and h/2 against |R| <= 1, a few ulp (measured 0)
    assert np.abs(S.T @ R).max() < 1e-14
    # an intact-like bending field (U_s = -z_s W', W = sin) slides nothing either
    q = np.zeros(model.n_full)
    for s in model.stack.segments:
        sp_ = model.spaces[s.name]
        b = sp_.bending
        x = b.doflocs[0] + sp_.x[0]
        val = np.zeros(b.N, dtype=bool)
        val[b.nodal_dofs[0]] = True
        q[sp_.dofs["W"][val]] = np.sin(np.pi * x[val])
        q[sp_.dofs["W"][~val]] = np.pi * np.cos(np.pi * x[~val])
        q[sp_.dofs["U"]] = -s.offset[1] * np.pi * np.cos(np.pi * (sp_.axial.doflocs[0] + sp_.x[0]))
    # four terms each, |S|^T |q| <= 0.053: <= 4 eps x 0.053 = 5e-17 (measured 3.5e-18)
    assert np.abs(S.T @ q).max() < 1e-15
    # moving the upper layer by 1 mm along x slides every face by 1 mm in x, none in y: s_x holds
    # U_u with coefficient 1 (exact), s_y no U at all (exactly 0)
    q = np.zeros(model.n_full)
    q[model.spaces["delamination_0_upper"].dofs["U"]] = 1e-3
    s = S.T @ q
    assert np.allclose(s[0::2], 1e-3, rtol=1e-15, atol=0.0) and np.all(s[1::2] == 0.0)
