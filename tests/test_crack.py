"""The breathing crack (issue 19): a hinge with the open crack's compliance whose faces are contacts.

References are independent of the FE model: the characteristic equation of an Euler-Bernoulli beam
with a rotational spring (a 8 x 8 determinant per root, bisected), the closed-form static deflection
of a hinged beam, the intact beam on the same mesh, and conservation of energy.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import nsfem
from nsfem.analysis.modes import natural_frequencies
from nsfem.analysis.stationary import scene_stationary
from nsfem.errors import SceneError
from nsfem.fem import build_model
from nsfem.simulate import run_scene

RECT = ("title = 'cracked bar'\n[shaft]\nlength = 1.0\nwidth = 0.02\nheight = 0.01\nsupports = '{supports}'\n"
        "[[crack]]\nx = {x}\ndepth = {depth}\nside = '{side}'\n[rotation]\ngravity = {g}\n")
CIRCLE = ("title = 'cracked shaft'\n[shaft]\nlength = 1.0\nsection = 'circle'\ndiameter = 0.02\n"
          "supports = 'pinned-pinned'\n[[crack]]\nx = 0.5\ndepth = {depth}\nside = '{side}'\n")


def scene(tmp_path, text, *overrides):
    p = tmp_path / "s.toml"
    p.write_text(text)
    return nsfem.load_scene(p, list(overrides))


# --- the characteristic equation of a beam with a rotational spring ------------------------------------

def _span(beta, s):
    """Rows (w, w', w'', w''') at local coordinate s of cos, sin, cosh, sinh (beta x)."""
    c, si, ch, sh = math.cos(beta * s), math.sin(beta * s), math.cosh(beta * s), math.sinh(beta * s)
    b = beta
    return np.array([[c, si, ch, sh], [-b * si, b * c, b * sh, b * ch], [-b * b * c, -b * b * si, b * b * ch, b * b * sh],
                     [b ** 3 * si, -b ** 3 * c, b ** 3 * sh, b ** 3 * ch]])


BC = {"pinned": (0, 2), "clamped": (0, 1), "free": (2, 3)}


def _determinant(beta, L, a, kappa, left, right):
    """det of the 8 x 8 system of two spans [0, a], [a, L] (local coordinates from each start) joined by a
    spring EI w'' = K (w2' - w1'), kappa = K / EI."""
    A0, Aa, B0, BL = _span(beta, 0.0), _span(beta, a), _span(beta, 0.0), _span(beta, L - a)
    rows = [np.r_[A0[i], np.zeros(4)] for i in BC[left]]
    rows += [np.r_[np.zeros(4), BL[i]] for i in BC[right]]
    rows += [np.r_[Aa[i], -B0[i]] for i in (0, 2, 3)]              # w, moment and shear continuous
    rows += [np.r_[Aa[2] + kappa * Aa[1], -kappa * B0[1]]]         # EI w1'' = K (w2' - w1')
    A = np.array(rows)
    return np.linalg.det(A / np.abs(A).max(axis=1, keepdims=True))


def spring_beam_frequencies(L, a, EI, rhoA, K, left, right, count):
    """The first ``count`` natural frequencies [Hz] (roots bracketed on a fine grid of beta, then brentq)."""
    kappa = K / EI
    grid = np.linspace(0.3, (count + 2) * math.pi / L, 4000)
    d = [_determinant(b, L, a, kappa, left, right) for b in grid]
    roots = [brentq(_determinant, grid[i], grid[i + 1], args=(L, a, kappa, left, right), xtol=1e-14)
             for i in range(len(grid) - 1) if d[i] * d[i + 1] < 0]
    return np.array(roots[:count]) ** 2 * math.sqrt(EI / rhoA) / (2 * math.pi)


# --- modes ------------------------------------------------------------------------------------------------

# Hermite cubics converge like (beta h)^4: at 100 elements on 1 m the third mode is off by ~1e-8
# (measured 1.2e-8 at 200 elements); 1e-6 leaves a factor 10-100 for the mesh and the eigensolver
@pytest.mark.parametrize("supports,ends", [("pinned-pinned", ("pinned", "pinned")), ("clamped-free", ("clamped", "free"))])
@pytest.mark.parametrize("side", ["-z", "+y"])
def test_open_crack_is_the_spring_beam(tmp_path, supports, ends, side):
    sc = scene(tmp_path, RECT.format(supports=supports, x=0.3, depth=0.4, side=side, g=0.0), "mesh.elements=100")
    seg, crack = sc.stack.segments[0], sc.stack.cracks[0]
    f = natural_frequencies(build_model(sc), "open", 8).frequencies_hz
    # W bends with E I_y about the slope W' (compliance[1]), V with E I_z about V' (compliance[0])
    for EI, c in ((seg.E * seg.I_y, crack.compliance[1]), (seg.E * seg.I_z, crack.compliance[0])):
        ref = spring_beam_frequencies(1.0, 0.3, EI, seg.rho * seg.area, 1.0 / c, *ends, 3)
        got = np.array([f[np.argmin(abs(f - r))] for r in ref])
        assert np.allclose(got, ref, rtol=1e-6, atol=0), (got, ref)
    # the crack matters: the spring softens the first bending mode by more than the tolerance
    intact = spring_beam_frequencies(1.0, 0.3, seg.E * seg.I_y, seg.rho * seg.area, 1e30, *ends, 1)
    assert f.min() < intact[0] * (1 - 1e-3)


def test_closed_crack_is_the_intact_beam(tmp_path):
    # the intact shaft on the same nodes: two segments joined rigidly at the crack's x
    low = ("title = 'intact'\n[[segment]]\nname = 'a'\nstart = 0.0\nend = 0.3\nwidth = 0.02\nheight = 0.01\n"
           "[[segment]]\nname = 'b'\nstart = 0.3\nend = 1.0\nwidth = 0.02\nheight = 0.01\n"
           "[[junction]]\nx = 0.3\nmaster = 'a'\nslaves = ['b']\n"
           "[[support]]\nsegment = 'a'\nx = 0.0\nfix = ['U', 'V', 'W']\n[[support]]\nsegment = 'b'\nx = 1.0\n"
           "fix = ['V', 'W']\n")
    cracked = scene(tmp_path, RECT.format(supports="pinned-pinned", x=0.3, depth=0.5, side="-z", g=0.0),
                    "mesh.elements=40")
    intact = nsfem.scene.scene_from_tree(__import__("tomllib").loads(low), ["mesh.elements=40"])
    assert [list(v) for v in build_model(cracked).mesh.nodes.values()][0] == \
        [list(v) for v in build_model(intact).mesh.nodes.values()][0]
    f_closed = natural_frequencies(build_model(cracked), "closed", 8).frequencies_hz
    f_intact = natural_frequencies(build_model(intact), "open", 8).frequencies_hz
    # the same matrices on the same coordinates up to the constraint basis: eigensolver round-off
    assert np.allclose(f_closed, f_intact, rtol=1e-9, atol=0)
    f_open = natural_frequencies(build_model(cracked), "open", 8).frequencies_hz
    assert f_open[0] < f_closed[0] * (1 - 1e-2)


@pytest.mark.parametrize("side", ["+y", "-z"])
def test_compliance_on_the_slope_the_crack_opens(tmp_path, side):
    # a rectangle's opening compliance is Rizos's 5.346 h J(a/h) / (E I) with h the side the crack runs into
    # (width for +-y, height for +-z) and I the second moment of that bending: on V' for +-y, on W' for +-z
    from nsfem.fem.crack import rizos_J

    sc = scene(tmp_path, RECT.format(supports="pinned-pinned", x=0.3, depth=0.4, side=side, g=0.0))
    seg, c = sc.stack.segments[0], sc.stack.cracks[0].compliance
    if side == "+y":
        assert c[0] == pytest.approx(5.346 * seg.width * rizos_J(0.4) / (seg.E * seg.I_z), rel=1e-12)
    else:
        assert c[1] == pytest.approx(5.346 * seg.height * rizos_J(0.4) / (seg.E * seg.I_y), rel=1e-12)


def test_circle_crack_opens_in_its_own_direction(tmp_path):
    # a circle is isotropic, the crack is not: its opening compliance exceeds the other one, so the
    # mode bending the crack open (W for a crack from -z) drops more
    sc = scene(tmp_path, CIRCLE.format(depth=0.4, side="-z"), "mesh.elements=60")
    c_v, c_w = sc.stack.cracks[0].compliance
    assert c_w > c_v > 0
    modes = natural_frequencies(build_model(sc), "open", 2)
    assert modes.fields[0] == "W" and modes.frequencies_hz[0] < modes.frequencies_hz[1]


# --- at rest under gravity ----------------------------------------------------------------------------------

@pytest.mark.parametrize("side,opens", [("-z", True), ("+z", False)])
def test_gravity_opens_the_tension_side(tmp_path, side, opens):
    # pinned-pinned under its weight: the bottom (-z) is in tension. Unreduced, so the static solution is
    # the FE one, whose nodal deflections are exact for a uniform load (Hermite cubics): a crack in the
    # middle adds the kink theta L / 4 with theta = c M, M = q L^2 / 8
    sc = scene(tmp_path, RECT.format(supports="pinned-pinned", x=0.5, depth=0.4, side=side, g=9.81),
               "mesh.elements=20", "reduction.method=none")
    st = scene_stationary(sc)
    model = build_model(sc)
    seg, crack = sc.stack.segments[0], sc.stack.cracks[0]
    q = seg.rho * seg.area * 9.81
    w = float((model.T @ st.q)[model.dof(seg.name, "W", 0.5)])
    bending = -5 * q / (384 * seg.E * seg.I_y)
    kink = -crack.compliance[1] * q / 8 * 0.25
    if opens:
        assert np.all(st.gap > 0) and np.all(st.normal_force == 0)
        assert w == pytest.approx(bending + kink, rel=1e-9)
    else:
        assert np.allclose(st.gap, 0, atol=1e-15) and st.normal_force.sum() > 0
        assert w == pytest.approx(bending, rel=1e-9)
        # the faces carry the bending moment: M = lam (z_arm) summed, the moment at midspan q L^2 / 8
        arms = np.array([c.arm[1] for c in sc.stack.contacts if c.kind == "crack"])
        assert abs(float(st.normal_force @ arms)) == pytest.approx(q / 8, rel=1e-9)


# --- rotating: breathing, energy ------------------------------------------------------------------------------

BREATHING = CIRCLE + "[rotation]\nspeed_hz = 5.0\n[damping]\nrayleigh = [20.0, 0.0]\n[simulation]\nt_end = 1.0\n" \
    "output_dt = 1e-3\n[output]\nvtu_every = 0\nplots = []\n"


def test_rotating_crack_breathes_once_per_revolution(tmp_path):
    # 5 Hz, far below the first critical speed (41 Hz): quasi-static breathing. The crack at -z in the
    # rotating frame is at the bottom (tension) at whole revolutions: open around them, closed around
    # half revolutions; the damped start-up transient (alpha = 20/s) is gone after 0.4 s
    sc = scene(tmp_path, BREATHING.format(depth=0.4, side="-z"), "mesh.elements=20")
    res, _ = run_scene(sc)
    keep = res.t > 0.4
    t, opened = res.t[keep], (res.gap[:, keep] > 0).any(axis=0)
    turns = t[1:][np.diff(opened.astype(int)) != 0]
    assert len(turns) == 6                                   # 3 revolutions: open and close once each
    phase = (turns * 5.0 + 0.5) % 1.0 - 0.5                  # revolutions from the bottom position
    starts, ends = phase[~opened[np.searchsorted(t, turns) - 1]], phase[opened[np.searchsorted(t, turns) - 1]]
    # symmetric about the bottom (the crack's two front ends open in turn), to the output step 1e-3 s
    # = 0.005 revolutions and the quasi-static lag
    assert np.allclose(starts, -ends, atol=0.02)
    # quasi-statically the crack is fully closed while the moment lies in the cone of the front ends' arms
    # (half-angle alpha about the closing direction, docs/theory.md): open from -(pi - alpha) to pi - alpha
    y, z = sc.stack.contacts[0].arm
    alpha = math.atan2(abs(y), abs(z))
    assert ends.mean() == pytest.approx((math.pi - alpha) / (2 * math.pi), abs=0.01)
    assert res.energy["relative_residual"] < 1e-9


def test_elastic_impacts_keep_the_energy(tmp_path):
    # restitution 1, no damping: the start from rest makes the faces clatter (some 470 impacts in the first
    # 5 ms); each impact LCP keeps the kinetic energy to its solution's accuracy (~1e-12 relative), the
    # closed-form propagation in between to round-off
    sc = scene(tmp_path, BREATHING.format(depth=0.4, side="-z"), "mesh.elements=20", "crack.0.restitution=1",
               "damping.rayleigh=[0, 0]", "simulation.t_end=0.01", "simulation.output_dt=1e-4")
    res, _ = run_scene(sc)
    assert len(res.impacts) > 50 and not any(i["plastic"] for i in res.impacts)
    assert res.energy["relative_residual"] < 1e-9
    ke = np.array([(i["kinetic_before_J"], i["kinetic_after_J"]) for i in res.impacts])
    assert np.allclose(ke[:, 1], ke[:, 0], rtol=1e-9, atol=1e-12 * ke.max())
    # the faces never interpenetrate beyond round-off of the opening (~1e-7 m)
    assert res.gap.min() > -1e-15


@pytest.mark.parametrize("method,tol", [
    ("rk", 1e-6),          # the same events, DOP853 at rtol 1e-8 between them: ~1e-8 measured
    ("moreau", 1e-2),      # first order in its step (output_dt / 10 = 1e-4 s): 7e-4 measured
    pytest.param("penalty", 1e-2, marks=pytest.mark.slow),   # c_p 100x the contact stiffness: 8e-4 measured
])
def test_every_method_breathes_alike(tmp_path, method, tol):
    sc = scene(tmp_path, BREATHING.format(depth=0.4, side="-z"), "mesh.elements=20", "simulation.t_end=0.1")
    ref, _ = run_scene(sc, "exact")
    res, _ = run_scene(sc, method)
    assert np.abs(res.q - ref.q).max() <= tol * np.abs(ref.q).max()
    # the crack opens and closes in both at the same samples but for the few at a transition
    assert np.mean((res.gap > 1e-12).any(axis=0) != (ref.gap > 1e-12).any(axis=0)) < 0.02


# --- bad inputs -----------------------------------------------------------------------------------------------

@pytest.mark.parametrize("override,key", [
    ("crack.0.depth=0.9", "crack.0.depth"),
    ("crack.0.depth=0.6", "crack.0.depth"),     # a circle: beyond 0.5 the strips are cut through
    ("crack.0.friction=0.3", "crack.0.friction"),
    ("crack.0.x=1.0", "crack.0.x"),
    ("crack.0.side=x", "crack.0.side"),
    ("shaft.inner_diameter=0.01", "crack.0.depth"),
    ("rotation.frame=inertial", "rotation.frame"),
])
def test_bad_crack_inputs_are_one_line(tmp_path, override, key):
    with pytest.raises(SceneError) as info:
        scene(tmp_path, CIRCLE.format(depth=0.4, side="-z"), override)
    assert str(info.value).startswith(key) and "\n" not in str(info.value)


def test_crack_in_a_delamination_is_refused():
    with pytest.raises(SceneError, match="crack.0.x: x=0.5 lies where two layers"):
        nsfem.load_scene(None, ["crack.0.x=0.5"])
    with pytest.raises(SceneError, match="crack.0.x: x=0.1 is where segments meet"):
        nsfem.load_scene(None, ["crack.0.x=0.1"])
