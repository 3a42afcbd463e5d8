"""Each preset's measured standing against ROSCO, from the campaign folders kept with the
code (docs/campaigns/): what docs/standing.md shows, made by
``wtftc presets --standing --out docs/standing.md``.

In each folder, every column whose settings are a preset's is paired with ROSCO's column
(the preset ``rosco``) scenario by scenario, as the folder's summary pairs them
(:func:`wtftc.campaign.sweep.paired.scenario`: same wind, turbulence class, seed, plant,
mismatch and fault). On the scenarios both held (:func:`wtftc.campaign.sweep.paired.held`:
status ok, never past the overspeed trip), each metric's ratio preset / ROSCO is summarised
by its geometric mean and the 95 % Student-t interval of the mean of the log ratios, for
the fault-free runs, for the runs under any fault, and for each fault type.

A ratio is a scale: 0.5 is as far below 1 as 2 is above it, so the mean is taken of the
logs. The verdict is "lower" when the whole interval is below 1, "higher" when above, and
"tie" when it holds 1."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from wtftc import controller
from wtftc.campaign.sweep import dlc, paired, record
from wtftc.campaign.sweep.store import read_results
from wtftc.errors import ConfigError
from wtftc.files import MAX_TOML_BYTES
from wtftc.model import turbine_file

#: the metrics compared: (run key, header, what it measures)
METRICS = [("rms_speed_error_rad_s", "RMS ω error", "the RMS rotor-speed error against rated "
            "(regulation)"),
           ("shaft_torque_del_1hz_Nm", "shaft-torque DEL", "the low-speed shaft torque's "
            "1 Hz damage-equivalent load, Wöhler exponent as docs/loads.md (drivetrain "
            "fatigue)"),
           ("tower_base_del_1hz_Nm", "tower-base DEL", "the tower-base fore-aft moment's "
            "1 Hz damage-equivalent load (tower fatigue)"),
           ("pitch_adc", "pitch ADC", "the pitch actuator duty cycle (bearing and "
            "actuator wear)")]
#: the preset every column is held against
REFERENCE = "rosco"
#: former column names that stand for a preset without storing the same settings:
#: name → (preset, why), from wtftc/data/presets.toml
STANDS_FOR = controller.standing_for()
#: the folders kept with the code, in a checkout
CAMPAIGNS = Path(__file__).resolve().parents[2] / "docs" / "campaigns"
#: the command that makes docs/standing.md
COMMAND = "wtftc presets --standing --out docs/standing.md"
#: the interval's confidence
LEVEL = 0.95
#: the group of a row: the fault-free runs, those under any fault, or one fault type
FAULT_FREE, ANY_FAULT = "none", "any"


def default_folders() -> list[Path]:
    """Every folder of docs/campaigns/ with saved runs (a checkout's; an installed wtftc
    has none, and is told to name the folders)."""
    if not CAMPAIGNS.is_dir():
        raise ConfigError("--standing", "(no folder)", "the sweep results folders to read "
                          "(wtftc presets --standing FOLDER ...): only a checkout of wtftc "
                          "has its campaign folders, in docs/campaigns/")
    return sorted(p for p in CAMPAIGNS.iterdir()
                  if p.is_dir() and any((p / "runs").glob("part-*.parquet")))


def standing(folders: list[Path]) -> list[dict]:
    """One row per folder, preset and group of runs (fault-free, any fault, each fault
    type): the counts of paired scenarios, those both held and those each side lost, the
    seeds and winds, and per metric of :data:`METRICS` the geometric-mean ratio preset /
    ROSCO, its interval and its verdict (``row["metrics"][key]``); with the folder, its
    engine, turbine and generated code's hash. A folder without ROSCO's column, or
    without a preset's, gives none."""
    return [row for folder in folders for row in _folder(Path(folder))]


def _folder(folder: Path) -> list[dict]:
    meta = _meta(folder)
    runs = read_results(folder, "--standing").to_pylist()
    names = _presets_of(meta, {r["controller"] for r in runs})
    refs = [c for c, p in names.items() if p == REFERENCE]
    if not refs:
        return []
    sweep = meta["sweep"]
    trip = dlc.parse_dlc(sweep.get("dlc") or {})["overspeed_trip"]
    info = {"folder": folder, "engine": sweep.get("engine", "wtftc"),
            "turbine": str(sweep.get("turbine") or turbine_file.DEFAULT),
            "code": meta["versions"].get("generated_code_sha256"), "reference": refs[0]}
    out = []
    for column, name in sorted(names.items(), key=lambda kv: _rank(kv[1], kv[0])):
        if name is None or name == REFERENCE:
            continue
        for group, pp in _groups(runs, column, refs[0]):
            out.append(info | {"preset": name, "column": column, "faults": group,
                               "stands_for": column in STANDS_FOR} | _stats(pp, trip))
    return out


def _rank(name: str | None, column: str) -> tuple:
    order = list(controller.presets())
    return (order.index(name) if name in order else len(order), column)


def _meta(folder: Path) -> dict:
    """The folder's sweep.json (its sweep, versions and, where it keeps them, its
    columns' settings), read as a regular file under a cap."""
    path = folder / "sweep.json"
    if not Path(folder).is_dir():
        raise ConfigError("--standing", str(folder), "a sweep's results folder (with "
                          "sweep.json)")
    try:
        meta = json.loads(record.read_file(path, "--standing", MAX_TOML_BYTES))
        meta["sweep"].get, meta["versions"].get  # noqa: B018
    except ConfigError:
        raise ConfigError("--standing", str(folder), "a sweep's results folder (with "
                          "sweep.json)") from None
    except (ValueError, KeyError, TypeError, AttributeError):
        raise ConfigError("--standing", str(path), "the sweep.json a sweep wrote (this "
                          "one is damaged)") from None
    return meta


def _presets_of(meta: dict, columns: set[str]) -> dict[str, str | None]:
    """Each column → the preset its settings are (None: a table that is none), from the
    settings sweep.json keeps or else from its name (wtftc.controller.lookup)."""
    kept = {}
    for key in ("controllers", "optional_controllers"):
        for tab in meta.get(key) or ():
            if isinstance(tab, dict) and "name" in tab:
                kept[tab["name"]] = {k: v for k, v in tab.items() if k != "name"}
    out = {}
    for c in columns:
        try:
            ctrl = controller.parse(kept[c], c) if c in kept else controller.lookup(c)
        except ConfigError:
            out[c] = None
            continue
        out[c] = STANDS_FOR[c][0] if c in STANDS_FOR else preset_of(ctrl)
    return out


def preset_of(ctrl: controller.Controller) -> str | None:
    """The preset whose settings ``ctrl`` runs (design, accommodation, the design's
    parameters, the torque law, the target mode: as a campaign runs them, every design
    but ROSCO on the baseline torque law unless it says otherwise), or None."""
    runs = ctrl.run_keys(True, torque_default=True)
    for name, p in controller.presets().items():
        if p.run_keys(True, torque_default=True) == runs:
            return name
    return None


def _groups(runs: list[dict], column: str, ref: str) -> list[tuple[str, list]]:
    """(group, the (run of ``column``, run of ``ref``) of each scenario both ran) for
    the fault-free runs, those under any fault and each fault type, where there are any;
    a scenario only one side ran is left out."""
    by_ref = {paired.scenario(r): r for r in runs if r["controller"] == ref}
    mine = {paired.scenario(r): r for r in runs if r["controller"] == column}
    pp = [(r, by_ref[k]) for k, r in mine.items() if k in by_ref]
    by_fault: dict[str, list] = {}
    for a, b in pp:
        by_fault.setdefault(dlc.fault_label(a), []).append((a, b))
    faulted = [p for f, v in by_fault.items() if f != FAULT_FREE for p in v]
    out = [(FAULT_FREE, by_fault.get(FAULT_FREE, [])), (ANY_FAULT, faulted)]
    out += [(f, by_fault[f]) for f in sorted(by_fault) if f != FAULT_FREE]
    return [(g, v) for g, v in out if v]


def _stats(pp: list[tuple[dict, dict]], trip: float) -> dict:
    """The counts of a group's scenarios and each metric's statistics over those both
    held (a scenario either run failed on, an error rather than the rotor, is counted
    apart and in neither side's losses)."""
    ok = [(a, b) for a, b in pp if "failed" not in (a["status"], b["status"])]
    both = [(a, b) for a, b in ok if paired.held(a, trip) and paired.held(b, trip)]
    return {"scenarios": len(pp), "failed": len(pp) - len(ok), "both_held": len(both),
            "lost_by_preset": sum(not paired.held(a, trip) for a, _ in ok),
            "lost_by_reference": sum(not paired.held(b, trip) for _, b in ok),
            "seeds": len({a["seed"] for a, _ in pp}),
            "winds": len({a["mean_wind_mps"] for a, _ in pp}),
            "metrics": {key: ratio_stats(both, key) for key, _, _ in METRICS}}


def ratio_stats(both: list[tuple[dict, dict]], key: str) -> dict:
    """``key``'s ratio preset / ROSCO over the pairs: n, the geometric mean, the
    :data:`LEVEL` Student-t interval of the mean log ratio mapped back (None below two
    pairs) and the verdict. A pair without the metric (a plant with no tower) or with a
    zero on a side has no log ratio and is left out: ``zero_both`` counts those at 0 on
    both sides (pitch ADC below rated, where neither pitches), ``zero_preset`` and
    ``zero_reference`` those at 0 on that side only."""
    vals = [(a.get(key), b.get(key)) for a, b in both]
    vals = [(x, y) for x, y in vals if x is not None and y is not None]
    logs = np.array([math.log(x / y) for x, y in vals if x > 0 and y > 0])
    out = {"n": len(logs), "zero_both": sum(x == 0 and y == 0 for x, y in vals),
           "zero_preset": sum(x == 0 and y != 0 for x, y in vals),
           "zero_reference": sum(x != 0 and y == 0 for x, y in vals),
           "ratio": None, "low": None, "high": None, "verdict": "none"}
    if len(logs) == 0:
        return out
    mean = float(np.mean(logs))
    out["ratio"] = math.exp(mean)
    if len(logs) < 2:
        out["verdict"] = "too few"
        return out
    half = t_quantile(0.5 + LEVEL / 2, len(logs) - 1) * float(np.std(logs, ddof=1)) \
        / math.sqrt(len(logs))
    out["low"], out["high"] = math.exp(mean - half), math.exp(mean + half)
    out["verdict"] = verdict(out["low"], out["high"])
    return out


def verdict(low: float, high: float) -> str:
    """"lower" when the interval lies below 1, "higher" above, "tie" when it holds 1."""
    return "lower" if high < 1.0 else "higher" if low > 1.0 else "tie"


def t_quantile(p: float, df: int) -> float:
    """Student's t quantile: the t with P(T ≤ t) = ``p`` (0.5 < p < 1) at ``df`` degrees
    of freedom. With t = √df tan θ, P(T ≤ t) − ½ = c ∫₀^θ cos^(df−1) φ dφ, c = Γ((df+1)/2)
    / (√π Γ(df/2)): a smooth integral on [0, π/2) (64-point Gauss-Legendre), solved for θ
    by Newton's method (its derivative the integrand)."""
    if not 0.5 < p < 1.0 or df < 1:
        raise ValueError(f"t_quantile needs 0.5 < p < 1 and df >= 1, not {p}, {df}")
    c = math.exp(math.lgamma((df + 1) / 2) - math.lgamma(df / 2)) / math.sqrt(math.pi)
    x, w = np.polynomial.legendre.leggauss(64)

    def area(theta: float) -> float:
        phi = 0.5 * theta * (x + 1.0)
        return c * 0.5 * theta * float(np.sum(w * np.cos(phi) ** (df - 1)))

    theta = math.atan(2.0 / math.sqrt(df))
    for _ in range(100):
        step = (area(theta) - (p - 0.5)) / (c * math.cos(theta) ** (df - 1))
        theta = min(max(theta - step, 0.5 * theta), 0.5 * (theta + math.pi / 2))
        if abs(step) < 1e-15:
            break
    return math.sqrt(df) * math.tan(theta)


#: a group's name in the tables
GROUP_TEXT = {FAULT_FREE: "fault-free", ANY_FAULT: "any fault"}


def _g(x: float) -> str:
    """3 significant digits: what the table shows, and what makes it the same text on
    any CPU (a last-bit difference in a log or a sum moves a value by about 1e-16 of
    itself, far below a 3-digit step, short of a value within that of a rounding edge)."""
    return f"{x:.3g}"


def _cell(m: dict, link: str, held: int) -> str:
    if m["ratio"] is None:
        return "—"
    num = _g(m["ratio"]) if m["low"] is None else \
        f"{_g(m['ratio'])} ({_g(m['low'])}–{_g(m['high'])})"
    n = "" if m["n"] == held else f", [{m['n']}]({link}) pairs"
    zeros = [f"{m[k]} at 0 {side}" for k, side in (
        ("zero_both", "on both sides"), ("zero_preset", "for the preset only"),
        ("zero_reference", "for ROSCO only")) if m[k]]
    return f"[{num}]({link}) {m['verdict']}{n}" + (f" ({', '.join(zeros)})" if zeros else "")


def _table(rows: list[dict], base: Path) -> list[str]:
    head = ["preset", "faults", "scenarios: both held / lost by preset / lost by ROSCO",
            "seeds", "winds", *(h for _, h, _ in METRICS), "folder (generated code)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    order = list(controller.presets())
    for r in sorted(rows, key=lambda r: (order.index(r["preset"]), r["faults"] != FAULT_FREE,
                                        r["faults"] != ANY_FAULT, r["faults"],
                                        r["folder"].name)):
        link = Path(os.path.relpath(Path(r["folder"]).resolve(), base.resolve())).as_posix()
        link += "/"
        counts = f"{r['both_held']} / {r['lost_by_preset']} / {r['lost_by_reference']}"
        if r["failed"]:
            counts += f" ({r['failed']} failed)"
        name = f"`{r['preset']}`" + ("¹" if r["stands_for"] else "")
        lines.append("| " + " | ".join([
            name, GROUP_TEXT.get(r["faults"], r["faults"]), f"[{counts}]({link})",
            f"[{r['seeds']}]({link})", f"[{r['winds']}]({link})",
            *(_cell(r["metrics"][k], link, r["both_held"]) for k, _, _ in METRICS),
            f"[`{Path(r['folder']).name}`]({link}) ({r['engine']}, `{r['code']}`)"]) + " |")
    return lines


def _notes(rows: list[dict]) -> list[str]:
    out = []
    for c, (name, why) in STANDS_FOR.items():
        if any(r["column"] == c for r in rows):
            out.append(f"- ¹ `{name}`: its folders name the column `{c}`, which {why}.")
    out.append("- A pair with a metric at 0 has no log ratio and is left out of that "
               "metric: at 0 on both sides, the pitch ADC below rated where neither "
               "controller pitches; at 0 on one side only, a pair the geometric mean cannot "
               "hold (that side pitched not at all, the other some), counted in the cell "
               "with the pairs it rests on. A row's metrics are over the fault-free runs, "
               "those under any fault, or one fault type (a runaway by its direction: "
               "`runaway_fine`, `runaway_feather`).")
    out.append("- Only the columns whose settings are a preset's are shown; the other "
               "columns of these folders (settings a campaign tried on the way) are in "
               "each folder's own `summary.md`.")
    return out


def _title(turbine: str) -> str:
    try:
        return f"{turbine_file.load(turbine).title} (`{turbine}`)"
    except ConfigError:
        return f"`{turbine}`"


def markdown(rows: list[dict], base: Path | None = None, command: str = COMMAND) -> str:
    """The rows as docs/standing.md: the definitions, one table per turbine, each number
    linking to its folder (relative to ``base``, the page's folder: default docs/), the
    notes, and ``command``, the line that makes the page again."""
    base = CAMPAIGNS.parent if base is None else base
    defs = [f"- **{h}**: {what}." for _, h, what in METRICS]
    lines = ["# Each preset against ROSCO, measured", "",
             "<!-- made by `" + command + "` from the campaign folders; do not edit -->", "",
             "Each cell is the geometric mean, over the scenarios both controllers ran and "
             "both held, of the ratio preset / ROSCO on the same scenario (same wind, "
             "turbulence seed and fault), with its 95 % Student-t interval on the log "
             "ratios in brackets, then the verdict: **lower** (the whole interval below 1: "
             "the preset's is lower than ROSCO's), **higher** (above 1) or **tie** (the "
             "interval holds 1). Lower is better for every metric. Ratios have no unit; "
             "the metrics are in SI units in each folder's `runs/`:", "", *defs, "",
             "A scenario is held when its run stayed in the envelope (status ok) and never "
             "passed the overspeed trip of the folder's DLC table (1.2 × rated speed by "
             "default); a scenario either controller lost is counted under that side, not "
             "compared. A scenario one side has no run of is left out. Every number links "
             "to the campaign folder it comes from (docs/campaigns/README.md says how each "
             "was run); the folder's `generated code` is the hash its `sweep.json` records "
             "(this version's is `" + _current_code() + "`, as `wtftc export discon` names "
             "it: a folder with another hash measured an earlier version of the designs).",
             ""]
    for turbine in sorted({r["turbine"] for r in rows}):
        lines += [f"## {_title(turbine)}", "", *_table([r for r in rows if r["turbine"] == turbine],
                                               base), ""]
    lines += ["## Notes", "", *_notes(rows), "",
              f"Made by `{command}`; tests/test_standing.py checks that this page is what "
              "it makes."]
    return "\n".join(lines) + "\n"


def _current_code() -> str:
    from wtftc.artefacts.loader import generated_code_sha256

    return generated_code_sha256()


def written_by_it(path: Path) -> bool:
    """Whether ``path`` is a page this module wrote (its first two lines), which a new
    page may replace."""
    try:
        with open(path, encoding="utf-8") as fh:
            head = [fh.readline(), fh.readline(), fh.readline()]
    except (OSError, UnicodeDecodeError):
        return False
    return head[0] == "# Each preset against ROSCO, measured\n" and \
        head[2].startswith("<!-- made by `wtftc presets --standing")


def main(folders: list[Path] | None = None, out: Path | None = None,
         write=None) -> str:
    """``wtftc presets --standing [FOLDER ...] [--out FILE]``: the page of the folders
    (default: every folder of docs/campaigns/ with runs), written to ``out`` if given,
    and returned (the CLI prints it without ``--out``). Its links are relative to
    ``out``'s folder; printed, to docs/ for the default folders (the page as committed),
    else to the working folder."""
    default = not folders
    folders = default_folders() if default else [Path(f) for f in folders]
    base = Path(out).resolve().parent if out is not None else \
        CAMPAIGNS.parent if default else Path.cwd()
    command = "wtftc presets --standing" + ("" if default else " " + " ".join(
        str(f) for f in folders)) + (f" --out {out}" if out is not None else "")
    text = markdown(standing(folders), base, command if (out or not default) else COMMAND)
    if out is not None:
        if write is None:
            Path(out).write_text(text, encoding="utf-8")
        else:  # whole or not at all (wtftc.results.io.atomic_write_text)
            write(Path(out), text)
    return text
