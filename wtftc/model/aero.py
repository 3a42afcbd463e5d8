"""Aerodynamics for the loop and the trim: the Cp(λ, β) lookup, the steady pitch, and the
∂T_aero/∂β gain schedule on the steady above-rated operating curve."""

from __future__ import annotations

from functools import cache

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.errors import ConfigError
from wtftc.model import spline
from wtftc.model.cp_table import CpTable, aero_torque, bisect


@cache
def cp_interpolant(table: CpTable, quantity: str = "cp") -> ca.Function:
    """Cubic B-spline Cp(λ, β) (or ``quantity = "ct"``: Ct) on the table grid; inputs
    clipped to the grid (no extrapolation)."""
    values = getattr(table, quantity)
    if values is None:
        raise ConfigError("cp_table", table.source, f"a table with the {quantity.upper()} "
                          "block (the tower plant needs the thrust coefficient)")
    f = ca.interpolant(f"{quantity}_table", "bspline", [table.tsr, table.pitch_rad],
                       np.asarray(values, dtype=float).ravel(order="F"))
    lam, b = ca.SX.sym("tsr"), ca.SX.sym("beta")
    lam_c = ca.fmin(ca.fmax(lam, float(table.tsr[0])), float(table.tsr[-1]))
    b_c = ca.fmin(ca.fmax(b, float(table.pitch_rad[0])), float(table.pitch_rad[-1]))
    return ca.Function(quantity, [lam, b], [f(ca.vertcat(lam_c, b_c))], ["tsr", "beta"],
                       [quantity])


def cp_loop_function(table: CpTable, quantity: str = "cp") -> ca.Function:
    """Cp(λ, β) (or Ct) for the closed loop: :func:`cp_interpolant`'s spline, evaluated by
    uniform-grid lookup (wtftc.model.spline, about 6× cheaper in the compiled step; same values to
    rounding) when the table grid is uniform, as CasADi's interpolant otherwise."""
    ref = cp_interpolant(table, quantity)
    if spline.is_uniform(table.tsr) and spline.is_uniform(table.pitch_rad):
        return spline.fast_cp(ref, table.tsr, table.pitch_rad, quantity)
    return ref


def steady_pitch(cp_fn: ca.Function, omega_r: float, torque: float, wind: float,
                 air_density: float, rotor_radius: float,
                 bracket=(0.0, 0.5235987755982988)) -> float:  # 0..30°, the NREL table
    """Pitch at which the aerodynamic torque on the interpolant equals ``torque`` [rad].

    Bisection on the feathering side; the lower end of the bracket when even it gives less
    torque (below rated: the pitch rests at its limit).
    """
    lam = omega_r * rotor_radius / wind

    def excess(beta):
        return aero_torque(float(cp_fn(lam, beta)), omega_r, wind, air_density,
                           rotor_radius) - torque

    if excess(bracket[0]) <= 0:
        return bracket[0]
    return bisect(lambda b: excess(b) > 0, *bracket)


def pitch_sensitivity_schedule(table: CpTable, p_turbine: np.ndarray) -> ca.Function:
    """The schedule of :func:`_pitch_sensitivity_schedule`, built once per table (by
    identity) and turbine parameters: every run and every trim needs it, and the bisections
    behind it take about 0.15 s."""
    return _schedule_function(*schedule_points(table, p_turbine))

def sched_loop_function(table: CpTable, p_turbine: np.ndarray) -> ca.Function:
    """:func:`pitch_sensitivity_schedule` for the closed loop: by uniform-grid lookup
    (wtftc.model.spline) where its breakpoints are uniform (the table's pitch grid), else CasADi's
    interpolant."""
    betas, grads = schedule_points(table, p_turbine)
    if spline.is_uniform(betas):
        return spline.fast_linear(betas, grads, "pitch_sensitivity", "beta", "dT_dbeta")
    return _schedule_function(betas, grads)

def schedule_points(table: CpTable, p_turbine: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Breakpoints (pitch [rad], ∂T_aero/∂β [N m/rad]) of the schedule, computed once per
    table (by identity) and turbine parameters."""
    return _schedule_points(table, tuple(float(v) for v in p_turbine))

@cache
def _schedule_points(table: CpTable, p_turbine: tuple) -> tuple[np.ndarray, np.ndarray]:
    """∂T_aero/∂β [N m/rad] against pitch on the steady above-rated operating curve.

    For each table pitch, the wind at which rated speed and rated torque balance (bisection
    on the Cp interpolant), then ∂T_aero/∂β there (the generated aero_torque_sensitivity,
    with ∂Cp/∂β by AD of the interpolant). Linear in between, held beyond the ends. This
    is the gain schedule of the PI baseline and of the physical and drivetrain designs.
    """
    p_turbine = np.array(p_turbine)
    cp_fn = cp_interpolant(table)
    dcp_fn = _dcp_dbeta_on_grid(table)
    sens = load("aero_torque_sensitivity")
    tp = lay.values("turbine_params", p_turbine)
    omega, torque, R = tp["omega_g_rated"], tp["gen_torque_rated"], tp["rotor_radius"]
    x6 = lay.vector("plant_states", {"omega_r": omega, "theta_s": 0.0, "omega_g": omega})
    betas, grads = [], []
    for beta in table.pitch_rad:
        if beta < 0:
            continue
        x6[lay.block("plant_states", "beta")] = beta

        def excess(v, beta=beta):
            return float(sens(x_plant=x6, wind=v, cp=cp_fn(omega * R / v, beta), dcp_dbeta=0,
                              p_turbine=p_turbine)["T_aero"]) - torque

        if excess(3.0) > 0 or excess(45.0) < 0:
            continue
        v = bisect(lambda v: not excess(v) > 0, 3.0, 45.0)
        g = float(sens(x_plant=x6, wind=v, cp=cp_fn(omega * R / v, beta),
                       dcp_dbeta=dcp_fn(omega * R / v, beta), p_turbine=p_turbine)["dT_dbeta"])
        betas.append(float(beta))
        grads.append(g)
    if len(betas) < 2:  # the table and the turbine together: name both
        tp = lay.values("turbine_params", p_turbine)
        raise ConfigError("cp_table", table.source, "a table with an above-rated operating "
                          "range at this turbine's rated speed and torque, for winds of 3-45 "
                          "m/s (none found with turbine_params.air_density = "
                          f"{tp['air_density']:g} kg/m^3, rotor_radius = "
                          f"{tp['rotor_radius']:g} m, omega_g_rated = "
                          f"{tp['omega_g_rated']:g} rad/s, gen_torque_rated = "
                          f"{tp['gen_torque_rated']:g} N m)")
    return np.array(betas), np.array(grads)

def _dcp_dbeta_on_grid(table: CpTable) -> ca.Function:
    """∂Cp/∂β of :func:`cp_interpolant`'s spline at a table pitch (λ clipped to the grid
    as there, β not: the derivative of the clip at the grid's last pitch is CasADi's ½ of
    a tie, which halved the schedule's last breakpoint before 2026-11-24)."""
    f = ca.interpolant("cp_table", "bspline", [table.tsr, table.pitch_rad],
                       np.asarray(table.cp, dtype=float).ravel(order="F"))
    lam, b = ca.SX.sym("tsr"), ca.SX.sym("beta")
    lam_c = ca.fmin(ca.fmax(lam, float(table.tsr[0])), float(table.tsr[-1]))
    return ca.Function("dcp", [lam, b], [ca.jacobian(f(ca.vertcat(lam_c, b)), b)])

def _schedule_function(betas: np.ndarray, grads: np.ndarray) -> ca.Function:
    interp = ca.interpolant("dTdbeta_table", "linear", [betas], grads)
    bb = ca.SX.sym("beta")
    bc = ca.fmin(ca.fmax(bb, betas[0]), betas[-1])
    return ca.Function("pitch_sensitivity", [bb], [interp(bc)], ["beta"], ["dT_dbeta"])
