"""wtftc.programs: an external program in its own process group, under a time limit,
stopped whole with wtftc (an exception, Ctrl-C, SIGTERM, wtftc killed outright), a signal
of another's told apart from a crash, and a folder held by one run at a time.

The programs here are small Python scripts; each writes the process ids of itself and of
what it starts into a file, and the tests look them up in the process table after."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import pytest
from processes import gone

from wtftc import programs
from wtftc.errors import ConfigError, EngineError, ProgramKilled

PY = sys.executable


def pids_of(path: Path) -> list[int]:
    return [int(w) for w in path.read_text().split()] if path.is_file() else []


def script(tmp_path: Path, body: str, name: str = "prog.py") -> list[str]:
    """A Python program that first records its pid in ``pids`` beside it."""
    p = tmp_path / name
    p.write_text("import os, sys, time, signal, subprocess\n"
                 f"PIDS = {str(tmp_path / 'pids')!r}\n"
                 "open(PIDS, 'a').write(f'{os.getpid()} ')\n"
                 "def sleeper():  # a child that records itself and sleeps\n"
                 "    return subprocess.Popen([sys.executable, '-c', 'import os, sys, time; "
                 "open(sys.argv[1], \"a\").write(str(os.getpid()) + \" \"); time.sleep(600)',"
                 " PIDS])\n" + textwrap.dedent(body))
    return [PY, str(p)]


#: the program waits until its child has recorded itself
WAIT_CHILD = "while len(open(PIDS).read().split()) < 2:\n    time.sleep(0.02)\n"


def prog(limit: float = 30.0) -> programs.Program:
    return programs.Program("Fake", limit, "a test's limit", "do what the test says")


def test_a_program_that_ends_is_reported_with_its_code_and_log(tmp_path):
    done = programs.run(script(tmp_path, "print('hé'); sys.exit(3)\n"), tmp_path,
                        tmp_path / "log", prog())
    assert done.code == 3 and done.text().strip() == "hé" and done.log == tmp_path / "log"
    assert gone(pids_of(tmp_path / "pids"))


def test_stdin_is_dev_null_so_a_program_reading_it_does_not_hang(tmp_path):
    done = programs.run(script(tmp_path, "print(repr(sys.stdin.read()))\n"), tmp_path,
                        tmp_path / "log", prog(10.0))
    assert done.code == 0 and done.text().strip() == "''"


def test_a_hang_is_stopped_at_its_time_limit_with_its_whole_group(tmp_path):
    """A program that starts a child and both sleep: past the limit both are gone, and
    the message names the program, the limit and what to do."""
    body = f"sleeper()\n{WAIT_CHILD}time.sleep(600)\n"
    t0 = time.monotonic()
    with pytest.raises(programs.TimedOut) as exc:
        programs.run(script(tmp_path, body), tmp_path, tmp_path / "log", prog(5.0))
    assert time.monotonic() - t0 < 5.0 + programs.GRACE_S + 5
    msg = str(exc.value)
    assert msg.startswith("Fake timed out after 5 s (a test's limit)") and "do what the " \
        "test says" in msg and str(tmp_path / "log") in msg and "\n" not in msg
    pids = pids_of(tmp_path / "pids")
    assert len(pids) == 2 and gone(pids)


def test_a_hang_that_ignores_sigterm_is_killed_after_the_grace(tmp_path, monkeypatch):
    monkeypatch.setattr(programs, "GRACE_S", 0.5)
    body = "signal.signal(signal.SIGTERM, signal.SIG_IGN)\ntime.sleep(600)\n"
    with pytest.raises(programs.TimedOut):
        programs.run(script(tmp_path, body), tmp_path, tmp_path / "log", prog(1.0))
    assert gone(pids_of(tmp_path / "pids"), 1.0)


def test_what_a_program_leaves_in_its_group_goes_with_it(tmp_path):
    """The program exits at once, its child would sleep on: the child is stopped too."""
    body = f"sleeper()\n{WAIT_CHILD}"
    done = programs.run(script(tmp_path, body), tmp_path, tmp_path / "log", prog())
    assert done.code == 0
    pids = pids_of(tmp_path / "pids")
    assert len(pids) == 2 and gone(pids)


def test_an_exception_in_wtftc_stops_the_program(tmp_path):
    def watch():
        raise RuntimeError("wtftc failed meanwhile")

    with pytest.raises(RuntimeError, match="meanwhile"):
        programs.run(script(tmp_path, "time.sleep(600)\n"), tmp_path, tmp_path / "log",
                     prog(), watch=watch, every_s=0.2)
    assert gone(pids_of(tmp_path / "pids"))


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM, signal.SIGHUP,
                                 signal.SIGINT, signal.SIGUSR1, signal.SIGQUIT])
def test_a_signal_of_anothers_is_program_killed_by_its_name(tmp_path, sig):
    body = f"time.sleep(0.2)\nos.kill(os.getpid(), {int(sig)})\ntime.sleep(10)\n"
    with pytest.raises(ProgramKilled) as exc:
        programs.run(script(tmp_path, "print('a warning: nothing wrong')\n" + body),
                     tmp_path, tmp_path / "log", prog())
    msg = str(exc.value)
    assert msg.startswith(f"Fake was killed by {sig.name} (exit code {-int(sig)})")
    assert "warning" not in msg and "unfinished" in msg and str(tmp_path / "log") in msg


@pytest.mark.parametrize("sig", sorted(programs.CRASHES))
def test_a_crash_is_the_programs_own_exit_code_not_a_kill(tmp_path, sig):
    body = ("import resource\nresource.setrlimit(resource.RLIMIT_CORE, (0, 0))\n"
            f"os.kill(os.getpid(), {int(sig)})\ntime.sleep(10)\n")
    done = programs.run(script(tmp_path, body), tmp_path, tmp_path / "log", prog())
    assert done.code == -int(sig) and programs.signal_name(done.code) == sig.name


def test_sigterm_to_wtftc_stops_the_program_and_raises_as_ctrl_c(tmp_path):
    """SIGTERM to the process running a program (the default handler would end it at once
    and leave the program running): KeyboardInterrupt, the program stopped first."""
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGTERM))
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            programs.run(script(tmp_path, "time.sleep(600)\n"), tmp_path, tmp_path / "log",
                         prog())
    finally:
        timer.cancel()
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    assert gone(pids_of(tmp_path / "pids"))


DRIVER = """
import os, sys, threading
sys.path.insert(0, {root!r})
from pathlib import Path
from wtftc import programs
SLEEPER = ("import os,time; open({pids!r}, 'a').write(str(os.getpid()) + ' '); "
           "time.sleep(600)")
WRAPPER = ("import subprocess,sys,time; subprocess.Popen([sys.executable, '-c', {{s!r}}]);"
           " exec({{s!r}})")
def go():
    body = {program} == "wrapper" and WRAPPER.format(s=SLEEPER) or SLEEPER
    programs.run([sys.executable, "-c", body], Path({tmp!r}), Path({log!r}),
                 programs.Program("Fake", 600, "r", "h"))
{how}
"""


@pytest.mark.parametrize("program", ["direct", "wrapper"])
@pytest.mark.parametrize("how", ["go()", "t = threading.Thread(target=go); t.start(); t.join()"])
def test_a_program_dies_with_wtftc_killed_outright(tmp_path, how, program):
    """SIGKILL to the process that runs a program, from its main thread or another (the
    parent-death signal follows the thread that forked, which waits): the program dies
    too, within a few seconds; so does what a wrapper of it started (the watchdog's work:
    the parent-death signal reaches the direct child only)."""
    pids = tmp_path / "pids"
    code = DRIVER.format(root=str(Path(__file__).resolve().parents[1]), pids=str(pids),
                         tmp=str(tmp_path), log=str(tmp_path / "log"), how=how,
                         program=repr(program))
    driver = subprocess.Popen([PY, "-c", code])
    end = time.monotonic() + 20
    while len(pids_of(pids)) < (2 if program == "wrapper" else 1) \
            and time.monotonic() < end:
        time.sleep(0.05)
    assert len(pids_of(pids)) == (2 if program == "wrapper" else 1), "it did not start"
    driver.kill()
    driver.wait()
    assert gone(pids_of(pids), 5.0)


def test_the_parent_death_request_is_made_before_exec(tmp_path):
    """The child's setup asks for SIGKILL on its parent's death (prctl PR_GET_PDEATHSIG
    reads it back from the running program)."""
    body = ("import ctypes\nlibc = ctypes.CDLL(None)\nv = ctypes.c_int(-1)\n"
            "libc.prctl(2, ctypes.byref(v), 0, 0, 0)\nprint(v.value)\n")
    done = programs.run(script(tmp_path, body), tmp_path, tmp_path / "log", prog())
    assert done.text().strip() == str(int(signal.SIGKILL))


def test_a_child_whose_parent_is_gone_before_the_request_kills_itself(monkeypatch):
    """The race the check closes: setup run where the parent is not the one expected."""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: its "parent" is a process id that is not its parent
        os.close(r)
        try:
            programs._child_setup(os.getppid() + 1000000)()
            os.write(w, b"survived")
        finally:
            os._exit(0)
    os.close(w)
    _, status = os.waitpid(pid, 0)
    said = os.read(r, 100)
    os.close(r)
    assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL and said == b""


# ------------------------------------------------------------------------ time limits

@pytest.mark.parametrize("value", ["abc", "0", "-5", "nan", "inf", "1e400", "  ", "3 s",
                                   "1e10", "3.3e7"])
def test_a_bad_timeout_variable_is_one_line_naming_it(monkeypatch, value):
    """Not a number of seconds in (0, a year]: one line naming the variable (1e10 s
    overflowed the wait's clock, a traceback, before it was bounded)."""
    monkeypatch.setenv(programs.TIMEOUT_ENV, value)
    if not value.strip():
        assert programs.openfast_limit_s(10.0) == 260.0  # unset: the rule
        return
    with pytest.raises(ConfigError) as exc:
        programs.openfast_limit_s(10.0)
    assert exc.value.field == programs.TIMEOUT_ENV and "\n" not in str(exc.value)


def test_the_longest_time_limit_is_waited_on_without_overflow(tmp_path, monkeypatch):
    """The largest limit allowed passes through the wait (select's timeout) as any other."""
    monkeypatch.setenv(programs.TIMEOUT_ENV, f"{programs.MAX_LIMIT_S:g}")
    limit = programs.openfast_limit_s(10.0)
    done = programs.run(script(tmp_path, "pass\n"), tmp_path, tmp_path / "log",
                        programs.Program("Fake", limit, "r", "h"))
    assert limit == programs.MAX_LIMIT_S and done.code == 0


def test_the_limits_follow_their_rules_and_the_variable_replaces_them(monkeypatch):
    monkeypatch.delenv(programs.TIMEOUT_ENV, raising=False)
    assert programs.openfast_limit_s(20.0) == 60.0 + 20.0 * 20.0
    # the default field (13 x 13 points and 13 tower points, 600 s at 0.05 s): measured
    # 9 s; 31 x 31 for 110 s: measured 263 s. The limits are 15-20 times those.
    assert 9 * 10 < programs.turbsim_limit_s(182, 12001) < 9 * 40
    assert 263 * 10 < programs.turbsim_limit_s(961, 2201) < 263 * 40
    monkeypatch.setenv(programs.TIMEOUT_ENV, "7.5")
    assert programs.openfast_limit_s(1e6) == programs.turbsim_limit_s(10**4, 10**6) == 7.5


# ------------------------------------------------------------------------- folder lock

def test_a_folder_is_held_by_one_run_and_named_to_a_second(tmp_path):
    root = str(Path(__file__).resolve().parents[1])
    holder = subprocess.Popen([PY, "-c", (
        f"import sys, time; sys.path.insert(0, {root!r})\nfrom wtftc import programs\n"
        f"with programs.folder_lock({str(tmp_path)!r}):\n"
        "    print('held', flush=True); time.sleep(600)\n")],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(programs.FolderBusy) as exc:
            with programs.folder_lock(tmp_path, "OpenFAST case folder"):
                pass
        msg = str(exc.value)
        assert f"process {holder.pid}" in msg and str(tmp_path) in msg and "\n" not in msg
    finally:
        holder.kill()
        holder.wait()
    with programs.folder_lock(tmp_path):  # free again once its holder is gone
        pass


def test_the_lock_is_reentrant_in_a_thread_and_refused_to_another(tmp_path):
    with programs.folder_lock(tmp_path) as fd, programs.folder_lock(tmp_path) as again:
        assert fd == again
        seen = []

        def other():
            try:
                with programs.folder_lock(tmp_path):
                    seen.append("held")
            except programs.FolderBusy:
                seen.append("busy")

        t = threading.Thread(target=other)
        t.start()
        t.join()
        assert seen == ["busy"]
    with programs.folder_lock(tmp_path):  # released by the outer block
        pass


def test_a_program_that_outlives_its_runner_keeps_the_lock(tmp_path):
    """The lock's descriptor is the program's too: while it runs, no second run."""
    with programs.folder_lock(tmp_path) as fd:
        child = subprocess.Popen([PY, "-c", "import time; time.sleep(600)"], pass_fds=(fd,))
    try:
        with pytest.raises(programs.FolderBusy):
            with programs.folder_lock(tmp_path):
                pass
    finally:
        child.kill()
        child.wait()


@pytest.mark.parametrize("make", ["symlink", "folder"])
def test_a_lock_file_that_is_not_a_file_is_one_line(tmp_path, make):
    lock = tmp_path / programs.LOCK_NAME
    if make == "symlink":
        lock.symlink_to(tmp_path / "elsewhere")
    else:
        lock.mkdir()
    with pytest.raises(ConfigError) as exc:
        with programs.folder_lock(tmp_path):
            pass
    assert "\n" not in str(exc.value) and not (tmp_path / "elsewhere").exists()


def test_a_folder_that_cannot_hold_a_lock_is_one_line(tmp_path):
    with pytest.raises(ConfigError, match="a folder wtftc can write its lock"):
        with programs.folder_lock(tmp_path / "missing"):
            pass


def test_errors_of_the_module_are_engine_errors_or_refusals():
    assert issubclass(programs.TimedOut, EngineError)
    assert issubclass(programs.FolderBusy, ConfigError)
