"""Issue 34: the physical AFTC's tower fore-aft damper (derivation/design.py, tower_damper):
derived into α1 and α̇1, fed by the tower-top acceleration that wtftc's tower plants
compute and a DISCON host gives in #53; off by default."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from discon_host import Host

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.export import discon
from wtftc.sim.rhs import rhs_function
from wtftc.verify import designs

control = pytest.importorskip("control", reason="python-control: pip install "
                              "'wtftc[linear]'")
from wtftc.campaign import linearize as lin  # noqa: E402

ON = {"phys_td_gain": 0.05}
#: the damper on the low-passed acceleration (ω_f = 5 rad/s)
FILTERED = {**ON, "phys_td_lpf": 5.0}
#: the physical AFTC on its observer with peak shaving (issue 34's candidate) on the plant
#: with the tower and the drivetrain-edgewise mode
TOWER = {"controller": "physical", "plant": "tower_edge",
         "controller_params": {"phys_obs_omega": 4.5, "phys_ps_pitch": 0.0349}}


def test_alpha1_dot_with_the_damper_against_central_differences():
    """With the damper on and a tower-top acceleration of 0.3 m/s² (designs.SCHED), the
    damper's pitch moves along the design model (its state integrates the acceleration,
    or its low-pass): d α1/dt by central differences falls to the generated α̇1 at O(h²),
    below 1e-6 relative at the best h, with the observer off and on, the acceleration
    unfiltered and low-passed."""
    for params in (ON, {**ON, "phys_obs_omega": 4.5}, FILTERED,
                   {**FILTERED, "phys_obs_omega": 4.5}):
        fd = designs.alpha_dot_fd("physical", params=params)
        assert np.all((1.9 < fd.slopes) & (fd.slopes < 2.1)), (params, fd.slopes)
        assert np.all(fd.errors.min(axis=0) < 1e-6), (params, fd.errors)


def test_the_damper_adds_its_pitch_to_alpha1_and_nothing_when_off():
    """At the same state, α1 with the damper is α1 without it plus K·ŝ (ŝ the damper's
    state, within the clip), to rounding; its α̇1 gains K·(a − ω_h ŝ) exactly."""
    on, off = designs.DesignModel("physical", ON), designs.DesignModel("physical")
    z = on.rk4(on.z0, 0.0, 1.0, 2000)
    s_hat = z[on.n_model + lay.index("physical_states", "phys_td_speed")]
    a, b = on.check_values(z, 1.0), off.check_values(z, 1.0)
    assert s_hat == pytest.approx(0.3 * (1 - np.exp(-0.2)) / 0.2, rel=1e-6)
    assert a["alpha1"] - b["alpha1"] == pytest.approx(0.05 * s_hat, rel=1e-9)
    assert a["alpha1_dot_full"] - b["alpha1_dot_full"] == pytest.approx(
        0.05 * (0.3 - 0.2 * s_hat), rel=1e-6)


def test_the_damper_damps_the_tower_mode_and_keeps_the_margins():
    """wtftc linearize at 16 m/s on the tower_edge plant: the tower's fore-aft mode (about
    1.9 rad/s) goes from ζ 0.06 without the damper (its aerodynamic damping) to above
    0.12 at K = 0.12 rad s/m, and the pitch loop keeps a gain margin above 10 dB."""
    def tower_mode(op):
        m = [r for r in lin.modes(op) if 1.5 < r["omega_n_rad_s"] < 2.6]
        assert len(m) == 1, m
        return m[0]

    off = lin.operating_point(TOWER, 16.0)
    params = {**TOWER["controller_params"], "phys_td_gain": 0.12}
    on = lin.operating_point({**TOWER, "controller_params": params}, 16.0)
    assert tower_mode(off)["damping"] == pytest.approx(0.06, abs=0.015)
    assert tower_mode(on)["damping"] > 2 * tower_mode(off)["damping"]
    assert lin.summary_row(on)["gain_margin_dB"] > 10
    # the damper's path from the wind (the acceleration's thrust) is in the closed loop's
    # wind input: ∂ż/∂w of the loop itself, by central differences
    assert np.abs(on.F_c).max() > 0 and np.all(off.F_c == 0)
    rc = config.make_config({**TOWER, "controller_params": params, "case": 1, "fault": []})
    loop = replace(rc.loop, fdi=False)
    vals = dict(zip(lin._PARAMS, lin._values(rc, loop), strict=True))
    rhs = rhs_function(loop)

    def zdot(w):
        return np.array(rhs.call({"z": on.z, "wind": w, **vals})["z_dot"]).ravel()

    fd = (zdot(16.0 + 1e-4) - zdot(16.0 - 1e-4)) / 2e-4
    b_w = on.state_spaces()["closed_loop"].B.ravel()
    assert np.allclose(b_w, fd, rtol=1e-5, atol=1e-6 * np.abs(fd).max())


@pytest.fixture(scope="module")
def library(tmp_path_factory):
    """The physical AFTC's exported library, compiled once for this module's hosts."""
    return discon.export("physical", tmp_path_factory.mktemp("lib")) / "libwtftc_physical.so"


def _held_host_demands(library, folder, calls: int, cases) -> dict[str, np.ndarray]:
    """Blade 1's demand from the exported library over ``calls`` 10-ms calls, per (name,
    controller_params, #53 [m/s²]): readings held at rated speed with 0.2 rad of pitch,
    the host with the benchmark actuator (no rate limit in the library)."""
    demands = {}
    for name, over, acc in cases:
        rc_k = config.make_config({"controller": "physical", "case": 1,
                                   "profile": "realistic", "controller_params": over})
        host = Host(library, discon.write_input(rc_k, folder / f"{name}.IN",
                                                demand_rate_limit=0))
        host.swap[52] = acc
        demands[name] = np.array([host.call(0 if k == 0 else 1, 0.01 * k, 1.26711,
                                            1.26711 * 97.0, [0.2] * 3)["pitch"][0]
                                  for k in range(calls)])
    return demands


def test_a_discon_host_feeds_the_damper_record_53(tmp_path, library):
    """The exported library reads the tower-top acceleration from #53: readings held at
    rated with 0.2 rad of pitch, and #53 held at 2 m/s²; with no actuator model in the
    design (U = α1) the demand departs from the one with #53 = 0 by the damper's pitch
    K ŝ, ŝ = a (1 − e^(−ω_h t))/ω_h, up to the clip at 2° (reached at 0.18 s), to float
    rounding; with the damper off, #53 changes nothing. Over 0.4 s: beyond it the FDI
    sees blades that do not follow the demand (the host holds them) and isolates them, as
    it should."""
    params = {"phys_actuator_model": 0.0, "phys_td_gain": 0.1}
    demands = _held_host_demands(library, tmp_path, 40, (
        ("on", params, 2.0), ("on_still", params, 0.0),
        ("off", {"phys_actuator_model": 0.0}, 2.0)))
    t = 0.01 * np.arange(40)
    expected = np.minimum(0.1 * 2.0 * (1 - np.exp(-0.2 * t)) / 0.2, 0.0349)
    assert expected[-1] == 0.0349  # the clip is reached
    assert np.abs(demands["on"] - demands["on_still"] - expected).max() < 1e-7
    assert np.array_equal(demands["off"], demands["on_still"])


def test_the_low_pass_keeps_the_acceleration_out_of_the_command(tmp_path, library):
    """Issue 34: unfiltered, the damper's rate K (a − ω_h ŝ) enters α̇1, and the command
    U = β̄ + τ_a (… + α̇1) inverts the actuator lag on it: the measured acceleration
    reaches the demand at once, with a gain K τ_a (here 0.1 × 0.108 s × 2 m/s² = 1.2°:
    OpenFAST's start put the first demand 1.3° off). Low-passed at ω_f the acceleration
    enters through the state a_f only: the first demand is the one with #53 = 0, and
    0.1 s later (blades held at 0.2 rad, so z2 carries the damper's pitch) the difference
    is τ_a K (c2 ŝ + a_f − ω_h ŝ) with a_f and ŝ in closed form, within 2 %."""
    K, w_f, w_h, acc = 0.1, 5.0, 0.2, 2.0
    design = lay.values("physical_params", lay.defaults("physical_params"))
    tau_a, c2 = design["phys_tau_a"], design["phys_c2"]
    demands = _held_host_demands(library, tmp_path, 11, (
        ("raw", {"phys_td_gain": K}, acc),
        ("filtered", {"phys_td_gain": K, "phys_td_lpf": w_f}, acc),
        ("still", {"phys_td_gain": K, "phys_td_lpf": w_f}, 0.0)))
    step = demands["raw"][0] - demands["still"][0]
    assert step == pytest.approx(K * tau_a * acc, rel=0.02)
    assert abs(demands["filtered"][0] - demands["still"][0]) < 1e-7
    # 0.1 s in: a_f = a (1 − e^(−ω_f t)); ŝ̇ = a_f − ω_h ŝ, solved in closed form
    t = 0.1
    e_f, e_h = np.exp(-w_f * t), np.exp(-w_h * t)
    s_hat = acc * ((1 - e_h) / w_h - (e_h - e_f) / (w_f - w_h))
    a_f = acc * (1 - e_f)
    # U's terms in α1 (the blades held: z2 = β̄ − α1 grows by K ŝ) and in α̇1
    expected = tau_a * (c2 * K * s_hat + K * (a_f - w_h * s_hat))
    assert demands["filtered"][10] - demands["still"][10] == pytest.approx(expected,
                                                                           rel=0.02)
