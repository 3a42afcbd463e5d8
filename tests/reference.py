"""SymPy references for the generated functions, evaluated with lambdify (NumPy).

The fuzzy quantities are rebuilt here from the *unfactored* normalized firing strengths
(:func:`derivation.fuzzy.reference_regressor`) and differentiated by SymPy, so the
generator's factorized evaluation and its derivative orders are checked, not assumed.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp
from sympy.logic.boolalg import ITE

from derivation import backstepping as bs
from derivation import (
    controllers,
    fdi,
    fuzzy,
    lyapunov,
    observer,
    plant,
    sensors,
    turbine,
)
from derivation import layout as dlay
from derivation.controllers import MEAS

X_OFFSET = sp.symbols("x_offset_1:5", real=True)
X_SCALE = sp.symbols("x_scale_1:5", positive=True)
FUZZY_PARAMS = [fuzzy.mf_width, *fuzzy.mf_centre]
#: the FDI's start-up alignment weight's index in its states (derivation/fdi.py)
ALIGN = [e.name for e in fdi.states(3)].index("fdi_align")


@cache
def dphi_function(i: int, alpha: tuple[int, ...], module: str = "numpy"):
    """Lambdified ∂^α φ_i(x̂1..x̂i) of the unfactored regressor, as a vector."""
    xs = observer.xhat[:i]
    der = fuzzy.reference_regressor_derivative(xs, X_OFFSET[:i], X_SCALE[:i], alpha)
    args = [*xs, *X_OFFSET[:i], *X_SCALE[:i], *FUZZY_PARAMS]
    return sp.lambdify(args, der, modules=module, cse=True), [a.name for a in args]


def dphi(i: int, alpha, values: dict[str, float]) -> np.ndarray:
    f, names = dphi_function(i, tuple(alpha))
    return np.asarray(f(*[values[n] for n in names]), dtype=float)


def theta_hat(values: dict[str, float], i: int) -> np.ndarray:
    return np.array([values[f"theta_hat_{i}[{m}]"] for m in range(dlay.rule_count(i))])


def fuzzy_symbol_values(values: dict[str, float]) -> dict[str, float]:
    """Numbers for every L/B symbol the derivation created, from the unfactored φ."""
    out = {}
    for rb in bs.derive().rule_bases:
        for sym, kind in rb.symbols().items():
            if kind[0] == "L":
                out[sym.name] = float(theta_hat(values, rb.i) @ dphi(rb.i, kind[1], values))
            else:
                out[sym.name] = float(dphi(rb.i, kind[1], values) @ dphi(rb.i, kind[2], values))
    return out


def magnitude(expr: sp.Expr, memo: dict | None = None) -> sp.Expr:
    """The expression with every sum taken over absolute values (outside exp and divisors).

    Floating-point evaluation of e is accurate to about ε·magnitude(e), not ε·|e|: where
    large terms cancel (α̇3 at random states), |e| says nothing about attainable accuracy.
    Each |·| is left unevaluated: SymPy's sign simplification of it costs seconds on the
    larger designs and changes no value.
    """
    memo = {} if memo is None else memo
    if expr in memo:
        return memo[expr]
    if expr.is_Add:
        out = sp.Add(*[sp.Abs(magnitude(a, memo), evaluate=False) for a in expr.args])
    elif expr.is_Mul:
        out = sp.Mul(*[magnitude(a, memo) for a in expr.args])
    elif expr.is_Pow and expr.exp.is_Integer and expr.exp > 0:
        out = magnitude(expr.base, memo) ** expr.exp
    elif isinstance(expr, sp.Piecewise):  # the accuracy of the branch taken
        out = sp.Piecewise(*[(magnitude(e, memo), c) for e, c in expr.args])
    else:
        out = expr
    memo[expr] = out
    return out


def _without_ite(e):
    """ITE(c, a, b) (SymPy's fold of a relation on a Piecewise) as (c ∧ a) ∨ (¬c ∧ b):
    NumPy's lambdify prints ITE as a select of booleans whose float result another select
    refuses as a condition."""
    return sp.sympify(e).replace(
        lambda x: isinstance(x, ITE),
        lambda x: sp.Or(sp.And(x.args[0], x.args[1]), sp.And(sp.Not(x.args[0]), x.args[2])))


@cache
def lambdified(key: str, exprs: tuple):
    exprs = tuple(_without_ite(e) for e in exprs)
    syms = sorted(set().union(*[e.free_symbols for e in exprs]), key=lambda s: s.name)
    return sp.lambdify(syms, list(exprs), modules="numpy", cse=True), [s.name for s in syms]


def evaluate(key: str, exprs, values: dict[str, float]) -> np.ndarray:
    f, names = lambdified(key, tuple(exprs))
    return np.asarray(f(*[values[n] for n in names]), dtype=float).reshape(-1)


@cache
def _magnitudes(exprs: tuple) -> tuple:
    return tuple(sp.Abs(magnitude(sp.sympify(e)), evaluate=False) for e in exprs)


def scale(key: str, exprs, values: dict[str, float]) -> np.ndarray:
    """|magnitude(e)| of each expression at values: the scale of attainable accuracy."""
    return evaluate(key + "|mag|", _magnitudes(tuple(exprs)), values)


def named_values(args: dict[str, np.ndarray]) -> dict[str, float]:
    """Map a generated function's arguments to SymPy symbol names via the layout."""
    groups = {"x_plant": dlay.PLANT_STATES, "x_ctrl": dlay.CONTROLLER_STATES,
              "p_plant": dlay.PLANT_PARAMS, "p_ctrl": dlay.CONTROLLER_PARAMS,
              "fault": dlay.FAULT_INPUTS, "yd": dlay.REFERENCE}
    out: dict[str, float] = {}
    for key, val in args.items():
        flat = np.asarray(val, dtype=float).reshape(-1, order="F")
        if key in groups:
            out.update({e.name: float(x) for e, x in zip(groups[key], flat, strict=True)})
        elif key == "z":
            entries = dlay.PLANT_STATES + dlay.CONTROLLER_STATES
            out.update({e.name: float(x) for e, x in zip(entries, flat, strict=True)})
        elif key == "v":
            out.update({f"v_{j + 1}": float(x) for j, x in enumerate(flat)})
        elif key == "xhat":
            out.update({f"xhat_{k + 1}": float(x) for k, x in enumerate(flat)})
        elif flat.size == 1:
            out[key] = float(flat[0])
    return out


def pair(key: str, exprs, values: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """(value, scale) of SymPy expressions at values."""
    return evaluate(key, exprs, values), scale(key, exprs, values)


def exact(value) -> tuple[np.ndarray, np.ndarray]:
    """(value, |value|) for outputs computed directly in NumPy."""
    v = np.asarray(value, dtype=float).reshape(-1)
    return v, np.abs(v)


def controller_reference(values: dict[str, float]) -> dict[str, tuple]:
    """controller / alpha_derivatives outputs from the SymPy design."""
    d = bs.derive()
    vals = {**values, **fuzzy_symbol_values(values)}
    out = {
        "u0": pair("u0", [d.u0], vals),
        "v": pair("v", bs.applied_commands(d.u0), vals),
        "chi": pair("chi", d.chi, vals),
        "alpha": pair("alpha", d.alpha, vals),
        "alpha_dot": pair("alpha_dot_comp", d.alpha_dot_comp, vals),
        "alpha_dot_comp": pair("alpha_dot_comp", d.alpha_dot_comp, vals),
        "ydot_hat": pair("ydot_hat", [d.ydot_hat], vals),
        "dalpha_dy": pair("dalpha_dy", d.dalpha_dy, vals),
    }
    if "ydot" in vals:
        out["alpha_dot_full"] = pair("alpha_dot_full", d.alpha_dot_full, vals)
    xhat_dot = pair("xhat_dot", d.xhat_dot, vals)
    theta_dot, theta_scale = [], []
    for i, (g_chi, r_i) in enumerate(bs.adaptive_law_coefficients(d)):
        gc, gc_scale = pair(f"gchi{i}", [g_chi], vals)
        th = theta_hat(vals, i + 1)
        phi = dphi(i + 1, (0,) * (i + 1), vals)
        theta_dot.append(gc[0] * phi - vals[r_i.name] * th)
        theta_scale.append(gc_scale[0] * np.abs(phi) + np.abs(vals[r_i.name] * th))
    out["x_ctrl_dot"] = (np.concatenate([xhat_dot[0], *theta_dot]),
                         np.concatenate([xhat_dot[1], *theta_scale]))
    return out


def plant_reference(values: dict[str, float], targets: bool = False) -> dict[str, tuple]:
    X = plant.chain_state()
    out = {"y": exact([values["omega_r"]]), "X": pair("X", X, values)}
    if targets:
        f = plant.strict_feedback_f(X)
        out["f_plus_d"] = pair("fpd", [f[0] + plant.d1, *f[1:]], values)
    else:
        out["x_plant_dot"] = pair("plant", plant.paper_rhs(), values)
    return out


def closed_loop_reference(values: dict[str, float]) -> dict[str, tuple]:
    vals = {**values, "y": values["omega_r"]}
    c = controller_reference(vals)
    vals.update({f"v_{j + 1}": float(x) for j, x in enumerate(c["v"][0])})
    p = plant_reference(vals)
    xp = p["x_plant_dot"][0]
    # the commands carry their own rounding (relative to their scale) into the plant
    v_mag = {f"v_{j + 1}": float(x) for j, x in enumerate(c["v"][1])}
    xs = scale("plant", plant.paper_rhs(), {**vals, **v_mag})
    return {"z_dot": (np.concatenate([xp, c["x_ctrl_dot"][0]]),
                      np.concatenate([xs, c["x_ctrl_dot"][1]])),
            "y": p["y"], "ydot": (xp[:1], xs[:1]), "u0": c["u0"], "v": c["v"]}


def lyapunov_reference(args: dict[str, np.ndarray]) -> dict[str, tuple]:
    values = named_values(args)
    values["y"] = values["omega_r"]
    vals = {**values, **fuzzy_symbol_values(values)}
    P = np.asarray(args["P"], dtype=float)
    vals.update({f"P_{i}_{j}": P[i, j] for i in range(4) for j in range(4)})
    ts_all = np.asarray(args["theta_star"], dtype=float).reshape(-1)
    k = 0
    for i in range(1, 5):
        n = dlay.rule_count(i)
        st, th = ts_all[k:k + n], theta_hat(vals, i)
        k += n
        vals[f"Lstar_{i}"] = float(st @ dphi(i, (0,) * i, vals))
        vals[f"tt_{i}"] = float((st - th) @ (st - th))
        vals[f"ts_{i}"] = float((st - th) @ th)
    terms = lyapunov.derive()
    return {"V": pair("V", terms.V, vals), "Vdot": pair("Vdot", terms.Vdot, vals)}


def bound_reference(args: dict[str, np.ndarray]) -> dict[str, tuple]:
    vals = named_values(args)
    ts_all = np.asarray(args["theta_star"], dtype=float).reshape(-1)
    k = 0
    for i in range(1, 5):
        n = dlay.rule_count(i)
        vals[f"star_norm2_{i}"] = float(ts_all[k:k + n] @ ts_all[k:k + n])
        k += n
    terms = lyapunov.derive()
    return {"kappa_terms": pair("kappa", terms.kappa_terms, vals),
            "zeta_theta": pair("zeta", [terms.zeta_theta], vals)}


def observer_lyapunov_reference(args: dict[str, np.ndarray]) -> dict[str, tuple]:
    """P from the Kronecker form of AᵀP + PA = -Q solved by mpmath at 40 digits."""
    import mpmath

    K = np.asarray(args["K_obs"], dtype=float).reshape(-1)
    vals = {f"K_obs_{k + 1}": K[k] for k in range(4)}
    A = np.array(sp.lambdify(observer.K_obs, observer.A_obs())(*K), dtype=float)
    Q = np.asarray(args["Q"], dtype=float)
    eye = np.eye(4)
    with mpmath.workdps(40):
        M = mpmath.matrix(np.kron(eye, A.T) + np.kron(A.T, eye))
        rhs = mpmath.matrix(-((Q + Q.T) / 2).reshape(-1, order="F"))
        P = np.array([float(x) for x in mpmath.lu_solve(M, rhs)])
    # a linear solve is accurate relative to ‖P‖, not entry by entry
    return {"P": (P, np.full(16, np.abs(P).max())), "A_obs": exact(A.reshape(-1, order="F")),
            "routh": pair("routh", observer.routh_hurwitz(), vals)}


def turbine_reference(name: str, args: dict[str, np.ndarray]) -> dict[str, tuple]:
    states = {"turbine_nrel5mw": dlay.NREL_STATES, "turbine_tower": dlay.TOWER_STATES,
              "rotor_inflow": dlay.TOWER_STATES, "turbine_tower_edge": dlay.TOWER_EDGE_STATES,
              "edge_inflow": dlay.TOWER_EDGE_STATES}.get(name, dlay.PLANT_STATES)
    entries = {"x_plant": states, "p_turbine": dlay.TURBINE_PARAMS,
               "actuator_faults": dlay.ACTUATOR_FAULTS}
    vals: dict[str, float] = {}
    for key, val in args.items():
        flat = np.asarray(val, dtype=float).reshape(-1, order="F")
        if key in entries:
            vals.update({e.name: float(x) for e, x in zip(entries[key], flat, strict=True)})
        elif key == "v":
            vals.update({f"v_{j + 1}": float(x) for j, x in enumerate(flat)})
        else:
            vals[key] = float(flat[0])
    return {k: pair(tag, exprs, vals) for k, (tag, exprs) in _turbine_exprs(name).items()}


@cache
def _turbine_exprs(name: str) -> dict[str, tuple[str, tuple]]:
    """The SymPy references of a generated plant function, built once per name: output
    name → (tag, expressions)."""
    if name == "aero_operating_point":
        return {"tsr": _P("tsr", [turbine.tip_speed_ratio()]),
                "beta_mean": _P("bmean", [turbine.mean_pitch()])}
    if name == "rotor_inflow":
        return {"wind_rel": _P("wrel", [turbine.relative_wind()])}
    if name == "edge_inflow":
        return {"wind_rel": _P("wrel", [turbine.relative_wind()]),
                "omega_aero": _P("waero", [turbine.aero_speed()])}
    if name == "turbine_tower_edge":
        w, t_gen = turbine.relative_wind(), turbine.generator_torque()
        return {"x_plant_dot": _P(name, turbine.tower_edge_rhs()),
                "T_aero": _P("taero_e", [turbine.edge_aero_torque()]),
                "T_gen": _P("tgen_t", [t_gen]),
                "P_gen": _P("pgen_t", [t_gen * turbine.omega_g]),
                "thrust": _P("thrust", [turbine.thrust(w)]),
                "M_tower": _P("mtower", [turbine.tower_base_moment()])}
    if name == "turbine_tower":
        w = turbine.relative_wind()
        t_gen = turbine.generator_torque()
        return {"x_plant_dot": _P(name, turbine.tower_rhs()),
                "T_aero": _P("taero_t", [turbine.aero_torque(w)]),
                "T_gen": _P("tgen_t", [t_gen]),
                "P_gen": _P("pgen_t", [t_gen * turbine.omega_g]),
                "thrust": _P("thrust", [turbine.thrust(w)]),
                "M_tower": _P("mtower", [turbine.tower_base_moment()])}
    loaded = name == "turbine_nrel5mw"
    rhs = turbine.nrel5mw_rhs() if loaded else turbine.paper_rhs()
    t_gen = turbine.generator_torque() if loaded else sp.S.Zero
    return {"x_plant_dot": _P(name, rhs),
            "T_aero": _P("taero", [turbine.aero_torque()]),
            "T_gen": _P(f"tgen{loaded}", [t_gen]),
            "P_gen": _P(f"pgen{loaded}", [t_gen * turbine.omega_g])}


def _P(tag: str, exprs) -> tuple[str, tuple]:  # noqa: N802 (reads as pair's twin)
    return tag, tuple(exprs)


def sensors_reference(args: dict[str, np.ndarray]) -> dict[str, tuple]:
    """The measurement chain of derivation/sensors.py (lag, fault, bias, noise,
    resolution) from SymPy."""
    vals: dict[str, float] = {}
    for key, syms in (("true_signals", sensors.true), ("x_lag", sensors.lagged),
                      ("noise", sensors.noise)):
        vals.update({s.name: float(x) for s, x in zip(syms, _flat(args, key), strict=True)})
    for key, entries in (("sensor_faults", sensors.fault_entries()),
                         ("p_sensors", sensors.param_entries())):
        vals.update({e.name: float(x) for e, x in zip(entries, _flat(args, key), strict=True)})
    return {"meas": pair("meas", sensors.measured(), vals),
            "x_lag_dot": pair("lagdot", sensors.lag_rhs(), vals)}


def _flat(args, key):
    return np.asarray(args[key], dtype=float).reshape(-1, order="F")


def controller_uniform_reference(name: str, args: dict[str, np.ndarray]) -> dict[str, tuple]:
    """ctrl_external / init_external: commands held from outside, v = p_ctrl. (Every other
    registered controller is a ControllerDesign: :func:`design_reference`.)"""
    if not name.endswith("_external"):
        raise KeyError(f"no uniform reference for {name}")
    if name.startswith("init"):
        return {"x_ctrl0": exact([0.0])}
    v = _flat(args, "p_ctrl")
    return {"v": exact(v), "x_ctrl_dot": exact([0.0]), "u0": exact([v.mean()]),
            "diag": exact(np.concatenate([v, [0.0]]))}


def fdi_reference(name: str, args: dict[str, np.ndarray]) -> dict[str, tuple]:
    if name == "init_fdi":
        out = []
        for b in _flat(args, "beta_meas"):
            out.append(evaluate("fdi_init", fdi.initial(sp.Symbol("b")), {"b": float(b)}))
        rest = [e.default for e in fdi.states(3)[len(out) * len(fdi.PER_BLADE):]]
        return {"x_fdi0": exact(np.concatenate([*out, rest]))}
    x, v, p = _flat(args, "x_fdi"), _flat(args, "v"), _flat(args, "p_fdi")
    rd = dict(zip(sensors.SENSOR_NAMES, _flat(args, "readings"), strict=True))
    meas = _flat(args, "meas")
    n = len(fdi.PER_BLADE)
    base = {e.name: float(y) for e, y in zip(fdi.PARAMS, p, strict=True)}
    rhs, known, rho, c, latch, rms, wh, zh, thr = [], [[], [], []], [], [], [], [], [], [], []
    excluded = {}
    ex = _fdi_exprs()
    for j in range(3):
        xs = x[j * n:(j + 1) * n]
        vals = {**base, "v": float(v[j]), "align": float(x[ALIGN]),
                "beta_m": rd[f"beta_meas_{j + 1}_m1"],
                "beta_m2": rd[f"beta_meas_{j + 1}_m2"], "beta_v": float(meas[2 + j]),
                **{sy.name: float(y) for sy, y in zip(fdi.STATE_SYMBOLS, xs, strict=True)}}
        rhs.append(pair("fdi_rhs", ex["rhs"], vals))
        for k, a in enumerate(ex["acc"]):
            known[k].append(pair(f"fdi_acc{k}", [a], vals))
        rho.append(pair("fdi_rho", ex["rho"], vals))
        c.append(pair("fdi_c", ex["c"], vals))
        latch.append(exact([xs[3]]))
        e_used = vals["mean_sq_m2"] if vals["sensor_latch_m1"] >= 0.5 else xs[2]
        rms.append(exact([np.sqrt(max(e_used, 0.0))]))
        wh.append(pair("fdi_wh", ex["wh"], vals))
        zh.append(pair("fdi_zh", ex["zh"], vals))
        thr.append(pair("fdi_thr", ex["thr"], vals))
        for k in (1, 2):
            excluded[f"beta_meas_{j + 1}_m{k}"] = vals[f"sensor_latch_m{k}"]
    rhs += _speed_pairs_reference(x[3 * n:], rd, base, excluded)
    rhs.append(pair("fdi_align", ex["align"], {**base, "align": float(x[ALIGN])}))

    def cat(parts):
        return (np.concatenate([q[0] for q in parts]), np.concatenate([q[1] for q in parts]))

    return {"x_fdi_dot": cat(rhs), "known_fault": cat(known[0] + known[1] + known[2]),
            "rho_hat": cat(rho), "c_hat": cat(c), "latch": cat(latch),
            "residual_rms": cat(rms), "omega_n_hat": cat(wh), "zeta_hat": cat(zh),
            "threshold": cat(thr),
            "excluded": exact([excluded[s] for s in sensors.SENSOR_NAMES])}


@cache
def _fdi_exprs() -> dict[str, tuple]:
    """The FDI's SymPy expressions per blade, built once: each build is 0.1-0.3 s of SymPy,
    and fdi_reference is called at hundreds of points."""
    _, r0 = fdi.estimates()
    w_hat, z_hat = fdi.dynamics_estimate()
    return {"rhs": tuple(fdi.blade_rhs()), "acc": tuple(fdi.accommodation()),
            "rho": (sp.Piecewise((0, fdi.is_locked()), (r0, True)),),
            "c": (fdi.stuck_angle(),), "wh": (w_hat,), "zh": (z_hat,),
            "thr": (sp.sqrt(fdi.threshold_sq()),), "align": (fdi.align_rhs(),)}


@cache
def _speed_pair_exprs(sig: str) -> tuple:
    """One speed sensor pair's test, built once (as _fdi_exprs)."""
    h = {"omega_r": fdi.h_rotor, "omega_g_hss": fdi.h_gen}
    floor = {"omega_r": fdi.speed_floor, "omega_g_hss": fdi.speed_floor * fdi.gear}
    return tuple(fdi.speed_pair_rhs(h[sig], floor[sig]))


def _speed_pairs_reference(xs, rd: dict, base: dict, excluded: dict) -> list[tuple]:
    """The speed sensors' pair tests from SymPy; fills ``excluded`` with their latches."""
    n = len(fdi.PER_PAIR)
    for k, (sig, *_) in enumerate(fdi.SPEED_PAIRS):
        excluded[f"{sig}_m1"], excluded[f"{sig}_m2"] = xs[k * n + 5], xs[k * n + 6]

    def healthy(name):
        a, b = rd[f"{name}_m1"], rd[f"{name}_m2"]
        return b if excluded[f"{name}_m1"] >= 0.5 else (
            a if excluded[f"{name}_m2"] >= 0.5 else (a + b) / 2)

    gear = base["fdi_gearbox_ratio"]
    refs = {"omega_r": healthy("omega_g_hss") / gear, "omega_g_hss": healthy("omega_r") * gear}
    out = []
    for k, (sig, *_) in enumerate(fdi.SPEED_PAIRS):
        vals = {**base, "speed_ref": float(refs[sig]), "speed_m1": rd[f"{sig}_m1"],
                "speed_m2": rd[f"{sig}_m2"],
                **{s.name: float(xs[k * n + i]) for i, s in enumerate(fdi.PAIR_SYMBOLS)}}
        out.append(pair(f"fdi_speed_{sig}", _speed_pair_exprs(sig), vals))
    return out


#: controllers derived as a derivation.design.ControllerDesign, by registered name
DESIGNS = {c.name: c.design for c in controllers.REGISTRY.values() if c.design is not None}


def design_reference(cname: str, name: str, args: dict[str, np.ndarray]) -> dict[str, tuple]:
    """ctrl_/init_/alpha_/closed_loop_<cname>_model of a ControllerDesign, from its SymPy
    expressions with the fuzzy terms from the unfactored regressor."""
    module = DESIGNS[cname]
    d = module.derive()
    pc = _flat(args, "p_ctrl")
    vals = {e.name: float(x) for e, x in zip(module.PARAMS, pc, strict=True)}
    kf = (_flat(args, "known_fault") if "known_fault" in args
          else np.array([e.default for e in dlay.FAULT_INPUTS]))
    for k, n in enumerate(["rho_hat", "lock_hat", "ubar_hat"]):
        vals.update({f"{n}_{j + 1}": float(kf[3 * k + j]) for j in range(3)})
    if "sched" in args:
        vals["dT_dbeta"] = float(_flat(args, "sched")[0])
        vals["tower_fa_acc"] = float(_flat(args, "sched")[1])
    if "yd" in args:
        vals.update({f"yd_{m}": float(x) for m, x in enumerate(_flat(args, "yd"))})
    model = name.startswith("closed_loop_")
    if model:
        z = _flat(args, "z")
        dm = module.design_model(sp.Symbol("dm_residual", real=True))
        n_m = len(dm["states"])
        vals.update({s.name: float(x) for s, x in zip(dm["states"], z, strict=False)})
        vals["dm_residual"] = float(_flat(args, "d")[0])
        xc = z[n_m:]
        for n in MEAS:
            vals[n] = float(evaluate(f"{cname}_dm_{n}", [dm["meas"][n]], vals)[0])
        for s in d.check_inputs:
            vals[s.name] = float(evaluate(f"{cname}_dm_{s.name}", [dm["true_rates"][s.name]],
                                          vals)[0])
    else:
        vals.update({n: float(x) for n, x in zip(MEAS, _flat(args, "meas"), strict=True)})
        xc = (_flat(args, "x_ctrl") if "x_ctrl" in args
              else np.array([e.default for e in module.STATES]))
        for s in d.check_inputs:
            if s.name in args:
                vals[s.name] = float(_flat(args, s.name)[0])
    vals.update({e.name: float(x) for e, x in zip(module.STATES, xc, strict=True)})
    if name.startswith("init"):
        return {"x_ctrl0": pair(f"{cname}_x0", d.x0, vals)}
    for sym, e in d.signals:
        vals[sym.name] = float(evaluate(f"{cname}_{sym.name}", [e], vals)[0])
    if d.fuzzy_systems()[0]:
        _fuzzy_values(d, vals)
    for sym, e in d.intermediates:
        vals[sym.name] = float(evaluate(f"{cname}_{sym.name}", [e], vals)[0])
    x_dot = pair(f"{cname}_xdot", d.x_dot, vals)
    if name.startswith("alpha"):
        return {k: pair(f"{cname}_{k}", [e], vals) for k, e in d.checks.items()}
    if model:
        rates = pair(f"{cname}_dm_rates", dm["rates"], vals)
        bdot = pair(f"{cname}_dm_bdot", [(d.u0 - dm["beta_mean"]) / dm["tau"]], vals)
        true = pair(f"{cname}_dm_true", [dm["true_rates"][s.name] for s in d.check_inputs],
                    vals)
        return {"z_dot": tuple(np.concatenate([rates[k], bdot[k], x_dot[k]]) for k in (0, 1)),
                "true_rates": true, "meas": exact([vals[n] for n in MEAS])}
    if isinstance(d.v, list):  # one command per blade
        v = pair(f"{cname}_v", d.v, vals)
    else:
        v = pair(f"{cname}_v", [d.v], vals)
        v = (np.repeat(v[0], 3), np.repeat(v[1], 3))
    return {"v": v, "u0": pair(f"{cname}_u0", [d.u0], vals),
            "x_ctrl_dot": x_dot, "diag": pair(f"{cname}_diag", d.diag, vals)}


def _fuzzy_values(d, vals: dict) -> None:
    """The L/B/φ symbols of a design's rule bases from the unfactored regressor."""
    for k, n in enumerate(d.fuzzy_inputs):  # the reference regressor's input symbols
        vals[f"xhat_{k + 1}"] = vals[n]
    for rb, group in zip(*d.fuzzy_systems(), strict=True):
        theta = np.array([vals[w] for w in group])
        for sym, kind in rb.symbols().items():
            if kind[0] == "L":
                vals[sym.name] = float(theta @ dphi(rb.i, kind[1], vals))
            else:
                vals[sym.name] = float(dphi(rb.i, kind[1], vals) @ dphi(rb.i, kind[2], vals))
        phi = dphi(rb.i, rb.zero(), vals)
        vals.update({sym.name: float(phi[m]) for sym, m in rb.phi_symbols().items()})


def reference(name: str, args: dict[str, np.ndarray]) -> dict[str, tuple]:
    """SymPy reference (value, scale) of each output of generated function ``name``."""
    for cname in DESIGNS:
        if name in (f"ctrl_{cname}", f"init_{cname}", f"alpha_{cname}",
                    f"closed_loop_{cname}_model"):
            return design_reference(cname, name, args)
    if name in ("fdi", "init_fdi"):
        return fdi_reference(name, args)
    if name == "sensors":
        return sensors_reference(args)
    if name == "virtual_sensors":
        vals = {s.name: float(x) for s, x in zip(sensors.readings, _flat(args, "readings"),
                                                  strict=True)}
        vals.update({s.name: float(x) for s, x in zip(sensors.excluded,
                                                       _flat(args, "excluded"), strict=True)})
        vals.update({e.name: float(x) for e, x in zip(sensors.param_entries(),
                                                      _flat(args, "p_sensors"), strict=True)})
        vals["gearbox_ratio"] = float(_flat(args, "gearbox_ratio")[0])
        voted, outputs = sensors.virtual_sensors()
        for sym, expr in voted.items():
            vals[sym.name] = float(evaluate(f"voted_{sym.name}", [expr], vals)[0])
        return {"meas": pair("virtual", outputs, vals)}
    if name.startswith(("ctrl_", "init_")):
        return controller_uniform_reference(name, args)
    if name == "aero_torque_sensitivity":
        vals = named_values({})
        vals.update({e.name: float(x) for e, x in zip(
            dlay.PLANT_STATES, _flat(args, "x_plant"), strict=True)})
        vals.update({e.name: float(x) for e, x in zip(
            dlay.TURBINE_PARAMS, _flat(args, "p_turbine"), strict=True)})
        vals.update({k: float(_flat(args, k)[0]) for k in ("wind", "cp", "dcp_dbeta")})
        dT = sp.diff(turbine.aero_torque(), turbine.cp) * sp.Symbol("dcp_dbeta")
        return {"T_aero": pair("taero", [turbine.aero_torque()], vals),
                "dT_dbeta": pair("dTdb", [dT], vals)}
    if name == "generator_torque":
        vals = {e.name: float(x) for e, x in zip(dlay.TURBINE_PARAMS, _flat(args, "p_turbine"),
                                                  strict=True)}
        vals["omega_g"] = float(_flat(args, "omega_g")[0])
        return {"T_gen": pair("tgen", [turbine.generator_torque()], vals)}
    if name == "pitch_actuator":  # derivation/turbine.py pitch_actuator_rhs, in SymPy
        vals = {e.name: float(x) for e, x in zip(dlay.TURBINE_PARAMS, _flat(args, "p_turbine"),
                                                  strict=True)}
        vals.update({e.name: float(x) for e, x in zip(
            dlay.NREL_STATES[3:3 + 2 * dlay.N_BLADES], _flat(args, "x_actuator"),
            strict=True)})
        vals.update({s.name: float(x) for s, x in zip(
            turbine.ACTUATOR_FAULTS, _flat(args, "actuator_faults"), strict=True)})
        vals.update({f"v_{j + 1}": float(x) for j, x in enumerate(_flat(args, "v"))})
        return {"x_actuator_dot": pair("actuator", turbine.pitch_actuator_rhs(), vals)}
    if name.startswith("turbine_") or name in ("aero_operating_point", "rotor_inflow",
                                                "edge_inflow"):
        return turbine_reference(name, args)
    if name == "lyapunov":
        return lyapunov_reference(args)
    if name == "lyapunov_bound":
        return bound_reference(args)
    if name == "observer_lyapunov":
        return observer_lyapunov_reference(args)
    values = named_values(args)
    if name == "plant_paper":
        return plant_reference(values)
    if name == "strict_feedback_targets":
        return plant_reference(values, targets=True)
    if name == "fuzzy_regressors":
        return {f"phi_{i}": exact(dphi(i, (0,) * i, values)) for i in range(1, 5)}
    if name in ("controller", "alpha_derivatives"):
        return controller_reference(values)
    if name == "closed_loop_paper":
        return closed_loop_reference(values)
    raise KeyError(name)
