"""`wtftc compare`: a small matrix end to end, cells re-runnable alone, bad input refused."""

import json
import subprocess
import sys

import numpy as np
import pytest

from wtftc.errors import ConfigError


def wtftc(*args):
    return subprocess.run([sys.executable, "-m", "wtftc.cli", *map(str, args)],
                          capture_output=True, text=True)


def test_small_matrix_and_a_cell_re_run_alone(tmp_path):
    out = tmp_path / "cmp"
    p = wtftc("compare", "--out", out, "--controllers", "physical_fdi", "pi", "--faults",
              "none", "loss_of_effectiveness", "--winds", "ntm_B_16", "--t-final", 30,
              "--quiet")
    assert p.returncode == 0, p.stderr
    lines = (out / "compare.csv").read_text().splitlines()
    assert len(lines) == 1 + 4 and lines[0].startswith("wind,fault,controller")
    assert (out / "compare.png").exists() and (out / "compare.md").exists()
    cell = out / "ntm_B_16" / "loss_of_effectiveness" / "physical_fdi"
    m = json.loads((cell / "metrics.json").read_text())
    assert m["case"] == 4 and m["fdi"]["isolation_correct"]
    # the matrix is on the tower plant, in the wind averaged over the 63-m rotor disk
    assert m["plant"] == "tower" and m["tower_base_del_1hz_Nm"] > 0
    assert "tower-base DEL" in (out / "compare.md").read_text()
    again = tmp_path / "again"
    p2 = wtftc("run", "--config", cell / "config.toml", "--out", again, "--quiet")
    assert p2.returncode == 0, p2.stderr
    m2 = json.loads((again / "metrics.json").read_text())
    assert np.isclose(m2["rms_speed_error_rad_s"], m["rms_speed_error_rad_s"], rtol=1e-12)


def test_the_matrix_runs_on_the_plant_it_is_given(tmp_path):
    """--plant tower_edge: the cells run on the plant with the blades' edgewise mode, whose
    drivetrain mode (1.69 Hz, docs/validation.md) the shaft torque carries."""
    out = tmp_path / "edge"
    p = wtftc("compare", "--out", out, "--controllers", "pi", "--faults", "none", "--winds",
              "ntm_B_16", "--t-final", 30, "--plant", "tower_edge", "--quiet")
    assert p.returncode == 0, p.stderr
    cell = out / "ntm_B_16" / "none" / "pi"
    m = json.loads((cell / "metrics.json").read_text())
    assert m["plant"] == "tower_edge" and m["shaft_torque_del_1hz_Nm"] > 0
    assert 'plant = "tower_edge"' in (cell / "config.toml").read_text()


def test_unknown_controller_fault_or_wind_is_refused(tmp_path):
    for flag, bad in (("--controllers", "rosco2"), ("--faults", "gearbox"),
                      ("--winds", "hurricane")):
        out = tmp_path / bad
        p = wtftc("compare", "--out", out, flag, bad, "--quiet")
        assert p.returncode == 2 and "Traceback" not in p.stderr
        assert bad in p.stderr and flag.lstrip("-") in p.stderr
        assert not out.exists()


def test_too_short_a_run_for_the_faults_is_refused(tmp_path):
    p = wtftc("compare", "--out", tmp_path / "x", "--t-final", 15, "--quiet")
    assert p.returncode == 2 and "t-final" in p.stderr and "onset" in p.stderr
    assert not (tmp_path / "x").exists()


def test_pitch_controllers_run_with_the_baseline_torque_law_and_rosco_with_its_own():
    """Every pitch controller competes with the NREL 5-MW baseline torque law; ROSCO, at
    any tuning, commands its own torque (its adapter holds it in gen_torque_rated, law 0).
    The _ct variants run the law's region 3 at constant torque (issue 34)."""
    from wtftc.campaign import compare
    from wtftc.config import make_config

    # the IEA 15-MW's candidate is tuned to 0.4 rad/s, ζ 0.85, which the physical AFTC
    # cannot reach on the NREL 5-MW (its lowest is about 0.55 rad/s at ζ 0.7): refused
    # there in one line naming [tuning], run on its own turbine here
    own = {"physical_obs15_w04_ps_ct_fdi": ("iea15mw", 120.97)}
    with pytest.raises(ConfigError) as e:
        compare.cell_config("physical_obs15_w04_ps_ct_fdi", "lock", "ntm_B_16", 30.0, 1e-3, 0)
    assert e.value.field == "tuning"
    for name in compare.CONTROLLERS:
        turbine, radius = own.get(name, (None, 63.0))
        cfg = compare.cell_config(name, "lock", "ntm_B_16", 30.0, 1e-3, 0, turbine=turbine)
        law = cfg.get("turbine_params", {}).get("gen_torque_law", 0.0)
        rosco = compare.CONTROLLERS[name].controller == "rosco"
        assert law == (0.0 if rosco else 1.0), name
        region3 = cfg.get("turbine_params", {}).get("vs_constant_torque", 0.0)
        assert region3 == (1.0 if name.endswith(("_ct", "_ct_fdi")) else 0.0), name
        assert make_config(cfg).param("vs_constant_torque") == region3, name
        assert cfg["plant"] == "tower" and cfg["wind"]["rotor_radius_m"] == radius
    iea = compare.cell_config("pi", "none", "ntm_B_16", 30.0, 1e-3, 0, turbine="iea15mw")
    assert iea["wind"]["rotor_radius_m"] == 120.97


def test_the_matrix_has_every_actuator_fault_type_and_names_the_fdi_variants():
    """compare.FAULTS holds one scenario of each pitch actuator fault type of the one list
    (model/faults.py); the variants that use wtftc's FDI are those that run in its case."""
    from wtftc import config
    from wtftc.campaign import compare
    from wtftc.model.faults import ACTUATOR_FAULT_TYPES

    assert set(compare.FAULTS) == {"none", *ACTUATOR_FAULT_TYPES}
    assert all(tabs[0]["type"] == f for f, tabs in compare.FAULTS.items() if tabs)
    assert [c for c, v in compare.CONTROLLERS.items() if v.uses_fdi] == [
        "physical_fdi", "drivetrain_fdi", "paper_fdi", "physical_obs_fdi",
        "physical_obs_ps_fdi", "physical_obs45_ps_fdi", "physical_obs45_ps_td_fdi",
        "physical_obs45_ps_ct_fdi", "physical_obs45_ps_td_ct_fdi",
        "physical_obs30_ps_td_ct_fdi", "physical_obs3to45_ps_td_ct_fdi",
        "physical_obs15_w04_ps_ct_fdi"]
    assert "FDI" in config.CASES[compare.FDI_CASE]
    cfg = compare.cell_config("physical_fdi", "lock", "ntm_B_16", 30.0, 1e-3, 0)
    assert (cfg["controller"], cfg["case"]) == ("physical", compare.FDI_CASE)
    assert compare.cell_config("physical_fdi", "none", "ntm_B_16", 30.0, 1e-3, 0)["case"] == 1


def test_the_paper_with_wtftcs_fdi_runs_on_the_native_engine(tmp_path):
    """paper_fdi (case 4: eq (49) fed by wtftc's FDI, no oracle) in a steady 20 m/s,
    blade 1 running away to fine pitch at 20 s: the FDI finds it."""
    out = tmp_path / "cmp"
    p = wtftc("compare", "--out", out, "--controllers", "paper_fdi", "--faults", "runaway",
              "--winds", "steady_20", "--t-final", 24, "--quiet")
    assert p.returncode == 0, p.stderr
    m = json.loads((out / "steady_20" / "runaway" / "paper_fdi" / "metrics.json").read_text())
    assert (m["controller"], m["case"]) == ("paper", 4) and m["fdi"]["ran"]
    assert m["fdi"]["faults"][0]["detected"] and m["fdi"]["faults"][0]["isolated_blade"] == 1
    row = (out / "compare.csv").read_text().splitlines()[1].split(",")
    assert row[:3] == ["steady_20", "runaway", "paper_fdi"] and row[-3] != ""  # a delay


def test_issue_34s_variants_carry_their_options_and_run_when_named(tmp_path):
    """physical_obs_fdi and pi_lpf are the physical AFTC on its speed observer and the PI on
    its filtered speed (the _ps variants add peak shaving): their cells carry the options in
    [controller_params] (and a cell
    re-runs alone from its config.toml); the other variants' configurations, hence sweep
    run ids, carry none. A bare `wtftc compare` does not run them."""
    from wtftc.campaign import compare

    obs = compare.cell_config("physical_obs_fdi", "lock", "ntm_B_16", 30.0, 1e-3, 0)
    assert (obs["controller"], obs["case"]) == ("physical", compare.FDI_CASE)
    assert obs["controller_params"] == {"phys_obs_omega": 6.0}
    lpf = compare.cell_config("pi_lpf", "none", "ntm_B_16", 30.0, 1e-3, 0)
    assert lpf["controller_params"] == {"pi_lpf_corner": 6.0}
    shaved = compare.cell_config("pi_lpf_ps", "none", "ntm_B_16", 30.0, 1e-3, 0)
    assert shaved["controller_params"] == {"pi_lpf_corner": 6.0, "pi_ps_pitch": 0.0349}
    assert all("controller_params" not in compare.cell_config(c, "lock", "ntm_B_16", 30.0,
                                                              1e-3, 0)
               for c in compare.DEFAULT_CONTROLLERS)
    assert not set(compare.ISSUE34) & set(compare.DEFAULT_CONTROLLERS)
    low = compare.cell_config("physical_obs45_ps_fdi", "none", "ntm_B_16", 30.0, 1e-3, 0)
    assert low["controller_params"] == {"phys_obs_omega": 4.5, "phys_ps_pitch": 0.0349}
    sched = compare.cell_config("physical_obs3to45_ps_td_ct_fdi", "none", "ntm_B_16", 30.0,
                                1e-3, 0)
    assert sched["controller_params"] == {"phys_obs_omega": 3.0, "phys_obs_omega_max": 4.5,
                                          "phys_ps_pitch": 0.0349, "phys_td_gain": 0.12}
    assert sched["turbine_params"]["vs_constant_torque"] == 1.0
    matched = compare.cell_config("rosco_matched", "lock", "ntm_B_16", 30.0, 1e-3, 0)
    assert matched["controller"] == "rosco" and matched["case"] == compare.UNAWARE_CASE
    assert matched["rosco"] == {"omega_pc_rad_s": 0.7, "zeta_pc": 0.85}
    assert "rosco" not in compare.cell_config("rosco", "lock", "ntm_B_16", 30.0, 1e-3, 0)
    out = tmp_path / "cmp"
    p = wtftc("compare", "--out", out, "--controllers", "physical_obs_fdi", "--faults",
              "none", "--winds", "ntm_B_16", "--t-final", 30, "--quiet")
    assert p.returncode == 0, p.stderr
    cfg = (out / "ntm_B_16" / "none" / "physical_obs_fdi" / "config.toml").read_text()
    assert "phys_obs_omega = 6.0" in cfg
