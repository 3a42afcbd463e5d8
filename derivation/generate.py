"""Turn the derivation into CasADi functions and files: ``python -m derivation.generate DIR``.

Writes into DIR (``generated/`` by default):

* ``<group>.c``           C source of every function of a group (one shared object each);
* ``<function>.casadi``   each function serialized (CasADi's virtual machine fallback);
* ``layout.json``         the ordering of states, inputs and parameters, and each
                          function's named inputs and outputs with their sizes;
* ``manifest.json``       sha256 of every derivation source and every artefact, the sympy
                          and casadi versions, and each function's operation count.

Every file is headed "generated from <module>, do not edit"; nothing in it depends on the
time, the machine or the hash seed, so two runs give identical bytes.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import sympy as sp

from derivation import backstepping as bs
from derivation import controllers, fdi, lyapunov, nrel5mw, observer, plant, sensors, turbine
from derivation import layout as lay
from derivation.casadi_build import FuzzyEvaluator, Translator, joint_cse
from wtftc.files import swap_folder

ROOT = Path(__file__).resolve().parent.parent
DERIVATION_DIR = Path(__file__).resolve().parent
HEADER = "generated from {modules}, do not edit"


@dataclass
class Group:
    """Functions that share one C file and one list of source modules."""

    name: str
    modules: list[str]
    functions: list[ca.Function]


def _vec(name: str, n: int) -> ca.SX:
    return ca.SX.sym(name, n)


def _named(vec: ca.SX, entries) -> dict[str, ca.SX]:
    return {e.name: vec[k] for k, e in enumerate(entries)}


class Symbols:
    """The SX inputs every function draws from, named by the layout."""

    def __init__(self):
        self.x_plant = _vec("x_plant", len(lay.PLANT_STATES))
        self.x_ctrl = _vec("x_ctrl", len(lay.CONTROLLER_STATES))
        self.p_plant = _vec("p_plant", len(lay.PLANT_PARAMS))
        self.p_ctrl = _vec("p_ctrl", len(lay.CONTROLLER_PARAMS))
        self.fault = _vec("fault", len(lay.FAULT_INPUTS))
        self.yd = _vec("yd", len(lay.REFERENCE))
        self.theta_star = _vec("theta_star", len(lay.THETA_STAR))
        self.v = _vec("v", lay.N_BLADES)
        self.d1 = ca.SX.sym("d1")
        self.y = ca.SX.sym("y")
        self.ydot = ca.SX.sym("ydot")
        self.xhat = self.x_ctrl[: lay.N_CHAIN]
        self.thetas = lay.split_by_rules(self.x_ctrl[lay.N_CHAIN:])
        self.thetas_star = lay.split_by_rules(self.theta_star)

    def names(self) -> dict[str, ca.SX]:
        out = {}
        out.update(_named(self.x_plant, lay.PLANT_STATES))
        out.update(_named(self.p_plant, lay.PLANT_PARAMS))
        out.update(_named(self.p_ctrl, lay.CONTROLLER_PARAMS))
        out.update(_named(self.fault, lay.FAULT_INPUTS))
        out.update(_named(self.yd, lay.REFERENCE))
        out.update({f"xhat_{k + 1}": self.xhat[k] for k in range(lay.N_CHAIN)})
        out.update({f"v_{j + 1}": self.v[j] for j in range(lay.N_BLADES)})
        out.update({"d1": self.d1, "y": self.y, "ydot": self.ydot})
        return out


def _function(name, inputs: dict, outputs: dict) -> ca.Function:
    outs = joint_cse(list(outputs.values()))
    return ca.Function(name, list(inputs.values()), outs, list(inputs), list(outputs))


def build_plant(S: Symbols) -> list[ca.Function]:
    tr = Translator(S.names())
    xdot = ca.vertcat(*[tr(e) for e in plant.paper_rhs()])
    X = ca.vertcat(*[tr(e) for e in plant.chain_state()])
    f_plus_d = [tr(e) for e in plant.strict_feedback_f(plant.chain_state())]
    f_plus_d[0] = f_plus_d[0] + S.d1
    ins = {"x_plant": S.x_plant, "v": S.v, "d1": S.d1, "fault": S.fault, "p_plant": S.p_plant}
    paper = _function("plant_paper", ins, {"x_plant_dot": xdot, "y": S.x_plant[0], "X": X})
    targets = _function(
        "strict_feedback_targets",
        {"x_plant": S.x_plant, "d1": S.d1, "p_plant": S.p_plant},
        {"f_plus_d": ca.vertcat(*f_plus_d), "X": X})
    return [paper, targets]


def _controller_translator(S: Symbols, d: bs.Design) -> tuple[Translator, FuzzyEvaluator]:
    params = _named(S.p_ctrl, lay.CONTROLLER_PARAMS)
    fz = FuzzyEvaluator(S.xhat, params, S.thetas)
    return Translator({**S.names(), **fz.symbol_values(d.rule_bases)}), fz


def controller_outputs(S: Symbols) -> dict[str, ca.SX]:
    """u0 (49), the commands v_j, the controller state derivative (21) + adaptive laws."""
    d = bs.derive()
    tr, fz = _controller_translator(S, d)
    u0 = tr(d.u0)
    v = ca.vertcat(*[tr(e) for e in bs.applied_commands(d.u0)])
    xhat_dot = [tr(e) for e in d.xhat_dot]
    theta_dot = [g_chi_i * fz.phi(i + 1) - tr(r_i) * S.thetas[i]
                 for i, (g_chi_i, r_i) in enumerate(
                     (tr(g), r) for g, r in bs.adaptive_law_coefficients(d))]
    return {
        "u0": u0,
        "v": v,
        "x_ctrl_dot": ca.vertcat(*xhat_dot, *theta_dot),
        "chi": ca.vertcat(*[tr(e) for e in d.chi]),
        "alpha": ca.vertcat(*[tr(e) for e in d.alpha]),
        "alpha_dot": ca.vertcat(*[tr(e) for e in d.alpha_dot_comp]),
        "ydot_hat": tr(d.ydot_hat),
    }


def build_controller(S: Symbols) -> list[ca.Function]:
    d = bs.derive()
    ins = {"x_ctrl": S.x_ctrl, "y": S.y, "yd": S.yd, "p_ctrl": S.p_ctrl}
    outs = controller_outputs(S)
    ctrl = _function("controller", ins, outs)
    tr, fz = _controller_translator(S, d)
    alphas = _function(
        "alpha_derivatives",
        {**ins, "ydot": S.ydot},
        {"alpha": ca.vertcat(*[tr(e) for e in d.alpha]),
         "alpha_dot_full": ca.vertcat(*[tr(e) for e in d.alpha_dot_full]),
         "alpha_dot_comp": ca.vertcat(*[tr(e) for e in d.alpha_dot_comp]),
         "dalpha_dy": ca.vertcat(*[tr(e) for e in d.dalpha_dy]),
         "ydot_hat": tr(d.ydot_hat)})
    phis = {f"phi_{i}": fz.phi(i) for i in range(1, lay.N_CHAIN + 1)}
    regress = _function("fuzzy_regressors", {"xhat": S.xhat, "p_ctrl": S.p_ctrl}, phis)
    return [ctrl, alphas, regress]


def build_closed_loop(S: Symbols, plant_fn: ca.Function, ctrl_fn: ca.Function) -> ca.Function:
    """Plant (1)-(4) with faults (19), observer (21), adaptive laws and u0 (49): ż = f(z)."""
    z = ca.vertcat(S.x_plant, S.x_ctrl)
    c = ctrl_fn(x_ctrl=S.x_ctrl, y=S.x_plant[0], yd=S.yd, p_ctrl=S.p_ctrl)
    p = plant_fn(x_plant=S.x_plant, v=c["v"], d1=S.d1, fault=S.fault, p_plant=S.p_plant)
    zdot = ca.vertcat(p["x_plant_dot"], c["x_ctrl_dot"])
    ins = {"z": z, "d1": S.d1, "yd": S.yd, "fault": S.fault,
           "p_plant": S.p_plant, "p_ctrl": S.p_ctrl}
    # z is a concatenation of symbols: rebuild it as one symbol for a clean signature
    zsym = _vec("z", z.numel())
    subs_from = [S.x_plant, S.x_ctrl]
    subs_to = [zsym[: S.x_plant.numel()], zsym[S.x_plant.numel():]]
    outs = {"z_dot": zdot, "y": S.x_plant[0], "ydot": p["x_plant_dot"][0], "u0": c["u0"],
            "v": c["v"]}
    outs = {k: ca.substitute([o], subs_from, subs_to)[0] for k, o in outs.items()}
    ins["z"] = zsym
    return _function("closed_loop_paper", ins, outs)


def build_lyapunov(S: Symbols) -> list[ca.Function]:
    d = bs.derive()
    terms = lyapunov.derive()
    tr_c, fz = _controller_translator(S, d)
    extra = {}
    for i in range(lay.N_CHAIN):
        th, st = S.thetas[i], S.thetas_star[i]
        extra[f"Lstar_{i + 1}"] = ca.dot(st, fz.phi(i + 1))
        extra[f"tt_{i + 1}"] = ca.sumsqr(st - th)
        extra[f"ts_{i + 1}"] = ca.dot(st - th, th)
        extra[f"star_norm2_{i + 1}"] = ca.sumsqr(st)
    Pm = ca.SX.sym("P", lay.N_CHAIN, lay.N_CHAIN)
    extra.update({f"P_{i}_{j}": Pm[i, j] for i in range(4) for j in range(4)})
    tr = Translator({**tr_c.symbols, **extra})
    tr.symbols["y"] = S.x_plant[0]  # y = x1, eq (9)
    V = ca.vertcat(*[tr(e) for e in terms.V])
    Vdot = ca.vertcat(*[tr(e) for e in terms.Vdot])
    lyap = _function(
        "lyapunov",
        {"x_plant": S.x_plant, "x_ctrl": S.x_ctrl, "d1": S.d1, "yd": S.yd, "fault": S.fault,
         "theta_star": S.theta_star, "P": Pm, "p_plant": S.p_plant, "p_ctrl": S.p_ctrl},
        {"V": V, "Vdot": Vdot})
    bound = _function(
        "lyapunov_bound", {"p_ctrl": S.p_ctrl, "theta_star": S.theta_star},
        {"kappa_terms": ca.vertcat(*[tr(e) for e in terms.kappa_terms]),
         "zeta_theta": tr(terms.zeta_theta)})

    # AᵀP + PA = -Q, solved in the upper triangle of P; Routh-Hurwitz of A (eq (20))
    K = _vec("K_obs", lay.N_CHAIN)
    Q = ca.SX.sym("Q", lay.N_CHAIN, lay.N_CHAIN)
    trk = Translator({**{f"K_obs_{k + 1}": K[k] for k in range(4)},
                      **{f"Q_{i}_{j}": Q[i, j] for i in range(4) for j in range(4)}})
    M, rhs, unknowns = lyapunov.lyapunov_equation()
    Msx = ca.SX(M.shape[0], M.shape[1])
    for i in range(M.shape[0]):
        for j in range(M.shape[1]):
            if M[i, j] != 0:
                Msx[i, j] = trk(M[i, j])
    bsx = ca.vertcat(*[trk(e) for e in rhs])
    p = ca.solve(Msx, bsx)
    for _ in range(2):  # iterative refinement: CasADi's symbolic QR alone gives ~1e-12
        p = p + ca.solve(Msx, bsx - ca.mtimes(Msx, p))
    Psx = ca.SX(4, 4)
    for u, val in zip(unknowns, ca.vertsplit(p), strict=True):
        _, i, j = u.name.split("_")
        Psx[int(i), int(j)] = val
        Psx[int(j), int(i)] = val
    routh = ca.vertcat(*[trk(e) for e in observer.routh_hurwitz()])
    A = observer.A_obs()
    Asx = ca.SX(4, 4)
    for i in range(4):
        for j in range(4):
            if A[i, j] != 0:
                Asx[i, j] = trk(A[i, j])
    lyap_P = _function("observer_lyapunov", {"K_obs": K, "Q": Q},
                       {"P": Psx, "routh": routh, "A_obs": Asx})
    return [lyap, bound, lyap_P]


def build_turbine() -> list[ca.Function]:
    """The simulator plants of derivation/turbine.py, with cp as an input."""
    x_p = _vec("x_plant", len(lay.PLANT_STATES))
    x_n = _vec("x_plant", len(lay.NREL_STATES))
    p_t = _vec("p_turbine", len(lay.TURBINE_PARAMS))
    af = _vec("actuator_faults", len(lay.ACTUATOR_FAULTS))
    v = _vec("v", lay.N_BLADES)
    wind, cp = ca.SX.sym("wind"), ca.SX.sym("cp")
    common = {**_named(p_t, lay.TURBINE_PARAMS), **_named(af, lay.ACTUATOR_FAULTS),
              "wind": wind, "cp": cp,
              **{f"v_{j + 1}": v[j] for j in range(lay.N_BLADES)}}
    out = []
    for name, x, entries, rhs, loaded in (
            ("turbine_paper", x_p, lay.PLANT_STATES, turbine.paper_rhs, False),
            ("turbine_nrel5mw", x_n, lay.NREL_STATES, turbine.nrel5mw_rhs, True)):
        tr = Translator({**common, **_named(x, entries)})
        t_gen = tr(turbine.generator_torque()) if loaded else ca.SX(0.0)
        outs = {
            "x_plant_dot": ca.vertcat(*[tr(e) for e in rhs()]),
            "T_aero": tr(turbine.aero_torque()),
            "T_gen": t_gen,
            "P_gen": t_gen * x[2],
        }
        out.append(_function(name, {"x_plant": x, "v": v, "wind": wind, "cp": cp,
                                    "actuator_faults": af, "p_turbine": p_t}, outs))
    out += _build_tower(common, p_t, v, wind, cp, af)
    out += _build_tower_edge(common, p_t, v, wind, cp, af)
    # the pitch actuators alone (the actuator rows of the plants above): OpenFAST's
    # plant-side actuator library integrates them (wtftc.openfast.plant_library)
    n_b = lay.N_BLADES
    xa = _vec("x_actuator", 2 * n_b)
    tr = Translator({**common, **_named(xa, lay.NREL_STATES[3:3 + 2 * n_b])})
    out.append(_function("pitch_actuator",
                         {"x_actuator": xa, "v": v, "actuator_faults": af, "p_turbine": p_t},
                         {"x_actuator_dot": ca.vertcat(*[tr(e) for e in
                                                         turbine.pitch_actuator_rhs()])}))
    # the generator torque law alone, on the generator speed (LSS) a controller measures:
    # the torque demand of an exported controller library (wtftc export discon)
    w_g = ca.SX.sym("omega_g")
    tr = Translator({**common, "omega_g": w_g})
    out.append(_function("generator_torque", {"omega_g": w_g, "p_turbine": p_t},
                         {"T_gen": tr(turbine.generator_torque())}))
    # (λ, β̄) at which the runtime evaluates Cp; the same for both plants (first 6 states)
    tr = Translator({**common, **_named(x_p, lay.PLANT_STATES)})
    out.append(_function("aero_operating_point",
                         {"x_plant": x_p, "wind": wind, "p_turbine": p_t},
                         {"tsr": tr(turbine.tip_speed_ratio()),
                          "beta_mean": tr(turbine.mean_pitch())}))
    # T_aero and ∂T_aero/∂β = (∂T_aero/∂Cp)(∂Cp/∂β); ∂Cp/∂β from the runtime's interpolant
    dcp = ca.SX.sym("dcp_dbeta")
    tr = Translator({**common, **_named(x_p, lay.PLANT_STATES), "dcp_dbeta": dcp})
    dT = sp.diff(turbine.aero_torque(), turbine.cp) * sp.Symbol("dcp_dbeta")
    out.append(_function("aero_torque_sensitivity",
                         {"x_plant": x_p, "wind": wind, "cp": cp, "dcp_dbeta": dcp,
                          "p_turbine": p_t},
                         {"T_aero": tr(turbine.aero_torque()), "dT_dbeta": tr(dT)}))
    return out


def _build_tower(common: dict, p_t, v, wind, cp, af) -> list[ca.Function]:
    """The tower plant (derivation/turbine.py ``tower_rhs``), Ct an input as Cp is, and
    the relative wind v_rel at which the runtime evaluates both tables."""
    x_t = _vec("x_plant", len(lay.TOWER_STATES))
    ct = ca.SX.sym("ct")
    tr = Translator({**common, **_named(x_t, lay.TOWER_STATES), "ct": ct})
    w_rel = turbine.relative_wind()
    t_gen = tr(turbine.generator_torque())
    plant = _function("turbine_tower", {"x_plant": x_t, "v": v, "wind": wind, "cp": cp,
                                        "ct": ct, "actuator_faults": af, "p_turbine": p_t}, {
        "x_plant_dot": ca.vertcat(*[tr(e) for e in turbine.tower_rhs()]),
        "T_aero": tr(turbine.aero_torque(w_rel)), "T_gen": t_gen, "P_gen": t_gen * x_t[2],
        "thrust": tr(turbine.thrust(w_rel)), "M_tower": tr(turbine.tower_base_moment())})
    inflow = _function("rotor_inflow", {"x_plant": x_t, "wind": wind},
                       {"wind_rel": tr(w_rel)})
    return [plant, inflow]


def _build_tower_edge(common: dict, p_t, v, wind, cp, af) -> list[ca.Function]:
    """The tower_edge plant (derivation/turbine.py ``tower_edge_rhs``), and the relative
    wind and the blades' aerodynamic speed ω_a at which the runtime evaluates the tables."""
    x_e = _vec("x_plant", len(lay.TOWER_EDGE_STATES))
    ct = ca.SX.sym("ct")
    tr = Translator({**common, **_named(x_e, lay.TOWER_EDGE_STATES), "ct": ct})
    w_rel, w_a = turbine.relative_wind(), turbine.aero_speed()
    t_gen = tr(turbine.generator_torque())
    plant = _function("turbine_tower_edge", {"x_plant": x_e, "v": v, "wind": wind, "cp": cp,
                                             "ct": ct, "actuator_faults": af,
                                             "p_turbine": p_t}, {
        "x_plant_dot": ca.vertcat(*[tr(e) for e in turbine.tower_edge_rhs()]),
        "T_aero": tr(turbine.edge_aero_torque()), "T_gen": t_gen, "P_gen": t_gen * x_e[2],
        "thrust": tr(turbine.thrust(w_rel)), "M_tower": tr(turbine.tower_base_moment())})
    inflow = _function("edge_inflow", {"x_plant": x_e, "wind": wind, "p_turbine": p_t},
                       {"wind_rel": tr(w_rel), "omega_aero": tr(w_a)})
    return [plant, inflow]


FDI_STATES = fdi.states(lay.N_BLADES)
#: the start-up alignment's weight in the FDI's state vector (derivation/fdi.py)
ALIGN = [e.name for e in FDI_STATES].index("fdi_align")
SENSOR_FAULTS, SENSOR_PARAMS = sensors.fault_entries(), sensors.param_entries()


def build_sensors() -> list[ca.Function]:
    """The measurement chain of derivation/sensors.py (lag, fault, bias, noise, resolution)
    of every sensor, and the virtual sensors that vote the controllers' measurements."""
    n = len(sensors.SENSOR_NAMES)
    ins = {"true_signals": _vec("true_signals", n), "x_lag": _vec("x_lag", n),
           "noise": _vec("noise", n), "sensor_faults": _vec("sensor_faults", len(SENSOR_FAULTS)),
           "p_sensors": _vec("p_sensors", len(SENSOR_PARAMS))}
    names = {**{s.name: ins["true_signals"][k] for k, s in enumerate(sensors.true)},
             **{s.name: ins["x_lag"][k] for k, s in enumerate(sensors.lagged)},
             **{s.name: ins["noise"][k] for k, s in enumerate(sensors.noise)},
             **_named(ins["sensor_faults"], SENSOR_FAULTS),
             **_named(ins["p_sensors"], SENSOR_PARAMS)}
    tr = Translator(names)
    chain = _function("sensors", ins, {"meas": ca.vertcat(*[tr(e) for e in sensors.measured()]),
                                       "x_lag_dot": ca.vertcat(*[tr(e) for e in
                                                                 sensors.lag_rhs()])})
    rd, ex, gear = _vec("readings", n), _vec("excluded", n), ca.SX.sym("gearbox_ratio")
    tr = Translator({**{s.name: rd[k] for k, s in enumerate(sensors.readings)},
                     **{s.name: ex[k] for k, s in enumerate(sensors.excluded)},
                     **_named(ins["p_sensors"], SENSOR_PARAMS), "gearbox_ratio": gear})
    virtual = _function("virtual_sensors",
                        {"readings": rd, "excluded": ex, "p_sensors": ins["p_sensors"],
                         "gearbox_ratio": gear},
                        {"meas": _virtual_meas(tr)})
    return [chain, virtual]


def _fdi_blades(x, v, rd, bv, params) -> dict[str, list]:
    """Per blade: the FDI's state derivatives and outputs (derivation/fdi.py)."""
    n, names = len(fdi.PER_BLADE), sensors.SENSOR_NAMES
    out: dict[str, list] = {k: [] for k in ("rhs", "rho", "lock", "ubar", "rho_hat", "c_hat",
                                            "latch", "rms", "w_hat", "z_hat", "thr", "init")}
    for j in range(lay.N_BLADES):
        xs = x[j * n:(j + 1) * n]
        tr = Translator({**params, "v": v[j], "beta_v": bv[j], "align": x[ALIGN],
                         "beta_m": rd[names.index(f"beta_meas_{j + 1}_m1")],
                         "beta_m2": rd[names.index(f"beta_meas_{j + 1}_m2")],
                         **{s.name: xs[k] for k, s in enumerate(fdi.STATE_SYMBOLS)}})
        out["rhs"] += [tr(e) for e in fdi.blade_rhs()]
        for key, expr in zip(("rho", "lock", "ubar"), fdi.accommodation(), strict=True):
            out[key].append(tr(expr))
        _, r0 = fdi.estimates()
        out["rho_hat"].append(tr(sp.Piecewise((0, fdi.is_locked()), (r0, True))))
        out["c_hat"].append(tr(fdi.stuck_angle()))
        out["latch"].append(xs[3])
        # the residual RMS of the pitch sensor in use (m2's once m1 is excluded)
        i_e2, i_l1 = (fdi.PER_BLADE.index(k) for k in ("mean_sq_m2", "sensor_latch_m1"))
        out["rms"].append(ca.sqrt(ca.fmax(ca.if_else(xs[i_l1] >= 0.5, xs[i_e2], xs[2]), 0)))
        out["thr"].append(ca.sqrt(tr(fdi.threshold_sq())))
        wh, zh = fdi.dynamics_estimate()
        out["w_hat"].append(tr(wh))
        out["z_hat"].append(tr(zh))
    return out


def _healthy(rd, latches: dict, name: str) -> ca.SX:
    """The mean of a quantity's two sensors, or the one not excluded (latch ≥ 1/2)."""
    i1, i2 = (sensors.SENSOR_NAMES.index(f"{name}_m{k}") for k in (1, 2))
    return ca.if_else(latches[f"{name}_m1"] >= 0.5, rd[i2],
                      ca.if_else(latches[f"{name}_m2"] >= 0.5, rd[i1], (rd[i1] + rd[i2]) / 2))


def _fdi_speeds(xs, rd, params) -> tuple[list, dict]:
    """The speed sensors' pair tests: state derivatives, and each sensor's latch."""
    n = len(fdi.PER_PAIR)
    latches = {}
    for k, (sig, *_) in enumerate(fdi.SPEED_PAIRS):
        block = xs[k * n:(k + 1) * n]
        latches[f"{sig}_m1"], latches[f"{sig}_m2"] = block[5], block[6]
    gear = params["fdi_gearbox_ratio"]
    refs = {"omega_r": _healthy(rd, latches, "omega_g_hss") / gear,
            "omega_g_hss": _healthy(rd, latches, "omega_r") * gear}
    h = {"omega_r": fdi.h_rotor, "omega_g_hss": fdi.h_gen}
    floor = {"omega_r": fdi.speed_floor, "omega_g_hss": fdi.speed_floor * fdi.gear}
    rhs = []
    for k, (sig, *_) in enumerate(fdi.SPEED_PAIRS):
        tr = Translator({**params, "speed_ref": refs[sig],
                         "speed_m1": rd[sensors.SENSOR_NAMES.index(f"{sig}_m1")],
                         "speed_m2": rd[sensors.SENSOR_NAMES.index(f"{sig}_m2")],
                         **{s.name: xs[k * n + i] for i, s in enumerate(fdi.PAIR_SYMBOLS)}})
        rhs += [tr(e) for e in fdi.speed_pair_rhs(h[sig], floor[sig])]
    return rhs, latches


def _virtual_meas(tr: Translator) -> ca.SX:
    """The virtual sensors' outputs, their intermediate voted speeds translated first."""
    voted, outputs = sensors.virtual_sensors()
    names = {sym.name: tr(expr) for sym, expr in voted.items()}
    tr2 = Translator({**tr.symbols, **names})
    return ca.vertcat(*[tr2(e) for e in outputs])


def build_fdi() -> list[ca.Function]:
    """Per-blade residual, detection latch and least-squares estimates, the pitch sensors'
    pair tests, and the speed sensors' (derivation/fdi.py)."""
    n_blade = len(fdi.PER_BLADE) * lay.N_BLADES
    x = _vec("x_fdi", len(FDI_STATES))
    v = _vec("v", lay.N_BLADES)
    rd = _vec("readings", len(sensors.SENSOR_NAMES))
    meas = _vec("meas", len(sensors.NAMES))
    p = _vec("p_fdi", len(fdi.PARAMS))
    params = _named(p, fdi.PARAMS)
    b = _fdi_blades(x, v, rd, meas[2:], params)
    speed_rhs, latches = _fdi_speeds(x[n_blade:], rd, params)
    per = len(fdi.PER_BLADE)
    for j in range(lay.N_BLADES):
        for k in (1, 2):
            latches[f"beta_meas_{j + 1}_m{k}"] = x[j * per + fdi.PER_BLADE.index(
                f"sensor_latch_m{k}")]
    f = _function("fdi", {"x_fdi": x, "v": v, "readings": rd, "meas": meas, "p_fdi": p},
                  {"x_fdi_dot": ca.vertcat(*b["rhs"], *speed_rhs,
                                           Translator({**params, "align": x[ALIGN]})(
                                               fdi.align_rhs())),
                   "known_fault": ca.vertcat(*b["rho"], *b["lock"], *b["ubar"]),
                   "rho_hat": ca.vertcat(*b["rho_hat"]), "c_hat": ca.vertcat(*b["c_hat"]),
                   "latch": ca.vertcat(*b["latch"]), "residual_rms": ca.vertcat(*b["rms"]),
                   "omega_n_hat": ca.vertcat(*b["w_hat"]), "zeta_hat": ca.vertcat(*b["z_hat"]),
                   "threshold": ca.vertcat(*b["thr"]),
                   "excluded": ca.vertcat(*[latches[s] for s in sensors.SENSOR_NAMES])})
    bm = _vec("beta_meas", lay.N_BLADES)
    init = [Translator({"b": bm[j]})(e) for j in range(lay.N_BLADES)
            for e in fdi.initial(sp.Symbol("b"))]
    init += [ca.SX(e.default) for e in FDI_STATES[n_blade:]]  # the pair tests' 0, align's 1
    g = _function("init_fdi", {"beta_meas": bm}, {"x_fdi0": ca.vertcat(*init)})
    return [f, g]


def groups() -> list[Group]:
    S = Symbols()
    plant_fns = build_plant(S)
    ctrl_fns = build_controller(S)
    closed = build_closed_loop(S, plant_fns[0], ctrl_fns[0])
    return [
        Group("plant", ["derivation/plant.py"], plant_fns),
        Group("controller", ["derivation/backstepping.py", "derivation/observer.py",
                             "derivation/fuzzy.py"], ctrl_fns),
        Group("turbine", ["derivation/turbine.py", "derivation/plant.py",
                          "derivation/sensors.py"], build_turbine() + build_sensors()),
        Group("controllers", controllers.sources(), controllers.build()),
        Group("fdi", ["derivation/fdi.py", "derivation/turbine.py", "derivation/sensors.py"],
              build_fdi()),
        Group("closed_loop", ["derivation/plant.py", "derivation/backstepping.py",
                              "derivation/observer.py", "derivation/fuzzy.py"], [closed]),
        Group("lyapunov", ["derivation/lyapunov.py", "derivation/backstepping.py",
                           "derivation/observer.py", "derivation/fuzzy.py"],
              build_lyapunov(S)),
    ]


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def source_files() -> list[Path]:
    """Every derivation source that can change the artefacts: the modules and the NREL
    5-MW's turbine file, whose values are the layout's turbine defaults."""
    return [*sorted(DERIVATION_DIR.glob("*.py")), nrel5mw.TURBINE_FILE]


def _signature(f: ca.Function) -> dict:
    def io(names, sparsities):
        return [{"name": n, "shape": [s.size1(), s.size2()]}
                for n, s in zip(names, sparsities, strict=True)]
    return {
        "inputs": io(f.name_in(), [f.sparsity_in(k) for k in range(f.n_in())]),
        "outputs": io(f.name_out(), [f.sparsity_out(k) for k in range(f.n_out())]),
    }


def _count_ops(f: ca.Function) -> dict:
    """Instructions of the SX algorithm, split into arithmetic operations and the rest."""
    n_ops = 0
    for k in range(f.n_instructions()):
        op = f.instruction_id(k)
        if op not in (ca.OP_CONST, ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_PARAMETER):
            n_ops += 1
    return {"instructions": f.n_instructions(), "operations": n_ops}


def write(outdir: Path) -> dict:
    """Regenerate every artefact into outdir (created or emptied of old artefacts)."""
    outdir.mkdir(parents=True, exist_ok=True)
    for old in outdir.iterdir():
        if old.suffix in {".c", ".casadi", ".json"}:
            old.unlink()
    functions: dict[str, dict] = {}
    artefacts: list[Path] = []
    gs = groups()
    for g in gs:
        header = HEADER.format(modules=", ".join(g.modules))
        cname = f"{g.name}.c"
        cg = ca.CodeGenerator(cname, {"with_header": False, "verbose": False})
        for f in g.functions:
            cg.add(f)
        with tempfile.TemporaryDirectory() as tmp:
            cg.generate(tmp + os.sep)
            code = Path(tmp, cname).read_text()
        (outdir / cname).write_text(f"/* {header} */\n{code}")
        artefacts.append(outdir / cname)
        for f in g.functions:
            path = outdir / f"{f.name()}.casadi"
            path.write_text(f"# {header}\n{f.serialize()}\n")
            artefacts.append(path)
            functions[f.name()] = {"group": g.name, "c_file": cname,
                                   "serialized": path.name, **_signature(f), **_count_ops(f)}
    reg = controllers.as_json()
    groups_extra = {**reg.pop("groups"), "fdi_states": FDI_STATES, "fdi_params": fdi.PARAMS,
                    "sensor_faults": SENSOR_FAULTS, "sensor_params": SENSOR_PARAMS}
    reg["sensors"] = [{"name": n, "measures": m, "unit": u}
                      for n, m, u, _, _ in sensors.SENSORS]
    extra_groups = {g: [e.as_json() for e in entries] for g, entries in groups_extra.items()}
    layout = {"_header": HEADER.format(modules="derivation/layout.py"), **lay.as_json(),
              **extra_groups, **reg,
              "functions": functions, "kappa_labels": lyapunov.derive().kappa_labels}
    (outdir / "layout.json").write_text(json.dumps(layout, indent=1, sort_keys=True,
                                                   ensure_ascii=False) + "\n")
    artefacts.append(outdir / "layout.json")
    manifest = {
        "_header": HEADER.format(modules="derivation/generate.py"),
        "versions": {"sympy": sp.__version__, "casadi": ca.__version__},
        "sources": {str(p.relative_to(ROOT)): _sha256(p) for p in source_files()},
        "artefacts": {p.name: _sha256(p) for p in sorted(artefacts)},
        "groups": {g.name: {"c_file": f"{g.name}.c",
                            "functions": [f.name() for f in g.functions]} for g in gs},
    }
    (outdir / "manifest.json").write_text(json.dumps(manifest, indent=1, sort_keys=True) + "\n")
    return manifest


def _not_replaceable(outdir: Path) -> str | None:
    """Why ``outdir`` may not be replaced by a new generation, or None: it must be missing,
    empty, or hold only an earlier generation (its manifest.json and the artefacts that
    manifest lists); a folder holding anything else is never touched."""
    if outdir.is_symlink():
        return "a symbolic link (give the folder itself)"
    if not outdir.exists():
        return None
    if not outdir.is_dir():
        return "not a folder"
    names = {p.name for p in outdir.iterdir()}
    if not names:
        return None
    try:
        listed = set(json.loads((outdir / "manifest.json").read_text())["artefacts"])
    except (OSError, ValueError, KeyError, TypeError):
        return "holds files but no readable manifest.json of an earlier generation"
    extra = sorted(names - listed - {"manifest.json"})
    if extra:
        return f"holds files the generation did not write ({', '.join(extra[:3])})"
    return None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if os.environ.get("PYTHONHASHSEED") != "0":
        # set iteration order must not leak into the artefacts: re-run with a fixed seed
        env = {**os.environ, "PYTHONHASHSEED": "0"}
        os.execve(sys.executable, [sys.executable, "-m", "derivation.generate", *argv], env)
    outdir = Path(argv[0]) if argv else ROOT / "generated"
    t0 = time.perf_counter()
    refusal = _not_replaceable(outdir)
    if refusal:
        print(f"derivation.generate: {outdir}: {refusal}; nothing was written",
              file=sys.stderr)
        return 2
    outdir.parent.mkdir(parents=True, exist_ok=True)
    # built whole in a sibling, then swapped in (issue 30): a run reading generated/
    # meanwhile sees the old artefacts or the new ones, never a folder half rewritten
    tmp = Path(tempfile.mkdtemp(prefix=f".{outdir.name}.", suffix=".partial",
                                dir=outdir.parent))
    try:
        manifest = write(tmp)
        os.chmod(tmp, (outdir.stat().st_mode & 0o7777) if outdir.is_dir() else 0o755)
        swap_folder(tmp, outdir)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"regenerated {len(manifest['artefacts'])} artefacts in {outdir} "
          f"({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
