"""OpenFAST's and TurbSim's runs under hostile conditions: programs that hang, crash, are
killed, print anything; a TurbSim field cache damaged in every way; decks in any
encoding; wtftc itself killed while OpenFAST runs.

A fake ``openfast`` / ``turbsim`` (set by $OPENFAST / $TURBSIM, as a user may name their
own) answers ``-v`` as the real ones do and otherwise runs the Python code in
$FAKE_BODY, after recording its process id in $FAKE_PIDS; after each case the test looks
those ids up in the process table. Every case asserts one line, the right error (or exit
code), nothing left running and the folder free for the next run."""

from __future__ import annotations

import os
import re
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from processes import alive, gone

from wtftc import files, programs
from wtftc.errors import ConfigError, EngineError, ProgramKilled
from wtftc.model import wind_field
from wtftc.openfast import case as ofcase
from wtftc.openfast import engine, install, turbsim

PY = sys.executable
ROOT = Path(__file__).resolve().parents[1]

FAKE = '''#!{py}
import os, sys, time, signal, subprocess, resource
if sys.argv[1:] == ["-v"]:
    print(" {banner}")
    sys.exit(0)
PIDS = os.environ["FAKE_PIDS"]
open(PIDS, "a").write(f"{{os.getpid()}} ")
resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
def out(b):
    sys.stdout.buffer.write(b)
    sys.stdout.flush()
def die(sig):
    if sig not in (signal.SIGKILL, signal.SIGSTOP):  # Python ignores SIGPIPE, takes SIGINT
        signal.signal(sig, signal.SIG_DFL)
    os.kill(os.getpid(), sig)
    time.sleep(60)
def sleeper():
    return subprocess.Popen([sys.executable, "-c", "import os, sys, time; "
                             "open(sys.argv[1], 'a').write(str(os.getpid()) + ' '); "
                             "time.sleep(600)", PIDS])
def wait_child():
    while len(open(PIDS).read().split()) < 2:
        time.sleep(0.02)
exec(os.environ.get("FAKE_BODY", "pass"))
'''


def recorded(path: Path) -> list[int]:
    return [int(w) for w in path.read_text().split()] if path.is_file() else []


@pytest.fixture
def fakes(tmp_path, monkeypatch):
    """$OPENFAST and $TURBSIM naming the fakes; a fresh cache; the pids file."""
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    for name, banner in (("openfast", "OpenFAST-v5.0.0"), ("turbsim", "TurbSim")):
        exe = bin_ / name
        exe.write_text(FAKE.format(py=PY, banner=banner))
        exe.chmod(0o755)
    monkeypatch.setenv("OPENFAST", str(bin_ / "openfast"))
    monkeypatch.setenv("TURBSIM", str(bin_ / "turbsim"))
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("FAKE_PIDS", str(tmp_path / "pids"))
    monkeypatch.delenv(programs.TIMEOUT_ENV, raising=False)
    monkeypatch.setattr(programs, "GRACE_S", 1.0)
    return tmp_path


def _case_folder(base: Path, t_max: float = 5.0) -> tuple[Path, Path]:
    folder = base / "case"
    folder.mkdir()
    fst = folder / "x.fst"
    fst.write_text(f"------- OpenFAST\n{t_max:g}   TMax   - total run time (s)\n")
    return folder, fst


HEAD = "FAST_Solution:FAST_UpdateStates:SrvD_UpdateStates:DLL_controller_call:"
WRAPPED = "".join(f"out(b' {HEAD if k == 0 else ''}{'x' * 97}{k}\\n')\n" for k in range(10))

#: (name, FAKE_BODY, what follows, words the one line must hold)
OPENFAST_CASES = [
    ("ends normally", "print('OpenFAST terminated normally')", "ok", ""),
    ("exit 0, no normal end", "pass", "abort", "(exit code 0) with no message"),
    ("exit 1, silent", "sys.exit(1)", "abort", "(exit code 1) with no message; its screen"),
    ("exit 255", "sys.exit(255)", "abort", "(exit code 255) with no message"),
    ("normal end but exit 1", "print('OpenFAST terminated normally'); sys.exit(1)", "abort",
     "exit code 1"),
    ("SIGSEGV, silent", "die(signal.SIGSEGV)", "abort",
     "(exit code -11, SIGSEGV) with no message; its screen output is in"),
    ("SIGSEGV after a warning", f"print(' {HEAD}Warning: last values used'); "
     "die(signal.SIGSEGV)", "abort", "SIGSEGV) with no message"),
    ("SIGSEGV with gfortran's words", "print('Program received signal SIGSEGV: "
     "Segmentation fault - invalid memory reference.'); die(signal.SIGSEGV)", "abort",
     "SIGSEGV): Program received signal SIGSEGV: Segmentation fault"),
    ("SIGFPE", "die(signal.SIGFPE)", "abort", "(exit code -8, SIGFPE)"),
    ("SIGABRT", "die(signal.SIGABRT)", "abort", "(exit code -6, SIGABRT)"),
    ("SIGBUS", "die(signal.SIGBUS)", "abort", "(exit code -7, SIGBUS)"),
    ("SIGILL", "die(signal.SIGILL)", "abort", "(exit code -4, SIGILL)"),
    ("SIGKILL after a warning", f"print(' {HEAD}Warning: last values used'); "
     "die(signal.SIGKILL)", "killed", "OpenFAST was killed by SIGKILL"),
    ("SIGTERM", "die(signal.SIGTERM)", "killed", "killed by SIGTERM"),
    ("SIGHUP", "die(signal.SIGHUP)", "killed", "killed by SIGHUP"),
    ("SIGINT", "die(signal.SIGINT)", "killed", "killed by SIGINT"),
    ("SIGQUIT", "die(signal.SIGQUIT)", "killed", "killed by SIGQUIT"),
    ("SIGUSR1", "die(signal.SIGUSR1)", "killed", "killed by SIGUSR1"),
    ("SIGPIPE", "die(signal.SIGPIPE)", "killed", "killed by SIGPIPE"),
    ("hangs", "time.sleep(600)", "timeout", "OpenFAST timed out after 1.5 s"),
    ("hangs deaf to SIGTERM", "signal.signal(signal.SIGTERM, signal.SIG_IGN); "
     "time.sleep(600)", "timeout", "timed out"),
    ("hangs with a child", "sleeper(); wait_child(); time.sleep(600)", "timeout",
     "stopped with its process group"),
    ("leaves a child behind", "sleeper(); wait_child(); "
     "print('OpenFAST terminated normally')", "ok", ""),
    ("Latin-1 in its error", f"out(b' {HEAD}bad \\xb0 value\\n'); sys.exit(1)", "abort",
     "bad \u00b0 value"),
    ("invalid UTF-8 mid-line", f"out(b' {HEAD}a \\xff\\xfe b\\n'); sys.exit(1)", "abort",
     "a \u00ff\u00fe b"),
    ("NUL and control bytes", f"out(b' {HEAD}x\\x00y\\x07z\\x1b[0m\\n'); sys.exit(1)",
     "abort", "x y z"),
    ("only carriage returns", "out(b'Time: 1 of 5 s\\rTime: 2 of 5 s\\r'); sys.exit(1)",
     "abort", "with no message"),
    ("10 MB of output", "out(b'Time: 1 of 5 seconds\\n' * 500000); "
     f"out(b' {HEAD}the end\\n'); sys.exit(1)", "abort", "the end"),
    ("a 1-MB line, no newline", "out(b'y' * 1000000); sys.exit(2)", "abort", "exit code 2"),
    ("a message wrapped over 10 lines", WRAPPED + "sys.exit(1)", "abort", "x9"),
    ("its output closed", "os.close(1); os.close(2); sys.exit(1)", "abort",
     "with no message"),
    ("reads its input", "sys.stdin.read(); sys.exit(3)", "abort", "exit code 3"),
    ("floods stderr", "sys.stderr.write('e' * 2000000 + '\\n'); "
     f"sys.stderr.write(' {HEAD}failed\\n'); sys.exit(1)", "abort", "failed"),
    ("an error then a later one", f"print(' {HEAD}first'); print(' {HEAD}second'); "
     "sys.exit(1)", "abort", "second"),
]


@pytest.mark.parametrize("name, body, follows, words", OPENFAST_CASES,
                         ids=[c[0] for c in OPENFAST_CASES])
def test_openfast_misbehaving_is_one_line_and_leaves_nothing_running(
        fakes, monkeypatch, name, body, follows, words):
    monkeypatch.setenv("FAKE_BODY", body)
    if follows == "timeout":
        monkeypatch.setenv(programs.TIMEOUT_ENV, "1.5")
    folder, fst = _case_folder(fakes)
    said = None
    if follows in ("ok", "abort"):
        _, abort, _ = engine.simulate_in(folder, fst)
        said = abort
        assert (abort is None) == (follows == "ok")
    else:
        kind = ProgramKilled if follows == "killed" else programs.TimedOut
        with pytest.raises(kind) as exc:
            engine.simulate_in(folder, fst)
        said = str(exc.value)
    if said is not None:
        assert "\n" not in said and words in said and len(said) < 2600
        if follows == "abort":
            reason = said.partition(")")[2]
            assert said.startswith("OpenFAST stopped (exit code") and reason.strip(" :")
            assert "Warning" not in reason
    assert (folder / "openfast.log").is_file()
    assert gone(recorded(fakes / "pids"))
    with programs.folder_lock(folder):  # free for the next run
        pass


def test_a_message_longer_than_the_reason_keeps_is_cut_saying_where_the_rest_is(fakes,
                                                                                 monkeypatch):
    monkeypatch.setenv("FAKE_BODY", f"print(' {HEAD}' + 'word ' * 3000); sys.exit(1)")
    folder, fst = _case_folder(fakes)
    _, abort, _ = engine.simulate_in(folder, fst)
    assert "(cut; its screen output is in" in abort and str(folder / "openfast.log") in abort


def test_openfasts_limit_follows_the_cases_tmax(fakes, monkeypatch):
    """No variable: 60 s + 20 x TMax; the message says the rule."""
    monkeypatch.setenv("FAKE_BODY", "time.sleep(600)")
    monkeypatch.setattr(programs, "OPENFAST_START_S", 0.5)
    monkeypatch.setattr(programs, "OPENFAST_PER_SIMULATED_S", 0.1)
    folder, fst = _case_folder(fakes, t_max=5.0)
    t0 = time.monotonic()
    with pytest.raises(programs.TimedOut, match=r"after 1 s \(0\.5 s \+ 0\.1 x TMax = 5 s"):
        engine.simulate_in(folder, fst)
    assert time.monotonic() - t0 < 1 + programs.GRACE_S + 5
    assert gone(recorded(fakes / "pids"))


@pytest.mark.parametrize("value", ["abc", "0", "-1", "nan"])
def test_a_bad_timeout_variable_stops_before_openfast_runs(fakes, monkeypatch, value):
    monkeypatch.setenv(programs.TIMEOUT_ENV, value)
    monkeypatch.setenv("FAKE_BODY", "print('OpenFAST terminated normally')")
    folder, fst = _case_folder(fakes)
    with pytest.raises(ConfigError, match=programs.TIMEOUT_ENV):
        engine.simulate_in(folder, fst)
    assert recorded(fakes / "pids") == []


def test_a_second_openfast_into_a_busy_case_folder_is_refused(fakes, monkeypatch):
    """One OpenFAST runs in the folder (another process); a second run into it is refused
    in one line before it starts, and the first is not disturbed."""
    monkeypatch.setenv("FAKE_BODY", "time.sleep(600)")
    folder, fst = _case_folder(fakes)
    first = subprocess.Popen([PY, "-c", (
        f"import sys; sys.path.insert(0, {str(ROOT)!r})\nfrom pathlib import Path\n"
        f"from wtftc.openfast import engine\nengine.simulate_in(Path({str(folder)!r}), "
        f"Path({str(fst)!r}))\n")])
    try:
        end = time.monotonic() + 30
        while not recorded(fakes / "pids") and time.monotonic() < end:
            time.sleep(0.05)
        assert len(recorded(fakes / "pids")) == 1
        with pytest.raises(programs.FolderBusy) as exc:
            engine.simulate_in(folder, fst)
        assert "\n" not in str(exc.value) and str(folder) in str(exc.value)
        assert len(recorded(fakes / "pids")) == 1 and alive(recorded(fakes / "pids")[0])
    finally:
        first.kill()
        first.wait()
    assert gone(recorded(fakes / "pids"))


# ------------------------------------------------------------------------ .outb length

def _outb_case(tmp_path: Path, t_max: float = 2.0, dt: float = 0.5) -> ofcase.Case:
    folder = tmp_path / "case"
    folder.mkdir(exist_ok=True)
    fst = folder / "x.fst"
    fst.write_text(f"{t_max:g}  TMax\n")
    fst.with_suffix(".outb").write_bytes(b"stand-in")
    return ofcase.Case(folder, fst, dt, dt, folder / "wtftc_plant.in",
                       folder / "wtftc_plant_records.bin")


@pytest.mark.parametrize("times, words", [
    (np.arange(0, 3.01, 0.5), "7 rows for a case of 5"),
    (np.array([0, 0.5, 1.0, 1.5, 2.5]), "time up to 2.5 s past the case's TMax = 2 s"),
    (np.array([0.5, 1.0, 1.5, 2.0]), "do not rise from 0"),
    (np.array([0, 0.5, 1.5, 2.0]), "do not rise from 0"),
    (np.array([0, 0.5, 0.5, 1.0]), "do not rise from 0"),
    (np.arange(0, 2.0 + 1e-9, 0.25)[:5] * 0 + np.arange(5) * 0.6, "past the case's TMax"),
    (np.arange(0, 1.01, 0.5), "3 rows for a case of 5"),  # ended "normally", short
    (np.array([0, 0.5, np.nan, 1.5, 2.0]), "do not rise from 0"),
])
def test_an_outb_that_is_not_the_cases_is_refused_naming_it(tmp_path, monkeypatch, times,
                                                              words):
    """An .outb with more time than the case's TMax, more rows than its steps, or times
    not its own (OpenFAST writes every DT from 0) is another run's output."""
    import wtftc.config as config

    case = _outb_case(tmp_path)
    monkeypatch.setattr(engine, "read_outb", lambda p: {"Time": np.asarray(times, float)})
    rc = config.make_config({"engine": "openfast", "profile": "realistic",
                             "controller": "pi", "case": 1, "t_final_s": 2.0,
                             "wind": {"kind": "constant", "speed_mps": 16.0}})
    with pytest.raises(EngineError) as exc:
        engine.result(rc, case, 1.0, None)
    msg = str(exc.value)
    assert str(case.outb) in msg and words in msg and "delete it" in msg and "\n" not in msg


@pytest.mark.parametrize("data", [b"", b"\x01", b"garbage that is no output" * 10])
def test_an_outb_cut_short_or_foreign_is_one_line(tmp_path, data):
    """An empty, cut or foreign .outb (a full disk, a crash): an EngineError naming it, not
    the reader's own exception (struct.error)."""
    path = tmp_path / "x.outb"
    path.write_bytes(data)
    with pytest.raises(EngineError) as exc:
        engine.read_outb(path)
    assert str(path) in str(exc.value) and "\n" not in str(exc.value)


def test_an_outb_of_the_cases_length_or_shorter_passes_the_check(tmp_path):
    """The case's own length passes; a shorter one only where OpenFAST stopped early (an
    abort: the run is lost there), never where it said it ended normally."""
    case = _outb_case(tmp_path)
    engine._check_length(case, {"Time": np.arange(5) * 0.5}, 2.0, True)
    for n in (5, 3, 1):
        engine._check_length(case, {"Time": np.arange(n) * 0.5}, 2.0, False)


def test_an_earlier_runs_outb_is_not_read_as_this_runs(fakes, monkeypatch):
    """OpenFAST stops before writing any output: the .outb a run before left in the
    folder is removed first, so the run is OpenFAST's failure, not the old numbers."""
    monkeypatch.setenv("FAKE_BODY", f"print(' {HEAD}cannot start'); sys.exit(1)")
    case = _outb_case(fakes)
    case.outb.write_bytes(b"an earlier run's output")
    wall, abort = engine.simulate(case, progress=False)
    assert not case.outb.exists() and "cannot start" in abort


# ------------------------------------------------------------------------ TurbSim cache

FIELD = turbsim.Field(16.0, "B", 3, 90.0, 63.0, 2.0)


def bts_bytes(nt: int = 4, nz: int = 3, ny: int = 3, ntwr: int = 1, fid: int = 7) -> bytes:
    """A small TurbSim full field in TurbSim's format (wind_field's module docstring)."""
    head = struct.pack("<h4i6f6fi", fid, nz, ny, ntwr, nt, 10.0, 10.0, 0.05, 16.0, 90.0,
                       80.0, 1000.0, -16000.0, 1000.0, 0.0, 1000.0, 0.0, 4) + b"test"
    counts = np.arange(nt * 3 * (ny * nz + ntwr), dtype="<i2") % 300
    return head + counts.tobytes()


@pytest.fixture
def made_field(fakes, monkeypatch):
    """A field made by the fake TurbSim (copying a valid .bts) into the fresh cache."""
    good = fakes / "good.bts"
    good.write_bytes(bts_bytes())
    monkeypatch.setenv("FAKE_GOOD", str(good))
    monkeypatch.setenv("FAKE_BODY", "import shutil; shutil.copy(os.environ['FAKE_GOOD'], "
                                    "'field.bts')")
    path = turbsim.generate(FIELD)
    assert path.read_bytes() == good.read_bytes() and files.seal_damage(path) is None
    return path


def _flip(p: Path) -> None:
    b = bytearray(p.read_bytes())
    b[-10] ^= 0x40
    p.write_bytes(bytes(b))


def _reseal_with_bad_header(p: Path) -> None:
    p.write_bytes(struct.pack("<h", 9) + p.read_bytes()[2:])
    files.seal(p)


DAMAGE = [
    ("a flipped byte, same size", _flip, "sha256"),
    ("truncated", lambda p: p.write_bytes(p.read_bytes()[:-100]), "bytes"),
    ("empty", lambda p: p.write_bytes(b""), "0 bytes"),
    ("a bad header, resealed", _reseal_with_bad_header, "file ID 9"),
    ("cut short, resealed", lambda p: (p.write_bytes(p.read_bytes()[:200]), files.seal(p)),
     "cut short"),
    ("no seal", lambda p: files.seal_path(p).unlink(), "no checksum"),
    ("a seal of garbage", lambda p: files.seal_path(p).write_text("{garbage"), "unreadable"),
    ("a seal that is a list", lambda p: files.seal_path(p).write_text("[1, 2]"),
     "not a listing"),
    ("a seal that is empty", lambda p: files.seal_path(p).write_text(""), "unreadable"),
    ("the field deleted, its seal left", lambda p: p.unlink(), "missing"),
    ("garbage of the same size", lambda p: p.write_bytes(b"\xff" * p.stat().st_size),
     "sha256"),
]


@pytest.mark.parametrize("name, spoil, why", DAMAGE, ids=[d[0] for d in DAMAGE])
def test_a_damaged_field_is_rebuilt_once_with_one_line(made_field, capsys, name, spoil, why):
    good = made_field.read_bytes() if made_field.exists() else None
    spoil(made_field)
    capsys.readouterr()
    assert turbsim.generate(FIELD) == made_field
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"wtftc: {made_field} in WTFTC_CACHE is "
                                                   "damaged (") and why in err
    assert err.rstrip().endswith("; rebuilding it")
    assert made_field.read_bytes() == good and files.seal_damage(made_field) is None
    capsys.readouterr()
    turbsim.generate(FIELD)  # whole now: used as it is, silently
    assert capsys.readouterr().err == ""


def test_a_field_damaged_again_after_its_rebuild_names_what_to_delete(made_field,
                                                                       monkeypatch, capsys):
    _flip(made_field)
    monkeypatch.setattr(turbsim, "damage", lambda p: "sha256 changed")
    with pytest.raises(EngineError) as exc:
        turbsim.generate(FIELD)
    msg = str(exc.value)
    assert f"delete {made_field} and {files.seal_path(made_field)}" in msg
    assert "\n" not in msg and capsys.readouterr().err.count("\n") == 1


def test_a_folder_in_place_of_the_field_is_one_line_naming_it(made_field, capsys):
    made_field.unlink()
    made_field.mkdir()
    (made_field / "user file").write_text("mine")
    with pytest.raises(EngineError) as exc:
        turbsim.generate(FIELD)
    assert f"delete {made_field}" in str(exc.value) and "\n" not in str(exc.value)
    assert (made_field / "user file").read_text() == "mine"


TURBSIM_FAILS = [
    ("garbage, exit 0", "open('field.bts', 'wb').write(b'garbage' * 100)",
     EngineError, "TurbSim failed (exit code 0 but its field.bts is not a field"),
    ("an empty field, exit 0", "open('field.bts', 'wb').close()", EngineError,
     "is not a field: 0 bytes"),
    ("a field with a bad ID, exit 0",
     "open('field.bts', 'wb').write(b'\\x09\\x00' + open(os.environ['FAKE_GOOD'], 'rb')"
     ".read()[2:])", EngineError, "file ID 9"),
    ("no field, exit 0", "print('done')", EngineError, "exit code 0 but no field.bts"),
    ("exit 1 with its words", "print('TurbSim: invalid grid'); sys.exit(1)", EngineError,
     "TurbSim failed (exit code 1): TurbSim: invalid grid"),
    ("exit 1, silent", "sys.exit(1)", EngineError, "it printed nothing"),
    ("SIGSEGV", "die(signal.SIGSEGV)", EngineError, "exit code -11, SIGSEGV"),
    ("killed by SIGKILL", "die(signal.SIGKILL)", ProgramKilled, "TurbSim was killed by SIGKILL"),
    ("killed by SIGTERM", "die(signal.SIGTERM)", ProgramKilled, "killed by SIGTERM"),
    ("hangs", "time.sleep(600)", programs.TimedOut, "TurbSim timed out after 1.5 s"),
    ("hangs with a child", "sleeper(); wait_child(); time.sleep(600)", programs.TimedOut,
     "timed out"),
    ("Latin-1 words, exit 2", "out(b'grid \\xb0 bad\\n'); sys.exit(2)", EngineError,
     "grid \u00b0 bad"),
]


@pytest.mark.parametrize("name, body, kind, words", TURBSIM_FAILS,
                         ids=[c[0] for c in TURBSIM_FAILS])
def test_turbsim_failing_is_one_line_and_caches_nothing(fakes, monkeypatch, name, body, kind,
                                                       words):
    good = fakes / "good.bts"
    good.write_bytes(bts_bytes())
    monkeypatch.setenv("FAKE_GOOD", str(good))
    monkeypatch.setenv("FAKE_BODY", body)
    monkeypatch.setenv(programs.TIMEOUT_ENV, "1.5")
    with pytest.raises(kind) as exc:
        turbsim.generate(FIELD)
    msg = str(exc.value)
    assert words in msg and "\n" not in msg
    path = turbsim.field_path(FIELD)
    assert not path.exists() and not files.seal_path(path).exists()
    assert list(path.parent.glob(".turbsim-*")) == []
    assert gone(recorded(fakes / "pids"))
    # its screen output kept, and named where it is
    assert str(path.with_suffix(".log")) in msg and path.with_suffix(".log").is_file()


def _stale(folder: Path, name: str, lock: bool, age_s: float) -> Path:
    tmp = folder / name
    tmp.mkdir(parents=True)
    (tmp / "field.inp").write_text("x")
    if lock:
        (tmp / turbsim.TEMP_LOCK).write_text("")
    old = time.time() - age_s
    os.utime(tmp, (old, old))
    return tmp


@pytest.mark.parametrize("lock, age_s, removed", [
    (True, 0, True),  # its lock free: its maker is gone
    (True, 3600, True),
    (False, 3600, True),  # no lock, old: left by a run from before locks
    (False, 0, False),  # no lock yet, new: its maker may be about to lock it
])
def test_stale_turbsim_folders_are_removed_on_the_next_use(made_field, lock, age_s,
                                                           removed):
    tmp = _stale(made_field.parent, ".turbsim-killed", lock, age_s)
    turbsim.generate(FIELD)
    assert tmp.exists() is not removed


def test_a_turbsim_folder_in_use_is_left_alone(made_field):
    import fcntl

    tmp = _stale(made_field.parent, ".turbsim-live", True, 3600)
    fd = os.open(tmp / turbsim.TEMP_LOCK, os.O_RDONLY)
    holder = subprocess.Popen([PY, "-c", "import time; time.sleep(600)"], pass_fds=(fd,))
    fcntl.flock(fd, fcntl.LOCK_EX)
    os.close(fd)  # the lock is the live holder's now
    try:
        turbsim.generate(FIELD)
        assert tmp.is_dir()
    finally:
        holder.kill()
        holder.wait()
    turbsim.generate(FIELD)
    assert not tmp.exists()


@pytest.mark.parametrize("kind", ["symlink", "file"])
def test_what_only_looks_like_a_turbsim_folder_is_not_followed(made_field, tmp_path, kind):
    mine = tmp_path / "users"
    mine.mkdir()
    (mine / "keep").write_text("mine")
    link = made_field.parent / ".turbsim-odd"
    if kind == "symlink":
        link.symlink_to(mine)
    else:
        link.write_text("a file")
    turbsim.generate(FIELD)
    assert (mine / "keep").read_text() == "mine" and link.exists()


def test_a_turbsim_killed_with_wtftc_leaves_a_folder_the_next_run_removes(fakes):
    """wtftc killed outright while TurbSim runs: TurbSim dies too (parent-death signal),
    its temporary folder stays; the next generate removes it and makes the field."""
    good = fakes / "good.bts"
    good.write_bytes(bts_bytes())
    env = {**os.environ, "FAKE_BODY": "time.sleep(600)", "FAKE_GOOD": str(good)}
    code = (f"import sys; sys.path.insert(0, {str(ROOT)!r})\n"
            "from wtftc.openfast import turbsim\n"
            "turbsim.generate(turbsim.Field(16.0, 'B', 3, 90.0, 63.0, 2.0))\n")
    runner = subprocess.Popen([PY, "-c", code], env=env)
    end = time.monotonic() + 30
    while not recorded(fakes / "pids") and time.monotonic() < end:
        time.sleep(0.05)
    runner.kill()
    runner.wait()
    assert gone(recorded(fakes / "pids"))
    folder = turbsim.field_path(FIELD).parent
    assert len(list(folder.glob(".turbsim-*"))) == 1
    os.environ["FAKE_BODY"] = "import shutil; shutil.copy(os.environ['FAKE_GOOD'], " \
                              "'field.bts')"
    os.environ["FAKE_GOOD"] = str(good)
    try:
        assert turbsim.generate(FIELD).read_bytes() == good.read_bytes()
    finally:
        del os.environ["FAKE_BODY"], os.environ["FAKE_GOOD"]
    assert list(folder.glob(".turbsim-*")) == []


@pytest.mark.parametrize("spoil", [_flip, lambda p: files.seal_path(p).unlink(),
                                   lambda p: p.write_bytes(b"")],
                         ids=["flipped", "no seal", "empty"])
def test_wtftcs_own_plant_refuses_a_damaged_field_naming_what_to_delete(made_field, spoil):
    spoil(made_field)
    ntm = {"parameters": {"mean_mps": 16.0, "turbulence_class": "B"}, "seed": 3}
    with pytest.raises(EngineError) as exc:
        wind_field.field_wind(FIELD, ntm, 2.0)
    msg = str(exc.value)
    assert f"{made_field} in WTFTC_CACHE is damaged" in msg and "delete it" in msg
    assert "\n" not in msg


def test_the_real_turbsims_field_with_a_flipped_byte_is_made_again(tmp_path, monkeypatch,
                                                                    capsys):
    """The real TurbSim's field with a byte of its data flipped, same size (it was used
    as it was, a wrong mean wind): found by its seal and made again, the same wind as
    before. (Not the same bytes: TurbSim writes the time it ran into the field's
    description.)"""
    inst = install.require()
    monkeypatch.setenv("OPENFAST", str(inst.openfast))
    monkeypatch.setenv("TURBSIM", str(inst.turbsim))
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path / "cache"))
    field = turbsim.Field(16.32, "B", 5, 90.0, 63.0, 2.0)
    path = turbsim.generate(field)
    first = path.read_bytes()
    before = wind_field.read_bts(path)
    b = bytearray(first)
    b[len(b) // 2] ^= 0x7F  # in the wind's data, far past the header
    path.write_bytes(bytes(b))
    assert len(path.read_bytes()) == len(first)
    capsys.readouterr()
    turbsim.generate(field)
    assert "damaged (sha256" in capsys.readouterr().err
    again = wind_field.read_bts(path)
    assert len(path.read_bytes()) == len(first)
    for name in ("u", "v", "w", "u_tower"):
        assert np.array_equal(getattr(again, name), getattr(before, name)), name


# ------------------------------------------------------------------------ decks, leniently

def _deck(tmp_path: Path, main: bytes, inflow: bytes | None) -> Path:
    fst = tmp_path / "deck" / "main.fst"
    fst.parent.mkdir(exist_ok=True)
    fst.write_bytes(main)
    if inflow is not None:
        (fst.parent / "inflow.dat").write_bytes(inflow)
    return fst


GOOD_MAIN = b'"inflow.dat"   InflowFile  - the wind\n'
GOOD_INFLOW = b"90.0   RefHt  - hub height (m)\n"

DECKS = [
    ("Latin-1 degree in the main file", b"! 5\xb0 tilt\n" + GOOD_MAIN, GOOD_INFLOW, 90.0),
    ("Latin-1 in the InflowWind file", GOOD_MAIN, b"! \xe9t\xe9\n" + GOOD_INFLOW, 90.0),
    ("UTF-8 with a BOM", b"\xef\xbb\xbf" + GOOD_MAIN, GOOD_INFLOW, 90.0),
    ("CRLF line ends", GOOD_MAIN.replace(b"\n", b"\r\n"),
     GOOD_INFLOW.replace(b"\n", b"\r\n"), 90.0),
    ("UTF-8 degree sign", "! 5° tilt\n".encode() + GOOD_MAIN, GOOD_INFLOW, 90.0),
    ("binary main file", bytes(range(256)) * 4, GOOD_INFLOW, EngineError),
    ("no InflowFile line", b"nothing here\n", GOOD_INFLOW, EngineError),
    ("InflowWind file missing", GOOD_MAIN, None, ConfigError),
    ("RefHt a word", GOOD_MAIN, b"ninety   RefHt\n", ConfigError),
    ("RefHt negative", GOOD_MAIN, b"-90   RefHt\n", ConfigError),
    ("RefHt nan", GOOD_MAIN, b"nan   RefHt\n", ConfigError),
    ("RefHt inf", GOOD_MAIN, b"inf   RefHt\n", ConfigError),
    ("RefHt zero", GOOD_MAIN, b"0   RefHt\n", ConfigError),
    ("binary InflowWind file", GOOD_MAIN, b"\x00\xff" * 500, EngineError),
]


@pytest.mark.parametrize("name, main, inflow, expect", DECKS, ids=[d[0] for d in DECKS])
def test_a_deck_is_read_as_its_author_wrote_it(tmp_path, name, main, inflow, expect):
    fst = _deck(tmp_path, main, inflow)
    before = {p: p.read_bytes() for p in fst.parent.iterdir()}
    if isinstance(expect, float):
        assert wind_field.deck_hub_height(fst) == expect
    else:
        with pytest.raises(expect) as exc:
            wind_field.deck_hub_height(fst)
        assert "\n" not in str(exc.value) and not isinstance(exc.value, UnicodeError)
    assert {p: p.read_bytes() for p in fst.parent.iterdir()} == before


@pytest.mark.parametrize("make", ["folder", "loop", "fifo"])
def test_an_inflowwind_file_that_is_no_file_is_one_line(tmp_path, make):
    """A folder, a link loop or a FIFO (which an open would block on) where the deck names
    its InflowWind file: one line naming it."""
    fst = _deck(tmp_path, GOOD_MAIN, None)
    target = fst.parent / "inflow.dat"
    if make == "folder":
        target.mkdir()
    elif make == "fifo":
        os.mkfifo(target)
    else:
        target.symlink_to(target)
    with pytest.raises(ConfigError) as exc:
        wind_field.deck_hub_height(fst)
    assert "\n" not in str(exc.value) and str(target) in str(exc.value)


# ------------------------------------------------------------------ wtftc killed meanwhile

#: the cache of the machine (the plant library and controllers compiled once): the fakes
#: fixture points WTFTC_CACHE elsewhere, the commands below run on the real one
MACHINE_CACHE = os.environ.get("WTFTC_CACHE")


def descendants(pid: int) -> set[int]:
    """Every process below ``pid`` now (from the process table)."""
    parent = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                parent[int(d.name)] = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, pp in parent.items() if pp in frontier} - found
        found |= frontier
    return found


def _command_env(extra: dict) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "WTFTC_CACHE"}
    if MACHINE_CACHE:
        env["WTFTC_CACHE"] = MACHINE_CACHE
    return {**env, **extra}


def _wait_for(pred, within_s: float) -> bool:
    end = time.monotonic() + within_s
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(0.1)
    return False


RUN = ["run", "--engine", "openfast", "--controller", "pi", "--profile", "realistic",
       "--wind", "constant", "--wind-mean", "16", "--fault", "none", "--quiet"]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGKILL])
def test_killing_wtftc_run_leaves_no_openfast_running(fakes, sig):
    """`wtftc run --engine openfast` stopped while OpenFAST runs (a fake that would run
    for ten minutes): OpenFAST is gone within a few seconds. SIGTERM and Ctrl-C end wtftc
    as an interrupt (exit code 130), with no --out and no partial folder left."""
    out = fakes / "run"
    p = subprocess.Popen([PY, "-m", "wtftc.cli", *RUN, "--t-final", "5", "--out", str(out)],
                         env=_command_env({"FAKE_BODY": "time.sleep(600)"}),
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_for(lambda: recorded(fakes / "pids"), 180), p.stderr
        below = descendants(p.pid)
        os.kill(p.pid, sig)
        p.wait(timeout=30)
        err = p.stderr.read()
    finally:
        if p.poll() is None:
            p.kill()
    assert recorded(fakes / "pids")[0] in below
    assert gone(below | set(recorded(fakes / "pids")), 5.0)
    assert not out.exists()
    if sig != signal.SIGKILL:
        assert p.returncode == 130 and err.strip() == "wtftc: interrupted"
        assert list(fakes.glob(".run.*")) == []


def test_sigkill_to_wtftc_run_leaves_no_real_openfast_running(tmp_path):
    """The real OpenFAST on a 300-s case, wtftc killed outright as soon as OpenFAST
    runs: no OpenFAST is left (the kernel's parent-death signal)."""
    out = tmp_path / "run"
    p = subprocess.Popen([PY, "-m", "wtftc.cli", *RUN, "--t-final", "300", "--out", str(out)],
                         env=_command_env({}), stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)

    def openfast_children() -> set[int]:
        return {q for q in descendants(p.pid)
                if Path(f"/proc/{q}/comm").is_file()
                and Path(f"/proc/{q}/comm").read_text().strip() == "openfast"}

    def the_case() -> set[int]:
        """The OpenFAST children alive 0.5 s apart: the case's run, not the version
        probe (``openfast -v``, install.py) that ends at once."""
        first = openfast_children()
        time.sleep(0.5)
        return first & openfast_children()

    try:
        end, running = time.monotonic() + 180, set()
        while not running and time.monotonic() < end:
            running = the_case()
        p.kill()
        p.wait()
    finally:
        if p.poll() is None:
            p.kill()
    assert running and gone(running, 5.0)


def test_a_wtftc_run_killed_outright_frees_its_folder_for_the_next(fakes):
    """SIGKILL to wtftc during OpenFAST: the next run into the same --out starts and ends
    (the lock went with the killed processes)."""
    out = fakes / "run"
    p = subprocess.Popen([PY, "-m", "wtftc.cli", *RUN, "--t-final", "2", "--out", str(out)],
                         env=_command_env({"FAKE_BODY": "time.sleep(600)"}),
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    assert _wait_for(lambda: recorded(fakes / "pids"), 180)
    p.kill()
    p.wait()
    assert gone(recorded(fakes / "pids"))
    again = subprocess.run([PY, "-m", "wtftc.cli", *RUN, "--t-final", "2", "--out", str(out)],
                           env=_command_env({"FAKE_BODY": "sys.exit(1)"}),
                           capture_output=True, text=True, timeout=300)
    assert again.returncode == 4 and again.stderr.count("\n") == 1
    assert "OpenFAST stopped (exit code 1) with no message" in again.stderr
    assert not out.exists()
    # the files the message names are there: the failed case is kept in the cache (the
    # folder it ran in, beside --out, is gone)
    named = re.findall(r"(/[^\s;()]+openfast\.log)", again.stderr)
    assert named and all(Path(n).is_file() for n in named), again.stderr
    assert ".partial" not in again.stderr


SWEEP = """t_final_s = 4.0
controllers = ["pi"]
[wind]
mean_mps = 16.0
seed = 0
"""


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_killing_an_openfast_sweep_leaves_nothing_running(fakes, sig):
    """`wtftc sweep --engine openfast` stopped while its OpenFAST runs in a Dask worker:
    every process below the sweep (the workers, OpenFAST) is gone within seconds."""
    spec = fakes / "of.toml"
    spec.write_text(SWEEP)
    real = _real_turbsim()
    p = subprocess.Popen([PY, "-m", "wtftc.cli", "sweep", str(spec), "--engine", "openfast",
                          "--workers", "1", "--out", str(fakes / "res")],
                         env=_command_env({"FAKE_BODY": "time.sleep(600)", "TURBSIM": real}),
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        assert _wait_for(lambda: recorded(fakes / "pids"), 240)
        below = descendants(p.pid)
        os.kill(p.pid, sig)
        p.wait(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert recorded(fakes / "pids")[0] in below
    assert gone(below | set(recorded(fakes / "pids")), 15.0), \
        [q for q in below if alive(q)]


def _real_turbsim() -> str:
    saved = {k: os.environ.pop(k) for k in ("OPENFAST", "TURBSIM", "WTFTC_CACHE")
             if k in os.environ}
    if MACHINE_CACHE:
        os.environ["WTFTC_CACHE"] = MACHINE_CACHE
    try:
        return str(install.require().turbsim)
    finally:
        os.environ.pop("WTFTC_CACHE", None)
        os.environ.update(saved)


# ------------------------------------------------------------------- wtftc modes' OpenFAST

def _linearize(tmp_path):
    from wtftc.config import openfast_deck
    from wtftc.model import turbine_file
    from wtftc.openfast import linearization

    deck = openfast_deck(turbine_file.load(turbine_file.DEFAULT))
    g = linearization.Guess(omega_r=1.267, pitch=0.2, tower_x=0.3, torque_hss=43093.0,
                            gearbox=97.0, f_max=2.0)
    return linearization.linearize(deck, 16.0, "rigid", 2, g, progress=False)


def test_a_failed_linearization_says_openfasts_whole_error_and_keeps_its_log(fakes,
                                                                            monkeypatch):
    """OpenFAST's error, wrapped over ten lines, is in the message whole; the case and
    OpenFAST's screen output are kept in the cache, and the message says where."""
    monkeypatch.setenv("FAKE_BODY", WRAPPED + "out(b' OpenFAST encountered an error at "
                       "simulation time 0 of 90 seconds.\\n'); sys.exit(1)")
    with pytest.raises(EngineError) as exc:
        _linearize(fakes)
    msg = str(exc.value)
    assert "\n" not in msg and all(f"x{k}" in msg for k in range(10))
    kept = next((fakes / "cache" / "openfast_lin").glob("failed-*"))
    assert f"OpenFAST's screen output is in {kept / 'openfast.log'}" in msg
    assert (kept / "openfast.log").read_bytes().count(b"x" * 97) == 10
    assert list((fakes / "cache" / "openfast_lin").glob(".work-*")) == []


@pytest.mark.parametrize("body, kind, words", [
    ("die(signal.SIGKILL)", ProgramKilled, "OpenFAST was killed by SIGKILL"),
    ("time.sleep(600)", programs.TimedOut, "OpenFAST timed out after 1.5 s"),
    ("die(signal.SIGSEGV)", EngineError, "(exit code -11, SIGSEGV) with no message; its "
     "screen output is in"),
])
def test_a_linearization_stopped_says_why_and_where_its_log_is(fakes, monkeypatch, body, kind,
                                                              words):
    monkeypatch.setenv("FAKE_BODY", body)
    monkeypatch.setenv(programs.TIMEOUT_ENV, "1.5")
    with pytest.raises(kind) as exc:
        _linearize(fakes)
    msg = str(exc.value)
    kept = next((fakes / "cache" / "openfast_lin").glob("failed-*"))
    assert words in msg and str(kept / "openfast.log") in msg and "\n" not in msg
    assert ".work-" not in msg  # the paths it names are where the files are now
    assert gone(recorded(fakes / "pids"))
