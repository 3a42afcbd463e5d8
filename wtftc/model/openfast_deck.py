"""An OpenFAST deck's files read with openfast-io, as a user's files.

openfast-io (NREL's reader of OpenFAST input files, PyPI ``openfast-io``) reads a file
line by line by position and trusts it: a missing line is an IndexError, a word where a
number belongs a ValueError, a file that ends before its ``END`` line loops forever, and a
station count of 10^10 allocates a list of that length before a line is read. Here every
file is first read as a user's file (:func:`user_text`: a regular file under a size cap,
text in UTF-8 or Latin-1; a FIFO, a device, a folder or a binary file is refused in one
line), and openfast-io then reads that text, never the file system: its ``open``
serves the text already read (a read past the end stops it), its ``int`` refuses a count
above :data:`MAX_COUNT`, and any failure becomes one ConfigError naming the file, the line,
its key and value. Output channel lists are not kept (wtftc needs none, and openfast-io's
matching of each channel against its whole tree is most of its reading time).

Which file names which: the main file's ``EDFile`` and ``ServoFile`` (relative to it),
ElastoDyn's ``BldFile1`` and ``TwrFile`` (relative to ElastoDyn's folder, as OpenFAST
resolves them), ServoDyn's ``DLL_InFile``. A bad name is refused naming the file that
gives it and its key, never an option the user did not give.
"""

from __future__ import annotations

import builtins
import functools
import io
import math
import os
import re
import threading
from collections import defaultdict
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from wtftc.errors import ConfigError, MissingExtra, range_text
from wtftc.files import decode_text, read_user_bytes

#: the largest deck file read (ElastoDyn files are ~20 kB, a BeamDyn blade ~0.1 MB)
MAX_DECK_BYTES = 16 * 1024 * 1024
#: the largest count openfast-io may read (stations, gauges, table rows): it allocates a
#: list of that length before reading the lines
MAX_COUNT = 100_000
#: reads past a file's end before openfast-io is stopped (it reads a line or two past the
#: end of ElastoDyn for the optional nodal output list; an ``END`` missing loops forever)
_EOF_READS = 16

_LOCK = threading.Lock()
#: the bytes no text file holds: C0 controls but \t \n \v \f \r and Ctrl-Z
_CONTROL = re.compile(rb"[\x00-\x08\x0e-\x19\x1b-\x1f]")
#: openfast-io's key → the key as the file spells it (what a message names)
LABELS = {"TwrFADmp1": "TwrFADmp(1)", "BldFile1": "BldFile(1)", "TwFAM1Sh": "TwFAM1Sh(2:6)"}


class _EndOfFile(Exception):
    """openfast-io read on past the end of a file."""


class _Lines(io.StringIO):
    """A file's text for openfast-io, with the number and text of the last line read."""

    def __init__(self, text: str):
        super().__init__(text, newline=None)
        self.lineno, self.last, self.at_end, self._eof = 0, "", False, 0

    def readline(self, size: int = -1) -> str:
        line = super().readline(size)
        self.at_end = not line
        if line:
            self.lineno, self.last = self.lineno + 1, line
        else:
            self._eof += 1
            if self._eof > _EOF_READS:
                raise _EndOfFile
        return line

    def close(self) -> None:  # openfast-io closes; the text stays for the error message
        pass


def _bounded_int(x, *args) -> int:
    v = builtins.int(x, *args)
    if abs(v) > MAX_COUNT:
        raise ValueError(f"a count of at most {MAX_COUNT}")
    return v


@functools.cache
def _reader_class():
    try:
        from openfast_io.FAST_reader import InputReader_OpenFAST
    except ImportError as exc:
        raise MissingExtra("--openfast", "openfast-io", "import", str(exc)) from None

    class Reader(InputReader_OpenFAST):
        """openfast-io's reader without its output-channel tree (a deep copy of ~10^4
        entries per instance) and without matching channels against it."""

        def __init__(self):  # noqa: D107 - the attributes openfast-io's readers use
            self.FAST_InputFile = self.FAST_directory = self.path2dll = None
            self.fst_vt = {"Fst": {}, "outlist": defaultdict(dict), "ElastoDyn": {},
                           "ElastoDynBlade": [{}, {}, {}], "ElastoDynTower": {},
                           "ServoDyn": {}}

        def set_outlist(self, vartree_head, channel_list):
            pass

    return Reader


def _key(path) -> str:
    return os.path.normpath(os.path.abspath(path))


@contextmanager
def _serving(path: Path, lines: _Lines):
    """openfast-io's ``open`` serves ``lines`` for ``path`` and refuses any other file;
    its ``int`` refuses a count above MAX_COUNT (module globals, restored after)."""
    import openfast_io.FAST_reader as fr

    def opener(name, *args, **kwargs):
        if _key(name) != _key(path):
            raise ConfigError("openfast-io", str(name), f"only {path} read here")
        lines.seek(0)
        return lines

    with _LOCK:
        fr.open, fr.int = opener, _bounded_int
        try:
            yield
        finally:
            del fr.open, fr.int


def user_text(path: Path, key: str, where: str | None) -> str:
    """A deck file's text as its user wrote it (:func:`wtftc.files.decode_text`: UTF-8,
    else Latin-1, a BOM dropped: a "°" written on Windows is read), refused naming
    ``key`` and the file ``where`` that gives its name when it is no regular file of text
    (a NUL or control byte: a binary file, or UTF-16, which OpenFAST cannot read)."""
    try:
        data = read_user_bytes(path, key, MAX_DECK_BYTES)
    except ConfigError as exc:
        raise ConfigError(key, exc.value, exc.allowed, where=where) from None
    m = _CONTROL.search(data)
    if m is not None:
        what = "a NUL" if m.group() == b"\0" else f"the control character 0x{m.group()[0]:02x}"
        raise ConfigError(key, str(path), f"an OpenFAST input file of text, UTF-8 or Latin-1 "
                          f"(byte {m.start()} is {what}: a binary file, or UTF-16?)",
                          where=where)
    return decode_text(data)


def _refused(path: Path, lines: _Lines, exc: Exception) -> ConfigError:
    """openfast-io's failure on ``path`` as one line: the file, the line, its key and
    value, and what openfast-io expected there."""
    if lines.lineno == 0:
        return ConfigError("file", "empty", "an OpenFAST input file", where=str(path))
    if isinstance(exc, _EndOfFile) or lines.at_end:
        return ConfigError(f"line {lines.lineno + 1}", "the end of the file", "more lines "
                           "(the file ends early: truncated, or an output list without its "
                           "END line)", where=str(path))
    words = lines.last.split()
    if not words:
        return ConfigError(f"line {lines.lineno}", lines.last.strip() or "an empty line",
                           "a value, then its key (openfast-io reads the file line by line: "
                           "a line missing or empty here, or the file ends early)",
                           where=str(path))
    key = words[1] if len(words) > 1 else f"line {lines.lineno}"
    why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    what = ("an integer" if "int()" in why or "count" in why else
            "a value openfast-io can read")
    return ConfigError(key, words[0], f"{what} (line {lines.lineno}; openfast-io reads "
                       "by position: a line missing or added above shifts those below; "
                       f"{type(exc).__name__}: {why})", where=str(path))


def _run(read, path: Path, text: str) -> None:
    """``read()`` (an openfast-io reader method) on ``text`` served as ``path``."""
    lines = _Lines(text)
    with _serving(path, lines):
        try:
            read()
        except ConfigError:
            raise
        except Exception as exc:  # openfast-io trusts its input: any failure is the file's
            raise _refused(path, lines, exc) from None


@dataclass
class Deck:
    """What openfast-io read: each module's values by key, and the files they came from
    (``discon``: the DISCON.IN ServoDyn names, and ``sd_file``, when it was read)."""

    fst: Path
    ed_file: Path
    blade_file: Path
    tower_file: Path
    ed: dict
    blade: dict
    tower: dict
    discon: Path | None = None
    sd_file: Path | None = None


def _named(base: Path, value, key: str, where: Path) -> Path:
    """The file ``value`` (a name relative to ``base``) that ``where`` gives as ``key``."""
    if not isinstance(value, str) or not value.strip():
        raise ConfigError(key, value, "a file name", where=str(where))
    return base / value


def read(fst: Path, servo: bool = True) -> Deck:
    """The main file, ElastoDyn, its first blade file and its tower file; with ``servo``,
    ServoDyn and the DISCON.IN it names."""
    reader = _reader_class()()
    reader.FAST_InputFile, reader.FAST_directory = fst.name, str(fst.parent)
    _run(reader.read_MainInput, fst.parent / fst.name, user_text(fst, "--openfast", None))
    main = reader.fst_vt["Fst"]
    given = _named(fst.parent, main.get("EDFile"), "EDFile", fst)
    text = user_text(given, "EDFile", str(fst))
    ed_file = Path(os.path.realpath(given))  # its files are relative to its real folder
    _run(lambda: reader.read_ElastoDyn(str(ed_file)), ed_file, text)
    ed = reader.fst_vt["ElastoDyn"]
    blade_file = _named(ed_file.parent, ed.get("BldFile1"), "BldFile(1)", ed_file)
    text = user_text(blade_file, "BldFile(1)", str(ed_file))
    _run(lambda: reader.read_ElastoDynBlade(str(blade_file), 0), blade_file, text)
    tower_file = _named(ed_file.parent, ed.get("TwrFile"), "TwrFile", ed_file)
    text = user_text(tower_file, "TwrFile", str(ed_file))
    _run(lambda: reader.read_ElastoDynTower(str(tower_file)), tower_file, text)
    deck = Deck(fst, ed_file, blade_file, tower_file, ed, reader.fst_vt["ElastoDynBlade"][0],
                reader.fst_vt["ElastoDynTower"])
    if servo:
        deck.discon, deck.sd_file = _servodyn_discon(reader, fst)
    return deck


def _servodyn_discon(reader, fst: Path) -> tuple[Path, Path]:
    """The DISCON.IN that the deck's ServoDyn names (``DLL_InFile``, relative to the
    ServoDyn file) and the ServoDyn file (what a bad name is blamed on)."""
    sd_file = Path(os.path.normpath(_named(fst.parent, reader.fst_vt["Fst"].get("ServoFile"),
                                           "ServoFile", fst)))
    try:
        text = user_text(sd_file, "ServoFile", str(fst))
    except ConfigError as exc:
        raise ConfigError(exc.field, exc.value, f"{exc.allowed}; or name the DISCON.IN "
                          "with --rosco", where=exc.where) from None
    _run(reader.read_ServoDyn, sd_file, text)
    infile = reader.fst_vt["ServoDyn"].get("DLL_InFile")  # openfast-io made it absolute
    return Path(os.path.normpath(_named(sd_file.parent, infile, "DLL_InFile", sd_file))), \
        sd_file


def number(d: dict, key: str, where: Path, low: float = -math.inf, high: float = math.inf,
           low_open: bool = False, high_open: bool = False, unit: str = "") -> float:
    """``d[key]`` (a value openfast-io read) as a finite float in the range, or a
    ConfigError naming the file ``where``, the key, the value and the range. NaN fails
    every comparison, so it is refused as not finite before any."""
    v, key = d.get(key), LABELS.get(key, key)
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise ConfigError(key, v if v is not None else "missing", "a number",
                          where=str(where))
    v = float(v)
    if not math.isfinite(v):
        raise ConfigError(key, v, "a finite number", where=str(where))
    if v < low or v > high or (low_open and v == low) or (high_open and v == high):
        raise ConfigError(key, v, range_text(low, high, low_open, high_open, unit),
                          where=str(where))
    return v


def numbers(d: dict, key: str, where: Path, low: float = -math.inf,
            high: float = math.inf, unit: str = "", increasing: bool = False) -> list[float]:
    """``d[key]`` (a column openfast-io read) as finite floats in [low, high], strictly
    increasing if asked; refused naming the file, the key and the first bad entry."""
    col, key = d.get(key), LABELS.get(key, key)
    if not isinstance(col, list) or not col:
        raise ConfigError(key, col, "a column of numbers", where=str(where))
    out = []
    for i, v in enumerate(col):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                or not low <= v <= high:
            raise ConfigError(f"{key}[{i + 1}]", v, "a finite " + range_text(
                low, high, False, False, unit).removeprefix("a "), where=str(where))
        if increasing and out and not v > out[-1]:
            raise ConfigError(f"{key}[{i + 1}]", v, f"a value above {key}[{i}] = "
                              f"{out[-1]:g} (strictly increasing)", where=str(where))
        out.append(float(v))
    return out
