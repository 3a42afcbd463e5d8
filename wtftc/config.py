"""A run's configuration: validated once, defaults filled in, resolved; TOML in and out."""

from __future__ import annotations

import copy
import hashlib
import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.errors import ConfigError
from wtftc.model.cp_table import nrel5mw_cp_table, read_cp_table
from wtftc.model.faults import DEFAULT_FAULT, parse_faults
from wtftc.model.wind import wind_from_config
from wtftc.sim import rhs
from wtftc.sim.trim import trim

CASES = {1: "no fault", 2: "fault, controller unaware", 3: "fault known to eq (49)",
         4: "fault detected and estimated by wtftc's FDI"}
#: the fault-free case, the case whose controller is unaware of the fault, the one told the
#: fault (an oracle), and the one fed by the FDI
FAULT_FREE_CASE, UNAWARE_CASE, ORACLE_CASE, FDI_CASE = 1, 2, 3, 4

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
    """One run, resolved: the compiled loop it needs (:class:`wtftc.sim.rhs.Loop`) and what
    is its own (case, timing, reference, gains, wind, faults). ``raw`` is the validated
    configuration with every default filled in, as saved with the results."""

    raw: dict
    case: int
    loop: rhs.Loop
    t_final: float
    dt: float
    seed: int
    decimate: int
    reference: float
    p_ctrl: np.ndarray
    wind: object
    faults: list = field(default_factory=list)
    omega_offset: float = 0.0

    plant = property(lambda self: self.loop.plant)
    controller = property(lambda self: self.loop.controller)
    table = property(lambda self: self.loop.table)
    table_key = property(lambda self: self.loop.table_key)
    p_turbine = property(lambda self: np.array(self.loop.p_turbine))

    @property
    def uses_rosco(self) -> bool:
        return self.raw["controller"] == "rosco"

    @property
    def told_fault(self) -> bool:
        """Eq (49) is given the fault as it happens (case 3, an oracle)."""
        return self.case == ORACLE_CASE

    @property
    def uses_fdi(self) -> bool:
        """The accommodation is fed by wtftc's FDI (case 4)."""
        return self.case == FDI_CASE

    @property
    def label(self) -> str:
        return self.raw.get("label") or f"{self.plant}_case{self.case}"

    @property
    def yd(self) -> np.ndarray:
        """The reference and its derivatives (a constant reference: zeros after y_d)."""
        yd = np.zeros(lay.size("reference"))
        yd[lay.index("reference", "yd_0")] = self.reference
        return yd

    @property
    def onset(self) -> float | None:
        """The first fault's onset [s], or None without a fault."""
        return min((f.onset_s for f in self.faults), default=None)

    def initial_state(self) -> np.ndarray:
        """The trimmed initial state of the loop (wtftc.sim.trim) at the wind at t = 0."""
        return trim(self.loop, self.p_ctrl, float(self.wind(0.0)), self.omega_offset)

    def param(self, name: str) -> float:
        """A turbine parameter by its layout name."""
        return float(self.loop.p_turbine[lay.index("turbine_params", name)])


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
    """Validate a configuration (as from TOML or the CLI), fill in the defaults, and
    resolve it: the turbine, the Cp table, the wind and the faults, once."""
    cfg = copy.deepcopy(cfg or {})
    for key in cfg:
        if key not in TOP_KEYS:
            raise ConfigError(key, cfg[key], "a known key: " + ", ".join(sorted(TOP_KEYS)))
    raw = {**copy.deepcopy(DEFAULTS), **cfg}
    case = raw["case"]
    if case not in CASES or isinstance(case, bool):
        raise ConfigError("case", case, "1 (no fault), 2 (fault, controller unaware), "
                          "3 (fault known to eq (49)) or 4 (fault detected by wtftc's FDI)")
    if raw["plant"] not in rhs.PLANTS:
        raise ConfigError("plant", raw["plant"], "one of " + ", ".join(
            f"{k} ({v['doc']})" for k, v in rhs.PLANTS.items()))
    controller = _controller(raw["controller"])
    t_final, dt, seed, decimate = _timing(raw)
    ref = _reference(raw)
    p_ctrl, p_turbine = _parameters(raw, controller)
    if not isinstance(raw["wind"], dict):
        raise ConfigError("wind", raw["wind"], "a table with kind = ...")
    wind = wind_from_config(raw["wind"], t_final=t_final, seed=seed)
    faults = _faults(raw, case, t_final)
    init = raw.get("initial", {})
    if not isinstance(init, dict) or set(init) - {"omega_r_offset_rad_s"}:
        raise ConfigError("initial", init, "a table with omega_r_offset_rad_s")
    loop = rhs.Loop(raw["plant"], controller, *_cp_table(raw), tuple(float(x) for x in p_turbine))
    return RunConfig(raw=raw, case=case, loop=loop, t_final=t_final, dt=dt, seed=seed,
                     decimate=decimate, reference=ref, p_ctrl=p_ctrl, wind=wind, faults=faults,
                     omega_offset=float(init.get("omega_r_offset_rad_s", 0.0)))


def _controller(name) -> str:
    """The registered controller a name runs ("external" for ROSCO, which drives it)."""
    regs = {k: v for k, v in rhs.controllers().items() if k != "external"}
    if name == "rosco":
        from wtftc.sim import rosco

        reason = rosco.available()
        if reason:
            raise ConfigError("controller", "rosco", reason)
        return "external"
    if name not in regs:
        raise ConfigError("controller", name, "one of " + ", ".join(
            [f"{k} ({v['doc']})" for k, v in regs.items()]
            + ["rosco (NREL's ROSCO through its ControllerInterface; optional extra)"]))
    return name


def _timing(raw: dict) -> tuple[float, float, int, int]:
    """t_final, dt, seed and the output decimation."""
    t_final = float(_number(raw, "t_final_s", lo=0, hi=36000))
    # the upper bound is only a sanity cap: the real limit is checked against the closed
    # loop's fastest mode before the run (wtftc.sim.stability.check_dt)
    dt = float(_number(raw, "dt_s", lo=0, hi=10.0))
    if dt > t_final:
        raise ConfigError("dt_s", dt, f"at most t_final_s = {t_final}")
    n_steps = round(t_final / dt)
    if abs(n_steps * dt - t_final) > 1e-9 * max(t_final, 1.0):
        raise ConfigError("t_final_s", t_final, f"a whole number of steps of dt_s = {dt:g} s "
                          f"(e.g. {n_steps * dt:g} or {(n_steps + 1) * dt:g} s): the run "
                          "would otherwise end at a time other than the one asked for")
    seed = _number(raw, "seed", lo=-1, integer=True)
    rate = float(_number(raw, "output_rate_hz", lo=0, hi=1e6))
    decimate = max(1, int(round(1.0 / (rate * dt))))
    if abs(decimate * dt * rate - 1.0) > 1e-6 and decimate > 1:
        raise ConfigError("output_rate_hz", rate, f"a rate whose interval is a whole number of "
                          f"steps of dt_s = {dt:g} s (e.g. {1.0 / (decimate * dt):.6g} Hz)")
    return t_final, dt, seed, decimate


def _reference(raw: dict) -> float:
    sign = raw["control_sign"]
    if sign not in (-1, 1) or isinstance(sign, bool):
        raise ConfigError("control_sign", sign, "-1 (corrected, default) or +1 (as written, "
                          "diverges: paper-notes defect 2)")
    ref = raw.get("reference_rad_s", PAPER_REFERENCE if raw["plant"] == "paper"
                  else lay.vector("turbine_params")[lay.index("turbine_params", "omega_g_rated")])
    raw["reference_rad_s"] = float(ref)
    return float(_number(raw, "reference_rad_s", lo=0, hi=10))


def _parameters(raw: dict, controller: str) -> tuple[np.ndarray, np.ndarray]:
    """The controller's and the turbine's parameter vectors, defaults with overrides."""
    ctrl_group = rhs.controllers()[controller]["params"]
    signed = "control_sign" in lay.names(ctrl_group)
    vectors = {}
    for key, group, extra in (
            ("controller_params", ctrl_group,
             {"control_sign": raw["control_sign"]} if signed else {}),
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
    p_turbine = vectors["turbine_params"]
    for flag in ("gen_torque_law", "gen_constant_power"):
        val = p_turbine[lay.index("turbine_params", flag)]
        if val not in (0.0, 1.0):
            raise ConfigError(f"turbine_params.{flag}", float(val), "0 or 1 (docs/running.md)")
    return vectors["controller_params"], p_turbine


def _faults(raw: dict, case: int, t_final: float) -> list:
    if case == FAULT_FREE_CASE:
        if raw.get("fault"):
            raise ConfigError("fault", raw["fault"], "no fault in case 1 (use case 2 or 3)")
        return []
    raw.setdefault("fault", copy.deepcopy(DEFAULT_FAULT))
    faults = parse_faults(raw["fault"])
    for k, f in enumerate(faults):
        if f.onset_s >= t_final:
            raise ConfigError(f"fault[{k}].onset_s", f.onset_s,
                              f"a time before t_final_s = {t_final:g} s")
    return faults


def _cp_table(raw: dict) -> tuple:
    """The Cp table and its key (the packaged NREL 5-MW table, or the file's sha256)."""
    if not raw.get("cp_table"):
        return nrel5mw_cp_table(), "nrel5mw"
    path = Path(raw["cp_table"])
    return read_cp_table(path), hashlib.sha256(path.read_bytes()).hexdigest()[:12]


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
