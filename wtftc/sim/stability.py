"""RK4's stability limit at the initial state, and the step refused beyond it."""

from __future__ import annotations

import sys
from functools import cache

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.errors import ConfigError
from wtftc.model.faults import nominal_actuator
from wtftc.sim.rhs import Loop, rhs_function


def stability_limit(loop: Loop, z0, wind0: float, yd, p_ctrl) -> float:
    """Largest |eigenvalue| of the closed-loop Jacobian at z0 (RK4: stable for |λ dt| < 2.78)."""
    args = {"z": z0, "wind": wind0, "actuator_faults": nominal_actuator(loop.p_turbine),
            "sensor_faults": lay.defaults("sensor_faults"),
            "ctrl_fault": lay.defaults("fault_inputs"), "yd": yd, "p_turbine": loop.p_turbine,
            "p_ctrl": p_ctrl, "use_fdi": 0.0}
    jac = _jacobian_function(loop)
    eig = np.linalg.eigvals(np.array(jac.call({n: args[n] for n in jac.name_in()})["dz_dot_dz"]))
    return float(np.max(np.abs(eig)))


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
