"""What keeps a command quick (issue 34 point 10), checked without a clock: which modules a command
loads, how many BLAS threads it runs with, and that the NumPy Welch estimate that replaced
scipy.signal's gives the same numbers. The timings themselves are studies/latency.py's."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from nsfem.spectrum import hann, welch

ROOT = Path(__file__).resolve().parents[1]
#: loaded only to draw (matplotlib), render (pyvista, vtk), sweep or fit (dask), write VTU (meshio), compute
#: a PSD with SciPy (scipy.signal) or run rk / penalty / a crack's compliance (scipy.integrate, scipy.optimize)
DRAWING = ("matplotlib", "pyvista", "vtk", "dask", "distributed", "meshio")
NUMERICS = ("scipy.signal", "scipy.integrate", "scipy.optimize")

#: a fresh interpreter runs ``nsfem ARGV`` (json list in argv[1]) and prints the modules it loaded (stderr)
LOADED = r"""
import json, sys
from nsfem import cli
try:
    code = cli.main(json.loads(sys.argv[1]))
except SystemExit as exc:
    code = exc.code
print(json.dumps({"code": code, "modules": sorted(sys.modules)}), file=sys.__stderr__)
"""


def _env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS",
                                                            "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    return {**env, "PYTHONPATH": str(ROOT), **extra}


def loaded(argv: list[str], cwd: Path) -> set[str]:
    """The modules ``nsfem argv`` loaded in a fresh interpreter (which must exit 0)."""
    run = subprocess.run([sys.executable, "-c", LOADED, json.dumps(argv)], cwd=cwd, env=_env(), capture_output=True,
                         text=True, timeout=300)
    found = json.loads(run.stderr.strip().splitlines()[-1])
    assert found["code"] in (0, None), run.stderr
    return set(found["modules"])


def _heavy(modules: set[str], names) -> list[str]:
    return sorted(m for m in modules if any(m == n or m.startswith(n + ".") for n in names))


def test_help_loads_no_numerics(tmp_path):
    """``nsfem --help`` and ``nsfem run --help`` answer from argparse alone: no NumPy, SciPy or drawing."""
    for argv in (["--help"], ["run", "--help"]):
        mods = loaded(argv, tmp_path)
        assert not _heavy(mods, ("numpy", "scipy", "skfem", *DRAWING)), (argv, _heavy(mods, ("numpy", "scipy")))


def test_import_nsfem_loads_no_scipy():
    """``import nsfem`` gives the public names on first use (PEP 562), each the module's own object."""
    code = ("import sys, nsfem; before = 'scipy' in sys.modules; f = nsfem.natural_frequencies; "
            "from nsfem.analysis.modes import natural_frequencies as g; print(before, f is g, 'scipy' in sys.modules)")
    run = subprocess.run([sys.executable, "-c", code], env=_env(), capture_output=True, text=True, check=True)
    assert run.stdout.split() == ["False", "True", "True"]


def test_run_without_plots_loads_no_drawing(tmp_path):
    """A run with plots and VTU off loads no drawing library and none of SciPy's signal, integrate or
    optimize (the exact method needs neither); drawing psd.png loads matplotlib, without pyplot, and still
    no scipy.signal (the PSD is NumPy's)."""
    short = ["--set", "simulation.t_end=0.05"]
    bare = loaded(["run", "--json", "--out", str(tmp_path / "bare"), *short, "--set", "output.plots=[]",
                   "--set", "output.vtu_every=0"], tmp_path)
    assert "nsfem.simulate" in bare            # it did run
    assert not _heavy(bare, (*DRAWING, *NUMERICS)), _heavy(bare, (*DRAWING, *NUMERICS))
    psd = loaded(["run", "--json", "--out", str(tmp_path / "psd"), *short, "--set", 'output.plots=["psd"]',
                  "--set", "output.vtu_every=0"], tmp_path)
    assert (tmp_path / "psd" / "psd.png").exists() and "matplotlib" in psd
    assert not _heavy(psd, ("pyvista", "vtk", "dask", "distributed", "meshio", "matplotlib.pyplot", *NUMERICS))


BLAS = r"""
import json, sys
from nsfem import cli
cli.one_blas_thread()
import numpy, scipy.linalg
from threadpoolctl import threadpool_info
print(json.dumps([p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]))
"""


@pytest.mark.skipif((os.cpu_count() or 1) < 2, reason="one core: one BLAS thread whatever the setting")
def test_command_runs_one_blas_thread_unless_told():
    """A command whose environment sets no BLAS threads gets one (small products: a second thread costs
    more than it gives); a user's OPENBLAS_NUM_THREADS=2 is kept."""
    def threads(**extra):
        run = subprocess.run([sys.executable, "-c", BLAS], env=_env(**extra), capture_output=True, text=True,
                             check=True)
        return json.loads(run.stdout)
    assert threads() and set(threads()) == {1}
    assert set(threads(OPENBLAS_NUM_THREADS="2")) == {2}


# ------------------------------------------------------------------ Welch in NumPy (nsfem.spectrum)
def test_hann_is_periodic():
    """n shifted periodic Hann windows sum to n / 2 everywhere (exact up to round-off of n cosines)."""
    for n in (2, 7, 64, 1001):
        w = hann(n)
        assert w[0] == 0.0 and np.allclose(sum(np.roll(w, k) for k in range(n)), n / 2, rtol=0, atol=1e-12 * n)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 3000), frac=st.floats(0.0, 1.0), seed=st.integers(0, 2**32 - 1),
       offset=st.floats(-1e3, 1e3), scale=st.floats(1e-9, 1e3))
def test_welch_equals_scipy(n, frac, seed, offset, scale):
    """Frequencies and PSD equal scipy.signal.welch(window="hann", detrend="constant", scaling="density") for
    any length, segment length and offset: the same sums in another order, so they agree to round-off --
    a few ulps of the largest bin per product and sum (FFT error grows like log2 n; 1e-10 of the largest
    bin leaves 1e5x room, while a wrong window, overlap, scaling or one-sided factor is off by O(1))."""
    from scipy.signal import welch as scipy_welch

    x = offset + scale * np.random.default_rng(seed).standard_normal(n)
    nperseg = max(1, int(round(frac * n)))
    f_ref, p_ref = scipy_welch(x, fs=1.0 / 1e-3, nperseg=nperseg, detrend="constant", scaling="density")
    f, p = welch(x, 1e-3, nperseg)
    assert f.shape == f_ref.shape and np.allclose(f, f_ref, rtol=1e-14, atol=0)
    assert np.all(np.abs(p - p_ref) <= 1e-10 * max(np.max(np.abs(p_ref)), 1e-300 * scale ** 2))


def test_welch_line_power():
    """A sine of amplitude a has power a^2 / 2: Hann's density scaling keeps it (to the window's leakage
    into no other bin than the line's neighbours: sum over the spectrum, exact to round-off for a whole
    number of periods per segment), and the peak sits on the line's frequency."""
    dt, f0, a = 1e-3, 50.0, 3.0
    t = np.arange(4000) * dt
    f, p = welch(a * np.sin(2 * np.pi * f0 * t) + 7.0, dt, 1000)   # 50 periods a segment; the offset removed
    assert f[np.argmax(p)] == f0
    assert np.sum(p) * (f[1] - f[0]) == pytest.approx(a * a / 2, rel=1e-12)


# --- issue 34: latency, second pass (the command's exit) -----------------------------------------------------
#: ``python -m nsfem ARGV`` (json list in argv[1]) with an exit handler that reports the frozen objects
EXITING = r"""
import atexit, gc, json, runpy, sys
atexit.register(lambda: print(json.dumps({"frozen": gc.get_freeze_count(), "young": gc.get_threshold()[0]}),
                              file=sys.__stderr__))
sys.argv = ["nsfem", *json.loads(sys.argv[1])]
runpy.run_module("nsfem", run_name="__main__", alter_sys=True)
"""


def test_the_command_exits_with_mains_status_its_output_whole_and_its_objects_frozen(tmp_path):
    """``python -m nsfem`` exits with main's status (0, or 2 for a bad key, its one-line error printed), its JSON
    whole on stdout, exit handlers run; the objects alive at its end are frozen (gc.freeze: none left for the
    shutdown's collections to walk), which is what saves the 0.12 s, and the collector passes over the young
    objects at the command's threshold, not Python's 700."""
    from nsfem.cli import YOUNG_OBJECTS_PER_COLLECTION

    def command(argv):
        run = subprocess.run([sys.executable, "-c", EXITING, json.dumps(argv)], cwd=tmp_path, env=_env(),
                             capture_output=True, text=True, timeout=300)
        return run.returncode, run.stdout, run.stderr.strip().splitlines()

    code, out, err = command(["run", "--json", "--out", str(tmp_path / "o"), "--set", "simulation.t_end=0.02",
                              "--set", "output.plots=[]", "--set", "output.vtu_every=0"])
    assert code == 0 and json.loads(out)["outputs"] == [str(tmp_path / "o" / "result.npz")]
    assert json.loads(err[-1])["frozen"] > 0 and json.loads(err[-1])["young"] == YOUNG_OBJECTS_PER_COLLECTION > 700
    code, out, err = command(["run", "--out", str(tmp_path / "p"), "--set", "shaft.nonsense=1"])
    assert code == 2 and out == "" and err[0].startswith("nsfem: error: ") and "nonsense" in err[0]
    assert json.loads(err[-1])["frozen"] > 0 and len(err) == 2
