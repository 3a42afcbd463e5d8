"""The scorecard's case matrix, as data (``wtftc/data/scorecard.toml``): the design load
cases every controller and its baseline run, identically, each turned into a sweep
(wtftc.campaign.sweep) on a turbine.

* ``normal_production`` (IEC 61400-1 DLC 1.2): NTM in mean-wind bins from the turbine's
  cut-in to cut-out, ``seeds`` turbulence seeds each, ``scored_s`` scored after the
  start-up; weighted by the Rayleigh distribution of ``annual_mean_mps`` into lifetime
  DELs and AEP (wtftc.campaign.sweep.dlc).
* ``actuator_faults`` (DLC 2.1): every pitch actuator fault type on one blade from
  ``onset_s``, the runaway to fine and to feather, at ``winds_mps``, ``seeds`` each.
* ``sensor_faults`` (DLC 2.1): the control system's sensor faults, each type at its own
  magnitude (``magnitudes``: a speed sensor's stuck value and offset as fractions of its
  shaft's rated speed), at ``winds_mps``, ``seeds`` each.
* ``deterministic``: the deterministic winds (``kinds``: the EOG, the ECD, a step, a ramp)
  at the turbine's rated wind plus ``winds_from_rated_mps``, one run each (no seed): the
  ECD is IEC DLC 1.4; the EOG in power production, the step and the ramp are the WEIS
  controller test bench's cases, not IEC's (:data:`WIND_IEC`).
* ``baseline_as_shipped``: the baseline column alone, its deck as shipped (exact sensors;
  in OpenFAST no benchmark actuator: the sweep's host = "as_shipped"), on the
  normal-production runs of the bins nearest ``near_mps`` with the same seeds and length,
  so that each pairs with the baseline's normal-production run of the same scenario.

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
from wtftc.model.wind import I_REF, V_REF

#: the shipped matrix, in wtftc/data
MATRIX_FILE = "scorecard.toml"
TOP = {"annual_mean_mps", "turbulence_class", "start_up_s", "groups"}
GROUPS = {
    "normal_production": {"iec", "what", "bin_width_mps", "cut_out_mps", "seeds",
                          "scored_s", "overspeed_trip"},
    "actuator_faults": {"iec", "what", "winds_mps", "seeds", "scored_s", "onset_s", "blade",
                        "types", "rho", "angle_deg", "severity", "runaway_targets_deg",
                        "overspeed_trip"},
    "sensor_faults": {"iec", "what", "winds_mps", "seeds", "scored_s", "onset_s", "blade",
                      "sensor", "types", "magnitudes", "overspeed_trip"},
    "deterministic": {"iec", "what", "kinds", "winds_from_rated_mps", "scored_s", "event_s",
                      "step_mps", "ramp_mps", "ramp_s", "ecd_sign", "turbine_class",
                      "overspeed_trip"},
    "baseline_as_shipped": {"iec", "what", "near_mps", "overspeed_trip"},
}
#: the IEC label of each deterministic wind in the deterministic group: the ECD at rated
#: and ± 2 m/s is DLC 1.4; IEC ed. 3 pairs the EOG at these winds with an event (grid
#: loss, start-up, shutdown: DLC 2.3, 3.2, 4.2), so in power production it is the test
#: bench's gust case, as the step and the ramp are its cases
WIND_IEC = {"eog": "test bench (the EOG of IEC 61400-1 ed. 3, 6.3.2.2, in power "
                   "production; no IEC DLC)",
            "ecd": "DLC 1.4 (the ECD of IEC 61400-1 ed. 3, 6.3.2.5)",
            "steps": "test bench (no IEC DLC)",
            "ramp": "test bench (WEIS's ramp; no IEC DLC)"}
#: the deterministic group's wind kinds (wtftc.campaign.sweep.spec.WIND_KINDS but the NTM)
DETERMINISTIC_KINDS = ("eog", "ecd", "steps", "ramp")
#: a speed sensor fault's magnitude given as a fraction of its shaft's rated speed
SPEED_FRACTIONS = ("value_rad_s", "offset_rad_s")
#: an estimate of one OpenFAST run of the NREL 5-MW on one core: about 0.43 s of wall
#: time per simulated second (the aftc-nrel5mw preset under an ECD, on a 2-core machine
#: shared with others: 6.8 s for 4 s simulated, 21.9 s for 40 s, 0.42 s a second past the
#: start), for :func:`plan` where no card's own rate is at hand
OPENFAST_WALL_PER_SIM_S = 0.43
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
    if "baseline_as_shipped" in groups and "normal_production" not in groups:
        raise ConfigError("groups.baseline_as_shipped", groups["baseline_as_shipped"],
                          "a group beside normal_production (it reruns some of its runs)",
                          where=where)
    for name, g in groups.items():
        _check_group(name, g, where)
        scored = g.get("scored_s", groups.get("normal_production", {}).get("scored_s"))
        _check_start_up(m["start_up_s"], name, scored, where)
    return m


def _check_start_up(start: float, name: str, scored: float, where: str) -> None:
    """The start-up must be the window the group's runs leave out of their metrics
    (config.transient_window: 30 s, a quarter of a run shorter than 120 s), so that what
    the matrix says is scored is what is."""
    from wtftc.config import TRANSIENT_S

    t_final = start + scored
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
    if not isinstance(g.get("iec"), str):
        raise ConfigError(f"groups.{name}.iec", g.get("iec"), "the group's IEC label, a "
                          "string", where=where)
    _number(g, "overspeed_trip", where, 1.0, 2.0, f"groups.{name}.")
    if name == "baseline_as_shipped":
        _winds(g, "near_mps", name, where)
        return
    _number(g, "scored_s", where, 1.0, 7200.0, f"groups.{name}.")
    if name == "deterministic":
        _check_deterministic(g, where)
        return
    seeds = g.get("seeds")
    if isinstance(seeds, bool) or not isinstance(seeds, int) or not 1 <= seeds <= MAX_SEEDS:
        raise ConfigError(f"groups.{name}.seeds", seeds, f"an integer in [1, {MAX_SEEDS}]",
                          where=where)
    if name == "normal_production":
        _number(g, "bin_width_mps", where, 0.5, 10.0, f"groups.{name}.")
        _number(g, "cut_out_mps", where, 5.0, 40.0, f"groups.{name}.")
        return
    _winds(g, "winds_mps", name, where)
    allowed = faults.ACTUATOR_FAULT_TYPES if name == "actuator_faults" \
        else faults.SENSOR_FAULT_TYPES
    types = g.get("types")
    if not isinstance(types, list) or not types or any(t not in allowed for t in types) \
            or len(set(types)) != len(types):
        raise ConfigError(f"groups.{name}.types", types, "a list of distinct types of "
                          + ", ".join(allowed), where=where)
    if not 0.0 <= _number(g, "onset_s", where, 0.0, 7200.0, f"groups.{name}.") < g["scored_s"]:
        raise ConfigError(f"groups.{name}.onset_s", g["onset_s"], "a time inside the "
                          f"scored {g['scored_s']:g} s", where=where)
    if name == "sensor_faults":
        _check_sensor_faults(g, where)


def _winds(g: dict, key: str, name: str, where: str) -> None:
    winds = g.get(key)
    if not isinstance(winds, list) or not winds or any(
            isinstance(v, bool) or not isinstance(v, numbers.Real) or not 3.0 <= v <= 40.0
            for v in winds) or len(set(winds)) != len(winds):
        raise ConfigError(f"groups.{name}.{key}", winds, "a list of distinct mean winds in "
                          "[3, 40] m/s", where=where)


def _check_sensor_faults(g: dict, where: str) -> None:
    """Each type's magnitude, in its key's unit (deg, -, deg/s; a speed sensor's stuck
    value and offset as a fraction of its shaft's rated speed), in the key's range; blade
    and sensor in theirs."""
    pre = "groups.sensor_faults."
    for key, lo, hi in (("blade", 1, 3), ("sensor", 1, 2)):
        v = g.get(key)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise ConfigError(pre + key, v, f"an integer in [{lo}, {hi}]", where=where)
    mags = g.get("magnitudes")
    if not isinstance(mags, dict) or set(mags) != set(g["types"]):
        raise ConfigError(pre + "magnitudes", mags, "a table of one magnitude per type of "
                          "types: " + ", ".join(g["types"]), where=where)
    for typ in g["types"]:
        key = faults.TYPES[typ].magnitude
        lo, hi = (0.0, 2.0) if key in SPEED_FRACTIONS else spec_bounds(key)
        _number(mags, typ, where, lo, hi, pre + "magnitudes.")


def spec_bounds(key: str) -> tuple[float, float]:
    """The sweep's range of a sensor fault's magnitude key (wtftc.campaign.sweep.spec)."""
    from wtftc.campaign.sweep.spec import SENSOR_MAGNITUDES

    return SENSOR_MAGNITUDES[key][1:3]


def _check_deterministic(g: dict, where: str) -> None:
    pre = "groups.deterministic."
    kinds = g.get("kinds")
    if not isinstance(kinds, list) or not kinds or any(
            k not in DETERMINISTIC_KINDS for k in kinds) or len(set(kinds)) != len(kinds):
        raise ConfigError(pre + "kinds", kinds, "a list of distinct kinds of "
                          + ", ".join(DETERMINISTIC_KINDS), where=where)
    offsets = g.get("winds_from_rated_mps")
    if not isinstance(offsets, list) or not offsets or any(
            isinstance(v, bool) or not isinstance(v, numbers.Real) or not -8.0 <= v <= 8.0
            for v in offsets) or len(set(offsets)) != len(offsets):
        raise ConfigError(pre + "winds_from_rated_mps", offsets, "a list of distinct "
                          "offsets from the rated wind in [-8, 8] m/s", where=where)
    if not 0.0 <= _number(g, "event_s", where, 0.0, 7200.0, pre) < g["scored_s"]:
        raise ConfigError(pre + "event_s", g["event_s"], "a time inside the scored "
                          f"{g['scored_s']:g} s", where=where)
    _number(g, "step_mps", where, 0.1, 10.0, pre)
    _number(g, "ramp_mps", where, 0.1, 20.0, pre)
    _number(g, "ramp_s", where, 1.0, 3600.0, pre)
    if g["event_s"] + g["ramp_s"] > g["scored_s"]:
        raise ConfigError(pre + "ramp_s", g["ramp_s"], f"a ramp that ends inside the scored "
                          f"{g['scored_s']:g} s (event_s + ramp_s)", where=where)
    if g.get("ecd_sign") not in (1, -1) or isinstance(g.get("ecd_sign"), bool):
        raise ConfigError(pre + "ecd_sign", g.get("ecd_sign"), "1 or -1", where=where)
    if g.get("turbine_class") not in V_REF:
        raise ConfigError(pre + "turbine_class", g.get("turbine_class"), "one of "
                          + ", ".join(V_REF), where=where)


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


def rated_wind(turbine: turbine_file.Turbine) -> float:
    """The turbine's rated wind [m/s] (config.rated_wind_speed: 11.42 m/s for the NREL
    5-MW) to 0.1 m/s, as the IEC's "V_r" the deterministic group is placed around."""
    from wtftc.config import rated_wind_speed

    return round(rated_wind_speed(turbine.vector(), turbine.table), 1)


def nearest_bins(m: dict, turbine: turbine_file.Turbine) -> list[float]:
    """The normal-production bins nearest the baseline_as_shipped group's ``near_mps``
    (the lower of two as near), each once, in order."""
    b = bins(m, turbine)
    near = m["groups"]["baseline_as_shipped"]["near_mps"]
    return sorted({min(b, key=lambda x, w=w: (abs(x - w), x)) for w in near})


def sweeps(m: dict, columns: list, turbine: str | None, engine: str,
           seeds: int | None = None) -> dict[str, dict]:
    """Each group of the matrix as a sweep file's content (wtftc.campaign.sweep.spec), on
    ``turbine`` in ``engine``, the controllers ``columns`` (names or tables, each a column
    of the results; the last is the baseline, which baseline_as_shipped runs alone),
    ``seeds`` in place of each group's when given (the deterministic group has none)."""
    t = turbine_file.load(turbine or turbine_file.DEFAULT)
    out = {}
    for name, g in m["groups"].items():
        k = seeds if seeds is not None else g.get(
            "seeds", m["groups"].get("normal_production", {}).get("seeds", 1))
        scored = g.get("scored_s", m["groups"].get("normal_production", {}).get("scored_s"))
        raw = {"name": f"scorecard {name} (DLC {g['iec']})", "engine": engine,
               "mode": "grid", "t_final_s": m["start_up_s"] + scored,
               "profile": "realistic",
               "controllers": copy.deepcopy(columns[-1:] if name == "baseline_as_shipped"
                                            else columns),
               "wind": {"rotor_radius_m": t.values["rotor_radius"],
                        "turbulence_class": m["turbulence_class"],
                        "seed": {"min": 0, "max": k - 1} if k > 1 else 0},
               **({"turbine": turbine} if turbine else {})}
        BUILD[name](raw, m, g, t)
        if engine == "wtftc":
            raw["plants"] = "tower_edge"
        out[name] = raw
    return out


def _normal_production(raw: dict, m: dict, g: dict, t) -> None:
    raw["wind"]["mean_mps"] = bins(m, t)
    raw["fault"] = {"type": "none"}
    raw["dlc"] = {"case": g["iec"], "annual_mean_mps": m["annual_mean_mps"],
                  "bin_width_mps": g["bin_width_mps"], "overspeed_trip": g["overspeed_trip"]}


def _actuator_faults(raw: dict, m: dict, g: dict, t) -> None:
    raw["wind"]["mean_mps"] = [float(v) for v in g["winds_mps"]]
    raw["fault"] = {"type": list(g["types"]), "blade": g["blade"],
                    "onset_s": m["start_up_s"] + g["onset_s"], "angle_deg": g["angle_deg"],
                    "rho": g["rho"], "severity": g["severity"],
                    "target_deg": [float(v) for v in g["runaway_targets_deg"]]}
    raw["dlc"] = {"case": g["iec"], "overspeed_trip": g["overspeed_trip"]}


def _sensor_faults(raw: dict, m: dict, g: dict, t) -> None:
    """Each type at its own magnitude (spec's per-type magnitude tables); a speed sensor's
    stuck value and offset scaled by its shaft's rated speed [rad/s] (the generator's on
    the fast shaft: the rotor's times the gearbox ratio)."""
    omega_r = float(t.values["omega_g_rated"])  # the rotor's rated speed [rad/s]
    rated = {"rotor_speed": omega_r,
             "generator_speed": omega_r * float(t.values["gearbox_ratio"])}
    fault = {"type": list(g["types"]), "blade": g["blade"], "sensor": g["sensor"],
             "onset_s": m["start_up_s"] + g["onset_s"]}
    for typ in g["types"]:
        ft = faults.TYPES[typ]
        value = float(g["magnitudes"][typ])
        if ft.magnitude in SPEED_FRACTIONS:
            value = round(value * rated[ft.signal], 9)
        fault.setdefault(ft.magnitude, {})[typ] = value
    raw["wind"]["mean_mps"] = [float(v) for v in g["winds_mps"]]
    raw["fault"] = fault
    raw["dlc"] = {"case": g["iec"], "overspeed_trip": g["overspeed_trip"]}


def _deterministic(raw: dict, m: dict, g: dict, t) -> None:
    """The kinds at rated + each offset, one run each: seed 0, no rotor radius (a uniform
    wind), the event ``event_s`` after the start-up; ``--seeds`` changes nothing here."""
    v_r = rated_wind(t)
    wind = raw["wind"]
    del wind["rotor_radius_m"]
    wind.update(seed=0, kind=list(g["kinds"]),
                mean_mps=[round(v_r + d, 6) for d in g["winds_from_rated_mps"]],
                event_s=m["start_up_s"] + g["event_s"], step_mps=g["step_mps"],
                ramp_mps=g["ramp_mps"], ramp_s=g["ramp_s"], sign=g["ecd_sign"],
                turbine_class=g["turbine_class"])
    raw["fault"] = {"type": "none"}
    # no [dlc] table: a sweep's summary weights DLC 1.2 and 2.1 only (sweep.dlc); the
    # group's overspeed trip is the matrix's


def _baseline_as_shipped(raw: dict, m: dict, g: dict, t) -> None:
    """The baseline alone, as its deck ships it (host = "as_shipped"), on the
    normal-production runs of the bins nearest near_mps: the same seeds, length and
    scoring, so each run pairs with the baseline's normal-production run."""
    npg = m["groups"]["normal_production"]
    raw["wind"]["mean_mps"] = nearest_bins(m, t)
    raw["fault"] = {"type": "none"}
    raw["host"] = "as_shipped"
    raw["dlc"] = {"case": npg["iec"], "overspeed_trip": g["overspeed_trip"]}


#: each group's sweep, from the matrix (sweeps)
BUILD = {"normal_production": _normal_production, "actuator_faults": _actuator_faults,
         "sensor_faults": _sensor_faults, "deterministic": _deterministic,
         "baseline_as_shipped": _baseline_as_shipped}


def plan(m: dict, turbine: str | None = None, seeds: int | None = None,
         wall_per_sim_s: float = OPENFAST_WALL_PER_SIM_S) -> dict[str, dict]:
    """Per group: its columns (2, the baseline_as_shipped group 1), runs per column, each
    run's simulated length, the simulated seconds per column, and the OpenFAST CPU time
    of the group (all its columns) at ``wall_per_sim_s`` [s of wall time per simulated s,
    one core]: the runs the sweeps list (wtftc.campaign.sweep.spec.expand), counted."""
    from wtftc.campaign.sweep import spec

    out = {}
    for name, raw in sweeps(m, ["pi", "rosco"], turbine, "wtftc", seeds).items():
        runs, _ = spec.expand(spec.parse_sweep(raw))
        n_cols = len(raw["controllers"])
        per_col = len(runs) // n_cols
        sim = per_col * raw["t_final_s"]
        out[name] = {"iec": m["groups"][name]["iec"], "columns": n_cols,
                     "runs_per_column": per_col, "t_final_s": raw["t_final_s"],
                     "simulated_s_per_column": sim,
                     "openfast_cpu_s": sim * n_cols * wall_per_sim_s}
    return out
