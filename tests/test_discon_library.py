"""A DISCON library wtftc did not build (``[controller] design = "discon"``, its library
and input file), run in OpenFAST behind the plant library's actuator, faults and sensors
exactly as ROSCO is: ROSCO's own libdiscon.so with its NREL 5-MW DISCON.IN given that
way runs the very case ``controller = "rosco"`` runs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from wtftc import config, controller
from wtftc.campaign import cases
from wtftc.campaign.compare import column_tables, resolve_columns
from wtftc.errors import ConfigError
from wtftc.openfast import engine
from wtftc.sim import rosco

T_FINAL = 20.0
WIND = {"kind": "constant", "speed_mps": 16.0}
#: a lock of blade 1 halfway, so that the fault library acts too (the sensors' noise acts
#: throughout: the realistic profile, OpenFAST's default)
FAULT = [{"blade": 1, "type": "lock", "onset_s": 10.0, "angle_deg": "current"}]
BASE = {"engine": "openfast", "t_final_s": T_FINAL, "wind": WIND}


def _rosco_files() -> tuple[Path, Path]:
    return rosco.discon_library(), rosco.discon_path(rosco.NREL5MW_DISCON)


def _users_input(folder: Path) -> Path:
    """ROSCO's NREL 5-MW DISCON.IN and the Cp file it names, in a user's folder."""
    _, inp = _rosco_files()
    folder.mkdir(parents=True, exist_ok=True)
    for f in (inp, inp.parent / "Cp_Ct_Cq.NREL5MW.txt"):
        shutil.copy2(f, folder / f.name)
    return folder / inp.name


def _table(lib, inp, **more) -> dict:
    return {"design": "discon", "library": str(lib), "input": str(inp), **more}


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    """The same 20-s case at 16 m/s with blade 1 locking at 10 s, run by ROSCO's own
    library as design = "discon" (its input file in a user's folder) and as controller =
    "rosco"."""
    base = tmp_path_factory.mktemp("discon")
    lib, _ = _rosco_files()
    inp = _users_input(base / "user")
    runs = {}
    for name, keys in (("discon", {"controller": _table(lib, inp)}),
                       ("rosco", {"controller": "rosco", "case": 2})):
        rc = config.make_config({**BASE, **keys, "fault": FAULT})
        runs[name] = (rc, cases.run(rc, progress=False, openfast_dir=base / name),
                      base / name)
    return runs, inp


def test_rosco_as_a_discon_library_gives_rosco_s_traces_bit_for_bit(both):
    """Same library, same input values, same deck, same actuator, fault and noise: the
    same arithmetic, so the tolerance is none (bit-identical), every OpenFAST channel and
    every output column; ROSCO's copy of its input (logging off, the Cp file by absolute
    path) changes no control value."""
    runs, inp = both
    (rc_d, d, fd), (rc_r, r, fr) = runs["discon"], runs["rosco"]
    assert rc_d.raw["controller"] == "discon" and rc_d.case == rc_r.case == 2
    assert d.diverged is None and r.diverged is None
    assert np.array_equal(d.t, r.t) and d.t[-1] == pytest.approx(T_FINAL)
    assert d.full_names == r.full_names
    assert np.array_equal(d.full, r.full, equal_nan=True)
    assert np.array_equal(d.outputs, r.outputs, equal_nan=True)
    od, orr = engine.read_outb(fd / "NREL-5MW.outb"), engine.read_outb(fr / "NREL-5MW.outb")
    assert od.keys() == orr.keys()
    assert all(np.array_equal(od[k], orr[k]) for k in od)
    # not two idle runs: blade 1 holds its angle once the lock has stopped it (within 1 s
    # of the onset: the actuator's own motion decays) while the others keep pitching, by
    # more than 0.1 deg, and the rotor speed moves
    beta = {j: od[f"BldPitch{j}"] for j in (1, 2, 3)}
    after = od["Time"] > 11.0
    assert np.ptp(beta[1][after]) < 1e-3 and np.ptp(beta[2][after]) > 0.1
    assert np.ptp(od["RotSpeed"]) > 0.05
    # the library and the input file the table named are what the plant library loads
    text = (fd / "wtftc_plant.in").read_text()
    assert f"controller_library {_rosco_files()[0].resolve()}" in text
    assert f"controller_infile {inp}" in text
    assert "controller_infile controller/DISCON.IN" in (fr / "wtftc_plant.in").read_text()


def test_a_run_keeps_the_files_and_their_hashes_and_reruns_from_its_record(both, tmp_path):
    """A saved run's config.toml: controller = "discon" and [discon] with the absolute
    paths and their sha256, which make_config takes back as they are."""
    runs, inp = both
    rc, res, _ = runs["discon"]
    assert res.config["discon"] == rc.raw["discon"]
    (tmp_path / "config.toml").write_text(config.to_toml(rc.raw))
    saved = config.load_toml(tmp_path / "config.toml")
    assert saved["controller"] == "discon"
    assert saved["discon"] == {"library": str(_rosco_files()[0]), "input": str(inp),
                               "library_sha256": controller.sha256_of(_rosco_files()[0]),
                               "input_sha256": controller.sha256_of(inp)}
    again = config.make_config(saved)
    assert again.raw["discon"] == saved["discon"] and again.loop == rc.loop
    assert np.array_equal(again.initial_state(), rc.initial_state())


def _elf_copy(tmp_path: Path) -> Path:
    lib = tmp_path / "libmine.so"
    shutil.copy2(_rosco_files()[0], lib)
    return lib


def test_a_changed_library_or_input_is_refused_not_run(tmp_path):
    """A hash given that the file no longer has is refused naming the key, from a table,
    from a run's saved [discon], and in the engine between the check and the run."""
    lib, inp = _elf_copy(tmp_path), _users_input(tmp_path / "user")
    c = controller.parse(_table(lib, inp))
    files = dict(c.files)
    rc = config.make_config({**BASE, "controller": "discon", "discon": files})
    with open(lib, "ab") as f:
        f.write(b"\0")
    with pytest.raises(ConfigError) as e:
        controller.parse(_table(lib, inp, library_sha256=files["library_sha256"]))
    assert e.value.field == "controller.library_sha256" and "changed" in str(e.value)
    with pytest.raises(ConfigError) as e:
        config.make_config({**BASE, "controller": "discon", "discon": files})
    assert e.value.field == "discon.library_sha256"
    with pytest.raises(ConfigError) as e:  # the run made before the change
        engine.controller_library(rc, tmp_path / "case")
    assert e.value.field == "discon.library_sha256"
    inp.write_text(inp.read_text() + "\n")
    with pytest.raises(ConfigError) as e:
        config.make_config({**BASE, "controller": {**_table(lib, inp), "input_sha256":
                                                   files["input_sha256"]}})
    assert e.value.field == "controller.input_sha256"


def _bad_elf(tmp_path: Path) -> Path:
    """An ELF file that is no shared object (e_type 2, an executable)."""
    head = bytearray(64)
    head[:6] = b"\x7fELF\x02\x01"
    head[16] = 2
    path = tmp_path / "exe.so"
    path.write_bytes(bytes(head))
    return path


@pytest.mark.parametrize("case", ["not_elf", "executable", "folder", "missing", "no_input",
                                  "input_folder", "fdi", "setting", "wtftc", "case4",
                                  "stray_table", "beside_table", "torque", "unknown_key"])
def test_refusals_are_one_line_naming_the_key(tmp_path, case):
    lib, inp = _elf_copy(tmp_path), _users_input(tmp_path / "user")
    tab = _table(lib, inp)
    cfg, field = {
        "not_elf": ({"controller": _table(inp, inp)}, "controller.library"),
        "executable": ({"controller": _table(_bad_elf(tmp_path), inp)}, "controller.library"),
        "folder": ({"controller": _table(tmp_path, inp)}, "controller.library"),
        "missing": ({"controller": _table(tmp_path / "no.so", inp)}, "controller.library"),
        "no_input": ({"controller": {k: v for k, v in tab.items() if k != "input"}},
                     "controller.input"),
        "input_folder": ({"controller": _table(lib, tmp_path)}, "controller.input"),
        "fdi": ({"controller": {**tab, "accommodation": "fdi"}}, "controller.accommodation"),
        "setting": ({"controller": {**tab, "zeta": 0.7}}, "controller.zeta"),
        "wtftc": ({"controller": tab, "engine": "wtftc"}, "controller.design"),
        "case4": ({"controller": "discon", "discon": tab | {"design": None}, "case": 4},
                  "case"),
        "stray_table": ({"controller": "rosco", "discon": {"library": str(lib)}}, "discon"),
        "beside_table": ({"controller": tab, "discon": {"library": str(lib)}}, "discon"),
        "torque": ({"controller": tab, "turbine_params": {"gen_torque_law": 1.0}},
                   "turbine_params.gen_torque_law"),
        "unknown_key": ({"controller": "discon", "discon": {"library": str(lib),
                                                            "input": str(inp), "x": 1}},
                        "discon.x"),
    }[case]
    if case == "case4":
        cfg["discon"] = {"library": str(lib), "input": str(inp)}
    raw = {**BASE, **cfg}
    if case == "wtftc":
        raw = {k: v for k, v in raw.items() if k != "engine"}
    with pytest.raises(ConfigError) as e:
        config.make_config(raw)
    assert e.value.field == field, str(e.value)
    assert "\n" not in str(e.value)


def test_a_relative_path_is_the_running_folder_s_and_kept_absolute(tmp_path, monkeypatch):
    lib, inp = _elf_copy(tmp_path), _users_input(tmp_path / "user")
    monkeypatch.chdir(tmp_path)
    c = controller.parse({"design": "discon", "library": "libmine.so",
                          "input": "user/DISCON.IN"})
    assert dict(c.files)["library"] == str(lib) and dict(c.files)["input"] == str(inp)
    assert c.accommodation == "none"
    assert c.run_keys(True, torque_default=True) == {"controller": "discon", "case": 2,
                                                     "discon": dict(c.files)}


def test_a_sweep_column_survives_its_record_and_its_run_ids(tmp_path):
    """A column with design = "discon" resolved as a sweep resolves it, its table() (what
    sweep.json keeps) parsed again to the same settings, and the sweep's runs: their
    configurations carry the files and hashes, are valid runs, and keep their ids when the
    sweep is read back from its record."""
    from wtftc.campaign.sweep import expand, parse_sweep
    from wtftc.campaign.sweep.summary import _sweep_of

    lib, inp = _elf_copy(tmp_path), _users_input(tmp_path / "user")
    entry = {"name": "mine", **_table(lib, inp)}
    cols = resolve_columns([entry])
    rec = json.loads(json.dumps(column_tables(cols)))
    assert rec[0]["library_sha256"] == controller.sha256_of(lib)
    assert resolve_columns(rec) == cols
    assert controller.parse({k: v for k, v in rec[0].items() if k != "name"}) == cols["mine"]
    raw = {"engine": "openfast", "controllers": [entry, "rosco"], "t_final_s": T_FINAL,
           "wind": {"mean_mps": 16.0}, "fault": {"type": ["none", "lock"]}}
    sw = parse_sweep(raw)
    runs, _ = expand(sw)
    mine = [pt for pt in runs if pt["controller"] == "mine"]
    assert mine and all(pt["config"]["discon"] == dict(cols["mine"].files) for pt in mine)
    for pt in mine:
        probe = {**pt["config"], "wind": {"kind": "constant", "speed_mps": 16.0}}
        assert config.make_config(probe).raw["controller"] == "discon"
    meta = {"sweep": raw, **json.loads(json.dumps(sw.record()))}
    back = _sweep_of(meta, Path("unused"))
    assert back.columns["mine"] == sw.columns["mine"]
    assert [pt["run_id"] for pt in expand(back)[0]] == [pt["run_id"] for pt in runs]


def test_a_runs_turbsim_field_is_the_one_rosco_s_run_reads(tmp_path, monkeypatch):
    """The TurbSim field made before a run (wtftc.openfast.turbsim.make_field reads it on
    wtftc's own plant, where a DISCON library does not run) is the wind's, turbine's and
    length's: the field of the same run with controller = "rosco"."""
    from wtftc.openfast import turbsim

    lib, inp = _elf_copy(tmp_path), _users_input(tmp_path / "user")
    monkeypatch.setattr(turbsim, "generate", lambda field: field)
    wind = {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B", "field": "turbsim"}
    files = {"library": str(lib), "input": str(inp)}
    made = [turbsim.make_field({**BASE, "wind": wind, "seed": 3, **keys}) for keys in (
        {"controller": _table(lib, inp)}, {"controller": "discon", "discon": files},
        {"controller": "rosco"})]
    assert made[0] == made[1] == made[2]
    assert (made[0].seed, made[0].mean_mps) == (3, 16.0)
