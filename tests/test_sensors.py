"""Sensor faults, model mismatch and their refusals: each sensor fault does to its
measurement what its type says, from its onset on, and nothing before; the plant under
mismatch is another plant than the controllers' model; bad values are refused naming
the field."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.errors import ConfigError

ONSET = 1.0
BASE = {"case": 2, "controller": "physical", "t_final_s": 3.0, "control_interval_s": 0.01,
        "wind": {"kind": "constant", "speed_mps": 16.0}, "output_rate_hz": 100.0}
GEAR = lay.defaults("turbine_params")[lay.index("turbine_params", "gearbox_ratio")]


def _run(fault: dict, **over):
    rc = config.make_config({**BASE, **over, "fault": [{"onset_s": ONSET, **fault}]})
    res = cases.run(rc, progress=False, keep_states=True)
    assert res.diverged is None
    return rc, res


def _signals(res, signal: str, k: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(reading of sensor m<k>, true) of a signal at the output times (= the sample
    instants)."""
    if signal == "omega_g_hss":
        return res.column(f"sensor_omega_g_hss_m{k}"), GEAR * res.z[
            :, lay.index("nrel5mw_states", "omega_g")]
    if signal == "omega_r":
        return res.column(f"sensor_omega_r_m{k}"), res.column("omega_r")
    j = signal[-1]
    return res.column(f"sensor_beta_meas_{j}_m{k}"), res.column(f"beta_{j}")


#: (fault table, signal, expected measurement from (true, t))
CASES = {
    "pitch_sensor_stuck": ({"type": "pitch_sensor_stuck", "blade": 2, "value_deg": 5.0},
                           "beta_2", lambda x, t: np.full_like(x, np.radians(5.0))),
    "pitch_sensor_gain": ({"type": "pitch_sensor_gain", "blade": 3, "gain": 1.2},
                          "beta_3", lambda x, t: 1.2 * x),
    "pitch_sensor_offset": ({"type": "pitch_sensor_offset", "blade": 1, "offset_deg": -1.0},
                            "beta_1", lambda x, t: x - np.radians(1.0)),
    "pitch_sensor_drift": ({"type": "pitch_sensor_drift", "blade": 1, "rate_deg_s": 0.5},
                           "beta_1", lambda x, t: x + np.radians(0.5) * (t - ONSET)),
    "rotor_speed_sensor_stuck": ({"type": "rotor_speed_sensor_stuck", "value_rad_s": 1.4},
                                 "omega_r", lambda x, t: np.full_like(x, 1.4)),
    "rotor_speed_sensor_gain": ({"type": "rotor_speed_sensor_gain", "gain": 1.1},
                                "omega_r", lambda x, t: 1.1 * x),
    "rotor_speed_sensor_offset": ({"type": "rotor_speed_sensor_offset", "offset_rad_s": 0.1},
                                  "omega_r", lambda x, t: x + 0.1),
    "generator_speed_sensor_stuck": ({"type": "generator_speed_sensor_stuck",
                                      "value_rad_s": 140.0}, "omega_g_hss",
                                     lambda x, t: np.full_like(x, 140.0)),
    "generator_speed_sensor_gain": ({"type": "generator_speed_sensor_gain", "gain": 0.9},
                                    "omega_g_hss", lambda x, t: 0.9 * x),
    "generator_speed_sensor_offset": ({"type": "generator_speed_sensor_offset",
                                       "offset_rad_s": 2.0}, "omega_g_hss",
                                      lambda x, t: x + 2.0),
}


@pytest.mark.parametrize("name", list(CASES))
def test_sensor_fault_acts_on_its_sensor_from_its_onset(name):
    fault, signal, expected = CASES[name]
    k = 2 if "offset" in name else 1  # the offsets on sensor m2, the others on m1
    rc, res = _run({**fault, "sensor": k})
    meas, true = _signals(res, signal, k)
    before, after = res.t < ONSET, res.t >= ONSET
    np.testing.assert_allclose(meas[before], true[before], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(meas[after], expected(true[after], res.t[after]), rtol=1e-12,
                               atol=1e-12)
    # every other sensor untouched, the failed one's partner too
    others = ["omega_r", "omega_g_hss", "beta_1", "beta_2", "beta_3"]
    for other, kk in ((o, m) for o in others for m in (1, 2) if (o, m) != (signal, k)):
        m, x = _signals(res, other, kk)
        np.testing.assert_allclose(m, x, rtol=1e-12, atol=1e-9 if "omega_g" in other else 0)


def test_precision_degradation_multiplies_the_noise():
    rc, res = _run({"type": "pitch_sensor_precision", "blade": 2, "factor": 3.0},
                   profile="realistic", t_final_s=30.0, control_interval_s=0.01)
    e = res.column("sensor_beta_meas_2_m1") - res.column("beta_2")
    ratio = e[res.t >= ONSET].std() / e[res.t < ONSET].std()
    assert ratio == pytest.approx(3.0, rel=0.2)  # 100 samples before the onset
    e1 = res.column("sensor_beta_meas_1_m1") - res.column("beta_1")
    assert e1.std() == pytest.approx(np.radians(0.2), rel=0.1)
    e2 = res.column("sensor_beta_meas_2_m2") - res.column("beta_2")  # its partner: healthy
    assert e2.std() == pytest.approx(np.radians(0.2), rel=0.1)


def test_old_sensor_fault_names_are_aliases():
    rc = config.make_config({**BASE, "fault": [
        {"type": "sensor_fixed", "blade": 1, "value_deg": 3.0, "onset_s": 1.0},
        {"type": "sensor_gain", "blade": 2, "gain": 1.1, "onset_s": 1.0}]})
    assert [f.type for f in rc.faults] == ["pitch_sensor_stuck", "pitch_sensor_gain"]


def test_mismatch_changes_the_plant_not_the_model():
    nominal = config.make_config({**BASE, "case": 1})
    rc = config.make_config({**BASE, "case": 1, "mismatch": {"inertia": 1.1, "cp_scale": 0.95,
                                                             "actuator_omega_n": 0.9}})
    assert rc.loop == nominal.loop  # the controllers' and the FDI's model: the same
    tp = lay.values("turbine_params", rc.p_plant)
    tn = lay.values("turbine_params", nominal.p_turbine)
    assert tp["J_r"] == pytest.approx(1.1 * tn["J_r"]) and tp["J_g"] == pytest.approx(
        1.1 * tn["J_g"])
    assert tp["omega_n_nominal"] == pytest.approx(0.9 * tn["omega_n_nominal"])
    a = cases.run(nominal, progress=False)
    b = cases.run(rc, progress=False)
    assert not np.allclose(a.column("omega_r"), b.column("omega_r"), rtol=1e-6)
    # the plant's Cp is the table's times cp_scale (at the common trimmed start)
    assert b.column("cp")[0] / a.column("cp")[0] == pytest.approx(0.95, rel=1e-12)


BAD = [
    ({"sensors": {"pitch_noise_deg": -0.1}, "control_interval_s": 0.01},
     "sensors.pitch_noise_deg"),
    ({"sensors": {"pitch_noise_deg": 0.1}}, "sensors.pitch_noise_deg"),  # continuous time
    ({"sensors": {"pitch_noise": 0.1}, "control_interval_s": 0.01}, "sensors.pitch_noise"),
    ({"control_interval_s": 0.0015}, "control_interval_s"),
    ({"control_interval_s": -0.01}, "control_interval_s"),
    ({"control_delay": True}, "control_delay"),
    ({"control_delay": "yes", "control_interval_s": 0.01}, "control_delay"),
    ({"profile": "noisy"}, "profile"),
    ({"mismatch": {"inertia": 0.0}}, "mismatch.inertia"),
    ({"fdi": {"test_pulse_deg": 1.0}}, "fdi.test_pulse_deg"),  # continuous time
    ({"control_interval_s": 0.01, "fdi": {"test_pulse_deg": 1.0, "test_width_s": 4.0}},
     "fdi.test_width_s"),
    ({"fdi": {"target_false_alarms_per_hour": 0.0}}, "fdi.target_false_alarms_per_hour"),
    ({"fdi": {"threshold": 1.0}}, "fdi.threshold"),
    ({"mismatch": {"mass": 1.1}}, "mismatch.mass"),
    ({"case": 2, "fault": [{"type": "pitch_sensor_wobble", "blade": 1}]}, "fault[0].type"),
    ({"case": 2, "fault": [{"type": "rotor_speed_sensor_gain", "blade": 1}]},
     "fault[0].blade"),
    ({"case": 2, "fault": [{"type": "pitch_sensor_gain", "blade": 1, "gain": -1}]},
     "fault[0].gain"),
    ({"case": 2, "fault": [{"type": "pitch_sensor_gain", "blade": 1, "sensor": 3}]},
     "fault[0].sensor"),
    ({"case": 2, "fault": [{"type": "lock", "blade": 1, "sensor": 2}]},  # an actuator's
     "fault[0].sensor"),
]


@pytest.mark.parametrize("over, field", BAD, ids=[f for _, f in BAD])
def test_bad_measurement_input_names_the_field(over, field):
    with pytest.raises(ConfigError) as exc:
        config.make_config({"t_final_s": 2.0, **over})
    assert exc.value.field == field


def test_cli_refuses_an_interval_off_the_grid_in_one_line(tmp_path):
    p = subprocess.run([sys.executable, "-m", "wtftc.cli", "run", "--control-interval", "0.0015",
                        "--t-final", "1", "--out", str(tmp_path / "x")],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "control_interval_s" in lines[0] and "0.0015" in lines[0]
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("fault", [
    {"type": "generator_speed_sensor_stuck", "value_rad_s": 1.5},
    {"type": "generator_speed_sensor_gain", "gain": 0.9, "sensor": 2},
    {"type": "rotor_speed_sensor_gain", "gain": 1.1},
    {"type": "rotor_speed_sensor_offset", "offset_rad_s": -0.2, "sensor": 2}])
def test_one_speed_sensor_fault_leaves_the_rotor_regulated(fault):
    """Each speed has two sensors; the virtual sensor (derivation/sensors.py) votes them,
    the failed one out by its distance from the other quantity's sensors, even without the
    FDI (case 2: the loop is not told). Before the second sensors, a generator speed
    sensor stuck near 0 ran the rotor away to 2 × rated, and a rotor speed sensor reading
    10 % high slowed it to below 0.95 × rated (it was the max-select's safe side)."""
    rc = config.make_config({"case": 2, "controller": "physical", "profile": "realistic",
                             "t_final_s": 40.0, "wind": {"kind": "ntm", "mean_mps": 18.0},
                             "fault": [{"onset_s": 10.0, **fault}]})
    res = cases.run(rc, progress=False)
    w = res.column("omega_r")[res.t > 10.0] / rc.param("omega_g_rated")
    assert res.diverged is None and w.max() < 1.1 and abs(w.mean() - 1) < 0.01, fault


@pytest.mark.parametrize("key", list(config.MISMATCH))
def test_each_mismatch_factor_changes_the_plant(key):
    """Every [mismatch] key is used: a factor of 1.1 on it alone changes the run (the
    actuator's under a pitch that moves, above rated with a hydraulic fault's onset)."""
    base = {**BASE, "case": 1, "t_final_s": 4.0,
            "wind": {"kind": "ntm", "mean_mps": 16.0}}
    a = cases.run(config.make_config(base), progress=False)
    b = cases.run(config.make_config({**base, "mismatch": {key: 1.1}}), progress=False)
    cols = ("omega_r", "beta_1", "theta_s", "cp")
    assert max(np.abs(a.column(c) - b.column(c)).max() for c in cols) > 0, key


def test_fdi_keys_are_used():
    """[fdi] model_uncertainty widens the threshold while the pitch moves; the target
    false-alarm rate moves its noise part (wtftc.sim.fdi)."""
    base = {**BASE, "case": 1, "t_final_s": 4.0, "profile": "realistic",
            "wind": {"kind": "ntm", "mean_mps": 16.0}}
    thr = {}
    for name, fdi in (("default", {}), ("wide", {"model_uncertainty": 0.6}),
                      ("loose", {"target_false_alarms_per_hour": 100.0})):
        rc = config.make_config({**base, "fdi": fdi})
        thr[name] = cases.run(rc, progress=False).column("fdi_threshold_1")
    assert np.all(thr["wide"] >= thr["default"]) and np.any(thr["wide"] > thr["default"])
    assert np.all(thr["loose"] < thr["default"])


@pytest.mark.parametrize("interval", [0.0, 0.01])
def test_an_excluded_sensor_leaves_the_controllers_in_both_loops(interval):
    """A pitch sensor offset of 0.08°, inside the voting's tolerance (0.1° with exact
    sensors) but above the FDI's pair threshold (√2 × 0.05°): unaware (case 2) the
    controllers read the two sensors' mean; with the FDI (case 4) they read the healthy
    sensor alone once the failed one is excluded, in the continuous loop and the sampled
    one, and no actuator latch rises."""
    over = {"control_interval_s": interval, "t_final_s": 3.0,
            "wind": {"kind": "ntm", "mean_mps": 16.0}}
    fault = {"type": "pitch_sensor_offset", "blade": 2, "offset_deg": 0.08}
    rc2, res2 = _run(fault, case=2, **over)
    rc4, res4 = _run(fault, case=4, **over)
    a, b = res2.column("sensor_beta_meas_2_m1"), res2.column("sensor_beta_meas_2_m2")
    np.testing.assert_allclose(res2.column("beta_meas_2"), (a + b) / 2, rtol=1e-12)
    excluded = res4.column("fdi_excluded_beta_meas_2_m1") >= 0.5
    assert excluded.any() and not excluded[res4.t < ONSET].any()
    # the controllers' sample is held from the last interval: compare after one more
    after = np.nonzero(excluded)[0][0] + 2
    np.testing.assert_array_equal(res4.column("beta_meas_2")[after:],
                                  res4.column("sensor_beta_meas_2_m2")[after:])
    assert all(res4.column(f"fdi_latch_{j}").max() < 0.5 for j in lay.blades())
    assert res4.column("fdi_excluded_beta_meas_2_m2").max() < 0.5
