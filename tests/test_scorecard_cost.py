"""A scorecard's wall time and the whole matrix's projection in OpenFAST
(wtftc.campaign.scorecard.cost): the rate by hand, the rounds of the projection by hand,
and the section on the committed NREL 5-MW card, whose OpenFAST runs it reads."""

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from wtftc.campaign.scorecard import cost, matrix, report

CARD = Path(__file__).resolve().parents[1] / "results" / "scorecard_nrel5mw"


def wtftc(*args):
    return subprocess.run([sys.executable, "-m", "wtftc.cli", *map(str, args)],
                          capture_output=True, text=True)


def _row(status, wall, t_final, stopped=None):
    return {"status": status, "wall_s": wall, "diverged_at_s": stopped,
            "config_json": json.dumps({"t_final_s": t_final})}


def test_rate_is_wall_over_simulated_seconds_of_the_runs_that_ran():
    rows = [_row("ok", 60.0, 120.0), _row("diverged", 10.0, 120.0, stopped=40.0),
            _row("failed", 500.0, 120.0), _row("ok", None, 120.0)]
    got = cost.rate(rows)
    assert (got["runs"], got["wall_s"], got["simulated_s"]) == (2, 70.0, 160.0)
    assert got["wall_per_simulated_s"] == 70.0 / 160.0
    assert (got["run_min"], got["run_max"]) == (0.25, 0.5)
    assert cost.rate([_row("failed", 5.0, 10.0)]) is None


def test_projection_runs_each_group_in_rounds_of_the_workers():
    """Group a: 2 columns × 3 runs of 100 s; group b: 1 run of 50 s; 0.5 s of wall a
    simulated second: 6 × 50 + 25 on one worker, 3 × 50 + 25 on two, 2 × 50 + 25 on
    four (⌈6/4⌉ = 2 rounds), one round each from six on."""
    plan = {"a": {"runs_per_column": 3, "columns": 2, "t_final_s": 100.0},
            "b": {"runs_per_column": 1, "columns": 1, "t_final_s": 50.0}}
    assert cost.projection(plan, 0.5, (1, 2, 4, 6, 100)) == {
        1: 325.0, 2: 175.0, 4: 125.0, 6: 75.0, 100: 75.0}


def test_a_card_without_openfast_runs_projects_nothing():
    plan = {"a": {"runs_per_column": 1, "columns": 2, "t_final_s": 10.0}}
    got = cost.summary({"a": {}}, [], plan, {"a": [{"wall_s": 7.0, "workers": 2}]})
    assert got["card_wall_s"] == 7.0 and got["openfast"] is None
    assert "projected_wall_s" not in got
    assert any("nothing to project" in line for line in cost.lines(got))


def test_the_committed_card_reports_its_wall_and_projection():
    """results/scorecard_nrel5mw: its wall is the sum of every call's in walls.json, its
    rate is over its OpenFAST confirmation runs (the <group>_openfast folders), and the
    projection covers every run of the matrix at 6 seeds; its scorecard.json holds the
    same figures (read back from JSON, where the worker counts are strings)."""
    calls = json.loads((CARD / "walls.json").read_text())
    result = {"matrix": matrix.load(), "screen": 1, "engine": "openfast", "seeds": 6,
              "groups": {g: {"wall_s": c[-1]["wall_s"], "calls_wall_s": c}
                         for g, c in calls.items()}}
    got = report._wall(CARD, result, "nrel5mw")
    assert got["card_wall_s"] == pytest.approx(
        sum(c["wall_s"] for cs in calls.values() for c in cs), rel=1e-12)
    plan = matrix.plan(matrix.load(), "nrel5mw", 6)
    assert got["matrix_runs"] == sum(g["runs_per_column"] * g["columns"]
                                     for g in plan.values())
    of = got["openfast"]
    folders = [p for p in CARD.iterdir() if p.name.endswith("_openfast")]
    assert of["runs"] == sum(r["status"] in ("ok", "diverged") and r["wall_s"] is not None
                             for p in folders for r in report._rows(CARD, p.name))
    assert of["run_min"] <= of["wall_per_simulated_s"] <= of["run_max"]
    # an OpenFAST run of the NREL 5-MW: 0.2-1 s of wall a simulated second on one core
    assert 0.2 < of["wall_per_simulated_s"] < 1.0
    proj = got["projected_wall_s"]
    assert proj[1] >= proj[2] >= proj[100] > 0
    assert proj[1] == pytest.approx(2 * proj[2], rel=0.01)  # rounds of two: ~half
    assert proj[100] >= max(g["t_final_s"] for g in plan.values()) \
        * of["wall_per_simulated_s"]
    kept = json.loads((CARD / "scorecard.json").read_text())["cost"]
    assert kept["openfast"]["runs"] == of["runs"]
    assert {int(w): s for w, s in kept["projected_wall_s"].items()} == pytest.approx(proj)
    assert math.isclose(kept["card_wall_s"], got["card_wall_s"], rel_tol=1e-12)


def test_the_plan_prices_a_card_at_its_own_rate():
    """`wtftc scorecard --plan --out CARD`: the rate is the one the card's OpenFAST runs
    measured (the report's), and the hours are the projection on --workers at it; without
    a card, the NREL 5-MW's planning rate. Nothing is written into the card."""
    before = sorted(p.name for p in CARD.iterdir())
    measured = cost.measured_in(CARD)
    kept = json.loads((CARD / "scorecard.json").read_text())["cost"]["openfast"]
    assert measured["runs"] == kept["runs"]
    assert measured["wall_per_simulated_s"] == pytest.approx(
        kept["wall_per_simulated_s"], rel=1e-12)
    p = wtftc("scorecard", "--plan", "--turbine", "nrel5mw", "--seeds", 6, "--workers", 3,
              "--out", CARD)
    assert p.returncode == 0, p.stderr
    hours = cost.projection(matrix.plan(matrix.load(), "nrel5mw", 6),
                            measured["wall_per_simulated_s"], (3,))[3] / 3600
    assert f"at {measured['wall_per_simulated_s']:.3g} s of wall" in p.stdout
    assert f"about {hours:.1f} h on 3 workers" in p.stdout
    assert sorted(p.name for p in CARD.iterdir()) == before
    q = wtftc("scorecard", "--plan", "--turbine", "nrel5mw", "--workers", 2)
    assert f"at {matrix.OPENFAST_WALL_PER_SIM_S:.3g} s of wall" in q.stdout


def test_the_plan_refuses_another_turbines_card_and_reads_no_other_folder(tmp_path):
    p = wtftc("scorecard", "--plan", "--turbine", "iea15mw", "--out", CARD)
    assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
    assert p.stderr.startswith("wtftc: error: --out") and "nrel5mw" in p.stderr
    (tmp_path / "mine" / "runs").mkdir(parents=True)  # a folder, not a card's
    q = wtftc("scorecard", "--plan", "--out", tmp_path)
    assert q.returncode == 0 and f"no OpenFAST run of a card in {tmp_path}" in q.stdout
