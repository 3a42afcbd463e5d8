"""The paper's three cases, run configurations, trim, metrics and output files.

Case 1: no fault. Case 2: a pitch actuator fault, the controller unaware. Case 3: the same
fault with eq (49) given the fault parameters ("known fault": no detection yet). Default
fault (the paper's Fig. 6 gives no numbers): blade 1 locked where it is, blades 2-3 at
ρ = 0.5, all from t = 20 s.
"""

from __future__ import annotations

import copy
import hashlib
import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from wtftc import layout as lay
from wtftc import simulate as sim
from wtftc.errors import ConfigError
from wtftc.faults import DEFAULT_FAULT, HYDRAULIC, Schedule, parse_faults
from wtftc.wind import wind_from_config

CASES = {1: "no fault", 2: "fault, controller unaware", 3: "fault known to eq (49)",
         4: "fault detected and estimated by wtftc's FDI"}
TOP_KEYS = {"case", "plant", "controller", "t_final_s", "dt_s", "seed", "output_rate_hz",
            "control_sign", "reference_rad_s", "cp_table", "wind", "fault", "controller_params",
            "turbine_params", "initial", "label"}
DEFAULTS = {
    "case": 1, "plant": "nrel5mw", "controller": "paper", "t_final_s": 60.0, "dt_s": 1e-3,
    "seed": 0, "output_rate_hz": 50.0, "control_sign": -1,
    "wind": {"kind": "paper_random"},
}
#: the paper's reference: "the rotor speed to the 1.27 rad/s value" (Section 5)
PAPER_REFERENCE = 1.27


@dataclass
class RunConfig:
    raw: dict  # the validated configuration, all defaults filled in (saved with results)
    case: int
    plant: str
    controller: str
    t_final: float
    dt: float
    seed: int
    decimate: int
    reference: float
    p_turbine: np.ndarray
    p_ctrl: np.ndarray
    wind: object
    faults: list = field(default_factory=list)
    omega_offset: float = 0.0
    table: object = None
    table_key: str = "nrel5mw"

    @property
    def uses_rosco(self) -> bool:
        return self.raw["controller"] == "rosco"

    @property
    def label(self) -> str:
        return self.raw.get("label") or f"{self.plant}_case{self.case}"


def _number(cfg, key, lo=None, hi=None, integer=False):
    val = cfg[key]
    ok = isinstance(val, int) if integer else isinstance(val, int | float)
    if isinstance(val, bool) or not ok or not np.isfinite(val):
        raise ConfigError(key, val, "an integer" if integer else "a finite number")
    if (lo is not None and val <= lo) or (hi is not None and val > hi):
        raise ConfigError(key, val, f"a number in ({lo}, {hi}]")
    return val


def load_toml(path: Path) -> dict:
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError("config", str(path), "an existing TOML file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError("config", str(path), f"valid TOML ({exc})") from None


def make_config(cfg: dict | None = None) -> RunConfig:
    """Validate a configuration (as from TOML or the CLI) and fill in the defaults."""
    cfg = copy.deepcopy(cfg or {})
    for key in cfg:
        if key not in TOP_KEYS:
            raise ConfigError(key, cfg[key], "a known key: " + ", ".join(sorted(TOP_KEYS)))
    raw = {**copy.deepcopy(DEFAULTS), **cfg}
    case = raw["case"]
    if case not in CASES or isinstance(case, bool):
        raise ConfigError("case", case, "1 (no fault), 2 (fault, controller unaware), "
                          "3 (fault known to eq 49) or 4 (fault detected by wtftc's FDI)")
    if raw["plant"] not in sim.PLANTS:
        raise ConfigError("plant", raw["plant"], "one of " + ", ".join(
            f"{k} ({v['doc']})" for k, v in sim.PLANTS.items()))
    regs = {k: v for k, v in sim.controllers().items() if k != "external"}
    use_rosco = raw["controller"] == "rosco"
    if raw["controller"] not in regs and not use_rosco:
        raise ConfigError("controller", raw["controller"], "one of " + ", ".join(
            [f"{k} ({v['doc']})" for k, v in regs.items()]
            + ["rosco (NREL's ROSCO through its ControllerInterface; optional extra)"]))
    if use_rosco:
        from wtftc import rosco

        reason = rosco.available()
        if reason:
            raise ConfigError("controller", "rosco", reason)
    internal = "external" if use_rosco else raw["controller"]
    ctrl_group = sim.controllers()[internal]["params"]
    t_final = float(_number(raw, "t_final_s", lo=0, hi=36000))
    # the upper bound is only a sanity cap: the real limit is checked against the closed
    # loop's fastest mode before the run (simulate.check_dt)
    dt = float(_number(raw, "dt_s", lo=0, hi=10.0))
    if dt > t_final:
        raise ConfigError("dt_s", dt, f"at most t_final_s = {t_final}")
    seed = _number(raw, "seed", lo=-1, integer=True)
    rate = float(_number(raw, "output_rate_hz", lo=0, hi=1e6))
    decimate = max(1, int(round(1.0 / (rate * dt))))
    if abs(decimate * dt * rate - 1.0) > 1e-6 and decimate > 1:
        raise ConfigError("output_rate_hz", rate, f"a rate whose interval is a whole number of "
                          f"steps of dt_s = {dt:g} s (e.g. {1.0 / (decimate * dt):.6g} Hz)")
    sign = raw["control_sign"]
    if sign not in (-1, 1) or isinstance(sign, bool):
        raise ConfigError("control_sign", sign, "-1 (corrected, default) or +1 (as written, "
                          "diverges: paper-notes defect 2)")
    ref = raw.get("reference_rad_s", PAPER_REFERENCE if raw["plant"] == "paper"
                  else lay.vector("turbine_params")[lay.index("turbine_params", "omega_g_rated")])
    raw["reference_rad_s"] = float(ref)
    ref = float(_number(raw, "reference_rad_s", lo=0, hi=10))
    vectors = {}
    signed = "control_sign" in lay.names(ctrl_group)
    for key, group, extra in (
            ("controller_params", ctrl_group, {"control_sign": sign} if signed else {}),
            ("turbine_params", "turbine_params", {})):
        over = raw.get(key, {})
        if not isinstance(over, dict):
            raise ConfigError(key, over, f"a table of {group} (see generated/layout.json)")
        if "control_sign" in over:
            raise ConfigError(f"{key}.control_sign", over["control_sign"],
                              "set control_sign at the top level (or --sign)")
        try:
            vectors[key] = lay.vector(group, {**over, **extra})
        except ValueError as exc:
            raise ConfigError(key, over, str(exc).split(": ", 1)[-1]) from None
    p_ctrl, p_turbine = vectors["controller_params"], vectors["turbine_params"]
    for flag in ("gen_torque_law", "gen_constant_power"):
        val = p_turbine[lay.index("turbine_params", flag)]
        if val not in (0.0, 1.0):
            raise ConfigError(f"turbine_params.{flag}", float(val), "0 or 1 (docs/running.md)")
    if not isinstance(raw["wind"], dict):
        raise ConfigError("wind", raw["wind"], "a table with kind = ...")
    wind = wind_from_config(raw["wind"], t_final=t_final, seed=seed)
    if case == 1:
        if raw.get("fault"):
            raise ConfigError("fault", raw["fault"], "no fault in case 1 (use case 2 or 3)")
        faults = []
    else:
        raw.setdefault("fault", copy.deepcopy(DEFAULT_FAULT))
        faults = parse_faults(raw["fault"])
        for k, f in enumerate(faults):
            if f.onset_s >= t_final:
                raise ConfigError(f"fault[{k}].onset_s", f.onset_s,
                                  f"a time before t_final_s = {t_final:g} s")
    init = raw.get("initial", {})
    if not isinstance(init, dict) or set(init) - {"omega_r_offset_rad_s"}:
        raise ConfigError("initial", init, "a table with omega_r_offset_rad_s")
    offset = float(init.get("omega_r_offset_rad_s", 0.0))
    table, table_key = None, "nrel5mw"
    if raw.get("cp_table"):
        from wtftc.cp_table import read_cp_table

        table = read_cp_table(Path(raw["cp_table"]))
        table_key = hashlib.sha256(Path(raw["cp_table"]).read_bytes()).hexdigest()[:12]
    return RunConfig(raw=raw, case=case, plant=raw["plant"], controller=internal,
                     t_final=t_final, dt=dt, seed=seed, decimate=decimate, reference=ref,
                     p_turbine=p_turbine, p_ctrl=p_ctrl, wind=wind, faults=faults,
                     omega_offset=offset, table=table, table_key=table_key)


def trim(rc: RunConfig) -> np.ndarray:
    """Initial state: rated speed (plus offset), drivetrain at rest under rated torque,
    blades at the pitch that balances it at the initial wind; observer at the chain state.

    The paper plant has no generator torque: its balance is T_aero = 0 (paper-notes defect 3).
    """
    from wtftc.cp_table import nrel5mw_cp_table

    table = rc.table or nrel5mw_cp_table()
    cp = sim.cp_interpolant(table)
    pt = rc.p_turbine
    get = {n: pt[k] for k, n in enumerate(lay.names("turbine_params"))}
    omega = get["omega_g_rated"] + rc.omega_offset
    loaded = rc.plant == "nrel5mw"
    torque = get["gen_torque_rated"] if loaded else 0.0
    beta0 = sim.steady_pitch(cp, omega, torque, float(rc.wind(0.0)), get["air_density"],
                             get["rotor_radius"])
    theta_s = torque / get["k_s"]
    xp = [omega, theta_s, omega, beta0, beta0, beta0]
    if loaded:
        xp += [0.0, 0.0, 0.0]
    # the controller starts from what it measures (init_<controller>, generated)
    from wtftc.generated import load

    reg = sim.controllers()[rc.controller]
    meas0 = np.array([omega, omega * get["gearbox_ratio"], beta0, beta0, beta0])
    sched0 = float(sim.pitch_sensitivity_schedule(table, rc.p_turbine)(beta0))
    xc = np.array(load(reg["init"])(meas=meas0, sched=sched0, p_ctrl=rc.p_ctrl)["x_ctrl0"])
    xc = xc.ravel()
    xf = np.array(load("init_fdi")(beta_meas=meas0[2:])["x_fdi0"]).ravel()
    return np.concatenate([xp, xc, xf])


def run(rc: RunConfig, progress: bool = True, keep_states: bool = False) -> sim.Result:
    if rc.uses_rosco:
        from wtftc import rosco

        if rc.case in (3, 4):
            raise ConfigError("case", rc.case, "1 or 2 with controller = rosco (ROSCO has no "
                              "fault accommodation)")
        res = rosco.run(rc, progress=progress)
        res.config = {**rc.raw, "wind_resolved": rc.wind.describe(),
                      "fault_resolved": res.schedule.describe() if res.schedule else [],
                      "rosco": {"version": rosco.ROSCO_VERSION,
                                "control_dt_s": rosco.CONTROL_DT}}
        return res
    return run_batch([rc], progress=progress, keep_states=keep_states)[0]


def run_batch(rcs: list[RunConfig], threads: int = 1, progress: bool = True,
              keep_states: bool = False) -> list[sim.Result]:
    """Many independent runs of one loop in one compiled call per chunk (the Python API for
    seeds and fault cases): the same results as :func:`run` on each, bit for bit.

    The runs must share what the compiled loop is built for: plant, controller, Cp table,
    turbine parameters, dt, t_final and output decimation; wind, faults, seed, case and
    controller gains may differ. ``threads``: CasADi threads over the runs (use the cores).
    """
    if not rcs:
        raise ConfigError("runs", "[]", "at least one run configuration")
    if threads < 1:
        raise ConfigError("threads", threads, "a positive integer")
    first = rcs[0]
    for i, rc in enumerate(rcs):
        if rc.uses_rosco:
            raise ConfigError(f"runs[{i}].controller", rc.controller,
                              "a generated controller (ROSCO runs one at a time)")
        for key in ("plant", "controller", "table_key", "dt", "t_final", "decimate"):
            if getattr(rc, key) != getattr(first, key):
                raise ConfigError(f"runs[{i}].{key}", getattr(rc, key),
                                  f"{getattr(first, key)!r}, as in runs[0]: a batch shares "
                                  "one compiled loop")
        if not np.array_equal(rc.p_turbine, first.p_turbine):
            raise ConfigError(f"runs[{i}].turbine", "different parameters",
                              "the turbine parameters of runs[0]")
    runs, schedules, stab = [], [], []
    for rc in rcs:
        z0 = trim(rc)
        yd = np.zeros(len(lay.names("reference")))
        yd[0] = rc.reference
        lam = sim.stability_limit(rc.plant, rc.controller, z0, float(rc.wind(0.0)), yd,
                                  rc.p_turbine, rc.p_ctrl, rc.table, rc.table_key)
        sim.check_dt(rc.dt, lam)
        schedule = Schedule(copy.deepcopy(rc.faults)) if rc.faults else None
        ctrl_schedule = Schedule(copy.deepcopy(rc.faults)) if rc.case == 3 else None
        runs.append(sim.Run(z0, rc.wind, schedule, ctrl_schedule, yd, rc.p_ctrl,
                            rc.case == 4))
        schedules.append(schedule)
        stab.append(lam)
    results = sim.run_loops(first.plant, first.controller, runs, first.p_turbine,
                            first.t_final, first.dt, first.table, first.table_key,
                            decimate=first.decimate, progress=progress,
                            keep_states=keep_states, threads=threads)
    for rc, res, schedule, lam in zip(rcs, results, schedules, stab, strict=True):
        res.config = {**rc.raw, "wind_resolved": rc.wind.describe(),
                      "fault_resolved": schedule.describe() if schedule else [],
                      "stability": {"max_abs_eigenvalue_1_s": lam, "dt_limit_s": 2.78 / lam}}
        res.schedule = schedule
    return results


def metrics(rc: RunConfig, res: sim.Result) -> dict:
    """Regulation and actuation figures of one run (units in every key)."""
    t = res.t
    w = res.column("omega_r")
    e = w - rc.reference
    beta = np.column_stack([res.column(f"beta_{j}") for j in (1, 2, 3)])
    dt_out = rc.dt * rc.decimate
    rate = np.gradient(beta, dt_out, axis=0) if len(t) > 2 else np.zeros_like(beta)
    # settled: inside ±1 % from this time to the end, and for at least the last 20 % of
    # the run (a run that merely ends inside the band has not settled)
    band = 0.01 * rc.reference
    outside = np.nonzero(np.abs(e) > band)[0]
    t_in = float(t[outside[-1] + 1]) if len(outside) and outside[-1] + 1 < len(t) else (
        0.0 if not len(outside) else None)
    settled = t_in if t_in is not None and t_in <= t[-1] - 0.2 * (t[-1] - t[0]) else None
    onset = min((f.onset_s for f in rc.faults), default=None)
    post = t >= onset if onset is not None else np.zeros_like(t, dtype=bool)
    eta = rc.p_turbine[lay.index("turbine_params", "gen_efficiency")]
    rated = rc.p_turbine[lay.index("turbine_params", "omega_g_rated")]
    m = {
        "label": rc.label, "case": rc.case, "case_doc": CASES[rc.case], "plant": rc.plant,
        "fdi": fdi_report(rc, res),
        "controller": rc.raw["controller"], "control_sign": rc.raw["control_sign"],
        "reference_rad_s": rc.reference,
        "rms_speed_error_rad_s": float(np.sqrt(np.mean(e**2))),
        "max_abs_speed_error_rad_s": float(np.max(np.abs(e))),
        "rms_speed_error_after_fault_rad_s": (float(np.sqrt(np.mean(e[post] ** 2)))
                                              if post.any() else None),
        "settling_time_s": settled,
        "settling_band_rad_s": band,
        "overspeed_peak_rad_s": float(np.max(w)),
        "overspeed_peak_over_rated": float(np.max(w) / rated),
        "pitch_min_deg": float(np.degrees(beta.min())),
        "pitch_max_deg": float(np.degrees(beta.max())),
        "pitch_rate_rms_deg_s": float(np.degrees(np.sqrt(np.mean(rate**2)))),
        "actuator_travel_deg": float(np.degrees(np.sum(np.abs(np.diff(beta, axis=0))))),
        "mean_electrical_power_W": float(np.mean(res.column("P_gen")) * eta),
        "output_interval_s": rc.dt * rc.decimate,
        "diverged": res.diverged,
        "simulated_s": float(res.steps * rc.dt),
        "wall_s": res.wall_s,
        "realtime_factor": float(res.steps * rc.dt / max(res.wall_s, 1e-9)),
        "seed": rc.seed,
        "config": res.config,
    }
    return m


def fdi_report(rc: RunConfig, res: sim.Result) -> dict:
    """Detection delay, isolation, estimation error and false alarms of wtftc's FDI.

    An actuator fault (lock, loss of effectiveness, pressure drop, air in oil) on blade j
    should raise blade j's latch after its onset and no other; the estimates are read at
    the end of the run. Sensor faults are not isolated from actuator faults by this FDI.
    """
    t = res.t
    faults = res.schedule.faults if res.schedule is not None else rc.faults  # angles bound
    actuator = [f for f in faults if f.type not in ("sensor_fixed", "sensor_gain")]
    faulty = {f.blade: f for f in actuator}
    out = {"blades": {}, "false_alarms": [], "isolation_correct": True}
    for j in (1, 2, 3):
        latch = res.column(f"fdi_latch_{j}")
        hit = np.nonzero(latch >= 0.5)[0]
        t_det = float(t[hit[0]]) if len(hit) else None
        rho_hat = float(res.column(f"fdi_rho_hat_{j}")[-1])
        c_hat = float(res.column(f"fdi_c_hat_{j}")[-1])
        b = {"detected_at_s": t_det, "rho_hat": rho_hat, "c_hat_deg": float(np.degrees(c_hat))}
        f = faulty.get(j)
        if f is not None:
            b["fault"] = f.type
            b["detection_delay_s"] = None if t_det is None else t_det - f.onset_s
            if t_det is None:
                out["isolation_correct"] = False
            elif t_det < f.onset_s:
                out["false_alarms"].append(f"blade {j} at {t_det:.2f} s, before the onset")
            if f.type == "loss_of_effectiveness":
                b["rho_error"] = rho_hat - f.rho
            if f.type == "lock" and f.angle is not None:
                b["stuck_angle_error_deg"] = float(np.degrees(c_hat - f.angle))
            if f.type in HYDRAULIC:
                w_hat = float(res.column(f"fdi_omega_n_hat_{j}")[-1])
                b["omega_n_hat_rad_s"] = w_hat
                b["zeta_hat"] = float(res.column(f"fdi_zeta_hat_{j}")[-1])
                b["dynamics_identified"] = bool(np.isclose(w_hat, HYDRAULIC[f.type][0]))
        elif t_det is not None:
            out["false_alarms"].append(f"blade {j} at {t_det:.2f} s (no actuator fault)")
            out["isolation_correct"] = False
        out["blades"][str(j)] = b
    return out


def write_outputs(out_dir: Path, rc: RunConfig, res: sim.Result, m: dict) -> list[Path]:
    """Traces (CSV with units, Parquet), metrics.json and config.toml, each written atomically."""
    from wtftc.io import atomic_write_json, atomic_write_text, write_parquet

    out_dir = Path(out_dir)
    spec = sim.output_spec(rc.controller)
    header = ["time_s"] + [n for n, _ in spec]
    units = ["s"] + [u for _, u in spec]
    data = np.column_stack([res.t, res.outputs])
    lines = ["# wtftc trace: " + json.dumps({"label": rc.label, "case": rc.case,
                                              "plant": rc.plant, "seed": rc.seed}),
             ",".join(f"{n} [{u}]" for n, u in zip(header, units, strict=True))]
    lines += [",".join(f"{x:.9g}" for x in row) for row in data]
    paths = [out_dir / "traces.csv", out_dir / "traces.parquet", out_dir / "metrics.json",
             out_dir / "config.toml"]
    atomic_write_text(paths[0], "\n".join(lines) + "\n")
    write_parquet(paths[1], dict(zip(header, data.T, strict=True)),
                  dict(zip(header, units, strict=True)))
    atomic_write_json(paths[2], m)
    atomic_write_text(paths[3], to_toml(rc.raw))
    return paths


def to_toml(d: dict, prefix: str = "") -> str:
    """A small TOML writer for configurations (scalars, lists, tables, arrays of tables)."""
    def val(x):
        if isinstance(x, bool):
            return "true" if x else "false"
        if isinstance(x, str):
            return json.dumps(x)
        if isinstance(x, int | float):
            return repr(float(x)) if isinstance(x, float) else str(x)
        if isinstance(x, list):
            return "[" + ", ".join(val(v) for v in x) + "]"
        raise TypeError(type(x))

    lines, tables = [], []
    for k, v in d.items():
        if isinstance(v, dict):
            tables.append((k, v))
        elif isinstance(v, list) and v and all(isinstance(e, dict) for e in v):
            tables.append((k, v))
        elif v is not None:
            lines.append(f"{k} = {val(v)}")
    for k, v in tables:
        name = f"{prefix}{k}"
        if isinstance(v, dict):
            lines += ["", f"[{name}]", to_toml(v, prefix=name + ".").strip()]
        else:
            for e in v:
                lines += ["", f"[[{name}]]", to_toml(e, prefix=name + ".").strip()]
    return "\n".join(x for x in lines) + "\n"


def lyapunov_trace(rc: RunConfig, res: sim.Result):
    """V_4(t) of eq (47) along a run, with θ* fitted on the run itself, and eq (51)'s check."""
    from wtftc import lyapunov
    from wtftc.generated import load

    n_p = len(lay.names(sim.PLANTS[rc.plant]["states"]))
    z = res.z
    n_c = len(lay.names(sim.controllers()[rc.controller]["states"]))
    x_plant, x_ctrl = z[:, :6], z[:, n_p:n_p + n_c]
    J_r = rc.p_turbine[lay.index("turbine_params", "J_r")]
    d1 = res.column("T_aero") / J_r
    p_plant = rc.p_turbine[:len(lay.names("plant_params"))]
    p_plant_map = dict(zip(lay.names("plant_params"), p_plant, strict=True))
    theta_star, _ = lyapunov.fit_theta_star(x_plant, x_ctrl, d1, p_plant_map,
                                            dict(zip(lay.names("controller_params"),
                                                     rc.p_ctrl, strict=True)))
    K = rc.p_ctrl[:4]
    obs = lyapunov.observer_lyapunov(K)
    P = obs.P if obs.hurwitz else np.eye(4)
    n = len(res.t)
    sched = getattr(res, "schedule", None)
    fault = (sched.actuator(res.t)[:9] if sched
             else np.tile(lay.defaults("fault_inputs")[:, None], (1, n)))
    yd = np.zeros((5, n))
    yd[0] = rc.reference
    V = np.array(load("lyapunov").map(n)(x_plant.T, x_ctrl.T, d1[None, :], yd, fault,
                                         theta_star, P, p_plant, rc.p_ctrl)[0])
    bound = lyapunov.decay_bound(dict(zip(lay.names("controller_params"), rc.p_ctrl,
                                          strict=True)), theta_star)
    return V[-1], bound, obs


def run_record(rc: RunConfig, res: sim.Result, m: dict) -> dict:
    """What the figures of one run need, in one dict (wtftc.figures)."""
    return {"result": res, "metrics": m, "case": rc.case, "plant": rc.plant,
            "case_doc": CASES[rc.case], "schedule": res.schedule, "rc": rc,
            "onset": min((f.onset_s for f in rc.faults), default=None),
            "gearbox_ratio": rc.p_turbine[lay.index("turbine_params", "gearbox_ratio")],
            "pitch_limits_deg": tuple(np.degrees([
                rc.p_turbine[lay.index("turbine_params", "pitch_min")],
                rc.p_turbine[lay.index("turbine_params", "pitch_max")]]))}


def write_run_figures(out_dir: Path, rc: RunConfig, res: sim.Result, m: dict) -> list[Path]:
    """The figures of one run (``wtftc run``) under out_dir/figures/, PNG and PDF: rotor
    speed, control and pitch, the fault shape when there is a fault, and wtftc's fault
    detection when the run uses it (case 4)."""
    from wtftc import figures

    rec = run_record(rc, res, m)
    fdir = Path(out_dir) / "figures"
    paths = figures.rotor_speed(rec, fdir, "rotor_speed", rc.label)
    if not rc.uses_rosco:
        paths += figures.control(rec, fdir, "control", rc.label)
    if res.schedule is not None:
        paths += figures.fault_shape(rec, fdir, "fault")
    if rc.case == 4:
        thr = float(lay.defaults("fdi_params")[lay.index("fdi_params", "fdi_r_thr")])
        paths += figures.fdi(rec, fdir, "fdi", threshold_rad=thr)
    return paths


def run_cases(out_dir: Path, plants=("nrel5mw", "paper"), overrides: dict | None = None,
              progress: bool = True, sign_as_written: bool = True) -> list[dict]:
    """The paper's three cases on each plant, figures and a metrics table under out_dir."""
    from wtftc import figures

    out_dir = Path(out_dir)
    rows = []
    for plant in plants:
        runs = []
        for case in (1, 2, 3):
            rc = make_config({**(overrides or {}), "plant": plant, "case": case})
            print(f"{plant}, case {case} ({CASES[case]}): {rc.t_final:g} s at dt = {rc.dt:g} s",
                  flush=True)
            res = run(rc, progress=progress, keep_states=True)
            m = metrics(rc, res)
            d = out_dir / plant / f"case{case}"
            write_outputs(d, rc, res, m)
            runs.append(run_record(rc, res, m))
            rows.append(m)
        fdir = out_dir / plant / "figures"
        r1, r2, r3 = runs
        figures.wind(r1, fdir)
        figures.rotor_speed(r1, fdir, "fig03_rotor_speed_case1", "Fig. 3")
        figures.control(r1, fdir, "fig04_control_case1", "Fig. 4")
        if r1["rc"].controller == "paper":
            figures.estimates(r1, fdir, "fig05_estimates_case1", "Fig. 5")
        figures.fault_shape(r2, fdir)
        figures.rotor_speed(r2, fdir, "fig07_rotor_speed_case2", "Fig. 7")
        figures.rotor_speed(r3, fdir, "fig08_rotor_speed_case3", "Fig. 8")
        figures.control(r3, fdir, "fig09_control_case3", "Fig. 9")
        if r3["rc"].controller == "paper":
            figures.estimates(r3, fdir, "fig10_estimates_case3", "Fig. 10")
        figures.comparison(runs, fdir)
        if len(r1["result"].t) > 10 and r1["rc"].controller == "paper":  # to divergence
            V, bound, _ = lyapunov_trace(r1["rc"], r1["result"])
            figures.lyapunov_figure(r1, V, r1["result"].t, bound, fdir)
            r1["metrics"]["eq51"] = {"holds": bound.holds, "report": bound.report()}
            from wtftc.io import atomic_write_json

            atomic_write_json(out_dir / plant / "case1" / "metrics.json", r1["metrics"])
    if sign_as_written:
        rc = make_config({**(overrides or {}), "plant": plants[0], "case": 1,
                          "control_sign": 1, "label": f"{plants[0]}_case1_sign_as_written"})
        print(f"{plants[0]}, case 1 with the control sign as written (s = +1)", flush=True)
        res = run(rc, progress=progress)
        m = metrics(rc, res)
        write_outputs(out_dir / plants[0] / "case1_sign_as_written", rc, res, m)
        rows.append(m)
    write_table(out_dir, rows)
    return rows


TABLE_COLUMNS = [
    ("label", "run", "{}"), ("rms_speed_error_rad_s", "RMS ω error [rad/s]", "{:.4f}"),
    ("max_abs_speed_error_rad_s", "max abs ω error [rad/s]", "{:.4f}"),
    ("rms_speed_error_after_fault_rad_s", "RMS after fault [rad/s]", "{:.4f}"),
    ("settling_time_s", "settled within ±1 % from [s]", "{:.1f}"),
    ("overspeed_peak_over_rated", "peak ω / rated [-]", "{:.3f}"),
    ("pitch_min_deg", "pitch min [deg]", "{:.1f}"), ("pitch_max_deg", "pitch max [deg]", "{:.1f}"),
    ("pitch_rate_rms_deg_s", "pitch rate RMS [deg/s]", "{:.2f}"),
    ("actuator_travel_deg", "travel [deg]", "{:.0f}"),
    ("mean_electrical_power_W", "mean electrical power [MW]", None),
    ("diverged", "diverged at [s]", None), ("realtime_factor", "× real time", "{:.0f}"),
]


def _cell(m: dict, key: str, fmt: str | None) -> str:
    v = m.get(key)
    if key == "mean_electrical_power_W":
        return f"{v / 1e6:.2f}"
    if key == "diverged":
        return f"{v['t_s']:.2f}" if v else "no"
    if v is None:
        return "—"
    text = fmt.format(v)
    return text[1:] if text.startswith("-") and float(text) == 0 else text


def write_table(out_dir: Path, rows: list[dict]) -> str:
    from wtftc.io import atomic_write_text

    head = [c[1] for c in TABLE_COLUMNS]
    body = [[_cell(m, k, f) for k, _, f in TABLE_COLUMNS] for m in rows]
    md = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    md += ["| " + " | ".join(r) + " |" for r in body]
    text = "\n".join(md) + "\n"
    def raw_cell(m, key):
        v = m.get(key)
        if key == "diverged":
            return f"{v['t_s']:.6g}" if v else ""
        if v is None:
            return ""
        return v if isinstance(v, str) else f"{v:.6g}"

    csv_head = ["label" if k == "label" else k for k, _, _ in TABLE_COLUMNS]
    csv_head = [("diverged_at_s" if k == "diverged" else k) for k in csv_head]
    csv = [",".join(csv_head)] + [",".join(raw_cell(m, k) for k, _, _ in TABLE_COLUMNS)
                                  for m in rows]
    atomic_write_text(Path(out_dir) / "metrics.md", text)
    atomic_write_text(Path(out_dir) / "metrics.csv", "\n".join(csv) + "\n")
    return text
