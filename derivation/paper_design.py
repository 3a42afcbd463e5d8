"""The paper's design (Bakhshi & Alfi 2020, eqs (21)-(49)) as a ControllerDesign (issue 34).

The equations stay in derivation/backstepping.py (observer (21), χ_i, α_i and α̇_i, u0 of
eq (49)) and derivation/observer.py; this module hands them to the generator the way every
other design is handed: ``ctrl_paper``/``init_paper`` come from
:func:`derivation.controllers.from_design`, not from a build path of their own.

* the measured output y of eq (9) is the rotor speed ω_r (a signal bound first);
* the four rule bases f̂_i(x̂1..x̂i) read the observer states (triangular regressors,
  paper-notes defect 7), their weights θ̂_i are the controller states after x̂;
* the adaptive laws of eqs (32), (37), (43), (49): θ̂̇_i = γ_i χ_i φ_i - r_i θ̂_i, with γ_i χ_i
  bound once per rule base (as the former build path formed it, so the product rounds the
  same way);
* the commands v_j = s b_j u0 (paper-notes defect 2: s = ``control_sign``), one per blade;
* eq (49)'s fault estimates ρ̂_j, σ̂_j, ū_j are the uniform known-fault input, which takes
  the place of the layout's parameters of the same names;
* the observer starts at rest on what is measured: x̂ = [ω_r, 0, ω_r, β̄], weights zero;
* the four diagnostics are x̂1..x̂4.

The paper's other generated functions (``controller``, ``alpha_derivatives``,
``closed_loop_paper``, ``lyapunov``) are verification artefacts of the same expressions,
built in derivation/generate.py.
"""

from __future__ import annotations

from functools import cache

import sympy as sp

from derivation import backstepping as bs
from derivation import design as design_
from derivation import layout as lay

STATES = lay.CONTROLLER_STATES
PARAMS = lay.CONTROLLER_PARAMS
omega_r = sp.Symbol("omega_r", real=True)
beta_meas = sp.symbols(f"beta_meas_1:{lay.N_BLADES + 1}", real=True)
#: γ_i χ_i of each adaptive law, bound before the laws
adapt_gain = sp.symbols(f"paper_adapt_gain_1:{lay.N_CHAIN + 1}", real=True)


def weight_groups() -> list[list[str]]:
    """The state names of θ̂_1..θ̂_4, in rule order (layout order)."""
    return lay.split_by_rules([e.name for e in STATES[lay.N_CHAIN:]])


@cache
def derive() -> design_.ControllerDesign:
    """The paper's controller in the uniform form; see the module docstring."""
    d = bs.derive()
    groups = weight_groups()
    coefficients = bs.adaptive_law_coefficients(d)
    theta_dot = []
    for i, (rb, group) in enumerate(zip(d.rule_bases, groups, strict=True)):
        _, r_i = coefficients[i]
        theta_dot += [adapt_gain[i] * rb.phi(m) - r_i * sp.Symbol(w, real=True)
                      for m, w in enumerate(group)]
    beta_mean = sum(beta_meas) / lay.N_BLADES
    n_w = len(STATES) - lay.N_CHAIN
    return design_.ControllerDesign(
        v=bs.applied_commands(d.u0), u0=d.u0, x_dot=[*d.xhat_dot, *theta_dot],
        diag=list(bs.xhat), x0=[omega_r, 0, omega_r, beta_mean, *[0] * n_w],
        rule_bases=d.rule_bases, fuzzy_inputs=[x.name for x in bs.xhat],
        weight_groups=groups, signals=[(bs.y, omega_r)],
        intermediates=[(adapt_gain[i], g) for i, (g, _) in
                       enumerate(coefficients)])
