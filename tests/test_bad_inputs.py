"""The corpus of bad input (issue 14): every case is refused with exit code 2 and exactly
one line on stderr, ``wtftc: error: ...``, that names the field; no traceback, and the
``--out`` folder is not created.

Table-driven: a case is (id, the field the message must name, the CLI arguments, the files
it needs). Add a row for every new key or file format. The CLI runs in-process
(``wtftc.cli.main``); only the cases that set environment variables start a process.

In the arguments and in file texts, ``{tmp}`` is the test's folder and ``{name}`` the path
of the case's file ``name``. A case with ``cfg`` text runs ``wtftc run --config {c.toml}``
unless it gives its own arguments.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import subprocess
import sys
from importlib.resources import files
from pathlib import Path
from typing import NamedTuple

import pytest

from wtftc import cli, config
from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import generated_dir
from wtftc.sim import integrate
from wtftc.sim.rhs import controllers


class Case(NamedTuple):
    id: str
    field: str
    argv: tuple = ()
    cfg: str | bytes | None = None
    files: dict | None = None  # name -> text or bytes, written into the test's folder


def _cp_text() -> str:
    return (files("wtftc") / "data" / "Cp_Ct_Cq.NREL5MW.txt").read_text()


def _cp_short_row() -> str:
    """The packaged Cp table with the last column of its first Cp row dropped."""
    lines = _cp_text().splitlines()
    i = next(k for k, line in enumerate(lines) if "Power coefficient" in line)
    lines[i + 2] = " ".join(lines[i + 2].split()[:-1])
    return "\n".join(lines) + "\n"


def _cp_above_betz() -> str:
    """The packaged Cp table with one power coefficient of 0.7, above the Betz limit."""
    lines = _cp_text().splitlines()
    i = next(k for k, line in enumerate(lines) if "Power coefficient" in line)
    row = lines[i + 2].split()
    lines[i + 2] = " ".join(["0.7", *row[1:]])
    return "\n".join(lines) + "\n"


def _wind(rows: str) -> dict:
    return {"w.csv": "time_s,speed_mps\n" + rows}


WIND_FILE = '[wind]\nkind = "file"\npath = "{w.csv}"\n'
SEED_64 = 2**64
BINARY = b"\xff\xfe\x00\x01case = 1\n"
SWEEP_OK = 'controllers = ["paper"]\n'

CASES = [
    # --- the command line (argparse: one line too, with where to find --help)
    Case("case-5", "--case", ("run", "--case", "5")),
    Case("case-not-int", "--case", ("run", "--case", "x")),
    Case("unknown-option", "--bogus", ("run", "--bogus")),
    Case("seed-cli-64bit", "seed", ("run", "--seed", str(SEED_64))),
    Case("seed-cli-negative", "--seed", ("run", "--seed", "-2")),
    Case("seed-cli-float", "--seed", ("run", "--seed", "1.5")),
    Case("seed-compare-64bit", "seed", ("compare", "--seed", str(2**70))),
    Case("seed-cases-64bit", "seed", ("cases", "--seed", str(SEED_64))),
    Case("seed-verify-negative", "--seed", ("verify", "--seed", "-3")),
    Case("verify-points-0", "--points", ("verify", "--points", "0")),
    Case("cases-plant", "--plant", ("cases", "--plant", "vestas")),
    Case("plant-vestas", "plant", ("run", "--plant", "vestas")),
    Case("controller-unknown", "controller", ("run", "--controller", "lqr")),
    Case("dt-negative", "dt_s", ("run", "--dt", "-0.001")),
    Case("dt-rk4-unstable", "dt_s", ("run", "--dt", "5")),
    Case("dt-inf", "dt_s", ("run", "--dt", "inf")),
    Case("t-final-nan", "t_final_s", ("run", "--t-final", "nan")),
    Case("t-final-not-whole-steps", "t_final_s", ("run", "--t-final", "1.0005")),
    Case("cases-dt-nan", "dt_s", ("cases", "--dt", "nan")),
    Case("wind-kind", "kind", ("run", "--wind", "hurricane")),
    Case("wind-mean-nan", "wind.mean_mps", ("run", "--wind-mean", "nan")),
    Case("compare-controller", "controllers", ("compare", "--controllers", "lqr")),
    Case("compare-t-final", "t-final", ("compare", "--t-final", "10")),
    Case("compare-plant-no-tower", "plant", ("compare", "--plant", "nrel5mw")),
    Case("compare-plant-openfast", "plant", ("compare", "--plant", "tower_edge", "--engine",
                                             "openfast")),
    # --- the config file itself
    Case("config-missing", "--config", ("run", "--config", "{tmp}/nowhere.toml")),
    Case("config-folder", "--config", ("run", "--config", "{tmp}")),
    Case("config-binary", "--config", cfg=BINARY),
    Case("config-not-toml", "--config", cfg="case = = 1\n"),
    Case("unknown-key", "turbo", cfg="case = 1\nturbo = true\n"),
    # --- top-level values: wrong type (a list where a scalar is expected), out of range
    Case("seed-64bit", "seed", cfg=f"seed = {SEED_64}\n"),
    Case("seed-negative", "seed", cfg="seed = -2\n"),
    Case("seed-minus-1", "seed", cfg="seed = -1\n"),
    Case("seed-float", "seed", cfg="seed = 1.5\n"),
    Case("seed-bool", "seed", cfg="seed = true\n"),
    Case("t-final-list", "t_final_s", cfg="t_final_s = [1, 2]\n"),
    Case("t-final-bool", "t_final_s", cfg="t_final_s = true\n"),
    Case("dt-list", "dt_s", cfg="dt_s = [0.001]\n"),
    Case("rate-list", "output_rate_hz", cfg="output_rate_hz = [50]\n"),
    Case("rate-not-whole-steps", "output_rate_hz", cfg="output_rate_hz = 300.0\n"),
    Case("case-list", "case", cfg="case = [1]\n"),
    Case("case-bool", "case", cfg="case = true\n"),
    Case("plant-list", "plant", cfg='plant = ["nrel5mw"]\n'),
    Case("controller-list", "controller", cfg='controller = ["paper"]\n'),
    Case("sign-list", "control_sign", cfg="control_sign = [1]\n"),
    Case("sign-2", "control_sign", cfg="control_sign = 2\n"),
    Case("reference-list", "reference_rad_s", cfg="reference_rad_s = [1.2]\n"),
    Case("reference-string", "reference_rad_s", cfg='reference_rad_s = "fast"\n'),
    Case("reference-negative", "reference_rad_s", cfg="reference_rad_s = -1.0\n"),
    Case("label-int", "label", cfg="label = 5\n"),
    Case("label-list", "label", cfg='label = ["a"]\n'),
    # --- the Cp table
    # --- controller parameters: each in its physical range (layout.json "valid")
    # --- the OpenFAST engine's run: the value the user gave is the one named
    Case("openfast-interval-past-alignment", "control_interval_s",
         cfg='engine = "openfast"\ncontroller = "pi"\ncontrol_interval_s = 1.0\n'
             "t_final_s = 10.0\n"),
    Case("openfast-interval-flag", "control_interval_s (--control-interval) = 0.5",
         ("run", "--engine", "openfast", "--controller", "physical", "--control-interval",
          "0.5", "--t-final", "10")),
    Case("validate-wind-file-and-mean", "wind.mean_mps (--wind-mean)",
         ("validate", "--wind", "file", "--wind-file", "{w.csv}", "--wind-mean", "16"),
         files=_wind("0,16\n60,16\n")),
    # --- found in review: accepted, then ignored or lost at once
    Case("sign-physical", "control_sign", ("run", "--controller", "physical", "--sign", "1")),
    Case("prefix-not-numbered", "gen_torque",
         cfg="[turbine_params]\ngen_torque = [4180074.35, 1]\n"),
    Case("reference-beyond-envelope", "reference_rad_s", cfg="reference_rad_s = 9.0\n"),
    Case("offset-stalls-at-start", "initial.omega_r_offset_rad_s",
         cfg="[initial]\nomega_r_offset_rad_s = -1.1\n"),
    Case("ctrl-told-fault", "controller_params.lock_hat_2",  # was accepted and ignored
         cfg="[controller_params]\nlock_hat_2 = 1.0\n"),
    Case("ctrl-gain-zero", "controller_params.phys_c1",
         cfg='controller = "physical"\n[controller_params]\nphys_c1 = 0.0\n'),
    Case("ctrl-gamma-negative", "controller_params.gamma_2",
         cfg="[controller_params]\ngamma = [1.0, -1.0, 1.0, 1.0]\n"),
    Case("ctrl-pitch-range", "controller_params.pi_pitch_min",
         cfg='controller = "pi"\n[controller_params]\npi_pitch_min = 0.5\npi_pitch_max = 0.4\n'),
    Case("ctrl-pitch-beyond-90", "controller_params.dt_pitch_max",
         cfg='controller = "drivetrain"\n[controller_params]\ndt_pitch_max = 2.0\n'),
    Case("cp-number", "cp_table", cfg="cp_table = 5\n"),
    Case("cp-bool", "cp_table", cfg="cp_table = true\n"),
    Case("cp-missing", "cp_table", cfg='cp_table = "{tmp}/nowhere.txt"\n'),
    Case("cp-folder", "cp_table", cfg='cp_table = "{tmp}"\n'),
    Case("cp-short-row", "cp_table", cfg='cp_table = "{cp.txt}"\n',
         files={"cp.txt": _cp_short_row()}),
    Case("cp-binary", "cp_table", cfg='cp_table = "{cp.txt}"\n', files={"cp.txt": BINARY}),
    Case("cp-above-betz", "cp_table", cfg='cp_table = "{cp.txt}"\n',
         files={"cp.txt": _cp_above_betz()}),
    # --- the wind
    Case("wind-number", "wind", cfg="wind = 5\n"),
    Case("wind-array-of-tables", "wind", cfg='[[wind]]\nkind = "ntm"\n'),
    Case("wind-kind-list", "wind.kind", cfg='[wind]\nkind = ["ntm"]\n'),
    Case("wind-speed-list", "wind.speed_mps", cfg='[wind]\nkind = "constant"\nspeed_mps = [12]\n'),
    Case("wind-speed-0", "wind.speed_mps", cfg='[wind]\nkind = "constant"\nspeed_mps = 0.0\n'),
    Case("wind-steps-number", "wind.steps",
         cfg='[wind]\nkind = "steps"\nspeed_mps = 12.0\nsteps = 5\n'),
    Case("wind-class-list", "wind.turbulence_class",
         cfg='[wind]\nkind = "ntm"\nturbulence_class = ["A"]\n'),
    Case("wind-unknown-field", "wind.gusty", cfg='[wind]\nkind = "ntm"\ngusty = true\n'),
    Case("wind-path-number", "wind.path", cfg='[wind]\nkind = "file"\npath = 5\n'),
    Case("wind-file-order", "wind.path", ("run", "--wind", "file", "--wind-file", "{w.csv}"),
         files=_wind("0,12\n2,13\n1,14\n")),
    Case("wind-file-all-zero", "wind.path", cfg=WIND_FILE, files=_wind("0,0\n10,0\n")),
    Case("wind-file-calm", "wind.path", cfg=WIND_FILE, files=_wind("0,12\n5,0\n10,12\n")),
    Case("wind-file-500-mps", "wind.path", cfg=WIND_FILE, files=_wind("0,12\n5,500\n")),
    Case("wind-file-nan", "wind.path", cfg=WIND_FILE, files=_wind("0,nan\n5,12\n")),
    Case("wind-file-binary", "wind.path", cfg=WIND_FILE, files={"w.csv": BINARY}),
    # --- faults
    Case("fault-number", "fault", cfg="case = 2\nfault = 5\n"),
    Case("fault-list-of-numbers", "fault[0]", cfg="case = 2\nfault = [1, 2]\n"),
    Case("fault-in-case-1", "fault",
         cfg='case = 1\n[[fault]]\nblade = 1\ntype = "lock"\nonset_s = 1.0\n'),
    Case("fault-rho", "fault[0].rho", cfg='case = 2\n[[fault]]\nblade = 2\n'
         'type = "loss_of_effectiveness"\nonset_s = 5.0\nrho = 1.5\n'),
    Case("fault-onset-list", "fault[0].onset_s",
         cfg='case = 2\n[[fault]]\nblade = 1\ntype = "lock"\nonset_s = [1.0]\n'),
    Case("fault-onset-after-end", "fault[0].onset_s",
         cfg='case = 2\nt_final_s = 10.0\n[[fault]]\nblade = 1\ntype = "lock"\n'
             'onset_s = 20.0\n'),
    Case("fault-blade-64bit", "fault[0].blade",
         cfg=f'case = 2\n[[fault]]\nblade = {SEED_64}\ntype = "lock"\nonset_s = 1.0\n'),
    Case("fault-type-list", "fault[0].type",
         cfg='case = 2\n[[fault]]\nblade = 1\ntype = ["lock"]\nonset_s = 1.0\n'),
    Case("fault-angle-nan", "fault[0].angle_deg",
         cfg='case = 2\n[[fault]]\nblade = 1\ntype = "lock"\nonset_s = 1.0\n'
             'angle_deg = nan\n'),
    # --- [controller_params], [turbine_params], [initial]: tables of finite numbers
    Case("controller-params-number", "controller_params", cfg="controller_params = 5\n"),
    Case("controller-params-unknown", "controller_params.foo",
         cfg="[controller_params]\nfoo = 1.0\n"),
    Case("controller-params-sign", "controller_params.control_sign",
         cfg="[controller_params]\ncontrol_sign = 1\n"),
    Case("k-obs-scalar", "controller_params.K_obs", cfg="[controller_params]\nK_obs = 5.0\n"),
    Case("k-obs-short", "controller_params.K_obs",
         cfg="[controller_params]\nK_obs = [1.0, 2.0, 3.0]\n"),
    Case("k-obs-nested", "controller_params.K_obs",
         cfg="[controller_params]\nK_obs = [[1, 2], [3, 4]]\n"),
    Case("k-obs-string", "controller_params.K_obs[0]",
         cfg='[controller_params]\nK_obs = ["a", "b", "c", "d"]\n'),
    Case("c-table", "controller_params.c", cfg="[controller_params.c]\na = 1\n"),
    Case("c-inf", "controller_params.c[0]",
         cfg="[controller_params]\nc = [inf, 6.0, 12.0, 9.0]\n"),
    Case("turbine-params-number", "turbine_params", cfg="turbine_params = 5\n"),
    Case("turbine-unknown", "turbine_params.K_obs", cfg="[turbine_params]\nK_obs = 1.0\n"),
    Case("j-r-list", "turbine_params.J_r", cfg="[turbine_params]\nJ_r = [1, 2]\n"),
    Case("j-r-string", "turbine_params.J_r", cfg='[turbine_params]\nJ_r = "heavy"\n'),
    Case("j-r-table", "turbine_params.J_r", cfg="[turbine_params.J_r]\na = 1\n"),
    Case("j-r-bool", "turbine_params.J_r", cfg="[turbine_params]\nJ_r = true\n"),
    Case("j-r-1e400", "turbine_params.J_r", cfg="[turbine_params]\nJ_r = 1e400\n"),
    Case("j-r-nan-paper-plant", "turbine_params.J_r",
         cfg='plant = "paper"\n[turbine_params]\nJ_r = nan\n'),
    Case("tau-b-0-paper-plant", "turbine_params.tau_b",
         cfg='plant = "paper"\n[turbine_params]\ntau_b = 0.0\n'),
    Case("pitch-min-above-max", "turbine_params.pitch_min",
         cfg="[turbine_params]\npitch_min = 1.0\npitch_max = 0.5\n"),
    Case("pitch-max-below-min", "turbine_params.pitch_max",
         cfg="[turbine_params]\npitch_max = -0.1\n"),
    Case("cut-in-above-region-2", "turbine_params.vs_cut_in_speed",
         cfg="[turbine_params]\nvs_cut_in_speed = 1.0\n"),
    Case("torque-law-half", "turbine_params.gen_torque_law",
         cfg="[turbine_params]\ngen_torque_law = 0.5\n"),
    Case("initial-number", "initial", cfg="initial = 5\n"),
    Case("initial-unknown", "initial.foo", cfg="[initial]\nfoo = 1.0\n"),
    Case("initial-nan", "initial.omega_r_offset_rad_s",
         cfg="[initial]\nomega_r_offset_rad_s = nan\n"),
    Case("initial-list", "initial.omega_r_offset_rad_s",
         cfg="[initial]\nomega_r_offset_rad_s = [0.1]\n"),
    Case("initial-string", "initial.omega_r_offset_rad_s",
         cfg='[initial]\nomega_r_offset_rad_s = "x"\n'),
    # --- sweep files
    Case("sweep-no-file", "SWEEP.toml", ("sweep",)),
    Case("sweep-missing", "SWEEP.toml", ("sweep", "{tmp}/nowhere.toml")),
    Case("sweep-folder", "SWEEP.toml", ("sweep", "{tmp}")),
    Case("sweep-binary", "SWEEP.toml", ("sweep", "{s.toml}"), files={"s.toml": BINARY}),
    Case("sweep-unknown-key", "turbo", ("sweep", "{s.toml}"),
         files={"s.toml": SWEEP_OK + "turbo = 1\n"}),
    Case("sweep-fault-rho", "fault.rho", ("sweep", "{s.toml}"),
         files={"s.toml": SWEEP_OK + '[fault]\ntype = "loss_of_effectiveness"\nrho = 1.5\n'}),
    Case("sweep-seed-64bit", "seed", ("sweep", "{s.toml}"),
         files={"s.toml": SWEEP_OK + f"[wind]\nseed = [{SEED_64}]\n"}),
]


def _turbine_range_cases() -> list[Case]:
    """For every turbine parameter: NaN, infinity, and a value just beyond each finite end
    of its range (the end itself where it is open), each refused with the range."""
    out = []
    for name, (lo, hi, lo_open, hi_open, _) in config.TURBINE_RANGES.items():
        values = {"nan": "nan", "-inf": "-inf"}
        for end, is_open, step in ((lo, lo_open, -0.5), (hi, hi_open, 0.5)):
            if math.isfinite(end):
                values[f"{end:g}" if is_open else f"{end + step:g}"] = repr(
                    end if is_open else end + step)
        for tag, text in values.items():
            out.append(Case(f"turbine-{name}-{tag}", f"turbine_params.{name}",
                            cfg=f"[turbine_params]\n{name} = {text}\n"))
    return out


def _controller_nan_cases() -> list[Case]:
    """NaN in the first parameter of every registered controller's group."""
    out = []
    for ctrl, reg in controllers().items():
        if ctrl == "external":  # ROSCO's plumbing: no user parameters
            continue
        name = lay.names(reg["params"])[0]
        out.append(Case(f"controller-{ctrl}-nan", f"controller_params.{name}",
                        cfg=f'controller = "{ctrl}"\n[controller_params]\n{name} = nan\n'))
    return out


def _controller_range_cases() -> list[Case]:
    """For every parameter of every registered controller with a finite end to its range
    (layout.json ``valid``; not eq (49)'s told fault, refused as such): a value just
    beyond it, refused naming controller_params.<name>. A new parameter adds its cases."""
    out = []
    for ctrl, reg in controllers().items():
        if ctrl == "external":
            continue
        for name, (lo, hi, lo_open, hi_open, _) in config._ranges(reg["params"]).items():
            if name.startswith(("rho_hat", "lock_hat", "ubar_hat", "control_sign")):
                continue
            for end, is_open, step in ((lo, lo_open, -0.5), (hi, hi_open, 0.5)):
                if math.isfinite(end):
                    value = end if is_open else end + step
                    out.append(Case(f"controller-{ctrl}-{name}-{value:g}",
                                    f"controller_params.{name}",
                                    cfg=f'controller = "{ctrl}"\n[controller_params]\n'
                                        f"{name} = {value!r}\n"))
    return out


ALL = (CASES + _turbine_range_cases() + _controller_nan_cases()
       + _controller_range_cases())


def _materialize(case: Case, tmp: Path) -> list[str]:
    """Write the case's files; its argv with the paths filled in, and --out."""
    paths = {"{tmp}": str(tmp)}
    named = dict(case.files or {})
    if case.cfg is not None:
        named["c.toml"] = case.cfg
    for name in named:
        paths["{" + name + "}"] = str(tmp / name)

    def fill(text: str) -> str:
        for key, val in paths.items():
            text = text.replace(key, val)
        return text

    for name, content in named.items():
        data = content if isinstance(content, bytes) else fill(content).encode()
        (tmp / name).write_bytes(data)
    argv = [fill(a) for a in (case.argv or ("run", "--config", "{c.toml}"))]
    return argv + ["--out", str(tmp / "out")] + (["--quiet"] if argv[0] != "verify" else [])


def _assert_refused(code, err: str, field: str, out: Path) -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err
    assert "Traceback" not in err, err
    assert len(lines) == 1, err
    assert lines[0].startswith("wtftc: error:"), err
    assert field in lines[0], err
    assert not out.exists(), f"{out} was created"


@pytest.fixture
def no_run(monkeypatch):
    """A case that got past validation would start simulating: fail it at once instead."""
    def started(*a, **k):
        raise AssertionError("the input was accepted: the run started")

    monkeypatch.setattr(integrate, "run_loops", started)


@pytest.mark.parametrize("case", [pytest.param(c, id=c.id) for c in ALL])
def test_bad_input_is_one_line_naming_the_field(case, tmp_path, capsys, no_run):
    argv = _materialize(case, tmp_path)
    try:
        code = cli.main(argv)
    except SystemExit as exc:
        code = exc.code
    _assert_refused(code, capsys.readouterr().err, case.field, tmp_path / "out")


def test_the_range_table_names_every_turbine_parameter_and_holds_the_defaults():
    assert set(config.TURBINE_RANGES) == set(lay.names("turbine_params"))
    config.check_turbine(lay.defaults("turbine_params"))
    units = dict(zip(lay.names("turbine_params"), lay.units("turbine_params"), strict=True))
    for name, (lo, hi, *_, unit) in config.TURBINE_RANGES.items():
        assert lo < hi and unit == units[name], name


def test_a_range_error_gives_the_value_and_the_range(tmp_path, capsys, no_run):
    cfg = tmp_path / "c.toml"
    cfg.write_text("[turbine_params]\nair_density = 0\n")
    assert cli.main(["run", "--config", str(cfg), "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip() == (
        "wtftc: error: turbine_params.air_density = 0.0 is not allowed: a number in (0, 2] "
        "[kg/m^3]")


def test_a_value_given_by_a_flag_is_refused_naming_the_flag(tmp_path, capsys, no_run):
    """The flag that set the value stands beside the field; a config file's value names the
    field alone; `--wind file` without `--wind-file` names the flag it needs."""
    out = str(tmp_path / "o")
    assert cli.main(["run", "--t-final", "0", "--out", out]) == 2
    assert capsys.readouterr().err.startswith(
        "wtftc: error: t_final_s (--t-final) = 0.0 is not allowed: a number in (0, ")
    assert cli.main(["run", "--wind-mean=-3", "--out", out]) == 2
    assert "wind.mean_mps (--wind-mean) = -3.0" in capsys.readouterr().err
    cfg = tmp_path / "c.toml"
    cfg.write_text("t_final_s = 0\n")
    assert cli.main(["run", "--config", str(cfg), "--out", out]) == 2
    assert capsys.readouterr().err.startswith("wtftc: error: t_final_s = 0 is not allowed")
    assert cli.main(["run", "--wind", "file", "--out", out]) == 2
    assert "wind.path (--wind-file) = None" in capsys.readouterr().err


# --- the environment: a process per case (the artefacts are read once per process)


def _generated_copy(tmp: Path, damage: str) -> Path:
    """manifest.json and layout.json (all that is read before a command starts), damaged."""
    folder = tmp / "generated"
    folder.mkdir()
    for name in ("manifest.json", "layout.json"):
        shutil.copy(generated_dir() / name, folder / name)
    layout, manifest = folder / "layout.json", folder / "manifest.json"
    if damage == "manifest-binary":
        manifest.write_bytes(b"\xff\x00\x01")
        return folder
    layout.write_text({"layout-edited": layout.read_text().replace('"J_r"', '"J_x"', 1),
                       "layout-not-json": "{\"functions\": ",
                       "layout-empty-object": "{}"}[damage])
    if damage != "layout-edited":  # the manifest agrees: only parsing can tell
        m = json.loads(manifest.read_text())
        m["artefacts"]["layout.json"] = hashlib.sha256(layout.read_bytes()).hexdigest()
        manifest.write_text(json.dumps(m))
    return folder


ENV_CASES = {  # id -> (WTFTC_GENERATED, the file the message names)
    "missing-folder": ("{tmp}/nowhere", "manifest.json"),
    "a-file": ("{tmp}/file.txt", "manifest.json"),
    "manifest-binary": ("damage", "manifest.json"),
    "layout-edited": ("damage", "layout.json"),
    "layout-not-json": ("damage", "layout.json"),
    "layout-empty-object": ("damage", "layout.json"),
}


def _wtftc(*args, env):
    return subprocess.run([sys.executable, "-m", "wtftc.cli", *map(str, args)],
                          capture_output=True, text=True, env=env)


@pytest.mark.parametrize("damage", sorted(ENV_CASES))
def test_damaged_artefacts_refuse_commands_but_not_help(damage, tmp_path):
    where, name = ENV_CASES[damage]
    (tmp_path / "file.txt").write_text("not a folder\n")
    folder = _generated_copy(tmp_path, damage) if where == "damage" else \
        Path(where.replace("{tmp}", str(tmp_path)))
    env = {**os.environ, "WTFTC_GENERATED": str(folder)}
    for args, shown in ((("--help",), "verify"), (("run", "--help"), "--controller"),
                        (("cases", "--help"), "--plant")):
        p = _wtftc(*args, env=env)
        assert p.returncode == 0 and shown in p.stdout and not p.stderr, p.stderr
    out = tmp_path / "out"
    for command in (("run", "--out", out, "--quiet"), ("functions",),
                    ("sweep", tmp_path / "s.toml", "--out", out)):
        p = _wtftc(*command, env=env)
        _assert_refused(p.returncode, p.stderr, name, out)
        assert "WTFTC_GENERATED" in p.stderr
