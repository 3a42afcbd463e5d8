"""A results folder's summary: the table per controller and fault type (summary.md,
summary.csv), the failed or diverged runs, the figures, and one run's configuration."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from wtftc import config
from wtftc.campaign.sweep import dlc, paired, record, tradeoff
from wtftc.campaign.sweep.record import FIGURES, Record
from wtftc.campaign.sweep.spec import FAULT_TYPES, Sweep, expand, parse_sweep
from wtftc.campaign.sweep.store import read_results
from wtftc.errors import ConfigError
from wtftc.files import MAX_TOML_BYTES

#: the summary table's columns: (header, format of a cell)
TABLE = [("controller", "{}"), ("fault", "{}"), ("runs", "{}"), ("diverged", "{}"),
         ("failed", "{}"), ("RMS ω error median [rad/s]", "{:.4f}"),
         ("RMS ω error p95 [rad/s]", "{:.4f}"), ("RMS ω error max [rad/s]", "{:.4f}"),
         ("peak ω / rated max [-]", "{:.3f}"), ("detection delay median [s]", "{:.2f}"),
         ("detection delay max [s]", "{:.2f}"), ("undetected", "{}"),
         ("isolated and classified right", "{}"), ("false alarms", "{}"),
         ("RMS ratio to fault-free median [-]", "{:.3f}"),
         ("RMS ratio to fault-free max [-]", "{:.3f}")]
#: the cost table (issue 18, docs/loads.md): (header, run key, statistic, scale, format)
COST = [("shaft DEL 1 Hz median [MN m]", "shaft_torque_del_1hz_Nm", 50, 1e-6, "{:.3f}"),
        ("shaft DEL 1 Hz p95 [MN m]", "shaft_torque_del_1hz_Nm", 95, 1e-6, "{:.3f}"),
        ("shaft torque max [MN m]", "shaft_torque_max_abs_Nm", 100, 1e-6, "{:.3f}"),
        ("shaft torque σ median [MN m]", "shaft_torque_std_Nm", 50, 1e-6, "{:.3f}"),
        ("tower-base DEL 1 Hz median [MN m]", "tower_base_del_1hz_Nm", 50, 1e-6, "{:.2f}"),
        ("tower-base moment max [MN m]", "tower_base_max_abs_Nm", 100, 1e-6, "{:.1f}"),
        ("pitch ADC median [-]", "pitch_adc", 50, 1.0, "{:.3f}"),
        ("pitch reversals median [-]", "pitch_reversals", 50, 1.0, "{:.0f}"),
        ("pitch reversals median [1/s]", "pitch_reversals_per_s", 50, 1.0, "{:.3f}"),
        ("pitch travel rate median [deg/s]", "pitch_travel_rate_deg_s", 50, 1.0, "{:.3f}"),
        ("RMS ω error, own reference, above rated, median [rad/s]",
         "rms_speed_error_own_above_rated_rad_s", 50, 1.0, "{:.4f}"),
        ("RMS ω error, own reference, below rated, median [rad/s]",
         "rms_speed_error_own_below_rated_rad_s", 50, 1.0, "{:.4f}"),
        ("time above 1.1 × rated max [s]", "time_above_1p1_rated_s", 100, 1.0, "{:.1f}"),
        ("mean power median [MW]", "mean_electrical_power_W", 50, 1e-6, "{:.3f}")]
#: the box plots: (metric, axis label, file name)
BOXES = [("rms_speed_error_rad_s", "RMS rotor-speed error [rad/s]", "rms_speed_error"),
         ("overspeed_peak_over_rated", "peak rotor speed / rated [-]", "overspeed")]


def summarize(out_dir: Path) -> str:
    """The summary table (Markdown, printed) and figures of a results folder:
    summary.md, summary.csv, and under figures/ the distributions of RMS speed error,
    overspeed and detection delay, per controller and fault type.

    Everything is made in memory first; then, if a file of the same name is there and is
    not the one a summary wrote (the folder's record, :mod:`record`), nothing is written
    and the refusal names it. The folder's files are read as regular files under a cap;
    a symbolic link or a special file anywhere in it is refused, never followed."""
    out_dir = record.check_path(out_dir, "--summary", must_exist=True)
    files = record.scan(out_dir, "--summary")
    if "sweep.json" not in files:
        raise ConfigError("--summary", str(out_dir), "a sweep's results folder (with "
                          "sweep.json)")
    meta = _meta(out_dir)
    rec = Record.open(out_dir, "--summary", files)
    rows = read_results(out_dir, "--summary").to_pylist()
    sw = _sweep_of(meta, out_dir)
    n_all = len(expand(sw)[0])
    columns, order = sw.columns, list(sw.columns)
    ref = paired.reference(columns)
    lines, csv = _table(rows, columns)
    cost, cost_csv = _cost_table(rows, order)
    dlc_table = meta["sweep"].get("dlc")
    dlc_lines, dlc_csv = _dlc(rows, dlc_table, order, ref)
    trip = dlc.parse_dlc(dlc_table or {})["overspeed_trip"]
    paired_lines, paired_csv = paired.section(rows, trip, ref, order)
    family = tradeoff.tuned(rows)
    tuned_lines, tuned_csv = tradeoff.section(rows, order) if family else ([], [])
    head = [f"# Sweep {meta['sweep_id']}: {len(rows)} of {n_all} runs saved",
            "", f"Results folder `{out_dir}`; made with "
            + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()) + ".", ""]
    text = "\n".join(head + lines + cost + dlc_lines + paired_lines + tuned_lines
                     + _alarm_rate(rows, meta, columns)
                     + _failures(rows)) + "\n"
    outputs = {"summary.md": text, "summary.csv": "\n".join(csv) + "\n",
               "summary_cost.csv": "\n".join(cost_csv) + "\n"}
    if dlc_csv:
        outputs["summary_dlc.csv"] = "\n".join(dlc_csv) + "\n"
    if paired_csv:
        outputs["summary_paired.csv"] = "\n".join(paired_csv) + "\n"
    if tuned_csv:
        outputs["summary_tuning.csv"] = "\n".join(tuned_csv) + "\n"
    data = {rel: t.encode() for rel, t in outputs.items()}
    if rows:
        _figures(data, rows, columns)
        _extra_figures(data, rows, dlc_table, family, order)
        if paired_csv:
            _save(paired.figure(rows, trip, ref, order), data, "paired_tradeoff")
    rec.refuse_unless_ours(data)  # all checked before any is written
    for rel, content in data.items():
        rec.write(rel, content)
    return text


def _meta(out_dir: Path) -> dict:
    """The results folder's sweep.json, read as a regular file under a cap."""
    path = out_dir / "sweep.json"
    try:
        meta = json.loads(record.read_file(path, "--summary", MAX_TOML_BYTES))
        meta["sweep_id"], meta["sweep"].get, meta["versions"].items  # noqa: B018
    except (ValueError, KeyError, TypeError, AttributeError):
        raise ConfigError("--summary", str(path), "the sweep.json a sweep wrote (this one "
                          "is damaged)") from None
    return meta


def _sweep_of(meta: dict, out_dir: Path) -> Sweep:
    """The folder's sweep, its columns those sweep.json records (every setting written
    out: no presets file needed); a folder whose sweep.json holds only their names
    resolves them as names (wtftc.controller.lookup: presets and former names)."""
    raw = meta["sweep"]
    if isinstance(meta.get("controllers"), list):
        raw = {k: v for k, v in raw.items() if k != "optional_controllers"} | {
            k: meta[k] for k in ("controllers", "optional_controllers") if k in meta}
    try:
        return parse_sweep(raw)
    except ConfigError as exc:
        raise ConfigError("--summary", str(out_dir / "sweep.json"), "the sweep.json a sweep "
                          f"wrote (its sweep is refused: {exc})") from None


def _dlc(rows: list[dict], table, order, ref) -> tuple[list[str], list[str]]:
    """The DLC section the sweep's [dlc] table asks for (wtftc.campaign.sweep.dlc)."""
    if table is None:
        return [], []
    if dlc.parse_dlc(table)["case"] == "2.1":
        return dlc.fault_section(rows, table, order)
    return dlc.section(rows, table, order, ref)


def _extra_figures(out: dict, rows: list[dict], dlc_table, family: bool, order) -> None:
    if dlc_table is not None:
        if dlc.parse_dlc(dlc_table)["case"] == "2.1":
            _save(dlc.fault_figure(rows, dlc_table, order), out, "dlc21_extremes")
        else:
            _save(dlc.figure(rows, order), out, "dlc_bins")
    if family:
        for faulted, name in ((False, "tradeoff_fault_free"), (True, "tradeoff_faulted")):
            if tradeoff.points(rows, faulted, order):
                _save(tradeoff.figure(rows, faulted, order), out, name)


def _uses_fdi(columns: dict, c: str) -> bool:
    """Whether column ``c`` runs wtftc's FDI (a row of a column the sweep no longer
    names: no)."""
    return c in columns and columns[c].uses_fdi


def _table(rows: list[dict], columns: dict) -> tuple[list[str], list[str]]:
    """The table's Markdown lines and CSV lines: one row per controller and fault type,
    the controllers in the order of ``columns`` (the sweep's)."""
    groups: dict[tuple, list] = {}
    for r in rows:
        groups.setdefault((r["controller"], r["fault_type"]), []).append(r)
    twins = {_scenario(r): r["rms_speed_error_after_fault_rad_s"] for r in rows
             if r["fault_type"] == "none" and r["status"] != "failed"}
    lines = ["| " + " | ".join(h for h, _ in TABLE) + " |", "|" + "---|" * len(TABLE)]
    csv = [",".join(h.replace(",", ";") for h, _ in TABLE)]
    place = dlc.rank(rows, columns)
    for (c, f), rs in sorted(groups.items(), key=lambda kv: (
            place[kv[0][0]], FAULT_TYPES.index(kv[0][1]))):
        vals = _cells(c, f, rs, twins, _uses_fdi(columns, c))
        cells = ["—" if v is None else fmt.format(v)
                 for v, (_, fmt) in zip(vals, TABLE, strict=True)]
        lines.append("| " + " | ".join(cells) + " |")
        csv.append(",".join("" if v is None else str(v) for v in vals))
    return lines, csv


def _cost_table(rows: list[dict], order) -> tuple[list[str], list[str]]:
    """What the regulation cost, per controller and fault type (docs/loads.md): the
    shaft's fatigue, the pitch's duty, the speed against each controller's own
    reference; Markdown lines under a heading, and CSV lines (SI units)."""
    groups: dict[tuple, list] = {}
    for r in rows:
        if r["status"] == "ok":
            groups.setdefault((r["controller"], r["fault_type"]), []).append(r)
    head = ["controller", "fault", "runs"] + [h for h, *_ in COST]
    lines = ["", "## Cost (docs/loads.md)", "", "| " + " | ".join(head) + " |",
             "|" + "---|" * len(head)]
    csv = [",".join(["controller", "fault", "runs"]
                    + [f"{k} p{q}" for _, k, q, _, _ in COST])]
    place = dlc.rank(rows, order)
    for (c, f), rs in sorted(groups.items(), key=lambda kv: (
            place[kv[0][0]], FAULT_TYPES.index(kv[0][1]))):
        vals = [_quantile([r[k] for r in rs if r.get(k) is not None], q)
                for _, k, q, _, _ in COST]
        lines.append("| " + " | ".join([c, f, str(len(rs))] + [
            "—" if v is None else fmt.format(v * scale)
            for v, (_, _, _, scale, fmt) in zip(vals, COST, strict=True)]) + " |")
        csv.append(",".join([c, f, str(len(rs))] + ["" if v is None else str(v) for v in vals]))
    return lines, csv


def _quantile(vals: list, p: float) -> float | None:
    return float(np.percentile(vals, p)) if vals else None


def _scenario(r: dict) -> tuple:
    """What a run shares with its fault-free twin: controller, plant, wind, seed,
    mismatch (a sweep's ``fault_free_twins``)."""
    return tuple(v for k, v in sorted(r.items())
                 if k in ("controller", "plant", "mean_wind_mps", "turbulence_class", "seed")
                 or k.startswith("mismatch_"))


def _cells(c: str, f: str, rs: list[dict], twins: dict | None, uses_fdi: bool) -> list:
    """The values of one row of the table: controller ``c`` (``uses_fdi``: it runs
    wtftc's FDI) under fault type ``f``; with ``twins`` (scenario → fault-free RMS
    error), each run's RMS error over its twin's."""
    good = [r for r in rs if r["status"] != "failed"]
    rms = [r["rms_speed_error_rad_s"] for r in good]
    peak = [r["overspeed_peak_over_rated"] for r in good]
    fdi = uses_fdi and f != "none"
    delays = [r["detection_delay_s"] for r in good if r["detection_delay_s"] is not None]
    return [c, f, len(rs), sum(r["status"] == "diverged" for r in rs),
            sum(r["status"] == "failed" for r in rs), _quantile(rms, 50), _quantile(rms, 95),
            max(rms) if rms else None, max(peak) if peak else None,
            _quantile(delays, 50) if fdi else None, max(delays) if fdi and delays else None,
            (len(good) - len(delays)) if fdi else None,
            sum(bool(r.get("fault_correct")) for r in good) if fdi else None,
            sum(r["false_alarms"] or 0 for r in good if uses_fdi),
            *_ratios(good, f, twins or {})]


def _ratios(good: list[dict], f: str, twins: dict) -> list:
    """Median and max of each run's RMS speed error after its fault's onset over its
    fault-free twin's over the same window (None without twins)."""
    ratios = [r["rms_speed_error_after_fault_rad_s"] / twins[_scenario(r)] for r in good
              if f != "none" and twins.get(_scenario(r))
              and r["rms_speed_error_after_fault_rad_s"] is not None]
    return [_quantile(ratios, 50), max(ratios) if ratios else None]


def _alarm_rate(rows: list[dict], meta: dict, columns: dict) -> list[str]:
    """The FDI's false alarms per simulated fault-free hour, per controller that runs it
    (the goal: none in 100 hours)."""
    t_final = float(meta["sweep"].get("t_final_s", 60.0))
    out = []
    for c in dlc.rank(rows, columns):
        free = [r for r in rows if r["controller"] == c and r["fault_type"] == "none"
                and r["status"] == "ok" and _uses_fdi(columns, c)]
        if free:
            hours = len(free) * t_final / 3600.0
            alarms = sum(r["false_alarms"] or 0 for r in free)
            runs = sum(bool(r["false_alarms"]) for r in free)
            out.append(f"- `{c}`: {alarms} false alarms in {hours:.1f} simulated fault-free "
                       f"hours ({runs} of {len(free)} runs), {alarms / hours:.3g} per hour")
    return ["", "## False alarms", "", *out] if out else []


def _failures(rows: list[dict]) -> list[str]:
    """The summary's last section: every failed or diverged run, and how to re-run it."""
    bad = [r for r in rows if r["status"] != "ok"]
    tail = ["", f"## Failed or diverged runs: {len(bad)}", ""]
    if not bad:
        return tail
    tail += ["| run id | controller | fault | wind [m/s] | class | seed | status | at [s] "
             "| cause |", "|---|---|---|---|---|---|---|---|---|"]
    for r in bad:
        at = "—" if r["diverged_at_s"] is None else f"{r['diverged_at_s']:.3f}"
        tail.append(f"| {r['run_id']} | {r['controller']} | {r['fault_type']} | "
                    f"{r['mean_wind_mps']:.2f} | {r['turbulence_class']} | {r['seed']} | "
                    f"{r['status']} | {at} | {(r['cause'] or '').replace('|', '/')} |")
    return tail + ["", "Each run re-runs alone: `wtftc sweep --show RUN_ID --out DIR > "
                   "run.toml`, then `wtftc run --config run.toml` (its configuration is also "
                   "the dataset's `config_json`)."]


def _figures(out: dict, rows: list[dict], columns: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ctrls = [c for c in dlc.rank(rows, columns) if any(r["controller"] == c for r in rows)]
    faults = [f for f in FAULT_TYPES if any(r["fault_type"] == f for r in rows)]
    for key, label, name in BOXES:
        fig, ax = plt.subplots(figsize=(max(7, 1.2 * len(faults) * len(ctrls) / 2), 4.5))
        _boxes(ax, rows, ctrls, faults, key)
        ax.set_ylabel(label)
        ax.set_title(f"{label.split(' [')[0]}: distribution over the sweep's runs", fontsize=9)
        _save(fig, out, name)
    fig, ax = plt.subplots(figsize=(7, 4))
    _delays(ax, rows, faults, columns)
    _save(fig, out, "detection_delay")


def _boxes(ax, rows: list[dict], ctrls: list[str], faults: list[str], key: str) -> None:
    """Box plots of ``key`` over the runs: a group per fault type, a box per controller."""
    width = 0.8 / len(ctrls)
    for k, c in enumerate(ctrls):
        data, pos = [], []
        for i, f in enumerate(faults):
            v = [r[key] for r in rows if r["controller"] == c and r["fault_type"] == f
                 and r[key] is not None and r["status"] != "failed"]
            if v:
                data.append(v)
                pos.append(i + (k - (len(ctrls) - 1) / 2) * width)
        if data:
            bp = ax.boxplot(data, positions=pos, widths=width * 0.9, patch_artist=True,
                            manage_ticks=False, flierprops={"markersize": 2},
                            medianprops={"color": "k"})
            for b in bp["boxes"]:
                b.set_facecolor(f"C{k}")
            ax.plot([], [], "s", color=f"C{k}", label=c)
    ax.set_xticks(range(len(faults)), faults, fontsize=8)
    ax.set_xlabel("fault type")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)


def _delays(ax, rows: list[dict], faults: list[str], columns: dict) -> None:
    """Histograms of the detection delays of the controllers with wtftc's FDI, per fault
    type."""
    fdi_rows = [r for r in rows if _uses_fdi(columns, r["controller"])
                and r["fault_type"] != "none" and r["detection_delay_s"] is not None]
    for k, f in enumerate(f for f in faults if f != "none"):
        v = [r["detection_delay_s"] for r in fdi_rows if r["fault_type"] == f]
        if v:
            ax.hist(v, bins=30, alpha=0.6, color=f"C{k}", label=f"{f} ({len(v)} runs)")
    ax.set_xlabel("detection delay [s]")
    ax.set_ylabel("runs [-]")
    ax.grid(alpha=0.3)
    if fdi_rows:
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no detected faults (no FDI controller, or no fault, in the sweep)",
                ha="center", va="center", transform=ax.transAxes)
    ax.set_title("Detection delay of wtftc's FDI (controllers with their own detection)",
                 fontsize=9)


def _save(fig, out: dict, name: str) -> None:
    """figures/<name>.png and .pdf, as bytes into ``out``; the figure is closed."""
    import io

    import matplotlib.pyplot as plt

    if name not in FIGURES:  # a bug: a folder without a record would not know it
        raise ValueError(f"figure {name!r} is not in wtftc.campaign.sweep.record.FIGURES")

    fig.tight_layout()
    for ext in ("png", "pdf"):
        buf = io.BytesIO()
        fig.savefig(buf, format=ext, dpi=120)
        out[f"figures/{name}.{ext}"] = buf.getvalue()
    plt.close(fig)


def show_run(out_dir: Path, run_id: str) -> str:
    """A saved run's configuration as TOML, for `wtftc run --config`."""
    out_dir = record.check_path(out_dir, "--out", must_exist=True)
    table = read_results(out_dir)
    for r in table.to_pylist():
        if r["run_id"] == run_id:
            cfg = json.loads(r["config_json"])
            if cfg["wind"].get("kind") == "ntm":  # a sweep saved before a run's NTM took
                # its turbine's rotor by default (wtftc.config) ran the hub-height point
                cfg["wind"].setdefault("rotor_radius_m", 0.0)
            return config.to_toml(cfg)
    raise ConfigError("--show", run_id, f"the run id of a run saved in {out_dir}")
