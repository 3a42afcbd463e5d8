"""External programs under control (OpenFAST, TurbSim): one way to run them.

:func:`run` starts a program in a process group of its own (a new session: Ctrl-C at the
terminal reaches wtftc only), its standard output and error into a log file that is kept,
its standard input ``/dev/null``, and waits for it under a time limit. The program never
outlives wtftc:

* a program over its time limit is stopped whole (its group SIGTERM, then SIGKILL after
  :data:`GRACE_S`) and reported as :class:`TimedOut`, naming it, the limit and what to do;
* Ctrl-C, SIGTERM (raised as KeyboardInterrupt while it runs, where no handler of the
  caller's is set) or any exception in wtftc stops the group whole before it propagates;
* wtftc killed outright (SIGKILL, the OOM killer) cannot clean up: the kernel kills the
  program then, through the parent-death signal (``prctl(PR_SET_PDEATHSIG, SIGKILL)``, set in
  the child between fork and exec), and a watchdog kills the rest of its group (what a
  wrapper script started: the parent-death signal reaches the direct child only). The
  watchdog is a small Python process that reads a pipe only wtftc writes: at the end of a run wtftc
  writes a line and it exits; when wtftc dies the pipe ends without one, and it kills
  the program's group.

A program ended by a signal wtftc did not send is sorted by the signal: a crash of its
own (SIGSEGV, SIGFPE, SIGABRT...) is the program's failure, left to the caller to report
with its output; any other (SIGKILL, SIGTERM, SIGHUP from another process or the machine)
is :class:`wtftc.errors.ProgramKilled`: the run is unfinished, not failed.

:func:`folder_lock` keeps a folder to one run at a time (OpenFAST's case folder): an
``flock`` on a lock file in it, which the program inherits, so that the lock holds as long
as the program runs, even past wtftc.

The time limits (:func:`openfast_limit_s`, :func:`turbsim_limit_s`) are generous multiples of
what the programs were measured to take on 2 cores; ``WTFTC_PROGRAM_TIMEOUT_S`` replaces
them all (seconds > 0).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import fcntl
import math
import os
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path

from wtftc import files
from wtftc.errors import ConfigError, EngineError, ProgramKilled

#: the environment variable that replaces every time limit [s]
TIMEOUT_ENV = "WTFTC_PROGRAM_TIMEOUT_S"
#: the longest time limit [s] (a year: the clocks' waits overflow far beyond it)
MAX_LIMIT_S = 3.2e7
#: how long a stopped program's group has between SIGTERM and SIGKILL [s]
GRACE_S = 3.0
#: the signals by which a program ends on a fault of its own: its failure, not a stop
CRASHES = frozenset({signal.SIGSEGV, signal.SIGBUS, signal.SIGFPE, signal.SIGILL,
                     signal.SIGABRT, signal.SIGTRAP, signal.SIGSYS})
#: the lock file :func:`folder_lock` keeps in a folder (left there: removing a lock file
#: that another process has opened would let two runs hold two different files)
LOCK_NAME = ".wtftc-running"
#: OpenFAST's limit: a fixed start-up allowance plus this much wall time per simulated
#: second [s/s] (the NREL 5-MW takes 0.3-0.5 s, the IEA 15-MW 1.0-1.6 s on 2 cores)
OPENFAST_START_S, OPENFAST_PER_SIMULATED_S = 60.0, 20.0
#: TurbSim's limit: start-up plus this many seconds per n³ × time step, n the grid's
#: points (its cost is a Cholesky factorisation of the n × n coherence matrix at each of
#: its nt/2 frequencies, ∝ n³ nt: 263 s for 961 points × 2,200 steps, 9 s for 169 points ×
#: 12,000 steps, shared/openfast/README.md; 2e-9 is 15-20 times that)
TURBSIM_START_S, TURBSIM_PER_CUBE_STEP_S = 60.0, 2e-9


class TimedOut(EngineError):
    """A program ran past its time limit and was stopped by wtftc."""


class FolderBusy(ConfigError):
    """Another run holds the folder (:func:`folder_lock`): refused, nothing written."""


@dataclass(frozen=True)
class Finished:
    """A program that ended by itself: its exit code (< 0: killed by a crash signal of its
    own, :data:`CRASHES`), wall time [s] and log file."""

    code: int
    wall_s: float
    log: Path

    def text(self) -> str:
        """The program's screen output, decoded as it came (any encoding)."""
        try:
            return files.decode_text(self.log.read_bytes())
        except OSError:
            return ""


def signal_name(code: int) -> str | None:
    """The name of the signal that ended a program with exit code ``code`` (< 0), e.g.
    "SIGSEGV"; None for an exit code of its own."""
    if code >= 0:
        return None
    try:
        return signal.Signals(-code).name
    except ValueError:
        return f"signal {-code}"


def limit_s(rule_s: float) -> float:
    """The time limit [s]: ``rule_s``, or ``WTFTC_PROGRAM_TIMEOUT_S`` where it is set."""
    env = os.environ.get(TIMEOUT_ENV)
    if env is None or not env.strip():
        return rule_s
    try:
        value = float(env)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and 0 < value <= MAX_LIMIT_S):
        raise ConfigError(TIMEOUT_ENV, env, f"a number of seconds in (0, {MAX_LIMIT_S:g}] "
                          "(the time limit of OpenFAST and TurbSim), or unset for the rule "
                          "of each")
    return value


def openfast_limit_s(t_final_s: float) -> float:
    """OpenFAST's time limit for a case of ``t_final_s`` simulated seconds [s]."""
    return limit_s(OPENFAST_START_S + OPENFAST_PER_SIMULATED_S * max(0.0, t_final_s))


def turbsim_limit_s(points: int, steps: int) -> float:
    """TurbSim's time limit for a field of ``points`` grid points and ``steps`` time steps."""
    return limit_s(TURBSIM_START_S + TURBSIM_PER_CUBE_STEP_S * float(points) ** 3 * steps)


# ------------------------------------------------------------------------ the child's side

_prctl = None


def _prctl_function():
    global _prctl
    if _prctl is None:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        _prctl = libc.prctl
        _prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong,
                           ctypes.c_ulong]
    return _prctl


def _child_setup(parent_pid: int) -> Callable[[], None]:
    """What the child does between fork and exec: ask the kernel for SIGKILL when its
    parent ends, then check that the parent did not end before the request (the race the
    check closes: a parent gone between fork and prctl would never signal). The ctypes
    function is looked up here, in the parent, so that the child only calls it."""
    prctl, pr_set_pdeathsig = _prctl_function(), 1

    def setup() -> None:
        prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)
        if os.getppid() != parent_pid:
            os.kill(os.getpid(), signal.SIGKILL)
    return setup


# ----------------------------------------------------------------------- the parent's side

def _ended(proc: subprocess.Popen, pidfd: int | None, timeout: float | None) -> bool:
    """Whether ``proc`` has ended within ``timeout`` [s] (None: wait for it), without
    reaping it: while it is a zombie its process group cannot be reused, so the group can
    still be signalled safely."""
    if pidfd is not None:
        ready, _, _ = select.select([pidfd], [], [], timeout)
        return bool(ready)
    end = None if timeout is None else time.monotonic() + timeout
    while True:  # no pidfd (an old kernel): poll without reaping
        if os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None:
            return True
        if end is not None and time.monotonic() >= end:
            return False
        time.sleep(0.02)


def _signal_group(pgid: int, sig: int) -> None:
    with suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, sig)


def _stop_group(proc: subprocess.Popen, pidfd: int | None) -> None:
    """SIGTERM to the program's whole group, SIGKILL after GRACE_S, then reap it. A second
    Ctrl-C meanwhile still ends in SIGKILL."""
    try:
        _signal_group(proc.pid, signal.SIGTERM)
        _ended(proc, pidfd, GRACE_S)
    finally:
        _signal_group(proc.pid, signal.SIGKILL)
        proc.wait()


#: the watchdog: a line read (wtftc released it), or the pipe's end (wtftc died)
_WATCHDOG = ("import os, signal, sys\n"
             "if not sys.stdin.buffer.readline():\n"
             "    try:\n"
             "        os.killpg({pgid}, signal.SIGKILL)\n"
             "    except OSError:\n"
             "        pass\n")


class _Watchdog:
    """A Python interpreter, in a session of its own, that kills the process group ``pgid`` if wtftc
    dies while the group runs: it reads a pipe whose writing end only wtftc holds, so
    :meth:`release` (a line) lets it exit, and wtftc's death (the end of the pipe, no
    line) makes it kill the group."""

    def __init__(self, pgid: int):
        read, self._write = os.pipe()
        try:
            self._dog = subprocess.Popen(
                [sys.executable, "-I", "-S", "-c", _WATCHDOG.format(pgid=pgid)],
                stdin=read, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                start_new_session=True)
        except BaseException:
            os.close(self._write)
            raise
        finally:
            os.close(read)

    def release(self) -> None:
        """The group is gone: the watchdog exits without a signal."""
        with suppress(OSError):
            os.write(self._write, b"done\n")
        os.close(self._write)
        self._dog.wait()


@contextmanager
def _sigterm_stops() -> Iterator[None]:
    """SIGTERM raises KeyboardInterrupt meanwhile, where nothing else handles it (the
    default handler would end wtftc without stopping the program or cleaning up)."""
    if threading.current_thread() is threading.main_thread() \
            and signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        with files.sigterm_as_interrupt():
            yield
    else:
        yield


@dataclass(frozen=True)
class Program:
    """What :func:`run` needs to say about a program: its name ("OpenFAST"), its time limit
    [s], how the limit was set and what to do when it is reached."""

    name: str
    limit_s: float
    rule: str
    hint: str


def run(args: list[str], cwd: Path, log: Path, prog: Program,
        watch: Callable[[], None] | None = None, every_s: float = 5.0,
        pass_fds: tuple[int, ...] = ()) -> Finished:
    """Run ``args`` in ``cwd`` under control (the module's rules), its output into ``log``
    (kept); ``watch()``, if given, is called every ``every_s`` [s] while it runs;
    ``pass_fds`` are inherited (a folder lock). Returns when it ends by itself; raises
    :class:`TimedOut` past its limit and ProgramKilled when a signal of another's ended it.

    The thread that starts the program waits for it here: the kernel sends the parent-death
    signal when the *thread* that forked the child ends, not the process, so the waiting
    must not be handed to another thread."""
    t0 = time.monotonic()
    with open(log, "wb") as out, _sigterm_stops():
        proc, pidfd, dog = None, None, None
        try:
            proc = subprocess.Popen(args, cwd=cwd, stdout=out, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL, start_new_session=True,
                                    preexec_fn=_child_setup(os.getpid()), pass_fds=pass_fds)
            dog = _Watchdog(proc.pid)
            with suppress(AttributeError, OSError):
                pidfd = os.pidfd_open(proc.pid)
            timed_out = _wait(proc, pidfd, t0 + prog.limit_s, watch, every_s)
            if timed_out:
                _stop_group(proc, pidfd)
            else:  # whatever the program left in its group goes with it
                _signal_group(proc.pid, signal.SIGKILL)
                proc.wait()
        except BaseException:
            if proc is not None:
                _stop_group(proc, pidfd)
            raise
        finally:
            if dog is not None:
                dog.release()
            if pidfd is not None:
                os.close(pidfd)
    wall = time.monotonic() - t0
    if timed_out:
        raise TimedOut(f"{prog.name} timed out after {prog.limit_s:g} s ({prog.rule}) and "
                       f"was stopped with its process group; {prog.hint}; its screen "
                       f"output is in {log}")
    code = proc.returncode
    if _killed_by_another(code):
        raise ProgramKilled(f"{prog.name} was killed by {signal_name(code)} (exit code "
                            f"{code}), a signal wtftc did not send (another process, the "
                            f"machine's memory); the run is unfinished, not failed: run it "
                            f"again; its screen output is in {log}")
    return Finished(code, wall, log)


def _killed_by_another(code: int) -> bool:
    """Whether exit code ``code`` is a signal other than a crash of the program's own."""
    if code >= 0:
        return False
    try:
        return signal.Signals(-code) not in CRASHES
    except ValueError:
        return True


def _wait(proc: subprocess.Popen, pidfd: int | None, deadline: float,
          watch: Callable[[], None] | None, every_s: float) -> bool:
    """Wait for ``proc`` until ``deadline`` (time.monotonic), calling ``watch`` every
    ``every_s``; True when the deadline passed first."""
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            return True
        if _ended(proc, pidfd, min(left, every_s) if watch else left):
            return False
        if watch is not None:
            watch()


# ---------------------------------------------------------------------------- folder lock

_held: dict[str, tuple[int, int]] = {}  # folder -> (thread, lock fd) held by this process
_held_guard = threading.Lock()


@contextmanager
def folder_lock(folder: Path, what: str = "case folder") -> Iterator[int]:
    """Hold ``folder`` for one run (an exclusive flock on its :data:`LOCK_NAME`, created if
    missing; the folder must exist); yields the lock's file descriptor, to be passed to
    the program so that the lock lasts while it runs. The same thread may take it again
    (nested); any other holder, in this process or another, makes it :class:`FolderBusy`
    in one line naming the folder and the holder's process id."""
    key = str(Path(folder).resolve())
    me = threading.get_ident()
    with _held_guard:
        held = _held.get(key)
    if held is not None and held[0] == me:
        yield held[1]
        return
    path = Path(key) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW, 0o644)
    except OSError as exc:
        raise ConfigError(what, key, f"a folder wtftc can write its lock into ({path}: "
                          f"{exc.strerror})") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EWOULDBLOCK, errno.EACCES):
                raise
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "unknown"
            raise FolderBusy(what, key, f"a folder no other run is using (another wtftc "
                             f"or its program, process {holder}, runs in it now: wait for "
                             "it to end, or stop it)") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        with _held_guard:
            _held[key] = (me, fd)
        try:
            yield fd
        finally:
            with _held_guard:
                _held.pop(key, None)
    finally:
        os.close(fd)
