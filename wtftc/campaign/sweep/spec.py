"""The sweep file: its validation (every error names its key), the runs that follow from it
deterministically, each with a stable run id, and their grouping into Dask tasks."""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign.compare import (
    PROFILE,
    column_tables,
    is_rosco,
    resolve_columns,
    variant_config,
)
from wtftc.campaign.sweep.dlc import parse_dlc
from wtftc.errors import ConfigError
from wtftc.model import faults, turbine_file, wind
from wtftc.sim import rhs

TOP_KEYS = {"name", "mode", "samples", "sampling_seed", "t_final_s", "dt_s", "output_rate_hz",
            "batch_size", "controllers", "optional_controllers", "plants", "wind", "fault",
            "profile", "mismatch", "fault_free_twins", "turbine", "dlc", "tuning", "engine", "host"}
#: the [mismatch] table's keys: the plant's factors against the controllers' model
#: (config.MISMATCH), each an axis like any other (1.0: none)
MISMATCH_KEYS = tuple(config.MISMATCH)
WIND_KEYS = {"mean_mps", "turbulence_class", "seed", "rotor_radius_m", "field", "kind",
             "event_s", "step_mps", "ramp_mps", "ramp_s", "sign", "turbine_class"}
#: the kinds a sweep's wind may be ([wind] kind, an axis): the NTM, or a deterministic wind
#: built around the scenario's mean_mps (:func:`deterministic_wind`), run once (no seed)
WIND_KINDS = ("ntm", "eog", "ecd", "steps", "ramp")
#: the deterministic winds' shape: [wind] key → (default, low, high, what), one value for
#: the sweep (the WEIS controller test bench's step and ramp are one size each)
WIND_SHAPE = {"event_s": (40.0, 0.0, 36000.0, "when the gust, step or ramp starts [s]"),
              "step_mps": (2.0, -30.0, 30.0, "the step's size [m/s], centred on mean_mps"),
              "ramp_mps": (4.0, -30.0, 30.0, "the ramp's change [m/s], centred on mean_mps"),
              "ramp_s": (125.0, 0.0, 36000.0, "the ramp's duration [s]")}
#: one fault per run, an actuator's or a sensor's (model/faults.py's list), or none
FAULT_TYPES = ("none", *faults.ACTUATOR_FAULT_TYPES, *faults.SENSOR_FAULT_TYPES)
#: the fault table key each fault type reads its magnitude from
MAGNITUDE = {t: faults.TYPES[t].magnitude for t in FAULT_TYPES[1:]}
FAULT_KEYS = {"type", "blade", "onset_s", "sensor", *MAGNITUDE.values()}
#: the sensor faults' magnitude keys: (default, low, high, unit) of their axes
SENSOR_MAGNITUDES = {"value_deg": (5.0, -90.0, 90.0, "deg"), "gain": (1.2, 0.0, 10.0, "-"),
                     "offset_deg": (1.0, -90.0, 90.0, "deg"),
                     "rate_deg_s": (0.01, -10.0, 10.0, "deg/s"),
                     "factor": (3.0, 0.0, 100.0, "-"),
                     "value_rad_s": (1.4, 0.0, 500.0, "rad/s"),
                     "offset_rad_s": (0.1, -100.0, 100.0, "rad/s")}
#: the dataset's column of each magnitude key
MAGNITUDE_COLUMN = {"angle_deg": "stuck_angle_deg", "rho": "rho", "severity": "severity",
                    "target_deg": "runaway_target_deg",
                    **{k: f"sensor_{k}" for k in SENSOR_MAGNITUDES}}
TURBULENCE_CLASSES = tuple(wind.I_REF)
PLANTS = tuple(rhs.PLANTS)
#: the axes that random mode crosses with every scenario, rather than draws (a tuned
#: family runs every scenario at each of its targets)
CROSSED = ("controllers", "plants", "tuning.omega_n_rad_s", "tuning.zeta")
#: the [tuning] table's keys (wtftc.campaign.tune.TUNING_KEYS): two axes and a setting
TUNING_AXES = ("omega_n_rad_s", "zeta")


@dataclass(frozen=True)
class Axis:
    """One swept quantity: discrete ``values``, or a ``range`` (lo, hi) with ``n`` grid
    points (grid mode) or uniform draws (random mode)."""
    key: str
    values: tuple | None = None
    range: tuple | None = None
    n: int | None = None
    integer: bool = False

    def grid(self) -> list:
        if self.values is not None:
            return list(self.values)
        lo, hi = self.range
        if self.integer:
            return list(range(int(lo), int(hi) + 1))
        return [float(v) for v in np.linspace(lo, hi, self.n)]

    def size(self) -> int:
        """len(self.grid()), without building it."""
        if self.values is not None:
            return len(self.values)
        if self.integer:
            return int(self.range[1]) - int(self.range[0]) + 1
        return int(self.n)

    def draw(self, rng: np.random.Generator):
        if self.values is not None:
            return self.values[int(rng.integers(len(self.values)))]
        lo, hi = self.range
        if self.integer:
            return int(rng.integers(int(lo), int(hi) + 1))
        return float(rng.uniform(lo, hi))


@dataclass
class Sweep:
    raw: dict  # the parsed sweep file
    text: str  # its canonical form (sorted JSON), hashed into sweep_id
    mode: str
    samples: int | None
    sampling_seed: int
    t_final: float
    dt: float
    output_rate_hz: float
    batch_size: int
    axes: list[Axis]
    profile: str = "realistic"
    #: random mode: every faulty scenario also run without its fault (same wind, seed and
    #: mismatch), so that the summary can give each fault's RMS ratio to its twin's
    fault_free_twins: bool = False
    #: every run's turbine (None: the NREL 5-MW)
    turbine: str | None = None
    #: every run's NTM averaged over a rotor disk of this radius [m] (None: the point)
    rotor_radius: float | None = None
    #: the engine every run is simulated in (config.ENGINES): wtftc's plants, or OpenFAST
    engine: str = "wtftc"
    #: where wtftc's plant takes every run's NTM from ([wind] field): None, its own
    #: synthesis; "turbsim", the TurbSim field OpenFAST runs on (in OpenFAST: always)
    wind_field: str | None = None
    #: the deterministic winds' shape ([wind] event_s, step_mps, ramp_mps, ramp_s, sign,
    #: turbine_class), None for a sweep of NTM winds only
    wind_shape: dict | None = None
    #: what stands between the controllers and the plant (HOSTS): the benchmark's sensors
    #: and actuator, or the controller as its deck ships it
    host: str = "benchmark"
    #: every column, the optional ones too: name → wtftc.controller.Controller, in the
    #: file's order (the summary's order)
    columns: dict = field(default_factory=dict)
    #: the names of the optional columns (ROSCO's: run where it is installed)
    optional: tuple = ()

    @property
    def sweep_id(self) -> str:
        """A hash of the file's canonical form (its columns' settings are recorded beside
        it: :meth:`record`, checked on a resume)."""
        return hashlib.sha256(self.text.encode()).hexdigest()[:16]

    def record(self) -> dict:
        """The resolved columns, as a sweep file's ``controllers`` and
        ``optional_controllers`` that need no presets file (what sweep.json keeps)."""
        main = {c: v for c, v in self.columns.items() if c not in self.optional}
        opt = {c: v for c, v in self.columns.items() if c in self.optional}
        return {"controllers": column_tables(main)} | (
            {"optional_controllers": column_tables(opt)} if opt else {})

    def axis(self, key: str) -> Axis:
        return next(a for a in self.axes if a.key == key)


# ---------------------------------------------------------------------------- validation

def _is_num(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _check_value(key: str, v, kind: str, lo=None, hi=None, lo_open=False, choices=None):
    if choices is not None:
        if v not in choices:
            raise ConfigError(key, v, "one of " + ", ".join(map(str, choices)))
        return v
    if kind == "int":
        if isinstance(v, bool) or not isinstance(v, int):
            raise ConfigError(key, v, "an integer")
    elif kind == "angle":
        if v == "current":
            return v
        if not _is_num(v):
            raise ConfigError(key, v, '"current" or an angle in [0, 90] degrees')
    elif not _is_num(v):
        raise ConfigError(key, v, "a finite number")
    if (lo is not None and (v <= lo if lo_open else v < lo)) or (hi is not None and v > hi):
        left = "(" if lo_open else "["
        raise ConfigError(key, v, f"a value in {left}{lo}, {hi}]")
    return float(v) if kind in ("float", "angle") else v


def _axis(key: str, spec, kind: str, mode: str, **bounds) -> Axis:
    """A list of values, a scalar, or a range table {min, max, n} (n: grid mode only;
    integer ranges take every integer in [min, max])."""
    if isinstance(spec, dict):
        return _range_axis(key, spec, kind, mode, **bounds)
    values = spec if isinstance(spec, list) else [spec]
    if not values:
        raise ConfigError(key, spec, "at least one value (an empty list sweeps nothing)")
    checked = tuple(_check_value(key, v, kind, **bounds) for v in values)
    if len(set(checked)) != len(checked):
        raise ConfigError(key, spec, "distinct values")
    return Axis(key, values=checked, integer=kind == "int")


def _range_axis(key: str, spec: dict, kind: str, mode: str, **bounds) -> Axis:
    if "choices" in bounds or kind == "angle":
        raise ConfigError(key, spec, "a list of values (this key has no range form)")
    extra = set(spec) - {"min", "max", "n"}
    if extra:
        raise ConfigError(f"{key}.{sorted(extra)[0]}", spec[sorted(extra)[0]],
                          "a key of a range: min, max, n")
    for k in ("min", "max"):
        if k not in spec:
            raise ConfigError(f"{key}.{k}", None, f"a {k} for the range")
    lo = _check_value(f"{key}.min", spec["min"], kind, **bounds)
    hi = _check_value(f"{key}.max", spec["max"], kind, **bounds)
    if hi < lo:
        raise ConfigError(f"{key}.max", hi, f"at least {key}.min = {lo} (an empty range)")
    n = None
    if kind != "int":
        if mode == "grid":
            n = spec.get("n")
            if isinstance(n, bool) or not isinstance(n, int) or n < 1:
                raise ConfigError(f"{key}.n", n, "an integer >= 1: the number of grid "
                                  "points (grid mode)")
            if n == 1 and hi != lo:
                raise ConfigError(f"{key}.n", n, "at least 2 for a range with min < max")
        elif "n" in spec:
            raise ConfigError(f"{key}.n", spec["n"], "no n in random mode (values are "
                              "drawn uniformly from [min, max])")
    elif "n" in spec:
        raise ConfigError(f"{key}.n", spec["n"], "no n for an integer range (every "
                          "integer in [min, max])")
    return Axis(key, range=(lo, hi), n=n, integer=kind == "int")


def _check_top(raw: dict) -> tuple[str, int | None]:
    """The sweep file is a table of known keys; its mode and number of samples."""
    if not isinstance(raw, dict):
        raise ConfigError("sweep", raw, "a TOML table")
    for key in raw:
        if key not in TOP_KEYS:
            raise ConfigError(key, raw[key], "a sweep key: " + ", ".join(sorted(TOP_KEYS)))
    mode = raw.get("mode", "grid")
    if mode not in ("grid", "random"):
        raise ConfigError("mode", mode, '"grid" (every combination) or "random" (samples '
                          "draws)")
    samples = raw.get("samples")
    if mode == "random":
        if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= 10**6:
            raise ConfigError("samples", samples, "an integer in [1, 1000000]: the number of "
                              "random scenarios (random mode)")
    elif samples is not None:
        raise ConfigError("samples", samples, 'only with mode = "random"')
    return mode, samples


def _settings(raw: dict) -> dict:
    """The settings every run shares, with their defaults: Sweep's fields by name."""
    engine = _engine(raw)
    return {
        "sampling_seed": _check_value("sampling_seed", raw.get("sampling_seed", 0), "int",
                                      lo=0),
        "t_final": _check_value("t_final_s", raw.get("t_final_s", 60.0), "float", lo=0,
                                hi=36000, lo_open=True),
        "dt": _check_value("dt_s", raw.get("dt_s", 1e-3), "float", lo=0, hi=0.1,
                           lo_open=True),
        "output_rate_hz": _check_value("output_rate_hz", raw.get("output_rate_hz", 10.0),
                                       "float", lo=0, hi=1e6, lo_open=True),
        # an OpenFAST run is a process of its own: one run a task
        "batch_size": _check_value("batch_size", raw.get("batch_size", 8), "int", lo=1,
                                   hi=10000) if engine == "wtftc" else 1,
        "profile": _profile(raw.get("profile", PROFILE)),
        "fault_free_twins": _twins(raw.get("fault_free_twins", False), raw),
        "turbine": _turbine(raw.get("turbine")),
        "rotor_radius": _rotor_radius(raw),
        "engine": engine,
        "wind_field": _wind_field(raw),
        "host": _host(raw),
    }


#: what stands between a sweep's controllers and the plant ([host]): the benchmark's
#: sensors and pitch actuator (the default), or the controller as its deck ships it
HOSTS = ("benchmark", "as_shipped")


def _host(raw: dict) -> str:
    """host: "benchmark" (the sweep's profile; in OpenFAST the benchmark actuator) or
    "as_shipped" (exact sensors, and in OpenFAST no benchmark actuator: :func:`_as_shipped`),
    fault-free only (the faults are the benchmark actuator's and sensors')."""
    host = raw.get("host", "benchmark")
    if not isinstance(host, str) or host not in HOSTS:
        raise ConfigError("host", host, "one of " + ", ".join(HOSTS))
    fault = raw.get("fault", {})
    types = _listed(fault.get("type", "none")) if isinstance(fault, dict) else []
    if host == "as_shipped" and any(t != "none" for t in types):
        raise ConfigError("host", host, 'benchmark with faults (fault.type other than "none": '
                          "the faults are the benchmark actuator's and sensors')")
    return host


def _wind_shape(raw: dict, t_final: float, turbine: str | None) -> dict | None:
    """The deterministic winds' shape (WIND_SHAPE, sign, turbine_class, and the turbine's
    rotor diameter for the EOG), one value each; None when every kind is the NTM, whose
    runs refuse those keys. A sweep of deterministic winds only takes one seed and no
    rotor radius (they draw nothing and are uniform over the rotor)."""
    tab = raw.get("wind", {})
    if not isinstance(tab, dict):
        return None  # (refused by _tables)
    kinds = _listed(tab.get("kind", "ntm"))
    for k in kinds:
        _check_value("wind.kind", k, "str", choices=WIND_KINDS)
    given = [k for k in (*WIND_SHAPE, "sign", "turbine_class") if k in tab]
    if set(kinds) == {"ntm"}:
        if given:
            raise ConfigError(f"wind.{given[0]}", tab[given[0]], "a key of a deterministic "
                              "wind only (kind = " + ", ".join(WIND_KINDS[1:]) + ")")
        return None
    if "ntm" not in kinds:
        for key, why in (("seed", "one seed: a deterministic wind draws nothing"),
                         ("rotor_radius_m", "no rotor radius: a deterministic wind is "
                          "uniform over the rotor")):
            if key in tab and (key == "rotor_radius_m" or len(_listed(tab[key])) > 1
                               or isinstance(tab[key], dict)):
                raise ConfigError(f"wind.{key}", tab[key], why)
    shape = {k: _check_value(f"wind.{k}", tab.get(k, d), "float", lo=lo, hi=hi)
             for k, (d, lo, hi, _) in WIND_SHAPE.items()}
    if shape["event_s"] >= t_final:
        raise ConfigError("wind.event_s", shape["event_s"], f"a time before t_final_s = "
                          f"{t_final:g} s")
    if shape["ramp_s"] <= 0:
        raise ConfigError("wind.ramp_s", shape["ramp_s"], "a duration > 0 s")
    sign = tab.get("sign", 1)
    if isinstance(sign, bool) or sign not in (1, -1):
        raise ConfigError("wind.sign", sign, "1 or -1: the sign of the ECD's direction change")
    shape["sign"] = int(sign)
    shape["turbine_class"] = _check_value("wind.turbine_class", tab.get("turbine_class", "I"),
                                          "str", choices=tuple(wind.V_REF))
    t = turbine_file.load(turbine or turbine_file.DEFAULT)
    shape["rotor_diameter_m"] = 2.0 * float(t.values["rotor_radius"])
    return shape


def _wind_field(raw: dict) -> str | None:
    """[wind] field: "spectral" (wtftc's own NTM, the default) or "turbsim" (the TurbSim
    field OpenFAST runs on: a screen whose worst scenarios OpenFAST confirms), one value
    for the sweep; None for the default (the run ids of earlier sweeps)."""
    tab = raw.get("wind", {})
    value = tab.get("field") if isinstance(tab, dict) else None
    if value is None or value == "spectral":
        return None
    if value != "turbsim":
        raise ConfigError("wind.field", value, 'one of "spectral", "turbsim" for every run '
                          "(not an axis)")
    return value


def _engine(raw: dict) -> str:
    """The engine of every run (config.ENGINES), and, with OpenFAST, the keys that mean
    nothing there refused in one line each, before any run is listed (config refuses
    them per run: a sweep would fail every one of its runs the same way)."""
    engine = raw.get("engine", "wtftc")
    if not isinstance(engine, str) or engine not in config.ENGINES:
        raise ConfigError("engine", engine, "one of " + ", ".join(config.ENGINES)
                          + " (docs/openfast.md)")
    if engine == "wtftc":
        return engine
    for key, why, accepted in (
            ("plants", config.OPENFAST_REFUSED["plant"], ()),
            ("mismatch", config.OPENFAST_REFUSED["mismatch"], ()),
            # (1: what its sweep.json says, read back by --summary)
            ("batch_size", "each OpenFAST run is a process of its own, one Dask task each",
             (1,))):
        if key in raw and raw[key] not in accepted:
            raise ConfigError(key, raw[key], f"no {key} with engine = openfast: {why}")
    if raw.get("profile", PROFILE) == "ideal":
        raise ConfigError("profile", "ideal", "realistic with engine = openfast: OpenFAST "
                          "calls the controller as a library every control interval")
    return engine


def _check_oracles(raw: dict, columns: dict) -> None:
    """With OpenFAST and a fault, no column told the fault (accommodation = known)."""
    told = [c for c, ctrl in columns.items() if ctrl.accommodation == "known"]
    fault = raw.get("fault", {})
    if raw.get("engine", "wtftc") != "wtftc" and told and any(t != "none" for t in _listed(
            fault.get("type", "none") if isinstance(fault, dict) else "none")):
        raise ConfigError("controllers", told, "controllers OpenFAST can run under a fault: "
                          "not those told the fault (accommodation = known: eq (49) told the "
                          "fault inside wtftc's loop; a DISCON library is not told)")


def _turbine(name) -> str | None:
    """Every run's turbine (a built-in name or a turbine file's path; none: the NREL 5-MW,
    and the run ids of earlier sweeps), checked before anything runs."""
    if name is not None:
        if not isinstance(name, str):
            raise ConfigError("turbine", name, "a built-in turbine or a turbine file's path")
        turbine_file.load(name)
    return name


def _twins(value, raw: dict) -> bool:
    if not isinstance(value, bool):
        raise ConfigError("fault_free_twins", value, "true or false")
    if value and raw.get("mode", "grid") != "random":
        raise ConfigError("fault_free_twins", value, 'only with mode = "random" (a grid '
                          'has its twins when its fault types include "none")')
    return value


def _profile(name) -> str:
    """The measurement profile of every run (docs/sensors.md), campaigns' default
    realistic."""
    if not isinstance(name, str) or name not in config.PROFILES:
        raise ConfigError("profile", name, "one of " + ", ".join(config.PROFILES))
    return name


def _tables(raw: dict) -> tuple[dict, dict]:
    """The [wind] and [fault] tables, of known keys (with their defaults when absent)."""
    wind_tab = raw.get("wind", {})
    fault_tab = raw.get("fault", {"type": "none"})
    for tab, name, keys in ((wind_tab, "wind", WIND_KEYS), (fault_tab, "fault", FAULT_KEYS),
                            (raw.get("mismatch", {}), "mismatch", set(MISMATCH_KEYS))):
        if not isinstance(tab, dict):
            raise ConfigError(name, tab, "a table")
        for key in tab:
            if key not in keys:
                raise ConfigError(f"{name}.{key}", tab[key],
                                  f"a key of [{name}]: " + ", ".join(sorted(keys)))
    return wind_tab, fault_tab


def resolve(raw: dict) -> tuple[dict, tuple]:
    """The sweep's columns, name → Controller, its ``controllers`` then its
    ``optional_controllers`` (each column a name or a table: compare.resolve_columns),
    and the optional ones' names: ROSCO's, run where it is installed."""
    if "controllers" not in raw:
        raise ConfigError("controllers", None, "a list of controllers: preset names or "
                          "tables with a name and [controller] keys (docs/sweep.md)")
    columns = resolve_columns(raw["controllers"], "controllers")
    optional: dict = {}
    if "optional_controllers" in raw:
        optional = resolve_columns(raw["optional_controllers"], "optional_controllers")
    for name, ctrl in optional.items():
        if not is_rosco(ctrl):
            raise ConfigError("optional_controllers", name, "ROSCO's columns (design = "
                              "rosco), run where it is installed; list the others in "
                              "controllers")
        if name in columns and columns[name] != ctrl:
            raise ConfigError("optional_controllers", name, "a name other than the "
                              "controllers' (this one is a column with other settings)")
    extra = tuple(c for c in optional if c not in columns)
    return columns | {c: optional[c] for c in extra}, extra


def _controllers(sw_columns: dict, optional: tuple) -> Axis:
    """The controllers axis, its names in the file's order, with the optional ones
    (ROSCO) where they are installed."""
    names = tuple(c for c in sw_columns if c not in optional)
    if optional:
        from wtftc.sim import rosco

        if rosco.available() is None:
            names += optional
    return Axis("controllers", values=names)


def _listed(v) -> list:
    """A sweep file's value as the list of its values (a scalar: one)."""
    return v if isinstance(v, list) else [v]


def _axes(raw: dict, wind_tab: dict, fault_tab: dict, mode: str, t_final: float,
          engine: str, ctrl: Axis) -> list[Axis]:
    """Every axis, in the order of a run's values (controllers and plants first: CROSSED)."""
    return [
        ctrl,
        # with OpenFAST the plant is the turbine's deck: the column says "openfast"
        _axis("plants", raw.get("plants", "nrel5mw"), "str", mode, choices=PLANTS)
        if engine == "wtftc" else Axis("plants", values=("openfast",)),
        _axis("wind.mean_mps", wind_tab.get("mean_mps", 16.0), "float", mode, lo=3.0,
              hi=40.0),
        _axis("wind.turbulence_class", wind_tab.get("turbulence_class", "B"), "str", mode,
              choices=TURBULENCE_CLASSES),
        _axis("wind.seed", wind_tab.get("seed", 0), "int", mode, lo=0),
        _axis("fault.type", fault_tab.get("type", "none"), "str", mode, choices=FAULT_TYPES),
        _axis("fault.blade", fault_tab.get("blade", 1), "int", mode, lo=1, hi=lay.n_blades()),
        # a default onset that fits the run: never refuse a value the user did not write
        _axis("fault.onset_s", fault_tab.get("onset_s", min(20.0, t_final / 2)), "float",
              mode, lo=0.0, hi=t_final, lo_open=False),
        _magnitude_axis("fault.rho", fault_tab.get("rho", 0.5), "float", mode, lo=0.0, hi=1.0,
              lo_open=True),
        _axis("fault.angle_deg", fault_tab.get("angle_deg", "current"), "angle", mode,
              lo=0.0, hi=90.0),
        _magnitude_axis("fault.severity", fault_tab.get("severity", 1.0), "float", mode, lo=0.0,
              hi=1.0, lo_open=True),
        *[_magnitude_axis(f"fault.{k}", fault_tab.get(k, d), "float", mode, lo=lo, hi=hi,
                          lo_open=lo == 0.0) for k, (d, lo, hi, _) in SENSOR_MAGNITUDES.items()],
        *[_axis(f"mismatch.{k}", raw.get("mismatch", {}).get(k, 1.0), "float", mode,
                lo=0.1, hi=10.0, lo_open=False) for k in MISMATCH_KEYS],
        # which of a quantity's two sensors a sensor fault hits (last: a single value
        # draws nothing, and earlier sweeps' scenarios stay what they were)
        _axis("fault.sensor", fault_tab.get("sensor", 1), "int", mode, lo=1, hi=2),
        # a runaway's target (last, as the sensor: earlier sweeps' scenarios unchanged)
        _magnitude_axis("fault.target_deg", fault_tab.get("target_deg", 0.0), "float", mode,
                        lo=0.0,
              hi=90.0, lo_open=False),
        # the wind's kind (last, as the sensor: earlier sweeps' scenarios unchanged)
        _axis("wind.kind", wind_tab.get("kind", "ntm"), "str", mode, choices=WIND_KINDS),
        *_tuning_axes(raw.get("tuning"), mode),
    ]


class ByType(tuple):
    """A fault magnitude given per fault type, ((type, value), ...) sorted by type: one
    value of its axis, each run taking its own type's (e.g. the benchmark's gains, 1.2 on
    a pitch sensor and 1.1 on a rotor speed sensor, in one sweep)."""


def _magnitude_axis(key: str, spec, kind: str, mode: str, **bounds) -> Axis:
    """A fault magnitude's axis (:func:`_axis`), or a table of one value per fault type
    that reads it ({pitch_sensor_gain = 1.2, rotor_speed_sensor_gain = 1.1}): one value."""
    if not isinstance(spec, dict) or not spec or set(spec) <= {"min", "max", "n"}:
        return _axis(key, spec, kind, mode, **bounds)
    mag = key.removeprefix("fault.")
    readers = sorted(t for t, m in MAGNITUDE.items() if m == mag)
    for typ, v in spec.items():
        if typ not in readers:
            raise ConfigError(f"{key}.{typ}", v, "a fault type that reads " + mag + ": "
                              + ", ".join(readers) + " (or a range {min, max, n})")
        _check_value(f"{key}.{typ}", v, kind, **bounds)
    return Axis(key, values=(ByType(sorted((t, float(v)) for t, v in spec.items())),))


def _tuning_axes(tab, mode: str) -> list[Axis]:
    """[tuning]: the pitch loop's target mode, an axis each (crossed in random mode);
    without the table one value, None (no run is retuned)."""
    from wtftc.campaign.tune import TUNING_KEYS

    if tab is None:
        return [Axis(f"tuning.{k}", values=(None,)) for k in TUNING_AXES]
    if not isinstance(tab, dict) or set(tab) - set(TUNING_KEYS) or not set(TUNING_AXES) <= set(tab):
        raise ConfigError("tuning", tab, "a table with omega_n_rad_s and zeta (values or "
                          "ranges) and optionally design_wind_mps and c2_over_c1 (one "
                          "number each)")
    for key in ("design_wind_mps", "c2_over_c1"):
        default, lo, hi = TUNING_KEYS[key]
        _check_value(f"tuning.{key}", tab.get(key, default), "float", lo=lo, hi=hi)
    return [_axis(f"tuning.{k}", tab[k], "float", "grid" if mode == "random" else mode,
                  lo=TUNING_KEYS[k][1], hi=TUNING_KEYS[k][2], lo_open=False)
            for k in TUNING_AXES]


def _check_together(by_key: dict[str, Axis], t_final: float, columns: dict) -> None:
    """What no single axis shows: onsets before the end, ROSCO on the NREL 5-MW only."""
    onsets = by_key["fault.onset_s"]
    faulty = set(by_key["fault.type"].values) != {"none"}
    if faulty and max(onsets.grid() if onsets.values else [onsets.range[1]]) >= t_final:
        raise ConfigError("fault.onset_s", list(onsets.values or onsets.range),
                          f"onsets before t_final_s = {t_final:g} s")
    roscos = [c for c in by_key["controllers"].values or () if is_rosco(columns[c])]
    if roscos and "paper" in (by_key["plants"].values or ()):
        raise ConfigError("plants", "paper", f"nrel5mw or tower when controllers include "
                          f"{roscos[0]} (ROSCO's DISCON.IN is tuned for the NREL 5-MW)")


def _check_winds(by_key: dict[str, Axis], shape: dict | None, t_final: float) -> None:
    """Every deterministic wind of the sweep built once (wtftc.model.wind checks it: an
    EOG's mean below V_e1, speeds > 0), a refusal naming the sweep's key: a step or ramp
    that would reach a calm names its size."""
    if shape is None:
        return
    a = by_key["wind.mean_mps"]
    means = a.grid() if a.values is not None or a.n else list(a.range)
    for kind in by_key["wind.kind"].grid():
        for mean in means if kind != "ntm" else ():
            for tc in by_key["wind.turbulence_class"].grid():
                tab = deterministic_wind(kind, float(mean), tc, shape)
                if kind in ("steps", "ramp") and min(tab["speed_mps"], tab.get(
                        "end_mps", tab.get("steps", [[0, 1.0]])[0][1])) <= 0:
                    key = "wind.step_mps" if kind == "steps" else "wind.ramp_mps"
                    raise ConfigError(key, shape[key[5:]], f"a change that keeps the {kind} "
                                      f"around mean_mps = {mean:g} m/s above 0 m/s")
                wind.wind_from_config(tab, t_final, where="wind")


def _check_by_type(by_key: dict[str, Axis]) -> None:
    """A magnitude given per fault type names every swept type that reads it."""
    types = [t for t in by_key["fault.type"].grid() if t != "none"]
    for t in types:
        value = by_key[f"fault.{MAGNITUDE[t]}"].values
        if value and isinstance(value[0], ByType) and t not in dict(value[0]):
            raise ConfigError(f"fault.{MAGNITUDE[t]}", dict(value[0]), f"a value for every "
                              f"swept fault type that reads it: {t} has none")


#: the most runs one sweep may hold (before duplicates are dropped): about a week of the
#: physical AFTC's 60-s runs on 2 cores, and 1 GB for the run list alone
MAX_RUNS = 1_000_000


def _check_size(mode: str, samples: int | None, axes: list[Axis], twins: bool = False
                ) -> None:
    """Refuse a sweep too large to list, before any of it is expanded (a grid of 1e10 runs
    once used 2 GB in 40 s without a word); fault-free twins double a random sweep."""
    crossed = [a for a in axes if a.key in CROSSED]
    grid = [a for a in axes if mode == "grid" or a.key in CROSSED]
    n = math.prod(a.size() for a in grid) * (samples * (2 if twins else 1)
                                             if mode == "random" else 1)
    if n > MAX_RUNS:
        sizes = ", ".join(f"{a.key}: {a.size()}" for a in (grid if mode == "grid" else crossed))
        raise ConfigError("samples" if mode == "random" else "grid", f"{n:,} runs",
                          f"at most {MAX_RUNS:,} runs in one sweep ({sizes}"
                          + (f", samples: {samples}" if mode == "random" else "")
                          + "): split it into several sweeps")


def _rotor_radius(raw: dict) -> float | None:
    """[wind] rotor_radius_m: every run's NTM averaged over a rotor disk of that radius
    (wtftc.model.wind.rotor_average_gain), one value for the sweep, not an axis; without
    it (or 0) the hub-height point, unlike a single run's default (docs/wind.md)."""
    tab = raw.get("wind", {})
    value = tab.get("rotor_radius_m") if isinstance(tab, dict) else None
    if value is None:
        return None
    top = wind.rotor_radius_max_m()
    if isinstance(value, bool) or not isinstance(value, int | float) or not 0 <= value <= top:
        raise ConfigError("wind.rotor_radius_m", value, f"one number in [0, {top:g}] [m] for "
                          "every run (0: the hub-height point), not an axis")
    return float(value)


def parse_sweep(raw: dict) -> Sweep:
    """Validate a sweep file's content before anything runs: each error names the key."""
    mode, samples = _check_top(raw)
    if "dlc" in raw:  # the summary's lifetime weighting (wtftc.campaign.sweep.dlc)
        parse_dlc(raw["dlc"])
    settings = _settings(raw)
    columns, optional = resolve(raw)
    _check_oracles(raw, columns)
    wind_tab, fault_tab = _tables(raw)
    settings["wind_shape"] = _wind_shape(raw, settings["t_final"], settings["turbine"])
    axes = _axes(raw, wind_tab, fault_tab, mode, settings["t_final"], settings["engine"],
                 _controllers(columns, optional))
    _check_together({a.key: a for a in axes}, settings["t_final"], columns)
    _check_winds({a.key: a for a in axes}, settings["wind_shape"], settings["t_final"])
    _check_by_type({a.key: a for a in axes})
    _check_size(mode, samples, axes, settings["fault_free_twins"])
    # (engine = "wtftc" is the default: absent, the ids of earlier sweeps)
    canonical = json.dumps({**{k: v for k, v in raw.items() if k != "engine"}, "mode": mode,
                            "sampling_seed": settings["sampling_seed"],
                            "t_final_s": settings["t_final"], "dt_s": settings["dt"],
                            "output_rate_hz": settings["output_rate_hz"],
                            "batch_size": settings["batch_size"],
                            "profile": settings["profile"]}
                           | ({"turbine": settings["turbine"]} if settings["turbine"] else {})
                           | ({"engine": settings["engine"]} if settings["engine"] != "wtftc"
                              else {})
                           | ({"fault_free_twins": True} if settings["fault_free_twins"]
                              else {}), sort_keys=True)
    return Sweep(raw=raw, text=canonical, mode=mode, samples=samples, axes=axes,
                 columns=columns, optional=optional, **settings)


def load_sweep(path: Path, engine: str | None = None, preset: str | None = None) -> Sweep:
    """The sweep file at ``path``; ``engine`` (``--engine``): every run's engine, where the
    file names none or the same; ``preset`` (``--preset``): the file's ``controllers``
    replaced by that one preset (its optional controllers kept)."""
    raw = config.load_toml(Path(path), "SWEEP.toml")
    if engine is not None:
        if raw.get("engine", engine) != engine:
            raise ConfigError("--engine", engine, f"the sweep file's engine, {raw['engine']} "
                              "(or leave --engine out)")
        raw = {**raw, "engine": engine}
    if preset is not None:
        from wtftc import controller

        controller.preset(preset, "--preset")
        raw = {**raw, "controllers": [preset]}
    return parse_sweep(raw)


# ---------------------------------------------------------------------------- the runs

def _point(sw: Sweep, values: dict) -> dict:
    """One run: the axis values that matter for it (the rest None) and its configuration."""
    p = {"controller": values["controllers"], "plant": values["plants"],
         "mean_wind_mps": float(values["wind.mean_mps"]),
         "turbulence_class": values["wind.turbulence_class"], "seed": int(values["wind.seed"]),
         "fault_type": values["fault.type"], "blade": None, "onset_s": None,
         "fault_sensor": None, **dict.fromkeys(MAGNITUDE_COLUMN.values())}
    fault_tabs = _fault_tables(values, p)
    wind_tab = _run_wind(sw, values, p)
    cfg = variant_config(sw.columns[p["controller"]], fault_tabs, wind_tab, sw.t_final,
                         sw.dt, p["seed"], "", profile=sw.profile)
    # OpenFAST's plant is the turbine's deck (config: engine = "openfast")
    cfg.update({"plant": p["plant"]} if sw.engine == "wtftc" else {"engine": sw.engine},
               output_rate_hz=sw.output_rate_hz)
    if sw.turbine:  # (absent: the run ids of earlier sweeps)
        cfg["turbine"] = sw.turbine
    if sw.host == "as_shipped":
        _as_shipped(sw, cfg)
    _tuning(sw, values, p, cfg)
    mismatch = {k: float(values[f"mismatch.{k}"]) for k in MISMATCH_KEYS}
    p.update({f"mismatch_{k}": v for k, v in mismatch.items()})
    if any(v != 1.0 for v in mismatch.values()):  # (absent: the run ids of earlier sweeps)
        cfg["mismatch"] = mismatch
    run_id = hashlib.sha256(json.dumps(cfg, sort_keys=True).encode()).hexdigest()[:16]
    cfg["label"] = f"sweep-{run_id}"
    if not sw.rotor_radius and p["wind_kind"] == "ntm":  # a sweep without one keeps the
        # hub-height point, said, as a run's NTM now takes its turbine's rotor by default
        # (wtftc.config); after the id: the run ids of earlier sweeps
        cfg["wind"]["rotor_radius_m"] = 0.0
    twin = {"twin_onset_s": float(values["twin_onset_s"])} if values.get("twin_onset_s") \
        is not None else {}
    return {"run_id": run_id, **p, "config": cfg, **twin}


def _fault_tables(values: dict, p: dict) -> list | None:
    """The run's fault tables (None without a fault), its fault's axes written into ``p``;
    a magnitude given per fault type takes the run's type's value."""
    ftype = values["fault.type"]
    if ftype == "none":
        return None
    p["blade"], p["onset_s"] = int(values["fault.blade"]), float(values["fault.onset_s"])
    tab = {"blade": p["blade"], "type": ftype, "onset_s": p["onset_s"]}
    if faults.TYPES[ftype].signal not in ("", "pitch"):  # a speed sensor: no blade
        p["blade"] = None
        del tab["blade"]
    if faults.TYPES[ftype].acts_on == "sensor":
        p["fault_sensor"] = int(values["fault.sensor"])
        if p["fault_sensor"] != 1:  # (absent: the run ids of earlier sweeps)
            tab["sensor"] = p["fault_sensor"]
    mag = MAGNITUDE[ftype]
    value = values[f"fault.{mag}"]
    tab[mag] = dict(value)[ftype] if isinstance(value, ByType) else value
    p[MAGNITUDE_COLUMN[mag]] = str(tab[mag]) if mag == "angle_deg" else float(tab[mag])
    return [tab]


def _run_wind(sw: Sweep, values: dict, p: dict) -> dict:
    """The run's [wind] table, its kind written into ``p`` (``wind_kind``): the NTM at the
    scenario's mean, class and seed, or a deterministic wind around the mean, seed 0 (it
    draws nothing) and a turbulence class only where it is used (the EOG's σ1)."""
    kind = values.get("wind.kind", "ntm")
    p["wind_kind"] = kind
    if kind != "ntm":
        p["seed"] = 0
        if kind != "eog":
            p["turbulence_class"] = None
        return deterministic_wind(kind, p["mean_wind_mps"], p["turbulence_class"],
                                  sw.wind_shape)
    wind_tab = {"kind": "ntm", "mean_mps": p["mean_wind_mps"],
                "turbulence_class": p["turbulence_class"]}
    if sw.rotor_radius:  # (absent: the run ids of earlier sweeps)
        wind_tab["rotor_radius_m"] = sw.rotor_radius
    if sw.wind_field and sw.engine == "wtftc":  # (OpenFAST's runs read it anyway: their ids
        wind_tab["field"] = sw.wind_field       # are those of the same file without it)
    return wind_tab


def deterministic_wind(kind: str, mean: float, turbulence_class: str | None,
                       shape: dict) -> dict:
    """The [wind] table (wtftc.model.wind) of a sweep's deterministic ``kind`` around the
    scenario's ``mean`` [m/s], with the sweep's ``shape`` (its [wind] event_s, step_mps,
    ramp_mps, ramp_s, sign, turbine_class and the turbine's rotor_diameter_m):

    * eog: the IEC EOG at V_hub = mean from event_s (IEC 61400-1 ed. 3, 6.3.2.2);
    * ecd: the IEC ECD at V_hub = mean from event_s, its direction turning by sign × θ_cg
      (6.3.2.5);
    * steps: mean - step_mps/2 until event_s, then mean + step_mps/2;
    * ramp: mean - ramp_mps/2 until event_s, then linear to mean + ramp_mps/2 over ramp_s
      (the WEIS controller test bench's ramp: a start speed, a change, a duration)."""
    event = shape["event_s"]
    if kind == "eog":
        return {"kind": "eog", "mean_mps": mean, "start_s": event,
                "turbine_class": shape["turbine_class"], "turbulence_class": turbulence_class,
                "rotor_diameter_m": shape["rotor_diameter_m"]}
    if kind == "ecd":
        return {"kind": "ecd", "mean_mps": mean, "start_s": event, "sign": shape["sign"],
                "turbine_class": shape["turbine_class"]}
    if kind == "steps":
        half = shape["step_mps"] / 2
        return {"kind": "steps", "speed_mps": round(mean - half, 9),
                "steps": [[event, round(mean + half, 9)]]}
    half = shape["ramp_mps"] / 2
    return {"kind": "ramp", "speed_mps": round(mean - half, 9),
            "end_mps": round(mean + half, 9), "start_s": event,
            "duration_s": shape["ramp_s"]}


def _as_shipped(sw: Sweep, cfg: dict) -> None:
    """host = "as_shipped": the controller as its deck ships it, without the benchmark's
    sensor noise or pitch actuator. In OpenFAST: every sensor exact (the realistic
    profile's noise set to 0) and no actuator between the controller and the blades
    ([openfast] actuator = false: ElastoDyn takes the demand); on wtftc's plant the ideal
    profile (exact sensors, continuous time); its plant keeps the actuator's dynamics,
    which are the plant's own there (docs/sweep.md)."""
    if sw.engine == "wtftc":
        cfg["profile"] = "ideal"
        return
    cfg["sensors"] = dict.fromkeys(config.PROFILES["realistic"]["sensors"], 0.0)
    cfg["openfast"] = {"actuator": False}


def _tuning(sw: Sweep, values: dict, p: dict, cfg: dict) -> None:
    """A retunable controller's [tuning] target into its run (and its columns)."""
    from wtftc.campaign.tune import RETUNABLE

    p["tuning_omega_n_rad_s"] = p["tuning_zeta"] = None
    w = values.get("tuning.omega_n_rad_s")
    if w is None or sw.columns[p["controller"]].design not in RETUNABLE:
        return
    tab = {"omega_n_rad_s": float(w), "zeta": float(values["tuning.zeta"])}
    for key in ("design_wind_mps", "c2_over_c1"):  # settings, one value for the sweep
        if key in sw.raw["tuning"]:
            tab[key] = float(sw.raw["tuning"][key])
    cfg["tuning"] = tab
    p["tuning_omega_n_rad_s"], p["tuning_zeta"] = tab["omega_n_rad_s"], tab["zeta"]


def _combinations(sw: Sweep):
    """Each run's axis values, by axis key, in a fixed order (duplicates included)."""
    keys = [a.key for a in sw.axes]
    if sw.mode == "grid":
        return (dict(zip(keys, vals, strict=True))
                for vals in itertools.product(*(a.grid() for a in sw.axes)))
    # random scenarios (wind, seed, fault), each run by every controller on every plant:
    # a paired comparison, and the draws do not depend on which controllers are swept
    rng = np.random.default_rng(sw.sampling_seed)
    crossed = [sw.axis(k) for k in CROSSED]
    drawn = [a for a in sw.axes if a.key not in CROSSED]
    scenarios = [{a.key: a.draw(rng) for a in drawn} for _ in range(sw.samples)]
    if sw.fault_free_twins:  # each scenario, then its fault-free twin (scored from the
        # faulty one's onset on: twin_onset_s)
        scenarios = [s for sc in scenarios for s in (sc, {
            **sc, "fault.type": "none",
            "twin_onset_s": sc["fault.onset_s"] if sc["fault.type"] != "none" else None})]
    return ({**sc, **dict(zip(CROSSED, cp, strict=True))} for sc in scenarios
            for cp in itertools.product(*(a.grid() for a in crossed)))


def expand(sw: Sweep) -> tuple[list[dict], int]:
    """Every run of the sweep, in a fixed order, duplicates removed (a fault-free run does
    not depend on blade, onset or magnitude); returns (runs, number of duplicates).

    Grid: every combination of every axis. Random: ``samples`` scenarios (wind, seed and
    fault drawn from their axes with ``sampling_seed``), each run with every controller
    and plant."""
    runs, seen, dup = [], set(), 0
    for values in _combinations(sw):
        pt = _point(sw, values)
        if pt["run_id"] in seen:
            dup += 1
            continue
        seen.add(pt["run_id"])
        runs.append(pt)
    return runs, dup


def batches(runs: list[dict], size: int) -> list[list[dict]]:
    """Runs grouped into tasks of at most ``size``, each of one compiled loop (controller
    and plant), so that a task advances its runs in one call (cases.run_batch)."""
    groups: dict[tuple, list] = {}
    for r in runs:
        groups.setdefault((r["controller"], r["plant"]), []).append(r)
    per_group = [[g[i:i + size] for i in range(0, len(g), size)] for g in groups.values()]
    # interleaved, so that the rate (and the ETA) mixes the fast loops with the slow ones
    return [b for row in itertools.zip_longest(*per_group) for b in row if b is not None]
