"""Bounds on scene values that no model can honour, and the linear-range warning (issue 16).

Each bound is checked where the physics or double precision puts it: a deeply nested TOML
value, a polygonal friction cone finer than any friction coefficient is known, a speed whose
centrifugal strain reaches 1, material scales outside double precision, damping whose time
scales double precision cannot separate, output arrays beyond memory, and deflections beyond
the small-deflection theory of eq. (22).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from nsfem import build_model, cli, load_scene
from nsfem.errors import SceneError
from nsfem.scene import MAX_FRICTION_DIRECTIONS, nesting_depth, speed_limit_hz

from test_scene_validation import check_cli_error, check_error, expect_scene_error, no_model, run_cli  # noqa: F401

F = ["--set", "simulation.t_end=0.01", "--set", "output.vtu_every=0", "--set", "output.plots=[]"]


# --------------------------------------------------------------------------- nesting
def test_deeply_nested_scene_file_is_one_line_error(tmp_path, capsys, no_model):
    path = tmp_path / "deep.toml"
    path.write_text("title = " + "[" * 100000 + "]" * 100000 + "\n")
    exc = expect_scene_error(load_scene, path)
    check_error(exc, "scene", "nested too deeply")
    check_cli_error(["modes", str(path)], capsys, "scene", "nested too deeply")


def test_nested_scene_file_below_the_parser_limit_is_refused_by_depth(tmp_path):
    # tomllib parses 100 levels; the scene never needs more than MAX_NESTING
    path = tmp_path / "deep.toml"
    path.write_text("title = " + "[" * 100 + "]" * 100 + "\n")
    check_error(expect_scene_error(load_scene, path), "scene", "101 levels")  # the file is a table: +1


def test_deeply_nested_override_names_the_key(capsys, no_model):
    exc = expect_scene_error(load_scene, None, ["title=" + "[" * 100000 + "]" * 100000])
    check_error(exc, "title", "nested too deeply")
    check_cli_error(["modes", "--set", "title=" + "[" * 50 + "]" * 50], capsys, "title", "50 levels")


def test_nesting_depth_counts_containers():
    assert nesting_depth("x") == 0
    assert nesting_depth({"delamination": [{"contact_points": [0.5]}]}) == 4
    assert nesting_depth([[[[]]]]) == 4


# --------------------------------------------------------------------------- friction cone
@pytest.mark.parametrize("key", ["delamination.0.friction_directions", "obstacle.0.friction_directions"])
def test_friction_directions_are_bounded(key, capsys, no_model):
    over = [f"{key}={MAX_FRICTION_DIRECTIONS + 2}"]
    check_error(expect_scene_error(load_scene, None, over), key, "1 - cos(pi/r)")
    check_cli_error(["stationary", "--set", f"{key}=100000"], capsys, key, f"exceeds {MAX_FRICTION_DIRECTIONS}")
    load_scene(None, [f"{key}={MAX_FRICTION_DIRECTIONS}"])  # the bound itself is allowed


def test_friction_cone_bound_is_below_any_known_friction_coefficient():
    # the inscribed r-gon under-estimates the circular cone by 1 - cos(pi/r): at the bound it must
    # lie far below the ~10 % to which friction coefficients are known, at half of it not yet
    assert 1 - math.cos(math.pi / MAX_FRICTION_DIRECTIONS) < 2e-3
    assert 1 - math.cos(math.pi / 4) > 0.25  # the default r = 4: 29 %


# --------------------------------------------------------------------------- speeds
def test_speed_limit_is_the_bar_wave_speed_at_the_outer_fibre():
    scene = load_scene(None)
    f, seg = speed_limit_hz(scene.stack)
    c = math.sqrt(2.1e11 / 7500.0)  # bar wave speed of the shipped steel
    r = math.hypot(0.01, 0.01)  # corner of the 20 mm x 20 mm section
    assert f == pytest.approx(c / r / (2 * math.pi), rel=1e-12)  # same formula, round-off only
    assert 1000 * 48.0 < f  # far above the first critical speeds (43, 48 Hz): supercritical speeds allowed


@pytest.mark.parametrize("speed", ["1e6", "1e300"])
def test_absurd_rotation_speed_is_refused(speed, capsys, no_model):
    check_error(expect_scene_error(load_scene, None, [f"rotation.speed_hz={speed}"]), "rotation.speed_hz",
                "centrifugal strain")
    check_cli_error(["stationary", "--set", f"rotation.speed_hz={speed}"], capsys, "rotation.speed_hz",
                    "bar wave speed")


def test_supercritical_speed_is_allowed():
    load_scene(None, ["rotation.speed_hz=5000"])  # 100 x critical, strain 7e-3


def test_campbell_speeds_beyond_the_limit_name_the_option(capsys, no_model):
    check_cli_error(["campbell", "--speeds", "0:1e300:3"], capsys, "--speeds", "centrifugal strain")


# --------------------------------------------------------------------------- material scales
@pytest.mark.parametrize("overrides, key", [
    (["shaft.E=1e-300"], "shaft.E"),
    (["shaft.rho=1e300"], "shaft.rho"),
    (["shaft.E=1e100", "shaft.rho=1e-100", "rotation.speed_hz=0"], "shaft.rho"),
])
def test_material_scales_outside_double_precision_are_refused(overrides, key, capsys, no_model):
    exc = expect_scene_error(load_scene, None, overrides)
    check_error(exc, key, "units closer to 1")
    argv = ["modes"] + [a for o in overrides for a in ("--set", o)]
    check_cli_error(argv, capsys, key, "outside")


@pytest.mark.parametrize("scale", [1e-60, 1.0, 1e60])
def test_frequencies_scale_as_sqrt_of_E_over_the_whole_allowed_range(scale):
    # dimensional analysis: omega ~ sqrt(E I / (rho A L^4)), so f(s E) = sqrt(s) f(E) exactly; the
    # computation must follow it. It does to round-off, but not to eps: the Craig-Bampton basis is
    # rebuilt at each E and its fixed-interface Ritz vectors come out of ARPACK along another path
    # (even for s = 2^200, an exact scaling: 4.9e-11); with the basis held fixed the error is 9e-12.
    # Measured over four OpenBLAS kernels: 2.4e-12 to 8.3e-12 at 1e-60, 2.5e-10 to 8.3e-10 at 1e60;
    # 1e-8 keeps 12x.
    from nsfem.analysis.modes import natural_frequencies
    from nsfem.fem.assemble import build_model
    from nsfem.reduce import scene_reduction

    def freqs(E):
        scene = load_scene(None, [f"shaft.E={E}", "rotation.speed_hz=0"])
        model = build_model(scene)
        m = natural_frequencies(model, "open", 4, scene_reduction(scene, model))
        return np.array(m.frequencies_hz), m.fields

    f0, fields0 = freqs(2.1e11)
    f, fields = freqs(2.1e11 * scale)
    np.testing.assert_allclose(f, f0 * math.sqrt(scale), rtol=1e-8)
    assert fields == fields0


def test_modes_prints_tiny_nondimensional_frequencies(capsys):
    # E = rho = 1: frequencies shrink by sqrt(7500 / 2.1e11) = 1.89e-4 (43.37 Hz -> 8.197e-3)
    code, out, err = run_cli(["modes", "--set", "shaft.E=1", "--set", "shaft.rho=1", "--set", "rotation.speed_hz=0",
                              "--count", "2"], capsys)
    assert code == 0, err
    first = float(out.splitlines()[3].split()[1])
    # 5 printed digits (<= 6.1e-5 relative for 8.197e-3) and the quoted 43.373 (<= 1.2e-5)
    assert first == pytest.approx(43.373 * math.sqrt(7500 / 2.1e11), rel=1e-4)


# --------------------------------------------------------------------------- damping
@pytest.mark.parametrize("rayleigh", ["[0, 1e300]", "[1e300, 0]"])
def test_absurd_rayleigh_damping_is_refused_before_integrating(rayleigh, capsys, monkeypatch, tmp_path):
    from nsfem import simulate

    monkeypatch.setattr(simulate, "integrate", lambda *a, **k: pytest.fail("integrated absurd damping"))
    check_cli_error(["run", *F, "--out", str(tmp_path), "--set", f"damping.rayleigh={rayleigh}"], capsys,
                    "damping.rayleigh", "damping ratio")


def test_damping_ratio_of_rayleigh_damping():
    from nsfem.simulate import ZETA_MAX, damping_ratio

    w = np.array([0.0, 100.0, 1000.0])  # a rigid mode and two elastic ones
    # zeta(w) = alpha / (2 w) + beta w / 2 is largest at an end of the elastic spectrum (exact arithmetic)
    assert damping_ratio((20.0, 0.0), w) == (pytest.approx(0.1, rel=1e-15), 100.0)
    assert damping_ratio((0.0, 2e-4), w) == (pytest.approx(0.1, rel=1e-15), 1000.0)
    # the bound: 4 zeta^2 (ratio of an overdamped pair's decay rates) reaches 1/eps
    assert 4 * ZETA_MAX**2 == pytest.approx(1 / np.finfo(float).eps, rel=1e-15)


def test_a_free_rotor_with_heavy_mass_damping_is_not_refused_for_its_rigid_modes():
    # a free-free shaft's rigid modes come out of the eigen solver at ~sqrt(eps) w_max (4e-3..2e-2
    # rad/s here), not 0: alpha = 1e6 1/s gave them zeta = 1e8 and was refused. Its lowest elastic
    # mode (~110 Hz) has zeta = alpha / (2 w) = 730, far inside ZETA_MAX
    from nsfem.analysis.campbell import campbell_report

    scene = load_scene(None, ["delamination=[]", "obstacle=[]", "shaft.supports=free-free",
                              "damping.rayleigh=[1e6, 0]", "mesh.elements=20"])
    rep = campbell_report(scene, build_model(scene), [0.0], 4)
    assert rep["speeds_hz"] == [0.0]


def test_heavy_but_representable_overdamping_runs(tmp_path):
    # alpha = 1e6 1/s: zeta = 4e3 at the lowest mode (38 Hz), heavily overdamped, far inside ZETA_MAX
    from nsfem.simulate import run_scene

    scene = load_scene(None, ["simulation.t_end=0.01", "damping.rayleigh=[1e6, 0]"])
    result, _ = run_scene(scene)
    assert result.completed and result.t[-1] == pytest.approx(0.01, rel=1e-12)  # the last output: t_end, ulps


# --------------------------------------------------------------------------- sample counts
def test_absurd_t_end_is_refused_with_the_right_advice(capsys, tmp_path):
    line = check_cli_error(["run", *F, "--out", str(tmp_path), "--set", "simulation.t_end=1e300", "--set",
                            "simulation.output_dt=1e294"], capsys, "simulation.t_end", "refused")
    assert "craig_bampton" not in line and "a reduced model" not in line  # it already is one
    assert "shorter simulation.t_end" in line
    line = check_cli_error(["run", *F, "--out", str(tmp_path), "--set", "simulation.t_end=1e300", "--set",
                            "simulation.output_dt=1e294", "--set", "reduction.method=none"], capsys,
                           "simulation.t_end", "refused")
    assert "reduction.method = craig-bampton or modal" in line


def test_search_cost_advice_fits_the_model():
    from nsfem.fem.assemble import build_model
    from nsfem.integrate import ContactSystem
    from nsfem.reduce import scene_reduction
    from nsfem.simulate import SAMPLES_WARN, check_search_cost

    scene = load_scene(None, ["reduction.method=modal"])
    model = build_model(scene)
    red = scene_reduction(scene, model)
    system = ContactSystem.from_scene(scene, model, red)
    assert check_search_cost(system, 1.0, "exact", red.info, 900.0, SAMPLES_WARN) is None
    text = check_search_cost(system, 1.0, "exact", red.info, 900.0, 2 * SAMPLES_WARN)
    assert "reduction.modes" in text and "craig" not in text
    text = check_search_cost(system, 1.0, "exact", {"method": "none"}, 5e5, 2 * SAMPLES_WARN)
    assert "craig-bampton or modal" in text


def test_output_arrays_beyond_memory_are_refused():
    from nsfem.fem.assemble import build_model
    from nsfem.integrate import ContactSystem
    from nsfem.reduce import scene_reduction
    from nsfem.simulate import check_outputs, output_bytes

    scene = load_scene(None)
    model = build_model(scene)
    system = ContactSystem.from_scene(scene, model, scene_reduction(scene, model))
    # 1e7 + 1 samples of (2 x 25 dofs + 5 x 9 contact values + t) doubles
    need = output_bytes(system, 1e4, 1e-3)
    assert need == 8.0 * (1e7 + 1) * (2 * 25 + 5 * 9 + 1)
    check_outputs(system, 1e4, 1e-3, memory=2 * need)
    with pytest.raises(SceneError) as exc:
        check_outputs(system, 1e4, 1e-3, memory=need / 2)
    check_error(exc.value, "simulation.output_dt", "GiB")


# --------------------------------------------------------------------------- linear range
LINEAR_RANGE = "range of the linear"


@pytest.mark.parametrize("extra", [
    ["rotation.gravity=1e6"],
    ["rotation.gravity=1e6", "rotation.speed_hz=0"],
    ["initial.velocity=[0, 0, 1e6]"],
])
def test_run_warns_beyond_the_linear_range(extra, capsys, tmp_path):
    import json

    argv = ["run", *F, "--out", str(tmp_path), "--json"] + [a for o in extra for a in ("--set", o)]
    code, out, err = run_cli(argv, capsys)
    assert code == 0, err
    assert LINEAR_RANGE in err
    payload = json.loads(out)
    assert any(LINEAR_RANGE in w for w in payload["warnings"])
    assert payload["max_gap_m"] > 0.009  # the gap the warning reports, wider than the 9 mm sub-beam


def test_shipped_scene_stays_in_the_linear_range(capsys, tmp_path):
    import json

    code, out, err = run_cli(["run", *F, "--out", str(tmp_path), "--json"], capsys)
    assert code == 0 and LINEAR_RANGE not in err and json.loads(out)["warnings"] == []


def test_stationary_warns_beyond_the_linear_range(capsys):
    import json

    code, out, err = run_cli(["stationary", "--set", "rotation.speed_hz=0", "--set", "rotation.gravity=1e6",
                              "--json"], capsys)
    assert code == 0 and LINEAR_RANGE in err
    assert any(LINEAR_RANGE in w for w in json.loads(out)["warnings"])
    code, out, err = run_cli(["stationary", "--json"], capsys)
    assert code == 0 and LINEAR_RANGE not in err and json.loads(out)["warnings"] == []


def test_lateral_deflection_measures_the_static_sag():
    # the stationary sag of a plain pinned shaft under gravity at rest against Euler-Bernoulli,
    # 5 q L^4 / (384 E I) at midspan: Hermite cubics are nodally exact for a uniform load, so the
    # unreduced model differs by round-off only: eps cond(K) = 2.2e-16 x 2.2e7 = 5e-9 (Jacobi-scaled
    # 1.3e6: 2.8e-10), plus the elements' shape-function round-off (eps x cond of their Vandermonde
    # matrices, <= 1e-9): rtol 1e-8 (measured 1e-11 to 1.5e-11 over four kernels). (Craig-Bampton's
    # 16 modes would miss 1e-5 of it: the static tail of the modes beyond.)
    from nsfem.analysis.deflection import lateral_deflection
    from nsfem.analysis.stationary import scene_stationary
    from nsfem.fem.assemble import build_model
    from nsfem.reduce import scene_reduction

    scene = load_scene(None, ["rotation.speed_hz=0", "delamination=[]", "reduction.method=none"])
    model = build_model(scene)
    red = scene_reduction(scene, model)
    st = scene_stationary(scene, model, red)
    rows = lateral_deflection(model, red.T, st.q)
    E, b, h, rho, g, L = 2.1e11, 0.02, 0.02, 7500.0, 9.81, 1.0
    expect = 5 * rho * b * h * g * L**4 / (384 * E * b * h**3 / 12)
    assert max(r[2] for r in rows) == pytest.approx(expect, rel=1e-8)
    assert max(r[1] for r in rows) == pytest.approx(expect / h, rel=1e-8)  # measured against the height


def test_stationary_without_contacts(capsys):
    # a scene without delamination has no contacts: the state is Q^-1 f0 (was a ValueError: max of
    # an empty array)
    code, out, err = run_cli(["stationary", "--set", "delamination=[]"], capsys)
    assert code == 0, err
    assert "no contacts" in out


def test_search_cost_follows_the_modes_the_contacts_see():
    """An end-on contact of a free bar sees its axial modes only: the search-cost estimate takes the
    fastest of those (for 40 linear axial elements, 2 c / h sqrt(3) at most: the consistent-mass
    bar's highest frequency), not the faster bending and torsion modes of the same mesh; a
    gyroscopic model (no real modes) keeps its whole spectrum; models beyond the dense limit get
    ARPACK's largest frequency, which matches the dense one."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parents[1] / "studies"))
    from bar_impact import E, L, RHO, scene

    from nsfem.integrate import ContactSystem
    from nsfem.simulate import fastest_frequency, search_cost, spectra

    system = ContactSystem.from_scene(scene(40, 0.0))
    w, seen = spectra(system)
    f_max, samples = search_cost(system, 1.0)
    c, h = math.sqrt(E / RHO), L / 40
    # (the free-free mesh's highest axial mode is the element's own, nodes alternating: 2 sqrt(3) c / h,
    # to the eigensolver's round-off)
    assert 2 * math.pi * f_max == pytest.approx(seen.max())
    assert seen.max() == pytest.approx(2 * c / h * math.sqrt(3.0), rel=1e-9)
    # the bending modes of 40 elements reach 3.5x higher (10x for 200 elements)
    assert w.max() > 3 * seen.max() and samples == pytest.approx(4 * seen.max() / math.pi)
    # ARPACK to its tolerance 1e-3 of the largest eigenvalue (1e-3 / 2 in its square root)
    assert fastest_frequency(system) == pytest.approx(w.max(), rel=1e-3)
    shipped = ContactSystem.from_scene(load_scene(None, []))
    assert not shipped.symmetric and np.array_equal(*spectra(shipped))
