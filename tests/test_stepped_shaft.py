"""Stepped shafts (``[[shaft.step]]``): frequencies against a transfer-matrix solution and ROSS, static
deflection against the closed form, validation of the steps."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize
import scipy.sparse.linalg as spla

from nsfem.analysis.modes import natural_frequencies
from nsfem.errors import SceneError
from nsfem.fem import build_model
from nsfem.scene import scene_from_tree

E, RHO = 2.1e11, 7850.0


def stepped_tree(steps, supports="pinned-pinned", elements=50, theory="euler-bernoulli", length=1.0, D=0.05, **extra):
    tree = {"shaft": {"length": length, "section": "circle", "diameter": D, "E": E, "rho": RHO,
                      "supports": supports, "step": steps},
            "mesh": {"elements": elements}, "beam": {"theory": theory}, "reduction": {"method": "none"}}
    tree.update(extra)
    return tree


def lateral(modes, field="V"):
    return np.array([f for f, k in zip(modes.frequencies_hz, modes.fields) if k == field])


def transfer_matrix_frequency(pieces, guess_hz):
    """First pinned-pinned bending frequency of an Euler-Bernoulli beam of constant pieces (length, EI, rho A):
    the state (w, w', EI w'', (EI w'')') is carried through each piece by expm(A l), and the frequency is the root
    of the 2x2 determinant that leaves w = EI w'' = 0 at the far end for w = EI w'' = 0 at x = 0."""
    def det(f):
        w2 = (2 * math.pi * f) ** 2
        T = np.eye(4)
        for l, EI, mu in pieces:
            A = np.array([[0, 1, 0, 0], [0, 0, 1 / EI, 0], [0, 0, 0, 1], [mu * w2, 0, 0, 0]], float)
            T = scipy.linalg.expm(A * l) @ T
        return T[0, 1] * T[2, 3] - T[0, 3] * T[2, 1]
    return scipy.optimize.brentq(det, 0.7 * guess_hz, 1.3 * guess_hz, xtol=1e-12, rtol=1e-14)


def circle(D):
    return math.pi * D**4 / 64 * E, RHO * math.pi * D**2 / 4


def test_a_step_of_the_shafts_own_section_changes_nothing():
    # the same beam meshed at the same nodes, split into three segments joined rigidly: the frequencies agree to
    # round-off of the eigen solver (1e-12 relative on well separated pairs, 1e-9 leaves room for the pairs'
    # splitting of V and W)
    plain = natural_frequencies(build_model(scene_from_tree(stepped_tree([]))), count=8)
    stepped = natural_frequencies(build_model(scene_from_tree(
        stepped_tree([{"start": 0.3, "end": 0.7, "diameter": 0.05}]))), count=8)
    np.testing.assert_allclose(stepped.frequencies_hz, plain.frequencies_hz, rtol=1e-9)


def test_two_diameter_pinned_shaft_first_frequency_matches_the_transfer_matrix():
    # d = 0.05 m with a 0.08 m collar over [0.3, 0.7]; Hermite cubic elements with a consistent mass err by about
    # (beta h)^4 / 2880 on the first mode: (pi / 50)^4 / 2880 = 5e-9 at h = 0.02 m (the collar's stiffer piece
    # lowers beta), so 1e-6 is a margin of 100 over the discretization error and far above the root finder's 1e-14
    steps = [{"start": 0.3, "end": 0.7, "diameter": 0.08}]
    f = lateral(natural_frequencies(build_model(scene_from_tree(stepped_tree(steps))), count=6))[0]
    (EIa, mua), (EIb, mub) = circle(0.05), circle(0.08)
    ref = transfer_matrix_frequency([(0.3, EIa, mua), (0.4, EIb, mub), (0.3, EIa, mua)], f)
    assert f == pytest.approx(ref, rel=1e-6)
    # and it is not the uniform shaft's (the check can fail): the collar raises it by 11 %
    EI, mu = circle(0.05)
    assert f > 1.1 * math.pi / 2 * math.sqrt(EI / mu)


#: ROSS 2.3.0 (/work/rossvenv, `ross.Rotor` of 50 `ShaftElement(L=0.02, odl=0.05 or 0.08 over (0.3, 0.7),
#: shear_effects=False, rotary_inertia=True, gyroscopic=True)`, steel E = 2.1e11, rho = 7850, two
#: `BearingElement(kxx=kyy=1e7)` at the ends, `run_modal(speed=0, num_modes=12)`, `sorted(wn) / 2 pi`): the first
#: three pairs of natural frequencies [Hz] (a V and a W mode each; ROSS's own pairs differ by up to 1.0e-9).
ROSS_STEPPED_HZ = [89.57996910240365, 89.57996917017603, 250.15259256981153, 250.1525926427206,
                   544.029656911939, 544.0296580755867]


def test_stepped_rotor_on_bearings_matches_ross_with_shear_off():
    # both are Rayleigh beams with cubic Hermite elements on the same 50 nodes and the same consistent matrices:
    # they agree to the eigen solvers' round-off, which ROSS's split of each V/W pair (equal in exact arithmetic)
    # shows to be 1.0e-9 here; 3e-9 is that with a margin of 3
    tree = stepped_tree([{"start": 0.3, "end": 0.7, "diameter": 0.08}], supports="free-free", theory="rayleigh",
                        bearing=[{"x": 0.0, "kyy": 1e7, "kzz": 1e7}, {"x": 1.0, "kyy": 1e7, "kzz": 1e7},
                                 {"x": 0.0, "kxx": 1e7}])
    modes = natural_frequencies(build_model(scene_from_tree(tree)), count=12)
    f = np.sort(np.concatenate([lateral(modes, "V")[:3], lateral(modes, "W")[:3]]))
    np.testing.assert_allclose(f, ROSS_STEPPED_HZ, rtol=3e-9)


def test_stepped_cantilever_tip_deflection_matches_the_sum_of_segment_integrals():
    # tip load P on a clamped-free shaft of three pieces: delta = P sum_k [(L - a_k)^3 - (L - b_k)^3] / (3 EI_k).
    # Hermite cubics reproduce the Euler-Bernoulli static solution exactly at the nodes for point loads on
    # piecewise-constant EI, so only round-off is left (K's condition number ~ (L / h)^4 = 6e6 times 1e-16)
    steps = [{"start": 0.0, "end": 0.25, "diameter": 0.09, "inner_diameter": 0.02},
             {"start": 0.25, "end": 0.6, "diameter": 0.07}]
    model = build_model(scene_from_tree(stepped_tree(steps, supports="clamped-free", elements=50)))
    P = 1000.0
    f = np.zeros(model.n_full)
    last = model.stack.segments[-1]
    f[model.dof(last.name, "W", 1.0)] = P
    q = spla.spsolve(model.K.tocsc(), model.T.T @ f)
    w = (model.T @ q)[model.dof(last.name, "W", 1.0)]
    pieces = [(0.0, 0.25, math.pi / 64 * (0.09**4 - 0.02**4)), (0.25, 0.6, math.pi / 64 * 0.07**4),
              (0.6, 1.0, math.pi / 64 * 0.05**4)]
    ref = sum(P * ((1.0 - a) ** 3 - (1.0 - b) ** 3) / (3 * E * I) for a, b, I in pieces)
    assert w == pytest.approx(ref, rel=1e-9)


@pytest.mark.parametrize("steps, key, words", [
    ([{"start": -0.1, "end": 0.2, "diameter": 0.06}], "shaft.step.0.start", "outside the shaft"),
    ([{"start": 0.2, "end": 1.5, "diameter": 0.06}], "shaft.step.0.end", "beyond the shaft's end"),
    ([{"start": 0.5, "end": 0.4, "diameter": 0.06}], "shaft.step.0.end", "must exceed start"),
    ([{"start": 0.1, "end": 0.5, "diameter": 0.06}, {"start": 0.4, "end": 0.6, "diameter": 0.07}],
     "shaft.step.1.start", "overlaps step 0"),
    ([{"start": 0.1, "end": 0.5, "diameter": -0.06}], "shaft.step.0.diameter", "positive"),
    ([{"start": 0.1, "end": 0.5, "width": 0.06}], "shaft.step.0.width", "steps take diameter"),
    ([{"start": 0.1, "end": 0.5, "inner_diameter": 0.06}], "shaft.step.0.inner_diameter", "smaller than diameter"),
    ([{"start": 0.1, "end": 0.5, "diameter": 0.06, "length": 2}], "shaft.step.0.length", "unknown key"),
])
def test_bad_steps_are_refused_naming_the_key(steps, key, words):
    with pytest.raises(SceneError) as err:
        scene_from_tree(stepped_tree(steps))
    assert err.value.key == key and words in err.value.reason, str(err.value)


def test_steps_and_a_delamination_are_refused():
    tree = {"shaft": {"step": [{"start": 0.1, "end": 0.2, "height": 0.03}]},
            "delamination": [{"start": 0.4, "end": 0.6}]}
    with pytest.raises(SceneError, match="cannot carry a delamination"):
        scene_from_tree(tree)


def test_touching_steps_make_one_node_each_and_a_step_from_the_end():
    steps = [{"start": 0.0, "end": 0.2, "diameter": 0.06}, {"start": 0.2, "end": 0.5, "diameter": 0.07},
             {"start": 0.8, "end": 1.0, "diameter": 0.04}]
    stack = scene_from_tree(stepped_tree(steps)).stack
    assert [(s.start, s.end, s.width) for s in stack.segments] == [
        (0.0, 0.2, 0.06), (0.2, 0.5, 0.07), (0.5, 0.8, 0.05), (0.8, 1.0, 0.04)]
    assert [j.x for j in stack.junctions] == [0.2, 0.5, 0.8]
