"""Peak shaving in the physical AFTC (issue 34, derivation/physical.py pitch_floor): a pitch
floor that rises from 0 at phys_ps_speed to phys_ps_pitch at the reference speed; off (0)
by default, the design as it was. In OpenFAST it removes the near-rated limit cycle with
the tower that the design (and the PI) fall into at 12 m/s."""

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.campaign import cases
from wtftc.results.metrics import metrics

N_W = len([n for n in lay.names("physical_states") if n.startswith("phys_theta_hat")])
FLOOR = 0.035  # rad, 2°
REF = 1.26711  # rad/s, the reference


def _command(omega_r: float, **params) -> float:
    """ctrl_physical's mean command at the measured speed ``omega_r`` with weights that ask
    for a pitch far below the stop (f̂ = -5 rad/s²), so that the floor is what it gives."""
    p = lay.vector("physical_params", params)
    out = load("ctrl_physical", "interpreted")(
        x_ctrl=[*[-5.0] * N_W, omega_r, *[0.0] * (lay.size("physical_states") - N_W - 1)],
        meas=[omega_r, omega_r * 97.0, 0.1, 0.1, 0.1],
        yd=[REF, 0, 0, 0, 0], sched=[-3.0e7, 0.0], p_ctrl=p,
        known_fault=lay.defaults("fault_inputs"))
    return float(np.asarray(out["v"]).ravel()[0])


def test_the_floor_rises_from_the_start_speed_to_the_reference():
    start = lay.vector("physical_params")[lay.index("physical_params", "phys_ps_speed")]
    assert start == pytest.approx(REF / 1.1, rel=1e-4)  # region 2½'s start, slip 10 %
    assert _command(start - 0.05, phys_ps_pitch=FLOOR) == 0.0  # region 2: the stop
    assert _command((start + REF) / 2, phys_ps_pitch=FLOOR) == pytest.approx(FLOOR / 2,
                                                                                rel=1e-9)
    assert _command(REF + 0.01, phys_ps_pitch=FLOOR) == pytest.approx(FLOOR, rel=1e-12)
    for w in (start - 0.05, REF, REF + 0.05):  # off (the default): the stop everywhere
        assert _command(w) == 0.0


def test_the_floor_takes_the_turbines_speeds():
    """The start speed is a fact of the turbine (scaled with its rated speed): on the IEA
    15-MW it is its rated speed / 1.1."""
    rc = config.make_config({"controller": "physical", "turbine": "iea15mw"})
    p = lay.values("physical_params", rc.p_ctrl)
    assert p["phys_ps_speed"] == pytest.approx(p["x_offset_1"] / 1.1, rel=1e-4)


def test_a_floor_out_of_range_is_refused_naming_it():
    with pytest.raises(config.ConfigError) as exc:
        config.make_config({"controller": "physical",
                            "controller_params": {"phys_ps_pitch": 2.0}})
    assert exc.value.field == "controller_params.phys_ps_pitch"


def test_the_pi_takes_the_same_floor():
    """The PI's command (its integrator far below the stop) is the same floor, on its own
    parameters pi_ps_pitch and pi_ps_speed."""
    def pi(omega_r, **params):
        out = load("ctrl_pi", "interpreted")(
            x_ctrl=[-1.0, omega_r], meas=[omega_r, omega_r * 97.0, 0.1, 0.1, 0.1],
            yd=[REF, 0, 0, 0, 0], sched=[-3.0e7, 0.0], p_ctrl=lay.vector("pi_params", params),
            known_fault=lay.defaults("fault_inputs"))
        return float(out["u0"])
    start = lay.vector("pi_params")[lay.index("pi_params", "pi_ps_speed")]
    assert pi(start - 0.05, pi_ps_pitch=FLOOR) == 0.0
    assert pi((start + REF) / 2, pi_ps_pitch=FLOOR) == pytest.approx(FLOOR / 2, rel=1e-9)
    assert pi(REF, pi_ps_pitch=FLOOR) == pytest.approx(FLOOR, rel=1e-12)
    assert pi(REF) == 0.0


def _openfast_12(ps_pitch: float, tmp) -> dict:
    """The physical AFTC on its observer in OpenFAST, NTM B 12 m/s (TurbSim, seed 0), 60 s,
    the benchmark actuator, realistic sensors, the baseline torque law."""
    from wtftc.openfast import turbsim

    cfg = {"engine": "openfast", "profile": "realistic", "controller": "physical", "case": 1,
           "t_final_s": 60.0, "seed": 0, "turbine_params": {"gen_torque_law": 1.0},
           "wind": {"kind": "ntm", "mean_mps": 12.0, "turbulence_class": "B"},
           "controller_params": {"phys_obs_omega": 6.0, "phys_ps_pitch": ps_pitch}}
    turbsim.ensure_field(cfg)  # as every command does first: make_config cannot run TurbSim
    rc = config.make_config(cfg)
    return metrics(rc, cases.run(rc, progress=False, openfast_dir=tmp / f"ps{ps_pitch:g}"))


def test_peak_shaving_ends_the_near_rated_limit_cycle_in_openfast(tmp_path):
    """At 12 m/s in OpenFAST the design limit-cycles with the tower, the pitch bouncing
    off its stop (docs/controllers.md: tower DEL 80 MN m over 120 s, ROSCO's 37); a 2°
    floor near rated takes the tower DEL below 60 % of it and the shaft DEL down too."""
    off, on = _openfast_12(0.0, tmp_path), _openfast_12(FLOOR, tmp_path)
    assert off["diverged"] is None and on["diverged"] is None
    assert on["tower_base_del_1hz_Nm"] < 0.6 * off["tower_base_del_1hz_Nm"]
    assert on["shaft_torque_del_1hz_Nm"] < off["shaft_torque_del_1hz_Nm"]


def test_a_start_speed_at_or_above_the_reference_is_refused_naming_it():
    """The floor rises between the start speed and the reference: a start at the
    reference would divide by zero."""
    with pytest.raises(config.ConfigError) as exc:
        config.make_config({"controller": "pi", "controller_params": {"pi_ps_speed": REF}})
    assert exc.value.field == "controller_params.pi_ps_speed"
    assert "below the reference" in str(exc.value)
