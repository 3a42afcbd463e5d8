"""IEC 61400-1 design load case summaries of a sweep (issue 18, docs/loads.md): the
runs of each mean-wind bin weighted by the wind's Rayleigh distribution into a lifetime
damage-equivalent load and an annual energy production.

A sweep file's ``[dlc]`` table asks for it:

    [dlc]
    case = "1.2"               # power production in normal turbulence (fatigue, energy)
    annual_mean_mps = 10.0     # the Rayleigh distribution's mean: IEC class I 10, II 8.5,
                               # III 7.5 m/s (IEC 61400-1 ed. 3, table 1)
    bin_width_mps = 2.0        # each mean wind stands for [v − w/2, v + w/2)

The probability of bin b is p_b = F(v_b + w/2) − F(v_b − w/2), F(v) = 1 − exp(−π/4
(v / V_ave)²) (IEC 61400-1, 6.3.1.1). Then, per controller, with D_b the mean over the
bin's seeds of the shaft's damage per 10 minutes (Σ n_i S_i^m, wtftc/results/loads.py)
and P_b their mean electrical power:

    lifetime DEL at 1 Hz = (Σ_b p_b D_b / 600 s)^(1/m)                      (MLife)
    AEP = 8760 h × Σ_b p_b P_b                                              (pCrunch's year)

The DEL follows NREL's MLife (Hayman, MLife Theory Manual v1.00, 2012): each bin's damage
is extrapolated to the design life T_L by the factor T_L p_b a / 600 s (a the
availability, here 1; it scales the AEP too), and the lifetime DEL is the constant range
whose T_L × f_eq cycles (f_eq = 1 Hz) do that damage. T_L cancels, leaving the line
above: a damage rate over calendar time, in which the wind outside the simulated bins
does no damage (it is not spread over them). The AEP takes the year as 365 × 24 = 8760 h,
as pCrunch does (NREL's Python successor to MLife, ``compute_aep``), and counts no energy
outside the bins. Two departures from pCrunch, stated: it scales its case probabilities
to sum to 1 over the simulated cases; p_b here are the Rayleigh bins' own shares of the
year, Σ_b p_b ≤ 1 (``share_of_year``, printed beside the figures); and its weighted DEL
is Σ prob × DEL, a mean of the DELs, where the DEL here is MLife's, from the summed
damage.

Before issue 31 the DEL was divided by (Σ_b p_b)^(1/m) (the damage rate of the covered
time only) and the year was 8766 h. Between two controllers over the same bins (what
``against`` compares) the division cancels: their ratios are the same either way.

The weighted pitch ADC is a duty cycle, so it stays a mean over the bins' time:
Σ_b p_b ADC_b / Σ_b p_b.
"""

from __future__ import annotations

import math

import numpy as np

from wtftc.config import LOADS_KEYS
from wtftc.errors import ConfigError

DLC_KEYS = {"case": ("1.2", "2.1"), "annual_mean_mps": (1.0, 30.0),
            "bin_width_mps": (0.1, 10.0), "overspeed_trip": (1.0, 2.0)}
DEFAULTS = {"case": "1.2", "annual_mean_mps": 10.0, "bin_width_mps": 2.0,
            "overspeed_trip": 1.2}
HOURS_PER_YEAR = 8760.0   # 365 × 24 h, pCrunch's year (module docstring)
AVAILABILITY = 1.0        # MLife's availability factor a (module docstring)


def parse_dlc(table) -> dict:
    """The ``[dlc]`` table, checked, defaults filled in."""
    if not isinstance(table, dict):
        raise ConfigError("dlc", table, "a table with " + ", ".join(DLC_KEYS))
    for key in table:
        if key not in DLC_KEYS:
            raise ConfigError(f"dlc.{key}", table[key], "a known key: " + ", ".join(DLC_KEYS))
    out = {**DEFAULTS, **table}
    if out["case"] not in DLC_KEYS["case"]:
        raise ConfigError("dlc.case", out["case"], '"1.2" (power production, normal '
                          'turbulence) or "2.1" (power production with a control fault)')
    for key, unit in (("annual_mean_mps", "m/s"), ("bin_width_mps", "m/s"),
                      ("overspeed_trip", "× rated speed")):
        lo, hi = DLC_KEYS[key]
        v = out[key]
        if isinstance(v, bool) or not isinstance(v, int | float) or not lo <= v <= hi:
            raise ConfigError(f"dlc.{key}", v, f"a number in [{lo:g}, {hi:g}] [{unit}]")
        out[key] = float(v)
    return out


def rayleigh_cdf(v, annual_mean: float):
    """F(v) = 1 − exp(−π/4 (v / V_ave)²) (IEC 61400-1, 6.3.1.1)."""
    v = np.maximum(np.asarray(v, dtype=float), 0.0)
    return 1.0 - np.exp(-math.pi / 4.0 * (v / annual_mean) ** 2)


def bin_probability(v, width: float, annual_mean: float):
    """The share of the year the mean wind is within [v − w/2, v + w/2)."""
    v = np.asarray(v, dtype=float)
    return rayleigh_cdf(v + width / 2, annual_mean) - rayleigh_cdf(v - width / 2, annual_mean)


def rank(rows: list[dict], order=()) -> dict[str, int]:
    """controller → its place in the summary: the sweep's columns' order (``order``),
    then any other controller in the rows' order."""
    names = dict.fromkeys([*order, *(r["controller"] for r in rows)])
    return {c: i for i, c in enumerate(names)}


def per_bin(rows: list[dict], order=()) -> dict:
    """controller → mean wind → the bin's means over its runs: damage per 10 minutes,
    electrical power, pitch ADC, shaft DEL; and the number of runs."""
    out: dict[str, dict[float, dict]] = {}
    for r in rows:
        if r["status"] != "ok" or r["fault_type"] != "none":
            continue
        out.setdefault(r["controller"], {}).setdefault(round(r["mean_wind_mps"], 6),
                                                       []).append(r)
    keys = ("shaft_torque_damage_per_10min", "mean_electrical_power_W", "pitch_adc",
            "shaft_torque_del_1hz_Nm", "tower_base_damage_per_10min", "tower_base_del_1hz_Nm")
    return {c: {v: {"runs": len(rs), **{k: _mean([r.get(k) for r in rs]) for k in keys}}
                for v, rs in sorted(out[c].items())} for c in rank(rows, order) if c in out}


def _mean(values: list) -> float | None:
    """The mean, or None where a run has no value (the tower's on a plant without one)."""
    return None if any(v is None for v in values) else float(np.mean(values))


def lifetime(bins: dict, dlc: dict, m: float, m_tower: float = 4.0) -> dict:
    """One controller's lifetime figures from its bins (per_bin's), module docstring; the
    tower base's where every bin has it (the tower plant)."""
    winds = np.array(list(bins))
    p = bin_probability(winds, dlc["bin_width_mps"], dlc["annual_mean_mps"])
    share = float(p.sum())

    def col(key):
        return np.array([b[key] for b in bins.values()], dtype=float)

    def life_del(key, mm):
        # MLife: damage over calendar time, none outside the bins (no division by Σp)
        if any(b.get(key) is None for b in bins.values()):
            return None
        return float((AVAILABILITY * (p @ col(key)) / 600.0) ** (1.0 / mm))

    return {"bins": len(winds), "share_of_year": share,
            "lifetime_shaft_del_1hz_Nm": life_del("shaft_torque_damage_per_10min", m),
            "lifetime_tower_del_1hz_Nm": life_del("tower_base_damage_per_10min", m_tower),
            "aep_Wh": float(HOURS_PER_YEAR * AVAILABILITY
                            * (p @ col("mean_electrical_power_W"))),
            "weighted_pitch_adc": float(p @ col("pitch_adc") / share)}


def section(rows: list[dict], table: dict, order=(), ref: str | None = None
            ) -> tuple[list[str], list[str]]:
    """The summary's DLC section: per controller the lifetime figures, then per bin the
    shaft DEL, the pitch ADC and the power; Markdown lines and CSV lines (SI units);
    ``order``: the sweep's columns, ``ref``: the one the others are set against (ROSCO)."""
    dlc = parse_dlc(table)
    # the Wöhler exponents of every sweep run: the [loads] defaults (a sweep has no [loads])
    m, m_tower = (LOADS_KEYS[k][0] for k in ("shaft_wohler_exponent", "tower_wohler_exponent"))
    bins = per_bin(rows, order)
    # the bins the campaign simulated, whether or not every controller kept them
    simulated = sorted({round(r["mean_wind_mps"], 6) for r in rows
                        if r["fault_type"] == "none"})
    covered = float(np.sum(bin_probability(simulated, dlc["bin_width_mps"],
                                           dlc["annual_mean_mps"])))
    lines = ["", f"## DLC {dlc['case']}: lifetime-weighted (Rayleigh, annual mean "
             f"{dlc['annual_mean_mps']:g} m/s, bins of {dlc['bin_width_mps']:g} m/s; "
             "docs/loads.md)", "",
             f"The simulated bins ({', '.join(f'{v:g}' for v in simulated)} m/s) cover "
             f"Σp = {covered:.3f} of the year; a controller's own Σp (below) leaves out the "
             "bins it lost. Lifetime DELs follow MLife: the damage over calendar time, none "
             "outside the bins (availability 1), not divided by Σp. The AEP takes the year "
             "as 8760 h (pCrunch) and counts no energy outside the bins. The weighted ADC "
             "is the mean over the bins' time (Σp-normalised).", "",
             "| controller | runs used (of fault-free) | bins | share of the year Σp [-] | "
             f"lifetime shaft DEL 1 Hz, m = {m:g} (MLife: calendar time, bins outside 0) "
             f"[MN m] | lifetime tower-base DEL 1 Hz, m = {m_tower:g} (MLife: calendar "
             "time, bins outside 0) [MN m] | AEP (8760 h, bins outside 0) [GWh] | "
             "weighted pitch ADC (mean over the bins, ÷ Σp) [-] |",
             "|---|---|---|---|---|---|---|---|"]
    keys = ("shaft_torque_del_1hz_Nm", "shaft_torque_damage_per_10min",
            "tower_base_del_1hz_Nm", "tower_base_damage_per_10min", "pitch_adc",
            "mean_electrical_power_W")
    csv = ["controller,mean_wind_mps,runs,bin_probability," + ",".join(keys)]
    for c, cb in bins.items():
        life = lifetime(cb, dlc, m, m_tower)
        used = sum(b["runs"] for b in cb.values())
        free = sum(r["controller"] == c and r["fault_type"] == "none" for r in rows)
        tower = life["lifetime_tower_del_1hz_Nm"]
        lines.append(f"| {c} | {used} of {free} | {life['bins']} | {life['share_of_year']:.3f} | "
                     f"{life['lifetime_shaft_del_1hz_Nm'] / 1e6:.3f} | "
                     f"{'—' if tower is None else f'{tower / 1e6:.2f}'} | "
                     f"{life['aep_Wh'] / 1e9:.2f} | {life['weighted_pitch_adc']:.3f} |")
        for v, b in cb.items():
            p = float(bin_probability(v, dlc["bin_width_mps"], dlc["annual_mean_mps"]))
            csv.append(f"{c},{v},{b['runs']},{p}," + ",".join(
                "" if b[k] is None else str(b[k]) for k in keys))
    lines += against(bins, dlc, m, m_tower, ref)
    lines += ["", "Per wind bin (`summary_dlc.csv`; figure `figures/dlc_bins.png`): shaft "
              "DEL [MN m] / pitch ADC [-], the mean over the bin's seeds.", ""]
    winds = sorted({v for cb in bins.values() for v in cb})
    lines += ["| controller | " + " | ".join(f"{v:g} m/s" for v in winds) + " |",
              "|---|" + "---|" * len(winds)]
    for c, cb in bins.items():
        lines.append(f"| {c} | " + " | ".join(
            f"{cb[v]['shaft_torque_del_1hz_Nm'] / 1e6:.3f} / {cb[v]['pitch_adc']:.3f}"
            if v in cb else "—" for v in winds) + " |")
    return lines, csv


def against(bins: dict, dlc: dict, m: float, m_tower: float, ref: str | None) -> list[str]:
    """Each controller against ``ref`` over the wind bins both kept (a lifetime figure
    over different bins compares different years): the ratios of the lifetime DELs and
    weighted ADC, and the AEP's difference."""
    if ref is None or ref not in bins or len(bins) < 2:
        return []
    lines = ["", f"Against {ref}, over the bins both kept (over the same bins the ratios do "
             "not depend on the normalisation: MLife's calendar-time DEL and the "
             "Σp-normalised one give the same ratio, and the AEP's difference does not "
             "depend on the hours a year):", "",
             f"| controller | bins in common | lifetime shaft DEL / {ref} (MLife) [-] | "
             f"lifetime tower-base DEL / {ref} (MLife) [-] | weighted ADC / {ref} [-] | "
             f"AEP (8760 h) vs {ref} [%] |",
             "|---|---|---|---|---|---|"]
    for c, cb in bins.items():
        common = sorted(set(cb) & set(bins[ref]))
        if c == ref or not common:
            continue
        a, b = (lifetime({v: x[v] for v in common}, dlc, m, m_tower) for x in (cb, bins[ref]))
        ratios = [_ratio(a[k], b[k]) for k in ("lifetime_shaft_del_1hz_Nm",
                                               "lifetime_tower_del_1hz_Nm",
                                               "weighted_pitch_adc")]
        lines.append(f"| {c} | {', '.join(f'{v:g}' for v in common)} | "
                     + " | ".join(ratios) + f" | {100 * (a['aep_Wh'] / b['aep_Wh'] - 1):+.2f} |")
    return lines


def _ratio(a, b) -> str:
    return "—" if a is None or not b else f"{a / b:.2f}"


def fault_label(r: dict) -> str:
    """A run's fault as the DLC 2.1 tables name it: a runaway by its direction."""
    if r["fault_type"] != "runaway":
        return r["fault_type"]
    return "runaway_fine" if (r.get("runaway_target_deg") or 0.0) < 45.0 else "runaway_feather"


#: the DLC 2.1 extremes: (key, header, scale, format)
EXTREMES = [("overspeed_peak_over_rated", "extreme ω / rated [-]", 1.0, "{:.3f}"),
            ("shaft_torque_max_abs_Nm", "extreme shaft torque [MN m]", 1e-6, "{:.2f}"),
            ("tower_base_max_abs_Nm", "extreme tower-base moment [MN m]", 1e-6, "{:.1f}")]


def extremes(rows: list[dict], trip: float, order=()) -> dict:
    """(controller, fault) → runs, lost (left the envelope), held (never above ``trip`` ×
    rated and not lost: no overspeed shutdown) and the extremes (EXTREMES) over its runs."""
    groups: dict[tuple, list] = {}
    for r in rows:
        if r["fault_type"] != "none" and r["status"] != "failed":
            groups.setdefault((r["controller"], fault_label(r)), []).append(r)
    out, place = {}, rank(rows, order)
    for key, rs in sorted(groups.items(), key=lambda kv: (place[kv[0][0]], kv[0][1])):
        held = sum(r["status"] == "ok" and (r["overspeed_peak_over_rated"] or 0.0) <= trip
                   for r in rs)
        out[key] = {"runs": len(rs), "lost": sum(r["status"] == "diverged" for r in rs),
                    "held": held, **{k: max((r[k] for r in rs if r.get(k) is not None),
                                            default=None) for k, *_ in EXTREMES}}
    return out


def fault_section(rows: list[dict], table: dict, order=()) -> tuple[list[str], list[str]]:
    """The summary's DLC 2.1 section: per controller and fault type, the runs held
    without an overspeed shutdown and the extremes; Markdown and CSV lines (SI)."""
    dlc = parse_dlc(table)
    trip = dlc["overspeed_trip"]
    head = ["controller", "fault", "runs", "rotor lost", f"held (ω ≤ {trip:g} × rated)"] + [
        h for _, h, _, _ in EXTREMES]
    lines = ["", "## DLC 2.1: power production with a control fault (docs/loads.md)", "",
             "A fault at a random time in each run; a runaway drives its blade toward fine "
             "pitch (0°) or feather (90°). \"Held\": the rotor never left the envelope nor "
             f"passed {trip:g} × rated speed (an overspeed protection would have shut the "
             "turbine down). Figure `figures/dlc21_extremes.png`.", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    csv = ["controller,fault,runs,lost,held," + ",".join(k for k, *_ in EXTREMES)]
    for (c, f), e in extremes(rows, trip, order).items():
        lines.append("| " + " | ".join([c, f, str(e["runs"]), str(e["lost"]), str(e["held"])]
                                       + ["—" if e[k] is None else fmt.format(e[k] * s)
                                          for k, _, s, fmt in EXTREMES]) + " |")
        csv.append(",".join([c, f, str(e["runs"]), str(e["lost"]), str(e["held"])]
                            + ["" if e[k] is None else str(e[k]) for k, *_ in EXTREMES]))
    return lines, csv


def fault_figure(rows: list[dict], table: dict, order=()):
    """The extreme overspeed and shaft torque per fault type, a bar per controller."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ext = extremes(rows, parse_dlc(table)["overspeed_trip"], order)
    ctrls = list(dict.fromkeys(c for c, _ in ext))
    faults = sorted({f for _, f in ext})
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    width = 0.8 / max(len(ctrls), 1)
    for ax, (key, label, scale, _) in zip(axes, EXTREMES[:2], strict=True):
        for i, c in enumerate(ctrls):
            vals = [(ext.get((c, f), {}).get(key) or np.nan) * scale for f in faults]
            ax.bar(np.arange(len(faults)) + i * width, vals, width, label=c)
        ax.set_xticks(np.arange(len(faults)) + 0.4 - width / 2, faults, rotation=20,
                      fontsize=8)
        ax.set_ylabel(label)
    axes[0].axhline(parse_dlc(table)["overspeed_trip"], color="k", lw=0.8, ls="--")
    axes[0].set_ylim(bottom=1.0)
    axes[0].legend(fontsize=8)
    fig.suptitle("DLC 2.1: extremes over every run of each fault type", fontsize=9)
    return fig


def figure(rows: list[dict], order=()):
    """Shaft DEL and pitch ADC per wind bin, one line per controller (the caller saves)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    bins = per_bin(rows, order)
    tower = any(b["tower_base_del_1hz_Nm"] is not None for cb in bins.values()
                for b in cb.values())
    fig, axes = plt.subplots(1, 3 if tower else 2, figsize=(14 if tower else 10, 4))
    panels = [("shaft_torque_del_1hz_Nm", 1e-6, "shaft torque DEL at 1 Hz [MN m]"),
              ("pitch_adc", 1.0, "pitch actuator duty cycle [-]"),
              ("tower_base_del_1hz_Nm", 1e-6, "tower-base fore-aft DEL at 1 Hz [MN m]")]
    for ax, (key, scale, label) in zip(axes, panels, strict=False):
        for c, cb in bins.items():
            pts = [(v, b[key] * scale) for v, b in cb.items() if b[key] is not None]
            if pts:
                ax.plot(*zip(*pts, strict=True), "o-", label=c)
        ax.set_xlabel("mean wind [m/s]")
        ax.set_ylabel(label)
    axes[0].legend(fontsize=8)
    fig.suptitle("Per wind bin, mean over seeds (fault-free runs)", fontsize=9)
    return fig
