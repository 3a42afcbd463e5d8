"""`wtftc validate` (issue 33 item 1): its short form on one scenario, and its spectral
peak finder on a signal whose mode is known."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from wtftc.campaign import validate
from wtftc.cli import main
from wtftc.openfast import engine


def test_the_peak_finder_gives_a_known_modes_frequency_and_damping():
    """The impulse responses of a 1.7-Hz mode with ζ 3 %, restarted every 60 s with random
    amplitudes, sampled at 200 Hz for 1200 s: the peak within 1 % of 1.7 Hz (the 0.017-Hz
    bins of a 60-s segment), its half-power damping within 20 % of 3 % (measured 3.3 %: the
    Hann window widens it), and nothing found where the band holds no peak."""
    f0, zeta, dt = 1.7, 0.03, 0.005
    rng = np.random.default_rng(1)
    t = np.arange(0, 60, dt)
    wd = 2 * math.pi * f0 * math.sqrt(1 - zeta**2)
    burst = np.exp(-zeta * 2 * math.pi * f0 * t) * np.sin(wd * t)
    x = np.concatenate([rng.normal() * burst for _ in range(20)])
    f, p = validate.welch(x, dt)
    freq, z = validate.peak(f, p, 2.2)
    assert abs(freq / f0 - 1) < 0.01 and abs(z / zeta - 1) < 0.2, (freq, z)
    assert validate.peak(f, p, 12.0) == (None, None)  # 6-24 Hz: a falling tail, no peak


def test_validate_runs_both_engines_on_one_field_and_scores_them_alike(tmp_path):
    """The short form (ROSCO, NTM B 16 m/s, 20 s, seed 0): the three run folders, the
    figures, and validation.json whose OpenFAST values are OpenFAST's own output (the mean
    rotor speed after the start-up window from the .outb, to 1e-9), whose ratios are
    wtftc's over OpenFAST's, and whose native runs read the same TurbSim field as the
    OpenFAST run, rotor-effective and at the hub."""
    out = tmp_path / "val"
    assert main(["validate", "--controller", "rosco", "--t-final", "20", "--quiet",
                 "--out", str(out)]) == 0
    for name in ("openfast/metrics.json", "wtftc/metrics.json", "wtftc_hub/metrics.json",
                 "validation.json", "validation.md", "time_series.png", "spectra.pdf"):
        assert (out / name).is_file(), name
    doc = json.loads((out / "validation.json").read_text())
    t0 = doc["scenario"]["transient_s"]
    ch = engine.read_outb(next((out / "openfast" / "openfast").glob("*.outb")))
    keep = ch["Time"] >= t0 - 1e-9
    rpm_to_rad = math.pi / 30
    m = doc["metrics"]
    assert m["rotor_speed_mean"]["openfast"] == pytest.approx(
        np.mean(ch["RotSpeed"][keep]) * rpm_to_rad, rel=1e-6)
    for row in m.values():
        if row.get("ratio_wtftc") is not None:
            assert row["ratio_wtftc"] == pytest.approx(row["wtftc"] / row["openfast"])
            assert row["verdict"] == ("agrees" if abs(row["ratio_wtftc"] - 1) <=
                                      row["tolerance"] else "differs")
    # the same regime on both engines: mean speed and power within the means' tolerance
    assert m["rotor_speed_mean"]["verdict"] == "agrees" and m["power_mean"]["verdict"] == "agrees"
    winds = [json.loads((out / e / "metrics.json").read_text())["config"]["wind"]
             for e in ("wtftc", "wtftc_hub")]
    assert all(w["field"] == "turbsim" for w in winds)
    assert winds[0]["rotor_radius_m"] > 60 and winds[1]["rotor_radius_m"] == 0.0
    # the rotor's wind as the blades sample it, turning at rated speed (16 m/s is above rated)
    assert winds[0]["rotor_wind"] == "blades" and "rotor_wind" not in winds[1]
    assert winds[0]["blade_speed_rad_s"] == pytest.approx(1.26711)
    assert doc["scenario"]["rotor_wind"] == "blades"
    # wtftc's side ran the validated plant, with the blades' edgewise mode
    assert doc["scenario"]["plant"] == "tower_edge"
    # its modes: the drivetrain with the blades' edge (1.69 Hz), not the rigid rotor's 2.22
    assert doc["modes_wtftc_hz"]["drivetrain"] == pytest.approx(1.69, abs=0.01)
    assert json.loads((out / "wtftc" / "metrics.json").read_text())["config"]["plant"] \
        == "tower_edge"


def test_a_figure_that_is_zero_on_both_engines_agrees_without_a_ratio():
    """Below rated the pitch rests at fine pitch: OpenFAST's σ is round-off (1e-24 rad),
    wtftc's 0. No ratio, the verdict "both zero"; a real σ against OpenFAST's zero
    differs; a real pair is scored as before."""
    from wtftc.campaign.validate import compare_figures

    def runs(of, wt):
        return {"openfast": {"figures": {"pitch_std": ("std", of)}},
                "wtftc": {"figures": {"pitch_std": ("std", wt)}}}
    row = compare_figures(runs(4.4e-24, 0.0))["pitch_std"]
    assert row["ratio_wtftc"] is None and row["verdict"] == "both zero"
    assert compare_figures(runs(4.4e-24, 0.01))["pitch_std"]["verdict"] == "differs"
    row = compare_figures(runs(0.02, 0.019))["pitch_std"]
    assert row["ratio_wtftc"] == pytest.approx(0.95) and row["verdict"] == "agrees"


def test_validate_names_a_plant_without_a_tower_in_one_line(capsys):
    """--plant takes the plants with a tower; any other is one line naming the flag, before
    anything runs."""
    assert main(["validate", "--plant", "nrel5mw", "--out", "unused"]) == 2
    err = capsys.readouterr().err
    assert "--plant = 'nrel5mw'" in err and "tower, tower_edge" in err
    assert "Traceback" not in err
