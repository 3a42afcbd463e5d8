"""The paper's plant, eqs (1)-(19), in SymPy.

Only symbols and expressions live here; :mod:`derivation.generate` turns them into code.

The pitch of eq (4) is modelled per blade (three actuators, paper-notes defect 9): each blade
follows eq (4) with its own command u_j, and the chain state x4 of eq (8) is their mean,
so that ẋ4 = -a5 x4 + Σ_j θ_j u_j with θ_j = a5/3, which is eq (14)'s θᵀu.
"""

from __future__ import annotations

import sympy as sp

from derivation.layout import N_BLADES

# states of eqs (1)-(4)
omega_r, theta_s, omega_g = sp.symbols("omega_r theta_s omega_g", real=True)
beta = sp.symbols(f"beta_1:{N_BLADES + 1}", real=True)
# parameters of eq (10)
J_r, J_g, k_s, d_s, tau_b = sp.symbols("J_r J_g k_s d_s tau_b", positive=True)
# disturbance d1(X, t) of eq (5): the F ω_r term of eq (1), aerodynamic torque / J_r
d1 = sp.Symbol("d1", real=True)
# applied commands v_j and the fault parameters of eq (19)
v = sp.symbols(f"v_1:{N_BLADES + 1}", real=True)
rho = sp.symbols(f"rho_1:{N_BLADES + 1}", real=True)
lock = sp.symbols(f"lock_1:{N_BLADES + 1}", real=True)
ubar = sp.symbols(f"ubar_1:{N_BLADES + 1}", real=True)

STATES = [omega_r, theta_s, omega_g, *beta]
PARAMS = [J_r, J_g, k_s, d_s, tau_b]
FAULT = [*rho, *lock, *ubar]


def a_coefficients() -> tuple[sp.Expr, ...]:
    """a1..a5 of eq (10)."""
    return k_s / J_r, d_s / J_r, k_s / J_g, d_s / J_g, 1 / tau_b


def actuator_input(v_j, rho_j, lock_j, ubar_j):
    """Eq (19): u = ρ v + σ (ū - ρ v); σ = 1 locks the actuator at ū."""
    return rho_j * v_j + lock_j * (ubar_j - rho_j * v_j)


def paper_rhs() -> list[sp.Expr]:
    """Eqs (1)-(4) with eq (4) per blade; F ω_r of eq (1) written as d1 (eq (5))."""
    u = [actuator_input(*a) for a in zip(v, rho, lock, ubar, strict=True)]
    return [
        -k_s / J_r * theta_s - d_s / J_r * omega_r + d_s / J_r * omega_g + d1,  # (1)
        omega_r - omega_g,  # (2)
        k_s / J_g * theta_s + d_s / J_g * omega_r - d_s / J_g * omega_g,  # (3)
        *[-1 / tau_b * b + 1 / tau_b * u_j for b, u_j in zip(beta, u, strict=True)],  # (4)
    ]


def chain_state() -> list[sp.Expr]:
    """X = [x1, x2, x3, x4] of eqs (5)-(8): x4 is the mean blade pitch."""
    return [omega_r, theta_s, omega_g, sum(beta) / N_BLADES]


def actuator_weights() -> list[sp.Expr]:
    """θ_j of θᵀu in eq (14): a5 / N_BLADES each, since x4 is the mean pitch."""
    a5 = a_coefficients()[4]
    return [a5 / N_BLADES] * N_BLADES


def strict_feedback_f(X) -> list[sp.Expr]:
    """f1..f4 of eqs (15)-(18) as functions of X = [x1, x2, x3, x4]."""
    a1, a2, a3, a4, a5 = a_coefficients()
    x1, x2, x3, x4 = X
    return [
        -a1 * x2 - a2 * x1 + a2 * x3 - x2,  # (15)
        x1 - 2 * x3,  # (16)
        a3 * x2 + a4 * x1 - a4 * x3 - x4,  # (17)
        -a5 * x4,  # (18)
    ]


def strict_feedback_rhs(X, thetaT_u, d) -> list[sp.Expr]:
    """Eqs (11)-(14): ẋ1 = f1 + x2 + d, ẋ2 = f2 + x3, ẋ3 = f3 + x4, ẋ4 = f4 + θᵀu."""
    f1, f2, f3, f4 = strict_feedback_f(X)
    x1, x2, x3, x4 = X
    return [f1 + x2 + d, f2 + x3, f3 + x4, f4 + thetaT_u]


def strict_feedback_residual() -> list[sp.Expr]:
    """Eqs (1)-(4) mapped to X minus eqs (11)-(18); identically zero when they agree.

    Eq (16) as printed, f2 = x1 - 2 x3, gives ẋ2 = x1 - x3 = eq (6). The check is exact
    (``sp.expand`` of small rational expressions, no ``simplify``).
    """
    rhs = paper_rhs()
    X = chain_state()
    Xdot_paper = [rhs[0], rhs[1], rhs[2], sum(rhs[3:]) / N_BLADES]
    u = [actuator_input(*a) for a in zip(v, rho, lock, ubar, strict=True)]
    thetaT_u = sum(t * u_j for t, u_j in zip(actuator_weights(), u, strict=True))
    Xdot_sf = strict_feedback_rhs(X, thetaT_u, d1)
    return [sp.expand(a - b) for a, b in zip(Xdot_paper, Xdot_sf, strict=True)]
