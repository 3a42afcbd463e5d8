"""Each controller against a reference on the same runs (issue 34's goals): for every
scenario both ran (same wind, turbulence class, seed, plant, mismatch, fault: type,
blade, sensor, onset and size, and the same [tuning] target where the sweep has one) and
both held, the ratio controller / reference of each metric, then per fault type the
median and the range of those ratios.

A ratio of medians over different runs compares different weather; a paired ratio does
not, and its range shows whether one controller wins on every run or only on average.
"Held" is DLC 2.1's: the rotor never left the envelope (status ok) nor passed the
overspeed trip; a scenario one of the two lost is counted, not compared, since its
metrics describe a rotor that stopped. A scenario either failed on (an error, not the
rotor) is counted apart and not compared."""

from __future__ import annotations

import numpy as np

from wtftc.campaign.sweep.dlc import fault_label, rank
from wtftc.campaign.sweep.spec import MAGNITUDE_COLUMN

#: the metrics compared: (run key, header)
PAIRED = [("rms_speed_error_rad_s", "RMS ω error"),
          ("overspeed_peak_over_rated", "peak ω"),
          ("shaft_torque_del_1hz_Nm", "shaft DEL"),
          ("shaft_torque_std_Nm", "shaft torque σ"),
          ("tower_base_del_1hz_Nm", "tower-base DEL"),
          ("pitch_adc", "pitch ADC")]
#: what pairs two runs: every axis of a scenario but the controller
SCENARIO = ("plant", "mean_wind_mps", "turbulence_class", "seed", "blade", "fault_sensor",
            "onset_s", *MAGNITUDE_COLUMN.values(), "tuning_omega_n_rad_s", "tuning_zeta")


def scenario(r: dict) -> tuple:
    """The key two runs of different controllers share when they ran the same case (a
    row without a wind kind is an NTM run's: made before sweeps had other winds)."""
    return (fault_label(r), r.get("wind_kind") or "ntm", *(r.get(k) for k in SCENARIO),
            *(v for k, v in sorted(r.items()) if k.startswith("mismatch_")))


def label(c: str, r: dict) -> str:
    """A controller's row: its name, and its [tuning] target where it has one."""
    w = r.get("tuning_omega_n_rad_s")
    return c if w is None else f"{c} at ({w:g} rad/s, ζ {r['tuning_zeta']:g})"


def reference(columns: dict) -> str | None:
    """The reference of the paired section: ROSCO's column (design = rosco), the first at
    its deck's tuning where there is one, at its deck's gains or at the sweep's [tuning]
    target (each tuned run is paired with ROSCO's at the same target); None without one."""
    roscos = [c for c, ctrl in columns.items() if ctrl.design == "rosco"]
    plain = [c for c in roscos if not columns[c].tuning and not columns[c].params]
    return (plain or roscos or [None])[0]


def held(r: dict, trip: float) -> bool:
    return r["status"] == "ok" and (r["overspeed_peak_over_rated"] or 0.0) <= trip


def pairs(rows: list[dict], c: str, ref: str) -> dict[str, dict[str, list]]:
    """Row label (``c`` and its tuning) → fault type → the (run of ``c``, run of ``ref``)
    on each scenario both ran, each scenario once (a duplicate row is paired once)."""
    by_ref = {scenario(r): r for r in rows if r["controller"] == ref}
    mine = {scenario(r): r for r in rows if r["controller"] == c}
    out: dict[str, dict[str, list]] = {}
    for key, r in mine.items():
        if key in by_ref:
            out.setdefault(label(c, r), {}).setdefault(fault_label(r), []).append(
                (r, by_ref[key]))
    return out


def ratios(pp: list[tuple[dict, dict]], key: str, trip: float) -> list[float]:
    """``key``'s ratio on each pair both held and both have a value for (a tower-less
    plant has no tower-base DEL; a zero reference gives no ratio)."""
    return [a[key] / b[key] for a, b in pp if held(a, trip) and held(b, trip)
            and a.get(key) is not None and b.get(key)]


def _cell(vals: list[float]) -> str:
    if not vals:
        return "—"
    return f"{np.median(vals):.2f} ({min(vals):.2f}-{max(vals):.2f})"


def section(rows: list[dict], trip: float, ref: str | None, order=()
            ) -> tuple[list[str], list[str]]:
    """The summary's paired section against column ``ref``: Markdown lines and CSV lines
    (the median, min and max ratio per controller, fault type and metric), the
    controllers in ``order``; nothing where no run pairs."""
    if ref is None:
        return [], []
    head = ["controller", "fault", "scenarios", "failed", "both held", "lost by it",
            f"lost by {ref}"]
    lines = ["", f"## Against {ref}, on the same runs", "",
             f"Each cell is the median ratio controller / {ref} over the scenarios both ran "
             f"and both held (never above {trip:g} × rated, rotor kept), with its min-max "
             f"in brackets: below 1, lower than {ref}'s on those runs. A tuned controller "
             f"meets {ref} at the same [tuning] target. `peak ω` is the ratio of the peak "
             "rotor speeds; \"failed\" counts the scenarios either run failed on (an error, "
             "not the rotor), left out of the rest. `summary_paired.csv` has the numbers; "
             "`figures/paired_tradeoff.png` each run both held.",
             "", "| " + " | ".join(head + [h for _, h in PAIRED]) + " |",
             "|" + "---|" * (len(head) + len(PAIRED))]
    csv = ["controller,reference,fault,scenarios,failed,both_held,lost_by_controller,"
           "lost_by_reference," + ",".join(f"{k}_ratio_{s}" for k, _ in PAIRED
                                           for s in ("median", "min", "max"))]
    for c in rank(rows, order):
        if c == ref:
            continue
        for lbl, by_fault in sorted(pairs(rows, c, ref).items()):
            for f, pp in [*sorted(by_fault.items()),
                          ("all", [p for v in by_fault.values() for p in v])]:
                counts, vals = _counts(pp, trip), [ratios(pp, k, trip) for k, _ in PAIRED]
                lines.append(f"| {lbl} | {f} | " + " | ".join(map(str, counts)) + " | "
                             + " | ".join(_cell(v) for v in vals) + " |")
                csv.append(",".join([lbl.replace(",", ";"), ref, f, *map(str, counts)] + [
                    "" if not v else repr(float(x)) for v in vals
                    for x in ((np.median(v), min(v), max(v)) if v else (None,) * 3)]))
    return (lines, csv) if len(csv) > 1 else ([], [])


def _counts(pp: list[tuple[dict, dict]], trip: float) -> list[int]:
    """Scenarios, failed on either side, both held, lost by the controller, lost by the
    reference (a failed scenario counts only as failed)."""
    ok = [(a, b) for a, b in pp if "failed" not in (a["status"], b["status"])]
    return [len(pp), len(pp) - len(ok), sum(held(a, trip) and held(b, trip) for a, b in ok),
            sum(not held(a, trip) for a, _ in ok), sum(not held(b, trip) for _, b in ok)]


#: the trade-off panels: what the regulation cost (y) against what it bought (x), each a
#: ratio to the reference on the same run
COSTS = [("shaft_torque_del_1hz_Nm", "shaft DEL"), ("tower_base_del_1hz_Nm", "tower-base DEL"),
         ("pitch_adc", "pitch ADC")]
GAINS = [("rms_speed_error_rad_s", "RMS ω error"), ("overspeed_peak_over_rated", "peak ω")]


def figure(rows: list[dict], trip: float, ref: str, order=()):
    """Each run both held, as a point per controller: a cost ratio to ``ref`` (columns:
    shaft DEL, tower-base DEL, ADC) against a regulation ratio (rows: RMS speed error,
    peak speed); below and left of the dashed lines, that run beat ``ref`` on both. The
    caller saves it (figures/paired_tradeoff)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    fig, axes = plt.subplots(len(GAINS), len(COSTS), figsize=(14, 8.5), squeeze=False)
    for k, c in enumerate(c for c in rank(rows, order) if c != ref):
        pp = [p for by_fault in pairs(rows, c, ref).values() for v in by_fault.values()
              for p in v if held(p[0], trip) and held(p[1], trip)]
        for (gx, _), row in zip(GAINS, axes, strict=True):
            for (cy, _), ax in zip(COSTS, row, strict=True):
                pts = [(a[gx] / b[gx], a[cy] / b[cy]) for a, b in pp
                       if all(x.get(key) for x in (a, b) for key in (gx, cy))]
                if pts:
                    ax.plot(*zip(*pts, strict=True), "o", ms=4, alpha=0.7, color=f"C{k}",
                            label=f"{c} ({len(pts)} runs)")
    for (_, gl), row in zip(GAINS, axes, strict=True):
        for (_, cl), ax in zip(COSTS, row, strict=True):
            # ratios on log axes (2 × and 0.5 × as far from 1), but the peak speed's,
            # within a few per cent of 1
            ax.set_yscale("log")
            logs = [ax.yaxis]
            if gl != "peak ω":
                ax.set_xscale("log")
                logs.append(ax.xaxis)
            for axis in logs:  # 0.5, 2, 10: not 5 × 10^-1
                axis.set_major_formatter(plain)
                axis.set_minor_formatter(_minor_labels(axis))
            ax.axhline(1.0, color="k", lw=0.8, ls="--")
            ax.axvline(1.0, color="k", lw=0.8, ls="--")
            ax.set_xlabel(f"{gl} / {ref}'s on the same run [-]")
            ax.set_ylabel(f"{cl} / {ref}'s on the same run [-]")
            ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(f"What each controller's regulation cost against {ref}, run by run (runs "
                 f"both held; below and left of the dashed lines: better on both)",
                 fontsize=9)
    return fig


def _minor_labels(axis):
    """The minor ticks' labels of a log axis: each of them while the axis spans less than
    a factor of 3 (a cluster of runs near 1 would otherwise show no number but 1), else
    only 2 and 5 (0.2, 0.5, 2, 5...)."""
    def label(v, _):
        lo, hi = sorted(axis.get_view_interval())
        every = lo > 0 and hi / lo < 3.0
        return f"{v:g}" if every or f"{v:.0e}"[0] in "25" else ""
    from matplotlib.ticker import FuncFormatter

    return FuncFormatter(label)
