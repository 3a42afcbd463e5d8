"""Chunks specialised to the switches their runs share (issue 35, wtftc.sim.specialise):
the options switched off cost nothing, and every number stays the general chunk's."""

from dataclasses import replace

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.sim import integrate, specialise
from wtftc.sim.rhs import rhs_function

#: the physical AFTC with issue 34's options on (the NREL 5-MW candidate's) and off
OPTIONS_ON = {"phys_obs_omega": 3.0, "phys_obs_omega_max": 4.5, "phys_ps_pitch": 0.02,
              "phys_td_gain": 0.02, "phys_td_lpf": 2.0}


def _prepared(raw: dict):
    rc = config.make_config(raw)
    return rc, cases._prepare(rc, check=False)[0]


def test_the_switches_are_the_options_by_name_with_their_defaults():
    rc, _ = _prepared({"controller": "physical", "case": 4})
    found = {lay.names("physical_params")[i]: v
             for i, v in specialise.switch_entries(rc.loop).items()}
    assert found == {**dict.fromkeys(OPTIONS_ON, 0.0), "phys_actuator_model": 1.0}
    pi, _ = _prepared({"controller": "pi", "case": 2})
    assert [lay.names("pi_params")[i] for i in specialise.switch_entries(pi.loop)] == \
        ["pi_lpf_corner", "pi_ps_pitch"]
    paper, _ = _prepared({"controller": "paper", "case": 3})
    assert specialise.switch_entries(paper.loop) == {}


def test_the_options_are_folded_all_off_or_not_at_all():
    rc, off = _prepared({"controller": "physical", "case": 2})
    _, on = _prepared({"controller": "physical", "case": 2, "controller_params": {
        "phys_td_gain": 0.02}})
    _, on2 = _prepared({"controller": "physical", "case": 2, "controller_params": {
        "phys_obs_omega": 3.0}})
    options = set(specialise.switch_entries(rc.loop))
    alone = integrate.run_switches(rc.loop, [off])
    assert {i for i, _ in alone} == options
    assert set(alone) == set(specialise.switch_entries(rc.loop).items())
    # any option on in the batch: none folded, so every option set and value shares the
    # one general chunk
    assert integrate.run_switches(rc.loop, [on]) == integrate.run_switches(rc.loop, [on2]) \
        == integrate.run_switches(rc.loop, [off, on]) == ()
    # a tag names what is folded: the folded chunk is compiled apart from the general one
    assert specialise.tag(alone) != "" and specialise.tag(()) == ""


def test_the_options_off_are_folded_out_of_the_physical_step():
    """The physical step with issue 34's options off and folded (the bench's loop, without
    its exact sensors): two thirds of the operations of the general step (4,744 → 3,074
    SX instructions when written)."""
    rc, run = _prepared({"controller": "physical", "case": 3,
                         "turbine_params": {"gen_torque_law": 0.0}})
    loop = replace(rc.loop, fdi=False)  # the loop of a run without the FDI: one SX step
    general = integrate.rk4_step(rhs_function(loop))
    fixed = {"p_ctrl": dict(integrate.run_switches(loop, [run]))}
    folded = integrate.rk4_step(rhs_function(loop), fixed=fixed)
    assert folded.name_in() == general.name_in()
    assert folded.n_instructions() < 0.7 * general.n_instructions(), (
        folded.n_instructions(), general.n_instructions())


@pytest.mark.parametrize("raw", [
    # continuous, exact sensors, the options off and the fixed torque (the bench's loop)
    {"controller": "physical", "case": 3, "t_final_s": 20.0,
     "turbine_params": {"gen_torque_law": 0.0},
     "fault": [{"type": "loss_of_effectiveness", "blade": 2, "rho": 0.5, "onset_s": 5.0}]},
    # sampled, noisy sensors and the FDI feeding the accommodation, a lock (the realistic
    # profile, its options off)
    {"controller": "physical", "case": 4, "t_final_s": 20.0, "profile": "realistic",
     "wind": {"kind": "ntm", "mean_mps": 16.0},
     "fault": [{"type": "lock", "blade": 1, "onset_s": 8.0}]},
])
def test_the_specialised_chunk_gives_the_general_ones_numbers(raw, monkeypatch):
    """Outputs, the states the metrics read and the final state, in raw bits (signed zeros
    included: CasADi's folding of x + 0 could part them, and does not on these runs)."""
    rc = config.make_config(raw)
    assert integrate.run_switches(rc.loop, [cases._prepare(rc, check=False)[0]]) != ()
    real = integrate.run_loops
    got = {}
    for spec in (True, False):
        monkeypatch.setattr(integrate, "run_loops", lambda *a, _s=spec, **k: real(
            *a, **{**k, "specialised": _s}))
        got[spec] = cases.run_batch([rc], progress=False)[0]
    assert got[True].steps == got[False].steps == round(raw["t_final_s"] / rc.dt)
    for name in ("outputs", "full", "z_final"):
        a, b = getattr(got[True], name), getattr(got[False], name)
        np.testing.assert_array_equal(a.view(np.uint64), b.view(np.uint64), err_msg=name)
