"""The README's table of the committed scorecards (wtftc.campaign.scorecard.headline):
made from results/*/scorecard.json by `make headline`, never typed."""

import json
from pathlib import Path

import pytest

from wtftc.campaign.scorecard import headline

ROOT = Path(__file__).resolve().parent.parent


def test_the_readmes_table_is_what_the_committed_cards_make():
    readme = ROOT / "README.md"
    assert headline.main(readme, ROOT / "results") == readme.read_text("utf-8"), \
        "run `make headline`"
    for folder, doc in headline.cards(ROOT / "results"):
        assert f"[`results/{folder.name}`](results/{folder.name}/scorecard.md)" in \
            readme.read_text("utf-8")
        assert doc["baseline"] == "rosco"


def card(tmp: Path, name: str, turbine: str, ratio: float, low, high, verdict: str) -> None:
    (tmp / name).mkdir()
    doc = {"controller": f"aftc-{turbine}", "baseline": "rosco", "turbine": turbine,
           "screen": 1, "generated_code_sha256": "abc", "groups": {
               "normal_production": {"metrics": [
                   {"metric": "pitch_adc", "what": "pitch duty", "unit": "-",
                    "ratio": ratio, "low": low, "high": high, "verdict": verdict}]},
               "deterministic": {"metrics": [
                   {"metric": "pitch_adc", "what": "pitch duty", "unit": "-",
                    "ratio": 9.0, "low": None, "high": None, "verdict": "x"}]}}}
    (tmp / name / "scorecard.json").write_text(json.dumps(doc))


def test_each_card_is_a_column_and_a_tie_is_called_one(tmp_path):
    card(tmp_path, "scorecard_a", "nrel5mw", 0.8, 0.7, 0.9, "better")
    card(tmp_path, "scorecard_b", "iea15mw", 1.02, 0.95, 1.1, "tie")
    text = headline.table(headline.cards(tmp_path), tmp_path)
    assert "| group | metric | nrel5mw | iea15mw |" in text
    assert "| normal_production | pitch duty [-] | 0.8 (0.7–0.9) better | " \
           "1.02 (0.95–1.1) **tie** |" in text
    assert "deterministic" not in text  # a group without seeds is not in the headline
    assert "OpenFAST" not in text.split("| group |")[1]  # nothing confirmed, nothing said
    assert "[`scorecard_a`](scorecard_a/scorecard.md): `aftc-nrel5mw` against `rosco`" in text


def test_a_readme_without_its_markers_is_refused():
    with pytest.raises(ValueError, match="results:begin"):
        headline.with_table("no markers", "x")
    assert headline.table([], ROOT).startswith("No scorecard is committed yet")


def test_a_confirmed_verdict_carries_openfasts_ratio_and_whether_it_agrees(tmp_path):
    card(tmp_path, "scorecard_a", "nrel5mw", 0.8, 0.7, 0.9, "better")
    doc = json.loads((tmp_path / "scorecard_a" / "scorecard.json").read_text())
    doc["groups"]["normal_production"]["confirmed"] = {"metrics": [
        {"metric": "pitch_adc", "ratio": 1.31, "low": 1.1, "high": 1.5, "n_pairs": 4,
         "verdict": "not enough seeds", "agree": "disagrees", "screen_ratio": 0.92}]}
    (tmp_path / "scorecard_a" / "scorecard.json").write_text(json.dumps(doc))
    text = headline.table(headline.cards(tmp_path), tmp_path)
    assert "| normal_production | pitch duty [-] | 0.8 (0.7–0.9) better; OpenFAST over 4 " \
           "confirmed: 1.31 (1.1–1.5) not enough seeds, screen 0.92 there " \
           "(**disagrees**) |" in text
