"""The NREL 5-MW aerodynamics: smooth Cp interpolant against the raw table."""

import numpy as np
import pytest

from wtftc import layout as lay
from wtftc import simulate as sim
from wtftc.cp_table import nrel5mw_cp_table, steady_pitch_raw


@pytest.fixture(scope="module")
def table():
    return nrel5mw_cp_table()


def test_interpolant_passes_through_the_table(table):
    cp = sim.cp_interpolant(table)
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
    smooth = sim.steady_pitch(sim.cp_interpolant(table), omega, torque, wind,
                              tp["air_density"], tp["rotor_radius"])
    raw = steady_pitch_raw(table, omega, torque, wind, tp["air_density"], tp["rotor_radius"])
    assert np.degrees(abs(smooth - raw)) < 0.15
    assert 2.0 < np.degrees(smooth) < 25.0


def test_interpolant_does_not_extrapolate(table):
    cp = sim.cp_interpolant(table)
    edge = float(cp(table.tsr[-1], table.pitch_rad[-1]))
    assert float(cp(table.tsr[-1] + 5, table.pitch_rad[-1] + 0.5)) == pytest.approx(edge)
