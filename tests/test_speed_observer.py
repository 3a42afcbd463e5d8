"""The physical AFTC's speed observer and its actuator-model switch (issue 34,
derivation/physical.py): off by default and then the design as it was; on, the design runs
on the observer's ω̂_r, its α̇1 is exact, the measured speed reaches the pitch only through
the observer's states, and on the plant with the blades' edgewise mode it stops driving the
drivetrain mode."""

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.campaign import cases
from wtftc.openfast import turbsim
from wtftc.results.metrics import metrics
from wtftc.verify import designs

N_W = len([n for n in lay.names("physical_states") if n.startswith("phys_theta_hat")])


def _ctrl(x_ctrl, omega_r, **params):
    """ctrl_physical at 16 m/s-like inputs: the measured rotor speed ``omega_r`` [rad/s], the
    pitch at 0.2 rad, the reference at rated; (command u0 [rad], state derivatives, diag)."""
    p = lay.vector("physical_params", params)
    meas = [omega_r, omega_r * 97.0, 0.2, 0.2, 0.2]
    out = load("ctrl_physical", "interpreted")(
        x_ctrl=x_ctrl, meas=meas, yd=[1.26711, 0, 0, 0, 0], sched=[-3.0e7, 0.0], p_ctrl=p,
        known_fault=lay.defaults("fault_inputs"))
    return (float(out["u0"]), np.asarray(out["x_ctrl_dot"]).ravel(),
            np.asarray(out["diag"]).ravel())


def _state(w_hat, eta):
    # the tower damper's states (and any after them) at rest
    return [*[0.05] * N_W, w_hat, eta, *[0.0] * (lay.size("physical_states") - N_W - 2)]


def test_alpha1_dot_with_the_observer_against_central_differences():
    """ω_o = 6 rad/s: d α1/dt by central differences along the design model's closed loop
    (the observer's states integrated with it) falls to the generated α̇1 at O(h²), below
    1e-6 relative at the best h, at a point where the weights adapt."""
    fd = designs.alpha_dot_fd("physical", params={"phys_obs_omega": 6.0})
    assert fd.kappa == 1.0 and np.all(np.abs(fd.alpha_dot) > 1e-6)
    assert np.all((1.9 < fd.slopes) & (fd.slopes < 2.1)), (fd.slopes, fd.errors)
    assert np.all(fd.errors.min(axis=0) < 1e-6), fd.errors


def test_with_the_observer_the_controller_computes_the_whole_alpha1_dot():
    """α̇1 runs through ω̂̇_r, a controller state's rate: the computable α̇1 is the full one
    whatever the plant's true ω̇_r (only ḃ is left out, zero here). Without the observer
    they differ by ∂α1/∂ω_r (ω̇_r - ω̇̂_r)."""
    on = designs.DesignModel("physical", {"phys_obs_omega": 6.0})
    off = designs.DesignModel("physical")
    for m in (on, off):
        z = m.rk4(m.z0, 0.0, 1.0, 2000)
        a = m.check_values(z, 1.0)
        gap = abs(a["alpha1_dot_comp"] - a["alpha1_dot_full"])
        if m is on:
            assert gap <= 1e-12 * abs(a["alpha1_dot_full"])
        else:
            assert gap > 1e-6


def test_without_the_observer_its_states_do_not_act():
    """ω_o = 0 (the default): the command is the design on the measured ω_r whatever the
    observer's states; ω̂_r follows ω_r at 1 rad/s, η decays at 1/s, both unused."""
    assert lay.vector("physical_params")[lay.index("physical_params", "phys_obs_omega")] == 0
    a, da, ga = _ctrl(_state(1.20, 0.01), 1.30)
    b, db, gb = _ctrl(_state(1.35, -0.02), 1.30)
    assert a == b and np.array_equal(da[:N_W], db[:N_W]) and np.array_equal(ga, gb)
    assert da[N_W] == pytest.approx(1.30 - 1.20, rel=1e-12) and da[N_W + 1] == -0.01


def test_with_the_observer_the_measured_speed_reaches_the_pitch_only_through_it():
    """ω_o = 6 rad/s: a step of the measured speed leaves the command where it is (no direct
    path, so the drivetrain mode and the noise reach the pitch integrated); it moves the
    observer's innovation, η̇ = 2 ζ_o ω_o (ω_r - ω̂_r - η). A faster ω̂_r asks for more
    pitch. Without the observer the same step moves the command."""
    a, da, _ = _ctrl(_state(1.30, 0.0), 1.30, phys_obs_omega=6.0)
    b, db, _ = _ctrl(_state(1.30, 0.0), 1.40, phys_obs_omega=6.0)
    assert a == b
    assert db[N_W + 1] - da[N_W + 1] == pytest.approx(2 * 0.7 * 6.0 * 0.10, rel=1e-12)
    c, _, _ = _ctrl(_state(1.35, 0.0), 1.30, phys_obs_omega=6.0)
    assert c > a
    assert _ctrl(_state(1.30, 0.0), 1.30)[0] != _ctrl(_state(1.30, 0.0), 1.40)[0]


def test_the_observer_s_corner_scheduled_on_the_mean_pitch():
    """phys_obs_omega_max > 0: ω_o rises linearly with the measured mean pitch from
    phys_obs_omega at phys_obs_pitch_min to phys_obs_omega_max at phys_obs_pitch_max, and
    holds outside: the innovation's rate η̇ = 2 ζ_o ω_o (ω_r − ω̂_r − η) at a pitch of 0.2
    rad is ω_o = 4.5 halfway up a 0.1-0.3 rad ramp from 3 to 6, 3 below it, 6 above it.
    With phys_obs_omega_max = 0 (the default) ω_o is phys_obs_omega, bit for bit. α̇1
    stays exact along the design model (central differences, below 1e-6 relative)."""
    ramp = {"phys_obs_omega": 3.0, "phys_obs_omega_max": 6.0}
    for lo, hi, w_o in ((0.1, 0.3, 4.5), (0.25, 0.3, 3.0), (0.05, 0.15, 6.0)):
        params = {**ramp, "phys_obs_pitch_min": lo, "phys_obs_pitch_max": hi}
        _, d, _ = _ctrl(_state(1.30, 0.0), 1.40, **params)
        assert d[N_W + 1] == pytest.approx(2 * 0.7 * w_o * 0.10, rel=1e-12), (lo, hi)
    fixed = _ctrl(_state(1.30, 0.01), 1.40, phys_obs_omega=3.0)
    assert np.array_equal(fixed[1], _ctrl(_state(1.30, 0.01), 1.40, phys_obs_omega=3.0,
                                           phys_obs_pitch_min=0.1)[1])
    fd = designs.alpha_dot_fd("physical", params={**ramp, "phys_obs_pitch_min": 0.1,
                                                  "phys_obs_pitch_max": 0.3})
    assert np.all((1.9 < fd.slopes) & (fd.slopes < 2.1)), fd.slopes
    assert np.all(fd.errors.min(axis=0) < 1e-6), fd.errors


def test_without_an_actuator_model_the_command_is_alpha1():
    """phys_actuator_model = 0 (a host whose blades take the demand): U = α1, the desired
    mean pitch itself (diag 3), with and without the observer; with the model (the
    default) U inverts the lag and differs from it."""
    for obs in (0.0, 6.0):
        u, _, diag = _ctrl(_state(1.31, 0.001), 1.30, phys_actuator_model=0.0,
                           phys_obs_omega=obs)
        assert u == diag[2]
    u, _, diag = _ctrl(_state(1.31, 0.001), 1.30)
    assert abs(u - diag[2]) > 1e-4


@pytest.mark.parametrize("field, value, allowed", [
    ("phys_obs_omega", -1.0, "a number >= 0 [rad/s]"),
    ("phys_obs_zeta", 0.0, "a number > 0"),
    ("phys_actuator_model", 0.5, "0 or 1")])
def test_the_options_out_of_range_are_refused_naming_them(field, value, allowed):
    with pytest.raises(config.ConfigError) as exc:
        config.make_config({"controller": "physical", "controller_params": {field: value}})
    assert exc.value.field == f"controller_params.{field}"
    assert allowed in str(exc.value), str(exc.value)


def _run(**params):
    cfg = {"plant": "tower_edge", "controller": "physical", "t_final_s": 60.0,
           "profile": "realistic", "seed": 0,
           "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B",
                    "field": "turbsim", "rotor_wind": "blades"},
           "turbine_params": {"gen_torque_law": 1.0}, "controller_params": params}
    turbsim.ensure_field(cfg)  # TurbSim's field, as OpenFAST's engine runs it (about 5 s)
    rc = config.make_config(cfg)
    return metrics(rc, cases.run(rc, progress=False))


def test_the_observer_takes_the_drivetrain_mode_out_of_the_pitch_loop():
    """NTM B 16 m/s as the blades sample TurbSim's field, 60 s, realistic sensors, the
    tower_edge plant (its drivetrain mode at 1.69 Hz, OpenFAST's): the observer at
    ω_o = 6 rad/s cuts the shaft DEL and the pitch ADC by 60 % or more, and the RMS speed
    error does not grow (docs/controllers.md has the 120-s figures)."""
    off, on = _run(), _run(phys_obs_omega=6.0)
    assert off["diverged"] is None and on["diverged"] is None
    assert on["shaft_torque_del_1hz_Nm"] < 0.4 * off["shaft_torque_del_1hz_Nm"]
    assert on["pitch_adc"] < 0.4 * off["pitch_adc"]
    assert on["rms_speed_error_rad_s"] < off["rms_speed_error_rad_s"]


def _drivetrain_mode(obs: float, **turbine) -> tuple[dict, dict]:
    """(the least-damped mode, the margins) of the physical AFTC's exact linear loop on
    tower_edge at 16 m/s, with the baseline torque law (and ``turbine``'s options), the
    observer at ``obs`` rad/s."""
    from wtftc.campaign import linearize as lin

    op = lin.operating_point({"controller": "physical", "plant": "tower_edge",
                              "turbine_params": {"gen_torque_law": 1.0, **turbine},
                              "controller_params": {"phys_obs_omega": obs}}, 16.0)
    row = lin.summary_row(op)
    return ({"omega_n": row["least_damped_omega_n_rad_s"], "zeta": row["least_damped_damping"]},
            {"gain_margin_dB": row["gain_margin_dB"]})


def test_the_observer_makes_the_drivetrain_mode_stable_in_the_linear_loop():
    """`wtftc linearize` on the plant validated against OpenFAST (tower_edge, 16 m/s): the
    design on the measured speed destabilises the drivetrain mode (measured ζ -0.014 at
    10.4 rad/s, gain margin -8.9 dB): its simulations limit-cycle, bounded by the rate
    limit; on the observer at 6 rad/s that mode is damped (ζ 0.012) with 8.2 dB of gain
    margin."""
    pytest.importorskip("control", reason="python-control: pip install 'wtftc[linear]'")
    (off, off_m), (on, on_m) = _drivetrain_mode(0.0), _drivetrain_mode(6.0)
    assert 9.5 < off["omega_n"] < 11.5 and 9.5 < on["omega_n"] < 11.5  # the drivetrain's
    assert off["zeta"] < -0.005 and off_m["gain_margin_dB"] < 0
    assert on["zeta"] > 0.005 and on_m["gain_margin_dB"] > 6.0


def test_constant_torque_above_rated_gives_the_drivetrain_mode_its_damping_back():
    """Issue 34: the baseline law's constant power on the unfiltered generator speed
    (dT/dω = -P/ω²) is negative damping on the generator's side of the drivetrain mode.
    With the law's region 3 at constant torque (vs_constant_torque = 1) the physical AFTC's
    drivetrain mode at 16 m/s (observer at 4.5 rad/s) goes from ζ 0.011 to 0.031 (measured;
    in OpenFAST, with its tower damper, 0.92-0.94 × ROSCO's shaft DEL at 20-24 m/s, seed 0,
    docs/controllers.md)."""
    pytest.importorskip("control", reason="python-control: pip install 'wtftc[linear]'")
    (power, _), (torque, _) = _drivetrain_mode(4.5), _drivetrain_mode(4.5, vs_constant_torque=1.0)
    assert 9.5 < power["omega_n"] < 11.5 and 9.5 < torque["omega_n"] < 11.5
    assert 0.005 < power["zeta"] < 0.02
    assert torque["zeta"] > 2.0 * power["zeta"]
