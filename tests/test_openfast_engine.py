"""OpenFAST as wtftc's second engine (issue 32): short runs of the NREL 5-MW deck of
ROSCO's examples through wtftc's plant library (`make test` gets OpenFAST first)."""

from __future__ import annotations

import json
import math
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts.loader import compiler
from wtftc.campaign import cases
from wtftc.cli import main
from wtftc.errors import EngineError
from wtftc.openfast import engine
from wtftc.openfast.case import get_value
from wtftc.results.metrics import metrics

T_FINAL = 20.0
WIND = {"kind": "constant", "speed_mps": 16.0}


@pytest.fixture(scope="module")
def rosco_run(tmp_path_factory) -> Path:
    """ROSCO fault-free at 16 m/s, 20 s, through `wtftc run --engine openfast`, with a
    relative --out (OpenFAST runs in another folder: every path it reads must hold)."""
    base = tmp_path_factory.mktemp("of")
    here = os.getcwd()
    os.chdir(base)
    try:
        code = main(["run", "--engine", "openfast", "--controller", "rosco", "--profile",
                     "realistic", "--wind", "constant", "--wind-mean", "16", "--t-final",
                     str(T_FINAL), "--fault", "none", "--quiet", "--out", "rosco"])
    finally:
        os.chdir(here)
    assert code == 0
    return base / "rosco"


@pytest.fixture(scope="module")
def runaway(tmp_path_factory):
    """The physical AFTC with wtftc's FDI (case 4), blade 1 running away to fine pitch at
    10 s, 16 m/s, 20 s."""
    rc = config.make_config({"engine": "openfast", "profile": "realistic",
                             "controller": "physical", "case": 4, "t_final_s": T_FINAL,
                             "wind": WIND, "fault": [{"type": "runaway", "blade": 1,
                                                      "onset_s": 10.0, "target_deg": 0.0}]})
    from wtftc.campaign import cases
    from wtftc.results.metrics import metrics

    res = cases.run(rc, progress=False, openfast_dir=tmp_path_factory.mktemp("of") / "phys")
    return rc, res, metrics(rc, res)


def test_a_run_writes_the_native_files_and_a_case_a_user_can_rerun(rosco_run):
    for name in ("metrics.json", "traces.csv", "traces.parquet", "config.toml",
                 "figures/rotor_speed.png", "openfast/NREL-5MW.fst",
                 "openfast/NREL-5MW.outb", "openfast/wtftc_plant.in",
                 "openfast/wtftc_wind.uni", "openfast/openfast.log"):
        assert (rosco_run / name).is_file(), name
    fst = rosco_run / "openfast" / "NREL-5MW.fst"
    assert float(get_value(fst, "TMax")) == T_FINAL
    servo = fst.parent / get_value(fst, "ServoFile")
    dt, dll_dt = float(get_value(fst, "DT")), float(get_value(servo, "DLL_DT"))
    assert dll_dt / dt == pytest.approx(round(dll_dt / dt), abs=1e-9)
    m = json.loads((rosco_run / "metrics.json").read_text())
    assert m["diverged"] is None and m["fdi"]["ran"] is False  # ROSCO carries no FDI


def test_the_metrics_equal_an_independent_computation_from_the_outb(rosco_run):
    """The RMS speed error and the mean power from OpenFAST's own channels, read here
    with openfast-io and NumPy, after the start-up window the run recorded."""
    from openfast_io.FAST_output_reader import FASTOutputFile

    m = json.loads((rosco_run / "metrics.json").read_text())
    f = FASTOutputFile(str(rosco_run / "openfast" / "NREL-5MW.outb"))
    ch = {n: f.data[:, i] for i, n in enumerate(f.info["attribute_names"])}
    keep = ch["Time"] >= m["transient_s"] - 1e-9
    err = ch["RotSpeed"][keep] * math.pi / 30 - m["reference_rad_s"]
    assert m["rms_speed_error_rad_s"] == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-9)
    # the mean power is read from the outputs, at the output rate (docs/loads.md: within
    # 4e-6 of the simulation rate's on wtftc's plant)
    assert m["mean_electrical_power_W"] == pytest.approx(np.mean(ch["GenPwr"][keep]) * 1e3,
                                                         rel=2e-5)
    # ROSCO holds the NREL 5-MW near rated at 16 m/s: within 1 % on average, 5 MW ± 2 %
    assert abs(np.mean(err)) < 0.01 * m["reference_rad_s"]
    assert m["mean_electrical_power_W"] == pytest.approx(5.0e6, rel=0.02)


def test_the_run_starts_at_its_operating_point(rosco_run):
    """The deck's initial rotor speed, pitch and tower-top displacement are the run's
    operating point (issue 31: ROSCO's own laws on wtftc's Cp table). OpenFAST's own
    steady pitch at 16 m/s is about 1° lower (flexible blades, BEM: docs/openfast.md), so
    ROSCO moves the pitch by that much and the rotor speed dips 3 % while it does."""
    from openfast_io.FAST_output_reader import FASTOutputFile

    from wtftc.artefacts import layout as lay
    from wtftc.sim.rhs import PLANTS

    rc = config.make_config(config.load_toml(rosco_run / "config.toml", "config"))
    z0, states = rc.initial_state(), PLANTS["tower"]["states"]
    ed = rosco_run / "openfast" / "NRELOffshrBsline5MW_Onshore_ElastoDyn.dat"
    assert float(get_value(ed, "RotSpeed")) * math.pi / 30 == pytest.approx(
        z0[lay.index(states, "omega_r")], rel=1e-8)
    assert math.radians(float(get_value(ed, "BlPitch(2)"))) == pytest.approx(
        z0[lay.index(states, "beta_2")], rel=1e-8)
    assert float(get_value(ed, "TTDspFA")) == pytest.approx(
        z0[lay.index(states, "tower_x")], rel=1e-8)
    f = FASTOutputFile(str(rosco_run / "openfast" / "NREL-5MW.outb"))
    ch = {n: f.data[:, i] for i, n in enumerate(f.info["attribute_names"])}
    first = ch["Time"] <= 2.0
    assert np.ptp(ch["BldPitch1"][first]) < 2.0
    assert np.ptp(ch["RotSpeed"][first]) < 0.05 * ch["RotSpeed"][0]  # measured 3.3 %


def test_the_physical_aftc_isolates_a_runaway_in_openfast(runaway):
    rc, res, m = runaway
    assert res.diverged is None
    fault = m["fdi"]["faults"][0]
    assert fault["detected"] and fault["isolated_blade"] == 1
    assert 0 < fault["detection_delay_s"] < 2.0
    assert m["fdi"]["false_alarms"] == []
    # blade 1 ends at fine pitch, where the runaway drives it (the actuator library)
    assert math.degrees(res.column("beta_1")[-1]) < 0.5
    assert m["overspeed_peak_over_rated"] < 1.1


def test_the_runaway_acts_in_the_actuator_library_not_in_the_controller(runaway):
    """Blade 1 leaves the controller's demand at the onset: the library's actuator obeys
    the fault; blades 2 and 3 follow their demands."""
    rc, res, m = runaway
    t = res.t
    after = (t > 12.0) & (t < t[-1])  # the last call (iStatus -1) closes the library
    gap = np.degrees(np.abs(res.column("v_1") - res.column("beta_1")))
    assert gap[after].min() > 1.0
    for j in (2, 3):  # behind their demands only by the actuator's lag and rate limit
        lag = np.degrees(np.abs(res.column(f"v_{j}") - res.column(f"beta_{j}")))[after]
        assert np.median(lag) < 1.0 and lag.max() < 5.0


def test_an_openfast_abort_is_a_lost_run_with_openfasts_message(tmp_path):
    """A controller library that fails at 2 s: OpenFAST stops, the run is lost there and
    its reason is OpenFAST's message, which carries the library's."""
    src = tmp_path / "failing.c"
    src.write_text('#include <string.h>\nvoid DISCON(float *s, int *fail, char *in, '
                   'char *out, char *msg) { s[46] = 40000.0f; s[41] = s[42] = s[43] = '
                   '0.2f; *fail = 0; if (s[1] > 2.0f) { *fail = -1; strcpy(msg, '
                   '"scripted failure"); } }\n')
    lib = tmp_path / "libfailing.so"
    subprocess.run([compiler(), "-shared", "-fPIC", "-o", str(lib), str(src)], check=True)
    rc = config.make_config({"engine": "openfast", "profile": "realistic",
                             "controller": "pi", "case": 1, "t_final_s": 6.0, "wind": WIND})
    case = engine.prepare(rc, tmp_path / "case")
    text = case.plant_settings.read_text().replace(  # named relative to the case
        "controller_library controller/libwtftc_pi.so", f"controller_library {lib}")
    assert str(lib) in text
    case.plant_settings.write_text(text)
    wall, abort = engine.simulate(case, progress=False)
    assert abort is not None and "scripted failure" in abort
    if case.outb.is_file():  # OpenFAST wrote what it had: the run is lost at ~2 s
        res = engine.result(rc, case, wall, abort)
        assert res.diverged["reason"] == abort and res.diverged["t_s"] <= 2.1


def test_a_missing_openfast_is_one_line_naming_openfast(tmp_path, monkeypatch, capsys):
    """$OPENFAST naming no file is the user's input refused (exit code 2), in one line
    naming the variable; nothing is written."""
    monkeypatch.setenv("OPENFAST", str(tmp_path / "no" / "openfast"))
    code = main(["run", "--engine", "openfast", "--controller", "rosco", "--profile",
                 "realistic", "--wind", "constant", "--wind-mean", "16", "--t-final", "5",
                 "--fault", "none", "--quiet", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "OPENFAST" in err
    assert not (tmp_path / "run").exists()


def test_openfast_not_installed_is_said_before_any_work(tmp_path, monkeypatch, capsys):
    """No OpenFAST found: one line with how to get it, exit code 4, before the run's
    header line and before its operating point is solved or a loop compiled."""
    from wtftc.openfast import install

    monkeypatch.setattr(install, "find", lambda *a, **k: None)
    monkeypatch.setattr(config, "make_config", lambda *a, **k: pytest.fail("work started"))
    code = main(["run", "--engine", "openfast", "--controller", "pi", "--wind", "constant",
                 "--wind-mean", "16", "--t-final", "5", "--out", str(tmp_path / "run")])
    out, err = capsys.readouterr()
    assert code == 4 and out == "" and err.count("\n") == 1 and "openfast get" in err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("over, field", [
    ({"plant": "nrel5mw"}, "plant"),
    ({"mismatch": {"J_r": 1.1}}, "mismatch"),
    ({"case": 3}, "case"),
    ({"profile": "ideal"}, "profile"),
    ({"engine": "fast"}, "engine"),
    ({"openfast": {"wind": "bts"}}, "openfast.wind"),
    ({"openfast": "turbsim"}, "openfast"),
    ({"openfast": {"actuator": "no"}}, "openfast.actuator"),
    ({"openfast": {"actuator": False}, "case": 4}, "openfast.actuator"),
])
def test_keys_without_meaning_in_openfast_are_refused_naming_them(over, field):
    cfg = {"engine": "openfast", "profile": "realistic", "controller": "physical",
           "case": 1, "wind": WIND, **over}
    with pytest.raises(config.ConfigError) as exc:
        config.make_config(cfg)
    assert exc.value.field == field


def test_a_deck_error_is_one_line_naming_openfasts_complaint(tmp_path):
    """A deck whose ElastoDyn file has a word where a number belongs."""
    rc = config.make_config({"engine": "openfast", "profile": "realistic",
                             "controller": "pi", "case": 1, "t_final_s": 2.0, "wind": WIND})
    case = engine.prepare(rc, tmp_path / "case")
    ed = case.fst.parent / get_value(case.fst, "EDFile")
    ed.write_text(ed.read_text().replace("TipRad", "TipRad", 1).replace(
        get_value(ed, "TipRad") + " ", "sixty-three ", 1))
    wall, abort = engine.simulate(case, progress=False)
    assert abort is not None and "while trying to read TipRad" in abort and "\n" not in abort
    with pytest.raises(EngineError, match="TipRad"):  # no output: nothing to score
        engine.result(rc, case, wall, abort)


def test_ntm_in_openfast_is_a_turbsim_field_made_once_and_shared(tmp_path):
    """An NTM run reads TurbSim's full field (class B, the run's seed and mean at hub
    height); a second run with the same inputs reuses the cached field."""
    from wtftc.openfast import turbsim

    cfg = {"engine": "openfast", "profile": "realistic", "controller": "rosco", "case": 1,
           "t_final_s": T_FINAL, "fault": [], "seed": 3,
           "wind": {"kind": "ntm", "mean_mps": 16.0}}
    # made once, before the configuration (as every command does: make_config, below the
    # OpenFAST room, reads the field but cannot run TurbSim); the run then reuses it
    turbsim.ensure_field(cfg)
    rc = config.make_config(cfg)
    from wtftc.campaign import cases
    from wtftc.results.metrics import metrics

    res = cases.run(rc, progress=False, openfast_dir=tmp_path / "a")
    inflow = tmp_path / "a" / "NRELOffshrBsline5MW_InflowWind.dat"
    assert get_value(inflow, "WindType") == "3"
    field = turbsim.Field(16.0, "B", 3, 90.0, 63.0, T_FINAL)
    assert "3            RandSeed1" in field.input_text()
    made = turbsim.field_path(field)
    assert made.is_file() and (tmp_path / "a" / "wtftc_wind.bts").read_bytes() == \
        made.read_bytes()
    stamp = made.stat().st_mtime_ns
    assert turbsim.generate(field) == made and made.stat().st_mtime_ns == stamp
    wind = res.column("wind")
    assert res.diverged is None and 14.0 < wind.mean() < 18.0 and wind.std() > 0.5
    assert metrics(rc, res)["mean_electrical_power_W"] > 4.5e6


def test_compare_runs_its_matrix_in_openfast(tmp_path, capsys):
    """`wtftc compare --engine openfast`: every cell's OpenFAST case under its folder, one
    table; a variant told the fault is refused under a fault, naming it."""
    out = tmp_path / "cmp"
    code = main(["compare", "--engine", "openfast", "--controllers", "rosco", "pi",
                 "--faults", "none", "--winds", "ntm_B_16", "--t-final", "10", "--quiet",
                 "--out", str(out)])
    assert code == 0
    for c in ("rosco", "pi"):
        assert (out / "ntm_B_16" / "none" / c / "openfast" / "NREL-5MW.outb").is_file()
    rows = (out / "compare.csv").read_text().splitlines()
    assert len(rows) == 3 and rows[1].split(",")[2] == "rosco"
    assert rows[1].endswith(",") and rows[2].endswith(",0")  # ROSCO has no FDI; the PI's
    capsys.readouterr()
    code = main(["compare", "--engine", "openfast", "--controllers", "paper", "--faults",
                 "runaway", "--winds", "ntm_B_16", "--out", str(tmp_path / "no")])
    err = capsys.readouterr().err
    assert code == 2 and "controllers = 'paper'" in err and not (tmp_path / "no").exists()


def test_the_abort_message_is_the_last_error_unwrapped():
    """OpenFAST's screen output: a warning routed like an error first, then the error,
    wrapped at 98 characters mid-word; the reason is the error, whole, on one line."""
    head = "FAST_Solution:FAST_UpdateStates:Solver_Step:FAST_UpdateStates:SrvD_UpdateStates:"
    log = "\n".join([
        " OpenFAST", "", " " + head + "DLL_controller_cal", " l:Using last calculated values "
        "from DLL. Warning will not be displayed again.", "",
        " " + head + "DLL_controller_cal", " l:scripted failure", "",
        " OpenFAST encountered an error at simulation time 2.01 of 6 seconds.",
        " Simulation error level: FATAL ERROR", "", "  Aborting OpenFAST."])
    assert engine.abort_message(log, 1) == ("OpenFAST stopped (exit code 1): " + head
                                             + "DLL_controller_call:scripted failure")


@pytest.mark.parametrize("controller", ["rosco", "pi"])
def test_the_case_reruns_by_hand_after_its_folder_is_moved(tmp_path, controller):
    """Item 3: `wtftc run --engine openfast` keeps a case a user can rerun by hand. The run
    folder is written beside its final name and renamed into place, and a user may move
    it: every path the case holds is relative to it but the plant library's (wtftc's
    cache). Run again by hand in a moved copy, OpenFAST ends normally and writes the same
    rotor speed."""
    from wtftc.openfast import install

    out = tmp_path / "run"
    code = main(["run", "--engine", "openfast", "--controller", controller, "--profile",
                 "realistic", "--wind", "constant", "--wind-mean", "16", "--t-final", "2",
                 "--fault", "none", "--quiet", "--out", str(out)])
    assert code == 0
    moved = tmp_path / "elsewhere" / "moved"
    moved.parent.mkdir()
    out.rename(moved)
    case = moved / "openfast"
    fst = next(case.glob("*.fst"))
    first = engine.read_outb(fst.with_suffix(".outb"))["RotSpeed"]
    fst.with_suffix(".outb").unlink()
    done = subprocess.run([str(install.require().openfast), fst.name], cwd=case,
                          capture_output=True, text=True)
    assert done.returncode == 0 and engine.NORMAL_END in done.stdout, done.stdout[-600:]
    again = engine.read_outb(fst.with_suffix(".outb"))["RotSpeed"]
    assert np.array_equal(first, again)
    assert str(tmp_path / "run") not in (case / "wtftc_plant.in").read_text()


@pytest.mark.parametrize("missing, text", [("openfast_io", "openfast-io 5.0.0"),
                                           ("rosco", "needs ROSCO 2.10.6")])
def test_a_missing_python_package_of_the_engine_is_one_line_before_any_run(
        monkeypatch, capsys, tmp_path, missing, text):
    """A `pip install wtftc` without the engine's packages: OpenFAST's output reader
    (openfast-io) and ROSCO's wheel (the built-in decks) are named, with the command that
    installs them, in one line and exit code 2 (a dependency missing, as for Dask: no
    program failed), before anything runs (a newcomer got a traceback after the whole
    simulation)."""
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == missing else real(name, *a))
    code = main(["run", "--engine", "openfast", "--controller", "pi", "--profile",
                 "realistic", "--wind", "constant", "--wind-mean", "16", "--t-final", "5",
                 "--quiet", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and text in err and "pip install" in err
    assert "which is not installed" in err and not (tmp_path / "run").exists()


def test_the_engine_defaults_to_the_realistic_profile_and_refuses_ideal_when_asked():
    """A newcomer's `--engine openfast` without `--profile` was told "profile = 'ideal' is
    not allowed", a value never given: OpenFAST calls a library every control interval,
    so the realistic profile is the engine's default; asked for, ideal is refused."""
    rc = config.make_config({"engine": "openfast", "controller": "pi", "case": 1,
                             "wind": WIND})
    assert rc.raw["profile"] == "realistic" and rc.control_interval == pytest.approx(0.01)
    with pytest.raises(config.ConfigError) as exc:
        config.make_config({"engine": "openfast", "controller": "pi", "case": 1,
                            "wind": WIND, "profile": "ideal"})
    assert exc.value.field == "profile"


def _bare_host_run(base: Path, actuator_model: float) -> dict:
    """The physical AFTC with its speed observer in OpenFAST without the benchmark actuator
    (the deck's blades take the demand, within the rate limit), 16 m/s steady, 30 s."""
    rc = config.make_config({
        "engine": "openfast", "profile": "realistic", "controller": "physical", "case": 1,
        "t_final_s": 30.0, "wind": WIND, "turbine_params": {"gen_torque_law": 1.0},
        "openfast": {"actuator": False},
        "controller_params": {"phys_obs_omega": 6.0, "phys_actuator_model": actuator_model}})
    res = cases.run(rc, progress=False, openfast_dir=base / f"am{actuator_model:g}")
    return metrics(rc, res)


def test_a_host_without_an_actuator_gets_a_design_without_one(tmp_path):
    """issue 34: on OpenFAST's deck as it is (`[openfast] actuator = false`), the design
    that inverts the benchmark's lag drives the drivetrain (docs/discon.md: the limit cycle
    of issue 22); with `phys_actuator_model = 0` (U = α1) the shaft DEL falls to a
    quarter of it or less, and the rotor stays within 5 % of rated."""
    with_lag, without = _bare_host_run(tmp_path, 1.0), _bare_host_run(tmp_path, 0.0)
    assert with_lag["diverged"] is None and without["diverged"] is None
    assert without["shaft_torque_del_1hz_Nm"] < 0.25 * with_lag["shaft_torque_del_1hz_Nm"]
    assert without["overspeed_peak_over_rated"] < 1.05


def test_an_abort_by_a_crash_names_the_signal_and_where_the_output_is():
    """OpenFAST ended by SIGSEGV with nothing said: the reason is never empty, it names the
    signal and the log; a warning printed before the crash is not taken as its reason."""
    log = Path("/run/case/openfast.log")
    assert engine.abort_message("", -11, log) == (
        "OpenFAST stopped (exit code -11, SIGSEGV) with no message; its screen output is "
        f"in {log}")
    warned = (" FAST_Solution:FAST_UpdateStates:SrvD_UpdateStates:DLL_controller_call:Using"
              " last calculated values from DLL.\n Time: 2 of 6 seconds.\n")
    assert engine.abort_message(warned, -11, log) == engine.abort_message("", -11, log)
    assert engine.abort_message(warned + "Program received signal SIGSEGV: Segmentation "
                                "fault - invalid memory reference.\n", -11, log) == (
        "OpenFAST stopped (exit code -11, SIGSEGV): Program received signal SIGSEGV: "
        "Segmentation fault - invalid memory reference.")
    assert engine.abort_message("Time: 1 of 6 seconds.\n", 1, log).endswith(
        f"(exit code 1) with no message; its screen output is in {log}")


def test_the_real_outb_passes_its_case_and_is_refused_for_a_shorter_one(tmp_path):
    """OpenFAST's own output of a 2-s case is read; handed to a 1-s case (a longer run's
    output left in its folder) it is refused, naming the file."""
    rc = config.make_config({"engine": "openfast", "profile": "realistic",
                             "controller": "pi", "case": 1, "t_final_s": 2.0, "wind": WIND})
    case = engine.prepare(rc, tmp_path / "case")
    wall, abort = engine.simulate(case, progress=False)
    assert abort is None
    res = engine.result(rc, case, wall, abort)
    assert res.t[-1] == pytest.approx(2.0, abs=rc.dt)
    short = config.make_config({**rc.raw, "t_final_s": 1.0})
    with pytest.raises(EngineError, match=r"NREL-5MW\.outb is not this case's output \("
                       r"\d+ rows for a case of \d+\): delete it"):
        engine.result(short, case, wall, abort)
