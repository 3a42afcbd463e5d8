"""The scorecard's figures (``<out>/figures/``, PNG and PDF) and its self-contained
``scorecard.html``: the Markdown report as HTML with the figures inside it."""

from __future__ import annotations

import base64
import html
from pathlib import Path

#: the per-bin figure's metrics: (key, label with its unit, scale)
PER_BIN = [("rms_speed_error_own_above_rated_rad_s",
            "RMS rotor-speed error, wind above rated [rad/s]", 1.0),
           ("shaft_torque_del_1hz_Nm", "shaft-torque DEL, 1 Hz [MN m]", 1e-6),
           ("tower_base_del_1hz_Nm", "tower-base DEL, 1 Hz [MN m]", 1e-6),
           ("blade_root_flap_del_1hz_Nm", "blade-root flapwise DEL, 1 Hz [MN m]", 1e-6),
           ("pitch_adc", "pitch actuator duty cycle [-]", 1.0),
           ("mean_electrical_power_W", "mean electrical power [MW]", 1e-6)]


#: the trade-off figure's panels: (x, y), each (key, label with its unit, scale)
TRADE_OFF = [(PER_BIN[0], PER_BIN[2]), (PER_BIN[0], PER_BIN[4]), (PER_BIN[0], PER_BIN[1])]


def _by_bin(rows: list[dict], c: str, key: str, scale: float) -> dict[float, list]:
    """Column ``c``'s values of ``key`` × ``scale`` per mean wind, over its runs that
    finished (status ok)."""
    by: dict[float, list] = {}
    for r in rows:
        if r["controller"] == c and r["status"] == "ok" and r.get(key) is not None:
            by.setdefault(r["mean_wind_mps"], []).append(r[key] * scale)
    return by


def _save(fig, out: Path, stem: str) -> list[Path]:
    from wtftc.results.io import atomic_savefig

    paths = []
    for ext in ("png", "pdf"):
        p = Path(out) / "figures" / f"{stem}.{ext}"
        atomic_savefig(fig, p, dpi=110)
        paths.append(p)
    return paths


def trade_off_figure(rows: list[dict], columns: list[str], out: Path) -> list[Path]:
    """What each column pays for its speed regulation: the tower-base DEL, the pitch duty
    and the shaft DEL against the RMS speed error, one point per mean-wind bin (the mean
    over its seeds), the bins of a column joined in order of the wind."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, axes = plt.subplots(1, len(TRADE_OFF), figsize=(4.2 * len(TRADE_OFF), 3.8))
    for ax, ((kx, lx, sx), (ky, ly, sy)) in zip(axes, TRADE_OFF, strict=True):
        for c in columns:
            bx, by = _by_bin(rows, c, kx, sx), _by_bin(rows, c, ky, sy)
            v = sorted(set(bx) & set(by))
            x, y = [np.mean(bx[w]) for w in v], [np.mean(by[w]) for w in v]
            ax.plot(x, y, marker="o", label=c)
            for w, xi, yi in zip(v, x, y, strict=True):
                ax.annotate(f"{w:g}", (xi, yi), fontsize=6, xytext=(3, 3),
                            textcoords="offset points")
        ax.set_xlabel(lx, fontsize=8)
        ax.set_ylabel(ly, fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("normal power production: cost against regulation, one point per bin "
                 "(labels: mean wind [m/s])", fontsize=9)
    fig.tight_layout()
    paths = _save(fig, out, "normal_production_trade_off")
    plt.close(fig)
    return paths


def per_bin_figure(rows: list[dict], columns: list[str], out: Path) -> list[Path]:
    """Each metric against the mean wind, per column: the mean over the seeds with the
    seeds' range, the runs that held only (status ok); a metric no run has (the blade
    root on wtftc's plant) is left out."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    panels = [p for p in PER_BIN if any(_by_bin(rows, c, p[0], 1.0) for c in columns)]
    fig, axes = plt.subplots(len(panels), 1, figsize=(7.5, 2.4 * len(panels)),
                             sharex=True, squeeze=False)
    axes = axes[:, 0]
    for ax, (key, label, scale) in zip(axes, panels, strict=True):
        for c in columns:
            by = _by_bin(rows, c, key, scale)
            v = sorted(by)
            mean = [np.mean(by[x]) for x in v]
            lo = [mean[i] - min(by[x]) for i, x in enumerate(v)]
            hi = [max(by[x]) - mean[i] for i, x in enumerate(v)]
            ax.errorbar(v, mean, yerr=[lo, hi], marker="o", capsize=3, label=c)
        ax.set_ylabel(label, fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("mean wind at hub height [m/s]")
    axes[0].legend(fontsize=8)
    axes[0].set_title("normal power production: mean over the seeds, bars their range",
                      fontsize=9)
    fig.tight_layout()
    paths = _save(fig, out, "normal_production_per_bin")
    plt.close(fig)
    return paths


def _inline(text: str) -> str:
    """Markdown's inline code and bold as HTML (the text escaped first)."""
    out, parts = [], html.escape(text).split("`")
    for i, part in enumerate(parts):
        if i % 2:
            out.append(f"<code>{part}</code>")
        else:
            bold = part.split("**")
            out.append("".join(f"<b>{b}</b>" if j % 2 else b for j, b in enumerate(bold)))
    return "".join(out)


def to_html(markdown: str, figures: list[Path], title: str) -> str:
    """The report's Markdown (headings, paragraphs, lists, tables: what report.markdown
    writes) as one HTML page, each PNG figure inside it."""
    body, table = [], []

    def flush():
        if table:
            rows = [r for r in table if set(r.replace("|", "").strip()) - {"-"}]
            cells = [[c.strip() for c in r.strip().strip("|").split("|")] for r in rows]
            body.append("<table><tr>" + "".join(f"<th>{_inline(c)}</th>" for c in cells[0])
                        + "</tr>" + "".join("<tr>" + "".join(f"<td>{_inline(c)}</td>"
                                                             for c in r) + "</tr>"
                                            for r in cells[1:]) + "</table>")
            table.clear()

    for line in markdown.splitlines():
        if line.startswith("|"):
            table.append(line)
            continue
        flush()
        if line.startswith("#"):
            level = len(line) - len(line.lstrip("#"))
            body.append(f"<h{level}>{_inline(line[level:].strip())}</h{level}>")
        elif line.startswith("- "):
            body.append(f"<ul><li>{_inline(line[2:])}</li></ul>")
        elif line.strip():
            body.append(f"<p>{_inline(line)}</p>")
    flush()
    for p in figures:
        data = base64.b64encode(Path(p).read_bytes()).decode()
        body.append(f'<figure><img alt="{html.escape(p.stem)}" '
                    f'src="data:image/png;base64,{data}"></figure>')
    style = ("body{font-family:sans-serif;max-width:1100px;margin:2em auto}"
             "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;"
             "padding:3px 6px;font-size:90%}img{max-width:100%}")
    return (f"<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>"
            f"{html.escape(title)}</title><style>{style}</style></head><body>\n"
            + "\n".join(body) + "\n</body></html>\n")
