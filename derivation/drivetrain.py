"""Adaptive fuzzy backstepping AFTC through the drivetrain (ours, not the paper's).

The other chain of the design notes (DESIGN.md): z1 = ω_g - (d_s/J_g)(θ_s - θ_s*) ← θ_s ←
ω_r ← β̄ ← u, on the two-mass drivetrain of the NREL 5-MW plant (eqs (1)-(3) with the
generator torque, derivation/turbine.py):

    J_r ω̇_r = T_aero - k_s θ_s - d_s (ω_r - ω_g),   θ̇_s = ω_r - ω_g,
    J_g ω̇_g = k_s θ_s + d_s (ω_r - ω_g) - T_g,       τ_a β̄̇ = u - β̄.

With x1 = ω_g - (d_s/J_g)(θ_s - θ_s*), θ_s* = T_g/k_s the steady twist, the damping terms
cancel: ẋ1 = (k_s/J_g) θ_s - T_g/J_g, so the chain is strict-feedback with known gains
g1 = k_s/J_g, 1, b = G/J_r (G = ∂T_aero/∂β, scheduled) and 1/τ_a. At steady state x1 = ω_g =
ω_r, so x1 tracks the rotor-speed reference y_d. The unknown aerodynamic residual
f = (T_aero - G β̄)/J_r enters at step 3 only and is approximated by f̂ = θ̂ᵀφ(ω_r).

θ_s is not measured: the controller integrates θ̂̇_s = ω_r - ω_g from the measured speeds,
starting at θ_s* (the plant starts trimmed). Exact here, where the speeds are measured
without noise; a speed-sensor bias would make it drift (docs/controllers.md).

    z1 = x1 - y_d                          α1 = (T_g/J_g + ẏ_d - c1 z1)/g1
    z2 = θ̂_s - α1                          α2 = ω_g + α̇1 - c2 z2 - g1 z1
    z3 = ω_r - α2                          α3 = (-c3 z3 - z2 - h3 - f̂ + α̇2)/b,
                                              h3 = -(k_s θ̂_s + d_s (ω_r - ω_g))/J_r
    z4 = β̄ - α3                            U = β̄ + τ_a (-c4 z4 - b z3 + α̇3)
    θ̂̇ = κ (γ z3 φ(ω_r) - σ θ̂)

V = ½Σz_i² + θ̃ᵀθ̃/(2γ) gives V̇ = -Σ c_i z_i² + z3 ε + σ θ̃ᵀθ̂ - Σ z_{i+1} (α̇_i - α̇_ic). The
α̇_i are total derivatives (SymPy); the computable ones replace the unmeasured ω̇_r by
b β̄ + h3 + f̂, ω̇_g by its model on θ̂_s, and ḃ by 0. Anti-windup, projection and eq (49)'s
accommodation as in derivation/physical.py (derivation/design.py).
"""

from __future__ import annotations

from functools import cache

import sympy as sp

from derivation import design, fuzzy, nrel5mw
from derivation.layout import N_BLADES, N_MF, Entry

# measurements, reference, schedule (bound by name, derivation/design.py)
omega_r, omega_g_hss = sp.symbols("omega_r omega_g_hss", real=True)
beta_meas = sp.symbols(f"beta_meas_1:{N_BLADES + 1}", real=True)
yd = sp.symbols("yd_0:5", real=True)
dT_dbeta = sp.Symbol("dT_dbeta", real=True)
# true rates the controller cannot measure: inputs of the verification function only
omega_r_dot, omega_g_dot, b_dot = sp.symbols("omega_r_dot omega_g_dot b_dot", real=True)

WEIGHTS = [f"dt_theta_hat[{m}]" for m in range(N_MF)]
STATES = [*[Entry(w, 0.0, "rad/s^2", f"fuzzy weight {m} of f̂(ω_r)", sample=(-0.5, 1.0))
            for m, w in enumerate(WEIGHTS)],
          Entry("dt_twist_hat", nrel5mw.RATED_SHAFT_TWIST, "rad",
                "shaft twist estimate θ̂_s, integrated from the measured speeds",
                sample=(2.4e-3, 7.2e-3))]
#: the design model's states (design_model): the finite-difference checks start at the
#: defaults, random inputs are drawn in the sample ranges
MODEL_STATES = [
    Entry("dm_omega_r", 1.28, "rad/s", "rotor speed ω_r", sample=(1.1, 1.45)),
    Entry("dm_theta_s", nrel5mw.RATED_SHAFT_TWIST, "rad", "shaft twist θ_s",
          sample=(2.4e-3, 7.2e-3)),
    Entry("dm_omega_g", 1.28, "rad/s", "generator speed on the LSS ω_g", sample=(1.1, 1.45)),
    Entry("dm_beta", 0.14, "rad", "mean blade pitch β̄", sample=(0.0, 0.4)),
]
#: the design model's aerodynamic residual d = (T_aero - G β̄)/J_r: near the value that
#: balances rated torque at 0.14 rad; the finite-difference run swings it over the range
MODEL_RESIDUAL = Entry("dm_residual", 0.14, "rad/s^2", "aerodynamic residual d",
                       sample=(0.12, 0.16))
theta = sp.symbols(WEIGHTS, real=True)
twist = sp.Symbol("dt_twist_hat", real=True)

PARAMS = [
    # chosen on 60 s of NTM class B at 16 m/s among the grid in docs/controllers.md
    Entry("dt_c1", 2.0, "1/s", "backstepping gain c1 (filtered generator speed error)"),
    Entry("dt_c2", 4.0, "1/s", "backstepping gain c2 (shaft twist error)"),
    Entry("dt_c3", 4.0, "1/s", "backstepping gain c3 (rotor speed error)"),
    Entry("dt_c4", 6.0, "1/s", "backstepping gain c4 (pitch error)"),
    Entry("dt_gamma", 2.0, "-", "adaptation rate γ"),
    Entry("dt_sigma", 0.01, "1/s", "σ-modification of the adaptive law"),
    Entry("dt_theta_max", 2.0, "rad/s^2", "projection bound |θ̂| ≤ θ_max"),
    Entry("dt_J_r", nrel5mw.ROTOR_INERTIA, "kg m^2", "rotor inertia (Jonkman 2009)"),
    Entry("dt_J_g", nrel5mw.GEN_INERTIA_LSS, "kg m^2",
          "generator inertia on the LSS (Jonkman 2009)"),
    Entry("dt_k_s", nrel5mw.SHAFT_STIFFNESS, "N m/rad",
          "drivetrain torsional stiffness (Jonkman 2009)"),
    Entry("dt_d_s", nrel5mw.SHAFT_DAMPING, "N m s/rad",
          "drivetrain torsional damping (Jonkman 2009)"),
    Entry("dt_gearbox_ratio", nrel5mw.GEARBOX_RATIO, "-",
          "gearbox ratio, HSS/LSS (Jonkman 2009)"),
    Entry("dt_gen_torque", nrel5mw.RATED_GEN_TORQUE_LSS, "N m",
          "generator torque on the LSS above rated (constant torque, Jonkman 2009)"),
    *design.actuator_and_fuzzy_params("dt"),
]
# bound by name (an unknown name would be left unbound and fail the generation)
(c1, c2, c3, c4, gam, sig, th_max, J_r, J_g, k_s, d_s, n_gear, T_g, tau_a, bmin, bmax, gmin,
 rmax) = sp.symbols(
    "dt_c1 dt_c2 dt_c3 dt_c4 dt_gamma dt_sigma dt_theta_max dt_J_r dt_J_g dt_k_s dt_d_s "
    "dt_gearbox_ratio dt_gen_torque dt_tau_a dt_pitch_min dt_pitch_max dt_dTdbeta_min "
    "dt_rate_max", real=True)
kappa = sp.Symbol("kappa", real=True)  # adaptation switch, bound to design.freeze


def beta_mean() -> sp.Expr:
    return sum(beta_meas) / N_BLADES


def omega_g() -> sp.Expr:
    """Generator speed on the LSS from the HSS measurement."""
    return omega_g_hss / n_gear


def twist_steady() -> sp.Expr:
    """θ_s* = T_g/k_s: the shaft twist that carries the generator torque."""
    return T_g / k_s


def omega_g_dot_model() -> sp.Expr:
    """Eq (3) with the generator torque, on the twist estimate."""
    return (k_s * twist + d_s * (omega_r - omega_g()) - T_g) / J_g


def h3() -> sp.Expr:
    """The known part of J_r ω̇_r besides G β̄, divided by J_r (eq (1)): the shaft torque."""
    return -(k_s * twist + d_s * (omega_r - omega_g())) / J_r


@cache
def derive() -> design.ControllerDesign:
    rb = fuzzy.RuleBase(1)  # f̂(ω_r)
    b_sym = sp.Symbol("b_sched", real=True)  # b as a symbol: its rate is b_dot
    b = -sp.Max(-dT_dbeta, gmin) / J_r  # G ≤ -gmin < 0 above rated
    F = rb.L()
    g1 = k_s / J_g
    wg = omega_g()
    twist_rate = omega_r - wg
    omega_r_dot_hat = b_sym * beta_mean() + h3() + F
    true_rates = {omega_r: omega_r_dot, omega_g_hss: n_gear * omega_g_dot, twist: twist_rate,
                  b_sym: b_dot, **{yd[k]: yd[k + 1] for k in range(4)}}
    computable = {omega_r_dot: omega_r_dot_hat, omega_g_dot: omega_g_dot_model(), b_dot: 0}

    x1 = wg - d_s / J_g * (twist - twist_steady())
    z1 = x1 - yd[0]
    alpha1 = (T_g / J_g + yd[1] - c1 * z1) / g1

    def rate(expr, z_adapt):
        full = fuzzy.total_derivative(expr, true_rates, rb, [omega_r_dot], z_adapt,
                                      kappa * gam, kappa * sig)
        return full, sp.expand(full.subs(computable))

    z3_sym = sp.Symbol("z3", real=True)  # placeholder for χ of the adaptive law
    a1_full, a1_comp = rate(alpha1, z3_sym)  # no L/B in α1: z3 does not appear
    z2 = twist - alpha1
    alpha2 = wg + a1_comp - c2 * z2 - g1 * z1
    a2_full, a2_comp = rate(alpha2, z3_sym)
    z3 = omega_r - alpha2
    alpha3 = (-c3 * z3 - z2 - h3() - F + a2_comp) / b_sym
    a3_full, a3_comp = rate(alpha3, z3_sym)
    z4 = beta_mean() - alpha3
    U = beta_mean() + tau_a * (-c4 * z4 - b_sym * z3 + a3_comp)

    def fix(e):
        return e.subs(z3_sym, z3).subs(b_sym, b)

    U = fix(U)
    theta_norm2 = sum(t**2 for t in theta)
    z3 = fix(z3)
    k = design.freeze(U.subs(kappa, 1), beta_mean(), tau_a, bmin, bmax, rmax, z3,
                      theta_norm2, gam * z3 * F - sig * theta_norm2, th_max)
    u_clip = sp.Min(sp.Max(U, bmin), bmax)
    x_dot = [kappa * (gam * z3 * rb.phi(m) - sig * t) for m, t in enumerate(theta)]
    x_dot.append(twist_rate)
    # start in equilibrium on the measured pitch: ω̇_r = 0 with θ̂_s = θ_s*, ω_r = ω_g,
    # i.e. f̂ = -h3 - b β̄ (the normalized φ sum to one)
    f0 = (k_s * twist_steady() + d_s * (omega_r - wg)) / J_r - b * beta_mean()
    return design.ControllerDesign(
        rule_base=rb, fuzzy_inputs=["omega_r"], weights=WEIGHTS,
        v=design.free_blade_command(u_clip), u0=U, x_dot=x_dot,
        diag=[fix(z1), z3, fix(z4), kappa], x0=[f0] * N_MF + [twist_steady()],
        intermediates=[(kappa, k)],
        checks={"alpha1": fix(alpha1), "alpha2": fix(alpha2), "alpha3": fix(alpha3),
                "alpha1_dot_full": fix(a1_full), "alpha2_dot_full": fix(a2_full),
                "alpha3_dot_full": fix(a3_full), "alpha1_dot_comp": fix(a1_comp),
                "alpha2_dot_comp": fix(a2_comp), "alpha3_dot_comp": fix(a3_comp),
                "omega_r_dot_hat": fix(omega_r_dot_hat),
                "omega_g_dot_hat": omega_g_dot_model(), "kappa": kappa},
        check_inputs=[omega_r_dot, omega_g_dot, b_dot])


def design_model(d_sym: sp.Symbol) -> dict:
    """The design model's closed loop, for the finite-difference checks of the α̇_i.

    States [ω_r, θ_s, ω_g, β̄] of the equations in the module docstring, with T_aero =
    G β̄ + J_r d (d an exogenous residual) and τ_a β̄̇ = U - β̄ (u = U, unclipped); the
    blades all at β̄, measured exactly, ω_g measured on the HSS. Returns the states, their
    rates, the measurements as expressions of them, and the true rates the α̇_i need.
    """
    w, s, g, bb = sp.symbols([e.name for e in MODEL_STATES], real=True)
    b = -sp.Max(-dT_dbeta, gmin) / J_r
    w_dot = b * bb + d_sym - (k_s * s + d_s * (w - g)) / J_r
    g_dot = (k_s * s + d_s * (w - g) - T_g) / J_g
    return {"states": [w, s, g, bb], "rates": [w_dot, w - g, g_dot],  # β̄̇ by the caller
            "beta_mean": bb, "tau": tau_a,
            "meas": {"omega_r": w, "omega_g_hss": n_gear * g,
                     **{f"beta_meas_{j}": bb for j in range(1, N_BLADES + 1)}},
            "true_rates": {"omega_r_dot": w_dot, "omega_g_dot": g_dot, "b_dot": sp.S.Zero}}
