"""The hand-written numba baseline of the benchmark (bench/numba_loop.py) computes
the same closed loop as wtftc: Cp and the schedule, the right-hand side of each controller
against the generated one, and a short RK4 run against ``cases.run``.

The case: the paper's case 3 on nrel5mw (fault known to eq (49)) with the default fault
moved to t = 1 s, so that 3 s of simulation cover the lock "wherever the blade is", the
loss of effectiveness and the accommodation.
"""

import numpy as np
import pytest

from bench import numba_loop as nl
from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.model import aero
from wtftc.model.cp_table import nrel5mw_cp_table
from wtftc.model.faults import DEFAULT_FAULT
from wtftc.sim import rhs

T_FINAL = 3.0
FAULT_AT_1S = [dict(f, onset_s=1.0) for f in DEFAULT_FAULT]
#: two evaluations of the same algebra in a different order (softmax memberships, Taylor-
#: mode α̇_i instead of the expanded chain rule, another B-spline recurrence) differ by
#: rounding, amplified where terms cancel: ω̇_r = (T_aero - k_s θ_s - ...)/J_r, and u0,
#: which sums terms of order 1e4 such as α̇3 into a command of order 0.1-1. Measured over
#: 500 states each: 3.4e-13 (physical), 3.6e-12 (paper). A missing or wrong term in
#: α̇1..α̇3, the plant or the accommodation moves ż by 1e-4 or more.
RTOL_RHS = 1e-10
#: RK4 over 3000 steps through the lock at 1 s: measured 1.8e-16 (physical) and 2.1e-14
#: (paper, whose adaptive loop amplifies a rounding difference about e^{1.4 t}: 1e-4 after
#: 60 s on the benchmark's wind, as much as a 1-ulp change of ω_r(0) in wtftc itself)
RTOL_RUN = 1e-9


@pytest.fixture(scope="module", params=["physical", "paper"])
def loop(request):
    ctrl = request.param
    rc = config.make_config({"case": 3, "controller": ctrl, "t_final_s": T_FINAL,
                            "fault": FAULT_AT_1S})
    prep = nl.prepare(ctrl, rc)
    res = cases.run(rc, progress=False, keep_states=True)
    assert res.diverged is None
    return ctrl, rc, prep, res


def test_cp_spline_and_schedule_are_casadis():
    """Cp(λ, β) on the coefficients CasADi solved for, and the linear schedule, against
    CasADi's evaluation inside, on and beyond the grid (measured: 3.4e-15 and 0)."""
    table = nrel5mw_cp_table()
    kx, ky, coef = nl.cp_spline_data(table)
    rng = np.random.default_rng(0)
    lam = np.concatenate([rng.uniform(1.0, 16.0, 1000),
                          np.repeat(table.tsr, table.pitch_rad.size)])
    beta = np.concatenate([rng.uniform(-0.2, 0.7, 1000),
                           np.tile(table.pitch_rad, table.tsr.size)])
    got = np.array([nl.cp_spline(a, b, kx, ky, coef) for a, b in zip(lam, beta, strict=True)])
    ref = np.array(aero.cp_interpolant(table)(lam, beta)).ravel()
    np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-15)
    pt = lay.vector("turbine_params")
    sb, sg = nl.sched_data(table, pt)
    b = np.concatenate([rng.uniform(-0.1, 0.7, 500), sb])
    got = np.array([nl.sched_linear(x, sb, sg) for x in b])
    ref = np.array(aero.pitch_sensitivity_schedule(table, pt)(b)).ravel()
    np.testing.assert_allclose(got, ref, rtol=1e-13)


def _blocks(ctrl: str, n: int) -> list[slice]:
    """State blocks whose entries share a unit and a scale."""
    if ctrl == "physical":
        return [slice(0, nl.N_P), slice(nl.N_P, n)]
    edges = [0, nl.N_P, nl.N_P + 4] + [nl.N_P + 4 + sum(nl.RULES[:i]) for i in range(1, 5)]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True)]


def test_rhs_matches_generated(loop):
    """ż of plant + controller against wtftc.sim.rhs.rhs_function (use_fdi = 0) at 100
    states along a faulted run, perturbed, with nominal and faulted inputs.

    Compared entry by entry relative to |ż_i|, floored at 1e-3 of the largest entry of its
    block: an entry such as θ̂̇_m = γ χ φ_m - r θ̂_m can cancel to far below the size of
    its own terms, where a relative error means nothing.
    """
    ctrl, rc, prep, res = loop
    f = rhs.rhs_function(rc.loop)
    n = prep.z0.size
    # the FDI's states, if this rhs has them, do not act on the rest with use_fdi = 0
    z_in = rc.initial_state()[:f.size1_in(0)]
    use_fdi = [0.0] if "use_fdi" in f.name_in() else []
    rng = np.random.default_rng(1)
    worst = 0.0
    for trial in range(100):
        k = rng.integers(len(res.t))
        z = res.z[k].copy()
        z[:nl.N_P] *= 1 + 0.02 * rng.standard_normal(nl.N_P)
        z[nl.N_P:n] *= 1 + 0.1 * rng.standard_normal(n - nl.N_P)
        wind = float(rc.wind(res.t[k])) * (1 + 0.1 * rng.standard_normal())
        af = res.schedule.actuator([res.t[k]])[:, 0]
        af[np.isnan(af)] = 0.05  # a lock "wherever it is" not bound yet at this time
        sf = res.schedule.sensor([res.t[k]])[:, 0]
        if trial % 3 == 0:
            # on both of blade 2's sensors (the numba loop models one sensor per blade:
            # two that agree give the virtual sensor their reading)
            for k in (1, 2):
                sf[lay.index("sensor_faults", f"gain_beta_meas_2_m{k}")] = 1.1
        ck = af[:len(lay.names("fault_inputs"))].copy()
        z_in[:n] = z[:n]
        ref = np.array(f.call({"z": z_in, "wind": wind, "actuator_faults": af,
                               "sensor_faults": sf, "ctrl_fault": ck, "yd": prep.yd,
                               "p_turbine": rc.p_turbine, "p_ctrl": rc.p_ctrl,
                               "p_sensors": lay.defaults("sensor_params"), "cp_scale": 1.0,
                               **({"use_fdi": 0.0, "p_fdi": rhs.fdi_params(rc.loop)}
                                  if use_fdi else {})})["z_dot"]
                       ).ravel()[:n]
        got = prep.closed_loop_rhs(z[:n], wind, af, sf, ck)
        assert np.all(np.isfinite(got))
        for s in _blocks(ctrl, n):
            scale = np.maximum(np.abs(ref[s]), 1e-3 * np.max(np.abs(ref[s])))
            err = np.abs(got[s] - ref[s]) / np.where(scale > 0, scale, 1.0)
            worst = max(worst, float(err.max()))
    assert worst < RTOL_RHS, worst


def test_rk4_run_matches_wtftc(loop):
    """One numba call for the whole run: ω_r (and every plant and controller state) at the
    output times of cases.run, same dt, same wind and fault inputs, same lock binding."""
    ctrl, rc, prep, res = loop
    t, z = nl.run(prep)
    assert t.shape == res.t.shape and np.allclose(t, res.t, rtol=0, atol=1e-12)
    omega_r = res.column("omega_r")
    np.testing.assert_allclose(z[:, 0], omega_r, rtol=RTOL_RUN, atol=0)
    n = prep.z0.size
    span = np.max(np.abs(res.z[:, :n]), axis=0)
    assert np.max(np.abs(z - res.z[:, :n]) / np.where(span > 0, span, 1.0)) < 1e-7
    # the benchmark's entry point: the same numbers
    om = nl.omega_trajectory(prep, None, rc.dt, T_FINAL, every=rc.decimate)
    np.testing.assert_array_equal(om, z[:, 0])
