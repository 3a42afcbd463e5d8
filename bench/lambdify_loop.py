"""What a user would write instead of generated code: the same closed loop, lambdified.

SymPy's ``lambdify`` (NumPy, ``cse=True``) of the very expressions wtftc generates from
(derivation/turbine.py, backstepping.py, physical.py), called from Python: the plant, the
measured pitch, the controller's commands and state derivatives. The fuzzy symbols L/B
are evaluated from the lambdified derivatives of the unfactored regressor
(``fuzzy.reference_regressor_derivative``), Cp(λ, β) and the pitch-sensitivity schedule by
the same CasADi interpolants as wtftc (a user would call a table library). Never used by
wtftc itself; the benchmark's baseline, and checked against the generated loop
(tests/test_bench.py).

Needs the source tree (derivation/ beside wtftc/).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from bench import require_source_tree
from wtftc.model import aero

require_source_tree()
from derivation import backstepping as bs  # noqa: E402
from derivation import fuzzy, observer, physical, sensors, turbine  # noqa: E402
from derivation import layout as dlay  # noqa: E402


def _lambdify(args: list[sp.Symbol], exprs: list[sp.Expr]):
    f = sp.lambdify(args, exprs, modules="numpy", cse=True)
    return lambda values: np.asarray(f(*values), dtype=float).ravel()


class _Regressors:
    """∂^α φ_i at x̂ from the unfactored regressor (lambdified once per (i, α))."""

    def __init__(self):
        self._f = {}
        self.off = sp.symbols("x_offset_1:5", real=True)
        self.scl = sp.symbols("x_scale_1:5", positive=True)

    def __call__(self, i, alpha, xhat, offsets, scales, mf) -> np.ndarray:
        key = (i, tuple(alpha))
        if key not in self._f:
            xs = observer.xhat[:i]
            der = fuzzy.reference_regressor_derivative(xs, self.off[:i], self.scl[:i], alpha)
            args = [*xs, *self.off[:i], *self.scl[:i], fuzzy.mf_width, *fuzzy.mf_centre]
            self._f[key] = sp.lambdify(args, der, modules="numpy", cse=True)
        return np.asarray(self._f[key](*xhat[:i], *offsets[:i], *scales[:i], *mf), dtype=float)


class LambdifiedLoop:
    """f(z, wind, actuator faults, sensor faults, told faults) -> ż for one Problem."""

    def __init__(self, problem):
        rc = problem.config
        self.controller = rc.controller
        self.pt, self.pc, self.yd = rc.p_turbine, rc.p_ctrl, problem.yd
        self.gear = float(rc.param("gearbox_ratio"))
        self.cp = aero.cp_interpolant(rc.table)
        self.sched = aero.pitch_sensitivity_schedule(rc.table,
                                                    rc.p_turbine)
        tp = [sp.Symbol(e.name, real=True) for e in dlay.TURBINE_PARAMS]
        af = list(turbine.ACTUATOR_FAULTS)
        states = list(turbine.NREL_STATES)
        self.n_p = len(states)
        args = [*states, *turbine.v, turbine.wind, turbine.cp, *af, *tp]
        self.plant = _lambdify(args, self._named(turbine.nrel5mw_rhs(), args))
        # the sensors (derivation/sensors.py) on the true signals: no lag, no noise
        m_args = [*sensors.true, *sensors.lagged, *sensors.noise,
                  *[sp.Symbol(e.name, real=True) for e in sensors.fault_entries()],
                  *[sp.Symbol(e.name, real=True) for e in sensors.param_entries()]]
        self.meas = _lambdify(m_args, self._named(sensors.measured(), m_args))
        # sensor m1 of each blade (the bench's runs fail none: m2 reads the same, and the
        # virtual sensor's mean is that reading)
        self.i_pitch = [sensors.SENSOR_NAMES.index(f"beta_meas_{j}_m1") for j in (1, 2, 3)]
        self.n_sens = len(sensors.SENSOR_NAMES)
        self.p_sensors = np.zeros(len(sensors.param_entries()))
        self.op = _lambdify(args, self._named([turbine.tip_speed_ratio(),
                                               turbine.mean_pitch()], args))
        self.regressors = _Regressors()
        if rc.controller == "paper":
            self._setup_paper()
        elif rc.controller == "physical":
            self._setup_physical()
        else:
            raise ValueError(f"no lambdify baseline for controller {rc.controller!r}")

    @staticmethod
    def _named(exprs, args):
        """Rename every symbol to the positive/real-agnostic one lambdify receives by name."""
        by_name = {a.name: a for a in args}
        out = []
        for e in exprs:
            e = sp.sympify(e)
            out.append(e.xreplace({s: by_name[s.name] for s in e.free_symbols
                                   if s.name in by_name}))
        return out

    # --- the paper's controller (eqs (21)-(49)), eq (49) told the fault ---
    def _setup_paper(self):
        d = bs.derive()
        self.design = d
        self.rbs = d.rule_bases
        fz = [s for rb in self.rbs for s in rb.symbols()]
        self.ctrl_entries = [e.name for e in dlay.CONTROLLER_STATES]
        self.p_names = [e.name for e in dlay.CONTROLLER_PARAMS]
        coeffs = bs.adaptive_law_coefficients(d)
        exprs = [d.u0, *bs.applied_commands(d.u0), *d.xhat_dot, *[g for g, _ in coeffs]]
        syms = sorted(set().union(*[sp.sympify(e).free_symbols for e in exprs]),
                      key=lambda s: s.name)
        self.c_args = syms
        self.c_fun = sp.lambdify(syms, exprs, modules="numpy", cse=True)
        self.fz_symbols = fz
        self.r_names = [r.name for _, r in coeffs]
        self.n_c = len(self.ctrl_entries)
        i0 = self.p_names.index("rho_hat_1")
        self.i_known = slice(i0, i0 + len(dlay.FAULT_INPUTS))

    def _paper(self, xc, omega_r, known):
        pc = self.pc.copy()
        pc[self.i_known] = known
        vals = dict(zip(self.p_names, pc, strict=True))
        vals.update(zip(self.ctrl_entries, xc, strict=True))
        vals["y"] = omega_r
        vals.update({f"yd_{k}": y for k, y in enumerate(self.yd)})
        xhat = xc[:4]
        off = [vals[f"x_offset_{k}"] for k in range(1, 5)]
        scl = [vals[f"x_scale_{k}"] for k in range(1, 5)]
        mf = [vals["mf_width"], *[vals[f"mf_centre_{m}"] for m in range(1, dlay.N_MF + 1)]]
        cache = {}

        def dphi(i, a):
            key = (i, tuple(a))
            if key not in cache:
                cache[key] = self.regressors(i, a, xhat, off, scl, mf)
            return cache[key]

        thetas = {}
        k = 4
        for rb in self.rbs:
            n = dlay.rule_count(rb.i)
            thetas[rb.i] = xc[k:k + n]
            k += n
        for rb in self.rbs:
            for sym, kind in rb.symbols().items():
                if kind[0] == "L":
                    vals[sym.name] = thetas[rb.i] @ dphi(rb.i, kind[1])
                else:
                    vals[sym.name] = dphi(rb.i, kind[1]) @ dphi(rb.i, kind[2])
        out = self.c_fun(*[vals[s.name] for s in self.c_args])
        v, xhat_dot, gchi = out[1:4], out[4:8], out[8:]
        theta_dot = [g * dphi(rb.i, (0,) * rb.i) - vals[r] * thetas[rb.i]
                     for g, r, rb in zip(gchi, self.r_names, self.rbs, strict=True)]
        return np.array(v, dtype=float), np.concatenate([np.asarray(xhat_dot, float),
                                                         *theta_dot])

    # --- the physical AFTC (derivation/physical.py), told the fault ---
    def _setup_physical(self):
        d = physical.chain()
        self.design = d
        self.p_names = [e.name for e in physical.PARAMS]
        th2, thdir = sp.Symbol("theta_norm2"), sp.Symbol("theta_dot_dir")
        # the design without its speed observer and peak shaving, on the actuator model (the
        # defaults): the switches folded, as a user lambdifying the default design would
        default = {physical.w_obs: 0, physical.act: 1, physical.ps_pitch: 0,
                   sp.Symbol("phys_td_gain", real=True): 0}
        kappa = physical.freeze_conditions(d, th2, thdir).subs(default)
        exprs = [d.v_free.subs(default), d.z1.subs(default), kappa]
        syms = sorted(set().union(*[sp.sympify(e).free_symbols for e in exprs])
                      - {sp.Symbol("kappa", real=True)}, key=lambda s: s.name)
        self.c_args = syms
        # κ enters v through α̇1: evaluate κ first, then v with it
        self.k_fun = sp.lambdify(syms, exprs[1:], modules="numpy", cse=True)
        self.v_args = sorted(sp.sympify(exprs[0]).free_symbols, key=lambda s: s.name)
        self.v_fun = sp.lambdify(self.v_args, exprs[0], modules="numpy", cse=True)
        self.n_c = len(physical.STATES)

    def _physical(self, xc, omega_r, beta_meas, sched, known):
        th, w_hat, eta = xc[:dlay.N_MF], xc[dlay.N_MF], xc[dlay.N_MF + 1]
        s_hat = xc[dlay.N_MF + 2]  # the tower damper's state (off, no tower)
        a_f = xc[dlay.N_MF + 3]  # its low-passed acceleration (the low-pass off)
        vals = dict(zip(self.p_names, self.pc, strict=True))
        if vals["phys_obs_omega"] != 0.0:
            raise ValueError("the lambdify loop runs the design without its speed observer")
        vals.update({"omega_r": omega_r, "dT_dbeta": sched, "phys_speed_hat": w_hat,
                     "phys_innovation": eta, "phys_td_speed": s_hat, "phys_td_acc": a_f,
                     "tower_fa_acc": 0.0,
                     **{f"beta_meas_{j + 1}": b for j, b in enumerate(beta_meas)},
                     **{f"yd_{k}": y for k, y in enumerate(self.yd)}})
        for k, n in enumerate(("rho_hat", "lock_hat", "ubar_hat")):
            vals.update({f"{n}_{j + 1}": known[3 * k + j] for j in range(3)})
        off, scl = [vals["x_offset_1"]], [vals["x_scale_1"]]
        mf = [vals["mf_width"], *[vals[f"mf_centre_{m}"] for m in range(1, dlay.N_MF + 1)]]
        rb = self.design.rule_base
        for sym, kind in rb.symbols().items():
            if kind[0] == "L":
                vals[sym.name] = th @ self.regressors(1, kind[1], [omega_r], off, scl, mf)
            else:
                vals[sym.name] = (self.regressors(1, kind[1], [omega_r], off, scl, mf)
                                  @ self.regressors(1, kind[2], [omega_r], off, scl, mf))
        L = vals[rb.L().name]
        z1 = omega_r - vals["yd_0"]
        th2 = float(th @ th)
        vals["theta_norm2"] = th2
        vals["theta_dot_dir"] = vals["phys_gamma"] * z1 * L - vals["phys_sigma"] * th2
        _, kappa = self.k_fun(*[vals[s.name] for s in self.c_args])
        vals["kappa"] = float(kappa)
        v = float(self.v_fun(*[vals[s.name] for s in self.v_args]))
        phi = self.regressors(1, (0,), [omega_r], off, scl, mf)
        theta_dot = kappa * (vals["phys_gamma"] * z1 * phi - vals["phys_sigma"] * th)
        # the observer off: ω̂_r follows ω_r, η decays; the damper's state decays at ω_h,
        # its low-pass's (off: phys_td_lpf = 0) at 1/s
        return np.full(3, v), np.concatenate([theta_dot, [omega_r - w_hat, -eta,
                                                          -vals["phys_td_corner"] * s_hat,
                                                          -a_f]])

    def __call__(self, z, wind, af, sf, known) -> np.ndarray:
        xp, xc = z[:self.n_p], z[self.n_p:]
        base = [*xp, 0.0, 0.0, 0.0, wind, 0.0, *af, *self.pt]
        lam, beta_mean = self.op(base)
        cp = float(self.cp(lam, beta_mean))
        base[self.n_p + 4] = cp
        true = [xp[0], xp[2] * self.gear, *xp[3:6]] * 2  # in sensors.SENSOR_NAMES' order
        beta_meas = self.meas([*true, *true, *np.zeros(self.n_sens), *sf, *self.p_sensors])[
            self.i_pitch]
        if self.controller == "paper":
            v, xc_dot = self._paper(xc, xp[0], known)
        else:
            sched = float(self.sched(beta_meas.mean()))
            v, xc_dot = self._physical(xc, xp[0], beta_meas, sched, known)
        base[self.n_p:self.n_p + 3] = v
        return np.concatenate([self.plant(base), xc_dot])


def rk4(loop: LambdifiedLoop, problem, dt: float, n_steps: int, every: int = 1) -> np.ndarray:
    """The plain Python RK4 a user would write around it: ω_r every ``every`` steps."""
    z = problem.z0.copy()
    out = []
    for k in range(n_steps):
        t = k * dt
        w = problem.config.wind(np.array([t, t + dt / 2, t + dt]))
        _, af, sf, ck = problem.inputs(t)
        af, sf, ck = af[:, 0], sf[:, 0], ck[:, 0]
        if k % every == 0:
            out.append(z[0])
        k1 = loop(z, w[0], af, sf, ck)
        k2 = loop(z + dt / 2 * k1, w[1], af, sf, ck)
        k3 = loop(z + dt / 2 * k2, w[1], af, sf, ck)
        k4 = loop(z + dt * k3, w[2], af, sf, ck)
        z = z + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return np.array(out)


__all__ = ["LambdifiedLoop", "rk4"]
