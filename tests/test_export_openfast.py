"""The exported library proven in plain OpenFAST: `wtftc export discon` of the NREL 5-MW's
recommended preset with its actuator, put into a copy of ROSCO's NREL 5-MW deck by the
export's README and nothing else, run by the openfast binary itself, equals `wtftc run
--engine openfast` of the same scenario (60 s of steady and of turbulent wind at 16 m/s).

The README's steps, as a user follows them: copy every file of the export into the
ServoDyn input file's folder; give ServoDyn the keys of servodyn_snippet.txt; set the
main file's DT to a whole fraction of DLL_DT; start ElastoDyn at the operating point
(from the wtftc run's case, OUT/openfast/); give InflowWind that run's wind file and the
plant library that run's noise table. The user's own choices of a scenario: TMax and a
binary output (OutFileFmt)."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from wtftc import config
from wtftc.campaign import cases
from wtftc.export import discon
from wtftc.model import turbine_file
from wtftc.openfast import install, plant_library, turbsim

PRESET = "aftc-nrel5mw"
T_FINAL = 60.0
SEED = 3
WINDS = {"steady": {"kind": "constant", "speed_mps": 16.0},
         "turbulent": {"kind": "ntm", "mean_mps": 16.0}}
#: the channels the deck's own OutList must share with the one wtftc's case sets for the
#: comparison to mean something (every shared channel is compared): the rotor, the
#: generator, a blade, the tower top, the wind
NEEDED = ("RotSpeed", "GenSpeed", "BldPitch1", "GenTq", "GenPwr", "RotTorq", "TwrBsMyt",
          "TTDspFA", "Wind1VelX")
#: the tolerance, relative to each channel's range over the run. The two runs are the
#: same openfast binary on the same machine, the same controller library (the same C from
#: the same generated code, compiled by the same compiler with the same flags: the .IN
#: values are asserted equal), the same plant library, deck, wind file, noise draws and
#: initial conditions (copied as text). What differs is only what the case files hold
#: beside the dynamics (the OutList, node outputs, echo, paths), so the runs are replicas:
#: bit-identical on this machine (every shared channel, steady and turbulent, difference
#: 0). The tolerance is what another machine could need without anything being wrong:
#: none of the arithmetic differs between the two runs there either, but a libm or BLAS
#: that picks its kernels at run time (by CPU, alignment or threads) could move a last
#: bit in one run; grown by the closed loop over 60 s that stays orders below 1e-9 of a
#: channel's range, while any real difference (a value of the .IN, an initial condition,
#: a wind sample, a noise draw) moves the channels by far more.
RTOL = 1e-9


def _set(path: Path, key: str, value: str) -> None:
    """An OpenFAST input line ``value  key  - ...``: its value replaced (as a user's
    editor does it)."""
    text = path.read_text()
    new, n = re.subn(rf"^(\s*)(\"[^\"]*\"|\S+)(\s+{re.escape(key)}(?=\s|$))", rf"\g<1>{value}\g<3>",
                     text, count=1, flags=re.MULTILINE)
    assert n == 1, f"{key} not in {path}"
    path.write_text(new)


def _get(path: Path, key: str) -> str:
    m = re.search(rf"^\s*(\"[^\"]*\"|\S+)\s+{re.escape(key)}(?=\s|$)", path.read_text(),
                  flags=re.MULTILINE)
    assert m, f"{key} not in {path}"
    return m.group(1)


def _snippet(path: Path) -> dict[str, str]:
    """servodyn_snippet.txt's keys and values (its lines ``value  key  - ...``)."""
    out = {}
    for line in path.read_text().splitlines():
        m = re.match(r"\s*(\"[^\"]*\"|\S+)\s+([A-Za-z_]\w*)\s", line)
        if m and not line.lstrip().startswith(("!", "-")):
            out[m.group(2)] = m.group(1)
    return out


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> Path:
    """`wtftc export discon --preset aftc-nrel5mw --with-actuator`."""
    return discon.export({"controller": {"preset": PRESET}},
                         tmp_path_factory.mktemp("export") / "aftc",
                         with_actuator=plant_library.add_to_export)


def _wtftc_run(wind: dict, out: Path):
    """`wtftc run --engine openfast --preset aftc-nrel5mw` of the scenario, its case kept
    in ``out`` (the run folder's openfast/)."""
    cfg = {"controller": {"preset": PRESET}, "engine": "openfast", "wind": wind,
           "t_final_s": T_FINAL, "seed": SEED}
    turbsim.ensure_field(cfg)  # what `wtftc run` does before the configuration
    rc = config.make_config(cfg)
    return rc, cases.run(rc, progress=False, openfast_dir=out)


def _users_deck(exported: Path, run_case: Path, deck: Path) -> Path:
    """ROSCO's NREL 5-MW deck, copied, with the export put in as its README says; the
    scenario (operating point, wind, noise) taken from the wtftc run's case. Returns the
    main file."""
    src = config.openfast_deck(turbine_file.load("nrel5mw"))
    shutil.copytree(src.parent, deck)
    fst = deck / src.name
    servo = deck / _get(fst, "ServoFile").strip('"')
    ed = deck / _get(fst, "EDFile").strip('"')
    inflow = deck / _get(fst, "InflowFile").strip('"')
    for f in exported.iterdir():  # 1. every file beside the ServoDyn input file
        if f.is_file():
            shutil.copy2(f, servo.parent / f.name)
    for key, value in _snippet(exported / "servodyn_snippet.txt").items():  # 2.
        _set(servo, key, value)
    dll_dt = float(_snippet(exported / "servodyn_snippet.txt")["DLL_DT"])
    readme = (exported / "README.txt").read_text()
    dt = re.search(r"set DT to a whole fraction of DLL_DT = \S+ s, e\.g\.\s+(\S+) s", readme)
    _set(fst, "DT", dt.group(1))  # 3.
    assert abs(dll_dt / float(dt.group(1)) - round(dll_dt / float(dt.group(1)))) < 1e-9
    run_ed = run_case / _get(run_case / fst.name, "EDFile").strip('"')
    for key in ("RotSpeed", "BlPitch(1)", "BlPitch(2)", "BlPitch(3)", "TTDspFA"):  # 4.
        _set(ed, key, _get(run_ed, key))
    _set(fst, "TMax", f"{T_FINAL:g}")  # the user's scenario: its length, a binary output
    _set(fst, "OutFileFmt", "2")
    run_inflow = run_case / _get(run_case / fst.name, "InflowFile").strip('"')
    kind = _get(run_inflow, "WindType")  # the run's wind file (the README's last section)
    _set(inflow, "WindType", kind)
    key = {"2": "Filename_Uni", "3": "FileName_BTS"}[kind]
    name = _get(run_inflow, key).strip('"')
    shutil.copy2(run_case / name, inflow.parent / name)
    _set(inflow, key, f'"{name}"')
    if kind == "2":
        _set(inflow, "RefHt_Uni", _get(run_inflow, "RefHt_Uni"))
    shutil.copy2(run_case / "wtftc_noise.bin", servo.parent / "wtftc_noise.bin")
    with open(servo.parent / plant_library.SETTINGS, "a") as f:  # the run's noise draws
        f.write(f"noise wtftc_noise.bin\nnoise_columns {plant_library.NOISE_COLUMNS[0]}\n")
    return fst


def _openfast(fst: Path) -> dict[str, np.ndarray]:
    """The openfast binary on ``fst`` in its folder; its .outb read."""
    done = subprocess.run([str(install.require().openfast), fst.name], cwd=fst.parent,
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0 and "OpenFAST terminated normally" in done.stdout, \
        done.stdout[-2000:] + done.stderr[-2000:]
    from openfast_io.FAST_output_reader import FASTOutputFile

    f = FASTOutputFile(str(fst.with_suffix(".outb")))
    return {n: f.data[:, i].astype(float) for i, n in enumerate(f.info["attribute_names"])}


def _params(path: Path) -> list[tuple[str, str]]:
    """The parameter lines of a .IN: (name, value), comments left out."""
    out = []
    for line in path.read_text().splitlines():
        words = line.split("!")[0].split()
        if len(words) == 2:
            out.append((words[0], words[1]))
    return out


@pytest.mark.parametrize("wind", list(WINDS))
def test_the_export_in_plain_openfast_runs_as_wtftc_runs_it(exported, tmp_path, wind):
    """60 s at 16 m/s, steady and turbulent (TurbSim's field, the run's seed): every
    channel plain OpenFAST with the export shares with the wtftc run equals it to RTOL of
    its range (bit for bit on this machine), the controller read the same values from
    both .IN files, and the run is a real one: the rotor near rated speed, the blades
    pitched."""
    rc, res = _wtftc_run(WINDS[wind], tmp_path / "wtftc")
    assert res.diverged is None
    run_case = tmp_path / "wtftc"
    assert _params(run_case / "controller" / "wtftc_physical.IN") == \
        _params(exported / "wtftc_physical.IN")
    fst = _users_deck(exported, run_case, tmp_path / "deck")
    mine = _openfast(fst)
    from openfast_io.FAST_output_reader import FASTOutputFile

    f = FASTOutputFile(str(next(run_case.glob("*.outb"))))
    theirs = {n: f.data[:, i].astype(float) for i, n in enumerate(f.info["attribute_names"])}
    assert np.array_equal(mine["Time"], theirs["Time"])
    assert mine["Time"][-1] == pytest.approx(T_FINAL)
    both = sorted(set(mine) & set(theirs) - {"Time"})
    assert set(NEEDED) <= set(both), both
    for ch in both:
        span = float(np.ptp(theirs[ch])) or 1.0
        err = float(np.max(np.abs(mine[ch] - theirs[ch]))) / span
        assert err <= RTOL, f"{ch}: {err:.3g} of its range"
    rated_rpm = rc.param("omega_g_rated") * 30 / math.pi
    assert abs(np.mean(mine["RotSpeed"][len(mine["RotSpeed"]) // 2:]) - rated_rpm) \
        < 0.05 * rated_rpm
    assert np.mean(mine["BldPitch1"]) > 5.0  # above rated: pitched to feather [deg]
