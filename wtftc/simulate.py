"""The closed loop: generated plant + Cp interpolant + generated controller, fixed-step RK4.

One CasADi function advances the whole loop by one RK4 step; ``mapaccum`` chains
``CHUNK`` steps into one compiled call (C, cached by hash like the generated code), and
the Python loop calls it chunk by chunk so that a progress bar moves and a divergence is
caught within one chunk. The controller sees only measured signals (rotor speed); the
plant state never enters it.

Per step k (from t_k to t_k + dt) the exogenous inputs are the wind at t_k, t_k + dt/2,
t_k + dt, and the fault inputs at t_k (held over the step). Outputs are reported at t_k
from the state z_k.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import casadi as ca
import numpy as np

from wtftc import layout as lay
from wtftc import spline
from wtftc.cp_table import CpTable, nrel5mw_cp_table
from wtftc.errors import ConfigError
from wtftc.generated import cache_dir, compile_cached, compiler, is_cached, load

PLANTS = {
    "nrel5mw": {"function": "turbine_nrel5mw", "states": "nrel5mw_states",
                "doc": "NREL 5-MW: two-mass drivetrain, generator torque, 2nd-order "
                       "limited actuators (default)"},
    "paper": {"function": "turbine_paper", "states": "plant_states",
              "doc": "eqs (1)-(4) as printed: UNLOADED, no generator torque "
                     "(paper-notes defect 3)"},
}
#: per-step outputs common to every controller, with units; then y_d and the controller's
#: four diagnostics (named in generated/layout.json, e.g. x̂1..x̂4 for the paper's design)
OUTPUTS = [
    ("omega_r", "rad/s"), ("theta_s", "rad"), ("omega_g_hss", "rad/s"),
    ("beta_1", "rad"), ("beta_2", "rad"), ("beta_3", "rad"),
    ("beta_meas_1", "rad"), ("beta_meas_2", "rad"), ("beta_meas_3", "rad"),
    ("u0", "rad"), ("v_1", "rad"), ("v_2", "rad"), ("v_3", "rad"),
    ("wind", "m/s"), ("tsr", "-"), ("cp", "-"), ("T_aero", "N m"), ("T_gen", "N m"),
    ("P_gen", "W"), ("dT_dbeta", "N m/rad"), ("y_d", "rad/s"),
    *[(f"fdi_latch_{j}", "-") for j in (1, 2, 3)],
    *[(f"fdi_rho_hat_{j}", "-") for j in (1, 2, 3)],
    *[(f"fdi_c_hat_{j}", "rad") for j in (1, 2, 3)],
    *[(f"fdi_residual_rms_{j}", "rad") for j in (1, 2, 3)],
    *[(f"fdi_omega_n_hat_{j}", "rad/s") for j in (1, 2, 3)],
    *[(f"fdi_zeta_hat_{j}", "-") for j in (1, 2, 3)],
]


def controllers() -> dict:
    """The registered controllers (derivation/controllers.py, via generated/layout.json)."""
    return lay.layout()["controllers"]


def output_spec(controller: str, fdi: bool = True) -> list[tuple[str, str]]:
    diag = controllers()[controller]["diag"]
    base = OUTPUTS if fdi else [o for o in OUTPUTS if not o[0].startswith("fdi_")]
    return base + [(n, "rad/s" if n == "xhat_1" else "-") for n in diag]


CHUNK = 1000  # RK4 steps per compiled call


class SimulationDiverged(RuntimeError):
    def __init__(self, t: float, state: dict, reason: str):
        self.t, self.state, self.reason = t, state, reason
        super().__init__(f"diverged at t = {t:.4f} s: {reason}")


@cache
def cp_interpolant(table: CpTable) -> ca.Function:
    """Cubic B-spline Cp(λ, β) on the table grid; inputs clipped to the grid (no extrapolation)."""
    f = ca.interpolant("cp_table", "bspline", [table.tsr, table.pitch_rad],
                       np.asarray(table.cp, dtype=float).ravel(order="F"))
    lam, b = ca.SX.sym("tsr"), ca.SX.sym("beta")
    lam_c = ca.fmin(ca.fmax(lam, float(table.tsr[0])), float(table.tsr[-1]))
    b_c = ca.fmin(ca.fmax(b, float(table.pitch_rad[0])), float(table.pitch_rad[-1]))
    return ca.Function("cp", [lam, b], [f(ca.vertcat(lam_c, b_c))], ["tsr", "beta"], ["cp"])


def cp_loop_function(table: CpTable) -> ca.Function:
    """Cp(λ, β) for the closed loop: :func:`cp_interpolant`'s spline, evaluated by
    uniform-grid lookup (wtftc.spline, about 6× cheaper in the compiled step; same values to
    rounding) when the table grid is uniform, as CasADi's interpolant otherwise."""
    ref = cp_interpolant(table)
    if spline.is_uniform(table.tsr) and spline.is_uniform(table.pitch_rad):
        return spline.fast_cp(ref, table.tsr, table.pitch_rad)
    return ref


def steady_pitch(cp_fn: ca.Function, omega_r: float, torque: float, wind: float,
                 air_density: float, rotor_radius: float,
                 bracket=(0.0, 0.5235987755982988)) -> float:  # 0..30°, the NREL table
    """Pitch at which the aerodynamic torque on the interpolant equals ``torque`` [rad].

    Bisection on the feathering side; the lower end of the bracket when even it gives less
    torque (below rated: the pitch rests at its limit).
    """
    lam = omega_r * rotor_radius / wind

    def excess(beta):
        c = float(cp_fn(lam, beta))
        return 0.5 * air_density * np.pi * rotor_radius**2 * wind**3 * c / omega_r - torque

    lo, hi = bracket
    if excess(lo) <= 0:
        return lo
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if excess(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def pitch_sensitivity_schedule(table: CpTable, p_turbine: np.ndarray) -> ca.Function:
    """The schedule of :func:`_pitch_sensitivity_schedule`, built once per table (by
    identity) and turbine parameters: every run and every trim needs it, and the bisections
    behind it take about 0.15 s."""
    return _schedule_function(*schedule_points(table, p_turbine))


def sched_loop_function(table: CpTable, p_turbine: np.ndarray) -> ca.Function:
    """:func:`pitch_sensitivity_schedule` for the closed loop: by uniform-grid lookup
    (wtftc.spline) where its breakpoints are uniform (the table's pitch grid), else CasADi's
    interpolant."""
    betas, grads = schedule_points(table, p_turbine)
    if spline.is_uniform(betas):
        return spline.fast_linear(betas, grads, "pitch_sensitivity", "beta", "dT_dbeta")
    return _schedule_function(betas, grads)


def schedule_points(table: CpTable, p_turbine: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Breakpoints (pitch [rad], ∂T_aero/∂β [N m/rad]) of the schedule, computed once per
    table (by identity) and turbine parameters."""
    return _schedule_points(table, tuple(float(v) for v in p_turbine))


@cache
def _schedule_points(table: CpTable, p_turbine: tuple) -> tuple[np.ndarray, np.ndarray]:
    """∂T_aero/∂β [N m/rad] against pitch on the steady above-rated operating curve.

    For each table pitch, the wind at which rated speed and rated torque balance (bisection
    on the Cp interpolant), then ∂T_aero/∂β there (the generated aero_torque_sensitivity,
    with ∂Cp/∂β by AD of the interpolant). Linear in between, held beyond the ends. This
    is the gain schedule of the PI baseline (and of the physical designs to come).
    """
    p_turbine = np.array(p_turbine)
    cp_fn = cp_interpolant(table)
    lam, b = ca.SX.sym("tsr"), ca.SX.sym("beta")
    dcp_fn = ca.Function("dcp", [lam, b], [ca.jacobian(cp_fn(lam, b), b)])
    sens = load("aero_torque_sensitivity")
    tp = dict(zip(lay.names("turbine_params"), p_turbine, strict=True))
    omega, torque, R = tp["omega_g_rated"], tp["gen_torque_rated"], tp["rotor_radius"]
    x6 = np.array([omega, 0, omega, 0, 0, 0], dtype=float)
    betas, grads = [], []
    for beta in table.pitch_rad:
        if beta < 0:
            continue
        x6[3:6] = beta

        def excess(v, beta=beta):
            return float(sens(x_plant=x6, wind=v, cp=cp_fn(omega * R / v, beta), dcp_dbeta=0,
                              p_turbine=p_turbine)["T_aero"]) - torque

        lo, hi = 3.0, 45.0
        if excess(lo) > 0 or excess(hi) < 0:
            continue
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if excess(mid) > 0 else (mid, hi)
        v = 0.5 * (lo + hi)
        g = float(sens(x_plant=x6, wind=v, cp=cp_fn(omega * R / v, beta),
                       dcp_dbeta=dcp_fn(omega * R / v, beta), p_turbine=p_turbine)["dT_dbeta"])
        betas.append(float(beta))
        grads.append(g)
    if len(betas) < 2:
        raise ConfigError("cp_table", table.source, "a table with an above-rated operating "
                          "range at rated speed and torque (none found)")
    return np.array(betas), np.array(grads)


def _schedule_function(betas: np.ndarray, grads: np.ndarray) -> ca.Function:
    interp = ca.interpolant("dTdbeta_table", "linear", [betas], grads)
    bb = ca.SX.sym("beta")
    bc = ca.fmin(ca.fmax(bb, betas[0]), betas[-1])
    return ca.Function("pitch_sensitivity", [bb], [interp(bc)], ["beta"], ["dT_dbeta"])


def _closed_loop_rhs(plant: str, table: CpTable, controller: str,
                     p_turbine_sched: np.ndarray, with_fdi: bool = True) -> ca.Function:
    """ż = f(z, wind, faults, reference, parameters): z = [plant states, controller states,
    FDI states].

    The controller sees only the measurements [ω_r, ω_g, β_meas,j] and the pitch-scheduled
    sensitivity; the plant state never enters it. ``with_fdi=False`` leaves the FDI out
    (no FDI states, no ``use_fdi`` input, no fdi_* outputs): the loop of cases 1-3 without
    the monitor, as the benchmark runs it.
    """
    reg = controllers()[controller]
    cp_fn = cp_loop_function(table)
    sched_fn = sched_loop_function(table, p_turbine_sched)
    pf = load(PLANTS[plant]["function"], "interpreted")
    cf = load(reg["function"], "interpreted")
    aero = load("aero_operating_point", "interpreted")
    fdi = load("fdi", "interpreted")
    n_p = len(lay.names(PLANTS[plant]["states"]))
    n_c = len(lay.names(reg["states"]))
    n_f = len(lay.names("fdi_states")) if with_fdi else 0
    z = ca.SX.sym("z", n_p + n_c + n_f)
    wind = ca.SX.sym("wind")
    af = ca.SX.sym("actuator_faults", len(lay.names("actuator_faults")))
    sf = ca.SX.sym("sensor_faults", len(lay.names("sensor_faults")))
    ck = ca.SX.sym("ctrl_fault", len(lay.names("fault_inputs")))
    yd = ca.SX.sym("yd", len(lay.names("reference")))
    pt = ca.SX.sym("p_turbine", len(lay.names("turbine_params")))
    pc = ca.SX.sym("p_ctrl", len(lay.names(reg["params"])))
    use_fdi = ca.SX.sym("use_fdi")  # 1: the accommodation is fed by the FDI, 0: by ctrl_fault
    xp, xc, xf = z[:n_p], z[n_p:n_p + n_c], z[n_p + n_c:]
    n_g = pt[lay.index("turbine_params", "gearbox_ratio")]
    op = aero(x_plant=xp[:6], wind=wind, p_turbine=pt)
    cp = cp_fn(op["tsr"], op["beta_mean"])
    sensors = pf(x_plant=xp, v=ca.DM.zeros(3), wind=wind, cp=cp, actuator_faults=af,
                 sensor_faults=sf, p_turbine=pt)["beta_meas"]  # independent of v
    meas = ca.vertcat(xp[0], xp[2] * n_g, sensors)
    sched = sched_fn(ca.sum1(sensors) / 3)
    if with_fdi:
        # the FDI's outputs depend on its states and the measurements only (no algebraic
        # loop)
        p_fdi = ca.DM(lay.defaults("fdi_params"))
        fd0 = fdi(x_fdi=xf, v=ca.DM.zeros(3), beta_meas=sensors, p_fdi=p_fdi)
        known = (1 - use_fdi) * ck + use_fdi * fd0["known_fault"]
    else:
        known = ck
    c = cf(x_ctrl=xc, meas=meas, yd=yd, sched=sched, p_ctrl=pc, known_fault=known)
    p = pf(x_plant=xp, v=c["v"], wind=wind, cp=cp, actuator_faults=af, sensor_faults=sf,
           p_turbine=pt)
    out = [xp[0], xp[1], xp[2] * n_g, xp[3:6], sensors, c["u0"], c["v"], wind, op["tsr"], cp,
           p["T_aero"], p["T_gen"], p["P_gen"], sched, yd[0]]
    names = ["z", "wind", "actuator_faults", "sensor_faults", "ctrl_fault", "yd", "p_turbine",
             "p_ctrl"]
    if with_fdi:
        fd = fdi(x_fdi=xf, v=c["v"], beta_meas=sensors, p_fdi=p_fdi)
        zdot = ca.vertcat(p["x_plant_dot"], c["x_ctrl_dot"], fd["x_fdi_dot"])
        out += [fd0["latch"], fd0["rho_hat"], fd0["c_hat"], fd0["residual_rms"],
                fd0["omega_n_hat"], fd0["zeta_hat"]]
        ins = [z, wind, af, sf, ck, yd, pt, pc, use_fdi]
        names.append("use_fdi")
    else:
        zdot = ca.vertcat(p["x_plant_dot"], c["x_ctrl_dot"])
        ins = [z, wind, af, sf, ck, yd, pt, pc]
    out = ca.vertcat(*out, c["diag"])
    assert out.numel() == len(output_spec(controller, with_fdi))
    # one pass of common-subexpression elimination over the assembled loop: the plant, the
    # controller and the FDI share the measured quantities and the aerodynamics
    zdot, out = ca.cse([zdot, out])
    return ca.Function("rhs", ins, [zdot, out], names, ["z_dot", "out"])


def rk4_step(rhs: ca.Function) -> ca.Function:
    """Classical RK4 over one step dt (Kutta 1901), the exogenous input (input 1 of rhs, the
    wind) at t, t + dt/2, t + dt; the other inputs held over the step."""
    z = ca.MX.sym("z", rhs.size1_in(0))
    w3 = ca.MX.sym("wind3", 3)
    others = [ca.MX.sym(rhs.name_in(k), rhs.sparsity_in(k)) for k in range(2, rhs.n_in())]
    dt = ca.MX.sym("dt")
    first = rhs(z, w3[0], *others)
    k1, out = first[0], first[1]  # ż and the reported outputs at the start of the step
    k2 = rhs(z + dt / 2 * k1, w3[1], *others)[0]
    k3 = rhs(z + dt / 2 * k2, w3[1], *others)[0]
    k4 = rhs(z + dt * k3, w3[2], *others)[0]
    z_next = z + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("rk4_step", [z, w3, *others, dt], [z_next, out],
                       ["z", "wind3", *[rhs.name_in(k) for k in range(2, rhs.n_in())], "dt"],
                       ["z_next", "out"])


#: flags of the closed-loop chunks (the verified generated functions keep CFLAGS):
#: -fno-semantic-interposition lets gcc inline CasADi's helpers (fmin, fmax, sq) instead of
#: calling them through the PLT; -fno-math-errno lets it treat sqrt, exp, ... as pure
#: functions (inline sqrtsd, no errno bookkeeping): 1.4-1.9× on the paper's loop. Both are
#: bit-identical to plain -O2 (docs/performance.md, tests/test_bench.py)
LOOP_CFLAGS = ("-O2", "-fno-semantic-interposition", "-fno-math-errno", "-fPIC", "-shared")
#: opt-in: -ffast-math also reassociates and assumes no NaN/inf: 1.05-1.2× more on the
#: loops (docs/performance.md); results differ at 1e-12..1e-9 relative (not bit-identical
#: to the default)
FAST_MATH_CFLAGS = ("-O2", "-fno-semantic-interposition", "-ffast-math", "-fPIC", "-shared")


def compiled(f: ca.Function, label: str, flags: tuple[str, ...] = LOOP_CFLAGS,
             quiet: bool = False) -> ca.Function:
    """f as generated C, compiled once and cached (or f itself with no compiler)."""
    return _compile_function(f, label, flags, quiet)


def _compile_function(f: ca.Function, label: str, flags: tuple[str, ...] = LOOP_CFLAGS,
                      quiet: bool = False) -> ca.Function:
    """Generate C for f and load it through the loader's hash-keyed compile cache."""
    cc = compiler()
    if cc is None:
        return f
    with tempfile.TemporaryDirectory() as tmp:
        cname = f"{label}.c"
        cg = ca.CodeGenerator(cname, {"with_header": False})
        cg.add(f)
        cg.generate(tmp + os.sep)
        c_path = Path(tmp, cname)
        if not quiet and not is_cached(c_path, cc, flags):
            print(f"  compiling the {label} loop (once; cached in {cache_dir()}) ...",
                  file=sys.stderr, flush=True)
        so = compile_cached(c_path, cc, flags)
    return ca.external(f.name(), str(so))


@cache
def chunk_function(plant: str, controller: str, table_key: str, table: CpTable | None = None,
                   sched_params: tuple | None = None, n: int = CHUNK,
                   fdi: bool = True, fast_math: bool = False) -> ca.Function:
    """``n`` RK4 steps in one compiled call (mapaccum over the step); ``fast_math``: compiled
    with FAST_MATH_CFLAGS instead of LOOP_CFLAGS."""
    step = rk4_step(rhs_function(plant, controller, table_key, table, sched_params, fdi))
    tag = "" if fdi else "_nofdi"
    chunk = step.mapaccum(f"loop_{plant}_{controller}{tag}", n)
    return _compile_function(chunk, f"loop_{plant}_{controller}{tag}_{table_key}_{n}",
                             FAST_MATH_CFLAGS if fast_math else LOOP_CFLAGS)


@cache
def rhs_function(plant: str, controller: str, table_key: str, table: CpTable | None = None,
                 sched_params: tuple | None = None, fdi: bool = True) -> ca.Function:
    """The closed-loop right-hand side; sched_params: the turbine parameters (a tuple)
    the pitch-sensitivity schedule is built for (default: the layout's); fdi=False: without
    the FDI (see :func:`_closed_loop_rhs`)."""
    pt = np.array(sched_params) if sched_params else lay.vector("turbine_params")
    return _closed_loop_rhs(plant, table or nrel5mw_cp_table(), controller, pt, fdi)


class Buffered:
    """A CasADi function called through ``Function.buffer()`` on NumPy arrays it owns.

    Skips the DM conversion at the Python boundary (measured at about 65 ns an element:
    2 µs a step for the loop's outputs). Every array bound to the buffer stays referenced
    by this object for its whole life (a dropped one would corrupt the heap); calls copy
    the inputs in and return copies of the results, shaped as CasADi's (rows, columns).
    """

    def __init__(self, f: ca.Function):
        self.f = f
        self._buf, self._trigger = f.buffer()
        self._in = [np.zeros((f.size2_in(i), f.size1_in(i))) for i in range(f.n_in())]
        self._out = [np.zeros((f.size2_out(i), f.size1_out(i))) for i in range(f.n_out())]
        for i, a in enumerate(self._in):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self._out):
            self._buf.set_res(i, memoryview(r))

    def put(self, i: int, value, run: int = 0, n_runs: int = 1) -> None:
        """Write input i of run ``run`` (of n_runs side by side) in place: ``value`` is
        (rows, columns) of that run, or one column (rows,) held over its columns."""
        a = self._in[i]
        w = a.shape[0] // n_runs
        seg = a[run * w:(run + 1) * w]
        v = np.asarray(value, dtype=float)
        if v.ndim == 2 and v.shape[1] > 1:
            seg[...] = v.T
        else:
            seg[...] = v.reshape(1, -1)

    def evaluate(self) -> list[np.ndarray]:
        """Evaluate on the inputs in place; results as (rows, columns) views of the
        buffers, valid until the next evaluation."""
        self._trigger()
        return [r.T for r in self._out]

    def __call__(self, *args, copy: bool = True) -> list[np.ndarray]:
        """Results as (rows, columns) arrays; ``copy=False``: views of the buffers, valid
        until the next call (no copy of what the caller does not keep)."""
        for a, x in zip(self._in, args, strict=True):
            x = np.asarray(x, dtype=float)
            cols, rows = a.shape
            k = x.size // rows if rows else 0
            if 0 < k < cols and x.size == rows * k and cols % k == 0:
                # k columns each repeated cols/k times, as a call of a mapped function
                # broadcasts an input given once per run (k = 1: once for all)
                a[...] = np.repeat(x.reshape((rows, k), order="F"), cols // k, axis=1).T
            else:
                a[...] = x.reshape((rows, cols), order="F").T
        self._trigger()
        return [r.T.copy() for r in self._out] if copy else [r.T for r in self._out]


@dataclass
class Result:
    t: np.ndarray
    outputs: np.ndarray  # (N, len(OUTPUTS))
    z_final: np.ndarray
    diverged: dict | None
    wall_s: float
    steps: int
    config: dict = field(default_factory=dict)
    z: np.ndarray | None = None  # full state trajectory at the output times (N, n_z)
    schedule: object = None  # the plant's fault schedule (wtftc.faults.Schedule), if any

    names: list = field(default_factory=list)  # output names, in column order

    def column(self, name: str) -> np.ndarray:
        return self.outputs[:, self.names.index(name)]


def state_names(plant: str, controller: str = "paper") -> list[str]:
    return (lay.names(PLANTS[plant]["states"]) + lay.names(controllers()[controller]["states"])
            + lay.names("fdi_states"))


@dataclass
class Run:
    """The per-run inputs of one closed loop in a batch (see :func:`run_loops`)."""

    z0: np.ndarray
    wind: object  # wind(t) -> m/s
    schedule: object = None  # the plant's faults (wtftc.faults.Schedule) or None
    ctrl_schedule: object = None  # the faults eq (49) is told, or None (nominal)
    yd: np.ndarray | None = None  # reference and its derivatives
    p_ctrl: np.ndarray | None = None
    use_fdi: bool = False


def run_loop(plant: str, controller: str, z0: np.ndarray, wind, schedule, ctrl_schedule,
             yd: np.ndarray, p_turbine: np.ndarray, p_ctrl: np.ndarray, t_final: float,
             dt: float, table: CpTable | None = None, table_key: str = "nrel5mw",
             decimate: int = 1, progress: bool = True, keep_states: bool = False,
             use_fdi: bool = False, fdi: bool = True, fast_math: bool = False) -> Result:
    """Integrate from t = 0 to t_final with fixed dt; outputs every ``decimate`` steps.

    ``schedule`` gives the plant's fault inputs, ``ctrl_schedule`` those eq (49) is told
    (a :class:`wtftc.faults.Schedule`, or None for a fault-free controller).
    """
    run = Run(z0, wind, schedule, ctrl_schedule, yd, p_ctrl, use_fdi)
    return run_loops(plant, controller, [run], p_turbine, t_final, dt, table, table_key,
                     decimate, progress, keep_states, fdi, fast_math=fast_math)[0]


@cache
def _mapped(f: ca.Function, n_runs: int, threads: int) -> ca.Function:
    """f evaluated for n_runs independent runs, side by side, on ``threads`` threads."""
    if n_runs == 1:
        return f
    return f.map(n_runs, "thread", threads) if threads > 1 else f.map(n_runs, "serial")


def run_loops(plant: str, controller: str, runs: list[Run], p_turbine: np.ndarray,
              t_final: float, dt: float, table: CpTable | None = None,
              table_key: str = "nrel5mw", decimate: int = 1, progress: bool = True,
              keep_states: bool = False, fdi: bool = True, threads: int = 1,
              fast_math: bool = False) -> list[Result]:
    """Integrate independent runs of one loop (same plant, controller, turbine, dt) together:
    each compiled chunk call advances all of them (``Function.map``, on ``threads`` threads).

    Every run gets the numbers it gets alone (the same compiled step, bit for bit); a run
    that diverges is recorded and frozen while the others go on.
    """
    n_steps = int(round(t_final / dt))
    f = chunk_function(plant, controller, table_key, table, tuple(p_turbine), fdi=fdi,
                       fast_math=fast_math)
    n_runs = len(runs)
    fm = _mapped(f, n_runs, threads)
    n_c = f.size2_out(1)
    n_z = f.size1_in(0)
    names = state_names(plant, controller)[:n_z]
    call = Buffered(fm)
    z = np.column_stack([np.asarray(r.z0, dtype=float) for r in runs])  # (n_z, n_runs)
    outs = [[] for _ in runs]
    ts = [[] for _ in runs]
    zs = [[] for _ in runs]
    diverged: list[dict | None] = [None] * n_runs
    steps = [0] * n_runs
    events = sorted({int(round(e / dt)) for r in runs if r.schedule
                     for e in r.schedule.events()})
    nominal_ctrl = lay.defaults("fault_inputs")
    nominal_act = lay.defaults("actuator_faults")[:, None]
    nominal_sen = lay.defaults("sensor_faults")[:, None]
    # the run-independent inputs are written once
    assert f.name_in() == ["z", "wind3", "actuator_faults", "sensor_faults", "ctrl_fault", "yd",
                           "p_turbine", "p_ctrl", *(["use_fdi"] if fdi else []), "dt"], \
        f.name_in()
    for b, r in enumerate(runs):
        call.put(5, r.yd, b, n_runs)
        call.put(6, p_turbine, b, n_runs)
        call.put(7, r.p_ctrl, b, n_runs)
        if fdi:
            call.put(8, [float(r.use_fdi)], b, n_runs)
        call.put(9 if fdi else 8, [dt], b, n_runs)
    out_names = [n for n, _ in output_spec(controller, fdi)]
    k = 0
    t0 = time.perf_counter()
    last_print = t0
    while k < n_steps and not all(diverged):
        # bind "lock wherever the blade is" at its onset step, from the current state
        for b, r in enumerate(runs):
            if r.schedule and k in {int(round(e / dt)) for e in r.schedule.events()}:
                r.schedule.bind_current_angles(k * dt, z[3:6, b], dt)
                if r.ctrl_schedule is not None:
                    r.ctrl_schedule.bind_current_angles(k * dt, z[3:6, b], dt)
        stop = min([n_steps, k + n_c] + [e for e in events if e > k])
        m = stop - k
        tk = (k + np.arange(n_c)) * dt
        # faults constant over the chunk's steps (the usual case): one column, held
        held = all(s is None or s.constant_between(tk[0], tk[m - 1])
                   for r in runs for s in (r.schedule, r.ctrl_schedule))
        tf = tk[:1] if held else tk
        call.put(0, z)
        for b, r in enumerate(runs):
            call.put(1, np.vstack([r.wind(tk), r.wind(tk + dt / 2), r.wind(tk + dt)]), b,
                     n_runs)
            s = r.schedule
            call.put(2, s.actuator(tf) if s else nominal_act, b, n_runs)
            call.put(3, s.sensor(tf) if s else nominal_sen, b, n_runs)
            call.put(4, r.ctrl_schedule.actuator(tf)[:len(nominal_ctrl)] if r.ctrl_schedule
                     else nominal_ctrl, b, n_runs)
        zz_all, oo_all = call.evaluate()
        first = (-k) % decimate  # the first step of this chunk on the output grid
        for b in range(n_runs):
            if diverged[b]:
                continue
            zz = zz_all[:, b * n_c:b * n_c + m]  # views, valid until the next call
            oo = oo_all[:, b * n_c:b * n_c + m]
            mb = m
            z_prev = z[:, b].copy()
            if not (np.abs(zz).max() <= 1e8 and np.isfinite(oo).all()):
                i, diverged[b] = divergence(zz, oo, z_prev, names, out_names, k, dt)
                mb = i + 1
            outs[b].append(oo[:, first:mb:decimate].T.copy())
            ts[b].append(np.arange(k + first, k + mb, decimate) * dt)
            if keep_states:
                # the state before step i is z (i = 0) or zz[:, i-1]
                z_before = np.hstack([z_prev[:, None], zz[:, :mb - 1]])
                zs[b].append(z_before[:, first::decimate].T.copy())
            steps[b] = k + mb
            # a diverged run is frozen at its last finite state (its column computes on,
            # unread, so that the batch keeps its shape)
            if diverged[b]:
                z[:, b] = zz[:, mb - 2] if mb > 1 else z_prev
            else:
                z[:, b] = zz[:, mb - 1]
        k = stop
        now = time.perf_counter()
        if progress and now - last_print > 0.5:
            _progress(k, n_steps, dt, now - t0, runs=n_runs)
            last_print = now
    wall = time.perf_counter() - t0
    if progress:
        _progress(k, n_steps, dt, wall, end=True, runs=n_runs)
    return [Result(t=np.concatenate(ts[b]), outputs=np.vstack(outs[b]), z_final=z[:, b].copy(),
                   diverged=diverged[b], wall_s=wall, steps=steps[b],
                   z=np.vstack(zs[b]) if keep_states else None, names=out_names)
            for b in range(n_runs)]


def divergence(zz: np.ndarray, oo: np.ndarray, z_prev: np.ndarray, names: list[str],
               out_names: list[str], k: int, dt: float) -> tuple[int, dict]:
    """The first step of a chunk that blew up, and its record.

    Column i of zz is the state after step k + i, column i of oo the outputs at the state
    before it (z_prev for i = 0). Step i is bad when that state is non-finite or beyond
    1e8, or when the outputs at its start are non-finite (the control law can fail before
    any state does: a state that is still finite then carries the NaN into the next step).
    The record names every quantity that failed, the time at the end of the step, and the
    last finite state.
    """
    bad = ~np.all(np.isfinite(oo), axis=0) | ~np.all(np.isfinite(zz), axis=0)
    bad |= np.any(np.abs(zz) > 1e8, axis=0)
    i = int(np.argmax(bad))
    blew = [n for n, a in zip(names, zz[:, i], strict=True)
            if not np.isfinite(a) or abs(a) > 1e8]
    nan_out = [n for n, a in zip(out_names, oo[:, i], strict=True) if not np.isfinite(a)]
    parts = []
    if blew:
        parts.append("non-finite or |state| > 1e8 in " + ", ".join(blew[:8])
                     + (" ..." if len(blew) > 8 else ""))
    if nan_out:
        parts.append("non-finite outputs " + ", ".join(nan_out[:8])
                     + (" ..." if len(nan_out) > 8 else ""))
    before = zz[:, i - 1] if i > 0 else z_prev
    return i, {"t_s": float((k + i + 1) * dt), "reason": "; ".join(parts),
               "last_finite_state": {n: float(a) for n, a in zip(names, before, strict=True)}}


def _progress(k: int, n: int, dt: float, wall: float, end: bool = False, runs: int = 1,
              ) -> None:
    """A progress bar on a terminal; one summary line when stderr is a file or a pipe.
    ``runs``: a batch advancing that many runs together (the rate counts all of them)."""
    rate = runs * k * dt / max(wall, 1e-9)
    what = f"{runs} runs × " if runs > 1 else ""
    if not sys.stderr.isatty():
        if end:
            print(f"    {what}{k * dt:.1f} s simulated in {wall:.1f} s ({rate:.0f}× real time)",
                  file=sys.stderr, flush=True)
        return
    width = 30
    done = int(width * k / max(n, 1))
    print(f"\r    [{'#' * done}{'.' * (width - done)}] {what}{k * dt:7.1f}/{n * dt:.1f} s "
          f"simulated, {rate:6.0f}× real time", end="\n" if end else "", file=sys.stderr,
          flush=True)


def stability_limit(plant: str, controller: str, z0, wind0: float, yd, p_turbine, p_ctrl,
                    table: CpTable | None = None, table_key: str = "nrel5mw") -> float:
    """Largest |eigenvalue| of the closed-loop Jacobian at z0 (RK4: stable for |λ dt| < 2.78)."""
    jac = _jacobian_function(plant, controller, table_key, table, tuple(p_turbine))
    args = [lay.defaults("actuator_faults"), lay.defaults("sensor_faults"),
            lay.defaults("fault_inputs"), yd, p_turbine, p_ctrl, 0.0]
    eig = np.linalg.eigvals(np.array(jac(z0, wind0, *args)))
    return float(np.max(np.abs(eig)))


@cache
def _jacobian_function(plant: str, controller: str, table_key: str, table: CpTable | None,
                       sched_params: tuple) -> ca.Function:
    """∂ż/∂z of the closed loop, built once per loop."""
    rhs = rhs_function(plant, controller, table_key, table, sched_params)
    ins = [ca.SX.sym(rhs.name_in(i), rhs.sparsity_in(i)) for i in range(rhs.n_in())]
    return ca.Function("closed_loop_jacobian", ins, [ca.jacobian(rhs(*ins)[0], ins[0])])


#: beyond this step the paper controller's start-up transient is not resolved: measured
#: errors of order 1 at dt = 4e-3 s against DOP853 (docs/verification.md, section 6)
DT_ACCURATE_S = 1e-3


def check_dt(dt: float, lam_max: float) -> None:
    """Refuse a dt beyond RK4's stability limit at the initial state, with the reason;
    warn (stderr) beyond the step at which the integration was verified accurate."""
    if not (np.isfinite(dt) and dt > 0):
        raise ConfigError("dt_s", dt, "a positive number of seconds")
    if dt > DT_ACCURATE_S * (1 + 1e-9):
        print(f"  warning: dt_s = {dt:g} s is larger than {DT_ACCURATE_S:g} s, the step at "
              "which the closed loop's RK4 integration is verified accurate "
              "(docs/verification.md); results may be inaccurate", file=sys.stderr)
    limit = 2.78 / lam_max
    if dt > limit:
        raise ConfigError("dt_s", dt, f"at most {limit:.3g} s: the fastest mode of the "
                          f"closed loop at the initial state has |λ| = {lam_max:.4g} 1/s and "
                          "RK4 is stable only for |λ·dt| < 2.78")
