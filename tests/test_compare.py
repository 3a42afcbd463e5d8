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
    p = wtftc("compare", "--out", out, "--controllers", "physical-plain", "pi", "--faults",
              "none", "loss_of_effectiveness", "--winds", "ntm_B_16", "--t-final", 30,
              "--quiet")
    assert p.returncode == 0, p.stderr
    lines = (out / "compare.csv").read_text().splitlines()
    assert len(lines) == 1 + 4 and lines[0].startswith("wind,fault,controller")
    assert (out / "compare.png").exists() and (out / "compare.md").exists()
    cell = out / "ntm_B_16" / "loss_of_effectiveness" / "physical-plain"
    m = json.loads((cell / "metrics.json").read_text())
    assert m["case"] == 4 and m["fdi"]["isolation_correct"]
    # the matrix is on the validated plant (the tower and the blades' edgewise mode), in
    # the wind averaged over the 63-m rotor disk
    assert m["plant"] == "tower_edge" and m["tower_base_del_1hz_Nm"] > 0
    assert "tower-base DEL" in (out / "compare.md").read_text()
    again = tmp_path / "again"
    p2 = wtftc("run", "--config", cell / "config.toml", "--out", again, "--quiet")
    assert p2.returncode == 0, p2.stderr
    m2 = json.loads((again / "metrics.json").read_text())
    assert np.isclose(m2["rms_speed_error_rad_s"], m["rms_speed_error_rad_s"], rtol=1e-12)


def test_the_matrix_runs_on_the_plant_it_is_given(tmp_path):
    """--plant tower: the cells run on the plant asked for, not the default tower_edge."""
    out = tmp_path / "tower"
    p = wtftc("compare", "--out", out, "--controllers", "pi", "--faults", "none", "--winds",
              "ntm_B_16", "--t-final", 30, "--plant", "tower", "--quiet")
    assert p.returncode == 0, p.stderr
    cell = out / "ntm_B_16" / "none" / "pi"
    m = json.loads((cell / "metrics.json").read_text())
    assert m["plant"] == "tower" and m["shaft_torque_del_1hz_Nm"] > 0
    assert 'plant = "tower"' in (cell / "config.toml").read_text()


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


def _every_named_controller():
    from wtftc import controller

    return {**controller.presets(), **controller.former_names()}


def test_pitch_controllers_run_with_the_baseline_torque_law_and_rosco_with_its_own():
    """Every pitch controller competes with the NREL 5-MW baseline torque law; ROSCO, at
    any tuning, commands its own torque (its adapter holds it in gen_torque_rated, law 0).
    A column that sets the law's region 3 at constant torque runs it so."""
    from wtftc.campaign import compare
    from wtftc.config import make_config

    cols = _every_named_controller()
    # the IEA 15-MW's candidate set by its target mode (0.4 rad/s, ζ 0.85), which the
    # physical AFTC cannot reach on the NREL 5-MW (its lowest is about 0.55 rad/s at ζ 0.7):
    # refused there in one line naming [tuning], run on its own turbine here
    own = {"physical_obs15_w04_ps_ct_fdi": ("iea15mw", 120.97),
           "aftc-iea15mw": ("iea15mw", 120.97)}
    with pytest.raises(ConfigError) as e:
        compare.cell_config("w04", "lock", "ntm_B_16", 30.0, 1e-3, 0,
                            ctrl=cols["physical_obs15_w04_ps_ct_fdi"])
    assert e.value.field == "tuning"
    constant = set()
    for name, ctrl in cols.items():
        turbine, radius = own.get(name, (None, 63.0))
        cfg = compare.cell_config(name, "lock", "ntm_B_16", 30.0, 1e-3, 0,
                                  turbine=turbine, ctrl=ctrl)
        law = cfg.get("turbine_params", {}).get("gen_torque_law", 0.0)
        assert law == (0.0 if ctrl.design == "rosco" else 1.0), name
        region3 = cfg.get("turbine_params", {}).get("vs_constant_torque", 0.0)
        if region3:
            constant.add(name)
        assert make_config(cfg).param("vs_constant_torque") == region3, name
        assert cfg["plant"] == "tower_edge" and cfg["wind"]["rotor_radius_m"] == radius
    assert constant == {"aftc-nrel5mw", "aftc-iea15mw", "pi-filtered",
                        "physical_obs3to45_ps_td_ct_fdi", "physical_obs15_w04_ps_ct_fdi",
                        "pi_lpf_ps_ct", "physical_obs45_ps_ct_fdi",
                        "physical_obs45_ps_td_ct_fdi", "physical_obs30_ps_td_ct_fdi"}
    iea = compare.cell_config("pi", "none", "ntm_B_16", 30.0, 1e-3, 0,
                              turbine="iea15mw", ctrl=cols["pi"])
    assert iea["wind"]["rotor_radius_m"] == 120.97


def test_the_matrix_has_every_actuator_fault_type_and_each_column_its_case():
    """compare.FAULTS holds one scenario of each pitch actuator fault type of the one list
    (model/faults.py); under a fault a column runs in its accommodation's case (wtftc's
    FDI: case 4), without one in case 1."""
    from wtftc import config
    from wtftc.campaign import compare
    from wtftc.model.faults import ACTUATOR_FAULT_TYPES

    assert set(compare.FAULTS) == {"none", *ACTUATOR_FAULT_TYPES}
    assert all(tabs[0]["type"] == f for f, tabs in compare.FAULTS.items() if tabs)
    case = {"none": config.UNAWARE_CASE, "known": config.ORACLE_CASE, "fdi": config.FDI_CASE}
    assert "FDI" in config.CASES[config.FDI_CASE]
    for name, ctrl in _every_named_controller().items():
        if ctrl.tuning and ctrl.design == "physical":
            continue  # (solved on its own turbine: the test above)
        cfg = compare.cell_config(name, "lock", "ntm_B_16", 30.0, 1e-3, 0, ctrl=ctrl)
        assert (cfg["controller"], cfg["case"]) == (ctrl.design, case[ctrl.accommodation])
        free = compare.cell_config(name, "none", "ntm_B_16", 30.0, 1e-3, 0, ctrl=ctrl)
        assert free["case"] == 1


def test_the_paper_with_wtftcs_fdi_runs_on_the_native_engine(tmp_path):
    """paper-fdi (case 4: eq (49) fed by wtftc's FDI, no oracle) in a steady 20 m/s,
    blade 1 running away to fine pitch at 20 s: the FDI finds it."""
    out = tmp_path / "cmp"
    p = wtftc("compare", "--out", out, "--controllers", "paper-fdi", "--faults", "runaway",
              "--winds", "steady_20", "--t-final", 24, "--quiet")
    assert p.returncode == 0, p.stderr
    m = json.loads((out / "steady_20" / "runaway" / "paper-fdi" / "metrics.json").read_text())
    assert (m["controller"], m["case"]) == ("paper", 4) and m["fdi"]["ran"]
    assert m["fdi"]["faults"][0]["detected"] and m["fdi"]["faults"][0]["isolated_blade"] == 1
    row = (out / "compare.csv").read_text().splitlines()[1].split(",")
    assert row[:3] == ["steady_20", "runaway", "paper-fdi"] and row[-3] != ""  # a delay


def test_a_columns_settings_reach_its_cells(tmp_path):
    """A column's design parameters go to [controller_params], a list of values makes one
    column each, a target mode becomes the controller's own gains (ROSCO's [rosco]); the
    PI and ROSCO presets carry none (their cells, hence sweep run ids, as they were); a
    cell re-runs alone from its config.toml."""
    from wtftc.campaign import compare

    cols = compare.resolve_columns([
        "pi", "rosco", "rosco-matched", "aftc-nrel5mw",
        {"name": "obs", "preset": "physical-plain", "phys_obs_omega": [4.5, 6.0],
         "phys_ps_pitch": 0.0349},
        {"name": "lpf", "design": "pi", "pi_lpf_corner": 6.0, "pi_ps_pitch": 0.0349}])
    assert list(cols) == ["pi", "rosco", "rosco-matched", "aftc-nrel5mw",
                          "obs[phys_obs_omega=4.5]", "obs[phys_obs_omega=6]", "lpf"]

    def cell(name, fault="lock"):
        return compare.cell_config(name, fault, "ntm_B_16", 30.0, 1e-3, 0,
                                   ctrl=cols[name])

    assert cell("obs[phys_obs_omega=6]")["controller_params"] == {"phys_obs_omega": 6.0,
                                                                  "phys_ps_pitch": 0.0349}
    assert cell("obs[phys_obs_omega=4.5]")["case"] == 4
    assert cell("lpf", "none")["controller_params"] == {"pi_lpf_corner": 6.0,
                                                        "pi_ps_pitch": 0.0349}
    assert all("controller_params" not in cell(c) for c in ("pi", "rosco"))
    sched = cell("aftc-nrel5mw", "none")
    assert sched["controller_params"] == {"phys_obs_omega": 3.0, "phys_obs_omega_max": 4.5,
                                          "phys_ps_pitch": 0.0349, "phys_td_gain": 0.12}
    assert sched["turbine_params"] == {"gen_torque_law": 1.0, "vs_constant_torque": 1.0}
    matched = cell("rosco-matched")
    assert matched["controller"] == "rosco" and matched["case"] == 2
    assert matched["rosco"] == {"omega_pc_rad_s": 0.7, "zeta_pc": 0.85}
    assert "rosco" not in cell("rosco")
    # a table on the command line (--controllers '{ ... }'), run as a matrix's column
    entries = compare.entries_from_text(
        ['{ name = "obs", preset = "physical-plain", phys_obs_omega = 6.0 }', "pi"])
    assert entries == [{"name": "obs", "preset": "physical-plain", "phys_obs_omega": 6.0},
                       "pi"]
    with pytest.raises(ConfigError) as e:
        compare.entries_from_text(["{ name = obs }"])
    assert e.value.field == "--controllers"
    out = tmp_path / "cmp"
    rows = compare.run_compare(out, entries[:1], ["none"], ["ntm_B_16"], t_final=30.0,
                               progress=False)
    assert [r["controller"] for r in rows] == ["obs"]
    cfg = (out / "ntm_B_16" / "none" / "obs" / "config.toml").read_text()
    assert "phys_obs_omega = 6.0" in cfg


def test_a_bare_matrix_is_the_recommended_preset_the_pi_and_rosco():
    """Without --controllers: the turbine's recommended preset (--preset another), the PI
    baseline and ROSCO; a turbine file that names none runs the PI, with a note."""
    from types import SimpleNamespace

    from wtftc import controller
    from wtftc.campaign import compare
    from wtftc.model import turbine_file

    assert list(compare.default_columns(turbine_file.load("nrel5mw"))) == [
        "aftc-nrel5mw", "pi", "rosco"]
    assert list(compare.default_columns(turbine_file.load("iea15mw"))) == [
        "aftc-iea15mw", "pi", "rosco"]
    cols = compare.default_columns(turbine_file.load("nrel5mw"), "pi-filtered")
    assert list(cols) == ["pi-filtered", "pi", "rosco"]
    assert cols["pi-filtered"] == controller.preset("pi-filtered")
    notes = []
    bare = SimpleNamespace(name="mine", recommended_preset=None, path="mine.toml")
    assert list(compare.default_columns(bare, note=notes.append)) == ["pi", "rosco"]
    assert len(notes) == 1 and "mine" in notes[0] and "recommended_preset" in notes[0]
    with pytest.raises(ConfigError) as e:
        compare.default_columns(turbine_file.load("nrel5mw"), "fastest")
    assert (e.value.field, e.value.value) == ("--preset", "fastest")
    with pytest.raises(ConfigError) as e:
        compare.run_compare("unused", controllers=["pi"], preset="pi-filtered")
    assert e.value.field == "--preset"


def test_oracles_and_rosco_are_left_out_with_a_note_or_refused_when_asked(monkeypatch,
                                                                           capsys):
    """Under OpenFAST's faults a column told the fault (accommodation known) cannot run:
    left out of a matrix it was not asked for, refused when asked; ROSCO likewise where
    it cannot run."""
    from wtftc.campaign import compare
    from wtftc.sim import rosco

    with pytest.raises(ConfigError) as e:
        compare._columns(["pi", "paper"], None, None, True)
    assert e.value.field == "controllers" and "paper" in str(e.value)
    assert list(compare._columns(["pi", "paper"], None, None, False)) == ["pi", "paper"]
    with pytest.raises(ConfigError) as exc:  # the preset asked for: refused, not dropped
        compare._columns(None, "physical-oracle", None, True)
    assert exc.value.field == "--preset"
    monkeypatch.setattr(rosco, "available", lambda: "ROSCO is not installed here")
    assert list(compare._columns(None, None, None, False)) == ["aftc-nrel5mw", "pi"]
    assert "ROSCO is not installed here" in capsys.readouterr().out
    with pytest.raises(ConfigError) as e:
        compare._columns(["pi", "rosco-matched"], None, None, False)
    assert e.value.value == "rosco-matched"
