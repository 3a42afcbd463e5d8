"""Verification of the generated functions, shared by the tests and ``wtftc verify``.

* :func:`random_inputs`           sensible random arguments for any generated function;
* :func:`compiled_vs_interpreted` compiled C against CasADi's virtual machine;
* :func:`closed_loop_trajectory`  a fixed-step RK4 run of the paper's closed loop
                                  (plant (1)-(4), faults (19), observer (21), eq (49));
* :func:`alpha_dot_fd`            α̇_i against central differences of α_i along it.

The verification run uses a time-varying reference y_d(t) = y0 + a sin(ω t) and a smooth
disturbance d1(t) so that every reference derivative and the ẏ term are exercised.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import layout_json, load
from wtftc.sim.integrate import rk4_path

#: input name → layout group whose defaults centre the random values
_GROUP_OF_INPUT = {
    "x_plant": "plant_states", "x_ctrl": "controller_states", "p_plant": "plant_params",
    "p_turbine": "turbine_params",
    "p_ctrl": "controller_params", "fault": "fault_inputs", "yd": "reference",
    "theta_star": "theta_star",
}


def random_inputs(name: str, rng: np.random.Generator,
                  z_span: float = 1.5) -> dict[str, np.ndarray]:
    """Random arguments for generated function ``name``, near the layout's defaults.

    Parameters vary by ±10 % around their defaults (keeping signs, so that inertias stay
    positive and eq (49) stays invertible); states, commands and weights get O(1) values;
    observer states x̂_k are drawn where the fuzzy systems live, at normalized inputs
    z_k = (x̂_k - offset_k)/scale_k uniform in [-z_span, z_span].
    """
    sig = layout_json()["functions"][name]
    special = _turbine_inputs(rng)
    pc = lay.defaults("controller_params")
    offsets = pc[lay.block("controller_params", "x_offset")]
    scales = pc[lay.block("controller_params", "x_scale")]
    xhat = lay.block("controller_states", "xhat")
    n_plant = lay.size("plant_states")
    out = {}
    for inp in sig["inputs"]:
        n, shape = inp["name"], tuple(inp["shape"])
        size = int(np.prod(shape))
        if n in special and special[n].size == size:
            val = special[n]
        elif n == "x_plant" and size in special["x_plant_sized"]:  # the tower plants'
            val = special["x_plant_sized"][size]
        elif n == "z" and name in _models():  # a design's model: model and controller states
            reg = _models()[name]
            val = np.concatenate([_draw(reg["model"]["states"], rng),
                                  _draw(lay.layout()[reg["states"]], rng)])
        elif n in ("x_ctrl", "p_ctrl") and size != len(lay.names(_GROUP_OF_INPUT[n])):
            group = _group_of(name, n, size)
            base = lay.defaults(group)
            val = (base * (1 + 0.1 * rng.uniform(-1, 1, base.size)) if n == "p_ctrl"
                   else _draw(lay.layout()[group], rng))
        elif n == "p_turbine":
            val = lay.defaults("turbine_params") * (1 + 0.1 * _added_last(
                rng, special["tower_rng"], lay.size("turbine_params"), TURBINE_PARAMS_ADDED))
        elif n in ("p_plant", "p_ctrl", "fault"):
            base = lay.defaults(_GROUP_OF_INPUT[n])
            val = base * (1 + 0.1 * rng.uniform(-1, 1, base.size))
        elif n in _GROUP_OF_INPUT or n == "z":
            groups = (["plant_states", "controller_states"] if n == "z"
                      else [_GROUP_OF_INPUT[n]])
            base = np.concatenate([lay.defaults(g) for g in groups])
            val = base + 0.3 * rng.standard_normal(base.size)
            k0 = {"x_ctrl": 0, "z": n_plant}.get(n)
            if k0 is not None:
                val[k0 + xhat.start:k0 + xhat.stop] = offsets + scales * rng.uniform(
                    -z_span, z_span, offsets.size)
        elif n == "xhat":
            val = offsets + scales * rng.uniform(-z_span, z_span, offsets.size)
        elif n == "K_obs":
            k_obs = lay.defaults("controller_params")[lay.block("controller_params", "K_obs")]
            val = k_obs * (1 + 0.2 * rng.uniform(-1, 1, k_obs.size))
        elif n in ("Q", "P"):
            m = rng.standard_normal(shape)
            val = (m @ m.T + shape[0] * np.eye(shape[0])).reshape(-1, order="F")
        else:
            val = 0.5 * rng.standard_normal(size)
        out[n] = np.asarray(val, dtype=float).reshape(shape, order="F")
    return out


def _models() -> dict[str, dict]:
    """Design-model function name → its controller's registry entry (layout.json)."""
    return {reg["model"]["function"]: reg for reg in lay.layout()["controllers"].values()
            if "model" in reg}


def _draw(entries: list[dict], rng: np.random.Generator) -> np.ndarray:
    """Random values of layout entries: uniform in each entry's sample range where the
    derivation gives one, else its default plus 0.05 N(0, 1)."""
    if all("sample" in e for e in entries):  # (measurements have no default)
        return np.array([rng.uniform(*e["sample"]) for e in entries])
    base = np.array([e["default"] for e in entries], dtype=float)
    if not any("sample" in e for e in entries):
        return base + 0.05 * rng.standard_normal(base.size)
    return np.array([rng.uniform(*e["sample"]) if "sample" in e
                     else e["default"] + 0.05 * rng.standard_normal() for e in entries])


def _group_of(name: str, kind: str, size: int) -> str:
    """The states/params group of the registered controller a function belongs to (by its
    name: ctrl_<c>, init_<c>, alpha_<c>, closed_loop_<c>_model), else the one of this size."""
    key = "states" if kind == "x_ctrl" else "params"
    regs = lay.layout()["controllers"]
    for c, reg in regs.items():
        if name.endswith(f"_{c}") or name == f"closed_loop_{c}_model":
            return reg[key]
    for reg in regs.values():
        if len(lay.names(reg[key])) == size:
            return reg[key]
    raise KeyError(f"no controller {key} group of size {size}")


def _turbine_inputs(rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Plant inputs that cross the actuator limits and exercise every fault: the layout
    groups drawn in their sample ranges (derivation/layout.py), the scalars here."""
    x_plant = _draw(lay.layout()["nrel5mw_states"], rng)
    wind, cp = rng.uniform(3.0, 25.0), rng.uniform(-0.1, 0.5)
    actuator = _draw(lay.layout()["actuator_faults"], rng)
    sensor = _draw(lay.layout()["sensor_faults"], rng)
    meas = _draw(lay.layout()["measurements"], rng)
    # the sensors' draws from a generator of their own, seeded by rng's state without
    # advancing it: every other function's points stay what they were
    rs = np.random.default_rng(int(rng.bit_generator.state["state"]["state"]) % 2**63)
    names = [m["name"] for m in lay.layout()["measurements"]]
    true = np.array([meas[names.index(s["measures"])] for s in lay.layout()["sensors"]])
    readings = true * (1 + 0.05 * rs.standard_normal(true.size)
                       * (rs.uniform(size=true.size) < 0.33))
    rt = np.random.default_rng(int(rng.bit_generator.state["state"]["state"]) % 2**61 + 1)
    # the tower-top acceleration (issue 34's tower damper) from a stream of its own: every
    # other draw stays what it was
    ra = np.random.default_rng(int(rng.bit_generator.state["state"]["state"]) % 2**61 + 2)
    return {
        "x_plant_sized": _tower_plant_states(rng, rt, x_plant),
        "ct": np.array([rt.uniform(-0.1, 1.2)]),
        "tower_rng": rt,
        "x_plant": x_plant,
        "wind": np.array([wind]),
        "cp": np.array([cp]),
        "actuator_faults": actuator,
        "sensor_faults": sensor,
        "meas": meas,
        # the sensors' chain: signals and lag states where they live, standard-normal
        # draws, parameters in their sample ranges (some zero: the no-lag, no-resolution
        # branches)
        "true_signals": true,
        "x_lag": true + 0.01 * rs.standard_normal(true.size),
        "noise": rs.standard_normal(true.size),
        # readings of two sensors per quantity: a third of the pairs disagree, a fifth of
        # the sensors excluded (every branch of the virtual sensors)
        "readings": readings,
        "excluded": (rs.uniform(size=true.size) < 0.2).astype(float),
        "gearbox_ratio": np.array([rs.uniform(50.0, 120.0)]),
        # the generator speed (LSS) across every region of the torque law
        "omega_g": np.array([rs.uniform(0.5, 1.6)]),
        "p_sensors": _draw(lay.layout()["sensor_params"], rs)
        * (rs.uniform(size=lay.size("sensor_params")) > 0.3),
        "sched": np.array([-rng.uniform(2e6, 3e7), ra.uniform(-1.0, 1.0)]),
        "known_fault": _draw(lay.layout()["fault_inputs"], rng),
        "dcp_dbeta": np.array([rng.uniform(-2.0, 0.2)]),
        "omega_dot": np.array([rng.uniform(-0.2, 0.2)]),
        "b_dot": np.array([rng.uniform(-0.05, 0.05)]),
        "d": np.array([rng.uniform(-0.05, 0.05)]),
        "x_fdi": _fdi_states(rng, rs),
        "beta_meas": rng.uniform(-0.05, 1.65, lay.n_blades()),
        "p_fdi": _fdi_base() * (1 + 0.1 * _fdi_param_draws(rng, rs)),
    }


def _tower_plant_states(rng: np.random.Generator, rt: np.random.Generator,
                        x_plant: np.ndarray) -> dict[int, np.ndarray]:
    """The tower plants' states by their count: the nrel5mw plant's ``x_plant``, then the
    tower's drawn from ``rt`` (issue 18), then the blades' edge mode from a fourth stream
    (issue 33): every other draw stays what it was."""
    tower_states = [e for e in lay.layout()["tower_states"]
                    if e["name"] not in lay.names("nrel5mw_states")]
    x_tower = np.concatenate([x_plant, _draw(tower_states, rt)])
    re_ = np.random.default_rng(int(rng.bit_generator.state["state"]["state"]) % 2**61 + 2)
    edge_states = [e for e in lay.layout()["tower_edge_states"]
                   if e["name"] not in lay.names("tower_states")]
    return {x_tower.size: x_tower,
            x_tower.size + len(edge_states): np.concatenate([x_tower,
                                                             _draw(edge_states, re_)])}


#: turbine parameters added after the points were fixed (the tower's, issue 18, last in
#: the layout): drawn from a stream of their own, the others from rng
TURBINE_PARAMS_ADDED = 10


def _added_last(rng: np.random.Generator, other: np.random.Generator, size: int,
                added: int) -> np.ndarray:
    """U(-1, 1) draws of ``size`` values, the last ``added`` from ``other``: rng advances
    as it did before they were added, so every function's points stay what they were."""
    return np.concatenate([rng.uniform(-1, 1, size - added), other.uniform(-1, 1, added)])


#: FDI parameters added after the points were fixed: drawn from rs, the others from rng,
#: so that every function's points stay what they were (the same rule as the sensors')
FDI_PARAMS_ADDED = ("fdi_delta_rate_limited",  # issue 17
                    "fdi_stop_band", "fdi_stop_gap", "fdi_T_w_fault",  # issue 18
                    "fdi_k_align")  # issue 34


def _fdi_base() -> np.ndarray:
    """The FDI's defaults, the start-up alignment on at a host's rate (its default, 0,
    would leave the pull's terms unchecked)."""
    p = lay.defaults("fdi_params")
    p[lay.index("fdi_params", "fdi_k_align")] = 5.0
    return p


def _fdi_param_draws(rng: np.random.Generator, rs: np.random.Generator) -> np.ndarray:
    names = lay.names("fdi_params")
    old = iter(rng.uniform(-1, 1, len(names) - len(FDI_PARAMS_ADDED)))
    return np.array([rs.uniform(-1, 1) if n in FDI_PARAMS_ADDED else next(old)
                     for n in names])


def _fdi_states(rng: np.random.Generator, rs: np.random.Generator) -> np.ndarray:
    """Plausible FDI states (derivation/fdi.py), limits and latches crossed, in the layout's
    order: drawn blade by blade, the regression sums S consistent with a mean and variance;
    the sensor pair tests' states from ``rs`` (rng's draws stay what they were)."""
    values = {}
    # the filtered pitch (issue 18) from a stream of its own, seeded by rng's state
    # without advancing it: every other draw stays what it was
    rp = np.random.default_rng(int(rng.bit_generator.state["state"]["state"]) % 2**59 + 2)
    for j in lay.blades():
        values |= {f"fdi_{kind}_{j}": v for kind, v in _fdi_blade(rng).items()}
        # the time at the rate limit, a fraction like the latch: its draw, so that the
        # draws of the states after it stay what they were before it was added (issue 17)
        values[f"fdi_rate_limited_fraction_{j}"] = values[f"fdi_latch_{j}"]
        values[f"fdi_pitch_filtered_{j}"] = rp.uniform(-0.05, 1.65)
        values[f"fdi_stop_held_{j}"] = rp.uniform(0, 1)
    # the start-up alignment's weight (1 → 0), from rp: the draws above stay what they were
    values["fdi_align"] = rp.uniform(0, 1)
    for n in lay.names("fdi_states"):
        if n not in values:  # the pair tests': residuals, mean squares, latches
            gen = 100.0 if "omega_g_hss" in n else 1.0  # the HSS: N times the rotor's
            values[n] = (rs.uniform(0, 1) if "latch" in n else rs.uniform(0, 1e-5) * gen**2
                         if "mean_sq" in n else rs.uniform(-0.01, 0.01) * gen)
    return np.array([values[n] for n in lay.names("fdi_states")])


def _fdi_blade(rng: np.random.Generator) -> dict[str, float]:
    s1 = rng.uniform(0.3, 1.0)
    mb, mm = rng.uniform(0, 0.5), rng.uniform(0, 0.5)
    var = rng.uniform(1e-5, 1e-2)
    return {"beta_hat": rng.uniform(-0.05, 1.65), "beta_hat_rate": rng.uniform(-0.25, 0.25),
            "mean_sq": rng.uniform(0, 1e-5), "latch": rng.uniform(0, 1),
            "confidence": rng.uniform(0, 1.2), "S_bb": s1 * (mb**2 + var), "S_b": s1 * mb,
            "S_1": s1, "S_mb": s1 * (mb * mm + rng.uniform(-1, 1) * var), "S_m": s1 * mm,
            "S_mm": s1 * (mm**2 + rng.uniform(0, 2) * var),
            "residual_filtered": rng.uniform(-0.01, 0.01), "rate_msq_model": rng.uniform(0, 1e-3),
            "beta_pd": rng.uniform(-0.05, 1.65), "beta_pd_rate": rng.uniform(-0.25, 0.25),
            "mean_sq_pd": rng.uniform(0, 1e-5),
            "beta_air": rng.uniform(-0.05, 1.65), "beta_air_rate": rng.uniform(-0.25, 0.25),
            "mean_sq_air": rng.uniform(0, 1e-5)}


def _evaluate(f, args: dict) -> dict[str, np.ndarray]:
    res = f(**args)
    return {k: np.array(v) for k, v in res.items()}


def relative_error(a: np.ndarray, b: np.ndarray) -> float:
    """‖a - b‖∞ / max(‖b‖∞, tiny): the error relative to the output's magnitude."""
    a, b = np.asarray(a, float).ravel(), np.asarray(b, float).ravel()
    if a.size == 0:
        return 0.0
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def compiled_vs_interpreted(n_points: int = 50, seed: int = 0) -> dict[str, float]:
    """Largest relative difference, over random points, of every function's outputs."""
    rng = np.random.default_rng(seed)
    worst = {}
    for name in sorted(layout_json()["functions"]):
        fc, fi = load(name, "compiled"), load(name, "interpreted")
        err = 0.0
        for _ in range(n_points):
            args = random_inputs(name, rng)
            oc, oi = _evaluate(fc, args), _evaluate(fi, args)
            err = max(err, *(relative_error(oc[k], oi[k]) for k in oi))
        worst[name] = err
    return worst


@dataclass
class Signals:
    """Exogenous signals of the verification run: y_d(t) and its derivatives, d1(t)."""

    y0: float = field(default_factory=lambda: float(  # the reference's default, y_d = 1.27
        lay.defaults("reference")[lay.index("reference", "yd_0")]))
    amp: float = 0.02  # rad/s
    omega: float = 0.8  # rad/s
    d_amp: float = 0.01  # rad/s²
    d_omega: float = 1.3  # rad/s

    def yd(self, t: float) -> np.ndarray:
        w, a = self.omega, self.amp
        s, c = np.sin(w * t), np.cos(w * t)
        return np.array([self.y0 + a * s, a * w * c, -a * w**2 * s, -a * w**3 * c,
                         a * w**4 * s])

    def d1(self, t: float) -> float:
        return self.d_amp * np.sin(self.d_omega * t)


@dataclass
class Trajectory:
    t: np.ndarray
    z: np.ndarray  # (N, n_z): plant states then controller states
    p_plant: np.ndarray
    p_ctrl: np.ndarray
    fault: np.ndarray
    signals: Signals


def initial_state(seed: int = 0) -> np.ndarray:
    """Plant near rated speed, observer at rest, small seeded fuzzy weights."""
    rng = np.random.default_rng(seed)
    xp = lay.defaults("plant_states")
    xp[lay.index("plant_states", "omega_r")] *= 0.97
    xc = lay.defaults("controller_states")
    xc[lay.index("controller_states", "xhat_1")] = xp[lay.index("plant_states", "omega_r")]
    weights = lay.block("controller_states", "xhat").stop  # the fuzzy weights follow x̂
    xc[weights:] = 0.01 * rng.standard_normal(xc.size - weights)
    return np.concatenate([xp, xc])


def closed_loop_trajectory(t_final: float = 1.0, dt: float = 1e-3, z0=None, p_plant=None,
                           p_ctrl=None, fault=None, signals: Signals | None = None,
                           t0: float = 0.0) -> Trajectory:
    """Fixed-step RK4 of ż = f(z, t) with the generated closed loop (dt < 0 runs backward)."""
    f = load("closed_loop_paper")
    sig = signals or Signals()
    pp = lay.vector("plant_params", p_plant)
    pc = lay.vector("controller_params", p_ctrl)
    fl = lay.vector("fault_inputs", fault)
    z = initial_state() if z0 is None else np.array(z0, dtype=float)
    n = int(round(abs(t_final - t0) / abs(dt)))

    def rhs(t, zz):
        return np.array(f(z=zz, d1=sig.d1(t), yd=sig.yd(t), fault=fl, p_plant=pp,
                          p_ctrl=pc)["z_dot"]).reshape(-1)

    ts, zs = rk4_path(rhs, z, t0, t_final, n)
    return Trajectory(ts, zs, pp, pc, fl, sig)


def alpha_values(traj: Trajectory, k: int) -> dict[str, np.ndarray]:
    """α_i, full and computable α̇_i, ∂α_i/∂y and ẏ̂ at sample k of a trajectory."""
    n_plant = len(lay.names("plant_states"))
    z = traj.z[k]
    t = traj.t[k]
    cl = load("closed_loop_paper")(z=z, d1=traj.signals.d1(t), yd=traj.signals.yd(t),
                                   fault=traj.fault, p_plant=traj.p_plant, p_ctrl=traj.p_ctrl)
    ydot = float(cl["ydot"])
    out = load("alpha_derivatives")(x_ctrl=z[n_plant:], y=z[0], yd=traj.signals.yd(t),
                                    p_ctrl=traj.p_ctrl, ydot=ydot)
    res = {key: np.array(v).reshape(-1) for key, v in out.items()}
    res["ydot"] = np.array([ydot])
    return res


@dataclass
class FDResult:
    h: np.ndarray
    errors: np.ndarray  # (len(h), 3): relative error of each α̇_i
    slopes: np.ndarray  # fitted log-log slope of each α̇_i on the truncation-dominated h
    alpha_dot: np.ndarray  # the analytic α̇_i (full)
    comp_minus_full: np.ndarray  # α̇_comp - α̇_full
    ydot_term: np.ndarray  # ∂α_i/∂y (ẏ̂ - ẏ)


def alpha_dot_fd(t_point: float = 0.5, h_values=(1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5),
                 substep: float = 2e-4, **kwargs) -> FDResult:
    """Central differences of α_i along the closed loop against the analytic α̇_i.

    The state at t ± h is reached by RK4 from the state at t with steps ≤ ``substep``,
    so the integration error (O(substep⁴)) stays far below the differencing error.
    Slopes are fitted on h ≥ 1e-3·(largest h) where truncation, not rounding, dominates.
    """
    base = closed_loop_trajectory(t_final=t_point, dt=1e-3, **kwargs)
    zt = base.z[-1]
    at = alpha_values(base, len(base.t) - 1)
    h_values = np.asarray(h_values, dtype=float)
    errors = np.empty((h_values.size, at["alpha"].size))
    for m, h in enumerate(h_values):
        n = max(1, int(np.ceil(h / substep)))
        fwd = closed_loop_trajectory(t_final=t_point + h, dt=h / n, z0=zt, t0=t_point, **kwargs)
        bwd = closed_loop_trajectory(t_final=t_point - h, dt=h / n, z0=zt, t0=t_point, **kwargs)
        a_plus = alpha_values(fwd, len(fwd.t) - 1)["alpha"]
        a_minus = alpha_values(bwd, len(bwd.t) - 1)["alpha"]
        fd = (a_plus - a_minus) / (2 * h)
        errors[m] = np.abs(fd - at["alpha_dot_full"]) / np.maximum(
            np.abs(at["alpha_dot_full"]), 1e-300)
    sel = h_values >= 1e-3 * h_values.max()
    slopes = np.array([np.polyfit(np.log(h_values[sel]), np.log(errors[sel, i]), 1)[0]
                       for i in range(errors.shape[1])])
    return FDResult(
        h=h_values, errors=errors, slopes=slopes, alpha_dot=at["alpha_dot_full"],
        comp_minus_full=at["alpha_dot_comp"] - at["alpha_dot_full"],
        ydot_term=at["dalpha_dy"] * (at["ydot_hat"] - at["ydot"]))


def grad_V_dot_f() -> ca.Function:
    """∇V·f: CasADi AD of the generated V along the generated closed loop (and ẏ_d).

    Independent of the structured V̇ that the derivation writes out (eqs (22)-(48)).
    """
    lyap = load("lyapunov", "interpreted")
    cl = load("closed_loop_paper", "interpreted")
    n_p = len(lay.names("plant_states"))
    z = ca.SX.sym("z", n_p + len(lay.names("controller_states")))
    yd = ca.SX.sym("yd", lay.size("reference"))
    d1, fault = ca.SX.sym("d1"), ca.SX.sym("fault", len(lay.names("fault_inputs")))
    ts = ca.SX.sym("theta_star", len(lay.names("theta_star")))
    n_chain = lay.layout()["n_chain"]
    P = ca.SX.sym("P", n_chain, n_chain)
    pp = ca.SX.sym("p_plant", len(lay.names("plant_params")))
    pc = ca.SX.sym("p_ctrl", len(lay.names("controller_params")))
    V = lyap(x_plant=z[:n_p], x_ctrl=z[n_p:], d1=d1, yd=yd, fault=fault, theta_star=ts, P=P,
             p_plant=pp, p_ctrl=pc)["V"]
    zdot = cl(z=z, d1=d1, yd=yd, fault=fault, p_plant=pp, p_ctrl=pc)["z_dot"]
    yd_rate = ca.vertcat(yd[1:], 0)  # y_d⁽⁴⁾ is not an argument of V
    dV = ca.jtimes(V, ca.vertcat(z, yd), ca.vertcat(zdot, yd_rate))
    return ca.Function("grad_V_dot_f", [z, d1, yd, fault, ts, P, pp, pc], [dV],
                       ["z", "d1", "yd", "fault", "theta_star", "P", "p_plant", "p_ctrl"],
                       ["Vdot"])


def vdot_identity_error(n_points: int = 200, seed: int = 3, control_sign: float = -1.0,
                        lock_fraction: float | None = None) -> float:
    """Largest relative difference between the structured V̇ (generated) and ∇V·f."""
    rng = np.random.default_rng(seed)
    g = grad_V_dot_f()
    lyap = load("lyapunov")
    worst = 0.0
    for _ in range(n_points):
        a = random_inputs("lyapunov", rng)
        a["p_ctrl"][lay.index("controller_params", "control_sign")] = control_sign
        # a partial lock on blade 2, so the actuation mismatch of eq (22) is exercised
        lock = rng.uniform(0, 1) if lock_fraction is None else lock_fraction
        a["fault"][lay.index("fault_inputs", "lock_2")] = lock
        z = np.concatenate([a["x_plant"].ravel(), a["x_ctrl"].ravel()])
        ref = np.array(g(z, a["d1"], a["yd"], a["fault"], a["theta_star"], a["P"],
                         a["p_plant"], a["p_ctrl"])).ravel()
        got = np.array(lyap(**a)["Vdot"]).ravel()
        worst = max(worst, relative_error(got, ref))
    return worst
