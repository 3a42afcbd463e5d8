"""Observer-based adaptive fuzzy backstepping, eqs (26)-(49), in SymPy.

Reading of the paper (docs/paper-notes.md gives the reasons and the tests):

* transformed errors (index typos of eqs (36), (41), (45) corrected, paper-notes defect 4):

      χ1 = y - y_d                       (26)
      χ2 = x̂2 - α1 - ẏ_d                 (31: x̂2 = χ2 + α1 + ẏ_d)
      χ3 = x̂3 - α2 - ÿ_d                 (36; printed with ẏ_d)
      χ4 = x̂4 - α3 - y_d⁽³⁾              (45; printed with ÿ_d)

  With this reading α1, α2, α3 and u0 are exactly as printed in eqs (32), (37), (43),
  (49) (with "ÿ_d^(4)" of eq (49) read as y_d⁽⁴⁾), and a time-varying reference is
  tracked: the y_d⁽ⁱ⁾ of χ_{i+1} cancels the -y_d⁽ⁱ⁾ of χ̇_i.
* α̇_i is the total derivative of α_i along the closed loop. It contains ẏ, which is not
  measured (paper-notes defect 5): the controller uses the *computable* part, with ẏ replaced
  by its estimate ẏ̂ = x̂2 + f̂1; the remainder is ∂α_i/∂y (ẏ - ẏ̂). α_{i+1} is built on
  the computable α̇_i.
* the fuzzy systems enter only through the L/B symbols of :mod:`derivation.fuzzy`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache

import sympy as sp

from derivation import fuzzy, observer, plant
from derivation.layout import N_BLADES, N_CHAIN

y, xhat, K_obs = observer.y, observer.xhat, observer.K_obs
ydot = sp.Symbol("ydot", real=True)  # the true ẏ (unmeasured), for the full α̇_i
yd = sp.symbols("yd_0:5", real=True)  # y_d and its first four derivatives
c = sp.symbols(f"c_1:{N_CHAIN + 1}", positive=True)
gamma = sp.symbols(f"gamma_1:{N_CHAIN + 1}", positive=True)
r = sp.symbols(f"r_1:{N_CHAIN + 1}", positive=True)
tau_young = sp.Symbol("tau_young", positive=True)
# the controller's model of the actuators and of the fault it knows (eq (49))
tau_b_model = sp.Symbol("tau_b_model", positive=True)
b = sp.symbols(f"b_1:{N_BLADES + 1}", real=True)
rho_hat = sp.symbols(f"rho_hat_1:{N_BLADES + 1}", real=True)
lock_hat = sp.symbols(f"lock_hat_1:{N_BLADES + 1}", real=True)
ubar_hat = sp.symbols(f"ubar_hat_1:{N_BLADES + 1}", real=True)
control_sign = sp.Symbol("control_sign", real=True)


@dataclass
class Design:
    """Every expression of the controller, in terms of the symbols above and L/B."""

    rule_bases: list[fuzzy.RuleBase]
    chi: list[sp.Expr] = field(default_factory=list)
    alpha: list[sp.Expr] = field(default_factory=list)
    alpha_dot_full: list[sp.Expr] = field(default_factory=list)
    alpha_dot_comp: list[sp.Expr] = field(default_factory=list)
    dalpha_dy: list[sp.Expr] = field(default_factory=list)
    ydot_hat: sp.Expr = sp.S.Zero
    xhat_dot: list[sp.Expr] = field(default_factory=list)
    act_model: sp.Expr = sp.S.Zero
    u0: sp.Expr = sp.S.Zero
    e1: sp.Expr = sp.S.Zero

    def F(self, i: int) -> sp.Symbol:
        """f̂_i = θ̂_iᵀφ_i (1-based i)."""
        return self.rule_bases[i - 1].L()

    def rates(self, ydot_value) -> dict:
        """Time derivatives of every time-varying symbol along the closed loop."""
        rates = {x: xd for x, xd in zip(xhat, self.xhat_dot, strict=True)}
        rates[y] = ydot_value
        rates.update({yd[m]: yd[m + 1] for m in range(4)})
        return rates

    def total_derivative(self, expr: sp.Expr, ydot_value) -> sp.Expr:
        """d/dt of expr along the closed-loop vector field (chain rule, symbol by symbol)."""
        rates = self.rates(ydot_value)
        lb = {}
        for i, rb in enumerate(self.rule_bases):
            for s in rb.symbols():
                lb[s] = i
        out = sp.S.Zero
        for s in sorted(expr.free_symbols, key=lambda q: q.name):
            if s in rates:
                rate = rates[s]
            elif s in lb:
                i = lb[s]
                if i >= len(self.chi):
                    raise ValueError(f"{s} needs χ{i + 1}, which is not defined yet")
                rate = self.rule_bases[i].rate(s, self.xhat_dot, self.chi[i], gamma[i], r[i])
            else:
                continue  # a parameter
            out += sp.diff(expr, s) * rate
        return out


def actuator_weights_model() -> list[sp.Expr]:
    """θ_j of eq (14) as the controller models them: 1/(3 τ_b)."""
    return [1 / (N_BLADES * tau_b_model)] * N_BLADES


@cache
def derive() -> Design:
    """Build χ1..χ4, α1..α3, α̇1..α̇3 (computable and full), and u0 of eq (49)."""
    rbs = [fuzzy.RuleBase(i) for i in range(1, N_CHAIN + 1)]
    d = Design(rule_bases=rbs)
    F = [d.F(i) for i in range(1, N_CHAIN + 1)]
    d.e1 = y - xhat[0]  # e1 = x1 - x̂1, measured since y = x1

    # eq (49)'s actuator model: θᵀu = Σ_locked θ_j ū_j + Σ_free ρ_j θ_j b_j u0, with the
    # lock indicator σ_j ∈ [0, 1] making the two sums one smooth expression.
    theta_act = actuator_weights_model()
    lock_sum = sum(lh * t * ub for lh, t, ub in zip(lock_hat, theta_act, ubar_hat, strict=True))
    gain = sum((1 - lh) * rh * t * bj
               for lh, rh, t, bj in zip(lock_hat, rho_hat, theta_act, b, strict=True))
    u0_sym = sp.Symbol("u0", real=True)
    d.act_model = lock_sum + gain * u0_sym

    d.xhat_dot = observer.observer_rhs(F, d.act_model)  # (21)
    d.ydot_hat = xhat[1] + F[0]  # ẏ̂ = x̂2 + f̂1, eq (11) with the estimates

    tau = tau_young
    # step 1, eqs (26)-(32)
    chi1 = y - yd[0]  # (26)
    alpha1 = -c[0] * chi1 - 2 * chi1 - F[0]  # (32)
    d.chi.append(chi1)
    d.alpha.append(alpha1)
    # step 2, eqs (34)-(37)
    chi2 = xhat[1] - alpha1 - yd[1]  # (31)
    d.chi.append(chi2)
    _differentiate(d, 0)
    alpha2 = (-c[1] * chi2 - chi1 + d.alpha_dot_comp[0] - F[1]
              - K_obs[1] * d.e1 - tau * chi2)  # (37)
    d.alpha.append(alpha2)
    # step 3, eqs (39)-(43)
    chi3 = xhat[2] - alpha2 - yd[2]  # (36)
    d.chi.append(chi3)
    _differentiate(d, 1)
    alpha3 = (-c[2] * chi3 - chi2 + d.alpha_dot_comp[1] - K_obs[2] * d.e1
              - F[2] - tau * chi3)  # (43)
    d.alpha.append(alpha3)
    # step 4, eqs (45)-(49)
    chi4 = xhat[3] - alpha3 - yd[3]  # (45)
    d.chi.append(chi4)
    _differentiate(d, 2)
    bracket = (-chi3 - c[3] * chi4 - K_obs[3] * d.e1 - F[3] + d.alpha_dot_comp[2]
               + yd[4] - tau * chi4 - lock_sum)
    d.u0 = bracket / gain  # (49)
    d.act_model = d.act_model.subs(u0_sym, d.u0)
    d.xhat_dot[-1] = d.xhat_dot[-1].subs(u0_sym, d.u0)
    return d


def _differentiate(d: Design, i: int) -> None:
    """α̇_i full (with the symbol ẏ) and computable (ẏ → ẏ̂); they differ by ∂α_i/∂y (ẏ - ẏ̂)."""
    full = d.total_derivative(d.alpha[i], ydot)
    d.alpha_dot_full.append(full)
    d.dalpha_dy.append(sp.diff(full, ydot))
    d.alpha_dot_comp.append(full.subs(ydot, d.ydot_hat))


def applied_commands(u0) -> list[sp.Expr]:
    """v_j = s b_j u0: the command sent to blade j; s = control_sign (paper-notes defect 2)."""
    return [control_sign * bj * u0 for bj in b]


def adaptive_law_coefficients(d: Design) -> list[tuple[sp.Expr, sp.Symbol]]:
    """θ̂̇_i = γ_i χ_i φ_i - r_i θ̂_i, eqs (32), (37), (43), (49): (γ_i χ_i, r_i) per i."""
    return [(gamma[i] * d.chi[i], r[i]) for i in range(N_CHAIN)]


__all__ = ["Design", "derive", "applied_commands", "adaptive_law_coefficients", "plant"]
