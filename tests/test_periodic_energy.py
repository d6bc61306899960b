"""The exact integrator without its energy balance (``energy_balance = False``, the shooting's flows) and the
configurations a lead transient hands to the shooting (issue 36, goal 1: the orbit >= 10x faster than the transient).

The work integrals only read the phases' closed forms, so the states, events and impacts must be the same bit for
bit with the balance off; its overflow guard must still stop a motion that leaves the floating-point range with the
same error. Shared configurations are built from the same system and mode: the shooting's orbit is the same.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

from nsfem import load_scene
from nsfem.errors import IntegrationError, NsfemError
from nsfem.fem.assemble import build_model
from nsfem.integrate import ContactSystem
from nsfem.integrate.base import single_threaded_blas
from nsfem.integrate.event_driven import Exact
from nsfem.periodic import periodic_orbit
from nsfem.periodic.flow import FlowMap
from nsfem.reduce import scene_reduction


@functools.lru_cache(maxsize=2)
def _system(name: str):
    scene = load_scene(name)
    model = build_model(scene)
    red = scene_reduction(scene.reduction, model)
    system = ContactSystem.from_model(model, red, scene.rotation, scene.damping)
    system.info.update(model=model, reduction=red)
    return scene, system


def _run(system, t_end, dt, q0, v0, energy: bool):
    integ = Exact(system, progress=False)
    integ.energy_balance = energy
    with single_threaded_blas(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return integ.run(t_end, dt, q0, v0)


@pytest.mark.parametrize("name, periods", [("crack", 3), ("rub", 2)])
def test_energy_off_keeps_states_and_events_bitwise(name, periods):
    """A crack flow (breathing crack's stick-slip and impacts) and a rub flow (a disk on its stator ring) from the
    scene's initial state: identical outputs, events and impacts with the balance on and off (exact equality: the
    balance only reads what the loop computes), and the balance off leaves the energy record empty."""
    scene, system = _system(name)
    from nsfem.simulate import initial_state

    q0, v0 = initial_state(scene, system.info["model"], system.info["reduction"], system)
    T = periods / scene.rotation.speed_hz
    on = _run(system, T, T / 64, q0, v0, True)
    off = _run(system, T, T / 64, q0, v0, False)
    assert on.events, "the flow must meet events for the comparison to mean something"
    for key in ("t", "q", "v", "gap", "normal_force", "tangential_force", "state"):
        assert np.array_equal(getattr(on, key), getattr(off, key)), key
    assert on.events == off.events and on.impacts == off.impacts
    assert "relative_residual" in on.energy and off.energy == {}


def test_energy_off_keeps_the_overflow_guard():
    """q'' = 1e6 q from q0 = 1 (q = cosh(1e3 t)): the state overflows at t = 0.7036 s within a phase: the same
    error and the same finite outputs kept with the balance on and off. To t = 0.36 s the state stays finite
    (q ~ 1e156, its energy ~1e312 overflows): neither stops (the balance judges its work integrals, not E), and
    the states are the same."""
    sysm = ContactSystem.from_arrays(M=[[1.0]], Q=[[-1e6]])
    errors = []
    for energy in (True, False):
        with pytest.raises(IntegrationError) as info:
            _run(sysm, 1.0, 1e-2, [1.0], None, energy)
        errors.append(info.value)
    assert str(errors[0]) == str(errors[1]) and "non-finite displacements or velocities" in str(errors[1])
    assert str(errors[1]).startswith("the motion overflowed the floating-point range at t = 0.7")
    assert np.array_equal(errors[0].result.q, errors[1].result.q) and errors[1].result.t.size > 60
    assert np.all(np.isfinite(errors[1].result.q))
    on, off = (_run(sysm, 0.36, 0.36, [1.0], None, e) for e in (True, False))
    assert np.array_equal(on.q, off.q) and np.array_equal(on.v, off.v) and np.all(np.isfinite(off.v))


def test_energy_off_stops_on_a_non_finite_end_state(monkeypatch):
    """A phase whose closed form ends non-finite (its end state forced to inf, as an overflowing phase ends without
    an output inside it) stops with the same error with the balance on and off: the state's guard."""
    from nsfem.integrate.configuration import Phase

    sysm = ContactSystem.from_arrays(M=[[1.0]], Q=[[1.0]])
    monkeypatch.setattr(Phase, "state_at", lambda self, t: (np.full(1, np.inf), np.full(1, np.inf)))
    errors = []
    for energy in (True, False):
        with pytest.raises(IntegrationError) as info:
            _run(sysm, 1.0, 1.0, [1.0], None, energy)
        errors.append(str(info.value))
    assert errors[0] == errors[1] and errors[1].startswith("the motion overflowed the floating-point range at t = 1 s")


@pytest.mark.parametrize("route", ["flowmap", "store"])
def test_shared_configurations_give_the_same_orbit(route):
    """The crack's shooting from a 3-period lead transient, with the lead's configurations handed over and without:
    the same Newton iterates bit for bit (a configuration depends on the system and mode alone), so the same orbit,
    residual history and multipliers; with them shared the shooting builds none of the lead's again. The lead is a
    FlowMap called period by period (the study's) or one exact run keeping them in a store (``nsfem periodic``'s
    transient through ``configurations``)."""
    scene, system = _system("crack")
    from nsfem.simulate import initial_state

    q0, v0 = initial_state(scene, system.info["model"], system.info["reduction"], system)
    T = 1.0 / scene.rotation.speed_hz
    if route == "flowmap":
        lead = FlowMap(system, 0.0, T)
        q, v = q0, v0
        for _ in range(3):
            f = lead(q, v, jacobian=False)
            q, v = f.q, f.v
        kept = dict(lead._integrator.kept()["modes"])
    else:
        lead = {}
        integ = Exact(system, progress=False, configurations=lead, energy_balance=False)
        with single_threaded_blas(), np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            res = integ.run(3 * T, T, q0, v0)
        q, v = res.q[:, -1].copy(), res.v[:, -1].copy()
        kept = dict(lead["modes"])
        assert lead["system"] is system and res.energy == {}
    assert kept, "the lead must have met configurations for the sharing to mean something"
    alone = periodic_orbit(system, T, q, v, tol=1e-9)
    shared = periodic_orbit(system, T, q, v, tol=1e-9, lead=lead)
    assert alone.converged and shared.converged
    assert alone.t0 == shared.t0 and alone.history == shared.history
    assert np.array_equal(alone.q0, shared.q0) and np.array_equal(alone.v0, shared.v0)
    assert np.array_equal(alone.multipliers, shared.multipliers)
    store = lead._integrator.kept() if route == "flowmap" else lead
    assert all(store["modes"][k] is c for k, c in kept.items())   # the lead's, not rebuilt
    assert math.isfinite(shared.residual)


def test_share_serves_every_section():
    """A FlowMap runs its system from its section t0 on the forcing's clock (``Exact.run(t_start=t0)``), so a lead's
    configurations at t0 = 0 are those of every section (they depend on the system and mode alone): a map at
    t0 = T/4 takes them and its flow is, bit for bit, that of a map that built its own (states, monodromy, events),
    building none of the lead's again; a map of another system is refused."""
    scene, system = _system("crack")
    T = 1.0 / scene.rotation.speed_hz
    lead = FlowMap(system, 0.0, T)
    first = lead(None, None, jacobian=False)
    assert system.harmonic and first.result.events
    kept = dict(lead._integrator.kept()["modes"])
    shared, alone = FlowMap(system, 0.25 * T, T), FlowMap(system, 0.25 * T, T)
    assert shared.share(lead)
    a, b = shared(first.q, first.v), alone(first.q, first.v)
    assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v) and np.array_equal(a.monodromy, b.monodromy)
    assert [e["t"] for e in a.result.events] == [e["t"] for e in b.result.events]
    assert a.result.t[0] == 0.25 * T and a.result.t[-1] == 0.25 * T + T   # (times on the forcing's clock)
    assert all(lead._integrator.kept()["modes"][k] is c for k, c in kept.items())
    other = ContactSystem.from_arrays(M=[[1.0]], Q=[[1.0]])
    assert not FlowMap(other, 0.0, 1.0).share(lead)


def test_a_store_of_another_system_is_refused():
    """Configurations kept for one system are wrong for another (their matrices): a store that names another system
    (or is no dict) is refused in one line; an empty one is taken and filled."""
    a = ContactSystem.from_arrays(M=[[1.0]], Q=[[1.0]])
    b = ContactSystem.from_arrays(M=[[1.0]], Q=[[4.0]])
    store = {}
    _ = Exact(a, progress=False, configurations=store).run(1.0, 0.5, [1.0], None)
    assert store["system"] is a and store["modes"]
    for bad in (store, [1]):
        with pytest.raises(NsfemError, match="configurations: a store") as info:
            Exact(b, configurations=bad)
        assert "\n" not in str(info.value)
    assert Exact(a, configurations=store).kept()["modes"] is store["modes"]
