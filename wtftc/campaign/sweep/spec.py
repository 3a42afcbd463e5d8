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
            "profile", "mismatch", "fault_free_twins", "turbine", "dlc", "tuning", "engine"}
#: the [mismatch] table's keys: the plant's factors against the controllers' model
#: (config.MISMATCH), each an axis like any other (1.0: none)
MISMATCH_KEYS = tuple(config.MISMATCH)
WIND_KEYS = {"mean_mps", "turbulence_class", "seed", "rotor_radius_m", "field"}
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
    }


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
        _axis("fault.rho", fault_tab.get("rho", 0.5), "float", mode, lo=0.0, hi=1.0,
              lo_open=True),
        _axis("fault.angle_deg", fault_tab.get("angle_deg", "current"), "angle", mode,
              lo=0.0, hi=90.0),
        _axis("fault.severity", fault_tab.get("severity", 1.0), "float", mode, lo=0.0,
              hi=1.0, lo_open=True),
        *[_axis(f"fault.{k}", fault_tab.get(k, d), "float", mode, lo=lo, hi=hi,
                lo_open=lo == 0.0) for k, (d, lo, hi, _) in SENSOR_MAGNITUDES.items()],
        *[_axis(f"mismatch.{k}", raw.get("mismatch", {}).get(k, 1.0), "float", mode,
                lo=0.1, hi=10.0, lo_open=False) for k in MISMATCH_KEYS],
        # which of a quantity's two sensors a sensor fault hits (last: a single value
        # draws nothing, and earlier sweeps' scenarios stay what they were)
        _axis("fault.sensor", fault_tab.get("sensor", 1), "int", mode, lo=1, hi=2),
        # a runaway's target (last, as the sensor: earlier sweeps' scenarios unchanged)
        _axis("fault.target_deg", fault_tab.get("target_deg", 0.0), "float", mode, lo=0.0,
              hi=90.0, lo_open=False),
        *_tuning_axes(raw.get("tuning"), mode),
    ]


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
    axes = _axes(raw, wind_tab, fault_tab, mode, settings["t_final"], settings["engine"],
                 _controllers(columns, optional))
    _check_together({a.key: a for a in axes}, settings["t_final"], columns)
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
    ftype = values["fault.type"]
    p = {"controller": values["controllers"], "plant": values["plants"],
         "mean_wind_mps": float(values["wind.mean_mps"]),
         "turbulence_class": values["wind.turbulence_class"], "seed": int(values["wind.seed"]),
         "fault_type": ftype, "blade": None, "onset_s": None, "fault_sensor": None,
         **dict.fromkeys(MAGNITUDE_COLUMN.values())}
    fault_tabs = None
    if ftype != "none":
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
        tab[mag] = values[f"fault.{mag}"]
        p[MAGNITUDE_COLUMN[mag]] = str(tab[mag]) if mag == "angle_deg" else float(tab[mag])
        fault_tabs = [tab]
    wind_tab = {"kind": "ntm", "mean_mps": p["mean_wind_mps"],
                "turbulence_class": p["turbulence_class"]}
    if sw.rotor_radius:  # (absent: the run ids of earlier sweeps)
        wind_tab["rotor_radius_m"] = sw.rotor_radius
    if sw.wind_field and sw.engine == "wtftc":  # (OpenFAST's runs read it anyway: their ids
        wind_tab["field"] = sw.wind_field       # are those of the same file without it)
    cfg = variant_config(sw.columns[p["controller"]], fault_tabs, wind_tab, sw.t_final,
                         sw.dt, p["seed"], "", profile=sw.profile)
    # OpenFAST's plant is the turbine's deck (config: engine = "openfast")
    cfg.update({"plant": p["plant"]} if sw.engine == "wtftc" else {"engine": sw.engine},
               output_rate_hz=sw.output_rate_hz)
    if sw.turbine:  # (absent: the run ids of earlier sweeps)
        cfg["turbine"] = sw.turbine
    _tuning(sw, values, p, cfg)
    mismatch = {k: float(values[f"mismatch.{k}"]) for k in MISMATCH_KEYS}
    p.update({f"mismatch_{k}": v for k, v in mismatch.items()})
    if any(v != 1.0 for v in mismatch.values()):  # (absent: the run ids of earlier sweeps)
        cfg["mismatch"] = mismatch
    run_id = hashlib.sha256(json.dumps(cfg, sort_keys=True).encode()).hexdigest()[:16]
    cfg["label"] = f"sweep-{run_id}"
    if not sw.rotor_radius:  # a sweep without one keeps the hub-height point, said, as a
        # run's NTM now takes its turbine's rotor by default (wtftc.config); after the id:
        # the run ids of earlier sweeps
        cfg["wind"]["rotor_radius_m"] = 0.0
    twin = {"twin_onset_s": float(values["twin_onset_s"])} if values.get("twin_onset_s") \
        is not None else {}
    return {"run_id": run_id, **p, "config": cfg, **twin}


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
