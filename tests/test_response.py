"""nsfem response: the steady unbalance response by a harmonic solve (issue 35 item 4)."""

from __future__ import annotations

import contextlib
import io
import json
import math

import numpy as np
import pytest

from nsfem import cli, load_scene
from nsfem.analysis.response import half_power_peaks, response_report
from nsfem.errors import NsfemError
from nsfem.fem.assemble import build_model
from nsfem.reduce import scene_reduction

#: A Jeffcott rotor: a 20 kg disk on a short thick shaft made nearly rigid (E = 2.1e14) on two isotropic
#: bearings of k/2, c/2 each, the unbalance and both probes at the middle. The symmetric unbalance drives the
#: translation alone (the tilt is uncoupled by symmetry), a single dof of the whole mass m (disk + shaft).
K, C, ME = 1e6, 400.0, 1e-4
JEFFCOTT = ["shaft.length=0.4", "shaft.diameter=0.1", "shaft.E=2.1e14", "mesh.elements=4", 'reduction.method="none"',
            "rotation.gravity=0.0", "bearing.1.x=0.4", "disk.0.x=0.2", "unbalance.0.x=0.2", "sensor.0.x=0.2",
            "sensor.1.x=0.2", f"unbalance.0.magnitude={ME}",
            *(f"bearing.{i}.{k}{a}{a}={v / 2}" for i in (0, 1) for a in "yz" for k, v in (("k", K), ("c", C)))]


def _report(overrides, speeds):
    scene = load_scene("critical_speed", overrides)
    model = build_model(scene)
    return scene, model, response_report(scene, model, np.asarray(speeds, dtype=float),
                                         scene_reduction(scene.reduction, model))


def _jeffcott_mass(model) -> float:
    return 20.0 + sum(s.rho * s.area * (s.end - s.start) for s in model.stack.segments)


def test_jeffcott_amplitude_and_phase_lag_are_the_closed_form():
    """A = m_u e w^2 / |k - m w^2 + i c w| and lag atan2(c w, k - m w^2) on the y probe, the same amplitude and
    lag + 90 deg on the z probe (the unbalance force turns from +y to +z), a circular forward orbit. Tolerance:
    the shaft is not rigid: its stiffness k_s = 48 E I / L^3 = 7.7e11 N/m in series with the bearings changes k
    by k / k_s = 1.3e-6, which the amplitude and the phase (rad) feel at most 1 / (2 zeta) = 17 times: 2.2e-5;
    5e-5 leaves margin for the shaft's own mass not moving rigidly (measured 8.4e-6 and 1.4e-5 rad)."""
    scene, model, rep = _report(JEFFCOTT, np.linspace(10.0, 40.0, 61))
    m = _jeffcott_mass(model)
    w = 2 * np.pi * np.asarray(rep["speeds_hz"])
    A = ME * w**2 / np.hypot(K - m * w**2, C * w)
    lag = np.degrees(np.arctan2(C * w, K - m * w**2))
    y, z = rep["sensors"]["disk_y"], rep["sensors"]["disk_z"]
    assert np.asarray(y["amplitude_m"]) == pytest.approx(A, rel=5e-5)
    assert np.asarray(z["amplitude_m"]) == pytest.approx(A, rel=5e-5)
    assert np.asarray(y["phase_deg"]) == pytest.approx(lag, abs=math.degrees(5e-5))
    assert np.asarray(z["phase_deg"]) == pytest.approx(lag + 90.0, abs=math.degrees(5e-5))
    (orbit,) = rep["orbits"]
    assert orbit["sensors"] == ["disk_y", "disk_z"]
    assert np.asarray(orbit["semi_major_m"]) == pytest.approx(A, rel=5e-5)
    assert np.asarray(orbit["semi_minor_m"]) == pytest.approx(A, rel=5e-5)     # + : forward whirl


def test_amplification_factor_of_a_single_dof_is_one_over_two_zeta():
    """The half-power AF of the Jeffcott rotor's unbalance response is 1 / (2 zeta) (1 - 4 zeta^2 + O(zeta^4))
    (the exact half-power points of r^2 / |1 - r^2 + 2 i zeta r|: AF 2 zeta - 1 = -4.005 zeta^2 at zeta = 0.03);
    zeta = 0.030 here. Tolerance 2e-4 on AF 2 zeta: the crossings are interpolated linearly on a grid of
    fn / 2000 across a band of 0.06 fn, (1/30)^2 / 8 of the band's curvature = 1.4e-4 at most; the O(zeta^4)
    term 1e-6, the shaft's flexibility 1e-5 (measured 1.7e-5 off). The separation margin is from the scene's
    26 Hz."""
    scene, model, rep = _report(JEFFCOTT, np.linspace(12.0, 36.0, 2001))
    m = _jeffcott_mass(model)
    zeta = C / (2 * math.sqrt(K * m))
    fn = math.sqrt(K / m) / (2 * math.pi)
    assert {p["sensor"] for p in rep["peaks"]} == {"disk_y", "disk_z"}
    for p in rep["peaks"]:
        assert p["amplification_factor"] * 2 * zeta == pytest.approx(1 - 4 * zeta**2, abs=2e-4)
        # the peak of r^2 / |...| lies at fn / sqrt(1 - 2 zeta^2); the parabola's vertex on a 0.012 Hz grid
        # is within a small share of the step of it
        assert p["speed_hz"] == pytest.approx(fn / math.sqrt(1 - 2 * zeta**2), abs=1e-3)
        assert p["separation_margin"] == pytest.approx(100 * abs(p["speed_hz"] - 26.0) / 26.0, rel=1e-12)
        assert p["band_hz"][0] < p["speed_hz"] < p["band_hz"][1]


def test_half_power_peaks_need_both_crossings_inside_the_speeds():
    """A peak whose amplitude does not fall to 1/sqrt(2) of it on one side within the speeds is not listed
    (its AF cannot be read); a monotonic curve has none; a single dof with zeta = 0.05 has AF 1/(2 zeta) within
    the method's O(zeta^2) (its force-excited curve: the half-power points are 1 -+ zeta to first order)."""
    f = np.linspace(0.5, 1.5, 2001)
    a = 1 / np.sqrt((1 - f**2) ** 2 + (0.1 * f) ** 2)
    (p,) = half_power_peaks(f, a)
    assert p["amplification_factor"] == pytest.approx(10.0, rel=3 * 0.05**2)
    assert half_power_peaks(f[f < 1.02], a[f < 1.02]) == []       # the band's upper side cut off
    assert half_power_peaks(f, f) == []


def test_both_frames_give_the_same_response_to_every_probe():
    """The critical_speed rotor on isotropic bearings (the inertial frame needs an axisymmetric rotor) solved in
    the inertial and the rotating frame: the same physics, so the same 1x at casing probes (in the rotating frame
    the static response to the unbalance, turned) and at a shaft-fixed probe (gravity: in the inertial frame a
    static sag, turned; in the rotating frame a 1x load). Tolerance: round-off eps times the condition of the
    dynamic stiffness on the full model (its fastest to slowest frequency squared, 1e6-1e7) = 1e-9; measured
    3e-11 relative, 9e-10 deg."""
    extra = ["bearing.0.kzz=5e5", "bearing.1.kzz=5e5", 'reduction.method="none"', 'sensor.2.name="rot_y"',
             "sensor.2.x=0.3", 'sensor.2.direction="+y"', 'sensor.2.frame="rotating"', 'sensor.3.name="in_z"',
             "sensor.3.x=0.3", 'sensor.3.direction="-z"']
    speeds = [15.0, 26.0, 40.0]
    a = _report(extra + ['rotation.frame="inertial"'], speeds)[2]["sensors"]
    b = _report(extra + ['rotation.frame="rotating"'], speeds)[2]["sensors"]
    assert set(a) == {"disk_y", "disk_z", "rot_y", "in_z"}
    for name in a:
        assert np.asarray(b[name]["amplitude_m"]) == pytest.approx(a[name]["amplitude_m"], rel=1e-8)
        d = (np.asarray(b[name]["phase_deg"]) - a[name]["phase_deg"] + 180.0) % 360.0 - 180.0
        assert np.abs(d).max() < 1e-6
    assert min(a["rot_y"]["amplitude_m"]) > 0 and min(a["in_z"]["amplitude_m"]) > 0


def test_response_equals_the_transient_runs_fitted_steady_harmonic():
    """critical_speed (anisotropic bearings, inertial frame, reduced model) at 26 and 31 Hz, with a probe on the
    shaft (rotating frame) beside the casing ones: the amplitude and phase lag the sweep fits to an 8 s transient
    run (sweep.sensor_amplitudes) equal the harmonic solve's. The fit is exact for the harmonic; the start decays
    at 5 1/s at its slowest, e^-20 = 2e-9 of it by the last half (docs/validation.md: the fit equals the solve to
    ~1e-11): 1e-8 relative and 1e-8 rad bound it."""
    from nsfem.simulate import run_scene
    from nsfem.sweep import sensor_amplitudes

    shaft = ['sensor.2.name="rot_z"', "sensor.2.x=0.5", 'sensor.2.direction="+z"', 'sensor.2.frame="rotating"']
    for speed in (26.0, 31.0):
        over = [*shaft, f"rotation.speed_hz={speed}"]
        result, system = run_scene(load_scene("critical_speed", over), progress=False)
        fitted = sensor_amplitudes(result, system)
        rep = _report(over, [speed])[2]["sensors"]
        for name in ("disk_y", "disk_z", "rot_z"):
            assert rep[name]["amplitude_m"][0] == pytest.approx(fitted[f"amplitude_{name}_m"], rel=1e-8)
            d = (rep[name]["phase_deg"][0] - fitted[f"phase_{name}_deg"] + 180.0) % 360.0 - 180.0
            assert abs(d) < math.degrees(1e-8)


def _cli(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(argv)
    return code, out.getvalue(), err.getvalue()


def test_cli_response_json_keys_and_png(tmp_path):
    png = tmp_path / "bode.png"
    code, out, err = _cli(["response", "critical_speed", "--speeds", "10:45:200", "--json", "--png", str(png)])
    assert code == 0, err
    rep = json.loads(out)
    assert len(rep["speeds_hz"]) == 200 and set(rep["sensors"]) == {"disk_y", "disk_z"}
    assert set(rep["sensors"]["disk_y"]) == {"amplitude_m", "phase_deg"}
    for p in rep["peaks"]:
        assert set(p) >= {"sensor", "speed_hz", "amplitude_m", "amplification_factor", "separation_margin"}
    # the vertical mode (damped critical speed 30.94 Hz per docs/validation.md) is the z probe's sharp peak
    (z,) = [p for p in rep["peaks"] if p["sensor"] == "disk_z"]
    assert abs(z["speed_hz"] - 30.94) < 0.2 and z["amplification_factor"] > 2.5
    assert rep["outputs"] == [str(png)] and png.stat().st_size > 0
    assert sorted(f.name for f in tmp_path.iterdir()) == ["bode.png"]


@pytest.mark.parametrize("argv, words", [
    (["rub", "--speeds", "1:10:5"], "contacts (obstacle)"),
    (["crack", "--speeds", "1:10:5"], "crack"),
    (["critical_speed", "--speeds", "0:10:5"], "START must be above 0"),
    (["critical_speed", "--speeds", "10:5:5"], "--speeds"),
    (["critical_speed", "--speeds", "1:10"], "START:STOP:N"),
    (["critical_speed", "--speeds", "1:10:5", "--set", "sensor=[]"], "no [[sensor]]"),
    (["critical_speed", "--speeds", "1:10:5", "--set", "unbalance=[]"], "no [[unbalance]]"),
    (["critical_speed", "--speeds", "1:10:5", "--png", "out.csv"], "--png"),
    (["critical_speed", "--speeds", "1:1e300:3"], "--speeds"),
])
def test_cli_response_refuses_with_one_line(argv, words):
    code, out, err = _cli(["response", *argv])
    lines = [line for line in err.splitlines() if line.startswith("nsfem: error:")]
    assert code == cli.EXIT_ERROR and len(lines) == 1 and words in lines[0], err
    assert "Traceback" not in err and out == ""


def test_check_linear_names_what_is_not_linear():
    from nsfem.analysis.response import check_linear

    with pytest.raises(NsfemError, match="contacts"):
        check_linear(load_scene("default", []).stack)


def test_round_off_wiggles_are_not_peaks():
    """With two kept modes (both along y), the z probe reads round-off (1e-20 m beside 5e-5 m): its wiggles
    are not listed as peaks, and a warning says the speeds pass half the highest kept mode."""
    rep = _report(["reduction.modes=2"], np.linspace(10.0, 45.0, 50))[2]
    assert max(rep["sensors"]["disk_z"]["amplitude_m"]) < 1e-12 * max(rep["sensors"]["disk_y"]["amplitude_m"])
    assert [p["sensor"] for p in rep["peaks"]] == ["disk_y"]
    assert len(rep["warnings"]) == 1 and "reduction.modes" in rep["warnings"][0]


#: ROSS 2.3.0 on the critical_speed rotor (20 ShaftElement(L=0.05, odl=0.04, steel E 2.1e11, rho 7850,
#: shear_effects=False, rotary_inertia=True, gyroscopic=True), DiskElement(n=10, m=20, Id=0.13, Ip=0.25),
#: BearingElement at nodes 0 and 20 with kxx=5e5, kyy=2e6, cxx=cyy=2000; ROSS's x is our y, its y our z):
#: rotor.run_unbalance_response(node=10, unbalance_magnitude=5e-4, unbalance_phase=0, frequency=2 pi f)
#: .forced_resp at the disk's x and y dofs (/work/rossvenv/bin/python, 2026-11-27), as Re + i Im
ROSS_SPEEDS_HZ = [15.0, 24.0, 26.0, 31.0, 40.0]
ROSS_DISK = {
    "disk_y": [[1.1688168871629539e-05, -1.7401984378586056e-06, -2.5211341436090945e-05, -3.438684715545259e-05, -2.825202010942043e-05], [-4.108753162615566e-06, -5.883904914405451e-05, -5.108987207642022e-05, -2.2898771743811553e-05, -9.407922032526907e-06]],
    "disk_z": [[-1.8238374324452102e-07, -2.808723091232355e-06, -6.550806517957541e-06, -0.00038254262794855983, -5.087284445872442e-06], [-6.026312673173069e-06, -2.934590893483921e-05, -4.61492049915018e-05, 2.2399567221900614e-05, 4.8410286705547506e-05]],
}


def test_unbalance_response_matches_ross_without_shear():
    """The full model (105 dofs) of critical_speed against ROSS's run_unbalance_response on the same Rayleigh
    beam: ROSS's complex response Z is our probe's 1x (amplitude |Z|, lag -arg Z). Both are one dense solve of the
    same matrices; the difference is round-off times the dynamic stiffness's condition (1e6-1e7, more at the
    sharp 31 Hz peak): 1e-9 relative and 1e-6 deg (measured 1.1e-11 and 8e-9 deg)."""
    rep = _report(['reduction.method="none"'], ROSS_SPEEDS_HZ)[2]["sensors"]
    for name, (re, im) in ROSS_DISK.items():
        Z = np.asarray(re) + 1j * np.asarray(im)
        assert np.asarray(rep[name]["amplitude_m"]) == pytest.approx(np.abs(Z), rel=1e-9)
        d = (np.asarray(rep[name]["phase_deg"]) + np.degrees(np.angle(Z)) + 180.0) % 360.0 - 180.0
        assert np.abs(d).max() < 1e-6


def test_sparse_and_dense_solves_agree_on_a_full_model(monkeypatch):
    """A full model of 505 dofs goes to the sparse LU (above DENSE_LIMIT); forced dense, the same numbers.
    Tolerance: two LU factorizations of one matrix differ by round-off times its condition: the fastest
    (axial, 1 cm elements, 1.8e6 rad/s) to the forcing frequency squared, 8e7, times 1 / (2 zeta) = 20 at the
    31 Hz peak: 2e9 eps = 4e-7; 1e-6 relative and 1e-6 rad (measured 3.5e-8 rad at 31 Hz)."""
    from nsfem.analysis import response

    over = ['reduction.method="none"', "mesh.elements=100"]
    speeds = [24.0, 31.0]
    scene, model, sparse = _report(over, speeds)
    assert sparse["ndof"] > response.DENSE_LIMIT
    monkeypatch.setattr(response, "DENSE_LIMIT", 10**6)
    dense = _report(over, speeds)[2]
    for name, v in sparse["sensors"].items():
        assert np.asarray(v["amplitude_m"]) == pytest.approx(dense["sensors"][name]["amplitude_m"], rel=1e-6)
        d = (np.asarray(v["phase_deg"]) - dense["sensors"][name]["phase_deg"] + 180.0) % 360.0 - 180.0
        assert np.abs(d).max() < math.degrees(1e-6)


def test_an_undamped_resonance_hit_exactly_is_refused_with_the_speed():
    """A Jeffcott rotor without damping at exactly its natural frequency: the dynamic stiffness is singular,
    refused naming the speed (the response is unbounded there)."""
    undamped = [a for a in JEFFCOTT if ".c" not in a] + [f"bearing.{i}.c{a}{a}=0.0" for i in (0, 1) for a in "yz"]
    scene = load_scene("critical_speed", undamped)
    model = build_model(scene)
    fn = math.sqrt(K / _jeffcott_mass(model)) / (2 * math.pi)
    with pytest.raises(NsfemError, match="singular"):
        response_report(scene, model, np.array([fn]), scene_reduction(scene.reduction, model))
