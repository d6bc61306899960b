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
    # strain energy of a unit rigid motion against that of a unit smooth bending field:
    # zero up to round-off (eps * |K| * |r|^2)
    energy = np.einsum("ij,ij->j", R, K @ R)
    assert np.all(np.abs(energy) < 1e-12 * abs(K).max() * (R**2).sum(axis=0))
    # all five pass through the junctions: they lie in range(T)
    Q = admissible(model.T, R)
    assert Q.shape[1] == 5
    assert np.abs(model.K @ Q).max() < 1e-9 * abs(model.K).max()
    modes = natural_frequencies(model, "open", 7)
    assert np.count_nonzero(modes.frequencies_hz == 0) == 5
    # the shapes reported at 0 Hz really carry no strain energy, the next one does
    phi = modes.shapes
    energy = np.einsum("ij,ij->j", phi, K @ phi)  # = omega^2 for mass-normalized shapes
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
    # independent check: dense eigenvalues of the constrained pencil, 10 at round-off
    w = sla.eigh(model.K.toarray(), model.M.toarray(), eigvals_only=True)
    assert np.all(np.abs(w[:10]) < 1e-14 * w[-1]) and w[10] > 1e-10 * w[-1]  # measured 1e-17, 1.1e-8


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
    assert np.allclose(f0, f1, rtol=1e-10)


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
    # psd with a five-dimensional null space: the smallest five at round-off of the largest
    assert np.all(w[:5] < 1e-10 * w[-1]) and w[5] > 1e-8 * w[-1] and w[0] > -1e-10 * w[-1]


def test_junction_constraints_hold_exactly():
    model = model_of("mesh.elements=20")
    rng = np.random.default_rng(0)
    q = model.T @ rng.standard_normal(model.n)
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
    assert np.allclose(J.T @ q, want, rtol=1e-12)


@pytest.mark.parametrize("elements", [20, 40, 80])
def test_shipped_mesh_files_give_the_generated_model(elements):
    scene = load_scene(None, [f"mesh.elements={elements}"])
    generated = build_model(scene)
    from_file = build_model(load_scene(None, [f"mesh.file={MESHES / f'paper_stack_{elements}.msh'}"]))
    assert from_file.n == generated.n
    for name in ("M", "K", "T"):
        a, b = getattr(generated, name), getattr(from_file, name)
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
    assert np.abs(S.T @ R).max() < 1e-14  # rigid motions do not slide the faces
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
    assert np.abs(S.T @ q).max() < 1e-14
    # moving the upper layer by 1 mm along x slides every face by 1 mm in x, none in y
    q = np.zeros(model.n_full)
    q[model.spaces["delamination_0_upper"].dofs["U"]] = 1e-3
    s = S.T @ q
    assert np.allclose(s[0::2], 1e-3) and np.allclose(s[1::2], 0.0)
