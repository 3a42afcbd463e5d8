"""The controllers the simulator can run: one entry each, one uniform generated signature.

Adding a controller is one derivation module (its equations) plus one entry in
:data:`REGISTRY`. For each entry the generator emits

    ctrl_<name>(x_ctrl, meas, yd, sched, p_ctrl, known_fault) -> (v, x_ctrl_dot, u0, diag)
    init_<name>(meas, p_ctrl) -> x_ctrl0

and lists it under "controllers" in generated/layout.json, from which wtftc reads it.

* meas = [ω_r, ω_g (HSS), β_meas,1..3]: what a turbine measures; never the plant state;
* yd = the rotor-speed reference and its four derivatives;
* sched = [∂T_aero/∂β] at the measured mean pitch on the steady operating curve, from
  the Cp table (the runtime builds it; see wtftc.simulate.pitch_sensitivity_schedule);
* known_fault = [ρ̂_j, σ̂_j, ū_j] as eq (49) is told (nominal when the fault is unknown);
* v = the three blade pitch commands [rad]; u0 = the controller's scalar command;
* diag = four controller-specific diagnostics (named in the registry).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca

from derivation import layout as lay
from derivation import pi_baseline
from derivation.casadi_build import Translator

MEAS = ["omega_r", "omega_g_hss", *[f"beta_meas_{j}" for j in range(1, lay.N_BLADES + 1)]]
MEAS_UNITS = ["rad/s", "rad/s", *["rad"] * lay.N_BLADES]
SCHED = ["dT_dbeta"]
N_DIAG = 4


@dataclass
class Controller:
    name: str
    doc: str
    states: list[lay.Entry]
    params: list[lay.Entry]
    states_group: str
    params_group: str
    diag_names: list[str]
    build: Callable  # (symbols dict) -> dict of CasADi outputs v, x_ctrl_dot, u0, diag, x0


def _paper(sym: dict, controller_fn: ca.Function) -> dict:
    """The paper's design (eqs 21-49) behind the uniform signature."""
    p = sym["p_ctrl"]
    i0 = [e.name for e in lay.CONTROLLER_PARAMS].index("rho_hat_1")
    kf = sym["known_fault"]
    p_eff = ca.vertcat(p[:i0], kf, p[i0 + kf.numel():])
    out = controller_fn(x_ctrl=sym["x_ctrl"], y=sym["meas"][0], yd=sym["yd"], p_ctrl=p_eff)
    meas = sym["meas"]
    beta_mean = ca.sum1(meas[2:]) / lay.N_BLADES
    # observer at rest on what is measured: x̂ = [ω_r, 0, ω_r, β̄], weights zero
    n_w = len(lay.CONTROLLER_STATES) - lay.N_CHAIN
    x0 = ca.vertcat(meas[0], 0, meas[0], beta_mean, ca.DM.zeros(n_w))
    return {"v": out["v"], "x_ctrl_dot": out["x_ctrl_dot"], "u0": out["u0"],
            "diag": sym["x_ctrl"][:4], "x0": x0}


def _pi(sym: dict) -> dict:
    names = {**{n: sym["meas"][k] for k, n in enumerate(MEAS)},
             "yd_0": sym["yd"][0], "dT_dbeta": sym["sched"][0],
             "pi_integrator": sym["x_ctrl"][0],
             **{e.name: sym["p_ctrl"][k] for k, e in enumerate(pi_baseline.PARAMS)}}
    tr = Translator(names)
    cmd, xi_dot, diag = pi_baseline.law()
    c = tr(cmd)
    return {"v": ca.repmat(c, lay.N_BLADES, 1), "x_ctrl_dot": tr(xi_dot), "u0": c,
            "diag": ca.vertcat(*[tr(d) for d in diag]),
            "x0": tr(pi_baseline.initial_integrator())}


REGISTRY: dict[str, Controller] = {
    "paper": Controller(
        "paper", "Bakhshi & Alfi (2020) observer-based adaptive fuzzy backstepping, eq (49)",
        lay.CONTROLLER_STATES, lay.CONTROLLER_PARAMS, "controller_states",
        "controller_params", ["xhat_1", "xhat_2", "xhat_3", "xhat_4"], None),
    "pi": Controller(
        "pi", "gain-scheduled PI on collective pitch with anti-windup (baseline, "
              "Jonkman 2009 / ROSCO)",
        pi_baseline.STATES, pi_baseline.PARAMS, "pi_states", "pi_params",
        ["speed_error", "integrator", "Kp", "Ki"], _pi),
}


def build(controller_fn: ca.Function) -> list[ca.Function]:
    """ctrl_<name> and init_<name> for every registered controller."""
    out = []
    for c in REGISTRY.values():
        sym = {"x_ctrl": ca.SX.sym("x_ctrl", len(c.states)),
               "meas": ca.SX.sym("meas", len(MEAS)),
               "yd": ca.SX.sym("yd", len(lay.REFERENCE)),
               "sched": ca.SX.sym("sched", len(SCHED)),
               "p_ctrl": ca.SX.sym("p_ctrl", len(c.params)),
               "known_fault": ca.SX.sym("known_fault", len(lay.FAULT_INPUTS))}
        res = _paper(sym, controller_fn) if c.name == "paper" else c.build(sym)
        ins = ["x_ctrl", "meas", "yd", "sched", "p_ctrl", "known_fault"]
        outs = {"v": res["v"], "x_ctrl_dot": res["x_ctrl_dot"], "u0": res["u0"],
                "diag": res["diag"]}
        out.append(ca.Function(f"ctrl_{c.name}", [sym[k] for k in ins],
                               [ca.cse(ca.densify(o)) for o in outs.values()], ins, list(outs)))
        out.append(ca.Function(f"init_{c.name}", [sym["meas"], sym["p_ctrl"]],
                               [ca.densify(res["x0"])], ["meas", "p_ctrl"], ["x_ctrl0"]))
    return out


def as_json() -> dict:
    return {
        "controllers": {c.name: {"function": f"ctrl_{c.name}", "init": f"init_{c.name}",
                                 "states": c.states_group, "params": c.params_group,
                                 "diag": c.diag_names, "doc": c.doc}
                        for c in REGISTRY.values()},
        "measurements": [{"name": n, "unit": u} for n, u in zip(MEAS, MEAS_UNITS, strict=True)],
        "schedule": SCHED,
        "groups": {f"{c.states_group}": c.states for c in REGISTRY.values()
                   if c.states_group != "controller_states"}
        | {f"{c.params_group}": c.params for c in REGISTRY.values()
           if c.params_group != "controller_params"},
    }
