"""Tuned families on the trade-off planes (issue 18, docs/compare.md): a sweep with a
[tuning] table runs ROSCO, the PI and the physical AFTC at each target mode (ω_n, ζ) of
their pitch loop; the summary places each controller's tunings on the planes engineers
read: the speed error against the pitch duty, the shaft DEL and the tower-base DEL,
fault-free and under faults.

Each point is the mean over its runs (winds, seeds and, under faults, fault types) of:
the RMS speed error against the own reference above rated, the pitch ADC, the DELs at
1 Hz; and the largest peak speed. Controllers without a [tuning] target (the paper's
design, or a sweep run at the defaults) are one point each.
"""

from __future__ import annotations

import numpy as np

from wtftc.campaign.sweep.dlc import rank

#: (key, header, scale, format, statistic)
COLUMNS = [("rms_speed_error_own_above_rated_rad_s",
            "RMS ω error, own ref., above rated, mean [rad/s]", 1.0, "{:.4f}", "mean"),
           ("pitch_adc", "pitch ADC mean [-]", 1.0, "{:.3f}", "mean"),
           ("shaft_torque_del_1hz_Nm", "shaft DEL 1 Hz mean [MN m]", 1e-6, "{:.3f}", "mean"),
           ("tower_base_del_1hz_Nm", "tower-base DEL 1 Hz mean [MN m]", 1e-6, "{:.2f}", "mean"),
           ("overspeed_peak_over_rated", "peak ω / rated max [-]", 1.0, "{:.3f}", "max"),
           ("shaft_torque_max_abs_Nm", "shaft torque max [MN m]", 1e-6, "{:.2f}", "max"),
           ("mean_electrical_power_W", "mean power [MW]", 1e-6, "{:.3f}", "mean")]
#: the planes: (y key, y label); x is the speed error
PLANES = [("pitch_adc", "pitch actuator duty cycle [-]"),
          ("shaft_torque_del_1hz_Nm", "shaft torque DEL at 1 Hz [MN m]"),
          ("tower_base_del_1hz_Nm", "tower-base fore-aft DEL at 1 Hz [MN m]")]


def tuned(rows: list[dict]) -> bool:
    """Whether the sweep ran a tuned family."""
    return any(r.get("tuning_omega_n_rad_s") is not None for r in rows)


def points(rows: list[dict], faulted: bool, order=()) -> dict[str, list[dict]]:
    """controller → its points, by target ω_n: the statistics of COLUMNS over its runs
    (status ok; fault-free or faulted)."""
    groups: dict[tuple, list] = {}
    for r in rows:
        if r["status"] == "ok" and (r["fault_type"] != "none") == faulted:
            key = (r["controller"], r.get("tuning_omega_n_rad_s"), r.get("tuning_zeta"))
            groups.setdefault(key, []).append(r)
    out: dict[str, list[dict]] = {}
    place = rank(rows, order)
    for (c, w, z), rs in sorted(groups.items(), key=lambda kv: (
            place[kv[0][0]], kv[0][1] or 0.0, kv[0][2] or 0.0)):
        pt = {"omega_n": w, "zeta": z, "runs": len(rs)}
        for key, _, _, _, stat in COLUMNS:
            vals = [r[key] for r in rs if r.get(key) is not None]
            pt[key] = (float(np.mean(vals)) if stat == "mean" else float(np.max(vals))) \
                if vals else None
        out.setdefault(c, []).append(pt)
    return out


def section(rows: list[dict], order=()) -> tuple[list[str], list[str]]:
    """The summary's tuned-family section: a table per condition; Markdown and CSV."""
    lines = ["", "## Tuned families (docs/compare.md): each controller at each target "
             "mode of its pitch loop", "",
             "Means over the runs (winds, seeds, fault types); figures "
             "`figures/tradeoff_fault_free.png`, `figures/tradeoff_faulted.png`.", ""]
    head = ["condition", "controller", "target ω_n [rad/s]", "target ζ [-]", "runs"] + [
        h for _, h, *_ in COLUMNS]
    csv = [",".join(["condition", "controller", "omega_n_rad_s", "zeta", "runs"]
                    + [f"{k} {stat}" for k, _, _, _, stat in COLUMNS])]
    lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for faulted in (False, True):
        cond = "faulted" if faulted else "fault-free"
        for c, pts in points(rows, faulted, order).items():
            for p in pts:
                cells = [cond, c, _f(p["omega_n"], "{:g}"), _f(p["zeta"], "{:g}"),
                         str(p["runs"])] + [_f(p[k], fmt, s) for k, _, s, fmt, _ in COLUMNS]
                lines.append("| " + " | ".join(cells) + " |")
                csv.append(",".join([cond, c, *("" if p[k] is None else str(p[k]) for k in (
                    "omega_n", "zeta")), str(p["runs"])] + [
                    "" if p[k] is None else str(p[k]) for k, *_ in COLUMNS]))
    return lines + overspeed_by_fault(rows, order), csv


def overspeed_by_fault(rows: list[dict], order=()) -> list[str]:
    """The largest peak speed per controller, target and fault type (a runaway by its
    direction): the extremes a design goal compares fault by fault."""
    from wtftc.campaign.sweep.dlc import fault_label

    peaks: dict[tuple, float] = {}
    for r in rows:
        if r["status"] != "failed" and r["fault_type"] != "none" \
                and r.get("overspeed_peak_over_rated") is not None:
            key = (r["controller"], r.get("tuning_omega_n_rad_s"), fault_label(r))
            peaks[key] = max(peaks.get(key, 0.0), r["overspeed_peak_over_rated"])
    faults = sorted({f for _, _, f in peaks})
    if not faults:
        return []
    lines = ["", "Largest peak ω / rated [-] per fault type (every run of it):", "",
             "| controller | target ω_n [rad/s] | " + " | ".join(faults) + " |",
             "|---|---|" + "---|" * len(faults)]
    place = rank(rows, order)
    targets = sorted({(c, w) for c, w, _ in peaks}, key=lambda cw: (place[cw[0]], cw[1] or 0.0))
    for c, w in targets:
        lines.append(f"| {c} | {_f(w, '{:g}')} | " + " | ".join(
            _f(peaks.get((c, w, f)), "{:.3f}") for f in faults) + " |")
    return lines


def _f(v, fmt: str, scale: float = 1.0) -> str:
    return "—" if v is None else fmt.format(v * scale)


def figure(rows: list[dict], faulted: bool, order=()):
    """The trade-off planes of one condition, a line per controller through its targets
    (labelled by ω_n); the caller saves it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pts = points(rows, faulted, order)
    fig, axes = plt.subplots(1, len(PLANES), figsize=(5 * len(PLANES), 4.2))
    x_key = COLUMNS[0][0]
    for ax, (y_key, label) in zip(axes, PLANES, strict=True):
        scale = 1e-6 if y_key.endswith("_Nm") else 1.0
        for c, ps in pts.items():
            xy = [(p[x_key], p[y_key] * scale, p["omega_n"]) for p in ps
                  if p[x_key] is not None and p[y_key] is not None]
            if not xy:
                continue
            line, = ax.plot([a for a, _, _ in xy], [b for _, b, _ in xy], "o-", label=c)
            for a, b, w in xy:
                if w is not None:
                    ax.annotate(f"{w:g}", (a, b), fontsize=7, color=line.get_color(),
                                xytext=(3, 3), textcoords="offset points")
        ax.set_xlabel("RMS rotor-speed error, own reference, above rated [rad/s]")
        ax.set_ylabel(label + " (log)")
        ax.set_yscale("log")  # a design far off (the paper's) leaves the others readable
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(("Under faults" if faulted else "Fault-free")
                 + ": each controller's tunings (labels: target ω_n [rad/s]), "
                   "means over runs", fontsize=9)
    return fig
