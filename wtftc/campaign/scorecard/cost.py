"""What a scorecard cost, and what its whole matrix in OpenFAST would cost.

Three figures, each from what the card's own folders hold:

- each group's wall time over every call that ran it (``walls.json``,
  wtftc.campaign.scorecard.run.log_wall), and the workers of each call;
- the OpenFAST runs' wall per simulated second: Σ wall / Σ simulated seconds over the
  card's OpenFAST runs (each run's wall as its worker measured it, one OpenFAST process
  on one core; a run that stopped early counts the seconds it simulated);
- the projection of the whole matrix in OpenFAST (the card without ``--screen``) on W
  workers at that rate: the groups one after another, as ``wtftc scorecard`` runs them,
  each group's runs in rounds of W, a round as long as one of its runs
  (Σ_g ⌈n_g / W⌉ · T_g · r, with n_g runs of T_g simulated seconds each). It leaves out
  the TurbSim fields, made before the runs, and the runs that end early; it assumes a
  worker runs OpenFAST as fast as the workers of the measurement did.
"""

from __future__ import annotations

import json
import math

#: the worker counts the projection is given for: one core, a two-core machine, a
#: workstation, a small and a large cluster
PROJECTED_WORKERS = (1, 2, 8, 32, 100)


def simulated_s(row: dict) -> float:
    """The simulated seconds a run covered: to its end, or to where it stopped."""
    stopped = row.get("diverged_at_s")
    if row.get("status") == "diverged" and stopped is not None:
        return float(stopped)
    return float(json.loads(row["config_json"])["t_final_s"])


def rate(rows: list[dict]) -> dict | None:
    """Σ wall / Σ simulated seconds over the runs that ran (a failed run's wall is not
    a simulation's), with the counts it stands on; None without a run."""
    ran = [r for r in rows if r.get("status") in ("ok", "diverged")
           and r.get("wall_s") and math.isfinite(r["wall_s"]) and simulated_s(r) > 0]
    if not ran:
        return None
    wall = sum(float(r["wall_s"]) for r in ran)
    sim = sum(simulated_s(r) for r in ran)
    each = [float(r["wall_s"]) / simulated_s(r) for r in ran]
    return {"runs": len(ran), "wall_s": wall, "simulated_s": sim,
            "wall_per_simulated_s": wall / sim, "run_min": min(each), "run_max": max(each)}


def card_turbine(folder) -> str | None:
    """The turbine a scorecard's folder was made for (its sweep files' ``turbine``), None
    where it holds no sweep file."""
    import tomllib
    from pathlib import Path

    for f in sorted((Path(folder) / "sweeps").glob("*.toml")):
        return str(tomllib.loads(f.read_text("utf-8")).get("turbine"))
    return None


def measured_in(folder) -> dict | None:
    """:func:`rate` over the OpenFAST runs (plant ``openfast``) of every results folder
    in a scorecard's folder: what its card measured, for ``wtftc scorecard --plan --out``;
    None where it holds none."""
    from pathlib import Path

    from wtftc.campaign.sweep.store import read_results

    rows = [r for d in sorted(Path(folder).iterdir()) if (d / "runs").is_dir()
            for r in read_results(d).to_pylist() if r.get("plant") == "openfast"]
    return rate(rows)


def projection(plan: dict[str, dict], wall_per_sim_s: float,
               workers=PROJECTED_WORKERS) -> dict[int, float]:
    """The whole matrix in OpenFAST on each of ``workers``: Σ over the groups of
    ⌈runs / W⌉ × one run's wall [s] (``plan``: wtftc.campaign.scorecard.matrix.plan)."""
    out = {}
    for w in workers:
        out[w] = sum(math.ceil(g["runs_per_column"] * g["columns"] / w)
                     * g["t_final_s"] * wall_per_sim_s for g in plan.values())
    return out


def summary(groups: dict[str, dict], openfast_rows: list[dict], plan: dict[str, dict],
            calls: dict[str, list[dict]]) -> dict:
    """scorecard.json's ``cost``: this card's wall over its calls, the OpenFAST rate it
    measured, and the whole matrix's projection at that rate."""
    walls = {g: sum(c["wall_s"] for c in calls.get(g, [])) for g in groups}
    measured = rate(openfast_rows)
    workers = sorted({c["workers"] for g in groups for c in calls.get(g, [])
                      if c.get("workers") is not None})
    out = {"card_wall_s": sum(walls.values()), "group_wall_s": walls,
           "call_workers": workers, "openfast": measured,
           "matrix_runs": sum(g["runs_per_column"] * g["columns"] for g in plan.values())}
    if measured is not None:
        out["projected_wall_s"] = projection(plan, measured["wall_per_simulated_s"])
    return out


def lines(cost: dict | None) -> list[str]:
    """The report's section: the card's wall, the measured rate, the projection."""
    if not cost:
        return []
    on = " and ".join(str(w) for w in cost["call_workers"]) or "an unrecorded number of"
    plural = "" if cost["call_workers"] == [1] else "s"
    out = ["", "## Wall time", "",
           f"This card: {cost['card_wall_s'] / 3600:.2f} h of wall over every call that "
           f"made it, on {on} worker{plural} (walls.json; a call's wall holds the TurbSim "
           "fields it made).", ""]
    of = cost.get("openfast")
    if of is None:
        return out + ["No OpenFAST run in this card: nothing to project the whole matrix "
                      "in OpenFAST from."]
    out += [f"Its {of['runs']} OpenFAST runs took {of['wall_per_simulated_s']:.3f} s of "
            f"wall per simulated second together ({of['wall_s']:.0f} s over "
            f"{of['simulated_s']:.0f} s simulated; single runs {of['run_min']:.2f}-"
            f"{of['run_max']:.2f} s/s), each run one OpenFAST process on one core beside "
            f"the card's other workers. Projected at that rate, not run: the whole matrix "
            f"in OpenFAST ({cost['matrix_runs']} runs, no --screen), each group's runs in "
            "rounds of as many as there are workers, a round as long as one run, the "
            "groups one after another, TurbSim fields aside:", "",
            "| workers | projected wall [h] |", "|---|---|"]
    out += [f"| {w} | {s / 3600:.2f} |" for w, s in cost["projected_wall_s"].items()]
    return out
