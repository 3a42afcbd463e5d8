"""The ranking agreement of two engines (issue 33 item 4): do they order the controllers
the same way, metric by metric and scenario by scenario?

A table is ``{scenario: {controller: {metric: value}}}`` (lower is better for every
metric here), as :func:`read_compare` reads it from `wtftc compare` trees. For each
metric and scenario, every pair of controllers is compared on each engine: one is
better, or they tie within the metric's tolerance (:data:`TOLERANCES`: |a − b| ≤
max(abs, rel · max(|a|, |b|))). A pair is

* **concordant**: the same controller is better on both engines;
* **discordant** (swapped): each engine prefers a different one;
* **tied**: a tie on either engine, which counts as agreement (one seed does not resolve
  differences inside the tolerance);
* **missing**: a value is absent or not finite (a lost run), left out.

The engines agree on a (metric, scenario) when no pair is swapped. Kendall's τ is
(concordant − discordant) / (pairs compared), ties in the denominator: τ = 1 only when
every pair is strictly ordered alike.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Tolerance:
    """Two values tie when |a − b| ≤ max(``abs``, ``rel`` · max(|a|, |b|))."""

    rel: float
    abs: float

    def tie(self, a: float, b: float) -> bool:
        return abs(a - b) <= max(self.abs, self.rel * max(abs(a), abs(b)))

    def __str__(self) -> str:
        return f"{self.rel:.0%} or {self.abs:g}"


#: the ranked metrics (metrics.json's keys, lower is better), their tolerances and names
TOLERANCES = {
    "rms_speed_error_rad_s": Tolerance(0.05, 1e-4),
    "shaft_torque_del_1hz_Nm": Tolerance(0.05, 1e3),
    "tower_base_del_1hz_Nm": Tolerance(0.05, 1e4),
    "pitch_adc": Tolerance(0.05, 0.005),
    # the peak ω / rated: a difference of 0.2 % of rated speed is a tie
    "overspeed_peak_over_rated": Tolerance(0.0, 0.002),
}
NAMES = {"rms_speed_error_rad_s": "RMS speed error", "shaft_torque_del_1hz_Nm": "shaft DEL",
         "tower_base_del_1hz_Nm": "tower DEL", "pitch_adc": "pitch ADC",
         "overspeed_peak_over_rated": "extreme overspeed"}


def _value(v) -> float | None:
    return float(v) if isinstance(v, int | float) and math.isfinite(v) else None


def sign(a: float | None, b: float | None, tol: Tolerance) -> int | None:
    """−1 if ``a`` is better (lower) than ``b``, +1 if worse, 0 for a tie, None if either
    is missing."""
    if a is None or b is None:
        return None
    return 0 if tol.tie(a, b) else (-1 if a < b else 1)


def order(values: dict[str, float | None]) -> list[str]:
    """The controllers best first; those without a value last, in their given order."""
    known = sorted((v, k) for k, v in values.items() if v is not None)
    return [k for _, k in known] + [k for k, v in values.items() if v is None]


def order_text(values: dict[str, float | None], tol: Tolerance) -> str:
    """The order as text, best first: "a < b ≈ c" (≈: within the tolerance of the one
    before), those without a value after "; no value: "."""
    known = order({k: v for k, v in values.items() if v is not None})
    text = ""
    for prev, name in zip([None, *known], known, strict=False):
        sep = "" if prev is None else (" ≈ " if tol.tie(values[prev], values[name]) else " < ")
        text += sep + name
    missing = [k for k, v in values.items() if v is None]
    return text + ("; no value: " + ", ".join(missing) if missing else "")


def compare_orders(a: dict[str, float | None], b: dict[str, float | None],
                   tol: Tolerance) -> dict:
    """One metric on one scenario: engine ``a``'s values against ``b``'s, per controller
    (the controllers of both). Each engine's order, the pairs concordant, discordant
    (``swapped``: the pair and both engines' values), tied and missing, Kendall's τ and
    whether the engines agree (no swapped pair)."""
    names = [c for c in a if c in b]
    va = {c: _value(a[c]) for c in names}
    vb = {c: _value(b[c]) for c in names}
    counts = {"concordant": 0, "discordant": 0, "tied": 0, "missing": 0}
    swapped = []
    for x, y in itertools.combinations(names, 2):
        sa, sb = sign(va[x], va[y], tol), sign(vb[x], vb[y], tol)
        if sa is None or sb is None:
            counts["missing"] += 1
        elif sa == 0 or sb == 0:
            counts["tied"] += 1
        elif sa == sb:
            counts["concordant"] += 1
        else:
            counts["discordant"] += 1
            swapped.append({"pair": [x, y], "a": [va[x], va[y]], "b": [vb[x], vb[y]]})
    n = counts["concordant"] + counts["discordant"] + counts["tied"]
    tau = (counts["concordant"] - counts["discordant"]) / n if n else None
    return {"order_a": order(va), "order_b": order(vb), "text_a": order_text(va, tol),
            "text_b": order_text(vb, tol), "values_a": va, "values_b": vb, **counts,
            "swapped": swapped,
            "kendall_tau": tau, "agree": counts["discordant"] == 0}


def agreement_table(a: dict, b: dict, metrics=None, tolerances=None) -> list[dict]:
    """Every (metric, scenario) of two tables (``{scenario: {controller: {metric:
    value}}}``, the scenarios of both): one row each, :func:`compare_orders`'s."""
    tols = tolerances or TOLERANCES
    rows = []
    for metric in metrics or list(tols):
        for scenario in (s for s in a if s in b):
            per = [{c: m.get(metric) for c, m in t[scenario].items()} for t in (a, b)]
            rows.append({"metric": metric, "scenario": scenario,
                         "tolerance": str(tols[metric]),
                         **compare_orders(*per, tols[metric])})
    return rows


def summary(rows: list[dict]) -> dict:
    """Per metric: the scenarios where the engines agree, of how many, the pairs swapped
    of those compared, and the mean Kendall's τ."""
    out = {}
    for row in rows:
        s = out.setdefault(row["metric"], {"agree": 0, "scenarios": 0, "swapped": 0,
                                           "pairs": 0, "taus": []})
        s["agree"] += row["agree"]
        s["scenarios"] += 1
        s["swapped"] += row["discordant"]
        s["pairs"] += row["concordant"] + row["discordant"] + row["tied"]
        if row["kendall_tau"] is not None:
            s["taus"].append(row["kendall_tau"])
    for s in out.values():
        taus = s.pop("taus")
        s["mean_tau"] = sum(taus) / len(taus) if taus else None
    return out


def summary_markdown(rows: list[dict]) -> str:
    """:func:`summary` as a Markdown table."""
    md = ["| metric | tolerance (rel. or abs.) | scenarios agreeing | pairs swapped "
          "| mean Kendall's τ |", "|---|---|---|---|---|"]
    tols = {r["metric"]: r["tolerance"] for r in rows}
    for metric, s in summary(rows).items():
        tau = "—" if s["mean_tau"] is None else f"{s['mean_tau']:.2f}"
        md.append(f"| {NAMES.get(metric, metric)} | {tols[metric]} | {s['agree']} / "
                  f"{s['scenarios']} | {s['swapped']} / {s['pairs']} | {tau} |")
    return "\n".join(md)


def _num(v: float | None) -> str:
    return "—" if v is None else f"{v:.4g}"


def rows_markdown(rows: list[dict], name_a: str = "a", name_b: str = "b") -> str:
    """Every (metric, scenario): both orders, τ, and each swapped pair with its values."""
    md = [f"| metric | scenario | order on {name_a} | order on {name_b} | τ | swapped "
          f"pairs ({name_a}; {name_b}) |", "|---|---|---|---|---|---|"]
    for r in rows:
        swaps = "; ".join(f"{x} vs {y}: {_num(a1)} / {_num(a2)}; {_num(b1)} / {_num(b2)}"
                          for (x, y), (a1, a2), (b1, b2)
                          in ((s["pair"], s["a"], s["b"]) for s in r["swapped"]))
        tau = "—" if r["kendall_tau"] is None else f"{r['kendall_tau']:.2f}"
        md.append(f"| {NAMES.get(r['metric'], r['metric'])} | {r['scenario']} | "
                  f"{r['text_a']} | {r['text_b']} | {tau} | "
                  f"{swaps or '—'} |")
    return "\n".join(md)


def read_compare(trees) -> dict:
    """The cells of `wtftc compare` trees (``<tree>/<wind>/<fault>/<controller>/
    metrics.json``, those finished) as a table, scenario ``<wind>/<fault>``."""
    table: dict = {}
    for tree in trees:
        for f in sorted(Path(tree).glob("*/*/*/metrics.json")):
            wind, fault, controller = f.parent.relative_to(tree).parts
            table.setdefault(f"{wind}/{fault}", {})[controller] = json.loads(f.read_text())
    return table


def values_markdown(tables: dict, metric: str, scale: float = 1.0, fmt: str = "{:.4g}") -> str:
    """One metric's values, a row per scenario and a column per controller, each cell the
    engines' values in ``tables``' order (``{engine: table}``) joined by " / "; missing
    as "—". ``scale`` divides every value (1e6: N m to MN m)."""
    names = list(tables)
    first = tables[names[0]]
    ctrls = list(dict.fromkeys(c for s in first.values() for c in s))
    md = [f"| scenario | {' | '.join(ctrls)} |", "|---" * (len(ctrls) + 1) + "|"]
    for scenario in first:
        cells = []
        for c in ctrls:
            vs = [_value(t.get(scenario, {}).get(c, {}).get(metric)) for t in tables.values()]
            cells.append(" / ".join("—" if v is None else fmt.format(v / scale) for v in vs))
        md.append(f"| {scenario} | {' | '.join(cells)} |")
    return "\n".join(md)
