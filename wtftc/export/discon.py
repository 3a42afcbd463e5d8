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
reading). The ∂T/∂β schedule is the packaged Cp table's, baked into the code at export.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

import casadi as ca

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.errors import ConfigError
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


def _groups(controller: str) -> dict[str, str]:
    """Layout group of each .IN section."""
    return {"controller": controllers()[controller]["params"], "fdi_params": "fdi_params",
            "sensor_params": "sensor_params", "turbine_params": "turbine_params",
            "reference": "reference"}


def exportable() -> list[str]:
    """The registered controllers a library can be made of: all but ``external`` (it holds
    commands given from outside the loop: ROSCO's; there is nothing to export)."""
    return [c for c in controllers() if c != "external"]


def run_config(controller: str, interval: float = CONTROL_DT) -> config.RunConfig:
    """The run whose sampled loop the library reproduces: case 4 (wtftc's FDI feeds the
    accommodation), the realistic profile's noise levels, the call interval ``interval``
    (a whole multiple of the 1-ms step the FDI substeps at: refused otherwise, naming
    --interval)."""
    if controller not in exportable():
        raise ConfigError("--controller", controller, "one of " + ", ".join(exportable()))
    n = round(interval / PLANT_DT) if isinstance(interval, (int, float)) else 0
    if not (n >= 1 and abs(n * PLANT_DT - interval) <= 1e-12):
        raise ConfigError("--interval", interval, f"a whole multiple of {PLANT_DT} s "
                          "(the FDI's substep), e.g. 0.01 or 0.005")
    return config.make_config({"case": 4, "controller": controller, "profile": "realistic",
                               "dt_s": PLANT_DT, "control_interval_s": interval,
                               "t_final_s": 60.0})


def parameters(rc: config.RunConfig) -> list[tuple[str, float, str, str]]:
    """(name, value, unit, source) of every parameter, in the library's order."""
    values = {"controller": rc.p_ctrl, "fdi_params": rc.p_fdi, "sensor_params": rc.p_sensors,
              "turbine_params": rc.p_turbine, "reference": rc.yd}
    out = []
    for section, group in _groups(rc.loop.controller).items():
        for e, v in zip(lay.layout()[group], values[section], strict=True):
            out.append((e["name"], float(v), e["unit"], e.get("doc", "")))
    return out


def step_function(rc: config.RunConfig) -> ca.Function:
    """One control interval: (readings, x_ctrl, x_fdi, p, T) → (pitch demands, x_ctrl and
    x_fdi at the next call, generator torque demand on the HSS, logged FDI outputs)."""
    loop = rc.loop
    n_sub = loop.interval
    sym = loop_symbols(loop, 0)
    n_c, n_f = loop.n_states[1], loop.n_states[2]
    rd = ca.SX.sym("readings", len(lay.layout()["sensors"]))
    xc, xf, T = ca.SX.sym("x_ctrl", n_c), ca.SX.sym("x_fdi", n_f), ca.SX.sym("T")
    p = ca.SX.sym("p", sum(lay.size(g) for g in _groups(loop.controller).values()))
    parts, k = {}, 0
    for section, group in _groups(loop.controller).items():
        parts[section], k = p[k:k + lay.size(group)], k + lay.size(group)
    args = {**sym, "p_ctrl": parts["controller"], "p_fdi": parts["fdi_params"],
            "p_sensors": parts["sensor_params"], "yd": parts["reference"],
            "use_fdi": ca.DM(1.0 if loop.fdi else 0.0),
            "ctrl_fault": ca.DM(lay.defaults("fault_inputs"))}
    ctl = controller_block(loop, xc, xf, rd, args)
    xc_next = sampled._rk4(lambda x: controller_block(loop, x, xf, rd, args)["x_ctrl_dot"],
                           xc, T)
    xf_next = xf
    if loop.fdi:
        fdi_step = sampled._fdi_step(loop)
        for _ in range(n_sub):
            xf_next = fdi_step(xf_next, ctl["v"], rd, ctl["m"]["meas"], parts["fdi_params"],
                               T / n_sub)
    pt = parts["turbine_params"]
    gear = pt[lay.index("turbine_params", "gearbox_ratio")]
    omega_g = ctl["m"]["meas"][measurement_index("omega_g_hss")] / gear
    t_gen = load("generator_torque", "interpreted")(omega_g=omega_g, p_turbine=pt)["T_gen"]
    logged = ca.vertcat(*ctl["fdi"][:len(LOGGED)]) if loop.fdi else ca.DM.zeros(0)
    outs = [ctl["v"], xc_next, xf_next, t_gen / gear, logged]
    outs = ca.cse(outs)
    return ca.Function("wtftc_step", [rd, xc, xf, p, T], outs,
                       ["readings", "x_ctrl", "x_fdi", "p", "T"],
                       ["pitch", "x_ctrl_next", "x_fdi_next", "torque_hss", "logged"])


def init_function(rc: config.RunConfig) -> ca.Function:
    """The states at the first call, from the first readings (what wtftc's trim gives
    a run: the controller's init_<name> at the measurements, the FDI's at the pitch)."""
    loop = rc.loop
    reg = controllers()[loop.controller]
    rd = ca.SX.sym("readings", len(lay.layout()["sensors"]))
    p = ca.SX.sym("p", sum(lay.size(g) for g in _groups(loop.controller).values()))
    n_pc = lay.size(reg["params"])
    sym = {**loop_symbols(loop, 0), "p_sensors": p[n_pc + lay.size("fdi_params"):][
        :lay.size("sensor_params")]}
    m = virtual(loop, rd, ca.DM.zeros(rd.numel()), sym)
    xc0 = load(reg["init"], "interpreted")(meas=m["meas"], sched=m["sched"],
                                            p_ctrl=p[:n_pc])["x_ctrl0"]
    xf0 = load("init_fdi", "interpreted")(beta_meas=m["sensors"])["x_fdi0"] if loop.fdi \
        else ca.DM.zeros(0)
    return ca.Function("wtftc_init", [rd, p], [xc0, xf0], ["readings", "p"],
                       ["x_ctrl0", "x_fdi0"])


#: the avrSWAP records the library may write (the issue's bound: 500)
SWAP_MAX = 500


def _meta_header(rc: config.RunConfig, params: list) -> str:
    loop = rc.loop
    names = ",\n    ".join(f'"{n}"' for n, *_ in params)
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
static const char *const WTFTC_PARAM_NAMES[WTFTC_N_PARAMS] = {{
    {names}
}};
"""


def input_file(rc: config.RunConfig, params: list) -> str:
    """The .IN file: every parameter by name, value, unit and source."""
    lines = [f"! wtftc {rc.loop.controller}: the parameters of libwtftc_{rc.loop.controller}.so"
             f" (wtftc export discon; docs/discon.md)",
             "! name  value  ! unit - source. Every parameter must be set, once; edit the",
             "! values to tune or to describe another turbine. '!' starts a comment."]
    section = None
    groups = _groups(rc.loop.controller)
    owner = {e["name"]: s for s, g in groups.items() for e in lay.layout()[g]}
    for name, value, unit, doc in params:
        if owner[name] != section:
            section = owner[name]
            lines += ["", f"! --- {section} ({groups[section]}) ---"]
        lines.append(f"{name:<28s} {value!r:>24s}  ! {unit} - {doc}".rstrip())
    return "\n".join(lines) + "\n"


def servodyn_snippet(controller: str, interval: float = CONTROL_DT) -> str:
    """The ServoDyn lines a user pastes (OpenFAST ServoDyn input file, v3.x)."""
    lib, infile = f"libwtftc_{controller}.so", f"wtftc_{controller}.IN"
    return f"""! ServoDyn lines for libwtftc_{controller}.so (paste over the same keys)
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

Call it every {dt} s (DLL_DT; another interval is refused). It reads from avrSWAP (1-based
records): #1 iStatus (0 first call, 1 running, -1 last; -8/-9 refused), #2 time, #3
interval, #4/#33/#34 blade pitch [rad], #20 generator speed [rad/s, HSS], #21 rotor speed
[rad/s], #50 and the input file name; #63 the first record for logged channels (none
written if 0 or beyond record {swap_max}). It writes #42-#44 the blade pitch demands
[rad], #45 = #42, #47 the generator torque demand [N m, HSS], #35 = 1, #36 = 0, #55 =
#56 = 0, #65 the number of logged channels, written from record #63 on: {logged}
(latches [-], effectiveness estimates [-], stuck-angle estimates [rad]). avcOUTNAME is
read only (the run's name); avcMSG holds at most #49 characters (256 when #49 is 0).

Input file: wtftc_{c}.IN, every parameter by name (value, unit, source); all must be set.
Errors (a bad or missing input file, a wrong interval, a non-finite measurement, an
unknown iStatus) set aviFAIL = -1 with a message in avcMSG; the host keeps running.
The controller's states advance at the call interval as in wtftc's sampled loop; the
FDI runs inside and feeds the accommodation (wtftc's case 4). Details: docs/discon.md.
"""


def build(rc: config.RunConfig, out: Path, cc: str = "gcc", opt: str = "-O2") -> None:
    """Generate the C of the library's functions into ``out`` and compile it there."""
    params = parameters(rc)
    cg = ca.CodeGenerator("wtftc_discon_gen.c", {"with_header": False, "verbose": False})
    cg.add(step_function(rc))
    cg.add(init_function(rc))
    cg.generate(str(out) + "/")
    (out / "wtftc_discon_meta.h").write_text(_meta_header(rc, params))
    shutil.copy(HERE / "discon_interface.c", out / "discon_interface.c")
    lib = out / f"libwtftc_{rc.loop.controller}.so"
    cmd = [cc, opt, "-std=c99", "-shared", "-fPIC", "-o", str(lib),
           str(out / "wtftc_discon_gen.c"), str(out / "discon_interface.c"), "-lm"]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    except FileNotFoundError:
        raise ConfigError("--cc", cc, "a C compiler on the PATH (gcc, clang)") from None
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed:\n{done.stderr[-2000:]}")
    (out / f"wtftc_{rc.loop.controller}.IN").write_text(input_file(rc, params))
    (out / "servodyn_snippet.txt").write_text(servodyn_snippet(rc.loop.controller,
                                                               rc.control_interval))
    logged = ", ".join(f"fdi_{k}_{j}" for k in LOGGED for j in lay.blades()) \
        if rc.loop.fdi else "none"
    (out / "README.txt").write_text(README.format(c=rc.loop.controller,
                                                  dt=rc.control_interval,
                                                  swap_max=SWAP_MAX, logged=logged))


def export(controller: str, out_dir: Path, cc: str = "gcc", opt: str = "-O2",
           interval: float = CONTROL_DT) -> Path:
    """Build the library of ``controller`` into ``out_dir`` as a whole: in a temporary
    folder beside it, moved into place when every file is written (an existing export
    folder is replaced; a folder holding anything else is refused)."""
    rc = run_config(controller, interval)
    out_dir = Path(out_dir).resolve()
    if out_dir.exists() and any(out_dir.iterdir()) and not (out_dir / "README.txt").exists():
        raise ConfigError("--out", str(out_dir), "a new folder or an earlier export's")
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}-", dir=out_dir.parent))
    try:
        build(rc, tmp, cc, opt)
        if out_dir.exists():
            shutil.rmtree(out_dir)
        tmp.rename(out_dir)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return out_dir
