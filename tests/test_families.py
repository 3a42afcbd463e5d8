"""Tuned families (issue 18, docs/compare.md): ROSCO retuned through its DISCON.IN's gain
schedule, the [tuning] table resolved per controller, a sweep's tuning axes, the
trade-off summary and the DLC 2.1 extremes."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from wtftc import config
from wtftc.campaign import sweep, tune
from wtftc.campaign.sweep import dlc, tradeoff
from wtftc.errors import ConfigError
from wtftc.sim import rosco

ROOT = Path(__file__).resolve().parent.parent


def test_rosco_gains_follow_the_toolbox_formula():
    """From a schedule made by K_p = (2ζω + A)/B, K_i = ω²/B (ROSCO's second_order_PI) at
    (0.6, 0.7), retuning to (1.1, 0.9) gives the toolbox's own gains for that target."""
    a, b = np.array([0.05, -0.1, -0.4]), np.array([-40.0, -90.0, -190.0])

    def toolbox(w, z):
        return (2 * z * w + a) / b, w**2 / b

    kp, ki = rosco.retuned_gains(*toolbox(0.6, 0.7), (1.1, 0.9, 0.6, 0.7))
    want_kp, want_ki = toolbox(1.1, 0.9)
    assert kp == pytest.approx(want_kp, rel=1e-12)
    assert ki == pytest.approx(want_ki, rel=1e-12)


@pytest.mark.skipif(rosco.available() is not None, reason="needs ROSCO (make setup installs it)")
def test_the_private_discon_copy_carries_the_retuned_schedule(tmp_path):
    """The same target leaves the schedule as written (4 digits); doubling ω_n at the
    same ζ quadruples K_i; logging is off."""
    src = rosco.discon_path(rosco.NREL5MW_DISCON).read_text()

    def gains(text, key):
        line = next(ln for ln in text.splitlines()
                    if "!" in ln and ln.split("!", 1)[1].split()[0] == key)
        return np.array(line.split("!")[0].split(), float)

    same = rosco.discon_copy(tmp_path, retune=(0.6, 0.7, 0.6, 0.7)).read_text()
    fast = rosco.discon_copy(tmp_path, retune=(1.2, 0.7, 0.6, 0.7)).read_text()
    for key in ("PC_GS_KP", "PC_GS_KI"):
        assert gains(same, key) == pytest.approx(gains(src, key), rel=1e-9)
    assert gains(fast, "PC_GS_KI") == pytest.approx(4 * gains(src, "PC_GS_KI"), rel=1e-9)
    assert next(ln for ln in same.splitlines() if "LoggingLevel" in ln).startswith("0")


def test_tuning_resolves_into_each_controllers_own_settings():
    """ROSCO: its [rosco] target; PI: its own ω_n, ζ; physical: the (c1, c2, γ) that
    `wtftc turbine tune` gives for the same target."""
    target = {"omega_n_rad_s": 0.9, "zeta": 0.7}
    r = tune.resolve({"controller": "rosco", "tuning": target})
    assert r["rosco"] == {"omega_pc_rad_s": 0.9, "zeta_pc": 0.7} and "tuning" not in r
    r = tune.resolve({"controller": "pi", "tuning": target})
    assert r["controller_params"] == {"pi_omega_n": 0.9, "pi_zeta": 0.7}
    r = tune.resolve({"controller": "physical", "tuning": target})
    assert r["controller_params"] == tune.tune("physical", None, 0.9, 0.7, 16.0)["gains"]


@pytest.mark.parametrize("cfg, field", [
    ({"controller": "paper", "tuning": {"omega_n_rad_s": 0.6, "zeta": 0.7}}, "tuning"),
    ({"controller": "pi", "tuning": {"omega_n_rad_s": 20.0, "zeta": 0.7}},
     "tuning.omega_n_rad_s"),
    ({"controller": "pi", "tuning": {"omega_n_rad_s": 0.6}}, "tuning.zeta"),
    ({"controller": "physical", "tuning": {"omega_n_rad_s": 0.3, "zeta": 0.7}}, "tuning"),
])
def test_a_bad_tuning_is_refused_naming_the_key(cfg, field):
    with pytest.raises(ConfigError) as e:
        tune.resolve(cfg)
    assert e.value.field == field


@pytest.mark.parametrize("cfg, field", [
    ({"controller": "pi", "rosco": {"omega_pc_rad_s": 0.6}}, "rosco"),
    ({"controller": "rosco", "rosco": {"omega_pc_rad_s": 9.0}}, "rosco.omega_pc_rad_s"),
    ({"controller": "rosco", "rosco": {"omega": 0.6}}, "rosco"),
    ({"controller": "pi", "tuning": {"omega_n_rad_s": 0.6, "zeta": 0.7}}, "tuning"),
])
def test_bad_rosco_and_unresolved_tuning_tables_are_refused(cfg, field):
    with pytest.raises(ConfigError) as e:
        config.make_config(cfg)
    assert e.value.field == field


def test_a_run_config_with_rosco_carries_the_retune():
    rc = config.make_config({"controller": "rosco", "rosco": {"omega_pc_rad_s": 0.3}})
    assert rc.rosco_retune == (0.3, 0.7, 0.6, 0.7)


def _family(**over) -> sweep.Sweep:
    raw = {"mode": "grid", "t_final_s": 30.0, "controllers": ["rosco", "pi", "paper"],
           "wind": {"mean_mps": [12.0, 16.0]},
           "tuning": {"omega_n_rad_s": [0.3, 0.6, 1.2], "zeta": 0.7}} | over
    return sweep.parse_sweep(raw)


def test_a_tuning_axis_retunes_the_retunable_controllers_only():
    """3 targets × 2 winds for ROSCO and the PI; the paper's design, not retunable, once
    per wind (its runs would be identical: dropped as duplicates)."""
    runs, dup = sweep.expand(_family())
    by = {c: [r for r in runs if r["controller"] == c] for c in ("rosco", "pi", "paper")}
    assert len(by["rosco"]) == len(by["pi"]) == 6 and len(by["paper"]) == 2 and dup == 4
    assert {r["tuning_omega_n_rad_s"] for r in by["pi"]} == {0.3, 0.6, 1.2}
    assert all(r["config"]["tuning"]["zeta"] == 0.7 for r in by["rosco"])
    assert all("tuning" not in r["config"] and r["tuning_omega_n_rad_s"] is None
               for r in by["paper"])


def test_random_mode_crosses_every_scenario_with_every_target():
    sw = _family(mode="random", samples=4, wind={"mean_mps": {"min": 12.0, "max": 20.0}})
    runs, _ = sweep.expand(sw)
    pi = [r for r in runs if r["controller"] == "pi"]
    winds = {r["mean_wind_mps"] for r in pi}
    assert len(pi) == 12 and len(winds) == 4
    for w in winds:
        assert {r["tuning_omega_n_rad_s"] for r in pi if r["mean_wind_mps"] == w} == {
            0.3, 0.6, 1.2}


def test_sweeps_without_the_new_axes_keep_their_runs():
    """The tuning and runaway-target axes add nothing to a sweep without them: the random
    robustness campaign draws the same 1,560 runs with the same ids as before they
    existed (digest of its run ids taken at commit 5b5dae7)."""
    import hashlib

    runs, _ = sweep.expand(sweep.load_sweep(ROOT / "examples" / "robustness.toml"))
    digest = hashlib.sha256("".join(r["run_id"] for r in runs).encode()).hexdigest()[:16]
    assert len(runs) == 1560 and digest == "a8b8b20f95fdd8cd"
    assert all("tuning" not in r["config"] and r["tuning_omega_n_rad_s"] is None
               for r in runs)


def _row(c, w, fault="none", **m):
    base = {"controller": c, "tuning_omega_n_rad_s": w, "tuning_zeta": 0.7 if w else None,
            "status": "ok", "fault_type": fault, "runaway_target_deg": None}
    keys = [k for k, *_ in tradeoff.COLUMNS] + ["tower_base_max_abs_Nm"]
    return base | dict.fromkeys(keys) | m


def test_tradeoff_points_are_the_means_of_their_runs():
    rows = [_row("pi", 0.6, pitch_adc=0.1, overspeed_peak_over_rated=1.05),
            _row("pi", 0.6, pitch_adc=0.3, overspeed_peak_over_rated=1.10),
            _row("pi", 1.2, pitch_adc=0.5), _row("paper", None, pitch_adc=0.9),
            _row("pi", 0.6, fault="lock", pitch_adc=0.7)]
    free = tradeoff.points(rows, faulted=False)
    assert [p["omega_n"] for p in free["pi"]] == [0.6, 1.2]
    assert free["pi"][0]["pitch_adc"] == pytest.approx(0.2)
    assert free["pi"][0]["overspeed_peak_over_rated"] == 1.10 and free["pi"][0]["runs"] == 2
    assert free["paper"][0]["omega_n"] is None
    assert tradeoff.points(rows, faulted=True)["pi"][0]["pitch_adc"] == 0.7
    lines, csv = tradeoff.section(rows)
    assert len(csv) == 1 + 4 and any("| fault-free | pi | 0.6 | 0.7 | 2 |" in ln for ln in lines)


def test_dlc21_extremes_by_hand():
    """Held: not lost and never above the trip; runaways named by their direction."""
    rows = [_row("pi", None, "runaway", runaway_target_deg=0.0,
                 overspeed_peak_over_rated=1.25, shaft_torque_max_abs_Nm=6e6),
            _row("pi", None, "runaway", runaway_target_deg=0.0,
                 overspeed_peak_over_rated=1.10, shaft_torque_max_abs_Nm=5e6),
            _row("pi", None, "runaway", runaway_target_deg=90.0,
                 overspeed_peak_over_rated=1.02),
            _row("pi", None, "lock", status="diverged", overspeed_peak_over_rated=2.1),
            _row("pi", None, "none", overspeed_peak_over_rated=1.5)]
    ext = dlc.extremes(rows, 1.2)
    assert ext[("pi", "runaway_fine")] | {} == {
        "runs": 2, "lost": 0, "held": 1, "overspeed_peak_over_rated": 1.25,
        "shaft_torque_max_abs_Nm": 6e6, "tower_base_max_abs_Nm": None}
    assert ext[("pi", "runaway_feather")]["held"] == 1
    assert ext[("pi", "lock")]["lost"] == 1 and ext[("pi", "lock")]["held"] == 0
    assert ("pi", "none") not in ext
    lines, csv = dlc.fault_section(rows, {"case": "2.1"})
    assert any(ln.startswith("| pi | runaway_fine | 2 | 0 | 1 | 1.250 | 6.00 |")
               for ln in lines)
    assert math.isclose(dlc.parse_dlc({"case": "2.1"})["overspeed_trip"], 1.2)


def test_the_c2_ratio_is_a_setting_of_the_procedure():
    """[tuning] c2_over_c1 reaches every run's table; the physical AFTC's c2 follows it,
    the default being the revised 2 (issue 18)."""
    sw = _family(controllers=["physical-plain"], tuning={"omega_n_rad_s": 0.9, "zeta": 0.7,
                                                   "c2_over_c1": 3.0})
    runs, _ = sweep.expand(sw)
    assert {r["config"]["tuning"]["c2_over_c1"] for r in runs} == {3.0}
    three = tune.resolve(runs[0]["config"])["controller_params"]
    two = tune.resolve({"controller": "physical", "tuning": {"omega_n_rad_s": 0.9,
                                                             "zeta": 0.7}})
    assert three["phys_c2"] == pytest.approx(3 * three["phys_c1"], rel=1e-12)
    assert two["controller_params"]["phys_c2"] == pytest.approx(
        2 * two["controller_params"]["phys_c1"], rel=1e-12)
    with pytest.raises(ConfigError, match="c2_over_c1"):
        _family(tuning={"omega_n_rad_s": 0.9, "zeta": 0.7, "c2_over_c1": 0.5})


def test_the_design_wind_is_used_and_a_bad_rosco_tuning_is_refused(tmp_path):
    """The physical AFTC's gains follow [tuning] design_wind_mps; a turbine file whose
    rosco_tuning is not the two positive numbers is refused naming the key."""
    at16, at20 = (tune.resolve({"controller": "physical", "tuning": {
        "omega_n_rad_s": 0.9, "zeta": 0.7, "design_wind_mps": w}})["controller_params"]
        for w in (16.0, 20.0))
    assert at16["phys_c1"] != pytest.approx(at20["phys_c1"], rel=1e-3)
    from wtftc.model import turbine_file

    src = Path(turbine_file.load("nrel5mw").path)
    text = src.read_text().replace("zeta_pc = 0.7 }", "zeta_pc = -0.7 }")
    (tmp_path / src.name).write_text(text)
    (tmp_path / "Cp_Ct_Cq.NREL5MW.txt").write_bytes(
        Path(turbine_file.load("nrel5mw").cp_path).read_bytes())
    with pytest.raises(ConfigError) as e:
        turbine_file.read(tmp_path / src.name)
    assert e.value.field == "rosco_tuning"
