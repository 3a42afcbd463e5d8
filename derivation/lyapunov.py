"""Lyapunov terms, eqs (22)-(52), in SymPy.

* P from AᵀP + PA = -Q (eq (22)) as a linear system in the entries of P; the generator
  solves it. The Routh-Hurwitz conditions of A say whether a P > 0 exists
  (Table 1's K = [1 1 5 5]: it does not, paper-notes defect 1).
* V_o = ½ eᵀPe (22), V_i = V_{i-1} + ½χ_i² + θ̃_iᵀθ̃_i/(2γ_i) (30, 35, 40, 47),
  with e = X - X̂ and θ̃_i = θ*_i - θ̂_i; θ*_i are parameters (fit them on a trajectory
  with :func:`wtftc.verify.lyapunov.fit_theta_star`).
* V̇_o .. V̇_4 along the closed loop in the paper's structured form, *before* any Young
  inequality: the exact identities behind eqs (22), (31), (36), (42), (48). Tests check
  them against ∇V·f of the generated closed loop.

The weight vectors enter only through scalars the generator computes:
``Lstar_i`` = θ*_iᵀφ_i, ``tt_i`` = θ̃_iᵀθ̃_i, ``ts_i`` = θ̃_iᵀθ̂_i.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import sympy as sp

from derivation import backstepping as bs
from derivation import observer, plant
from derivation.layout import N_BLADES, N_CHAIN

P_entries = sp.symbols("P_0:4_0:4", real=True)
Q_entries = sp.symbols("Q_0:4_0:4", real=True)
Lstar = sp.symbols(f"Lstar_1:{N_CHAIN + 1}", real=True)
tt = sp.symbols(f"tt_1:{N_CHAIN + 1}", real=True)
ts = sp.symbols(f"ts_1:{N_CHAIN + 1}", real=True)
STAR_NORM2 = sp.symbols(f"star_norm2_1:{N_CHAIN + 1}", real=True)  # θ*_iᵀθ*_i


def P_matrix() -> sp.Matrix:
    return sp.Matrix(N_CHAIN, N_CHAIN, P_entries)


def lyapunov_equation() -> tuple[sp.Matrix, sp.Matrix, list[sp.Symbol]]:
    """AᵀP + PA = -Q with P symmetric, as M(K) p = b(Q) in the upper-triangle unknowns p."""
    n = N_CHAIN
    unknowns = [sp.Symbol(f"p_{i}_{j}") for i in range(n) for j in range(i, n)]
    Psym = sp.zeros(n, n)
    it = iter(unknowns)
    for i in range(n):
        for j in range(i, n):
            Psym[i, j] = Psym[j, i] = next(it)
    A = observer.A_obs()
    Q = sp.Matrix(n, n, Q_entries)
    R = A.T * Psym + Psym * A + (Q + Q.T) / 2
    eqs = [R[i, j] for i in range(n) for j in range(i, n)]
    M, rhs = sp.linear_eq_to_matrix(eqs, unknowns)
    return M, rhs, unknowns


@dataclass
class Terms:
    V: list[sp.Expr]  # V_o, V_1..V_4
    Vdot: list[sp.Expr]  # their time derivatives along the closed loop, structured form
    kappa_terms: list[sp.Expr]  # eq (51)'s decay-rate candidates (all > 0 needed)
    kappa_labels: list[str]
    zeta_theta: sp.Expr  # the θ* part of ζ, eq (52)


@cache
def derive() -> Terms:
    d = bs.derive()
    X = plant.chain_state()
    e = [X[k] - observer.xhat[k] for k in range(N_CHAIN)]  # e = X - X̂, eq (22)
    P = (P_matrix() + P_matrix().T) / 2  # only the symmetric part of P enters V_o
    ev = sp.Matrix(e)
    V_o = sp.Rational(1, 2) * (ev.T * P * ev)[0, 0]  # (22)

    # true θᵀu (eq (14) on the plant) and the observer's model of it (eq (49))
    a5 = plant.a_coefficients()[4]
    u0 = d.u0
    v = bs.applied_commands(u0)
    u_true = [plant.actuator_input(*a) for a in zip(v, plant.rho, plant.lock, plant.ubar,
                                                    strict=True)]
    act_true = sum(a5 / N_BLADES * u_j for u_j in u_true)
    act_err = act_true - d.act_model

    f = plant.strict_feedback_f(X)
    f_plus_d = [f[0] + plant.d1, f[1], f[2], f[3]]
    # Δ_i = f_i(X) + d_i - θ*_iᵀφ_i: approximation error and disturbance (paper Δf + δ)
    Delta = [f_plus_d[k] - Lstar[k] for k in range(N_CHAIN)]
    theta_tilde_phi = [Lstar[k] - d.F(k + 1) for k in range(N_CHAIN)]  # θ̃_iᵀφ_i
    A = observer.A_obs()
    Ae = A * ev
    PAe = (ev.T * P * Ae)[0, 0]  # = ½ eᵀ(AᵀP + PA)e, P symmetric
    drive = [Delta[k] + theta_tilde_phi[k] for k in range(N_CHAIN)]
    drive[-1] += act_err
    Vdot_o = PAe + (ev.T * P * sp.Matrix(drive))[0, 0]  # (22), exact

    chi = d.chi
    c, gamma, r, tau = bs.c, bs.gamma, bs.r, bs.tau_young
    ydot_true = f[0] + X[1] + plant.d1  # eq (11)
    remainder = [d.dalpha_dy[i] * (d.ydot_hat - ydot_true) for i in range(3)]  # α̇c - α̇f
    e2 = e[1]
    chi_dot = [
        chi[1] - (c[0] + 2) * chi[0] + e2 + Delta[0] + theta_tilde_phi[0],  # (29) with (32)
        chi[2] - chi[0] - (c[1] + tau) * chi[1] + remainder[0],  # (34) with (37)
        chi[3] - chi[1] - (c[2] + tau) * chi[2] + remainder[1],  # (39) with (43)
        -chi[2] - (c[3] + tau) * chi[3] + remainder[2],  # (46) with (49)
    ]
    V = [V_o]
    Vdot = [Vdot_o]
    for i in range(N_CHAIN):
        V.append(V[-1] + chi[i] ** 2 / 2 + tt[i] / (2 * gamma[i]))  # (30), (35), (40), (47)
        # θ̃̇ = -θ̂̇ = -(γ χ φ - r θ̂): θ̃ᵀθ̃̇/γ = -χ θ̃ᵀφ + (r/γ) θ̃ᵀθ̂
        Vdot.append(Vdot[-1] + chi[i] * chi_dot[i]
                    - chi[i] * theta_tilde_phi[i] + r[i] / gamma[i] * ts[i])

    # eq (50) → (51): V̇_4 ≤ -κ V_4 + ζ needs every candidate below positive
    kappa_terms = [2 * ci for ci in c]
    kappa_terms.append(r[0] - 2 * gamma[0] / tau)  # θ̃1: (1/τ - r1/(2γ1)) θ̃ᵀθ̃ in (50)
    kappa_terms += [r[i] - 4 * gamma[i] / tau for i in range(1, N_CHAIN)]  # (2/τ) θ̃ᵀθ̃
    # (52) sums i = 2..4; eq (50) carries the i = 1 term as well, so it is kept here
    zeta_theta = sum(r[i] / (2 * gamma[i]) * STAR_NORM2[i] for i in range(N_CHAIN))
    labels = [f"2 c{k}" for k in range(1, 5)] + ["r1 - 2γ1/τ"] + [
        f"r{k} - 4γ{k}/τ" for k in range(2, 5)]
    return Terms(V=V, Vdot=Vdot, kappa_terms=kappa_terms, kappa_labels=labels,
                 zeta_theta=zeta_theta)

