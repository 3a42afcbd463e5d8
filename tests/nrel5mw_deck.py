"""ROSCO's NREL 5-MW OpenFAST deck (the files `wtftc turbine import` reads) for the import's
tests: read once, copied into a test's folder with some files changed, and the import run
in-process with a user's files beside its output to check that none is touched."""

from __future__ import annotations

import functools
import importlib.util
import os
import signal
from contextlib import contextmanager
from pathlib import Path

from wtftc import cli

#: the deck in the installed rosco package (make setup installs it with openfast-io)
DECK = (Path(importlib.util.find_spec("rosco").origin).parent.parent / "Examples"
        / "Test_Cases" / "NREL-5MW")
#: short name → file: every file the import reads from this deck
FILES = {"fst": "NREL-5MW.fst", "ed": "NRELOffshrBsline5MW_Onshore_ElastoDyn.dat",
         "blade": "NRELOffshrBsline5MW_Blade.dat",
         "tower": "NRELOffshrBsline5MW_Onshore_ElastoDyn_Tower.dat",
         "sd": "NRELOffshrBsline5MW_Onshore_ServoDyn.dat", "discon": "DISCON.IN",
         "cp": "Cp_Ct_Cq.NREL5MW.txt"}
#: a user's file in the output folder, which no import may touch
SENTINEL = "my_notes.txt"


@functools.cache
def originals() -> dict[str, bytes]:
    """The deck's files' bytes, read once."""
    return {k: (DECK / name).read_bytes() for k, name in FILES.items()}


def make_deck(folder: Path, changed: dict[str, bytes] | None = None,
              base: Path | None = None) -> Path:
    """The deck in ``folder`` with the files ``changed`` (short name → bytes); the others
    hard links to ``base`` (a folder made by this function, unchanged) when given. Its
    main file's path."""
    folder.mkdir(parents=True)
    changed = changed or {}
    for key, name in FILES.items():
        if key in changed:
            (folder / name).write_bytes(changed[key])
        elif base is not None:
            os.link(base / name, folder / name)
        else:
            (folder / name).write_bytes(originals()[key])
    return folder / FILES["fst"]


def user_folder(folder: Path, extra: dict[str, bytes] | None = None) -> dict:
    """An output folder holding a user's files (the sentinel and ``extra``); their
    snapshot (name → (bytes, mtime_ns)) for :func:`untouched`."""
    folder.mkdir(parents=True, exist_ok=True)
    files = {SENTINEL: b"my own notes: never touch\n", **(extra or {})}
    for name, data in files.items():
        (folder / name).write_bytes(data)
    return {name: ((folder / name).read_bytes(), (folder / name).stat().st_mtime_ns)
            for name in files}


def untouched(folder: Path, snapshot: dict) -> list[str]:
    """The user's files in ``folder`` that changed since ``snapshot`` (empty: none)."""
    bad = []
    for name, (data, mtime) in snapshot.items():
        p = folder / name
        if not p.is_file() or p.read_bytes() != data or p.stat().st_mtime_ns != mtime:
            bad.append(name)
    return bad


class Hang(BaseException):
    """A case ran past its time (a BaseException: no `except Exception` swallows it)."""


@contextmanager
def time_limit(seconds: float):
    def alarm(signum, frame):
        raise Hang(f"no answer in {seconds} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def run_import(argv: list[str], capsys, seconds: float = 20.0) -> tuple[int, list[str]]:
    """``wtftc turbine import ARGV`` in-process: (exit code, stderr's lines). Any exception
    but the CLI's own refusals propagates (a traceback is a failure)."""
    capsys.readouterr()
    with time_limit(seconds):
        code = cli.main(["turbine", "import", *argv])
    return code, capsys.readouterr().err.splitlines()
