"""RK4's stability limit at the initial state, and the step refused beyond it."""

from __future__ import annotations

import sys
from functools import cache

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.errors import ConfigError
from wtftc.model.faults import nominal_actuator
from wtftc.sim.rhs import Loop, fdi_params, rhs_function


def _jacobian(loop: Loop, z0, wind0: float, yd, p_ctrl) -> np.ndarray:
    """The closed-loop Jacobian ∂ż/∂z at z0, fault-free (the continuous loop's states: a
    sampled loop's sensor lags and held command are cut off)."""
    args = fault_free_args(loop, wind0, yd, p_ctrl)
    jac = _jacobian_function(loop)
    args["z"] = np.asarray(z0, dtype=float)[:jac.size1_in("z")]
    return np.array(jac.call({n: args[n] for n in jac.name_in()})["dz_dot_dz"])


def fault_free_args(loop: Loop, wind: float, yd, p_ctrl) -> dict:
    """The closed-loop right-hand side's inputs but the state: fault-free, exact sensors,
    nominal actuators, the FDI not used, constant ``wind``."""
    return {"wind": wind, "actuator_faults": nominal_actuator(loop.p_turbine),
            "sensor_faults": lay.defaults("sensor_faults"),
            "ctrl_fault": lay.defaults("fault_inputs"), "yd": yd, "p_turbine": loop.p_turbine,
            "p_ctrl": p_ctrl, "use_fdi": 0.0, "cp_scale": 1.0, "p_fdi": fdi_params(loop),
            "p_sensors": lay.defaults("sensor_params")}


def stability_limit(loop: Loop, z0, wind0: float, yd, p_ctrl) -> float:
    """Largest |eigenvalue| of the closed-loop Jacobian at z0 (RK4: stable for |λ dt| < 2.78)."""
    return float(np.max(np.abs(np.linalg.eigvals(_jacobian(loop, z0, wind0, yd, p_ctrl)))))


@cache
def _jacobian_function(loop: Loop) -> ca.Function:
    """∂ż/∂z of the closed loop, built once per loop."""
    rhs = rhs_function(loop)
    ins = {n: ca.SX.sym(n, rhs.sparsity_in(n)) for n in rhs.name_in()}
    z_dot = rhs.call(ins)["z_dot"]
    return ca.Function("closed_loop_jacobian", list(ins.values()),
                       [ca.jacobian(z_dot, ins["z"])], list(ins), ["dz_dot_dz"])


#: beyond this step the paper controller's start-up transient is not resolved: measured
#: errors of order 1 at dt = 4e-3 s against DOP853 (docs/verification.md, section 6)
DT_ACCURATE_S = 1e-3

def check_dt(dt: float, lam_max: float) -> None:
    """Refuse a dt beyond RK4's stability limit at the initial state, with the reason;
    warn (stderr) beyond the step at which the integration was verified accurate."""
    if not (np.isfinite(dt) and dt > 0):
        raise ConfigError("dt_s", dt, "a positive number of seconds")
    limit = 2.78 / lam_max
    if dt > limit:
        raise ConfigError("dt_s", dt, f"at most {limit:.3g} s: the fastest mode of the "
                          f"closed loop at the initial state has |λ| = {lam_max:.4g} 1/s and "
                          "RK4 is stable only for |λ·dt| < 2.78")
    if dt > DT_ACCURATE_S * (1 + 1e-9):  # a refused dt gets only the refusal's one line
        print(f"  warning: dt_s = {dt:g} s is larger than {DT_ACCURATE_S:g} s, the step at "
              "which the closed loop's RK4 integration is verified accurate "
              "(docs/verification.md); results may be inaccurate", file=sys.stderr)


def controller_limit(loop: Loop, z0, wind0: float, yd, p_ctrl) -> float:
    """Largest |eigenvalue| of the controller's and the FDI's own dynamics at z0 (their
    block of the closed-loop Jacobian): a sampled loop advances them by one RK4 step of the
    control interval."""
    n_p = loop.n_states[0]
    block = _jacobian(loop, z0, wind0, yd, p_ctrl)[n_p:, n_p:]
    return float(np.max(np.abs(np.linalg.eigvals(block)))) if block.size else 0.0


def check_interval(interval: float, lam_max: float) -> None:
    """Refuse a control interval beyond RK4's stability limit of the controller's own
    dynamics (they advance by one RK4 step of the interval)."""
    if lam_max > 0 and interval > 2.78 / lam_max:
        raise ConfigError("control_interval_s", interval,
                          f"at most {2.78 / lam_max:.3g} s: the controller's and the FDI's "
                          f"fastest mode has |λ| = {lam_max:.4g} 1/s and their RK4 step over "
                          "the interval is stable only for |λ·T| < 2.78")
