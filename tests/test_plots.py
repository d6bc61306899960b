"""Result plots (nsfem.plot.results): files written off-screen and atomically, and the numbers behind them."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from nsfem import load_scene
from nsfem.analysis.modes import natural_frequencies
from nsfem.errors import NsfemError
from nsfem.integrate import ContactSystem
from nsfem.plot import results as rp
from nsfem.result import Result
from nsfem.simulate import run_scene

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def run():
    return run_scene(load_scene(None, ["simulation.t_end=0.3"]))


def assert_png(path, min_bytes=10_000):
    assert path.exists()
    assert path.read_bytes()[:8] == PNG
    assert path.stat().st_size > min_bytes


@pytest.mark.parametrize("name", rp.RESULT_PLOTS)
def test_each_plot_is_written_without_display(run, tmp_path, name):
    result, system = run
    out = rp.PLOT_FUNCTIONS[name](result, system, tmp_path / "sub" / f"{name}.png")
    assert out == tmp_path / "sub" / f"{name}.png"
    assert_png(out)
    assert [p.name for p in out.parent.iterdir()] == [f"{name}.png"]  # no temporary file left


def test_write_plots_selects_and_skips_campbell(run, tmp_path):
    result, system = run
    warned = []
    paths = rp.write_plots(result, system, tmp_path, ["gap", "campbell", "phase", "gap"], warn=warned.append)
    assert [p.name for p in paths] == ["gap.png", "phase.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gap.png", "phase.png"]
    assert warned == []
    with pytest.raises(NsfemError, match="unknown plot"):
        rp.write_plots(result, system, tmp_path, ["phase", "bode"])


def test_modal_basis_is_the_open_non_rotating_one(run):
    result, system = run
    f, Phi = rp.modal_basis(system)
    M = system.M
    # M-orthonormality of the dense generalized eigenvectors: ~n eps cond(M) = 25 x 2.2e-16 x 31 =
    # 1.7e-13 (measured 2e-15 to 3.1e-15)
    assert np.allclose(Phi.T @ M @ Phi, np.eye(system.n), rtol=0.0, atol=1e-12)
    model = system.info["model"]
    # the reduced model's lowest modes are those of the full finite-element model (non-rotating),
    # up to the Craig-Bampton truncation error of the shipped scene (3.5e-5, test_reduce)
    ref = natural_frequencies(model, "open", 3).frequencies_hz
    assert np.allclose(f[:3], ref, rtol=1e-4)
    # ... and not those of the rotating system's Q (centrifugal softening at 21 Hz: 5.4 Hz apart)
    fq = np.sqrt(np.abs(np.linalg.eigvals(np.linalg.solve(M, system.Q)))) / (2 * np.pi)
    assert abs(np.sort(fq)[0] - f[0]) > 1.0


def test_modal_coordinates_reconstruct_the_motion(run):
    result, system = run
    f, eta, deta = rp.modal_coordinates(result, system)
    _, Phi = rp.modal_basis(system)
    assert eta.shape == result.q.shape == deta.shape
    scale = np.abs(result.q).max()
    # q -> Phi^T M q -> Phi eta: sums of 25 terms, 25 eps |Phi| |Phi^T M| |q| <= 25 x 2.2e-16 x 4.6
    # max|q| = 2.5e-14 max|q|, plus Phi Phi^T M = I to ~1.7e-13 (above). Measured 1.3e-15 to 2.2e-15
    assert np.abs(Phi @ eta - result.q).max() < 1e-12 * scale
    assert np.abs(Phi @ deta - result.v).max() < 1e-12 * np.abs(result.v).max()
    # the first three modes carry the vibration (as in the paper's fig. 3a)
    rms = eta.std(axis=1)
    assert set(np.argsort(rms)[-3:]) == {0, 1, 2}  # the fourth has 0.14 of the largest rms


def test_welch_peak_and_power_of_a_pure_harmonic():
    dt, f0, amp = 1e-3, 21.0, 2e-4
    t = np.arange(0.0, 2.0, dt)
    f, P = rp.welch_psd(amp * np.sin(2 * np.pi * f0 * t) + 1e-3, dt)  # offset removed
    df = f[1] - f[0]
    assert abs(f[np.argmax(P)] - f0) <= df  # the bin spacing (1 Hz; 21 Hz lies on a bin: measured 0)
    # 1 s segments hold 21 whole periods: the Hann-windowed, density-scaled PSD sums to the
    # variance exactly, and leaks nothing into the DC bin, but for the FFT's round-off (eps log2 N
    # relative; measured 1.7e-15 and 2.5e-32): the DC bin is at most (4 eps log2 N)^2 = 1e-27 of the
    # peak (a DC error of eps log2 N x N amp against the peak's N amp / 4)
    assert np.sum(P) * df == pytest.approx(amp**2 / 2, rel=1e-12)  # Parseval: variance
    assert P[0] < 1e-24 * P.max()


def test_psd_point_lies_in_an_undamaged_region(run):
    _, system = run
    model = system.info["model"]
    pt = rp.measurement_point(model)
    assert pt["undamaged"] and pt["segment"] == "intact_0"
    assert 0.0 < pt["x"] < 0.1  # outside the delamination (0.1, 0.9), off the support
    assert pt["dof"] == model.dof("intact_0", "W", pt["x"])
    assert np.abs(system.info["reduction"].T[pt["dof"]]).max() > 0  # a free dof, not a support
    right = rp.measurement_point(model, x=0.95)
    # snapped to the nearest node: within half the 25 mm node spacing
    assert right["segment"] == "intact_1" and right["x"] == pytest.approx(0.95, abs=0.0125)


def test_gap_plot_uses_the_midspan_contact(run):
    result, system = run
    (g,) = rp.delamination_middles(system)
    assert g["name"] == "delamination.0" and g["span"] == (0.1, 0.9)
    assert g["x"] == pytest.approx(0.5, abs=1e-15)  # contact positions: a linspace over the span, ulps
    assert system.contacts.labels[g["middle"]] == "delamination.0.4"
    assert g["indices"] == list(range(system.contacts.m))


def test_closed_intervals_from_events_and_from_states(run):
    result, _ = run
    k = 4
    spans = rp.closed_intervals(result, k)
    assert spans and all(a <= b for a, b in spans)
    closes = [e["t"] for e in result.events if k in e["after"]["closed"]]
    assert spans[0][0] in closes
    # without events, the sampled states give the intervals
    t = np.linspace(0.0, 1.0, 11)
    state = np.zeros((1, 11), int)
    state[0, 2:4] = 1
    state[0, 9:] = 2
    r = Result("moreau", t, np.zeros((1, 11)), np.zeros((1, 11)), np.zeros((1, 11)), np.zeros((1, 11)),
               np.zeros((1, 2, 11)), state)
    # the times are a linspace: 0.3 is 0.30000000000000004 there (a few ulps at most)
    assert rp.closed_intervals(r, 0) == [(0.2, pytest.approx(0.3, abs=1e-15)), (pytest.approx(0.9, abs=1e-15), 1.0)]


def test_loaded_contacts_are_those_with_force_or_impulse(run):
    result, _ = run
    rows = rp.loaded_contacts(result)
    hit = {k for im in result.impacts for k in im["contacts"]}
    assert hit <= set(rows)
    for k in set(range(result.gap.shape[0])) - set(rows):
        assert not result.normal_force[k].any()


def test_plots_without_data_are_skipped_with_a_reason(tmp_path):
    # two uncoupled oscillators (1 and 3 Hz), no contacts, no finite-element model
    w = 2 * np.pi * np.array([1.0, 3.0])
    system = ContactSystem.from_arrays(M=np.eye(2), Q=np.diag(w**2))
    t = np.linspace(0.0, 2.0, 201)
    q = np.vstack([np.cos(w[0] * t), 0.1 * np.sin(w[1] * t)])
    v = np.vstack([-w[0] * np.sin(w[0] * t), 0.1 * w[1] * np.cos(w[1] * t)])
    empty = np.zeros((0, t.size))
    r = Result("exact", t, q, v, empty, empty, np.zeros((0, 2, t.size)), empty.astype(int), t_end=2.0)
    warned = []
    paths = rp.write_plots(r, system, tmp_path, list(rp.RESULT_PLOTS), warn=warned.append)
    assert [p.name for p in paths] == ["phase.png"]
    assert_png(paths[0])
    assert len(warned) == 3 and all("skipped" in m for m in warned)
    assert any("gap" in m and "no contacts" in m for m in warned)
    assert any("psd" in m and "model" in m for m in warned)
    f, eta, _ = rp.modal_coordinates(r, system)  # no model: the symmetric part of Q
    # diagonal K and M = I: eigenvalues, sqrt and scaling to a few ulps; Phi = I up to signs, so
    # eta = q (|q| <= 1; measured exact)
    assert np.allclose(f, [1.0, 3.0], rtol=1e-14, atol=0.0)
    assert np.allclose(np.abs(eta), np.abs(q), rtol=0.0, atol=1e-14)
    with pytest.warns(UserWarning, match="forces.*no contacts"):
        assert rp.write_plots(r, system, tmp_path, ["forces"]) == []


def test_a_failed_write_keeps_the_old_file(run, tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    result, system = run
    path = rp.psd_plot(result, system, tmp_path / "psd.png")
    before = path.read_bytes()

    def broken(self, fname, *args, **kwargs):
        with open(fname, "wb") as fh:
            fh.write(b"partial")
        raise OSError("disk full")

    monkeypatch.setattr(Figure, "savefig", broken)
    with pytest.raises(OSError, match="disk full"):
        rp.psd_plot(result, system, path)
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["psd.png"]


def test_hermite_refine_draws_a_harmonic_between_samples():
    from nsfem.plot.results import hermite_refine

    f = 83.0
    w = 2 * np.pi * f
    t = np.arange(0.0, 0.05, 1e-3)          # 12 samples per period: a 12-gon when joined by chords
    x, dx = hermite_refine(t, np.cos(w * t), -w * np.sin(w * t), f)
    assert x.size > 3 * t.size               # 48 points per period
    # on the circle x^2 + (x'/w)^2 = 1 to the interpolant's accuracy: (w h)^4 / 384 = 2e-4 for the value,
    # (w h)^3 / 72 = 2e-3 for the slope; a chord's midpoint sits 1 - cos(pi / 12) = 3.4e-2 inside
    r = np.hypot(x, dx / w)
    assert np.max(np.abs(r - 1)) < 3e-3
    # an impact between two samples keeps that interval a chord (no loop across the jump)
    x2, _ = hermite_refine(t, np.cos(w * t), -w * np.sin(w * t), f, kicks=[0.0105])
    assert x2.size == x.size - (x.size - t.size) // (t.size - 1)


def test_plots_of_a_scene_whose_only_contacts_are_a_crack(tmp_path):
    """A crack's two front ends are one group crack.0 (the gap plot's panel of its opening, the forces plot's
    line of the faces' force), and every plot is written for a scene with no other contact."""
    from nsfem.scene.load import scene_from_tree

    from test_vtu_crack import cracked_tree

    result, system = run_scene(scene_from_tree(cracked_tree()))
    (g,) = rp.delamination_middles(system)
    assert (g["name"], g["kind"], g["indices"], g["span"]) == ("crack.0", "crack", [0, 1], (0.5, 0.5))
    assert rp._force_series(system, rp.loaded_contacts(result)) == [("crack.0 (x = 0.5 m)", [0, 1])]
    # both ends closed lies within one end closed; the run has both (test_vtu_crack)
    both, one = rp.closed_intervals(result, [0, 1]), rp.closed_intervals(result, [0, 1], every=False)
    assert both and len(one) >= 1 and sum(b - a for a, b in both) < sum(b - a for a, b in one)
    assert all(any(c <= a and b <= d for c, d in one) for a, b in both)
    warned = []
    paths = rp.write_plots(result, system, tmp_path, list(rp.RESULT_PLOTS), warn=warned.append)
    assert [p.name for p in paths] == [f"{n}.png" for n in rp.RESULT_PLOTS] and warned == []
    for p in paths:
        assert_png(p)


# --- issue 34: one definition of each count and maximum; plots per contact kind ---------------------------
#: a pinned-pinned shaft dropped under its weight on a stop 50 um below its middle: with restitution 1 and no
#: damping it bounces without ever resting on it in 0.04 s (impacts only, no sustained force)
STOP_TOML = """
title = "bouncing on a stop"
[shaft]
length = 1.0
width = 0.02
height = 0.02
E = 2.1e11
rho = 7500.0
supports = "pinned-pinned"
[[obstacle]]
x = 0.5
normal = "-z"
clearance = 5e-5
restitution = 1.0
[rotation]
speed_hz = 0.0
gravity = 9.81
[mesh]
elements = 20
[reduction]
method = "craig-bampton"
modes = 4
[simulation]
t_end = 0.04
output_dt = 1e-3
"""


def stop_tree() -> dict:
    import tomllib

    return tomllib.loads(STOP_TOML)


def figure_text(monkeypatch, module, draw) -> tuple[str, object]:
    """Every text of the figure ``draw()`` makes through ``module.save`` (titles, legends, suptitle), and the figure."""
    from matplotlib.text import Text

    seen = []

    def grab(fig, path):
        seen.append(fig)
        return path

    monkeypatch.setattr(module, "save", grab)
    draw()
    (fig,) = seen
    return " | ".join(t.get_text() for t in fig.findobj(Text)), fig


def struck(result, rows) -> int:
    """The impact records in which one of ``rows`` takes a positive impulse, counted here without the tally."""
    return sum(any(int(c) in rows and p > 0 for c, p in zip(im["contacts"], im["impulse_Ns"]))
               for im in result.impacts)


@pytest.fixture(scope="module")
def kinds():
    """One short run per kind of contact part: a delamination (the shipped scene, 0.3 s), a crack, a ring (rub,
    0.1 s: the impacts that bring the rotor onto the ring) and a stop (impacts only)."""
    from nsfem.scene.load import scene_from_tree

    from test_vtu_crack import cracked_tree

    return {"delamination": run_scene(load_scene(None, ["simulation.t_end=0.3"])),
            "crack": run_scene(scene_from_tree(cracked_tree())),
            "ring": run_scene(load_scene("rub", ["simulation.t_end=0.1"])),
            "stop": run_scene(scene_from_tree(stop_tree()))}


@pytest.mark.parametrize("kind", ["delamination", "crack", "ring", "stop"])
def test_counts_agree_between_summary_json_and_plots(kinds, kind, monkeypatch, tmp_path):
    """The run JSON's counts (impacts per run and per part, each part's largest resultant force and impulse)
    are the ones gap.png and forces.png print and draw, and an impact is counted once per record however
    many of the part's points it strikes."""
    import json

    from nsfem.jsonio import dumps
    from nsfem.plot import forces as forces_module
    from nsfem.plot import gap as gap_module

    result, system = kinds[kind]
    summary = json.loads(dumps(result.summary()))     # what the JSON carries
    (part,) = summary["parts"]
    rows = rp.delamination_middles(system)[0]["indices"]
    assert part["kind"] == kind and part["contacts"] == len(rows)
    assert summary["impacts"] == part["impacts"] == struck(result, set(rows)) > 0
    text, fig = figure_text(monkeypatch, gap_module, lambda: rp.gap_plot(result, system, tmp_path / "gap.png"))
    assert f"impacts ({part['impacts']}, largest {part['max_impulse_Ns']:.3g} N s)" in text
    title = {"delamination": "Gap at the middle of the delamination", "crack": "Crack opening",
             "ring": "Stator ring clearance", "stop": "Gap at the stop"}[kind]
    assert fig._suptitle.get_text() == title
    marks = [ln for ln in fig.axes[0].get_lines() if ln.get_marker() == "v"]
    assert len(marks) == 1 and len(marks[0].get_xdata()) == part["impacts"]
    text, fig = figure_text(monkeypatch, forces_module,
                            lambda: rp.forces_plot(result, system, tmp_path / "forces.png"))
    assert f"Impacts: {summary['impacts']}, largest impulse {part['max_impulse_Ns']:.3g} N s" in text
    assert f"{part['name']}: {part['impacts']} impacts" in text
    if part["max_normal_force_N"] > 0:
        assert f"{part['name']}: max {part['max_normal_force_N']:.4g} N" in text
    else:
        assert f"{part['name']}: no force (impacts only)" in text
    assert "lam_T" not in text
    # a part's force is its points' resultant, at least the largest point's and at most their sum
    # (equal for parallel normals; a ring's facets add as vectors); summation round-off: len(rows) eps
    top = result.normal_force[rows]
    slack = len(rows) * np.finfo(float).eps * top.sum(axis=0).max(initial=0.0)
    assert top.max(initial=0.0) - slack <= part["max_normal_force_N"] <= top.sum(axis=0).max(initial=0.0) + slack
    assert part["max_point_force_N"] == summary["max_normal_force_N"] == top.max(initial=0.0)
    if kind != "ring":
        assert part["max_normal_force_N"] == pytest.approx(top.sum(axis=0).max(initial=0.0), rel=2 * slack + 1e-300,
                                                           abs=slack)


def test_a_rings_resultant_is_the_vector_sum_of_its_facet_forces(kinds):
    """The ring's force at each output time is sum_k lambda_k n_k over its facets, n_k = (cos, sin) of the facet's
    normal angle in the model; its angle is that vector's."""
    from nsfem.contact.tally import system_parts, tally

    result, system = kinds["ring"]
    (part,) = system_parts(system)
    contacts = system.info["model"].stack.contacts
    a = np.array([contacts[k].angle for k in part.rows])
    lam = result.normal_force[list(part.rows)]
    vec = np.stack([np.cos(a) @ lam, np.sin(a) @ lam])
    (pt,) = tally(result).parts
    # summation round-off over 64 facets: 64 eps of the largest facet force
    tol = 64 * np.finfo(float).eps * lam.max()
    np.testing.assert_allclose(pt.force, np.hypot(*vec), rtol=0, atol=tol)
    on = pt.force > 1e3 * tol
    assert on.any()
    np.testing.assert_allclose(np.exp(1j * pt.angle[on]), np.exp(1j * np.arctan2(vec[1], vec[0])[on]), atol=1e-9)


def test_ring_resultant_of_facets_in_closed_form():
    """Hand cases: 3 N on the facet at 0 and 4 N on the one at 90 degrees make 5 N at atan(4/3); equal forces
    on opposite facets cancel; the impulses resolve the same way."""
    from nsfem.contact.tally import Part, resultant, tally

    part = Part("stator.0", "ring", (0, 1, 2, 3), tuple(np.pi / 2 * np.arange(4)))
    normal = np.array([[3.0, 2.0], [4.0, 0.0], [0.0, 2.0], [0.0, 0.0]])
    mag, _, angle = resultant(part, normal)
    np.testing.assert_allclose(mag, [5.0, 0.0], atol=1e-15)       # cos(pi) = -1 exactly; sin(pi) = 1.2e-16
    assert angle[0] == pytest.approx(np.arctan2(4.0, 3.0), abs=1e-15)
    t = np.array([0.0, 1.0])
    r = Result("exact", t, np.zeros((1, 2)), np.zeros((1, 2)), np.ones((4, 2)), normal, np.zeros((4, 2, 2)),
               np.zeros((4, 2), int), impacts=[{"t": 0.5, "contacts": [0, 1], "impulse_Ns": [0.3, 0.4]},
                                               {"t": 0.7, "contacts": [3], "impulse_Ns": [0.0]}],
               info={"parts": [part.record()]})
    (pt,) = tally(r).parts
    # one impact (the record without an impulse is none), its resultant 0.5 N s; 0.4 N s at one point
    assert (pt.impacts, pt.max_impulse_Ns, r.summary()["max_impulse_Ns"]) == (1, pytest.approx(0.5, abs=1e-16), 0.4)
    assert r.summary()["impacts"] == 1 and pt.max_normal_force_N == 5.0 and pt.max_point_force_N == 4.0


def test_zoom_on_the_last_revolutions_of_long_runs_only():
    """gap.png zooms on the last 3 revolutions of a run of more than 30 (the crack scene's 3 s at 12.4 Hz: 37),
    not of the shipped scene's 21 revolutions; the window ends at the last output."""
    from nsfem.plot.gap import zoom_window

    t = np.linspace(0.0, 3.0, 6001)
    start, revolutions = zoom_window(t, 12.4)
    assert revolutions == 3 and start == pytest.approx(3.0 - 3 / 12.4, abs=1e-15)
    assert zoom_window(np.linspace(0.0, 1.0, 1001), 21.0) is None
    assert zoom_window(t, 0.0) is None


def test_the_shipped_rubs_ring_force_settles_on_the_stationary_resultant():
    """`nsfem run rub` settles onto the full annular rub of `nsfem stationary rub`: the ring's resultant force
    (the tally's, drawn by forces.png) at the end of the run is the vector sum of the stationary facet forces,
    in magnitude and direction, though the polygon shares it between two facets (62 and 63). The slowest
    mode in contact decays as e^(-c t / 2 m) = e^(-4 t): 3.4e-4 of the transient is left after 2 s, so 1e-3."""
    from nsfem.analysis.stationary import scene_stationary
    from nsfem.contact.tally import tally

    scene = load_scene("rub")
    result, _ = run_scene(scene)
    st = scene_stationary(scene)
    F = scene["stator"][0]["facets"]
    z = np.sum(np.asarray(st.normal_force) * np.exp(2j * np.pi * np.arange(F) / F))
    (ring,) = tally(result).parts
    assert ring.part.kind == "ring" and np.count_nonzero(st.normal_force) == 2
    assert ring.force[-1] == pytest.approx(abs(z), rel=1e-3)
    assert abs(np.exp(1j * ring.angle[-1]) - z / abs(z)) < 1e-3


# --- issue 34: plots that read (envelope of long signals, phase, psd, orbits, units on every axis) ---
def test_envelope_bounds_every_sample_and_touches_the_extremes_of_each_bin():
    """min/max per bin: every sample of a bin lies in [lo, hi] of its bin, and lo and hi are samples (exact:
    reduceat only compares floats)."""
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0.0, 8.0, 50_001))
    y = np.sin(2 * np.pi * 21.0 * t) * np.exp(-0.1 * t) + 0.1 * rng.standard_normal(t.size)
    from nsfem.plot.common import envelope

    tc, lo, hi = envelope(t, y, 300)
    assert tc.size <= 300 and np.all(np.diff(tc) > 0)
    edges = np.linspace(t[0], t[-1], 301)
    b = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, 299)
    for k in rng.choice(np.unique(b), 25, replace=False):
        j = np.searchsorted(tc, 0.5 * (t[b == k][0] + t[b == k][-1]))
        assert lo[j] == y[b == k].min() and hi[j] == y[b == k].max()
    assert lo.min() == y.min() and hi.max() == y.max()


def test_zoom_span_is_the_last_periods_from_the_rotation_or_the_spectrum():
    from nsfem.plot.common import zoom_span

    t = np.arange(0.0, 4.0, 1e-4)
    y = np.sin(2 * np.pi * 37.0 * t)
    assert zoom_span(t, period=0.05) == (pytest.approx(4.0 - 1e-4 - 0.25, abs=1e-12), t[-1])
    # from the spectrum: the peak bin of a 2 s Hann record is within its 0.5 Hz spacing of 37 Hz
    a, b = zoom_span(t, y=y)
    assert b == t[-1] and (b - a) == pytest.approx(5 / 37.0, rel=0.5 / 37.0)
    assert zoom_span(t[:2000], period=0.05) is None     # 0.2 s of 0.05 s periods: short enough as it is
    assert zoom_span(t, y=np.ones_like(t)) is None      # no period to zoom on


# Every PNG: each axis that shows numbers names a quantity and its unit, "[unit]" (a dimensionless quantity: "[-]");
# no legend lies over plotted data. Every figure saved while a case draws is checked (Figure.savefig is wrapped,
# so a plot added to any module is caught); to cover a new kind of plot, add a case to PLOT_CASES.
UNIT = re.compile(r"\[[^\[\]]+\]")


def _shows_numbers(labels) -> bool:
    return any(t.get_visible() and t.get_text().strip() for t in labels)


def axis_problems(fig) -> list[str]:
    """What a reader could not tell from the figure: an axis with tick labels but no "quantity [unit]"."""
    out = []
    for ax in fig.axes:
        if not ax.get_visible() or not ax.axison:
            continue
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            if not _shows_numbers(axis.get_ticklabels()):
                continue
            label = axis.get_label_text()
            if not UNIT.search(label):
                out.append(f"{ax.get_title()!r}: {name} axis labelled {label!r}, no [unit]")
    return out


def _data_paths(ax):
    """(display-coordinate path, filled, markers only) of what ``ax`` plots in data coordinates (not the
    axvline/axvspan kind, which span the axes whatever the data)."""
    from matplotlib.collections import PathCollection
    from matplotlib.path import Path as MPath

    for line in ax.lines:
        xy = np.asarray(line.get_xydata(), dtype=float)
        if line.get_visible() and line.get_transform() == ax.transData and xy.size:
            markers_only = line.get_linestyle() in ("None", "none", " ", "")
            yield MPath(ax.transData.transform(xy)), False, markers_only
    for coll in ax.collections:
        if not coll.get_visible():
            continue
        if isinstance(coll, PathCollection):        # scatter: the markers at the offsets
            off = np.asarray(coll.get_offsets(), dtype=float)
            if off.size:
                yield MPath(coll.get_offset_transform().transform(off)), False, True
        elif coll.get_transform() == ax.transData:  # fill_between, stems
            for p in coll.get_paths():
                yield p.transformed(ax.transData), True, False
    for patch in ax.patches:                        # bars
        if patch.get_visible() and patch.get_data_transform() == ax.transData:
            yield patch.get_path().transformed(patch.get_transform()), True, False


def legend_problems(fig) -> list[str]:
    """Legends lying over plotted data: the legend's box (in pixels, shrunk by one) against each axes'
    data (lines, markers, fills, bars) within the axes' box."""
    from matplotlib.transforms import Bbox

    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
    out = []
    for leg in legends:
        box = leg.get_window_extent(renderer)
        box = Bbox.from_extents(box.x0 + 1, box.y0 + 1, box.x1 - 1, box.y1 - 1)
        for ax in fig.axes:
            if not ax.get_visible():
                continue
            region = Bbox.intersection(box, ax.get_window_extent(renderer))
            if region is None or region.width <= 0 or region.height <= 0:
                continue
            for path, filled, markers in _data_paths(ax):
                v = path.vertices
                inside = ((v[:, 0] > region.x0) & (v[:, 0] < region.x1) & (v[:, 1] > region.y0)
                          & (v[:, 1] < region.y1))
                hit = bool(inside.any()) if markers or len(v) < 2 else path.intersects_bbox(region, filled=filled)
                if hit:
                    texts = [t.get_text() for t in leg.get_texts()]
                    out.append(f"legend {texts[:3]} covers data of {ax.get_title()!r}")
                    break
    return out


@pytest.fixture
def saved_figures(monkeypatch):
    """[(file name, axis problems, legend problems, figure)] of every figure saved while the test runs."""
    from matplotlib.figure import Figure

    seen = []
    real = Figure.savefig

    def spy(self, fname, *args, **kwargs):
        done = real(self, fname, *args, **kwargs)
        # the tmp name of write_atomic: ".<target>.<random>.tmp"
        name = Path(str(fname)).name.lstrip(".").split(".png")[0] + ".png"
        seen.append((name, axis_problems(self), legend_problems(self), self))
        return done

    monkeypatch.setattr(Figure, "savefig", spy)
    return seen


def _tiny(overrides, t_end=0.05):
    return run_scene(load_scene(None, ["mesh.elements=16", "reduction.modes=8", f"simulation.t_end={t_end}",
                                       *overrides]))


def _run_plots(result, system, out):
    warned = []
    rp.write_plots(result, system, out, list(rp.RESULT_PLOTS), warn=warned.append)
    return warned


def _case_delamination(out):
    return _run_plots(*_tiny(["simulation.t_end=0.1"]), out)


def _case_stop(out):
    return _run_plots(*_tiny(["delamination=[]", 'obstacle=[{x=0.5, clearance=2e-4, normal="-z"}]',
                              "rotation.speed_hz=5"], t_end=0.1), out)


def _case_crack(out):
    from nsfem.scene.load import scene_from_tree

    from test_vtu_crack import cracked_tree

    return _run_plots(*run_scene(scene_from_tree(cracked_tree(t_end=0.03))), out)


def _case_ring_and_sensors(out):
    """The rub scene (a stator ring, an orbit pair of probes at it) over 0.4 s: 9 periods of 22.4 Hz."""
    from nsfem.plot.sensors import sensors_plot, stator_rings
    from nsfem.simulate import sensor_signals

    scene = load_scene("rub", ["simulation.t_end=0.4", "mesh.elements=8"])
    result, system = run_scene(scene)
    warned = _run_plots(result, system, out)
    sensors_plot(out / "sensors.png", result.t, sensor_signals(result, system), scene.sensors,
                 scene.rotation.speed_hz, scene.title, stator_rings(system))
    return warned


def _case_long_sensor_record(out):
    """8 s of two probes at 26 Hz (208 periods: the envelope and the zoom panel) and one far from the first."""
    from nsfem.plot.sensors import sensors_plot
    from nsfem.sensors import Sensor

    t = np.arange(0.0, 8.0, 1e-4)
    w = 2 * np.pi * 26.0
    values = 5e-5 * np.column_stack([np.cos(w * t), np.sin(w * t) - 5.0, np.cos(w * t)])
    sensors = [Sensor("a_y", 0.5, "+y", "inertial", "s"), Sensor("a_z", 0.5, "+z", "inertial", "s"),
               Sensor("b_y", 0.2, "-y", "rotating", "s")]
    sensors_plot(out / "sensors.png", t, values, sensors, 26.0, "long", rings=[(0.5, 3e-4)])
    return []


def _case_campbell(out):
    from nsfem import cli

    assert cli.main(["campbell", "critical_speed", "--speeds", "0:60:7", "--count", "4",
                     "--png", str(out / "campbell.png")]) == 0
    return []


def _case_resonance(out):
    from nsfem.plot.sweep import plot_resonance

    keys = ["rotation.speed_hz", "stator.0.friction"]
    points = [{keys[0]: s, keys[1]: m} for m in (0.0, 0.2) for s in (10.0, 20.0, 30.0)]
    runs = [{"closed_fraction": 0.1 * s / 10, "min_gap_m": -1e-9, "max_gap_m": 1e-4 / s,
             "max_normal_force_N": s * (1 + m), "amplitude_disk_y_m": 1e-6 * s}
            for p in points for s, m in [(p[keys[0]], p[keys[1]])]]
    plot_resonance(out / "resonance.png", keys, points, runs, "contacts", marks={"resonance": [22.0]})
    plot_resonance(out / "resonance_rotor.png", keys[:1], points[:3],
                   [{"amplitude_disk_y_m": 1e-6 * s, "min_gap_m": None} for s in (10, 20, 30)], "rotor")
    return []


def _case_fit(out):
    from nsfem.plot.fit import fit_plot, landscape_plot

    t = np.linspace(0.0, 0.5, 501)
    measured = 1e-5 * np.column_stack([np.sin(60 * t), np.cos(60 * t)])
    fit_plot(out / "fit.png", t, measured, 1.01 * measured, ["disk_y", "disk_z"], 0.01)
    t_long = np.arange(0.0, 4.0, 1e-4)   # 160 periods: envelopes and a zoom column
    long = 1e-5 * np.column_stack([np.sin(2 * np.pi * 40 * t_long), np.cos(2 * np.pi * 40 * t_long)])
    fit_plot(out / "fit_long.png", t_long, long, 1.01 * long, ["disk_y", "disk_z"], 0.01)
    rng = np.random.default_rng(0)
    x = rng.uniform([10.0, 0.0], [30.0, 0.3], (20, 2))
    misfit = (x[:, 0] - 21.0) ** 2 / 100 + x[:, 1]
    landscape_plot(out / "landscape.png", ["rotation.speed_hz", "stator.0.friction"], x, misfit, x[0])
    landscape_plot(out / "landscape1.png", ["rotation.speed_hz"], x[:, :1], misfit, x[0, :1])
    return []


def _case_periodic(out):
    """orbit.png with a probe pair at a ring (its clearance circle), a lone probe and two contacts; floquet.png
    with multipliers inside and outside the unit circle."""
    from nsfem.plot.periodic import floquet_plot, orbit_plot
    from nsfem.sensors import Sensor

    t = np.linspace(0.0, 1 / 20.0, 257)
    w = 2 * np.pi * 20.0
    values = 1e-4 * np.column_stack([np.cos(w * t), np.sin(w * t), 0.5 * np.cos(2 * w * t)])
    sensors = [Sensor("a_y", 0.5, "+y", "inertial", "s"), Sensor("a_z", 0.5, "+z", "inertial", "s"),
               Sensor("b_y", 0.2, "-y", "rotating", "s")]
    gap = np.vstack([np.maximum(0.0, 1e-5 * np.cos(w * t)), 2e-5 + 1e-5 * np.sin(w * t)])
    force = np.vstack([np.where(gap[0] == 0.0, 10.0, 0.0), np.zeros_like(t)])
    orbit_plot(out / "orbit.png", t, values, sensors, gap, force, ["ring.0.0", "ring.0.1"], [(0.5, 1.2e-4)], "orbit")
    floquet_plot(out / "floquet.png", np.array([1.2, 0.5 + 0.5j, 0.5 - 0.5j, -0.3, 0.0]), "unstable: fold", "mu")
    return []


def _case_branch(out):
    """branch.png: two sensors, a branch losing its stability at a period doubling (a bifurcation marked), a
    doubled branch, over a key with its unit."""
    from nsfem.plot.periodic import branch_plot

    x = np.linspace(10.0, 20.0, 21)
    pts = [{"value": v, "stable": v < 15.0, "multiple": 1, "amplitudes": {"a_y": 1e-5 * (1 + 0.1 * v),
                                                                          "a_z": 2e-5 / (1 + (v - 14.0) ** 2)}}
           for v in x]
    doubled = [{"multiple": 2, "points": [{"value": v, "stable": True, "multiple": 2,
                                           "amplitudes": {"a_y": 1e-5 * (1 + 0.1 * v) + 1e-6 * math.sqrt(v - 15.0),
                                                          "a_z": 1e-5}} for v in x[10:]]}]
    branch_plot(out / "branch.png", "rotation.speed_hz", pts, ["a_y", "a_z"],
                [{"kind": "period-doubling", "value": 15.0}], doubled, "branch")
    return []


#: name -> draw(out_dir) -> the skip warnings of write_plots; each PNG it saves is checked
PLOT_CASES = {
    "delamination": _case_delamination, "stop": _case_stop, "crack": _case_crack,
    "ring+sensors": _case_ring_and_sensors, "long sensor record": _case_long_sensor_record,
    "campbell": _case_campbell, "resonance": _case_resonance, "fit": _case_fit,
    "portrait about its mean": lambda out: _portrait_case(out), "periodic": _case_periodic,
    "branch": _case_branch,
}
#: the PNGs each case must produce (a run plot without data may be skipped, with a reason, where listed)
EXPECTED = {
    "delamination": {"phase.png", "gap.png", "psd.png", "forces.png"},
    "stop": {"phase.png", "gap.png", "psd.png", "forces.png"},
    "crack": {"phase.png", "gap.png", "psd.png", "forces.png"},
    "ring+sensors": {"phase.png", "gap.png", "psd.png", "forces.png", "sensors.png"},
    "long sensor record": {"sensors.png"},
    "campbell": {"campbell.png"},
    "resonance": {"resonance.png", "resonance_rotor.png"},
    "fit": {"fit.png", "fit_long.png", "landscape.png", "landscape1.png"},
    "portrait about its mean": {"phase.png", "psd.png"},
    "periodic": {"orbit.png", "floquet.png"},
    "branch": {"branch.png"},
}


@pytest.mark.parametrize("case", list(PLOT_CASES))
def test_every_axis_has_a_unit_and_no_legend_covers_data(case, saved_figures, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)   # a command's default output folder lands here, not in the checkout
    warned = PLOT_CASES[case](tmp_path)
    names = {name for name, *_ in saved_figures}
    assert names == EXPECTED[case], (names, warned)
    problems = {name: axes + legends for name, axes, legends, _ in saved_figures if axes + legends}
    assert problems == {}


def test_the_checks_catch_a_missing_unit_and_a_legend_over_data(saved_figures, tmp_path):
    """The checks above can fail: an unlabelled axis and a legend on the line are reported."""
    from nsfem.plot.common import figure, save

    fig, ax = figure()
    ax.plot([0.0, 1.0], [0.0, 1.0], label="a line through the legend")
    ax.plot([0.0, 1.0], [0.5, 0.5], label="another")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("displacement")
    ax.legend(loc="center")
    save(fig, tmp_path / "bad.png")
    (name, axes, legends, _), = saved_figures
    assert name == "bad.png"
    assert axes == ["'': y axis labelled 'displacement', no [unit]"]
    assert len(legends) == 1 and "covers data" in legends[0]


def test_phase_portraits_are_each_modes_displacement_where_it_is_largest(run, saved_figures, tmp_path):
    """mode_peaks: phi_j at the largest translation of mode j, so scale * eta_j is what mode j alone moves
    there; on the shipped scene the modes drawn are the first three (the paper's fig. 3a)."""
    from nsfem.plot.phase import mode_peaks

    result, system = run
    model, T = system.info["model"], system.info["reduction"].T
    _, Phi = rp.modal_basis(system)
    peaks = mode_peaks(system, 4)
    shapes = np.asarray(T @ Phi[:, :4])
    rotations = np.concatenate([sp_.dofs[f][sp_.bending.nodal_dofs[1]] for sp_ in model.spaces.values()
                                for f in "VW"])
    translations = np.setdiff1d(np.arange(model.n_full), rotations)
    for j, p in enumerate(peaks):
        dof = model.dof(p["segment"], p["field"], p["x"])
        assert shapes[dof, j] == p["scale"]                                   # the same number, read back
        assert abs(p["scale"]) == np.abs(shapes[translations, j]).max()       # the largest translation
    # the shipped delamination's first modes bend in W then V, largest at midspan (a symmetric beam)
    assert [p["field"] for p in peaks[:2]] == ["W", "V"] and peaks[0]["x"] == pytest.approx(0.5, abs=0.05)
    rp.phase_plot(result, system, tmp_path / "phase.png")
    (_, axes, legends, fig), = saved_figures
    titles = [ax.get_title() for ax in fig.axes if ax.get_visible()]
    assert [t.split(":")[0] for t in titles[:3]] == ["mode 1", "mode 2", "mode 3"]
    # the portrait of mode 1 spans the mode's displacement at its peak, in um: 1e6 scale eta (a plotted copy)
    f, eta, _ = rp.modal_coordinates(result, system)
    sel = result.t >= 0.5 * result.t[-1]
    x = fig.axes[0].lines[0].get_xdata()
    span = 1e6 * abs(peaks[0]["scale"]) * np.ptp(eta[0, sel])
    # the curve between samples reaches the extremes the samples miss by at most 1 - cos(w h / 2) of the
    # amplitude each (43.4 Hz sampled every 1 ms: 0.93 %), so the spans differ by at most 1.9 %
    assert span * (1 - 1e-12) <= np.ptp(x) <= 1.019 * span   # (1e-12: the two products' round-off)


def test_psd_plot_spans_twelve_decades_below_its_peak(run, saved_figures, tmp_path):
    result, system = run
    rp.psd_plot(result, system, tmp_path / "psd.png")
    (_, _, _, fig), = saved_figures
    ax = fig.axes[0]
    lo, hi = ax.get_ylim()
    peak = max(line.get_ydata().max() for line in ax.lines if line.get_label().startswith("sensor")
               or "at x =" in line.get_label())
    # the axis limits are set from the peak: float products, a few ulps
    assert lo == pytest.approx(peak * 1e-12, rel=1e-12) and hi == pytest.approx(peak * 10, rel=1e-12)
    assert ax.get_ylabel().endswith("[m$^2$/Hz]")


def test_long_signal_draws_a_band_when_periods_are_denser_than_the_pixels():
    """208 periods of 26 Hz in 8 s get an envelope band with one bin per period whose edges are the amplitude
    (sampled every 0.1 ms: the largest sample of a period is within 1 - cos(w dt / 2) = 3.3e-5 of it); 0.4 s
    (10 periods) is drawn as a line."""
    from nsfem.plot.common import figure, long_signal, zoom_span

    t = np.arange(0.0, 8.0, 1e-4)
    y = 3.0 * np.cos(2 * np.pi * 26.0 * t)
    fig, ax = figure()
    fig2, zoom = figure()
    span = zoom_span(t, 1 / 26.0)
    (band,) = long_signal(ax, t, y, period=1 / 26.0, zoom=zoom, span=span)
    v = band.get_paths()[0].vertices
    n = int(8.0 * 26.0)
    assert ax.lines == [] or all(len(line.get_xdata()) == 0 for line in ax.lines)   # no solid block of lines
    assert abs(v[:, 1]).max() == 3.0 and np.all(abs(v[2:-2, 1]) > 3.0 * (1 - 3.4e-5))
    assert len(v) <= 2 * n + 8                  # one point per period on each edge (+ closing vertices)
    (line,) = zoom.lines
    assert line.get_xdata()[0] >= span[0] and line.get_xdata()[-1] == t[-1]
    fig3, ax3 = figure()
    short = t < 0.4
    (drawn,) = long_signal(ax3, t[short], y[short], period=1 / 26.0)
    assert len(drawn.get_xdata()) == short.sum()


# --- issue 34: pictures that read at a glance (the shipped scenes' PNGs looked at) ---
def test_an_envelope_per_revolution_where_revolutions_are_denser_than_the_pixels():
    """The crack scene's 8 s at 12.4 Hz (99 revolutions) on a 6.4 in axes: one bin per revolution, so the band's
    upper edge is the breathing opening's amplitude in every bin (its largest sample is within
    1 - cos(w dt / 2) = 7.6e-4 of it, sampled every 1 ms) and its lower edge its zero, not each revolution's
    oscillation drawn as strokes (:func:`nsfem.plot.common.long_signal`, the one mechanism since the merge with
    i34-r1); 1 s of 21 Hz (the shipped scene, 8+ columns a revolution) stays a line through every sample."""
    from nsfem.plot.common import envelope, figure, long_signal

    fig, ax = figure(figsize=(6.4, 4.8))
    t = np.arange(0.0, 8.0 + 5e-4, 1e-3)
    y = np.maximum(np.sin(2 * np.pi * 12.4 * t), 0.0)   # open half a revolution, closed the other half
    (band,) = long_signal(ax, t, y, period=1 / 12.4)
    bins = int(8.0 * 12.4)
    v = band.get_paths()[0].vertices
    assert len(v) <= 2 * bins + 8
    _, lo, hi = envelope(t, y, bins)
    assert np.isin(hi, v[:, 1]).all() and np.isin(lo, v[:, 1]).all()   # the band's edges are these bins'
    assert hi.min() > 1.0 - 7.6e-4 and lo.max() == 0.0
    fig, ax = figure(figsize=(6.4, 4.8))
    short = np.linspace(0.0, 1.0, 1001)
    (line,) = long_signal(ax, short, np.sin(2 * np.pi * 21.0 * short), period=1 / 21.0)
    assert len(line.get_xdata()) == short.size


@pytest.fixture(scope="module")
def steady_rub():
    """The rub scene over 1.5 s (34 revolutions of 22.4 Hz, closed from 0.02 s on), on a coarse mesh."""
    return run_scene(load_scene("rub", ["simulation.t_end=1.5", "mesh.elements=8"]))


def test_a_steady_rub_zooms_on_its_first_revolutions_and_draws_its_friction_lighter(steady_rub, saved_figures,
                                                                                      tmp_path):
    """gap.png: closed throughout its last revolutions, the ring gets its zoom on the first 3 (where the gap
    closes), the shading behind the gap line; forces.png: its zoom on the first revolutions too, the friction
    force in the ring's colour lightened (a band has no dashes), named so in the legend."""
    from matplotlib.colors import to_rgb

    from nsfem.plot.forces import lighter

    result, system = steady_rub
    rp.gap_plot(result, system, tmp_path / "gap.png")
    rp.forces_plot(result, system, tmp_path / "forces.png")
    (_, axes_g, legends_g, gap), (_, axes_f, legends_f, forces) = saved_figures
    assert axes_g + legends_g + axes_f + legends_f == []
    main, zoom = gap.axes[:2]
    assert zoom.get_title() == "the first 3 revolutions"
    t = result.t
    a, b = zoom.get_xlim()
    # the first output time, and the last output time within 3 revolutions (outputs every 0.1 ms or so)
    assert a == t[0] and b == t[t <= t[0] + 3 / 22.4][-1]
    shading = [c for c in main.collections if c.get_zorder() < 1]
    assert shading and all(c.get_zorder() < line.get_zorder() for c in shading for line in main.lines)
    # 34 revolutions: forces.png has its zoom on the last 5 too (i34-r1), which carries the legend, beside the
    # panel over the whole run
    ax = next(a for a in forces.axes if a.get_ylabel() == "force [N]" and a.get_xlim()[0] == t[0])
    # its zoom, as gap.png's, on the first revolutions (the last 5 were two flat lines), titled so
    (zoom,) = [a for a in forces.axes if a.get_ylabel() == "force [N]" and a is not ax]
    assert zoom.get_xlim()[0] == t[0] and zoom.get_title().startswith("first ")
    texts = [x.get_text() for a in forces.axes if a.get_legend() for x in a.get_legend().get_texts()]
    assert "friction force (tangential): lighter" in texts and not any("dashed" in s or "lambda" in s for s in texts)
    drawn = [to_rgb(line.get_color()) for line in ax.lines] + [tuple(c.get_facecolor()[0][:3]) for c in ax.collections]
    assert any(np.allclose(c, lighter("C0"), rtol=0, atol=1e-12) for c in drawn)   # colour arithmetic: ulps


def _portrait_case(out):
    """ross_example for 0.2 s: a rotor under its weight, mode 1's sag (1.29 mm) far larger than its vibration."""
    return _run_plots(*run_scene(load_scene("ross_example", ["simulation.t_end=0.2"])), out)


def test_a_portrait_dominated_by_the_sag_is_drawn_about_its_mean(saved_figures, tmp_path):
    """ross_example: mode 1's portrait spans ~25 um about a mean of -1.29 mm: it is drawn about its mean (the
    drawn points average to 0 to round-off of the 1.3e3 subtracted, 1e-9 um) and the label names the mean; the bar
    panel's log axis starts at 1e-6 of the largest bar, and the modes below it are named in its title."""
    from nsfem.plot.phase import phase_plot

    result, system = run_scene(load_scene("ross_example", ["simulation.t_end=0.2"]))
    phase_plot(result, system, tmp_path / "phase.png")
    (_, axes, legends, fig), = saved_figures
    assert axes + legends == []
    shifted = [ax for ax in fig.axes if "about its mean" in ax.get_xlabel()]
    assert shifted
    for ax in shifted:
        x = ax.lines[0].get_xdata()
        mean = float(re.search(r"about its mean (\S+) \[", ax.get_xlabel())[1])
        assert abs(np.mean(x)) < 1e-9 * max(1.0, abs(mean)) * 1e3 and abs(mean) > 3 * np.ptp(x)
    bars = fig.axes[[ax.get_title().startswith("each mode") for ax in fig.axes].index(True)]
    heights = np.array([p.get_height() for p in bars.patches])
    lo = bars.get_ylim()[0]
    assert lo >= 1e-6 * heights.max() * (1 - 1e-12)
    hidden = [i + 1 for i, h in enumerate(heights) if h < 1e-6 * heights.max()]
    if hidden:
        assert f"not shown: mode {', '.join(map(str, hidden))}" in bars.get_title()


def test_sensor_amplitudes_are_linear_over_less_than_100x_and_log_with_plain_labels_over_more(saved_figures,
                                                                                             tmp_path):
    """The rub sweep's amplitudes (30 to 100 um) on a log axis read "3x10^1, 4x10^1, 6x10^1": linear from 0
    below a ratio of 100; above (a resonance peak over decades), log with the decades labelled as numbers."""
    from nsfem.plot.sweep import plot_resonance

    keys = ["rotation.speed_hz"]
    points = [{keys[0]: s} for s in (10.0, 20.0, 30.0)]
    narrow = [{"amplitude_disk_y_m": a, "min_gap_m": None} for a in (3e-5, 6e-5, 1e-4)]
    wide = [{"amplitude_disk_y_m": a, "min_gap_m": None} for a in (2e-6, 6e-4, 3e-6)]
    plot_resonance(tmp_path / "narrow.png", keys, points, narrow, "narrow")
    plot_resonance(tmp_path / "wide.png", keys, points, wide, "wide")
    (_, p1, l1, f1), (_, p2, l2, f2) = saved_figures
    assert p1 + l1 + p2 + l2 == []
    (a1,), (a2,) = f1.axes, f2.axes
    assert a1.get_yscale() == "linear" and a1.get_ylim()[0] == 0.0 and a1.get_ylim()[1] >= 100.0
    assert a2.get_yscale() == "log"
    fmt = a2.yaxis.get_major_formatter()
    assert [fmt(v, 0) for v in (1.0, 10.0, 100.0)] == ["1", "10", "100"]


# --- issue 34: gap.png and forces.png draw long runs with the shared long_signal ---
def test_gap_and_forces_of_a_long_run_are_envelopes_over_each_revolution(saved_figures, tmp_path):
    """8 s at 21 Hz (168 revolutions, more than 30: a long run) are drawn as bands with one bin per
    revolution (:func:`nsfem.plot.common.long_signal`), not as 8001-sample lines, and their last revolutions
    beside them as lines; the bands' upper edge is the largest gap and force exactly (a min/max over samples:
    no arithmetic), and no legend covers them."""
    from matplotlib.collections import PolyCollection

    from nsfem.contact.tally import tally

    result, system = _tiny([], t_end=8.0)
    (pt,) = tally(result).parts
    rp.write_plots(result, system, tmp_path, ["gap", "forces"])
    figs = {name: fig for name, *_ , fig in saved_figures}
    assert set(figs) == {"gap.png", "forces.png"}
    assert [p for name, a, leg, _ in saved_figures for p in a + leg] == []
    revolutions = int(8.0 * 21.0)
    for name, peak in (("gap.png", 1e3 * result.gap[list(pt.part.rows)].max()), ("forces.png", pt.max_normal_force_N)):
        # the panel over the whole run (the zoom beside it spans its last revolutions)
        ax = next(a for a in figs[name].axes if a.get_ylabel().startswith(("gap", "force", "normal force"))
                  and a.get_xlim()[0] == result.t[0])
        assert all(len(line.get_xdata()) < result.t.size for line in ax.lines)   # no line through every sample
        zoom = [a for a in figs[name].axes if a.get_ylabel() == ax.get_ylabel() and a.get_xlim()[0] > 7.5]
        assert len(zoom) == 1 and max(len(line.get_xdata()) for line in zoom[0].lines) > 100
        bands = [c for c in ax.collections if isinstance(c, PolyCollection) and c.get_transform() == ax.transData]
        top = max(c.get_paths()[0].vertices[:, 1].max() for c in bands)
        assert top == peak
        assert all(len(c.get_paths()[0].vertices) <= 2 * revolutions + 8 for c in bands)


def test_long_signal_dense_draws_the_envelope_per_period_even_when_periods_have_room():
    """80 periods of a signal with three peaks a period (a crack's gap) get 9+ pixel columns each on a
    wide axes: by the period rule a line (a solid block of 240 peaks); ``dense=True`` draws the band, one bin
    a period, its upper edge the amplitude (a max over samples: exact). Fewer samples than bins stay a line."""
    from nsfem.plot.common import PIXELS_PER_PERIOD, columns, figure, long_signal

    t = np.arange(0.0, 8.0, 1e-3)
    y = np.abs(np.sin(2 * np.pi * 30.0 * t))
    fig, ax = figure(figsize=(9.0, 3.0))
    assert 80 * PIXELS_PER_PERIOD <= columns(ax)          # the period rule alone draws a line here
    (line,) = long_signal(ax, t, y, period=0.1)
    assert len(line.get_xdata()) == t.size
    fig, ax = figure(figsize=(9.0, 3.0))
    (band,) = long_signal(ax, t, y, period=0.1, dense=True)
    v = band.get_paths()[0].vertices
    assert len(v) <= 2 * 80 + 8 and v[:, 1].max() == y.max()
    fig, ax = figure(figsize=(9.0, 3.0))
    (few,) = long_signal(ax, t[::200], y[::200], period=0.1, dense=True)   # 40 samples, 80 periods
    assert len(few.get_xdata()) == 40


def test_a_long_runs_dense_closures_are_shaded_in_the_zoom_only(saved_figures, tmp_path):
    """A breathing crack over 4 s at 10 Hz (40 revolutions: a long run) closes hundreds of times: shaded on the
    main panel, one interval per few pixel columns, they were a moire over the envelope; now only the zoom on
    the last 3 revolutions shades them, and the legend still gives the closed share."""
    from matplotlib.collections import PolyCollection

    from nsfem.contact.tally import tally
    from nsfem.plot.common import columns
    from nsfem.plot.gap import SHADE_COLUMNS
    from nsfem.scene.load import scene_from_tree

    from test_vtu_crack import cracked_tree

    result, system = run_scene(scene_from_tree(cracked_tree(t_end=4.0)))
    (pt,) = tally(result).parts
    rp.write_plots(result, system, tmp_path, ["gap"])
    ((_, axis, legend, fig),) = saved_figures
    assert axis + legend == []
    main, zoom = fig.axes[0], fig.axes[1]
    assert len(pt.spans) * SHADE_COLUMNS > columns(main)

    def shaded(ax):   # the closed intervals: bars spanning the axes' height (x in data, y in axes coordinates)
        return [c for c in ax.collections if isinstance(c, PolyCollection) and c.get_transform() != ax.transData]

    assert shaded(main) == [] and len(shaded(zoom)) >= 1
    assert any("% of the time" in text.get_text() for text in zoom.get_legend().get_texts())


# --- issue 34: latency, second pass (one layout pass per save; the Hermite refinement vectorized) ------------
@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 40), f_hz=st.floats(0.0, 3000.0), seed=st.integers(0, 2**32 - 1),
       kicks=st.integers(0, 4))
def test_hermite_refine_reproduces_a_cubic_on_its_documented_grid(n, f_hz, seed, kicks):
    """The cubic Hermite interpolant of a cubic's values and slopes is that cubic: every drawn point is p(tau),
    p'(tau) at tau = t_i + k h_i / n_i, k = 1..n_i, n_i = ceil(h_i f 48) within [1, 64], n_i = 1 on an interval
    holding an impact (its chord: the end sample itself), the first sample first. On [0, 1] with coefficients
    of order 1 a value sums four products of order 1 (a few ulps: 1e-13 is 500 of them); a slope divides
    a difference of such by h >= 1e-3 (2e-11)."""
    from nsfem.plot.data import hermite_refine

    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0.0, 1.0, n))
    t = t[np.r_[True, np.diff(t) >= 1e-3]]
    assume(t.size >= 2)
    c = rng.normal(size=4)
    p, dp = np.polynomial.Polynomial(c), np.polynomial.Polynomial(c).deriv()
    kick = list(rng.uniform(-0.1, 1.1, kicks)) + list(t[rng.integers(0, t.size, kicks // 2)])
    x, dx = hermite_refine(t, p(t), dp(t), f_hz, kick)
    h = np.diff(t)
    ni = np.clip(np.ceil(h * f_hz * 48).astype(int), 1, 64) if f_hz > 0 else np.ones(h.size, int)
    if np.all(ni == 1):     # nothing to refine: the samples as they are
        tau = t
    else:
        ni[[any(t[i] < k <= t[i + 1] for k in kick) for i in range(h.size)]] = 1
        tau = np.r_[t[0], np.concatenate([t[i] + h[i] * np.arange(1, m + 1) / m for i, m in enumerate(ni)])]
    assert x.shape == dx.shape == tau.shape
    np.testing.assert_allclose(x, p(tau), rtol=0, atol=1e-13)
    np.testing.assert_allclose(dx, dp(tau), rtol=0, atol=2e-11)
    ends = np.r_[0, np.cumsum(ni)] if not np.all(ni == 1) else np.arange(t.size)
    assert np.array_equal(x[ends], p(t)) and np.array_equal(dx[ends], dp(t))   # the samples exactly


def test_save_lays_a_figure_out_once_and_draws_it_once(tmp_path, monkeypatch):
    """A constrained figure and a tight_layout one are saved as matplotlib's own savefig saves them (the same
    pixels: the same layout, computed once), with one draw of the figure instead of two."""
    from matplotlib.figure import Figure
    from PIL import Image

    from nsfem.plot.common import figure, save

    def draw(fig_kw, tight):
        fig, axes = figure(nrows=2, figsize=(4, 3), **fig_kw)
        for k, ax in enumerate(axes):
            ax.plot(np.linspace(0, 1, 50) ** (k + 1) * 10.0 ** (3 * k), label=f"curve {k}")
            ax.set_xlabel("time [s]")
            ax.set_ylabel(f"amplitude {k} [µm]")
            ax.legend()
        fig.suptitle("a title\nover two lines")
        if tight:
            fig.tight_layout()
        return fig

    draws = []
    real = Figure.draw
    monkeypatch.setattr(Figure, "draw", lambda self, renderer: (draws.append(1), real(self, renderer))[1])
    cases = [("constrained", {"layout": "constrained"}, False, 130), ("tight", {}, True, 130),
             ("constrained_at_90_dpi", {"layout": "constrained"}, False, 90)]   # laid out at the dpi saved with
    for name, kw, tight, dpi in cases:
        ours, theirs = tmp_path / f"{name}_ours.png", tmp_path / f"{name}_mpl.png"
        draws.clear()
        save(draw(kw, tight), ours, dpi=dpi)
        assert len(draws) == 1
        draw(kw, tight).savefig(theirs, format="png", dpi=dpi)
        assert np.array_equal(np.asarray(Image.open(ours)), np.asarray(Image.open(theirs)))


# --- issue 35: bearings.png reads (units, legends outside the bands, round-off drawn as zero) ---
def test_bearings_plot_has_units_legends_off_the_data_and_draws_round_off_as_zero(saved_figures, tmp_path):
    """Two lateral bearings carrying 150 N +- 20 N at 26 Hz over 8 s and a thrust bearing whose axial force is
    1e-11 N of round-off (critical_speed's): every axis has its unit, no legend crosses the bands, and the thrust
    bearing's line is the zero it is (1e-11 N is 7e-14 of the largest force, far below ROUND_OFF)."""
    from nsfem.plot.bearings import ROUND_OFF, bearings_plot

    t = np.arange(0.0, 8.0 + 5e-4, 1e-3)
    F = np.zeros((t.size, 3, 3))
    for b in (0, 1):
        F[:, b, 1] = 20.0 * np.sin(2 * np.pi * 26.0 * t)
        F[:, b, 2] = 150.0 + 20.0 * np.cos(2 * np.pi * 26.0 * t)
    F[:, 2, 0] = 1e-11 * np.sin(2 * np.pi * 26.0 * t)
    assert 1e-11 < ROUND_OFF * 170.0
    index = np.array([[0, 1], [0, 2], [1, 1], [1, 2], [2, 0]])
    bearings_plot(tmp_path / "bearings.png", t, F, ["bearing.0", "bearing.1", "bearing.2"], index, 26.0, "t")
    (_, axes, legends, fig), = saved_figures
    assert axes == [] and legends == []
    labels = [text.get_text() for ax in fig.axes if ax.get_legend() for text in ax.get_legend().get_texts()]
    assert "Fx (round-off: 0)" in labels and labels.count("Fy") == 2
    thrust = [ax for ax in fig.axes if ax.get_ylabel() == "bearing.2 force [N]"]
    assert thrust and all(np.all(p.vertices[:, 1] == 0.0) for ax in thrust for c in ax.collections
                          for p in c.get_paths()) and all(np.all(line.get_ydata() == 0.0) for ax in thrust
                                                          for line in ax.get_lines() if len(line.get_ydata()))


def test_floquet_titles_fit_in_the_figure(saved_figures, tmp_path):
    """review2: floquet.png's title holds the verdict, which for a marginally stable orbit (critical_speed: 14
    multipliers on the unit circle) is a sentence of 150 characters: it ran off both sides of the 6 in figure,
    the verdict unreadable. Every title's drawn extent lies inside the figure (to a pixel)."""
    from nsfem.periodic.scene import SceneOrbit
    from nsfem.plot.periodic import floquet_plot

    class Orbit:   # what SceneOrbit.verdict reads: a converged orbit, stable, 14 multipliers with |mu| = 1
        converged, stable, loss = True, True, None
        multipliers = np.concatenate([np.exp(1j * np.linspace(0.1, 3.0, 14)), 0.3 * np.ones(4)])

    so = SceneOrbit.__new__(SceneOrbit)
    so.orbit = Orbit()
    verdict = so.verdict()
    assert len(verdict) > 120   # the long verdict this test is about
    floquet_plot(tmp_path / "floquet.png", Orbit.multipliers, verdict,
                 "A rotor on anisotropic bearings through its critical speeds: unbalance response")
    (_, _, _, fig), = saved_figures
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    texts = [ax.title for ax in fig.axes] + ([fig._suptitle] if fig._suptitle is not None else [])
    for text in texts:
        if not text.get_text():
            continue
        e = text.get_window_extent(renderer)
        assert e.x0 >= box.x0 - 1 and e.x1 <= box.x1 + 1 and e.y1 <= box.y1 + 1, (text.get_text(), e, box)
