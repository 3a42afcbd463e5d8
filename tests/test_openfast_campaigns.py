"""Campaigns in OpenFAST (issue 32 item 8): `wtftc sweep --engine openfast` (one run a Dask
task, each case kept under the results folder, resumable) and `wtftc compare --engine
openfast` (its cells as Dask tasks); the FDI report's ``ran``; keys OpenFAST has no
meaning for refused in one line. Short runs (12 s and 10 s simulated): `make test` gets
OpenFAST first."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wtftc.campaign import cluster, compare, sweep
from wtftc.cli import main
from wtftc.errors import ConfigError
from wtftc.openfast.case import get_value
from wtftc.results.metrics import NO_FDI, fdi_ran

SWEEP = """t_final_s = 12.0
controllers = ["rosco", "physical-plain"]
[wind]
mean_mps = 16.0
seed = 0
"""


def wtftc(*args, **kw):
    return subprocess.run([sys.executable, "-m", "wtftc.cli", *map(str, args)],
                          capture_output=True, text=True, **kw)


def _outb_rms(case: Path, t0: float, reference: float) -> float:
    """The RMS rotor-speed error from the case's own OpenFAST output, read here."""
    from openfast_io.FAST_output_reader import FASTOutputFile

    f = FASTOutputFile(str(case / "NREL-5MW.outb"))
    ch = {n: f.data[:, i] for i, n in enumerate(f.info["attribute_names"])}
    keep = ch["Time"] >= t0 - 1e-9
    return float(np.sqrt(np.mean((ch["RotSpeed"][keep] * math.pi / 30 - reference) ** 2)))


def test_a_sweep_in_openfast_on_two_workers_keeps_each_case_and_resumes(tmp_path):
    """Two runs (ROSCO, the physical AFTC with its FDI), one Dask task each on a local
    cluster of 2 workers: the dataset's rows, each run's case in openfast/<run id>/ (its
    metrics those of its own .outb, its paths its own folder, every file recorded), and a
    second call that runs nothing."""
    f = tmp_path / "of.toml"
    f.write_text(SWEEP)
    out = tmp_path / "res"
    p = wtftc("sweep", f, "--engine", "openfast", "--workers", 2, "--out", out, timeout=600)
    assert p.returncode == 0, p.stderr
    assert "2 to run one a task" in p.stdout and "2 of 2 saved" in p.stdout
    rows = {r["controller"]: r for r in sweep.read_results(out).to_pylist()}
    assert set(rows) == {"rosco", "physical-plain"}
    assert all(r["status"] == "ok" and r["plant"] == "openfast" for r in rows.values())
    assert all(json.loads(r["config_json"])["engine"] == "openfast" for r in rows.values())
    # ROSCO's library has no FDI: no false alarms to count, none to judge
    assert rows["rosco"]["false_alarms"] is None and rows["rosco"]["isolation_correct"] is None
    assert rows["physical-plain"]["false_alarms"] == 0
    record = (out / ".wtftc-sweep-written").read_text()
    for r in rows.values():
        case = out / "openfast" / r["run_id"]
        cfg = json.loads(r["config_json"])
        from wtftc import config

        rc = config.make_config(cfg)
        assert r["rms_speed_error_rad_s"] == pytest.approx(
            _outb_rms(case, r["transient_s"], rc.reference), rel=1e-9)
        servo = case / get_value(case / "NREL-5MW.fst", "ServoFile")
        named = get_value(servo, "DLL_InFile").strip('"')
        settings = servo.parent / named  # relative to ServoDyn's file: reruns when moved
        assert not Path(named).is_absolute() and settings.is_file()
        assert settings.resolve().parent == case.resolve()
        assert f'"path":"openfast/{r["run_id"]}/NREL-5MW.outb"' in record
    stamp = (out / "openfast" / rows["rosco"]["run_id"] / "NREL-5MW.outb").stat().st_mtime_ns

    again = wtftc("sweep", f, "--engine", "openfast", "--workers", 2, "--out", out,
                  timeout=300)
    assert again.returncode == 0, again.stderr
    assert "2 already in" in again.stdout and "0 to run" in again.stdout
    assert "0 runs done now, 2 of 2 saved" in again.stdout
    assert (out / "openfast" / rows["rosco"]["run_id"] / "NREL-5MW.outb").stat(
        ).st_mtime_ns == stamp
    # the same folder without --engine: refused in one line naming the engine to resume with
    native = wtftc("sweep", f, "--out", out, timeout=120)
    assert native.returncode == 2 and native.stderr.count("\n") == 1
    assert "--engine openfast" in native.stderr
    summary = wtftc("sweep", "--summary", out, timeout=120)
    assert summary.returncode == 0, summary.stderr
    assert "2 of 2 runs saved" in summary.stdout


def test_compare_in_openfast_runs_its_cells_as_dask_tasks(tmp_path, monkeypatch):
    """Two cells on a local cluster of 2 workers: the same tree and table as one after
    the other; the FDI report says whether an FDI ran."""
    made = []
    real = cluster.client

    def client(scheduler, workers):
        made.append(workers)
        return real(scheduler, workers)

    monkeypatch.setattr(cluster, "client", client)
    out = tmp_path / "cmp"
    code = main(["compare", "--engine", "openfast", "--controllers", "rosco", "physical-plain",
                 "--faults", "none", "--winds", "steady_16", "--t-final", "10", "--workers",
                 "2", "--quiet", "--out", str(out)])
    assert code == 0 and made == [2]
    rows = (out / "compare.csv").read_text().splitlines()
    assert [r.split(",")[2] for r in rows[1:]] == ["rosco", "physical-plain"]
    assert rows[1].endswith(",") and rows[2].endswith(",0")  # ROSCO: no FDI ("—")
    for c, ran in (("rosco", False), ("physical-plain", True)):
        cell = out / "steady_16" / "none" / c
        assert (cell / "openfast" / "NREL-5MW.outb").is_file() and (cell / "config.toml").is_file()
        m = json.loads((cell / "metrics.json").read_text())
        assert m["fdi"]["ran"] is ran and fdi_ran(m["fdi"]) is ran
    assert "| steady_16 | none | rosco |" in (out / "compare.md").read_text()


def test_the_fdi_report_says_whether_an_fdi_ran_and_old_metrics_still_read():
    """``ran``: false with nothing detected for a run without the FDI; a metrics.json from
    before the flag (null without an FDI, a report without ``ran`` with one) reads the
    same through fdi_ran, and its row in compare's table too."""
    assert NO_FDI["ran"] is False and not NO_FDI["blades"] and not NO_FDI["false_alarms"]
    assert fdi_ran(None) is False and fdi_ran({"blades": {}, "false_alarms": []}) is True
    assert fdi_ran(dict(NO_FDI)) is False
    old = {"fdi": None, "diverged": None}
    assert compare._row("rosco", "none", "steady_16", old, False)["false_alarms"] is None
    new = {"fdi": dict(NO_FDI), "diverged": None}
    assert compare._row("rosco", "none", "steady_16", new, False)["false_alarms"] is None


@pytest.mark.parametrize("change, key", [
    ({"plants": ["tower"]}, "plants"),
    ({"mismatch": {"J_r": 1.1}}, "mismatch"),
    ({"batch_size": 8}, "batch_size"),
    ({"profile": "ideal"}, "profile"),
    ({"controllers": ["paper"], "fault": {"type": ["none", "lock"]}}, "controllers"),
    ({"engine": "fast"}, "engine"),
])
def test_keys_without_meaning_in_openfast_are_refused_before_any_run(change, key):
    raw = {"t_final_s": 12.0, "controllers": ["pi"], "engine": "openfast", **change}
    with pytest.raises(ConfigError) as exc:
        sweep.parse_sweep(raw)
    assert exc.value.field == key


def test_a_refused_key_is_one_line_and_writes_nothing(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('plants = ["nrel5mw", "tower"]\n' + SWEEP)
    p = wtftc("sweep", f, "--engine", "openfast", "--out", tmp_path / "out", timeout=120)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "Traceback" not in p.stderr
    assert "plants" in p.stderr and "engine = openfast" in p.stderr
    assert not (tmp_path / "out").exists()
    f.write_text('engine = "wtftc"\n' + SWEEP)  # the file's engine and --engine disagree
    p = wtftc("sweep", f, "--engine", "openfast", "--out", tmp_path / "out", timeout=120)
    assert p.returncode == 2 and "--engine" in p.stderr and not (tmp_path / "out").exists()


def test_an_openfast_sweep_has_its_own_ids_and_a_native_one_keeps_its_ids():
    """engine is part of a sweep's id (its runs are other runs); a native sweep's id and
    run ids are those it had before the key existed."""
    base = {"t_final_s": 12.0, "controllers": ["pi"]}
    native, same, of = (sweep.parse_sweep(base), sweep.parse_sweep({**base, "engine": "wtftc"}),
                        sweep.parse_sweep({**base, "engine": "openfast"}))
    assert native.sweep_id == same.sweep_id != of.sweep_id
    (run,), _ = sweep.expand(of)
    assert run["config"]["engine"] == "openfast" and "plant" not in run["config"]
    assert run["plant"] == "openfast" and of.batch_size == 1
    assert sweep.expand(native)[0][0]["run_id"] != run["run_id"]


def test_the_progress_of_runs_in_flight_is_read_from_openfasts_log(tmp_path):
    log = tmp_path / "openfast.log"
    log.write_text(" OpenFAST\n Time: 5 of 120 seconds.  Estimated final completion at x.\r"
                   " Time: 35 of 120 seconds.  Estimated final completion at x.\r")
    assert cluster.simulated(tmp_path, 0.0) == (35.0, 120.0)
    assert cluster.simulated(tmp_path, log.stat().st_mtime + 10) is None  # an older attempt
    assert cluster.simulated(tmp_path / "none", 0.0) is None
    assert cluster.describe(cluster.in_flight([tmp_path], 0.0)) == "1 in OpenFAST at 35/120 s"
    assert "50 % simulated" in cluster.describe([(60.0, 120.0)] * 5)


def test_the_measured_matrix_names_its_columns_and_winds_beside_the_default():
    """docs/openfast.md's matrix (rosco, pi, physical-plain, paper-fdi × every fault ×
    steady 16, steady 20, NTM B 12 and 16) is nameable; a bare `wtftc compare` keeps its
    three winds."""
    assert compare.DEFAULT_WINDS == ("paper_random_12", "ntm_B_16", "eog_rated")
    cols = compare.resolve_columns(["rosco", "pi", "physical-plain", "paper-fdi"])
    cfg = compare.cell_config("paper-fdi", "runaway", "steady_20", 30.0, 1e-3, 0,
                              engine="openfast", ctrl=cols["paper-fdi"])
    assert (cfg["controller"], cfg["case"], cfg["engine"]) == ("paper", 4, "openfast")
    assert cfg["wind"] == {"kind": "constant", "speed_mps": 20.0}
    assert compare.WINDS["ntm_B_12"]["mean_mps"] == 12.0


def test_the_sweep_file_in_the_docs_is_a_valid_openfast_sweep():
    """docs/openfast.md's false-alarm sweep file: 9 runs in OpenFAST, NTM B 8-24 m/s."""
    import re
    import tomllib

    text = (Path(__file__).resolve().parents[1] / "docs" / "openfast.md").read_text()
    block = re.search(r"`of_false_alarms\.toml`.*?```toml\n(.*?)```", text, re.S).group(1)
    sw = sweep.parse_sweep(tomllib.loads(block))
    runs, _ = sweep.expand(sw)
    assert sw.engine == "openfast" and len(runs) == 9
    assert [r["mean_wind_mps"] for r in runs] == [8.0 + 2 * k for k in range(9)]
