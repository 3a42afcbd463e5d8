"""The closed-loop simulator: integrator order, determinism, regulation, faults, signs."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.results.metrics import metrics
from wtftc.sim import integrate

WIND_14 = {"kind": "constant", "speed_mps": 14.0}


def _run(**over):
    rc = config.make_config({"t_final_s": 30.0, "wind": WIND_14, **over})
    res = cases.run(rc, progress=False)
    return rc, res, metrics(rc, res)


def test_rk4_converges_with_order_4_against_dop853():
    """The simulator's RK4 step and mapaccum chunks on a smooth closed loop (the paper's
    plant, observer and controller with d1(t) exogenous) against SciPy DOP853 at rtol 1e-12.

    On the NREL 5-MW loop the paper's gains keep the blades on the 8°/s rate limit (a
    relay-like limit cycle, docs/cases.md): that vector field is not smooth and no
    fixed-step method shows order 4 there, so the order is measured where it exists.
    """
    from wtftc.artefacts.loader import load
    from wtftc.verify.checks import Signals, initial_state

    f = load("closed_loop_paper")
    sig = Signals()
    args = [sig.yd(0.0), lay.defaults("fault_inputs"), lay.defaults("plant_params"),
            lay.defaults("controller_params")]
    args[0][1:] = 0.0  # constant reference: the step holds it over each step
    z0 = initial_state()
    t_end = 1.0

    def rhs(t, z):
        return np.array(f(z, sig.d1(t), *args)[0]).ravel()

    ref = solve_ivp(rhs, (0, t_end), z0, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
    # below dt ≈ 1e-3 the observer/controller's fast modes are resolved (asymptotic range)
    dts = np.array([1e-3, 5e-4, 2.5e-4, 1.25e-4])
    errors = []
    for dt in dts:
        n = int(round(t_end / dt))
        chunk = integrate.rk4_step(f, exogenous="d1", report="y").mapaccum("chunk", n)
        tk = np.arange(n) * dt
        d3 = np.vstack([sig.d1(tk), sig.d1(tk + dt / 2), sig.d1(tk + dt)])
        z_end = np.array(chunk(z0, d3, *args, dt)[0])[:, -1]
        errors.append(np.max(np.abs(z_end - ref) / (np.abs(ref) + 1e-3)))
    slope = np.polyfit(np.log(dts), np.log(errors), 1)[0]
    assert 3.8 < slope < 4.2, (errors, slope)
    assert errors[-1] < 1e-6


def test_same_seed_same_numbers_and_seed_matters():
    over = {"wind": {"kind": "paper_random"}, "t_final_s": 10.0}
    a = _run(seed=3, **over)[1]
    b = _run(seed=3, **over)[1]
    c = _run(seed=4, **over)[1]
    assert np.array_equal(a.outputs, b.outputs)
    assert not np.array_equal(a.column("wind"), c.column("wind"))


def test_case1_nrel5mw_regulates_rotor_speed():
    """Corrected sign, IEC NTM class B at 16 m/s (10.8-23.3 m/s in these 60 s, mostly
    above rated): RMS error within 1 % of rated (the settling band) and no excursion beyond
    3 %. Measured: 0.60 % and 2.1 %. The paper's random wind around 12 m/s is below rated
    11.4 m/s a third of the time, where no pitch controller can hold the speed (pitch at
    0°, constant-torque generator) and this design winds up: that run is reported
    (docs/cases.md), not bounded here."""
    rc, res, m = _run(wind={"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"},
                      t_final_s=60.0)
    assert m["diverged"] is None
    assert m["rms_speed_error_rad_s"] < 0.01 * rc.reference
    assert m["max_abs_speed_error_rad_s"] < 0.03 * rc.reference
    assert m["overspeed_peak_over_rated"] < 1.03


def test_case3_is_not_worse_than_case2():
    """The paper's setting (random wind around 12 m/s, default fault at 20 s), 40 s.

    "Not worse" within 5 %: with the paper's gains the loop rides the rate limit and
    absorbs the loss of effectiveness by itself, so eq (49)'s accommodation changes the
    error by about 1 % either way (docs/cases.md gives the measured figures)."""
    m2 = _run(case=2, t_final_s=40.0, wind={"kind": "paper_random"})[2]
    m3 = _run(case=3, t_final_s=40.0, wind={"kind": "paper_random"})[2]
    assert m2["diverged"] is None and m3["diverged"] is None
    assert m3["rms_speed_error_after_fault_rad_s"] <= 1.05 * m2["rms_speed_error_after_fault_rad_s"]
    assert m3["max_abs_speed_error_rad_s"] <= 1.05 * m2["max_abs_speed_error_rad_s"]


def test_sign_as_written_pitches_the_wrong_way_and_stalls_the_rotor():
    """Paper-notes defect 2: with the control direction as written the law pitches the wrong
    way, toward feather, while the rotor is below its reference; the rotor slows until it
    leaves the operating envelope (below 0.2 × rated: stalled; 23.4 s), where the run is
    recorded as lost, with the reason. (Before the operating envelope it ran on to 90° of
    pitch and a rotor at a fraction of rated, reported as not diverged; with the floor at
    0.3 × rated it was lost at 7.2 s.)"""
    rc, res, m = _run(control_sign=1, t_final_s=30.0,
                      turbine_params={"gen_torque_law": 0.0})  # the paper's fixed torque
    lost = m["diverged"]
    assert lost is not None and "the rotor stalled" in lost["reason"], lost
    assert 15.0 < lost["t_s"] < 30.0
    assert res.t[-1] <= lost["t_s"] and np.all(np.isfinite(res.outputs))
    beta = np.degrees(res.column("beta_1"))
    assert beta[-1] > beta[0] + 30.0  # toward feather, away from the power it needs
    w = res.column("omega_r")
    assert w[-1] < 0.31 * rc.param("omega_g_rated") and np.all(np.diff(w[res.t > 1.0]) < 0)
    corrected = _run(t_final_s=30.0)[2]
    assert corrected["diverged"] is None


def test_a_rotor_that_runs_away_is_recorded_as_lost():
    """A blade that cannot pitch (rate limit 1e-4 rad/s) under a step from 12 to 25 m/s:
    the rotor accelerates past 2 × rated, the operating envelope's bound, and the run stops
    there with the reason (it used to run on, reported as not diverged)."""
    wind = {"kind": "steps", "speed_mps": 12.0, "steps": [[5.0, 25.0]]}
    rc, res, m = _run(controller="physical", wind=wind, t_final_s=30.0,
                      turbine_params={"pitch_rate_max": 1e-4})
    lost = m["diverged"]
    assert lost is not None and "the rotor ran away" in lost["reason"], lost
    assert 5.0 < lost["t_s"] < 15.0
    assert res.column("omega_r").max() <= 2.0 * rc.param("omega_g_rated")
    assert res.t[-1] <= lost["t_s"]


def test_a_real_divergence_stops_with_its_time_cause_and_last_finite_state():
    from conftest import DIVERGING_RUN

    rc = config.make_config(DIVERGING_RUN)
    res = cases.run(rc, progress=False)
    m = metrics(rc, res)
    assert m["diverged"] is not None
    assert 10.0 < m["diverged"]["t_s"] < 40.0
    assert "xhat_4" in m["diverged"]["reason"]
    last = m["diverged"]["last_finite_state"]
    assert all(np.isfinite(v) and abs(v) <= 1e8 for v in last.values())
    assert np.all(np.isfinite(res.outputs))  # nothing after the blow-up is reported
    assert res.t[-1] <= m["diverged"]["t_s"]


def test_wind_step_up_raises_the_pitch():
    wind = {"kind": "steps", "speed_mps": 14.0, "steps": [[10.0, 18.0]]}
    rc, res, m = _run(wind=wind, t_final_s=25.0)
    beta = np.degrees(np.mean([res.column(f"beta_{j}") for j in (1, 2, 3)], axis=0))
    before = beta[(res.t > 8) & (res.t < 10)].mean()
    after = beta[res.t > 22].mean()
    assert after > before + 3.0  # the 18 m/s trim is about 7° above the 14 m/s one


def test_default_fault_locks_blade_1_where_it_is():
    rc, res, m = _run(case=2, t_final_s=30.0)
    b1 = res.column("beta_1")
    at_onset = b1[np.searchsorted(res.t, 20.0)]
    np.testing.assert_allclose(b1[res.t > 25], at_onset, atol=np.radians(0.05))
    locked = [f for f in m["config"]["fault_resolved"] if f["type"] == "lock"]
    assert locked and locked[0]["angle_deg"] == pytest.approx(np.degrees(at_onset), abs=0.05)


@pytest.mark.parametrize("onset_s", [20.0, 20.00037, 19.99962])
def test_lock_where_it_is_binds_at_an_onset_off_the_step_grid(onset_s):
    """A sweep draws onsets at random: a lock "wherever the blade is" must read the angle on
    the step nearest its onset. Unbound, it commanded NaN: the plant's position clip turned
    that into 0° and the paper's controller, told the fault (case 3), returned NaN."""
    fault = [{"blade": 1, "type": "lock", "angle_deg": "current", "onset_s": onset_s}]
    rc, res, m = _run(case=3, fault=fault, t_final_s=26.0)
    assert m["diverged"] is None
    b1 = res.column("beta_1")
    at_onset = b1[np.searchsorted(res.t, 20.0)]
    assert np.degrees(at_onset) > 3.0  # far from the 0° an unbound lock would drive it to
    np.testing.assert_allclose(b1[res.t > 22], at_onset, atol=np.radians(0.05))
    locked = [f for f in m["config"]["fault_resolved"] if f["type"] == "lock"]
    assert locked[0]["angle_deg"] == pytest.approx(np.degrees(at_onset), abs=0.05)


def test_a_divergence_names_the_states_or_outputs_that_failed():
    """The control law can return NaN while every state is still finite: the record then
    names the outputs (it once read "non-finite ... in " with nothing after it)."""
    names, out_names = ["omega_r", "beta_1"], ["u0", "v_1", "wind"]
    z_prev = np.array([1.0, 0.1])
    zz = np.array([[1.0, 1.0, 1.0, np.nan], [0.1, 0.1, 2e8, np.nan]])
    oo = np.array([[0.0, 0.0, np.nan, np.nan], [0.0, 0.0, np.nan, np.nan],
                   [14.0, 14.0, 14.0, 14.0]])
    i, rec = integrate.divergence(zz, oo, z_prev, names, out_names, k=100, dt=0.01)
    assert i == 2 and rec["t_s"] == pytest.approx(1.03)
    assert rec["reason"] == "non-finite or |state| > 1e8 in beta_1; non-finite outputs u0, v_1"
    assert rec["last_finite_state"] == {"omega_r": 1.0, "beta_1": 0.1}
    oo[:, 2] = 0.0
    oo[:2, 1] = np.nan  # outputs fail first, at a finite state
    i, rec = integrate.divergence(zz, oo, z_prev, names, out_names, k=100, dt=0.01)
    assert i == 1 and rec["reason"] == "non-finite outputs u0, v_1"


def test_too_large_dt_is_refused_with_the_reason():
    rc = config.make_config({"dt_s": 0.09, "t_final_s": 0.9, "wind": WIND_14,
                            "controller_params": {"c": [60, 60, 60, 60]}})
    from wtftc.errors import ConfigError

    with pytest.raises(ConfigError, match="RK4 is stable only"):
        cases.run(rc, progress=False)


def test_sensor_and_hydraulic_faults_act_from_their_onset():
    faults = [{"blade": 3, "type": "sensor_gain", "onset_s": 5.0, "gain": 1.2},
              {"blade": 2, "type": "sensor_fixed", "onset_s": 5.0, "value_deg": 30.0},
              {"blade": 1, "type": "air_in_oil", "onset_s": 5.0, "ramp_s": 2.0}]
    rc, res, m = _run(case=2, fault=faults, t_final_s=10.0)
    after, before = res.t > 5.0, res.t < 5.0
    # each fault acts on its sensor (m1, the default) alone
    np.testing.assert_allclose(res.column("sensor_beta_meas_3_m1")[after],
                               1.2 * res.column("beta_3")[after], rtol=1e-12)
    np.testing.assert_allclose(res.column("sensor_beta_meas_2_m1")[after], np.radians(30.0),
                               rtol=1e-12)
    for j in (1, 2, 3):
        np.testing.assert_allclose(res.column(f"sensor_beta_meas_{j}_m2"),
                                   res.column(f"beta_{j}"), rtol=1e-12)
    np.testing.assert_allclose(res.column("sensor_beta_meas_1_m1"), res.column("beta_1"),
                               rtol=1e-12)
    np.testing.assert_allclose(res.column("sensor_beta_meas_3_m1")[before],
                               res.column("beta_3")[before], rtol=1e-12)
    # air in oil slows blade 1's actuator (ω_n 11.11 → 3.42 rad/s): it lags the others
    lag = np.abs(res.column("beta_1") - res.column("beta_2"))
    assert lag[res.t > 7.0].max() > 10 * max(lag[before].max(), 1e-6)
    sched = res.schedule.actuator(np.array([4.0, 6.0, 8.0]))
    wn1 = sched[lay.index("actuator_faults", "omega_n_1")]
    np.testing.assert_allclose(wn1, [11.11, (11.11 + 3.42) / 2, 3.42])


def test_another_turbines_cp_table_is_used(tmp_path):
    from dataclasses import replace

    from wtftc.model.cp_table import nrel5mw_cp_table, write_cp_table

    t = nrel5mw_cp_table()
    path = tmp_path / "Cp_Ct_Cq.scaled.txt"
    write_cp_table(replace(t, cp=t.cp * 1.1), path)
    rc, res, m = _run(cp_table=str(path), t_final_s=2.0)
    rc0, res0, m0 = _run(t_final_s=2.0)
    # 10 % more Cp at the same wind: the rated balance needs more pitch
    assert res.column("beta_1")[0] > res0.column("beta_1")[0] + np.radians(0.3)  # 0.7° here
    assert m["config"]["cp_table"] == str(path)


def test_pi_baseline_regulates_and_does_not_wind_up():
    """The gain-scheduled PI (derivation/pi_baseline.py) through the same loop: within 3 %
    RMS of rated under NTM class B at 16 m/s (measured 1.9 %), and on the paper's wind,
    which is below rated a third of the time, its conditional integration keeps it finite
    where the paper's design diverges."""
    rc, res, m = _run(controller="pi", t_final_s=60.0,
                      wind={"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"})
    assert m["diverged"] is None
    assert m["rms_speed_error_rad_s"] < 0.03 * rc.reference
    assert m["overspeed_peak_over_rated"] < 1.1
    rc, res, m = _run(controller="pi", t_final_s=60.0, wind={"kind": "paper_random"})
    assert m["diverged"] is None
    assert abs(res.column("integrator")).max() < np.radians(90.0)
    # the schedule follows the pitch: |∂T/∂β| grows with pitch above rated
    g = res.column("dT_dbeta")
    beta = np.mean([res.column(f"beta_{j}") for j in (1, 2, 3)], axis=0)
    hi, lo = beta > np.radians(8), (beta > np.radians(1)) & (beta < np.radians(4))
    assert g[hi].mean() < g[lo].mean() < 0


def test_held_fault_columns_are_reused_only_while_the_schedules_stay_constant():
    """Issue 19: a batch's chunks recomputed every run's fault columns, most of the serial
    Python time per chunk. Held columns are now reused while every schedule stays constant
    from when they were computed: across an onset, or while a drift grows, they are
    computed again, and what is reused equals what would be computed."""
    from types import SimpleNamespace

    from wtftc.model import faults
    s = faults.Schedule(faults.parse_faults([
        {"blade": 2, "type": "loss_of_effectiveness", "rho": 0.5, "onset_s": 10.0},
        {"blade": 1, "type": "pitch_sensor_drift", "onset_s": 20.0}]))
    run, held = SimpleNamespace(schedule=s, ctrl_schedule=s), {}

    def at(t):
        return integrate._fault_columns(run, {}, held, np.array([t]), np.array([t]))

    first = at(1.0)
    assert at(5.0) is first  # nothing changes before the onset
    after = at(12.0)
    assert after is not first
    assert np.array_equal(after["actuator_faults"], s.actuator(np.array([12.0])))
    assert at(15.0) is after
    drifting = at(21.0)
    assert at(22.0) is not drifting  # a drift grows: never reused
    assert np.array_equal(at(23.0)["sensor_faults"], s.sensor(np.array([23.0])))


def test_uneven_shards_on_worker_threads_give_the_runs_alone(capsys):
    """Five runs on three worker threads (shards of 1, 2 and 2 runs, issue 19): each run's
    numbers are its own alone, bit for bit, in the order given; one progress line counts
    all five runs."""
    base = {"controller": "physical", "t_final_s": 12.0, "dt_s": 1e-3,
            "wind": {"kind": "ntm", "mean_mps": 18.0, "turbulence_class": "B"},
            "fault": [{"type": "lock", "blade": 2, "onset_s": 4.3}]}
    rcs = [config.make_config({**base, "seed": s, "case": 3 + s % 2}) for s in range(5)]
    assert [list(r) for r in integrate._shards(5, 3)] == [[0], [1, 2], [3, 4]]
    assert len(integrate._shards(2, 8)) == 2
    single = [cases.run(rc, progress=False) for rc in rcs]
    capsys.readouterr()
    batch = cases.run_batch(rcs, threads=3, progress=True)
    for a, b in zip(single, batch, strict=True):
        np.testing.assert_array_equal(a.outputs, b.outputs)
        np.testing.assert_array_equal(a.z_final, b.z_final)
    assert "5 runs × 12.0 s simulated" in capsys.readouterr().err


def test_an_error_in_a_worker_thread_reaches_the_caller(monkeypatch):
    rcs = [config.make_config({"controller": "physical", "t_final_s": 2.0, "seed": s})
           for s in range(2)]

    def broken(*args, **kwargs):
        raise RuntimeError("wind file went away")

    monkeypatch.setattr(integrate, "_put_chunk", broken)
    with pytest.raises(RuntimeError, match="wind file went away"):
        cases.run_batch(rcs, threads=2, progress=False)
