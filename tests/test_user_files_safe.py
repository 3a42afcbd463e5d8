"""Nothing a user owns is ever deleted, and no file wtftc reads can hang it (issue 30).

* Every command that writes a folder (run, cases, compare, linearize, verify; export and
  sweep in their own tests; regenerate below) refuses an --out that holds a file wtftc did
  not write, in one line, exit 2, touching nothing (defect 1). It replaces a folder it
  wrote as a whole, keeping the folder's mode; a listed file that changed, or a file added
  anywhere, makes the folder the user's.
* A killed run's hidden partial folder is removed by the next run into the same --out;
  a live one is not (defect 8).
* A directory at a cached library's name heals; `make regenerate` builds in a sibling and
  swaps, so generated/ is never half rewritten (defect 8).
* A FIFO, /dev/zero, a folder or a symlink loop given as a config, wind file, Cp table or
  --out is refused in one line, without reading it (defect 4).
* Set-up installs in an order that leaves pip's resolver nothing to report (defect 9).
"""

import json
import os
import signal
import stat
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
from conftest import no_hang, snapshot

from wtftc import cli, files
from wtftc.errors import ConfigError

ROOT = Path(__file__).resolve().parent.parent

#: every folder-writing command reachable in-process, with arguments that would make it
#: run for long if it did not refuse first (the refusal must come before any work)
COMMANDS = {
    "run": ["run", "--t-final", "1", "--quiet"],
    "cases": ["cases", "--t-final", "21", "--quiet"],
    "compare": ["compare", "--t-final", "25", "--quiet", "--controllers", "pi"],
    "linearize": ["linearize", "--winds", "16", "--quiet"],
    "verify": ["verify", "--points", "1"],
}


def _user_folder(tmp_path: Path) -> Path:
    out = tmp_path / "mine"
    (out / "sub").mkdir(parents=True)
    (out / "README.txt").write_text("my notes\n")
    (out / "sub" / "thesis.tex").write_text("keep")
    os.chmod(out, 0o750)
    return out


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_folder_holding_a_users_file_is_refused_untouched(command, tmp_path, capsys):
    out = _user_folder(tmp_path)
    before = snapshot(out)
    code = cli.main([*COMMANDS[command], "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("wtftc: error: --out") and err.count("\n") == 1, err
    assert "did not write" in err
    assert snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine"]  # no partial left


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_the_current_folder_is_refused(command, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "README.txt").write_text("x")
    for out in (".", str(tmp_path), ".."):
        assert cli.main([*COMMANDS[command], "--out", out]) == 2
        assert "--out" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["README.txt"]


def test_a_symlink_loop_as_out_is_one_line(tmp_path, capsys):
    (tmp_path / "loop").symlink_to("loop")
    for out in (tmp_path / "loop", tmp_path / "loop" / "sub"):
        assert cli.main([*COMMANDS["run"], "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.startswith("wtftc: error: --out") and err.count("\n") == 1, err


@contextmanager
def _written(out: Path, files_: dict[str, str]):
    with files.owned_folder(out, command="test") as tmp:
        for name, text in files_.items():
            (tmp / name).parent.mkdir(parents=True, exist_ok=True)
            (tmp / name).write_text(text)
        yield tmp


def test_a_folder_wtftc_wrote_is_replaced_whole_keeping_its_mode(tmp_path):
    out = tmp_path / "o"
    with _written(out, {"a.csv": "1", "figures/f.png": "png"}):
        pass
    assert stat.S_IMODE(out.stat().st_mode) == 0o777 & ~_umask()  # not mkdtemp's 0700
    os.chmod(out, 0o750)
    with _written(out, {"b.csv": "2"}):
        pass
    assert sorted(p.name for p in out.iterdir()) == [".wtftc-written", "b.csv"]
    assert stat.S_IMODE(out.stat().st_mode) == 0o750
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]


@pytest.mark.parametrize("change", ["added", "added_deep", "edited", "symlink", "emptied"])
def test_a_folder_the_user_changed_is_theirs(change, tmp_path):
    out = tmp_path / "o"
    with _written(out, {"a.csv": "1,2", "figures/f.png": "png"}):
        pass
    if change == "added":
        (out / "notes.txt").write_text("mine")
    elif change == "added_deep":
        (out / "figures" / "edited.svg").write_text("mine")
    elif change == "edited":
        (out / "a.csv").write_text("1,2,3 my edit")
    elif change == "symlink":
        (out / "link").symlink_to("/etc/hostname")
    else:  # the marker alone no longer describes the folder: a user's file is the rest
        (out / "a.csv").unlink()
    before = snapshot(out)
    with pytest.raises(ConfigError, match="did not write"), _written(out, {"b": "x"}):
        pass
    assert snapshot(out) == before


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def test_a_killed_runs_partial_folder_is_cleaned_by_the_next_run(tmp_path):
    out = tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-m", "wtftc.cli", "run", "--t-final", "600",
                          "--quiet", "--out", str(out)], stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not list(tmp_path.glob(".run.*.partial")) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert list(tmp_path.glob(".run.*.partial")), "the run never started its folder"
    finally:
        p.send_signal(signal.SIGKILL)
        p.wait()
    assert len(list(tmp_path.glob(".run.*.partial"))) == 1  # the litter of the killed run
    assert cli.main(["run", "--t-final", "0.5", "--quiet", "--out", str(out)]) == 0
    assert sorted(q.name for q in tmp_path.iterdir()) == ["run"]


def test_a_live_partial_folder_and_a_users_lookalike_are_left_alone(tmp_path):
    out = tmp_path / "o"
    lookalike = tmp_path / ".o.mine.partial"
    lookalike.mkdir()
    (lookalike / "data.txt").write_text("mine")
    with _written(out, {"a": "1"}) as live:
        with _written(out, {"b": "2"}):  # a second command into the same --out meanwhile
            assert live.is_dir()
        assert live.is_dir()
    assert (lookalike / "data.txt").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == [".o.mine.partial", "o"]


def test_a_folder_at_a_cached_librarys_name_heals(tmp_path, monkeypatch):
    from wtftc.artefacts import loader

    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path / "cache"))
    c = tmp_path / "f.c"
    c.write_text("int f(void) { return 7; }\n")
    cc = loader.compiler()
    so = loader.compile_cached(c, cc)
    so.unlink()
    so.mkdir()
    (so / "user.txt").write_text("mine")
    healed = loader.compile_cached(c, cc)
    assert healed == so and healed.is_file()
    moved = [p for p in so.parent.iterdir() if ".moved-" in p.name]
    assert len(moved) == 1 and (moved[0] / so.name / "user.txt").read_text() == "mine"


def test_regenerate_builds_in_a_sibling_and_never_half_rewrites(tmp_path, monkeypatch):
    """A failure in the middle of a regeneration leaves the old folder as it was and no
    litter; a success swaps the new folder in whole; a user's folder is refused."""
    from derivation import generate

    monkeypatch.setenv("PYTHONHASHSEED", "0")
    out = tmp_path / "generated"
    out.mkdir()
    (out / "manifest.json").write_text(json.dumps({"artefacts": {"a.c": "x"}}))
    (out / "a.c").write_text("old")
    before = snapshot(out)

    def failing(outdir):
        (outdir / "manifest.json").write_text("{}")
        assert snapshot(out) == before  # the old folder is untouched while writing
        raise RuntimeError("stop halfway")

    monkeypatch.setattr(generate, "write", failing)
    with pytest.raises(RuntimeError, match="halfway"):
        generate.main([str(out)])
    assert snapshot(out) == before and sorted(p.name for p in tmp_path.iterdir()) == [
        "generated"]

    def complete(outdir):
        (outdir / "manifest.json").write_text(json.dumps({"artefacts": {"b.c": "y"}}))
        (outdir / "b.c").write_text("new")
        return {"artefacts": {"b.c": "y"}}

    monkeypatch.setattr(generate, "write", complete)
    assert generate.main([str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["b.c", "manifest.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["generated"]
    (out / "notes.md").write_text("mine")
    before = snapshot(out)
    assert generate.main([str(out)]) == 2
    assert snapshot(out) == before


# ------------------------------------------------------------------------ special files

def _special(kind: str, tmp: Path, suffix: str = "") -> Path:
    p = tmp / f"{kind}{suffix}"
    if kind == "dev_zero":
        if not suffix:
            return Path("/dev/zero")
        p.symlink_to("/dev/zero")  # a name the command takes for a file of its kind
    if kind == "fifo":
        os.mkfifo(p)
    elif kind == "folder":
        p.mkdir()
    elif kind == "symlink_loop":
        p.symlink_to(p.name)
    return p


SPECIAL = ["fifo", "dev_zero", "folder", "symlink_loop"]
#: every file argument of `wtftc run`, as arguments for a path p, and the field it names
FILE_ARGS = {
    "config": (lambda p: ["--config", str(p)], "--config"),
    "wind_file": (lambda p: ["--wind", "file", "--wind-file", str(p)], "wind.path"),
    "turbine": (lambda p: ["--turbine", str(p)], "turbine"),
}


@pytest.mark.parametrize("kind", SPECIAL)
@pytest.mark.parametrize("arg", sorted(FILE_ARGS))
def test_a_special_file_argument_is_refused_unread(arg, kind, tmp_path, capsys):
    make_args, field = FILE_ARGS[arg]
    path = _special(kind, tmp_path, ".toml" if arg == "turbine" else "")
    with no_hang():
        code = cli.main(["run", *make_args(path), "--t-final", "0.5", "--quiet",
                         "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("wtftc: error: ") and err.count("\n") == 1, err
    assert field in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", SPECIAL)
def test_a_special_cp_table_is_refused_unread(kind, tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'cp_table = "{_special(kind, tmp_path)}"\nt_final_s = 0.5\n')
    with no_hang():
        code = cli.main(["run", "--config", str(cfg), "--quiet", "--out",
                         str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "cp_table" in err, err


def test_a_file_over_the_cap_is_refused_before_it_is_read(tmp_path):
    big = tmp_path / "big.toml"
    with open(big, "wb") as fh:  # sparse: no disk used
        fh.truncate(files.MAX_TOML_BYTES + 1)
    with pytest.raises(ConfigError, match="at most"):
        cli_config = __import__("wtftc.config", fromlist=["load_toml"])
        cli_config.load_toml(big, "--config")


def test_files_written_together_are_all_or_none(tmp_path, monkeypatch):
    a, b = tmp_path / "a.toml", tmp_path / "b.txt"
    a.write_text("old a")
    real = os.replace
    calls = []

    def second_fails(src, dst):
        calls.append(dst)
        if Path(dst) == b:
            raise OSError(28, "No space left on device")
        return real(src, dst)

    monkeypatch.setattr(os, "replace", second_fails)
    with pytest.raises(OSError):
        files.write_files_together({a: b"new a", b: b"new b"})
    monkeypatch.setattr(os, "replace", real)
    assert a.read_text() == "old a" and not b.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.toml"]


def test_set_up_leaves_pips_resolver_nothing_to_report():
    """pip re-checks an installed package's declared dependencies whenever a later install
    touches one of them: the --no-deps installs (rosco, openfast-io, which declare
    wisdem and pandas) must come after every install with dependencies (the ERROR line of
    defect 9 came from deepdiff installed after openfast-io)."""
    lines = [ln.strip() for ln in (ROOT / "Makefile").read_text().splitlines()
             if "pip install" in ln and not ln.strip().startswith("@#")]
    no_deps = [i for i, ln in enumerate(lines) if "--no-deps" in ln]
    assert no_deps and max(i for i, ln in enumerate(lines) if "--no-deps" not in ln) \
        < min(no_deps), lines


@pytest.mark.parametrize("kind", SPECIAL)
@pytest.mark.parametrize("argv,field", [
    (["sweep", "{p}", "--out", "{out}"], "SWEEP.toml"),
    (["turbine", "show", "{p}"], "turbine"),
    (["turbine", "tune", "--turbine", "{p}"], "turbine"),
    (["linearize", "--turbine", "{p}", "--out", "{out}"], "turbine"),
], ids=["sweep", "turbine_show", "turbine_tune", "linearize"])
def test_special_files_in_the_other_commands_are_refused_unread(argv, field, kind, tmp_path,
                                                                 capsys):
    path = _special(kind, tmp_path, ".toml")
    args = [a.format(p=path, out=tmp_path / "out") for a in argv]
    with no_hang():
        code = cli.main(args)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.startswith("wtftc: error: ") and err.count("\n") == 1 and field in err, err
    assert not (tmp_path / "out").exists()


def test_turbine_tune_never_writes_over_a_users_file(tmp_path, capsys):
    """--out: a user's file is refused before the tuning (nothing changes); the file an
    earlier tuning wrote is replaced; --overwrite replaces the user's; the package's own
    data is never written."""
    import wtftc

    out = tmp_path / "gains.toml"
    out.write_text("my gains\n")
    tune = ["turbine", "tune", "--controller", "pi", "--out", str(out)]
    assert cli.main(tune) == 2
    err = capsys.readouterr().err
    assert err.startswith("wtftc: error: --out") and "--overwrite" in err, err
    assert out.read_text() == "my gains\n"
    assert cli.main([*tune, "--overwrite"]) == 0
    first = out.read_text()
    assert first.startswith("# wtftc turbine tune --controller pi")
    assert cli.main([*tune[:-2], "--zeta", "0.8", "--out", str(out)]) == 0  # its own file
    assert out.read_text() != first and "--zeta 0.8" in out.read_text()
    out.write_text(out.read_text() + "# my comment\n")  # edited since: the user's now
    edited = out.read_text()
    assert cli.main(tune) == 2 and "--overwrite" in capsys.readouterr().err
    assert out.read_text() == edited
    assert cli.main(["run", "--config", str(out), "--t-final", "0.2", "--quiet", "--out",
                     str(tmp_path / "r")]) == 0  # what it wrote runs as a configuration
    (tmp_path / "r" / files.MARKER).unlink()
    import shutil

    shutil.rmtree(tmp_path / "r")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["gains.toml"]
    data = Path(wtftc.__file__).parent / "data" / "tuned.toml"
    assert cli.main([*tune[:-1], str(data), "--overwrite"]) == 2
    assert "outside the installed wtftc package" in capsys.readouterr().err
    assert not data.exists()


def test_a_listed_file_edited_to_the_same_size_is_the_users(tmp_path):
    """A tuned value edited in place (2.0 -> 3.0 in a .IN) keeps the file's size: the
    marker's sha256 still tells that wtftc did not write it."""
    out = tmp_path / "o"
    with _written(out, {"wtftc_physical.IN": "2.0   ! phys_c1\n"}):
        pass
    (out / "wtftc_physical.IN").write_text("3.0   ! phys_c1\n")
    with pytest.raises(ConfigError, match="did not write"), _written(out, {"b": "x"}):
        pass
    assert (out / "wtftc_physical.IN").read_text() == "3.0   ! phys_c1\n"


# ------------------------------------------------------- found by the hostile review

@pytest.mark.parametrize("command,top", [("cases", ("metrics.md", "metrics.csv")),
                                         ("compare", ("compare.md", "compare.csv"))])
def test_a_users_folder_that_looks_like_an_old_result_is_refused(command, top, tmp_path,
                                                                  capsys):
    """The review's case: a paper folder with metrics.md and metrics.csv at its top beside
    a thesis, a data folder and photos, all of kinds wtftc writes: it was deleted."""
    out = tmp_path / "paper"
    (out / "data").mkdir(parents=True)
    (out / "photos").mkdir()
    for name in top:
        (out / name).write_text("x")
    (out / "thesis.md").write_text("chapter 3")
    (out / "data" / "field_campaign_2019.csv").write_text("1,2")
    (out / "photos" / "wedding.png").write_bytes(b"\x89PNG")
    before = snapshot(out)
    assert cli.main([*COMMANDS[command], "--out", str(out)]) == 2
    assert "did not write" in capsys.readouterr().err
    assert snapshot(out) == before


def _old_run_folder(out: Path) -> None:
    """A run folder as a wtftc from before the marker wrote it (no .wtftc-written)."""
    assert cli.main(["run", "--t-final", "0.5", "--quiet", "--out", str(out)]) == 0
    (out / files.MARKER).unlink()


@pytest.mark.parametrize("extra", ["figures/thesis_chapter3.docx", "figures/raw/lab.dat",
                                   "traces.csv/inner.txt"])
def test_an_old_run_folder_with_anything_more_is_the_users(extra, tmp_path, capsys):
    out = tmp_path / "leg"
    _old_run_folder(out)
    target = out / extra
    if target.parent.name == "traces.csv":
        (out / "traces.csv").unlink()
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text("mine")
    before = snapshot(out)
    assert cli.main(["run", "--t-final", "0.5", "--quiet", "--out", str(out)]) == 2
    assert "did not write" in capsys.readouterr().err
    assert snapshot(out) == before


def test_an_old_run_folder_as_it_was_written_is_replaced(tmp_path):
    out = tmp_path / "leg"
    _old_run_folder(out)
    assert cli.main(["run", "--t-final", "0.5", "--quiet", "--out", str(out)]) == 0
    assert (out / files.MARKER).is_file()


def test_an_empty_folder_added_makes_the_folder_the_users(tmp_path):
    out = tmp_path / "o"
    with _written(out, {"a.csv": "1"}):
        pass
    (out / "my_notes").mkdir()
    with pytest.raises(ConfigError, match="did not write"), _written(out, {"b": "x"}):
        pass
    assert (out / "my_notes").is_dir()


@pytest.mark.parametrize("target", ["run_folder", "empty"])
def test_an_out_that_is_a_symlink_is_refused_and_left_alone(target, tmp_path, capsys):
    real = tmp_path / "big" / "run"
    if target == "run_folder":
        assert cli.main(["run", "--t-final", "0.5", "--quiet", "--out", str(real)]) == 0
    else:
        real.mkdir(parents=True)
    link = tmp_path / "link_out"
    link.symlink_to(real)
    before = snapshot(real)
    assert cli.main(["run", "--t-final", "0.5", "--quiet", "--out", str(link)]) == 2
    assert "symbolic link" in capsys.readouterr().err
    assert link.is_symlink() and snapshot(real) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big", "link_out"]


def test_an_out_through_dot_dot_is_checked_as_the_folder_it_names(tmp_path, capsys):
    mine = _user_folder(tmp_path)
    (mine / "figures").mkdir()
    assert cli.main([*COMMANDS["run"], "--out", str(mine / "figures" / "..")]) == 2
    assert "did not write" in capsys.readouterr().err
    run = tmp_path / "r"
    assert cli.main(["run", "--t-final", "0.5", "--quiet", "--out", str(run)]) == 0
    assert cli.main(["run", "--t-final", "0.5", "--quiet", "--out",
                     str(run / "figures" / "..")]) == 0
    assert (run / files.MARKER).is_file() and not (run / "figures" / "figures").exists()


def test_regenerate_into_a_symlink_loop_is_one_line(tmp_path, monkeypatch, capsys):
    from derivation import generate

    monkeypatch.setenv("PYTHONHASHSEED", "0")
    (tmp_path / "loop").symlink_to("loop")
    assert generate.main([str(tmp_path / "loop")]) == 2
    err = capsys.readouterr().err
    assert "symbolic link" in err and err.count("\n") == 1


@pytest.mark.parametrize("fake", ["true", "writes_text"])
def test_export_refuses_a_compiler_that_builds_no_library(fake, tmp_path, capsys):
    cc = "/bin/true"
    if fake == "writes_text":
        cc = str(tmp_path / "fakecc")
        Path(cc).write_text('#!/bin/sh\nfor a; do [ "$prev" = -o ] && echo text > "$a"; '
                            'prev=$a; done\nexit 0\n')
        os.chmod(cc, 0o755)
    out = tmp_path / "ex"
    assert cli.main(["export", "discon", "--controller", "pi", "--out", str(out),
                     "--cc", cc]) == 2
    err = capsys.readouterr().err
    assert err.startswith("wtftc: error: --cc") and "status 0" in err, err
    assert not out.exists()


@pytest.mark.parametrize("argv,field", [
    (["cases", "--t-final", "1"], "--t-final"),  # was blamed on fault[0].onset_s
    (["run", "--turbine", "missing.toml"], "there is none"),
], ids=["cases_short", "turbine_missing"])
def test_messages_name_what_the_user_gave(argv, field, tmp_path, capsys):
    assert cli.main([*argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert field in err and err.count("\n") == 1, err


def test_an_output_rate_with_fewer_than_two_outputs_is_refused():
    from wtftc import config

    with pytest.raises(ConfigError, match="output_rate_hz.*at least two outputs"):
        config.make_config({"output_rate_hz": 1e-9, "t_final_s": 1.0})
