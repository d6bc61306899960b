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


# --- issue 32: output folders (signals during writes, one run per folder, bounded files) ---
import json  # noqa: E402
import re  # noqa: E402
import signal  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from nsfem.atomic import write_text_atomic  # noqa: E402
from nsfem.outdir import FIT_FILES, LOCK, MANIFEST, claim  # noqa: E402

#: a tiny cracked rotor (4 VTU files a frame), a few hundredths of a second per output
TINY = ["crack", "--set", "mesh.elements=10"]


def folder_is_valid(out: Path, foreign=()) -> list[str]:
    """The files of a folder a run left; asserts the property: no temporary file, a .pvd that
    indexes exactly the VTU frames there (each one parsing; ``foreign``: a user's files), a
    result.npz that loads."""
    import meshio

    names = sorted(p.name for p in out.iterdir()) if out.exists() else []
    assert not [n for n in names if n.endswith(".tmp") or n.startswith(".nsfem-probe")], names
    assert LOCK not in names, names  # released and removed
    frames = {n for n in names if n.endswith(".vtu")} - set(foreign)
    if "nsfem.pvd" in names:
        indexed = re.findall(r'file="([^"]+)"', (out / "nsfem.pvd").read_text())
        assert set(indexed) == frames and len(indexed) == len(frames), (sorted(frames - set(indexed)), indexed)
        for f in indexed[-4:]:
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
    return lambda p: any(out.glob(pattern))


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


def check_interrupted(code: int, err: str, out: Path) -> list[str]:
    """Exit 130 (the project's Ctrl-C status, SIGTERM too) with one line, no traceback; a valid folder.
    (Every trigger comes well before the command's end: a run that ended first fails the test.)"""
    assert code == 130, err
    assert "Traceback" not in err, err
    assert len([line for line in err.splitlines() if line.startswith("nsfem: interrupted")]) == 1, err
    return folder_is_valid(out)


SIGNAL_CASES = [  # (argv after TINY, trigger, signal): writing frames, writing result.npz, integrating
    (["--set", "simulation.t_end=0.2", "--set", "output.vtu_every=1", "--set", "output.plots=[]"],
     "nsfem_00000.vtu", signal.SIGTERM),
    (["--set", "simulation.t_end=0.05", "--set", "simulation.output_dt=1e-6", "--set", "output.vtu_every=0",
      "--set", "output.plots=[]"], ".result.npz.*.tmp", signal.SIGTERM),
    (["--set", "simulation.t_end=20", "--set", "output.vtu_every=0", "--set", "output.plots=[]"], "integrating",
     signal.SIGINT),
]
SLOW_SIGNAL_CASES = [
    (["--set", "simulation.t_end=0.2", "--set", "output.vtu_every=1", "--set", "output.plots=[]"],
     "nsfem_00004.vtu", signal.SIGINT),
    (["--set", "simulation.t_end=0.2", "--set", "output.vtu_every=1", "--set", "output.plots=[]"],
     "nsfem_contacts_00002.vtu", signal.SIGTERM),
    (["--set", "simulation.t_end=0.05", "--set", "simulation.output_dt=1e-6", "--set", "output.vtu_every=0",
      "--set", "output.plots=[]"], ".result.npz.*.tmp", signal.SIGINT),
    (["--set", "simulation.t_end=0.05", "--set", "output.vtu_every=0"], ".phase.png.*.tmp", signal.SIGTERM),
    (["--set", "simulation.t_end=20", "--set", "output.vtu_every=0", "--set", "output.plots=[]"], "integrating",
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
        assert code == 130 and "result.npz" in names
        with np.load(out / "result.npz") as r:
            meta = json.loads(str(r["meta"]))
        assert meta["completed"] is False and 0 < meta["t_end"] < 20
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
                          appears(out, "nsfem_00002.vtu"), signal.SIGTERM)
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
            frames = set(re.findall(r'file="([^"]+)"', (out / "nsfem.pvd").read_text())) if run["vtu_every"] else set()
            assert names == outputs | frames | {"notes.txt", "nsfem_99999.vtu"}, (run, sorted(names))
            n_frames = len(range(0, round(run["t_end"] / 1e-3) + 1, run["vtu_every"])) if run["vtu_every"] else 0
            assert len(frames) == 4 * n_frames  # stack, contacts, disks, cracks
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
    vtus = {n for n in after if n.endswith(".vtu")}
    assert len(vtus) == 4 * 3   # outputs 0, 2, 4
    assert after - vtus == {n for n in before if not n.endswith(".vtu")}   # result, plot, sensors kept


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
      "output.vtu_every=1", "--set", "output.plots=[]"], "output.vtu_every: this run would write 400007 files"),  # 100001 outputs x 4 files + pvd, result, sensors
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
        frame = list(out.glob(f"nsfem*_{i:05d}.vtu"))
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
    assert len(list(out.glob("*.png"))) == 5 and len(list(out.glob("*.vtu"))) == 4 * 11   # outputs 0..40
    assert cli.main(["run", *TINY, "--set", "simulation.t_end=0.004", "--set", "output.plots=[]",
                     "--set", "output.vtu_every=4", "--out", str(out)]) == 0
    names = folder_is_valid(out)
    assert not [n for n in names if n.endswith(".png")]
    assert len([n for n in names if n.endswith(".vtu")]) == 4 * 3   # outputs 0, 4, 8


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
    ("1", 10, None, "--every: 23 files (11 of the 11 output times)"),   # 11 frames x 2 files + the pvd
    ("5", 10, None, None),                                              # 3 frames: 7 files
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
        assert code == 0 and len(list((tmp_path / "v").glob("*.vtu"))) == 2 * 3
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
