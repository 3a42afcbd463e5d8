"""Each preset's standing against ROSCO (wtftc.campaign.standing): the committed page is
what the campaign folders make, and the statistics are those a hand computation gives."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from wtftc import controller
from wtftc.campaign import standing
from wtftc.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]
#: t_{0.975} at 4 degrees of freedom (any Student's t table: 2.776)
T_975_4 = 2.7764451051977987


def test_committed_page_is_what_the_folders_make():
    """docs/standing.md, made again from docs/campaigns/, text for text. The numbers are
    written to 3 significant digits: a last-bit difference of another CPU's log or sum
    (about 1e-16 of a value) cannot move a 3-digit number unless the value lies within
    that of a rounding edge, so the text is the same on any machine."""
    made = standing.markdown(standing.standing(standing.default_folders()))
    kept = (ROOT / "docs" / "standing.md").read_text(encoding="utf-8")
    assert made == kept, ("docs/standing.md is stale: run `wtftc presets --standing --out "
                          "docs/standing.md`")


def test_campaign_columns_resolve_to_their_presets():
    """The folders' former names stand for the presets the page names them by."""
    assert standing.preset_of(controller.lookup("physical_obs3to45_ps_td_ct_fdi")) \
        == "aftc-nrel5mw"
    assert standing.preset_of(controller.lookup("rosco")) == "rosco"
    assert standing.preset_of(controller.lookup("rosco_matched")) == "rosco-matched"
    assert standing.preset_of(controller.lookup("pi_lpf_ps")) is None  # a table tried
    # the former IEA 15-MW name: its target mode where the preset has the gains solved
    # from it; every other setting the same
    former = controller.lookup("physical_obs15_w04_ps_ct_fdi")
    name, _ = standing.STANDS_FOR["physical_obs15_w04_ps_ct_fdi"]
    p = controller.preset(name)
    gains = ("phys_c1", "phys_c2", "phys_gamma")
    assert dict(former.tuning) == {"omega_n_rad_s": 0.4, "zeta": 0.85} and not p.tuning
    assert {k: v for k, v in p.params if k not in gains} == dict(former.params)
    assert (former.design, former.accommodation) == (p.design, p.accommodation)
    assert former.run_keys(True, True)["turbine_params"] \
        == p.run_keys(True, True)["turbine_params"]
    assert standing.preset_of(former) is None  # hence the named exception


def test_t_quantile_matches_scipy():
    for df in range(1, 201):
        for p in (0.6, 0.9, 0.975, 0.995):
            assert standing.t_quantile(p, df) == pytest.approx(stats.t.ppf(p, df),
                                                               rel=1e-9)


def _run(controller: str, wind: float, seed: int, **kw) -> dict:
    return {"run_id": f"{controller}-{wind}-{seed}", "controller": controller,
            "plant": "openfast", "mean_wind_mps": wind, "turbulence_class": "B",
            "seed": seed, "fault_type": "none", "blade": None, "onset_s": None,
            "runaway_target_deg": None, "status": "ok",
            "overspeed_peak_over_rated": 1.05, "rms_speed_error_rad_s": 0.1,
            "shaft_torque_del_1hz_Nm": 1e6, "tower_base_del_1hz_Nm": 1e7, "pitch_adc": 0.2,
            **kw}


def _folder(tmp_path: Path, runs: list[dict], name: str = "camp") -> Path:
    import pyarrow as pa
    import pyarrow.parquet as pq

    folder = tmp_path / name
    (folder / "runs").mkdir(parents=True)
    (folder / "sweep.json").write_text(json.dumps({
        "sweep": {"engine": "openfast", "turbine": "nrel5mw", "dlc": {"case": "1.2"}},
        "versions": {"generated_code_sha256": "0123456789abcdef"}}))
    # every row has every key: from_pylist takes its columns from the first row
    pq.write_table(pa.Table.from_pylist(runs), folder / "runs" / "part-0123456789abcdef.parquet")
    return folder


#: the preset's ratios to ROSCO on five scenarios: speed error lower on all, shaft DEL
#: either way, tower DEL 1.2 on every one
RMS = [0.8, 0.9, 0.85, 0.7, 0.95]
SHAFT = [0.9, 1.1, 1.0, 0.95, 1.05]


def _pairs_of_five() -> list[dict]:
    runs = []
    for i, (r_rms, r_shaft) in enumerate(zip(RMS, SHAFT, strict=True)):
        wind, seed = 12.0 + 2 * (i % 3), i // 3
        ref = _run("rosco", wind, seed, rms_speed_error_rad_s=0.1 + 0.01 * i,
                   shaft_torque_del_1hz_Nm=1e6 * (1 + i), pitch_adc=0.3 if i else 0.0)
        runs += [ref, _run("aftc-nrel5mw", wind, seed,
                           rms_speed_error_rad_s=r_rms * ref["rms_speed_error_rad_s"],
                           shaft_torque_del_1hz_Nm=r_shaft * ref["shaft_torque_del_1hz_Nm"],
                           tower_base_del_1hz_Nm=1.2e7, pitch_adc=0.6 if i else 0.0)]
    return runs


def _hand(ratios: list[float]) -> tuple[float, float, float]:
    """The geometric mean and the 95 % interval, by the textbook's formula."""
    logs = [math.log(r) for r in ratios]
    n = len(logs)
    mean = sum(logs) / n
    sd = math.sqrt(sum((x - mean) ** 2 for x in logs) / (n - 1))
    half = T_975_4 * sd / math.sqrt(n)
    return math.exp(mean), math.exp(mean - half), math.exp(mean + half)


def test_statistics_against_a_hand_computation(tmp_path):
    rows = standing.standing([_folder(tmp_path, _pairs_of_five())])
    assert [(r["preset"], r["faults"]) for r in rows] == [("aftc-nrel5mw", "none")]
    row = rows[0]
    assert (row["scenarios"], row["both_held"], row["lost_by_preset"],
            row["lost_by_reference"], row["seeds"], row["winds"]) == (5, 5, 0, 0, 2, 3)
    assert (row["engine"], row["turbine"], row["code"]) == ("openfast", "nrel5mw",
                                                            "0123456789abcdef")
    m = row["metrics"]
    for key, ratios, verdict in (("rms_speed_error_rad_s", RMS, "lower"),
                                 ("shaft_torque_del_1hz_Nm", SHAFT, "tie")):
        ratio, low, high = _hand(ratios)
        assert (m[key]["n"], m[key]["verdict"]) == (5, verdict)
        np.testing.assert_allclose([m[key]["ratio"], m[key]["low"], m[key]["high"]],
                                   [ratio, low, high], rtol=1e-12)
    assert SHAFT and _hand(SHAFT)[1] < 1.0 < _hand(SHAFT)[2]  # the tie is the interval's
    assert m["tower_base_del_1hz_Nm"]["verdict"] == "higher"
    assert m["tower_base_del_1hz_Nm"]["ratio"] == pytest.approx(1.2, rel=1e-12)
    # the pitch ADC at 0 on both sides is left out of that metric only, and counted
    assert (m["pitch_adc"]["n"], m["pitch_adc"]["zero_both"]) == (4, 1)
    assert m["pitch_adc"]["ratio"] == pytest.approx(2.0, rel=1e-12)


def test_unpaired_scenario_left_out_and_lost_runs_counted(tmp_path):
    runs = _pairs_of_five()
    runs.append(_run("aftc-nrel5mw", 24.0, 0, rms_speed_error_rad_s=9.0))  # no ROSCO twin
    runs += [_run("rosco", 20.0, 0), _run("aftc-nrel5mw", 20.0, 0, status="diverged",
                                          rms_speed_error_rad_s=9.0)]
    runs += [_run("rosco", 20.0, 1, overspeed_peak_over_rated=1.3),  # past the trip
             _run("aftc-nrel5mw", 20.0, 1, rms_speed_error_rad_s=9.0)]
    runs += [_run("rosco", 22.0, 1), _run("aftc-nrel5mw", 22.0, 1, status="failed")]
    (row,) = standing.standing([_folder(tmp_path, runs)])
    assert (row["scenarios"], row["failed"], row["both_held"], row["lost_by_preset"],
            row["lost_by_reference"]) == (8, 1, 5, 1, 1)
    ratio, low, high = _hand(RMS)  # the five both held, nothing else
    assert row["metrics"]["rms_speed_error_rad_s"]["ratio"] == pytest.approx(ratio,
                                                                             rel=1e-12)


def test_faults_grouped_and_page_written(tmp_path):
    runs = _pairs_of_five()
    for f in ("lock", "runaway"):
        for seed in (0, 1):
            runs += [_run("rosco", 16.0, seed, fault_type=f, blade=1, onset_s=50.0,
                          runaway_target_deg=90.0),
                     _run("aftc-nrel5mw", 16.0, seed, fault_type=f, blade=1, onset_s=50.0,
                          runaway_target_deg=90.0, rms_speed_error_rad_s=0.05 + 0.01 * seed)]
    folder = _folder(tmp_path, runs)
    rows = standing.standing([folder])
    assert [(r["faults"], r["scenarios"]) for r in rows] == [
        ("none", 5), ("any", 4), ("lock", 2), ("runaway_feather", 2)]
    out = tmp_path / "page" / "standing.md"
    out.parent.mkdir()
    text = standing.main([folder], out)
    assert out.read_text(encoding="utf-8") == text
    assert "(../camp/)" in text and f"wtftc presets --standing {folder} --out {out}" in text
    assert "NREL 5-MW" in text and "any fault" in text and "runaway_feather" in text


def test_a_folder_without_a_sweep_is_refused(tmp_path):
    with pytest.raises(ConfigError, match="--standing.*sweep.json"):
        standing.standing([tmp_path])


def test_presets_standing_writes_whole_and_refuses_a_users_file(tmp_path):
    import subprocess
    import sys

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "wtftc.cli", "presets", "--standing",
                               *map(str, args)], capture_output=True, text=True, cwd=ROOT)

    mine = tmp_path / "notes.md"
    mine.write_text("my notes\n")
    p = cli("--out", mine)
    assert p.returncode == 2 and "--out" in p.stderr and mine.read_text() == "my notes\n"
    page = tmp_path / "standing.md"
    assert cli("--out", page).returncode == 0
    assert cli("--out", page).returncode == 0  # its own page is replaced
    assert page.read_text().startswith("# Each preset against ROSCO, measured\n")
    p = cli()
    assert p.returncode == 0
    assert p.stdout == (ROOT / "docs" / "standing.md").read_text(encoding="utf-8")


def test_a_file_among_the_folders_is_one_line(tmp_path):
    import subprocess
    import sys

    p = subprocess.run([sys.executable, "-m", "wtftc.cli", "presets", "--standing",
                        str(ROOT / "docs" / "campaigns" / "README.md")],
                       capture_output=True, text=True)
    assert p.returncode == 2 and p.stderr.count("\n") == 1
    assert "--standing = " in p.stderr and "README.md" in p.stderr
