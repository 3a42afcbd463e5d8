"""Before a sweep in OpenFAST starts, and before it resumes.

* :func:`check_deck`: the first run's OpenFAST case written into a temporary folder
  (wtftc.openfast.engine.prepare: the deck copied and edited, the wind, the controller
  and plant libraries) and OpenFAST started on it for :data:`PREFLIGHT_CALLS` controller
  calls, so that a deck every run would fail on (a key missing, a value OpenFAST refuses
  at its initialisation) is refused in one line before the first run, not recorded as
  every run's failure.
* :func:`check_idle`: no run of the results folder is still in OpenFAST, started by an
  earlier sweep whose own process is gone (killed outright, its workers and their OpenFAST
  left running): a resumed sweep would otherwise run a second OpenFAST in the same case
  folder. The case folder's lock (wtftc.programs.folder_lock, held by OpenFAST itself
  while it runs) says so.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path

from wtftc import config, programs
from wtftc.errors import ConfigError, EngineError, ProgramKilled
from wtftc.model import turbine_file

#: how many controller calls the check runs OpenFAST for: its initialisation (every
#: module reads and checks its input files) and the first calls of both libraries
PREFLIGHT_CALLS = 4


def check_deck(raw: dict) -> None:
    """Write the case of the run ``raw`` (a valid configuration with engine = openfast)
    into a temporary folder and start OpenFAST on it. A deck that cannot be written or
    that OpenFAST stops on is a ConfigError naming the turbine file's ``openfast_deck``
    (exit code 2); a built-in turbine's deck that fails is an EngineError (4: the install
    is damaged). OpenFAST killed, or past its time limit, is raised as it is."""
    from wtftc.openfast import case as ofcase
    from wtftc.openfast import engine

    rc = config.make_config(raw)
    deck = engine.deck_of(rc)
    with tempfile.TemporaryDirectory(prefix="wtftc-preflight-") as tmp:
        folder = Path(tmp) / "case"
        try:
            case = engine.prepare(rc, folder)
            ofcase.set_values(case.fst, {"TMax": f"{PREFLIGHT_CALLS * case.dll_dt:.9g}"})
            _, abort = engine.simulate(case, False)
        except (ConfigError, ProgramKilled, programs.TimedOut):
            raise
        except EngineError as exc:
            if str(folder) not in str(exc) and str(deck.parent) not in str(exc):
                raise  # not about the deck's files: a program's own failure (exit 4)
            _refuse(rc, deck, str(exc).replace(f"{folder}/", ""))
        except (OSError, ValueError, RuntimeError) as exc:  # a file of it unreadable
            _refuse(rc, deck, f"{type(exc).__name__}: {exc}".replace(f"{folder}/", ""))
        if abort:
            _refuse(rc, deck, abort.replace(f"{folder}/", ""))


def _refuse(rc, deck: Path, why: str) -> None:
    name = rc.raw.get("turbine", turbine_file.DEFAULT)
    turbine = turbine_file.load(name)
    what = (f"a deck OpenFAST runs (the first run's case was started before any run: "
            f"{' '.join(why.split())}; every run would fail the same way)")
    if name in turbine_file.BUILTIN:
        raise EngineError(f"the OpenFAST deck of the built-in turbine {name}, {deck}, "
                          f"fails: {' '.join(why.split())}; reinstall ROSCO's package "
                          f"({config.OPENFAST_PACKAGES})")
    raise ConfigError("openfast_deck", str(deck), what, where=turbine.path)


def busy_cases(case_root: Path, run_ids) -> list[tuple[str, str]]:
    """The runs of ``run_ids`` whose case folder under ``case_root`` is held now
    (wtftc.programs.folder_lock): (run id, the holder's process id as its lock says)."""
    busy = []
    for run_id in run_ids:
        lock = Path(case_root) / run_id / programs.LOCK_NAME
        try:
            fd = os.open(lock, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
        except OSError:
            continue  # no case folder, or no lock in it: no run there
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            busy.append((run_id, os.pread(fd, 32, 0).decode("ascii", "replace").strip()
                         or "unknown"))
        finally:
            os.close(fd)  # (a shared lock taken is dropped with it)
    return busy


def check_idle(out_dir: Path, case_root: Path, run_ids) -> None:
    """Refuse, in one line naming ``--out``, to resume while a run of it is still in
    OpenFAST (:func:`busy_cases`): a second OpenFAST would run in its case folder."""
    busy = busy_cases(case_root, run_ids)
    if busy:
        run_id, pid = busy[0]
        raise ConfigError("--out", str(out_dir), "a results folder none of whose runs is "
                          f"still in OpenFAST: {len(busy)} still run, left by an earlier "
                          f"sweep (run {run_id} in {Path(case_root) / run_id}, process "
                          f"{pid}); wait for them to end, or stop them (kill {pid}), then "
                          "run the same command again")
