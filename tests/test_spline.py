"""The closed loop's Cp(λ, β) (wtftc.model.spline: bicubic cells of CasADi's B-spline, looked up on
the uniform grid) against CasADi's own evaluation of the same spline."""

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from wtftc.model import aero, spline
from wtftc.model.cp_table import nrel5mw_cp_table
from wtftc.sim import integrate


@pytest.fixture(scope="module")
def cps():
    table = nrel5mw_cp_table()
    ref = aero.cp_interpolant(table)
    return table, ref, aero.cp_loop_function(table)


def test_the_nrel_grid_is_uniform_and_takes_the_fast_path(cps):
    table, ref, fast = cps
    assert spline.is_uniform(table.tsr) and spline.is_uniform(table.pitch_rad)
    assert fast.is_a("MXFunction") and not ref.is_a("MXFunction")
    assert not spline.is_uniform(np.array([0.0, 1.0, 2.5, 3.0, 4.0]))


def test_same_values_inside_on_the_grid_and_clipped_outside(cps):
    """Inside, on every grid node and cell edge, and beyond the grid (clipped): measured
    8.9e-15 absolute on Cp values up to 12 (rounding of the bicubic form). A wrong cell,
    coefficient or clipping errs by 1e-3 or more."""
    table, ref, fast = cps
    rng = np.random.default_rng(0)
    lam = np.concatenate([rng.uniform(table.tsr[0], table.tsr[-1], 4000),
                          np.repeat(table.tsr, table.pitch_rad.size),
                          rng.uniform(-5, 30, 500)])
    beta = np.concatenate([rng.uniform(table.pitch_rad[0], table.pitch_rad[-1], 4000),
                           np.tile(table.pitch_rad, table.tsr.size),
                           rng.uniform(-1, 2, 500)])
    want = np.array(ref(lam, beta)).ravel()
    got = np.array(fast(lam, beta)).ravel()
    scale = np.max(np.abs(want))
    assert np.max(np.abs(got - want)) < 5e-14 * scale
    # the table itself on its nodes (an interpolating spline)
    np.testing.assert_allclose(got[4000:4000 + table.cp.size],
                               np.asarray(table.cp).ravel(), atol=1e-9)


def test_derivatives_and_compiled_code_agree(cps):
    """AD through the lookup (the loop's stability check takes the Jacobian) and the
    compiled C against CasADi's interpolant."""
    table, ref, fast = cps
    x = ca.MX.sym("x", 2)
    jf = ca.Function("jf", [x], [ca.jacobian(fast(x[0], x[1]), x)])
    jr = ca.Function("jr", [x], [ca.jacobian(ref(x[0], x[1]), x)])
    for pt in ([7.3, 0.1], [4.1, 0.02], [11.9, 0.4]):
        np.testing.assert_allclose(np.array(jf(pt)), np.array(jr(pt)), rtol=1e-10, atol=1e-12)
    n = 500
    comp = integrate.compiled(fast.map(n), "test_fast_cp", quiet=True)
    rng = np.random.default_rng(2)
    lam, beta = rng.uniform(2, 14, n), rng.uniform(0, 0.5, n)
    np.testing.assert_array_equal(np.array(comp(lam, beta)), np.array(fast.map(n)(lam, beta)))


def test_schedule_lookup_is_casadis_linear_interpolant():
    """The loop's pitch-sensitivity schedule (uniform-grid lookup) against CasADi's 'linear'
    interpolant on the same breakpoints, inside, on them and beyond (held): bit-identical
    (the same arithmetic, measured 0)."""
    from wtftc.artefacts import layout as lay

    table, pt = nrel5mw_cp_table(), lay.vector("turbine_params")
    betas, _ = aero.schedule_points(table, pt)
    fast = aero.sched_loop_function(table, pt)
    assert fast.is_a("MXFunction")
    x = np.concatenate([np.random.default_rng(3).uniform(-0.3, 1.0, 3000), betas])
    np.testing.assert_array_equal(np.array(fast(x)),
                                  np.array(aero.pitch_sensitivity_schedule(table, pt)(x)))


def _casadis_own_c(f: ca.Function, tmp_path, label: str) -> ca.Function:
    """f compiled from CasADi's code as it writes it (no lean bodies), with the loop flags."""
    from wtftc.artefacts.loader import compiled_external

    cg = ca.CodeGenerator(f"{label}.c", {"with_header": False})
    cg.add(f)
    cg.generate(str(tmp_path) + "/")
    return compiled_external(f.name(), tmp_path / f"{label}.c", integrate.loop_flags())


def _bits(a) -> np.ndarray:
    return np.asarray(a, dtype=float).ravel().view(np.int64)


def _points(grid: np.ndarray, rng, n: int) -> np.ndarray:
    special = [0.0, -0.0, np.inf, -np.inf, np.nan, 1e-310, -1e-310]
    return np.concatenate([special, grid, np.nextafter(grid, np.inf), np.nextafter(grid, -np.inf),
                           rng.uniform(grid[0] - 1, grid[-1] + 1, n)])


@pytest.mark.parametrize("origin", [0.0, 2.0])
def test_the_lean_c_is_casadis_code_bit_for_bit(origin, tmp_path):
    """The lean bodies put into a loop's C in place of CasADi's (spline.lean_c: one integer
    base for the 16 coefficients, no per-entry checks; 6 % of the physical loop's step)
    give CasADi's bits everywhere: on and beside every grid node, inside, beyond the grid,
    at signed zeros, infinities, NaN and subnormals; on a grid starting at 0 (where CasADi
    simplifies v - 0) and one that does not, with a unit and a half step."""
    rng = np.random.default_rng(7)
    x = origin + np.arange(9) * (1.0 if origin == 0 else 0.5)
    y = origin + np.arange(7) * 0.25
    values = rng.uniform(0, 1, (x.size, y.size))
    ref = ca.interpolant("t", "bspline", [x, y], values.ravel(order="F"))
    cell = spline.fast_cp(ref, x, y, "cpx")
    sched = spline.fast_linear(y, rng.uniform(-2, 0, y.size), "schedx", "beta", "g")
    lam, beta = np.meshgrid(_points(x, rng, 60), _points(y, rng, 60))
    lam, beta = lam.ravel(), beta.ravel()
    n = lam.size
    for f, args in ((cell, (lam, beta)), (sched, (beta,))):
        mapped = f.map(n)
        text = integrate.loop_source(mapped, tmp_path, f"lean_{f.name()}").read_text()
        assert "wtftc.model.spline: fast_" in text  # the lean body is in place
        lean = integrate.compiled(mapped, f"test_lean_{f.name()}", quiet=True)
        own = _casadis_own_c(mapped, tmp_path, f"own_{f.name()}")
        np.testing.assert_array_equal(_bits(lean(*args)), _bits(own(*args)))
        # and the virtual machine's values (which give +0 where libm's max gives -0)
        np.testing.assert_array_equal(np.array(lean(*args)), np.array(mapped(*args)))


def test_each_table_gets_its_own_lean_function():
    """The lean bodies are found by function name: two tables never share one."""
    table = nrel5mw_cp_table()
    from wtftc.model.cp_table import read_cp_table

    other = read_cp_table(Path(aero.__file__).parent.parent / "data" / "Cp_Ct_Cq.IEA15MW.txt")
    names = {aero.cp_loop_function(t, q).name() for t in (table, other) for q in ("cp", "ct")}
    assert len(names) == 4 and all(n in spline.LEAN_C for n in names)
