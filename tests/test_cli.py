"""`wtftc run` end to end, and bad input: one clear line, exit code 2, no output written."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest


def wtftc(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "wtftc.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd)


def test_run_end_to_end(tmp_path):
    out = tmp_path / "run"
    p = wtftc("run", "--case", 3, "--t-final", 25, "--wind", "constant", "--wind-mean", 15,
              "--out", out, "--quiet")
    assert p.returncode == 0, p.stderr
    names = {f.name for f in out.iterdir()}
    assert {"traces.csv", "traces.parquet", "metrics.json", "config.toml", "metrics.md"} <= names
    # figures of the run, PNG and PDF; no FDI figure in case 3 (the fault is told)
    figs = {f.name for f in (out / "figures").iterdir()}
    assert figs == {f"{n}.{ext}" for n in ("rotor_speed", "control", "fault")
                    for ext in ("png", "pdf")}
    m = json.loads((out / "metrics.json").read_text())
    assert m["case"] == 3 and m["diverged"] is None and m["seed"] == 0
    assert m["config"]["wind"] == {"kind": "constant", "speed_mps": 15.0}
    assert [f["type"] for f in m["config"]["fault_resolved"]] == [
        "lock", "loss_of_effectiveness", "loss_of_effectiveness"]
    header = (out / "traces.csv").read_text().splitlines()[1]
    assert header.startswith("time_s [s],omega_r [rad/s]")
    data = np.loadtxt(out / "traces.csv", delimiter=",", skiprows=2)
    assert data.shape[0] == 25 * 50  # 50 Hz output
    import pyarrow.parquet as pq

    table = pq.read_table(out / "traces.parquet")
    np.testing.assert_allclose(table.column("omega_r").to_numpy(), data[:, 1], rtol=1e-8)
    assert table.schema.field("omega_r").metadata[b"unit"] == b"rad/s"
    # the saved configuration re-runs to the same numbers
    p2 = wtftc("run", "--config", out / "config.toml", "--out", tmp_path / "again", "--quiet")
    assert p2.returncode == 0, p2.stderr
    again = np.loadtxt(tmp_path / "again" / "traces.csv", delimiter=",", skiprows=2)
    np.testing.assert_array_equal(again, data)


def test_diverging_run_exits_3_with_time_and_state(tmp_path):
    from conftest import DIVERGING_RUN

    cfg = tmp_path / "diverging.toml"
    w = DIVERGING_RUN["wind"]
    cfg.write_text(f'controller = "paper"\ncase = 1\nseed = {DIVERGING_RUN["seed"]}\n'
                   f'[wind]\nkind = "ntm"\nmean_mps = {w["mean_mps"]}\n'
                   f'turbulence_class = "{w["turbulence_class"]}"\n'
                   f'rotor_radius_m = {w["rotor_radius_m"]}\n'
                   '[turbine_params]\ngen_torque_law = 1.0\n')
    p = wtftc("run", "--config", cfg, "--t-final", 40, "--out", tmp_path / "d", "--quiet")
    assert p.returncode == 3
    assert "DIVERGED at t =" in p.stdout
    m = json.loads((tmp_path / "d" / "metrics.json").read_text())
    assert m["diverged"]["t_s"] > 0 and m["diverged"]["last_finite_state"]


def _bad_wind_file(tmp_path):
    f = tmp_path / "w.csv"
    f.write_text("time_s,speed_mps\n0,12\n2,13\n1,14\n")
    return f


def _bad_cp_table(tmp_path):
    from wtftc.model.cp_table import nrel5mw_cp_table

    src = nrel5mw_cp_table().source
    text = open(src).read() if not src.startswith("NREL") else None
    f = tmp_path / "cp.txt"
    if text is None:
        from importlib.resources import files

        text = (files("wtftc") / "data" / "Cp_Ct_Cq.NREL5MW.txt").read_text()
    lines = text.splitlines()
    i = next(k for k, line in enumerate(lines) if "Power coefficient" in line)
    # drop the last column of the first Cp row
    lines[i + 2] = " ".join(lines[i + 2].split()[:-1])
    f.write_text("\n".join(lines) + "\n")
    return f


@pytest.mark.parametrize("args,field", [
    (["--case", "5"], "--case"),
    (["--plant", "vestas"], "plant"),
    (["--dt", "-0.001"], "dt_s"),
    (["--dt", "5"], "dt_s"),
    (["--t-final", "1.0005"], "t_final_s"),  # not a whole number of steps: was run as 1.0 s
    (["--wind", "hurricane"], "kind"),
    (["--wind", "file", "--wind-file", "{wind}"], "wind.path"),
    (["--config", "{cfg_unknown}"], "turbo"),
    (["--config", "{cfg_cp}"], "cp_table"),
    (["--config", "{cfg_fault}"], "fault[0].rho"),
])
def test_bad_input_is_one_clear_line_exit_2_no_output(tmp_path, args, field):
    cfg_unknown = tmp_path / "u.toml"
    cfg_unknown.write_text("case = 1\nturbo = true\n")
    cfg_cp = tmp_path / "c.toml"
    cfg_cp.write_text(f'cp_table = "{_bad_cp_table(tmp_path)}"\n')
    cfg_fault = tmp_path / "f.toml"
    cfg_fault.write_text('case = 2\n[[fault]]\nblade = 2\ntype = "loss_of_effectiveness"\n'
                         'onset_s = 5.0\nrho = 1.5\n')
    subs = {"{wind}": _bad_wind_file(tmp_path), "{cfg_unknown}": cfg_unknown,
            "{cfg_cp}": cfg_cp, "{cfg_fault}": cfg_fault}
    args = [str(subs.get(a, a)) for a in args]
    out = tmp_path / "out"
    p = wtftc("run", *args, "--out", out, "--quiet")
    assert p.returncode == 2, (p.stdout, p.stderr)
    assert "Traceback" not in p.stderr
    assert field in p.stderr, p.stderr
    assert not out.exists()


def test_help_explains_the_commands():
    p = wtftc("--help")
    assert p.returncode == 0
    for cmd in ("cases", "run", "verify"):
        assert cmd in p.stdout
    r = wtftc("run", "--help")
    assert "--case" in r.stdout and "known to eq (49)" in r.stdout


def test_an_internal_error_shows_its_traceback_not_a_user_error(tmp_path, monkeypatch):
    """A bug in wtftc (here a KeyError inside the run) must not print as "wtftc: error: X"
    as if the user had erred: it propagates with its traceback."""
    from wtftc import cli

    def broken(*a, **k):
        raise KeyError("an internal key")

    from wtftc.campaign import cases

    monkeypatch.setattr(cases, "run", broken)
    with pytest.raises(KeyError, match="an internal key"):
        cli.main(["run", "--t-final", "1", "--out", str(tmp_path / "o"), "--quiet"])
    assert not (tmp_path / "o" / "metrics.json").exists()


def test_the_command_runs_blas_on_one_thread_unless_told_otherwise():
    """Set before numpy loads OpenBLAS, whose idle worker threads otherwise spin on the
    cores the loops use (docs/performance.md); a user's own setting wins."""
    from wtftc import cli

    code = "import os, wtftc.cli, numpy; print(os.environ['OPENBLAS_NUM_THREADS'])"
    env = {k: v for k, v in os.environ.items() if k not in cli.BLAS_THREADS}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.strip()
    assert out == "1"
    out = subprocess.run([sys.executable, "-c", code], env={**env, "OPENBLAS_NUM_THREADS": "3"},
                         capture_output=True, text=True, check=True).stdout.strip()
    assert out == "3"


@pytest.mark.parametrize("argv, module, extra", [
    (["linearize", "--out", "x"], "control", "linear"),
    (["turbine", "tune", "--omega-n", "1", "--zeta", "0.7", "--out", "x.toml"], "control",
     "linear"),
    (["sweep", "sweep.toml", "--out", "x"], "distributed", "sweep")])
def test_a_missing_extra_is_one_line_naming_it_and_its_pip_line(argv, module, extra,
                                                                 monkeypatch, capsys, tmp_path):
    """An optional dependency that is not installed: exit 2, one line that names the
    command, the package and the pip line, nothing written."""
    from wtftc import cli

    monkeypatch.setitem(sys.modules, module, None)  # import fails as if not installed
    monkeypatch.chdir(tmp_path)
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "which is not installed: pip install 'wtftc[" + extra + "]'" in err, err
    assert "is not allowed" not in err and not list(tmp_path.iterdir())


@pytest.mark.parametrize("argv", [["run", "--t-final", "2", "--out", "{bad}"],
                                  ["cases", "--out", "{bad}"],
                                  ["run", "--config", "{bad}"]])
def test_a_path_that_is_not_utf8_is_one_line_naming_its_option(tmp_path, capsys, argv):
    """A path whose bytes are not UTF-8 (the shell passes them as they are): refused
    naming its option before any work (it was a traceback from the Parquet writer)."""
    from wtftc.cli import main

    bad = str(tmp_path / os.fsdecode(b"w\xff\xfe"))
    code = main([a.replace("{bad}", bad) for a in argv])
    err = capsys.readouterr().err
    option = argv[argv.index("{bad}") - 1]
    assert code == 2 and err.count("\n") == 1 and f"{option} = " in err and "UTF-8" in err
    assert list(tmp_path.iterdir()) == []
