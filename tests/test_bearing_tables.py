"""Speed-dependent bearings (``speeds_hz`` tables): read at each speed of a Campbell diagram, at the scene's speed
everywhere else, against constant bearings and ROSS; validation of the tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from nsfem.analysis.campbell import campbell_report
from nsfem.analysis.modes import natural_frequencies
from nsfem.errors import SceneError
from nsfem.fem import build_model
from nsfem.scene import scene_from_tree


def rotor_tree(bearing: dict, theory="rayleigh", speed_hz=0.0, disk=True, elements=20):
    """A 1 m steel shaft of 50 mm on two equal isotropic bearings, a disk in its middle, inertial frame."""
    tree = {"shaft": {"length": 1.0, "section": "circle", "diameter": 0.05, "E": 2.1e11, "rho": 7850.0},
            "beam": {"theory": theory}, "mesh": {"elements": elements}, "reduction": {"method": "none"},
            "rotation": {"frame": "inertial", "speed_hz": speed_hz, "gravity": 0.0},
            "bearing": [{"x": 0.0, **bearing}, {"x": 1.0, **bearing}, {"x": 0.0, "kxx": 1e7}]}
    if disk:
        tree["disk"] = [{"x": 0.5, "mass": 20.0, "polar_inertia": 0.2, "diametral_inertia": 0.1}]
    return tree


def campbell_of(tree, speeds, count=6):
    scene = scene_from_tree(tree)
    return np.array(campbell_report(scene, build_model(scene), speeds, count)["frequencies_hz"], dtype=float)


SPEEDS = np.linspace(0.0, 40.0, 5)


def test_a_constant_table_gives_the_constant_bearings_diagram_to_round_off():
    # the same coefficients at every speed: the operators differ only by adding a zero change, so the eigenvalues
    # agree to the eigen solver's round-off (1e-12 relative on these well separated roots; 1e-10 a margin)
    constant = {"kyy": 2e6, "kzz": 2e6, "cyy": 300.0, "czz": 300.0}
    table = {"speeds_hz": [0.0, 20.0, 50.0], "kyy": [2e6] * 3, "kzz": [2e6] * 3, "cyy": [300.0] * 3,
             "czz": 300.0}
    np.testing.assert_allclose(campbell_of(rotor_tree(table), SPEEDS), campbell_of(rotor_tree(constant), SPEEDS),
                               rtol=1e-10)


TABLE = {"speeds_hz": [0.0, 25.0, 50.0], "kyy": [1e6, 3e6, 4e6], "kzz": [1e6, 3e6, 4e6],
         "cyy": [0.0, 0.0, 0.0], "czz": [0.0, 0.0, 0.0]}


def at(speed):
    """The table's coefficients at ``speed`` by hand (linear between its rows)."""
    k = float(np.interp(speed, TABLE["speeds_hz"], TABLE["kyy"]))
    return {"kyy": k, "kzz": k}


@pytest.mark.parametrize("speed", [10.0, 25.0, 40.0])
def test_a_varying_table_at_each_speed_is_the_constant_bearing_with_its_coefficients_there(speed):
    # gyroscopic rotor (Rayleigh shaft, disk with polar inertia): the diagram's column at `speed` is the diagram of
    # the rotor whose bearings are constant at the table's value there (same operators to round-off: 1e-10)
    table = campbell_of(rotor_tree(TABLE), [speed])[0]
    const = campbell_of(rotor_tree(at(speed)), [speed])[0]
    np.testing.assert_allclose(table, const, rtol=1e-10)
    # and the table does move the frequencies (the check can fail): the standstill bearings give others
    assert abs(table[0] / campbell_of(rotor_tree(at(0.0)), [speed])[0][0] - 1) > 1e-3


def test_without_gyroscopic_terms_the_diagram_at_speed_is_modes_of_the_bearings_there():
    # Euler-Bernoulli shaft, point-mass disk, no damping, inertial frame: nothing depends on the speed but the
    # bearings, so the whirl frequencies at S are the non-rotating natural frequencies with the bearings at S
    # (two eigen solvers, each to ~1e-12: 1e-9)
    S = 35.0
    diagram = campbell_of(rotor_tree(TABLE, theory="euler-bernoulli", disk=False), [S], count=4)[0]
    modes = natural_frequencies(build_model(scene_from_tree(rotor_tree(at(S), theory="euler-bernoulli",
                                                                        disk=False))), count=8)
    # (the diagram lists the axial mode on the thrust bearing too, as modes does)
    np.testing.assert_allclose(diagram, np.sort(modes.frequencies_hz)[:4], rtol=1e-9)


def test_modes_and_runs_use_the_table_at_the_scenes_speed():
    scene = scene_from_tree(rotor_tree(TABLE, speed_hz=37.5))
    k = scene.stack.bearings[0].K
    assert k == ((3.5e6, 0.0), (0.0, 3.5e6))   # halfway between 3e6 at 25 Hz and 4e6 at 50 Hz, exactly
    f_table = natural_frequencies(build_model(scene), count=4).frequencies_hz
    f_const = natural_frequencies(build_model(scene_from_tree(rotor_tree(at(37.5), speed_hz=37.5))),
                                  count=4).frequencies_hz
    np.testing.assert_allclose(f_table, f_const, rtol=1e-12)   # the same matrices: round-off only


#: ROSS 2.3.0 (/work/rossvenv): 50 `ShaftElement(L=0.02, odl=0.05, shear_effects=False, rotary_inertia=True,
#: gyroscopic=True)` of steel (E 2.1e11, rho 7850), `BearingElement(kxx=[1e6, 4e6], kyy=[1e6, 4e6], cxx=[0, 0],
#: frequency=[0, 200])` at nodes 0 and 50 (two rows: ROSS interpolates them with interp1d kind=1, linear, as nsfem;
#: its kxx_interpolated(100) = 2.5e6), `run_modal(speed=100 rad/s)`: sorted wd / 2 pi [Hz]. The same rotor with
#: constant 2.5e6 N/m bearings gives the same six numbers in ROSS.
ROSS_TABLE_HZ = [69.33068981603824, 69.34069803780568, 149.73870503043725, 149.79042408328863, 295.75790684680805,
                 295.983308796797]


def test_a_speed_table_matches_ross_frequency_table_at_speed():
    # the same Rayleigh elements and nodes, bearings read at 100 rad/s from a two-row table (linear in both):
    # the forward/backward pairs agree to 2.3e-9, the eigen solvers' round-off (ROSS's equal V/W pairs of the
    # stepped-shaft test split by 1e-9); 5e-9 is a margin of 2. nsfem also lists the axial mode on its thrust
    # bearing, which ROSS's model has not: each ROSS frequency is matched to the nearest of nsfem's
    w = 100.0 / (2 * math.pi)
    bearing = {"speeds_hz": [0.0, 200.0 / (2 * math.pi)], "kyy": [1e6, 4e6], "kzz": [1e6, 4e6]}
    f = campbell_of(rotor_tree(bearing, disk=False, elements=50), [w], count=8)[0]
    nearest = [f[np.argmin(abs(f - r))] for r in ROSS_TABLE_HZ]
    np.testing.assert_allclose(nearest, ROSS_TABLE_HZ, rtol=5e-9)
    assert len(set(nearest)) == len(ROSS_TABLE_HZ)   # six distinct roots, none matched twice


@pytest.mark.parametrize("bearing, key, words", [
    ({"speeds_hz": [0.0, 50.0], "kyy": [1e6, 2e6, 3e6]}, "bearing.0.kyy", "3 values for the 2 speeds"),
    ({"kyy": [1e6, 2e6]}, "bearing.0.kyy", "needs the bearing's speeds_hz"),
    ({"speeds_hz": [0.0, 50.0], "kyy": 1e6}, "bearing.0.speeds_hz", "at least one coefficient given as a list"),
    ({"speeds_hz": [10.0, 5.0], "kyy": [1e6, 2e6]}, "bearing.0.speeds_hz", "increase strictly"),
    ({"speeds_hz": [10.0], "kyy": [1e6]}, "bearing.0.speeds_hz", "at least two speeds"),
    ({"speeds_hz": [-1.0, 5.0], "kyy": [1e6, 2e6]}, "bearing.0.speeds_hz", ">= 0"),
    ({"speeds_hz": [0.0, 5.0], "kyy": [1e6, "a"]}, "bearing.0.kyy.1", "must be a number"),
    ({"speeds_hz": [0.0, 5.0], "kyy": [1e6, -2e6]}, "bearing.0.kyy", "positive semidefinite"),
    ({"speeds_hz": [5.0, 50.0], "kyy": [1e6, 2e6], "kzz": [1e6, 2e6]}, "bearing.0.speeds_hz",
     "0 Hz lies outside the bearing's table [5, 50] Hz"),
])
def test_bad_tables_are_refused_naming_the_key(bearing, key, words):
    with pytest.raises(SceneError) as err:
        scene_from_tree(rotor_tree(bearing))
    assert err.value.key == key and words in err.value.reason, str(err.value)


def test_a_diagram_beyond_the_table_is_refused_before_computing():
    scene = scene_from_tree(rotor_tree(TABLE))
    with pytest.raises(SceneError, match=r"bearing.0.speeds_hz: 60 Hz lies outside the bearing's table \[0, 50\] Hz"):
        campbell_report(scene, build_model(scene), [0.0, 60.0], 4)
