"""``nsfem run``: the JSON contract, the results file, interruption (design section 5)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from nsfem import cli, load_scene
from nsfem.errors import NsfemError
from nsfem.integrate import configuration
from nsfem.result import Result

RUN_KEYS = ("method", "t_end", "wall_s", "ndof_full", "ndof", "events", "impacts", "min_gap_m", "max_gap_m",
            "closed_fraction", "max_normal_force_N", "energy", "outputs")
SHORT = ["--set", "mesh.elements=20", "--set", "simulation.t_end=0.05", "--set", "simulation.output_dt=0.005"]
#: relative energy residual allowed to ``exact``. Its work integrals use 4-point Gauss-Legendre on a
#: grid of 1/8 of the fastest period, which integrates a mode of that period to
#: (pi/4)^8 4!^4 / (9 8!^3) = 8e-11 of its work per step; the modal propagation adds cond(V) eps
#: per phase (cond(V) = 3e4..3e5 on these scenes: 7e-12..7e-11). Measured 7e-14..6e-12 under four
#: BLAS kernels (up to 84 events).
EXACT_ENERGY = 1e-9


def test_run_json_contract_and_results_file(tmp_path, capsys):
    assert cli.main(["run", "--json", "--out", str(tmp_path), *SHORT]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in RUN_KEYS:
        assert key in out, key
    assert out["method"] == "exact" and out["t_end"] == pytest.approx(0.05) and out["completed"]
    assert out["energy"] < EXACT_ENERGY  # closed-form propagation (measured <= 3e-13)
    path = tmp_path / "result.npz"
    # the results file, then the plots of output.plots that have data (0.05 s: no contact force yet)
    assert out["outputs"][0] == str(path) and str(tmp_path / "phase.png") in out["outputs"]
    assert str(tmp_path / "gap.png") in out["outputs"]
    assert all(Path(p).stat().st_size > 10_000 for p in out["outputs"] if p.endswith(".png"))
    assert out["outputs"][-1] == str(tmp_path / "nsfem.pvd")   # VTU series every output.vtu_every steps
    with np.load(path) as r:  # numpy alone
        meta = json.loads(str(r["meta"]))
        assert r["t"].shape == (11,) and r["gap"].shape == (9, 11)
        # k x 0.005 with t_end itself last; linspace rounds its own way, within an ulp or two
        np.testing.assert_allclose(r["t"], np.linspace(0, 0.05, 11), rtol=1e-15, atol=0)
        q_full = r["basis"] @ r["q"]
        assert q_full.shape[1] == 11
    assert "delamination" in meta["scene"] and meta["scene_tree"]["simulation"]["t_end"] == 0.05
    res, meta, extra = Result.load(path)
    assert res.summary()["events"] == out["events"] and extra["contact_x"].shape == (9,)


def test_run_rk_agrees_with_exact(tmp_path, capsys):
    gaps = {}
    for method in ("exact", "rk"):
        assert cli.main(["run", "--json", "--method", method, "--out", str(tmp_path / method), *SHORT,
                         "--set", "simulation.rtol=1e-10", "--set", "simulation.atol=1e-14"]) == 0
        json.loads(capsys.readouterr().out)
        with np.load(tmp_path / method / "result.npz") as r:
            gaps[method] = r["gap"]
    # rk at rtol 1e-10 against the closed form: DOP853's global error is a small multiple of rtol
    # (measured 7.4e-11..7.5e-11 of the largest gap under four BLAS kernels); allowed 100 rtol
    assert np.abs(gaps["exact"] - gaps["rk"]).max() <= 1e-8 * np.abs(gaps["exact"]).max()


@pytest.mark.parametrize("args, match", [
    (["--method", "euler"], "invalid choice"),
    (["--set", "simulation.moreau_step=0.01"], "moreau_step"),
    (["--set", "simulation.moreau_theta=0.3"], "moreau_theta"),
    (["--set", "simulation.stiff_solver=RK45"], "stiff_solver"),
    (["--set", "simulation.output_dt=2"], "output_dt"),
    (["--set", "simulation.rtol=2"], "rtol"),
    (["--set", "simulation.rk_solver=LSODA"], "rk_solver"),
])
def test_run_rejects_bad_input_before_computing(args, match, capsys):
    assert cli.main(["run", *args]) == cli.EXIT_ERROR
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0]


def test_interrupted_run_leaves_a_valid_results_file(tmp_path, capsys, monkeypatch):
    """Ctrl-C during the integration: the file holds the run up to the last output, exit 130."""
    calls = {"n": 0}
    original = configuration.Phase.xi

    def xi(self, t):
        if not calls["n"] and np.max(t) > 0.05:  # one Ctrl-C, once the run is past 0.05 s
            calls["n"] += 1
            raise KeyboardInterrupt
        return original(self, t)

    monkeypatch.setattr(configuration.Phase, "xi", xi)
    code = cli.main(["run", "--json", "--out", str(tmp_path), "--set", "mesh.elements=20",
                     "--set", "simulation.t_end=0.2", "--set", "simulation.output_dt=0.001"])
    assert code == 130
    out = json.loads(capsys.readouterr().out)
    assert out["completed"] is False
    res, meta, _ = Result.load(tmp_path / "result.npz")
    assert not res.completed and 0 < res.t.size < 201
    assert np.all(np.diff(res.t) > 0) and res.gap.shape == (9, res.t.size)
    # the work integrals stop where the state does: the balance holds for the partial run
    assert out["energy"] < EXACT_ENERGY  # measured <= 2.7e-13


def test_failed_run_keeps_its_results(tmp_path, capsys, monkeypatch):
    """Review D7: an error during the integration (here a contact problem that fails at the
    third event) still writes the run up to there, names the file, exits 2."""
    from nsfem.integrate import event_driven

    calls = {"n": 0}
    original = event_driven.resolve

    def resolve(*args, **kw):
        calls["n"] += 1
        if calls["n"] == 3:
            raise NsfemError("transition LCP (29) at t = 0.1 s: no solution (injected)")
        return original(*args, **kw)

    monkeypatch.setattr(event_driven, "resolve", resolve)
    code = cli.main(["run", "--json", "--out", str(tmp_path), "--set", "simulation.t_end=0.2"])
    assert code == cli.EXIT_ERROR
    err = capsys.readouterr().err
    assert "injected" in err and str(tmp_path / "result.npz") in err
    res, meta, _ = Result.load(tmp_path / "result.npz")
    assert not res.completed and "injected" in meta["info"]["error"] and 0 < res.t[-1] < 0.2
    assert res.energy["relative_residual"] < EXACT_ENERGY  # measured <= 8.1e-13


@pytest.mark.parametrize("extra, horizon", [
    # 40 modes: the layer lands on contacts 2, 5, 6 at 0.166 s; each plastic closure of 5 lifted 2
    # by 1e-15 m and back (review D1: 926 events in 1e-5 s); such lifts stay closed
    (["--set", "reduction.modes=40"], 0.2),
    # a stop under midspan with eps = 0.5, rebounds shorter than the sampling step (review D1: stalled at 2.2 ms)
    (["--set", 'obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]'], 0.02),
])
def test_run_impact_clusters_end(extra, horizon, tmp_path, capsys):
    """Impact clusters end in persistent contact: no window of 1e-5 s holds more than 100
    events (a resolved sequence with eps <= 0.5 reaches the gap band in <= 20 impacts per
    contact; before the fix: 926), every impact dissipates (frictionless Newton impacts with
    eps <= 1 and settling projections cannot add kinetic energy), and the work balance holds."""
    assert cli.main(["run", "--json", "--out", str(tmp_path), *extra, "--set", f"simulation.t_end={horizon}"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["completed"] and out["energy"] < EXACT_ENERGY and out["impacts"] >= 3  # energy: <= 6e-12
    res, meta, _ = Result.load(tmp_path / "result.npz")
    t = np.array([e["t"] for e in meta["events"]])
    # <= 20 impacts per contact and sequence (0.25^20 of a rebound's height is below the 1e-11 band),
    # three contacts landing together: ~60 with their closures (measured 7 and 12; 926 before)
    assert np.max(np.searchsorted(t, t + 1e-5) - np.arange(t.size)) <= 100
    for imp in meta["impacts"]:
        # round-off of 1/2 v^T M v after the impact LCP, ~n eps = 65 x 2.2e-16 = 1.4e-14 of it (the
        # smallest loss measured is 2.3e-11 of the kinetic energy)
        assert imp["kinetic_after_J"] <= imp["kinetic_before_J"] * (1 + 1e-12), imp["t"]
    assert all(e["before"] != e["after"] or e["impact"] or e["graze"] for e in meta["events"])


def test_four_methods_agree_on_the_shipped_scene():
    """Shipped scene from rest, 0.1 s (the interface touches at midspan once): every method
    within its expected error of `exact` in max |g - g_exact| / max |g_exact| (measured under
    four BLAS kernels: rk at rtol 1e-10 6.0e-10..6.1e-10; moreau 2.0e-2 at h = 1e-4 s and 2.7e-3
    at 2.5e-5 s; penalty 3.9e-5 at factor 100 and 3.6e-6 at 1000). Bounds: rk 100 rtol (a small
    multiple of rtol, as in test_run_rk_agrees_with_exact); moreau 5e-2 and, first order (1/4
    expected), at least 2x better at a quarter of the step; penalty 1e-3 (a static contact
    penetrates k / c_p = 1 % of its deflection at factor 100; this light touch much less) and,
    its error falling like 1 / c_p (static) to 1 / sqrt(c_p) (impact), 0.3x or better at 10x
    the stiffness (1 / sqrt(10) = 0.32 would be an impact's)."""
    from nsfem import load_scene
    from nsfem.simulate import run_scene

    gaps = {}
    for name, sets in [("exact", []), ("rk", ["simulation.rtol=1e-10", "simulation.atol=1e-14"]),
                       ("moreau", ["simulation.moreau_step=1e-4"]), ("moreau4", ["simulation.moreau_step=2.5e-5"]),
                       ("penalty", []), ("penalty_stiff", ["simulation.penalty_factor=1e3"])]:
        scene = load_scene(None, ["simulation.t_end=0.1", *sets])
        res, _ = run_scene(scene, name.rstrip("4").replace("_stiff", ""))
        assert res.completed and res.t.size == 101
        gaps[name] = res.gap
    ref = gaps["exact"]
    err = {k: float(np.abs(g - ref).max() / np.abs(ref).max()) for k, g in gaps.items()}
    assert err["rk"] < 1e-8
    assert err["moreau"] < 5e-2 and err["moreau4"] < 0.5 * err["moreau"]
    assert err["penalty"] < 1e-3 and err["penalty_stiff"] < 0.3 * err["penalty"]


def test_exact_and_rk_agree_through_impact_sequences():
    """A stop 0.2 mm under midspan, eps = 0.5: sequences of ~15 impacts every revolution, each
    ending by settling. exact and rk (rtol 1e-12) must cut them alike (same zero bands; rk
    restarts at the top of a rebound) and agree on the gaps to 1e-7 of the largest (measured
    1.6e-11..5.3e-11 under four BLAS kernels, 1.5e-9 over 0.05 s; before rk had bands of its
    own and restarts: 12 %). Not rtol-limited (that is 53 rtol here): each of the >= 20 impacts
    restarts rk from its own state, so the bound is kept well above the 0.05 s value."""
    from nsfem import load_scene
    from nsfem.integrate import ContactSystem, integrate

    scene = load_scene(None, ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]'])
    s = ContactSystem.from_scene(scene)
    a = integrate(s, 0.02, "exact", 1e-4)
    b = integrate(s, 0.02, "rk", 1e-4, rtol=1e-12, atol=1e-16)
    assert len(a.impacts) >= 20
    assert np.abs(a.gap - b.gap).max() <= 1e-7 * np.abs(a.gap).max()


def test_penalty_warns_that_it_neglects_friction(tmp_path, capsys):
    assert cli.main(["run", "--method", "penalty", "--out", str(tmp_path), "--set", "delamination.0.friction=0.3",
                     "--set", "simulation.t_end=0.002", "--set", "simulation.output_dt=0.001"]) == 0
    assert "penalty neglects friction" in capsys.readouterr().err


def test_export_rewrites_the_vtu_series_of_a_results_file(tmp_path, capsys):
    """nsfem export rebuilds the model from the scene stored in the results file: the series
    it writes is byte-identical to the one nsfem run wrote (shipped scene with an override)."""
    assert cli.main(["run", "--out", str(tmp_path / "run"), "--set", "simulation.t_end=0.02",
                     "--set", "output.plots=[]", "--set", "output.vtu_every=5"]) == 0
    assert cli.main(["export", str(tmp_path / "run" / "result.npz"), "--vtu", str(tmp_path / "again")]) == 0
    capsys.readouterr()
    written = sorted(str(p.relative_to(tmp_path / "run")) for p in (tmp_path / "run").glob("vtu/*.vt[um]"))
    # 5 frames of the stack, its contacts and the .vtm naming them, in the subfolder vtu/
    assert len(written) == 3 * 5 and written == sorted(str(p.relative_to(tmp_path / "again"))
                                                      for p in (tmp_path / "again").glob("vtu/*.vt[um]"))
    for name in written + ["nsfem.pvd"]:
        assert (tmp_path / "run" / name).read_bytes() == (tmp_path / "again" / name).read_bytes(), name
    assert cli.main(["export", str(tmp_path / "missing.npz"), "--vtu", str(tmp_path / "x")]) == cli.EXIT_ERROR
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.parametrize("overrides, unstable", [
    (["rotation.speed_hz=120"], True),                  # flutter past the open bands (campbell: 255 1/s)
    (["delamination.0.upper_height=0.0199"], True),     # a 0.1 mm sub-beam diverges from 0.85 Hz on
    ([], False),                                        # the shipped scene: stable at 21 Hz
])
def test_run_warns_when_the_open_structure_is_unstable(overrides, unstable):
    """Found by studies/extremes.py: runs at 120 Hz and with a very thin sub-beam grew to 1e20 m
    without a word. The growth rate of the contact-free linearization (its eigenvalues) is the
    independent check: Campbell's growth rate at 120 Hz is 255 1/s, three digits (0.2 %); the
    20-element mesh moves it by 3e-5 relative and round-off by far less (254.566 measured under
    four BLAS kernels), allowed 0.5 %."""
    from nsfem.simulate import growth_rate, run_scene

    said = []
    scene = load_scene(None, ["mesh.elements=20", "simulation.t_end=0.001", *overrides])
    result, system = run_scene(scene, warn=said.append)
    grows = [w for w in said if "unstable at" in w]
    assert bool(grows) == unstable
    if overrides == ["rotation.speed_hz=120"]:
        assert growth_rate(system) == pytest.approx(255, rel=5e-3)


# --- issue 34: the run's counts, one definition (nsfem.contact.tally) ---------------------------------------
def test_impact_only_run_reports_its_impulses_not_a_zero_force(tmp_path, capsys):
    """A shaft bouncing on a stop with restitution 1 never rests on it: the JSON and the text give its impacts
    and largest impulse, and say there was no sustained force instead of "max normal force 0 N"."""
    from test_plots import STOP_TOML

    scene = tmp_path / "stop.toml"
    scene.write_text(STOP_TOML)
    assert cli.main(["run", str(scene), "--out", str(tmp_path / "o"), "--set", "output.plots=[]",
                     "--set", "output.vtu_every=0"]) == 0
    text = capsys.readouterr().out
    res, meta, _ = Result.load(tmp_path / "o" / "result.npz")
    s = meta["summary"]
    largest = max(max(im["impulse_Ns"]) for im in res.impacts)
    assert s["max_normal_force_N"] == 0.0 and s["impacts"] == len(res.impacts) > 3
    assert s["max_impulse_Ns"] == largest > 0
    (part,) = s["parts"]
    assert (part["name"], part["kind"], part["impacts"], part["max_impulse_Ns"]) == ("obstacle.0", "stop",
                                                                                       s["impacts"], largest)
    assert "max normal force 0 N" not in text
    assert f"no sustained normal force, largest impulse {largest:.3g} N s at one contact point" in text
    assert f"obstacle.0 (stop, 1 contact point): {s['impacts']} impacts (largest impulse {largest:.3g} N s)" in text


def test_run_json_parts_agree_with_the_run(tmp_path, capsys):
    """The shipped scene's JSON: one part, delamination.0, whose impacts are the run's and whose closed share,
    booked from the events' closure times, is the run's closed_fraction (booked by the integrator between
    events): the same intervals summed in another order, round-off of t_end (1e-15) over the run."""
    assert cli.main(["run", "--json", "--out", str(tmp_path), "--set", "simulation.t_end=0.3",
                     "--set", "output.plots=[]", "--set", "output.vtu_every=0"]) == 0
    out = json.loads(capsys.readouterr().out)
    (part,) = out["parts"]
    assert part["name"] == "delamination.0" and part["kind"] == "delamination" and part["contacts"] == 9
    assert part["impacts"] == out["impacts"] > 0
    assert out["closed_fraction"] > 0 and part["closed_fraction"] == pytest.approx(out["closed_fraction"], rel=1e-9)
    assert part["max_point_force_N"] == out["max_normal_force_N"] <= part["max_normal_force_N"]
    assert out["max_impulse_Ns"] <= part["max_impulse_Ns"]


# --- issue 34: contact plots of a rotor without contacts ---
def test_contact_plots_of_a_scene_without_contacts_are_skipped_silently_unless_listed(tmp_path, capsys):
    """A rotor without contacts that leaves output.plots to its default (which lists gap and forces) gets no
    warning about them; a scene that lists them itself is still told why they are missing."""
    from nsfem import cli
    from nsfem.scene.load import scene_file

    text = scene_file("critical_speed").read_text(encoding="utf-8")
    assert 'plots = ["psd"]' in text
    path = tmp_path / "rotor.toml"
    path.write_text(text.replace('plots = ["psd"]', ""), encoding="utf-8")
    short = ["--set", "simulation.t_end=0.05", "--set", "output.vtu_every=0"]
    assert cli.main(["run", str(path), *short, "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    assert "skipped" not in err, err
    # (bearings.png: the scene's bearings' forces, drawn whenever plots are, issue 35)
    assert sorted(p.name for p in (tmp_path / "a").glob("*.png")) == ["bearings.png", "phase.png", "psd.png",
                                                                      "sensors.png"]
    assert cli.main(["run", str(path), *short, "--set", 'output.plots=["gap", "psd", "forces"]',
                     "--out", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err
    assert "plot 'gap' skipped" in err and "plot 'forces' skipped" in err
