"""Screen on wtftc's plant, confirm in OpenFAST (issue 35 item 4):
``wtftc sweep SWEEP.toml --confirm-openfast N``.

The sweep runs on wtftc's plant first (every scenario, minutes). Then the N scenarios that
matter most are run again in OpenFAST, every controller of each, on the same wind (the
screen reads the TurbSim field OpenFAST runs on: ``[wind] field = "turbsim"``), fault and
seed, into a second results folder; the report sets both engines side by side with the
ranking agreement of issue 23 (wtftc.campaign.ranking).

A scenario is every axis of a run but the controller and the plant (paired.scenario
without the plant: wtftc's plant and OpenFAST's deck are the two engines). Which matter
most, in this order: those a controller lost (past the overspeed trip, or the rotor out of
its envelope), the worst first by their extreme speed; then, taken in turn, the worst
extreme overspeed, the worst shaft DEL and the worst tower-base DEL (each the worst over
the scenario's controllers), until N are chosen.
"""

from __future__ import annotations

import json
from pathlib import Path

from wtftc.campaign import ranking
from wtftc.campaign.sweep import paired, record
from wtftc.campaign.sweep.dlc import fault_label, parse_dlc
from wtftc.campaign.sweep.record import Record
from wtftc.campaign.sweep.spec import MAGNITUDE_COLUMN, Sweep, expand, parse_sweep
from wtftc.campaign.sweep.store import read_results
from wtftc.errors import ConfigError

#: every axis of a scenario but the controller and the plant (and the controller's tuning):
#: paired.SCENARIO's, the engines' plants left out
AXES = tuple(k for k in paired.SCENARIO
             if k not in ("plant", "tuning_omega_n_rad_s", "tuning_zeta"))
#: what ranks the scenarios after the lost ones: (run key, the reason's words)
WORST = [("overspeed_peak_over_rated", "worst extreme overspeed"),
         ("shaft_torque_del_1hz_Nm", "worst shaft DEL"),
         ("tower_base_del_1hz_Nm", "worst tower-base DEL")]
#: the report's columns: (run key, header, scale, format)
COLUMNS = [("overspeed_peak_over_rated", "peak ω / rated [-]", 1.0, "{:.3f}"),
           ("rms_speed_error_rad_s", "RMS ω error [rad/s]", 1.0, "{:.4f}"),
           ("shaft_torque_del_1hz_Nm", "shaft DEL [MN m]", 1e-6, "{:.3f}"),
           ("tower_base_del_1hz_Nm", "tower-base DEL [MN m]", 1e-6, "{:.1f}"),
           ("pitch_adc", "pitch ADC [-]", 1.0, "{:.3f}")]
REPORT = "confirm.md"
#: the SI units of COLUMNS' run keys, in confirm.csv's header
UNITS = ["-", "rad/s", "N m", "N m", "-"]


def scenario(r: dict) -> tuple:
    """The key a run shares with the runs of the same case on either engine."""
    return (fault_label(r), r.get("wind_kind") or "ntm", *(r.get(k) for k in AXES),
            *(v for k, v in sorted(r.items()) if k.startswith("mismatch_")))


def describe(r: dict) -> str:
    """A scenario in words: wind, turbulence class, seed and the fault with its size."""
    s = (f"{r['mean_wind_mps']:g} m/s" + (f" NTM {r['turbulence_class']}"
                                          if r.get("turbulence_class") else "")
         + f", seed {r['seed']}, {fault_label(r)}")
    if r["fault_type"] != "none":
        size = [f"{col} {r[col]:g}" if isinstance(r[col], int | float) else f"{col} {r[col]}"
                for col in MAGNITUDE_COLUMN.values() if r.get(col) is not None]
        s += ((f" on blade {r['blade']}" if r.get("blade") is not None else "")
              + (f" on sensor {r['fault_sensor']}" if r.get("fault_sensor") is not None
                 else "") + f" at {r['onset_s']:g} s" + (f" ({', '.join(size)})" if size
                                                          else ""))
    return s


def state(r: dict | None, trip: float) -> str:
    """A run's outcome in the report: held, lost (the rotor), failed (an error), absent."""
    if r is None:
        return "—"
    if r["status"] == "failed":
        return "failed"
    return "yes" if paired.held(r, trip) else "lost"


def _worst(rs: list[dict], key: str) -> float | None:
    vals = [v for v in (ranking._value(r.get(key)) for r in rs) if v is not None]
    return max(vals) if vals else None


def pick(rows: list[dict], n: int, trip: float) -> list[tuple[tuple, str]]:
    """The ``n`` scenarios of ``rows`` that matter most, each with why (module doc)."""
    by: dict[tuple, list[dict]] = {}
    for r in rows:
        by.setdefault(scenario(r), []).append(r)
    peak = {k: _worst(rs, "overspeed_peak_over_rated") or 0.0 for k, rs in by.items()}
    chosen: dict[tuple, str] = {}
    lost = {k: [r["controller"] for r in rs if state(r, trip) == "lost"]
            for k, rs in by.items()}
    for k in sorted((k for k in by if lost[k]), key=lambda k: -peak[k]):
        chosen.setdefault(k, "lost by " + ", ".join(sorted(set(lost[k]))))
    ranked = [sorted((k for k in by if _worst(by[k], key) is not None),
                     key=lambda k, key=key: -_worst(by[k], key)) for key, _ in WORST]
    for i in range(len(by)):
        for (_, why), order in zip(WORST, ranked, strict=True):
            if i < len(order):
                chosen.setdefault(order[i], f"{why} (#{i + 1})")
    return list(chosen.items())[:n]


def openfast_sweep(raw: dict) -> Sweep:
    """The same sweep in OpenFAST: its plants, batch size and engine dropped (the deck is
    the plant, one run a task)."""
    return parse_sweep({k: v for k, v in raw.items()
                        if k not in ("plants", "batch_size", "engine")} | {"engine": "openfast"})


def check_screen(sw: Sweep, n: int) -> None:
    """A sweep that can be screened and confirmed, refused in one line naming the key."""
    if sw.engine != "wtftc":
        raise ConfigError("--confirm-openfast", n, "a sweep on wtftc's plant to screen "
                          f"(this one's engine is {sw.engine}): leave engine out of the "
                          "sweep file, or run it in OpenFAST without --confirm-openfast")
    if sw.wind_field != "turbsim":
        raise ConfigError("wind.field", sw.wind_field or "spectral", '"turbsim" with '
                          "--confirm-openfast: the screen must run on the TurbSim fields "
                          "OpenFAST confirms on (docs/sweep.md)")
    if any(k.startswith("mismatch") for k in sw.raw):
        raise ConfigError("mismatch", sw.raw["mismatch"], "no [mismatch] with "
                          "--confirm-openfast: OpenFAST's plant is the turbine's deck")
    plants = sw.axis("plants").values
    if len(plants) > 1:
        raise ConfigError("plants", list(plants), "one plant with --confirm-openfast (each "
                          "scenario is confirmed once, against one of wtftc's plants)")


def confirm_runs(sw_of: Sweep, chosen: list[tuple[tuple, str]]) -> list[dict]:
    """The OpenFAST runs of the chosen scenarios: every controller of each."""
    keys = {k for k, _ in chosen}
    return [pt for pt in expand(sw_of)[0] if scenario(pt) in keys]


def report(screen_dir: Path, confirm_dir: Path, chosen: list[tuple[tuple, str]],
           trip: float, walls: dict) -> str:
    """confirm.md (and confirm.csv) in ``confirm_dir``: each chosen scenario's runs on both
    engines, and the engines' ranking agreement over them; returns the Markdown."""
    a = read_results(screen_dir).to_pylist()
    b = read_results(confirm_dir).to_pylist()
    keys = [k for k, _ in chosen]
    why = dict(chosen)
    on = [{scenario(r): {} for r in rows} for rows in (a, b)]
    for rows, table in ((a, on[0]), (b, on[1])):
        for r in rows:
            table[scenario(r)][paired.label(r["controller"], r)] = r
    n_screen = len(on[0])
    md = [f"# Screened on wtftc's plant, confirmed in OpenFAST: {len(keys)} of {n_screen} "
          "scenarios", "",
          f"Screen: `{screen_dir}` ({len(a)} runs, {walls.get('screen', 0):.0f} s); "
          f"confirmation: `{confirm_dir}` ({len(b)} runs, {walls.get('confirm', 0):.0f} s). "
          f"Each cell is wtftc / OpenFAST. Outcome: \"yes\", held; \"lost\", past {trip:g} × "
          "rated or the rotor out of its envelope (its metrics describe a rotor that "
          "stopped: not ranked); \"failed\", an error (the cause: `wtftc sweep --summary`).",
          "",
          "| scenario | why | controller | outcome | "
          + " | ".join(h for _, h, _, _ in COLUMNS) + " |",
          "|---" * (4 + len(COLUMNS)) + "|"]
    csv = ["scenario,why,controller,engine,outcome,"
           + ",".join(f"{k} [{u}]" for (k, *_), u in zip(COLUMNS, UNITS, strict=True))]
    for k in keys:
        runs = on[0].get(k, {})
        for c in sorted(runs):
            pair = [on[0].get(k, {}).get(c), on[1].get(k, {}).get(c)]
            held = " / ".join(state(r, trip) for r in pair)
            cells = [" / ".join(_fmt(r, key, scale, f) for r in pair)
                     for key, _, scale, f in COLUMNS]
            name = describe(next(iter(runs.values())))
            md.append(f"| {name} | {why[k]} | {c} | {held} | " + " | ".join(cells) + " |")
            for eng, r in zip(("wtftc", "openfast"), pair, strict=True):
                if r is not None:
                    csv.append(",".join(f'"{x}"' for x in (name, why[k], c)) + f",{eng},"
                               f"{state(r, trip)},"
                               + ",".join(_raw(r, key) for key, *_ in COLUMNS))
    rows = _agreement(on, keys, trip)
    md += ["", "## Ranking agreement (ties within each metric's tolerance count as "
           "agreement)", "", ranking.summary_markdown(rows) if rows else
           "No scenario has two controllers on both engines.", "",
           ranking.rows_markdown(rows, "wtftc", "OpenFAST") if rows else ""]
    text = "\n".join(md).rstrip() + "\n"
    _write(confirm_dir, {REPORT: text.encode(), "confirm.csv": ("\n".join(csv) + "\n").encode(),
                         "confirm.json": (json.dumps(
                             {"scenarios": [{"scenario": list(k), "why": w} for k, w in chosen],
                              "wall_s": walls}, indent=1) + "\n").encode()})
    return text


def _agreement(on: list[dict], keys: list[tuple], trip: float) -> list[dict]:
    """ranking.agreement_table over the chosen scenarios both engines ran; a run that did
    not hold (or failed) has no values to rank (its metrics describe a rotor that
    stopped), so its pairs count as missing."""
    tables = []
    for table in on:
        tables.append({describe(next(iter(table[k].values()))): {
            c: (r if state(r, trip) == "yes" else {}) for c, r in table[k].items()}
            for k in keys if table.get(k)})
    return ranking.agreement_table(*tables)


def _fmt(r: dict | None, key: str, scale: float, f: str) -> str:
    v = None if r is None else ranking._value(r.get(key))
    return "—" if v is None else f.format(v * scale)


def _raw(r: dict, key: str) -> str:
    v = ranking._value(r.get(key))
    return "" if v is None else repr(v)


def _write(folder: Path, data: dict[str, bytes]) -> None:
    """Through the folder's record, atomically, refusing a file it did not write."""
    rec = Record.open(folder, "--confirm-out", record.scan(folder, "--confirm-out"))
    rec.refuse_unless_ours(data)
    for rel, content in data.items():
        rec.write(rel, content)


def trip_of(sw: Sweep) -> float:
    """The sweep's overspeed trip ([dlc] overspeed_trip; 1.2 × rated by default)."""
    return parse_dlc(sw.raw.get("dlc") or {})["overspeed_trip"]
