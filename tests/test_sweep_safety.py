"""`wtftc sweep`: --overwrite deletes only what a sweep wrote (issue 30, defect 1), and
--retry-failed runs again the runs saved as failed; every sweep's last line says how many
failed (defect 8).

The results folders are built here with the store's own functions (no Dask), so that only
the one retry below starts a cluster (a one-run sweep of 2 s)."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pyarrow.parquet as pq
import pytest

pytest.importorskip("distributed", reason="Dask: pip install 'wtftc[sweep]'")

from wtftc import cli  # noqa: E402
from wtftc.campaign import sweep  # noqa: E402
from wtftc.campaign.sweep import store, tasks  # noqa: E402
from wtftc.errors import ConfigError  # noqa: E402

#: the smallest sweep: one run of the PI, 2 s (tests/test_sweep.py's last test)
ONE_RUN = """name = "one run"
mode = "grid"
t_final_s = 2.0
controllers = ["pi"]
"""
#: three runs, for rows of each status
THREE_RUNS = """mode = "grid"
t_final_s = 2.0
controllers = ["pi"]
[wind]
mean_mps = [14.0, 16.0, 18.0]
"""


def _sweep_file(tmp_path: Path, text: str = ONE_RUN) -> Path:
    f = tmp_path / "s.toml"
    f.write_text(text)
    return f


def _results_folder(f: Path, out: Path, statuses: tuple[str, ...]) -> list[dict]:
    """A results folder of sweep file ``f`` as a sweep leaves it, its runs saved with
    ``statuses`` (rows made by the task's own function; no run is run)."""
    sw = sweep.load_sweep(f)
    runs, _ = sweep.expand(sw)
    done, lock = store._prepare(out, sw, f.read_text(), overwrite=False)[:2]
    try:
        rows = []
        for pt, status in zip(runs, statuses, strict=False):
            cause = "MemoryError: a worker ran out of memory" if status == "failed" else None
            diverged = ({"t_s": 1.5, "reason": "rotor overspeed", "last_finite_state": {}}
                        if status == "diverged" else None)
            rows.append((tasks._row(pt, status, cause=cause, diverged=diverged), None))
        store._save_batch(out, done, rows)
    finally:
        store.release(lock)
    return runs


def _written_by_a_sweep(out: Path) -> None:
    """Everything else a sweep writes there: traces, the summary's tables and figures, and
    the hidden temporaries a killed sweep's atomic writes leave."""
    (out / "traces").mkdir()
    (out / "traces" / "0123456789abcdef.parquet").write_bytes(b"PAR1")
    (out / "traces" / ".0123456789abcdef.parquet.x1y2z3ab").write_bytes(b"PAR1")
    (out / "runs" / ".part-0123456789abcdef.parquet.k2j3h4cd").write_bytes(b"PAR1")
    for name in ("summary.md", "summary.csv", "summary_cost.csv", "summary_dlc.csv",
                 "summary_tuning.csv", ".summary.md.q9w8e7rt", ".sweep.json.abcd_123"):
        (out / name).write_text("table\n")
    (out / "figures").mkdir()
    for name in ("rms_speed_error.png", "rms_speed_error.pdf", "dlc_bins.png",
                 ".rms_speed_error.a1b2c3d4.png"):
        (out / "figures" / name).write_bytes(b"\x89PNG")


def _snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() and not p.is_symlink()
                                         else os.readlink(p) if p.is_symlink() else None,
                                         stat.S_IMODE(p.lstat().st_mode))
            for p in sorted(folder.rglob("*"))}


# ------------------------------------------------------------------------- --overwrite

@pytest.mark.parametrize("theirs", ["notes.txt", "runs/my_analysis.csv", "runs/part-1.parquet",
                                    "traces/mydata.parquet", "figures/paper.png",
                                    "figures/drafts/", ".summary.md.bak", "traces->",
                                    "sweep.json->"])
def test_overwrite_refuses_a_sweep_folder_holding_anything_else_and_deletes_nothing(
        theirs, tmp_path, capsys):
    """--overwrite used to delete every child of --out once it held a sweep.json: a
    user's notes beside the results went with them. Now a file, a folder or a symbolic
    link the sweep did not write (a figure in a subfolder of figures/, a traces/ that
    links elsewhere) makes the folder refused whole, in one line naming --out."""
    f = _sweep_file(tmp_path)
    out = tmp_path / "res"
    _results_folder(f, out, ("ok",))
    _written_by_a_sweep(out)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "precious.parquet").write_text("keep")
    if theirs.endswith("->"):  # a symbolic link at a name the sweep writes
        target = out / theirs[:-2]
        if target.is_dir():
            for p in target.iterdir():
                p.unlink()
            target.rmdir()
        else:
            target.unlink()
        target.symlink_to(elsewhere / "precious.parquet" if target.name == "sweep.json"
                          else elsewhere)
    elif theirs.endswith("/"):
        (out / theirs).mkdir()
    else:
        (out / theirs).write_text("mine")
    before, outside = _snapshot(out), _snapshot(elsewhere)
    code = cli.main(["sweep", str(f), "--out", str(out), "--overwrite"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith(f"wtftc: error: --out = '{out}'") and err.count("\n") == 1, err
    assert "nothing was deleted" in err and theirs.rstrip("/->") in err, err
    assert _snapshot(out) == before and _snapshot(elsewhere) == outside
    with pytest.raises(ConfigError) as exc:  # the library refuses it the same way
        sweep.run_sweep(f, out, workers=1, overwrite=True, quiet=True)
    assert exc.value.field == "--out"
    assert _snapshot(out) == before


def test_overwrite_deletes_what_a_sweep_wrote_and_starts_anew(tmp_path):
    """A folder holding only what a sweep wrote is emptied of it (the runs, traces,
    summary, figures, temporaries) and begun again with the new sweep file."""
    old = _sweep_file(tmp_path, THREE_RUNS)
    out = tmp_path / "res"
    _results_folder(old, out, ("ok", "diverged", "failed"))
    _written_by_a_sweep(out)
    new = tmp_path / "new.toml"
    new.write_text(ONE_RUN)
    sw = sweep.load_sweep(new)
    done, lock = store._prepare(out, sw, new.read_text(), overwrite=True)[:2]
    store.release(lock)
    assert done == set()
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == [
        "runs", "sweep.json", "sweep.toml"]
    assert (out / "sweep.toml").read_text() == ONE_RUN


def test_a_folder_that_is_not_a_sweeps_is_refused_with_or_without_overwrite(tmp_path):
    f = _sweep_file(tmp_path)
    out = tmp_path / "mine"
    (out / "runs").mkdir(parents=True)  # a name a sweep uses does not make it a sweep's
    (out / "runs" / "part-0.parquet").write_text("mine")
    before = _snapshot(out)
    for overwrite in (False, True):
        with pytest.raises(ConfigError) as exc:
            sweep.run_sweep(f, out, workers=1, overwrite=overwrite, quiet=True)
        assert exc.value.field == "--out"
        assert _snapshot(out) == before


# ----------------------------------------------------------------------- --retry-failed

def test_drop_failed_keeps_diverged_runs_and_rewrites_batches(tmp_path):
    """A diverged run is a result (its time, state and cause) and stays; a failed one
    (the run raised) is removed, its batch file rewritten without it, or removed when it
    held nothing else."""
    f = _sweep_file(tmp_path, THREE_RUNS)
    out = tmp_path / "res"
    runs = _results_folder(f, out, ("ok", "diverged", "failed"))
    # and a second batch holding a failed run alone
    sw = sweep.load_sweep(f)
    only_failed = {**runs[2], "run_id": "another"}
    store._save_batch(out, set(), [(tasks._row(only_failed, "failed", cause="E: x"), None)])
    assert len(list((out / "runs").glob("part-*.parquet"))) == 2
    assert sweep.count_status(out) == {"ok": 1, "diverged": 1, "failed": 2}
    done, lock, retried = store._prepare(out, sw, f.read_text(), overwrite=False,
                                         retry_failed=True)
    store.release(lock)
    assert retried == 2 and done == {runs[0]["run_id"], runs[1]["run_id"]}
    assert sweep.count_status(out) == {"ok": 1, "diverged": 1, "failed": 0}
    parts = list((out / "runs").glob("part-*.parquet"))
    assert len(parts) == 1 and pq.read_table(parts[0]).num_rows == 2
    assert not [p for p in (out / "runs").iterdir() if p.name.startswith(".")]


def test_retry_failed_runs_the_failed_runs_again_and_the_last_line_counts_failures(
        tmp_path, capsys):
    """A run saved as failed (here: its worker ran out of memory) stayed failed on every
    resume. The last line of every sweep now says how many failed, and --retry-failed
    runs them again."""
    f = _sweep_file(tmp_path)
    out = tmp_path / "res"
    (run,) = _results_folder(f, out, ("failed",))
    assert cli.main(["sweep", str(f), "--out", str(out), "--quiet"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert "1 of 1 saved" in last and "; 1 failed" in last and "--retry-failed" in last
    assert sweep.count_status(out)["failed"] == 1
    assert cli.main(["sweep", str(f), "--out", str(out), "--retry-failed", "--workers", "1",
                     "--quiet"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("1 runs done now, 1 of 1 saved") and "; 0 failed" in last, last
    table = sweep.read_results(out)
    assert table.column("run_id").to_pylist() == [run["run_id"]]
    assert table.column("status").to_pylist() == ["ok"]
