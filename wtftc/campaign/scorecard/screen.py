"""Which scenarios a screened scorecard runs again in OpenFAST: those that decide its
verdicts (``wtftc scorecard --screen N``).

The screen runs every scenario of a group on wtftc's plant. A verdict is a paired ratio
over the scenarios both columns held (wtftc.campaign.scorecard.stats), and an outcome
count over every scenario (wtftc.campaign.scorecard.outcome). What decides them, and so
what OpenFAST confirms, in this order:

1. **where the outcomes differ** (one column held, the other tripped or was brought
   down): for each fault and each such pair of outcomes, the scenario with the highest
   peak speed. These decide the outcome counts, and leave the ratios;
2. **one scenario of each fault both columns lost**, the one with the highest peak speed:
   whether OpenFAST loses it too;
3. **each metric's scenario most against the screen's ratio**: the largest log ratio
   where the controller is better, the smallest where it is worse. A verdict rests on its
   ends (the bootstrap interval over the seeds is widest where they differ most), and the
   end that argues against it is the one that could overturn it;

then, until at least N are chosen, each metric's scenario that carries its ratio most,
then the next ones against and for, every metric in turn. The list holds every scenario
of steps 1 to 3 even when that is more than N: a verdict is confirmed whole or not at
all. In OpenFAST a scenario of a long run costs minutes: steps 1 to 3 are what a screened
scorecard needs, N what it can afford beyond them.
"""

from __future__ import annotations

import math

from wtftc.campaign.scorecard import outcome, scored
from wtftc.campaign.sweep import confirm
from wtftc.campaign.sweep.dlc import fault_label


def _by_scenario(rows: list[dict], cand: str, base: str) -> dict[tuple, dict]:
    """{scenario: {"cand": row, "base": row}} over the scenarios both columns ran."""
    by: dict[tuple, dict] = {}
    for r in rows:
        side = "cand" if r["controller"] == cand else "base" if r["controller"] == base \
            else None
        if side is not None:
            by.setdefault(confirm.scenario(r), {})[side] = r
    return {k: v for k, v in by.items() if len(v) == 2}


def _outcomes(pair: dict, trip: float) -> tuple[str, str]:
    return tuple(outcome.classify(pair[s], pair[s].get("onset_s"), trip)
                 for s in ("cand", "base"))


def _peak(pair: dict) -> float:
    vals = [pair[s].get("overspeed_peak_over_rated") for s in ("cand", "base")]
    return max((v for v in vals if v is not None and math.isfinite(v)), default=0.0)


def _lost(by: dict, trip: float) -> dict[tuple, str]:
    """Steps 1 and 2 of the module docstring, in that order: {scenario: why}."""
    differ: dict[tuple, tuple] = {}
    both: dict[tuple, tuple] = {}
    for k in sorted(by, key=lambda k: -_peak(by[k])):
        mine, theirs = _outcomes(by[k], trip)
        label = fault_label(by[k]["cand"])
        if mine != theirs and (label, mine, theirs) not in differ.values():
            differ[k] = (label, mine, theirs)
        elif mine == theirs != "held" and (label, mine) not in both.values():
            both[k] = (label, mine)
    return {**{k: f"{v[0]}: controller {v[1]}, baseline {v[2]} (the highest peak speed "
                  "of those)" for k, v in differ.items()},
            **{k: f"{v[0]} {v[1]} by both (the highest peak speed of those)"
               for k, v in both.items()}}


def _ends(by: dict, trip: float, metric: tuple) -> list[tuple[tuple, str]]:
    """One metric's scenarios both held, by how strongly each argues against the screen's
    ratio, then for it, alternately: [against #1, for #1, against #2, ...]."""
    key, what = metric[0], metric[1]
    logs = []
    for k, pair in by.items():
        if _outcomes(pair, trip) != ("held", "held"):
            continue
        a, b = pair["cand"].get(key), pair["base"].get(key)
        if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)) \
                or a <= 0.0 or b <= 0.0:
            continue
        logs.append((math.log(a / b), k))
    if not logs:
        return []
    mean = sum(x for x, _ in logs) / len(logs)
    against = sorted(logs, key=lambda e: -e[0] if mean <= 0.0 else e[0])
    out = []
    for i in range(len(logs)):
        for side, (x, k) in (("against", against[i]), ("for", against[-1 - i])):
            out.append((k, f"{what}: #{i + 1} {side} the screen's ratio ({math.exp(x):.3g})"))
    return out


def decisive(rows: list[dict], n: int, trip: float, group: str, cand: str,
             base: str) -> list[tuple[tuple, str]]:
    """The scenarios (confirm.scenario keys, each with why) of one group's screened
    ``rows`` that OpenFAST confirms: the module docstring's, at least ``n`` where the group
    has them."""
    by = _by_scenario(rows, cand, base)
    chosen = _lost(by, trip)
    ends = [_ends(by, trip, m) for m in scored.METRICS.get(group, [])]
    depth = max((len(e) for e in ends), default=0)
    for i in range(depth):
        if i >= 1 and len(chosen) >= n:  # the first of each: the most against
            break
        for e in ends:
            if i < len(e):
                chosen.setdefault(*e[i])
    return list(chosen.items())
