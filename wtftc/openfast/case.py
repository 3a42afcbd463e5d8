"""An OpenFAST case written from a run's configuration (ours).

The turbine's deck (its ``openfast_deck``) is copied into the run folder's ``openfast/``:
the regular files its input lines name, to the end, wherever they live (their names
rewritten to the copies), nothing else of its folder; and edited there, so that a user
can rerun it by hand (``openfast <name>.fst`` in that folder):

* the main file: TMax, DT (DLL_DT a whole multiple of it), binary output at every step,
  and no substructure (the tower clamped at its base, as wtftc's tower plant is);
* ElastoDyn: the initial rotor speed, blade pitch and tower-top fore-aft displacement of
  the run's operating point, and the output channels the metrics need;
* InflowWind: the run's wind as a uniform wind file (WindType 2), the same series
  wtftc's own plant gets: hub-height or rotor-effective, uniform over the rotor, no shear;
* ServoDyn: ``libwtftc_plant.so`` (wtftc.openfast.plant_library) as its DISCON library,
  which calls the run's controller library through wtftc's pitch actuator and sensors.

An OpenFAST input line is ``value  Key  - description``; a key is edited by its value
only, the rest of its line kept. A deck file is read as its user wrote it: UTF-8 or
Latin-1, with or without a BOM, LF or CRLF, and written back so; a file where text
belongs with a NUL or control byte (binary, UTF-16), a symbolic link loop, a FIFO, a
device, a folder where a file belongs named by the deck is refused in one line naming
the file and what names it.
"""

from __future__ import annotations

import codecs
import errno
import math
import os
import re
import stat
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wtftc.errors import ConfigError
from wtftc.files import MAX_INPUT_BYTES, check_user_file, decode_text, read_user_bytes

#: ElastoDyn's output channels the results read (its OutList is replaced by these);
#: AeroDyn's, InflowWind's and ServoDyn's lists of the deck are kept
ELASTODYN_CHANNELS = ("BldPitch1", "BldPitch2", "BldPitch3", "RotSpeed", "GenSpeed",
                      "TTDspFA", "RotTorq", "TwrBsMyt", "RotThrust", "RootMyb1", "RootMyb2",
                      "RootMyb3")
#: the channels read from the other modules' lists (the decks of ROSCO's examples have them)
OTHER_CHANNELS = ("Wind1VelX", "GenPwr", "GenTq")
#: the wind file's sample interval [s] (InflowWind interpolates linearly between rows)
WIND_DT = 0.02
#: OpenFAST's largest step [s] (the NREL 5-MW deck's 0.00625 rounded down to divide the
#: 0.01-s and 0.005-s control intervals)
MAX_DT = 0.005


# ------------------------------------------------------------------- a deck file's text

#: the bytes no text file holds: C0 controls but \t \n \v \f \r and Ctrl-Z
_CONTROL = re.compile(rb"[\x00-\x08\x0e-\x19\x1b-\x1f]")
#: a copy of a deck file wtftc edits (the main file, the files it names) → the user's
#: file it was copied from: what a message names; the latest MAX_SOURCES copies
_SOURCES: dict[Path, Path] = {}
_SOURCES_LOCK = threading.Lock()  # a campaign's cases may be written from several threads
MAX_SOURCES = 4096


def _remember(copy: Path, source: Path) -> None:
    with _SOURCES_LOCK:
        _SOURCES.pop(copy, None)
        _SOURCES[copy] = source
        while len(_SOURCES) > MAX_SOURCES:
            del _SOURCES[next(iter(_SOURCES))]


def source_of(path: Path) -> Path:
    """The user's file that ``path`` (a deck file, or its copy in a case) was copied from."""
    with _SOURCES_LOCK:
        return _SOURCES.get(Path(path), Path(path))


def refused(path: Path, allowed: str, by: tuple[Path, str] | None = None) -> ConfigError:
    """A deck file refused in one line, naming it and what names it (``by``: the file and
    its key)."""
    where = f"; {source_of(by[0])} names it as {by[1] or 'a list entry'}" if by else ""
    return ConfigError("openfast_deck", str(source_of(path)), allowed + where)


@dataclass(frozen=True)
class Text:
    """A deck file's text as its user wrote it: decoded from UTF-8 (a BOM dropped), else
    from Latin-1 (wtftc.files.decode_text), and written back in the same encoding, BOM
    and line endings, so that an edit changes only the values edited (a Latin-1 "°" stays
    one byte)."""

    text: str
    encoding: str
    bom: bytes

    def encode(self, text: str) -> bytes:
        return self.bom + text.encode(self.encoding, "surrogateescape")

    def fs_text(self, name: str) -> str:
        """A file name as this text holds it: its bytes on disk in the file's encoding
        (OpenFAST opens the bytes the file holds)."""
        return os.fsencode(name).decode(self.encoding, "surrogateescape")

    def fs_path(self, word: str) -> Path:
        """The file a word of this text names (its bytes taken as the name on disk)."""
        return Path(os.fsdecode(word.encode(self.encoding, "surrogateescape")))


def binary_byte(data: bytes) -> str | None:
    """Where ``data`` cannot be a text file, said in words: its first NUL or other control
    byte but tab, line feed, form feed, carriage return and Ctrl-Z (an editor's end of
    file); None for text. Latin-1 or Windows-1252 letters are text."""
    m = _CONTROL.search(data)
    if m is None:
        return None
    what = "a NUL" if m.group() == b"\0" else f"the control character 0x{m.group()[0]:02x}"
    return f"byte {m.start()} is {what}: a binary file, or UTF-16?"


def decoded(data: bytes, path: Path, by: tuple[Path, str] | None = None) -> Text:
    """The text of a deck file's bytes; a binary file (a NUL or a control byte; UTF-16,
    which OpenFAST cannot read) is refused naming the file and what names it."""
    why = binary_byte(data)
    if why is not None:
        raise refused(path, f"an OpenFAST input file of text, UTF-8 or Latin-1 ({why})", by)
    try:
        data.decode("utf-8")
        encoding = "utf-8"
    except UnicodeDecodeError:
        encoding = "latin-1"
    bom = codecs.BOM_UTF8 if encoding == "utf-8" and data.startswith(codecs.BOM_UTF8) else b""
    return Text(decode_text(data), encoding, bom)


def read_text(path: Path) -> Text:
    """A deck file's text (a copy's refusal names the user's file it came from)."""
    try:
        data = read_user_bytes(path, "openfast_deck", MAX_INPUT_BYTES)
    except ConfigError as exc:
        raise refused(path, exc.allowed) from None
    return decoded(data, path)


#: a ``value  Key`` line: its value (a quoted one may hold spaces) and its key
_KEYED = re.compile(r"""[ \t]*(?P<value>"[^"\n]*"|'[^'\n]*'|\S+)[ \t]+(?P<key>\S+)""")


def _unquoted(value: str) -> str:
    return value[1:-1] if len(value) > 1 and value[0] == value[-1] and value[0] in "\"'" \
        else value.strip('"')


def set_values(path: Path, values: dict[str, str]) -> None:
    """Each ``Key`` of ``values`` given its value, in the file at ``path`` (the rest of
    its line kept); a key missing or given twice is refused naming the file (the user's,
    for a copy)."""
    doc = read_text(path)
    lines = doc.text.split("\n")
    seen = dict.fromkeys(values, 0)
    for i, line in enumerate(lines):
        m = _KEYED.match(line)
        if m and m["key"] in values:
            lines[i] = f"{doc.fs_text(values[m['key']]):>14}   {line[m.start('key'):]}"
            seen[m["key"]] += 1
    wrong = [k for k, n in seen.items() if n != 1]
    if wrong:
        raise refused(path, f"an OpenFAST 5.0 input file with each of {', '.join(wrong)} "
                      "on one line, once (`value  Key  - description`)")
    path.write_bytes(doc.encode("\n".join(lines)))


def get_value(path: Path, key: str) -> str:
    """The value (first word, quotes removed) of ``Key`` in the file at ``path``."""
    for line in read_text(path).text.split("\n"):
        m = _KEYED.match(line)
        if m and m["key"] == key:
            return _unquoted(m["value"])
    raise refused(path, f"an OpenFAST 5.0 input file with a {key} line (`value  {key}  - "
                  "description`)")


def set_outlist(path: Path, channels: tuple[str, ...]) -> None:
    """ElastoDyn's OutList replaced by ``channels`` (in the file's line endings)."""
    doc = read_text(path)
    lines = doc.text.split("\n")
    start = next((i for i, ln in enumerate(lines) if ln.split()[:1] == ["OutList"]
                  or ln.split()[1:2] == ["OutList"]), None)
    end = next((i for i in range(start + 1 if start is not None else 0, len(lines))
                if lines[i].strip().upper().startswith("END")), None)
    if start is None or end is None:
        raise refused(path, "an ElastoDyn file with an OutList ... END block")
    cr = "\r" if lines[start].endswith("\r") else ""
    lines[start + 1:end] = [f'"{c}"{cr}' for c in channels]
    path.write_bytes(doc.encode("\n".join(lines)))


@dataclass(frozen=True)
class Case:
    """A written case: its folder, main file, steps and where its outputs will be."""

    folder: Path
    fst: Path
    dt: float
    dll_dt: float
    plant_settings: Path
    records: Path

    @property
    def outb(self) -> Path:
        return self.fst.with_suffix(".outb")


def steps(interval: float) -> tuple[float, float]:
    """(DT, DLL_DT): the control interval as DLL_DT and the largest DT ≤ MAX_DT that
    divides it (ServoDyn: DLL_DT must be a whole multiple of DT)."""
    n = max(1, math.ceil(interval / MAX_DT - 1e-9))
    return interval / n, interval


# ------------------------------------------------------------------ copying a deck

#: the module files of the main file that wtftc edits: each must name a text file
MODULE_KEYS = ("EDFile", "InflowFile", "AeroFile", "ServoFile")
#: values that name no file
_NO_FILE = {"", "none", "unused", "default", "true", "false", "t", "f"}
#: an input line's value: its first word, quoted or not, an ``@`` include marked
_VALUE = re.compile(r"""[ \t]*(@?)(?:"([^"\n]*)"|'([^'\n]*)'|([^\s"'!,]+))""")
#: what follows a value on an input line: nothing, a key, or ``! Key`` (ROSCO's DISCON.IN)
_AFTER = re.compile(r"\s*$|\s+(?:!\s*)?(?P<key>[A-Za-z_][\w()\[\].,:%-]*)(?:\s|$)")
#: keys whose file is an OpenFAST input file (text): the module files, ElastoDyn's blade
#: and tower files, AeroDyn's blade and airfoil files, ServoDyn's controller input
_TEXT_KEY = re.compile(r"\w*(File|Files|AFNames)(\(\d+\))?")


def input_value(line: str) -> tuple[int, int, str, str, bool] | None:
    """The value of an OpenFAST input line (``value  Key  - description``, ``value  !
    Key  - description``, a list entry alone on its line, an ``@file`` include): (start,
    end, the word without its quotes, its key or "", whether an include); None for a
    comment, a header or a line of free text. Nothing after the value is a name: a path
    in a description or a comment is never one."""
    if line.lstrip()[:1] in "!#-=":
        return None
    m = _VALUE.match(line)
    after = _AFTER.match(line, m.end()) if m else None
    if not m or not after:
        return None
    g = next(k for k in (2, 3, 4) if m.group(k) is not None)
    return m.start(g), m.end(g), m.group(g), after["key"] or "", m.group(1) == "@"


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def _target(path: Path, doc: Text, word: str, by: tuple[Path, str]) -> Path | None:
    """The regular file ``word`` (in the file ``path``) names, as OpenFAST resolves it (a
    relative name against the naming file's folder), links followed; None for a name of
    no file (missing, or a folder where no file key asks for a file: left as written). A
    symbolic link loop, a FIFO, a device, a socket, a file too large or unreadable, a
    folder named by a ``...File`` key is refused."""
    full = path.parent / doc.fs_path(word)
    try:
        st = os.stat(full)
    except OSError as exc:
        if exc.errno in (errno.ENOENT, errno.ENOTDIR, errno.ENAMETOOLONG):
            return None
        why = "a symbolic link loop" if exc.errno == errno.ELOOP else exc.strerror
        raise refused(full, f"a file that can be read ({why})", by) from None
    if stat.S_ISDIR(st.st_mode):
        if _text_wanted(by[1], False):
            raise refused(full, "a file (this is a folder)", by)
        return None
    try:
        check_user_file(full, "openfast_deck", MAX_INPUT_BYTES)
    except ConfigError as exc:
        raise refused(full, exc.allowed, by) from None
    return Path(os.path.realpath(full))


def references(path: Path, doc: Text) -> list[tuple[int, int, int, Path, str, bool]]:
    """Every file the deck file ``path`` (its text ``doc``) names on its input lines:
    (line, start, end of the name, the file, the key, whether an include). The title
    (the second line, after an OpenFAST header ``---- ... ----``) is free text."""
    found = []
    lines = doc.text.split("\n")
    title = 1 if lines[0].lstrip()[:1] in ("-", "=") else None
    for i, line in enumerate(lines):
        value = None if i == title else input_value(line)
        if value is None:
            continue
        a, b, word, key, include = value
        if word.lower() in _NO_FILE or _is_number(word):
            continue
        target = _target(path, doc, word, (path, key))
        if target is not None:
            found.append((i, a, b, target, key, include))
    return found


#: keys whose value is the root of several files' names (HydroDyn's WAMIT files
#: ``<root>.1``, ``.3``, ``.hst``), no file itself
_ROOT_KEYS = ("PotFile",)


def _text_wanted(key: str, include: bool) -> bool:
    return include or (bool(_TEXT_KEY.fullmatch(key)) and not key.startswith(_ROOT_KEYS))


def _deck_files(fst: Path) -> dict[Path, tuple[bytes, list]]:
    """Every file the main file names, and those they name, to the end: each file's bytes
    and its references (line, start, end, file). A file named where text belongs (the
    main file, a ``...File`` key, an include) with a NUL or control byte is refused; any other
    binary file (a wind field, a library) is copied as it is, not read for names."""
    fst = Path(os.path.realpath(fst))
    files: dict[Path, tuple[bytes, list]] = {}
    todo: list[tuple[Path, tuple[Path, str] | None, bool]] = [(fst, None, True)]
    while todo:
        path, by, text = todo.pop(0)
        if path in files:
            continue
        try:
            data = read_user_bytes(path, "openfast_deck", MAX_INPUT_BYTES)
        except ConfigError as exc:
            raise refused(path, exc.allowed, by) from None
        if not text and binary_byte(data) is not None:
            files[path] = (data, [])
            continue
        refs = references(path, decoded(data, path, by))
        files[path] = (data, [r[:4] for r in refs])
        todo += [(r[3], (path, r[4]), _text_wanted(r[4], r[5])) for r in refs]
    return files


def _check_modules(fst: Path, files: dict) -> None:
    """Each module file of the main file that wtftc edits (MODULE_KEYS) that it names is
    a file (a key it lacks is refused where it is edited, :func:`module_file`)."""
    doc = decoded(files[fst][0], fst)
    for line in doc.text.split("\n"):
        value = input_value(line)
        if value is not None and value[3] in MODULE_KEYS:
            _module_path(fst, doc, value[3], value[2])


def _module_path(fst: Path, doc: Text, key: str, word: str) -> Path:
    """The module file the main file ``fst`` names as ``key`` (``word``): a file, else
    refused naming the main file, the key and what it names."""
    path = fst.parent / doc.fs_path(word)
    if not path.is_file():
        what = "a folder" if path.is_dir() else "no file"
        raise refused(fst, f"an OpenFAST main file whose {key} names its module's input "
                      f"file, which wtftc edits ({word!r} is {what} there)")
    return path


def _free(name: str, taken: set[str]) -> str:
    """``name``, or ``<stem>_<n><suffix>`` when it is taken."""
    stem, dot, ext = name.partition(".")
    n, out = 1, name
    while out in taken:
        out, n = f"{stem}_{n}{dot}{ext}", n + 1
    return out


def _destinations(fst: Path, files: dict, deck: Path, folder: Path) -> dict[Path, Path]:
    """Where each of the deck's files goes in ``folder``: the main file and the module
    files it names at the top (OpenFAST resolves a module's files against the module
    file's folder: the wind files written beside InflowWind's), a file under the deck's
    folder where it is under it, every other file under ``<its common folder's name>/``
    in the same layout as where it lives."""
    fst = Path(os.path.realpath(fst))
    deck = Path(os.path.realpath(deck))
    taken = {p.relative_to(deck).parts[0] for p in files if p.is_relative_to(deck)}
    dest = {fst: folder / fst.name}
    for target in dict.fromkeys(r[3] for r in files[fst][1]):
        if target == fst:
            continue
        name = target.name if target.parent == deck else _free(target.name, taken)
        taken.add(name)
        dest[target] = folder / name
    inside = {p: folder / p.relative_to(deck) for p in files
              if p not in dest and p.is_relative_to(deck)}
    dest.update(inside)
    outside = [p for p in files if p not in dest]
    if outside:
        common = Path(os.path.commonpath([p.parent for p in outside]))
        root = folder / _free(common.name or "deck_files", taken)
        dest.update({p: root / p.relative_to(common) for p in outside})
    return dest


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _write_copy(path: Path, data: bytes, source: Path) -> None:
    """``data`` written to ``path`` no more readable than ``source`` (its permission bits,
    less the umask; the owner may read and write it, for the edits that follow)."""
    mode = (os.stat(source).st_mode & 0o777 & ~_umask()) | 0o600
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o600)
    try:
        os.fchmod(fd, mode)
        view = memoryview(data)
        while view:  # a short write (a full disk) never leaves a copy cut short
            view = view[os.write(fd, view):]
    finally:
        os.close(fd)


def _rewritten(data: bytes, refs: list, out: Path, dest: dict) -> bytes:
    """A deck file's bytes with each file it names renamed to the copy's relative path."""
    doc = decoded(data, out)
    lines = doc.text.split("\n")
    for i, a, b, target in sorted(refs, key=lambda r: (r[0], -r[1])):
        new = doc.fs_text(Path(os.path.relpath(dest[target], out.parent)).as_posix())
        lines[i] = lines[i][:a] + new + lines[i][b:]
    return doc.encode("\n".join(lines))


def check_main_file(fst: Path) -> Path:
    """The deck's main file: a regular file of text (a FIFO, a folder, a device, a
    symbolic link loop, a binary file is refused in one line saying what it is)."""
    try:
        check_user_file(fst, "openfast_deck", MAX_INPUT_BYTES)
    except ConfigError as exc:
        raise ConfigError("openfast_deck", str(fst), "an OpenFAST main input file (.fst): "
                          + exc.allowed) from None
    return fst


def copy_deck(fst: Path, folder: Path) -> Path:
    """The deck copied into ``folder``, so that it runs from there: the regular files its
    input lines name, to the end, wherever they live (``../`` of another example, an
    absolute path), each name rewritten to the copy's relative path
    (:func:`_destinations`), each copy no more readable than its file; nothing else of
    the deck's folder. Returns the copied main file."""
    fst = check_main_file(Path(fst))
    files = _deck_files(fst)
    real = Path(os.path.realpath(fst))
    _check_modules(real, files)
    folder = Path(folder).resolve()
    dest = _destinations(real, files, real.parent, folder)
    for path, (data, refs) in files.items():
        out = dest[path]
        _write_copy(out, _rewritten(data, refs, out, dest) if refs else data, path)
    for path in (real, *(r[3] for r in files[real][1])):
        _remember(dest[path], path)
    return dest[real]


#: the switches of the modules below the tower, all off: the case is the tower clamped at
#: its base (TowerBsHt), as wtftc's tower plant is (docs/openfast.md: the IEA 15-MW)
SUBSTRUCTURE_OFF = {"CompSeaSt": "0", "CompHydro": "0", "CompSub": "0", "CompMooring": "0",
                    "CompIce": "0"}
#: ElastoDyn's platform: no degree of freedom, no initial displacement
PLATFORM_FIXED = {**{f"Ptfm{d}DOF": "False" for d in ("Sg", "Sw", "Hv", "R", "P", "Y")},
                  **{f"Ptfm{d}": "0" for d in ("Surge", "Sway", "Heave", "Roll", "Pitch",
                                               "Yaw")}}


def no_node_outputs(path: Path) -> None:
    """A module's per-node outputs off (``BldNd_BladesOut`` 0, where the file has it): the
    IEA 15-MW deck's ElastoDyn and AeroDyn write 50 nodes' worth, about 970 channels a
    step, which nothing here reads (a 600-s run would read back 0.9 GB)."""
    if any(ln.split()[1:2] == ["BldNd_BladesOut"] for ln in read_text(path).text.split("\n")):
        set_values(path, {"BldNd_BladesOut": "0"})


def clamp_fixed_bottom(fst: Path, ed: Path) -> None:
    """The case clamped at the tower's base: no sea state, hydrodynamics, substructure,
    mooring or ice, and ElastoDyn's platform fixed (a land deck is unchanged)."""
    set_values(fst, SUBSTRUCTURE_OFF)
    set_values(ed, PLATFORM_FIXED)


def module_file(fst: Path, key: str) -> Path:
    """The file the main file's ``key`` (EDFile, ServoFile, InflowFile) names."""
    return _module_path(fst, read_text(fst), key, get_value(fst, key))


def write_wind(path: Path, t_final: float, wind) -> None:
    """The run's wind as InflowWind's uniform wind file, every WIND_DT s: the horizontal
    speed and its direction (wind.horizontal, wind.direction: an ECD turns, every other
    kind blows along the rotor's axis), no shear, no gust. The direction goes in degrees,
    InflowWind's unit and sign: its components are u = V cos Δ along the rotor's axis and
    v = -V sin Δ across it (as OpenFAST reports them: Wind1VelX, Wind1VelY;
    tests/test_sweep_winds.py)."""
    t = np.arange(0.0, t_final + 2 * WIND_DT, WIND_DT)
    u = np.broadcast_to(np.asarray(wind.horizontal(t), dtype=float), t.shape)
    direction_deg = np.degrees(np.broadcast_to(np.asarray(wind.direction(t), dtype=float),
                                               t.shape))
    head = ["! wtftc: the run's wind (uniform over the rotor), docs/openfast.md",
            "! Time  Wind  Wind  Vert.  Horiz.  Pwr.Law  Lin.Vert.  Gust",
            "! (s)  (m/s)  (deg)  (m/s)  (-)  (-)  (-)  (m/s)"]
    rows = [f"{a:.4f} {b:.6f} {c:.6f} 0 0 0 0 0"
            for a, b, c in zip(t, u, direction_deg, strict=True)]
    path.write_text("\n".join(head + rows) + "\n")


def initial_conditions(ed: Path, omega_r: float, beta: np.ndarray, tower_x: float) -> None:
    """ElastoDyn's initial rotor speed [rpm], blade pitch [deg] and tower-top fore-aft
    displacement [m]."""
    set_values(ed, {"RotSpeed": f"{omega_r * 30 / math.pi:.9g}",
                    "TTDspFA": f"{tower_x:.9g}",
                    **{f"BlPitch({j + 1})": f"{math.degrees(b):.9g}"
                       for j, b in enumerate(beta)}})


# ------------------------------------------------------------- checks before a run

def check_out_outside_deck(out: Path, fst: Path) -> None:
    """``--out`` outside the deck's own folder (the folder of its main file): a run copies
    the deck's files into ``--out``, and a run folder inside the deck would be copied into
    the next. Refused in one line before anything is written."""
    try:
        real = Path(os.path.realpath(out))
        deck = Path(os.path.realpath(fst)).parent
    except (OSError, ValueError) as exc:
        raise ConfigError("--out", str(out), f"a folder that can be reached ({exc})") from None
    if real == deck or deck in real.parents:
        raise ConfigError("--out", str(out), f"a folder outside the OpenFAST deck's own "
                          f"folder {deck} (the run copies the deck into --out)")


#: the relative difference allowed between a deck's value and the turbine file's (the
#: DISCON.IN rounds its rated speed; as ``wtftc turbine import`` cross-checks its files)
DECK_TOLERANCE = 5e-3


def _deck_number(path: Path, key: str, discon: bool = False) -> float | None:
    """``key``'s value in the user's deck file ``path`` (``value  Key`` lines, or ROSCO's
    ``value  ! Key`` with ``discon``), a finite number; None when the file has no such
    line (a DISCON.IN that is not ROSCO's)."""
    for line in read_text(path).text.split("\n"):
        words = line.split()
        if words[1 + discon:2 + discon] == [key] and (not discon or words[1] == "!"):
            try:
                v = float(words[0].replace("d", "e").replace("D", "E"))
            except ValueError:
                v = math.nan
            if not math.isfinite(v):
                raise ConfigError(key, words[0], "a finite number", where=str(path))
            return v
    if discon:
        return None
    raise ConfigError(key, "missing", "a value (`value  Key  - description`)",
                      where=str(path))


def _named_file(path: Path, key: str) -> Path | None:
    """The user's file that the deck file ``path`` names as ``key``; None for none."""
    doc = read_text(path)
    for line in doc.text.split("\n"):
        value = input_value(line)
        if value is not None and value[3] == key:
            target = path.parent / doc.fs_path(value[2])
            return target if value[2].lower() not in _NO_FILE and target.is_file() else None
    return None


def deck_turbine_values(fst: Path) -> dict[str, tuple[float, Path, str]]:
    """The deck's values that its turbine file also gives: turbine parameter → (value in
    the turbine file's unit, the deck file, its key). ElastoDyn's GBRatio and TipRad
    (``wtftc turbine import``'s gearbox_ratio and rotor_radius); the rated rotor speed
    omega_g_rated = PC_RefSpd / GBRatio [rad/s] of the DISCON.IN the deck's ServoDyn names
    (DLL_InFile), where it is ROSCO's: the deck's own controller's rated speed."""
    fst = check_main_file(Path(fst))
    ed = _named_file(fst, "EDFile")
    if ed is None:
        raise refused(fst, "an OpenFAST main file whose EDFile names its ElastoDyn file")
    n = _deck_number(ed, "GBRatio")
    out = {"gearbox_ratio": (n, ed, "GBRatio"),
           "rotor_radius": (_deck_number(ed, "TipRad"), ed, "TipRad")}
    servo = _named_file(fst, "ServoFile")
    discon = _named_file(servo, "DLL_InFile") if servo is not None else None
    rated = _deck_number(discon, "PC_RefSpd", discon=True) if discon is not None else None
    if rated is not None and n != 0:
        out["omega_g_rated"] = (rated / n, discon, "PC_RefSpd / GBRatio")
    return out


def check_deck_matches_turbine(fst: Path, turbine, param=None) -> None:
    """The deck and the turbine file describe one turbine: its gearbox ratio, rotor radius
    and rated rotor speed (:func:`deck_turbine_values`) within DECK_TOLERANCE of the
    run's (``param(name)``, by default the turbine file's values). A mismatch is one
    ConfigError naming both files, the key and both values: OpenFAST would run the deck's
    turbine under a controller tuned for the turbine file's, to a result that means
    nothing (a deck GBRatio of 50 against 97: 0 W)."""
    param = param or turbine.values.__getitem__
    for name, (deck_value, path, key) in deck_turbine_values(fst).items():
        ours = float(param(name))
        if not abs(deck_value - ours) <= DECK_TOLERANCE * abs(ours):
            raise ConfigError(
                key, float(f"{deck_value:.6g}"), f"the turbine's {name} = {ours:.6g} within "
                f"{DECK_TOLERANCE:.1%} (the turbine file {turbine.path}: the deck and the "
                "turbine file describe different turbines; correct one, or import the "
                "turbine from its deck: wtftc turbine import)", where=str(path))
