"""``wtftc export discon``: a registered controller as a Bladed-style DISCON library (ours).

What goes into ``DIR``:

* ``libwtftc_<controller>.so``: the generated C of one control interval (below) and the
  hand-written Bladed interface ``discon_interface.c`` (this package), built with the C
  compiler; plain C99, no Python and no CasADi at load time;
* ``wtftc_<controller>.IN``: every parameter the library reads, by its layout name, with
  value, unit and source; the user edits it to tune or to describe another turbine;
* ``servodyn_snippet.txt``, ``README.txt``.

One call advances the controller exactly as wtftc's sampled loop does every control
interval T (``wtftc/sim/sampled.py``): the sensors' readings are voted by the virtual
sensors, the FDI's latches exclude failed sensors and tell the accommodation (case 4),
the controller computes its command and its states take one RK4 step of T with the
samples held; the FDI takes T/dt RK4 steps of dt with the command held (dt: the
simulator's step the library was exported for); the generator torque demand is the
turbine's torque law (``generator_torque``) at the measured generator speed. A DISCON
caller measures each quantity once: the reading goes to both of its sensors (the pair
tests then see no disagreement; a sensor fault reaches the library as a changed
reading).

The ∂T/∂β schedule of the controllers that use one (all but the paper's) is computed at
load time from the Cp_Ct_Cq file the .IN names (``PerfFileName``, relative to the .IN's
folder as ROSCO resolves it), by ``discon_cp.c`` (this package): the same steps as
``wtftc.model.aero.schedule_points`` with the turbine parameters of the .IN; the export
writes the table the run used beside the .IN. The gearbox ratio the virtual sensors use
is the .IN's too: editing the .IN's turbine values retunes the library without a new
export.

Every value of the .IN is checked at the first call (``wtftc_discon_checks.h``, generated
by :mod:`wtftc.export.discon_checks`: the layout's valid ranges, the FDI's, wtftc.config's
cross-checks). The export writes its folder through :func:`wtftc.files.owned_folder`
(never over a folder it did not write) and runs the compiler in its own process group,
killed whole on an interrupt or a timeout.
"""

from __future__ import annotations

import copy
import hashlib
import importlib.resources
import math
import os
import shutil
import signal
import subprocess
from collections.abc import Callable
from contextlib import suppress
from pathlib import Path

import casadi as ca
import numpy as np

from wtftc import config, files
from wtftc import controller as ctl
from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.errors import ConfigError
from wtftc.export import discon_checks
from wtftc.model import turbine_file
from wtftc.model.cp_table import NREL5MW_FILE, NREL5MW_SOURCE, CpTable, write_cp_table
from wtftc.sim import sampled
from wtftc.sim.rhs import (
    controller_block,
    controllers,
    loop_symbols,
    measurement_index,
    virtual,
)

#: the interval and step a library is exported for by default: the realistic profile's
CONTROL_DT = 0.01
PLANT_DT = 0.001
#: the parameter groups of the .IN file, in the library's parameter vector order
GROUPS = ("controller", "fdi_params", "sensor_params", "turbine_params", "reference")
#: the FDI's outputs logged per blade (OutName channels)
LOGGED = ("latch", "rho_hat", "c_hat")
HERE = Path(__file__).resolve().parent
#: the most breakpoints a schedule may have (table pitch angles ≥ 0 on the operating
#: curve); the generated lookup sums a term per breakpoint
SCHED_MAX = 100
#: the schedule's runtime table: ∂T/∂β at the first breakpoint, then per segment its
#: start [rad], width [rad] and slope [N m/rad²] (the library fills it at load time)
SCHED_LEN = 1 + 3 * (SCHED_MAX - 1)
#: the .IN key naming the Cp_Ct_Cq file (ROSCO's DISCON.IN key of the same file)
CP_KEY = "PerfFileName"


#: the library's own settings after the layout's parameters: not the controller's, the
#: host's (what the library does with its demands before it writes them)
INTERFACE_SECTION = "interface"
#: demand_rate_limit: 1, the demands' rate is limited to pitch_rate_max as well as their
#: position to [pitch_min, pitch_max] (a host whose blades follow the demand directly,
#: as ElastoDyn's do: the export's default); 0, position only (a host with the benchmark
#: actuator, whose own rate limit the controller and the FDI are designed for: wtftc's
#: plant library in OpenFAST, wtftc's own plants)
DEMAND_RATE_LIMIT = discon_checks.DEMAND_RATE_LIMIT


def _interface_params(demand_rate_limit: int) -> list[tuple[str, float, str, str]]:
    return [(DEMAND_RATE_LIMIT, float(demand_rate_limit), "-",
             "1: demands rate-limited to pitch_rate_max (a host with no pitch actuator); 0: "
             "position limits only (a host with the benchmark actuator; docs/discon.md)")]


def _groups(controller: str) -> dict[str, str]:
    """Layout group of each .IN section."""
    return {"controller": controllers()[controller]["params"], "fdi_params": "fdi_params",
            "sensor_params": "sensor_params", "turbine_params": "turbine_params",
            "reference": "reference"}


def exportable() -> list[str]:
    """The registered controllers a library can be made of: all but ``external`` (it holds
    commands given from outside the loop: ROSCO's; there is nothing to export)."""
    return [c for c in controllers() if c != "external"]


def needs_cp(controller: str) -> bool:
    """Whether the controller reads the ∂T/∂β schedule (then the .IN names a Cp file)."""
    f = load(controllers()[controller]["function"], "interpreted")
    # the schedule is sched[0]; sched[1] (the tower-top acceleration) needs no Cp file
    return any(f.which_depends("sched", [o], 1, False)[0] for o in f.name_out())


def runtime_schedule(tab: ca.SX, beta: ca.SX) -> ca.SX:
    """∂T/∂β at the mean pitch ``beta`` from the runtime table ``tab`` (SCHED_LEN): linear
    between breakpoints, held beyond the ends, as the simulator's schedule
    (wtftc.model.aero.sched_loop_function), written as a sum of clipped segments so that
    the breakpoints are runtime values: g_0 + Σ_k s_k min(max(β - β_k, 0), h_k). Unused
    segments have s_k = 0."""
    n = SCHED_MAX - 1
    start, width, slope = tab[1:1 + n], tab[1 + n:1 + 2 * n], tab[1 + 2 * n:1 + 3 * n]
    return tab[0] + ca.dot(slope, ca.fmin(ca.fmax(beta - start, 0), width))


def schedule_table(betas: np.ndarray, grads: np.ndarray) -> np.ndarray:
    """The runtime table of breakpoints (betas [rad], grads [N m/rad]), as
    discon_interface.c packs it (for tests and for a library's reference)."""
    n = SCHED_MAX - 1
    start = np.full(n, betas[-1])
    width, slope = np.ones(n), np.zeros(n)
    start[:len(betas) - 1] = betas[:-1]
    width[:len(betas) - 1] = np.diff(betas)
    slope[:len(betas) - 1] = np.diff(grads) / np.diff(betas)
    return np.concatenate([[grads[0]], start, width, slope])


#: the length of the run a library's parameters are made for [s] (its wind decides the
#: torque law, wtftc.config): a whole number of call intervals near this
RUN_S = 60.0


#: the keys of a run's configuration that make a library: its controller, turbine, sensors
#: and FDI (and control_interval_s, the call interval unless --interval gives one); the
#: rest are the scenario's (wind, faults, length, outputs, engine), which a library does
#: not hold: an export leaves them out and its header names them
LIBRARY_KEYS = ("controller", "controller_params", "tuning", "controller_preset", "turbine",
                "turbine_params", "sensors", "fdi", "control_sign", "reference_rad_s",
                "cp_table")


def _interval(cfg: dict, interval: float | None) -> tuple[float, str]:
    """The call interval and the field it came from: ``interval`` (--interval), else the
    configuration's control_interval_s, else :data:`CONTROL_DT`; refused unless a whole
    multiple of the FDI's 1-ms substep."""
    field = "--interval"
    if interval is None:
        field, interval = "control_interval_s", cfg.get("control_interval_s", CONTROL_DT)
    ok = (isinstance(interval, (int, float)) and not isinstance(interval, bool)
          and math.isfinite(interval) and interval > 0)
    n = round(interval / PLANT_DT) if ok else 0
    if not (n >= 1 and abs(n * PLANT_DT - interval) <= 1e-12):
        raise ConfigError(field, interval, f"a whole multiple of {PLANT_DT} s (the FDI's "
                          "substep), e.g. 0.01 or 0.005")
    return float(interval), field


def controller_of(cfg: dict) -> tuple:
    """The configuration's controller: its ``controller`` (a table, or a bare design's
    name), else the turbine's recommended preset as a table; and that as a
    :class:`wtftc.controller.Controller`, checked exportable: ROSCO is refused (its library
    is ROSCO's own), and an AFTC design's accommodation must be fdi (the library detects
    faults itself; nobody tells it one)."""
    tab = cfg.get("controller")
    if tab is None:
        name, _ = ctl.recommended(turbine_file.load(cfg.get("turbine", turbine_file.DEFAULT)))
        tab = {"preset": name}
    field = "controller" if isinstance(tab, str) else "controller.design"
    c = ctl.parse({"design": tab} if isinstance(tab, str) else tab)
    if c.design not in exportable():
        raise ConfigError(field, c.design, "a design wtftc builds a library of: "
                          + ", ".join(exportable()) + " (ROSCO's library is ROSCO's own "
                          "libdiscon.so with its DISCON.IN)")
    if c.accommodation != ctl.default_accommodation(c.design):
        raise ConfigError("controller.accommodation", c.accommodation, f"fdi for an export of "
                          f"{c.design}: the library detects faults with wtftc's FDI inside "
                          "it, and no host tells it one")
    return tab, c


def run_config(cfg, interval: float | None = None) -> config.RunConfig:
    """The run whose sampled loop the library of ``cfg`` reproduces. ``cfg``: a run's
    configuration (a ``[controller]`` table with or without ``preset``, or the flat keys
    ``controller``/``controller_params``; ``turbine``, ``turbine_params``, ``sensors``,
    ``fdi``; no controller: the turbine's recommended preset), or a bare design's name.
    The library's run: case 4 (wtftc's FDI feeds the accommodation), the realistic
    profile's sensors unless ``[sensors]`` says otherwise, the call interval ``interval``
    (default: the configuration's control_interval_s, else 0.01 s; a whole multiple of the
    1-ms step the FDI substeps at, within what wtftc's sampled loop accepts), the FDI's
    host alignment rate. The scenario's keys (:func:`scenario_keys`) are left out."""
    if isinstance(cfg, str):  # a bare design: --controller DESIGN
        if cfg not in exportable():
            raise ConfigError("--controller", cfg, "one of " + ", ".join(exportable()))
        cfg = {"controller": {"design": cfg}}
    if not isinstance(cfg, dict):
        raise ConfigError("config", cfg, "a run's configuration (a table: docs/discon.md)")
    for key in cfg:
        if key not in config.TOP_KEYS:
            raise ConfigError(key, cfg[key], "a known key: " + ", ".join(sorted(config.TOP_KEYS)))
    interval, field = _interval(cfg, interval)
    own = {k: copy.deepcopy(v) for k, v in cfg.items() if k in LIBRARY_KEYS}
    own["controller"], _ = controller_of(own)
    flat, names = ctl.expand(own)  # (a bare design's name: the flat keys as they are)
    calls = round(RUN_S / interval)
    t_final = interval * calls if calls >= 1 else RUN_S  # longer: the loop refuses it
    fdi = flat.get("fdi", {})
    fdi = {"align_rate_per_s": config.HOST_ALIGN_RATE, **fdi} if isinstance(fdi, dict) else fdi
    try:
        return config.make_config({**flat, "case": ctl.FDI_CASE, "profile": "realistic",
                                   "dt_s": PLANT_DT, "control_interval_s": interval,
                                   "t_final_s": t_final, "fdi": fdi})
    except ConfigError as exc:
        if exc.field in names:  # a range refused of a key the [controller] table set
            raise ConfigError(names[exc.field], exc.value, exc.allowed, where=exc.where) \
                from None
        if exc.field != "control_interval_s":
            raise
        raise ConfigError(field, interval, f"a whole multiple of {PLANT_DT} s (the FDI's "
                          f"substep); wtftc's sampled loop takes {exc.allowed}") from None


def scenario_keys(cfg) -> list[str]:
    """The keys of ``cfg`` an export leaves out: the scenario's, not the library's."""
    if not isinstance(cfg, dict):
        return []
    return sorted(k for k in cfg if k not in (*LIBRARY_KEYS, "control_interval_s"))


def parameters(rc: config.RunConfig, demand_rate_limit: int = 1
               ) -> list[tuple[str, float, str, str]]:
    """(name, value, unit, source) of every parameter, in the library's order: the
    layout's (the controller's, the FDI's, the sensors', the turbine's, the reference),
    then the library's own settings (:data:`DEMAND_RATE_LIMIT`)."""
    values = {"controller": rc.p_ctrl, "fdi_params": rc.p_fdi, "sensor_params": rc.p_sensors,
              "turbine_params": rc.p_turbine, "reference": rc.yd}
    out = []
    turbine = turbine_file.load(rc.raw.get("turbine", turbine_file.DEFAULT))
    for section, group in _groups(rc.loop.controller).items():
        for e, v in zip(lay.layout()[group], values[section], strict=True):
            doc = e.get("doc", "")
            if section == "turbine_params":
                doc = _turbine_source(turbine, e["name"], float(v), doc)
            out.append((e["name"], float(v), e["unit"], doc))
    return out + _interface_params(demand_rate_limit)


def generated_code_sha256() -> str:
    """The hash of the generated code the library is made of (wtftc.artefacts.loader:
    what a campaign's results record as ``generated_code_sha256``)."""
    from wtftc.artefacts.loader import generated_code_sha256 as code_hash

    return code_hash()


def differences(rc: config.RunConfig) -> list[tuple[str, float, float]]:
    """(name, value, default) of every .IN value of ``rc`` that differs from its design's
    defaults on its turbine (the bare design's export: ``{"controller": {"design": d}}``
    with the same turbine and call interval)."""
    base = {"controller": {"design": rc.controller}}
    if "turbine" in rc.raw:
        base["turbine"] = rc.raw["turbine"]
    ref = parameters(run_config(base, rc.control_interval))
    return [(n, v, b) for (n, v, *_), (m, b, *_) in zip(parameters(rc), ref, strict=True)
            if v != b]


def _turbine_file(t: turbine_file.Turbine) -> str:
    builtin = turbine_file.path_of(t.name) if t.name in turbine_file.BUILTIN else None
    if builtin is not None and Path(builtin).resolve() == Path(t.path).resolve():
        return f"wtftc's built-in file {Path(t.path).name} (--turbine {t.name})"
    return f"the file {Path(t.path).resolve()}"


def header(rc: config.RunConfig, cfg=None) -> list[str]:
    """What an export is, as the .IN's header and the README say it: the preset (or a
    [controller] table), the turbine by name and file, the generated code's hash, every
    setting that differs from the design's defaults, and the configuration's keys the
    export left out (the scenario's)."""
    t = turbine_file.load(rc.raw.get("turbine", turbine_file.DEFAULT))
    preset = rc.raw.get("controller_preset")
    doc = ctl.presets()[preset].doc if preset in ctl.presets() else ""
    what = f"preset {preset}" if preset else "a [controller] table"
    diff = differences(rc)
    lines = [f"controller: {what}, design {rc.controller}" + (f" ({doc})" if doc else ""),
             f"turbine: {t.name}, {_turbine_file(t)}",
             f"generated code: sha256 {generated_code_sha256()} (of generated/manifest.json's "
             "artefacts, as a campaign records it: generated_code_sha256)",
             f"settings other than {rc.controller}'s defaults on {t.name}:"
             + ("" if diff else " none")]
    lines += [f"  {n} = {v!r} (default {b!r})" for n, v, b in diff]
    left = scenario_keys(cfg)
    if left:
        lines.append("left out of the configuration (the scenario's, not the library's): "
                     + ", ".join(left))
    return lines


def _turbine_source(turbine: turbine_file.Turbine, name: str, value: float, doc: str) -> str:
    """A turbine parameter's source in the .IN: its turbine file's (the layout's doc is
    the NREL 5-MW's, wrong beside another turbine's value); where the run set another
    value (its configuration or profile), that, with the file's value and source."""
    if name not in turbine.sources:
        return doc
    source = turbine.sources[name] or doc
    if value == turbine.values[name]:
        return source
    return (f"set by the run (its configuration or profile); {turbine.name}'s file: "
            f"{turbine.values[name]:g}, {source}")


def _split(p: ca.SX, controller: str) -> dict[str, ca.SX]:
    """The library's parameter vector by .IN section."""
    parts, k = {}, 0
    for section, group in _groups(controller).items():
        parts[section], k = p[k:k + lay.size(group)], k + lay.size(group)
    return parts


def _runtime_values(parts: dict, tab: ca.SX) -> dict:
    """The loop symbols that are the .IN's values in a library: the gearbox ratio and the
    schedule from the runtime table (see :func:`wtftc.sim.rhs.virtual`)."""
    return {"gearbox_ratio": parts["turbine_params"][lay.index("turbine_params",
                                                               "gearbox_ratio")],
            "sched_fn": lambda beta: runtime_schedule(tab, beta)}


def _n_params(controller: str) -> int:
    return sum(lay.size(g) for g in _groups(controller).values())


def step_function(rc: config.RunConfig) -> ca.Function:
    """One control interval: (readings, x_ctrl, x_fdi, p, T, sched, tower_fa_acc) → (pitch
    demands, x_ctrl and x_fdi at the next call, generator torque demand on the HSS, logged
    FDI outputs); ``tower_fa_acc`` the host's tower-top fore-aft acceleration (#53), which
    only a tower damper reads."""
    loop = rc.loop
    n_sub = loop.interval
    sym = loop_symbols(loop, 0)
    n_c, n_f = loop.n_states[1], loop.n_states[2]
    rd = ca.SX.sym("readings", len(lay.layout()["sensors"]))
    xc, xf, T = ca.SX.sym("x_ctrl", n_c), ca.SX.sym("x_fdi", n_f), ca.SX.sym("T")
    p, tab = ca.SX.sym("p", _n_params(loop.controller)), ca.SX.sym("sched", SCHED_LEN)
    acc = ca.SX.sym("tower_fa_acc")
    parts = _split(p, loop.controller)
    args = {**sym, "tower_fa_acc": acc, "p_ctrl": parts["controller"], "p_fdi": parts["fdi_params"],
            "p_sensors": parts["sensor_params"], "yd": parts["reference"],
            "use_fdi": ca.DM(1.0 if loop.fdi else 0.0),
            "ctrl_fault": ca.DM(lay.defaults("fault_inputs")), **_runtime_values(parts, tab)}
    ctl = controller_block(loop, xc, xf, rd, args)
    xc_next = sampled._rk4(lambda x: controller_block(loop, x, xf, rd, args)["x_ctrl_dot"],
                           xc, T)
    pt = parts["turbine_params"]
    gear = pt[lay.index("turbine_params", "gearbox_ratio")]
    omega_g = ctl["m"]["meas"][measurement_index("omega_g_hss")] / gear
    t_gen = load("generator_torque", "interpreted")(omega_g=omega_g, p_turbine=pt)["T_gen"]
    logged = ca.vertcat(*ctl["fdi"][:len(LOGGED)]) if loop.fdi else ca.DM.zeros(0)
    names = ["readings", "x_ctrl", "x_fdi", "p", "T", "sched", "tower_fa_acc"]
    outs = ["pitch", "x_ctrl_next", "x_fdi_next", "torque_hss", "logged"]
    ins = [rd, xc, xf, p, T, tab, acc]
    if not loop.fdi:
        return ca.Function("wtftc_step", ins, ca.cse([ctl["v"], xc_next, xf, t_gen / gear,
                                                      logged]), names, outs)
    head = ca.Function("wtftc_ctl", ins, ca.cse([ctl["v"], xc_next, t_gen / gear, logged,
                                                 ctl["m"]["meas"], parts["fdi_params"]]))
    return _with_fdi_substeps(head, sampled._fdi_step(loop), n_sub, names, outs)


def _with_fdi_substeps(head: ca.Function, fdi_step: ca.Function, n_sub: int,
                       names: list[str], outs: list[str]) -> ca.Function:
    """The step as the controller's part, then the FDI's ``n_sub`` RK4 substeps as calls
    of one generated function: the same arithmetic as the substeps written out in one
    expression (each call is the same operations on the same values), in a fifth of
    the C, which is most of the export's compile time."""
    ins = [ca.MX.sym(n, head.size_in(k)) for k, n in enumerate(names)]
    v, xc_next, torque, logged, meas, p_fdi = head(*ins)
    rd, xf, T = ins[0], ins[2], ins[4]
    h = T / n_sub
    for _ in range(n_sub):
        xf = fdi_step(xf, v, rd, meas, p_fdi, h)
    return ca.Function("wtftc_step", ins, [v, xc_next, xf, torque, logged], names, outs)


def init_function(rc: config.RunConfig) -> ca.Function:
    """The states at the first call, from the first readings (what wtftc's trim gives
    a run: the controller's init_<name> at the measurements, the FDI's at the pitch)."""
    loop = rc.loop
    reg = controllers()[loop.controller]
    rd = ca.SX.sym("readings", len(lay.layout()["sensors"]))
    p, tab = ca.SX.sym("p", _n_params(loop.controller)), ca.SX.sym("sched", SCHED_LEN)
    acc = ca.SX.sym("tower_fa_acc")
    parts = _split(p, loop.controller)
    sym = {**loop_symbols(loop, 0), "p_sensors": parts["sensor_params"],
           "tower_fa_acc": acc, **_runtime_values(parts, tab)}
    m = virtual(loop, rd, ca.DM.zeros(rd.numel()), sym)
    xc0 = load(reg["init"], "interpreted")(meas=m["meas"], sched=m["sched"],
                                            p_ctrl=parts["controller"])["x_ctrl0"]
    xf0 = load("init_fdi", "interpreted")(beta_meas=m["sensors"])["x_fdi0"] if loop.fdi \
        else ca.DM.zeros(0)
    return ca.Function("wtftc_init", [rd, p, tab, acc], [xc0, xf0],
                       ["readings", "p", "sched", "tower_fa_acc"],
                       ["x_ctrl0", "x_fdi0"])


def sched_functions(controller: str) -> list[ca.Function]:
    """The turbine's side of the schedule computed at load time (discon_cp.c), as
    wtftc.model.aero.schedule_points computes it: ``wtftc_sched_tsr(v, p)`` the tip-speed
    ratio at rated speed in wind v, ``wtftc_sched_point(beta, v, cp, dcp, p)`` the
    aerodynamic torque's excess over rated torque and ∂T_aero/∂β (generated
    aero_torque_sensitivity at rated speed, the three blades at beta)."""
    p, v = ca.SX.sym("p", _n_params(controller)), ca.SX.sym("v")
    pt = _split(p, controller)["turbine_params"]
    tp = {n: pt[lay.index("turbine_params", n)]
          for n in ("omega_g_rated", "gen_torque_rated", "rotor_radius")}
    tsr = ca.Function("wtftc_sched_tsr", [v, p],
                      [tp["omega_g_rated"] * tp["rotor_radius"] / v], ["v", "p"], ["tsr"])
    beta, cp, dcp = ca.SX.sym("beta"), ca.SX.sym("cp"), ca.SX.sym("dcp")
    x6 = [ca.SX(float(d)) for d in lay.defaults("plant_states")]
    names = lay.names("plant_states")
    for n, val in (("omega_r", tp["omega_g_rated"]), ("theta_s", ca.SX(0.0)),
                   ("omega_g", tp["omega_g_rated"])):
        x6[names.index(n)] = val
    for k in range(*lay.block("plant_states", "beta").indices(len(names))):
        x6[k] = beta
    sens = load("aero_torque_sensitivity", "interpreted")(
        x_plant=ca.vertcat(*x6), wind=v, cp=cp, dcp_dbeta=dcp, p_turbine=pt)
    point = ca.Function("wtftc_sched_point", [beta, v, cp, dcp, p],
                        [sens["T_aero"] - tp["gen_torque_rated"], sens["dT_dbeta"]],
                        ["beta", "v", "cp", "dcp", "p"], ["excess", "dT_dbeta"])
    return [tsr, point]


#: the hand-written C of every library (this package)
SOURCES = ("discon_interface.c", "discon_cp.c")
#: the avrSWAP records the library may write (the issue's bound: 500)
SWAP_MAX = 500


def _meta_header(rc: config.RunConfig, params: list) -> str:
    loop = rc.loop
    fs = sched_functions(loop.controller)
    work = {k: max(getattr(f, f"sz_{k}")() for f in fs) for k in ("arg", "res", "iw", "w")}
    names = ",\n    ".join(f'"{n}"' for n, *_ in params)
    names_list = [n for n, *_ in params]
    logged = [f"fdi_{k}_{j}" for k in LOGGED for j in lay.blades()] if loop.fdi else []
    return f"""/* wtftc export discon: the sizes and parameter names of {loop.controller} */
#define WTFTC_CONTROLLER "{loop.controller}"
#define WTFTC_DT {rc.control_interval!r}
#define WTFTC_N_PARAMS {len(params)}
#define WTFTC_N_CTRL {loop.n_states[1]}
#define WTFTC_N_FDI {loop.n_states[2]}
#define WTFTC_N_READINGS {len(lay.layout()["sensors"])}
#define WTFTC_N_LOG {len(logged)}
#define WTFTC_SWAP_MAX {SWAP_MAX}
#define WTFTC_NEEDS_CP {int(needs_cp(loop.controller))}
#define WTFTC_CP_KEY "{CP_KEY}"
#define WTFTC_SCHED_MAX {SCHED_MAX}
#define WTFTC_SCHED_LEN {SCHED_LEN}
#define WTFTC_SCHED_ARG {work["arg"]}
#define WTFTC_SCHED_RES {work["res"]}
#define WTFTC_SCHED_IW {work["iw"]}
#define WTFTC_SCHED_W {work["w"]}
#define WTFTC_MAX_IN_BYTES {files.MAX_TOML_BYTES}LL
#define WTFTC_MAX_CP_BYTES {files.MAX_TABLE_BYTES}LL
/* the demands' limits (the turbine's) and the library's rate-limit setting, by index */
#define WTFTC_PITCH_MIN {names_list.index("pitch_min")}
#define WTFTC_PITCH_MAX {names_list.index("pitch_max")}
#define WTFTC_PITCH_RATE_MAX {names_list.index("pitch_rate_max")}
#define WTFTC_DEMAND_RATE_LIMIT {names_list.index(DEMAND_RATE_LIMIT)}
static const char *const WTFTC_PARAM_NAMES[WTFTC_N_PARAMS] = {{
    {names}
}};
"""


#: the Cp_Ct_Cq file an export writes beside its .IN
CP_FILE = "Cp_Ct_Cq.wtftc.txt"


def input_file(rc: config.RunConfig, params: list, cp_file: str = CP_FILE,
               about: list[str] | None = None) -> str:
    """The .IN file: what the export is (``about``, :func:`header`'s lines, as comments),
    the Cp file if the controller needs one, then every parameter by name, value, unit and
    source."""
    lines = [f"! wtftc {rc.loop.controller}: the parameters of libwtftc_{rc.loop.controller}.so"
             f" (wtftc export discon; docs/discon.md)",
             *(f"! {ln}" for ln in about or ()),
             "! name  value  ! unit - source. Every parameter must be set, once; edit the",
             "! values to tune or to describe another turbine. '!' starts a comment."]
    if needs_cp(rc.loop.controller):
        lines += ["", f'{CP_KEY:<28s} {chr(34) + cp_file + chr(34):>24s}  ! - the rotor '
                  "performance table (ROSCO's Cp_Ct_Cq format) of the ∂T/∂β schedule, "
                  "relative to this file's folder unless absolute"]
    section = None
    groups = _groups(rc.loop.controller)
    owner = {e["name"]: s for s, g in groups.items() for e in lay.layout()[g]}
    groups = groups | {INTERFACE_SECTION: "the library's own"}
    for name, value, unit, doc in params:
        if owner.get(name, INTERFACE_SECTION) != section:
            section = owner.get(name, INTERFACE_SECTION)
            lines += ["", f"! --- {section} ({groups[section]}) ---"]
        lines.append(f"{name:<28s} {value!r:>24s}  ! {unit} - {doc}".rstrip())
    return "\n".join(lines) + "\n"


def servodyn_snippet(controller: str, interval: float = CONTROL_DT,
                     lib: str | None = None, infile: str | None = None) -> str:
    """The ServoDyn lines a user pastes (OpenFAST ServoDyn input file, v3.x): ServoDyn
    calls ``lib`` with ``infile`` (default: the controller's library and .IN)."""
    lib = lib or f"libwtftc_{controller}.so"
    infile = infile or f"wtftc_{controller}.IN"
    return f"""! ServoDyn lines for {lib} (paste over the same keys)
---------------------- PITCH CONTROL -------------------------------------------
          5   PCMode       - Pitch control mode {{5: Bladed-style DLL}} (switch)
---------------------- GENERATOR AND TORQUE CONTROL ----------------------------
          5   VSContrl     - Variable-speed control mode {{5: Bladed-style DLL}} (switch)
---------------------- BLADED INTERFACE ----------------------------------------
"{lib}"    DLL_FileName - Name/location of the dynamic library (.so) (quoted string)
"{infile}"    DLL_InFile   - Name of input file sent to the DLL (-) (quoted string)
"DISCON"      DLL_ProcName - Name of procedure in DLL to be called (-) (case sensitive)
{interval!r:>11}   DLL_DT       - Communication interval for dynamic library (s): as exported
          1   Ptch_Cntrl   - Record 28: individual pitch control {{0: collective, 1: individual}}
"""


README = """libwtftc_{c}.so: wtftc's `{c}` controller with wtftc's FDI, as a Bladed-style DISCON.

WHAT IT IS (also the header of wtftc_{c}.IN)
{about}
library sources: sha256 {sources} (the C it was compiled from, in this folder)

Call it every {dt} s (DLL_DT; another interval is refused). It reads from avrSWAP (1-based
records): #1 iStatus (0 first call, 1 running, -1 last; -8/-9 refused), #2 time, #3
interval, #4/#33/#34 blade pitch [rad], #20 generator speed [rad/s, HSS], #21 rotor speed
[rad/s], #28 Ptch_Cntrl (must be 1: individual pitch), #53 the tower-top fore-aft
acceleration [m/s^2, positive downwind] (read by a tower damper only, phys_td_gain > 0 in
the .IN; a host that leaves it 0 gives the damper nothing), #50 and the input file name;
#63 the first record for logged channels (none written if 0 or beyond record {swap_max}).
It writes #42-#44 the blade pitch demands [rad], #45 = #42, #47 the generator torque
demand [N m, HSS], #35 = 1, #36 = 0, #55 = #56 = 0, #65 the number of logged channels,
written from record #63 on: {logged}
(latches [-], effectiveness estimates [-], stuck-angle estimates [rad]). avcOUTNAME is
read only (the run's name); avcMSG gets at most #49 bytes, its NUL included (nothing when
#49 is below 1).

Input file: wtftc_{c}.IN, every parameter by name (value, unit, source); all must be set,
each within its valid range (wtftc's own: e.g. angles in rad within +-pi/2, inertias,
ratios and time constants > 0) and wtftc's cross-checks (pitch_min < pitch_max, cut-in
below region-2 speed, flags 0 or 1, the reference inside the operating envelope).
{cp}Errors (a bad or missing input file or Cp file, a value out of its range, a wrong
interval, a non-finite measurement, an unknown iStatus, a demand that would not be a finite
float) set aviFAIL = -1 with a message in avcMSG; the host keeps running. No call returns
aviFAIL = 0 with a demand that is not finite.
The controller's states advance at the call interval as in wtftc's sampled loop; the
FDI runs inside and {fdi_use}. Details: docs/discon.md.

THE PITCH ACTUATOR. The controller and its FDI are designed for the benchmark's pitch
actuator between the demand and the blade: a second order (omega_n_nominal = {wn:g} rad/s,
zeta_nominal = {zeta:g} in the .IN) with a rate limit (pitch_rate_max, {rate:g} deg/s) and
the position limits. OpenFAST's decks have none: ElastoDyn applies the demand directly,
and the physical AFTC is then unstable in OpenFAST 5.0.0 (docs/openfast.md). So the
library limits what it writes: every demand within pitch_min..pitch_max, and, with
demand_rate_limit = 1 in the .IN (the default), within pitch_rate_max x DLL_DT of the
last one, the rate the missing actuator would have allowed. That keeps the blades in
range; it does not make the design right for such a host. Put the actuator in: `wtftc
export discon --with-actuator` adds libwtftc_plant.so, wtftc's plant-side pitch
actuator (its settings in wtftc_plant.in), which ServoDyn calls instead and which calls
this library (demand_rate_limit = 0 then); `wtftc run --engine openfast` runs OpenFAST
so (docs/openfast.md).

INTO YOUR OWN DECK (OpenFAST 5.0, ServoDyn input file v3.x), step by step:
1. Copy every file of this folder into the folder of the deck's ServoDyn input file
   (ServoDyn reads DLL_FileName and DLL_InFile relative to that file, and each library
   reads the names in its input file relative to that input file).
2. In the ServoDyn input file, give the keys servodyn_snippet.txt lists (PCMode,
   VSContrl, DLL_FileName, DLL_InFile, DLL_ProcName, DLL_DT, Ptch_Cntrl) its values;
   leave every other line as it is.
3. In the main input file (.fst), set DT to a whole fraction of DLL_DT = {dt} s, e.g.
   {deck_dt:g} s, what `wtftc run --engine openfast` uses (ServoDyn refuses a DLL_DT that
   is not a whole multiple of DT; ROSCO's NREL 5-MW deck has DT = 0.00625 s).
4. In the ElastoDyn input file, start at the operating point of the wind at t = 0:
   RotSpeed [rpm], BlPitch(1), BlPitch(2), BlPitch(3) [deg], TTDspFA [m]. The library
   starts its states at its first readings; a start far from the operating point is a
   start-up transient. `wtftc run --engine openfast --out OUT` of this controller and
   that wind starts where wtftc's trim puts it: the values are in OUT/openfast/'s
   ElastoDyn file.
5. Run openfast on the main input file.
"""


def _source_bytes(table: CpTable) -> bytes:
    if table.source == NREL5MW_SOURCE:
        return (importlib.resources.files("wtftc") / "data" / NREL5MW_FILE).read_bytes()
    src = Path(table.source)
    return src.read_bytes() if src.is_file() else b""


def _table_bytes(table: CpTable) -> bytes | None:
    """The bytes of the file ``table`` was read from when that file is at hand and
    unchanged since (the packaged NREL 5-MW table, a user's file), else None."""
    raw = _source_bytes(table)
    return raw if table.sha256 is not None and \
        hashlib.sha256(raw).hexdigest() == table.sha256 else None


def _write_table(table: CpTable, path: Path) -> None:
    """The controllers' Cp table as a file: the file it was read from, byte for byte, when
    that is at hand (the packaged NREL 5-MW table, a user's file unchanged since it was
    read), else written round-trip exact (wtftc.model.cp_table.write_cp_table)."""
    raw = _table_bytes(table)
    if raw is not None:
        path.write_bytes(raw)
    else:
        write_cp_table(table, path, title=table.source)


def cp_file_name(table: CpTable) -> str:
    """The name the Cp file of ``table`` gets beside a .IN: its own file's name."""
    if table.source == NREL5MW_SOURCE:
        return NREL5MW_FILE
    return Path(table.source).name if Path(table.source).suffix else CP_FILE


def write_input(rc: config.RunConfig, path: Path, demand_rate_limit: int = 1,
                about: list[str] | None = None) -> Path:
    """The .IN file of ``rc``'s parameters at ``path`` (``about``: its header, what the
    export is), and beside it the Cp file it names when the controller needs one.
    ``demand_rate_limit``: 1 for a host without a pitch actuator (the default), 0 for one
    with the benchmark actuator (:data:`DEMAND_RATE_LIMIT`)."""
    cp = cp_file_name(rc.loop.table)
    path.write_text(input_file(rc, parameters(rc, demand_rate_limit), cp, about),
                    encoding="utf-8")
    if needs_cp(rc.loop.controller):
        _write_table(rc.loop.table, path.parent / cp)
    return path


#: the longest a compile may take [s] (the physical controller's: about 4 s at -O2)
COMPILE_TIMEOUT_S = 600.0


def _kill_group(proc: subprocess.Popen) -> None:
    """Kill the compiler and every process it started (its own process group), then reap
    it; its leader not yet reaped, the group's id cannot have been reused."""
    with suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    for pipe in (proc.stdout, proc.stderr):
        if pipe is not None:
            pipe.close()


def compile_library(cmd: list[str], cc: str, timeout: float | None = None) -> None:
    """Run the compiler command ``cmd`` in a process group of its own: on an interrupt
    (Ctrl-C, SIGTERM) or after ``timeout`` s (:data:`COMPILE_TIMEOUT_S`) the whole group is
    killed, so no compiler is left behind. A compiler that cannot be started, fails or
    times out is a ConfigError naming --cc, in one line."""
    timeout = COMPILE_TIMEOUT_S if timeout is None else timeout
    with files.sigterm_as_interrupt():
        try:
            proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True, errors="replace",
                                    start_new_session=True)
        except (OSError, ValueError) as exc:
            why = getattr(exc, "strerror", None) or str(exc)
            raise ConfigError("--cc", cc, f"a C compiler on the PATH, e.g. gcc or clang "
                              f"({why})") from None
        try:
            _, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            _kill_group(proc)
            raise ConfigError("--cc", cc, f"a C compiler that builds the library within "
                              f"{timeout:g} s (stopped with every process it started)") \
                from None
        except BaseException:
            _kill_group(proc)
            raise
    if proc.returncode != 0:
        lines = [ln.strip() for ln in err.splitlines() if ln.strip()]
        first = next((ln for ln in lines if "error" in ln.lower()), lines[0] if lines else "")
        raise ConfigError("--cc", cc, f"a C compiler that builds the library (it exited with "
                          f"status {proc.returncode}" + (f": {first[:300]}" if first else "")
                          + ")")


def check_library(lib: Path, cc: str) -> None:
    """Refuse (naming --cc) a compiler that exits 0 without building the library: no file,
    not an ELF shared object, or no DISCON symbol in it (read, never loaded)."""
    data = lib.read_bytes() if lib.is_file() and not lib.is_symlink() else b""
    if not data:
        why = "it wrote no library"
    elif not (data[:4] == b"\x7fELF" and data[16:18] in (b"\x03\x00", b"\x00\x03")):
        why = f"{lib.name} is not an ELF shared object"
    elif b"DISCON\x00" not in data:
        why = f"{lib.name} has no DISCON symbol"
    else:
        return
    raise ConfigError("--cc", cc, f"a C compiler that builds the library (it exited with "
                      f"status 0, but {why})")


def write_sources(rc: config.RunConfig, out: Path) -> list[Path]:
    """The library's C sources in ``out``: the generated functions, the headers of its
    parameters and checks, and the hand-written interface (the compiled library depends
    on these files only; the parameter values are the .IN's)."""
    params = parameters(rc)
    cg = ca.CodeGenerator("wtftc_discon_gen.c", {"with_header": False, "verbose": False})
    cg.add(step_function(rc))
    cg.add(init_function(rc))
    for f in sched_functions(rc.loop.controller):
        cg.add(f)
    cg.generate(str(out) + "/")
    (out / "wtftc_discon_meta.h").write_text(_meta_header(rc, params))
    (out / "wtftc_discon_checks.h").write_text(
        discon_checks.header(rc, _groups(rc.loop.controller)))
    for name in SOURCES:
        shutil.copy(HERE / name, out / name)
    return [out / "wtftc_discon_gen.c", out / "wtftc_discon_meta.h",
            out / "wtftc_discon_checks.h", *(out / n for n in SOURCES)]


def compile_command(out: Path, controller: str, cc: str = "gcc", opt: str = "-O2",
                    lib: Path | None = None) -> list:
    """The compiler command that builds the library (``lib``, default
    ``out/libwtftc_<controller>.so``) from the sources write_sources wrote into ``out``."""
    lib = lib if lib is not None else out / f"libwtftc_{controller}.so"
    return [cc, opt, "-std=c99", "-shared", "-fPIC", "-o", str(lib),
            str(out / "wtftc_discon_gen.c"),
            *(str(out / n) for n in SOURCES), "-lm"]


#: the longest step an OpenFAST deck takes under wtftc (wtftc.openfast.case.MAX_DT) [s]
DECK_DT_MAX = 0.005


def build(rc: config.RunConfig, out: Path, cc: str = "gcc", opt: str = "-O2",
          demand_rate_limit: int = 1, about: list[str] | None = None) -> None:
    """Generate the C of the library's functions into ``out`` and compile it there; write
    its .IN (headed by ``about``, :func:`header`'s lines), ServoDyn lines and README."""
    sources = write_sources(rc, out)
    lib = out / f"libwtftc_{rc.loop.controller}.so"
    compile_library(compile_command(out, rc.loop.controller, cc, opt), cc)
    check_library(lib, cc)
    write_input(rc, out / f"wtftc_{rc.loop.controller}.IN", demand_rate_limit, about)
    (out / "servodyn_snippet.txt").write_text(servodyn_snippet(rc.loop.controller,
                                                               rc.control_interval))
    (out / "README.txt").write_text(readme(rc, about or [], sources_sha256(sources)))


def sources_sha256(sources: list[Path]) -> str:
    """The hash of a library's C sources (16 hex digits): each file's name and bytes."""
    h = hashlib.sha256()
    for p in sorted(sources, key=lambda p: p.name):
        data = p.read_bytes()
        h.update(p.name.encode() + b"\0" + len(data).to_bytes(8, "little") + data)
    return h.hexdigest()[:16]


def readme(rc: config.RunConfig, about: list[str], sources: str) -> str:
    """The export's README.txt."""
    logged = ", ".join(f"fdi_{k}_{j}" for k in LOGGED for j in lay.blades()) \
        if rc.loop.fdi else "none"
    cp = (f"Its PerfFileName names the Cp_Ct_Cq file ({cp_file_name(rc.loop.table)}, "
          "relative to the .IN's folder)\nthe library reads at its first call to compute "
          "the dT/dbeta schedule.\n") if needs_cp(rc.loop.controller) else ""
    dt = rc.control_interval
    return README.format(c=rc.loop.controller, cp=cp, dt=dt, swap_max=SWAP_MAX,
                         logged=logged, about="\n".join(about), sources=sources,
                         deck_dt=dt / math.ceil(dt / DECK_DT_MAX - 1e-9),
                         wn=rc.param("omega_n_nominal"), zeta=rc.param("zeta_nominal"),
                         rate=math.degrees(rc.param("pitch_rate_max")),
                         fdi_use="feeds the accommodation (wtftc's case 4)"
                         if "fdi" in ctl.accommodations(rc.loop.controller) else
                         f"its findings are logged; the {rc.loop.controller} design has no "
                         "fault accommodation, so what it commands does not change with them")


def _earlier_export(folder: Path) -> bool:
    """Whether ``folder`` is an export written before the marker existed, untouched since:
    exactly the files an export of one controller writes (the C it built from, the
    library, its .IN, the Cp file if it needs one, the ServoDyn lines, the README), each a
    regular file, the README's first line naming that library, and the .IN and the Cp
    file as the export writes them for the interval its ServoDyn lines give (a user's
    edit, to tune, makes the folder the user's)."""
    try:
        entries = {e.name: e for e in os.scandir(folder)}
        if not all(e.is_file(follow_symlinks=False) for e in entries.values()):
            return False
        libs = [n[len("libwtftc_"):-3] for n in entries
                if n.startswith("libwtftc_") and n.endswith(".so")]
        if len(libs) != 1 or libs[0] not in exportable():
            return False
        c = libs[0]
        dt = float((folder / "servodyn_snippet.txt").read_text(encoding="utf-8")
                   .split("DLL_DT")[0].split()[-1])
        rc = run_config(c, dt)
        cp = [cp_file_name(rc.loop.table)] if needs_cp(c) else []
        expected = {f"libwtftc_{c}.so", f"wtftc_{c}.IN", "servodyn_snippet.txt", "README.txt",
                    "wtftc_discon_gen.c", "wtftc_discon_meta.h", *SOURCES, *cp}
        first = README.split("\n")[0].format(c=c)
        infile = input_file(rc, parameters(rc), cp_file_name(rc.loop.table))
        return (set(entries) == expected
                and (folder / "README.txt").read_text(encoding="utf-8").split("\n")[0] == first
                and (folder / f"wtftc_{c}.IN").read_text(encoding="utf-8") == infile
                and all(_table_bytes(rc.loop.table) == (folder / n).read_bytes() for n in cp))
    except (OSError, ValueError, IndexError, ConfigError):
        return False


def export(cfg, out_dir: Path, cc: str = "gcc", opt: str = "-O2",
           interval: float | None = None,
           with_actuator: Callable[[config.RunConfig, Path], None] | None = None) -> Path:
    """Build the library of the run configuration ``cfg`` (:func:`run_config`: a
    ``[controller]`` table, a preset, a turbine; or a bare design's name) into ``out_dir``
    as a whole (wtftc.files.owned_folder): in a hidden folder beside it, swapped in when
    every file is written. ``out_dir`` may be new, empty, or a folder an export wrote and
    nobody changed since (its marker; or :func:`_earlier_export`); anything else is
    refused in one line naming --out, nothing touched. The .IN's header and the README
    say what was exported (:func:`header`). Returns ``out_dir``, resolved
    (:func:`written` lists its files).

    ``with_actuator`` (``export discon --with-actuator``: wtftc.openfast.plant_library.
    add_to_export) adds the plant-side actuator library the controller is designed for;
    the .IN then leaves the demands' rate to that actuator (demand_rate_limit = 0)."""
    rc = run_config(cfg, interval)
    about = header(rc, cfg)
    with files.owned_folder(out_dir, "--out", command="export discon",
                            legacy=_earlier_export) as tmp:
        build(rc, tmp, cc, opt, demand_rate_limit=0 if with_actuator else 1, about=about)
        if with_actuator is not None:
            with_actuator(rc, tmp)
    return Path(out_dir).resolve()


#: the files of an export a user puts into a deck, in the order :func:`written` names
#: them (the Cp file, of any name, after the .IN; the C sources last)
_ORDER = ("libwtftc_plant.so", "wtftc_plant.in", "servodyn_snippet.txt", "README.txt")


def written(out_dir: Path) -> list[str]:
    """The files of the export in ``out_dir`` by name: the library, its .IN, the Cp file,
    the plant library and its settings (--with-actuator), the ServoDyn lines, the README;
    then the C sources it was compiled from."""
    def rank(n: str) -> tuple:
        if n in _ORDER:
            return (3 + _ORDER.index(n), n)
        if n.endswith((".c", ".h")):
            return (9, n)
        return (0 if n.endswith(".so") else 1 if n.endswith(".IN") else 2, n)

    return sorted((e.name for e in os.scandir(out_dir)
                   if e.is_file() and e.name != files.MARKER), key=rank)
