"""Fatigue and pitch-duty figures (wtftc/results/loads.py) against cases computed by hand."""

from __future__ import annotations

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.errors import ConfigError
from wtftc.results import loads
from wtftc.results.metrics import metrics


@pytest.mark.parametrize("m", [3.0, 4.0, 10.0])
def test_the_del_of_a_sine_is_its_range_times_the_frequency_to_one_over_m(m):
    """A cosine of amplitude A at f Hz over whole periods: f T cycles of range 2A, so
    DEL at 1 Hz over T is (f T (2A)^m / T)^(1/m) = 2A f^(1/m)."""
    amplitude, f, duration = 3.0e6, 0.4, 100.0
    t = np.arange(0.0, duration + 1e-9, 0.01)
    x = 5.0e6 + amplitude * np.cos(2 * np.pi * f * t)  # a mean does not count
    assert loads.del_1hz(x, duration, m) == pytest.approx(2 * amplitude * f ** (1 / m),
                                                          rel=1e-9)


def test_the_del_of_a_two_level_block_load_is_the_miner_sum():
    """30 cycles of range 10 and 200 of range 4 over 50 s, m = 4:
    DEL = ((30·10⁴ + 200·4⁴) / 50)^(1/4) = 9.6825..., and the damage per 10 minutes is
    the sum scaled by 600/50."""
    block = np.array([0.0, 10.0] * 30 + [0.0, 4.0] * 200 + [0.0])
    miner = 30 * 10.0**4 + 200 * 4.0**4
    assert loads.damage_sum(block, 4.0) == pytest.approx(miner, rel=1e-12)
    assert loads.del_1hz(block, 50.0, 4.0) == pytest.approx((miner / 50.0) ** 0.25,
                                                            rel=1e-12)
    assert loads.damage_per_10min(block, 50.0, 4.0) == pytest.approx(miner * 12.0,
                                                                     rel=1e-12)


def test_a_ten_minute_run_has_its_del_from_its_damage_per_ten_minutes():
    x = np.random.default_rng(0).standard_normal(6001).cumsum()
    f = loads.fatigue(x, 600.0, 4.0)
    assert f["del_1hz"] == pytest.approx((f["damage_per_10min"] / 600.0) ** 0.25, rel=1e-12)
    assert f["max_abs"] == pytest.approx(np.max(np.abs(x)))


def test_a_constant_load_does_no_damage():
    assert loads.del_1hz(np.full(100, 7.0), 10.0, 4.0) == 0.0


def test_reversals_count_turns_larger_than_the_hysteresis_only():
    """A triangle wave of 1° amplitude from 0, 20 periods: two turns a period (at +1° and
    −1°), 40; jitter of ±0.04° on it adds none at the 0.1° hysteresis; the jitter alone
    gives none, and with a hysteresis below it, a turn at almost every sample."""
    one = np.radians(np.concatenate([np.linspace(0, 1, 50), np.linspace(1, -1, 100)[1:],
                                     np.linspace(-1, 0, 50)[1:]]))
    wave = np.tile(one[:-1], 20)
    jitter = np.radians(0.04) * np.where(np.arange(wave.size) % 2, 1.0, -1.0)
    assert loads.reversals(wave) == 40
    assert loads.reversals(wave + jitter) == 40
    assert loads.reversals(jitter) == 0
    assert loads.reversals(jitter, hysteresis=np.radians(0.05)) > 100


@pytest.mark.parametrize("seed", range(40))
def test_turning_points_leave_rainflow_and_reversals_unchanged(seed):
    """Rainflow counting and the play operator see only a series' extrema: reduced to its
    turning points (loads.turning_points, which makes 1-kHz series cheap), a random walk,
    white noise, a series with plateaus or a monotone one counts exactly as the whole
    series through the `rainflow` package and a sample-by-sample play operator."""
    import rainflow

    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 400))
    x = [rng.normal(size=n).cumsum(), rng.normal(size=n), np.sort(rng.normal(size=n)),
         np.repeat(np.round(rng.normal(size=n).cumsum(), 1), 3)][seed % 4]
    whole = sum(c * r**4 for r, c in rainflow.count_cycles(x)) if x.size > 1 else 0.0
    assert loads.damage_sum(x, 4.0) == pytest.approx(whole, rel=1e-12, abs=0.0)

    def play(x, h):  # the definition, sample by sample
        y, direction, count = x[0], 0, 0
        for v in x[1:]:
            new = max(v - h, min(v, y))
            if new != y:
                step = 1 if new > y else -1
                count += direction == -step
                direction, y = step, new
        return count

    for h in (0.0, 0.05, 0.5):
        assert loads.reversals(x, h) == play(x, h)


def test_the_pitch_duty_of_a_ramp_at_half_the_rate_limit():
    """Three blades ramping at 4°/s against an 8°/s limit for 10 s: ADC 0.5, a travel
    rate of 4°/s, 40° of travel each, no reversal."""
    dt = 0.01
    t = np.arange(0.0, 10.0 + 1e-9, dt)
    beta = np.radians(4.0) * np.column_stack([t, t, t])
    duty = loads.pitch_duty(beta, dt, np.radians(8.0))
    assert duty["adc"] == pytest.approx(0.5, rel=1e-9)
    assert duty["travel_rate_deg_s"] == pytest.approx(4.0, rel=1e-9)
    assert duty["travel_deg"] == pytest.approx(40.0, rel=1e-9)
    assert duty["reversals"] == 0


# --- the figures in metrics.json -------------------------------------------------------

#: on the hub-height point series (not a run's default rotor average, issue 31): its
#: sub-rotor eddies turn the pitch often enough in 20 s for the reversal counts to differ
RUN = {"controller": "pi", "t_final_s": 20.0, "output_rate_hz": 100.0,
       "turbine_params": {"gen_torque_law": 1.0},
       "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B",
                "rotor_radius_m": 0.0}}


def _metrics(**over):
    rc = config.make_config({**RUN, **over})
    res = cases.run(rc, progress=False)
    return rc, res, metrics(rc, res)


def test_the_shaft_del_is_the_plants_shaft_torque_counted():
    """metrics.json's shaft DEL is the rainflow DEL of k_s θ_s + d_s (ω_r − ω_g) with the
    plant's own (mismatched) stiffness and damping, and its Wöhler exponent is the
    [loads] key's."""
    rc, res, m = _metrics(mismatch={"shaft_stiffness": 1.1, "shaft_damping": 0.9},
                          loads={"shaft_wohler_exponent": 3.0})
    tp = lay.values("turbine_params", rc.p_plant)
    # from the states at every step (1 ms), after the start-up window (a quarter of this
    # 20-s run: 5 s), over n dt
    t = np.arange(len(res.full)) * res.dt
    keep = t >= m["transient_s"]
    assert m["transient_s"] == 5.0 and m["metrics_rate_hz"] == pytest.approx(1000.0)
    shaft = (tp["k_s"] * res.state("theta_s") + tp["d_s"] * (
        res.state("omega_r") - res.state("omega_g")))[keep]
    duration = keep.sum() * res.dt
    assert duration == pytest.approx(15.0)
    assert m["shaft_wohler_exponent"] == 3.0
    assert m["shaft_torque_del_1hz_Nm"] == pytest.approx(
        loads.del_1hz(shaft, duration, 3.0), rel=1e-12)
    assert m["shaft_torque_max_abs_Nm"] == pytest.approx(np.max(np.abs(shaft)), rel=1e-12)
    # σ about the window's own mean (issue 34's fault-free goal against ROSCO)
    assert m["shaft_torque_std_Nm"] == pytest.approx(np.std(shaft), rel=1e-12)
    assert 0 < m["shaft_torque_std_Nm"] < 0.2 * np.mean(shaft)
    # the shaft carries the rated torque, 4.18 MN m on the NREL 5-MW's low-speed shaft
    assert 3.5e6 < np.mean(shaft) < 5.0e6
    assert 0 < m["shaft_torque_del_1hz_Nm"] < m["shaft_torque_max_abs_Nm"]
    assert 0 < m["pitch_adc"] < 1 and m["pitch_reversals"] > 0


def test_below_rated_the_own_reference_is_the_optimal_tip_speed_ratios():
    """In a steady 8 m/s the torque law holds the rotor near λ_opt v / R (0.96 rad/s), far
    below rated speed: against rated the RMS error is 0.30 rad/s, against the own
    reference less than a fifth of it; nothing is above rated."""
    _, _, m = _metrics(t_final_s=120.0, output_rate_hz=20.0,
                       wind={"kind": "constant", "speed_mps": 8.0})
    assert m["rms_speed_error_own_above_rated_rad_s"] is None
    assert m["rms_speed_error_rad_s"] > 0.25
    assert m["rms_speed_error_own_below_rated_rad_s"] < 0.2 * m["rms_speed_error_rad_s"]
    assert m["time_above_1p1_rated_s"] == 0.0


@pytest.mark.parametrize("loads_table, field", [
    ({"shaft_wohler_exponent": 0.5}, "loads.shaft_wohler_exponent"),
    ({"wohler": 4}, "loads.wohler"),
    ({"reversal_hysteresis_deg": "0.1"}, "loads.reversal_hysteresis_deg"),
    ({"tower_wohler_exponent": 25.0}, "loads.tower_wohler_exponent"),
])
def test_a_bad_loads_table_is_refused_naming_the_key(loads_table, field):
    with pytest.raises(ConfigError) as err:
        config.make_config({**RUN, "loads": loads_table})
    assert err.value.field == field


def test_the_reversal_hysteresis_key_is_used():
    """A wider hysteresis counts fewer reversals of the same run."""
    _, _, fine = _metrics()
    _, _, coarse = _metrics(loads={"reversal_hysteresis_deg": 1.0})
    assert coarse["pitch_reversals"] < fine["pitch_reversals"]


@pytest.mark.parametrize("over, field", [
    ({"fdi": {"rate_limited_uncertainty": 11.0}}, "fdi.rate_limited_uncertainty"),
    ({"wind": {"kind": "ntm", "mean_mps": 12.0, "rotor_radius_m": -3.0}},
     "wind.rotor_radius_m"),
])
def test_the_new_fdi_and_wind_keys_refuse_a_value_out_of_range(over, field):
    with pytest.raises(ConfigError) as err:
        config.make_config({**RUN, **over})
    assert err.value.field == field
