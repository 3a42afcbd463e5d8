"""The PI baseline's low-pass filter on the rotor speed (issue 34, derivation/pi_baseline.py):
off by default and then the PI as it was; on, the PI regulates the filtered speed, and on the
plant with the blades' edgewise mode it stops feeding the drivetrain mode back into the pitch."""

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.campaign import cases
from wtftc.openfast import turbsim
from wtftc.results.metrics import metrics


def _ctrl(x_ctrl, omega_r, corner):
    """ctrl_pi at 16 m/s-like inputs: the measured rotor speed ``omega_r`` [rad/s], the
    pitch at 0.2 rad, the reference at rated; (command [rad], state derivatives)."""
    p = lay.defaults("pi_params")
    p[lay.index("pi_params", "pi_lpf_corner")] = corner
    meas = [omega_r, omega_r * 97.0, 0.2, 0.2, 0.2]
    out = load("ctrl_pi", "interpreted")(x_ctrl=x_ctrl, meas=meas, yd=[1.26711, 0, 0, 0, 0],
                                          sched=[-3.0e7, 0.0], p_ctrl=p, known_fault=np.zeros(
                                              len(lay.names("fault_inputs"))))
    return float(out["u0"]), np.asarray(out["x_ctrl_dot"]).ravel()


def test_without_the_filter_the_command_ignores_the_filter_state():
    """ω_c = 0 (the default): the command is the PI of the measured speed, whatever the
    filter's state; the state follows ω_r at 1 rad/s, unused."""
    assert lay.defaults("pi_params")[lay.index("pi_params", "pi_lpf_corner")] == 0.0
    a, da = _ctrl([0.2, 1.20], 1.30, 0.0)
    b, db = _ctrl([0.2, 1.35], 1.30, 0.0)
    assert a == b and da[0] == db[0]
    assert da[1] == pytest.approx(1.30 - 1.20, rel=1e-12)


def test_with_the_filter_the_pi_regulates_the_filtered_speed():
    """ω_c > 0: the command follows ω_f, not the measurement (a step of the measured speed
    reaches the command only through ω̇_f = ω_c (ω_r - ω_f))."""
    a, da = _ctrl([0.2, 1.30], 1.30, 6.0)
    b, db = _ctrl([0.2, 1.30], 1.40, 6.0)
    assert a == b  # the same ω_f, a different measurement: the same command
    assert db[1] == pytest.approx(6.0 * (1.40 - 1.30), rel=1e-12)
    c, _ = _ctrl([0.2, 1.40], 1.30, 6.0)
    assert c > a  # a faster filtered speed asks for more pitch


def test_a_negative_corner_is_refused_naming_it():
    """The corner's range is [0, ∞) rad/s (derivation/layout.py CONTROLLER_VALID)."""
    with pytest.raises(config.ConfigError) as exc:
        config.make_config({"controller": "pi", "controller_params": {"pi_lpf_corner": -1.0}})
    assert exc.value.field == "controller_params.pi_lpf_corner"
    assert "a number >= 0 [rad/s]" in str(exc.value)


def _run(corner):
    cfg = {"plant": "tower_edge", "controller": "pi", "t_final_s": 60.0,
           "profile": "realistic", "seed": 0,
           "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B",
                    "field": "turbsim", "rotor_wind": "blades"},
           "turbine_params": {"gen_torque_law": 1.0},
           "controller_params": {"pi_lpf_corner": corner}}
    turbsim.ensure_field(cfg)  # TurbSim's field, as OpenFAST's engine runs it (about 5 s)
    rc = config.make_config(cfg)
    return metrics(rc, cases.run(rc, progress=False))


def test_the_filter_takes_the_drivetrain_mode_out_of_the_pitch_loop():
    """NTM B 16 m/s as the blades sample TurbSim's field (whose 3P and 6P excite the
    drivetrain, docs/validation.md), 60 s, realistic sensors, the tower_edge plant (its
    drivetrain mode at 1.69 Hz, OpenFAST's): a corner of 6 rad/s (0.95 Hz) cuts the shaft
    DEL and the pitch ADC by 40 % or more (measured: 1.02 → 0.47 MN m, 0.26 → 0.08; on 120 s
    1.78 → 0.49 MN m), with the RMS speed error within 10 % (measured +4 %)."""
    off, on = _run(0.0), _run(6.0)
    assert off["diverged"] is None and on["diverged"] is None
    assert on["shaft_torque_del_1hz_Nm"] < 0.6 * off["shaft_torque_del_1hz_Nm"]
    assert on["pitch_adc"] < 0.6 * off["pitch_adc"]
    assert on["rms_speed_error_rad_s"] < 1.1 * off["rms_speed_error_rad_s"]
