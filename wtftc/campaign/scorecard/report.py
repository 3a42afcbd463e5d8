"""The scorecard's report: ``scorecard.json`` (every figure), ``scorecard.md`` (the
verdict table first), ``scorecard.html`` (the same with its figures inside) and
``figures/``, from the groups' results folders (wtftc.campaign.scorecard.run).

Every ratio is the controller's over the baseline's on the same scenario, over the
scenarios both held (wtftc.campaign.scorecard.stats.held_pairs), with a bootstrap
interval over the seeds and a verdict: better, worse, or a tie where the interval holds 1
(stats.paired_ratio; fewer than stats.MIN_SEEDS seeds: no verdict). Every fault run's
outcome is counted (wtftc.campaign.scorecard.outcome): none is dropped.
"""

from __future__ import annotations

import json
from pathlib import Path

from wtftc.campaign.scorecard import outcome, stats
from wtftc.campaign.scorecard.scored import FAULT_GROUPS, METRICS, PITCH, SPECTRA


def _rows(out: Path, group: str) -> list[dict]:
    from wtftc.campaign.sweep.store import read_results

    return read_results(out / group).to_pylist()


def _paired(pp: list, key: str, lower: bool) -> dict:
    return stats.paired_ratio([(a["seed"], a.get(key), b.get(key)) for a, b in pp],
                              lower_is_better=lower)


def _metrics(group: str, pp: list, table=None) -> list[dict]:
    return [{"metric": key, "what": what, "unit": unit, **_paired(pp, key, lower)}
            for key, what, unit, lower in (METRICS[group] if table is None else table)]


def fdi_columns(columns: list[dict]) -> set[str]:
    """The names of the columns (scorecard.run.column's tables) whose accommodation is
    wtftc's FDI: on wtftc's plant the FDI watches every run, but acts, and is judged, only
    in these."""
    from wtftc import controller

    return {c["name"] for c in columns
            if controller.parse({k: v for k, v in c.items() if k != "name"}).uses_fdi}


def _fdi(rows: list[dict], judged: set[str]) -> dict:
    """The FDI's timing per column that runs it (``judged``), per fault type: runs,
    detected, isolated (the right blade and kind), the median and largest detection delay
    [s] from the onset."""
    import numpy as np

    from wtftc.campaign.sweep.dlc import fault_label

    out: dict = {}
    for r in rows:
        if r["status"] == "failed" or r["controller"] not in judged:
            continue
        cell = out.setdefault(r["controller"], {}).setdefault(
            fault_label(r), {"runs": 0, "detected": 0, "isolated": 0, "delays_s": []})
        cell["runs"] += 1
        cell["detected"] += bool(r.get("fault_detected"))
        cell["isolated"] += bool(r.get("fault_correct"))
        if r.get("detection_delay_s") is not None:
            cell["delays_s"].append(r["detection_delay_s"])
    for cols in out.values():
        for cell in cols.values():
            d = cell.pop("delays_s")
            cell["median_delay_s"] = float(np.median(d)) if d else None
            cell["max_delay_s"] = max(d) if d else None
    return out


def _false_alarms(rows: list[dict], scored_s: float, judged: set[str]) -> dict:
    """Per column that runs wtftc's FDI (``judged``), over the fault-free runs: its false
    alarms, the hours scored, the rate and its 95 % upper bound (stats.upper_rate_bound)."""
    out = {}
    for c in sorted(judged):
        free = [r for r in rows if r["controller"] == c and r["status"] != "failed"
                and r["fault_type"] == "none" and r.get("false_alarms") is not None]
        if free:
            n, hours = sum(r["false_alarms"] for r in free), len(free) * scored_s / 3600.0
            out[c] = {"alarms": n, "hours": hours, "runs": len(free),
                      "runs_with_an_alarm": sum(r["false_alarms"] > 0 for r in free),
                      "per_hour": n / hours,
                      "per_hour_upper_95": stats.upper_rate_bound(n, hours, 0.95)}
    return out


def _energy(rows: list[dict]) -> dict:
    """What a faulted turbine keeps, per fault type and column: the mean electrical
    energy from the onset to the run's end [J] over every run that finished (held or
    not: the outcome table says which)."""
    import numpy as np

    from wtftc.campaign.sweep.dlc import fault_label

    by: dict = {}
    for r in rows:
        if r["status"] != "failed" and r.get("energy_after_onset_J") is not None:
            by.setdefault(fault_label(r), {}).setdefault(r["controller"], []).append(
                r["energy_after_onset_J"])
    return {f: {c: {"runs": len(v), "mean_J": float(np.mean(v))} for c, v in cols.items()}
            for f, cols in by.items()}


def _lifetime(rows_c: list, rows_b: list, m: dict, turbine: str | None) -> dict:
    """Lifetime shaft and tower DELs and AEP, whole and below or above rated."""
    from wtftc import config

    g = m["groups"]["normal_production"]
    rc = config.make_config({"controller": "pi", **({"turbine": turbine} if turbine else {})})
    rated = config.rated_wind_speed(rc.loop.p_turbine, rc.loop.table)
    loads = config.loads_options({})
    out = {"rated_wind_mps": rated, "annual_mean_mps": m["annual_mean_mps"]}
    for name, key, exp in (("shaft", "shaft_torque_damage_per_10min",
                            loads["shaft_wohler_exponent"]),
                           ("tower", "tower_base_damage_per_10min",
                            loads["tower_wohler_exponent"]),
                           ("blade", "blade_root_flap_damage_per_10min",
                            loads["blade_wohler_exponent"])):
        out[name] = stats.lifetime_ratio(rows_c, rows_b, m["annual_mean_mps"],
                                         g["bin_width_mps"], exp, key, rated,
                                         g["overspeed_trip"])
    return out


def _outcomes(rows: list, trip: float, label=None) -> dict:
    """Each fault type's (or ``label(row)``'s) outcomes per column:
    {label: {column: {outcome: n}}}."""
    from wtftc.campaign.sweep.dlc import fault_label

    out: dict = {}
    for r in rows:
        cell = out.setdefault((label or fault_label)(r), {}).setdefault(
            r["controller"], dict.fromkeys(outcome.OUTCOMES, 0))
        cell[outcome.classify(r, r.get("onset_s"), trip)] += 1
    return out


def _same_scenario(r: dict) -> tuple:
    """A scenario's key on either engine (the plant left out: tower_edge or openfast)."""
    from wtftc.campaign.sweep import paired

    return paired.scenario({**r, "plant": None})


def _confirmed(screen_rows: list, conf_rows: list, group: str, cand: str, base: str,
               trip: float) -> dict:
    """The confirmed scenarios on both engines: each metric's ratio in OpenFAST and on the
    screen over the scenarios both engines held and both have the metric for (OpenFAST's
    alone where the screen has no such metric: the blade root), and how OpenFAST's
    interval stands to the screen's ratio (stats.agreement)."""
    keys = {_same_scenario(r) for r in conf_rows}
    mine = [r for r in screen_rows if _same_scenario(r) in keys]

    def held(rows):
        return stats.held_pairs([r for r in rows if r["controller"] == cand],
                                [r for r in rows if r["controller"] == base], trip)

    of_pp, counts = held(conf_rows)
    on_screen = {_same_scenario(a): (a, b) for a, b in held(mine)[0]}
    both = [(p, on_screen[_same_scenario(p[0])]) for p in of_pp
            if _same_scenario(p[0]) in on_screen]
    metrics = []
    for key, what, unit, lower in METRICS[group]:
        if not any(s[0].get(key) is not None for _, s in both):
            r = {"metric": key, "what": what, "unit": unit, **_paired(of_pp, key, lower),
                 "screen_ratio": None, "agree": None}
        else:
            ok = [(o, s) for o, s in both if stats.has_ratio(o[0].get(key), o[1].get(key))
                  and stats.has_ratio(s[0].get(key), s[1].get(key))]
            r = {"metric": key, "what": what, "unit": unit,
                 **_paired([o for o, _ in ok], key, lower)}
            r["screen_ratio"] = _paired([s for _, s in ok], key, lower)["ratio"]
            r["agree"] = stats.agreement(r, r["screen_ratio"])
        metrics.append(r)
    label = _case_label if group == "deterministic" else None
    return {"counts": counts, "metrics": metrics,
            "outcomes": {"openfast": _outcomes(conf_rows, trip, label),
                         "screen": _outcomes(mine, trip, label)}}


def analyse(out: Path, result: dict, turbine: str | None = None) -> dict:
    """Every figure of the scorecard, as scorecard.json holds it."""
    from wtftc.artefacts.loader import generated_code_sha256
    from wtftc.campaign.sweep.store import versions

    m = result["matrix"]
    cand, base = (c["name"] for c in result["columns"])
    doc = {"controller": cand, "baseline": base, "matrix_hash": result["matrix_hash"],
           "generated_code_sha256": generated_code_sha256(), "turbine": turbine,
           "engine": result.get("engine"), "versions": versions(), "groups": {}}
    judged = fdi_columns(result["columns"])
    for group in m["groups"]:
        rows = _rows(Path(out), group)
        trip = m["groups"][group]["overspeed_trip"]
        if group == "baseline_as_shipped":
            g = _as_shipped(rows, _rows(Path(out), "normal_production"), base, trip)
        else:
            g = _group(group, rows, cand, base, trip, judged, m, turbine)
        g.update(iec=m["groups"][group]["iec"], wall_s=result["groups"][group]["wall_s"],
                 calls=result["groups"][group].get("calls_wall_s"))
        conf = Path(out) / f"{group}_openfast"
        if result.get("screen") is not None and conf.is_dir():
            g["confirmed"] = _confirmed(rows, _rows(Path(out), conf.name), group, cand,
                                        base, trip)
        doc["groups"][group] = g
    doc["screen"] = result.get("screen")
    doc["seeds"] = result.get("seeds")
    doc["cost"] = _wall(Path(out), result, turbine)
    return doc


def _wall(out: Path, result: dict, turbine: str | None) -> dict:
    """The card's wall over its calls, its OpenFAST runs' rate, the whole matrix's
    projection at that rate (wtftc.campaign.scorecard.cost)."""
    from wtftc.campaign.scorecard import cost, matrix

    m, groups = result["matrix"], result["groups"]
    if result.get("screen") is not None:
        folders = [f"{g}_openfast" for g in groups if (out / f"{g}_openfast").is_dir()]
    else:
        folders = list(groups) if (result.get("engine") or "openfast") == "openfast" else []
    rows = [r for f in folders for r in _rows(out, f)]
    calls = {g: groups[g].get("calls_wall_s") or [{"wall_s": groups[g]["wall_s"],
                                                    "workers": None}] for g in groups}
    return cost.summary(groups, rows, matrix.plan(m, turbine, result.get("seeds")), calls)


def _group(group: str, rows: list, cand: str, base: str, trip: float, judged: set,
           m: dict, turbine: str | None) -> dict:
    """One group's figures: the paired verdicts; the lifetime, bands and false alarms
    (normal production); the outcomes, energy, per-fault verdicts (the fault groups); each
    case's ratios (the deterministic group); the FDI's timing."""
    from wtftc.campaign.sweep.dlc import fault_label

    mine = [r for r in rows if r["controller"] == cand]
    theirs = [r for r in rows if r["controller"] == base]
    pp, counts = stats.held_pairs(mine, theirs, trip)
    g = {"counts": counts, "metrics": _metrics(group, pp), "fdi": _fdi(rows, judged)}
    if group == "normal_production":
        g["lifetime"] = _lifetime(mine, theirs, m, turbine)
        g["spectra"] = _metrics(group, pp, SPECTRA)
        g["pitch"] = _metrics(group, pp, PITCH)
        g["false_alarms"] = _false_alarms(rows, m["groups"][group]["scored_s"], judged)
    elif group in FAULT_GROUPS:
        g["outcomes"] = _outcomes(rows, trip)
        g["energy_after_onset"] = _energy(rows)
        g["by_fault"] = {label: _metrics(group, [(a, b) for a, b in pp
                                                 if fault_label(a) == label])
                         for label in sorted({fault_label(r) for r in rows})}
    elif group == "deterministic":
        g["outcomes"] = _outcomes(rows, trip, _case_label)
        g["by_case"] = {_case_label(a): _metrics(group, [(a, b)]) for a, b in pp}
    return g


def _case_label(r: dict) -> str:
    """A deterministic run's case: its wind's kind and mean wind."""
    return f"{r.get('wind_kind') or 'ntm'} at {r['mean_wind_mps']:g} m/s"


def _as_shipped(rows: list, normal: list, base: str, trip: float) -> dict:
    """The baseline with the benchmark's actuator and sensors (its normal-production
    runs) over the baseline as shipped (this group's runs), paired by mean wind and seed:
    what the benchmark costs it, a ratio above 1."""
    shipped = {(r["mean_wind_mps"], r["seed"]): r for r in rows}
    bench = [r for r in normal if r["controller"] == base
             and (r["mean_wind_mps"], r["seed"]) in shipped]
    pp, counts = stats.held_pairs(bench, [shipped[(r["mean_wind_mps"], r["seed"])]
                                          for r in bench], trip)
    if len(bench) < len(shipped):  # a run of either side missing
        counts["unpaired"] = len(shipped) - len(bench)
    return {"counts": counts, "metrics": _metrics("baseline_as_shipped", pp),
            "pairs": "the baseline's normal-production runs over its as-shipped runs"}


def _cell(r: dict) -> str:
    if r.get("ratio") is None:
        return "—"
    if r.get("low") is None:
        return f"{r['ratio']:.3g} ({r['verdict']})"
    return f"{r['ratio']:.3g} ({r['low']:.3g}–{r['high']:.3g}) **{r['verdict']}**"


def markdown(doc: dict) -> str:
    """The report: the verdict table first; the screen's confirmation; the lifetime
    figures; the loads in the 1P and 3P bands; the outcomes of the fault runs with the
    energy each kept; the FDI's timing and false alarms; the provenance."""
    lines = [f"# Scorecard: `{doc['controller']}` against `{doc['baseline']}`", "",
             "Each cell: the ratio controller / baseline (geometric mean over the scenarios "
             "both held), its 90 % bootstrap interval over the seeds, and the verdict "
             "(better, worse, or a tie where the interval holds 1).", "",
             "| group | metric | ratio (interval) verdict | pairs | seeds |",
             "|---|---|---|---|---|"]
    for name, g in doc["groups"].items():
        for r in g["metrics"] if name != "baseline_as_shipped" else []:
            lines.append(f"| {name} (DLC {g['iec']}) | {r['what']} [{r['unit']}] | "
                         f"{_cell(r)} | {r['n_pairs']} | {r['n_seeds']} |")
    for section in (_confirmed_lines, _lifetime_lines, _spectra_lines, _pitch_lines,
                    _case_lines, _as_shipped_lines, _outcome_lines, _fdi_lines,
                    _alarm_lines, _wall_lines, _provenance_lines):
        lines += section(doc)
    return "\n".join(lines) + "\n"


def _lifetime_lines(doc: dict) -> list[str]:
    life = doc["groups"].get("normal_production", {}).get("lifetime")
    if not life:
        return []
    lines = ["", f"## Lifetime (Rayleigh mean {life['annual_mean_mps']:g} m/s, rated "
             f"wind {life['rated_wind_mps']:.3g} m/s)", "",
             "| load | part | DEL ratio | AEP ratio |", "|---|---|---|---|"]
    for load in ("shaft", "tower", "blade"):
        for part in stats.PARTS:
            p = (life.get(load) or {}).get(part) or {}
            if load in life:
                lines.append(f"| {load} | {part} | {_cell(p.get('del') or {})} | "
                             f"{_cell(p.get('aep') or {})} |")
    return lines


def _spectra_lines(doc: dict) -> list[str]:
    rows = doc["groups"].get("normal_production", {}).get("spectra") or []
    if not any(r.get("ratio") is not None for r in rows):
        return []
    return ["", "## Loads in the rotor's 1P and 3P bands (normal production)", "",
            "| load, band | ratio (interval) verdict | pairs |", "|---|---|---|",
            *(f"| {r['what']} [{r['unit']}] | {_cell(r)} | {r['n_pairs']} |"
              for r in rows if r.get("ratio") is not None)]


def _pitch_lines(doc: dict) -> list[str]:
    rows = doc["groups"].get("normal_production", {}).get("pitch") or []
    if not any(r.get("ratio") is not None for r in rows):
        return []
    return ["", "## The blades' pitch direction changes (normal production)", "",
            "The mean over the blades; a direction change is a turn back by more than the "
            "hysteresis (`[loads] reversal_hysteresis_deg`). The blades' pitch travel per "
            "second is the pitch actuator duty cycle times the rate limit: its ratio is "
            "the duty cycle's.", "",
            "| metric | ratio (interval) verdict | pairs |", "|---|---|---|",
            *(f"| {r['what']} [{r['unit']}] | {_cell(r)} | {r['n_pairs']} |"
              for r in rows if r.get("ratio") is not None)]


def _case_lines(doc: dict) -> list[str]:
    """The deterministic group's cases, one run each: each metric's ratio per case."""
    cases = doc["groups"].get("deterministic", {}).get("by_case") or {}
    if not cases:
        return []
    metrics = next(iter(cases.values()))
    lines = ["", "## Deterministic winds: the ratio controller / baseline per case (one run "
             "each, no interval)", "",
             "| case | " + " | ".join(f"{r['what']} [{r['unit']}]" for r in metrics) + " |",
             "|" + "---|" * (1 + len(metrics))]
    for case, rs in sorted(cases.items()):
        lines.append(f"| {case} | " + " | ".join(
            "—" if r.get("ratio") is None else f"{r['ratio']:.3g}" for r in rs) + " |")
    return lines


def _as_shipped_lines(doc: dict) -> list[str]:
    """What the benchmark's actuator and sensors cost the baseline."""
    g = doc["groups"].get("baseline_as_shipped")
    if not g:
        return []
    where = ("in OpenFAST" if doc.get("screen") is None and doc.get("engine") != "wtftc"
             else "on wtftc's plant, where the actuator's dynamics are the plant's in both "
             "runs: what the sensors' noise and sampling cost, not the actuator")
    return ["", f"## What the benchmark's actuator and sensors cost `{doc['baseline']}`", "",
            "Each cell: the baseline behind the benchmark's actuator and noisy sensors over "
            "the baseline as its deck ships it (ideal pitch, exact sensors), paired by wind "
            f"and seed, with its 90 % interval over the seeds: above 1, what they cost; "
            f"{where}.", "",
            "| metric | ratio (interval) | pairs | seeds |", "|---|---|---|---|",
            *(f"| {r['what']} [{r['unit']}] | {_cell({**r, 'verdict': _cost(r)})} | "
              f"{r['n_pairs']} | {r['n_seeds']} |" for r in g["metrics"])]


def _cost(r: dict) -> str:
    """A ratio benchmark / as shipped in words: it costs, saves, or a tie."""
    if r.get("low") is None or r["verdict"] in (stats.FEW_SEEDS, stats.NO_PAIRS):
        return r["verdict"]
    return "tie" if r["low"] <= 1.0 <= r["high"] else "costs" if r["low"] > 1.0 else "saves"


def _outcome_lines(doc: dict) -> list[str]:
    lines = []
    for name, g in doc["groups"].items():
        if "outcomes" not in g:
            continue
        energy = g.get("energy_after_onset") or {}
        lines += ["", f"## Outcomes of {name} (every run), and the energy kept", "",
                  "| fault or case | column | " + " | ".join(outcome.OUTCOMES)
                  + " | mean energy after the onset [MWh] |",
                  "|" + "---|" * (3 + len(outcome.OUTCOMES))]
        for label, cols in g["outcomes"].items():
            for col, n in cols.items():
                e = (energy.get(label) or {}).get(col)
                kept = "—" if e is None else f"{e['mean_J'] / 3.6e9:.3g}"
                lines.append(f"| {label} | {col} | "
                             + " | ".join(str(n[o]) for o in outcome.OUTCOMES)
                             + f" | {kept} |")
    return lines


def _fdi_lines(doc: dict) -> list[str]:
    lines = []
    for name, g in doc["groups"].items():
        cells = [(col, label, c) for col, by in (g.get("fdi") or {}).items()
                 for label, c in by.items() if label != "none"]
        if not cells:
            continue
        lines += ["", f"## The FDI's detection and isolation ({name})", "",
                  "| column | fault | runs | detected | isolated | median delay [s] | "
                  "largest delay [s] |", "|---|---|---|---|---|---|---|"]
        for col, label, c in cells:
            med = "—" if c["median_delay_s"] is None else f"{c['median_delay_s']:.3g}"
            top = "—" if c["max_delay_s"] is None else f"{c['max_delay_s']:.3g}"
            lines.append(f"| {col} | {label} | {c['runs']} | {c['detected']} | "
                         f"{c['isolated']} | {med} | {top} |")
    return lines


def _alarm_lines(doc: dict) -> list[str]:
    rates = doc["groups"].get("normal_production", {}).get("false_alarms") or {}
    if not rates:
        return []
    return ["", "## False alarms in the fault-free hours", "",
            "| column | alarms | hours | runs with one | per hour | 95 % upper bound per "
            "hour |", "|---|---|---|---|---|---|",
            *(f"| {c} | {a['alarms']} | {a['hours']:.3g} | {a['runs_with_an_alarm']} of "
              f"{a['runs']} | {a['per_hour']:.3g} | {a['per_hour_upper_95']:.3g} |"
              for c, a in rates.items())]


def _wall_lines(doc: dict) -> list[str]:
    from wtftc.campaign.scorecard import cost

    return cost.lines(doc.get("cost"))


def _provenance_lines(doc: dict) -> list[str]:
    return ["", "## Provenance", "",
            f"- generated code: `{doc['generated_code_sha256']}`; case matrix: "
            f"`{doc['matrix_hash']}`; turbine: {doc['turbine'] or 'nrel5mw'}; engine: "
            f"{doc.get('engine') or 'openfast'}",
            "- versions: " + ", ".join(f"{k} {v}" for k, v in doc["versions"].items()
                                       if k != "generated_code_sha256"),
            *(f"- {name}: {g['counts']['scenarios']} scenarios, wall {g['wall_s']:.0f} s "
              "this call" + _calls(g.get("calls") or []) for name, g in doc["groups"].items())]


def _calls(calls: list[dict]) -> str:
    """The wall times of every call that ran the group, where there were several."""
    if len(calls) < 2:
        return ""
    return (f", {sum(c['wall_s'] for c in calls):.0f} s over its {len(calls)} calls ("
            + ", ".join(f"{c['wall_s']:.0f} s on {c['workers']} workers" for c in calls)
            + ")")


def _confirmed_lines(doc: dict) -> list[str]:
    """The screen's confirmed scenarios on both engines, side by side."""
    if doc.get("screen") is None:
        return []
    lines = ["", f"## The screen, confirmed in OpenFAST (--screen {doc['screen']})", "",
             "The verdicts above are the screen's, on wtftc's tower_edge plant over every "
             "scenario. Here each metric over the confirmed scenarios both engines held, "
             "on both engines (OpenFAST's alone where the screen has no such metric). "
             "OpenFAST agrees where its interval lies wholly on the screen's side of 1, "
             "disagrees where wholly on the other, and decides nothing where it holds 1. "
             "The scenarios are each metric's most against and most for its verdict and "
             "those whose outcomes differ: not a sample of the whole.", "",
             "| group | metric | OpenFAST | screen, same scenarios | OpenFAST's interval |",
             "|---|---|---|---|---|"]
    for name, g in doc["groups"].items():
        for r in g.get("confirmed", {}).get("metrics", []):
            screen = "—" if r["screen_ratio"] is None else f"{r['screen_ratio']:.3g}"
            agree = "—" if r["agree"] is None else \
                f"**{r['agree']}**" if r["agree"] == "disagrees" else r["agree"]
            lines.append(f"| {name} | {r['what']} | {_cell(r)} | {screen} | {agree} |")
    return lines + _confirmed_outcome_lines(doc)


def _counts(n: dict | None) -> str:
    return "—" if n is None else ", ".join(f"{o} {k}" for o, k in n.items() if k)


def _confirmed_outcome_lines(doc: dict) -> list[str]:
    """The confirmed scenarios' outcomes on both engines, where either lost one."""
    lines = []
    for name, g in doc["groups"].items():
        both = (g.get("confirmed") or {}).get("outcomes") or {}
        for label, cols in (both.get("openfast") or {}).items():
            for col, n in cols.items():
                screen = (both.get("screen") or {}).get(label, {}).get(col)
                if n.get("held", 0) != sum(n.values()) or screen is None or \
                        screen.get("held", 0) != sum(screen.values()):
                    lines.append(f"| {name} | {label} | {col} | {_counts(screen)} | "
                                 f"{_counts(n)} |")
    if not lines:
        return []
    return ["", "The confirmed scenarios that either engine did not hold, their outcomes "
            "on each:", "", "| group | fault or case | column | screen | OpenFAST |",
            "|---|---|---|---|---|", *lines]


def write(out: Path, result: dict, turbine: str | None = None) -> str:
    """scorecard.json and scorecard.md into ``out``, each written whole; the Markdown."""
    from wtftc.campaign.scorecard import html
    from wtftc.results.io import atomic_write_text

    doc = analyse(out, result, turbine)
    text = markdown(doc)
    figures = []
    if "normal_production" in doc["groups"]:
        rows, cols = _rows(Path(out), "normal_production"), [doc["controller"],
                                                               doc["baseline"]]
        figures = [*html.per_bin_figure(rows, cols, Path(out)),
                   *html.trade_off_figure(rows, cols, Path(out))]
    atomic_write_text(Path(out) / "scorecard.json", json.dumps(doc, indent=1, default=str))
    atomic_write_text(Path(out) / "scorecard.md", text)
    atomic_write_text(Path(out) / "scorecard.html", html.to_html(
        text, [p for p in figures if p.suffix == ".png"],
        f"Scorecard: {doc['controller']} against {doc['baseline']}"))
    return text
