"""A run's configuration: validated once, defaults filled in, resolved; TOML in and out."""

from __future__ import annotations

import copy
import functools
import importlib.util
import json
import math
import numbers
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.controller import (  # noqa: F401
    DISCON_KEYS,
    FAULT_FREE_CASE,
    FDI_CASE,
    LIBRARIES,
    ORACLE_CASE,
    UNAWARE_CASE,
    check_record,
    discon_files,
)
from wtftc.controller import expand as expand_controller
from wtftc.errors import ConfigError, EngineError, MissingExtra, range_text
from wtftc.files import check_user_file
from wtftc.model import tuning, turbine_file, wind_field
from wtftc.model.cp_table import nrel5mw_cp_table, read_cp_table
from wtftc.model.faults import DEFAULT_FAULT, parse_faults
from wtftc.model.wind import field_default, wind_from_config
from wtftc.sim import fdi, rhs
from wtftc.sim.integrate import Envelope
from wtftc.sim.trim import start_wind, trim

CASES = {1: "no fault", 2: "fault, controller unaware", 3: "fault known to eq (49)",
         4: "fault detected and estimated by wtftc's FDI"}

TOP_KEYS = {"case", "plant", "controller", "t_final_s", "dt_s", "seed", "output_rate_hz",
            "control_sign", "reference_rad_s", "cp_table", "wind", "fault", "controller_params",
            "turbine_params", "initial", "label", "profile", "control_interval_s",
            "control_delay", "sensors", "mismatch", "fdi", "turbine", "loads", "rosco",
            "tuning", "engine", "openfast", "controller_preset", "discon"}

DEFAULTS = {
    "case": 1, "plant": "nrel5mw", "controller": "paper", "t_final_s": 60.0, "dt_s": 1e-3,
    "seed": 0, "output_rate_hz": 50.0, "control_sign": -1,
    "wind": {"kind": "paper_random"}, "profile": "ideal", "control_delay": False,
    "engine": "wtftc",
}

#: the engines a run can be simulated in: wtftc's own plants, or OpenFAST 5.0 through
#: ServoDyn with wtftc's plant-side actuator, fault and sensor library (docs/openfast.md)
ENGINES = ("wtftc", "openfast")
#: the keys that describe wtftc's own plant, which OpenFAST's deck replaces
OPENFAST_REFUSED = {"plant": "the plant is the turbine's OpenFAST deck (openfast_deck)",
                    "mismatch": "the plant is OpenFAST's deck: there is no model mismatch "
                                "to set", "control_delay": "OpenFAST calls the controller "
                                "library itself"}
#: how an OpenFAST run gets a turbulent wind ([openfast] wind): TurbSim's full field, or
#: the series wtftc's own plant gets, uniform over the rotor
OPENFAST_WINDS = ("turbsim", "uniform")
#: the values of those keys a saved OpenFAST run writes (config.toml), accepted back
OPENFAST_ACCEPTED = {"plant": ("tower",), "mismatch": ({},), "control_delay": (False,)}

#: measurement profiles (docs/sensors.md): what a run's controller sees unless the
#: configuration says otherwise. "ideal": continuous time, exact sensors (the paper's
#: world); "realistic": 100 Hz sampled control with the benchmark's sensor noise (Odgaard,
#: Stoustrup & Kinnaert 2013) and the baseline torque law
PROFILES = {
    "ideal": {"control_interval_s": 0.0, "sensors": {}},
    "realistic": {"control_interval_s": 0.01,
                  "sensors": {"pitch_noise_deg": 0.2, "rotor_speed_noise_rad_s": 0.0251,
                              "generator_speed_noise_rad_s": 0.05},
                  "turbine_params": {"gen_torque_law": 1.0}},
}

#: the [sensors] table: signal → (its measurements, degrees at the edge); each signal takes
#: <signal>_noise, _bias, _resolution in its unit (deg or rad/s) and <signal>_lag_s
#: (the quantity its sensors measure, a prefix for the pitch's three; every sensor of the
#: layout's that measures it, m1 and m2 of each, shares the specification)
SENSOR_KEYS = {"pitch": ("beta_meas_", True), "rotor_speed": ("omega_r", False),
               "generator_speed": ("omega_g_hss", False)}


def _sensors_of(signal: str) -> list[str]:
    """The layout's sensors of a [sensors] signal (generated/layout.json "sensors")."""
    q = SENSOR_KEYS[signal][0]
    return [s["name"] for s in lay.layout()["sensors"]
            if s["measures"] == q or (q.endswith("_") and s["measures"].startswith(q))]
#: [sensors] key kind → the layout sensor_params prefix
_SENSOR_PARAM = {"noise": "sigma", "bias": "bias", "resolution": "resolution", "lag": "lag"}

#: the [mismatch] table: the plant's parameters relative to the model the controllers and
#: the FDI carry (factors; 1: none) → the turbine parameters each scales (cp_scale: the
#: plant's Cp surface)
MISMATCH = {"inertia": ("J_r", "J_g"), "shaft_stiffness": ("k_s",), "shaft_damping": ("d_s",),
            "air_density": ("air_density",), "cp_scale": (),
            "actuator_omega_n": ("omega_n_nominal",), "actuator_zeta": ("zeta_nominal",)}

#: the paper's reference: "the rotor speed to the 1.27 rad/s value" (Section 5)
PAPER_REFERENCE = 1.27

#: the largest seed: the sweep stores seeds as signed 64-bit integers
SEED_MAX = 2**63 - 1
#: the most RK4 steps one run may take (t_final_s / dt_s): 2e8 steps are about 9 min at
#: the compiled loop's 2.7 µs a step (docs/performance.md); the longest run, 36,000 s,
#: takes 3.6e7 at the default dt_s. A dt_s of 1e-9 over 60 s (6e10 steps, days without a
#: line of progress) is refused (issue 30)
MAX_STEPS = 200_000_000

_INF = math.inf
@functools.cache
def _ranges(group: str) -> dict[str, tuple[float, float, bool, bool, str]]:
    """The physical range of every entry of a layout group that has one (derivation/
    layout.py, ``valid``): name → (low, high, low_open, high_open, unit). Whatever the
    source (defaults, a config file, the CLI, a sweep, a batch), :func:`check_turbine`
    refuses a value outside it, naming the field, the value and the range."""
    out = {}
    for e in lay.layout()[group]:
        v = e.get("valid")
        if v:
            out[e["name"]] = (-_INF if v["min"] is None else v["min"],
                              _INF if v["max"] is None else v["max"],
                              v["min_open"], v["max_open"], e["unit"])
    return out


TURBINE_RANGES = _ranges("turbine_params")
#: turbine parameters that must increase strictly, in pairs (lower, upper): a pitch range,
#: and the torque law's region 1½ (its slope divides by region2 - cut-in speed)
TURBINE_ORDER = (("pitch_min", "pitch_max"), ("vs_cut_in_speed", "vs_region2_speed"))
#: turbine parameters that switch a behaviour on (1) or off (0)
TURBINE_FLAGS = ("gen_torque_law", "gen_constant_power", "vs_constant_torque")
#: controller parameters that are switches
CONTROLLER_FLAGS = ("phys_actuator_model",)


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
    #: start where the closed loop rests ([initial] closed_loop_rest; wtftc.sim.trim)
    closed_loop_rest: bool = True
    #: the sensors' parameters (layout sensor_params); the plant's turbine parameters and
    #: Cp scale under model mismatch
    p_sensors: np.ndarray = field(default_factory=lambda: lay.defaults("sensor_params"))
    p_plant: np.ndarray | None = None
    cp_scale: float = 1.0
    #: the FDI's parameters of this run (its thresholds from the sensors: wtftc.sim.fdi)
    p_fdi: np.ndarray = field(default_factory=lambda: lay.defaults("fdi_params"))
    #: the FDI's test movement of resting blades (amplitude rad, period s, width s), or
    #: None ([fdi] test_pulse_deg = 0)
    test_pulse: tuple | None = None
    #: ROSCO's DISCON.IN for the run's turbine (controller = rosco; turbine files)
    rosco_discon: str | None = None
    #: its pitch gains retuned: (ω_pc, ζ_pc, the DISCON.IN's ω_pc, ζ_pc), or None
    rosco_retune: tuple | None = None

    plant = property(lambda self: self.loop.plant)
    controller = property(lambda self: self.loop.controller)
    table = property(lambda self: self.loop.table)
    table_key = property(lambda self: self.loop.table_key)
    p_turbine = property(lambda self: np.array(self.loop.p_turbine))

    @property
    def uses_rosco(self) -> bool:
        return self.raw["controller"] == "rosco"

    @property
    def uses_discon(self) -> bool:
        """A DISCON library wtftc did not build (controller = "discon", its [discon])."""
        return self.raw["controller"] == "discon"

    @property
    def library_controller(self) -> bool:
        """The controller is a DISCON library commanding the pitch and the generator torque
        itself (ROSCO's, or any other: wtftc.controller.LIBRARIES)."""
        return self.raw["controller"] in LIBRARIES

    @property
    def told_fault(self) -> bool:
        """Eq (49) is given the fault as it happens (case 3, an oracle)."""
        return self.case == ORACLE_CASE

    @property
    def uses_fdi(self) -> bool:
        """The accommodation is fed by wtftc's FDI (case 4)."""
        return self.case == FDI_CASE

    @property
    def model_name(self) -> str:
        """The plant's name, or on a turbine other than the NREL 5-MW the turbine's (its
        built-in name or its file's stem): what tables and figure titles call the run's
        turbine; ``openfast-<turbine>`` for a run in OpenFAST."""
        turbine = self.raw.get("turbine", turbine_file.DEFAULT)
        if self.raw.get("engine") == "openfast":  # the deck is the plant
            return f"openfast-{Path(turbine).stem}"
        return self.plant if turbine == turbine_file.DEFAULT else Path(turbine).stem

    @property
    def label(self) -> str:
        """The run's name: ``label``, else <model_name>_case<N>."""
        return self.raw.get("label") or f"{self.model_name}_case{self.case}"

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

    @property
    def transient(self) -> tuple[float, str]:
        """The start-up window left out of the metrics [s], and why (transient_window)."""
        return transient_window(self.raw, self.t_final, first_event(self.faults, self.wind))

    def initial_state(self) -> np.ndarray:
        """The trimmed initial state of the loop (wtftc.sim.trim) at the wind at t = 0."""
        rosco = None
        if self.uses_rosco:  # ROSCO's own laws set its operating point
            from wtftc.sim.rosco import discon_values

            rosco = discon_values(self.rosco_discon)
        elif self.uses_discon:
            rosco = rosco_like(self.raw["discon"]["input"])
        yd = self.yd if self.closed_loop_rest else None
        wind0 = float(self.wind(0.0))
        try:
            return trim(self.loop, self.p_ctrl, wind0, self.omega_offset, yd, rosco)
        except ConfigError:
            # no operating point at the first second (below cut-in in a turbulent field):
            # the lowest wind up to the run's mean that has one, where there is one
            mean = float(np.mean(self.wind(np.linspace(0.0, self.t_final, 401))))
            start = start_wind(self.loop, wind0, mean)
            if start == wind0:
                raise
            return trim(self.loop, self.p_ctrl, start, self.omega_offset, yd, rosco)

    @property
    def control_interval(self) -> float:
        """The controller's sampling interval [s] (0: continuous time)."""
        return self.loop.interval * self.dt

    @property
    def signed(self) -> bool:
        """Whether the controller has the paper's control sign (paper-notes defect 2)."""
        return "control_sign" in lay.names(rhs.controllers()[self.controller]["params"])

    def param(self, name: str) -> float:
        """A turbine parameter by its layout name."""
        return float(self.loop.p_turbine[lay.index("turbine_params", name)])


def _finite(val, field: str) -> float:
    """``val`` as a float if it is a finite number (not a bool, a string, a list, a table);
    else a ConfigError naming ``field``."""
    if isinstance(val, bool) or not isinstance(val, numbers.Real):
        raise ConfigError(field, val, "a finite number")
    try:
        x = float(val)
    except OverflowError:  # an integer beyond a float's range
        x = math.inf
    if not math.isfinite(x):
        raise ConfigError(field, val, "a finite number")
    return x


def _number(cfg, key, lo=None, hi=None) -> float:
    """``cfg[key]``: a finite number in (lo, hi] (either bound may be None)."""
    val = _finite(cfg[key], key)
    if lo is not None and val <= lo:
        raise ConfigError(key, cfg[key], f"a number > {lo}" if hi is None
                          else f"a number in ({lo}, {hi}]")
    if hi is not None and val > hi:
        raise ConfigError(key, cfg[key], f"a number <= {hi}" if lo is None
                          else f"a number in ({lo}, {hi}]")
    return val


def _seed(raw: dict) -> int:
    val = raw["seed"]
    if isinstance(val, bool) or not isinstance(val, numbers.Integral) \
            or not 0 <= val <= SEED_MAX:
        raise ConfigError("seed", val, f"an integer in [0, {SEED_MAX}] (0 to 2^63 - 1)")
    return int(val)


def load_toml(path: Path, field: str = "config") -> dict:
    """The table of a TOML file; anything unreadable is a ConfigError naming ``field`` (the
    option or key that gave the path)."""
    from wtftc.files import MAX_TOML_BYTES, check_user_file, read_user_bytes

    check_user_file(path, field, MAX_TOML_BYTES)  # a FIFO, a device, a folder: refused
    try:
        return tomllib.loads(read_user_bytes(path, field, MAX_TOML_BYTES).decode())
    except FileNotFoundError:
        raise ConfigError(field, str(path), "an existing TOML file") from None
    except IsADirectoryError:
        raise ConfigError(field, str(path), "a TOML file, not a folder") from None
    except OSError as exc:
        raise ConfigError(field, str(path), f"a readable TOML file ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(field, str(path), f"a UTF-8 text file in TOML (byte "
                          f"0x{exc.object[exc.start]:02x} at offset {exc.start} is not "
                          "UTF-8: a binary file?)") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(field, str(path), f"valid TOML ({exc})") from None


def make_config(cfg: dict | None = None) -> RunConfig:
    """Validate a configuration (as from TOML or the CLI), fill in the defaults, and
    resolve it: the turbine, the Cp table, the wind and the faults, once."""
    cfg = copy.deepcopy(cfg or {})
    for key in cfg:
        if key not in TOP_KEYS:
            raise ConfigError(key, cfg[key], "a known key: " + ", ".join(sorted(TOP_KEYS)))
    cfg, names = expand_controller(cfg)
    try:
        return _make_config(cfg)
    except ConfigError as exc:  # a range refused of a key a [controller] table set
        if exc.field in names:
            raise ConfigError(names[exc.field], exc.value, exc.allowed, where=exc.where) \
                from None
        raise


def _make_config(cfg: dict) -> RunConfig:
    check_record(cfg)
    raw = {**copy.deepcopy(DEFAULTS), **cfg}
    case = raw["case"]
    if isinstance(case, bool) or not isinstance(case, numbers.Integral) or case not in CASES:
        raise ConfigError("case", case, "1 (no fault), 2 (fault, controller unaware), "
                          "3 (fault known to eq (49)) or 4 (fault detected by wtftc's FDI)")
    raw["case"] = case = int(case)  # a NumPy integer too
    _engine(raw, cfg)
    _discon(raw)
    if not isinstance(raw["plant"], str) or raw["plant"] not in rhs.PLANTS:
        raise ConfigError("plant", raw["plant"], "one of " + ", ".join(
            f"{k} ({v['doc']})" for k, v in rhs.PLANTS.items()))
    controller = _controller(raw["controller"])
    if not isinstance(raw.get("label", ""), str):
        raise ConfigError("label", raw["label"], "a string (the run's name in tables)")
    _profile(raw, cfg)
    t_final, dt, seed, decimate = _timing(raw, given=cfg)
    interval = _control_interval(raw, dt, t_final)
    p_sensors = _sensors(raw, interval)
    if raw["controller"] == "rosco" and any(
            float(raw["sensors"].get(f"{s}_lag_s", 0.0)) > 0 for s in SENSOR_KEYS):
        raise ConfigError("sensors", raw["sensors"], "no lag with controller = rosco (it "
                          "reads the speeds with their noise only: docs/sensors.md)")
    _control_sign(raw)
    loads_options(raw)  # refused here, used by the metrics
    turbine = _turbine(raw)
    retune = _rosco(raw, turbine)
    p_ctrl, p_turbine = _parameters(raw, controller, turbine)
    _scale_speed_noise(raw, cfg, p_turbine, p_sensors)
    ref = _reference(raw, p_turbine)
    _peak_shaving(controller, p_ctrl, ref)
    table = _cp_table(raw, turbine)
    wind = wind_from_config(_wind_table(raw, p_turbine, table[0]), t_final=t_final, seed=seed)
    wind = _turbsim_wind(wind, turbine, p_turbine, t_final)
    faults = _faults(raw, case, t_final)
    transient_window(raw, t_final, first_event(faults, wind))
    offset, rest = _initial(raw)
    _torque_law(raw, p_turbine, wind, t_final, table[0])
    _region3(raw, p_turbine)
    loop = rhs.Loop(raw["plant"], controller, *table, tuple(float(x) for x in p_turbine),
                    interval=interval, delay=raw["control_delay"],
                    cut_in_wind=turbine.cut_in_wind_mps or 0.0)
    _check_envelope(loop, ref, offset)
    p_plant, cp_scale = _mismatch(raw, p_turbine)
    p_fdi, test_pulse = _fdi(raw, loop, p_sensors, interval * dt)
    return RunConfig(raw=raw, case=case, loop=loop, t_final=t_final, dt=dt, seed=seed,
                     decimate=decimate, reference=ref, p_ctrl=p_ctrl, wind=wind, faults=faults,
                     omega_offset=offset, closed_loop_rest=rest, p_sensors=p_sensors,
                     p_plant=p_plant,
                     cp_scale=cp_scale, p_fdi=p_fdi, test_pulse=test_pulse,
                     rosco_discon=turbine.rosco_discon, rosco_retune=retune)


def check_before_field(cfg: dict) -> None:
    """Validate ``cfg`` as :func:`make_config` does, before the TurbSim field it may read is
    made (wtftc.openfast.turbsim.ensure_field: minutes on a large grid), so that a value
    every run refuses is refused first: an NTM on TurbSim's field is checked on wtftc's own
    synthesis of it, and in OpenFAST on the uniform series; every other key as it is. A
    run in OpenFAST also needs a WTFTC_CACHE that OpenFAST can read its libraries from
    (wtftc.artefacts.loader.openfast_cache_dir), checked first."""
    if isinstance(cfg, dict) and cfg.get("engine") == "openfast":
        from wtftc.artefacts.loader import openfast_cache_dir

        openfast_cache_dir()
    wind = cfg.get("wind") if isinstance(cfg, dict) else None
    if not isinstance(wind, dict) or wind.get("kind") != "ntm":
        return  # no field is made: make_config checks the rest
    probe = copy.deepcopy(cfg)
    if probe.get("engine") == "openfast":
        table = probe.get("openfast", {})
        if isinstance(table, dict):
            probe["openfast"] = {**table, "wind": "uniform"}
        if wind.get("field", "turbsim") == "turbsim":
            probe["wind"] = {k: v for k, v in wind.items() if k != "field"}
    elif wind.get("field") == "turbsim":  # (the blades sample TurbSim's field only)
        probe["wind"] = {**{k: v for k, v in wind.items()
                            if k not in ("rotor_wind", "blade_speed_rad_s")},
                         "field": "spectral"}
    else:
        return  # no field is made: make_config checks it after
    rc = make_config(probe)
    check_deck(turbine_file.load(rc.raw.get("turbine", turbine_file.DEFAULT)))


def check_deck(turbine: turbine_file.Turbine) -> Path | None:
    """The turbine's OpenFAST deck (:func:`openfast_deck`, None when its file names none),
    checked before any work reads it: its main file a regular file (a FIFO would block)
    and its InflowWind file's hub height readable (what a TurbSim field is made for);
    else one line naming the turbine file's ``openfast_deck``."""
    deck = openfast_deck(turbine)
    if deck is None:
        return None
    try:
        check_user_file(deck, "openfast_deck")
        wind_field.deck_hub_height(deck)
    except ConfigError as exc:
        raise ConfigError("openfast_deck", exc.value, "an OpenFAST main input file "
                          f"(.fst): {exc.allowed}", where=turbine.path) from None
    except EngineError as exc:  # a key missing: the deck's fault, not a program's
        raise ConfigError("openfast_deck", str(deck), "a deck whose InflowWind file gives "
                          f"the hub height, RefHt ({exc})", where=turbine.path) from None
    return deck


def openfast_deck(turbine: turbine_file.Turbine) -> Path | None:
    """The turbine's OpenFAST deck (its main file; ``rosco:`` names one in ROSCO's
    wheel, inside its examples: :func:`check_rosco_path`), None when its file names none."""
    if not turbine.openfast_deck:
        return None
    if turbine.openfast_deck.startswith("rosco:"):
        check_rosco_path("openfast_deck", turbine.openfast_deck, turbine.path)
        if importlib.util.find_spec("rosco") is None:
            raise MissingExtra(f"turbine {turbine.name}", "ROSCO 2.10.6",
                               None, f"its OpenFAST deck is ROSCO's, "
                               f"{turbine.openfast_deck[len('rosco:'):]}",
                               OPENFAST_PACKAGES + " (docs/openfast.md)")
        from wtftc.sim.rosco import discon_path

        path = discon_path(turbine.openfast_deck)
        tree = discon_path(f"rosco:{ROSCO_TREE}").resolve()
        if not path.resolve().is_relative_to(tree):  # a link in the tree that leaves it
            raise ConfigError("openfast_deck", turbine.openfast_deck, f"a file inside "
                              f"ROSCO's installed examples, {tree} (this one resolves to "
                              f"{path.resolve()})", where=turbine.path)
        return path
    return Path(turbine.openfast_deck)


#: the cut-out wind speed at hub height [m/s] of the built-in turbines (the NREL 5-MW:
#: Jonkman et al. 2009, Table 1-1; the IEA 15-MW: Gaertner et al. 2020, Table 1-1), and of
#: a turbine file that sets none. IEC 61400-1's power-production cases (DLC 1.x) lie
#: between cut-in and cut-out; above it a turbine shuts down and idles (DLC 6.x)
CUT_OUT_WIND_MPS = 25.0


def cut_out_note(rc: RunConfig) -> str | None:
    """One line when the run's mean wind (over the run, at hub height) is above its
    turbine's cut-out: the controller then runs a turbine in power production where a
    real one has shut down. None otherwise."""
    turbine = turbine_file.load(rc.raw.get("turbine", turbine_file.DEFAULT))
    cut_out = getattr(turbine, "cut_out_wind_mps", None) or CUT_OUT_WIND_MPS
    mean = float(np.mean(rc.wind(np.linspace(0.0, rc.t_final, 2001))))
    if not mean > cut_out:
        return None
    return (f"note: {rc.label}: the mean wind, {mean:.4g} m/s, is above the turbine's "
            f"cut-out, {cut_out:g} m/s: a turbine shuts down there (IEC 61400-1's "
            "power-production cases, DLC 1.x, end at cut-out); this run keeps it producing")


#: the folder of ROSCO's wheel that ``rosco:<path>`` names files in: its examples (the
#: decks and DISCON.IN files of its test cases, Examples/Test_Cases/)
ROSCO_TREE = "Examples"


def check_rosco_path(key: str, spec, where: str | None = None) -> None:
    """A turbine file's ``rosco:<path>`` (``rosco_discon``, ``openfast_deck``) names a file
    inside ROSCO's installed examples, ``rosco:Examples/...``: a relative path with no
    ``..``, so that it cannot name the package's folders or anything beyond them. Any other
    value (a path of the user's own, None) is not checked here."""
    if not isinstance(spec, str) or not spec.startswith("rosco:"):
        return
    rel = spec[len("rosco:"):].replace("\\", "/")
    parts = [p for p in rel.split("/") if p not in ("", ".")]
    if rel.startswith("/") or ".." in parts or len(parts) < 2 or parts[0] != ROSCO_TREE:
        raise ConfigError(key, spec, f"rosco:{ROSCO_TREE}/<path>, a file inside ROSCO's "
                          f"installed examples (e.g. rosco:{ROSCO_TREE}/Test_Cases/NREL-5MW/"
                          "DISCON.IN): a relative path without '..'; a file elsewhere is "
                          "named by its own path", where=where)


#: what the OpenFAST engine needs from Python besides wtftc's core: ROSCO's wheel (the
#: built-in turbines' decks, ROSCO's controller) and openfast-io (OpenFAST's output read
#: back); both without their heavy dependencies, as `make setup` installs them
OPENFAST_PACKAGES = ("pip install pyzmq pyyaml ruamel.yaml 'deepdiff>8.0' && pip install "
                     "--no-deps rosco==2.10.6 openfast-io==5.0.0")


def _turbsim_wind(wind, turbine: turbine_file.Turbine, p_turbine: np.ndarray, t_final: float):
    """An NTM with ``field = "turbsim"`` read from TurbSim's field, the very one the
    OpenFAST engine runs on (the same wtftc.model.wind_field.turbsim_field); any other
    wind as it is."""
    desc = wind.describe()
    if desc["parameters"].get("field") != "turbsim":
        return wind
    deck = openfast_deck(turbine)
    if deck is None:
        raise ConfigError("wind.field", "turbsim", "a turbine whose file names its OpenFAST "
                          "deck (openfast_deck: the field's hub height is its InflowWind "
                          "RefHt), or field = \"spectral\"")
    radius = lay.values("turbine_params", p_turbine)["rotor_radius"]  # [m] the grid's size
    return wind_field.field_wind(wind_field.turbsim_field(desc, deck, radius, t_final), desc,
                                 t_final)


def _wind_table(raw: dict, p_turbine: np.ndarray, cp) -> dict:
    """The [wind] table, an NTM's ``rotor_radius_m`` filled in when not given: the run's
    turbine's rotor radius, the rotor-effective wind (docs/wind.md), as the load campaigns
    run it; ``rotor_radius_m = 0`` keeps the hub-height point. With ``rotor_wind =
    "blades"`` its ``blade_speed_rad_s`` too, when not given or 0: :func:`blade_speed` at
    the mean wind. Written into ``raw``, so that the saved configuration says which it was
    and re-runs to the same wind."""
    if not isinstance(raw["wind"], dict):
        raise ConfigError("wind", raw["wind"], "a table with kind = ...")
    wind = raw["wind"]
    if wind.get("kind") == "ntm" and "rotor_radius_m" not in wind:
        radius = lay.values("turbine_params", p_turbine)["rotor_radius"]  # [m]
        raw["wind"] = wind = {**wind, "rotor_radius_m": radius}
    mean = wind.get("mean_mps", field_default("ntm", "mean_mps"))
    if (wind.get("kind") == "ntm" and wind.get("rotor_wind") == "blades"
            and not wind.get("blade_speed_rad_s") and not isinstance(mean, bool)
            and isinstance(mean, float | int) and mean > 0):  # else refused with its name
        raw["wind"] = {**wind, "blade_speed_rad_s": blade_speed(p_turbine, cp, float(mean))}
    return raw["wind"]


def blade_speed(p_turbine, cp, mean_mps: float) -> float:
    """The rotor speed [rad/s] at which the blades sample an NTM of mean ``mean_mps``
    [m/s]: rated speed, or below it the speed of the best tip-speed ratio, λ* v / R (the
    region-2 law's aim; 0.95 rad/s at 8 m/s on the NREL 5-MW, where OpenFAST's mean over
    120 s of NTM B was 0.93-0.98 rad/s under ROSCO and the PI, two seeds)."""
    tp = lay.values("turbine_params", p_turbine)
    return float(min(tp["omega_g_rated"], cp.cp_max()[1] * mean_mps / tp["rotor_radius"]))


#: the [rosco] table: ROSCO's pitch PI retuned to this closed-loop target (docs/compare.md)
ROSCO_KEYS = {"omega_pc_rad_s": (0.01, 5.0), "zeta_pc": (0.1, 3.0)}


def _rosco(raw: dict, turbine) -> tuple | None:
    """The [rosco] table's target as (ω_pc, ζ_pc, ω_pc0, ζ_pc0), None without one; a
    [tuning] table left unresolved is refused (wtftc.campaign.tune.resolve turns it into
    each controller's own gains, as `wtftc run` and `wtftc sweep` do)."""
    if "tuning" in raw:
        raise ConfigError("tuning", raw["tuning"], "resolved before the run: "
                          "wtftc.campaign.tune.resolve(cfg) (wtftc run and sweep do it)")
    tab = raw.get("rosco")
    if tab is None:
        return None
    if not isinstance(tab, dict) or set(tab) - set(ROSCO_KEYS) or not tab:
        raise ConfigError("rosco", tab, "a table with " + ", ".join(ROSCO_KEYS))
    if raw["controller"] != "rosco":
        raise ConfigError("rosco", tab, "only with controller = rosco")
    if turbine.rosco_tuning is None:
        raise ConfigError("rosco", tab, "a turbine file with rosco_tuning (the target its "
                          "DISCON.IN was tuned for: docs/turbines.md)")
    out = []
    for (key, (lo, hi)), base in zip(ROSCO_KEYS.items(), turbine.rosco_tuning, strict=True):
        v = tab.get(key, base)
        if isinstance(v, bool) or not isinstance(v, int | float) or not lo <= v <= hi:
            raise ConfigError(f"rosco.{key}", v, f"a number in [{lo:g}, {hi:g}]")
        out.append(float(v))
    return (*out, *turbine.rosco_tuning)


#: the [loads] table (docs/loads.md): key → (default, low, high, what); m = 4 is the value
#: used for low-speed shafts and gearboxes (10 for composite blades)
LOADS_KEYS = {"shaft_wohler_exponent": (4.0, 1.0, 20.0, "the shaft's Wöhler exponent m of its "
                                                        "damage-equivalent load"),
              "reversal_hysteresis_deg": (0.1, 0.0, 10.0, "the turn-back a pitch reversal "
                                                          "needs [deg]"),
              "tower_wohler_exponent": (4.0, 1.0, 20.0, "the tower base's Wöhler exponent m "
                                                        "of its damage-equivalent load"),
              # WEIS's fatigue channels give the blade root's RootMyb slope 10
              "blade_wohler_exponent": (10.0, 1.0, 20.0, "the blade root's Wöhler exponent "
                                                         "m of its flapwise damage-equivalent "
                                                         "load"),
              # None: the default window, transient_window's
              "transient_s": (None, 0.0, 36000.0, "the start-up left out of every metric "
                                                  "[s]")}

#: the default start-up window left out of the metrics (docs/loads.md "The start-up
#: window"): 30 s, NREL's practice with FAST (30 s of 630-s runs discarded); a quarter of a
#: run shorter than 120 s; cut to the first fault's onset where that comes sooner
TRANSIENT_S = 30.0


def first_event(faults: list, wind) -> tuple[float, str] | None:
    """The first thing a run is about, (time [s], what): a fault's onset, a gust's (EOG,
    ECD) or a ramp's start, or a step of the wind; None for a wind and faults that have
    no moment."""
    events = [(f.onset_s, "the first fault's onset") for f in faults]
    kind = getattr(wind, "kind", None)
    if kind in ("eog", "ecd", "ramp"):
        events.append((float(wind.start_s), "the ramp's start" if kind == "ramp"
                       else "the gust's start"))
    if getattr(wind, "kind", None) == "steps" and len(wind.times):
        events.append((float(wind.times[0]), "the wind's first step"))
    return min(events, default=None)


def transient_window(raw: dict, t_final: float, event: tuple[float, str] | None
                     ) -> tuple[float, str]:
    """The start-up left out of every metric [s] and why it is that long: ``[loads]
    transient_s`` as given, which must end before the run does and not after its first
    event (first_event: a fault, a gust or a step inside it would go unscored); else
    TRANSIENT_S, a quarter of a run shorter than 120 s, cut to the event where that comes
    sooner."""
    given = loads_options(raw)["transient_s"]
    if given is not None:
        if given >= t_final:
            raise ConfigError("loads.transient_s", given, f"a start-up window shorter than "
                              f"the run (t_final_s = {t_final:g} s): something left to score")
        if event is not None and given > event[0]:
            raise ConfigError("loads.transient_s", given, f"at most {event[1]}, {event[0]:g} s "
                              "(a window over it would leave it unscored)")
        return float(given), "[loads] transient_s"
    window, why = min(TRANSIENT_S, t_final / 4), ("the default, 30 s" if t_final >= 120
                                                  else "the default, a quarter of the run")
    if event is not None and event[0] < window:
        return float(event[0]), f"cut to {event[1]} ({why} would cover it)"
    return float(window), why


def loads_options(raw: dict) -> dict:
    """The ``[loads]`` table's values, defaults filled in (docs/loads.md)."""
    table = raw.get("loads", {})
    if not isinstance(table, dict):
        raise ConfigError("loads", table, "a table with " + ", ".join(LOADS_KEYS))
    for key in table:
        if key not in LOADS_KEYS:
            raise ConfigError(f"loads.{key}", table[key], "a known key: " + ", ".join(LOADS_KEYS))
    out = {}
    for key, (default, lo, hi, what) in LOADS_KEYS.items():
        if table.get(key, default) is None:
            out[key] = None
            continue
        x = _finite(table.get(key, default), f"loads.{key}")
        if not lo <= x <= hi:
            raise ConfigError(f"loads.{key}", table[key], f"{what}: a number in [{lo:g}, {hi:g}]")
        out[key] = x
    return out


#: the [fdi] table: key → (default, low, high, what)
FDI_KEYS = {"target_false_alarms_per_hour": (fdi.TARGET_ALARMS_PER_HOUR, 1e-12, 3600.0,
                                             "false alarms per hour the threshold allows"),
            "test_pulse_deg": (0.0, 0.0, 5.0, "test movement of a blade resting at its "
                                              "lower stop [deg] (0: none)"),
            "test_period_s": (4.0, 0.1, 600.0, "period of the test movement [s]"),
            "test_width_s": (1.0, 0.01, 600.0, "duration of each test movement [s]"),
            "model_uncertainty": (None, 0.0, 1.0, "relative error of the actuator's time "
                                                  "constant the threshold allows for"),
            "rate_limited_uncertainty": (None, 0.0, 10.0, "offset allowed for while the "
                                         "blade is at its rate limit, in actuator lags"),
            "align_rate_per_s": (None, 0.0, 100.0, "the start-up alignment's initial rate "
                                 "[1/s] (0: none)")}
#: the FDI's start-up alignment rate on a host (derivation/fdi.py ``align_pull``): OpenFAST
#: and an exported library start the FDI's models at one noisy reading, wtftc's trim at
#: the true pitch (its default there: 0, none). 5 /s: the initial offset decays e^-5 within
#: about 3 s, and the pulled model follows the sensor noise by 0.16 σ at a 10-ms interval
#: (docs/fdi.md)
HOST_ALIGN_RATE = 5.0
#: the largest alignment rate × control interval: a held sample pulled harder than this
#: per interval is not a stable discrete filter (RK4's bound is 2.78; margin kept)
ALIGN_STEP_MAX = 1.0


def _check_pulse(vals: dict, interval: float) -> None:
    if vals["test_pulse_deg"] > 0 and interval == 0:
        raise ConfigError("fdi.test_pulse_deg", vals["test_pulse_deg"], "0 with "
                          "control_interval_s = 0 (the test movement is a sampled "
                          "controller's: e.g. profile = \"realistic\")")
    if vals["test_width_s"] >= vals["test_period_s"]:
        raise ConfigError("fdi.test_width_s", vals["test_width_s"],
                          f"less than fdi.test_period_s = {vals['test_period_s']:g} s")


def _fdi(raw: dict, loop: rhs.Loop, p_sensors: np.ndarray,
         interval: float) -> tuple[np.ndarray, tuple | None]:
    """The FDI's parameters, its thresholds from the run's sensors and the ``[fdi]``
    table's target false-alarm rate and model uncertainty, and its test movement
    (amplitude rad, period s, width s) or None (docs/fdi.md)."""
    table = raw.get("fdi", {})
    if not isinstance(table, dict):
        raise ConfigError("fdi", table, "a table with " + ", ".join(FDI_KEYS))
    vals = {}
    for key, (default, lo, hi, what) in FDI_KEYS.items():
        if default is None and key not in table:  # the FDI's own default (layout.json)
            vals[key] = None
            continue
        x = _finite(table.get(key, default), f"fdi.{key}")
        if not lo <= x <= hi:
            raise ConfigError(f"fdi.{key}", table[key], f"{what}: a number in [{lo:g}, {hi:g}]")
        vals[key] = x
    for key in table:
        if key not in FDI_KEYS:
            raise ConfigError(f"fdi.{key}", table[key], "a known key: " + ", ".join(FDI_KEYS))
    _check_pulse(vals, interval)
    pulse = (math.radians(vals["test_pulse_deg"]), vals["test_period_s"],
             vals["test_width_s"]) if vals["test_pulse_deg"] > 0 else None
    p = fdi.run_params(rhs.fdi_params(loop), p_sensors, interval,
                       vals["target_false_alarms_per_hour"], vals["model_uncertainty"],
                       vals["rate_limited_uncertainty"])
    align = vals["align_rate_per_s"]
    if align is None and raw["engine"] == "openfast":
        align = HOST_ALIGN_RATE
        if align * interval > ALIGN_STEP_MAX:  # the user gave the interval, not the rate
            raise ConfigError("control_interval_s", raw["control_interval_s"], "at most "
                              f"{ALIGN_STEP_MAX / align:g} s with engine = openfast: the FDI of "
                              "wtftc's controller library starts with an alignment that pulls "
                              f"at fdi.align_rate_per_s = {align:g} /s by default, and a "
                              f"pull over {ALIGN_STEP_MAX:g} per interval is unstable (or "
                              "set fdi.align_rate_per_s to at most 1 / the interval, 0 for "
                              "none)")
    if align is not None and align * interval > ALIGN_STEP_MAX:
        raise ConfigError("fdi.align_rate_per_s", align, f"at most {ALIGN_STEP_MAX:g} / "
                          f"the control interval ({ALIGN_STEP_MAX / interval:g} /s here): a "
                          "faster pull is unstable in the sampled FDI")
    if align is not None:
        p[lay.index("fdi_params", "fdi_k_align")] = align
    return p, pulse


def _openfast_actuator(raw: dict) -> None:
    """[openfast] actuator: true (the default) puts the benchmark pitch actuator between
    the controller and OpenFAST's blades; false is a host without one (the deck as it is:
    ElastoDyn takes the demand, limited in rate by the controller library), fault-free."""
    act = raw["openfast"]["actuator"]
    if not isinstance(act, bool):
        raise ConfigError("openfast.actuator", act, "true (the benchmark actuator in the "
                          "plant library, the default) or false (none: the blades take the "
                          "demand)")
    if not act and raw["case"] != 1:
        raise ConfigError("openfast.actuator", act, "true for case 2 or 4 (the faults are "
                          "the actuator's)")


def _engine(raw: dict, given: dict) -> None:
    """The engine: OpenFAST refuses the keys of wtftc's own plant and needs a controller
    it can call every control interval; its operating point is the tower plant's."""
    engine = raw["engine"]
    if not isinstance(engine, str) or engine not in ENGINES:
        raise ConfigError("engine", engine, "wtftc (its own plants) or openfast (OpenFAST "
                          "5.0 through ServoDyn: docs/openfast.md)")
    if engine != "openfast":
        if "openfast" in given:
            raise ConfigError("openfast", given["openfast"], "no [openfast] table with "
                              "engine = wtftc")
        return
    if importlib.util.find_spec("openfast_io") is None:  # checked before, not after, a run
        raise MissingExtra("engine = openfast", "openfast-io 5.0.0", None,
                           "OpenFAST's output reader", OPENFAST_PACKAGES)
    for key, why in OPENFAST_REFUSED.items():
        # what a saved run's config.toml holds is accepted back: the engine's own values
        if key in given and given[key] not in OPENFAST_ACCEPTED.get(key, ()):
            raise ConfigError(key, given[key], f"no {key} with engine = openfast: {why}")
    raw["plant"] = "tower"
    table = raw.get("openfast", {})
    if not isinstance(table, dict) or set(table) - {"wind", "actuator"}:
        raise ConfigError("openfast", table, "a table with the keys wind and actuator")
    raw["openfast"] = {"wind": table.get("wind", "turbsim"),
                       "actuator": table.get("actuator", True)}
    if raw["openfast"]["wind"] not in OPENFAST_WINDS:
        raise ConfigError("openfast.wind", raw["openfast"]["wind"], "turbsim (NTM and ETM "
                          "winds as TurbSim full fields, the default) or uniform (the "
                          "series wtftc's own plant gets, uniform over the rotor)")
    _openfast_actuator(raw)
    wind = raw.get("wind")
    if raw["openfast"]["wind"] == "turbsim" and isinstance(wind, dict) \
            and wind.get("kind") == "ntm":
        # OpenFAST reads TurbSim's field: the operating point it starts from is read from
        # the same field (wtftc.model.wind_field), not from wtftc's own synthesis
        if wind.get("field", "turbsim") != "turbsim":
            raise ConfigError("wind.field", wind["field"], '"turbsim" with engine = openfast '
                              "(OpenFAST reads TurbSim's field; [openfast] wind = "
                              '"uniform" gives it wtftc\'s own series instead)')
        raw["wind"] = {**wind, "field": "turbsim"}
    if raw["case"] == ORACLE_CASE:
        raise ConfigError("case", 3, "1, 2 or 4 with engine = openfast (case 3 tells eq (49) "
                          "the fault inside wtftc's loop; a DISCON library is not told)")
    if "profile" not in given and not given.get("control_interval_s"):
        raw["profile"] = "realistic"  # the engine's default: a library every interval
    if raw.get("profile", "ideal") == "ideal" and not given.get("control_interval_s"):
        raise ConfigError("profile", raw.get("profile", "ideal"), "realistic with engine = "
                          "openfast (or a control_interval_s > 0): OpenFAST calls the "
                          "controller as a library every control interval")


def _profile(raw: dict, given: dict) -> None:
    """Fill in the profile's defaults where the configuration is silent."""
    name = raw["profile"]
    if not isinstance(name, str) or name not in PROFILES:
        raise ConfigError("profile", name, "one of " + ", ".join(PROFILES)
                          + " (docs/sensors.md)")
    prof = PROFILES[name]
    interval = prof["control_interval_s"]
    if raw["controller"] in LIBRARIES and interval > 0:
        interval = ROSCO_INTERVAL_S  # ROSCO is called at its own interval (any library:
        # ROSCO's unless control_interval_s is given)
    raw.setdefault("control_interval_s", interval)
    if not isinstance(raw.get("sensors", {}), dict):
        raise ConfigError("sensors", raw["sensors"], "a table of sensor keys (docs/sensors.md)")
    raw["sensors"] = {**prof["sensors"], **raw.get("sensors", {})}
    for key, table in prof.items():
        if key == "turbine_params" and raw["controller"] in LIBRARIES:
            continue  # ROSCO (a DISCON library) commands the generator torque itself
        if key.endswith("_params") and isinstance(given.get(key, {}), dict):
            raw[key] = {**table, **given.get(key, {})}


#: ROSCO's call interval [s] (wtftc.sim.rosco.CONTROL_DT; not imported: ROSCO is optional)
ROSCO_INTERVAL_S = 0.005


def _control_interval(raw: dict, dt: float, t_final: float) -> int:
    """The controller's sampling interval in plant steps (0: continuous time). ROSCO
    samples the loop itself, every 5 ms: its compiled loop stays continuous (0)."""
    val = _finite(raw["control_interval_s"], "control_interval_s")
    if raw["controller"] == "discon":  # the interval OpenFAST calls the library at
        if not 0 < val <= 1.0 or raw["control_delay"] is not False:
            raise ConfigError("control_interval_s" if not 0 < val <= 1.0 else "control_delay",
                              val if not 0 < val <= 1.0 else raw["control_delay"],
                              "an interval in (0, 1] s and no delay with controller = discon "
                              "(OpenFAST calls the library every interval)")
        return 0
    if raw["controller"] == "rosco":
        if val not in (0.0, ROSCO_INTERVAL_S) or raw["control_delay"] is not False:
            raise ConfigError("control_interval_s" if val not in (0.0, ROSCO_INTERVAL_S)
                              else "control_delay", val if val not in (0.0, ROSCO_INTERVAL_S)
                              else raw["control_delay"],
                              f"{ROSCO_INTERVAL_S} s (or 0) and no delay with controller = "
                              "rosco: ROSCO is called at its own interval")
        return 0
    if val < 0 or val > 1.0:
        raise ConfigError("control_interval_s", val, "0 (continuous) or an interval in "
                          "(0, 1] s")
    if not isinstance(raw["control_delay"], bool):
        raise ConfigError("control_delay", raw["control_delay"], "true or false")
    if val == 0:
        if raw["control_delay"]:
            raise ConfigError("control_delay", True, "false with control_interval_s = 0 "
                              "(a delay of one interval needs an interval)")
        return 0
    n = round(val / dt)
    if n < 1 or abs(n * dt - val) > 1e-9 * max(val, 1.0):
        raise ConfigError("control_interval_s", val, f"a whole multiple of dt_s = {dt:g} s "
                          f"(e.g. {max(n, 1) * dt:g} s)")
    if abs(round(t_final / (n * dt)) * n * dt - t_final) > 1e-9 * max(t_final, 1.0):
        raise ConfigError("control_interval_s", val, f"an interval that divides t_final_s = "
                          f"{t_final:g} s into whole intervals")
    return n


#: the profile's speed noise keys and the shaft speed each is scaled by (its rated value
#: on that shaft: the rotor's, and the generator's on the HSS)
_SPEED_NOISE = {"rotor_speed_noise_rad_s": ("omega_g_rated",),
                "generator_speed_noise_rad_s": ("omega_g_rated", "gearbox_ratio")}


def _scale_speed_noise(raw: dict, given: dict, p_turbine: np.ndarray,
                       p_sensors: np.ndarray) -> None:
    """The profile's speed noise, quoted for the NREL 5-MW (the benchmark's σ), at the
    same fraction of rated speed on the run's turbine, on each shaft: 0.05 rad/s on a
    direct drive's 0.79-rad/s generator would be 6 % of rated (docs/sensors.md). A σ the
    configuration sets is kept as given; on the NREL 5-MW the factor is exactly 1."""
    tp = lay.values("turbine_params", p_turbine)
    ref = lay.values("turbine_params", lay.defaults("turbine_params"))
    own = given.get("sensors", {}) if isinstance(given.get("sensors"), dict) else {}
    for key, shaft in _SPEED_NOISE.items():
        if key in own or key not in PROFILES[raw["profile"]]["sensors"]:
            continue
        factor = math.prod(tp[n] for n in shaft) / math.prod(ref[n] for n in shaft)
        if factor == 1.0:
            continue
        raw["sensors"][key] = float(raw["sensors"][key]) * factor
        for m in _sensors_of(key.split("_noise")[0]):
            p_sensors[lay.index("sensor_params", f"sigma_{m}")] = raw["sensors"][key]


def _sensors(raw: dict, interval: int) -> np.ndarray:
    """The ``[sensors]`` table as the layout's sensor_params vector (SI)."""
    p = lay.defaults("sensor_params")
    for key, val in raw["sensors"].items():
        sig = next((s for s in SENSOR_KEYS if isinstance(key, str) and key.startswith(s + "_")),
                   None)
        rest = key[len(sig) + 1:] if sig else ""
        deg = sig is not None and SENSOR_KEYS[sig][1]
        unit = "_s" if rest.startswith("lag") else ("_deg" if deg else "_rad_s")
        kind = rest[:-len(unit)] if rest.endswith(unit) else None
        if kind not in _SENSOR_PARAM:
            raise ConfigError(f"sensors.{key}", val, "a known key: " + ", ".join(
                f"{s}_{k}{'_s' if k == 'lag' else ('_deg' if d else '_rad_s')}"
                for s, (_, d) in SENSOR_KEYS.items() for k in _SENSOR_PARAM))
        x = _finite(val, f"sensors.{key}")
        if kind != "bias" and x < 0:
            raise ConfigError(f"sensors.{key}", val, "a number >= 0")
        if kind in ("noise", "lag") and x > 0 and interval == 0 \
                and raw["controller"] not in LIBRARIES:
            raise ConfigError(f"sensors.{key}", val, "0 with control_interval_s = 0: noise and "
                              "lags need a sampled controller (e.g. control_interval_s = 0.01, "
                              "or profile = \"realistic\")")
        for m in _sensors_of(sig):
            p[lay.index("sensor_params", f"{_SENSOR_PARAM[kind]}_{m}")] = (
                np.radians(x) if unit == "_deg" else x)
    return p


def _torque_law(raw: dict, p_turbine: np.ndarray, wind, t_final: float, table) -> None:
    """The NREL 5-MW baseline torque law (in ``p_turbine`` and the saved configuration)
    when the configuration sets none and the wind falls below the turbine's rated wind
    speed during the run: with the fixed rated torque such a wind stalls the rotor (issue
    15). The paper's own wind keeps the paper's fixed torque (docs/cases.md), and ROSCO
    commands its own torque."""
    tp = raw.get("turbine_params", {})
    if raw["controller"] in LIBRARIES and p_turbine[lay.index("turbine_params",
                                                             "gen_torque_law")] != 0.0:
        raise ConfigError("turbine_params.gen_torque_law", tp.get("gen_torque_law"),
                          f"0 with controller = {raw['controller']} (the library commands "
                          "the generator torque)")
    if (raw["plant"] == "paper" or "gen_torque_law" in tp or raw["controller"] in LIBRARIES
            or raw["wind"].get("kind") == "paper_random"):
        return
    if float(np.min(wind(np.linspace(0.0, t_final, int(t_final / 0.1) + 2)))) \
            >= rated_wind_speed(p_turbine, table):
        return
    raw["turbine_params"] = {**tp, "gen_torque_law": 1.0}
    p_turbine[lay.index("turbine_params", "gen_torque_law")] = 1.0


def _region3(raw: dict, p_turbine: np.ndarray) -> None:
    """vs_constant_torque sets the baseline law's region 3: refused where the law does not
    run (gen_torque_law 0: a fixed torque, which it would silently leave as it is)."""
    value = p_turbine[lay.index("turbine_params", "vs_constant_torque")]
    if value != 0.0 and p_turbine[lay.index("turbine_params", "gen_torque_law")] != 1.0:
        raise ConfigError("turbine_params.vs_constant_torque",
                          raw.get("turbine_params", {}).get("vs_constant_torque", value),
                          "0 unless the baseline torque law runs (gen_torque_law = 1): it "
                          "sets that law's region 3, and a fixed torque has none")


def rated_wind_speed(p_turbine, table) -> float:
    """The wind [m/s] at which the rotor at its best Cp makes rated power,
    (2 T_rated ω_rated / (ρ π R² Cp_max))^(1/3): 11.42 m/s for the NREL 5-MW (Jonkman et
    al. 2009 give 11.4 m/s)."""
    tp = lay.values("turbine_params", p_turbine)
    power = tp["gen_torque_rated"] * tp["omega_g_rated"]
    area = math.pi * tp["rotor_radius"] ** 2
    return (2 * power / (tp["air_density"] * area * table.cp_max()[0])) ** (1 / 3)


def _mismatch(raw: dict, p_turbine: np.ndarray) -> tuple[np.ndarray | None, float]:
    """The plant's turbine parameters under the ``[mismatch]`` table's factors, and its Cp
    scale (None, 1.0 without mismatch)."""
    table = raw.get("mismatch", {})
    if not isinstance(table, dict):
        raise ConfigError("mismatch", table, "a table of factors: " + ", ".join(MISMATCH))
    if not table:
        return None, 1.0
    p = np.array(p_turbine, dtype=float)
    cp_scale = 1.0
    for key, val in table.items():
        if key not in MISMATCH:
            raise ConfigError(f"mismatch.{key}", val, "a known factor: " + ", ".join(MISMATCH))
        x = _finite(val, f"mismatch.{key}")
        if not 0.1 <= x <= 10:
            raise ConfigError(f"mismatch.{key}", val, "a factor in [0.1, 10] (1: no mismatch)")
        for name in MISMATCH[key]:
            p[lay.index("turbine_params", name)] *= x
        cp_scale = x if key == "cp_scale" else cp_scale
    check_turbine(p)
    return p, cp_scale


def _check_envelope(loop: rhs.Loop, ref: float, offset: float) -> None:
    """The reference and the start inside the loop's operating envelope (the one that ends
    a run as lost: sim.integrate.Envelope); outside, a run is lost at once, or driven out."""
    env, rated = Envelope.of(loop), loop.p_turbine[lay.index("turbine_params", "omega_g_rated")]
    lo, hi = env.low, env.high
    what = f"inside the operating envelope ({lo:.4g}-{hi:.4g} rad/s, layout.json envelope)"
    if not lo < ref < hi:
        raise ConfigError("reference_rad_s", ref, f"a speed {what}")
    if not lo < rated + offset < hi:
        raise ConfigError("initial.omega_r_offset_rad_s", offset, f"an offset from rated "
                          f"speed ({rated:.6g} rad/s) that starts the rotor {what}")


#: the keys of the ``[initial]`` table
INITIAL_KEYS = ("omega_r_offset_rad_s", "closed_loop_rest")


def _initial(raw: dict) -> tuple[float, bool]:
    """The ``[initial]`` table: the offset of the rotor speed from its trim [rad/s], and
    whether the plant and the controller start where the closed loop rests (default true;
    false: the controller at rest on its first measurements, as an exported DISCON library
    starts at its first call; wtftc.sim.trim)."""
    init = raw.get("initial", {})
    if not isinstance(init, dict):
        raise ConfigError("initial", init, "a table with " + ", ".join(INITIAL_KEYS))
    for key in init:
        if key not in INITIAL_KEYS:
            raise ConfigError(f"initial.{key}", init[key], "a known key: "
                              + ", ".join(INITIAL_KEYS))
    rest = init.get("closed_loop_rest", True)
    if not isinstance(rest, bool):
        raise ConfigError("initial.closed_loop_rest", rest, "true or false")
    return (_finite(init.get("omega_r_offset_rad_s", 0.0), "initial.omega_r_offset_rad_s"),
            rest)


def _discon(raw: dict) -> None:
    """controller = "discon": its [discon] table (library, input, their sha256: checked,
    and filled in where not given), in OpenFAST only, told of no fault (case 1 or 2)."""
    tab = raw.get("discon")
    if raw["controller"] != "discon":
        if tab is not None:
            raise ConfigError("discon", tab, 'none unless controller = "discon" (a DISCON '
                              "library's files; docs/openfast.md)")
        return
    if raw["engine"] != "openfast":
        raise ConfigError("controller", "discon", 'a DISCON library with engine = "openfast" '
                          "only (wtftc's own plants run its generated controllers and ROSCO)")
    if raw["case"] not in (FAULT_FREE_CASE, UNAWARE_CASE):
        raise ConfigError("case", raw["case"], "1 or 2 with controller = discon (a DISCON "
                          "library is told of no fault: accommodation none)")
    if not isinstance(tab, dict):
        raise ConfigError("discon", tab, "a table with library and input (the DISCON "
                          "library's path and its input file's) with controller = discon")
    for key in tab:
        if key not in DISCON_KEYS:
            raise ConfigError(f"discon.{key}", tab[key], "a known key: "
                              + ", ".join(DISCON_KEYS))
    raw["discon"] = dict(discon_files(tab, "discon"))


def rosco_like(path: str) -> dict | None:
    """A DISCON library's input file read as a ROSCO DISCON.IN, where it is one with the
    values ROSCO's operating point needs (wtftc.sim.trim.rosco_operating_point: the run
    starts where ROSCO's laws rest); else None (the turbine's baseline operating point)."""
    from wtftc.model.turbine_import import read_discon

    try:
        values = read_discon(Path(path), "discon.input")
        for key in ("PC_RefSpd", "PC_FinePit", "PS_Mode", "VS_TSRopt", "VS_MinOMSpd"):
            np.array(values[key].split(), dtype=float)[0]  # noqa: B018 - a number, or out
        if float(values["PS_Mode"].split()[0]) > 0:
            for key in ("PS_WindSpeeds", "PS_BldPitchMin"):
                np.array(values[key].split(), dtype=float)  # noqa: B018
    except (ConfigError, KeyError, ValueError, IndexError):
        return None
    return values


def _controller(name) -> str:
    """The registered controller a name runs ("external" for ROSCO, which drives it)."""
    regs = {k: v for k, v in rhs.controllers().items() if k != "external"}
    if name == "discon":  # a DISCON library: it drives the loop, as ROSCO does
        return "external"
    if name == "rosco":
        from wtftc.sim import rosco

        reason = rosco.available()
        if reason:
            raise ConfigError("controller", "rosco", reason)
        return "external"
    if not isinstance(name, str) or name not in regs:
        raise ConfigError("controller", name, "one of " + ", ".join([*regs, *LIBRARIES])
                          + " (docs/controllers.md)")
    return name


def _timing(raw: dict, given: dict | None = None) -> tuple[float, float, int, int]:
    """t_final, dt, seed and the output decimation. An ``output_rate_hz`` the
    configuration ``given`` sets must be reachable (at most one output per step, its
    interval a whole number of steps); the default's is lowered to one per step where
    dt_s is longer than its interval, and ``raw`` records the rate used."""
    t_final = float(_number(raw, "t_final_s", lo=0, hi=36000))
    # the upper bound is only a sanity cap: the real limit is checked against the closed
    # loop's fastest mode before the run (wtftc.sim.stability.check_dt)
    dt = float(_number(raw, "dt_s", lo=0, hi=10.0))
    if dt > t_final:
        raise ConfigError("dt_s", dt, f"at most t_final_s = {t_final}")
    if t_final / dt > MAX_STEPS:
        raise ConfigError("dt_s", dt, f"a step that takes at most {MAX_STEPS:.3g} steps over "
                          f"t_final_s = {t_final:g} s (this one takes {t_final / dt:.3g}): "
                          f"dt_s >= {t_final / MAX_STEPS:.3g} s, or a shorter t_final_s")
    n_steps = round(t_final / dt)
    if abs(n_steps * dt - t_final) > 1e-9 * max(t_final, 1.0):
        raise ConfigError("t_final_s", t_final, f"a whole number of steps of dt_s = {dt:g} s "
                          f"(e.g. {n_steps * dt:g} or {(n_steps + 1) * dt:g} s): the run "
                          "would otherwise end at a time other than the one asked for")
    seed = _seed(raw)
    rate = float(_number(raw, "output_rate_hz", lo=0, hi=1e6))
    if rate * t_final < 1.0:  # fewer than two outputs: no series to plot or score
        raise ConfigError("output_rate_hz", raw["output_rate_hz"], f"a rate of at least "
                          f"1/t_final_s = {1.0 / t_final:.6g} Hz (at least two outputs over "
                          f"the run's {t_final:g} s)")
    decimate = max(1, int(round(1.0 / (rate * dt))))
    if abs(decimate * dt * rate - 1.0) > 1e-6:
        if "output_rate_hz" in (given or {}):
            # a rate above 1/dt_s used to be lowered to it silently, while the saved
            # configuration kept the rate asked for (issue 30)
            raise ConfigError("output_rate_hz", raw["output_rate_hz"], (
                f"at most 1/dt_s = {1.0 / dt:.6g} Hz (one output per step of dt_s = "
                f"{dt:g} s)") if rate * dt > 1.0 + 1e-6 else (
                f"a rate whose interval is a whole number of steps of dt_s = {dt:g} s "
                f"(e.g. {1.0 / (decimate * dt):.6g} Hz)"))
        raw["output_rate_hz"] = 1.0 / (decimate * dt)  # the default's, as used
    return t_final, dt, seed, decimate


def _control_sign(raw: dict) -> None:
    sign = raw["control_sign"]
    if isinstance(sign, bool) or not isinstance(sign, numbers.Real) or sign not in (-1, 1):
        raise ConfigError("control_sign", sign, "-1 (corrected, default) or +1 (as written, "
                          "stalls the rotor: paper-notes defect 2)")


def _peak_shaving(controller: str, p_ctrl, ref: float) -> None:
    """A peak-shaving floor rises from its start speed to the reference speed: the start
    must lie below the reference (derivation/design.py pitch_floor). ``controller``: the
    registered one (ROSCO's is "external")."""
    group = rhs.controllers()[controller]["params"]
    for name in (n for n in lay.names(group) if n.endswith("_ps_speed")):
        val = float(p_ctrl[lay.index(group, name)])
        if val >= ref:
            raise ConfigError(f"controller_params.{name}", val, f"a speed below the "
                              f"reference (here {ref:g} rad/s): the floor rises between them")


def _reference(raw: dict, p_turbine) -> float:
    """The rotor-speed reference: given, the paper's on its plant, else the run's turbine's
    rated speed (not the layout's: a turbine with another rated speed regulates to it)."""
    raw.setdefault("reference_rad_s", PAPER_REFERENCE if raw["plant"] == "paper" else
                   float(p_turbine[lay.index("turbine_params", "omega_g_rated")]))
    raw["reference_rad_s"] = _number(raw, "reference_rad_s", lo=0, hi=10)
    return raw["reference_rad_s"]


def _turbine(raw: dict) -> turbine_file.Turbine:
    """The run's turbine (``turbine``: a built-in name or a turbine file's path; the NREL
    5-MW by default, and then not written into the saved configuration)."""
    name = raw.get("turbine", turbine_file.DEFAULT)
    if not isinstance(name, str):
        raise ConfigError("turbine", name, "a built-in turbine (" + ", ".join(
            turbine_file.BUILTIN) + ") or the path of a turbine file (.toml)")
    turbine = turbine_file.load(name)
    for key in ("rosco_discon", "openfast_deck"):
        check_rosco_path(key, getattr(turbine, key), turbine.path)
    if turbine.rosco_discon is None and raw["controller"] == "rosco":
        raise ConfigError("turbine", name, "a turbine whose file names ROSCO's DISCON.IN "
                          "for it (rosco_discon) with controller = rosco (docs/turbines.md)")
    if raw["plant"] == "paper" and turbine.name != turbine_file.DEFAULT:
        raise ConfigError("turbine", name, "nrel5mw with plant = paper (the paper's plant "
                          "is its own, eq (10)); plant = nrel5mw or tower runs any turbine file")
    return turbine


def _turbine_vector(raw: dict, turbine: turbine_file.Turbine) -> np.ndarray:
    """The turbine file's parameters with the run's overrides, checked: a value from the
    file that is out of range is named with the file."""
    over = _overrides(raw, "turbine_params", "turbine_params")
    base = lay.values("turbine_params", turbine.vector())
    p_turbine = lay.vector("turbine_params", {**base, **over})
    try:
        check_turbine(p_turbine, given=over)
    except ConfigError as exc:
        name = exc.field.split(".", 1)[1]
        if name in over:
            raise
        raise ConfigError(f"params.{name}", exc.value, exc.allowed,
                          where=turbine.path) from None
    return p_turbine


def _parameters(raw: dict, controller: str, turbine: turbine_file.Turbine
                ) -> tuple[np.ndarray, np.ndarray]:
    """The controller's and the turbine's parameter vectors, defaults with overrides; the
    turbine's from its file, checked against :data:`TURBINE_RANGES`; the controller's
    facts of the turbine (its inertia, limits, ...) from it (wtftc.model.tuning)."""
    ctrl_group = rhs.controllers()[controller]["params"]
    signed = "control_sign" in lay.names(ctrl_group)
    if not signed and raw["control_sign"] != -1:
        raise ConfigError("control_sign", raw["control_sign"], f"-1: the {raw['controller']} "
                          "controller has no sign to flip (only the paper's design has it: "
                          "paper-notes defect 2)")
    table = raw.get("controller_params")
    told = [n for n in (table if isinstance(table, dict) else {})
            if isinstance(n, str) and n.startswith(("rho_hat", "lock_hat", "ubar_hat"))]
    if told:  # the generated law takes them from its known_fault input, set by the case
        raise ConfigError(f"controller_params.{told[0]}", raw["controller_params"][told[0]],
                          "not a parameter: eq (49) is told the fault by the case (3: the "
                          "true fault; 4: wtftc's FDI), so a value here would be ignored")
    p_turbine = _turbine_vector(raw, turbine)
    # the PI baseline's pitch-loop target: the one the turbine's reference deck tunes ROSCO's
    # pitch PI to, where the file gives it (the NREL 5-MW's is the layout's default)
    target = dict(zip(("pi_omega_n", "pi_zeta"), turbine.rosco_tuning, strict=True)) \
        if turbine.rosco_tuning and "pi_omega_n" in lay.names(ctrl_group) else {}
    p_ctrl = lay.vector(ctrl_group, {**tuning.turbine_params_of(ctrl_group, p_turbine), **target,
                                     **_overrides(raw, "controller_params", ctrl_group),
                                     **({"control_sign": raw["control_sign"]} if signed else {})})
    vals = check_ranges(ctrl_group, p_ctrl, "controller_params")
    for flag in (n for n in vals if n in CONTROLLER_FLAGS):
        if vals[flag] not in (0.0, 1.0):
            raise ConfigError(f"controller_params.{flag}", vals[flag],
                              "0 or 1 (docs/controllers.md)")
    for low in (n for n in vals if n.endswith("pitch_min")):  # a controller's pitch range
        high = low.replace("pitch_min", "pitch_max")
        if high in vals and vals[low] >= vals[high]:
            raise ConfigError(f"controller_params.{low}", vals[low],
                              f"{low} < {high} (here {high} = {vals[high]:g})")
    return p_ctrl, p_turbine


def _overrides(raw: dict, key: str, group: str) -> dict:
    """The table ``raw[key]`` of overrides of the layout group ``group``: each a finite
    number, or for the prefix of numbered entries (``K_obs`` for ``K_obs_1..4``) a list of
    as many; a ConfigError names ``key.name`` (and the list index) otherwise."""
    over = raw.get(key, {})
    if not isinstance(over, dict):
        raise ConfigError(key, over, f"a table of {group} names = numbers "
                          "(see generated/layout.json)")
    all_names = lay.names(group)
    out = {}
    for name, val in over.items():
        field = f"{key}.{name}"
        if name == "control_sign":
            raise ConfigError(field, val, "set control_sign at the top level (or --sign)")
        if name in all_names:
            out[name] = _finite(val, field)
            continue
        members = [n for n in all_names
                   if n.rsplit("_", 1)[0] == name and n.rsplit("_", 1)[-1].isdigit()]
        if not members:
            prefixes = sorted({n.rsplit("_", 1)[0] for n in all_names
                               if "_" in n and n.rsplit("_", 1)[-1].isdigit()})
            known = ", ".join(n for n in all_names if n != "control_sign")
            raise ConfigError(field, val, f"a name of {group}: {known}" + (
                f" (or the prefix of numbered ones: {', '.join(prefixes)})" if prefixes else ""))
        if not isinstance(val, list) or len(val) != len(members):
            raise ConfigError(field, val, f"a list of {len(members)} finite numbers "
                              f"({', '.join(members)})")
        out[name] = [_finite(x, f"{field}[{i}]") for i, x in enumerate(val)]
    return out


def check_ranges(group: str, vec, key: str) -> dict[str, float]:
    """Refuse a parameter vector of a layout group with a value that is not finite or is
    outside its physical range (layout.json ``valid``): a ConfigError naming
    ``<key>.<name>``, the value and the range. Returns the values by name."""
    ranges = _ranges(group)
    vals = lay.values(group, vec)
    for name, val in vals.items():
        field = f"{key}.{name}"
        if not math.isfinite(val):
            raise ConfigError(field, val, "a finite number")
        if name in ranges:
            lo, hi, lo_open, hi_open, _ = ranges[name]
            if val < lo or val > hi or (lo_open and val == lo) or (hi_open and val == hi):
                raise ConfigError(field, val, range_text(*ranges[name]))
    return vals


def check_turbine(p_turbine, given=()) -> None:
    """Refuse a turbine parameter vector with a value outside :data:`TURBINE_RANGES`, out of
    :data:`TURBINE_ORDER`, or a flag other than 0 or 1: a ConfigError naming
    ``turbine_params.<name>``, the value and the allowed range. ``given``: the names the
    user set (an order error names the one of the pair that was set)."""
    vals = check_ranges("turbine_params", p_turbine, "turbine_params")
    for low, high in TURBINE_ORDER:
        if vals[low] >= vals[high]:
            name, other = (high, low) if high in given and low not in given else (low, high)
            raise ConfigError(f"turbine_params.{name}", vals[name],
                              f"{low} < {high} (here {other} = {vals[other]:g})")
    for flag in TURBINE_FLAGS:
        if vals[flag] not in (0.0, 1.0):
            raise ConfigError(f"turbine_params.{flag}", vals[flag], "0 or 1 (docs/running.md)")


def _faults(raw: dict, case: int, t_final: float) -> list:
    if case == FAULT_FREE_CASE:
        if raw.get("fault"):
            raise ConfigError("fault", raw["fault"], "no fault in case 1 (use case 2, 3 or "
                              "4, or a [controller] table, whose accommodation sets the case)")
        return []
    default = "fault" not in raw
    raw.setdefault("fault", copy.deepcopy(DEFAULT_FAULT))
    faults = parse_faults(raw["fault"])
    for k, f in enumerate(faults):
        if f.onset_s >= t_final:
            raise ConfigError(f"fault[{k}].onset_s", f.onset_s,
                              f"a time before t_final_s = {t_final:g} s"
                              + (" (the default fault starts at 20 s: a longer --t-final, or "
                                 "a [[fault]] table with its own onset_s)" if default else ""))
    return faults


def _cp_table(raw: dict, turbine: turbine_file.Turbine) -> tuple:
    """The Cp table and its key (the packaged NREL 5-MW table, or the file's sha256): the
    ``cp_table`` given, else the turbine's."""
    path = raw.get("cp_table")
    if (path is None or path == "") and turbine.name == turbine_file.DEFAULT \
            and turbine.path == str(turbine_file.path_of(turbine_file.DEFAULT)):
        return nrel5mw_cp_table(), "nrel5mw"
    if path is None or path == "":
        table = turbine.table
        return table, table.sha256[:12]
    if not isinstance(path, str):
        raise ConfigError("cp_table", path, "the path of a Cp table file (a string), in the "
                          "ROSCO Cp_Ct_Cq text format")
    table = read_cp_table(Path(path))
    return table, table.sha256[:12]


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
