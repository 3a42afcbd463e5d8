"""The metrics table of a set of runs, as Markdown and CSV (units in every header)."""

from __future__ import annotations

from pathlib import Path

TABLE_COLUMNS = [
    ("label", "run", "{}"), ("transient_s", "scored from [s]", "{:g}"),
    ("rms_speed_error_rad_s", "RMS ω error [rad/s]", "{:.4f}"),
    ("max_abs_speed_error_rad_s", "max abs ω error [rad/s]", "{:.4f}"),
    ("rms_speed_error_after_fault_rad_s", "RMS after fault [rad/s]", "{:.4f}"),
    ("settling_time_s", "settled within ±1 % from [s]", "{:.1f}"),
    ("overspeed_peak_over_rated", "peak ω / rated [-]", "{:.3f}"),
    ("pitch_min_deg", "pitch min [deg]", "{:.1f}"), ("pitch_max_deg", "pitch max [deg]", "{:.1f}"),
    ("pitch_rate_rms_deg_s", "pitch rate RMS [deg/s]", "{:.2f}"),
    ("actuator_travel_deg", "travel [deg]", "{:.0f}"),
    ("pitch_adc", "pitch ADC [-]", "{:.3f}"),
    ("shaft_torque_del_1hz_Nm", "shaft DEL 1 Hz [MN m]", None),
    ("tower_base_del_1hz_Nm", "tower-base DEL 1 Hz [MN m]", None),
    ("mean_electrical_power_W", "mean electrical power [MW]", None),
    ("diverged", "diverged at [s]", None), ("realtime_factor", "× real time", "{:.0f}"),
]

def _cell(m: dict, key: str, fmt: str | None) -> str:
    v = m.get(key)
    if key == "mean_electrical_power_W":
        return "—" if v is None else f"{v / 1e6:.2f}"
    if key == "shaft_torque_del_1hz_Nm":
        return f"{v / 1e6:.3f}"
    if key == "tower_base_del_1hz_Nm":
        return "—" if v is None else f"{v / 1e6:.2f}"
    if key == "diverged":
        return f"{v['t_s']:.2f}" if v else "no"
    if v is None:
        return "—"
    text = fmt.format(v)
    return text[1:] if text.startswith("-") and float(text) == 0 else text

def write_table(out_dir: Path, rows: list[dict]) -> str:
    from wtftc.results.io import atomic_write_text

    head = [c[1] for c in TABLE_COLUMNS]
    body = [[_cell(m, k, f) for k, _, f in TABLE_COLUMNS] for m in rows]
    md = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    md += ["| " + " | ".join(r) + " |" for r in body]
    text = "\n".join(md) + "\n"
    def raw_cell(m, key):
        v = m.get(key)
        if key == "diverged":
            return f"{v['t_s']:.6g}" if v else ""
        if v is None:
            return ""
        return v if isinstance(v, str) else f"{v:.6g}"

    csv_head = ["label" if k == "label" else k for k, _, _ in TABLE_COLUMNS]
    csv_head = [("diverged_at_s" if k == "diverged" else k) for k in csv_head]
    csv = [",".join(csv_head)] + [",".join(raw_cell(m, k) for k, _, _ in TABLE_COLUMNS)
                                  for m in rows]
    atomic_write_text(Path(out_dir) / "metrics.md", text)
    atomic_write_text(Path(out_dir) / "metrics.csv", "\n".join(csv) + "\n")
    return text
