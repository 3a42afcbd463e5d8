"""A test-only controller: the smallest adaptive fuzzy backstepping pitch design.

It exists to prove that a controller is one derivation module plus one registry entry
(tests/test_new_controller.py registers it in a temporary copy of the registry; no other
file knows it). The chain is the physical design's (derivation/physical.py) without its
anti-windup and projection:

    z1 = ω_r - y_d                α1 = (-c1 z1 - h0 - f̂ + ẏ_d)/b    (desired mean pitch)
    z2 = β̄ - α1                   U = β̄ + τ_a (-c2 z2 - b z1 + α̇1c)
    θ̂̇ = γ z1 φ(ω_r) - σ θ̂        b = G/J, h0 = -T_g/J, G = ∂T/∂β (scheduled)
"""

from __future__ import annotations

from functools import cache

import sympy as sp

from derivation import design, fuzzy
from derivation.layout import N_BLADES, N_MF, Entry

omega_r = sp.Symbol("omega_r", real=True)
beta_meas = sp.symbols(f"beta_meas_1:{N_BLADES + 1}", real=True)
yd = sp.symbols("yd_0:5", real=True)
dT_dbeta = sp.Symbol("dT_dbeta", real=True)
omega_r_dot, b_dot = sp.symbols("omega_r_dot b_dot", real=True)  # true rates (checks only)

WEIGHTS = [f"toy_theta_hat[{m}]" for m in range(N_MF)]
STATES = [Entry(w, 0.0, "rad/s^2", f"fuzzy weight {m} of f̂(ω_r)", sample=(-0.5, 1.0))
          for m, w in enumerate(WEIGHTS)]
PARAMS = [
    Entry("toy_c1", 2.0, "1/s", "gain c1 (speed error)"),
    Entry("toy_c2", 6.0, "1/s", "gain c2 (pitch error)"),
    Entry("toy_gamma", 2.0, "-", "adaptation rate γ"),
    Entry("toy_sigma", 0.01, "1/s", "σ-modification"),
    Entry("toy_inertia", 43_784_725.0, "kg m^2", "J_r + N² J_g of the NREL 5-MW"),
    Entry("toy_gen_torque", 4_180_074.35, "N m", "rated generator torque on the LSS"),
    *design.actuator_and_fuzzy_params("toy"),
]
c1, c2, gam, sig, J, T_g, tau_a, bmin, bmax, gmin = sp.symbols(
    "toy_c1 toy_c2 toy_gamma toy_sigma toy_inertia toy_gen_torque toy_tau_a toy_pitch_min "
    "toy_pitch_max toy_dTdbeta_min", real=True)
theta = sp.symbols(WEIGHTS, real=True)
MODEL_STATES = [Entry("dm_omega_r", 1.28, "rad/s", "rotor speed", sample=(1.1, 1.45)),
                Entry("dm_beta", 0.14, "rad", "mean blade pitch", sample=(0.0, 0.4))]
MODEL_RESIDUAL = Entry("dm_residual", 0.14, "rad/s^2", "aerodynamic residual d",
                       sample=(0.12, 0.16))


def _b() -> sp.Expr:
    return -sp.Max(-dT_dbeta, gmin) / J


@cache
def derive() -> design.ControllerDesign:
    rb = fuzzy.RuleBase(1)
    b_sym = sp.Symbol("b_sched", real=True)
    beta = sum(beta_meas) / N_BLADES
    h0, F = -T_g / J, rb.L()
    z1 = omega_r - yd[0]
    alpha1 = (-c1 * z1 - h0 - F + yd[1]) / b_sym
    full = fuzzy.total_derivative(alpha1, {omega_r: omega_r_dot, yd[0]: yd[1], yd[1]: yd[2],
                                           b_sym: b_dot}, rb, [omega_r_dot], z1, gam, sig)
    comp = full.subs({omega_r_dot: b_sym * beta + h0 + F, b_dot: 0})
    U = (beta + tau_a * (-c2 * (beta - alpha1) - b_sym * z1 + comp)).subs(b_sym, _b())
    alpha1 = alpha1.subs(b_sym, _b())
    return design.ControllerDesign(
        rule_base=rb, fuzzy_inputs=["omega_r"], weights=WEIGHTS,
        v=design.free_blade_command(sp.Min(sp.Max(U, bmin), bmax)), u0=U,
        x_dot=[gam * z1 * rb.phi(m) - sig * t for m, t in enumerate(theta)],
        diag=[z1, beta - alpha1, alpha1, F], x0=[-h0 - _b() * beta] * N_MF,
        checks={"alpha1": alpha1, "alpha1_dot_full": full.subs(b_sym, _b()),
                "alpha1_dot_comp": comp.subs(b_sym, _b())},
        check_inputs=[omega_r_dot, b_dot])


def design_model(d_sym: sp.Symbol) -> dict:
    """Rigid rotor J ω̇ = G β̄ + J d - T_g, τ_a β̄̇ = U - β̄ (β̄ last: its rate is the caller's)."""
    w, bb = sp.symbols([e.name for e in MODEL_STATES], real=True)
    w_dot = _b() * bb + d_sym - T_g / J
    return {"states": [w, bb], "rates": [w_dot], "beta_mean": bb, "tau": tau_a,
            "meas": {"omega_r": w, "omega_g_hss": 97 * w,  # rigid shaft, gearbox 97
                     **{f"beta_meas_{j}": bb for j in range(1, N_BLADES + 1)}},
            "true_rates": {"omega_r_dot": w_dot, "b_dot": sp.S.Zero}}
