"""The NREL 5-MW aerodynamics: smooth Cp interpolant against the raw table."""

import numpy as np
import pytest

from wtftc.artefacts import layout as lay
from wtftc.model import aero
from wtftc.model.cp_table import nrel5mw_cp_table, steady_pitch_raw


@pytest.fixture(scope="module")
def table():
    return nrel5mw_cp_table()


def test_interpolant_passes_through_the_table(table):
    cp = aero.cp_interpolant(table)
    rng = np.random.default_rng(0)
    for _ in range(50):
        i, j = rng.integers(len(table.tsr)), rng.integers(len(table.pitch_rad))
        assert float(cp(table.tsr[i], table.pitch_rad[j])) == pytest.approx(
            table.cp[i, j], abs=1e-9)


@pytest.mark.parametrize("wind", [12.0, 14.0, 16.0, 20.0, 24.0])
def test_rated_steady_state_matches_the_raw_table(table, wind):
    """Rated speed and rated LSS torque: the pitch root on the cubic B-spline and on the
    bilinear raw table agree within 0.15° (the two interpolations differ by up to about
    1e-3 in Cp between 1° grid lines, which moves the root by about 0.1° at 24 m/s)."""
    tp = dict(zip(lay.names("turbine_params"), lay.vector("turbine_params"), strict=True))
    omega, torque = tp["omega_g_rated"], tp["gen_torque_rated"]
    smooth = aero.steady_pitch(aero.cp_interpolant(table), omega, torque, wind,
                              tp["air_density"], tp["rotor_radius"])
    raw = steady_pitch_raw(table, omega, torque, wind, tp["air_density"], tp["rotor_radius"])
    assert np.degrees(abs(smooth - raw)) < 0.15
    assert 2.0 < np.degrees(smooth) < 25.0


def test_interpolant_does_not_extrapolate(table):
    cp = aero.cp_interpolant(table)
    edge = float(cp(table.tsr[-1], table.pitch_rad[-1]))
    assert float(cp(table.tsr[-1] + 5, table.pitch_rad[-1] + 0.5)) == pytest.approx(edge)


def _jonkman_torque_hss(w):
    """The NREL 5-MW baseline torque law on the HSS as its DISCON source writes it (Jonkman
    et al. 2009, section 7.1), regions by speed: the reference for the generated plant."""
    ct_in, rgn2, k, rated, slip, power, tmax = (70.16224, 91.21091, 2.332287, 121.6805,
                                                10.0, 5296610.0, 47402.91)
    sync = rated / (1 + 0.01 * slip)
    slope15 = k * rgn2**2 / (rgn2 - ct_in)
    slope25 = power / rated / (rated - sync)
    # region 2½ begins where the 2½ line meets k ω² (VS_TrGnSp)
    trans = (slope25 - np.sqrt(slope25 * (slope25 - 4 * k * sync))) / (2 * k)
    if w >= rated:
        t = power / w
    elif w <= ct_in:
        t = 0.0
    elif w < rgn2:
        t = slope15 * (w - ct_in)
    elif w < trans:
        t = k * w**2
    else:
        t = slope25 * (w - sync)
    return min(t, tmax)


@pytest.mark.parametrize("w_hss", [50.0, 70.16224, 80.0, 91.21091, 100.0, 110.0, 115.0,
                                   119.0, 121.0, 121.6805, 122.90967, 130.0, 140.0])
def test_baseline_torque_law_is_jonkmans(w_hss):
    """gen_torque_law = 1 in the generated plant against the DISCON formulas, every region
    and boundary (rounding only: 1e-9 relative); law 0 keeps the rated torque."""
    from wtftc.artefacts.loader import load

    f = load("turbine_nrel5mw")
    n = 97.0
    x = np.array([w_hss / n, 0.0, w_hss / n, 0.1, 0.1, 0.1, 0.0, 0.0, 0.0])
    args = dict(x_plant=x, v=np.full(3, 0.1), wind=12.0, cp=0.4,
                actuator_faults=lay.defaults("actuator_faults"))
    t1 = float(f(**args, p_turbine=lay.vector("turbine_params", {"gen_torque_law": 1.0}))[
        "T_gen"]) / n
    assert t1 == pytest.approx(_jonkman_torque_hss(w_hss), rel=1e-9, abs=1e-6)
    t0 = float(f(**args, p_turbine=lay.vector("turbine_params"))["T_gen"]) / n
    assert t0 == pytest.approx(43_093.55, rel=1e-12)


@pytest.mark.parametrize("w_hss", [100.0, 119.0, 121.0, 121.5, 121.6805, 122.0, 122.90967,
                                   130.0, 140.0])
def test_the_laws_region_3_at_constant_torque(w_hss):
    """vs_constant_torque = 1 (issue 34): the baseline law is Jonkman's until it reaches
    the rated torque P_rated/ω_g,rated (43,093.55 N m on the HSS, on its region-2½ line
    just below 121.68 rad/s) and that torque above; at the rated speed, where the pitch
    holds the rotor, it is Jonkman's constant-power torque (the same operating point). The
    default 0 is Jonkman's constant power."""
    from wtftc.artefacts.loader import load

    f = load("turbine_nrel5mw")
    n = 97.0
    x = np.array([w_hss / n, 0.0, w_hss / n, 0.1, 0.1, 0.1, 0.0, 0.0, 0.0])
    args = dict(x_plant=x, v=np.full(3, 0.1), wind=12.0, cp=0.4,
                actuator_faults=lay.defaults("actuator_faults"))
    law = {"gen_torque_law": 1.0}
    t_ct = float(f(**args, p_turbine=lay.vector("turbine_params", law | {
        "vs_constant_torque": 1.0}))["T_gen"]) / n
    t_cp = float(f(**args, p_turbine=lay.vector("turbine_params", law))["T_gen"]) / n
    tp = dict(zip(lay.names("turbine_params"), lay.vector("turbine_params"), strict=True))
    rated_torque = tp["vs_rated_power"] / tp["omega_g_rated"] / n  # the turbine file's
    assert rated_torque == pytest.approx(43_093.55, rel=1e-5)  # Jonkman's rated, rounded
    assert t_cp == pytest.approx(_jonkman_torque_hss(w_hss), rel=1e-9)
    below = _jonkman_torque_hss(w_hss) if w_hss < 121.6805 else np.inf
    assert t_ct == pytest.approx(min(below, rated_torque), rel=1e-9)
    if w_hss == 122.90967:
        assert t_ct == pytest.approx(t_cp, rel=1e-9)


def test_constant_torque_without_the_law_is_refused_naming_both():
    """vs_constant_torque sets the baseline law's region 3: with a fixed torque
    (gen_torque_law 0, the default above rated) it would change nothing, silently."""
    from wtftc.config import make_config
    from wtftc.errors import ConfigError

    raw = {"controller": "physical", "t_final_s": 5.0,
           "wind": {"kind": "constant", "speed_mps": 16.0},
           "turbine_params": {"vs_constant_torque": 1.0}}
    with pytest.raises(ConfigError, match="vs_constant_torque.*gen_torque_law = 1"):
        make_config(raw)
    raw["turbine_params"]["gen_torque_law"] = 1.0
    assert make_config(raw).param("vs_constant_torque") == 1.0
