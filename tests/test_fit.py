"""Parameter estimation (``nsfem fit``): the truth back from its own data, honest intervals, the
parameters the data cannot see reported, bad inputs refused before any run.

The scene: the shipped delaminated shaft, 20 elements, 6 Craig-Bampton modes, a 0.1 s record from
rest of two probes outside the delamination (x = 0.05 m, +z; x = 0.95 m, +y); a run takes about
0.05 s. The fitted key is the delamination's start (truth 0.23 m in 0.1..0.4 m). The mirrored
delamination: the same shaft from its stationary state, probes at its middle (``SYMMETRIC``).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from nsfem import cli
from nsfem.errors import NsfemError
from nsfem.fit import fit
from nsfem.scene import load_scene
from nsfem.simulate import run_scene, sensor_signals

FIXED = ["mesh.elements=20", "reduction.modes=6", 'sensor.0.name="a"', "sensor.0.x=0.05", 'sensor.0.direction="+z"',
         'sensor.1.name="b"', "sensor.1.x=0.95", 'sensor.1.direction="+y"']
KEY, TRUTH, RANGE = "delamination.0.start", 0.23, (0.1, 0.4)


def measure(extra=(), t_end=0.1, noise=0.0, seed=0):
    """(t, {name: signal}) of the scene at the truth, with white noise of ``noise`` x each signal's RMS."""
    scene = load_scene(None, [*FIXED, f"{KEY}={TRUTH}", f"simulation.t_end={t_end}", *extra])
    result, system = run_scene(scene)
    v = sensor_signals(result, system)
    v = v + noise * np.sqrt(np.mean(v**2, axis=0)) * np.random.default_rng(seed).standard_normal(v.shape)
    return result.t, {"a": v[:, 0], "b": v[:, 1]}


def write_csv(path, t, signals):
    names = list(signals)
    rows = [",".join(repr(float(x)) for x in (ti, *(signals[n][k] for n in names))) for k, ti in enumerate(t)]
    path.write_text("\n".join([",".join(["t", *names]), *rows]) + "\n")
    return path


@pytest.fixture(scope="module")
def inprocess():
    """A one-thread in-process cluster (no process start-up)."""
    distributed = pytest.importorskip("distributed")
    c = distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0")
    yield c
    c.close()


@pytest.fixture(scope="module")
def clean():
    return measure()


def test_noise_free_data_give_back_the_truth(inprocess, clean, tmp_path):
    # from the global stage (16 Sobol samples over the range) and from two starts on either side of
    # the truth: the misfit of contact dynamics is rugged (events come and go), its basin about the
    # truth about +-0.01 m wide; the global stage's job is to land in it
    lines = []
    # (refine=False: the data come from this model, so its discretization error is not in them)
    res = fit(None, clean, {KEY: RANGE}, overrides=FIXED, client=inprocess, out_dir=tmp_path / "g",
              progress=lines.append, refine=False)
    width = RANGE[1] - RANGE[0]
    assert abs(res.estimate[0] - TRUTH) < 1e-5 * width and res.misfit < 1e-3
    assert not res.warnings and res.identifiable
    # the residual variance is floored at the resolution (RESOLUTION): round-off alone made an interval
    # 2.4e-7 m wide, 4 half-widths off the truth
    assert res.interval[0, 0] <= TRUTH <= res.interval[0, 1] and np.diff(res.interval[0])[0] < 1e-4 * width
    assert res.info["global_samples"] == 16 and any(line.startswith("[global") for line in lines)
    for start in (0.222, 0.236):
        other = fit(None, clean, {KEY: RANGE}, overrides=FIXED, client=inprocess, out_dir=tmp_path / str(start),
                    n_global=0, start={KEY: start}, plot=False)
        assert abs(other.estimate[0] - TRUTH) < 1e-5 * width
    payload = json.loads((tmp_path / "g" / "fit.json").read_text())
    p = payload["parameters"][KEY]
    assert p["at_bound"] is False and p["identified"] is True and p["interval"][0] <= p["estimate"] <= p["interval"][1]
    assert payload["runs"] == len(res.evaluations) and payload["misfit"] == pytest.approx(res.misfit)
    assert len(payload["global_stage"]["samples"]) == 16 and payload["identifiability"]["rank"] == 1
    for name in ("fit.json", "evaluations.csv", "fit.png", "landscape.png"):
        assert (tmp_path / "g" / name).is_file() and str(tmp_path / "g" / name) in res.outputs
    rows = (tmp_path / "g" / "evaluations.csv").read_text().splitlines()
    assert rows[0] == f"run,stage,{KEY},misfit,error" and len(rows) == 1 + len(res.evaluations)


def test_bad_inputs_are_one_line_errors_before_any_run(clean, tmp_path, monkeypatch):
    import nsfem.sweep

    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster was started")

    monkeypatch.setattr(nsfem.sweep, "_client", no_cluster)
    t, sig = clean
    good = write_csv(tmp_path / "good.csv", t, sig)
    cases = {
        "no t": (write_csv(tmp_path / "x.csv", t, {"a": sig["a"]}).read_text().replace("t,a", "time,a"),
                 {KEY: RANGE}, "no column 't'"),
        "unknown column": (write_csv(tmp_path / "x.csv", t, {"a": sig["a"], "c": sig["b"]}).read_text(), {KEY: RANGE},
                           "column 'c' is no sensor of the scene"),
        "NaN": (good.read_text().replace(repr(float(sig["b"][5])), "nan", 1), {KEY: RANGE},
                "column 'b' holds NaN or inf at line 7"),
        "duplicate column": ("t,a,a\n0,1,2\n0.1,3,4\n", {KEY: RANGE}, "column 'a' appears 2 times in the header"),
        "t not increasing": ("t,a\n0,1\n0.2,2\n0.1,3\n", {KEY: RANGE}, "t must increase"),
        # a duplicated time stamp a rounding step apart: the runs would output at 1e-9 s
        "t nearly repeated": ("t,a\n0,1\n0.001,2\n0.001000001,3\n0.002,4\n", {KEY: RANGE},
                              "lines 3 and 4 lie 1e-09 s apart"),
        "unknown key": (None, {"delamination.0.begin": RANGE}, "delamination.0.begin: unknown key"),
        "no such delamination": (None, {"delamination.3.start": RANGE}, "the scene has no delamination.3"),
        # one past the end: an override would append an item (a crack the scene does not have)
        "no crack": (None, {"crack.0.x": (0.95, 0.99)}, "the scene has no crack.0 "),
        "no second delamination": (None, {"delamination.1.start": RANGE}, "the scene has no delamination.1 "),
        "LOW >= HIGH": (None, {KEY: (0.4, 0.1)}, "LOW must be below HIGH"),
        "invalid at an end": (None, {KEY: (0.1, 0.95)}, f"at {KEY}=0.95: delamination.0.end: must exceed start"),
    }
    for name, (text, vary, message) in cases.items():
        path = good
        if text is not None:
            path = tmp_path / f"{name}.csv"
            path.write_text(text)
        with pytest.raises(NsfemError, match=message) as info:
            fit(None, path, vary, overrides=FIXED, out_dir=tmp_path / "out")
        assert "\n" not in str(info.value), name
    with pytest.raises(NsfemError, match="varied twice"):
        fit(None, good, [f"{KEY}=0.1:0.4", f"{KEY}=0.1:0.3"], overrides=FIXED)
    with pytest.raises(NsfemError, match="workers= cannot be combined with client="):
        fit(None, good, {KEY: RANGE}, overrides=FIXED, client=object(), workers=2)
    # a spreadsheet's UTF-8 byte-order mark before the header is not part of the column 't'
    from nsfem.measurement import read_measurement

    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + good.read_bytes())
    assert read_measurement(bom).names == ("a", "b")
    with pytest.raises(NsfemError, match="both varied and fixed"):
        fit(None, good, {KEY: RANGE}, overrides=[*FIXED, f"{KEY}=0.2"])
    # the command line: exit code 2 and one line on stderr
    argv = ["fit", "--data", str(tmp_path / "no t.csv"), "--vary", f"{KEY}=0.1:0.4", "--out", str(tmp_path / "o")]
    for o in FIXED:
        argv += ["--set", o]
    assert cli.main(argv) == cli.EXIT_ERROR


def test_a_key_the_sensors_do_not_see_is_not_identified(inprocess, clean, tmp_path):
    # simulation.rtol is the tolerance of rk; the exact integrator does not read it: its Jacobian
    # column is zero, the rank 1 of 2, and its interval the whole range
    res = fit(None, clean, {KEY: RANGE, "simulation.rtol": (1e-9, 1e-6)}, overrides=FIXED, client=inprocess,
              out_dir=tmp_path, n_global=0, start={KEY: 0.232}, plot=False)
    assert abs(res.estimate[0] - TRUTH) < 1e-5 * (RANGE[1] - RANGE[0])
    assert res.identified.tolist() == [True, False]
    payload = res.to_json()
    ident = payload["identifiability"]
    assert ident["rank"] == 1 and ident["not_identified"] == ["simulation.rtol"]
    [direction] = ident["directions"]
    assert direction["reason"] == "rank" and direction["keys"] == ["simulation.rtol"]
    assert payload["parameters"]["simulation.rtol"]["interval"] == [1e-9, 1e-6]
    assert payload["correlation"]["matrix"][1][1] is None


#: the shipped shaft (pinned-pinned, mirror-symmetric about x = 0.5 m) seen by two probes at its middle, on the
#: lower layer of the delamination, from its stationary state: a delamination at [a, b] and its mirror image
#: [1 - b, 1 - a] give the same signals (to 5e-11 of their RMS)
SYMMETRIC = ["mesh.elements=20", "reduction.modes=6", 'initial.state="stationary"',
             'sensor.0.name="a"', "sensor.0.x=0.5", 'sensor.0.layer="lower"', 'sensor.0.direction="+z"',
             'sensor.1.name="b"', "sensor.1.x=0.5", 'sensor.1.layer="lower"', 'sensor.1.direction="+y"']


def test_a_mirrored_delamination_is_not_identifiable(inprocess, tmp_path, monkeypatch, capsys):
    # noise-free data of a delamination at [0.2, 0.6] m; the box holds it and its mirror [0.4, 0.8] m. The 32
    # samples of the global stage (16 miss a basin): the best (0.23) lies in one basin, one within twice its
    # misfit (0.25) in the other: two local stages, two minima at round-off, F = 1, p = 0.5: not identifiable
    scene = load_scene(None, [*SYMMETRIC, "delamination.0.start=0.2", "delamination.0.end=0.6",
                              "simulation.t_end=0.05"])
    result, system = run_scene(scene)
    v = sensor_signals(result, system)
    lines = []
    res = fit(None, (result.t, {"a": v[:, 0], "b": v[:, 1]}),
              {"delamination.0.start": (0.1, 0.45), "delamination.0.end": (0.55, 0.9)}, overrides=SYMMETRIC,
              client=inprocess, out_dir=tmp_path, plot=False, progress=lines.append, refine=False)
    [alt] = res.alternatives
    found = sorted([res.estimate.tolist(), alt.estimate.tolist()])
    assert np.allclose(found, [[0.2, 0.6], [0.4, 0.8]], atol=1e-6)
    assert res.misfit < 1e-6 and alt.misfit < 1e-6 and alt.indistinguishable and alt.p_value > 0.4
    assert not res.identifiable and res.ambiguous.tolist() == [True, True] and res.identified.tolist() == [False, False]
    # the second basin is found from the estimate's mirror image, before any global sample is tried
    assert any(line.startswith("mirror local stage from") for line in lines)
    payload = json.loads((tmp_path / "fit.json").read_text())
    assert payload["identifiable"] is False
    assert "delamination.0.start, delamination.0.end" in payload["identifiable_reason"]
    [a] = payload["alternatives"]
    assert a["indistinguishable"] is True and a["p_value"] == pytest.approx(alt.p_value)
    assert a["parameters"]["delamination.0.start"] == pytest.approx(alt.estimate[0])
    for p in payload["parameters"].values():
        assert p["ambiguous"] is True and p["identified"] is False
    assert payload["warnings"] == []       # a fit to round-off: structured residuals, but no information in them
    # the command line's summary says so in one line (the fit itself replaced by this one)
    import nsfem.fit

    monkeypatch.setattr(nsfem.fit, "fit", lambda *args, **kwargs: res)
    assert cli.main(["fit", "--data", "m.csv", "--vary", "delamination.0.start=0.1:0.45"]) == 0
    out = capsys.readouterr().out
    [line] = [line for line in out.splitlines() if "not identifiable" in line]
    assert "explains the data as well" in line and "p = 0.5" in line and "are not confident" in line
    assert out.count("ambiguous: a second minimum") == 2


def test_a_wrong_local_minimum_is_warned_about(inprocess, clean, tmp_path):
    # the local stage started at 0.3 m on noise-free data of 0.23 m, without a global stage: it ends in a
    # local minimum near 0.303 m with a misfit of 79 % and a narrow noise interval that excludes the truth; its
    # residuals are smooth (lag-1 autocorrelation 0.73 and 0.71 against the bound 0.26 of white noise). The
    # refined model has its minimum there too, as structured: the misfit is no discretization
    # error, and the fit promises no interval (the whole range, not identified)
    lines = []
    res = fit(None, clean, {KEY: RANGE}, overrides=FIXED, client=inprocess, out_dir=tmp_path, n_global=0,
              start={KEY: 0.3}, plot=False, progress=lines.append)
    assert res.misfit > 0.1 and not res.noise_interval[0, 0] <= TRUTH <= res.noise_interval[0, 1]
    assert res.interval[0].tolist() == list(RANGE) and not res.identifiable
    warning, lost = res.warnings
    assert lost.startswith(f"no interval for {KEY}: neither the fitted nor the refined model explains the data")
    assert "residuals are structured" in warning and "local minimum" in warning
    stats = res.info["residuals"]
    assert stats["structured"] == ["a", "b"] and min(stats["lag1_autocorrelation"].values()) > 0.5
    assert [line for line in lines if line.startswith("warning:")] == [f"warning: {warning}", f"warning: {lost}"]
    assert res.to_json()["warnings"] == [warning, lost]


def test_a_start_in_a_wrong_basin_is_left_for_the_truth(inprocess, clean, tmp_path):
    # the same wrong start with a global stage: the first local stage ends at 0.303 m (misfit 79 %), the
    # best distant global sample starts a second one that finds the truth; the wrong minimum stays as a
    # distinguishable alternative (F-test p ~ 0 against a fit to round-off)
    lines = []
    res = fit(None, clean, {KEY: RANGE}, overrides=FIXED, client=inprocess, out_dir=tmp_path, start={KEY: 0.3},
              plot=False, progress=lines.append, refine=False)
    assert abs(res.estimate[0] - TRUTH) < 1e-5 * (RANGE[1] - RANGE[0]) and res.misfit < 1e-3
    assert not res.warnings and res.identifiable
    [alt] = res.alternatives
    assert abs(alt.estimate[0] - 0.303) < 0.005 and alt.misfit > 0.1 and not alt.indistinguishable
    [further] = res.info["further_local"]
    assert further["stage"] == "second" and any(line.startswith("second local stage from") for line in lines)


def test_a_zoomed_design_finds_a_narrow_basin_next_to_a_local_minimum(inprocess, clean, tmp_path):
    # a local stage started at 0.27 m stops in a local minimum (structured residuals); the 4 global samples
    # (0.115, 0.225, 0.325, 0.355 m) hold no good distant start (0.225 m lies within a quarter of the range of
    # that minimum); the zoomed design within 0.1 of the range about it (32 runs, +-0.03 m) has a point in
    # the truth's basin (about 0.01 m wide), whose local stage ends at the truth
    res = fit(None, clean, {KEY: RANGE}, overrides=FIXED, client=inprocess, out_dir=tmp_path, n_global=4,
              start={KEY: 0.27}, plot=False, refine=False)
    assert abs(res.estimate[0] - TRUTH) < 1e-5 * (RANGE[1] - RANGE[0]) and res.misfit < 1e-3 and not res.warnings
    assert [f["stage"] for f in res.info["further_local"]] == ["zoom"]
    assert sum(e.stage == "zoom" for e in res.evaluations) == 32
    [alt] = res.alternatives
    assert alt.misfit > 0.1 and not alt.indistinguishable and res.identifiable


def test_further_starts_keep_away_from_minima_and_used_starts():
    from nsfem.fit import Evaluation, second_start

    evs = [Evaluation(np.array([x]), "global", m) for x, m in ((0.1, 1.0), (0.5, 1.5), (0.52, 1.2), (0.9, 3.0))]
    found = [np.array([0.12])]
    assert second_start(evs, found).u.tolist() == [0.52]          # the best far sample within twice the best
    assert second_start(evs, found, used=[np.array([0.52])]) is None   # 0.5 lies within SEPARATION of it
    assert second_start(evs, [np.array([0.12]), np.array([0.7])]) is None   # 0.9: three times the best


def _noisy_fit(client, tmp_path, t_end, seed):
    data = measure(t_end=t_end, noise=0.01, seed=seed)
    # refine=False: data from the fitted model itself carry none of its discretization error
    return fit(None, data, {KEY: RANGE}, overrides=FIXED, client=client, out_dir=tmp_path / f"{t_end}-{seed}",
               n_global=0, start={KEY: 0.232}, plot=False, refine=False)


def test_noisy_data_cover_the_truth_and_longer_records_narrow_the_interval(inprocess, tmp_path):
    # 1 % white noise. Seeds 0-2 here; seeds 0-9 gave 10 of 10 covered for both records (t_end
    # 0.1 s: widths 4.1e-5 to 4.8e-5 m; 0.2 s: 1.4e-5 to 1.6e-5 m), so these seeds are not chosen
    # to pass: 95 % coverage makes a miss among 3 seeds a 14 % event, among 10 a 40 % one
    for seed in range(3):
        short, long = (_noisy_fit(inprocess, tmp_path, t_end, seed) for t_end in (0.1, 0.2))
        for res in (short, long):
            lo, hi = res.interval[0]
            assert lo <= TRUTH <= hi and res.identified[0]
            assert 0.008 < res.misfit < 0.012           # the noise's 1 %: the model explains the rest
            assert res.uncertainty.dof == 2 * res.data.t.size - 1
            # white residuals: lag-1 autocorrelations from -0.26 to 0.10 against bounds of 0.26 and 0.18
            assert not res.warnings and not res.info["residuals"]["structured"]
        assert np.diff(long.interval[0])[0] < 0.6 * np.diff(short.interval[0])[0]


@pytest.mark.slow
def test_coverage_over_ten_seeds(inprocess, tmp_path):
    covered = sum(bool(res.interval[0, 0] <= TRUTH <= res.interval[0, 1])
                  for res in (_noisy_fit(inprocess, tmp_path, 0.1, seed) for seed in range(10)))
    assert covered >= 8                                  # P(<= 7 of 10 | 95 %) = 1.2 %


def test_cli_fit_json(tmp_path, capsys):
    t, sig = measure(t_end=0.05)
    path = write_csv(tmp_path / "m.csv", t, sig)
    argv = ["fit", "--data", str(path), "--vary", f"{KEY}=0.2:0.26", "--workers", "1", "--out", str(tmp_path / "o"),
            "--json"]
    for o in FIXED:
        argv += ["--set", o]
    assert cli.main(argv) == 0
    out, err = capsys.readouterr()
    payload = json.loads(out)
    assert set(payload) >= {"parameters", "misfit", "runs", "wall_s", "outputs"}
    assert payload["parameters"][KEY]["estimate"] == pytest.approx(TRUTH, abs=1e-5)
    assert "[global" in err and "local stage" in err


def test_ctrl_c_keeps_the_runs_so_far(inprocess, clean, tmp_path):
    from nsfem.fit import FitInterrupted

    lines = []

    def progress(line):
        lines.append(line)
        if len(lines) == 6:       # the header and five runs of the global stage
            raise KeyboardInterrupt

    with pytest.raises(FitInterrupted) as info:
        fit(None, clean, {KEY: RANGE}, overrides=FIXED, client=inprocess, out_dir=tmp_path, progress=progress)
    res = info.value.result
    assert res.info["interrupted"] and len(res.evaluations) == 5 and res.uncertainty is None
    rows = (tmp_path / "evaluations.csv").read_text().splitlines()
    payload = json.loads((tmp_path / "fit.json").read_text())
    assert len(rows) == 6 and payload["runs"] == 5 and payload["interrupted"] is True
    assert payload["misfit"] == pytest.approx(min(e.misfit for e in res.evaluations))

    def at_once(line):
        raise KeyboardInterrupt

    # interrupted before any run: no estimate, written as null (a bare NaN is not JSON)
    with pytest.raises(FitInterrupted):
        fit(None, clean, {KEY: RANGE}, overrides=FIXED, client=inprocess, out_dir=tmp_path / "none", progress=at_once)

    def refuse(name):
        raise ValueError(f"{name} is not JSON")

    payload = json.loads((tmp_path / "none" / "fit.json").read_text(), parse_constant=refuse)
    assert payload["runs"] == 0 and payload["parameters"][KEY]["estimate"] is None


@pytest.mark.parametrize("seed", [0, 1])
def test_data_from_a_finer_model_keep_the_truth_inside(inprocess, tmp_path, seed):
    # the measurement from 40 elements and 12 modes, fitted with 20 and 6: the model error (a misfit of
    # ~5 %, five times the 1 % noise) enters the residual variance that scales the interval, which widens
    # to hold the truth (measured: 0.22998 +- 0.00011 and 0.22999 +- 0.00011 for seeds 0, 1)
    data = measure(extra=["mesh.elements=40", "reduction.modes=12"], noise=0.01, seed=seed)
    res = fit(None, data, {KEY: RANGE}, overrides=FIXED, client=inprocess, out_dir=tmp_path, plot=False)
    low, high = res.interval[0]
    assert low <= TRUTH <= high and res.identifiable
    assert res.misfit > 0.02     # the fit is not handed its own discretization


def test_the_refined_runs_find_the_discretization_shift(inprocess, tmp_path):
    # noise-free data from 40 elements and 12 modes, 0.3 s from the stationary state, fitted with 20 and 6:
    # the fitted model's minimum lies off the truth by its discretization error; where exactly depends on the
    # BLAS kernel (-6.7e-4 m with SkylakeX, +1.1e-4 m with Sandybridge: the misfit, 1.7 % of model error, is
    # rugged at that scale). The refined runs are the data's model, so their Gauss-Newton step goes the rest
    # of the way to the truth, wherever the fit stopped, up to the step's second-order error (measured 0.6 %
    # and 0.3 %; allowed 5 %) and the floor of a model meeting its own data only to its contact thresholds
    # (1e-6 of the range, as in test_a_key_at_a_range_end_is_shifted_only_into_the_range)
    st = ['initial.state="stationary"', "damping.rayleigh=[20.0, 0.0]"]
    data = measure(extra=["mesh.elements=40", "reduction.modes=12", *st], t_end=0.3)
    lines = []
    res = fit(None, data, {KEY: RANGE}, overrides=[*FIXED, *st], client=inprocess, out_dir=tmp_path, n_global=0,
              start={KEY: 0.232}, plot=False, progress=lines.append)
    offset = TRUTH - res.estimate[0]
    assert res.misfit > 0.01                                   # the model error this test is about (1.7 %)
    assert abs(res.discretization_shift[0] - offset) <= 0.05 * abs(offset) + 1e-6 * (RANGE[1] - RANGE[0])
    lo, hi = res.interval[0]
    assert lo <= TRUTH <= hi and res.identified[0]
    assert res.discretization.overrides == ("mesh.elements=40", "reduction.modes=12")
    # at the estimate, one step away and at the shifted point (the check of the linear step); the model error
    # leaves structured residuals, so the refined model was fitted itself too (its runs: "refined-local")
    assert sum(e.stage == "refined" for e in res.evaluations) == 3
    assert res.discretization.refit is not None and any(e.stage == "refined-local" for e in res.evaluations)
    # the whole shift (4/3 of it) beyond the noise half-width is warned about, else not
    half = np.max(np.abs(res.noise_interval[0] - res.estimate[0]))
    assert any("discretization limits the estimate" in w and KEY in w for w in res.warnings) == (
        abs(4 / 3 * res.discretization_shift[0]) > half)
    payload = json.loads((tmp_path / "fit.json").read_text())
    p = payload["parameters"][KEY]
    assert p["discretization_shift"] == pytest.approx(res.discretization_shift[0])
    assert p["noise_interval"] == pytest.approx(res.noise_interval[0].tolist()) and p["interval"] == [lo, hi]
    assert payload["discretization"]["refined"] == ["mesh.elements=40", "reduction.modes=12"]
    # without the refined runs: the noise interval alone, no shift
    bare = fit(None, data, {KEY: RANGE}, overrides=[*FIXED, *st], client=inprocess, out_dir=tmp_path / "bare",
               n_global=0, start={KEY: 0.232}, plot=False, refine=False)
    assert bare.interval.tolist() == bare.noise_interval.tolist() and np.isnan(bare.discretization_shift[0])
    assert json.loads((tmp_path / "bare" / "fit.json").read_text())["discretization"] is None


def test_the_refined_runs_estimate_a_finer_models_shift(inprocess, tmp_path):
    # the same record from 80 elements and 24 modes, finer than the refined runs (40 and 12). If the model
    # error falls like h^q with q >= 2 (the assumption behind the 4/3), the refined model keeps at most a
    # quarter of the fitted one's error, i.e. a third of the measured shift: its step lands within |du| / 3
    # of the truth (measured 1.2e-4 of 2.1e-4 m with SkylakeX, 9.4e-5 of 1.5e-4 m with Sandybridge), and the
    # interval, moved by 4/3 of the shift, holds the truth
    st = ['initial.state="stationary"', "damping.rayleigh=[20.0, 0.0]"]
    data = measure(extra=["mesh.elements=80", "reduction.modes=24", *st], t_end=0.3)
    res = fit(None, data, {KEY: RANGE}, overrides=[*FIXED, *st], client=inprocess, out_dir=tmp_path, n_global=0,
              start={KEY: 0.232}, plot=False)
    du = res.discretization_shift[0]
    assert abs(du) > 5e-5 and abs(res.estimate[0] + du - TRUTH) <= abs(du) / 3
    assert res.interval[0, 0] <= TRUTH <= res.interval[0, 1]


def test_a_key_at_a_range_end_is_shifted_only_into_the_range(inprocess, clean, tmp_path):
    # the truth (0.23 m) lies below the range: the estimate sits on its lower end, where the refined model's
    # Gauss-Newton step points out of the range as the fitted model's does (4e-3 m): that is no
    # discretization error, the step in the box is zero and no warning claims one
    res = fit(None, clean, {KEY: (0.235, 0.3)}, overrides=FIXED, client=inprocess, out_dir=tmp_path, n_global=0,
              start={KEY: 0.24}, plot=False)
    # (the optimizer stops within 1e-8 of the range of its end, and the step may take it the rest of the way)
    assert res.estimate[0] == pytest.approx(0.235, abs=1e-8) and abs(res.discretization_shift[0]) <= 1e-8
    assert res.interval == pytest.approx(res.noise_interval, abs=1e-8)
    assert not any("discretization" in w for w in res.warnings)
    # the truth just inside the lower end, data from the refined settings (40 elements, 12 modes). Where the
    # optimizer stops on this misfit depends on the BLAS kernel (the fitted model's minimum lies 3.6e-5 m
    # below the truth, outside the range; stops measured from 3.6e-5 m below the truth at the end to 6e-7 m
    # above it inside), so what is asserted is what must hold wherever it stops: the shifted estimate stays
    # in the range, a shift at the lower end points into it, and, the data being the refined model's own,
    # its Gauss-Newton step lands on the truth up to the error of its Jacobian, a forward difference over
    # h = 1e-4 of the range (1.7e-5 m): a relative error h r''/(2 r') of the step, up to 5 % measured where an
    # event comes or goes within h (the misfit is piecewise smooth); 10 % allowed. Below that the step has a
    # floor: the model meets its own data only to its contact thresholds (approach speeds under 1e-7 of the
    # contact velocities settle rather than impact), measured 1e-8 to 3e-8 m; 1e-6 of the range allowed
    lo, hi = 0.2298, 0.4
    data = measure(extra=["mesh.elements=40", "reduction.modes=12"])
    res = fit(None, data, {KEY: (lo, hi)}, overrides=FIXED, client=inprocess, out_dir=tmp_path / "in",
              n_global=0, start={KEY: 0.2299}, plot=False)
    est, du = res.estimate[0], res.discretization_shift[0]
    assert np.isfinite(du) and lo <= est + du <= hi
    if res.at_bound[0] and est - lo < hi - est:
        assert du >= 0.0
    assert abs(est + du - TRUTH) <= 0.1 * abs(est - TRUTH) + 1e-6 * (hi - lo)


def test_a_shift_at_a_range_end_is_kept_when_it_points_into_the_range():
    # the refined model's step from an estimate on a range end: into the range it is the shift, out of it
    # the key is held (u + du stays in [0, 1]); one key held does not stop the other from moving
    from nsfem.fit.discretization import shift

    J = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    r_in = -J @ np.array([0.02, -0.03])               # the exact step is (+0.02, -0.03)
    du = shift(J, r_in, np.array([0.0, 0.5]), np.array([True, True]))
    np.testing.assert_allclose(du, [0.02, -0.03], atol=1e-14)     # lstsq of a consistent system: round-off
    du = shift(J, r_in, np.array([0.5, 1.0]), np.array([True, True]))
    np.testing.assert_allclose(du, [0.02, -0.03], atol=1e-14)     # from the upper end, back into the range
    r_out = -J @ np.array([-0.02, 0.03])              # both steps point out of the range at their ends
    du = shift(J, r_out, np.array([0.0, 1.0]), np.array([True, True]))
    assert du.tolist() == [0.0, 0.0]
    du = shift(J, -J @ np.array([-0.02, 0.03]), np.array([0.0, 0.5]), np.array([True, True]))
    # the first key held at 0; the second, free, fits rows 2 and 3 (0.03 and 0.03 - 0.02): their mean, 0.02
    np.testing.assert_allclose(du, [0.0, 0.02], atol=1e-12)


def test_refined_settings_per_integrator():
    from nsfem.fit.discretization import factor, order, refined_overrides

    base = load_scene(None, FIXED)
    sets, kept = refined_overrides(base)
    assert sets == ["mesh.elements=40", "reduction.modes=12"] and any("contact discretization" in k for k in kept)
    sets, _ = refined_overrides(load_scene(None, [*FIXED, 'simulation.method="rk"', "simulation.rtol=1e-8"]))
    assert sets[2:] == ["simulation.rtol=1e-09", "simulation.atol=1e-13"]
    for method, rtol in (("rk", 2.3e-14), ("rk", 5e-14), ("penalty", 1e-13), ("penalty", 3e-13)):
        # at or near the integrator's smallest rtol (rk: 100 eps = 2.2e-14, penalty: 1e-13): kept, never an
        # override the scene would refuse
        scene = load_scene(None, [*FIXED, f'simulation.method="{method}"', f"simulation.rtol={rtol}"])
        sets, kept = refined_overrides(scene)
        assert not any(o.startswith("simulation.rtol") for o in sets) and any("smallest" in k for k in kept)
    sets, _ = refined_overrides(load_scene(None, [*FIXED, 'simulation.method="rk"', "simulation.rtol=1e-12"]))
    assert "simulation.rtol=1e-13" in sets
    for o in sets:
        load_scene(None, [*FIXED, 'simulation.method="rk"', o])      # every override is one the scene takes
    sets, _ = refined_overrides(load_scene(None, [*FIXED, 'simulation.method="moreau"', "simulation.output_dt=1e-3"]))
    assert sets[2:] == ["simulation.moreau_step=5e-05"]          # the default step output_dt / 10, halved
    # moreau is first order through impacts: a doubling measures half its error
    assert order("moreau") == 1 and factor(order("moreau")) == 2.0 and factor(order("exact")) == pytest.approx(4 / 3)


def test_modes_the_refined_model_cannot_keep_are_kept(inprocess, clean, tmp_path, monkeypatch):
    # a mesh from a file keeps its interior coordinates; doubled modes can exceed them and the reduction
    # refuses (simulated here): the refined runs are made again with the fitted modes, and the JSON says so
    import nsfem.fit.stages

    run = nsfem.fit.stages.run_signals

    def refuse_12(scene, shared, t, columns):
        if scene.reduction.modes == 12:
            return None, "reduction.modes = 12 exceeds the 10 interior coordinates"
        return run(scene, shared, t, columns)

    monkeypatch.setattr(nsfem.fit.stages, "run_signals", refuse_12)
    res = fit(None, clean, {KEY: RANGE}, overrides=FIXED, client=inprocess, out_dir=tmp_path, n_global=0,
              start={KEY: 0.232}, plot=False)
    d = res.discretization
    assert d.overrides == ("mesh.elements=40",) and not d.error and np.isfinite(d.shift[0])
    assert any(k.startswith("reduction.modes=12: the refined model cannot keep them") for k in d.kept)


def _failing_above(monkeypatch, start):
    """Runs of a delamination starting past ``start`` fail on the worker (an integration error, say)."""
    import nsfem.fit.stages

    run = nsfem.fit.stages.run_signals

    def flaky(scene, shared, t, columns):
        if scene["delamination"][0]["start"] > start:
            return None, "simulated failure"
        return run(scene, shared, t, columns)

    monkeypatch.setattr(nsfem.fit.stages, "run_signals", flaky)


def test_a_failed_run_in_the_local_stage_with_the_spectrum_misfit(inprocess, tmp_path, monkeypatch):
    # a failed run scores FAILED_RESIDUAL in every entry of a residual vector as long as a real one: the
    # spectrum's bins, not the samples. The start's forward step of the Jacobian fails: the fit goes on
    _failing_above(monkeypatch, 0.24001)
    res = fit(None, measure(t_end=0.05), {KEY: RANGE}, misfit="spectrum", overrides=FIXED, client=inprocess,
              out_dir=tmp_path, n_global=0, start={KEY: 0.24}, plot=False)
    assert any(e.error == "simulated failure" for e in res.evaluations)
    assert res.estimate[0] <= 0.24001 and np.isfinite(res.misfit)
    # it stops at the edge of the failing region: the final Jacobian's step failed, its column was a
    # penalty (a confident interval 4e-7 m wide about 0.24, the truth 0.23): no statistics for the key
    assert res.estimate[0] > 0.24001 - 1e-4 * (RANGE[1] - RANGE[0])
    assert res.interval[0].tolist() == list(RANGE) and not res.identified[0] and not res.identifiable
    assert any("failed for delamination.0.start" in w for w in res.warnings)


def test_data_off_the_output_grid_are_not_interpolated_coarsely(inprocess, tmp_path):
    # a DAQ clock 0.3 ms off the scene's: samples every 1 ms at 0.3, 1.3, ... ms, with 1 % noise. Linear
    # interpolation of outputs every 1 ms made a misfit of 3 % at the truth; the runs output 8 times per
    # data step and a cubic spline leaves the noise's 1 %
    scene = load_scene(None, [*FIXED, f"{KEY}={TRUTH}", "simulation.t_end=0.1", "simulation.output_dt=1e-4"])
    result, system = run_scene(scene)
    v = sensor_signals(result, system)[3::10]
    v = v + 0.01 * np.sqrt(np.mean(v**2, axis=0)) * np.random.default_rng(0).standard_normal(v.shape)
    t = result.t[3::10]
    res = fit(None, (t, {"a": v[:, 0], "b": v[:, 1]}), {KEY: RANGE}, overrides=FIXED, client=inprocess,
              out_dir=tmp_path, n_global=0, start={KEY: 0.232}, plot=False, refine=False)
    assert 0.008 < res.misfit < 0.012 and not res.warnings
    assert res.interval[0, 0] <= TRUTH <= res.interval[0, 1]


# --- issue 32: fit intervals that keep their promise ---
def _ar1(a: float, n: int, rng) -> np.ndarray:
    """A stationary AR(1) series of unit variance: x_i = a x_(i-1) + sqrt(1 - a^2) e_i."""
    from scipy.signal import lfilter

    e = rng.standard_normal(n) * np.sqrt(1 - a * a)
    e[0] = rng.standard_normal()
    return lfilter([1.0], [1.0, -a], e)


def test_correlated_residuals_widen_the_noise_interval_to_its_coverage():
    # a fit of two smooth regressors to data with AR(1) noise, a = 0.8 (autocorrelation time 9): the white-noise
    # interval assumes N independent samples where there are about N / 9, and covers the truth about half the
    # time; the interval with the residuals' autocorrelation must cover it at the nominal rate. 300 draws of 2000
    # samples, two keys: the binomial spread of a 95 % coverage over 600 checks is 0.9 % (1.3 % counting the
    # keys as one), so >= 0.91 is 3 spreads below; the autocorrelation estimate is biased low for records only a
    # few correlation times long (measured: 0.91 with 600 samples, 0.945 with 2000), hence the long record
    from nsfem.analysis.uncertainty import correlated, linearized

    rng = np.random.default_rng(7)
    n, truth = 2000, np.array([0.4, 0.6])
    x = np.linspace(0.0, 1.0, n)
    J = np.column_stack([np.ones(n), np.sin(7 * x)]) * 0.05
    hit_white = hit = 0
    draws = 300
    for _ in range(draws):
        r_data = J @ truth + 0.01 * _ar1(0.8, n, rng)
        u = np.linalg.lstsq(J, r_data, rcond=None)[0]
        r = J @ u - r_data
        white = linearized(J, r, u)
        wide, tau = correlated(white, J, r, u, 1, np.array([True]))
        # never narrower than the white interval
        assert np.all(wide.interval[:, 0] <= white.interval[:, 0]) and np.all(wide.interval[:, 1] >= white.interval[:, 1])
        hit_white += np.sum((white.interval[:, 0] <= truth) & (truth <= white.interval[:, 1]))
        hit += np.sum((wide.interval[:, 0] <= truth) & (truth <= wide.interval[:, 1]))
        assert 1.0 <= tau[0]
    assert hit_white / (2 * draws) < 0.8 and hit / (2 * draws) >= 0.91
    # white residuals, said to be white: the statistics are untouched
    r = 0.01 * rng.standard_normal(n)
    white = linearized(J, r, np.array([0.5, 0.5]))
    same, tau = correlated(white, J, r, np.array([0.5, 0.5]), 1, np.array([False]))
    assert same is white and tau.tolist() == [1.0]


def test_a_reported_interval_holds_the_noise_interval_and_both_minima():
    # the reported interval is the hull of the noise interval about the estimate and about the estimate moved by
    # the whole shift (4/3 of it), in the box; a key without an interval gets its whole range
    from hypothesis import given, settings, strategies as st

    from nsfem.fit.discretization import Discretization, reported

    unit = st.floats(0.0, 1.0)

    @settings(max_examples=60, deadline=None)
    @given(unit, st.floats(0.0, 0.3), st.floats(-1.0, 1.0), st.booleans())
    def holds(u, half, du, lost):
        iv = np.array([[max(u - half, 0.0), min(u + half, 1.0)]])
        d = Discretization((), (), 0.0, np.array([du]), no_interval=np.array([lost]))
        out = reported(iv, d)
        assert out[0, 0] <= iv[0, 0] and out[0, 1] >= iv[0, 1]                  # never narrower
        moved = np.clip(u + 4 / 3 * du, 0.0, 1.0)
        assert out[0, 0] - 1e-12 <= moved <= out[0, 1] + 1e-12                # the extrapolated minimum inside
        assert 0.0 <= out[0, 0] <= out[0, 1] <= 1.0
        assert (out[0].tolist() == [0.0, 1.0]) or not lost

    holds()


def test_an_untrusted_linear_step_is_replaced_by_the_refined_minimum(inprocess, tmp_path, monkeypatch):
    # a coarse model (12 elements, 4 modes) fitted to data from its refined settings (24 and 8) with 1 % noise,
    # 0.1 s from rest: a model bias of several noise half-widths. The refined model's Jacobian is made 1 / 0.15
    # times too steep, so its Gauss-Newton step finds only 15 % of the shift (as in the issue's delamination
    # from rest: 0.22 of 1.5 mm, the local slope of a rugged misfit): the interval built on that step misses the
    # truth. The refined run at the shifted point falls by more than the linear model predicts (1.85 times on a
    # quadratic misfit), outside the trust ratio, and the refined model's own minimization must end at its
    # minimum for these data, which lies within the noise interval of the truth (the data are that model's)
    # plus the minimization's tolerance (half a noise sigma): the interval then holds the truth
    import nsfem.fit
    from nsfem.fit import refit, stages
    from nsfem.fit.discretization import widen

    monkeypatch.setattr(nsfem.fit, "jacobian", lambda *a: stages.jacobian(*a) / 0.15)   # the refined runs' only
    coarse = [*FIXED, "mesh.elements=12", "reduction.modes=4"]
    data = measure(extra=["mesh.elements=24", "reduction.modes=8"], noise=0.01)
    res = fit(None, data, {KEY: RANGE}, overrides=coarse, client=inprocess, out_dir=tmp_path, n_global=0,
              start={KEY: 0.2305}, plot=False)
    d, width = res.discretization, RANGE[1] - RANGE[0]
    half = np.diff(res.noise_interval[0])[0] / 2
    assert abs(TRUTH - res.estimate[0]) > 2 * half                       # the bias this test is about
    linear = RANGE[0] + width * widen(res.uncertainty.interval, d.linear_shift)[0]
    assert not linear[0] <= TRUTH <= linear[1]                           # what the linear step alone promised
    assert not abs(d.ratio - 1) <= refit.TRUST and "linear step predicts" in d.refit["why"]
    assert d.refit["converged"] and not d.no_interval.any()
    sigma = res.uncertainty.sigma[0] * width
    assert abs(res.estimate[0] + res.discretization_shift[0] - TRUTH) <= half + refit.STEP_TOLERANCE * sigma
    assert res.interval[0, 0] <= TRUTH <= res.interval[0, 1] and res.identified[0]
    # the hull of both minima: never narrower than the noise interval
    assert res.interval[0, 0] <= res.noise_interval[0, 0] and res.interval[0, 1] >= res.noise_interval[0, 1]
    payload = json.loads((tmp_path / "fit.json").read_text())["discretization"]
    assert payload["refit"]["why"] == d.refit["why"] and payload["reduction_ratio"] == pytest.approx(d.ratio)
    assert payload["linear_shift"][KEY] == pytest.approx(d.linear_shift[0] * (RANGE[1] - RANGE[0]))
    # a refined minimization that cannot settle (no step allowed, any step too long) leaves no interval to promise
    monkeypatch.setattr(refit, "REFIT_RUNS", 0)
    monkeypatch.setattr(refit, "STEP_TOLERANCE", 0.0)
    res = fit(None, data, {KEY: RANGE}, overrides=coarse, client=inprocess, out_dir=tmp_path / "lost", n_global=0,
              start={KEY: 0.2305}, plot=False)
    assert res.interval[0].tolist() == list(RANGE) and not res.identified[0] and not res.identifiable
    assert any(w.startswith(f"no interval for {KEY}: the refined model's own minimization failed: its steps did "
                            "not settle in 0 runs")
               for w in res.warnings)
    payload = json.loads((tmp_path / "lost" / "fit.json").read_text())
    assert payload["parameters"][KEY]["identified"] is False and payload["discretization"]["no_interval"] == [KEY]
    assert "no interval for" in payload["identifiable_reason"]


def test_the_secant_minimization_reaches_a_minimum_a_short_step_misses():
    # residuals of two keys with a cubic term (a misfit far from quadratic, as a delamination's ends from rest) and
    # a starting Jacobian 1 / 0.15 times too steep (a rugged misfit's local slope): one Gauss-Newton step goes
    # 15 % of the way. The minimization must end where its stopping rule says (the next step below the tolerance
    # per key), lower than it started, and at the unique minimum u* = (0.6, 0.3) to within the tolerance (the
    # residuals vanish there, so the Gauss-Newton step from the exact Jacobian is at most the distance to it,
    # up to the cubic's second-order error)
    from nsfem.fit.discretization import shift
    from nsfem.fit.refit import secant_minimum

    target = np.array([0.6, 0.3])
    A = np.array([[1.0, 0.4], [0.2, 1.0], [0.5, -0.3]])

    def residual(u):
        e = u - target
        return A @ e + 40.0 * (A @ e) ** 3

    u0 = np.array([0.5, 0.45])
    J0 = (A * (1 + 120 * ((A @ (u0 - target)) ** 2))[:, None]) / 0.15
    assert np.max(np.abs(np.nan_to_num(shift(J0, residual(u0), u0, np.array([True, True]))))) < 0.05  # short
    tol = np.array([1e-4, 1e-4])
    runs = []
    u, r, last, failed = secant_minimum(lambda vs: runs.extend(vs) or [residual(v) for v in vs], J0, u0,
                                        residual(u0), tol)
    assert not failed and np.all(np.abs(last) <= tol) and r @ r < residual(u0) @ residual(u0)
    assert np.all(np.abs(u - target) <= 2 * tol) and len(runs) <= 20
    # a failed run ends it with the reason, at the best point so far
    u, r, last, failed = secant_minimum(lambda vs: [None] * len(vs), J0, u0, residual(u0), tol)
    assert failed == "its run at a step failed" and u.tolist() == u0.tolist()


@pytest.mark.slow
def test_the_issue_32_delamination_from_rest_keeps_its_promise(tmp_path):
    # the issue's case: an asymmetric delamination (0.22-0.71 m) falling from rest at 15 Hz for 0.5 s, four
    # rotating-frame probes next to the supports, data from 80 elements and 32 modes (the fit's refined settings)
    # with 1 % noise, fitted with the shipped 40 and 16 over 0.1-0.4 and 0.55-0.9 (~400 runs, 2-5 min on 2
    # cores). One refined Gauss-Newton step found 0.22 of a 1.5 mm offset and the interval missed the truth by
    # 1.2 mm. A fit must now hold the truth in each key's interval, or say it has none (the whole range, not
    # identified, a warning naming the key)
    distributed = pytest.importorskip("distributed")
    probes = [o for i, (x, d) in enumerate([(0.05, "+y"), (0.05, "+z"), (0.95, "+y"), (0.95, "+z")])
              for o in (f'sensor.{i}.name="s{i}"', f"sensor.{i}.x={x}", f'sensor.{i}.direction="{d}"',
                        f'sensor.{i}.frame="rotating"')]
    setup = [*probes, "rotation.speed_hz=15.0", 'initial.state="rest"', "simulation.t_end=0.5"]
    truth = {"delamination.0.start": 0.22, "delamination.0.end": 0.71}
    scene = load_scene(None, [*setup, "mesh.elements=80", "reduction.modes=32", *(f"{k}={v}" for k, v in truth.items())])
    result, system = run_scene(scene)
    v = sensor_signals(result, system)
    v = v + 0.01 * np.sqrt(np.mean(v**2, axis=0)) * np.random.default_rng(1).standard_normal(v.shape)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cl, \
            distributed.Client(cl) as client:
        res = fit(None, (result.t, {f"s{i}": v[:, i] for i in range(4)}),
                  {"delamination.0.start": (0.1, 0.4), "delamination.0.end": (0.55, 0.9)}, client=client,
                  overrides=setup, out_dir=tmp_path, plot=False)
    lost = res.discretization.no_interval if res.discretization.no_interval is not None else np.zeros(2, bool)
    for i, key in enumerate(res.keys):
        lo, hi = res.interval[i]
        if not lost[i]:
            assert lo <= truth[key] <= hi, (key, truth[key], lo, hi)
        else:
            assert [lo, hi] == [res.params[i].low, res.params[i].high]
            assert any(w.startswith("no interval for") and key in w for w in res.warnings)
        assert lo <= res.noise_interval[i, 0] and hi >= res.noise_interval[i, 1]    # never narrower
    # and it cannot pass by giving up: in the truth's basin (the fitted model's misfit 2.9 %, wrong basins 4.65 to
    # 5.2 % in the study's draws; 4 % between them) the data are the refined model's own (80 elements, 32
    # modes), whose minimum explains them to the noise (1.005 %): nothing stands in the way of both intervals
    if res.misfit < 0.04:
        assert not np.any(lost), (res.misfit, res.warnings)


def test_the_correlated_statistics_never_narrow_an_interval_nor_break():
    # any residuals (smooth, white, zero, constant) and Jacobians (a column of zeros: an unseen key) the fit may
    # meet: the intervals stay in the box, hold the white ones, are finite where those are, and the
    # autocorrelation times are at least 1
    from hypothesis import given, settings, strategies as st

    from nsfem.analysis.uncertainty import correlated, linearized

    @settings(max_examples=60, deadline=None, derandomize=True, database=None)
    @given(st.integers(1, 3), st.integers(1, 3), st.integers(4, 60), st.integers(0, 2**32 - 1),
           st.sampled_from(["white", "smooth", "zero", "constant"]), st.booleans())
    def holds(sensors, p, k, seed, kind, unseen):
        rng = np.random.default_rng(seed)
        n = sensors * k
        J = rng.standard_normal((n, p)).cumsum(axis=0) / np.sqrt(n)
        if unseen:
            J[:, -1] = 0.0
        r = {"white": rng.standard_normal(n), "smooth": np.sin(np.linspace(0, 3, n)), "zero": np.zeros(n),
             "constant": np.ones(n)}[kind] * 0.01
        u = rng.uniform(0, 1, p)
        white = linearized(J, r, u, floor=1e-3)
        wide, tau = correlated(white, J, r, u, sensors, rng.uniform(size=sensors) < 0.7)
        iv, w = wide.interval, white.interval
        assert np.all((0.0 <= iv) & (iv <= 1.0)) and np.all(iv[:, 0] <= w[:, 0]) and np.all(iv[:, 1] >= w[:, 1])
        assert np.all(tau >= 1.0) and np.all(np.isfinite(tau))
        assert not np.any(np.isnan(iv)) and wide.dof >= 1

    holds()


def test_an_equally_good_minimum_outside_an_interval_makes_the_key_ambiguous():
    # the quick study's asymmetric delamination, draw 3: a second minimum the data cannot tell from the estimate
    # (F-test p = 0.35) moved the end by 7 mm and the start by 2.8 mm, under the 1 % of its range that makes two
    # minima distinct but outside its interval 0.6 mm wide: both keys are ambiguous (the interval would promise
    # a start the data do not pin); a worse second minimum (p ~ 0) leaves the near key alone
    from nsfem.fit.problem import Parameter
    from nsfem.fit.stages import alternative

    params = (Parameter("delamination.0.start", 0.1, 0.4), Parameter("delamination.0.end", 0.55, 0.9))
    u = np.array([(0.21225 - 0.1) / 0.3, (0.56871 - 0.55) / 0.35])
    u2 = np.array([(0.21503 - 0.1) / 0.3, (0.57591 - 0.55) / 0.35])
    iv = np.array([[(0.21174 - 0.1) / 0.3, (0.21297 - 0.1) / 0.3], [(0.56832 - 0.55) / 0.35, (0.56930 - 0.55) / 0.35]])
    r = 0.045 * np.random.default_rng(3).standard_normal(800)
    same = alternative(params, u, r, iv, u2, r * 1.001)
    assert same.indistinguishable and same.differs.tolist() == [True, True]
    worse = alternative(params, u, r, iv, u2, r * 1.5)
    assert not worse.indistinguishable and worse.differs.tolist() == [False, True]


# --- issue 32: review of the fit intervals ---
def _model_error_check(u: np.ndarray):
    """refit.check on a refined model whose residuals are a coherent signal no key moves (a model error refinement
    does not reduce) plus a linear term, the fitted residuals that signal too: (the checked Discretization)."""
    from types import SimpleNamespace

    from nsfem.fit import refit
    from nsfem.fit.discretization import Discretization
    from nsfem.fit.problem import Evaluation, Parameter

    k, sensors = 200, 2
    t = np.arange(k)
    signal = 0.05 * np.column_stack([np.sin(2 * np.pi * t / 10), np.cos(2 * np.pi * t / 13)]).ravel()
    J = np.random.default_rng(0).standard_normal((k * sensors, 2)) * 0.1
    J -= np.outer(signal, signal @ J) / (signal @ signal)         # the keys cannot touch the signal

    class Runner:
        def run_refined(self, vs, overrides, stage="refined"):
            return [Evaluation(np.array(v, float), stage, 0.0, residuals=signal + J @ (np.asarray(v) - u)) for v in vs]

    problem = SimpleNamespace(params=(Parameter("a", 0.0, 1.0), Parameter("b", 0.0, 1.0)),
                              data=SimpleNamespace(names=("s0", "s1")), kind="time")
    d = Discretization(("mesh.elements=2",), (), 0.05, np.zeros(2), jacobian=J, residuals=signal.copy())
    return refit.check(Runner(), problem, u, signal.copy(), SimpleNamespace(sigma=np.full(2, 0.01)), d,
                       lambda line: None)


def test_a_key_on_a_range_end_does_not_keep_the_other_keys_interval():
    # structured residuals that the refined model's own minimum leaves as they are (refinement explains 0 % of the
    # sum of squares): the misfit is not the discretization's and no interval is promised. A key whose estimate
    # sits on a range end is reported at_bound and keeps its interval; the other key's is no better founded for
    # it (it was promised before: a wrong basin with one key pinned at an end kept a narrow interval)
    inside = _model_error_check(np.array([0.3, 0.5]))
    assert inside.refit["converged"] and inside.no_interval.tolist() == [True, True]
    assert "neither the fitted nor the refined model explains the data" in inside.no_interval_reason
    one_end = _model_error_check(np.array([0.0, 0.5]))
    assert one_end.refit["converged"] and one_end.no_interval.tolist() == [False, True]
    both_ends = _model_error_check(np.array([0.0, 1.0]))
    assert both_ends.no_interval.tolist() == [False, False]


def test_a_refit_after_a_fit_to_round_off_does_not_break():
    # noise-free data of the fitted model, started at the truth: the fitted residuals vanish exactly. A refined
    # model far from linear (its linear step reaches 0.64 of the predicted reduction, outside the trust ratio)
    # is fitted itself; the share of the sum of squares it explains is then undefined (0 / 0, a
    # ZeroDivisionError before) and must neither break the fit nor its JSON. The refined residuals
    # c + J (d - 300 d^2), c = 0.002 J, vanish at d* = (1 - sqrt(3.4)) / 600: the minimization ends where its
    # next step is below the tolerance, and near a simple root Gauss-Newton's step is the remaining distance
    # to second order, so within 2 tolerances of d*
    from types import SimpleNamespace

    from nsfem.fit import refit
    from nsfem.fit.discretization import Discretization, shift
    from nsfem.fit.problem import Evaluation, Parameter
    from nsfem.jsonio import as_text, dumps

    J = np.random.default_rng(0).standard_normal((200, 1)) * 0.1
    u = np.array([0.5])

    def refined(v):
        d = float(np.asarray(v)[0] - u[0])
        return J[:, 0] * (0.002 + d - 300 * d**2)

    class Runner:
        def run_refined(self, vs, overrides, stage="refined"):
            return [Evaluation(np.array(v, float), stage, 0.0, residuals=refined(v)) for v in vs]

    problem = SimpleNamespace(params=(Parameter("a", 0.0, 1.0),), data=SimpleNamespace(names=("s0", "s1")),
                              kind="time")
    d = Discretization(("mesh.elements=2",), (), 0.01, shift(J, refined(u), u, np.array([True])), jacobian=J,
                       residuals=refined(u))
    unc = SimpleNamespace(sigma=np.array([1e-4]))
    out = refit.check(Runner(), problem, u, np.zeros(200), unc, d, lambda line: None)
    assert not abs(out.ratio - 1) <= refit.TRUST and out.refit["converged"] and not out.no_interval.any()
    assert np.isnan(out.refit["explained"]) and json.loads(dumps(out.refit, as_text))["explained"] is None
    assert abs(out.shift[0] - (1 - np.sqrt(3.4)) / 600) <= 2 * refit.STEP_TOLERANCE * unc.sigma[0]


@pytest.mark.parametrize("k, sensors", [(16, 1), (16, 8), (24, 8), (40, 8), (400, 2)])
def test_white_noise_of_a_short_record_is_not_called_coherent(k, sensors):
    # the coherent-residual rule withdraws intervals: on white noise it must fire at most at its level (1 %,
    # Bonferroni over the lags and sensors; the fixed 0.5 fired on 47 % of 16-sample, 8-sensor records). 1000
    # draws: a 1 % rate gives 10 +- 3, 20 allowed. A signal of a period of 4 samples (rho(2) = -1) still fires
    # from 24 samples on (with 16 its sample autocorrelation reaches only 14/16: with 8 sensors too short to
    # tell at 1 %)
    from nsfem.fit.refit import coherent_bound, coherent_share

    rng = np.random.default_rng(k * sensors)
    bound = coherent_bound(k, sensors)
    hits = sum(coherent_share(rng.standard_normal(k * sensors), sensors) > bound for _ in range(1000))
    assert hits <= 20
    signal = np.repeat(np.cos(np.pi * np.arange(k) / 2)[:, None], sensors, axis=1)
    if k >= 24:
        assert coherent_share(signal + 0.05 * rng.standard_normal(signal.shape), sensors) > bound
