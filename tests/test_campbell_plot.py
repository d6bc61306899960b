"""Campbell diagram: branches followed in speed, damped critical speeds on them, and the figure (issue 34)."""

from __future__ import annotations

import contextlib
import io
import json
import math

import numpy as np
import pytest
import scipy.linalg as sla
from conftest import beam_tree

from nsfem import build_model, cli, load_scene, natural_frequencies
from nsfem.analysis.branches import MAC_MIN, XTOL, mac
from nsfem.analysis.campbell import campbell, campbell_report, shown_branches
from nsfem.analysis.whirl import AXIAL
from nsfem.fem.rotating import rotor_operators
from nsfem.reduce import scene_reduction
from nsfem.scene import scene_from_tree
from nsfem.system import linear_system


@pytest.fixture(scope="module")
def critical():
    """The shipped critical_speed scene's inertial Campbell report (40 modal dofs, 61 speeds to 288 Hz)."""
    scene = load_scene("critical_speed")
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    return scene, model, red, campbell_report(scene, model, None, 6, red)


def direct_eigenvalues(system) -> np.ndarray:
    """All roots of det(lambda^2 M + lambda C + Q) = 0 from the generalized companion pencil (no Cholesky,
    no shift-invert: independent of nsfem.analysis.campbell.state_eigenvalues)."""
    n = system.n
    M, Q = system.M.toarray(), system.Q.toarray()
    C = system.C.toarray() if system.C is not None else np.zeros((n, n))
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Q, -C]])
    B = np.block([[np.eye(n), np.zeros((n, n))], [np.zeros((n, n)), M]])
    return sla.eigvals(A, B)


def test_damped_critical_speeds_are_roots_of_the_damped_eigenproblem(critical):
    """Each reported critical speed s is where a damped root whirls at s: the eigenvalue problem solved
    directly at s (companion pencil, QZ) has a root with Im / 2 pi = s. Brent stops within XTOL x 288 Hz
    = 2.9e-9 Hz of the root of f - s, so |f(s) - s| <= |1 - f'| 2.9e-9 (|f'| <= 1 here: 6e-9 Hz); QZ
    resolves a root of this 24-state pencil to a few eps x cond (measured 3e-15 to 7e-11 of |lambda| over
    the six crossings, the 7e-11 being Brent's stop on the flat 23.5 Hz branch): 1e-8 relative to the
    speed bounds both with room for other BLAS kernels."""
    scene, model, red, rep = critical
    damp = scene.damping
    from nsfem.analysis.modes import contact_basis

    ops = rotor_operators(model, contact_basis(model, "open", red))
    found = rep["critical_speeds"]["open"]
    assert found, "no critical speed"
    for c in found:
        lam = direct_eigenvalues(linear_system(ops, c["speed_hz"], 0.0, 0.0, damp.rayleigh, damp.external, "inertial"))
        f = lam.imag / (2 * math.pi)
        k = int(np.argmin(np.abs(f - c["speed_hz"])))
        assert abs(f[k] - c["speed_hz"]) <= 1e-8 * c["speed_hz"], (c, f[k])
        # its damping ratio is that root's
        assert -lam[k].real / abs(lam[k]) == pytest.approx(c["damping_ratio"], rel=1e-6, abs=1e-9)
    # the plain lists keep the contract's shape and agree with the detailed entries
    assert rep["critical_speeds_hz"]["open"] == [c["speed_hz"] for c in found]
    assert rep["critical_whirl"]["open"] == [c["whirl"] for c in found]


def test_markers_lie_on_their_tracked_branches(critical):
    """A critical speed s of branch b lies between two grid speeds where f_b - speed changes sign, and
    the branch's root found again at s (MAC to its grid vectors) whirls at s to Brent's tolerance."""
    _, _, _, rep = critical
    res = rep["_results"]["open"]
    B = res.branches
    shown = shown_branches(res)
    s = B.speeds_hz
    tol = XTOL * float(s.max())
    for c in rep["_critical"]["open"]:
        f = B.frequencies_hz[shown[c.branch]]
        i = int(np.searchsorted(s, c.speed_hz)) - 1
        g = f[i:i + 2] - s[i:i + 2]
        assert np.all(np.isfinite(g)) and g[0] * g[1] <= 0.0, (c, g)
        # on the curve drawn: the polyline through the branch's points and the marker bends less
        # than the curvature between two grid points allows, and the marker is a root of f_b - speed
        assert abs(c.eigenvalue.imag / (2 * math.pi) - c.speed_hz) <= 2 * tol
        assert c.whirl == B.label[shown[c.branch]]


def test_the_damped_backward_crossing_near_118_hz(critical):
    """The issue's case: the damped backward branch falling from 145 Hz (gyroscopic stiffening of the
    backward tilt) crosses 1x near 118 Hz; it is reported as a backward critical speed, and the undamped
    ones (74.4, 142.3, 163.3, 234.3 Hz, none on a damped branch) are kept apart."""
    _, _, _, rep = critical
    back = [c for c in rep["critical_speeds"]["open"] if c["whirl"] == "backward" and 100 < c["speed_hz"] < 140]
    assert len(back) == 1
    # it whirls backward there itself, far from planar (|Im(x^H J x)| / x^H x about 0.4, threshold 1e-3)
    assert back[0]["whirl_at_speed"] == "backward"
    branch = rep["branches"]["open"][back[0]["branch"]]
    assert branch["whirl"] == "backward"
    f = np.array([np.nan if x is None else x for x in branch["frequencies_hz"]])
    # the branch falls monotonically with speed (one mode, not a sort order switching modes where it
    # crosses the 88 Hz branch near 196 Hz)
    assert np.all(np.diff(f) < 0)
    assert rep["undamped_critical_speeds_hz"]["open"][:2] == pytest.approx([22.84, 30.83], abs=0.01)


def test_branches_are_one_mode_each_and_keep_their_label(critical):
    """Along each branch the eigenvectors of neighbouring speeds match (MAC >= MAC_MIN), each branch has
    one label (its whirl at its highest speed), and at every speed > 0 a branch's points whirl in that
    sense or are planar (never the opposite sense)."""
    _, _, _, rep = critical
    res = rep["_results"]["open"]
    B = res.branches
    for b in shown_branches(res):
        idx = np.flatnonzero(np.isfinite(B.frequencies_hz[b]))
        assert np.all(np.diff(idx) == 1)  # no gaps
        last = idx[-1]
        assert B.label[b] == B.whirl[b, last]
        moving = idx[B.speeds_hz[idx] > 0]
        if B.label[b] in (1, -1):
            assert not np.any(B.whirl[b, moving] == -B.label[b]), (b, B.whirl[b])
    names = [br["whirl"] for br in rep["branches"]["open"]]
    assert names.count("backward") >= 3 and "forward" in names and "axial" in names


def test_branch_vectors_match_between_neighbouring_speeds(critical):
    scene, model, red, rep = critical
    from nsfem.analysis.modes import contact_basis

    ops = rotor_operators(model, contact_basis(model, "open", red))
    B = rep["_results"]["open"].branches
    for b in range(B.label.size):
        idx = np.flatnonzero(np.isfinite(B.frequencies_hz[b]))
        for i, j in zip(idx[:-1], idx[1:]):
            if B.speeds_hz[i] > 0:
                m = mac(ops.M, B.vectors[b, i][:, None], B.vectors[b, j][:, None])[0, 0]
                assert m >= MAC_MIN


def test_isotropic_shaft_branches_through_zero_frequency():
    """Rotating frame, isotropic Euler-Bernoulli shaft: the whirl pair is exactly |f0 - Omega| and f0 +
    Omega (test_rotating). Followed as branches, one is f0 + Omega at every speed and the other
    |f0 - Omega|, reflected at Omega = f0 (the conjugate root goes on), not two pieces joined by sort
    order. Tolerance as test_rotating's: eigensolver round-off 9e-11 of f0."""
    model = build_model(scene_from_tree(beam_tree("pinned-pinned", 0.02, 0.02, 30)))
    ops = rotor_operators(model)
    f0 = natural_frequencies(model, "open", 2).frequencies_hz[0]
    speeds = f0 * np.linspace(0.0, 1.57, 15)  # no grid point on Omega = f0 (a double root at 0)
    res = campbell(ops, speeds, 2)
    F = res.branches.frequencies_hz
    for expected in (f0 + speeds, np.abs(f0 - speeds)):
        err = np.abs(F - expected[None, :])
        hit = np.all(err <= 1e-9 * f0, axis=1)
        assert np.count_nonzero(hit) == 1, (expected, F)


def test_rotating_frame_report_has_branches_and_no_damped_critical_speeds():
    scene = load_scene(None)
    model = build_model(scene)
    rep = campbell_report(scene, model, [0.0, 10.0, 20.0], 3, scene_reduction(scene.reduction, model))
    assert rep["frame"] == "rotating" and rep["_critical"] == {"open": [], "closed": []}
    assert all("whirl" not in b for b in rep["branches"]["open"])
    assert len(rep["branches"]["open"]) >= 3


def test_axial_modes_give_no_critical_speed(critical):
    _, _, _, rep = critical
    res = rep["_results"]["open"]
    axial = {j for j, b in enumerate(shown_branches(res)) if res.branches.label[b] == AXIAL}
    assert axial  # the thrust bearing's 29.1 Hz mode crosses 1x but an unbalance does not drive it
    assert not [c for c in rep["_critical"]["open"] if c.branch in axial]


# ------------------------------------------------------------------------------------------ the figure
def _figure(monkeypatch, draw):
    """Run ``draw()`` and return the figure it saves (drawn, not closed)."""
    import nsfem.plot.campbell as pc

    figs = []
    monkeypatch.setattr(pc, "save", lambda fig, path: figs.append(fig) or path)
    draw()
    fig = figs[0]
    fig.canvas.draw()
    return fig


def test_figure_markers_on_curves_labels_and_legend_outside(critical, monkeypatch, tmp_path):
    from nsfem.plot.campbell import report_plot

    scene, _, _, rep = critical
    fig = _figure(monkeypatch, lambda: report_plot(tmp_path / "c.png", rep, scene.title, 26.0))
    ax = fig.axes[0]
    assert ax.get_xlabel() == "rotor speed [Hz]" and ax.get_ylabel() == "frequency [Hz]"
    assert "damped natural frequencies (inertial frame: whirl frequencies)" in ax.get_title()
    lines = {ln.get_label(): ln for ln in ax.lines}
    marks = lines["critical speeds (1x crossings of damped branches)"]
    assert "undamped critical speeds (reference)" in lines and "run speed 26 Hz" in lines
    curves = [ln for ln in ax.lines if ln.get_linestyle() != "None" and len(ln.get_xdata()) > 2]
    for x, y in zip(marks.get_xdata(), marks.get_ydata()):
        # each marker is a vertex of a drawn branch (the crossing inserted into its polyline)
        assert any(np.any((np.asarray(c.get_xdata()) == x) & (np.asarray(c.get_ydata()) == y)) for c in curves)
    # the legend lies below the axes, over no data
    leg = fig.legends[0].get_window_extent()
    assert leg.y1 <= ax.get_window_extent().y0
    # the title is inside the figure (not cut off)
    box = ax.title.get_window_extent()
    assert box.x0 >= 0 and box.x1 <= fig.bbox.x1 and box.y1 <= fig.bbox.y1


def test_crack_title_is_not_cut_off(monkeypatch, tmp_path):
    """The issue's case: the crack scene's title ran past the figure's edge."""
    from nsfem.plot.campbell import report_plot

    scene = load_scene("crack")
    model = build_model(scene)
    rep = campbell_report(scene, model, np.linspace(0.0, 30.0, 7), 4, scene_reduction(scene.reduction, model))
    fig = _figure(monkeypatch, lambda: report_plot(tmp_path / "c.png", rep, scene.title, scene.rotation.speed_hz))
    ax = fig.axes[0]
    box = ax.title.get_window_extent()
    assert box.x0 >= 0 and box.x1 <= fig.bbox.x1 and box.y1 <= fig.bbox.y1
    assert "damped natural frequencies (rotating frame)" in ax.get_title()
    assert fig.legends[0].get_window_extent().y1 <= ax.get_window_extent().y0


# --------------------------------------------------------------------------------------- side effects
def test_png_writes_only_its_file(tmp_path, monkeypatch):
    """`nsfem campbell ross_example --png X` wrote X and ./out/campbell.png; now X only."""
    monkeypatch.chdir(tmp_path)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert cli.main(["campbell", "ross_example", "--speeds", "0:100:11", "--png", "x.png", "--json"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.png"]
    payload = json.loads(out.getvalue())
    assert payload["outputs"] == ["x.png"]
    for key in ("speeds_hz", "frequencies_hz", "whirl", "critical_speeds_hz", "critical_whirl", "critical_speeds",
                "undamped_critical_speeds_hz", "branches", "gravity_resonances_hz", "instability_hz"):
        assert key in payload
    assert not any(k.startswith("_") for k in payload)


@pytest.mark.slow
def test_run_draws_the_campbell_plot_the_scene_lists(tmp_path):
    """ross_example lists campbell in output.plots: `nsfem run` writes campbell.png (it wrote none)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert cli.main(["run", "ross_example", "--out", str(tmp_path / "o"), "--json", "--set",
                         "simulation.t_end=0.05", "--set", "output.vtu_every=0"]) == 0
    outputs = json.loads(out.getvalue())["outputs"]
    assert str(tmp_path / "o" / "campbell.png") in outputs
    assert (tmp_path / "o" / "campbell.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_run_says_why_it_draws_no_campbell_plot(tmp_path, capsys):
    """A scene whose diagram is refused (anisotropic bearings in the rotating frame, at rest: the run is
    fine, the spun diagram is not) gets a warning naming the reason, never a silently missing plot."""
    assert cli.main(["run", "critical_speed", "--out", str(tmp_path), "--set", "rotation.frame=rotating", "--set",
                     "rotation.speed_hz=0", "--set", 'output.plots=["campbell"]', "--set", "simulation.t_end=0.01",
                     "--set", "output.vtu_every=0"]) == 0
    err = capsys.readouterr().err
    assert "plot 'campbell' skipped: rotation.frame: bearing.0 is not isotropic" in err
    assert not (tmp_path / "campbell.png").exists()


# ROSS 2.3.0 on the same rotor (20 Euler-Bernoulli elements with rotary inertia and gyroscopics, no shear;
# disk 20 kg, Id 0.13, Ip 0.25 kg m^2 at midspan; bearings kxx 5e5, kyy 2e6 N/m, 2000 N s/m): the speeds
# where a damped root of its run_modal whirls at the speed (wd = speed, Brent on the root followed by
# nearness, xtol 1e-9 Hz): docs/validation.md
ROSS_DAMPED_CRITICAL_HZ = [23.489836885757, 30.939505488612, 85.742542911515, 119.840136379237, 216.720556795355,
                           221.086896309461]


@pytest.mark.slow
def test_full_model_damped_critical_speeds_match_ross():
    """The full model (105 dofs; the same elements as ROSS's) crosses 1x where ROSS's damped roots do, to
    1e-7 relative (measured 6e-12 to 3e-10: both sides' Brent tolerances and the two codes' round-off; the
    axial mode and thrust bearing ROSS lacks do not couple to bending)."""
    scene = load_scene("critical_speed", ["reduction.method=none"])
    rep = campbell_report(scene, build_model(scene), None, 6)
    assert rep["critical_speeds_hz"]["open"] == pytest.approx(ROSS_DAMPED_CRITICAL_HZ, rel=1e-7)
    assert rep["warnings"] == []


def test_reduced_model_critical_speeds_the_full_model_does_not_confirm_are_warned():
    """A 12-mode modal reduction of critical_speed puts the heavily damped crossings (damping ratios
    0.3-0.85) 1-5 % off the full model's (88.00 against 85.74 Hz, 209.59 against 221.09 Hz): the report
    says so, naming them; the well-separated lightly damped ones (23.48, 30.94 Hz: 4e-4 and 8e-5 off) pass."""
    scene = load_scene("critical_speed", ["reduction.modes=12"])
    model = build_model(scene)
    rep = campbell_report(scene, model, None, 6, scene_reduction(scene.reduction, model))
    assert len(rep["warnings"]) == 1
    text = rep["warnings"][0]
    assert "88.00 Hz" in text and "209.59 Hz" in text and "23.48" not in text and "30.94" not in text
    assert "reduction.modes" in text


def test_shipped_critical_speed_scene_does_not_warn_about_itself(critical):
    """The shipped scene's own reduction keeps its six damped critical speeds within the campbell check's
    0.1 % of the full model's (ROSS's, to 1e-10 above): no warning, and each within 1e-3 relative (the
    check's threshold; 40 modal dofs measured 5.4e-4 at worst, on the 0.86-damped 85.74 Hz crossing)."""
    _, _, _, rep = critical
    assert rep["warnings"] == []
    assert rep["critical_speeds_hz"]["open"] == pytest.approx(ROSS_DAMPED_CRITICAL_HZ, rel=1e-3)


def test_open_ended_and_zero_width_bands(critical, monkeypatch, tmp_path):
    """An instability band open to the top (onset, no end: (a, inf)) is shaded from a to the last speed; a
    zero-width one (an isotropic shaft's double divergence speed) is no band and gets no legend entry."""
    from nsfem.plot.campbell import report_plot

    scene, _, _, rep = critical
    top = rep["speeds_hz"][-1]
    for bands, shaded in (([(100.0, math.inf)], [(100.0, top)]), ([(50.0, 50.0)], [])):
        fig = _figure(monkeypatch, lambda: report_plot(tmp_path / "c.png", {**rep, "_bands": bands}, scene.title))
        ax = fig.axes[0]
        got = [x for p in ax.patches for x in (p.get_x(), p.get_x() + p.get_width())]  # axvspan: data x
        assert got == pytest.approx([x for band in shaded for x in band], rel=1e-12)
        assert ("unstable" in [t.get_text() for t in fig.legends[0].get_texts()]) == bool(shaded)


# --- issue 34: the text of `nsfem campbell` for a rotor without contacts ---
def test_text_of_a_rotor_without_contacts_has_no_closed_rows_and_says_none(capsys):
    """ross_example has no contacts: its "closed" rows only repeated the open ones, and an empty list
    printed as nothing after the colon; now the closed rows are left out and an empty list reads "none"
    (the JSON keeps both keys)."""
    from nsfem import cli

    assert cli.main(["campbell", "ross_example", "--speeds", "0:60:7", "--count", "4"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert not any("closed:" in line for line in lines), lines
    assert "instability onsets [Hz]  open: none" in lines
    assert all(not line.rstrip().endswith(":") for line in lines), lines
    assert cli.main(["campbell", "ross_example", "--speeds", "0:60:7", "--count", "4", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["critical_speeds_hz"]["closed"] == rep["critical_speeds_hz"]["open"]


# --- issue 35: Campbell by log decrement (JSON log_decrements, the figure coloured by them) ---
def test_json_log_decrements_are_those_of_the_state_space_roots(critical):
    """``log_decrements`` (aligned with ``frequencies_hz``) at a speed are -2 pi Re(s) / Im(s) of the roots of the
    damped eigenproblem there: nsfem.analysis.damped's modes (the same roots, ``modes --speed``) and, independently,
    the companion pencil solved by QZ. Tolerances: both solves resolve a root to a few eps x cond of this 80-state
    pencil (measured 3e-15 to 7e-11 of |s|, test above); the log dec's error is 2 pi |ds| / Im s <= 2 pi 1e-10 |s|
    / Im s, about 1e-8 absolute for these roots (|s| / Im s <= 2 at the 0.86-damped one; measured against QZ 1.6e-9
    and 9.9e-9; against damped_modes, which solves the same system, 0): 1e-6 abs leaves room for other BLAS
    kernels; the frequencies to 1e-9 relative for the same reason."""
    from nsfem.analysis.damped import damped_modes
    from nsfem.analysis.modes import contact_basis

    scene, model, red, rep = critical
    damp = scene.damping
    ops = rotor_operators(model, contact_basis(model, "open", red))
    D = np.array(rep["log_decrements"], dtype=float)
    F = np.array(rep["frequencies_hz"], dtype=float)
    assert D.shape == F.shape and np.array_equal(np.isnan(D), np.isnan(F))
    for i in (12, 40):  # 57.6 and 192.1 Hz: between critical speeds
        speed = rep["speeds_hz"][i]
        modes = damped_modes(model, ops, speed, 6, damp.rayleigh, damp.external, "inertial")
        assert modes.frequencies_hz == pytest.approx(F[i], rel=1e-9)
        assert modes.log_decrements == pytest.approx(D[i], abs=1e-6)
        lam = direct_eigenvalues(linear_system(ops, speed, 0.0, 0.0, damp.rayleigh, damp.external, "inertial"))
        lam = lam[lam.imag > 0]
        for f, d in zip(F[i], D[i]):
            s = lam[np.argmin(np.abs(lam.imag / (2 * math.pi) - f))]
            assert d == pytest.approx(-2 * math.pi * s.real / abs(s.imag), abs=1e-6)
    # each damped critical speed carries its crossing root's log dec, consistent with its damping ratio
    for c in rep["critical_speeds"]["open"]:
        z = c["damping_ratio"]
        assert c["log_decrement"] == pytest.approx(2 * math.pi * z / math.sqrt(1 - z * z), rel=1e-12, abs=1e-15)


def _bands(ax):
    """The coloured LineCollections of the branches: (segments, RGBA colours)."""
    from matplotlib.collections import LineCollection

    out = [(c.get_segments(), c.get_colors() if len(c.get_array()) == 0 else c.to_rgba(c.get_array()))
           for c in ax.collections if isinstance(c, LineCollection)]
    return [(np.array(s), np.array(col)) for s, col in out]


def test_figure_colours_branches_by_log_dec_and_draws_an_unstable_branch_red(monkeypatch, tmp_path):
    """ross_example with a strong cross-coupled bearing (kyz = -kzy = 5e6 N/m: a circulatory force that feeds forward
    whirl) has a growing forward branch: the figure has a "log dec" colour bar, is written, and draws the branch's
    segments where its log dec < 0 in the unstable colour, stable segments never in it."""
    from matplotlib.colors import to_rgba

    from nsfem.plot.campbell import UNSTABLE_COLOUR, report_plot

    scene = load_scene("ross_example", ["bearing.0.kyz=5e6", "bearing.0.kzy=-5e6", "bearing.0.cyy=200",
                                        "bearing.0.czz=200", "reduction.modes=12"])
    model = build_model(scene)
    rep = campbell_report(scene, model, np.linspace(0.0, 60.0, 13), 4, scene_reduction(scene.reduction, model))
    D = np.array(rep["log_decrements"], dtype=float)
    assert np.nanmin(D) < -1e-3 and np.nanmax(D) > 0  # the case: a growing and a decaying mode
    fig = _figure(monkeypatch, lambda: report_plot(tmp_path / "c.png", rep, scene.title))
    bar = [a for a in fig.axes if "log dec" in a.get_ylabel()]
    assert len(bar) == 1
    red = np.array(to_rgba(UNSTABLE_COLOUR))
    res = rep["_results"]["open"]
    B = res.branches
    unstable_points = [(s, f) for b in shown_branches(res) for s, f, lam in
                       zip(B.speeds_hz, B.frequencies_hz[b], B.eigenvalues[b]) if lam.real > res.resolution_per_s]
    assert unstable_points
    segs = np.concatenate([s for s, _ in _bands(fig.axes[0])])
    cols = np.concatenate([c for _, c in _bands(fig.axes[0])])
    is_red = np.all(np.isclose(cols, red), axis=1)
    for s, f in unstable_points:   # every segment ending on a growing root is red
        ends = np.any(np.all(np.isclose(segs, [s, f], rtol=1e-12, atol=0), axis=2), axis=1)
        assert ends.any() and is_red[ends].all(), (s, f)
    # and no segment between two decaying roots is
    stable = [(s, f) for b in shown_branches(res) for s, f, lam in
              zip(B.speeds_hz, B.frequencies_hz[b], B.eigenvalues[b]) if lam.real < -res.resolution_per_s]
    for k in np.flatnonzero(is_red):
        assert not all(any(np.allclose(p, q, rtol=1e-12, atol=0) for q in stable) for p in segs[k])
    # the legend lists each damped critical speed with its log dec
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    for c in rep["critical_speeds"]["open"]:
        assert any(t.startswith(f"{c['speed_hz']:.2f} Hz ({c['whirl']}") and f"): log dec {c['log_decrement']:.3g}" in t
                   for t in texts), texts
    # written through the real save: a PNG
    monkeypatch.undo()
    path = report_plot(tmp_path / "written.png", rep, scene.title)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# --- issue 35 review: every line of the Campbell legend can be told apart ---
@pytest.mark.slow   # stepped_rotor's campbell under pytest: 30-40 s on a loaded 2-core machine
def test_campbell_legend_lines_are_distinct(monkeypatch):
    """stepped_rotor has an axial branch (its thrust bearing): since the branches' lines are all black (their colour
    is the log dec's band), the axial branch's line must not share the 1x line's style, or the legend cannot tell
    the two apart (both were ':' black)."""
    import nsfem.plot.campbell as pc

    figs = []
    monkeypatch.setattr(pc, "save", lambda fig, path: figs.append(fig) or path)
    scene = load_scene("stepped_rotor")
    model = build_model(scene)
    rep = campbell_report(scene, model, None, 6, scene_reduction(scene.reduction, model))   # (61 speeds: 4 s)
    pc.report_plot("unused.png", rep, scene.title, scene.rotation.speed_hz)
    legend = figs[0].legends[0]
    seen = {}
    for handle, text in zip(legend.legend_handles, [t.get_text() for t in legend.get_texts()]):
        if hasattr(handle, "get_linestyle") and handle.get_linestyle() not in ("None", "none", "") and text:
            key = (str(handle.get_linestyle()), str(getattr(handle, "_unscaled_dash_pattern", "")),  # (a custom dash reads '--')
                   handle.get_color() if hasattr(handle, "get_color") else None, getattr(handle, "get_marker",
                                                                                        lambda: None)())
            assert key not in seen, (text, seen.get(key))
            seen[key] = text
    assert "axial" in seen.values() and any(t.startswith("1x") for t in seen.values())
