"""Rotating frame: operator properties, closed-form rotor results, loads, Campbell and CLI."""

from __future__ import annotations

import contextlib
import io
import json
import math

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from conftest import RHO, beam_tree

from nsfem import build_model, cli, load_scene, natural_frequencies
from nsfem.analysis.campbell import (
    campbell,
    divergence_bands,
    divergence_speeds,
    gravity_resonances,
    supercritical_warning,
)
from nsfem.analysis.modes import contact_basis
from nsfem.contact.kinematics import gap_jacobian
from nsfem.fem.rotating import rotor_operators
from nsfem.scene import scene_from_tree
from nsfem.system import linear_system


def uniform(width, height, elements=30, supports="pinned-pinned"):
    model = build_model(scene_from_tree(beam_tree(supports, width, height, elements)))
    return model, rotor_operators(model)


def test_operator_symmetries_survive_the_constraints():
    model = build_model(load_scene(None, ["mesh.elements=20"]))
    full = rotor_operators(model, basis=sp.identity(model.n_full, format="csr"))
    for ops in (full, rotor_operators(model), rotor_operators(model, contact_basis(model, "closed"))):
        assert abs(ops.G1 + ops.G1.T).max() == 0 and abs(ops.P1 + ops.P1.T).max() == 0  # skew
        for A in (ops.M, ops.K0, ops.Kc1, ops.De1):
            assert abs(A - A.T).max() == 0
        # negative (positive) semi-definite: eigvalsh is good to n eps ||A|| = 200 x 2.2e-16 x (<= 1.2
        # max|A|) = 5e-14 max|A| (measured <= 4.2e-16)
        w = np.linalg.eigvalsh(ops.Kc1.toarray())
        assert w.max() <= 1e-12 * abs(w).max()  # negative semi-definite (eq. 25)
        assert np.linalg.eigvalsh(ops.De1.toarray()).min() >= -1e-12 * abs(ops.De1).max()


def test_isotropic_shaft_frequencies_split_by_the_speed():
    # Euler-Bernoulli, square section: in the rotating frame the whirl pair sits exactly at
    # |f0 - Omega| and f0 + Omega (Kc1 = -lateral mass exactly, G couples V and W)
    model, ops = uniform(0.02, 0.02)
    f0 = natural_frequencies(model, "open", 2).frequencies_hz[0]
    speeds = [0.0, 7.0, 0.4 * f0, 1.3 * f0]
    res = campbell(ops, speeds, 2)
    # both sides carry eigensolver round-off, eps x the componentwise condition of the Rayleigh
    # quotient (4.1e5 here) = 9e-11 of f0 (measured 9e-12 to 1.1e-11 over four kernels)
    for s, f in zip(speeds, res.frequencies_hz):
        assert np.allclose(np.sort(f), np.sort([abs(f0 - s), f0 + s]), rtol=1e-9, atol=1e-9 * f0)
    # and gravity, a backward-rotating load in this frame, excites no resonance of it
    assert len(gravity_resonances(ops)[0]) == 0


def test_rectangular_shaft_gravity_resonance_and_divergence_band():
    model, ops = uniform(0.03, 0.01)
    modes = natural_frequencies(model, "open", 6)
    fw = [f for f, k in zip(modes.frequencies_hz, modes.fields) if k == "W"][0]
    fv = [f for f, k in zip(modes.frequencies_hz, modes.fields) if k == "V"][0]
    a, b = (2 * math.pi * fw) ** 2, (2 * math.pi * fv) ** 2
    # Omega^2 = a b / (2 (a + b)) (derived in nsfem.analysis.campbell): the first-mode pair
    # decouples exactly in the FE model (same shape functions in both planes)
    expect = math.sqrt(a * b / (2 * (a + b))) / (2 * math.pi)
    # round-off of the eigensolvers on both sides: eps x the componentwise condition of the Rayleigh
    # quotient (4.1e5) = 9e-11 (measured: resonance 4e-13 to 4e-12, divergence 1.5e-12 to 4.5e-12)
    speeds, excitation = gravity_resonances(ops)
    assert speeds[0] == pytest.approx(expect, rel=1e-9)
    assert excitation[0] > 0.1  # 0.80
    d = divergence_speeds(ops, 2)
    # Q = K0 + Omega^2 Kc1 is singular at the two bending frequencies (lateral mass only)
    assert d == pytest.approx([fw, fv], rel=1e-9)
    assert divergence_bands(d) == [(d[0], d[1])]
    # inside the band the rotor diverges: a real positive eigenvalue (132 1/s); outside, the roots of
    # the conservative gyroscopic system are imaginary, their round-off real parts (~eps omega_max)
    # far below campbell's resolution sqrt(eps) omega_max = 1.2e-2 1/s, below which it reports 0
    inside = campbell(ops, [0.5 * (fw + fv)], 2)
    outside = campbell(ops, [0.5 * fw], 2)
    assert inside.growth_per_s[0] > 1.0 and outside.growth_per_s[0] == 0.0
    assert supercritical_warning(0.5 * (fw + fv), d) and supercritical_warning(0.5 * fw, d) is None


def test_centrifugal_load_per_segment_and_it_opens_the_delamination():
    model = build_model(load_scene(None, ["mesh.elements=40"]))
    full = rotor_operators(model, basis=sp.identity(model.n_full, format="csr"))
    for s in model.stack.segments:
        W = model.spaces[s.name].dofs["W"]
        value = model.spaces[s.name].bending.nodal_dofs[0]
        ones = np.zeros(model.n_full)
        ones[W[value]] = 1.0  # the constant field W = 1 (slopes 0): sum of nodal loads
        # <= 33 nodal loads: 33 eps = 7e-15 (measured exact; the intact segments' offset is 0)
        assert ones @ full.fc1 == pytest.approx(s.rho * s.area * s.offset[1] * s.length, rel=1e-13, abs=1e-18)
    # static open response to the centrifugal load alone: the sub-beams move apart
    ops = rotor_operators(model)
    w = 2 * math.pi * 21.0
    q = spla.spsolve((ops.K0 + w**2 * ops.Kc1).tocsc(), w**2 * ops.fc1)
    J, j = gap_jacobian(model)
    gaps = J.T @ (model.T @ q) + j
    assert np.all(gaps > 0) and gaps[4] > gaps[0]  # largest at mid-delamination


def test_gravity_load_is_harmonic_in_the_rotating_frame():
    model, ops = uniform(0.02, 0.02)
    g, phase = 9.81, 30.0
    s = linear_system(ops, speed_hz=5.0, gravity=g, phase_deg=phase)
    w = 2 * math.pi * 5.0
    for t in (0.0, 0.013, 0.1):
        th = w * t + math.radians(phase)
        want = -g * math.sin(th) * ops.Fy - g * math.cos(th) * ops.Fz
        # load() forms sin(wt + phase) by the angle-sum formula: the angle's rounding (eps x 3.7 rad)
        # and a few roundings of the terms, times g: <= 2.2e-14 max|Fz| (measured 2.1e-15)
        assert np.allclose(s.load(t), want, rtol=0.0, atol=1e-13 * np.abs(ops.Fz).max())
    # not rotating: a constant load; in full coordinates its z-resultant is the weight rho A L g
    s0 = linear_system(ops, speed_hz=0.0, gravity=g)
    # f0 = (-g sin 0) Fy + (-g cos 0) Fz = -g Fz to the bit (adding -0.0 Fy is exact)
    assert s0.fc is None and s0.fs is None and np.array_equal(s0.f0, -g * ops.Fz)
    full = rotor_operators(model, basis=sp.identity(model.n_full, format="csr"))
    space = model.spaces["intact_0"]
    ones = np.zeros(model.n_full)
    ones[space.dofs["W"][space.bending.nodal_dofs[0]]] = 1.0
    # a sum of 31 nodal loads: 31 eps = 7e-15 (measured <= 2.2e-16)
    assert -g * full.Fz @ ones == pytest.approx(-g * RHO * 0.02 * 0.02 * 1.0, rel=1e-13)


def test_system_leaves_out_what_the_scene_does_not_need():
    _, ops = uniform(0.02, 0.02)
    s = linear_system(ops)
    assert s.C is None and s.f0 is None and s.fc is None and s.fs is None
    assert abs(s.Q - ops.K0).max() == 0
    s = linear_system(ops, speed_hz=3.0)  # rotation without gravity or damping
    assert s.C is not None and s.fc is None
    d = linear_system(ops, rayleigh=(2.0, 1e-4))  # damping without rotation
    assert abs(d.C - (2.0 * ops.M + 1e-4 * ops.K0)).max() == 0
    e = linear_system(ops, speed_hz=3.0, external=5.0)
    w = 2 * math.pi * 3.0
    # compare the skew part alone: it is small against K0, so a tolerance on Q would hide it. P1 and
    # G1 live in the V-W coupling blocks, where K0, Kc1 and De1 vanish: every entry is one product,
    # formed as here, so both sides agree to an ulp or two (measured exactly)
    skew = (e.Q - e.Q.T) / 2
    assert abs(skew - w * 5.0 * ops.P1).max() <= 1e-15 * abs(w * 5.0 * ops.P1).max()
    assert abs(e.C - (w * ops.G1 + 5.0 * ops.De1)).max() <= 1e-15 * abs(e.C).max()
    # the uniform shaft's centroid is on the axis: no centrifugal or drag load; the shipped scene's
    # sub-beams carry both: one product and one sum per entry, as in linear_system (measured exact)
    assert not np.any(e.f0)
    ops_d = rotor_operators(build_model(load_scene(None, ["mesh.elements=20"])))
    want = w**2 * ops_d.fc1 + w * 5.0 * ops_d.fd1
    f0_d = linear_system(ops_d, speed_hz=3.0, external=5.0).f0
    assert np.abs(want).max() > 0 and np.allclose(f0_d, want, rtol=0, atol=1e-15 * np.abs(want).max())


@pytest.mark.parametrize("contact", ["open", "closed"])
def test_campbell_at_rest_equals_modes(contact):
    model = build_model(load_scene(None, ["mesh.elements=20"]))
    ops = rotor_operators(model, contact_basis(model, contact))
    f = campbell(ops, [0.0], 5).frequencies_hz[0]
    # two eigensolvers' round-off: eps x the componentwise condition of the Rayleigh quotient (1.1e5)
    # = 2.5e-11 (measured 5e-13 to 2.1e-12 over four kernels)
    assert np.allclose(f, natural_frequencies(model, contact, 5).frequencies_hz, rtol=1e-9)


def test_gravity_resonance_scales_with_sqrt_E():
    # all stiffness scales with E: every resonance speed with sqrt(E)
    r1 = gravity_resonances(rotor_operators(build_model(load_scene(None, ["mesh.elements=20"]))))[0][0]
    r2 = gravity_resonances(rotor_operators(build_model(load_scene(None, ["mesh.elements=20",
                                                                          "shaft.E=1.05e11"]))))[0][0]
    # halving E halves K to the bit, but the eigensolvers' paths need not scale alike: round-off,
    # eps x the componentwise condition of the Rayleigh quotient (1.1e5) = 2.5e-11 (measured 8e-14
    # to 4e-13)
    assert r2 == pytest.approx(r1 * math.sqrt(0.5), rel=1e-9)


def test_campbell_cli_json_and_png(tmp_path):
    png = tmp_path / "c.png"
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = cli.main(["campbell", "--json", "--speeds", "0:30:7", "--count", "4", "--png", str(png),
                         "--set", "mesh.elements=20"])
    assert code == 0
    d = json.loads(buf.getvalue())
    for key in ("speeds_hz", "frequencies_hz", "gravity_resonances_hz", "instability_hz", "ndof_full", "ndof"):
        assert key in d
    assert len(d["frequencies_hz"]) == 7 and len(d["frequencies_hz"][0]) == 4
    assert set(d["gravity_resonances_hz"]) == {"open", "closed"}
    # the shipped scene's first gravity resonance, with E = 210 GPa and pinned supports: 22.7766,
    # quoted to 4 digits (half a unit of the last: 0.005)
    assert d["gravity_resonances_hz"]["open"][0] == pytest.approx(22.78, abs=0.005)
    assert png.stat().st_size > 10_000 and d["outputs"] == [str(png)]


def test_free_free_rotor_has_a_campbell_diagram():
    # no supports: K0 is singular; resonances and divergence speeds come from the QZ fallback
    from nsfem.analysis.campbell import campbell_report

    scene = load_scene(None, ['shaft.supports="free-free"', "mesh.elements=20"])
    rep = campbell_report(scene, build_model(scene), [0.0, 30.0], 8)
    f30 = np.array(rep["frequencies_hz"][1])
    # the four lateral rigid motions appear at the rotation frequency in the rotating frame:
    # tilts within 2e-4 (1.19e-4 low), since their inertia also holds the sub-beams' axial
    # (Steiner) part that the lateral centrifugal term does not see; the translations exactly.
    # They are a defective double root (uniform drift), which any eigen solver splits by
    # ~sqrt(eps) omega_max (2.4e-6 relative under one OpenBLAS kernel, 1.4e-6 under another);
    # campbell reports the split pair's mean (merge_defective), which is first-order accurate:
    # eps omega_max^2 / Omega = 2.2e-16 x 1.5e11 / 188 rad/s = 1.8e-7 rad/s, 1e-9 relative
    assert np.count_nonzero(np.abs(f30 - 30.0) < 2e-4 * 30.0) == 4
    assert np.count_nonzero(np.abs(f30 - 30.0) < 1e-8 * 30.0) == 2
    # a free rotor falls rigidly: gravity deforms it at no speed
    assert rep["gravity_resonances_hz"] == {"open": [], "closed": []}
    # divergence speeds of a free-free shaft are its natural frequencies but for the sub-beams'
    # axial inertia, which -Kc1 lacks (measured 2.2e-5)
    f0 = natural_frequencies(build_model(scene), "open", 7).frequencies_hz[5]
    assert rep["instability_hz"]["open"][0] == pytest.approx(f0, rel=1e-4)


@pytest.mark.parametrize("text", ["0:60", "a:b:c", "10:5:3", "0:60:0", "-1:5:3", "0:inf:3"])
def test_bad_speed_ranges_are_rejected(text, capsys):
    assert cli.main(["campbell", "--speeds", text]) == cli.EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--speeds" in err[0]


def test_external_damping_seen_from_the_rotating_frame():
    # an isotropic shaft with external (inertial) viscous damping only: the rotating-frame
    # eigenvalues are the inertial ones shifted by -+ i Omega (checks the signs of G1, P1, De1)
    _, ops = uniform(0.02, 0.02, elements=20)
    from nsfem.analysis.campbell import state_eigenvalues

    lam0 = state_eigenvalues(linear_system(ops, 0.0, external=40.0), 2)
    lam0 = lam0[lam0.imag > 0][:1]  # the first (degenerate) pair
    w = 2 * math.pi * 9.0
    lam = state_eigenvalues(linear_system(ops, 9.0, external=40.0), 4)
    want = np.concatenate([lam0 - 1j * w, lam0 + 1j * w])
    got = lam[np.argsort(np.abs(lam - lam0[0]))][:4]
    # eigensolver round-off on both sides: eps x the componentwise condition of the Rayleigh quotient
    # (8.3e4) = 1.8e-11 of |lam0| (measured 3e-12 to 4e-12 over four kernels)
    for x in want:
        assert np.min(np.abs(got - x)) < 1e-10 * abs(lam0[0]) or np.min(np.abs(got - x.conjugate())) < 1e-10 * abs(
            lam0[0])


def test_drag_load_per_segment():
    # inertial velocity of an offset centroid is Omega x r = Omega (0, -z_c, y_c): the drag
    # -c_e of it totals Omega c_e (z_c, -y_c) L on a segment; fd1 holds it per Omega c_e
    model = build_model(load_scene(None, ["mesh.elements=20"]))
    full = rotor_operators(model, basis=sp.identity(model.n_full, format="csr"))
    for s in model.stack.segments:
        space = model.spaces[s.name]
        for fld, want in (("V", s.offset[1]), ("W", -s.offset[0])):
            ones = np.zeros(model.n_full)
            ones[space.dofs[fld][space.bending.nodal_dofs[0]]] = 1.0
            # <= 17 nodal loads: 17 eps = 4e-15 relative (measured 8.7e-19 m on 3.6e-3)
            assert ones @ full.fd1 == pytest.approx(want * s.length, rel=1e-13, abs=1e-18)


def test_rayleigh_rigid_tilt_whirls_at_the_rotation_frequency():
    # free-free uniform Rayleigh shaft: with the rotary-inertia centrifugal term the rigid
    # motions sit at Omega in the rotating frame and nothing grows; without it the tilt grows
    # (3.8 /s). Two translations and one tilt stay at Omega; the other tilt is the spinning rod's
    # nutation, Omega I_p / I_d in the inertial frame, so Omega (1 - I_p / I_d) here, with
    # I_p / I_d = (b^2 + h^2) / (L^2 + h^2) = 8.0e-4 (rotary inertia). The rigid eigenvalues are
    # defective (uniform drift): round-off resolves them only to campbell's resolution sqrt(eps)
    # omega_max = 3.4e-3 1/s (omega_max = 2.3e5 rad/s), 1.8e-5 of Omega = 188 rad/s (measured within
    # 4e-8: 4e-5 allowed), and campbell reports growth below it as 0 (measured 0; 0.05 /s allowed)
    model = build_model(scene_from_tree(beam_tree("free-free", 0.02, 0.02, 20, theory="rayleigh")))
    ops = rotor_operators(model)
    res = campbell(ops, [30.0], 6)
    f = np.sort(res.frequencies_hz[0])
    nutation = 30.0 * (1 - (0.02**2 + 0.02**2) / (1.0**2 + 0.02**2))
    assert np.count_nonzero(np.abs(f - 30.0) < 4e-5 * 30) == 3
    assert f[0] == pytest.approx(nutation, rel=4e-5)
    assert abs(res.growth_per_s[0]) < 0.05
    from dataclasses import replace

    S = ops.Kc1 - rotor_operators(build_model(scene_from_tree(beam_tree("free-free", 0.02, 0.02, 20)))).Kc1
    assert abs(S).max() > 0  # the Rayleigh term is there
    without = campbell(replace(ops, Kc1=ops.Kc1 - S), [30.0], 6)
    assert without.growth_per_s[0] > 1.0


def test_speed_on_a_divergence_speed_and_heavy_damping_stay_sane():
    # a grid point exactly on a divergence speed makes Q singular: no spurious growth, and
    # the sparse solver agrees with the dense one; heavy stiffness-proportional damping makes
    # overdamped real roots that must not crowd out the oscillating modes
    from nsfem.analysis.campbell import _dense_state, frequencies_of, state_eigenvalues

    model = build_model(load_scene(None, ["mesh.elements=20"]))  # 175 dofs: dense is affordable
    ops = rotor_operators(model)
    d = divergence_speeds(ops, 2)
    for speed, beta in ((d[1], 0.0), (d[0], 0.0), (20.0, 1e-3)):
        sys_ = linear_system(ops, speed, rayleigh=(0.0, beta))
        sparse = frequencies_of(state_eigenvalues(sys_, 4), 4)
        C = sys_.C if sys_.C is not None else sp.csr_matrix(sys_.M.shape)
        dense = frequencies_of(_dense_state(sys_.M, C, sys_.Q), 4)
        # at a divergence speed a double root at 0 splits by ~sqrt(eps) x scale: 1e-4 Hz here
        assert np.allclose(sparse, dense, rtol=1e-6, atol=1e-3), (speed, sparse, dense)
        assert np.all(np.isfinite(sparse))
    # on a divergence speed the double root at 0 is defective: its round-off split (+-5e-4 to
    # +-1.4e-3 1/s, by BLAS kernel) and Arnoldi's errors in its edge roots (1.4e-3 1/s at 2748
    # rad/s) lie below the resolution sqrt(eps) omega_max = 5.8e-3 1/s of this 20-element
    # model, so campbell reports no growth there (growth_rate, merge_defective)
    for speed in d:
        assert campbell(ops, [speed], 4).growth_per_s[0] == 0.0


def test_reduced_campbell_matches_the_full_one():
    from nsfem.analysis.campbell import campbell_report
    from nsfem.reduce import reduce

    scene = load_scene(None)
    model = build_model(scene)
    full = campbell_report(scene, model, [0.0, 21.0, 50.0], 4)
    red = campbell_report(scene, model, [0.0, 21.0, 50.0], 4, reduce(model, "craig-bampton", 64))
    # Craig-Bampton truncation errors (64 modes; kernel-independent to 1e-12): measured 7.2e-7 and
    # 5.8e-7 open, 8.8e-10 and 7.6e-9 closed, frequencies 1.1e-6; bounds ~2.8x the largest
    for c in ("open", "closed"):
        assert red["instability_hz"][c] == pytest.approx(full["instability_hz"][c], rel=2e-6)
        assert red["gravity_resonances_hz"][c][:2] == pytest.approx(full["gravity_resonances_hz"][c][:2], rel=2e-6)
    assert np.allclose(red["frequencies_hz"], full["frequencies_hz"], rtol=3e-6)


def test_supercritical_warning_branches():
    d = [43.4, 48.0, 83.3, 98.9]
    assert supercritical_warning(40.0, d) is None
    assert "inside the divergence band" in supercritical_warning(45.0, d)
    assert "past a divergence band" in supercritical_warning(60.0, d)
    assert divergence_bands(np.array(d[:3]))[-1] == (83.3, math.inf)
