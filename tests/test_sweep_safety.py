"""`wtftc sweep`: it never deletes or overwrites a file it did not write (issue 30,
defect 1): --overwrite and --summary replace only what the folder's record
(``.wtftc-sweep-written``) lists, with its sha256, and never follow a symbolic link;
bad results folders are one line, never a traceback or a hang (defects 2, 4);
--retry-failed runs again the runs saved as failed, and every sweep's last line says how
many failed (defect 8).

The results folders are built here with the store's own functions (no Dask), so that only
the one retry below starts a cluster (a one-run sweep of 2 s)."""

from __future__ import annotations

import hashlib
import json
import os
import stat
from pathlib import Path

import pyarrow.parquet as pq
import pytest

pytest.importorskip("distributed", reason="Dask: pip install 'wtftc[sweep]'")

from conftest import no_hang  # noqa: E402

from wtftc import cli  # noqa: E402
from wtftc.campaign import sweep  # noqa: E402
from wtftc.campaign.sweep import record, store, tasks  # noqa: E402
from wtftc.campaign.sweep.record import RECORD, Record  # noqa: E402
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
PNG = b"\x89PNG\r\n\x1a\n" + b"\0" * 16 + b"IEND\xaeB`\x82"
PDF = b"%PDF-1.4\n%%EOF\n"


def _sweep_file(tmp_path: Path, text: str = ONE_RUN) -> Path:
    f = tmp_path / "s.toml"
    f.write_text(text)
    return f


def _results_folder(f: Path, out: Path, statuses: tuple[str, ...]) -> list[dict]:
    """A results folder of sweep file ``f`` as a sweep leaves it, its runs saved with
    ``statuses`` (rows made by the task's own function, with metrics; no run is run)."""
    sw = sweep.load_sweep(f)
    runs, _ = sweep.expand(sw)
    done, lock = store._prepare(out, sw, f.read_text(), overwrite=False)[:2]
    try:
        rows = []
        for pt, status in zip(runs, statuses, strict=False):
            cause = "MemoryError: a worker ran out of memory" if status == "failed" else None
            diverged = ({"t_s": 1.5, "reason": "rotor overspeed", "last_finite_state": {}}
                        if status == "diverged" else None)
            row = tasks._row(pt, status, cause=cause, diverged=diverged)
            if status != "failed":
                row.update({k: 1.0 for k, _ in store.METRICS}, false_alarms=0)
            rows.append((row, None))
        store._save_batch(out, done, rows, lock.record)
    finally:
        store.release(lock)
    return runs


def _killed_write(rec: Record, rel: str, data: bytes, complete: bool) -> str:
    """What a sweep killed as it wrote ``rel`` leaves: its line in the record and its
    hidden temporary, made (empty) or complete."""
    path = Path(rel)
    temp = str(path.parent / f".{path.name}.deadbeef.partial")
    rec._append(record._line(rel, len(data), hashlib.sha256(data).hexdigest(), temp))
    (rec.folder / temp).parent.mkdir(exist_ok=True)
    (rec.folder / temp).write_bytes(data if complete else b"")
    return temp


def _written_by_a_sweep(out: Path) -> None:
    """Everything else a sweep writes there, through its record: traces, the summary's
    tables and figures, and the temporaries a sweep killed as it wrote leaves."""
    rec = Record.open(out, "--out")
    rec.write("traces/0123456789abcdef.parquet", b"PAR1 a trace PAR1")
    for name in ("summary.md", "summary.csv", "summary_cost.csv", "summary_dlc.csv"):
        rec.write(name, b"table\n")
    for name in ("rms_speed_error.png", "dlc_bins.png"):
        rec.write(f"figures/{name}", PNG)
    rec.write("figures/rms_speed_error.pdf", PDF)
    _killed_write(rec, "runs/part-0123456789abcdef.parquet", b"PAR1 runs PAR1", True)
    _killed_write(rec, "traces/fedcba9876543210.parquet", b"PAR1 trace PAR1", False)
    _killed_write(rec, "summary.md", b"table\n", False)
    _killed_write(rec, "figures/overspeed.png", PNG, True)


def _legacy_folder(f: Path, out: Path) -> None:
    """A results folder as wtftc wrote it before the record existed: a summarized sweep,
    the hidden temporaries of its killed writes (tempfile's names), no record."""
    _results_folder(f, out, ("ok",))
    sweep.summarize(out)
    (out / RECORD).unlink()
    (out / ".summary.md.q9w8e7rt").write_text("# Sweep abc: 1 of 1 runs saved\n")
    (out / "runs" / ".part-0123456789abcdef.parquet.k2j3h4cd").write_bytes(b"")
    (out / "figures" / ".overspeed.a1b2c3d4.png").write_bytes(PNG[:12])


def _snapshot(folder: Path) -> dict:
    return {str(p.relative_to(folder)): (p.read_bytes() if p.is_file() and not p.is_symlink()
                                         else os.readlink(p) if p.is_symlink() else None,
                                         stat.S_IMODE(p.lstat().st_mode))
            for p in sorted(folder.rglob("*"))}


def _one_line(err: str, option: str, value) -> None:
    assert err.startswith(f"wtftc: error: {option} = '{value}' is not allowed: "), err
    assert err.count("\n") == 1 and "Traceback" not in err and "Errno" not in err, err


# ------------------------------------------------------------------------- --overwrite

@pytest.mark.parametrize("theirs", ["notes.txt", "runs/my_analysis.csv", "runs/part-1.parquet",
                                    "traces/mydata.parquet", "figures/paper.png",
                                    "figures/drafts/", ".summary.md.bak", "traces->",
                                    "sweep.json->", "summary_tuning.csv", "summary.md*",
                                    "figures/dlc_bins.png*", "runs/part-*",
                                    "traces/0123456789abcdef.parquet*", RECORD + "*"])
def test_overwrite_refuses_a_sweep_folder_holding_anything_else_and_deletes_nothing(
        theirs, tmp_path, capsys):
    """--overwrite used to delete every child of --out once it held a sweep.json, then
    every file of a name a sweep writes: a user's summary_tuning.csv, an edited
    summary.md. Now a file, a folder or a symbolic link the sweep did not write, or a
    file it wrote and that was edited since ("*": its record says so), makes the folder
    refused whole, in one line naming --out and the file."""
    f = _sweep_file(tmp_path)
    out = tmp_path / "res"
    _results_folder(f, out, ("ok",))
    _written_by_a_sweep(out)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "precious.parquet").write_text("keep")
    if theirs == "runs/part-*":
        theirs = str(next((out / "runs").glob("part-*")).relative_to(out)) + "*"
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
    elif theirs.endswith("*"):  # edited since the sweep wrote it
        with open(out / theirs[:-1], "ab") as fh:
            fh.write(b"mine\n")
    else:
        (out / theirs).write_text("mine")
    before, outside = _snapshot(out), _snapshot(elsewhere)
    code = cli.main(["sweep", str(f), "--out", str(out), "--overwrite"])
    err = capsys.readouterr().err
    assert code == 2, err
    if theirs == RECORD + "*":  # the record itself cannot be read: said so
        _one_line(err, "--out", out / RECORD)
    else:
        _one_line(err, "--out", out)
        assert "deleted" in err and theirs.rstrip("/->*") in err, err
    assert _snapshot(out) == before and _snapshot(elsewhere) == outside
    with pytest.raises(ConfigError) as exc:  # the library refuses it the same way
        sweep.run_sweep(f, out, workers=1, overwrite=True, quiet=True)
    assert exc.value.field == "--out"
    assert _snapshot(out) == before


def test_overwrite_deletes_what_a_sweep_wrote_and_starts_anew(tmp_path):
    """A folder holding only what a sweep wrote (its record says so) is emptied of it
    (the runs, traces, summary, figures, temporaries) and begun again with the new sweep
    file."""
    old = _sweep_file(tmp_path, THREE_RUNS)
    out = tmp_path / "res"
    _results_folder(old, out, ("ok", "diverged", "failed"))
    _written_by_a_sweep(out)
    sweep.summarize(out)  # the summary's own files replaced, and recorded
    new = tmp_path / "new.toml"
    new.write_text(ONE_RUN)
    sw = sweep.load_sweep(new)
    done, lock = store._prepare(out, sw, new.read_text(), overwrite=True)[:2]
    store.release(lock)
    assert done == set()
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == [
        RECORD, "runs", "sweep.json", "sweep.toml"]
    assert (out / "sweep.toml").read_text() == ONE_RUN


def test_resume_removes_only_the_temporaries_of_its_own_killed_writes(tmp_path):
    """A sweep killed as it wrote a batch or a trace leaves a hidden temporary: the next
    run into the folder removes it when the record lists it (empty or complete); the
    summary's are left to the summary (it may be running)."""
    f = _sweep_file(tmp_path)
    out = tmp_path / "res"
    _results_folder(f, out, ("ok",))
    _written_by_a_sweep(out)
    (out / "runs" / ".part-aaaaaaaaaaaaaaaa.parquet.cafecafe.partial").write_bytes(b"mine")
    done, lock = store._prepare(out, sweep.load_sweep(f), f.read_text(), False)[:2]
    store.release(lock)
    assert len(done) == 1
    hidden = sorted(str(p.relative_to(out)) for p in out.rglob(".*") if p.name != RECORD)
    assert hidden == [".summary.md.deadbeef.partial", "figures/.overspeed.png.deadbeef.partial",
                      "runs/.part-aaaaaaaaaaaaaaaa.parquet.cafecafe.partial"]


def test_overwrite_of_a_folder_without_a_record_goes_by_exact_names_and_kinds(tmp_path):
    """A results folder written before the record existed: only files of the exact names
    a sweep writes, each of the kind its name says (Parquet, PNG, PDF, the summary's own
    headers, a sweep.json that parses), are the sweep's and go."""
    f = _sweep_file(tmp_path)
    out = tmp_path / "res"
    _legacy_folder(f, out)
    assert not (out / RECORD).exists()
    done, lock = store._prepare(out, sweep.load_sweep(f), f.read_text(), True)[:2]
    store.release(lock)
    assert done == set()
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == [
        RECORD, "runs", "sweep.json", "sweep.toml"]


@pytest.mark.parametrize("theirs, content", [
    ("summary_tuning.csv", b"my,own,tuning\n1,2,3\n"),
    ("summary.md", b"# My notes on this sweep\n"),
    ("summary.csv", b"controller,fault\n"),  # a header a summary never wrote
    ("figures/overspeed.png", b"\xff\xd8\xff\xe0 a JPEG"),
    ("figures/dlc_bins.pdf", PNG),
    ("runs/part-0123456789abcdef.parquet", b"my own text"),
    ("traces/0123456789abcdef.parquet", b"PAR1 cut short"),
    (".summary.csv.abcd1234", b"my backup"),
    ("sweep.toml", b"\xff\xfe not a sweep file"),
])
def test_overwrite_of_a_folder_without_a_record_refuses_a_file_of_another_kind(
        theirs, content, tmp_path, capsys):
    """Without a record, a name is not enough: a user's summary_tuning.csv, notes in
    summary.md, a JPEG named overspeed.png make the folder refused whole."""
    f = _sweep_file(tmp_path)
    out = tmp_path / "res"
    _legacy_folder(f, out)
    (out / theirs).parent.mkdir(exist_ok=True)
    (out / theirs).write_bytes(content)
    before = _snapshot(out)
    assert cli.main(["sweep", str(f), "--out", str(out), "--overwrite"]) == 2
    err = capsys.readouterr().err
    _one_line(err, "--out", out)
    assert theirs in err and "nothing was deleted" in err
    assert _snapshot(out) == before


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


def test_a_users_file_at_the_lock_name_is_never_overwritten(tmp_path, capsys):
    f = _sweep_file(tmp_path)
    out = tmp_path / "res"
    _results_folder(f, out, ("ok",))
    (out / "sweep.lock").write_text("my notes on locking\n")
    before = _snapshot(out)
    assert cli.main(["sweep", str(f), "--out", str(out)]) == 2
    _one_line(capsys.readouterr().err, "--out", out / "sweep.lock")
    assert _snapshot(out) == before


# ------------------------------------------------------------------------- --summary

@pytest.mark.parametrize("theirs", ["summary.md", "summary_cost.csv", "figures/overspeed.png",
                                    "summary.md*", "figures/overspeed.png*",
                                    "summary.csv*"])
def test_summary_never_overwrites_a_users_file_and_writes_nothing(theirs, tmp_path, capsys):
    """--summary used to overwrite a summary.md the user wrote or edited. A file of a name
    the summary writes that is not the one it wrote (a user's, or one edited since its
    last summary: "*") refuses the summary in one line naming it, before anything is
    written."""
    f = _sweep_file(tmp_path, THREE_RUNS)
    out = tmp_path / "res"
    _results_folder(f, out, ("ok", "diverged", "failed"))
    if theirs.endswith("*"):
        sweep.summarize(out)
        with open(out / theirs[:-1], "ab") as fh:
            fh.write(b"my edit")
    else:
        (out / theirs).parent.mkdir(exist_ok=True)
        (out / theirs).write_bytes(b"mine")
    before = _snapshot(out)
    assert cli.main(["sweep", "--summary", str(out)]) == 2
    err = capsys.readouterr().err
    _one_line(err, "--summary", out)
    assert theirs.rstrip("*") in err and "nothing was written" in err
    assert _snapshot(out) == before


def test_summary_replaces_its_own_files_and_records_them(tmp_path):
    f = _sweep_file(tmp_path, THREE_RUNS)
    out = tmp_path / "res"
    _results_folder(f, out, ("ok", "diverged", "failed"))
    text = sweep.summarize(out)
    assert sweep.summarize(out) == text  # again: its own files replaced
    rec = Record.open(out, "--summary")
    assert all(rec.ours(rel) for rel in ("summary.md", "summary.csv", "summary_cost.csv",
                                         "figures/overspeed.png", "figures/overspeed.pdf"))
    # a folder written before the record: its summary recognised, replaced, recorded
    (out / RECORD).unlink()
    assert sweep.summarize(out) == text
    assert Record.open(out, "--summary").ours("figures/rms_speed_error.png")


def test_summary_pairs_each_controller_with_rosco_in_its_own_csv(tmp_path):
    """With ROSCO among the controllers, summary.md has the paired section and
    summary_paired.csv its numbers, recorded as the summary's (every metric 1.0 in these
    rows: each ratio 1)."""
    f = _sweep_file(tmp_path, THREE_RUNS.replace('["pi"]', '["pi", "rosco"]'))
    out = tmp_path / "res"
    _results_folder(f, out, ("ok",) * 6)
    text = sweep.summarize(out)
    assert "## Against rosco, on the same runs" in text
    rows = (out / "summary_paired.csv").read_text().splitlines()
    assert rows[0].startswith("controller,reference,fault,scenarios,failed,both_held,")
    cells = dict(zip(rows[0].split(","), rows[-1].split(","), strict=True))
    assert (cells["controller"], cells["fault"], cells["scenarios"], cells["both_held"]) == (
        "pi", "all", "3", "3")
    assert float(cells["rms_speed_error_rad_s_ratio_median"]) == 1.0
    assert all(Record.open(out, "--summary").ours(rel) for rel in (
        "summary_paired.csv", "figures/paired_tradeoff.png", "figures/paired_tradeoff.pdf"))
    # a folder kept without its record (copied, or committed): its summary is recognised by
    # its header, replaced, recorded
    (out / RECORD).unlink()
    assert sweep.summarize(out) == text
    assert Record.open(out, "--summary").ours("summary_paired.csv")


@pytest.mark.parametrize("link", ["figures", "figures/overspeed.png", "summary.md", "runs",
                                  "runs/part"])
def test_summary_never_follows_a_symbolic_link(link, tmp_path, capsys):
    """With DIR/figures -> ../myphotos, --summary overwrote myphotos/overspeed.png. A
    symbolic link anywhere in the results folder is refused in one line naming it; nothing
    outside (or inside) is touched."""
    f = _sweep_file(tmp_path)
    out = tmp_path / "res"
    _results_folder(f, out, ("ok",))
    sweep.summarize(out)
    photos = tmp_path / "myphotos"
    photos.mkdir()
    (photos / "overspeed.png").write_bytes(b"my holiday")
    (photos / "notes.md").write_text("mine")
    if link == "runs/part":
        part = next((out / "runs").glob("part-*"))
        (photos / part.name).write_bytes(part.read_bytes())
        part.unlink()
        part.symlink_to(photos / part.name)
        link = str(part.relative_to(out))
    elif link in ("figures", "runs"):
        for p in (out / link).iterdir():
            p.rename(photos / p.name) if link == "runs" else p.unlink()
        (out / link).rmdir()
        (out / link).symlink_to(photos)
    else:
        (out / link).unlink()
        (out / link).symlink_to(photos / ("notes.md" if link.endswith(".md")
                                          else "overspeed.png"))
    before, outside = _snapshot(out), _snapshot(photos)
    assert cli.main(["sweep", "--summary", str(out)]) == 2
    err = capsys.readouterr().err
    _one_line(err, "--summary", out)
    assert f"{link} is one" in err
    assert _snapshot(out) == before and _snapshot(photos) == outside
    assert cli.main(["sweep", str(f), "--out", str(out)]) == 2  # a resume too
    _one_line(capsys.readouterr().err, "--out", out)
    assert _snapshot(out) == before and _snapshot(photos) == outside


# --------------------------------------------------- bad results folders: one line

@pytest.mark.parametrize("kind", ["loop", "loop/sub", "dangling", "file"])
def test_out_that_cannot_be_a_folder_is_one_line(kind, tmp_path, capsys):
    """--out a symbolic link loop was a RuntimeError traceback (store._prepare's resolve),
    a dangling link a raw "[Errno 17] File exists"."""
    f = _sweep_file(tmp_path)
    t1 = tmp_path / "t1"
    t1.mkdir()
    if kind.startswith("loop"):
        (t1 / "loopA").symlink_to(t1 / "loopB")
        (t1 / "loopB").symlink_to(t1 / "loopA")
        out = t1 / kind.replace("loop", "loopA")
        why = "symbolic link loop"
    elif kind == "dangling":
        (t1 / "gone").symlink_to(t1 / "nowhere")
        out, why = t1 / "gone", "dangling symbolic link"
    else:
        (t1 / "afile").write_text("mine")
        out, why = t1 / "afile", "this is a file"
    before = _snapshot(t1)
    for args in (["sweep", str(f), "--out", str(out)], ["sweep", "--summary", str(out)],
                 ["sweep", "--show", "0123456789abcdef", "--out", str(out)]):
        assert cli.main(args) == 2
        err = capsys.readouterr().err
        _one_line(err, "--summary" if "--summary" in args else "--out", out)
        assert why in err
    assert _snapshot(t1) == before


@pytest.mark.parametrize("recorded", [True, False])
def test_a_damaged_batch_is_named_on_resume_and_summary(recorded, tmp_path, capsys):
    """A batch file cut short (`truncate -s 100`) was an ArrowInvalid traceback on resume
    and on --summary. Now one line names the file and says what to do; removed, its
    batch runs again. Without a record (an older folder), it is found by reading it."""
    f = _sweep_file(tmp_path, THREE_RUNS)
    out = tmp_path / "res"
    _results_folder(f, out, ("ok", "ok", "ok"))
    if not recorded:
        (out / RECORD).unlink()
    (part,) = (out / "runs").glob("part-*.parquet")
    os.truncate(part, 100)
    before = _snapshot(out)
    for args, option in ((["sweep", str(f), "--out", str(out)], "--out"),
                         (["sweep", "--summary", str(out)], "--summary"),
                         (["sweep", "--retry-failed", str(f), "--out", str(out)], "--out")):
        assert cli.main(args) == 2
        err = capsys.readouterr().err
        _one_line(err, option, part)
        assert "remove it" in err and "runs its batch again" in err
        assert _snapshot(out) == before
    part.unlink()
    done, lock = store._prepare(out, sweep.load_sweep(f), f.read_text(), False)[:2]
    store.release(lock)
    assert done == set()


@pytest.mark.parametrize("special", ["sweep.json FIFO", "sweep.json -> /dev/zero",
                                     "runs/part-0123456789abcdef.parquet FIFO",
                                     "summary.md FIFO", RECORD + " FIFO"])
def test_special_files_in_the_results_folder_are_refused_unread(special, tmp_path, capsys):
    """--summary DIR hung for ever with DIR/sweep.json a FIFO or a link to /dev/zero. Every
    file of the results folder is checked before it is read: a special file or a link
    anywhere is one line naming it, on --summary and on a resume, and nothing hangs."""
    f = _sweep_file(tmp_path)
    out = tmp_path / "res"
    _results_folder(f, out, ("ok",))
    name = special.split(" ")[0]
    if (out / name).exists():
        (out / name).unlink()
    if special.endswith("FIFO"):
        os.mkfifo(out / name)
    else:
        (out / name).symlink_to("/dev/zero")
    before = _snapshot(out)
    with no_hang():
        for args, option in ((["sweep", "--summary", str(out)], "--summary"),
                             (["sweep", str(f), "--out", str(out)], "--out"),
                             (["sweep", str(f), "--out", str(out), "--overwrite"], "--out")):
            assert cli.main(args) == 2
            err = capsys.readouterr().err
            _one_line(err, option, out)
            assert name in err
    assert _snapshot(out) == before


def test_a_batch_written_after_the_record_was_read_is_not_taken_for_damaged(tmp_path):
    """--summary reads a folder a sweep is writing: a batch recorded and renamed into
    place after the summary read the record is read again from the record, not refused."""
    f = _sweep_file(tmp_path, THREE_RUNS)
    out = tmp_path / "res"
    runs = _results_folder(f, out, ("ok",))
    stale = Record.open(out, "--summary")
    store._save_batch(out, set(), [(tasks._row(runs[1], "failed", cause="E: x"), None)])
    assert len([rel for rel, _, _ in store._batches(out, "--summary", stale)]) == 2


def test_a_damaged_record_is_one_line(tmp_path, capsys):
    f = _sweep_file(tmp_path)
    out = tmp_path / "res"
    _results_folder(f, out, ("ok",))
    with open(out / RECORD, "ab") as fh:
        fh.write(b"not json\n")
    for args, option in ((["sweep", "--summary", str(out)], "--summary"),
                         (["sweep", str(f), "--out", str(out)], "--out")):
        assert cli.main(args) == 2
        err = capsys.readouterr().err
        _one_line(err, option, out / RECORD)
        assert "line 4" in err


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


def test_a_batch_is_read_into_the_schema_columns_missing_as_nulls_wrong_types_refused():
    """Batches are read by ParquetFile on the calling thread (Arrow's dataset reader left
    the last reference to the bytes in its thread pool, and dropping it at interpreter
    exit aborted 1 sweep in 40 on a loaded machine). The schema is still enforced: the
    columns come back in its order and types, a column an older batch lacks as nulls,
    one of a type that does not convert refused."""
    import pyarrow as pa

    full = store.schema().empty_table()
    row = {f.name: pa.array([None], f.type) for f in store.schema()}
    row["run_id"] = pa.array(["a" * 16])
    row["seed"] = pa.array([3], pa.int64())
    table = pa.Table.from_pydict({k: v for k, v in row.items() if k != "false_alarms"})
    got = store._conform(pq.ParquetFile(pa.BufferReader(store._parquet_bytes(table)))
                         .read(use_threads=False))
    assert got.schema == full.schema and got.schema.field("onset_s").metadata == {
        b"unit": b"s"}
    assert got.column("run_id").to_pylist() == ["a" * 16]
    assert got.column("seed").to_pylist() == [3]
    assert got.column("false_alarms").to_pylist() == [None]
    bad = pa.Table.from_pydict({"seed": pa.array(["three"])})
    with pytest.raises(pa.ArrowInvalid):
        store._conform(bad)


def test_a_campaign_resumes_across_an_edit_of_the_sources_but_not_of_the_code(
        tmp_path, monkeypatch):
    """A results folder resumes on the same generated artefacts: an edit of derivation/
    that leaves every artefact as it was (a comment, a refactor: the manifest's sources
    change) resumes; a changed artefact, a folder that recorded only the whole manifest's
    hash (before issue 34), or one made under other run semantics (store.RUN_SEMANTICS),
    is refused in one line naming --out."""
    from wtftc.artefacts import loader

    f, out = _sweep_file(tmp_path), tmp_path / "out"
    _results_folder(f, out, ("ok",))
    sw, real = sweep.load_sweep(f), loader.manifest()

    def resume():
        lock = store._prepare(out, sw, f.read_text(), overwrite=False)[1]
        store.release(lock)

    edited = {**real, "sources": {k: "0" * 64 for k in real["sources"]}}
    monkeypatch.setattr(loader, "manifest", lambda: edited)
    resume()
    name = sorted(real["artefacts"])[0]
    changed = {**real, "artefacts": {**real["artefacts"], name: "0" * 64}}
    monkeypatch.setattr(loader, "manifest", lambda: changed)
    with pytest.raises(ConfigError) as e:
        resume()
    assert e.value.field == "--out" and "generated/ changed" in str(e.value)
    monkeypatch.setattr(loader, "manifest", lambda: real)
    meta = out / "sweep.json"
    old = json.loads(meta.read_text())
    older = json.loads(meta.read_text())
    old["versions"]["generated_manifest_sha256"] = old["versions"].pop("generated_code_sha256")
    meta.write_text(json.dumps(old))
    with pytest.raises(ConfigError, match="earlier wtftc.*whole manifest's hash"):
        resume()
    # a folder made before a change to what runs compute outside the generated code (issue
    # 34's speed noise scaled to the turbine) records no run semantics, or an older one
    del older["versions"]["run_semantics"]
    meta.write_text(json.dumps(older))
    with pytest.raises(ConfigError, match=f"run semantics 1, this wtftc's are "
                                          f"{store.RUN_SEMANTICS}"):
        resume()


def test_a_campaign_does_not_resume_on_an_edited_turbine_file_or_cp_table(tmp_path):
    """A run's configuration names its turbine, not its values: a campaign resumed after
    its turbine file or Cp table changed would mix two turbines (how the IEA 15-MW's rated
    power was mended, issue 34). sweep.json records their hash; a changed one is refused
    in one line naming --out, the same again resumes, and a folder made before the hash
    was recorded resumes unchecked."""
    from wtftc.model import turbine_file

    iea = turbine_file.path_of("iea15mw")
    cp = tmp_path / "cp.txt"
    cp.write_bytes((iea.parent / "Cp_Ct_Cq.IEA15MW.txt").read_bytes())
    mine = tmp_path / "mine.toml"
    mine.write_text(iea.read_text().replace('cp_table = "Cp_Ct_Cq.IEA15MW.txt"',
                                            'cp_table = "cp.txt"'))
    f = _sweep_file(tmp_path, ONE_RUN + f'turbine = "{mine}"\n')
    out = tmp_path / "out"
    _results_folder(f, out, ("ok",))
    sw = sweep.load_sweep(f)

    def resume():
        store.release(store._prepare(out, sw, f.read_text(), overwrite=False)[1])

    resume()  # the same turbine
    text, table = mine.read_text(), cp.read_bytes()
    for path, edited in ((mine, text.replace("value = 15664814.737457706",
                                             "value = 15000000.0")),
                         (cp, table.replace(b"0.", b"1.", 1))):
        path.write_bytes(edited.encode() if isinstance(edited, str) else edited)
        with pytest.raises(ConfigError) as e:
            resume()
        assert e.value.field == "--out" and "turbine file or its Cp table changed" \
            in str(e.value)
        path.write_bytes(text.encode() if path == mine else table)
        resume()  # as it was: resumes
    meta = out / "sweep.json"
    old = json.loads(meta.read_text())
    del old["turbine_sha256"]
    meta.write_text(json.dumps(old))
    mine.write_text(text.replace("value = 15664814.737457706", "value = 15000000.0"))
    resume()  # no hash recorded: not checked
