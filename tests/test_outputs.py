"""Output folders are never mixed, stale or half-written (issue 14, item 6).

`wtftc run` writes into a hidden temporary sibling of --out and swaps it in as a whole
(wtftc.results.io.run_folder); a folder that is not a run folder is refused before any
work; --out "" (the current folder) is refused.
"""

import json
import subprocess
import sys
import tomllib
from pathlib import Path

FAULTED = ["--case", "2", "--wind", "ntm", "--wind-mean", "16"]


def wtftc(*args, cwd=None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "wtftc.cli", "run", *map(str, args),
                             "--quiet"], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _done(p: subprocess.Popen) -> subprocess.CompletedProcess:
    out, err = p.communicate(timeout=300)
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)


def _case_of(out: Path) -> tuple[int, int, bool]:
    """(case in config.toml, case in metrics.json, whether the fault figure is there)."""
    cfg = tomllib.loads((out / "config.toml").read_text())
    m = json.loads((out / "metrics.json").read_text())
    return cfg["case"], m["case"], (out / "figures" / "fault.png").exists()


def test_a_second_run_replaces_the_first_as_a_whole(tmp_path):
    out = tmp_path / "run"
    p = _done(wtftc(*FAULTED, "--t-final", 25, "--out", out))
    assert p.returncode == 0, p.stderr
    assert _case_of(out) == (2, 2, True)
    p = _done(wtftc("--case", 1, "--t-final", 2, "--out", out))
    assert p.returncode == 0, p.stderr
    assert _case_of(out) == (1, 1, False)  # the case-2 run's fault figure is gone
    assert [q.name for q in tmp_path.iterdir()] == ["run"]  # no temporary left


def test_two_runs_at_once_into_one_folder_leave_one_whole_run(tmp_path):
    out = tmp_path / "run"
    a = wtftc(*FAULTED, "--t-final", 25, "--out", out)
    b = wtftc("--case", 1, "--t-final", 25, "--out", out)
    pa, pb = _done(a), _done(b)
    assert pa.returncode == 0 and pb.returncode == 0, (pa.stderr, pb.stderr)
    cfg_case, metrics_case, fault_png = _case_of(out)
    assert cfg_case == metrics_case and fault_png == (cfg_case == 2)
    n_traces = len((out / "traces.csv").read_text().splitlines())
    assert n_traces > 1000  # 25 s at 50 Hz: complete
    assert [q.name for q in tmp_path.iterdir()] == ["run"]


def test_a_folder_that_is_not_a_run_folder_is_refused_untouched(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    p = _done(wtftc("--t-final", 1, "--out", out))
    assert p.returncode == 2 and "--out" in p.stderr and "Traceback" not in p.stderr
    assert [q.name for q in out.iterdir()] == ["notes.txt"]
    assert sorted(q.name for q in tmp_path.iterdir()) == ["mine"]


def test_the_current_folder_and_a_path_under_a_file_are_refused(tmp_path):
    (tmp_path / "afile").write_text("")
    for out in ("", ".", "afile", "afile/sub"):
        p = _done(wtftc("--t-final", 1, "--out", out, cwd=tmp_path))
        assert p.returncode == 2, (out, p.stderr)
        assert p.stderr.startswith("wtftc: error: --out") and "Traceback" not in p.stderr
    assert sorted(q.name for q in tmp_path.iterdir()) == ["afile"]


def test_a_folder_that_only_looks_like_a_run_folder_is_refused(tmp_path):
    """config.toml and metrics.json beside other files (a user's, or added to a run
    folder) make no run folder: nothing is deleted (it was, before review)."""
    out = tmp_path / "p"
    (out / "notes").mkdir(parents=True)
    (out / "config.toml").write_text("x = 1\n")
    (out / "metrics.json").write_text("{}")
    (out / "thesis.tex").write_text("keep")
    p = _done(wtftc("--t-final", 1, "--out", out))
    assert p.returncode == 2 and "--out" in p.stderr
    assert (out / "thesis.tex").read_text() == "keep" and (out / "notes").is_dir()


def test_a_refused_run_leaves_no_folder(tmp_path):
    p = _done(wtftc("--dt", 0.5, "--t-final", 1, "--out", tmp_path / "a" / "b" / "run"))
    assert p.returncode == 2 and "dt_s" in p.stderr
    assert list(tmp_path.iterdir()) == []
