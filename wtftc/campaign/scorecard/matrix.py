"""The scorecard's case matrix, as data (``wtftc/data/scorecard.toml``): the design load
cases every controller and its baseline run, identically, each turned into a sweep
(wtftc.campaign.sweep) on a turbine.

* ``normal_production`` (IEC 61400-1 DLC 1.2): NTM in mean-wind bins from the turbine's
  cut-in to cut-out, ``seeds`` turbulence seeds each, ``scored_s`` scored after the
  start-up; weighted by the Rayleigh distribution of ``annual_mean_mps`` into lifetime
  DELs and AEP (wtftc.campaign.sweep.dlc).
* ``actuator_faults`` (DLC 2.1): every pitch actuator fault type on one blade from
  ``onset_s``, the runaway to fine and to feather, at ``winds_mps``, ``seeds`` each.

The same file gives the same runs: :func:`matrix_hash` names it in a scorecard's
provenance.
"""

from __future__ import annotations

import copy
import hashlib
import importlib.resources
import json
import math
import numbers
import tomllib
from pathlib import Path

from wtftc.errors import ConfigError
from wtftc.model import faults, turbine_file
from wtftc.model.wind import I_REF

#: the shipped matrix, in wtftc/data
MATRIX_FILE = "scorecard.toml"
TOP = {"annual_mean_mps", "turbulence_class", "start_up_s", "groups"}
GROUPS = {
    "normal_production": {"iec", "what", "bin_width_mps", "cut_out_mps", "seeds",
                          "scored_s", "overspeed_trip"},
    "actuator_faults": {"iec", "what", "winds_mps", "seeds", "scored_s", "onset_s", "blade",
                        "types", "rho", "angle_deg", "severity", "runaway_targets_deg",
                        "overspeed_trip"},
}
#: the most seeds a group may ask for (a grid of 11 bins × 100 seeds is 1,100 runs a
#: controller)
MAX_SEEDS = 100


def load(path: Path | None = None) -> dict:
    """The matrix of ``path`` (default: the shipped one), checked; a refused key or value
    is one line naming it and the file."""
    if path is None:
        text = (importlib.resources.files("wtftc") / "data" / MATRIX_FILE).read_text("utf-8")
        where = MATRIX_FILE
    else:
        from wtftc.config import load_toml

        return check(load_toml(Path(path), "--matrix"), str(path))
    return check(tomllib.loads(text), where)


def _number(tab: dict, key: str, where: str, lo: float, hi: float, prefix: str = "") -> float:
    v = tab.get(key)
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v) \
            or not lo <= v <= hi:
        raise ConfigError(prefix + key, v, f"a number in [{lo:g}, {hi:g}]", where=where)
    return float(v)


def check(m: dict, where: str) -> dict:
    """``m`` checked: known keys, numbers in their ranges, known fault types."""
    unknown = sorted(set(m) - TOP)
    if unknown:
        raise ConfigError(unknown[0], m[unknown[0]], "a key of the matrix: "
                          + ", ".join(sorted(TOP)), where=where)
    _number(m, "annual_mean_mps", where, 1.0, 30.0)
    _number(m, "start_up_s", where, 0.0, 600.0)
    if m.get("turbulence_class") not in I_REF:
        raise ConfigError("turbulence_class", m.get("turbulence_class"), "one of "
                          + ", ".join(I_REF), where=where)
    groups = m.get("groups")
    if not isinstance(groups, dict) or not groups or set(groups) - set(GROUPS):
        raise ConfigError("groups", groups, "tables of " + ", ".join(GROUPS), where=where)
    for name, g in groups.items():
        _check_group(name, g, where)
        _check_start_up(m["start_up_s"], name, g, where)
    return m


def _check_start_up(start: float, name: str, g: dict, where: str) -> None:
    """The start-up must be the window the group's runs leave out of their metrics
    (config.transient_window: 30 s, a quarter of a run shorter than 120 s), so that what
    the matrix says is scored is what is."""
    from wtftc.config import TRANSIENT_S

    t_final = start + g["scored_s"]
    window = min(TRANSIENT_S, t_final / 4)
    if abs(start - window) > 1e-9:
        raise ConfigError("start_up_s", start, f"the start-up the runs of groups.{name} "
                          f"leave out, {window:g} s ({TRANSIENT_S:g} s, or a quarter of a "
                          "run shorter than 120 s: start_up_s + scored_s)", where=where)


def _check_group(name: str, g, where: str) -> None:
    if not isinstance(g, dict):
        raise ConfigError(f"groups.{name}", g, "a table", where=where)
    unknown = sorted(set(g) - GROUPS[name])
    if unknown:
        raise ConfigError(f"groups.{name}.{unknown[0]}", g[unknown[0]], "a key of "
                          f"{name}: " + ", ".join(sorted(GROUPS[name])), where=where)
    seeds = g.get("seeds")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or not 1 <= seeds <= MAX_SEEDS:
        raise ConfigError(f"groups.{name}.seeds", seeds, f"an integer in [1, {MAX_SEEDS}]",
                          where=where)
    _number(g, "scored_s", where, 1.0, 7200.0, f"groups.{name}.")
    _number(g, "overspeed_trip", where, 1.0, 2.0, f"groups.{name}.")
    if name == "normal_production":
        _number(g, "bin_width_mps", where, 0.5, 10.0, f"groups.{name}.")
        _number(g, "cut_out_mps", where, 5.0, 40.0, f"groups.{name}.")
        return
    winds = g.get("winds_mps")
    if not isinstance(winds, list) or not winds or any(
            isinstance(v, bool) or not isinstance(v, numbers.Real) or not 3.0 <= v <= 40.0
            for v in winds):
        raise ConfigError(f"groups.{name}.winds_mps", winds, "a list of mean winds in "
                          "[3, 40] m/s", where=where)
    types = g.get("types")
    if not isinstance(types, list) or not types or any(
            t not in faults.ACTUATOR_FAULT_TYPES for t in types):
        raise ConfigError(f"groups.{name}.types", types, "a list of "
                          + ", ".join(faults.ACTUATOR_FAULT_TYPES), where=where)
    if not 0.0 <= _number(g, "onset_s", where, 0.0, 7200.0, f"groups.{name}.") < g["scored_s"]:
        raise ConfigError(f"groups.{name}.onset_s", g["onset_s"], "a time inside the "
                          f"scored {g['scored_s']:g} s", where=where)


def matrix_hash(m: dict) -> str:
    """16 hex digits of the sha256 of the matrix as checked (its keys sorted)."""
    return hashlib.sha256(json.dumps(m, sort_keys=True).encode()).hexdigest()[:16]


def bins(m: dict, turbine: turbine_file.Turbine) -> list[float]:
    """The normal-production bins' mean winds: from the turbine's cut-in (3 m/s where its
    file names none) to the cut-out, each bin ``bin_width_mps`` wide and whole."""
    g = m["groups"]["normal_production"]
    w, lo, hi = g["bin_width_mps"], turbine.cut_in_wind_mps or 3.0, g["cut_out_mps"]
    n = math.floor((hi - lo) / w + 1e-9)
    return [round(lo + w * (k + 0.5), 6) for k in range(n)]


def sweeps(m: dict, columns: list, turbine: str | None, engine: str,
           seeds: int | None = None) -> dict[str, dict]:
    """Each group of the matrix as a sweep file's content (wtftc.campaign.sweep.spec), on
    ``turbine`` in ``engine``, the controllers ``columns`` (names or tables, each a column
    of the results), ``seeds`` in place of each group's when given."""
    t = turbine_file.load(turbine or turbine_file.DEFAULT)
    out = {}
    for name, g in m["groups"].items():
        k = seeds if seeds is not None else g["seeds"]
        raw = {"name": f"scorecard {name} (DLC {g['iec']})", "engine": engine,
               "mode": "grid", "t_final_s": m["start_up_s"] + g["scored_s"],
               "profile": "realistic", "controllers": copy.deepcopy(columns),
               "wind": {"rotor_radius_m": t.values["rotor_radius"],
                        "turbulence_class": m["turbulence_class"],
                        "seed": {"min": 0, "max": k - 1} if k > 1 else 0},
               **({"turbine": turbine} if turbine else {})}
        if name == "normal_production":
            raw["wind"]["mean_mps"] = bins(m, t)
            raw["fault"] = {"type": "none"}
            raw["dlc"] = {"case": g["iec"], "annual_mean_mps": m["annual_mean_mps"],
                          "bin_width_mps": g["bin_width_mps"],
                          "overspeed_trip": g["overspeed_trip"]}
        else:
            raw["wind"]["mean_mps"] = [float(v) for v in g["winds_mps"]]
            raw["fault"] = {"type": list(g["types"]), "blade": g["blade"],
                            "onset_s": m["start_up_s"] + g["onset_s"],
                            "angle_deg": g["angle_deg"], "rho": g["rho"],
                            "severity": g["severity"],
                            "target_deg": [float(v) for v in g["runaway_targets_deg"]]}
            raw["dlc"] = {"case": g["iec"], "overspeed_trip": g["overspeed_trip"]}
        if engine == "wtftc":
            raw["plants"] = "tower_edge"
        out[name] = raw
    return out
