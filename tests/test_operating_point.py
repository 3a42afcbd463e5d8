"""Every run starts at the operating point of its initial wind (issue 31, item 1).

* The plant's operating point (wtftc.sim.trim.operating_point) against an independent
  solve: the raw Cp table, bilinear (cp_table.aero_torque_raw, not the loop's spline), the
  NREL 5-MW baseline torque law written here from Jonkman et al. (2009), section 7.1,
  and scipy's brentq.
* Runs at constant winds from 4 to 25 m/s start within 1 % of the rotor speed they settle
  at and within 0.1° of the pitch, for the PI, the physical AFTC and ROSCO, on the NREL
  5-MW and the IEA 15-MW (at 4 m/s its minimum rotor speed puts the tip-speed ratio past
  its Cp table's last, 14.5: the point with Cp held at the table's edge, as the plant holds
  it, above the turbine's cut-in wind).
* A wind with no operating point (below cut-in) is refused in one line.
"""

from dataclasses import replace

import numpy as np
import pytest
from scipy.optimize import brentq

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.errors import ConfigError
from wtftc.model import aero, turbine_file
from wtftc.model.cp_table import aero_torque, aero_torque_raw
from wtftc.sim import trim


def _rc(controller: str, turbine: str, wind: float, t_final: float = 1.0,
        profile: str = "ideal", **extra):
    raw = {"controller": controller, "turbine": turbine, "profile": profile,
           "wind": {"kind": "constant", "speed_mps": wind}, "t_final_s": t_final,
           "output_rate_hz": 10.0, **extra}
    if controller != "rosco":
        raw["turbine_params"] = {"gen_torque_law": 1.0}
    return config.make_config(raw)


def _baseline_law(tp: dict, w: float) -> float:
    """Jonkman et al. (2009), section 7.1, on the LSS: 0 below cut-in; region 1½ linear
    from cut-in to the start of region 2; k ω² in region 2; region 2½ linear through the
    synchronous speed ω_rated/(1 + slip) up to rated power at rated speed; P_rated/ω in
    region 3 (here by speed alone)."""
    k, w_ci, w_r2 = tp["vs_region2_k"], tp["vs_cut_in_speed"], tp["vs_region2_speed"]
    w_rated, p_rated = tp["vs_rated_speed"], tp["vs_rated_power"]
    w_sync = w_rated / (1 + tp["vs_slip"])
    if w < w_ci:
        t = 0.0
    elif w < w_r2:
        t = k * w_r2**2 * (w - w_ci) / (w_r2 - w_ci)
    else:
        t = k * w**2
    t25 = p_rated / w_rated / (w_rated - w_sync) * (w - w_sync)
    t = max(t, t25) if w > w_sync else t
    return min(t, p_rated / w, tp["vs_max_torque"])


@pytest.mark.parametrize("turbine,winds", [("nrel5mw", (4, 5, 6, 7, 8, 9, 10, 11)),
                                           ("iea15mw", (6, 7, 8, 9, 10))])
def test_below_rated_the_speed_is_the_torque_laws_equilibrium(turbine, winds):
    rc = _rc("physical", turbine, 8.0)
    tp = lay.values("turbine_params", rc.loop.p_turbine)
    table, rho, R = rc.loop.table, tp["air_density"], tp["rotor_radius"]
    for v in winds:
        w, torque, beta = trim.operating_point(rc.loop, float(v))

        def excess(x, v=v):
            return aero_torque_raw(table, x, v, 0.0, rho, R) - _baseline_law(tp, x)

        ref = brentq(excess, 0.5 * w, min(1.5 * w, table.tsr[-1] * v / R * 0.999))
        assert w == pytest.approx(ref, rel=3e-3), v  # spline against bilinear: 0.3 %
        assert torque == pytest.approx(_baseline_law(tp, w), rel=1e-9)
        assert beta == 0.0


def test_the_nrel5mw_at_6mps_rests_at_0_828_rad_s():
    """The issue's own number: 0.828 rad/s at 6 m/s, where every run used to start at
    1.267 rad/s and spend its first ~30 s decelerating."""
    w, _, _ = trim.operating_point(_rc("pi", "nrel5mw", 6.0).loop, 6.0)
    assert w == pytest.approx(0.828, abs=1e-3)


@pytest.mark.parametrize("turbine", ["nrel5mw", "iea15mw"])
def test_above_rated_the_pitch_balances_rated_torque(turbine):
    rc = _rc("pi", turbine, 16.0)
    tp = lay.values("turbine_params", rc.loop.p_turbine)
    cp = aero.cp_interpolant(rc.loop.table)  # the loop's own Cp: checks the solve itself
    R, rho = tp["rotor_radius"], tp["air_density"]
    for v in (12.0, 16.0, 20.0, 25.0):
        w, torque, beta = trim.operating_point(rc.loop, v)
        assert w == tp["omega_g_rated"] and torque == pytest.approx(_baseline_law(tp, w))
        def loop_excess(b, w=w, v=v, torque=torque):
            return aero_torque(float(cp(w * R / v, b)), w, v, rho, R) - torque

        def raw_excess(b, w=w, v=v, torque=torque):
            return aero_torque_raw(rc.loop.table, w, v, b, rho, R) - torque

        spline = brentq(loop_excess, beta - 0.05, beta + 0.05, xtol=1e-12)
        assert beta == pytest.approx(spline, abs=1e-8), v
        ref = brentq(raw_excess, beta - 0.05, beta + 0.05)
        # the raw table, bilinear: the two interpolations of the table differ by up to
        # 0.16° of pitch at 25 m/s on the NREL 5-MW (coarse grid, steep Cp)
        assert np.degrees(beta) == pytest.approx(np.degrees(ref), abs=0.25), v


CASES = [(c, t, v) for c in ("pi", "physical", "rosco")
         for t, winds in (("nrel5mw", (4, 6, 8, 10, 11, 12, 16, 20, 25)),
                          ("iea15mw", (4, 6, 8, 10, 11, 12, 16, 20, 25)))
         for v in winds if (c, t) != ("rosco", "iea15mw") or v > 6]
#: The one run that misses: ROSCO on the IEA 15-MW at 6 m/s, where its minimum speed
#: (VS_MinOMSpd 0.5236 rad/s) binds, starts there and settles 2.1 % lower (0.5125 rad/s):
#: ROSCO's own behaviour at that constraint (its setpoint smoother shifts the torque loop's
#: reference), not a start-up artefact; tested as it is, below (and at 4 m/s, where it
#: binds too, it is not run).


@pytest.mark.parametrize("controller,turbine,wind", CASES)
def test_a_run_in_constant_wind_starts_where_it_settles(controller, turbine, wind):
    """30 s in constant wind with exact sensors: the speed at t = 0 within 1 % of the mean
    over the last 5 s, the pitch within 0.1°. (With the benchmark's sensor noise a loop
    settles elsewhere: the PI on the IEA 15-MW at 11 m/s 0.5 % below rated with 0.4° less
    pitch, the noise straddling the corner of the torque law's regions 2½ and 3.)"""
    rc = _rc(controller, turbine, float(wind), t_final=30.0)
    res = cases.run(rc, progress=False)
    assert not res.diverged
    w = res.column("omega_r")
    beta = np.degrees(np.mean([res.column(f"beta_{j}") for j in lay.blades()], axis=0))
    end = res.t >= res.t[-1] - 5.0
    assert w[0] == pytest.approx(np.mean(w[end]), rel=0.01)
    assert beta[0] == pytest.approx(np.mean(beta[end]), abs=0.1)


def test_below_cut_in_there_is_no_operating_point_and_the_run_is_refused(capsys):
    from wtftc import cli

    assert cli.main(["run", "--controller", "pi", "--wind", "constant", "--wind-mean", "2",
                     "--t-final", "1", "--quiet", "--out", "/nonexistent/never"]) == 2
    out, err = capsys.readouterr()
    assert err.startswith("wtftc: error: wind = 2") and err.count("\n") == 1, err
    assert out == ""  # refused before the run's first line
    loop = _rc("pi", "iea15mw", 8.0).loop
    with pytest.raises(ConfigError, match="below the turbine's cut-in wind, 3 m/s"):
        trim.operating_point(loop, 2.99)
    trim.operating_point(loop, 3.0)  # from its cut-in wind, it has one


def test_past_the_cp_tables_ratios_a_turbine_above_cut_in_still_has_a_point():
    """The IEA 15-MW's DLC 1.2 field at 4 m/s, seed 0, starts at 3.99 m/s (its candidate's
    OpenFAST run was refused there): at its slowest speed, 0.5236 rad/s, the tip-speed ratio
    is 15.7, past the Cp table's 14.5. Its point holds Cp at the table's edge, as the plant
    does, just above the torque law's cut-in speed; a turbine file that does not give its
    cut-in wind (cut_in_wind_mps) is refused there, as before."""
    loop = _rc("pi", "iea15mw", 8.0).loop
    tp = lay.values("turbine_params", loop.p_turbine)
    w, torque, beta = trim.operating_point(loop, 3.99)
    assert tp["vs_cut_in_speed"] < w < 1.02 * tp["vs_cut_in_speed"] and beta == 0.0
    assert w * tp["rotor_radius"] / 3.99 > loop.table.tsr[-1]
    # the torques balance with Cp at the table's edge, and only there
    cp_edge = float(aero.cp_interpolant(loop.table)(loop.table.tsr[-1], 0.0))
    assert aero_torque(cp_edge, w, 3.99, tp["air_density"], tp["rotor_radius"]) \
        == pytest.approx(torque, rel=1e-6)
    assert torque == pytest.approx(_baseline_law(tp, w), rel=1e-9)
    with pytest.raises(ConfigError, match="operating point"):
        trim.operating_point(replace(loop, cut_in_wind=0.0), 3.99)
    # inside the table nothing moves: the point at 5 m/s is the table's own
    assert trim.operating_point(replace(loop, cut_in_wind=0.0), 5.0) \
        == trim.operating_point(loop, 5.0)


@pytest.mark.parametrize("value", ["0", "-3.0", "30", "nan", '"3"', "true"])
def test_a_cut_in_wind_that_is_not_a_wind_is_refused_naming_the_key(value):
    path = turbine_file.path_of("iea15mw")
    text = path.read_text().replace("cut_in_wind_mps = 3.0", f"cut_in_wind_mps = {value}")
    with pytest.raises(ConfigError) as e:
        turbine_file.parse(text, path)
    assert e.value.field == "cut_in_wind_mps" and str(path) in str(e.value)
    assert turbine_file.parse(path.read_text(), path).cut_in_wind_mps == 3.0


def test_rosco_on_the_iea15mw_at_its_minimum_speed_settles_2_percent_lower():
    rc = _rc("rosco", "iea15mw", 6.0, t_final=30.0)
    res = cases.run(rc, progress=False)
    w = res.column("omega_r")
    assert w[0] == pytest.approx(0.5236, rel=1e-4)
    assert np.mean(w[res.t >= 25.0]) == pytest.approx(0.5125, rel=3e-3)


def test_closed_loop_rest_is_a_boolean_and_false_keeps_the_controllers_own_start():
    with pytest.raises(ConfigError, match="initial.closed_loop_rest"):
        config.make_config({"initial": {"closed_loop_rest": "yes"}})
    on = _rc("physical", "nrel5mw", 25.0).initial_state()
    off = _rc("physical", "nrel5mw", 25.0, initial={"closed_loop_rest": False}).initial_state()
    # the physical AFTC rests off the plant's point at 25 m/s: +0.65 % speed (see above)
    assert on[0] == pytest.approx(1.0065 * off[0], rel=1e-3)


def test_a_first_second_below_cut_in_starts_at_the_lowest_wind_with_a_point():
    """A turbulent field whose first second is below cut-in (OpenFAST's 4-m/s NTM B,
    seed 0, starts at 2.67 m/s: every DLC 1.2 run of that bin was refused) starts at the
    operating point of the lowest wind between it and the run's mean that has one; a run
    whose mean has none either (a constant wind below cut-in) is still refused."""
    loop = _rc("pi", "nrel5mw", 8.0).loop
    w = trim.start_wind(loop, 2.67, 4.0)
    assert w == pytest.approx(3.0, abs=1e-3)  # the NREL 5-MW's cut-in wind
    trim.operating_point(loop, w)  # it has one
    with pytest.raises(ConfigError, match="operating point"):
        trim.operating_point(loop, w - 2e-3)  # and 2 mm/s below, none
    assert trim.start_wind(loop, 4.0, 5.0) == 4.0  # a wind with a point: itself
    assert trim.start_wind(loop, 2.0, 2.5) == 2.0  # none up to the mean: refused later
