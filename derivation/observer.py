"""The fuzzy state observer, eqs (20)-(22), in SymPy."""

from __future__ import annotations

import sympy as sp

from derivation.layout import N_CHAIN

xhat = sp.symbols(f"xhat_1:{N_CHAIN + 1}", real=True)
K_obs = sp.symbols(f"K_obs_1:{N_CHAIN + 1}", real=True)
y = sp.Symbol("y", real=True)


def A_obs(K=K_obs) -> sp.Matrix:
    """A of eqs (20)-(21): -K in the first column, ones on the superdiagonal.

    (Eq (20) says it rewrites "Eq. (4)"; it rewrites eqs (11)-(14), paper-notes defect 4.)
    """
    n = len(K)
    A = sp.zeros(n, n)
    for k in range(n):
        A[k, 0] = -K[k]
        if k + 1 < n:
            A[k, k + 1] = 1
    return A


def observer_rhs(F, act) -> list[sp.Expr]:
    """Eq (21): x̂̇ = A x̂ + K y + Σ B_i f̂_i(x̂1..x̂i) + B θᵀu.

    F[i] is f̂_i = θ̂_iᵀφ_i(x̂1..x̂i) (triangular regressors, paper-notes defect 7);
    act is θᵀu as the controller models it (with the fault it knows of, eq (49)).
    """
    Ax = A_obs() * sp.Matrix(xhat)
    rhs = [Ax[k] + K_obs[k] * y + F[k] for k in range(N_CHAIN)]
    rhs[-1] += act
    return rhs


def error_rhs(e, f_true_plus_d, F_hat, act_error) -> list[sp.Expr]:
    """Eq (22)'s error dynamics: ė = A e + Σ B_i (f_i(X) + d_i - f̂_i) + B (θᵀu - θᵀû).

    Follows from eq (20) minus eq (21): the Ky terms cancel because y = x1.
    """
    Ae = A_obs() * sp.Matrix(e)
    out = [Ae[k] + f_true_plus_d[k] - F_hat[k] for k in range(N_CHAIN)]
    out[-1] += act_error
    return out


def characteristic_polynomial(K=K_obs) -> sp.Poly:
    """det(sI - A) = s⁴ + K1 s³ + K2 s² + K3 s + K4 for the companion form of eq (20)."""
    s = sp.Symbol("s")
    return sp.Poly((s * sp.eye(len(K)) - A_obs(K)).det(), s)


def routh_hurwitz(K=K_obs) -> list[sp.Expr]:
    """Routh-Hurwitz conditions for the quartic above: all > 0 ⇔ A is Hurwitz.

    For s⁴ + a s³ + b s² + c s + d: a > 0, ab - c > 0, c(ab - c) - a² d > 0, d > 0.
    """
    coeffs = characteristic_polynomial(K).all_coeffs()
    assert coeffs[0] == 1 and len(coeffs) == 5
    _, a, b, c, d = coeffs
    return [a, a * b - c, c * (a * b - c) - a**2 * d, d]
