"""The sampled controller (wtftc.sim.sampled): it converges to the continuous loop as the
interval shrinks, holds its command, delays it by one interval when asked, and the
sensors' noise has the configured statistics, independent across signals, the same for
the same seed."""

from __future__ import annotations

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases

BASE = {"case": 1, "controller": "physical", "t_final_s": 8.0,
        "wind": {"kind": "ntm", "mean_mps": 16.0}, "output_rate_hz": 1000.0}


def _run(keep_states=False, **over):
    rc = config.make_config({**BASE, **over})
    return rc, cases.run(rc, progress=False, keep_states=keep_states)


def test_sampled_loop_converges_to_the_continuous_loop():
    """First order in the interval: the measurements are held over it (zero-order hold),
    so halving the interval halves the rotor-speed difference."""
    ref = _run()[1].column("omega_r")
    errs = []
    for interval in (0.008, 0.004, 0.002, 0.001):
        res = _run(control_interval_s=interval)[1]
        assert res.diverged is None
        errs.append(np.abs(res.column("omega_r") - ref).max())
    slopes = np.diff(np.log(errs)) / np.log(0.5)
    assert np.all((slopes > 0.8) & (slopes < 1.2)), (errs, slopes)
    assert errs[-1] < 5e-5  # rad/s, against a 0.02 rad/s regulation error


def test_command_is_held_over_the_interval():
    rc, res = _run(control_interval_s=0.01, t_final_s=2.0)
    v = res.column("v_1")
    n = rc.loop.interval
    blocks = v[: len(v) // n * n].reshape(-1, n)
    assert np.all(blocks == blocks[:, :1])  # constant within each interval, bit for bit
    assert np.any(np.diff(blocks[:, 0]) != 0)  # and changing between them


def test_delay_applies_each_command_one_interval_late():
    """With the delay, the plant's pitch responds to the command of the previous
    interval: the delayed run's first interval is driven by the trimmed pitch, so its
    blade does not move, while the undelayed blade follows the first command."""
    # off rated speed by 0.02 rad/s: a run starts where its loop rests (issue 31), and a
    # command that equals the trimmed pitch would not show the delay
    kick = {"initial": {"omega_r_offset_rad_s": 0.02}}
    on = _run(control_interval_s=0.01, control_delay=True, t_final_s=1.0, **kick)[1]
    off = _run(control_interval_s=0.01, t_final_s=1.0, **kick)[1]
    n = 10
    # the same first command (same state, same samples)
    assert on.column("v_1")[0] == off.column("v_1")[0]
    beta_on, beta_off = on.column("beta_1")[:n + 1], off.column("beta_1")[:n + 1]
    assert np.ptp(beta_on) < 1e-12 < np.ptp(beta_off)


REALISTIC = {"profile": "realistic", "wind": {"kind": "constant", "speed_mps": 16.0},
             "t_final_s": 60.0, "output_rate_hz": 100.0}


def _noise(res) -> np.ndarray:
    """Every sensor's reading minus the truth, at the sample instants (output rate =
    control rate), in the sensors' order: m1 then m2 of ω_r, ω_g (HSS), β_1..3."""
    gear = lay.defaults("turbine_params")[lay.index("turbine_params", "gearbox_ratio")]
    truth = {"omega_r": res.column("omega_r"),
             "omega_g_hss": gear * res.z[:, lay.index("nrel5mw_states", "omega_g")],
             **{f"beta_meas_{j}": res.column(f"beta_{j}") for j in lay.blades()}}
    cols = [res.column(f"sensor_{s['name']}") - truth[s["measures"]]
            for s in lay.layout()["sensors"]]
    return np.column_stack(cols)[100:]


def test_noise_has_the_benchmark_sigma_and_is_independent():
    rc, res = _run(**REALISTIC, keep_states=True)
    e = _noise(res)
    sigma = ([0.0251, 0.05] + [np.radians(0.2)] * 3) * 2
    # 5900 samples: σ known to about 1 %
    for k in range(10):
        assert e[:, k].std() == pytest.approx(sigma[k], rel=0.05), k
        assert abs(e[:, k].mean()) < 4 * sigma[k] / np.sqrt(len(e))
    c = np.corrcoef(e.T)
    assert np.abs(c[np.triu_indices(10, 1)]).max() < 0.06  # 4.6/sqrt(n): independent
    # white from one sample to the next
    for k in (0, 2, 7):
        assert abs(np.corrcoef(e[:-1, k], e[1:, k])[0, 1]) < 0.06
    # the controllers see each pitch as the mean of its two sensors (σ/√2) and the rotor
    # speed mostly through the generator's sensors (σ 0.05/N/√2 ≈ 0.00036 rad/s, plus the
    # shaft's torsion rate)
    e_pitch = res.column("beta_meas_1")[100:] - res.column("beta_1")[100:]
    assert e_pitch.std() == pytest.approx(np.radians(0.2) / np.sqrt(2), rel=0.05)
    e_speed = res.column("omega_r_meas")[100:] - res.column("omega_r")[100:]
    assert e_speed.std() < 0.002


def test_noise_is_deterministic_from_the_seed():
    short = {**REALISTIC, "t_final_s": 5.0}
    a, b, c = _run(**short)[1], _run(**short)[1], _run(**short, seed=1)[1]
    np.testing.assert_array_equal(a.outputs, b.outputs)
    assert not np.array_equal(a.column("beta_meas_1"), c.column("beta_meas_1"))


def test_resolution_and_bias():
    res = _run(control_interval_s=0.01, t_final_s=2.0, output_rate_hz=100.0,
               sensors={"pitch_resolution_deg": 0.1, "rotor_speed_bias_rad_s": 0.01})[1]
    q = np.radians(0.1)
    b = res.column("sensor_beta_meas_2_m1")
    np.testing.assert_allclose(b / q, np.round(b / q), atol=1e-9)
    assert np.abs(b - res.column("beta_2")).max() <= q / 2 + 1e-12
    np.testing.assert_allclose(res.column("omega_r_meas") - res.column("omega_r"), 0.01,
                               atol=1e-12)


def test_lag_is_first_order():
    """A step of the true pitch is not available; the lag is checked on a constant
    offset: a lagged sensor starting in balance stays in balance, and its state obeys
    ẏ = (x - y)/T (the derivation's check covers the equation; this the wiring)."""
    rc, res = _run(control_interval_s=0.01, t_final_s=2.0, output_rate_hz=100.0,
                   sensors={"rotor_speed_lag_s": 0.5})
    w, wm = res.column("omega_r"), res.column("omega_r_meas")
    # the lagged measurement trails the truth: smaller swings, and it follows a low-pass
    # of it (RK4 of the lag against a discrete first-order filter of the sampled truth)
    y = np.empty_like(w)
    y[0] = w[0]
    a = np.exp(-0.01 / 0.5)
    for k in range(1, len(w)):
        y[k] = a * y[k - 1] + (1 - a) * w[k - 1]
    assert np.abs(wm - y).max() < 0.1 * np.abs(w - w.mean()).max()
    assert np.ptp(wm) < np.ptp(w)
