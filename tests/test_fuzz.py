"""Hostile and careless input to every subcommand: exit 0 or 2, never a traceback, nothing half
written (issue 16).

The property (:func:`check_invocation`): ``nsfem.cli.main`` returns 0 or 2 (no exception
escapes it), a 2 comes with a one-line ``nsfem: error:`` message, and the working folder holds
no temporary file, no empty file and no empty folder afterwards. The issue's reproductions are
listed one by one below; hypothesis then mixes keys, values and options at random (a few
seconds by default, many more examples under ``-m slow``).
"""

from __future__ import annotations

import contextlib
import io
import os
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nsfem import cli

#: keep every run short: the fuzz is about input handling, not about physics
CHEAP = ["--set", "mesh.elements=20", "--set", "simulation.t_end=0.01", "--set", "output.vtu_every=0",
         "--set", "output.plots=[]"]


def leftovers(root: Path) -> list[str]:
    """Temporary files, empty files and empty folders under ``root``."""
    bad = []
    for dirpath, dirnames, filenames in os.walk(root):
        d = Path(dirpath)
        if d != root and not dirnames and not filenames:
            bad.append(f"empty folder {d.relative_to(root)}")
        for f in filenames:
            p = d / f
            if f.endswith(".tmp") or p.stat().st_size == 0:
                bad.append(f"half-written file {p.relative_to(root)}")
    return bad


def check_invocation(argv: list[str], root: Path) -> tuple[int, str, str]:
    """Run ``nsfem argv`` in-process inside ``root``; assert the property; (code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    cwd = os.getcwd()
    os.chdir(root)
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = cli.main(argv)
    finally:
        os.chdir(cwd)
    stderr = err.getvalue()
    assert code in (0, cli.EXIT_ERROR), (argv, code, stderr)
    assert "Traceback" not in stderr, (argv, stderr)
    if code == cli.EXIT_ERROR:
        errors = [line for line in stderr.splitlines() if line.startswith("nsfem: error:")]
        assert len(errors) == 1, (argv, stderr)
    assert not leftovers(root), (argv, leftovers(root))
    return code, out.getvalue(), stderr


@pytest.fixture(scope="module")
def saved_result(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("fuzz-result")
    assert cli.main(["run", "--out", str(out), *CHEAP]) == 0
    return out / "result.npz"


# ------------------------------------------------------------------ the issue's reproductions
# (arguments, what must happen: "error" = exit 2 with one line; "warn" = exit 0 with this text
# on stderr). The hostile write targets are in test_write_targets.py, the bounds in
# test_bounds.py, the integrator guards in test_progress_guard.py; here all go through main.
F = ["--set", "simulation.t_end=0.01", "--set", "output.vtu_every=0", "--set", "output.plots=[]"]
REPRODUCTIONS = [
    (["campbell", "--speeds", "0:1e300:3"], "error", "--speeds"),
    (["run", *F, "--set", "delamination.0.friction=0.3", "--set", "delamination.0.friction_directions=100000"],
     "error", "friction_directions"),
    (["stationary", "--set", "delamination.0.friction=0.3", "--set", "delamination.0.friction_directions=100000"],
     "error", "friction_directions"),
    (["run", *F, "--set", "damping.rayleigh=[0,1e300]"], "error", "damping.rayleigh"),
    (["run", *F, "--set", "damping.rayleigh=[1e300,0]"], "error", "damping.rayleigh"),
    (["campbell", "--set", "damping.rayleigh=[0,1e300]"], "error", "damping.rayleigh"),
    (["campbell", "--set", "damping.rayleigh=[1e300,0]"], "error", "damping.rayleigh"),
    (["campbell", "--set", "damping.external=1e300"], "error", "damping.external"),
    (["run", *F, "--set", "damping.external=1e300"], "error", "damping.external"),
    (["run", *F, "--set", "rotation.speed_hz=1e6"], "error", "rotation.speed_hz"),
    (["sweep", *F, "--set", "rotation.speed_hz=1e6:2e6:2"], "error", "rotation.speed_hz"),
    (["run", "--set", "simulation.t_end=1e300", "--set", "simulation.output_dt=1e294", "--set",
      "output.vtu_every=0", "--set", "output.plots=[]"], "error", "simulation."),
    (["modes", "--set", "shaft.E=1e-300"], "error", "shaft.E"),
    (["campbell", "--set", "shaft.length=1e300"], "error", "shaft.length"),  # slow fuzz: OverflowError
    # found by review: log10(0) of an underflowed element length; widths/heights blamed; I_z checked
    (["modes", "plain.toml", "--set", "shaft.length=1e-322"], "error", "shaft.length"),
    (["modes", "plain.toml", "--set", "shaft.width=1e-105"], "error", "shaft.width"),
    (["modes", "plain.toml", "--set", "shaft.width=1e-40"], "error", "shaft.width"),
    (["campbell", "--set", "shaft.width=1e300"], "error", "shaft.width"),  # slow fuzz: OverflowError in I_z
    (["modes", "plain.toml", "--set", "shaft.height=1e-40"], "error", "shaft.height"),
    (["render", ".", "--time", "-1"], "error", "is a folder"),  # found by the slow fuzz (ValueError)
    (["run", *F, "--set", "rotation.gravity=1e6"], "warn", "range of the linear"),
    (["run", *F, "--set", "rotation.gravity=1e6", "--set", "rotation.speed_hz=0"], "warn", "range of the linear"),
    (["run", *F, "--set", "initial.velocity=[0,0,1e6]"], "warn", "range of the linear"),
    (["stationary", "--set", "rotation.speed_hz=0", "--set", "rotation.gravity=1e6"], "warn", "range of the linear"),
    (["sweep", *F, "--set", "rotation.gravity=1e6", "--set", "rotation.speed_hz=20:21:2"], "warn",
     "range of the linear"),
]


@pytest.mark.parametrize("argv, outcome, text", REPRODUCTIONS, ids=[" ".join(r[0]) for r in REPRODUCTIONS])
def test_issue_reproductions(argv, outcome, text, tmp_path):
    (tmp_path / "plain.toml").write_text('title = "plain"\n[shaft]\nlength = 1.0\n')  # no delamination
    code, _, stderr = check_invocation(argv, tmp_path)
    assert code == (cli.EXIT_ERROR if outcome == "error" else 0), stderr
    assert text in stderr, stderr


def test_deeply_nested_scene_is_one_line(tmp_path):
    (tmp_path / "deep.toml").write_text("title = " + "[" * 100_000 + "]" * 100_000 + "\n")
    code, _, stderr = check_invocation(["modes", "deep.toml"], tmp_path)
    assert code == cli.EXIT_ERROR and "nested" in stderr


# ------------------------------------------------------------------ random mixes
KEYS = ["shaft.length", "shaft.width", "shaft.height", "shaft.E", "shaft.rho", "shaft.supports",
        "delamination.0.start", "delamination.0.end", "delamination.0.upper_height",
        "delamination.0.contact_points", "delamination.0.friction", "delamination.0.friction_directions",
        "delamination.0.restitution", "delamination.0.weighting", "delamination.3.start", "obstacle.0.x",
        "rotation.speed_hz", "rotation.gravity", "rotation.phase_deg", "damping.rayleigh", "damping.external",
        "mesh.elements", "mesh.file", "mesh.axial", "reduction.method", "reduction.modes", "initial.state",
        "initial.velocity", "simulation.method", "simulation.t_end", "simulation.output_dt", "output.plots",
        "output.vtu_every", "title", "nonsense", "shaft", "delamination", "", ".", "shaft..E"]
VALUES = ["0", "-1", "1", "2", "7", "0.5", "1e-300", "1e300", "-1e300", "inf", "-inf", "nan", "3.5e5", "1e-12",
          '"x"', '"free-free"', '"clamped-free"', '"none"', '"modal"', '"stationary"', '"rk"', '"moreau"', "true",
          "[]", "[0]", "[0,0,0]", "[1e300,0]", "[0,1e300]", '["gap"]', '["nope"]', "{a=1}", "[[[]]]", "x=y",
          "'unterminated", '"\\u001b[2J"', '"\u00e9\u4e2d"', "", "0x10", "1_000", "12:00:00", "2026-11-23"]
OPTIONS = {
    "run": [[], ["--method", "rk"], ["--method", "penalty"], ["--method", "bogus"], ["--json"], ["--out", "o"],
            ["--out", ""], ["--out", "o/result.npz"]],
    "modes": [[], ["--count", "0"], ["--count", "-3"], ["--count", "3"], ["--count", "x"], ["--contact", "closed"],
              ["--contact", "ajar"], ["--json"]],
    "campbell": [[], ["--speeds", "0:30:3"], ["--speeds", "30:0:3"], ["--speeds", "0:nan:2"],
                 ["--speeds", "0:1e300:2"], ["--speeds", "::"], ["--count", "0"], ["--png", "c.png"],
                 ["--png", "."], ["--json"]],
    "stationary": [[], ["--json"], ["--bogus"]],
    "export": [["--vtu", "v"], ["--vtu", ""], ["--vtu", "result.npz"], []],
    "render": [["--png", "r.png"], ["--png", "."], ["--time", "-1"], ["--time", "nan"], ["--time", "0.005"],
               ["--exaggeration", "0"], ["--exaggeration", "1e300"], ["--exaggeration", "nan"]],
}
FAST = {"run", "modes", "campbell", "stationary", "export", "render"}


@st.composite
def invocations(draw, commands=tuple(sorted(FAST))):
    command = draw(st.sampled_from(commands))
    argv = [command]
    if command in ("export", "render"):
        argv.append(draw(st.sampled_from(["RESULT", "RESULT", "missing.npz", ".", "scene.txt"])))
    else:
        argv += CHEAP
        for _ in range(draw(st.integers(0, 3))):
            key, value = draw(st.sampled_from(KEYS)), draw(st.sampled_from(VALUES))
            argv += ["--set", f"{key}={value}" if draw(st.booleans()) else key]
    argv += draw(st.sampled_from(OPTIONS[command]))
    return argv


def fuzz_one(argv: list[str], result: Path) -> None:
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        (root / "scene.txt").write_text("not a scene\n")
        argv = [str(result) if a == "RESULT" else a for a in argv]
        check_invocation(argv, root)


@settings(max_examples=80, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(invocations())
def test_fuzz_cli(saved_result, argv):
    fuzz_one(argv, saved_result)


@pytest.mark.slow
@settings(max_examples=3000, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(invocations())
def test_fuzz_cli_many(saved_result, argv):
    fuzz_one(argv, saved_result)


# --- issue 32: resources, parsing and error messages (sweep / fit / export / measurement) ---
# The resources: --workers capped, run counts and simulated spans refused before any set-up, workers
# torn down on SIGTERM. The parsing: CSV cells, sample values, times, list indices, sensor names.
# The messages: each names the file, column and line (or the key and the count) it is about. And
# every JSON written is strict (RFC 8259: no NaN or Infinity).
import json
import math
import signal
import subprocess
import sys
import time

import numpy as np

from nsfem.errors import NsfemError
from nsfem.jsonio import dumps
from nsfem.measurement import ABSURD, GAP, read_measurement
from nsfem.result import check_times
from nsfem.sweep import MAX_POINTS, local_workers, max_workers, parse_ranges

#: the shipped shaft with two probes (as tests/test_fit.py), for fit's data checks: every one of them
#: comes before any run, so the data need not be the scene's
PROBES = ["--set", 'sensor.0.name="a"', "--set", "sensor.0.x=0.05", "--set", 'sensor.0.direction="+z"']
VARY = ["--vary", "delamination.0.start=0.1:0.4"]


def _strict(text: str):
    """JSON parsed strictly: NaN, Infinity and -Infinity are errors, as in every non-Python parser."""
    def refuse(token):
        raise ValueError(f"non-standard JSON token {token}")
    return json.loads(text, parse_constant=refuse)


def _data(root: Path, t, a, name: str = "d.csv") -> str:
    rows = [f"{ti!r},{ai!r}" for ti, ai in zip(map(float, t), map(float, a))]
    (root / name).write_text("t,a\n" + "\n".join(rows) + "\n")
    return name


T = np.arange(50) * 1e-3                       # 50 samples, 1 ms apart (the default output step)
A = 1e-4 * np.sin(2 * np.pi * 40 * T + 0.3)


def _fit_argv(data: str, *extra: str) -> list[str]:
    return ["fit", *PROBES, "--data", data, *VARY, "--out", "f", *extra]


def _csv_case(root: Path, case: str) -> str:
    """The issue's hostile data files, by name."""
    t, a = T.copy(), A.copy()
    if case == "1e308":
        a[7] = 1e308
    elif case == "denormal":
        a = np.full_like(a, 5e-324) * np.sign(np.sin(np.arange(a.size)) + 0.5)
    elif case == "duplicated":
        t[10] = t[9]
    elif case == "unsorted":
        t[10], t[11] = t[11], t[10]
    elif case == "gap":
        t[25:] += 1000.0
    elif case == "late":
        t = t + 1e6
    elif case == "apart":
        t, a = np.array([0.0, 1000.0]), np.array([1e-4, -1e-4])
    name = _data(root, t, a)
    if case == "underscore":
        path = root / name
        lines = path.read_text().splitlines()
        lines[5] = lines[5].split(",")[0] + ",1_0e-5"
        path.write_text("\n".join(lines) + "\n")
    return name


# (case, words the one-line error must hold: the file, the column and the line it is about)
DATA_CASES = [
    ("1e308", ["d.csv", "column 'a'", "line 9", "1e+308"]),
    ("denormal", ["d.csv", "column 'a'", "below 1e-100"]),
    ("duplicated", ["d.csv", "column 't'", "lines 11 and 12"]),
    ("unsorted", ["d.csv", "column 't'", "t must increase", "lines 12 and 13"]),
    ("gap", ["d.csv", "column 't'", "lines 26 and 27", "gap"]),
    ("late", ["d.csv", "column 't'", "starts at t = 1e+06 s (line 2)"]),
    ("apart", ["d.csv", "column 't'", "2 samples up to line 3"]),
    ("underscore", ["d.csv", "line 6", "column 'a'", "'1_0e-5' is not a number"]),
]


@pytest.mark.parametrize("case, words", DATA_CASES, ids=[c for c, _ in DATA_CASES])
def test_issue32_hostile_data_name_the_file_column_and_line(case, words, tmp_path, monkeypatch):
    import nsfem.sweep

    monkeypatch.setattr(nsfem.sweep, "_client", lambda *a, **k: pytest.fail("a cluster was started"))
    code, _, stderr = check_invocation(_fit_argv(_csv_case(tmp_path, case)), tmp_path)
    assert code == cli.EXIT_ERROR
    for w in words:
        assert w in stderr, (w, stderr)
    assert "simulation.output_dt" not in stderr      # a key the user never set is never blamed


def test_issue32_two_million_samples_blame_the_data_not_output_dt():
    """2e6 samples 1 ms apart: 2000 s of runs, 2e6 outputs each: the data are named, not a key."""
    from nsfem.fit.problem import MAX_OUTPUTS, prepare

    t = np.arange(2_000_000) * 1e-3
    with pytest.raises(NsfemError, match=r"^data: column 't': the runs would simulate 0 to 2000 s") as info:
        prepare(None, (t, {"a": np.sin(t)}), ["delamination.0.start=0.1:0.4"], overrides=[o for o in PROBES
                                                                                          if o != "--set"])
    assert f"{MAX_OUTPUTS:.0e}" in str(info.value) and "output_dt" not in str(info.value)


@given(st.lists(st.sampled_from(["0", "1e-3", "-2.5e-4", " 7.0 ", "1_0e-5", "0x10", "1,5", "", "nan", "inf",
                                 "1e308", "-1e101", "5e-324", "1e-99", "１", "1e", ".5", "5.", "+3", "infinity",
                                 "1 0", "\u00a0"]),
                min_size=2, max_size=8),
       st.sampled_from([(0.0, 1e-3), (1e-3, 1e-3), (0.0, 0.0), (0.0, -1e-3), (1e6, 1e-3), (0.0, 1e3), (-1.0, 1.0)]),
       st.integers(0, 7))
@settings(max_examples=150, deadline=None, derandomize=True, database=None)
def test_issue32_property_data_are_refused_naming_the_file_or_kept_exactly(cells, clock, jump):
    """Any data file: a one-line error naming the file (and a line or column), or a measurement whose
    every value is the cell's decimal number, finite and within 1/ABSURD..ABSURD, times increasing
    with no step below 1e-3 or above GAP median steps."""
    t = clock[0] + clock[1] * np.arange(len(cells))
    if jump < len(cells):
        t[jump:] += 0.5                  # sometimes a step of its own
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "m.csv"
        path.write_text("t,a\n" + "".join(f"{ti!r},{c}\n" for ti, c in zip(t, cells)))
        try:
            m = read_measurement(path)
        except NsfemError as exc:
            text = str(exc)
            assert "\n" not in text and text.startswith(f"--data {path}: ")
            assert any(w in text for w in ("line", "column", "samples", "empty")), text
            return
    values = m.values[:, 0]
    assert np.all(np.isfinite(values)) and np.max(np.abs(values)) <= ABSURD
    assert np.max(np.abs(values)) >= 1 / ABSURD
    steps = np.diff(m.t)
    assert np.all(steps > 0) and np.max(steps) <= GAP * np.median(steps) and m.t[0] >= 0
    kept = [c for c in cells if c.strip()]
    assert len(kept) == values.size     # blank cells are blank rows only when the whole row is; else refused
    for c, v in zip(kept, values):
        assert c.strip().isascii() and "_" not in c and v == float(c)


# ----- run counts and workers
def test_issue32_worker_counts_are_capped_and_never_exceed_the_runs(tmp_path, monkeypatch):
    import nsfem.sweep

    monkeypatch.setattr(nsfem.sweep, "_client", lambda *a, **k: pytest.fail("a cluster was started"))
    cap = max_workers()
    for argv in (["sweep", *CHEAP, "--set", "rotation.speed_hz=10:20:2", "--workers", "1000"],
                 _fit_argv(_data(tmp_path, T, A), "--workers", "1000")):
        code, _, stderr = check_invocation(argv, tmp_path)
        assert code == cli.EXIT_ERROR and f"--workers 1000: more than 4 per core ({cap} " in stderr


@given(st.one_of(st.none(), st.integers(-3, 10 ** 6)), st.integers(1, 10 ** 6))
@settings(max_examples=200, deadline=None, derandomize=True, database=None)
def test_issue32_property_local_workers(workers, runs):
    """Refused (below 1, above 4 per core) or between 1 and the runs: never a process without a run."""
    try:
        n = local_workers(workers, runs)
    except NsfemError as exc:
        assert workers is not None and (workers < 1 or workers > max_workers()) and "--workers" in str(exc)
        return
    assert 1 <= n <= runs and (workers is None or n <= workers)


@given(st.lists(st.integers(1, 400), min_size=1, max_size=3))
@settings(max_examples=60, deadline=None, derandomize=True, database=None)
def test_issue32_property_run_counts_are_refused_before_any_scene(counts):
    """A grid of more than MAX_POINTS runs is one line naming each key, its count and the total; the
    count is known from the ranges alone (no scene is loaded)."""
    keys = ["rotation.speed_hz", "damping.external", "rotation.phase_deg"][:len(counts)]
    sets = [f"{k}=0:1:{n}" if n > 1 else f"{k}=1:1:1" for k, n in zip(keys, counts)]
    total = math.prod(counts)
    try:
        _, axes = parse_ranges(sets)
    except NsfemError as exc:
        assert total > MAX_POINTS and f"the sweep has {total} runs" in str(exc)
        assert all(f"{k}: {n} values" in str(exc) for k, n in zip(keys, counts))
        return
    assert total <= MAX_POINTS and [len(a.values) for a in axes] == counts


def test_issue32_huge_sweeps_are_refused_at_once(tmp_path, monkeypatch):
    """Refused from the ranges alone: no scene is loaded (90 000 scenes took 9 minutes)."""
    import nsfem.scene

    monkeypatch.setattr(nsfem.scene, "load_scene", lambda *a, **k: pytest.fail("a scene was loaded"))
    for argv, words in ((["sweep", "crack", *F, "--set", "rotation.speed_hz=1:20:90000"], "N = 90000 exceeds"),
                        (["sweep", *F, "--set", "rotation.speed_hz=1:20:300", "--set", "damping.external=0:1:300"],
                         "the sweep has 90000 runs (rotation.speed_hz: 300 values x damping.external: 300 values)")):
        code, _, stderr = check_invocation(argv, tmp_path)
        assert code == cli.EXIT_ERROR and words in stderr


def test_issue32_a_large_sweep_loads_its_scenes_lazily(monkeypatch):
    """1000 runs of the crack scene: 64 values are checked before anything runs; the others are loaded
    as their runs are submitted (9 minutes for 90 000 scenes before the first run)."""
    from nsfem.sweep import CHECKED_VALUES, plan

    p = plan("crack", ["rotation.speed_hz=1:20:1000"])
    assert len(p.points) == 1000 and len(p.scenes) == CHECKED_VALUES
    assert p.scene(500).rotation.speed_hz == pytest.approx(p.points[500]["rotation.speed_hz"])
    with pytest.raises(NsfemError, match="rotation.speed_hz"):   # a checked value the scene refuses
        plan("crack", ["rotation.speed_hz=-1:20:1000"])


# ----- list indices and sensor names
@given(st.integers(0, 4), st.booleans())
@settings(max_examples=10, deadline=None, derandomize=True, database=None)
def test_issue32_property_a_swept_or_varied_item_must_exist(index, swept):
    """``crack.K.depth`` on the crack scene (one crack): K = 0 is swept/varied, any other K is refused
    by sweep and fit alike, naming the item (an override there would add a crack)."""
    from nsfem.fit.problem import _check_item
    from nsfem.scene import load_scene
    from nsfem.sweep import plan

    key = f"crack.{index}.depth"
    try:
        if swept:
            plan("crack", [f"{key}=0.1:0.3:2"])
        else:
            _check_item(load_scene("crack"), key)
    except NsfemError as exc:
        assert index >= 1 and f"the scene has no crack.{index} " in str(exc)
        return
    assert index == 0


def test_issue32_sweep_past_the_last_crack_is_refused(tmp_path):
    code, _, stderr = check_invocation(["sweep", "crack", *F, "--set", "crack.1.depth=0.1:0.3:2"], tmp_path)
    assert code == cli.EXIT_ERROR and "--set crack.1.depth=START:STOP:N: the scene has no crack.1" in stderr


@given(st.text(st.sampled_from(list("ab_ -,\"'\t\n\x1b.é")), min_size=1, max_size=6))
@settings(max_examples=60, deadline=None, derandomize=True, database=None)
def test_issue32_property_sensor_names_round_trip_or_are_refused(name):
    """A sensor name is refused at scene load, naming sensor.0.name, or sensors.csv's header read back
    (as fit reads it) gives the name exactly."""
    from nsfem.measurement import read_measurement
    from nsfem.scene import load_scene
    from nsfem.sensors import write_csv

    try:
        scene = load_scene(None, [f"sensor.0.name={json.dumps(name)}", "sensor.0.x=0.05"])
    except NsfemError as exc:
        assert str(exc).startswith("sensor.0.name: ") and "\n" not in str(exc)
        return
    with tempfile.TemporaryDirectory() as d:
        path = write_csv(Path(d) / "sensors.csv", T, scene.sensors, A[:, None])
        assert read_measurement(path).names == (name,)


def test_issue32_padded_sensor_name_is_refused_by_run(tmp_path):
    code, _, stderr = check_invocation(["run", *CHEAP, "--set", 'sensor.0.name=" padded "', "--set",
                                        "sensor.0.x=0.05"], tmp_path)
    assert code == cli.EXIT_ERROR and "sensor.0.name: ' padded ' begins or ends with a blank" in stderr


# ----- export of damaged results
def _tampered(saved: Path, root: Path, case: str) -> str:
    with np.load(saved) as r:
        arrays = {k: r[k] for k in r.files}
    t = arrays["t"]
    if case == "empty":
        for k in ("t", "q", "v", "gap", "normal_force", "state", "tangential_force"):
            arrays[k] = arrays[k][..., :0]
    elif case == "reversed":
        arrays["t"] = t[::-1].copy()
    elif case == "scaled":
        arrays["t"] = t * 1e300
    elif case == "nan":
        arrays["t"] = t.copy()
        arrays["t"][3] = np.nan
    with open(root / f"{case}.npz", "wb") as fh:
        np.savez_compressed(fh, **arrays)
    return f"{case}.npz"


@pytest.mark.parametrize("case, words", [("empty", "holds no output time"), ("reversed", "do not increase"),
                                         ("scaled", "lie outside the run's span"), ("nan", "is nan (not finite)")])
def test_issue32_export_refuses_damaged_times(saved_result, case, words, tmp_path):
    name = _tampered(saved_result, tmp_path, case)
    for argv in (["export", name, "--vtu", "v"], ["render", name, "--png", "r.png"]):
        code, _, stderr = check_invocation(argv, tmp_path)
        assert code == cli.EXIT_ERROR and f"{name}: " in stderr and words in stderr, stderr
        assert not (tmp_path / "v").exists() and not (tmp_path / "r.png").exists()


@given(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.just(0.0)), max_size=6),
       st.floats(0.0, 10.0))
@settings(max_examples=150, deadline=None, derandomize=True, database=None)
def test_issue32_property_result_times_are_refused_or_sane(times, t_end):
    """Output times are refused (one line naming the file) or non-empty, finite, increasing and in
    [0, t_end] to 1e-9 of t_end."""
    t = np.array(times, dtype=float)
    try:
        check_times(t, t_end, "r.npz")
    except NsfemError as exc:
        assert str(exc).startswith("r.npz: ") and "\n" not in str(exc)
        return
    assert t.size and np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)
    assert t[0] >= -1e-9 * t_end and t[-1] <= t_end * (1 + 1e-9)


# ----- strict JSON
FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10 ** 20, 10 ** 20),
                   st.floats(allow_nan=True, allow_infinity=True).map(np.float64),
                   st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=3).map(np.array))
PAYLOADS = st.recursive(st.one_of(FLOATS, st.none(), st.booleans(), st.text(max_size=3)),
                        lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                st.dictionaries(st.text(max_size=3), inner, max_size=3)),
                        max_leaves=12)


def _same(a, b) -> bool:
    """``b`` (parsed JSON) is ``a`` with numpy values as Python ones and every non-finite float None."""
    if isinstance(a, np.ndarray):
        a = a.tolist()
    if isinstance(a, np.generic):
        a = a.item()
    if isinstance(a, float) and not math.isfinite(a):
        return b is None
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return isinstance(b, list) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b and type(a) is type(b)


@given(PAYLOADS)
@settings(max_examples=150, deadline=None, derandomize=True, database=None)
def test_issue32_property_json_is_strict(payload):
    """Whatever the payload, the JSON text parses strictly and gives it back, NaN/inf as null (finite
    floats exactly: repr round-trips a double)."""
    assert _same(payload, _strict(dumps(payload)))


def test_issue32_overflowed_sweep_run_is_a_failed_row_in_strict_json(tmp_path, monkeypatch):
    """The issue's sweep (unbalance 1e-3:1e300:2, which printed ``"energy": NaN``) is refused at load now
    (an unbalance beyond 1e12 x an element's mass x the rotor's length); a run whose motion overflows all
    the same (made so here: its displacements infinite) fails its row with the reason, holds no
    amplitudes, and sweep.json parses strictly."""
    distributed = pytest.importorskip("distributed")
    import nsfem.simulate
    from nsfem.sweep import run_sweep

    # 0.05 s: the last half holds a whole period of 50 Hz, which the 1x amplitude needs (issue 34)
    base = ["simulation.t_end=0.05", "output.plots=[]", "output.vtu_every=0"]
    code, _, stderr = check_invocation(["sweep", "ross_example", *sum((["--set", o] for o in base), []), "--set",
                                        "unbalance.0.magnitude=1e-3:1e300:2", "--workers", "1", "--json"], tmp_path)
    assert code == cli.EXIT_ERROR and "unbalance.0.magnitude" in stderr
    real = nsfem.simulate.run_scene

    def overflowing(scene, *args, **kwargs):
        result, system = real(scene, *args, **kwargs)
        if scene["unbalance"][0]["magnitude"] > 5e-3:
            result.q[:, 1:] = np.inf
        return result, system

    monkeypatch.setattr(nsfem.simulate, "run_scene", overflowing)
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        res = run_sweep("ross_example", [*base, "unbalance.0.magnitude=1e-3:1e-2:2"], tmp_path / "s", client=c,
                        plot=False)
    payload = _strict((tmp_path / "s" / "sweep.json").read_text())
    ok, bad = payload["runs"]
    assert ok["error"] == "" and ok["amplitude_disk1_y_m"] > 0
    assert "overflowed" in bad["error"] and not any(k.startswith("amplitude_") for k in bad)
    assert all(v is None or not isinstance(v, float) or abs(v) < 1e100 for k, v in bad.items()
               if k != "unbalance.0.magnitude")
    assert len(res.failed) == 1


def test_issue32_fit_reports_a_reason_for_runs_whose_misfit_overflows():
    """A run whose signals overflow the misfit is a failed evaluation with a reason (it was an empty
    "(first: )" when every run of the global stage failed that way)."""
    from nsfem.fit.stages import _Runner
    from nsfem.measurement import Measurement, scales

    class Done:
        def __init__(self, value):
            self.value = value

        def result(self):
            return self.value

    m = Measurement(T, ("a",), A[:, None])
    runner = _Runner.__new__(_Runner)
    runner.problem = type("P", (), {"data": m, "kind": "time"})()
    runner.scale = scales(m, "time")
    ev = runner._evaluation(Done((np.full((T.size, 1), 1e300), "")), np.array([0.5]), "global")
    assert math.isinf(ev.misfit) and "not finite" in ev.error
    ev = runner._evaluation(Done((None, "")), np.array([0.5]), "global")
    assert ev.error


# ----- workers never outlive the command
def _descendants(pid: int) -> set[int]:
    parents: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            parents.setdefault(ppid, []).append(int(d.name))
    out, todo = set(), [pid]
    while todo:
        for c in parents.get(todo.pop(), []):
            out.add(c)
            todo.append(c)
    return out


def _running(pid: int) -> bool:
    try:
        return (Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]) != "Z"
    except OSError:
        return False


def _terminate_with_workers(argv: list[str], cwd: Path, started: str) -> None:
    """Start ``argv`` (a command with two local workers), wait for a stderr line starting with ``started``
    (its cluster is up), send SIGTERM: exit 130, one 'interrupted' line, no traceback, and none of its
    processes (scheduler, nannies, workers) alive within 30 s (their own exit, on a loaded machine)."""
    if not Path("/proc/self/stat").is_file():
        pytest.skip("needs /proc")
    proc = subprocess.Popen(argv, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, cwd=cwd)
    try:
        lines = []
        while not (lines and lines[-1].startswith(started)):
            line = proc.stderr.readline()
            assert line, "".join(lines)
            lines.append(line)
        family = _descendants(proc.pid)
        assert len(family) >= 2, family                    # at least the two workers
        proc.send_signal(signal.SIGTERM)
        err = proc.stderr.read()
        code = proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert code in (130, -signal.SIGINT) and "Traceback" not in err and "nsfem: interrupted" in err, err
    deadline = time.monotonic() + 30
    while any(map(_running, family)) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not [p for p in family if _running(p)]


@pytest.mark.slow   # 11-14 s (a cluster of two processes started, runs, torn down); the fast in-process
# check of the teardown is test_issue32_a_signal_while_the_cluster_starts_closes_it
def test_issue32_sigterm_during_a_sweep_leaves_no_process(tmp_path):
    """SIGTERM to ``nsfem sweep --workers 2`` once runs are under way: exit 130 with the finished rows,
    no traceback, and none of its processes (scheduler, nannies, workers) alive a few seconds later."""
    argv = [sys.executable, "-m", "nsfem", "sweep", *CHEAP, "--set", "rotation.speed_hz=10:30:12", "--workers", "2",
            "--out", str(tmp_path / "s")]
    _terminate_with_workers(argv, tmp_path, "[")           # "[" : a finished run


def test_issue32_signals_while_the_cluster_starts_are_held():
    """SIGTERM within the deferral is recorded and acted on after it (the cluster is then closed)."""
    import os

    from nsfem.sweep import _deferred_signals

    before = signal.getsignal(signal.SIGTERM)
    with _deferred_signals() as received:
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)
    assert received == [signal.SIGTERM] and signal.getsignal(signal.SIGTERM) is before


@pytest.mark.parametrize("every, writes", [(0.0, 4), (1e9, 2)])
def test_issue32_the_table_is_rewritten_at_most_once_per_interval(every, writes, tmp_path, monkeypatch):
    """Three runs: the table is written after each (interval 0) or after the first and at the end
    (an interval longer than the sweep); either way the final table holds all three rows."""
    distributed = pytest.importorskip("distributed")
    import nsfem.sweep

    calls = []
    real = nsfem.sweep.write_table
    monkeypatch.setattr(nsfem.sweep, "TABLE_EVERY", every)
    monkeypatch.setattr(nsfem.sweep, "TABLE_SHARE", 0.0)
    monkeypatch.setattr(nsfem.sweep, "write_table", lambda *a: calls.append(1) or real(*a))
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        res = nsfem.sweep.run_sweep(None, ["mesh.elements=20", "simulation.t_end=0.01", "rotation.speed_hz=10:30:3"],
                                    tmp_path, client=c, plot=False)
    assert not res.failed and len(calls) == writes
    assert len((tmp_path / "sweep.csv").read_text().splitlines()) == 1 + 3


@given(st.floats(0.0, 1e7), st.floats(1e-6, 1e3), st.integers(2, 50), st.floats(1e-6, 1e-2))
@settings(max_examples=200, deadline=None, derandomize=True, database=None)
def test_issue32_property_a_fits_simulated_span_is_bounded(t0, step, n, scene_dt):
    """Data from t0 on, n samples ``step`` apart: refused, naming the data's column t and a line, exactly
    when the runs (0 to the last sample, an output every output_step) would exceed MAX_OUTPUTS."""
    from nsfem.fit.problem import MAX_OUTPUTS, check_span, output_step
    from nsfem.measurement import Measurement

    t = t0 + step * np.arange(n)
    m = Measurement(t, ("a",), np.ones((n, 1)), tuple(range(2, n + 2)))
    dt = output_step(t, scene_dt)
    try:
        check_span(m, dt, "--data d.csv")
    except NsfemError as exc:
        assert t[-1] / dt > MAX_OUTPUTS
        assert str(exc).startswith("--data d.csv: column 't': ") and "line " in str(exc) and "\n" not in str(exc)
        return
    assert t[-1] / dt <= MAX_OUTPUTS


def test_issue32_a_lazily_loaded_scene_the_scene_refuses_fails_its_row_only(tmp_path, monkeypatch):
    """A large sweep checks some values before; a value it did not check and the scene refuses
    (mesh.elements = 20.5 between 20 and 21) fails its own row, the others run."""
    distributed = pytest.importorskip("distributed")
    import nsfem.sweep

    monkeypatch.setattr(nsfem.sweep, "CHECK_ALL", 1)
    monkeypatch.setattr(nsfem.sweep, "CHECKED_VALUES", 2)      # the ends: 20 and 21
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        res = nsfem.sweep.run_sweep(None, ["simulation.t_end=0.01", "mesh.elements=20:21:3"], tmp_path, client=c,
                                    plot=False)
    errors = {p["mesh.elements"]: r["error"] for p, r in zip(res.points, res.runs)}
    assert errors[20] == "" and errors[21] == "" and errors[20.5].startswith("scene refused: mesh.elements")
    assert res.info["models_built"] == 2


@pytest.mark.slow
def test_issue32_sigterm_during_a_fit_leaves_no_process(tmp_path):
    """As for the sweep: SIGTERM to ``nsfem fit --workers 2`` in its global stage exits 130 with the
    runs so far, no traceback, and no process of it alive afterwards."""
    data = _data(tmp_path, T, A)
    argv = [sys.executable, "-m", "nsfem", *_fit_argv(data, "--workers", "2", "--set", "mesh.elements=20",
                                                      "--no-refine")]
    _terminate_with_workers(argv, tmp_path, "[global")
    assert (tmp_path / "f" / "fit.json").is_file()


# --- issue 32: review of the inputs change (repeated sweep values, cluster teardown, the sweep table) ---
@pytest.mark.parametrize("text", ["10:10:3", "10:10.0000000000001:3", "0.1:0.1000000000001:2"])
def test_issue32_repeated_sweep_values_are_refused(text, tmp_path, monkeypatch):
    """Values that repeat at 12 digits (a run's folder name) were N runs of one value, at once into one
    folder, the table holding one row after "[3/3]"; now one line before anything is loaded."""
    import nsfem.scene

    monkeypatch.setattr(nsfem.scene, "load_scene", lambda *a, **k: pytest.fail("a scene was loaded"))
    code, _, stderr = check_invocation(["sweep", *F, "--set", f"rotation.speed_hz={text}"], tmp_path)
    assert code == cli.EXIT_ERROR and "are not distinct at 12 significant digits" in stderr, stderr


@given(st.floats(-1e3, 1e3), st.floats(0.0, 1e-6), st.integers(1, 40), st.sampled_from([1.0, 1e-9, 1e-15]))
@settings(max_examples=200, deadline=None, derandomize=True, database=None)
def test_issue32_property_every_run_of_a_sweep_has_its_own_folder(start, width, n, scale):
    """A range is refused (one line naming the key) or each of its values names a folder of its own."""
    from nsfem.sweep import run_name

    stop = start + width * scale if n > 1 else start
    try:
        _, [axis] = parse_ranges([f"rotation.speed_hz={start!r}:{stop!r}:{n}"])
    except NsfemError as exc:
        assert str(exc).startswith("--set rotation.speed_hz=START:STOP:N: ") and "\n" not in str(exc)
        return
    assert len({run_name({"k": v}) for v in axis.values}) == n == len(axis.values)


class _FakeCluster:
    """A LocalCluster and its Client that record their closing (no process is started)."""

    def __init__(self, events: list, signal_in: str | None = None):
        self.events, self.signal_in = events, signal_in

    def cluster(self, **kwargs):
        self.events.append("cluster")
        if self.signal_in == "cluster":
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(0.05)            # the handler runs in the main thread, between bytecodes
        return self

    def client(self, cluster):
        self.events.append("client")
        return self

    def close(self, timeout=None):
        self.events.append("closed")

    def wait_for_workers(self, n, timeout=None):
        pass


@pytest.mark.parametrize("where", ["cluster", "restore"])
def test_issue32_a_signal_while_the_cluster_starts_closes_it(where, monkeypatch):
    """SIGTERM while the local cluster starts ("cluster"), or arriving just as the deferred handlers are
    restored ("restore": the window between the deferral and the caller holding what to close; the
    cluster was left to distributed's failing close at exit): a KeyboardInterrupt, every part closed."""
    distributed = pytest.importorskip("distributed")
    import nsfem.sweep

    events: list = []
    fake = _FakeCluster(events, where)
    monkeypatch.setattr(distributed, "LocalCluster", fake.cluster)
    monkeypatch.setattr(distributed, "Client", fake.client)
    if where == "restore":
        real, first = nsfem.sweep._release_signals, []

        def release(held):
            real(held)
            if not first:
                first.append(1)
                raise KeyboardInterrupt     # as a signal handled right after the restore
        monkeypatch.setattr(nsfem.sweep, "_release_signals", release)

    def interrupt(signum, frame):
        raise KeyboardInterrupt
    before = signal.signal(signal.SIGTERM, interrupt)    # as the command line's SIGTERM handler
    try:
        with pytest.raises(KeyboardInterrupt):
            nsfem.sweep._client(None, 1, None, 1)
    finally:
        signal.signal(signal.SIGTERM, before)
    assert events == ["cluster", "client", "closed", "closed"], events


def test_issue32_table_cells_do_not_depend_on_a_resume():
    """A non-finite value is an empty cell, as its JSON null read back from record.json on a resume (the
    table said "nan" for a fresh row, "" for the same row resumed)."""
    from nsfem.sweep import Axis, write_table

    row = {"k": 1.0, "energy": float("nan"), "min_gap_m": float("-inf"), "max_gap_m": 2e-5, "error": "overflow"}
    with tempfile.TemporaryDirectory() as d:
        fresh = write_table(Path(d) / "a.csv", [Axis("k", (1.0,))], [row]).read_text()
        resumed = write_table(Path(d) / "b.csv", [Axis("k", (1.0,))], [json.loads(dumps(row))]).read_text()
    assert fresh == resumed and "nan" not in fresh and "inf" not in fresh and "2e-05" in fresh


def test_issue32_a_sweep_that_stops_on_an_error_keeps_its_finished_rows_in_the_table(tmp_path, monkeypatch):
    """The table is rewritten at most once a second; a sweep stopped by an error (here its progress
    stream broken after the second run) still leaves every finished row in sweep.csv and sweep.json."""
    distributed = pytest.importorskip("distributed")
    import nsfem.sweep

    monkeypatch.setattr(nsfem.sweep, "TABLE_EVERY", 1e9)        # only the first row is written on the way

    def progress(line):
        if line.startswith("[2/"):
            raise BrokenPipeError("stderr closed")
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        with pytest.raises(BrokenPipeError):
            nsfem.sweep.run_sweep(None, ["mesh.elements=20", "simulation.t_end=0.01", "rotation.speed_hz=10:30:3"],
                                  tmp_path, client=c, progress=progress, plot=False)
    assert len((tmp_path / "sweep.csv").read_text().splitlines()) == 1 + 2
    assert len(_strict((tmp_path / "sweep.json").read_text())["runs"]) == 2


def test_issue32_workers_that_join_a_running_sweep_get_runs(tmp_path, monkeypatch):
    """A scheduler's workers may join after the sweep began (it waits for the first only): the runs kept
    submitted follow the cluster's threads, AHEAD per thread (they were fixed at 2 per worker present
    at the start: one worker then, two runs at a time for the whole sweep, however many joined)."""
    distributed = pytest.importorskip("distributed")
    import nsfem.sweep
    from nsfem.sweep import AHEAD

    monkeypatch.setattr(nsfem.sweep, "THREADS_EVERY", 0.0)      # look at the threads before every submission
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        finished, in_flight = [0], []
        submit = c.submit

        def counted(*args, **kwargs):
            in_flight.append(len(in_flight) + 1 - finished[0])      # with this one, as the client counts them
            return submit(*args, **kwargs)
        c.submit = counted

        def progress(line):
            if line.startswith("["):
                finished[0] += 1
                if finished[0] == 1:                                 # two more workers join
                    c.cluster.scale(3)
                    c.wait_for_workers(3, timeout=60)
        res = nsfem.sweep.run_sweep(None, ["mesh.elements=20", "simulation.t_end=0.01", "rotation.speed_hz=10:30:12"],
                                    tmp_path, client=c, progress=progress, plot=False)
    assert not res.failed and len(in_flight) == 12
    assert max(in_flight[:AHEAD]) == AHEAD and max(in_flight) == 3 * AHEAD, in_flight


def test_issue32_an_ignored_signal_stays_ignored_while_the_cluster_starts():
    """SIGINT ignored (a job a shell starts in the background): the deferral neither records it (it was
    then raised as a KeyboardInterrupt once the cluster was there) nor leaves another handler behind."""
    from nsfem.sweep import _deferred_signals

    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with _deferred_signals() as received:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.05)
        assert received == [] and signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, before)


def test_issue32_a_data_loggers_csv_is_read_exactly(tmp_path):
    """A logger's export: a byte-order mark, quoted heads, CRLF line ends, a delimiter ending every line,
    blanks around cells, '+' signs and exponents, negative values, nanometre amplitudes (1e-9 m, far above
    1/ABSURD), t from 5 s, a trailing empty line: read back to the bit (every cell is a decimal that
    float() reads exactly as it reads the text)."""
    t = 5.0 + np.arange(200) / 51200
    a = 3e-9 * np.sin(2 * np.pi * 120 * t)
    cells = [(f"{ti:+.9e}", f" {ai:.6E} ") for ti, ai in zip(t, a)]
    text = '\ufeff"t","a",\r\n' + "".join(f"{ti},{ai},\r\n" for ti, ai in cells) + "\r\n"
    (tmp_path / "log.csv").write_bytes(text.encode("utf-8"))
    m = read_measurement(tmp_path / "log.csv")
    assert m.names == ("a",) and m.lines == tuple(range(2, 202))
    assert np.array_equal(m.t, [float(ti) for ti, _ in cells])
    assert np.array_equal(m.values[:, 0], [float(ai) for _, ai in cells])


@given(st.lists(st.tuples(st.integers(0, 5), st.integers(0, 3), st.one_of(st.none(), st.integers(0, 9))),
                max_size=30))
@settings(max_examples=150, deadline=None, derandomize=True, database=None)
def test_issue32_property_sweep_rows_stay_sorted_and_latest(entries):
    """Rows entered in any order (None: a point to do; a row replaces the point's row, None never does):
    the points sorted by the swept values, each with its latest row, whether it was sorted in or
    replaced in place."""
    from nsfem.sweep import Axis, SweepResult

    res = SweepResult([Axis("a", tuple(range(6))), Axis("b", tuple(range(4)))], [], [], Path("o"), Path("o/t.csv"))
    latest: dict = {}
    for a, b, tag in entries:
        res.set_row({"a": a, "b": b}, None if tag is None else {"tag": tag})
        if tag is not None or (a, b) not in latest:
            latest[(a, b)] = tag
    assert [(p["a"], p["b"]) for p in res.points] == sorted(latest)
    assert [None if r is None else r["tag"] for r in res.runs] == [latest[k] for k in sorted(latest)]


def test_issue32_a_scene_edited_during_a_sweep_does_not_change_its_later_runs(tmp_path, monkeypatch):
    """Scenes loaded as their runs are submitted come from the scene's text as the sweep read it (the
    file edited during a sweep of hours changed its later runs, under the first text's fingerprint)."""
    import nsfem.sweep
    from nsfem.scene import default_scene_path

    monkeypatch.setattr(nsfem.sweep, "CHECK_ALL", 1)
    monkeypatch.setattr(nsfem.sweep, "CHECKED_VALUES", 2)            # the ends; the middle loaded later
    scene = tmp_path / "s.toml"
    text = default_scene_path().read_text(encoding="utf-8")
    title = next(line for line in text.splitlines() if line.startswith("title = "))
    scene.write_text(text.replace(title, 'title = "as planned"'))
    p = nsfem.sweep.plan(scene, ["rotation.speed_hz=10:20:3"])
    assert 1 not in p.scenes
    scene.write_text(text.replace(title, 'title = "edited"'))
    later = p.scene(1)
    assert later["title"] == "as planned" and later.rotation.speed_hz == 15 and later.path == scene


def test_issue32_a_mesh_edited_during_a_sweep_fails_the_models_built_after(tmp_path, monkeypatch):
    """Models are built as their first run is submitted: after the mesh file changed, the later models'
    rows fail naming it (they were built from the edited mesh, under the first mesh's fingerprint)."""
    distributed = pytest.importorskip("distributed")
    import nsfem.sweep

    mesh = tmp_path / "m.msh"
    mesh.write_bytes((Path(__file__).parents[1] / "meshes" / "paper_stack_20.msh").read_bytes())
    monkeypatch.setattr(nsfem.sweep, "AHEAD", 1)          # one run at a time: one model built per finished run

    def progress(line):
        if line.startswith("[1/"):
            mesh.write_bytes(mesh.read_bytes() + b"\n")
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        res = nsfem.sweep.run_sweep(None, [f"mesh.file={mesh}", "simulation.t_end=0.01", "output.vtu_every=0",
                                           "delamination.0.friction=0:0.2:3"], tmp_path / "s", client=c,
                                    progress=progress, plot=False)
    errors = [r["error"] for r in res.runs]
    assert errors[0] == "" and all(f"the mesh file {mesh} has changed since the sweep began" in e for e in errors[1:])
    assert res.info["models_built"] == 1


# --- issue 32: physics validation (tracebacks, silently wrong results, errors that blame the wrong key) ---
# Each listed case: (argv, outcome, text): "error" = exit 2 with one line holding text (the key the user
# set); "ok" = exit 0; "warn" = exit 0 with text on stderr. No Python warning may leak (IntegrationWarning,
# RuntimeWarning): the messages are ours. Tiny models (6 to 10 elements): the checks act before or around
# the computation, whatever its size.
ROSS = ["ross_example", "--set", "mesh.elements=6", "--set", "reduction.modes=8"]
RUB = ["rub", "--set", "mesh.elements=8", "--set", "reduction.modes=6"]
CRACK = ["crack", "--set", "mesh.elements=10"]
TINY_RUN = ["--set", "simulation.t_end=0.002", "--set", "simulation.output_dt=0.001", "--set", "output.vtu_every=0",
            "--set", "output.plots=[]"]
PHYSICS_CASES = [
    # shallow cracks: a stiff hinge tending to the intact shaft, no ZeroDivisionError, no IntegrationWarning
    *[(["modes", *CRACK, "--set", f"crack.0.depth={d}"], "ok", "") for d in ("1e-300", "1e-200", "1e-17", "1e-10",
                                                                             "1e-6", "1e-3")],
    (["modes", *CRACK, "--set", "crack.0.depth=1e-10", "--set", "shaft.section=\"rectangle\"",
      "--set", "shaft.width=0.02", "--set", "shaft.height=0.02"], "ok", ""),
    # absurd penalty factors and tolerances are refused at load, naming the key
    (["run", "rub", "--method", "penalty", *TINY_RUN, "--set", "simulation.penalty_factor=1e-300"], "error",
     "simulation.penalty_factor"),
    (["run", "rub", "--method", "penalty", *TINY_RUN, "--set", "simulation.penalty_factor=1e300"], "error",
     "simulation.penalty_factor"),
    (["run", "--method", "rk", *TINY_RUN, "--set", "simulation.rtol=1e-300"], "error", "simulation.rtol"),
    (["run", "--method", "penalty", *TINY_RUN, "--set", "simulation.rtol=1e-14"], "error", "simulation.rtol"),
    # damping beyond double precision is blamed on damping in stationary as in run; a bearing's on the bearing
    (["stationary", "--set", "damping.external=1e300"], "error", "damping.external"),
    (["run", *ROSS, *TINY_RUN, "--set", "bearing.0.cyy=1e300"], "error", "bearing.0.cyy"),
    # zeta = c / (2 sqrt(k m)) = 3e11 on the stiffest element: "no progress" at t = 0 before, a result without samples
    (["run", *ROSS, *TINY_RUN, "--set", "bearing.0.cyy=5e16"], "error", "bearing.0.cyy"),
    (["run", *RUB, *TINY_RUN, "--set", "stator.0.stiffness=1e300"], "error", "stator.0.stiffness"),
    (["run", *RUB, *TINY_RUN, "--set", "stator.0.stiffness=1e6", "--set", "stator.0.damping=1e300"], "error",
     "stator.0.damping"),
    (["run", *TINY_RUN, "--set", "stator=[{x=0.5}]"], "error", "inside delamination.0 [0.1, 0.9]"),
    # stationary names the actual cause of an unsymmetric Q
    (["stationary", *RUB, "--set", "bearing.0.kyz=1e3", "--set", "bearing.0.kzy=-1e3"], "warn",
     "bearing.0's cross coupling"),
    # found by the hunt over keys x extreme values x commands
    (["modes", *ROSS, "--set", "bearing.0.kyz=1e300"], "error", "bearing.0.kyz"),        # was OverflowError
    (["campbell", *ROSS, "--speeds", "0:10:2", "--set", "bearing.0.czy=1e300"], "error", "bearing.0.czy"),
    (["modes", *ROSS, "--set", "bearing.0.kzz=-1"], "error", "bearing.0.kzz"),            # blamed kyy
    (["modes", *ROSS, "--set", "bearing.0.czy=-1"], "error", "bearing.0.czy"),            # blamed cyy
    (["modes", *ROSS, "--set", "disk.0.outer_diameter=1e300"], "error", "disk.0.outer_diameter"),  # blamed mass
    (["modes", *ROSS, "--set", "disk.0.width=1e300"], "error", "disk.0.width"),           # "disk.0.diametral"
    (["modes", *ROSS, "--set", "shaft.diameter=1e-300"], "error", "shaft.diameter"),      # blamed shaft.width
    (["modes", *ROSS, "--set", "disk.0.x=1e-300"], "error", "disk.0.x"),                  # blamed mesh.elements
    (["modes", *ROSS, "--set", "unbalance.0.x=1e-300"], "error", "unbalance.0.x"),        # blamed mesh.elements
    (["campbell", *RUB, "--speeds", "0:10:2", "--set", "disk.0.polar_inertia=1e300"], "error",
     "disk.0.polar_inertia"),                                                              # was ValueError
    (["stationary", *RUB, "--set", "disk.0.diametral_inertia=1e300"], "error", "disk.0.diametral_inertia"),
    (["stationary", *RUB, "--set", "stator.0.radius=1e300"], "error", "stator.0.radius"),  # was LinAlgError
    (["stationary", *RUB, "--set", "unbalance.0.magnitude=1e300"], "error", "unbalance.0.magnitude"),
    (["modes", "--set", "delamination.0.start=1e-300"], "error", "delamination.0.start"),  # mesh.elements
    (["modes", "--set", "delamination.0.start=1e300"], "error", "delamination.0.start"),   # blamed .end
    (["modes", "--set", "delamination.0.end=1e300"], "error", "delamination.0.end"),       # "delamination.0:"
    (["run", "--method", "penalty", *TINY_RUN, "--set", "obstacle.0.clearance=0"], "ok",
     ""),                                    # a stop on a pinned end (never touched): penalty's RuntimeWarning
]


def check_physics_invocation(argv, root):
    """:func:`check_invocation`, and no Python warning escapes (nsfem words its own)."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code, out, err = check_invocation(argv, root)
    leaked = [f"{w.category.__name__}: {w.message}" for w in caught
              if not issubclass(w.category, (DeprecationWarning, PendingDeprecationWarning))]
    assert not leaked, (argv, leaked)
    return code, out, err


@pytest.mark.parametrize("argv, outcome, text", PHYSICS_CASES, ids=[" ".join(c[0]) for c in PHYSICS_CASES])
def test_physics_reproductions(argv, outcome, text, tmp_path):
    code, _, stderr = check_physics_invocation(argv, tmp_path)
    assert code == (cli.EXIT_ERROR if outcome == "error" else 0), stderr
    assert text in stderr, stderr
    if outcome == "error":
        assert not (tmp_path / "out" / "result.npz").exists()   # refused before any computation


def test_penetration_warning_names_the_key():
    """A penalty run that lets the rotor 1.65 mm into a 0.25 mm ring (the issue's penalty_factor = 1e-300)
    warns, naming the key; one 1 % of the clearance in (what the default factor gives) does not."""
    from types import SimpleNamespace

    import numpy as np

    from nsfem.analysis.deflection import penetration_warning
    from nsfem.stack import Contact

    ring = SimpleNamespace(contacts=(Contact("obstacle", 0.4, ("s",), clearance=2.5e-4, label="stator.0.0"),
                                     Contact("obstacle", 0.4, ("s",), clearance=2.5e-4, label="stator.0.1")))
    for method, depth, warned in (("penalty", 1.65e-3, True), ("moreau", 1.65e-3, True), ("penalty", 2.5e-6, False)):
        gap = np.array([[2.5e-4, -depth, 1e-4], [2.5e-4, 4e-4, 2e-4]])
        result = SimpleNamespace(gap=gap, info={"contacts": ["stator.0.0", "stator.0.1"]}, method=method)
        text = penetration_warning(result, ring)
        assert (text is not None) == warned, text
        if warned:
            assert "0.00165 m deep at stator.0.0" in text
            assert ("penalty_factor" if method == "penalty" else "moreau_step") in text


# one property per class: an absurd magnitude (+-1e300) of a component's physical key, under any command,
# exits 0 (a command the key does not enter: modes ignores damping) or 2 with one line (check_invocation) that
# names the key set, and leaks no Python warning
EXTREME_KEYS = [(ROSS, k) for k in ("bearing.0.kyy", "bearing.0.kzz", "bearing.0.kyz", "bearing.0.kzy", "bearing.0.cyy",
                                    "bearing.0.czz", "bearing.0.cyz", "bearing.0.czy", "bearing.0.kxx", "bearing.0.x",
                                    "disk.0.outer_diameter", "disk.0.width", "disk.0.x", "unbalance.0.magnitude",
                                    "unbalance.0.x", "damping.external", "rotation.speed_hz", "shaft.diameter")] + \
               [(RUB, k) for k in ("stator.0.stiffness", "stator.0.damping", "stator.0.radius", "stator.0.clearance",
                                   "stator.0.x", "disk.0.mass", "disk.0.polar_inertia", "disk.0.diametral_inertia")] + \
               [(CRACK, k) for k in ("crack.0.depth", "crack.0.x")]
COMMANDS = [["modes"], ["stationary"], ["campbell", "--speeds", "0:10:2"], ["run", *TINY_RUN]]


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(EXTREME_KEYS), st.sampled_from(["1e300", "-1e300"]), st.sampled_from(COMMANDS))
def test_extreme_component_values_name_their_key(case, value, command):
    scene, key = case
    with tempfile.TemporaryDirectory() as d:
        code, _, stderr = check_physics_invocation([command[0], *scene, *command[1:], "--set", f"{key}={value}"],
                                                   Path(d))
    assert code == 0 or key in stderr, stderr


@settings(max_examples=6, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.floats(min_value=1e-300, max_value=0.5, allow_subnormal=False).map(lambda d: float(f"{d:.3g}")),
       st.sampled_from(["modes", "stationary"]))
def test_any_crack_depth_runs(depth, command):
    """Any depth in (0, 0.5] of the circle's crack gives an answer, without a warning leaking."""
    with tempfile.TemporaryDirectory() as d:
        code, _, stderr = check_physics_invocation([command, *CRACK, "--set", f"crack.0.depth={depth!r}"], Path(d))
    assert code == 0, stderr


# --- issue 32: output folders (signals during writes, one run per folder, bounded files) ---
import re  # noqa: E402

import numpy as np  # noqa: E402

from nsfem.atomic import write_text_atomic  # noqa: E402
from nsfem.outdir import FIT_FILES, LOCK, MANIFEST, claim  # noqa: E402

#: a tiny cracked rotor (4 VTU files a frame), a few hundredths of a second per output
TINY = ["crack", "--set", "mesh.elements=10"]


def folder_is_valid(out: Path, foreign=()) -> list[str]:
    """The files of a folder a run left (those of its subfolder vtu/ as ``vtu/<name>``, the subfolder
    itself not listed); asserts the property: no temporary file, a .pvd that indexes exactly the
    frames there (a .vtm a time and the .vtu files it names, each one parsing; ``foreign``: a user's
    files), no empty vtu/, a result.npz that loads."""
    import meshio

    from nsfem.export.vtu import series_parts

    names = sorted(p.name for p in out.iterdir() if p.name != "vtu") if out.exists() else []
    if (out / "vtu").is_dir():
        inner = sorted(f"vtu/{p.name}" for p in (out / "vtu").iterdir())
        assert inner, "an empty vtu/ left behind"
        names = sorted(names + inner)
    assert not [n for n in names if n.endswith(".tmp") or ".nsfem-probe" in n], names
    assert LOCK not in names, names  # released and removed
    frames = {n for n in names if n.endswith((".vtu", ".vtm"))} - set(foreign)
    if "nsfem.pvd" in names:
        vtms = re.findall(r'file="([^"]+)"', (out / "nsfem.pvd").read_text())
        parts = [f for v in series_parts(out / "nsfem.pvd").values() for _, f in v]
        indexed = vtms + parts
        assert set(indexed) == frames and len(indexed) == len(frames), (sorted(frames - set(indexed)), indexed)
        for f in parts[-4:]:
            meshio.read(out / f)
    else:
        assert not frames, frames
    if "result.npz" in names:
        with np.load(out / "result.npz") as r:
            meta = json.loads(str(r["meta"]))
            assert r["t"].size == r["q"].shape[1] and r["t"][-1] <= meta["t_end"] + 1e-12
    return names


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def signalled(argv: list[str], out: Path, trigger, sig: int, timeout: float = 120.0):
    """Start ``nsfem argv``, send ``sig`` once ``trigger(process)`` is true (polled); (code, stderr)."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1]), "MPLBACKEND": "Agg"}
    p = subprocess.Popen([sys.executable, "-m", "nsfem", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, env=env)
    t0 = time.monotonic()
    try:
        while p.poll() is None and not trigger(p):
            assert time.monotonic() - t0 < timeout, "trigger never came"
            time.sleep(0.002)
        p.send_signal(sig)
        _, err = p.communicate(timeout=timeout)
    finally:
        if p.poll() is None:
            p.kill()
    return p.returncode, err


def appears(out: Path, pattern: str):
    """A trigger: a file matching ``pattern`` exists in ``out`` (which the command may not have made yet, or
    may remove again while it is empty: scanning it then raises on Python 3.11)."""
    def trigger(p) -> bool:
        try:
            return any(out.glob(pattern))
        except OSError:
            return False
    return trigger


def integrating(out: Path, cpu: float = 0.5):
    """True once the run holds its folder and has computed ``cpu`` more seconds (model build and
    spectrum of the tiny model take 0.1 to 0.3 s: then it integrates)."""
    start = {}

    def ready(p):
        if not (out / LOCK).exists():
            return False
        start.setdefault("cpu", cpu_seconds(p.pid))
        return cpu_seconds(p.pid) - start["cpu"] >= cpu
    return ready


#: the exit of an interrupted command as its parent sees it: 130, the project's Ctrl-C status (SIGTERM too),
#: or death by SIGINT, which a shell shows as the same 130 (CPython ends that way when an interrupt reaches
#: its top level as it shuts down: 1 to 2 in 40 SIGTERMs sent right after the folder is locked, after the
#: command had printed its line and returned 130)
INTERRUPTED = (130, -signal.SIGINT)


def check_interrupted(code: int, err: str, out: Path) -> list[str]:
    """Exit 130 (the project's Ctrl-C status, SIGTERM too) with one line, no traceback; a valid folder.
    (Every trigger comes well before the command's end: a run that ended first fails the test.)"""
    assert code in INTERRUPTED, err
    assert "Traceback" not in err, err
    assert len([line for line in err.splitlines() if line.startswith("nsfem: interrupted")]) == 1, err
    return folder_is_valid(out)


SIGNAL_CASES = [  # (argv after TINY, trigger, signal): writing frames, writing result.npz, integrating
    (["--set", "simulation.t_end=0.2", "--set", "output.vtu_every=1", "--set", "output.plots=[]"],
     "vtu/nsfem_00000.vtu", signal.SIGTERM),
    (["--set", "simulation.t_end=0.05", "--set", "simulation.output_dt=1e-6", "--set", "output.vtu_every=0",
      "--set", "output.plots=[]"], ".result.npz.*.tmp", signal.SIGTERM),
    (["--set", "simulation.t_end=100", "--set", "output.vtu_every=0", "--set", "output.plots=[]"], "integrating",
     signal.SIGINT),
]
SLOW_SIGNAL_CASES = [
    (["--set", "simulation.t_end=0.2", "--set", "output.vtu_every=1", "--set", "output.plots=[]"],
     "vtu/nsfem_00004.vtu", signal.SIGINT),
    (["--set", "simulation.t_end=0.2", "--set", "output.vtu_every=1", "--set", "output.plots=[]"],
     "vtu/nsfem_contacts_00002.vtu", signal.SIGTERM),
    (["--set", "simulation.t_end=0.05", "--set", "simulation.output_dt=1e-6", "--set", "output.vtu_every=0",
      "--set", "output.plots=[]"], ".result.npz.*.tmp", signal.SIGINT),
    (["--set", "simulation.t_end=0.05", "--set", "output.vtu_every=0"], ".phase.png.*.tmp", signal.SIGTERM),
    (["--set", "simulation.t_end=100", "--set", "output.vtu_every=0", "--set", "output.plots=[]"], "integrating",
     signal.SIGTERM),
    (["--set", "simulation.t_end=20", "--set", "output.vtu_every=0", "--set", "output.plots=[]"], LOCK,
     signal.SIGTERM),  # while building the model
]


def _signal_case(extra, trigger, sig, tmp_path):
    out = tmp_path / "out"
    when = integrating(out) if trigger == "integrating" else appears(out, trigger)
    code, err = signalled(["run", *TINY, "--out", str(out), *extra], out, when, sig)
    names = check_interrupted(code, err, out)
    if trigger == "integrating":  # the run up to the interrupt, saved
        assert code in INTERRUPTED and "result.npz" in names
        with np.load(out / "result.npz") as r:
            meta = json.loads(str(r["meta"]))
        assert meta["completed"] is False and 0 < meta["t_end"] < 100   # (100 s: minutes even compiled)
    if trigger.startswith(".result"):  # the file being written is finished: the whole run
        with np.load(out / "result.npz") as r:
            assert r["t"][-1] == pytest.approx(0.05, rel=1e-12) and r["t"].size == 50_001


@pytest.mark.parametrize("extra, trigger, sig", SIGNAL_CASES, ids=["frames-TERM", "result-TERM", "integrate-INT"])
def test_a_signal_leaves_valid_partial_output(extra, trigger, sig, tmp_path):
    _signal_case(extra, trigger, sig, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("extra, trigger, sig", SLOW_SIGNAL_CASES,
                         ids=["frame4-INT", "contacts2-TERM", "result-INT", "plot-TERM", "integrate-TERM", "build-TERM"])
def test_a_signal_leaves_valid_partial_output_anywhere(extra, trigger, sig, tmp_path):
    _signal_case(extra, trigger, sig, tmp_path)


@pytest.mark.slow
def test_a_signal_during_export_leaves_a_pvd_of_the_frames_written(tmp_path):
    saved = tmp_path / "run"   # 201 output times: the export takes seconds, the signal comes at its third frame
    assert cli.main(["run", *TINY, "--set", "simulation.t_end=0.2", "--set", "simulation.output_dt=1e-3", "--set",
                     "output.vtu_every=0", "--set", "output.plots=[]", "--out", str(saved)]) == 0
    out = tmp_path / "vtu"
    code, err = signalled(["export", str(saved / "result.npz"), "--vtu", str(out), "--every", "1"], out,
                          appears(out, "vtu/nsfem_00002.vtu"), signal.SIGTERM)
    names = check_interrupted(code, err, out)
    assert "nsfem.pvd" in names and "result.npz" not in names


def test_a_killed_runs_temporary_files_are_removed_by_the_next_run(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    killed = [".result.npz.k1ll3d_x.tmp", ".nsfem_00007.vtu.abcdefgh.tmp", ".nsfem-probe.12345678"]
    for name in killed:
        (out / name).write_bytes(b"half")
    (out / "notes.tmp").write_text("mine")  # not a name nsfem makes: kept
    assert cli.main(["run", *CHEAP, "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "notes.tmp", "result.npz"]


# a folder holds one run: what the previous run wrote and this one does not is removed, a user's
# own files never; every run leaves exactly its own outputs
RUN_SETTINGS = st.fixed_dictionaries({
    "plots": st.lists(st.sampled_from(["gap", "forces"]), unique=True, max_size=2),
    "vtu_every": st.sampled_from([0, 1, 3]),
    "t_end": st.sampled_from([0.002, 0.004]),
})


def folder_holds_the_last_run_only(runs):
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        out = root / "out"
        out.mkdir()
        (out / "notes.txt").write_text("my notes")
        (out / "nsfem_99999.vtu").write_text("mine too")   # named like a frame, never written by nsfem
        for run in runs:
            argv = ["run", *TINY, "--set", f"simulation.t_end={run['t_end']}", "--set", "simulation.output_dt=1e-3",
                    "--set", f"output.vtu_every={run['vtu_every']}", "--set", f"output.plots={json.dumps(run['plots'])}",
                    "--json", "--out", "out"]
            code, stdout, stderr = check_invocation(argv, root)
            assert code == 0, stderr
            outputs = {Path(o).name for o in json.loads(stdout)["outputs"]}
            names = set(folder_is_valid(out, foreign=["nsfem_99999.vtu"])) - {MANIFEST}
            frames = {n for n in names if n.startswith("vtu/")} if run["vtu_every"] else set()
            assert names == outputs | frames | {"notes.txt", "nsfem_99999.vtu"}, (run, sorted(names))
            n_frames = len(range(0, round(run["t_end"] / 1e-3) + 1, run["vtu_every"])) if run["vtu_every"] else 0
            assert len(frames) == 5 * n_frames  # stack, contacts, disks, cracks and the .vtm naming them
        assert (out / "notes.txt").read_text() == "my notes" and (out / "nsfem_99999.vtu").read_text() == "mine too"


@settings(max_examples=3, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(runs=st.lists(RUN_SETTINGS, min_size=2, max_size=2))
def test_a_folder_holds_the_last_run_only(runs):
    folder_holds_the_last_run_only(runs)


@pytest.mark.slow
@settings(max_examples=30, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(runs=st.lists(RUN_SETTINGS, min_size=2, max_size=4))
def test_a_folder_holds_the_last_run_only_many(runs):
    folder_holds_the_last_run_only(runs)


def test_an_interrupted_fit_leaves_no_plots_of_the_previous_fit(tmp_path):
    # the previous fit: all its files
    with claim(tmp_path, "fit", {"fit": FIT_FILES}):
        for name in sorted(FIT_FILES):
            write_text_atomic(tmp_path / name, "old")
    (tmp_path / "data.csv").write_text("t,s\n0,0\n")  # the user's
    with pytest.raises(KeyboardInterrupt):
        with claim(tmp_path, "fit", {"fit": FIT_FILES}):   # interrupted: evaluations and fit.json only
            write_text_atomic(tmp_path / "evaluations.csv", "new")
            write_text_atomic(tmp_path / "fit.json", "new")
            raise KeyboardInterrupt
    assert sorted(p.name for p in tmp_path.iterdir()) == [MANIFEST, "data.csv", "evaluations.csv", "fit.json"]
    assert (tmp_path / "fit.json").read_text() == "new"


def test_an_export_into_the_runs_folder_replaces_its_series_only(tmp_path):
    out = tmp_path / "out"
    assert cli.main(["run", *TINY, "--set", "simulation.t_end=0.004", "--set", "simulation.output_dt=1e-3",
                     "--set", "output.vtu_every=1",
                     "--set", "output.plots=[\"gap\"]", "--out", str(out)]) == 0
    before = {p.name for p in out.iterdir()}
    assert cli.main(["export", str(out / "result.npz"), "--vtu", str(out), "--every", "2"]) == 0
    after = set(folder_is_valid(out))
    vtus = {n for n in after if n.startswith("vtu/")}
    assert len(vtus) == 5 * 3   # outputs 0, 2, 4: 4 parts and the .vtm each
    assert after - vtus == before - {"vtu"}   # result, plot, sensors, the .pvd (rewritten) kept


COMMANDS_INTO = {  # each command that writes a folder, into "busy" (exit 2 before any computing)
    "run": ["run", *CHEAP, "--out", "busy"],
    "export": ["export", "RESULT", "--vtu", "busy"],
    "sweep": ["sweep", *CHEAP, "--set", "rotation.speed_hz=20:21:2", "--out", "busy"],
}


@settings(max_examples=6, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(command=st.sampled_from(sorted(COMMANDS_INTO)), holder=st.sampled_from(["run", "export", "fit", "sweep"]))
def test_a_second_writer_of_a_folder_is_refused(saved_result, command, holder):
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        busy = root / "busy"
        busy.mkdir()
        (busy / "result.npz").write_bytes(saved_result.read_bytes())
        before = {p.name: p.stat().st_mtime_ns for p in busy.iterdir()}
        argv = [str(saved_result) if a == "RESULT" else a for a in COMMANDS_INTO[command]]
        with claim(busy, holder):   # another process's lock (flock: per open file, so this process too)
            code, _, stderr = check_invocation(argv, root)
            assert code == cli.EXIT_ERROR and "is being written by another nsfem process" in stderr, stderr
            assert "busy is being written" in stderr and f"nsfem {holder} started" in stderr
            assert {p.name: p.stat().st_mtime_ns for p in busy.iterdir() if p.name != LOCK} == before


def test_two_runs_at_once_into_one_folder(tmp_path):
    """The reproduction: of two concurrent runs into one folder the second is refused (in this
    process, while the first integrates in its own); the first, stopped, leaves its folder valid."""
    out = tmp_path / "same"
    long = ["run", *TINY, "--set", "simulation.t_end=20", "--set", "output.vtu_every=0", "--set", "output.plots=[]",
            "--out", str(out)]
    pid = {}

    def second_refused(p):
        if not (out / LOCK).exists():
            return False
        pid["first"] = p.pid
        code, _, stderr = check_invocation(long[:-1] + ["same"], tmp_path)
        assert code == cli.EXIT_ERROR, stderr
        assert f"--out: same is being written by another nsfem process (pid {p.pid}, nsfem run" in stderr
        return True

    code, err = signalled(long, out, second_refused, signal.SIGTERM)
    assert "first" in pid
    check_interrupted(code, err, out)


# ---- files without bound: the output's size is estimated before the run
BOUND_REPRODUCTIONS = [
    (["run", "crack", "--set", "simulation.t_end=1", "--set", "simulation.output_dt=1e-5", "--set",
      "output.vtu_every=1", "--set", "output.plots=[]"],
     "output.vtu_every: this run would write 500008 files"),  # 100001 outputs x (4 parts + vtm) + pvd, result, sensors
    (["run", "crack", "--set", "simulation.t_end=1", "--set", "simulation.output_dt=1e-5", "--set",
      "output.vtu_every=3", "--set", "output.plots=[]"], "more than the limit of 100000 files"),
]


@pytest.mark.parametrize("argv, text", BOUND_REPRODUCTIONS)
def test_too_many_files_are_refused_before_the_run(argv, text, tmp_path):
    code, _, stderr = check_invocation(argv, tmp_path)
    assert code == cli.EXIT_ERROR and text in stderr, stderr
    assert not (tmp_path / "out").exists()   # refused before anything was written


def test_more_bytes_than_the_disk_holds_are_refused(tmp_path, monkeypatch):
    from nsfem import simulate

    monkeypatch.setattr(simulate, "free_bytes", lambda folder: 1e5)   # 100 kB free
    code, _, stderr = check_invocation(["run", *TINY, "--set", "simulation.t_end=0.05", "--set",
                                        "output.vtu_every=1", "--set", "output.plots=[]"], tmp_path)
    assert code == cli.EXIT_ERROR and "output.vtu_every" in stderr and "GB free there" in stderr, stderr
    code, _, stderr = check_invocation(["run", *TINY, "--set", "simulation.t_end=0.05", "--set",
                                        "simulation.output_dt=1e-5", "--set", "output.vtu_every=0",
                                        "--set", "output.plots=[]"], tmp_path)
    assert code == cli.EXIT_ERROR and "simulation.output_dt" in stderr, stderr


@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(files=st.integers(1, 10**6), nbytes=st.floats(0, 1e13), free=st.one_of(st.none(), st.floats(0, 1e13)),
       every=st.integers(0, 50))
def test_output_size_limits(files, nbytes, free, every):
    from nsfem.errors import SceneError
    from nsfem.simulate import BYTES_WARN, FILES_MAX, FILES_WARN, check_output_size

    refused = files > FILES_MAX or (free is not None and nbytes > free)
    try:
        text = check_output_size(files, nbytes, free, every, 10 * files)
    except SceneError as exc:
        assert refused and exc.key == ("output.vtu_every" if every else "simulation.output_dt")
        return
    assert not refused
    assert (text is not None) == (files > FILES_WARN or nbytes > BYTES_WARN)


@pytest.mark.parametrize("scene", ["crack", "rub", "ross_example", "default"])
def test_the_size_estimate_bounds_the_files_written(scene, tmp_path):
    """frame_size counts the files of a frame exactly and bounds their bytes (raw arrays before
    zlib, so above what meshio writes: 3x to 6x measured on these scenes)."""
    from nsfem import build_model, load_scene
    from nsfem.export.vtu import frame_size

    out = tmp_path / "out"
    args = [scene, "--set", "simulation.t_end=0.002", "--set", "simulation.output_dt=1e-3", "--set",
            "output.vtu_every=1", "--set", "output.plots=[]", "--out", str(out)]
    assert cli.main(["run", *args]) == 0
    files, nbytes = frame_size(build_model(load_scene(scene, [])))
    for i in range(3):
        frame = list(out.glob(f"vtu/nsfem*_{i:05d}.vt[um]"))
        assert len(frame) == files
        assert sum(p.stat().st_size for p in frame) <= nbytes


def test_a_sweeps_resume_removes_the_writes_a_kill_cut_short(tmp_path):
    """A worker killed while writing leaves ``.result.npz.XXXXXXXX.tmp`` in its run folder; the next
    sweep into the folder (here a resume with every run done) removes it and keeps the runs."""
    distributed = pytest.importorskip("distributed")
    from nsfem.sweep import run_name, run_sweep

    args = ["mesh.elements=20", "simulation.t_end=0.01", "rotation.speed_hz=20:21:2"]
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        first = run_sweep(None, args, tmp_path, client=c, plot=False)
    runs = [tmp_path / run_name(p) for p in first.points]
    killed = [runs[0] / ".result.npz.k1ll3d00.tmp", runs[1] / ".record.json.abcdefgh.tmp",
              tmp_path / ".sweep.csv.12345678.tmp"]
    for f in killed:
        f.write_bytes(b"half")
    again = run_sweep(None, args, tmp_path, plot=False)   # nothing to run: no cluster is started
    assert again.info["resumed"] == 2 and again.info["executed"] == 0
    assert not any(f.exists() for f in killed)
    assert not leftovers(tmp_path), leftovers(tmp_path)
    assert all((r / "result.npz").is_file() for r in runs)


def test_a_refused_run_leaves_the_previous_run_as_it_was(tmp_path):
    """Refused after taking the folder (its output too large, known once the model is built): the
    previous run's plots and frames stay; a render next to the result is the run's, replaced by the
    next run that writes."""
    out = tmp_path / "out"
    assert cli.main(["run", *TINY, "--set", "simulation.t_end=0.004", "--set", "output.vtu_every=2",
                     "--set", "output.plots=[\"gap\"]", "--out", str(out)]) == 0
    assert cli.main(["render", str(out / "result.npz")]) == 0
    before = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    assert "render.png" in before and "gap.png" in before
    code, _, stderr = check_invocation(["run", *TINY, "--set", "simulation.t_end=1", "--set",
                                        "simulation.output_dt=1e-5", "--set", "output.vtu_every=1",
                                        "--out", "out"], tmp_path)
    assert code == cli.EXIT_ERROR and "output.vtu_every" in stderr
    assert {p.name: p.stat().st_mtime_ns for p in out.iterdir()} == before
    assert cli.main(["run", *TINY, "--set", "simulation.t_end=0.004", "--set", "output.vtu_every=0",
                     "--set", "output.plots=[]", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "result.npz", "sensors.csv"]


def test_a_shorter_run_without_plots_leaves_nothing_of_the_longer_one(tmp_path):
    """The reproduction: a short run without plots into a longer run's folder left its five PNGs
    and its later VTU frames beside the new result."""
    out = tmp_path / "out"
    assert cli.main(["run", *TINY, "--set", "simulation.t_end=0.02", "--set", "output.vtu_every=4",
                     "--out", str(out)]) == 0
    assert len(list(out.glob("*.png"))) == 5 and len(list(out.glob("vtu/*.vt[um]"))) == 5 * 11   # outputs 0..40
    assert cli.main(["run", *TINY, "--set", "simulation.t_end=0.004", "--set", "output.plots=[]",
                     "--set", "output.vtu_every=4", "--out", str(out)]) == 0
    names = folder_is_valid(out)
    assert not [n for n in names if n.endswith(".png")]
    assert len([n for n in names if n.startswith("vtu/")]) == 5 * 3   # outputs 0, 4, 8


@pytest.mark.slow
def test_a_terminated_sweep_leaves_a_resumable_folder(tmp_path):
    """SIGTERM to the sweep (as `timeout` sends it) once a run has finished: exit 130 with one line;
    the folder holds no temporary file and a rerun resumes it to the end. (A kill of the whole
    process group, workers too, hangs about 1 in 6 times under load at exit, in multiprocessing's
    join of a dask nanny that outlived its SIGTERM: the sweep's cluster handling, not its folder.)"""
    out = tmp_path / "sweep"
    argv = ["sweep", "--set", "mesh.elements=20", "--set", "simulation.t_end=0.05", "--set",
            "rotation.speed_hz=15:25:12", "--workers", "2", "--out", str(out)]
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1]), "MPLBACKEND": "Agg"}
    p = subprocess.Popen([sys.executable, "-m", "nsfem", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, env=env, start_new_session=True)
    try:
        t0 = time.monotonic()
        while not any(out.glob("*/record.json")) and p.poll() is None:
            assert time.monotonic() - t0 < 120
            time.sleep(0.002)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
    assert p.returncode == 130 and err.count("\n") == 1 and "run the same command again" in err, err
    assert "Traceback" not in err, err
    assert not leftovers(out) and not list(out.glob("**/.nsfem*")), leftovers(out)
    assert cli.main(argv) == 0
    assert len(list(out.glob("*/result.npz"))) == 12 and not leftovers(out)


@pytest.mark.parametrize("manifest", ['{"files": {"run": ["../victim.txt", "..", "", ".", "/etc/x", 3]}}',
                                      "not json", '{"files": ["result.npz"]}', "[]", '{"files": {"run": "gap.png"}}'])
def test_a_hostile_manifest_or_lock_removes_nothing_outside_the_folder(manifest, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_text("keep")
    (out / MANIFEST).write_text(manifest)
    (out / "gap.png").write_text("a user's")
    (out / LOCK).symlink_to(victim)   # a planted link: never followed, never truncated
    code, _, stderr = check_invocation(["run", *CHEAP, "--out", "out"], tmp_path)
    assert code == cli.EXIT_ERROR and "lock file" in stderr
    (out / LOCK).unlink()
    assert cli.main(["run", *CHEAP, "--out", str(out)]) == 0
    assert victim.read_text() == "keep" and (out / "gap.png").read_text() == "a user's"


def test_an_interrupt_while_writing_the_plots_still_prints_the_json(tmp_path, monkeypatch):
    """Ctrl-C in the middle of the plots (here raised by the second one): exit 130, one line on
    stderr, and the one JSON object on stdout, listing exactly the files written."""
    from nsfem.plot import results

    calls = []
    real = dict(results.PLOT_FUNCTIONS)

    def interrupting(name):
        def plot(*a, **k):
            calls.append(name)
            if len(calls) == 2:
                raise KeyboardInterrupt
            return real[name](*a, **k)
        return plot

    monkeypatch.setattr(results, "PLOT_FUNCTIONS", {n: interrupting(n) for n in real})
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(["run", *TINY, "--set", "simulation.t_end=0.004", "--set", "output.vtu_every=0",
                         "--json", "--out", str(tmp_path / "out")])
    assert code == 130
    assert [line for line in err.getvalue().splitlines() if line.startswith("nsfem:")] == [
        err.getvalue().splitlines()[-1]] and "interrupted while writing the outputs" in err.getvalue()
    payload = json.loads(out.getvalue())
    assert payload["interrupted"] is True
    assert sorted(Path(o).name for o in payload["outputs"]) == ["phase.png", "result.npz"]
    assert sorted(folder_is_valid(tmp_path / "out")) == [MANIFEST, "phase.png", "result.npz"]


@pytest.mark.parametrize("every, limit, free, text", [
    ("1", 10, None, "--every: 34 files (11 of the 11 output times)"),   # 11 frames x 3 files + the pvd
    ("5", 10, None, None),                                              # 3 frames: 10 files
    ("1", None, 1e3, "GB free in"),
    ("0", None, None, "--every must be a positive integer, got 0"),
    ("x", None, None, "--every"),
])
def test_export_size_is_bounded(saved_result, every, limit, free, text, tmp_path, monkeypatch):
    from nsfem import simulate

    if limit is not None:
        monkeypatch.setattr(simulate, "FILES_MAX", limit)
    if free is not None:
        monkeypatch.setattr(simulate, "free_bytes", lambda folder: free)
    code, _, stderr = check_invocation(["export", str(saved_result), "--vtu", "v", "--every", every], tmp_path)
    if text is None:
        assert code == 0 and len(list((tmp_path / "v").glob("vtu/*.vt[um]"))) == 3 * 3
    else:
        assert code == cli.EXIT_ERROR and text in stderr, stderr
        assert not (tmp_path / "v").exists()


@pytest.mark.slow
def test_an_interrupted_fit_into_a_fits_folder_leaves_no_old_plots(tmp_path):
    """The reproduction: an interrupted fit left the previous fit's PNGs beside its fit.json."""
    distributed = pytest.importorskip("distributed")
    from nsfem.fit import FitInterrupted, fit
    from nsfem.simulate import run_scene, sensor_signals
    from nsfem.scene import load_scene

    fixed = ["mesh.elements=20", "reduction.modes=6", 'sensor.0.name="a"', "sensor.0.x=0.05",
             'sensor.0.direction="+z"', "simulation.t_end=0.02"]
    result, system = run_scene(load_scene(None, fixed))
    data = (result.t, {"a": sensor_signals(result, system)[:, 0]})
    vary = {"delamination.0.start": (0.1, 0.4)}

    def stop(line):
        raise KeyboardInterrupt

    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as c:
        fit(None, data, vary, overrides=fixed, client=c, out_dir=tmp_path, n_global=2, max_nfev=2, refine=False)
        assert {"fit.png", "landscape.png"} <= {p.name for p in tmp_path.iterdir()}
        with pytest.raises(FitInterrupted):
            fit(None, data, vary, overrides=fixed, client=c, out_dir=tmp_path, progress=stop)
    assert sorted(p.name for p in tmp_path.iterdir()) == [MANIFEST, "evaluations.csv", "fit.json"]
    assert json.loads((tmp_path / "fit.json").read_text())["interrupted"] is True


def test_a_closed_stderr_costs_the_run_nothing(tmp_path):
    """`nsfem run ... 2>&1 | head -1`: the reader of stderr goes away before the run's warning; the
    warning was a BrokenPipeError that lost the results file, with exit 0. Now the run ends as usual."""
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1]), "MPLBACKEND": "Agg"}
    p = subprocess.Popen([sys.executable, "-m", "nsfem", "run", *CHEAP, "--set", "rotation.gravity=1e6",  # warns
                          "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    p.stderr.close()
    stdout, _ = p.communicate(timeout=120)
    assert p.returncode == 0 and b"wrote" in stdout
    with np.load(out / "result.npz") as r:
        assert json.loads(str(r["meta"]))["completed"] is True


def test_a_file_system_without_locks_writes_the_folder_unlocked(tmp_path, monkeypatch):
    """flock answering ENOLCK (a network file system without locks): the command writes its folder
    unlocked rather than refusing every run there; any other lock error is one line naming the file."""
    import errno as _errno

    import nsfem.outdir as outdir

    def no_locks(fd, op):
        raise OSError(_errno.ENOLCK, "No locks available")

    monkeypatch.setattr(outdir.fcntl, "flock", no_locks)
    with outdir.claim(tmp_path / "a", "run", {}, "--out") as written:
        assert written is not None   # (the lock file, unlocked, logs the files written: see the review's block)
    assert not (tmp_path / "a").exists()   # nothing left

    def denied(fd, op):
        raise OSError(_errno.EACCES, "Permission denied")

    monkeypatch.setattr(outdir.fcntl, "flock", denied)
    with pytest.raises(NsfemError, match=r"--out: cannot lock .*\.nsfem\.lock"):
        with outdir.claim(tmp_path / "b", "run", {}, "--out"):
            pass


# --- issue 32: review of the physics change (penetration per stop, ...) ---

def test_penetration_is_judged_against_each_stops_own_clearance():
    """A retainer 10 mm away penetrated 20 um (0.2 % of its clearance: a stop that holds) beside a 0.1 mm
    stator that is not touched: no warning (the check once measured every stop against the smallest
    clearance, 20 um > 0.1 x 0.1 mm, and warned). The same 20 um into the 0.1 mm stator (20 %) warns and names
    it. The margins are factors of 50 and 2 from the 10 % threshold, far beyond the gaps' round-off."""
    from types import SimpleNamespace

    import numpy as np

    from nsfem.analysis.deflection import penetration_warning
    from nsfem.stack import Contact

    stops = SimpleNamespace(contacts=(Contact("obstacle", 0.4, ("s",), clearance=1e-4, label="stator.0.0"),
                                      Contact("obstacle", 0.1, ("s",), clearance=1e-2, label="obstacle.0")))
    labels = ["stator.0.0", "obstacle.0"]
    far = SimpleNamespace(gap=np.array([[1e-4, 5e-5], [1e-2, -2e-5]]), info={"contacts": labels}, method="penalty")
    assert penetration_warning(far, stops) is None
    near = SimpleNamespace(gap=np.array([[1e-4, -2e-5], [1e-2, 5e-3]]), info={"contacts": labels}, method="penalty")
    text = penetration_warning(near, stops)
    assert text is not None and "2e-05 m deep at stator.0.0" in text and "clearance 0.0001 m" in text


# --- issue 32: review of the outputs change (files of a killed command, ...) ---
#: names a run may write (kind run), in the order it writes them
RUN_NAMES = ["result.npz", "gap.png", "sensors.csv", "sensors.png", "render.png"]


def killed_claim(out: Path, planned: list[str], written: list[str]) -> None:
    """A command that plans ``planned`` in ``out``, writes ``written`` and is killed outright
    (SIGKILL, power loss: no finally runs), in a forked child."""
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        try:
            with claim(out, "run", {"run": planned}):
                for name in written:
                    write_text_atomic(out / name, f"killed run's {name}")
                os._exit(9)
        finally:
            os._exit(1)
    t0 = time.monotonic()   # a guard only (a fork of a threaded process could hang): not a timing assertion
    while (done := os.waitpid(pid, os.WNOHANG))[0] == 0:
        if time.monotonic() - t0 > 120:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            pytest.fail("the forked command hung")
        time.sleep(0.005)
    assert os.WIFEXITED(done[1]) and os.WEXITSTATUS(done[1]) == 9


def a_killed_commands_planned_names_spare_the_users_files(planned, n_written, users, rewrite):
    written = planned[:n_written]
    users = [n for n in users if n not in written]
    with tempfile.TemporaryDirectory() as d:
        out = Path(d)
        killed_claim(out, planned, written)
        for name in users:  # the user's own files, made after the kill, under names the killed run planned
            (out / name).write_text(f"user's {name}")
        if written and set(users) & set(rewrite):  # a file nsfem did not write, to be overwritten, in a
            # folder it keeps (its first write made the manifest): refused, no file touched
            def files():
                return {p.name: p.read_bytes() for p in out.iterdir() if p.name not in (MANIFEST, LOCK)}

            before = files()
            with pytest.raises(NsfemError, match="which nsfem did not write"):
                with claim(out, "run", {"run": rewrite}):
                    pass
            assert files() == before
            return
        with claim(out, "run", {"run": rewrite}):
            for name in rewrite:
                write_text_atomic(out / name, f"new {name}")
        names = {p.name for p in out.iterdir()} - {MANIFEST}
        # exactly: the new run's files, the user's files it did not overwrite; none of the killed run's
        assert names == set(rewrite) | set(users), (planned, written, users, rewrite, sorted(names))
        for name in set(users) - set(rewrite):
            assert (out / name).read_text() == f"user's {name}"
        assert json.loads((out / MANIFEST).read_text()) == {"files": {"run": sorted(rewrite)}}


@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(planned=st.permutations(RUN_NAMES), n_written=st.integers(0, 5),
       users=st.lists(st.sampled_from(RUN_NAMES), unique=True),
       rewrite=st.lists(st.sampled_from(RUN_NAMES), unique=True, min_size=1))
def test_a_killed_commands_planned_names_spare_the_users_files(planned, n_written, users, rewrite):
    """The class: a command killed outright left its manifest planning names it never wrote; the next
    command removed any file of such a name, also one the user made since. Now only the files the
    killed command's log confirms are nsfem's."""
    a_killed_commands_planned_names_spare_the_users_files(planned, n_written, users, rewrite)


def test_a_killed_run_does_not_cost_the_user_a_file_named_like_its_outputs(tmp_path):
    """The reproduction: a run with sensors killed (SIGKILL) after result.npz; the user then copies
    measured data in as sensors.csv; the next run, without sensors, removed it."""
    killed_claim(tmp_path, ["result.npz", "sensors.csv"], ["result.npz"])
    (tmp_path / "sensors.csv").write_text("t,probe\n0,1\n")
    with claim(tmp_path, "run", {"run": ["result.npz"]}):
        write_text_atomic(tmp_path / "result.npz", "new")
    assert (tmp_path / "sensors.csv").read_text() == "t,probe\n0,1\n"


def test_a_fits_data_in_the_folder_is_kept_by_the_next_run(tmp_path, monkeypatch):
    """The reproduction: `nsfem run` with sensors into a folder, `nsfem fit --data <folder>/sensors.csv
    --out <folder>` (the run's signals as the data), then a run without sensors there: the run's
    sensors.csv, now the fit's data, was removed as the earlier run's file. Read by the fit, it is the
    user's from then on (the fit's search itself is left out: the folder's bookkeeping is what is tested)."""
    import nsfem.fit as fitting

    fixed = ["mesh.elements=20", "reduction.modes=6", 'sensor.0.name="a"', "sensor.0.x=0.05",
             'sensor.0.direction="+z"', "simulation.t_end=0.01", "output.vtu_every=0", "output.plots=[]"]
    out = tmp_path / "study"
    assert cli.main(["run", *[a for f in fixed for a in ("--set", f)], "--out", str(out)]) == 0
    data = out / "sensors.csv"
    measured = data.read_text()

    def estimate(problem, folder, *args):
        write_text_atomic(folder / "fit.json", "{}")

    monkeypatch.setattr(fitting, "_estimate", estimate)
    fitting.fit(None, data, {"delamination.0.start": (0.1, 0.4)}, overrides=fixed, out_dir=out)
    assert cli.main(["run", *CHEAP, "--out", str(out)]) == 0  # no sensors
    assert data.read_text() == measured
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "fit.json", "result.npz", "sensors.csv"]


@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(earlier=st.lists(st.sampled_from(RUN_NAMES), unique=True, min_size=1), read=st.data(),
       rewrite=st.lists(st.sampled_from(RUN_NAMES), unique=True, min_size=1))
def test_property_a_commands_inputs_in_its_folder_are_never_removed(earlier, read, rewrite):
    """The class: a file of an earlier run that a command in the folder reads (its input) is the
    user's from then on: a later run that does not write that name leaves it as it is."""
    inputs = read.draw(st.lists(st.sampled_from(earlier), unique=True))
    with tempfile.TemporaryDirectory() as d:
        out = Path(d)
        with claim(out, "run", {"run": earlier}):
            for name in earlier:
                write_text_atomic(out / name, f"earlier {name}")
        with claim(out, "fit", {"fit": FIT_FILES}, inputs=[out / n for n in inputs]):
            write_text_atomic(out / "fit.json", "{}")
        if set(inputs) & set(rewrite):  # the data would be overwritten: refused
            with pytest.raises(NsfemError, match="which nsfem did not write"):
                with claim(out, "run", {"run": rewrite}):
                    pass
            return
        with claim(out, "run", {"run": rewrite}):
            for name in rewrite:
                write_text_atomic(out / name, f"new {name}")
        names = {p.name for p in out.iterdir()} - {MANIFEST}
        assert names == set(rewrite) | set(inputs) | {"fit.json"}, (earlier, inputs, rewrite, sorted(names))
        for name in set(inputs) - set(rewrite):
            assert (out / name).read_text() == f"earlier {name}"


def disk_full(tmp):
    import errno as _errno

    raise OSError(_errno.ENOSPC, "No space left on device", tmp)


def test_a_run_that_cannot_write_its_results_leaves_the_previous_run(tmp_path, monkeypatch):
    """The reproduction: a run whose result.npz could not be written (disk full) removed, before that
    first write, the previous run's plots and old .pvd, and at its end all the previous run's files,
    its result.npz too. Now nothing is removed before the command's first file is in place."""
    import nsfem.result as result_module

    out = tmp_path / "out"
    assert cli.main(["run", *CHEAP[:-2], "--set", "output.plots=[\"gap\"]", "--set", "output.vtu_every=5",
                     "--out", str(out)]) == 0
    before = {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*") if p.is_file()}  # frames in vtu/
    assert {"result.npz", "gap.png", "nsfem.pvd", MANIFEST} <= set(before)
    monkeypatch.setattr(result_module, "np", type("np", (), {**vars(np), "savez_compressed": staticmethod(
        lambda fh, **arrays: disk_full(fh))}))
    code, _, stderr = check_invocation(["run", *CHEAP, "--out", "out"], tmp_path)  # no plots, no series
    assert code == cli.EXIT_ERROR and "No space left on device" in stderr, stderr
    assert {str(p.relative_to(out)): p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(earlier=st.lists(st.sampled_from(RUN_NAMES + ["nsfem.pvd", "nsfem_00000.vtu"]), unique=True, min_size=1),
       rewrite=st.lists(st.sampled_from(RUN_NAMES + ["nsfem.pvd"]), unique=True, min_size=1),
       command=st.sampled_from(["run", "export"]))
def test_property_a_command_whose_writes_fail_leaves_the_folder_as_it_was(earlier, rewrite, command):
    """The class: a command that fails (or stops) before any of its files is in place removes nothing."""
    kind = {n: "series" if n.endswith((".pvd", ".vtu")) else "run" for n in RUN_NAMES + ["nsfem.pvd", "nsfem_00000.vtu"]}
    with tempfile.TemporaryDirectory() as d:
        out = Path(d)
        plan = {}
        for n in earlier:
            plan.setdefault(kind[n], []).append(n)
        with claim(out, "run", plan):
            for name in earlier:
                write_text_atomic(out / name, f"earlier {name}")
        before = {p.name: p.read_bytes() for p in out.iterdir()}
        with pytest.raises(OSError):
            with claim(out, command, {kind[rewrite[0]]: rewrite}):
                for name in rewrite:
                    from nsfem.atomic import write_atomic

                    write_atomic(out / name, disk_full)
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_an_interrupt_while_the_folder_is_locked_leaves_no_lock_file(tmp_path, monkeypatch):
    """A Ctrl-C between the lock file's creation and its flock left `.nsfem.lock` in a folder the
    command had created (so the folder too): the lock is taken with signals deferred."""
    import nsfem.outdir as outdir

    flock = outdir.fcntl.flock

    def interrupted(fd, op):
        signal.raise_signal(signal.SIGINT)
        return flock(fd, op)

    monkeypatch.setattr(outdir.fcntl, "flock", interrupted)
    with pytest.raises(KeyboardInterrupt):
        with claim(tmp_path / "new", "run", {"run": ["result.npz"]}):
            pass
    assert not (tmp_path / "new").exists()


@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(stem=st.text(st.characters(blacklist_categories=("Cs", "Cc"), blacklist_characters="/\\"), min_size=1,
                    max_size=12),
       suffix=st.sampled_from([".toml", ".msh", ".md", ".py", "", ".csv", ".png", ".npz"]))
def test_property_a_manifest_names_only_outputs_to_remove(stem, suffix):
    """A manifest edited by hand (or copied with a folder) that names a user's scene, mesh or notes
    (unicode and spaces too) removes none of them: only files of the kinds nsfem writes are ever removed."""
    from hypothesis import assume

    name = stem + suffix
    assume(name not in (".", "..", LOCK, MANIFEST, "result.npz") and not name.startswith("."))
    with tempfile.TemporaryDirectory() as d:
        out = Path(d)
        (out / name).write_text("the user's")
        (out / MANIFEST).write_text(json.dumps({"files": {"run": [name, "result.npz"]}}))
        with claim(out, "run", {"run": ["result.npz"]}):
            write_text_atomic(out / "result.npz", "new")
        kept = (out / name).exists()
        assert kept == (not name.endswith((".csv", ".png", ".npz"))), (name, kept)


def test_a_run_re_run_into_its_own_folder_counts_the_room_of_the_files_it_replaces(tmp_path, monkeypatch):
    """The reproduction: a run re-run into its folder on a nearly full disk was refused for more bytes
    than the free space, although the earlier run's files it replaces (here a 1 GB result.npz, sparse)
    give their room back. A user's file of that size gives none."""
    from nsfem import simulate

    out = tmp_path / "out"
    out.mkdir()
    argv = ["run", *TINY, "--set", "simulation.t_end=0.01", "--set", "output.vtu_every=1", "--set",
            "output.plots=[]", "--out", "out"]
    monkeypatch.setattr(simulate, "free_bytes", lambda folder: 1e5)   # 100 kB free: less than the run's ~1 MB
    with open(out / "result.npz", "wb") as fh:   # the user's: no room of the run's
        fh.truncate(10**9)
    code, _, stderr = check_invocation(argv, tmp_path)
    assert code == cli.EXIT_ERROR and "GB free there" in stderr, stderr
    (out / "result.npz").unlink()
    with claim(out, "run", {"run": ["result.npz"]}):   # the earlier run's: its room comes back
        write_text_atomic(out / "result.npz", "")
        os.truncate(out / "result.npz", 10**9)
    code, _, stderr = check_invocation(argv, tmp_path)
    assert code == 0, stderr


@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(files=st.lists(st.tuples(st.sampled_from(["run", "series", "fit"]), st.integers(0, 10**6)), max_size=5),
       user=st.integers(0, 10**6), command=st.sampled_from(["run", "export", "fit", "render", "sweep"]))
def test_property_the_room_a_command_gets_back_is_its_kinds_files_only(files, user, command):
    from nsfem.outdir import REPLACES, replaced_bytes

    with tempfile.TemporaryDirectory() as d:
        out = Path(d)
        listed = {}
        for i, (kind, size) in enumerate(files):
            name = f"f{i}.npz"
            with open(out / name, "wb") as fh:
                fh.truncate(size)
            listed.setdefault(kind, []).append(name)
        with open(out / "mine.npz", "wb") as fh:   # the user's: never counted
            fh.truncate(user)
        (out / "link.npz").symlink_to(out / "mine.npz")   # a link: no room of its own
        listed.setdefault("run", []).append("link.npz")
        (out / MANIFEST).write_text(json.dumps({"files": listed}))
        assert replaced_bytes(out, command) == sum(s for k, s in files if k in REPLACES[command])


def test_render_onto_its_own_results_file_is_refused(saved_result, tmp_path):
    """The reproduction: `nsfem render out/result.npz --png out/result.npz` (a slip) replaced the
    results file with a picture, exit 0; a scene or the data named as --png likewise."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "result.npz").write_bytes(saved_result.read_bytes())
    (out / "scene.toml").write_text('title = "mine"\n')
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    for png in ["out/result.npz", "out/scene.toml", "out/picture"]:
        code, _, stderr = check_invocation(["render", "out/result.npz", "--png", png], tmp_path)
        assert code == cli.EXIT_ERROR and f"--png: {png} does not end in .png" in stderr, stderr
    code, _, stderr = check_invocation(["campbell", "--png", "out/scene.toml"], tmp_path)
    assert code == cli.EXIT_ERROR and "does not end in .png" in stderr, stderr
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(stem=st.text(st.characters(blacklist_categories=("Cs", "Cc"), blacklist_characters="/\\\0"), min_size=1,
                    max_size=12),
       suffix=st.sampled_from([".png", ".PNG", ".npz", ".toml", ".csv", "", ".png.bak", ".pngx"]))
def test_property_png_targets_end_in_png(stem, suffix, tmp_path_factory):
    """Any --png name not ending in .png is refused in one line naming it, before the result is read
    (here missing: a name ending in .png gets that error instead)."""
    root = tmp_path_factory.mktemp("png")
    png = stem + suffix
    code, _, stderr = check_invocation(["render", "missing.npz", f"--png={png}"], root)
    assert code == cli.EXIT_ERROR
    refused = "does not end in .png" in stderr
    assert refused == (Path(png).suffix.lower() != ".png" and not (root / png).is_dir()), (png, stderr)


def test_a_run_refuses_to_overwrite_the_users_data_named_like_its_output(tmp_path):
    """The reproduction: the user's measured sensors.csv in the run's folder (`--out .` beside the
    scene and the data) was replaced by the run's sensors.csv. In a folder nsfem keeps, such a file is
    refused in one line, before the run; the fit's data (read by a fit there) likewise."""
    sensors = ["--set", 'sensor.0.name="a"', "--set", "sensor.0.x=0.05", "--set", 'sensor.0.direction="+z"']
    argv = ["run", *CHEAP, *sensors, "--out", "out"]
    assert check_invocation(["run", *CHEAP, "--out", "out"], tmp_path)[0] == 0   # a folder nsfem keeps
    out = tmp_path / "out"
    (out / "sensors.csv").write_text("t,a\n0,1\n")   # the user's measurement, put there since
    code, _, stderr = check_invocation(argv, tmp_path)
    assert code == cli.EXIT_ERROR and "holds sensors.csv, which nsfem did not write" in stderr, stderr
    assert (out / "sensors.csv").read_text() == "t,a\n0,1\n"
    assert check_invocation(["run", *CHEAP, "--out", "out"], tmp_path)[0] == 0   # a run that writes no sensors.csv
    assert (out / "sensors.csv").read_text() == "t,a\n0,1\n"


@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(earlier=st.lists(st.sampled_from(RUN_NAMES), unique=True, min_size=1),
       users=st.lists(st.sampled_from(RUN_NAMES + ["notes.txt"]), unique=True),
       rewrite=st.lists(st.sampled_from(RUN_NAMES), unique=True, min_size=1))
def test_property_a_file_nsfem_did_not_write_is_never_overwritten(earlier, users, rewrite):
    """The class: in a folder nsfem keeps, a command that would overwrite a file it did not write there
    is refused (one line naming the file) and leaves the folder as it was; otherwise it runs."""
    with tempfile.TemporaryDirectory() as d:
        out = Path(d)
        with claim(out, "run", {"run": earlier}):
            for name in earlier:
                write_text_atomic(out / name, f"earlier {name}")
        users = [n for n in users if n not in earlier]   # (a file nsfem wrote, replaced by the user, is not told apart)
        for name in users:
            (out / name).write_text(f"user's {name}")
        before = {p.name: p.read_bytes() for p in out.iterdir()}
        clash = sorted(set(users) & set(rewrite))
        try:
            with claim(out, "run", {"run": rewrite}):
                for name in rewrite:
                    write_text_atomic(out / name, f"new {name}")
        except NsfemError as exc:
            assert clash and f"holds {clash[0]}" in str(exc) and "\n" not in str(exc)
            assert {p.name: p.read_bytes() for p in out.iterdir()} == before
        else:
            assert not clash
        for name in set(users) - set(rewrite):
            assert (out / name).read_text() == f"user's {name}"


def test_on_a_file_system_without_locks_a_killed_commands_files_are_still_known(tmp_path, monkeypatch):
    """Without flock (ENOLCK: a network or parallel file system; a batch job SIGKILLed at its time
    limit), the files a killed run wrote were unknown to the next one, which then refused them as
    files nsfem did not write. The lock file, unlocked there, still logs them."""
    import errno as _errno

    import nsfem.outdir as outdir

    def no_locks(fd, op):
        raise OSError(_errno.ENOLCK, "No locks available")

    monkeypatch.setattr(outdir.fcntl, "flock", no_locks)
    killed_claim(tmp_path, ["result.npz", "gap.png"], ["result.npz", "gap.png"])
    with claim(tmp_path, "run", {"run": ["result.npz"]}):
        write_text_atomic(tmp_path / "result.npz", "new")
    assert sorted(p.name for p in tmp_path.iterdir()) == [MANIFEST, "result.npz"]


# --- issue 33: compiled Lemke (event core part "lcp") ---

_HOSTILE = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                     st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 5e-324, 1e300, -1e300, 1.0, -1.0]))


@st.composite
def _hostile_lcp(draw):
    """LCP data a caller might pass: any floats (nan, inf, subnormal, huge), shapes that do not match, a
    covering vector of any sign, row labels of any kind."""
    import numpy as np

    n = draw(st.integers(0, 4))
    m = n if draw(st.integers(0, 5)) else draw(st.integers(0, 4))
    A = np.array(draw(st.lists(_HOSTILE, min_size=n * m, max_size=n * m)), dtype=float).reshape(n, m)
    b = np.array(draw(st.lists(_HOSTILE, min_size=n, max_size=n)), dtype=float)
    kw = {}
    if draw(st.booleans()):
        kw["d"] = draw(st.lists(_HOSTILE, min_size=n, max_size=n + draw(st.integers(0, 1))))
    if draw(st.booleans()):
        kw["groups"] = draw(st.lists(st.sampled_from([0, 1, "gap", "limit"]), min_size=n, max_size=n))
    kw["scale"] = draw(st.booleans())
    return A, b, kw


def _outcome(A, b, kw):
    """('error', message) or ('result', LCPResult) of lemke."""
    import warnings

    from nsfem.errors import NsfemError
    from nsfem.lcp import lemke

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # overflowing products of 1e300 entries
        try:
            return "result", lemke(A, b, **kw)
        except NsfemError as exc:
            return "error", str(exc)


@settings(max_examples=150, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(_hostile_lcp())
def test_compiled_lemke_rejects_and_certifies_as_the_reference(problem):
    """Property: on any input the compiled Lemke raises the reference's one-line error (same message), or
    returns, as the reference does, a result that claims success only with a finite, certified x."""
    from nsfem.integrate import core
    from nsfem.lcp.pivoting import ACCEPT

    if core.compiled("lcp") is None:
        pytest.skip("the compiled event core's part 'lcp' is not built or is switched off")
    A, b, kw = problem
    fast = _outcome(A, b, kw)
    with core.reference():
        ref = _outcome(A, b, kw)
    assert fast[0] == ref[0], (fast, ref)
    if fast[0] == "error":
        assert fast[1] == ref[1] and "\n" not in fast[1]
        return
    for res in (fast[1], ref[1]):
        if res.success:
            import math
            assert res.residual <= ACCEPT and all(map(math.isfinite, res.x.tolist()))


@pytest.mark.parametrize("A, b, status", [
    ([[1e-300]], [-1e300], "overflow"),                             # x = 1e600: beyond the floating-point range
    ([[1e-300, 0.0], [0.0, 1.0]], [-1e300, -1.0], "overflow"),
    ([[5e-324, 0.0], [0.0, 1.0]], [-1.0, -1.0], None),              # a subnormal pivot
    ([[1e300, 1e300], [1e300, 1e300]], [-1e300, -1e300], None),     # products overflow in the certificate
    ([[0.0, 0.0], [0.0, 0.0]], [-1.0, 0.0], "ray"),                 # A = 0, b < 0: infeasible
])
def test_compiled_lemke_extreme_scales_as_the_reference(A, b, status):
    from nsfem.integrate import core

    if core.compiled("lcp") is None:
        pytest.skip("the compiled event core's part 'lcp' is not built or is switched off")
    fast = _outcome(A, b, {})
    with core.reference():
        ref = _outcome(A, b, {})
    assert fast[0] == ref[0] == "result"
    assert (fast[1].status, fast[1].pivots) == (ref[1].status, ref[1].pivots)
    assert status is None or fast[1].status == status


@pytest.mark.parametrize("A, b, kw, expect", [
    # found by the property above: R d underflowed to 0 (d_0 = 1e-300 against a row scaled by 2.5e-24), and
    # the lexicographic rule's 0/0 and -inf + inf left no candidate (ValueError from numpy's min)
    ([[0.0, 0.0, 1.63866689e47], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]], [0.0, 0.0, -1.0], {"d": [1e-300, 1.0, 1.0]},
     "covering vector d leaves the floating-point range"),
    # ratios b / d overflow to -inf on every row (d finite and positive): they tie, the next column decides;
    # z0 = 1e310 then overflows the pivoting (-inf + inf: nan ratios, no tie at all: the first row is taken);
    # the reference's BLAS products of inf and 0 end in nan (overflow), the kernels' polish may still find
    # and certify x = (5e299, 0) on the second
    ([[1.0, 0.0], [0.0, 1.0]], [-1e300, -1e300], {"d": [1e-10, 1e-10], "scale": False}, "overflow"),
    ([[2.0, 1.0], [1.0, 2.0]], [-1e300, -1.0], {"d": [1e-10, 1.0], "scale": False}, "overflow"),
    # one unknown, R d = 0.5 * 5e-324 rounds to 0 (the reference divided by it: ZeroDivisionError)
    ([[4.0]], [-1.0], {"d": [5e-324]}, "covering vector d leaves the floating-point range"),
    # x = (1.2e244, 2e231) is finite but A x is not (1.8e308 - 1.8e308): no certificate (nan), was 'solved'
    ([[1.45687514e64, -9.20312771e76], [1e-13, 0.0]], [0.0, -1.23393769e231], {"scale": False}, "overflow"),
])
def test_lemke_overflowed_covering_ratios(A, b, kw, expect):
    """On whichever path runs (compiled, or the reference under NSFEM_PURE_PYTHON=1): a covering vector that
    the scaling takes out of range is a one-line error; ratios that overflow end the pivoting with a status
    (not numpy's ValueError from an empty tie set), never 'solved' without a certified x."""
    kind, out = _outcome(A, b, kw)
    if kind == "error":
        assert expect in out and "\n" not in out
    else:
        assert out.status in (expect, "solved", "ray", "inaccurate"), out.message
        assert not out.success or (out.residual <= 1e-8 and np.isfinite(out.x).all())


# --- issue 33: round stator rings ---
@settings(max_examples=12, deadline=None, derandomize=True, database=None)
@given(st.text(min_size=0, max_size=12))
def test_a_stator_shape_other_than_polygon_or_round_is_refused_naming_it(tmp_path_factory, shape):
    """Any text for ``[[stator]] shape`` but polygon or round: exit 2, one line naming the key and the values
    allowed, before anything is computed."""
    if shape in ("polygon", "round"):
        return
    root = tmp_path_factory.mktemp("shape")
    code, _, err = check_invocation(["stationary", "rub", "--set", f"stator.0.shape={json.dumps(shape)}"], root)
    assert code == cli.EXIT_ERROR and "stator.0.shape" in err and "polygon | round" in err


def test_the_stator_shape_reproductions(tmp_path):
    for value in ("oval", "ROUND", "1"):
        code, _, err = check_invocation(["stationary", "rub", "--set", f"stator.0.shape={value}"], tmp_path)
        assert code == cli.EXIT_ERROR and "stator.0.shape" in err
    code, out, err = check_invocation(["stationary", "rub", "--set", "stator.0.shape=round", "--json"], tmp_path)
    assert code == 0, err   # stationary's LCP holds the polygon: the key only changes the exact method's run


# --- issue 33: review 2 (compiled Lemke, compiled phase, round rings) ---
@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(n=st.integers(1, 6), which=st.integers(0, 1), at=st.integers(0, 5),
       bad=st.sampled_from([0.0, -0.0, -1.0, -1e-300, math.nan, math.inf, -math.inf]))
def test_lemke_refuses_scales_that_are_not_positive_and_finite(n, which, at, bad):
    """lemke's ``scales`` (row and column scalings, as equilibrate returns them) with an entry that is 0,
    negative or not finite: a one-line NsfemError naming them on both paths. (A zero row scaling made the
    compiled path's certificate divide by 0 and accept a point with w < 0 as 'solved'; the reference raised
    ZeroDivisionError; a nan made the two paths end differently.)"""
    from nsfem.integrate import core
    from nsfem.lcp import lemke

    rng = np.random.default_rng(n)
    G = rng.standard_normal((n, n))
    A, b = G @ G.T + np.eye(n), -np.abs(rng.standard_normal(n)) - 0.1
    scales = [np.ones(n), np.ones(n)]
    scales[which][at % n] = bad
    for reference in (False, True):
        with core.reference() if reference else contextlib.nullcontext(), pytest.raises(NsfemError) as err:
            lemke(A, b, scales=tuple(scales))
        assert "scales" in str(err.value) and "\n" not in str(err.value)


def test_lemke_zero_row_scaling_reproduction():
    # the case found: w = A x + b = (-2, 0) was returned as 'solved' by the compiled path
    from nsfem.lcp import lemke

    with pytest.raises(NsfemError, match="scales"):
        lemke(np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0]), scales=(np.array([0.0, 1.0]), np.ones(2)))


# --- issue 33: compiled search set-up (csetup) ---

#: the compiled Search's arguments, by name (events._compiled_search)
_SEARCH_ARGS = ("nu", "gnodes", "gm", "U", "H", "Hd", "A", "t0", "w", "images", "order", "steady", "weights", "gb",
                "node_rate", "fastest", "t_start", "t_stop", "tol", "band")


def _captured_search_args():
    """The arguments of the first compiled search of a short stop-scene run (images as (HV, c, g)), or None
    where the compiled search is not built."""
    from nsfem import load_scene
    from nsfem.integrate import core
    from nsfem.simulate import run_scene

    search = core.compiled("search")
    if search is None:
        return None
    cached = _captured_search_args.__dict__.get("args")
    if cached is None:
        captured = []

        class Spy:
            @staticmethod
            def Search(*args):
                captured.append(args)
                return search.Search(*args)

        scene = load_scene("default", ['obstacle=[{x=0.5, normal="-z", clearance=2e-4, restitution=0.5}]',
                                       "simulation.t_end=0.003"])
        core._active["search"] = Spy
        try:
            run_scene(scene, "exact")
        finally:
            core._active["search"] = search
        cached = _captured_search_args.args = dict(zip(_SEARCH_ARGS, captured[0]))
    return cached


def _spoil(value, how: str):
    """An array one row (entry) short, one column short, or empty."""
    import numpy as np

    a = np.asarray(value)
    if how == "empty":
        return np.ascontiguousarray(a[:0])
    if how == "row" or a.ndim == 1:
        return np.ascontiguousarray(a[:-1]) if a.shape[0] else np.ascontiguousarray(np.append(a, a.dtype.type(0)))
    return np.ascontiguousarray(a[:, :-1]) if a.shape[1] else np.ascontiguousarray(np.zeros((a.shape[0], 1), a.dtype))


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(which=st.sampled_from(["U", "H", "Hd", "A", "order", "weights", "gb", "tol", "band", "HV", "c", "g", "HU"]),
       how=st.sampled_from(["row", "column", "empty"]))
def test_compiled_search_refuses_any_array_of_the_wrong_shape(which, how):
    """Property: the compiled search reads its arrays without bounds checks; a call with any one of them one
    row or column short, or empty (the rows' images given either as H U or as (H V, c, g)), is a ValueError
    naming the shapes, never a read past an array (a crash) nor a search on garbage."""
    from nsfem.integrate import core

    args = _captured_search_args()
    if args is None:
        pytest.skip("the compiled event core's part 'search' is not built or is switched off")
    search = core.compiled("search")
    args = dict(args)
    HV, c, g = args["images"]
    if which in ("HV", "c", "g"):
        parts = {"HV": HV, "c": c, "g": g}
        parts[which] = _spoil(parts[which], how)
        args["images"] = (parts["HV"], parts["c"], parts["g"])
    elif which == "HU":
        args["images"] = _spoil(np.ascontiguousarray(np.hstack([HV * c, HV @ g.T])), how)
    else:
        args[which] = _spoil(args[which], how)
    with pytest.raises(ValueError):
        search.Search(*(args[name] for name in _SEARCH_ARGS))


def test_compiled_search_images_of_the_wrong_forcing_count_reproduction():
    # (H V, c, g) with g's rows not the phase's forcing terms (pe - modes): refused before any image is formed
    from nsfem.integrate import core

    args = _captured_search_args()
    if args is None:
        pytest.skip("the compiled event core's part 'search' is not built or is switched off")
    HV, c, g = args["images"]
    bad = dict(args, images=(HV, c, np.ascontiguousarray(g[:1])))
    with pytest.raises(ValueError, match="images"):
        core.compiled("search").Search(*(bad[name] for name in _SEARCH_ARGS))


# --- issue 33: review-b (compiled resolve bands, elastic rings' shared configurations, group integrals) ---

def _bands_outcome(call):
    """(values as float arrays, or the exception's type): what a band function gave."""
    import numpy as np

    try:
        return tuple(np.asarray(x, dtype=float) for x in call())
    except (ValueError, IndexError) as exc:
        return type(exc)


@settings(max_examples=40, deadline=None)
@given(m=st.integers(1, 6), n=st.integers(1, 5), tol_len=st.sampled_from([None, 0, 1, 2, 5, 7, "scalar"]),
       q_len=st.integers(0, 6), seed=st.integers(0, 2 ** 16))
def test_compiled_bands_of_any_shapes_are_the_references(m, n, tol_len, q_len, seed):
    """The compiled band kernels (core part "resolve") read their arrays without bounds checks: arguments of
    other shapes than they expect (a gap tolerance given as one number or of another length, a state of
    another length, a band of another length) must give what the reference gives (numpy's broadcast of a
    number, its ValueError otherwise), never numbers read beyond an array."""
    import copy

    import numpy as np

    from nsfem.contact.set import ContactSet
    from nsfem.integrate import core
    from nsfem.integrate.transitions import Memory, _bands, _rate_bands

    kernel = core.compiled("resolve")
    if kernel is None:
        pytest.skip("the compiled core part 'resolve' is not active")
    rng = np.random.default_rng(seed)
    cs = ContactSet.from_arrays(rng.standard_normal((n, m)), 1e-3 * rng.standard_normal(m))
    mem = Memory(np.zeros(m), np.zeros(m, dtype=int))
    mem.observe(cs, rng.standard_normal(n), rng.standard_normal(n))
    q, v = rng.standard_normal(q_len), rng.standard_normal(q_len)
    tol = None if tol_len is None else 0.5 if tol_len == "scalar" else rng.uniform(0, 1, tol_len)
    with np.errstate(all="ignore"):
        ref = _bands_outcome(lambda: _bands(cs, copy.deepcopy(mem), q, v, tol))
        got = _bands_outcome(lambda: _bands(cs, copy.deepcopy(mem), q, v, tol, kernel))
        if isinstance(ref, tuple):
            assert isinstance(got, tuple)
            # (gaps and rates: C sums against BLAS, within the dot product's bound; the bands exact or as close)
            scale = np.abs(cs.JN).T @ np.abs(q) + np.abs(cs.jN) + np.abs(cs.JN).T @ np.abs(v) + 1e-300
            for a, b in zip(got, ref):
                assert np.all(np.abs(a - b) <= 4 * (n + 2) * np.finfo(float).eps * np.maximum(scale, np.abs(b)))
        else:
            assert got is ref
        tv = rng.uniform(0, 1, tol_len) if isinstance(tol_len, int) and tol_len else rng.uniform(0, 1, m)
        ref = _bands_outcome(lambda: _rate_bands(cs, mem, v, tv))
        got = _bands_outcome(lambda: _rate_bands(cs, mem, v, tv, kernel))
    if not isinstance(ref, tuple):
        assert got is ref
        return
    # (g' = J^T v: C sum against BLAS, within twice the dot product's bound n eps |J|^T |v|; the bands as close)
    scale = np.abs(cs.JN).T @ np.abs(v) + 1e-300
    assert isinstance(got, tuple) and all(
        np.all(np.abs(a - b) <= 4 * (n + 2) * np.finfo(float).eps * np.maximum(scale, np.abs(b))) for a, b in zip(got, ref))


# --- issue 33: review of the compiled search set-up and the kernels' shapes (review-a) ---

def _guarded(shape: tuple, dtype=float):
    """(an output array of ``shape`` that is a C-contiguous view at the start of a larger buffer, the buffer):
    a kernel writing past the output's end changes the buffer's tail (filled with a sentinel)."""
    size = int(np.prod(shape)) if shape else 1
    buf = np.full(size + 64, 12345.0, dtype=dtype)
    return buf[:size].reshape(shape), buf


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(m=st.integers(0, 4), n=st.integers(0, 4),
       deltas=st.lists(st.sampled_from([-1, 0, 0, 1]), min_size=16, max_size=16))
def test_resolve_and_phase_kernels_refuse_any_shape_they_cannot_serve(m, n, deltas):
    """Property: the compiled kernels of the parts 'resolve' (state_bands, rate_bands) and 'phase'
    (exp_integrals, xi_at) read and write without bounds checks. With each array's size perturbed by -1, 0 or
    +1 entries (rows, columns), a call is a ValueError naming the kernel or runs; it never writes past an
    output (each output is the head of a larger buffer whose tail must stay as filled). Unperturbed, it runs."""
    from nsfem.integrate import core

    resolve, phase = core.compiled("resolve"), core.compiled("phase")
    if resolve is None or phase is None:
        pytest.skip("the compiled event core's parts 'resolve' and 'phase' are not built or are switched off")
    rng = np.random.default_rng(m * 10 + n)
    d = iter(deltas)
    size = lambda s: max(0, s + next(d))  # noqa: E731
    JNT = np.ascontiguousarray(rng.standard_normal((size(m), size(n))))
    aJT = np.abs(rng.standard_normal((size(m), size(n))))
    vecs = [rng.standard_normal(size(k)) for k in (m, m, n, n, m, m)]   # jN, aj, q, v, gap_scale, rate_scale
    out, buf = _guarded((size(6), size(m)))
    exact = all(x == 0 for x in deltas[:12])

    def runs_or_refuses(fun, args, name, exact, bufs):
        try:
            fun(*args)
        except ValueError as err:
            assert name in str(err) and not exact, (name, str(err))
        for b, filled in bufs:
            assert np.all(b[filled:] == 12345.0), f"{name} wrote past its output"

    runs_or_refuses(resolve.state_bands, [JNT, aJT, *vecs[:2], *vecs[2:4], *vecs[4:], np.zeros(0), 0.0, out],
                    "state_bands", exact, [(buf, out.size)])
    out2, buf2 = _guarded((2, m))
    runs_or_refuses(resolve.rate_bands, [JNT, aJT, vecs[3], vecs[4], out2], "rate_bands",
                    JNT.shape == (m, n) and aJT.shape == (m, n) and vecs[3].size == n and vecs[4].size == m,
                    [(buf2, out2.size)])
    # exp_integrals(a, b, T, phi): phi len(a) x len(b) complex (interleaved)
    na, nb = size(m), size(n)
    phi, buf3 = _guarded((m, 2 * n))
    runs_or_refuses(phase.exp_integrals, [rng.standard_normal(2 * na), rng.standard_normal(2 * nb), 0.5, phi],
                    "exp_integrals", na == m and nb == n, [(buf3, phi.size)])
    # xi_at(U, nu, tau, w, t, out): U d x p complex, out d + 3 entries with a frequency
    p = m + 1
    U = rng.standard_normal((n, 2 * size(p)))
    xi, buf4 = _guarded((n + 3 + next(d),))
    runs_or_refuses(phase.xi_at, [U, rng.standard_normal(2 * p), 0.1, 3.0, 0.1, xi], "xi_at",
                    U.shape[1] == 2 * p and xi.size >= n + 3, [(buf4, xi.size)])


def test_compiled_search_of_a_U_without_columns_reproduction():
    # U (the state's terms) without columns was read through a NULL pointer (a segfault) before its shape was
    # checked; run in a child process so that a regression fails this test instead of killing the suite
    from nsfem.integrate import core

    if core.compiled("search") is None:
        pytest.skip("the compiled event core's part 'search' is not built or is switched off")
    code = ("import numpy as np\n"
            "from nsfem.integrate import core\n"
            "nu = np.array([-1 + 10j, -1 - 10j])\n"
            "try:\n"
            "    core.compiled('search').Search(nu, np.zeros((0, 3), complex), np.zeros(0, np.intc),\n"
            "        np.zeros((2, 0), complex), np.zeros((1, 3)), np.zeros((1, 3)), np.eye(3), 0.0, 0.0,\n"
            "        np.zeros((2, 2), complex), np.array([0], np.intc), True, np.ones(1), np.zeros((2, 0)),\n"
            "        0.0, 10.0, 0.0, 1.0, np.empty(1), np.empty(1))\n"
            "except ValueError as err:\n"
            "    print('refused:', err)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, (done.returncode, done.stderr[-500:])
    assert done.stdout.startswith("refused:") and "column of U" in done.stdout


# --- issue 33: review-c (compiled impact path and phase set-up) ---

@settings(max_examples=40, deadline=None)
@given(m=st.integers(1, 4), tol_len=st.sampled_from([None, 0, 1, 2, 4, 5, "scalar"]), dq=st.integers(-1, 1),
       dmem=st.integers(-1, 1), seed=st.integers(0, 2 ** 16))
def test_compiled_impact_path_of_any_shapes_is_the_references(m, tol_len, dq, dmem, seed):
    """resolve on the compiled core (its impact path reads q, q', gap_tol and the memory's per-contact arrays
    without bounds checks, and writes the Zeno memory in place) against the reference core on arguments of any
    shapes: a gap tolerance as one number, a list or of another length, a state or a memory of another length.
    The same outcome: the same exception type, or the same configuration, impact contacts, plastic contacts and
    impact counts (m independent stops approached at 1 m/s; the velocities after are -e q'- on each, a few ulp)."""
    import numpy as np

    from nsfem.contact.set import ContactSet
    from nsfem.integrate import ContactSystem, core
    from nsfem.integrate.configuration import Mode
    from nsfem.integrate.transitions import Memory, resolve
    from nsfem.linalg import factorize

    if core.compiled("resolve") is None:
        pytest.skip("the compiled core part 'resolve' is not active")
    rng = np.random.default_rng(seed)
    n = m
    M = np.diag(rng.uniform(0.5, 2.0, n))
    gaps = rng.choice([0.0, 1e-6, 1e-2], m)
    cs = ContactSet.from_arrays(np.eye(n), gaps, eps=rng.choice([0.0, 0.5, 1.0], m))
    system, Mf = ContactSystem.from_arrays(M=M, Q=np.eye(n), contacts=cs), factorize(M)
    q, v = np.zeros(n + dq) if n + dq else np.zeros(0), -np.ones(max(n + dq, 0))
    tol = None if tol_len is None else 1e-3 if tol_len == "scalar" else rng.uniform(0, 2e-3, tol_len)
    touching = {k for k in range(m) if gaps[k] == 0.0}

    def outcome():
        mem = Memory(np.zeros(m + dmem), np.zeros(m + dmem, dtype=np.int64))
        mem.observe(cs, np.zeros(n), -np.ones(n))
        try:
            with np.errstate(all="ignore"):
                mode, v_new, imp = resolve(system, Mf, 0.0, q, v, Mode(), mem, touching, tol)
        except (ValueError, IndexError) as exc:
            return type(exc), None
        key = (mode, None if imp is None else (imp["contacts"], imp["plastic"]), mem.impacts.tolist())
        return key, np.asarray(v_new, dtype=float)

    got = outcome()
    with core.reference():
        ref = outcome()
    assert got[0] == ref[0]
    if got[1] is not None:   # (each stop alone: q'+ = -e q'- or 0 in one division and product, 4 ulp of 1 m/s)
        assert np.all(np.abs(got[1] - ref[1]) <= 4 * np.finfo(float).eps)


@settings(max_examples=30, deadline=None)
@given(kind=st.integers(0, 2), dg=st.integers(-1, 2), dq=st.integers(-1, 1), dv=st.integers(-1, 1),
       seed=st.integers(0, 2 ** 16))
def test_compiled_phase_setup_of_any_shapes_is_the_references(kind, dg, dq, dv, seed):
    """Phase's compiled set-up (PhaseSetup.start reads g0, q0 and q0' without bounds checks) against the reference
    on closed gaps and states of any lengths: the same exception type, or, where a shape differs from the
    configuration's (which the reference broadcasts), its result bit for bit (the reference runs); with the right
    shapes q_p and x0 within twice the dot product's bound (n + 2) eps of their terms (C sums against BLAS)."""
    import contextlib

    import numpy as np

    from nsfem.integrate import core
    from nsfem.integrate.configuration import Phase
    from test_event_search import KINDS, _phase

    if core.compiled("phase") is None:
        pytest.skip("the compiled core part 'phase' is not active")
    rng = np.random.default_rng([37, kind, seed])
    with core.reference():
        base, *_ = _phase(rng, KINDS[kind], "modal")
    cfg = base.config
    n, nc = cfg.system.n, cfg.Gpinv.shape[1]
    q0, v0 = rng.standard_normal(max(n + dq, 0)), rng.standard_normal(max(n + dv, 0))
    g0 = rng.standard_normal(max(nc + dg, 0)) * 1e-3
    out = []
    for reference in (True, False):
        try:
            with core.reference() if reference else contextlib.nullcontext():
                p = Phase(cfg, 0.0, q0, v0, g0)
            out.append((p.qp, p.x0))
        except ValueError:
            out.append(None)
    if out[0] is None:
        assert out[1] is None
        return
    assert out[1] is not None
    if (q0.size, v0.size) != (n, n) or g0.size not in (0, nc):
        assert all(np.array_equal(a, b) for a, b in zip(*out))
        return
    eps = np.finfo(float).eps
    qp_terms = np.abs(cfg.Gpinv) @ np.abs(g0) if g0.size else np.zeros(n)
    assert np.all(np.abs(out[1][0] - out[0][0]) <= 2 * (nc + 2) * eps * qp_terms)
    x_terms = np.abs(cfg.N).T @ np.abs(np.stack([q0 - out[0][0], v0], axis=1)) + np.abs(cfg.N).T @ qp_terms[:, None]
    assert np.all(np.abs(out[1][1] - out[0][1]) <= 4 * (n + 2) * eps * x_terms.T.ravel() + 1e-300)


# --- issue 34: stationary for rotors and rings, rigid motions -----------------------------------------
ROSS_FAST = ["ross_example", "--set", "mesh.elements=6", "--set", "reduction.method=none"]


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(zeroed=st.sets(st.sampled_from(["bearing.2.kxx", "bearing.0.kyy", "bearing.0.kzz", "bearing.1.kyy",
                                       "bearing.1.kzz"])))
def test_stationary_names_every_unrestrained_rigid_motion(zeroed, tmp_path):
    """Any bearing stiffness taken away: either a stationary state whose reactions carry the weight, or one
    line naming the free motion and each key that would restrain it (kxx for axial travel, kyy / kzz per
    plane); ``modes`` warns once and labels the 0 Hz modes instead."""
    import json

    sets = [a for key in sorted(zeroed) for a in ("--set", f"{key}=0")]
    code, out, err = check_invocation(["stationary", *ROSS_FAST, *sets, "--json"], tmp_path)
    axial = "bearing.2.kxx" in zeroed
    planes = {p for p in ("yy", "zz") if any(k.endswith(p) for k in zeroed)}
    if not axial and not planes:
        assert code == 0
        parts = json.loads(out)
        weight = -parts["load_N"][1]
        # no reduction: equilibrium of the exact discrete solution, round-off of the solve (~1e5 eps)
        assert sum(b["reaction_N"][1] for b in parts["bearings"]) == pytest.approx(weight, rel=1e-9)
        return
    assert code == cli.EXIT_ERROR and "unrestrained" in err
    assert ("kxx" in err) == axial and ("axial" in err) == axial
    for p in ("yy", "zz"):
        assert (f"k{p}" in err) == (p in planes)
    code, out, err = check_invocation(["modes", *ROSS_FAST, *sets, "--count", "4", "--json"], tmp_path)
    assert code == 0 and err.count("nsfem modes: warning:") == 1
    assert json.loads(out)["frequencies_hz"][0] == 0.0 and json.loads(out)["rigid_motions"]


def test_issue34_stationary_rub_prints_one_ring_line(tmp_path):
    code, out, err = check_invocation(["stationary", "rub", "--set", "mesh.elements=8", "--set", "reduction.modes=6"],
                                      tmp_path)
    assert code == 0 and not any(line.lstrip().startswith("stator.0.") for line in out.splitlines())
    ring = [line for line in out.splitlines() if line.lstrip().startswith("stator.0 ")]
    assert len(ring) == 1 and "slip on facets" in ring[0]
    assert (out + err).count("existence not guaranteed") == 1


def test_issue34_stationary_ross_example_prints_sag_and_bearing_loads(tmp_path):
    code, out, _ = check_invocation(["stationary", *ROSS_FAST], tmp_path)
    assert code == 0 and "no contacts: the stationary state is Q^-1 f0" in out
    # three bearings: two lateral ones and the thrust bearing at x = 0 (ross_example.toml), which carries no lateral load
    assert out.count("bearing.") == 3 and "disk.0" in out and "largest shaft deflection" in out


def test_issue34_run_warns_once_of_a_free_axial_motion(tmp_path):
    """`run` used to accept a rotor without a thrust bearing silently; it says so once (and runs)."""
    code, _, err = check_invocation(["run", *ROSS_FAST, "--set", "bearing.2.kxx=0", "--set", 'initial.state="rest"',
                                     "--set", "simulation.t_end=0.002", "--set", "output.vtu_every=0",
                                     "--set", "output.plots=[]", "--out", str(tmp_path / "o"), "--json"], tmp_path)
    assert code == 0 and err.count("free rigid motion") == 1 and "kxx" in err


def test_issue34_retainer_drop_lateral_freedom_is_caught_by_its_rings():
    from nsfem import build_model, load_scene
    from nsfem.analysis.rigid_motion import free_motions, rigid_warning

    model = build_model(load_scene("retainer_drop", ["mesh.elements=8"]))
    assert len(free_motions(model)) == 2                  # both lateral planes float on failed magnetic bearings
    assert rigid_warning(model, caught=True) is None and "x-z" in rigid_warning(model)

# --- issue 34: sweep table for rotors ---
def test_issue34_a_rotor_sweep_prints_amplitudes_not_contact_columns(tmp_path):
    """The issue's sweep of a rotor without contacts: contact columns that all read "no contacts", no
    amplitudes, speeds as 13.3333333333. Now: each probe's 1x amplitude and phase under a line saying how
    they are fitted, 6 significant digits, and the start that has not died out in 0.4 s said per run."""
    code, out, err = check_invocation(["sweep", "critical_speed", "--set", "simulation.t_end=0.4", "--set",
                                       "rotation.speed_hz=10:20:4", "--workers", "1", "--out", "s"], tmp_path)
    assert code == 0 and "no contacts" not in out and "13.3333333" not in out + err
    lines = out.splitlines()
    assert "1x" in lines[1] and "whole periods" in lines[1]
    assert lines[2].split() == ["rotation.speed_hz", "disk_y", "[m]", "disk_y", "[deg]", "disk_z", "[m]", "disk_z",
                                "[deg]"]
    assert [line.split()[0] for line in lines[3:7]] == ["10", "13.3333", "16.6667", "20"]
    assert all(float(v) > 0 for line in lines[3:7] for v in line.split()[1:])
    assert "not steady yet" in err                     # 0.4 s: the start (5 1/s) is still there


_CELL = st.one_of(st.none(), st.integers(-10**30, 10**30), st.floats(allow_nan=True, allow_infinity=True),
                  st.text(max_size=12), st.booleans())


@settings(max_examples=60, deadline=None)
@given(rows=st.lists(st.fixed_dictionaries(
    {"s": st.one_of(st.integers(0, 10**6), st.floats(0, 1e6)), "min_gap_m": _CELL, "max_gap_m": _CELL,
     "closed_fraction": st.one_of(st.none(), st.floats(0, 1)), "events": _CELL, "max_normal_force_N": _CELL,
     "error": st.one_of(st.just(""), st.text(min_size=1, max_size=40)),
     "amplitude_p q_m": _CELL, "phase_p q_deg": _CELL}), max_size=6))
def test_issue34_property_the_sweep_table_prints_any_rows_one_line_each(rows):
    """Whatever the rows hold (missing, non-finite, huge, text, failures with newlines), the table is a
    header line and one line per row, failed rows say so, and cells of the same column line up."""
    from nsfem.sweep import table_lines

    lines = table_lines(["s"], rows)
    assert all("\n" not in line and "\r" not in line for line in lines)
    body = lines[-len(rows):] if rows else []
    assert len(lines) == len(rows) + 2
    assert [("failed:" in line) for line in body] == [bool(r["error"]) for r in rows]
    if rows and not any(r["error"] for r in rows):     # aligned: each column starts where its header does
        starts = [i for i in range(1, len(lines[1])) if lines[1][i - 1] == " " == lines[1][i - 2] != lines[1][i]]
        assert all(line[i - 2:i] == "  " for line in body for i in starts if i < len(line))


@settings(max_examples=60, deadline=None)
@given(A=st.floats(1e-9, 1e3), phi=st.floats(-10, 10), c=st.floats(-1e3, 1e3), f=st.floats(0.5, 500),
       per=st.floats(3.5, 200), periods=st.floats(1, 30))
def test_issue34_property_the_harmonic_fit_returns_a_sampled_sinusoid(A, phi, c, f, per, periods):
    """A sampled harmonic with an offset, on any grid of at least 3.5 samples a period (not a whole number
    of samples a period, nor of periods), is returned exactly: the model holds the signal, so the least
    squares only adds round-off (the offset, up to 1e12 x A, enters through cond ~ |c|/A: bounded by
    1e-9 (1 + |c| / A) in amplitude)."""
    import numpy as np

    from nsfem.analysis.harmonic import amplitude_phase, harmonic_fit

    t = np.arange(int(per * periods) + 1) / (f * per)
    amp, lag = amplitude_phase(harmonic_fit(t, c + A * np.cos(2 * np.pi * f * t - phi), f))
    tol = 1e-9 * (1 + abs(c) / A)
    assert abs(amp - A) <= tol * A
    assert abs((np.radians(lag) - phi + np.pi) % (2 * np.pi) - np.pi) <= tol


# --- issue 34: counts and maxima (nsfem.contact.tally) ---
# A results file is input too (``Result.load`` of a file edited by hand or written by an older version): its
# impact records may name contacts that do not exist, carry zero, negative or non-finite impulses, and its
# labels may follow no scene's pattern. The tally never fails on them, counts an impact once per record with a
# positive finite impulse on an existing contact, and the summary stays strict JSON.
TALLY_LABELS = ["delamination.0.0", "delamination.0.1", "stator.0.0", "stator.0.3", "stator.1.1", "crack.0.0",
                "crack.0.1", "obstacle.0", "contact.3", "stator.x.y", "crack..1", "", "delamination.0.-1", "a.b.c.d"]
IMPULSES = st.sampled_from([0.0, 1e-12, 0.1, 2.5, -0.3, -1e-19, float("nan"), float("inf")])


@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(st.lists(st.sampled_from(TALLY_LABELS), min_size=1, max_size=8),
       st.lists(st.lists(st.tuples(st.integers(-2, 9), IMPULSES), max_size=4), max_size=6),
       st.integers(1, 5), st.integers(0, 2 ** 31 - 1))
def test_tally_of_any_records_is_consistent(labels, records, K, seed):
    from nsfem.contact.tally import tally
    from nsfem.jsonio import dumps
    from nsfem.result import Result

    m = len(labels)
    rng = np.random.default_rng(seed)
    normal = np.abs(rng.standard_normal((m, K))) * (rng.random((m, K)) < 0.5)
    impacts = [{"t": 0.01 * i, "contacts": [c for c, _ in rec], "impulse_Ns": [p for _, p in rec]}
               for i, rec in enumerate(records)]
    # a parts record that names rows the arrays do not have, or an unknown kind, is read from the labels instead
    broken = [None, [{"name": "stator.0", "kind": "ring", "rows": [0, m + 3]}], [{"name": "x", "kind": "gear",
                                                                                  "rows": list(range(m))}],
              [{"name": "x"}], "parts"][seed % 5]
    r = Result("exact", np.linspace(0.0, 1.0, K), np.zeros((1, K)), np.zeros((1, K)), rng.random((m, K)), normal,
               np.zeros((m, 2, K)), (normal > 0).astype(int), impacts=impacts,
               info={"contacts": labels, "parts": broken})
    counts = tally(r)
    expected = sum(any(0 <= c < m and np.isfinite(p) and p > 0 for c, p in rec) for rec in records)
    assert counts.impacts == expected
    assert sorted(k for p in counts.parts for k in p.part.rows) == list(range(m))   # each row in one part
    part_impacts = [p.impacts for p in counts.parts]
    assert max(part_impacts) <= expected <= sum(part_impacts)
    owner = {k: i for i, p in enumerate(counts.parts) for k in p.part.rows}
    struck = [{owner[c] for c, p in rec if 0 <= c < m and np.isfinite(p) and p > 0} for rec in records]
    assert counts.shared_impacts == sum(len(s) > 1 for s in struck)
    assert sum(part_impacts) == sum(len(s) for s in struck)
    for p in counts.parts:
        rows = list(p.part.rows)
        # a resultant lies between the largest point's force (parallel normals) or 0 (a ring's vectors) and the sum
        assert p.max_normal_force_N <= normal[rows].sum(axis=0).max() * (1 + 1e-12) + 1e-300
        assert 0.0 <= p.closed_fraction <= 1.0 and p.max_impulse_Ns >= 0.0
    json.loads(dumps(r.summary()))   # strict JSON: no NaN, no inf


@pytest.mark.parametrize("restitution, sustained", [(1.0, False), (0.5, True)])
def test_issue34_impact_only_run_is_not_reported_as_zero_force(restitution, sustained, tmp_path):
    """Reproduction: a run of impacts only (21 of up to 0.1 N s) said "max normal force 0 N"."""
    from test_plots import STOP_TOML

    (tmp_path / "stop.toml").write_text(STOP_TOML.replace("restitution = 1.0", f"restitution = {restitution}")
                                        .replace("t_end = 0.04", "t_end = 0.15"))
    code, out, err = check_invocation(["run", "stop.toml", "--out", "o", "--set", "output.vtu_every=0",
                                       "--set", "output.plots=[]"], tmp_path)
    assert code == 0 and "max normal force 0 N" not in out
    assert ("no sustained normal force" in out) is not sustained and "largest impulse" in out


# --- issue 34: scene defaults, notes and axis names ---
# Notes are no errors: a command exits 0 with each note once on stderr ("nsfem <command>: note: ..."), and a
# bearing key in another program's axes (ROSS's cxx, kxy) is a one-line error naming our axes.
ROTOR_TOML = """
[shaft]
length = 0.8
diameter = 0.03
{supports}
[beam]
theory = "euler-bernoulli"
[[disk]]
x = 0.4
mass = 3.0
polar_inertia = 0.0
diametral_inertia = 0.0
[[bearing]]
x = 0.0
{bearing}
[[bearing]]
x = 0.8
kyy = 1e7
kzz = 1e7
[rotation]
frame = "inertial"
gravity = 0.0
[mesh]
elements = 20
[reduction]
method = "none"
"""


def test_issue34_bearings_get_no_hidden_supports(tmp_path):
    """The issue's rotor (0.8 m steel shaft of 30 mm, 3 kg disk, bearings 1e7 N/m) without a supports key: its
    first bending pair is the spring-supported one (ROSS 2.3.0: 60.4584 Hz; tests/test_scene_defaults.py solves
    the continuous beam), not the 62.52 Hz of pinned ends hidden under the bearings. 20 Hermite elements miss the
    first mode by (beta h)^4 / 1440 = 1.7e-7 (beta h = 0.125): 1e-5 holds it and the ROSS digits printed."""
    import json

    scene = tmp_path / "rotor.toml"
    scene.write_text(ROTOR_TOML.format(supports="", bearing="kyy = 1e7\nkzz = 1e7\nkxx = 1e6"))
    code, out, err = check_invocation(["modes", str(scene), "--json", "--count", "4"], tmp_path)
    assert code == 0 and "note:" not in err, err
    payload = json.loads(out)
    bending = [f for f, fld in zip(payload["frequencies_hz"], payload["fields"]) if fld != "U"]
    assert bending[0] == pytest.approx(60.4584, rel=1e-5) and payload["notes"] == []


def test_issue34_ross_way_bearing_is_refused_at_its_damping_key(tmp_path):
    """A bearing copied from ROSS (kxx, kyy, cxx, cyy): cxx is no key of ours; the error says which axis is which."""
    scene = tmp_path / "rotor.toml"
    scene.write_text(ROTOR_TOML.format(supports="", bearing="kxx = 1e7\nkyy = 1e7\ncxx = 100.0\ncyy = 100.0"))
    code, _, err = check_invocation(["modes", str(scene)], tmp_path)
    assert code == cli.EXIT_ERROR and "bearing.0.cxx: unknown key: x is the shaft axis" in err
    assert "y (horizontal) and z (vertical, up)" in err


@settings(max_examples=20, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.fixed_dictionaries({}, optional={k: st.sampled_from([0.0, 5e5, 1e6, 2e6]) for k in ("kxx", "kyy", "kzz")}),
       st.sampled_from(["", 'supports = "free-free"', 'supports = "pinned-pinned"']))
def test_issue34_bearing_axes_notes(bearing, supports):
    """Any mix of kxx, kyy, kzz on a bearing: exit 0; a note naming the axes exactly when kxx is there beside kyy
    without kzz (ROSS's horizontal and vertical) or at least as large as the smaller lateral stiffness, never for
    a thrust bearing alone or one whose kxx is below both lateral ones; every note printed once, and the same
    list in the JSON."""
    import json

    from nsfem.scene import load_scene

    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        scene = root / "rotor.toml"
        scene.write_text(ROTOR_TOML.format(supports=supports, bearing="\n".join(f"{k} = {v}" for k, v in
                                                                               bearing.items())))
        argv = ["modes", str(scene), "--json", "--count", "2"]   # every command's hook: test_scene_defaults.py
        code, out, err = check_invocation(argv, root)
        notes = list(load_scene(scene).notes)
    assert code == 0, err
    kxx, kyy, kzz = (bearing.get(k, 0.0) for k in ("kxx", "kyy", "kzz"))
    lateral = [k for k in (kyy, kzz) if k > 0]
    axes = [n for n in notes if "x is the shaft axis" in n]
    if kxx > 0 and kyy > 0 and kzz == 0:
        assert axes and "with kyy and no kzz" in axes[0]
    elif kxx > 0 and lateral and kxx >= min(lateral):
        assert axes and "as large as its lateral" in axes[0]
    else:
        assert not axes
    # a free axial motion is the model's warning (said by run/modes/stationary), never a note as well
    assert not any("along its axis" in n or "axial rigid motion" in n for n in notes)
    for n in notes:
        assert err.count(n) == 1 and f"nsfem modes: note: {n}" in err
    assert json.loads(out)["notes"] == notes


@settings(max_examples=15, deadline=None, derandomize=True, database=None)
@given(st.sampled_from("kc"), st.sampled_from("xyz"), st.sampled_from("xyz"))
def test_issue34_bearing_keys_of_other_axes_name_the_axes(kind, a, b):
    """Every stiffness or damping key in three letters: ours are keys, any other is one line naming our axes."""
    from nsfem.scene import SCHEMA

    key = f"{kind}{a}{b}"
    with tempfile.TemporaryDirectory() as d:
        code, _, err = check_invocation(["modes", "ross_example", "--count", "1", "--set", "mesh.elements=6",
                                         "--set", f"bearing.0.{key}=1.0"], Path(d))
    if key in SCHEMA["bearing"][0]:   # ours: loaded (1 N/m may still leave a direction unheld: its own error)
        assert "unknown key" not in err, err
    else:
        assert code == cli.EXIT_ERROR and f"bearing.0.{key}: unknown key: x is the shaft axis" in err


@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(st.fixed_dictionaries({}, optional={"section": st.sampled_from(["rectangle", "circle"]),
                                           "diameter": st.just(0.03), "inner_diameter": st.just(0.01),
                                           "width": st.just(0.03), "height": st.just(0.02),
                                           "supports": st.sampled_from(["pinned-pinned", "free-free", "clamped-free"])}),
       st.booleans())
def test_issue34_supports_and_sections_follow_what_the_scene_says(shaft, bearings):
    """Any mix of section and supports keys, with or without bearings: the scene loads with the supports it names
    (none hidden under bearings: free-free when it names none), the section it names or its keys imply (a diameter
    alone: a circle), or is refused with one line naming a shaft key."""
    from nsfem.scene import SceneError, scene_from_tree

    tree = {"shaft": {"length": 0.8, **shaft}, "rotation": {"speed_hz": 0.0}, "mesh": {"elements": 8},
            "bearing": [{"x": 0.0, "kyy": 1e6, "kzz": 1e6, "kxx": 1e5}, {"x": 0.8, "kyy": 1e6, "kzz": 1e6}]
            if bearings else []}
    try:
        scene = scene_from_tree(tree)
    except SceneError as exc:
        assert str(exc).startswith("shaft.") and "\n" not in str(exc), exc
        return
    named = shaft.get("supports", "free-free" if bearings else "pinned-pinned")
    assert scene["shaft"]["supports"] == named
    assert bool(scene.stack.supports) == (named != "free-free")
    roundish = ("diameter" in shaft or "inner_diameter" in shaft) and not ("width" in shaft or "height" in shaft)
    assert scene["shaft"]["section"] == shaft.get("section", "circle" if roundish else "rectangle")
    assert scene.stack.segments[0].section == scene["shaft"]["section"]


# --- issue 34: plots that read (sensors.png, long signals) ---
from hypothesis.extra import numpy as hnp  # noqa: E402


@settings(max_examples=30, deadline=None, derandomize=True, database=None)
@given(n=st.integers(1, 3000), speed=st.sampled_from([0.0, 26.0, 1e6]),
       values=hnp.arrays(float, 64, elements=st.one_of(st.floats(-1e3, 1e3),
                                                       st.sampled_from([np.nan, np.inf, -np.inf]))),
       scale=st.sampled_from([1e-300, 1e-6, 1.0, 1e20]))
def test_sensor_panels_draw_any_record(n, speed, values, scale):
    """The panels of sensors.png (the run with its zoom, the spectra, the orbit) take a record of any length,
    speed and values (constant, 1e-300 m to 1e23 m, with NaN and inf: a diverged run's sensors) without an
    exception or a numpy warning (laid out, not rendered: test_sensors_plot_reproductions saves). Beyond about
    1e300 matplotlib's own axis arithmetic overflows: no record of a machine comes near."""
    import warnings

    import matplotlib.pyplot as plt

    from nsfem.plot.common import dominant_period, figure, long_signal, zoom_panel, zoom_span
    from nsfem.plot.sensors import _orbit, _spectra
    from nsfem.sensors import Sensor

    t = np.linspace(0.0, 1e-3 * n, n)
    v = scale * np.resize(values, (n, 2))
    sensors = [Sensor("a", 0.5, "+y", "inertial", "s"), Sensor("b", 0.5, "+z", "inertial", "s")]
    fig, axes = figure(ncols=3)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            period = 1 / speed if speed else dominant_period(t, v[:, 0])
            span = zoom_span(t, period)
            ax, zoom = zoom_panel(axes[0]) if span else (axes[0], None)
            for k in range(2):
                long_signal(ax, t, v[:, k], period=period, zoom=zoom, span=span)
            _spectra(axes[1], t, v, sensors, ["C0", "C1"], speed)
            _orbit(axes[2], t, v, sensors[0], sensors[1], 0, 1, [(0.5, 1e-4)])
    finally:
        plt.close(fig)


def test_sensors_plot_reproductions(tmp_path):
    """The listed cases: an 8 s record at 26 Hz (a solid block before: now an envelope and a zoom of the
    last 5 periods), a constant record (no period: no zoom), a record of NaN (a diverged run)."""
    from nsfem.plot.sensors import sensors_plot
    from nsfem.sensors import Sensor

    sensors = [Sensor("a", 0.5, "+y", "inertial", "s"), Sensor("b", 0.5, "+z", "inertial", "s")]
    t = np.arange(0.0, 8.0, 1e-4)
    for name, v in (("long", 1e-5 * np.column_stack([np.cos(163 * t), np.sin(163 * t)])),
                    ("constant", np.full((t.size, 2), 3e-6)), ("nan", np.full((t.size, 2), np.nan))):
        assert sensors_plot(tmp_path / f"{name}.png", t, v, sensors, 26.0, name).stat().st_size > 10_000


# --- issue 34: render and ParaView (the series in vtu/, export --frame) ---
VTU_TARGETS = ("missing", "file", "users_folder")


def _vtu_target(out: Path, kind: str) -> None:
    """What stands at ``out/vtu`` before an export into ``out``: nothing (no ``out`` either), a user's
    file, or a folder holding a user's file."""
    if kind != "missing":
        out.mkdir()
    if kind == "file":
        (out / "vtu").write_text("mine")
    elif kind == "users_folder":
        (out / "vtu").mkdir()
        (out / "vtu" / "mine.vtu").write_text("mine")


@settings(max_examples=12, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(frame=st.sampled_from([None, "rotating", "inertial", "lab", "", "INERTIAL"]),
       target=st.sampled_from(VTU_TARGETS), every=st.sampled_from(["1", "4", "0"]))
def test_export_frame_and_subfolder_property(saved_result, frame, target, every):
    """Any --frame, any thing at DIR/vtu, any --every: exit 0 with a valid folder (the .pvd indexing
    exactly its frames in vtu/, a user's file there kept) or one line naming the problem, nothing written."""
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        _vtu_target(root / "v", target)
        argv = ["export", str(saved_result), "--vtu", "v", "--every", every]
        argv += [] if frame is None else ["--frame", frame]
        code, _, stderr = check_invocation(argv, root)
        ok = frame in (None, "rotating", "inertial") and target != "file" and every != "0"
        assert (code == 0) == ok, (argv, target, stderr)
        if ok:
            folder_is_valid(root / "v", foreign=["vtu/mine.vtu"] if target == "users_folder" else ())
            assert (root / "v" / "nsfem.pvd").is_file()
        else:
            assert not (root / "v" / "nsfem.pvd").exists()
        if target == "file":
            assert (root / "v" / "vtu").read_text() == "mine"
        if target == "users_folder":
            assert (root / "v" / "vtu" / "mine.vtu").read_text() == "mine"


@pytest.mark.parametrize("argv, text", [
    (["--frame", "lab"], "--frame: invalid choice: 'lab'"),
    (["--frame", ""], "--frame: invalid choice: ''"),
])
def test_export_frame_reproductions(saved_result, argv, text, tmp_path):
    code, _, stderr = check_invocation(["export", str(saved_result), "--vtu", "v", *argv], tmp_path)
    assert code == cli.EXIT_ERROR and text in stderr, stderr
    assert not (tmp_path / "v").exists()


@pytest.mark.skipif(not hasattr(os, "symlink"), reason="needs symbolic links")
def test_a_manifest_never_removes_through_a_linked_vtu(tmp_path):
    """A run's folder whose vtu/ was replaced by a link to another folder: the next run, which writes no
    series, removes the frames the manifest names but never the linked folder's files of those names."""
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    assert cli.main(["run", *CHEAP[:2], *TINY_RUN, "--set", "output.vtu_every=1", "--out", str(out)]) == 0
    listed = json.loads((out / MANIFEST).read_text())["files"]["series"]
    frames = [n for n in listed if n.startswith("vtu/")]
    assert frames
    (out / "vtu").rename(elsewhere)
    os.symlink(elsewhere, out / "vtu")
    before = sorted(p.name for p in elsewhere.iterdir())
    code, _, stderr = check_invocation(["run", *CHEAP[:2], *TINY_RUN, "--out", "out"], tmp_path)
    assert code == 0, stderr
    assert sorted(p.name for p in elsewhere.iterdir()) == before


# --- issue 34: campbell ---
def test_campbell_png_writes_only_that_file(tmp_path):
    """The reproduction: `nsfem campbell ross_example --png X` wrote X and also ./out/campbell.png (the
    scene lists campbell in output.plots); --png names the one file written."""
    code, out, _ = check_invocation(["campbell", "ross_example", "--speeds", "0:60:7", "--png", "x.png"], tmp_path)
    assert code == 0 and sorted(p.name for p in tmp_path.iterdir()) == ["x.png"], out


@settings(max_examples=8, deadline=None, derandomize=True, database=None)
@given(start=st.floats(0.0, 200.0), span=st.floats(0.0, 300.0), n=st.integers(1, 9), count=st.integers(1, 8))
def test_property_campbell_critical_speeds_lie_on_the_speeds_and_the_branches(start, span, n, count,
                                                                              tmp_path_factory):
    """Any speed grid and count: exit 0, the critical speeds lie within the grid's range, each is the
    frequency of a damped root at that speed (to Brent's tolerance, 1e-11 of the range, relative 1e-8
    with the eigen solver's round-off), the JSON has no private keys and the plot is the only file."""
    from nsfem.analysis.campbell import state_eigenvalues
    from nsfem.analysis.modes import contact_basis
    from nsfem.fem.assemble import build_model
    from nsfem.fem.rotating import rotor_operators
    from nsfem.reduce import scene_reduction
    from nsfem.scene import load_scene
    from nsfem.system import linear_system

    root = tmp_path_factory.mktemp("campbell")
    speeds = f"{start!r}:{start + span!r}:{n}"
    code, out, stderr = check_invocation(["campbell", "critical_speed", "--speeds", speeds, "--count", str(count),
                                          "--png", "c.png", "--json"], root)
    assert code == 0, stderr
    payload = json.loads(out)
    assert not [k for k in payload if k.startswith("_")]
    assert sorted(p.name for p in root.iterdir()) == ["c.png"]
    found = payload["critical_speeds"]["open"]
    assert [c["speed_hz"] for c in found] == payload["critical_speeds_hz"]["open"]
    scene = load_scene("critical_speed")
    model = build_model(scene)
    ops = rotor_operators(model, contact_basis(model, "open", scene_reduction(scene.reduction, model)))
    for c in found:
        assert start <= c["speed_hz"] <= start + span
        lam = state_eigenvalues(linear_system(ops, c["speed_hz"], frame="inertial", rayleigh=scene.damping.rayleigh,
                                              external=scene.damping.external), 2 * count)
        assert np.min(np.abs(lam.imag / (2 * math.pi) - c["speed_hz"])) <= 1e-8 * c["speed_hz"]


# --- issue 34: latency (a command's BLAS threads) ---
# A fresh command sets one BLAS thread only where the environment names none (nsfem.cli.one_blas_thread);
# whatever a user put in those variables reaches OpenBLAS as it is, and the command still answers.
def _modes_with_blas_threads(value: str | None, cwd: Path) -> list[float]:
    env = {k: v for k, v in os.environ.items() if k not in cli.BLAS_THREAD_VARIABLES}
    env["PYTHONPATH"] = str(Path(__file__).resolve().parents[1])
    if value is not None:
        env["OPENBLAS_NUM_THREADS"] = value
    run = subprocess.run([sys.executable, "-m", "nsfem", "modes", "--count", "2", "--json"], cwd=cwd, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0 and "Traceback" not in run.stderr, (value, run.stderr)
    return json.loads(run.stdout)["frequencies_hz"]


@pytest.fixture(scope="module")
def modes_one_thread(tmp_path_factory) -> list[float]:
    return _modes_with_blas_threads(None, tmp_path_factory.mktemp("blas"))


@pytest.mark.parametrize("value", ["abc", "-1", "99999999999999999999"])
def test_hostile_blas_thread_setting(value, tmp_path, modes_one_thread):
    """A hostile OPENBLAS_NUM_THREADS: the command answers (exit 0, no traceback, nothing left behind) with the
    frequencies of a command left to its one thread (to 1e-9: the thread count only reorders the eigensolver's
    sums, round-off of order 1e-13 relative)."""
    assert np.allclose(_modes_with_blas_threads(value, tmp_path), modes_one_thread, rtol=1e-9, atol=0)
    assert not leftovers(tmp_path)


# --- issue 34: pictures that read (envelope bins, resonance amplitude axis, render ruler) ---
@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(speed=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.none(),
                       st.sampled_from([np.inf, -np.inf, np.nan, 1e300, 1.7e308, 12.4])),
       n=st.integers(0, 3000), duration=st.sampled_from([0.0, 1e-9, 1.0, 8.0, 1e6]),
       dense=st.sampled_from([None, True]))
def test_revolution_envelope_of_any_speed_and_record(speed, n, duration, dense):
    """The per-revolution envelope of gap.png and forces.png (:func:`nsfem.plot.common.long_signal` with the
    rotation's period, as they call it: none unless the speed is positive): for any speed (0, negative, NaN, inf,
    a scene's 1e300 Hz) and record (empty, one sample, no duration, a million seconds), ``dense`` or not, it
    draws one artist, a line through every sample or a band of at least one bin and at most one per sample,
    never an exception (1.7e308 Hz over 1e6 s: more periods than a float holds)."""
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from nsfem.plot.common import figure, long_signal

    t = np.linspace(0.0, duration, n)
    with np.errstate(divide="ignore", over="ignore"):
        period = 1.0 / speed if speed is not None and speed > 0 else None
    fig, ax = figure()
    try:
        (drawn,) = long_signal(ax, t, np.sin(t), period=period, dense=dense)
        if isinstance(drawn, Line2D):
            assert len(drawn.get_xdata()) == n
        else:
            assert n > 1 and 4 <= len(drawn.get_paths()[0].vertices) <= 2 * n + 8
    finally:
        plt.close(fig)


@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(amps=st.lists(st.one_of(st.none(), st.floats(-1e200, 1e200), st.sampled_from([0.0, 1e-200, 1e-6, np.nan,
                                                                                       np.inf, -np.inf])),
                     min_size=1, max_size=5))
def test_resonance_amplitude_axis_of_any_values(amps, tmp_path_factory):
    """resonance.png's amplitude panel (linear below a ratio of 100, log above) takes any amplitudes a sweep
    may hold (missing, 0, negative, NaN, inf, 1e-200 to 1e200 m) and writes its PNG, no exception, no temporary
    file (beyond about 1e300 matplotlib's own log-axis arithmetic overflows: no machine comes near)."""
    from nsfem.plot.sweep import plot_resonance

    out = tmp_path_factory.mktemp("res")
    keys = ["rotation.speed_hz"]
    points = [{keys[0]: 10.0 + i} for i in range(len(amps))]
    runs = [{"amplitude_disk_y_m": a, "min_gap_m": None} for a in amps]
    path = plot_resonance(out / "resonance.png", keys, points, runs, "fuzz")
    assert path.stat().st_size > 0 and [p.name for p in out.iterdir()] == ["resonance.png"]


@given(length=st.floats(allow_nan=True, allow_infinity=True))
@settings(max_examples=200, deadline=None, derandomize=True, database=None)
def test_ruler_labels_of_any_length(length):
    """render's ruler: 4 to 9 labels (3 to 8 parts) for any stack length (0, negative, NaN, inf, 1e-300 to
    1e300 m), never an exception."""
    from nsfem.export.render import ruler_labels

    n = ruler_labels(length)
    assert isinstance(n, int) and 4 <= n <= 9


def test_ruler_labels_reproductions():
    """The shipped scenes' lengths: 1.5 m (ross_example) in steps of 0.25 (0.375 before), 0.8 m (crack, rub) of
    0.2, 0.6 m (retainer_drop) of 0.1, 1 m (default, critical_speed) of 0.2; a length of no round step: 5."""
    from nsfem.export.render import ruler_labels

    assert [ruler_labels(x) for x in (1.5, 0.8, 0.6, 1.0, 0.77)] == [7, 5, 7, 6, 5]


# --- issue 34: review r3 (the series in vtu/ after an interrupt, output folders, lazy names) ---
def _interrupt_the_nth_vtu(monkeypatch, n: int) -> None:
    """The ``n``-th .vtu write of the process raises KeyboardInterrupt (Ctrl-C mid-frame), before writing."""
    from nsfem.export import vtu

    calls, write = [0], vtu._write_vtu

    def interrupted(path, mesh):
        calls[0] += 1
        if calls[0] == n:
            raise KeyboardInterrupt
        write(path, mesh)

    monkeypatch.setattr(vtu, "_write_vtu", interrupted)


def test_an_export_interrupted_mid_frame_lists_only_the_files_left(saved_result, tmp_path, monkeypatch):
    """Ctrl-C on a frame's second part: the frame's first .vtu is removed again, so the manifest must not
    name it (else the next command takes a user's file of that name for nsfem's and removes it)."""
    out = tmp_path / "v"
    _interrupt_the_nth_vtu(monkeypatch, 4)   # frame 0: stack, contacts; frame 1: stack, then Ctrl-C
    assert cli.main(["export", str(saved_result), "--vtu", str(out), "--every", "1"]) == 130
    folder_is_valid(out)
    listed = set().union(*map(set, json.loads((out / MANIFEST).read_text())["files"].values()))
    assert {n for n in listed if not (out / n).exists()} == set()
    monkeypatch.undo()
    (out / "vtu" / "nsfem_00001.vtu").write_text("mine")   # the user's file of the name removed
    assert cli.main(["export", str(saved_result), "--vtu", str(out), "--every", "2"]) == 0
    assert (out / "vtu" / "nsfem_00001.vtu").read_text() == "mine"


def test_ctrl_c_while_the_index_is_written_still_leaves_the_index(saved_result, tmp_path, monkeypatch):
    """Ctrl-C (a real SIGINT) just as the series' nsfem.pvd is written, every frame done: the index is
    finished (the signal acted on after it), so ParaView finds every frame; before, the frames were left
    with no .pvd at all (the old one is removed by then)."""
    from nsfem.export import vtu

    write = vtu.write_atomic

    def ctrl_c_on_the_index(path, fn):
        if str(path).endswith(".pvd"):
            os.kill(os.getpid(), signal.SIGINT)
        return write(path, fn)

    monkeypatch.setattr(vtu, "write_atomic", ctrl_c_on_the_index)
    out = tmp_path / "v"
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)   # Ctrl-C's, even where started ignored
    try:
        assert cli.main(["export", str(saved_result), "--vtu", str(out), "--every", "1"]) == 130
    finally:
        signal.signal(signal.SIGINT, previous)
    assert (out / "nsfem.pvd").is_file()
    folder_is_valid(out)
    assert len(vtu.series_parts(out / "nsfem.pvd")["stack"]) == len(np.load(saved_result)["t"])


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(name=st.one_of(st.text(max_size=12), st.sampled_from(["no.such", "export.nosuch", "a..b", ".", "1x",
                                                            "nosuch", "__nosuch__"])))
def test_property_any_attribute_of_nsfem_is_a_value_or_absent(name):
    """``getattr(nsfem, name, default)`` (what hasattr, IDEs and doc tools do) of any string gives a value or
    the default, never another exception (a dotted name used to raise ModuleNotFoundError from the lazy
    __getattr__); every public name resolves and ``from nsfem import *`` binds them."""
    import nsfem

    missing = object()
    value = getattr(nsfem, name, missing)
    assert value is missing or name in dir(nsfem) or name.isidentifier()
    namespace: dict = {}
    exec("from nsfem import *", namespace)
    assert {n: namespace[n] for n in nsfem.__all__} == {n: getattr(nsfem, n) for n in nsfem.__all__}


def test_a_dotted_attribute_of_nsfem_is_absent_reproduction():
    import nsfem

    assert not hasattr(nsfem, "no.such") and not hasattr(nsfem, "export.nosuch")


def test_ctrl_c_during_the_series_keeps_the_sensor_signals(tmp_path, monkeypatch):
    """The VTU series is the longest output to write: Ctrl-C there must not cost the sensors' file (the
    probes' signals, which no other command writes from a results file); they are written before it."""
    out = tmp_path / "r"
    _interrupt_the_nth_vtu(monkeypatch, 3)
    assert cli.main(["run", "rub", "--out", str(out), "--set", "simulation.t_end=0.01", "--set",
                     "output.vtu_every=1", "--set", "output.plots=[]"]) == 130
    folder_is_valid(out)
    assert (out / "sensors.csv").is_file() and (out / "nsfem.pvd").is_file()


@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(n=st.integers(1, 64), extra=st.integers(0, 200), seed=st.integers(0, 2**32 - 1))
def test_property_welch_of_a_record_shorter_than_a_segment_is_scipys(n, extra, seed):
    """psd.png of a short run: a record of n samples shorter than the segment asked for (n + extra) is one
    segment of n, as scipy.signal.welch does (it warns); odd and even n. Same sums in another order: equal
    to round-off (1e-10 of the largest bin, as in test_latency.test_welch_equals_scipy)."""
    import warnings

    from scipy.signal import welch as scipy_welch

    from nsfem.spectrum import welch

    x = np.random.default_rng(seed).standard_normal(n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)   # "nperseg = ... is greater than input length"
        f_ref, p_ref = scipy_welch(x, fs=1e3, nperseg=n + extra, detrend="constant", scaling="density")
    f, p = welch(x, 1e-3, n + extra)
    assert f.shape == f_ref.shape and np.allclose(f, f_ref, rtol=1e-14, atol=0)
    assert np.all(np.abs(p - p_ref) <= 1e-10 * max(np.max(np.abs(p_ref)), 1e-300))


def _frame_name_as_folder(out: Path, name: str) -> None:
    """A user's folder (holding a file) at ``out/vtu/<name>``, where a series writes a frame file."""
    (out / "vtu" / name).mkdir(parents=True)
    (out / "vtu" / name / "mine.txt").write_text("mine")


@settings(max_examples=6, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(command=st.sampled_from(["run", "export"]), index=st.integers(0, 10),
       part=st.sampled_from(["nsfem_{:05d}.vtu", "nsfem_{:05d}.vtm", "nsfem_contacts_{:05d}.vtu"]))
def test_property_a_folder_named_like_a_frame_is_refused_before_the_run(saved_result, command, index, part):
    """A folder in vtu/ named like a frame file the series would write: one line naming it, before anything
    is computed or written (it used to fail at that frame after the run, leaving frames with no .pvd)."""
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        name = part.format(index)
        _frame_name_as_folder(root / "o", name)
        argv = (["run", *CHEAP, "--set", "output.vtu_every=1", "--out", "o"] if command == "run"
                else ["export", str(saved_result), "--vtu", "o", "--every", "1"])
        code, _, stderr = check_invocation(argv, root)
        assert code == cli.EXIT_ERROR and f"vtu/{name}" in stderr, stderr
        assert sorted(p.name for p in (root / "o").iterdir()) == ["vtu"]
        assert sorted(p.name for p in (root / "o" / "vtu").iterdir()) == [name]


def test_a_series_that_cannot_write_a_frame_still_indexes_the_frames_before(saved_result, tmp_path):
    """write_series (from Python, no checks before) meeting a folder where frame 2's .vtm goes: OSError, and
    nsfem.pvd indexes frames 0 and 1; the user's folder is left alone."""
    from nsfem.export.vtu import series_parts, write_series

    res, extra, model, _ = cli._saved(str(saved_result), "export")   # the model rebuilt from the file
    out = tmp_path / "o"
    _frame_name_as_folder(out, "nsfem_00002.vtm")
    with pytest.raises(OSError):
        write_series(res, (model, extra["basis"]), out, every=1)
    assert [t for t, _ in series_parts(out / "nsfem.pvd")["stack"]] == [float(t) for t in res.t[:2]]
    assert (out / "vtu" / "nsfem_00002.vtm" / "mine.txt").read_text() == "mine"
    assert not (out / "vtu" / "nsfem_00002.vtu").exists()   # the frame cut short is removed


@pytest.mark.skipif(not hasattr(os, "symlink"), reason="needs symbolic links")
@pytest.mark.parametrize("command", ["run", "export"])
def test_a_dangling_vtu_link_is_refused_before_the_run(saved_result, command, tmp_path, capsys):
    """vtu/ a link to a folder that does not exist (a scratch disk not mounted): one line naming it before the
    run; it failed after the run with "cannot write out/vtu: File exists", leaving an empty nsfem.pvd."""
    out = tmp_path / "o"
    out.mkdir()
    os.symlink(tmp_path / "not-mounted" / "frames", out / "vtu")
    argv = (["run", *CHEAP, "--set", "output.vtu_every=1", "--out", str(out)] if command == "run"
            else ["export", str(saved_result), "--vtu", str(out), "--every", "1"])
    assert cli.main(argv) == cli.EXIT_ERROR
    err = capsys.readouterr().err
    assert err.count("nsfem: error:") == 1 and f"{out / 'vtu'}" in err and "does not exist" in err, err
    assert sorted(p.name for p in out.iterdir()) == ["vtu"]


# --- issue 34: review (r2): stationary parts, notes, modes ---
def test_issue34_modes_of_retainer_drop_does_not_warn_about_the_scene_itself(tmp_path):
    """`run retainer_drop` is silent about the lateral freedom its retainer rings catch; `modes` warned
    ("restrain them with bearings' kyy and kzz"), advice against the scene's own design. It lists the 0 Hz
    modes of the open contacts by name and warns of nothing; a free axial motion is still said once."""
    code, out, err = check_invocation(["modes", "retainer_drop", "--set", "mesh.elements=8"], tmp_path)
    assert code == 0 and "warning" not in err and out.count("rigid lateral motion") == 4
    code, _, err = check_invocation(["modes", "retainer_drop", "--set", "mesh.elements=8", "--set",
                                     "bearing.0.kxx=0"], tmp_path)
    assert code == 0 and err.count("free rigid motion") == 1 and "axial" in err and "x-z" not in err


@pytest.mark.parametrize("name", ["default", "crack", "critical_speed", "retainer_drop", "ross_example", "rub",
                                  "stepped_rotor", "runup"])
def test_issue34_shipped_scenes_have_no_notes_and_modes_no_warning(tmp_path, name):
    """A shipped scene states what it means: no note at load, no warning from `modes`."""
    from nsfem import load_scene

    assert load_scene(name).notes == ()
    code, _, err = check_invocation(["modes", name, "--set", "reduction.modes=6", "--count", "4"], tmp_path)
    assert code == 0 and "warning" not in err and "note" not in err


def test_issue34_stationary_note_on_the_unbalance_advises_what_the_scene_can_do(tmp_path):
    """On anisotropic bearings (critical_speed, ross_example) the rotating frame is refused, so the stationary
    note must not send the user there; on isotropic ones (the Jeffcott rotor of tests/test_sweep.py) it may."""
    from test_sweep import JEFFCOTT

    for name in ("critical_speed", "ross_example"):
        code, out, err = check_invocation(["stationary", name], tmp_path)
        assert code == 0 and "harmonic in the inertial frame" in out and "rotation.frame" not in out + err
        # both are linear (no contacts, no cracks): their steady 1x comes from the harmonic solve (issue 35)
        assert "nsfem response" in out
    (tmp_path / "j.toml").write_text(JEFFCOTT)
    code, out, _ = check_invocation(["stationary", str(tmp_path / "j.toml"), "--set", "rotation.speed_hz=40"],
                                    tmp_path)
    assert code == 0 and 'rotation.frame = "rotating"' in out


def test_issue34_stationary_of_a_rotor_its_rings_catch_says_why_not_and_what_to_run(tmp_path):
    """retainer_drop's rotor is held laterally by its retainer rings only: the stationary LCP needs Q itself
    invertible, so it is refused, but not with advice against the scene's design (add bearings) alone: the
    message says the rings catch it and that `nsfem run` computes the drop."""
    code, _, err = check_invocation(["stationary", "retainer_drop"], tmp_path)
    assert code == 2 and "unrestrained" in err and "stator" in err and "nsfem run" in err


# --- issue 34: contact plots of a scene without contacts (write_plots, output.plots left out or listed) ---
@settings(max_examples=8, deadline=None, derandomize=True, database=None,   # a phase.png is 0.4 s
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(names=st.lists(st.sampled_from(["phase", "gap", "psd", "forces", "campbell"]), max_size=6), listed=st.booleans())
def test_contact_plots_of_a_run_without_contacts_warn_only_when_listed(names, listed, tmp_path):
    """A run without contacts: the plots the scene listed (``listed``) that need contacts are each skipped with
    one warning naming them; from the default list (not listed) they are left out without a word. The CLI's
    reproduction is test_run.py::test_contact_plots_of_a_scene_without_contacts_are_skipped_silently_unless_listed."""
    from nsfem.integrate import ContactSystem
    from nsfem.plot.results import write_plots
    from nsfem.result import Result

    w = 2 * np.pi * np.array([1.0, 3.0])
    system = ContactSystem.from_arrays(M=np.eye(2), Q=np.diag(w ** 2))
    t = np.linspace(0.0, 1.0, 51)
    q = np.vstack([np.cos(w[0] * t), np.sin(w[1] * t)])
    empty = np.zeros((0, t.size))
    r = Result("exact", t, q, -q, empty, empty, np.zeros((0, 2, t.size)), empty.astype(int), t_end=1.0)
    out = Path(tempfile.mkdtemp(dir=tmp_path))
    warned = []
    paths = write_plots(r, system, out, names, warn=warned.append, listed=listed)
    for p in ("gap", "forces"):
        said = [m for m in warned if m.startswith(f"plot '{p}' skipped")]
        assert len(said) == (listed and p in names), (names, listed, warned)
    assert [p.name for p in paths] == ["phase.png"] * ("phase" in names)   # psd: no model to locate a point
    assert sorted(f.name for f in out.iterdir()) == ["phase.png"] * ("phase" in names)   # no temporary file left


# --- issue 35: nsfem response (harmonic unbalance response) ---
RESPONSE_SPEEDS = ["10:45:20", "0:10:3", "10:5:3", "1:10", "::", "1:nan:3", "1:inf:3", "1:1e300:3", "-1:5:3",
                   "1:2:0", "1:2:1e9", "x:y:z", "5:5:1", "1e-300:1e-299:2"]
RESPONSE_SETS = [[], ["--set", "unbalance=[]"], ["--set", "sensor=[]"], ["--set", "unbalance.0.magnitude=-1"],
                 ["--set", "bearing.0.kyy=0"], ["--set", 'rotation.frame="rotating"'],
                 ["--set", "reduction.modes=2"]]


@settings(max_examples=12, deadline=None, derandomize=True, database=None,   # each under 0.5 s
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(scene=st.sampled_from(["critical_speed", "rub", "crack", "ross_example"]),
       speeds=st.sampled_from(RESPONSE_SPEEDS), sets=st.sampled_from(RESPONSE_SETS),
       png=st.sampled_from([[], ["--png", "b.png"], ["--png", "b.txt"], ["--png", "."]]))
def test_response_invocations_end_in_a_result_or_one_line(scene, speeds, sets, png, tmp_path):
    """Any scene, speed range, override and picture name: exit 0 with finite numbers (and the PNG when asked),
    or exit 2 with one line, no traceback, nothing half-written."""
    import json
    import math

    with tempfile.TemporaryDirectory(dir=tmp_path) as d:
        code, out, err = check_invocation(["response", scene, "--speeds", speeds, *sets, *png, "--json"], Path(d))
        if code == 0:
            rep = json.loads(out)
            assert all(math.isfinite(a) for v in rep["sensors"].values() for a in v["amplitude_m"])
            assert rep["outputs"] == ([] if not png else [png[1]])


@pytest.mark.parametrize("argv, words", [
    (["rub", "--speeds", "1:10:5"], "contacts"),
    (["crack", "--speeds", "1:10:5"], "crack"),
    (["critical_speed", "--speeds", "0:10:5"], "START must be above 0"),
    (["critical_speed", "--speeds", "1:1e300:3"], "--speeds"),
    (["critical_speed", "--speeds", "1:10:5", "--set", "unbalance=[]"], "[[unbalance]]"),
])
def test_response_reproductions(argv, words, tmp_path):
    code, _, err = check_invocation(["response", *argv], tmp_path)
    assert code == cli.EXIT_ERROR and words in err


# --- issue 35: stepped shafts and speed-dependent bearings (scene) ---
STEP_SCENE = """[shaft]
length = 1.0
section = "circle"
diameter = 0.05
[mesh]
elements = 20
[reduction]
method = "none"
"""
TABLE_SCENE = """[shaft]
length = 1.0
section = "circle"
diameter = 0.05
[[bearing]]
x = 0.0
speeds_hz = [0.0, 25.0, 50.0]
kyy = [1e6, 3e6, 4e6]
kzz = [1e6, 3e6, 4e6]
[[bearing]]
x = 1.0
kyy = 2e6
kzz = 2e6
[[bearing]]
x = 0.0
kxx = 1e7
[rotation]
frame = "inertial"
[mesh]
elements = 20
[reduction]
method = "none"
"""
_step_number = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-3, 3), st.just("x"),
                         st.lists(st.floats(-1, 2), max_size=2))


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(step=st.dictionaries(st.sampled_from(["start", "end", "diameter", "inner_diameter", "width", "height", "E",
                                             "rho", "bore"]), _step_number, max_size=5))
def test_any_shaft_step_is_modes_or_a_one_line_error(step, tmp_path):
    """Whatever a ``[[shaft.step]]`` holds, ``modes`` answers or refuses it in one line naming a key."""
    from nsfem.jsonio import dumps as _dumps

    sets = [f"shaft.step.0.{k}={_dumps(v)}" for k, v in step.items()]
    (tmp_path / "s.toml").write_text(STEP_SCENE)
    code, _, err = check_invocation(["modes", "s.toml", "--count", "2", *sum((["--set", s] for s in sets), [])],
                                    tmp_path)
    if code == 2 and "shaft.step" in err:
        assert "nsfem: error: shaft.step" in err, err


@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(speeds=st.lists(st.floats(-10, 100), max_size=4), kyy=st.one_of(st.floats(-1e6, 1e7), st.lists(
    st.one_of(st.floats(-1e6, 1e7), st.just(float("nan"))), max_size=4)), speed=st.floats(0, 120))
def test_any_bearing_table_is_modes_or_a_one_line_error(speeds, kyy, speed, tmp_path):
    """A bearing table of any speeds and values, at any scene speed: ``modes`` answers or refuses in one line."""
    from nsfem.jsonio import dumps as _dumps

    (tmp_path / "b.toml").write_text(TABLE_SCENE)
    argv = ["modes", "b.toml", "--count", "2", "--set", f"bearing.0.speeds_hz={_dumps(speeds)}",
            "--set", f"bearing.0.kyy={_dumps(kyy)}", "--set", f"rotation.speed_hz={speed!r}"]
    check_invocation(argv, tmp_path)


@pytest.mark.parametrize("argv, words", [
    (["campbell", "b.toml", "--speeds", "0:80:3"], "bearing.0.speeds_hz: 80 Hz lies outside the bearing's table"),
    (["modes", "b.toml", "--set", "rotation.speed_hz=60"], "bearing.0.speeds_hz: 60 Hz lies outside"),
    (["stationary", "b.toml", "--set", "rotation.speed_hz=51"], "bearing.0.speeds_hz: 51 Hz lies outside"),
    (["modes", "b.toml", "--set", "bearing.0.kzz=[1e6, 2e6]"], "bearing.0.kzz: has 2 values for the 3 speeds"),
    (["modes", "b.toml", "--set", "bearing.1.kyy=[1e6, 2e6]"], "needs the bearing's speeds_hz"),
    (["campbell", "b.toml", "--set", "rotation.frame=rotating", "--set", "bearing.0.kzz=[1e6, 3e6, 5e6]"],
     "bearing.0 is not isotropic at 50 Hz of its table"),
    (["modes", "s.toml", "--set", "shaft.step.0.start=0.5", "--set", "shaft.step.0.end=0.4"],
     "shaft.step.0.end: must exceed start"),
    (["modes", "s.toml", "--set", "shaft.step.0.start=0.2", "--set", "shaft.step.0.end=0.6",
      "--set", "shaft.step.1.start=0.5", "--set", "shaft.step.1.end=0.7"], "shaft.step.1.start: step 1"),
    (["modes", "s.toml", "--set", "shaft.step.0.start=0.2", "--set", "shaft.step.0.end=1.2"],
     "beyond the shaft's end"),
    (["modes", "s.toml", "--set", "shaft.step.0.start=0.2", "--set", "shaft.step.0.end=0.6",
      "--set", "shaft.step.0.diameter=1e-40"], "shaft.step.0.diameter: the bending stiffness"),
    (["modes", "s.toml", "--set", "shaft.step.0.start=0.2", "--set", "shaft.step.0.end=0.6",
      "--set", "shaft.diameter=1e-40", "--set", "shaft.step.0.diameter=0.05"], "shaft.diameter: the bending"),
])
def test_issue35_scene_reproductions(argv, words, tmp_path):
    (tmp_path / "s.toml").write_text(STEP_SCENE)
    (tmp_path / "b.toml").write_text(TABLE_SCENE)
    code, _, err = check_invocation(argv, tmp_path)
    assert code == 2 and words in err, err


def test_a_speed_sweep_of_a_tabled_bearing_builds_a_model_per_speed(tmp_path):
    """Runs of a sweep share a model only where the bearings are the same: with a table, one per speed, each
    scene's bearings read at its speed."""
    from nsfem.sweep import plan

    (tmp_path / "b.toml").write_text(TABLE_SCENE)
    p = plan(tmp_path / "b.toml", ["rotation.speed_hz=10:40:2"])
    assert p.model_group(0) != p.model_group(1)
    assert [p.scene(i).stack.bearings[0].K[0][0] for i in (0, 1)] == [1.8e6, 3.6e6]   # 1e6 + 0.8 (2e6), 3e6 + 0.6e6


# --- issue 35: damped modes at speed (modes --speed, --png) and bearing forces of a run ---
MODES_SPEED_CASES = [
    (["modes", *ROSS, "--speed", "nan"], "error", "--speed"),
    (["modes", *ROSS, "--speed", "-1"], "error", "--speed"),
    (["modes", *ROSS, "--speed", "inf"], "error", "--speed"),
    (["modes", *ROSS, "--speed", "1e300"], "error", "--speed"),            # beyond the bar wave speed
    (["modes", *ROSS, "--png", "orbits.png"], "error", "--speed"),         # orbits of damped modes only
    (["modes", *ROSS, "--speed", "10", "--png", "orbits.txt"], "error", "--png"),
    (["modes", *ROSS, "--speed", "10", "--count", "0"], "error", "--count"),
    (["modes", *ROSS, "--speed", "10", "--set", "rotation.frame=\"rotating\""], "error", "bearing.0"),  # anisotropic
    (["modes", *ROSS, "--speed", "10"], "ok", ""),
    (["modes", *RUB, "--speed", "0", "--contact", "closed"], "ok", ""),
    # a growing mode (cross-coupled bearings) and modes beyond a reduction's trust are said, not hidden
    (["modes", *ROSS, "--speed", "50", "--set", "bearing.0.kyz=5e5", "--set", "bearing.0.kzy=-5e5"], "ok",
     "unstable at 50 Hz"),
    (["modes", *ROSS, "--speed", "50", "--count", "30"], "ok", "not converged in the reduction"),
]


@pytest.mark.parametrize("argv,outcome,text", MODES_SPEED_CASES)
def test_modes_speed_reproductions(argv, outcome, text, tmp_path):
    code, _, stderr = check_invocation(argv, tmp_path)
    assert code == (0 if outcome == "ok" else cli.EXIT_ERROR), stderr
    assert text in stderr


@settings(max_examples=10, deadline=None, derandomize=True, database=None,   # a modes --speed is 0.2 s
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(speed=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(0.0, 200.0)),
       count=st.integers(-2, 30), png=st.sampled_from([None, "o.png", "o.npz", "sub"]))
def test_modes_speed_either_answers_aligned_lists_or_one_line(speed, count, png, tmp_path):
    """Any --speed, --count and --png: exit 0 with the four lists aligned, ascending damped frequencies and
    the log decrements those of the damping ratios, or exit 2 with one line; no file but the PNG asked for."""
    root = Path(tempfile.mkdtemp(dir=tmp_path))
    (root / "sub").mkdir()
    (root / "sub" / "mine.txt").write_text("the user's")   # a folder named as --png: refused, kept
    argv = ["modes", *ROSS, "--json", "--speed", repr(speed), "--count", str(count)] + (["--png", png] if png else [])
    code, stdout, _ = check_invocation(argv, root)
    if code == 0:
        out = json.loads(stdout)
        f, z, d = (np.array(out[k], dtype=float) for k in ("frequencies_hz", "damping_ratios", "log_decrements"))
        assert len(out["whirl"]) == f.size == z.size == d.size <= count
        assert np.all(np.diff(f) >= 0) and np.all(f > 0)
        assert d == pytest.approx(2 * np.pi * z / np.sqrt(1 - z**2), rel=1e-9, abs=1e-12)
        assert sorted(p.name for p in root.iterdir()) == sorted(["sub"] + ([png] if png else []))


def test_bearing_forces_of_a_run_in_a_folder_that_refuses_bearings_csv(tmp_path):
    """bearings.csv is claimed with the run's files: a folder of that name where it goes is refused before the
    run, naming it, and nothing is written."""
    out = tmp_path / "out"
    (out / "bearings.csv").mkdir(parents=True)
    (out / "bearings.csv" / "mine.txt").write_text("the user's")
    code, _, stderr = check_invocation(["run", *ROSS, *CHEAP[2:], "--out", "out"], tmp_path)
    assert code == cli.EXIT_ERROR and "bearings.csv" in stderr, stderr
    assert sorted(p.name for p in out.iterdir()) == ["bearings.csv"]


# --- issue 35: timoshenko (shear modulus G, beam theory, shear coefficient) ---
SHEAR_MODES = ["modes", "ross_example", "--set", "mesh.elements=6", "--set", "reduction.method=\"none\"",
               "--set", "beam.theory=\"timoshenko\""]
SHEAR_CASES = [
    (["--set", "shaft.G=0"], "shaft.G"),
    (["--set", "shaft.G=-8e10"], "shaft.G"),
    (["--set", "shaft.G=nan"], "shaft.G"),
    (["--set", "shaft.G=inf"], "shaft.G"),
    (["--set", "shaft.G=1e10"], "shaft.G"),                 # nu = 9.55: not a material
    (["--set", "shaft.G=2e11"], "shaft.G"),                 # nu < 0: outside the shear coefficients' range
    (["--set", "shaft.G=\"hard\""], "shaft.G"),
    (["--set", "beam.theory=\"timoshenk\""], "beam.theory"),
    (["--set", "beam.theory=\"Timoshenko\""], "beam.theory"),
    (["--set", "beam.shear_coefficient=\"cowpr\""], "beam.shear_coefficient"),
    (["--set", "shaft.step=[{start=0.2, end=0.4, diameter=0.06, G=-1.0}]"], "shaft.step.0.G"),
    (["--set", "shaft.step=[{start=0.2, end=0.4, E=1e9, G=8.12e10}]"], "shaft.step.0.G"),
]


@pytest.mark.parametrize("extra, key", SHEAR_CASES, ids=[" ".join(c[0][1::2]) for c in SHEAR_CASES])
def test_bad_shear_input_is_one_line_naming_the_key(extra, key, tmp_path):
    """Each bad G (not positive, not finite, not a number, a Poisson's ratio E / (2 G) - 1 outside [0, 0.5]
    against its own E, a step's against the step's E) and a misspelt theory or shear coefficient: exit 2,
    one line naming the key."""
    code, _, stderr = check_invocation([*SHEAR_MODES, *extra], tmp_path)
    assert code == cli.EXIT_ERROR and key in stderr, stderr


def test_bad_segment_shear_modulus_names_the_segment(tmp_path):
    """The low-level [[segment]] takes G too, checked against its own E."""
    (tmp_path / "s.toml").write_text('[beam]\ntheory = "timoshenko"\n[[segment]]\nname = "a"\nstart = 0.0\n'
                                     'end = 1.0\nE = 2e11\nG = 5e10\n[[support]]\nsegment = "a"\nx = 0.0\n'
                                     'fix = ["U", "V", "W", "V\'", "W\'"]\n')
    code, _, stderr = check_invocation(["modes", "s.toml"], tmp_path)
    assert code == cli.EXIT_ERROR and "segment.0.G" in stderr and "Poisson" in stderr, stderr


@settings(max_examples=12, deadline=None, derandomize=True, database=None,   # a 6-element modes is 0.1 s
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(G=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(7.1e10, 1.05e11)),
       theory=st.sampled_from(["timoshenko", "rayleigh", "euler-bernoulli", "timo"]))
def test_any_shear_modulus_either_answers_or_one_line(G, theory, tmp_path):
    """Any G with any theory: exit 0 with ascending positive frequencies (a G in [E / 3, E / 2]) or exit 2 with
    one line naming shaft.G or beam.theory."""
    root = Path(tempfile.mkdtemp(dir=tmp_path))
    argv = ["modes", "ross_example", "--set", "mesh.elements=6", "--set", "reduction.method=\"none\"", "--json",
            "--set", f"beam.theory=\"{theory}\"", "--set", f"shaft.G={G!r}"]
    code, stdout, stderr = check_invocation(argv, root)
    ok = math.isfinite(G) and 2.11e11 / 3 <= G <= 2.11e11 / 2 and theory != "timo"
    assert (code == 0) == ok, (G, theory, stderr)
    if code == 0:
        f = np.array(json.loads(stdout)["frequencies_hz"])
        assert np.all(f > 0) and np.all(np.diff(f) >= 0)
    else:
        assert ("shaft.G" in stderr) or ("beam.theory" in stderr), stderr


# --- issue 35: Campbell by log decrement, tables not reaching 0 Hz (stepped_rotor's bearings) ---
@settings(max_examples=8, deadline=None, derandomize=True, database=None,   # a campbell of ROSS: about 0.3 s
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(q=st.one_of(st.just(0.0), st.floats(-2e7, 2e7)), c=st.one_of(st.just(0.0), st.floats(0.0, 1e5)),
       png=st.sampled_from([None, "c.png"]))
def test_campbell_log_decrements_are_aligned_and_the_figure_drawn_for_any_cross_coupling(q, c, png, tmp_path):
    """Any bearing cross coupling and damping (stable, growing, undamped): exit 0 with ``log_decrements`` aligned
    with ``frequencies_hz`` (null exactly where they are) and each critical speed's log dec that of its damping
    ratio (growing: negative), the PNG written if asked; or exit 2 with one line."""
    root = Path(tempfile.mkdtemp(dir=tmp_path))
    argv = ["campbell", *ROSS, "--speeds", "0:40:5", "--count", "4", "--json", "--set", f"bearing.0.kyz={q!r}",
            "--set", f"bearing.0.kzy={-q!r}", "--set", f"bearing.0.cyy={c!r}", "--set", f"bearing.0.czz={c!r}"]
    code, stdout, _ = check_invocation(argv + (["--png", png] if png else []), root)
    if code == 0:
        out = json.loads(stdout)
        for f_key, d_key in (("frequencies_hz", "log_decrements"), ("frequencies_closed_hz", "log_decrements_closed")):
            F = np.array(out[f_key], dtype=float)
            D = np.array(out[d_key], dtype=float)
            assert F.shape == D.shape and np.array_equal(np.isnan(F), np.isnan(D))
        for crit in out["critical_speeds"]["open"]:
            z = crit["damping_ratio"]
            assert crit["log_decrement"] == pytest.approx(2 * np.pi * z / np.sqrt(1 - z * z), rel=1e-9, abs=1e-12)
        # the PNG asked for, else the scene's own out/campbell.png (ross_example lists campbell in output.plots)
        assert sorted(p.name for p in root.iterdir()) == ([png] if png else ["out"])


TABLE_FROM_10 = TABLE_SCENE.replace("speeds_hz = [0.0, 25.0, 50.0]", "speeds_hz = [10.0, 25.0, 50.0]").replace(
    "[rotation]\n", "[rotation]\nspeed_hz = 30.0\n")


@pytest.mark.parametrize("argv", [
    ["campbell", "t.toml", "--speeds", "10:40:4", "--count", "2", "--set", "mesh.elements=8", "--set",
     "bearing.1.kyz=5e5", "--set", "bearing.1.kzy=-5e5"],                   # undamped crossings, onset read 0 Hz
    ["stationary", "t.toml"],                                                          # the rest system read 0 Hz
    ["run", "t.toml", "--set", "simulation.t_end=0.01", "--set", "output.vtu_every=0", "--set", "output.plots=[]"],
])
def test_issue35_a_table_from_10_hz_is_never_read_at_0_hz(argv, tmp_path):
    """A bearing table starting above 0 Hz (a journal bearing has no film at rest): campbell of a cross-coupled
    rotor (its undamped crossings and, unstable from the table's first speed on, its instability onset searched
    from 0 Hz) and stationary/run at the table's speeds refused it, '0 Hz lies outside the bearing's table', where
    nothing asks for 0 Hz; now they answer (an explicit speed outside the table is still refused)."""
    (tmp_path / "t.toml").write_text(TABLE_FROM_10)
    code, _, err = check_invocation(argv, tmp_path)
    assert code == 0 and "outside" not in err, err
    code, _, err = check_invocation(["campbell", "t.toml", "--speeds", "0:40:5"], tmp_path)
    assert code == cli.EXIT_ERROR and "bearing.0.speeds_hz: 0 Hz lies outside" in err, err


# --- issue 35: run-up and coast-down ([rotation] ramp_to_hz, ramp_s) ---
import nsfem  # noqa: E402

RUNUP_TOML = Path(nsfem.__file__).parent / "scenes" / "runup.toml"
RUNUP = ["runup", "--set", "simulation.t_end=0.02", "--set", "stator.0.clearance=0.05", "--out", "out"]

RUNUP_CASES = [
    # (extra --set values, method or None, the words of the one-line error)
    (["rotation.ramp_s=0"], None, "rotation.ramp_s: must be > 0 with rotation.ramp_to_hz"),
    (["rotation.ramp_s=-1"], None, "rotation.ramp_s"),
    (["rotation.ramp_to_hz=-5"], None, "rotation.ramp_to_hz"),
    (["rotation.ramp_to_hz=nan"], None, "rotation.ramp_to_hz: must be finite"),
    (["rotation.ramp_to_hz=inf"], None, "rotation.ramp_to_hz: must be finite"),
    (["rotation.ramp_to_hz=\"fast\""], None, "rotation.ramp_to_hz: must be a number"),
    (["rotation.ramp_to_hz=1e9"], None, "rotation.ramp_to_hz: 1e+09 Hz spins the outermost fibre"),
    (["rotation.frame=\"rotating\""], None, "stator.0.stiffness: a run-up in the rotating frame does not carry an "
     "elastic ring"),
    ([], "exact", "rotation.ramp_to_hz: the exact method integrates constant speeds"),
    (["stator.0.stiffness=0", "stator.0.damping=0"], "rk",
     "rotation.ramp_to_hz: rk integrates a run-up of a rotor whose contacts are elastic rings"),
    (["stator.0.friction=0.1"], "rk", "stator.0.friction: an elastic ring's friction against the shaft surface"),
    (["stator.0.stiffness=0", "stator.0.damping=0", "stator.0.friction=0.1"], "exact",
     "rotation.ramp_to_hz: the exact method integrates constant speeds"),
]


@pytest.mark.parametrize("sets,method,text", RUNUP_CASES)
def test_runup_reproductions(sets, method, text, tmp_path):
    argv = ["run", *RUNUP, *[a for s in sets for a in ("--set", s)]] + (["--method", method] if method else [])
    code, _, stderr = check_invocation(argv, tmp_path)
    assert code == cli.EXIT_ERROR and text in stderr, stderr
    assert not (tmp_path / "out").exists()


def test_ramp_s_without_ramp_to_hz_is_refused(tmp_path):
    code, _, stderr = check_invocation(["run", "critical_speed", "--set", "rotation.ramp_s=2", "--out", "out"],
                                       tmp_path)
    assert code == cli.EXIT_ERROR and "rotation.ramp_s: 2 s given without rotation.ramp_to_hz" in stderr


@settings(max_examples=12, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(start=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(0.0, 60.0)),
       end=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(0.0, 60.0)),
       ramp=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-1.0, 3.0)),
       method=st.sampled_from(["rk", "penalty", "moreau", "exact"]))
def test_any_ramp_runs_or_is_refused_in_one_line(start, end, ramp, method, tmp_path):
    """Any speeds and duration and any method: exit 0 with run info whose profile is the scene's (speed_hz the
    initial speed, ramp_to_hz and ramp_s), or exit 2 with one line before anything is written."""
    root = Path(tempfile.mkdtemp(dir=tmp_path))
    argv = ["run", "runup", "--set", "simulation.t_end=0.005", "--set", "simulation.output_dt=1e-3",
            "--set", "stator.0.clearance=0.05", "--set", f"rotation.speed_hz={start!r}",
            "--set", f"rotation.ramp_to_hz={end!r}", "--set", f"rotation.ramp_s={ramp!r}", "--method", method,
            "--set", "simulation.moreau_step=1e-4", "--out", "out", "--json"]
    code, stdout, _ = check_invocation(argv, root)
    if code == 0:
        out = json.loads(stdout)
        assert method != "exact" or end == start
        assert out["completed"] and out["speed_hz"] == start
        assert end == start or (out["ramp_to_hz"], out["ramp_s"]) == (end, ramp)
    else:
        assert not (root / "out").exists()


def test_runup_into_an_unstable_speed_warns(tmp_path):
    """Internal damping (beta = 1e-3 s) makes the rotor unstable above its onset: a run-up that reaches 300 Hz
    from a stable 18 Hz says so before the run, naming the speed (exit 0)."""
    argv = ["run", "runup", "--set", "damping.rayleigh=[0,1e-3]", "--set", "stator.0.clearance=0.05",
            "--set", "rotation.ramp_to_hz=300", "--set", "simulation.t_end=0.01", "--out", "out"]
    code, _, stderr = check_invocation(argv, tmp_path)
    assert code == 0 and "the run-up reaches speeds where the structure without contact forces is unstable: at " \
        "rotation.ramp_to_hz = 300 Hz" in stderr, stderr


RUNUP_TABLE_CASES = [
    (["rotation.speed_table_s=[0,1]", "rotation.speed_table_hz=[18]"], "rotation.speed_table_hz: the table needs "
     "as many speeds as times"),
    (["rotation.speed_table_s=[0.1,1]", "rotation.speed_table_hz=[18,30]"], "rotation.speed_table_s.0: the table "
     "starts at t = 0"),
    (["rotation.speed_table_s=[0,1,1]", "rotation.speed_table_hz=[18,30,20]"], "rotation.speed_table_s.2: the "
     "times must increase strictly"),
    (["rotation.speed_table_s=[0,1]", "rotation.speed_table_hz=[18,-3]"], "rotation.speed_table_hz.1: must be >= 0"),
    (["rotation.speed_table_s=[0,nan]", "rotation.speed_table_hz=[18,20]"], "rotation.speed_table_s.1: must be "
     "finite"),
    (["rotation.speed_table_s=[0,1]", "rotation.speed_table_hz=[20,30]"], "rotation.speed_hz: 18 Hz differs from "
     "the table's first speed"),
    (["rotation.speed_table_s=[0,1]", "rotation.speed_table_hz=[18,1e9]"], "rotation.speed_table_hz.1: 1e+09 Hz"),
]


@pytest.mark.parametrize("sets,text", RUNUP_TABLE_CASES)
def test_runup_table_reproductions(sets, text, tmp_path):
    """A speed table beside the scene's ramp is refused first; without the ramp, each bad table in one line."""
    base = ["run", "runup", "--set", "simulation.t_end=0.02", "--set", "stator.0.clearance=0.05", "--out", "out"]
    code, _, stderr = check_invocation(base + [a for s in sets for a in ("--set", s)], tmp_path)
    # (a key's own check, finite, within the speed limit, comes first)
    assert code == cli.EXIT_ERROR and ("give a ramp (ramp_to_hz, ramp_s) or a speed table" in stderr
                                       or text in stderr), stderr
    (tmp_path / "r.toml").write_text(re.sub(r"ramp_to_hz = .*\nramp_s = .*\n", "", RUNUP_TOML.read_text()))
    code, _, stderr = check_invocation(["run", "r.toml", *base[2:], *[a for s in sets for a in ("--set", s)]],
                                       tmp_path)
    assert code == cli.EXIT_ERROR and text in stderr, stderr
    assert not (tmp_path / "out").exists()


def test_runup_table_runs(tmp_path):
    (tmp_path / "r.toml").write_text(re.sub(r"ramp_to_hz = .*\nramp_s = .*\n", "", RUNUP_TOML.read_text()))
    argv = ["run", "r.toml", "--set", "rotation.speed_table_s=[0,0.01,0.02]", "--set",
            "rotation.speed_table_hz=[18,30,0]", "--set", "simulation.t_end=0.03", "--out", "out", "--json"]
    code, stdout, stderr = check_invocation(argv, tmp_path)
    assert code == 0, stderr
    out = json.loads(stdout)
    assert out["speed_table_hz"] == [18.0, 30.0, 0.0] and out["speed_hz"] == 18.0
    code, _, stderr = check_invocation(argv[:-1] + ["--method", "exact"], tmp_path)
    assert code == cli.EXIT_ERROR and "rotation.speed_table_s: the exact method integrates constant speeds" in stderr


# --- issue 35: response above the structure's instability onset, campbell text log decs ---
def test_issue35_response_above_the_oil_whip_onset_warns_and_marks_the_speeds(tmp_path):
    """stepped_rotor's contact-free structure grows above its oil-whip onset (campbell: 135.778 Hz): a harmonic solve
    there is no steady state. ``response --speeds 100:150:51`` (1 Hz steps) warns once (stderr and JSON), the onset
    it names within one speed step of campbell's, marks exactly the speeds above it ``unstable`` and flags any peak
    found there; the PNG (Bode/polar, unstable range shaded) is written."""
    code, out, err = check_invocation(["response", "stepped_rotor", "--speeds", "100:150:51", "--json",
                                       "--png", "r.png"], tmp_path)
    assert code == 0, err
    rep = json.loads(out)
    said = [w for w in rep["warnings"] if "unstable" in w]
    assert len(said) == 1 and err.count("structure is unstable") == 1, (rep["warnings"], err)
    onset = rep["stable_below_hz"]
    assert abs(onset - 135.778) <= 1.0, onset            # the grid step: 1 Hz
    assert f"{onset:.4g} Hz" in said[0] and "1/s" in said[0]
    s = np.array(rep["speeds_hz"])
    assert rep["unstable"] == [bool(x >= onset) for x in s]
    assert all(p["unstable"] == (p["speed_hz"] >= onset) for p in rep["peaks"])
    assert (tmp_path / "r.png").is_file()


def test_issue35_response_of_a_stable_rotor_marks_nothing(tmp_path):
    """Below the onset (stepped_rotor 20-120 Hz): no warning, every speed stable, ``stable_below_hz`` null."""
    code, out, err = check_invocation(["response", "stepped_rotor", "--speeds", "20:120:11", "--json"], tmp_path)
    assert code == 0, err
    rep = json.loads(out)
    assert "unstable" not in err and rep["unstable"] == [False] * 11 and rep["stable_below_hz"] is None
    assert not any(p["unstable"] for p in rep["peaks"])


def test_issue35_campbell_text_prints_log_decrements_of_the_critical_speeds(tmp_path):
    """The text of ``campbell`` gives each damped critical speed's log dec (what the figure's legend and ``modes
    --speed`` print), the same number as its JSON ``log_decrement``."""
    code, text, err = check_invocation(["campbell", *ROSS, "--speeds", "0:60:13", "--set", "bearing.0.cyy=2e3",
                                        "--set", "bearing.0.czz=2e3"], tmp_path)
    assert code == 0, err
    code, out, err = check_invocation(["campbell", *ROSS, "--speeds", "0:60:13", "--set", "bearing.0.cyy=2e3",
                                       "--set", "bearing.0.czz=2e3", "--json"], tmp_path)
    crit = json.loads(out)["critical_speeds"]["open"]
    assert crit and "log dec" in text
    for c in crit:
        assert f"log dec {c['log_decrement']:.3g}" in text, (c, text)


def test_issue35_stationary_note_points_a_linear_rotor_to_response(tmp_path):
    """stationary of stepped_rotor (unbalance, anisotropic bearings, no contact) says where its steady 1x response
    is: `nsfem response` (the harmonic solve), not a transient `nsfem sweep`."""
    code, out, err = check_invocation(["stationary", "stepped_rotor", "--json"], tmp_path)
    assert code == 0, err
    assert "nsfem response" in json.loads(out)["note"]


@pytest.mark.parametrize("q", [0.0, 5e6, -5e6])
def test_issue35_response_unstable_speeds_are_campbells_growing_ones(q, tmp_path):
    """Any cross coupling of ross_example's bearing (stable, growing from rest on): ``response``'s ``unstable`` flags
    are exactly the speeds where ``campbell`` at the same speeds reports a positive growth rate, and it warns once
    exactly when one is flagged."""
    common = [*ROSS, "--speeds", "1:60:12", "--json", "--set", f"bearing.0.kyz={q!r}",
              "--set", f"bearing.0.kzy={-q!r}"]
    code, out, err = check_invocation(["response", *common], tmp_path)
    assert code == 0, err
    rep = json.loads(out)
    code, out, err2 = check_invocation(["campbell", *common], tmp_path)
    grows = [g > 0 for g in json.loads(out)["growth_rate_per_s"]["open"]]
    assert rep["unstable"] == grows
    assert err.count("structure is unstable") == (1 if any(grows) else 0)
    assert (rep["stable_below_hz"] is None) == (not any(grows))


# --- issue 35: bearing tables in a run-up ---
# a run-up reads a tabulated bearing at Omega(t): the ramp's speeds (runup: 18 -> 38 Hz) must lie inside every
# bearing's table, refused at loading (one line naming the bearing, its speeds_hz and both ranges) otherwise
RUNUP_TABLE = ["runup", "--set", "simulation.t_end=0.002", "--set", "output.vtu_every=0", "--set", "output.plots=[]",
               "--set", "stator.0.clearance=0.05"]


def _table_argv(lo: float, hi: float, out: str) -> list[str]:
    return ["run", *RUNUP_TABLE, "--out", out, "--set", f"bearing.0.speeds_hz=[{lo!r}, {hi!r}]",
            "--set", "bearing.0.cyy=[40.0, 60.0]", "--set", "bearing.0.czz=[40.0, 60.0]"]


def test_issue35_a_ramp_leaving_a_bearing_table_is_refused(tmp_path):
    code, _, err = check_invocation(_table_argv(0.0, 30.0, "out"), tmp_path)
    assert code == 2, err
    line = [x for x in err.splitlines() if x.startswith("nsfem: error:")][0]
    assert "bearing.0.speeds_hz" in line and "[18, 38] Hz" in line and "[0, 30] Hz" in line, line


@settings(max_examples=6, deadline=None, suppress_health_check=list(HealthCheck))
@given(lo=st.floats(0.0, 40.0), width=st.floats(1.0, 40.0))
def test_issue35_a_ramp_runs_exactly_when_every_table_covers_it(lo, width):
    hi = lo + width
    with tempfile.TemporaryDirectory() as d:
        code, _, err = check_invocation(_table_argv(lo, hi, "out"), Path(d))
    inside = lo <= 18.0 and hi >= 38.0
    assert code == (0 if inside else 2), (lo, hi, err)
    if not inside:   # refused at the scene's speed 18 Hz already, or by the ramp's range
        assert "bearing.0.speeds_hz" in err and "table [" in err


# --- issue 36: periodic ---
# nsfem periodic refuses, in one line naming the option or key and before any integration: a bad --multiple,
# --transient or --tol, a --continue that is not KEY=LOW:HIGH of a numeric key with two finite different ends
# (a good one runs: tests/test_periodic_continue.py), a rotor at rest (nsfem stationary answers it), a run-up, a --start that is missing,
# a folder, not a results file or of another model, and --transient together with --start.
PERIODIC = ["periodic", "crack", "--set", "output.vtu_every=0", "--set", "output.plots=[]"]


def _a_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


@settings(max_examples=12, deadline=None, suppress_health_check=list(HealthCheck))
@given(option=st.sampled_from(["--multiple", "--transient", "--tol"]),
       value=st.one_of(st.integers(-10**6, 0), st.integers(10**5 + 1, 10**9),
                       st.floats(allow_nan=True, allow_infinity=True).filter(lambda x: not 1e-14 <= x <= 1e-3),
                       st.text(max_size=6).filter(lambda s: not _a_number(s))))
def test_issue36_periodic_options_out_of_range_are_refused_by_name(option, value):
    if option == "--transient" and isinstance(value, int) and value == 0:
        value = -1   # 0 transient periods is valid (shoot from the scene's initial state)
    if option == "--multiple" and isinstance(value, int) and 1 <= value <= 64:
        value = 0
    with tempfile.TemporaryDirectory() as d:
        code, _, err = check_invocation([*PERIODIC, "--out", "o", option, str(value)], Path(d))
        assert code == 2 and option in err, (option, value, err)
        assert not (Path(d) / "o").exists()


@settings(max_examples=10, deadline=None, suppress_health_check=list(HealthCheck))
@given(key=st.sampled_from(["rotation.speed_hz", "disk.0.mass", "rotation.frame", "disk.7.mass", "nokey", "",
                            "crack.0", "sensor.0.name"]),
       low=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=4)),
       high=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=4)),
       sep=st.sampled_from([":", "::", ",", ""]))
def test_issue36_continue_is_always_one_line_and_never_runs(key, low, high, sep):
    """Whatever --continue says, the command ends with one line (a refusal of the text or the key) before any
    integration, writing nothing; a good one reaches the branch (here a stub refusing it in one line)."""
    from nsfem.periodic import scene_branch

    def stub(*args, **kwargs):
        raise NsfemError("--continue: valid (the branch is not computed in this test)")

    real = scene_branch.branch_of_scene
    scene_branch.branch_of_scene = stub
    try:
        _continue_one_line(key, low, high, sep)
    finally:
        scene_branch.branch_of_scene = real


def _continue_one_line(key, low, high, sep) -> None:
    with tempfile.TemporaryDirectory() as d:
        code, out, err = check_invocation([*PERIODIC, "--out", "o", "--continue", f"{key}={low}{sep}{high}"],
                                          Path(d))
        assert code == 2 and "--continue" in err and out == "", err
        assert not (Path(d) / "o").exists()


PERIODIC_REPRODUCTIONS = [
    (["--set", "rotation.speed_hz=0"], "rotation.speed_hz", "nsfem stationary"),
    (["--multiple", "0"], "--multiple", "from 1 to 64"),
    (["--tol", "nan"], "--tol", "must lie in"),
    (["--transient", "-3"], "--transient", "from 0"),
    (["--continue", "rotation.speed_hz=12:12"], "--continue rotation.speed_hz", "same value"),
    (["--continue", "rotation.frame=1:2"], "--continue rotation.frame", "not a number"),
    (["--continue", "rotation.speed_hz=-5:12"], "--continue rotation.speed_hz", "must be >= 0"),
    (["--continue", "mesh.elements=10:14"], "--continue mesh.elements", "coordinates"),
    (["--start", "missing.npz"], "--start", "does not exist"),
    (["--start", "."], "--start", "is a folder"),
    (["--start", "scene.toml"], "--start", "not a results file"),
    (["--start", "scene.toml", "--transient", "5"], "--transient with --start", "one of them"),
    (["--out", "scene.toml"], "--out", "scene.toml"),
]


@pytest.mark.parametrize("extra,names,reason", PERIODIC_REPRODUCTIONS)
def test_issue36_periodic_reproductions(extra, names, reason, tmp_path):
    (tmp_path / "scene.toml").write_text("title = 'not a result'\n")
    code, _, err = check_invocation([*PERIODIC, "--out", "o", *extra], tmp_path)
    line = [x for x in err.splitlines() if x.startswith("nsfem: error:")]
    assert code == 2 and names in line[0] and reason in line[0], err
    assert not (tmp_path / "o").exists()


def test_issue36_periodic_refuses_a_round_ring_before_its_transient(tmp_path, monkeypatch):
    """retainer_drop's rings are round (a turning facet with a state of its own): refused by the shooting's
    map before any integration (the integrator is not called)."""
    from nsfem.integrate import event_driven

    def never(*args, **kwargs):
        raise AssertionError("integrated before refusing")

    monkeypatch.setattr(event_driven.Exact, "run", never)
    code, _, err = check_invocation(["periodic", "retainer_drop", "--out", "o"], tmp_path)
    assert code == 2 and 'shape = "round"' in err and "polygon" in err, err


def test_issue36_periodic_refuses_a_run_up(tmp_path):
    code, _, err = check_invocation(["periodic", "runup", "--out", "o"], tmp_path)
    assert code == 2 and "rotation.ramp_to_hz" in err and "not periodic" in err, err


def test_issue36_periodic_refuses_a_start_of_another_model(saved_result, tmp_path):
    """A results file of the default scene (its reduced coordinates) cannot start the crack scene's orbit."""
    code, _, err = check_invocation([*PERIODIC, "--out", "o", "--start", str(saved_result)], tmp_path)
    assert code == 2 and "--start" in err and "coordinates" in err, err
    assert not (tmp_path / "o").exists()


# --- issue 36: continuation ---
# nsfem.periodic.continuation.continue_branch and critical_vector (library functions, no command yet): a bad
# argument or a residual/stability breaking its contract raises one NsfemError of one line naming it, before
# any continuation; anything else returns a Branch that says why it stopped (never another exception)
from nsfem.periodic.continuation import Branch, continue_branch, critical_vector  # noqa: E402


def _circle36(u, p):
    return np.array([u[0] ** 2 + p ** 2 - 1.0]), np.array([[2.0 * u[0]]]), np.array([2.0 * p])


def _raises36(u, p):
    raise NsfemError("the flow failed\nover two lines")


_RESIDUALS36 = {
    "circle": _circle36,
    "r too long": lambda u, p: (np.zeros(2), np.eye(2), np.zeros(2)),
    "J_u too small": lambda u, p: (np.zeros(1), np.eye(2), np.zeros(1)),
    "pair": lambda u, p: (np.zeros(1), np.eye(1)),
    "nan": lambda u, p: (np.full(1, np.nan), np.eye(1), np.zeros(1)),
    "complex": lambda u, p: (np.zeros(1, complex), np.eye(1), np.zeros(1)),
    "text": lambda u, p: ("r", "J", "p"),
    "raises": _raises36,
    "not callable": 3,
}

CONTINUATION_CASES = [   # (the arguments changed from a valid circle branch, words of the one-line error)
    (dict(u0=[np.nan]), "u0[0]"),
    (dict(u0=[[0.1]]), "1-D"),
    (dict(u0=[]), "non-empty"),
    (dict(u0="abc"), "u0"),
    (dict(p_end=-0.8), "p_end = p0"),
    (dict(p_end=math.inf), "p_end"),
    (dict(p0=-1e308, p_end=1e308), "finite length"),
    (dict(step=0.0), "step"),
    (dict(step=-1.0), "step"),
    (dict(step=1.0, max_step=0.5), "min_step <= step <= max_step"),
    (dict(step=1e-14), "round-off"),
    (dict(locate_tol=1e-20), "locate_tol"),
    (dict(tol=0.0), "tol"),
    (dict(tol="tiny"), "tol"),
    (dict(max_steps=0), "max_steps"),
    (dict(max_steps=2.5), "max_steps"),
    (dict(max_iter=True), "max_iter"),
    (dict(u_scale=0.0), "u_scale"),
    (dict(u_scale=[1.0, 2.0]), "u_scale"),
    (dict(margin=-1.0), "margin"),
    (dict(unit_tol=-1e-6), "unit_tol"),
    (dict(stability=3), "stability"),
    (dict(residual=3), "residual must be callable"),
    (dict(residual=_RESIDUALS36["r too long"]), "r of shape (2,)"),
    (dict(residual=_RESIDUALS36["J_u too small"]), "J_u of shape (2, 2)"),
    (dict(residual=_RESIDUALS36["pair"]), "tuple (r, J_u, J_p)"),
    (dict(residual=_RESIDUALS36["nan"]), "not finite"),
    (dict(residual=_RESIDUALS36["complex"]), "real arrays"),
    (dict(residual=_RESIDUALS36["raises"]), "the flow failed over two lines"),
    (dict(stability=lambda u, p: np.zeros((2, 2))), "1-D array of multipliers"),
]


def _continue36(**changes) -> Branch:
    args = dict(residual=_circle36, u0=[-0.6], p0=-0.8, p_end=0.8, max_steps=4)
    args.update(changes)
    return continue_branch(args.pop("residual"), args.pop("u0"), args.pop("p0"), args.pop("p_end"), **args)


def _one_line36(exc: NsfemError) -> str:
    message = str(exc)
    assert message and "\n" not in message, repr(message)
    return message


@pytest.mark.parametrize("changes, words", CONTINUATION_CASES)
def test_issue36_continuation_refuses_bad_arguments_in_one_line(changes, words):
    with pytest.raises(NsfemError) as info:
        _continue36(**changes)
    message = _one_line36(info.value)
    assert words in message, message


def test_issue36_a_failing_stability_at_the_start_says_so():
    branch = _continue36(stability=_raises36)
    assert branch.stop == "failed" and branch.reason.startswith("at the start: the stability failed")
    assert len(branch.points) == 1 and branch.points[0].converged and branch.points[0].multipliers is None


def test_issue36_a_failing_residual_ends_the_branch_keeping_its_points():
    def fails_late(u, p):
        return _raises36(u, p) if p > 0.0 else _circle36(u, p)

    branch = _continue36(residual=fails_late, max_steps=200)
    assert branch.stop == "failed" and "the flow failed over two lines" in branch.reason
    assert "\n" not in branch.reason and all(pt.converged and pt.p <= 0.0 for pt in branch.points)


_number36 = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-3, 3), st.just("x"))


_HOSTILE36 = {   # each argument's strategy: hostile values mixed with valid ones
    "residual": st.sampled_from(sorted(_RESIDUALS36)).map(_RESIDUALS36.get),
    "u0": st.one_of(st.lists(st.floats(-1.0, 1.0), min_size=1, max_size=1),
                    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=2), st.just([[0.1]])),
    "p0": st.one_of(st.floats(-0.99, 0.99), _number36),
    "p_end": st.one_of(st.floats(-2.0, 2.0), _number36),
    "step": st.one_of(st.none(), st.floats(1e-3, 0.5), _number36),
    "tol": st.one_of(st.floats(1e-12, 1e-6), _number36),
    "max_steps": st.one_of(st.integers(-1, 6), st.floats(0, 4)),
    "u_scale": st.one_of(st.floats(0.1, 10.0), _number36, st.lists(st.floats(), max_size=2)),
    "stability": st.sampled_from([None, "unit", "bad"]).map(
        {None: None, "unit": lambda u, p: np.array([0.5, -2.0 + 0j]), "bad": lambda u, p: "mu"}.get),
}


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data(), keys=st.lists(st.sampled_from(sorted(_HOSTILE36)), max_size=3, unique=True))
def test_issue36_continuation_raises_one_line_or_returns_an_honest_branch(data, keys):
    changes = {key: data.draw(_HOSTILE36[key], label=key) for key in keys}
    try:
        branch = _continue36(**changes)
    except NsfemError as exc:
        assert _one_line36(exc).startswith("continue_branch: "), str(exc)
        return
    assert branch.stop in ("end", "left", "closed", "max_steps", "failed") and branch.reason
    assert "\n" not in branch.reason and len(branch.points) <= changes.get("max_steps", 4) + 1
    # every point but an unconverged start (stop "failed") solves r(u, p) = 0 to tol
    tol, residual = float(changes.get("tol", 1e-9)), changes.get("residual", _circle36)
    for pt in branch.points:
        assert pt.converged or (branch.stop == "failed" and len(branch.points) == 1)
        if pt.converged:
            assert np.max(np.abs(residual(pt.u, pt.p)[0])) <= tol


@pytest.mark.parametrize("matrix, target, words", [
    ([[1.0, 2.0]], -1.0, "square"),
    ([], -1.0, "square"),
    ([[np.nan]], -1.0, "finite"),
    ([[1.0]], np.inf, "finite"),
    ([["a"]], -1.0, "numbers"),
])
def test_issue36_critical_vector_refuses_bad_matrices_in_one_line(matrix, target, words):
    with pytest.raises(NsfemError) as info:
        critical_vector(matrix, target)
    assert words in _one_line36(info.value)


# --- issue 36: continue/steady ---
# nsfem periodic --continue refuses, in one line naming the option or key and before any orbit is computed: a bad
# --steps or --step, --steps/--step without --continue, a key of the mesh or the reduction (they change the
# coordinates), a key that does not shape the orbit, speeds at or below 0 or beyond the model's limit; nsfem sweep
# --steady periodic refuses another --steady, an integrator other than exact, a run-up and a rotor at rest.
CONTINUE36 = ["periodic", "critical_speed", "--set", "mesh.elements=10", "--set", "reduction.modes=16",
              "--set", "output.plots=[]", "--out", "o"]


@pytest.fixture
def no_branch36(monkeypatch):
    """The branch must not be reached: any call fails the test."""
    from nsfem.periodic import scene_branch

    def never(*args, **kwargs):
        raise AssertionError("the branch was computed before the refusal")

    monkeypatch.setattr(scene_branch, "branch_of_scene", never)


@settings(max_examples=15, deadline=None, suppress_health_check=list(HealthCheck))
@given(option=st.sampled_from(["--steps", "--step"]),
       value=st.one_of(st.integers(-10**6, 0), st.integers(10**4 + 1, 10**9),
                       st.floats(allow_nan=True, allow_infinity=True).filter(lambda x: not 0 < x <= 10),
                       st.text(max_size=6).filter(lambda s: not _a_number(s))))
def test_issue36_continue_options_out_of_range_are_refused_by_name(no_branch36, option, value):
    if option == "--step" and isinstance(value, int) and 0 < value <= 10:
        value = 0
    with tempfile.TemporaryDirectory() as d:
        code, out, err = check_invocation([*CONTINUE36, "--continue", "rotation.speed_hz=20:30", option, str(value)],
                                          Path(d))
        assert code == 2 and option in err and out == "", (option, value, err)
        assert not (Path(d) / "o").exists()


CONTINUE36_REPRODUCTIONS = [
    (["--steps", "5"], "--steps", "option of --continue"),
    (["--step", "0.5"], "--step", "option of --continue"),
    (["--continue", "rotation.speed_hz=20:30", "--step", "20"], "--step", "at most the range's length 10"),
    (["--continue", "rotation.speed_hz=20:30", "--steps", "2.5"], "--steps", "invalid int"),
    (["--continue", "reduction.modes=10:20"], "--continue reduction.modes", "coordinates"),
    (["--continue", "simulation.t_end=1:2"], "--continue simulation.t_end", "does not shape"),
    (["--continue", "rotation.speed_hz=0:20"], "--continue rotation.speed_hz", "> 0 Hz"),
    (["--continue", "rotation.speed_hz=20:1e9"], "rotation.speed_hz", "bar wave speed"),
    (["--continue", "disk.3.mass=1:2"], "--continue disk.3.mass", "no disk.3"),
]


@pytest.mark.parametrize("extra,names,reason", CONTINUE36_REPRODUCTIONS)
def test_issue36_continue_reproductions(no_branch36, extra, names, reason, tmp_path):
    code, out, err = check_invocation([*CONTINUE36, *extra], tmp_path)
    line = [x for x in err.splitlines() if x.startswith("nsfem: error:")]
    assert code == 2 and names in line[0] and reason in line[0] and out == "", err
    assert not (tmp_path / "o").exists()


STEADY36 = ["sweep", "critical_speed", "--set", "mesh.elements=10", "--set", "reduction.modes=16", "--out", "s"]
STEADY36_REPRODUCTIONS = [
    (["--set", "rotation.speed_hz=20:30:2", "--steady", "harmonic"], "--steady", "invalid choice"),
    (["--set", "rotation.speed_hz=20:30:2", "--steady", "periodic", "--method", "rk"], "--method rk",
     "exact flow"),
    (["--set", "rotation.speed_hz=0:30:2", "--steady", "periodic"], "rotation.speed_hz", "at rest"),
    (["--set", "rotation.speed_hz=20:30:2", "--set", "rotation.ramp_to_hz=40", "--set", "rotation.ramp_s=1",
      "--steady", "periodic"], "rotation.ramp_to_hz", "not periodic"),
]


@pytest.mark.parametrize("extra,names,reason", STEADY36_REPRODUCTIONS)
def test_issue36_sweep_steady_reproductions(extra, names, reason, tmp_path, monkeypatch):
    import nsfem.sweep as sweep

    def never(*args, **kwargs):
        raise AssertionError("a value was computed before the refusal")

    monkeypatch.setattr(sweep, "orbit_point", never)
    monkeypatch.setattr(sweep, "run_point", never)
    code, out, err = check_invocation([*STEADY36, *extra], tmp_path)
    line = [x for x in err.splitlines() if x.startswith("nsfem: error:")]
    assert code == 2 and names in line[0] and reason in line[0], err
    assert not (tmp_path / "s").exists()


@settings(max_examples=10, deadline=None, suppress_health_check=list(HealthCheck))
@given(steady=st.text(min_size=1, max_size=8).filter(lambda s: s not in ("transient", "periodic")),
       method=st.sampled_from(["rk", "penalty", "moreau"]))
def test_issue36_sweep_steady_is_refused_by_name_unless_known(steady, method):
    """An unknown --steady, or --steady periodic with an integrator other than exact: one line naming the option,
    before anything runs (the sweep folder is not created)."""
    with tempfile.TemporaryDirectory() as d:
        for extra, name in ((["--steady", steady], "--steady"), (["--steady", "periodic", "--method", method],
                                                                  f"--method {method}")):
            code, _, err = check_invocation([*STEADY36, "--set", "rotation.speed_hz=20:30:2", *extra], Path(d))
            assert code == 2 and name in err, (extra, err)
            assert not (Path(d) / "s").exists()


# --- issue 36: periodic orbits (shooting, orbit branches) ---
# nsfem.periodic.periodic_orbit and orbit_branch (library functions): a bad argument raises one NsfemError of one
# line naming it before any flow is integrated (was: TypeError, ValueError, OverflowError tracebacks from int() and
# math.isfinite of None, NaN, inf or text); anything else returns an orbit (converged or said not to be)
from nsfem.integrate.problem import ContactSystem as _System36  # noqa: E402
from nsfem.periodic import orbit_branch as _orbit_branch36  # noqa: E402
from nsfem.periodic import periodic_orbit as _periodic_orbit36  # noqa: E402


def _forced36(w: float = 7.0):
    """Two masses on springs, forced at w: no contact, the orbit is the harmonic solution (one Newton step)."""
    K = np.array([[3.0, -1.0], [-1.0, 2.0]]) * 100.0
    return _System36.from_arrays(M=np.diag([1.0, 2.0]), Q=K, C=0.02 * K, fc=[1.0, 0.0], fs=[0.0, 0.5], omega=w)


_T36 = 2 * math.pi / 7.0

PERIODIC_CASES = [
    ({"max_iter": None}, "max_iter"), ({"max_iter": "3"}, "max_iter"), ({"max_iter": math.nan}, "max_iter"),
    ({"max_iter": 2.5}, "max_iter"), ({"attempts": math.nan}, "attempts"), ({"attempts": 0}, "attempts"),
    ({"settle_periods": math.inf}, "settle_periods"), ({"settle_periods": -1}, "settle_periods"),
    ({"t0": "a"}, "t0"), ({"t0": None}, "t0"), ({"t0": math.inf}, "t0"),
    ({"tol": None}, "tol"), ({"tol": "1e-9"}, "tol"), ({"tol": 0.1}, "tol"),
    ({"q0": "ab"}, "starting state"), ({"v0": [1j, 0.0]}, "starting state"), ({"q0": [[0.0, 0.0]]}, "starting state"),
    ({"output_dt": 0.0}, "output_dt"), ({"output_dt": math.nan}, "output_dt"), ({"output_dt": 10 * _T36}, "output_dt"),
    ({"period_s": None}, "period"), ({"period_s": "1"}, "period"), ({"period_s": True}, "period"),
    ({"period_s": 1.0}, "not a multiple of the forcing period"),
]


@pytest.mark.parametrize("changes, words", PERIODIC_CASES)
def test_issue36_periodic_orbit_refuses_bad_arguments_in_one_line(changes, words):
    with pytest.raises(NsfemError) as info:
        _periodic_orbit36(_forced36(), **{"period_s": _T36, **changes})
    message = _one_line36(info.value)
    assert message.startswith("periodic: ") and words in message, message


BRANCH_CASES = [
    ({"p0": "7"}, "range"), ({"p_end": None}, "range"), ({"p_end": 7.0}, "range"), ({"p_end": math.nan}, "range"),
    ({"depth": "x"}, "depth"), ({"depth": -1}, "depth"), ({"multiple": 1.5}, "multiple"), ({"multiple": 0}, "multiple"),
    ({"t0": math.nan}, "t0"), ({"system_at": 3}, "functions"),
    ({"period_at": lambda w: 1.0 / w}, "not a multiple of the forcing period"),
]


@pytest.mark.parametrize("changes, words", BRANCH_CASES)
def test_issue36_orbit_branch_refuses_bad_arguments_in_one_line(changes, words):
    args = {"system_at": _forced36, "period_at": lambda w: 2 * math.pi / w, "q0": [0.0, 0.0], "v0": [0.0, 0.0],
            "p0": 7.0, "p_end": 7.5, **changes}
    with pytest.raises(NsfemError) as info:
        _orbit_branch36(**args)
    message = _one_line36(info.value)
    assert message.startswith("periodic: ") and words in message, message


_JUNK36 = st.one_of(st.none(), st.booleans(), st.text(max_size=3), st.integers(-3, 40),
                    st.floats(allow_nan=True, allow_infinity=True), st.lists(st.floats(-1.0, 1.0), max_size=3))


@settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data(), keys=st.lists(st.sampled_from(["period_s", "t0", "tol", "max_iter", "attempts",
                                                      "settle_periods", "output_dt", "q0", "v0"]),
                                     min_size=1, max_size=3, unique=True))
def test_issue36_periodic_orbit_raises_one_line_or_returns_an_orbit(data, keys):
    """Property: whatever junk the arguments get, one NsfemError of one line or an orbit whose converged flag
    is its residual's verdict (no other exception)."""
    changes = {key: data.draw(_JUNK36, label=key) for key in keys}
    args = {"period_s": _T36, **changes}
    try:
        orbit = _periodic_orbit36(_forced36(), **args)
    except NsfemError as exc:
        _one_line36(exc)
        return
    assert orbit.converged == (orbit.residual <= float(args.get("tol", 1e-9)))


FLOW_CASES = [
    ((0.0, None, None, "1"), {}, "period"), ((None, None, None, _T36), {}, "t0"),
    ((0.0, "ab", None, _T36), {}, "starting state"), ((0.0, None, None, _T36), {"output_dt": "x"}, "output_dt"),
    ((0.0, None, None, _T36), {"output_dt": 2 * _T36}, "output_dt"), ((0.0, None, None, _T36), {"zeno": None}, "zeno"),
    ((0.0, None, None, math.inf), {}, "period"),
]


@pytest.mark.parametrize("args, kwargs, words", FLOW_CASES)
def test_issue36_flow_refuses_bad_arguments_in_one_line(args, kwargs, words):
    from nsfem.periodic import flow

    with pytest.raises(NsfemError) as info:
        flow(_forced36(), *args, **kwargs)
    message = _one_line36(info.value)
    assert message.startswith("periodic: ") and words in message, message


@pytest.mark.parametrize("multipliers, tol, words", [
    ([0.5], -1.0, "tol"), ([0.5], math.nan, "tol"), ([0.5], None, "tol"), ([0.5], 2.0, "tol"),
    (["a"], 1e-6, "numbers"), ([math.inf], 1e-6, "not finite"),
])
def test_issue36_classify_refuses_bad_arguments_in_one_line(multipliers, tol, words):
    from nsfem.periodic import classify

    with pytest.raises(NsfemError) as info:
        classify(multipliers, tol)
    message = _one_line36(info.value)
    assert message.startswith("periodic: ") and words in message, message


# --- issue 36: review2 (periodic command) ---
# nsfem periodic --start takes a run's result.npz or an orbit.npz; a branch.npz (section states of several
# orbits, (points, n)) is refused as what it is, not as a state "of points x n coordinates" of another model.


@settings(max_examples=10, deadline=None, suppress_health_check=list(HealthCheck))
@given(points=st.integers(1, 4))
def test_issue36_review2_a_branch_file_is_no_start(tmp_path_factory, points):
    root = tmp_path_factory.mktemp("start")
    n = 40   # critical_speed with the shipped mesh and reduction: any n, the file is refused for its shape
    np.savez(root / "branch.npz", q0=np.zeros((points, n)), v0=np.zeros((points, n)), t0=np.array(0.0),
             value=np.arange(points, dtype=float))
    code, _, err = check_invocation(["periodic", "critical_speed", "--start", "branch.npz", "--out", "o"], root)
    assert code == cli.EXIT_ERROR and "branch" in err and "orbit.npz" in err, err
    assert not (root / "o").exists()


# --- issue 36: rub whirl study (studies/rub_whirl.py's options) ---
def _rub_whirl_main():
    studies = str(Path(__file__).resolve().parents[1] / "studies")
    if studies not in sys.path:
        sys.path.insert(0, studies)
    import rub_whirl

    return rub_whirl.main


def _refused_in_one_line(argv, capsys) -> str:
    """The study's main(argv) exits 2 with one 'error:' line (argparse's), before any computation."""
    with pytest.raises(SystemExit) as exc:
        _rub_whirl_main()(argv)
    assert exc.value.code == 2
    err = [line for line in capsys.readouterr().err.splitlines() if "error:" in line]
    assert len(err) == 1
    return err[0]


@pytest.mark.parametrize("argv", [["--mu", "nan"], ["--mu", "0"], ["--speeds", "30:20"], ["--speeds", "a"],
                                  ["--onset-range", "10:27"], ["--facets", "4"], ["--transient-hz", "inf"],
                                  ["--periods", "2"]])
def test_issue36_rub_whirl_study_refuses_bad_options(argv, capsys):
    assert argv[0] in _refused_in_one_line(argv, capsys)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(low=st.floats(allow_nan=True, allow_infinity=True), high=st.floats(allow_nan=True, allow_infinity=True))
def test_issue36_rub_whirl_study_refuses_every_bad_speed_range(low, high, capsys):
    """Property: a --speeds range outside 16 <= LOW < HIGH <= 60 Hz (or not finite) is refused naming --speeds."""
    if math.isfinite(low) and math.isfinite(high) and 16.0 <= low < high <= 60.0:
        return
    assert "--speeds" in _refused_in_one_line(["--speeds", f"{low!r}:{high!r}"], capsys)


# --- issue 36: continuation on Dask ---
# nsfem periodic --continue --workers N | --scheduler ADDRESS refuses, in one line naming the option and before any
# orbit is computed (and before a local cluster starts): --workers outside 1..4 per core, --workers with
# --scheduler, either without --continue (a single orbit is one computation), an empty address, and an address
# where no Dask scheduler answers (the orbit not started: checked by failing the test if it is).
@pytest.fixture
def no_orbit36(monkeypatch):
    """Neither the branch's start orbit nor a local cluster may be reached: any call fails the test."""
    from nsfem import sweep
    from nsfem.periodic import scene

    def never(*args, **kwargs):
        raise AssertionError("computed (or started a cluster) before the refusal")

    monkeypatch.setattr(scene, "orbit_of_scene", never)
    monkeypatch.setattr(sweep, "LocalCluster", never, raising=False)
    import distributed

    monkeypatch.setattr(distributed, "LocalCluster", never)


DASK36_REPRODUCTIONS = [
    (["--continue", "rotation.speed_hz=25:27", "--workers", "0"], "--workers", "positive integer, got 0"),
    (["--continue", "rotation.speed_hz=25:27", "--workers", "-3"], "--workers", "positive integer, got -3"),
    (["--continue", "rotation.speed_hz=25:27", "--workers", "100000"], "--workers 100000", "per core"),
    (["--continue", "rotation.speed_hz=25:27", "--workers", "x"], "--workers", "invalid int"),
    (["--continue", "rotation.speed_hz=25:27", "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "--workers",
     "cannot be combined with --scheduler"),
    (["--workers", "2"], "--workers", "option of --continue"),
    (["--workers", "1"], "--workers", "option of --continue"),
    (["--scheduler", "tcp://127.0.0.1:1"], "--scheduler", "option of --continue"),
    (["--continue", "rotation.speed_hz=25:27", "--scheduler", ""], "--scheduler", "an address"),
    (["--continue", "rotation.speed_hz=25:27", "--scheduler", "nonsense"], "--scheduler nonsense",
     "cannot connect to a Dask scheduler"),
]


@pytest.mark.parametrize("extra,names,reason", DASK36_REPRODUCTIONS)
def test_issue36_dask_continue_reproductions(no_orbit36, extra, names, reason, tmp_path):
    code, out, err = check_invocation([*CONTINUE36, *extra], tmp_path)
    line = [x for x in err.splitlines() if x.startswith("nsfem: error:")]
    assert code == 2 and names in line[0] and reason in line[0] and out == "", err
    assert not (tmp_path / "o").exists()


@settings(max_examples=15, deadline=None, suppress_health_check=list(HealthCheck))
@given(workers=st.one_of(st.integers(-10**6, 0), st.integers(4 * (os.cpu_count() or 1) + 1, 10**9)),
       continued=st.booleans())
def test_issue36_dask_workers_out_of_range_are_refused_by_name(no_orbit36, workers, continued):
    """Property: a --workers below 1 or above 4 per core, or any --workers without --continue, is refused naming
    --workers, before anything is computed or started."""
    extra = ["--continue", "rotation.speed_hz=25:27"] if continued else []
    with tempfile.TemporaryDirectory() as d:
        code, out, err = check_invocation([*CONTINUE36, *extra, "--workers", str(workers)], Path(d))
        assert code == 2 and "--workers" in err and out == "", (workers, err)
        assert not (Path(d) / "o").exists()


@pytest.mark.parametrize("kwargs,words", [
    ({"client": object()}, "client must be a distributed.Client"),
    ({"workers": True}, "--workers must be a positive integer"),
    ({"workers": 2.5}, "--workers must be a positive integer"),
    ({"workers": 0}, "--workers must be a positive integer"),
    ({"workers": 2, "scheduler": "tcp://127.0.0.1:1"}, "cannot be combined with --scheduler"),
    ({"scheduler": 7}, "--scheduler must be an address"),
], ids=["client-not-a-client", "workers-bool", "workers-float", "workers-zero", "workers-and-scheduler",
        "scheduler-not-text"])
def test_issue36_dask_branch_of_scene_refuses_bad_cluster_arguments(no_orbit36, kwargs, words):
    """The Python API (branch_of_scene) refuses bad cluster arguments with one line, before any orbit."""
    from nsfem import load_scene
    from nsfem.errors import NsfemError
    from nsfem.periodic.scene_branch import branch_of_scene

    with pytest.raises(NsfemError, match=words) as exc:
        branch_of_scene(load_scene("critical_speed"), "rotation.speed_hz", 25.0, 27.0, **kwargs)
    assert "\n" not in str(exc.value)


def test_issue36_dask_a_cluster_failure_is_one_line_a_task_error_is_the_serial_ones():
    """A task's result: a cluster's failure (here a closed connection) becomes one line naming the side; the
    task's own NsfemError stays itself; an error of ours (a bug) is not dressed up as the cluster's."""
    from distributed.comm import CommClosedError

    from nsfem.errors import NsfemError
    from nsfem.periodic.branch_cluster import _result

    class Failed:
        def __init__(self, exc):
            self.exc = exc

        def result(self):
            raise self.exc

    with pytest.raises(NsfemError, match="the Dask cluster failed on the branch towards 27 .*CommClosedError"):
        _result(Failed(CommClosedError("in <TCP (closed)>: Stream is closed\nmore")), 27.0)
    with pytest.raises(NsfemError, match="^periodic: no orbit"):
        _result(Failed(NsfemError("periodic: no orbit")), 27.0)
    with pytest.raises(ZeroDivisionError):
        _result(Failed(ZeroDivisionError("a bug")), 27.0)


# --- issue 36: rub backward whirl study (studies/rub_backward_whirl.py's options) ---
def _study_refusal(study: str, argv, capsys) -> str:
    """studies/<study>.py's main(argv) exits 2 with one 'error:' line, before any long computation."""
    import importlib

    studies = str(Path(__file__).resolve().parents[1] / "studies")
    if studies not in sys.path:
        sys.path.insert(0, studies)
    with pytest.raises(SystemExit) as exc:
        importlib.import_module(study).main(argv)
    assert exc.value.code == 2
    err = [line for line in capsys.readouterr().err.splitlines() if "error:" in line]
    assert len(err) == 1
    return err[0]


def _backward_whirl_refusal(argv, capsys) -> str:
    return _study_refusal("rub_backward_whirl", argv, capsys)


@pytest.mark.parametrize("argv", [["--mu", "nan"], ["--mu", "0"], ["--mu", "-0.1"], ["--stiffness", "inf"],
                                  ["--stiffness", "10"], ["--facets", "4"], ["--periods", "2"], ["--steps", "0"],
                                  ["--transient-hz", "nan"], ["--transient-hz", "100"]])
def test_issue36_backward_whirl_study_refuses_bad_options(argv, capsys):
    assert argv[0].lstrip("-").split("-")[0] in _backward_whirl_refusal(argv, capsys)


def test_issue36_backward_whirl_study_refuses_a_friction_without_onset(capsys):
    """mu = 0.1 on the 2e6 N/m ring is unstable from the rub's start (closed form: above mu = 0.0400): no onset for the
    exact flow to check; the transient's speed must lie past the onset (20.669 Hz at mu = 0.03)."""
    assert "--mu 0.1" in _backward_whirl_refusal(["--mu", "0.1"], capsys)
    assert "past the onset" in _backward_whirl_refusal(["--transient-hz", "19"], capsys)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(k_s=st.floats(allow_nan=True, allow_infinity=True))
def test_issue36_backward_whirl_study_refuses_every_bad_stiffness(k_s, capsys):
    """Property: a --stiffness outside [1e5, 1e8] N/m (or not finite) is refused naming --stiffness."""
    if math.isfinite(k_s) and 1e5 <= k_s <= 1e8:
        return
    assert "--stiffness" in _backward_whirl_refusal(["--stiffness", repr(k_s)], capsys)


# --- issue 36: a branch's section moves (continue_branch's reanchor) ---
# a reanchor that is not callable, or returns the wrong shapes, is refused in one line naming it; one that fails
# ends the branch with a one-line reason, keeping its points (never another exception)

@pytest.mark.parametrize("reanchor, words", [
    (3, "reanchor must be callable"),
    (lambda u, p, forced: (np.zeros(2), None), "reanchor returned u of shape (2,)"),
    (lambda u, p, forced: (u, np.eye(2)), "M of shape (2, 2)"),
    (lambda u, p, forced: "moved", "reanchor(u, p, forced) must return None or (u_new, M or None)"),
])
def test_issue36_reanchor_breaking_its_contract_is_refused_in_one_line(reanchor, words):
    with pytest.raises(NsfemError) as info:
        _continue36(reanchor=reanchor)
    message = _one_line36(info.value)
    assert words in message, message


def test_issue36_a_failing_reanchor_ends_the_branch_keeping_its_points():
    def fails(u, p, forced):
        raise NsfemError("the section's flow failed\nover two lines")

    branch = _continue36(reanchor=fails)
    assert branch.stop == "failed" and "the section's flow failed over two lines" in branch.reason
    # (the coordinates are asked at the start already: the branch ends there, with its start point)
    assert "\n" not in branch.reason and branch.reason.startswith("at the start")
    assert len(branch.points) == 1 and all(pt.converged for pt in branch.points)


@settings(max_examples=40, deadline=None, derandomize=True, database=None)
@given(values=st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-2.0, 2.0)),
                       min_size=1, max_size=3),
       forced_only=st.booleans())
def test_issue36_any_reanchor_output_is_a_branch_or_one_line(values, forced_only):
    """Property: whatever state a reanchor returns (non-finite, off the branch, a shape), the continuation gives a
    Branch whose reason is one line, or one NsfemError of one line."""
    def reanchor(u, p, forced):
        if forced_only and not forced:
            return None
        return np.array(values), None

    try:
        branch = _continue36(reanchor=reanchor)
    except NsfemError as exc:
        _one_line36(exc)
        return
    assert "\n" not in branch.reason and branch.points and all(pt.converged for pt in branch.points)


# --- issue 36: review (reanchor's du_new/dp) ---
# a reanchor may return the new state's derivative in p as a third element (it orients the new tangent); one of the
# wrong shape, or not numbers, is refused in one line naming it; a non-finite one ends the branch in one line

@pytest.mark.parametrize("dudp, words", [
    (np.zeros(2), "du_new/dp of shape (2,)"),
    ("steep", "must return None or (u_new, M or None) or (u_new, M or None, du_new/dp or None)"),
])
def test_issue36_review_a_reanchor_derivative_of_the_wrong_shape_is_refused(dudp, words):
    with pytest.raises(NsfemError) as info:
        _continue36(reanchor=lambda u, p, forced: (u, None, dudp))
    message = _one_line36(info.value)
    assert words in message, message


def test_issue36_review_a_non_finite_reanchor_derivative_ends_the_branch_in_one_line():
    branch = _continue36(reanchor=lambda u, p, forced: (u, None, np.array([np.nan])))
    assert branch.stop == "failed" and "not finite" in branch.reason and "\n" not in branch.reason
    assert len(branch.points) == 1 and all(pt.converged for pt in branch.points)   # (asked at the start)


# --- issue 36: review (studies/delamination_resonance.py's options) ---
def _delamination_refusal(argv, capsys) -> str:
    return _study_refusal("delamination_resonance", argv, capsys)


@pytest.mark.parametrize("argv", [
    ["--touching", "--beta", "inf"], ["--touching", "--beta", "nan"], ["--touching", "--step", "inf"],
    ["--touching", "--touch-speed", "nan"], ["--touching", "--lead-speed", "-5"],
    ["--touching", "--open-speeds", "22.9:22.7:3"], ["--touching", "--open-speeds", "22.7:22.9"],
    ["--touching", "--contraction-periods", "0"], ["--alphas", "nan"], ["--alphas", "2", "0"],
    ["--speeds", "a:b:3"], ["--speeds", "22.5:23:0"], ["--budget", "-1"], ["--max-iter", "0"],
])
def test_issue36_review_delamination_study_refuses_bad_options(argv, capsys):
    # (before the fix: tracebacks from the scene (inf/nan/negative), or the study running on: --step inf, reversed
    # --open-speeds)
    words = [a for a in argv if a.startswith("--") and a != "--touching"][0]
    assert words in _delamination_refusal(argv, capsys)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(beta=st.floats(allow_nan=True, allow_infinity=True))
def test_issue36_review_delamination_study_refuses_every_bad_beta(beta, capsys):
    """Property: a --beta that is not a finite number > 0 is refused naming --beta."""
    if math.isfinite(beta) and beta > 0:
        return
    assert "--beta" in _delamination_refusal(["--touching", "--beta", repr(beta)], capsys)


# --- issue 36: continuation across grazing points (the events / invariant / solve hooks) ---
# A hook that is no function is refused by name; one that breaks its contract (wrong types, shapes) raises one
# NsfemError of one line naming it; one that fails or gives non-finite or negative values ends the branch with a
# one-line reason (or is skipped: solve); never another exception.
def _kink36(u, p):
    low = u[0] < 0.3
    return np.array([u[0] - (p if low else 0.3 + 4 * (p - 0.3))]), np.eye(1), np.array([-1.0 if low else -4.0])


def _graze_hooks36():
    def fails(u, p):
        raise NsfemError("the hook failed\non two lines")

    return {
        "events": [lambda u, p: 3.0, lambda u, p: ([1], 0.5), lambda u, p: ("a", "x"), lambda u, p: ("a", math.nan),
                   lambda u, p: ("a", -1.0), lambda u, p: ("a", math.inf), fails, lambda u, p: None,
                   lambda u, p: (u[0] < 0.3, abs(u[0] - 0.3))],
        "invariant": [lambda u, p: "x", lambda u, p: np.array([math.nan]), lambda u, p: np.ones((2, 2)), fails,
                      lambda u, p: np.array([u[0]])],
        "solve": [lambda u, p: None, lambda u, p: np.ones(3), lambda u, p: np.array([math.nan]), fails,
                  lambda u, p: "x"],
    }


@pytest.mark.parametrize("name", ["events", "invariant", "solve"])
@pytest.mark.parametrize("value", [3, "f", [1.0]])
def test_issue36_grazing_hooks_that_are_not_functions_are_refused_by_name(name, value):
    with pytest.raises(NsfemError, match=f"{name} must be callable") as info:
        continue_branch(_kink36, [0.0], 0.0, 1.0, **{name: value})
    assert "\n" not in str(info.value)


@settings(max_examples=40, deadline=None)
@given(events=st.integers(0, 8), invariant=st.integers(0, 4), solve=st.integers(0, 4),
       step=st.floats(1e-3, 0.3))
def test_issue36_hostile_grazing_hooks_end_the_branch_with_one_line(events, invariant, solve, step):
    """Property: any mix of hostile hooks gives a Branch whose reason is one line, or one NsfemError of one line."""
    hooks = _graze_hooks36()
    try:
        branch = continue_branch(_kink36, [0.0], 0.0, 1.0, step=step, max_steps=40, events=hooks["events"][events],
                                 invariant=hooks["invariant"][invariant], solve=hooks["solve"][solve])
    except NsfemError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("continue_branch:")
        return
    assert isinstance(branch, Branch) and "\n" not in branch.reason
    assert branch.stop in ("end", "left", "closed", "max_steps", "failed")


def test_issue36_hostile_events_reproductions():
    hooks = _graze_hooks36()
    # a non-tuple, an unhashable structure, a margin that is no number: the hook's contract, one line
    for k in (0, 1, 2, 7):
        with pytest.raises(NsfemError, match=r"events\(u, p\) must return"):
            continue_branch(_kink36, [0.0], 0.0, 1.0, events=hooks["events"][k])
    # a NaN or negative margin, a failing hook: the branch ends at the start, saying why on one line
    for k in (3, 4, 6):
        branch = continue_branch(_kink36, [0.0], 0.0, 1.0, events=hooks["events"][k])
        assert branch.stop == "failed" and "\n" not in branch.reason and len(branch.points) == 1
    # a margin of inf (nothing grazes) is allowed: the branch runs to its end
    assert continue_branch(_kink36, [0.0], 0.0, 1.0, events=hooks["events"][5]).stop == "end"


# --- issue 36: crack's orbit faster (studies/periodic.py's options) ---
@pytest.mark.parametrize("argv", [["--accuracy", "nan"], ["--accuracy", "0"], ["--accuracy", "1e-4", "0.5"],
                                  ["--accuracy", "inf"], ["--lead", "-1"], ["--repeat", "0"], ["--max-periods", "0"],
                                  ["--section", "middle"], ["--scenes", "nope"]])
def test_issue36_periodic_study_refuses_bad_options(argv, capsys):
    # (before: nan/0/0.5 ran the study into periodic_orbit's tol refusal or a traceback after the reference orbit,
    # --repeat 0 ended in min() of nothing, --lead -1 ran no lead silently)
    assert argv[0] in _study_refusal("periodic", argv, capsys)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(accuracy=st.floats(allow_nan=True, allow_infinity=True))
def test_issue36_periodic_study_refuses_every_bad_accuracy(accuracy, capsys):
    """Property: an --accuracy that is not a finite number in (0, 0.1) is refused naming --accuracy."""
    if math.isfinite(accuracy) and 0.0 < accuracy < 0.1:
        return
    assert "--accuracy" in _study_refusal("periodic", ["--accuracy", repr(accuracy)], capsys)


# --- issue 36: delamination variants study (studies/delamination_variants.py's options) ---
@pytest.mark.parametrize("argv", [["--mu", "nan"], ["--mu", "-0.1"], ["--beta", "0"], ["--beta", "inf"],
                                  ["--step", "-1"], ["--fine", "nan"], ["--fine", "0.01"], ["--touch-speed", "0"],
                                  ["--speeds", "22.9:22.7:5"], ["--speeds", "a:b:c"], ["--max-iter", "0"],
                                  ["--periods", "0"], ["--settle", "-1"], ["--start", "/nonexistent/orbit.npz"],
                                  ["--gravity", "0"], ["--gravity", "nan"], ["--gravity", "1e9"],
                                  ["--fold-range", "22.84:22.78"], ["--fold-range", "x"], ["--fold-steps", "0"],
                                  ["--fold-start-speed", "-1"]])
def test_issue36_delamination_variants_study_refuses_bad_options(argv, capsys):
    assert argv[0].lstrip("-").split("-")[0] in _study_refusal("delamination_variants", argv, capsys)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(mu=st.floats(allow_nan=True, allow_infinity=True))
def test_issue36_delamination_variants_study_refuses_every_bad_friction(mu, capsys):
    """Property: a --mu that is not a finite number >= 0 is refused naming --mu (before any model is built)."""
    if math.isfinite(mu) and mu >= 0:
        return
    assert "--mu" in _study_refusal("delamination_variants", ["--mu", repr(mu)], capsys)


# --- issue 36: review of the delaminated shaft's fold study (studies/delamination_variants.py --fold) ---
@pytest.mark.parametrize("argv", [["--fold", "--fold-start-speed", "22.7"],
                                  ["--fold", "--fold-start-speed", "22.9"],
                                  ["--fold", "--fold-range", "22.81:22.84"]])
def test_issue36_fold_study_refuses_a_start_speed_it_cannot_reach(argv, capsys):
    # (before: a --fold-start-speed below the start orbit's 22.78 Hz ran 40 revolutions and the shooting, then ended
    # in an IndexError traceback (no speed to walk to); one outside --fold-range ran the walk, then the continuation
    # started from the range's end instead of the orbit walked to)
    assert "--fold-start-speed" in _study_refusal("delamination_variants", argv, capsys)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(speed=st.floats(min_value=0.1, max_value=100.0))
def test_issue36_fold_study_refuses_every_start_speed_off_its_walk(speed, capsys):
    """Property: with --fold, a --fold-start-speed below the stored start orbit's speed (22.78 Hz) or outside
    --fold-range (22.72:22.84) is refused naming it, before any model is built."""
    if 22.78 <= speed and 22.72 < speed < 22.84:
        return
    assert "--fold-start-speed" in _study_refusal("delamination_variants", ["--fold", "--fold-start-speed",
                                                                            repr(speed)], capsys)


# --- issue 36: delamination variants study, the unstable branch at 2 g (--unstable) ---
@pytest.mark.parametrize("argv, named", [(["--unstable-range", "22.83:22.805"], "--unstable-range"),
                                         (["--unstable-range", "x"], "--unstable-range"),
                                         (["--unstable-range", "nan:22.83"], "--unstable-range"),
                                         (["--unstable", "--fold"], "--fold and --unstable")])
def test_issue36_delamination_unstable_study_refuses_bad_options(argv, named, capsys):
    assert named in _study_refusal("delamination_variants", argv, capsys)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lo=st.floats(allow_nan=True, allow_infinity=True), hi=st.floats(allow_nan=True, allow_infinity=True))
def test_issue36_delamination_unstable_study_refuses_every_bad_range(lo, hi, capsys):
    """Property: an --unstable-range that is not finite speeds 0 < LOW < HIGH is refused naming it (before any
    flow)."""
    if math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi:
        return
    assert "--unstable-range" in _study_refusal("delamination_variants", ["--unstable-range", f"{lo!r}:{hi!r}"],
                                                capsys)
