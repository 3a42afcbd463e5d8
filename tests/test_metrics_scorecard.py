"""The scorecard's per-run metrics (wtftc/results/metrics.py, loads.py) on series whose
answer is known: the content in the 1P and 3P bands, the energy a faulted turbine keeps,
the loads' extremes from a fault's onset on, the blade-root flapwise DEL of the worst
blade, the largest pitch rate; None where the plant has no blade or the run no fault."""

from __future__ import annotations

import numpy as np
import pytest

from wtftc import config
from wtftc.campaign import cases
from wtftc.results import loads
from wtftc.results.metrics import (
    Signals,
    blade_cost,
    energy_after,
    loads_after_onset,
    metrics,
    spectra,
)

#: a rotor at 12.1 rpm (the NREL 5-MW's rated speed): 1P = 0.2017 Hz
OMEGA = 12.1 * np.pi / 30
F1P = OMEGA / (2 * np.pi)
DT, DURATION = 0.01, 600.0


def _sig(tower=None, flap=None, n=None, t0=0.0) -> Signals:
    n = n or int(round(DURATION / DT))
    t = t0 + np.arange(n) * DT
    return Signals(t=t, dt=DT, rate="simulation", omega_r=np.full(n, OMEGA),
                   beta=np.zeros((n, 3)), shaft=np.zeros(n), tower=tower, t0=t0,
                   blade_flap=flap)


def test_a_sine_at_1p_has_its_amplitude_over_root_two_in_the_1p_band_and_none_in_3p():
    """A sine of amplitude A at the rotor frequency (off the periodogram's bins, with a
    mean and a 3P sine of another amplitude beside it): the 1P band's standard deviation
    is A/√2, the 3P band's B/√2. 0.5 %: over 600 s the ±10 % band is ±12 bins wide and the
    Hann window's leakage past it, and each sine's into the other's band, is below 1e-4 of
    the power."""
    t = np.arange(int(round(DURATION / DT))) * DT
    a, b = 2.0e6, 0.7e6
    tower = 4.0e7 + a * np.sin(2 * np.pi * F1P * t + 0.3) + b * np.sin(
        2 * np.pi * 3 * F1P * t + 1.1)
    out = spectra(_sig(tower=tower), None)
    assert out["tower_base_1p_std_Nm"] == pytest.approx(a / np.sqrt(2), rel=5e-3)
    assert out["tower_base_3p_std_Nm"] == pytest.approx(b / np.sqrt(2), rel=5e-3)
    assert out["blade_root_flap_1p_std_Nm"] is None  # no blade on this plant
    # a sine outside both bands (2P) leaves them all but empty
    two_p = a * np.sin(2 * np.pi * 2 * F1P * t)
    quiet = spectra(_sig(tower=two_p), None)
    assert quiet["tower_base_1p_std_Nm"] < 1e-3 * a
    assert quiet["tower_base_3p_std_Nm"] < 1e-3 * a


def test_the_band_sums_to_the_variance_over_the_whole_spectrum():
    """Parseval: the band from 0 Hz to Nyquist holds the windowed variance of white noise
    exactly (to rounding, 1e-12)."""
    x = np.random.default_rng(3).standard_normal(4001)
    w = np.hanning(x.size)
    whole = loads.band_std(x, DT, 0.0, 0.5 / DT)
    assert whole == pytest.approx(np.sqrt(np.sum(((x - x.mean()) * w) ** 2) / np.sum(w**2)),
                                  rel=1e-12)
    assert loads.harmonic_std(x, DT, 0.0, 1) is None  # a standing rotor has no 1P


def test_the_energy_of_a_constant_power_is_power_times_the_time_after_the_onset():
    """3 MW from an onset at 12.5 s to the end at 40 s: 82.5 MJ (exact on the samples),
    whatever came before; None without a fault; a run that ended at its onset kept 0."""
    t = np.arange(0.0, 40.0 + 1e-9, 0.05)
    p = np.where(t < 12.5, 9.0e6, 3.0e6)
    assert energy_after(t, p, 12.5) == pytest.approx(3.0e6 * 27.5, rel=1e-12)
    assert energy_after(t, p, None) is None
    assert energy_after(t, p, 40.0) == 0.0


def test_the_extremes_after_the_onset_ignore_a_larger_value_before_it():
    """A spike before the onset (10 s) is 5 times anything after it: the extremes after
    the onset are the later ones; None without a fault, and the blade's None on a plant
    without blades."""
    sig = _sig(n=3000)
    sig.shaft = np.where(np.abs(sig.t - 5.0) < 0.5, 5.0e6, 1.0e6)
    sig.shaft[2500] = -1.5e6  # after the onset, negative: |.| counts
    sig.tower = np.where(sig.t < 10.0, 9.0e7, 2.0e7)
    flap = np.full((3000, 3), 1.0e7)
    flap[500, 0], flap[2000, 2] = 6.0e7, -1.2e7
    post = sig.t >= 10.0
    got = loads_after_onset(sig, post)
    assert got["shaft_torque_max_abs_after_onset_Nm"] == 1.5e6
    assert got["tower_base_max_abs_after_onset_Nm"] == 2.0e7
    assert got["blade_root_flap_max_abs_after_onset_Nm"] is None
    sig.blade_flap = flap
    assert loads_after_onset(sig, post)["blade_root_flap_max_abs_after_onset_Nm"] == 1.2e7
    assert set(loads_after_onset(sig, np.zeros(3000, bool)).values()) == {None}


def test_the_blade_del_is_the_worst_blades_and_its_spectra_follow_it():
    """Three blades at 1P of amplitudes 1, 3 and 2 MN m over a mean: blade 2 is the worst;
    its DEL is 2A f^(1/m) (a whole number of cycles: the sine's closed form, 1e-6 for the
    ends of a window that cuts a cycle), its damage per 10 min the Miner sum over 600 s,
    the extreme the largest |moment| of any blade, and the 1P band is blade 2's."""
    f = 0.2  # 120 whole cycles in 600 s
    t = np.arange(int(round(DURATION / DT)) + 1) * DT
    amps = (1.0e6, 3.0e6, 2.0e6)
    flap = np.column_stack([5.0e6 + a * np.cos(2 * np.pi * f * t) for a in amps])
    sig = _sig(flap=flap, n=t.size)
    sig.omega_r = np.full(t.size, 2 * np.pi * f)
    m = loads.BLADE_WOHLER_EXPONENT
    got = blade_cost(sig, DURATION, m)
    assert got["blade_root_flap_worst_blade"] == 2
    assert got["blade_root_flap_del_1hz_Nm"] == pytest.approx(2 * 3.0e6 * f ** (1 / m),
                                                              rel=1e-6)
    assert got["blade_root_flap_damage_per_10min"] == pytest.approx(
        f * DURATION * (6.0e6) ** m, rel=1e-6)
    assert got["blade_root_flap_max_abs_Nm"] == pytest.approx(8.0e6)
    band = spectra(sig, got["blade_root_flap_worst_blade"])["blade_root_flap_1p_std_Nm"]
    assert band == pytest.approx(3.0e6 / np.sqrt(2), rel=5e-3)
    assert set(blade_cost(_sig(), DURATION, m).values()) == {None, m}


#: a runaway of blade 1 to feather on wtftc's tower plant: the actuator's rate limit is
#: met, and there is a fault to score from
RUNAWAY = {"plant": "tower", "controller": "physical", "t_final_s": 30.0, "seed": 2,
           "control_interval_s": 0.01, "case": 2,
           "fault": {"type": "runaway", "blade": 1, "onset_s": 10.0, "target_deg": 90.0},
           "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B",
                    "rotor_radius_m": 63.0}}


def test_a_native_run_of_a_runaway_scores_the_rate_limit_and_what_it_kept():
    """On wtftc's own tower plant: the largest pitch rate of a runaway to feather is the
    actuator's rate limit (8°/s; 1e-6 for the central difference at the rate limit's
    corners), the energy after the onset the trapezoid of η P_gen over the outputs from
    10 s on, the shaft's and tower's extremes after the onset those of the states from
    10 s on; no blade flap on this plant (None)."""
    rc = config.make_config(RUNAWAY)
    res = cases.run(rc, progress=False)
    m = metrics(rc, res)
    assert m["pitch_rate_max_abs_deg_s"] == pytest.approx(np.degrees(rc.param(
        "pitch_rate_max")), rel=1e-6)
    eta = rc.param("gen_efficiency")
    a = res.t >= 10.0
    assert m["energy_after_onset_J"] == pytest.approx(
        np.trapezoid(res.column("P_gen")[a] * eta, res.t[a]), rel=1e-12)
    assert m["energy_after_onset_J"] > 0.5 * m["mean_electrical_power_W"] * 20.0
    t = np.arange(len(res.full)) * res.dt
    after = t >= 10.0 - 1e-9
    tower = rc.param("tower_stiffness") * res.state("tower_x") * rc.param("tower_moment_arm")
    assert m["tower_base_max_abs_after_onset_Nm"] == pytest.approx(
        np.max(np.abs(tower[after])), rel=1e-12)
    assert m["shaft_torque_max_abs_after_onset_Nm"] <= m["shaft_torque_max_abs_Nm"]
    assert m["tower_base_1p_std_Nm"] > 0 and m["tower_base_3p_std_Nm"] > 0
    for k in ("blade_root_flap_del_1hz_Nm", "blade_root_flap_damage_per_10min",
              "blade_root_flap_max_abs_Nm", "blade_root_flap_max_abs_after_onset_Nm",
              "blade_root_flap_1p_std_Nm", "blade_root_flap_3p_std_Nm"):
        assert m[k] is None, k


def test_a_fault_free_native_run_has_no_after_onset_figures():
    free = {k: v for k, v in RUNAWAY.items() if k != "fault"}
    rc = config.make_config({**free, "case": 1, "t_final_s": 12.0})
    m = metrics(rc, cases.run(rc, progress=False))
    for k in ("shaft_torque_max_abs_after_onset_Nm", "tower_base_max_abs_after_onset_Nm",
              "blade_root_flap_max_abs_after_onset_Nm", "energy_after_onset_J"):
        assert m[k] is None, k
    assert m["pitch_rate_max_abs_deg_s"] > 0


def test_the_blade_exponent_is_a_loads_setting_checked_like_the_others():
    assert config.loads_options({})["blade_wohler_exponent"] == loads.BLADE_WOHLER_EXPONENT
    assert config.loads_options({"loads": {"blade_wohler_exponent": 12.0}})[
        "blade_wohler_exponent"] == 12.0
    with pytest.raises(config.ConfigError, match="loads.blade_wohler_exponent"):
        config.loads_options({"loads": {"blade_wohler_exponent": 25.0}})
