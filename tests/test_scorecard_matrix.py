"""The scorecard's case matrix as data (wtftc.campaign.scorecard.matrix): checked, the
same runs for every controller, and the runs the kept campaign made."""

from pathlib import Path

import pyarrow.parquet as pq
import pytest

from wtftc.campaign.scorecard import matrix
from wtftc.campaign.sweep import spec
from wtftc.errors import ConfigError
from wtftc.model import turbine_file

ROOT = Path(__file__).resolve().parents[1]


def _runs(raw: dict) -> list[dict]:
    return spec.expand(spec.parse_sweep(raw))[0]


def test_the_shipped_matrix_is_checked_and_names_its_hash():
    m = matrix.load()
    assert set(m["groups"]) == {"normal_production", "actuator_faults"}
    h = matrix.matrix_hash(m)
    assert len(h) == 16 and h == matrix.matrix_hash(matrix.load())
    edited = {**m, "annual_mean_mps": 8.5}
    assert matrix.matrix_hash(matrix.check(edited, "edited")) != h


@pytest.mark.parametrize("turbine", list(turbine_file.BUILTIN))
def test_the_bins_run_from_cut_in_to_cut_out(turbine):
    t = turbine_file.load(turbine)
    b = matrix.bins(matrix.load(), t)
    assert b[0] - 1.0 == pytest.approx(t.cut_in_wind_mps) and b[-1] + 1.0 <= 25.0
    steps = [y - x for x, y in zip(b[:-1], b[1:], strict=True)]
    assert len(b) == 11 and steps == pytest.approx([2.0] * 10)


def test_every_controller_runs_the_same_scenarios():
    """The test bench's check: one matrix, identical for every column."""
    m = matrix.load()
    for raw in matrix.sweeps(m, ["aftc-nrel5mw", "pi", "rosco"], None, "wtftc",
                             seeds=2).values():
        runs = _runs(raw)
        by = {}
        for r in runs:
            key = tuple((k, v) for k, v in sorted(r.items())
                        if k not in ("run_id", "controller", "config"))
            by.setdefault(r["controller"], set()).add(key)
        assert len(by) == 3 and by["aftc-nrel5mw"] == by["pi"] == by["rosco"]


def test_the_groups_sizes_and_times():
    m = matrix.load()
    sw = matrix.sweeps(m, ["aftc-nrel5mw", "rosco"], None, "openfast", seeds=3)
    npp, faults = _runs(sw["normal_production"]), _runs(sw["actuator_faults"])
    assert len(npp) == 11 * 3 * 2  # bins × seeds × columns
    assert len(faults) == 4 * 3 * (4 + 2) * 2  # winds × seeds × (types, 2 runaways) × columns
    assert {r["config"]["t_final_s"] for r in npp} == {630.0}
    assert {r["onset_s"] for r in faults} == {40.0}
    # the shipped seeds without --seeds
    assert len(_runs(matrix.sweeps(m, ["rosco"], None, "openfast")["actuator_faults"])) \
        == 4 * 6 * 6


def test_its_fault_cases_are_the_kept_dlc21_campaigns_runs():
    """With 2 seeds the actuator faults are, run for run, the OpenFAST campaign kept in
    docs/campaigns/dlc21_openfast_obs3to45_nrel5mw (the same run ids)."""
    raw = matrix.sweeps(matrix.load(), ["aftc-nrel5mw", "rosco"], None, "openfast",
                        seeds=2)["actuator_faults"]
    mine = {r["run_id"] for r in _runs(raw)}
    kept = set(pq.read_table(ROOT / "docs" / "campaigns" / "dlc21_openfast_obs3to45_nrel5mw"
                             / "runs", columns=["run_id"]).column("run_id").to_pylist())
    assert mine == kept


@pytest.mark.parametrize("edit, field", [
    ({"typo": 1}, "typo"),
    ({"annual_mean_mps": 0.5}, "annual_mean_mps"),
    ({"turbulence_class": "Z"}, "turbulence_class"),
    ({"groups": {"normal_production": {"seeds": 0}}}, "groups.normal_production.seeds"),
    ({"groups": {"actuator_faults": {"types": ["lock", "gremlins"]}}},
     "groups.actuator_faults.types"),
    ({"groups": {"actuator_faults": {"onset_s": 95.0}}}, "groups.actuator_faults.onset_s"),
    ({"groups": {"actuator_faults": {"winds_mps": [50.0]}}},
     "groups.actuator_faults.winds_mps"),
    ({"groups": {"other": {}}}, "groups"),
    ({"start_up_s": 20.0}, "start_up_s"),
    ({"groups": {"actuator_faults": {"scored_s": 30.0}}}, "start_up_s"),
])
def test_a_refused_matrix_names_its_key(tmp_path, edit, field):
    m = matrix.load()
    for k, v in edit.items():
        if k == "groups":
            for g, tab in v.items():
                m["groups"][g] = {**m["groups"].get(g, {}), **tab}
        else:
            m[k] = v
    with pytest.raises(ConfigError) as exc:
        matrix.check(m, "edited.toml")
    assert exc.value.field == field and exc.value.where == "edited.toml"
