"""The ranking agreement of two engines (wtftc.campaign.ranking, issue 33 item 4) on
hand-made metric tables: the same order, one swapped pair, a tie within the tolerance,
a lost run, and the compare tree it reads."""

import json

import pytest

from wtftc.campaign import ranking

RMS = "rms_speed_error_rad_s"
TOL = ranking.Tolerance(0.05, 0.0)


def _table(**scenarios):
    """{scenario: {controller: {RMS: value}}} from {scenario: {controller: value}}."""
    return {s: {c: {RMS: v} for c, v in cells.items()} for s, cells in scenarios.items()}


def test_the_same_order_agrees_with_tau_one():
    r = ranking.compare_orders({"a": 1.0, "b": 2.0, "c": 3.0}, {"a": 10.0, "b": 20.0, "c": 40.0},
                               TOL)
    assert r["order_a"] == r["order_b"] == ["a", "b", "c"]
    assert (r["concordant"], r["discordant"], r["tied"], r["missing"]) == (3, 0, 0, 0)
    assert r["agree"] and r["kendall_tau"] == 1.0 and r["swapped"] == []


def test_one_swapped_pair_disagrees_and_is_named_with_its_values():
    r = ranking.compare_orders({"a": 1.0, "b": 2.0, "c": 3.0}, {"a": 1.0, "b": 3.0, "c": 2.0},
                               TOL)
    assert r["order_b"] == ["a", "c", "b"]
    assert (r["concordant"], r["discordant"]) == (2, 1) and not r["agree"]
    assert r["kendall_tau"] == pytest.approx(1 / 3)
    assert r["swapped"] == [{"pair": ["b", "c"], "a": [2.0, 3.0], "b": [3.0, 2.0]}]


def test_a_tie_within_the_tolerance_counts_as_agreement():
    # b and c swap, but on engine b they differ by 2 % (< 5 %): a tie, not a swap
    r = ranking.compare_orders({"a": 1.0, "b": 2.0, "c": 3.0}, {"a": 1.0, "b": 3.06, "c": 3.0},
                               TOL)
    assert (r["concordant"], r["discordant"], r["tied"]) == (2, 0, 1)
    assert r["agree"] and r["kendall_tau"] == pytest.approx(2 / 3)
    # the same 2 % outside a tighter tolerance is a swap
    tight = ranking.compare_orders({"b": 2.0, "c": 3.0}, {"b": 3.06, "c": 3.0},
                                   ranking.Tolerance(0.01, 0.0))
    assert tight["discordant"] == 1 and not tight["agree"]
    # the absolute floor: two near-zero values tie
    assert ranking.sign(0.001, 0.003, ranking.Tolerance(0.05, 0.005)) == 0


def test_a_lost_run_is_left_out_and_ranked_last():
    r = ranking.compare_orders({"a": 1.0, "b": None, "c": 3.0},
                               {"a": 1.0, "b": 2.0, "c": float("nan")}, TOL)
    assert r["order_a"] == ["a", "c", "b"] and r["order_b"] == ["a", "b", "c"]
    assert (r["missing"], r["concordant"]) == (3, 0) and r["kendall_tau"] is None
    assert r["agree"]


def test_the_table_summary_and_markdown():
    a = _table(s1={"a": 1.0, "b": 2.0, "c": 3.0}, s2={"a": 1.0, "b": 2.0, "c": 3.0},
               only_a={"a": 1.0})
    b = _table(s1={"a": 1.0, "b": 2.0, "c": 3.0}, s2={"a": 2.0, "b": 1.0, "c": 3.0})
    rows = ranking.agreement_table(a, b, metrics=[RMS])
    assert [r["scenario"] for r in rows] == ["s1", "s2"]  # the scenarios of both
    s = ranking.summary(rows)[RMS]
    assert (s["agree"], s["scenarios"], s["swapped"], s["pairs"]) == (1, 2, 1, 6)
    assert s["mean_tau"] == pytest.approx((1 + 1 / 3) / 2)
    assert "| RMS speed error | 5% or 0.0001 | 1 / 2 | 1 / 6 | 0.67 |" \
        in ranking.summary_markdown(rows)
    md = ranking.rows_markdown(rows, "wtftc", "OpenFAST")
    assert "| RMS speed error | s2 | a < b < c | b < a < c | 0.33 | a vs b: 1 / 2; 2 / 1 |" in md


def test_order_text_marks_ties_and_missing_values():
    values = {"a": 3.0, "b": 1.0, "c": 1.04, "d": None}
    assert ranking.order_text(values, TOL) == "b ≈ c < a; no value: d"
    r = ranking.compare_orders(values, values, TOL)
    assert r["text_a"] == r["text_b"] == "b ≈ c < a; no value: d"


def test_read_compare_reads_the_finished_cells(tmp_path):
    for tree, wind, fault, ctrl, v in [("t1", "ntm_B_8", "none", "pi", 0.1),
                                       ("t1", "ntm_B_8", "none", "rosco", 0.2),
                                       ("t2", "ntm_B_16", "runaway", "pi", 0.3)]:
        d = tmp_path / tree / wind / fault / ctrl
        d.mkdir(parents=True)
        (d / "metrics.json").write_text(json.dumps({RMS: v}))
    (tmp_path / "t2" / "ntm_B_16" / "runaway" / "rosco").mkdir()  # not finished
    table = ranking.read_compare([tmp_path / "t1", tmp_path / "t2"])
    assert table == {"ntm_B_8/none": {"pi": {RMS: 0.1}, "rosco": {RMS: 0.2}},
                     "ntm_B_16/runaway": {"pi": {RMS: 0.3}}}


def test_a_tuned_column_runs_at_its_target():
    """A column's target mode (the ranking matrix's second tuning, a table's omega_n_rad_s
    and zeta) becomes the controller's own settings; the plant is the one asked for."""
    import importlib.util
    from pathlib import Path

    from wtftc.campaign import compare

    path = Path(__file__).resolve().parent.parent / "examples" / "ranking_matrix.py"
    spec = importlib.util.spec_from_file_location("ranking_matrix", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    cols = compare.resolve_columns(example.CONTROLLERS)
    assert list(cols) == ["rosco", "pi", "physical_fdi", "rosco_fast", "pi_fast",
                          "physical_fdi_fast"]
    rosco = compare.cell_config("rosco_fast", "none", "ntm_B_16", 30.0, 1e-3, 0,
                                plant="tower_edge", ctrl=cols["rosco_fast"])
    assert rosco["rosco"] == {"omega_pc_rad_s": 0.9, "zeta_pc": 0.7} and "tuning" not in rosco
    assert rosco["plant"] == "tower_edge"
    pi = compare.cell_config("pi_fast", "runaway", "ntm_B_16", 30.0, 1e-3, 0,
                             engine="openfast", ctrl=cols["pi_fast"])
    assert pi["controller_params"] == {"pi_omega_n": 0.9, "pi_zeta": 0.7}
    assert pi["engine"] == "openfast" and "plant" not in pi
    assert "controller_params" not in compare.cell_config("pi", "none", "ntm_B_16", 30.0,
                                                          1e-3, 0)
    phys = compare.cell_config("physical_fdi_fast", "lock", "ntm_B_16", 30.0, 1e-3, 0,
                               ctrl=cols["physical_fdi_fast"])
    assert phys["case"] == 4 and {"phys_c1", "phys_gamma"} <= set(phys["controller_params"])


def test_values_markdown_joins_the_engines():
    a = _table(s1={"a": 1.0, "b": 2.0})
    b = _table(s1={"a": 3.0})
    md = ranking.values_markdown({"x": a, "y": b}, RMS, fmt="{:.1f}")
    assert md.splitlines()[0] == "| scenario | a | b |"
    assert md.splitlines()[2] == "| s1 | 1.0 / 3.0 | 2.0 / — |"
