"""OpenFAST decks read as users write them: hostile mutations of a copy of ROSCO 2.10.6's
NREL 5-MW deck, given to wtftc.openfast.case's copy and checks directly (no OpenFAST run),
and a few short runs of `wtftc run --engine openfast` that show such a deck still runs.

Every refusal is one line (a ConfigError, exit code 2 at the CLI), comes before anything
is written, and leaves the user's deck as it was; every accepted deck is copied with only
the files its input lines name, byte for byte but for the names rewritten."""

from __future__ import annotations

import errno
import os
import shutil
import socket
import stat
from pathlib import Path

import pytest
from nrel5mw_deck import DECK, time_limit

from wtftc.errors import ConfigError
from wtftc.model import openfast_deck, turbine_file
from wtftc.openfast import case as ofcase

FST = "NREL-5MW.fst"
ED = "NRELOffshrBsline5MW_Onshore_ElastoDyn.dat"
BLADE = "NRELOffshrBsline5MW_Blade.dat"
TOWER = "NRELOffshrBsline5MW_Onshore_ElastoDyn_Tower.dat"
AD = "NRELOffshrBsline5MW_Onshore_AeroDyn15.dat"
IW = "NRELOffshrBsline5MW_InflowWind.dat"
SD = "NRELOffshrBsline5MW_Onshore_ServoDyn.dat"
DISCON = "DISCON.IN"
#: the 28 files the deck's input lines name (ROSCO 2.10.6: its main file, ElastoDyn,
#: BeamDyn, AeroDyn with 8 airfoils and their coordinates, the DISCON.IN and its Cp table)
N_NAMED = 28
#: a user's file that no deck names by an input line: never copied
SECRET = b"a user's secret, named only in comments\n"


@pytest.fixture
def deck(tmp_path) -> Path:
    """A private copy of ROSCO's NREL 5-MW deck folder (its main file's folder)."""
    folder = tmp_path / "deck"
    shutil.copytree(DECK, folder)
    (tmp_path / "secret.txt").write_bytes(SECRET)
    return folder


def _tree(root: Path) -> dict:
    """Every entry under ``root`` (not followed): its kind, size, mode and mtime, the
    bytes of a small regular file: what a test checks no refusal touched."""
    out = {}
    for here, dirs, files in os.walk(root):
        for name in dirs + files:
            p = Path(here) / name
            st = p.lstat()
            small = stat.S_ISREG(st.st_mode) and st.st_size < 1 << 20
            out[str(p)] = (st.st_mode, st.st_size, st.st_mtime_ns,
                           p.read_bytes() if small else None)
    return out


def _edit(path: Path, old: bytes, new: bytes, count: int = 1) -> None:
    data = path.read_bytes()
    assert old in data, (path, old)
    path.write_bytes(data.replace(old, new, count))


def _line_of(path: Path, key: str) -> bytes:
    return next(ln for ln in path.read_bytes().split(b"\n") if key.encode() in ln.split()[1:2])


def _set(path: Path, key: str, value: bytes) -> None:
    """``key``'s value in the deck file ``path`` replaced by ``value`` (bytes); in ROSCO's
    DISCON.IN (``value  ! Key``) too."""
    if path.name == DISCON:
        line = next(ln for ln in path.read_bytes().split(b"\n") if ln.split()[1:3] == [
            b"!", key.encode()])
        _edit(path, line, value + b"  " + line[line.index(b"!"):])
        return
    line = _line_of(path, key)
    _edit(path, line, value + b"   " + line.split(None, 1)[1])


def _copied(case: Path) -> set[str]:
    return {p.relative_to(case).as_posix() for p in case.rglob("*") if not p.is_dir()}


# ------------------------------------------------------------- mutations that are refused

def _binary_fst(d, t):
    (d / FST).write_bytes(b"\x7fELF\x02\x01\x01\x00" + bytes(range(256)) * 4)


def _elf_as(name):
    def mutate(d, t):
        (d / name).write_bytes(b"\x7fELF\x02\x01\x01\xff\xfe" * 50)  # no NUL
    return mutate


def _escape_in(name):
    def mutate(d, t):
        _at_line_3(d / name, b" \x1b[31m red")
    return mutate


def _utf16_fst(d, t):
    (d / FST).write_bytes((d / FST).read_text().encode("utf-16"))


def _nul_in(name):
    def mutate(d, t):
        _edit(d / name, b"\n", b"\n\x00", 1)
    return mutate


def _loop(name_key):
    name, key = name_key

    def mutate(d, t):
        os.symlink("loop_b", d / "loop_a")
        os.symlink("loop_a", d / "loop_b")
        _set(d / name, key, b'"loop_a"')
    return mutate


def _fst_is(kind):
    def mutate(d, t):
        (d / FST).unlink()
        if kind == "fifo":
            os.mkfifo(d / FST)
        elif kind == "folder":
            (d / FST).mkdir()
        elif kind == "loop":
            os.symlink(FST, d / FST)
        elif kind == "dangling":
            os.symlink("nowhere.fst", d / FST)
    return mutate


def _named_special(kind, name=TOWER, key="TwrFile"):
    def mutate(d, t):
        target = d / "special"
        if kind == "fifo":
            os.mkfifo(target)
        elif kind == "device":
            os.symlink("/dev/zero", target)
        elif kind == "socket":
            s = socket.socket(socket.AF_UNIX)
            s.bind(str(target))
            s.close()
        elif kind == "huge":
            with open(target, "wb") as fh:
                fh.truncate(ofcase.MAX_INPUT_BYTES + 1)  # sparse: nothing is written
        _set(d / ED if name == TOWER else d / name, key, b'"special"')
    return mutate


def _module_is(key, value, make=None):
    def mutate(d, t):
        if make == "folder":
            (d / value.strip(b'"').decode()).mkdir()
        _set(d / FST, key, value)
    return mutate


def _folder_as(name, key):
    def mutate(d, t):
        (d / "a_folder").mkdir()
        _set(d / name, key, b'"a_folder"')
    return mutate


def _discon_nul(d, t):
    _edit(d / DISCON, b"\n", b"\n\x00", 1)


REFUSED = [
    # (id, mutation, words the one line must hold)
    ("binary main file", _binary_fst, [FST, "control character 0x02", "binary"]),
    ("ELF bytes as ElastoDyn", _elf_as(ED), [ED, "0x02", "EDFile"]),
    ("ESC bytes in AeroDyn", _escape_in(AD), [AD, "0x1b", "AeroFile"]),
    ("UTF-16 main file", _utf16_fst, [FST, "NUL", "UTF-16"]),
    ("NUL in ElastoDyn", _nul_in(ED), [ED, "NUL", f"{FST} names it as EDFile"]),
    ("NUL in the blade file", _nul_in(BLADE), [BLADE, "NUL", "BldFile(1)"]),
    ("NUL in the tower file", _nul_in(TOWER), [TOWER, "NUL", "TwrFile"]),
    ("NUL in AeroDyn", _nul_in(AD), [AD, "NUL", "AeroFile"]),
    ("NUL in InflowWind", _nul_in(IW), [IW, "NUL", "InflowFile"]),
    ("NUL in ServoDyn", _nul_in(SD), [SD, "NUL", "ServoFile"]),
    ("NUL in DISCON.IN", _discon_nul, [DISCON, "NUL", "DLL_InFile"]),
    ("NUL in an airfoil", _nul_in("Airfoils/Cylinder1.dat"), ["Cylinder1.dat", "AFNames"]),
    ("NUL in an include", _nul_in("Airfoils/DU40_A17_coords.txt"),
     ["DU40_A17_coords.txt", "NumCoords"]),
    ("loop named as EDFile", _loop((FST, "EDFile")), ["loop_a", "symbolic link loop",
                                                     "EDFile"]),
    ("loop named as BldFile(1)", _loop((ED, "BldFile(1)")), ["loop_a", "BldFile(1)",
                                                             "symbolic link loop"]),
    ("loop named as TwrFile", _loop((ED, "TwrFile")), ["loop_a", "TwrFile"]),
    ("loop named as DLL_InFile", _loop((SD, "DLL_InFile")), ["loop_a", "DLL_InFile"]),
    ("loop named as FileName_BTS", _loop((IW, "FileName_BTS")), ["loop_a", "FileName_BTS"]),
    ("main file a FIFO", _fst_is("fifo"), [FST, "FIFO"]),
    ("main file a folder", _fst_is("folder"), [FST, "a folder"]),
    ("main file a link loop", _fst_is("loop"), [FST, "symbolic link loop"]),
    ("main file a dangling link", _fst_is("dangling"), [FST, "there is none"]),
    ("a FIFO named as TwrFile", _named_special("fifo"), ["special", "FIFO", "TwrFile"]),
    ("/dev/zero named as TwrFile", _named_special("device"), ["special", "character "
                                                              "device"]),
    ("a socket named as TwrFile", _named_special("socket"), ["special", "socket"]),
    ("a file over the size cap", _named_special("huge"), ["special", "at most"]),
    ("a FIFO named as FileName_BTS", _named_special("fifo", IW, "FileName_BTS"),
     ["special", "FIFO", "FileName_BTS"]),
    ("a FIFO named as PerfFileName", _named_special("fifo", DISCON, "PerfFileName"),
     ["special", "FIFO"]),
    ("EDFile a folder", _module_is("EDFile", b'"EDfolder"', "folder"),
     [FST, "EDFile", "a folder"]),
    ("EDFile missing", _module_is("EDFile", b'"no_such_ed.dat"'), [FST, "EDFile", "no file"]),
    ("AeroFile unused", _module_is("AeroFile", b'"unused"'), [FST, "AeroFile", "no file"]),
    ("ServoFile the deck's folder", _module_is("ServoFile", b'"."'),
     [FST, "ServoFile", "a folder"]),
    ("a folder named as TwrFile", _folder_as(ED, "TwrFile"), ["a_folder", "TwrFile",
                                                              "a folder"]),
    ("a folder named as an airfoil", _folder_as(AD, "AFNames"), ["a_folder", "AFNames"]),
]


def _ed_unreadable(monkeypatch, deck):
    """ElastoDyn unreadable (EACCES: root reads any file, so the refusal is simulated at
    the open, where a user's permission would stop it)."""
    real_open = os.open
    target = str(deck / ED)

    def deny(path, *args, **kwargs):
        if str(path) == target:
            raise PermissionError(errno.EACCES, "Permission denied", target)
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(os, "open", deny)


@pytest.mark.parametrize("name, mutate, words", REFUSED, ids=[r[0] for r in REFUSED])
def test_a_hostile_deck_is_refused_in_one_line_before_anything_is_written(
        deck, tmp_path, name, mutate, words):
    mutate(deck, tmp_path)
    before = _tree(tmp_path)
    case = tmp_path / "case"
    with time_limit(20), pytest.raises(ConfigError) as exc:
        ofcase.copy_deck(deck / FST, case)
    text = str(exc.value)
    assert "\n" not in text and exc.value.field == "openfast_deck", text
    for w in words:
        assert w in text, (w, text)
    assert not case.exists()
    assert _tree(tmp_path) == before


def test_an_unreadable_file_is_one_line(deck, tmp_path, monkeypatch):
    _ed_unreadable(monkeypatch, deck)
    with pytest.raises(ConfigError, match="Permission denied") as exc:
        ofcase.copy_deck(deck / FST, tmp_path / "case")
    assert ED in str(exc.value) and "EDFile" in str(exc.value)
    assert not (tmp_path / "case").exists()


# ------------------------------------------------------ mutations that copy and run as before

def _comment_names(line: bytes):
    def mutate(d, t):
        _edit(d / FST, b"\n", b"\n" + line + b"\n", 1)
    return mutate


def _description_names(d, t):
    _edit(d / FST, b"EDFile          - Name", b'EDFile  - like "../secret.txt" or '
          b"../secret.txt - Name")


def _discon_comment_names(d, t):
    _edit(d / DISCON, b"! PC_RefSpd", b'! PC_RefSpd - see "../secret.txt" ! "../secret.txt"')


def _title_names(d, t):
    lines = (d / ED).read_bytes().split(b"\n")
    lines[1] = b"../secret.txt   Title - a title that starts with a path"
    (d / ED).write_bytes(b"\n".join(lines))


def _unrelated(kind):
    def mutate(d, t):
        p = d / "unrelated"
        if kind == "huge":
            with open(p, "wb") as fh:
                fh.truncate(300 * 1024 * 1024)
        elif kind == "fifo":
            os.mkfifo(p)
        elif kind == "loop":
            os.symlink("unrelated", p)
        elif kind == "dangling":
            os.symlink("/nonexistent/unrelated", p)
        elif kind == "outside link":
            os.symlink(t / "secret.txt", p)
        elif kind == "folder":
            p.mkdir()
            for i in range(50):
                (p / f"f{i}.dat").write_bytes(SECRET)
        elif kind == "socket":
            s = socket.socket(socket.AF_UNIX)
            s.bind(str(p))
            s.close()
    return mutate


def _at_line_3(path: Path, text: bytes) -> None:
    """``text`` added at the end of the file's fourth line (a description or a comment:
    openfast-io reads by position, so no line is added)."""
    lines = (path).read_bytes().split(b"\n")
    lines[3] += text
    path.write_bytes(b"\n".join(lines))


def _latin1(name):
    def mutate(d, t):
        _at_line_3(d / name, b" angles in \xb0 (degrees), \xe9t\xe9 \xb5m")
    return mutate


def _utf8_text(d, t):
    _at_line_3(d / ED, b" angles in \xc2\xb0, \xe2\x88\x82\xcf\x89/\xe2\x88\x82t")


def _cp1252(d, t):
    _at_line_3(d / ED, b" \x93quoted\x94 \x80 it\x92s")


def _editor_bytes(d, t):
    _at_line_3(d / FST, b"\t\x0c")
    (d / AD).write_bytes((d / AD).read_bytes() + b"\x1a")


def _bom(name):
    def mutate(d, t):
        (d / name).write_bytes(b"\xef\xbb\xbf" + (d / name).read_bytes())
    return mutate


def _crlf(name):
    def mutate(d, t):
        (d / name).write_bytes((d / name).read_bytes().replace(b"\n", b"\r\n"))
    return mutate


def _outside(rel: str, key=("EDFile", FST), abs_path=False):
    """ElastoDyn (or the file ``key`` names) moved to ``rel`` from the deck's folder."""
    k, named_by = key

    def mutate(d, t):
        src = d / named_by
        old = d / ofcase.get_value(src, k)
        new = (d / rel).resolve()
        new.parent.mkdir(parents=True, exist_ok=True)
        data = old.read_bytes()
        for name in (BLADE, TOWER) if k == "EDFile" else ():  # its files, from its folder
            data = data.replace(f'"{name}"'.encode(),
                                f'"{os.path.relpath(d / name, new.parent)}"'.encode())
        new.write_bytes(data)
        old.unlink()
        _set(src, k, f'"{new if abs_path else rel}"'.encode())
    return mutate


def _named_link_outside(d, t):
    (t / "blade_elsewhere.dat").write_bytes((d / BLADE).read_bytes())
    (d / BLADE).unlink()
    os.symlink(t / "blade_elsewhere.dat", d / BLADE)


def _spaces_and_quotes(d, t):
    os.rename(d / TOWER, d / "my tower.dat")
    _set(d / ED, "TwrFile", b'"my tower.dat"')
    _set(d / ED, "BldFile(2)", b"'" + BLADE.encode() + b"'")
    _set(d / ED, "BldFile(3)", b"./" + BLADE.encode())


def _module_names_with_spaces(d, t):
    os.rename(d / ED, d / "my elasto dyn.dat")
    _set(d / FST, "EDFile", b'"my elasto dyn.dat"')
    _set(d / FST, "ServoFile", b"'" + SD.encode() + b"'")
    os.rename(d / DISCON, d / "my discon.in")
    _set(d / SD, "DLL_InFile", b'"my discon.in"')


def _utf8_name(d, t):
    os.rename(d / TOWER, d / "Türm.dat")
    _set(d / ED, "TwrFile", '"Türm.dat"'.encode())


def _latin1_name(d, t):
    os.rename(os.fsencode(d / TOWER), os.fsencode(d) + b"/T\xfcrm.dat")
    _set(d / ED, "TwrFile", b'"T\xfcrm.dat"')
    _edit(d / ED, b"\n", b"\n! \xb0\n", 1)  # the file is Latin-1


def _dangling_named(d, t):
    os.symlink("/nonexistent/wind.bts", d / "wind.bts")
    _set(d / IW, "FileName_BTS", b'"wind.bts"')


def _two_same_names(d, t):
    for sub in ("a", "b"):
        (t / sub).mkdir()
        (t / sub / "same.dat").write_bytes((d / BLADE).read_bytes() + sub.encode() + b"\n")
    _set(d / ED, "BldFile(2)", b'"../a/same.dat"')
    _set(d / ED, "BldFile(3)", b'"../b/same.dat"')


def _binary_wind(d, t):
    (d / "wind.bts").write_bytes(bytes(range(256)) * 64)
    _set(d / IW, "FileName_BTS", b'"wind.bts"')


def _cycle(d, t):
    _edit(d / ED, b"------- ELASTODYN", b'"../deck/' + FST.encode() + b'"   Cycle - back\n'
          b"------- ELASTODYN")


def _long_name(d, t):
    _set(d / FST, "BDBldFile(1)", b'"' + b"x" * 5000 + b'.dat"')


def _root_name_a_folder(d, t):
    """HydroDyn's PotFile is the root of its WAMIT files' names; a folder of that name."""
    (d / "HydroData").mkdir()
    (d / FST).write_bytes((d / FST).read_bytes() + b'"HydroData"   PotFile  - root\n')


def _no_header_title(d, t):
    _edit(d / FST, b"------- OpenFAST", b"OpenFAST", 1)


ACCEPTED = [
    # (id, mutation, files the copy must hold besides the deck's, files it must not)
    ("a comment names a file", _comment_names(b'! see "../secret.txt" or ../secret.txt'),
     [], ["secret.txt"]),
    ("a # comment names a file", _comment_names(b'# "../secret.txt"'), [], ["secret.txt"]),
    ("a header names a file", _comment_names(b'---- "../secret.txt" ----'), [],
     ["secret.txt"]),
    ("a description names a file", _description_names, [], ["secret.txt"]),
    ("a DISCON.IN comment names a file", _discon_comment_names, [], ["secret.txt"]),
    ("a title names a file", _title_names, [], ["secret.txt"]),
    ("a huge unrelated file", _unrelated("huge"), [], ["unrelated"]),
    ("an unrelated FIFO", _unrelated("fifo"), [], ["unrelated"]),
    ("an unrelated link loop", _unrelated("loop"), [], ["unrelated"]),
    ("an unrelated dangling link", _unrelated("dangling"), [], ["unrelated"]),
    ("an unrelated link outside", _unrelated("outside link"), [], ["unrelated"]),
    ("an unrelated folder", _unrelated("folder"), [], ["unrelated/f0.dat"]),
    ("an unrelated socket", _unrelated("socket"), [], ["unrelated"]),
    ("Latin-1 main file", _latin1(FST), [], []),
    ("Latin-1 ElastoDyn", _latin1(ED), [], []),
    ("Latin-1 AeroDyn", _latin1(AD), [], []),
    ("Latin-1 DISCON.IN", _latin1(DISCON), [], []),
    ("Latin-1 airfoil", _latin1("Airfoils/DU40_A17.dat"), [], []),
    ("UTF-8 ElastoDyn", _utf8_text, [], []),
    ("Windows-1252 quotes", _cp1252, [], []),
    ("tab, form feed, Ctrl-Z", _editor_bytes, [], []),
    ("BOM main file", _bom(FST), [], []),
    ("BOM ElastoDyn", _bom(ED), [], []),
    ("BOM AeroDyn", _bom(AD), [], []),
    ("CRLF main file", _crlf(FST), [], []),
    ("CRLF ElastoDyn", _crlf(ED), [], []),
    ("CRLF AeroDyn", _crlf(AD), [], []),
    ("CRLF DISCON.IN", _crlf(DISCON), [], []),
    ("ElastoDyn in ../", _outside("../elsewhere/ed.dat"), ["ed.dat"], [ED]),
    ("ElastoDyn by absolute path", _outside("../abs/ed.dat", abs_path=True), ["ed.dat"],
     [ED]),
    ("the tower two levels up", _outside("../../up2/tower.dat", ("TwrFile", ED)),
     ["up2/tower.dat"], [TOWER]),
    ("the blade in a sibling", _outside("../sib/blade.dat", ("BldFile(1)", ED)),
     ["sib/blade.dat"], []),
    ("a link to a file outside", _named_link_outside, [], []),
    ("spaces, single quotes, ./", _spaces_and_quotes, ["my tower.dat"], [TOWER]),
    ("module names with spaces, quotes", _module_names_with_spaces,
     ["my elasto dyn.dat", "my discon.in"], [ED, DISCON]),
    ("a UTF-8 file name", _utf8_name, ["Türm.dat"], [TOWER]),
    ("a Latin-1 file name", _latin1_name, [os.fsdecode(b"T\xfcrm.dat")], [TOWER]),
    ("a dangling link named", _dangling_named, [], ["wind.bts"]),
    ("two files of one name", _two_same_names, ["a/same.dat", "b/same.dat"], []),
    ("no header: the title is read", _no_header_title, [], []),
    ("a binary wind file named", _binary_wind, ["wind.bts"], []),
    ("a root name that is a folder", _root_name_a_folder, [], ["HydroData"]),
    ("a cycle of names", _cycle, [], []),
    ("a name too long for a file", _long_name, [], []),
]


@pytest.mark.parametrize("name, mutate, has, lacks", ACCEPTED, ids=[r[0] for r in ACCEPTED])
def test_a_deck_as_users_write_it_is_copied_with_only_what_it_names(
        deck, tmp_path, name, mutate, has, lacks):
    mutate(deck, tmp_path)
    before = _tree(tmp_path / "deck")
    case = tmp_path / "case"
    with time_limit(20):
        fst = ofcase.copy_deck(deck / FST, case)
    assert fst == case / FST
    got = _copied(case)
    assert all(any(p == h or p.endswith("/" + h) for p in got) for h in has), got
    assert not set(lacks) & got, got
    assert all(SECRET not in p.read_bytes() for p in case.rglob("*") if p.is_file())
    assert len(ofcase._deck_files(fst)) == len(got) <= N_NAMED + len(has)
    assert sum(p.stat().st_size for p in case.rglob("*") if p.is_file()) < 1_000_000
    # the case's module files are where the engine edits them, each readable
    for key in ofcase.MODULE_KEYS:
        assert ofcase.module_file(fst, key).is_file()
    assert _tree(tmp_path / "deck") == before


def test_the_copy_is_the_deck_byte_for_byte_and_edits_keep_its_encoding(deck, tmp_path):
    """A Latin-1 ElastoDyn with CRLF lines and a UTF-8 main file with a BOM: each copied
    byte for byte (its names are already the copies' names); an edit changes the value
    and nothing else: the "°" stays the one byte 0xB0, the BOM and CRLF stay."""
    _latin1(ED)(deck, tmp_path)
    _crlf(ED)(deck, tmp_path)
    _bom(FST)(deck, tmp_path)
    fst = ofcase.copy_deck(deck / FST, tmp_path / "case")
    for name in (FST, ED, BLADE, AD, DISCON, "Airfoils/DU40_A17.dat"):
        assert (fst.parent / name).read_bytes() == (deck / name).read_bytes(), name
    ed = ofcase.module_file(fst, "EDFile")
    ofcase.set_values(ed, {"RotSpeed": "11.5", "TTDspFA": "0.25"})
    ofcase.set_outlist(ed, ("RotSpeed", "GenSpeed"))
    ofcase.set_values(fst, {"TMax": "2"})
    data = ed.read_bytes()
    assert b"\xb0 (degrees)" in data and b"\xc2\xb0" not in data
    assert data.count(b"\n") == data.count(b"\r\n")
    assert ofcase.get_value(ed, "RotSpeed") == "11.5" and ofcase.get_value(fst, "TMax") == "2"
    assert fst.read_bytes().startswith(b"\xef\xbb\xbf") and fst.read_bytes().count(
        b"\xef\xbb\xbf") == 1
    old, new = (deck / ED).read_bytes().split(b"\r\n"), data.split(b"\r\n")
    n = next(i for i, ln in enumerate(old) if b"OutList" in ln)  # the same lines to it
    changed = [a.split()[1] for a, b in zip(old[:n], new[:n], strict=True) if a != b]
    assert changed == [b"RotSpeed", b"TTDspFA"]


def test_the_ieas_deck_copies_files_outside_its_folder_and_nothing_else(tmp_path):
    """ROSCO's IEA 15-MW monopile deck names files in ../IEA-15-240-RWT/ (its blades, 50
    airfoils and their coordinates, InflowWind, the Cp table): each copied, and nothing
    of the 81-MB example folder it does not name (its ROSCO.yaml, other variants)."""
    fst = (DECK.parent / "IEA-15-240-RWT" / "IEA-15-240-RWT-Monopile"
           / "IEA-15-240-RWT-Monopile.fst")
    case = ofcase.copy_deck(fst, tmp_path / "case").parent
    got = _copied(case)
    assert len(got) == 116 and "IEA-15-240-RWT-Monopile_ROSCO.yaml" not in got
    assert sum(1 for p in got if "Polar" in p) == 50
    assert sum(p.stat().st_size for p in case.rglob("*") if p.is_file()) < 2_000_000


def test_only_what_the_input_lines_name_is_found():
    """A line's value is its first word (quoted or not, an include's ``@`` dropped),
    followed by nothing, a key, or ``! Key``; a comment, a header, a description is none."""
    v = ofcase.input_value
    assert v('"a b.dat"    EDFile   - the "c.dat" file')[2:4] == ("a b.dat", "EDFile")
    assert v('@"coords.txt"   NumCoords ! x')[2:] == ("coords.txt", "NumCoords", True)
    assert v('"Cp.txt"      ! PerfFileName  - "x.dat"')[2:4] == ("Cp.txt", "PerfFileName")
    assert v('"Airfoils/DU21_A17.dat"\r')[2:4] == ("Airfoils/DU21_A17.dat", "")
    assert v("'x.dat'   Key")[2] == "x.dat"
    for line in ('! "x.dat"  Key', '# "x.dat"', '---- "x.dat" ----', '= "x.dat"', "",
                 "NREL 5.0 MW Baseline", '"x.dat" "y.dat"', '"x.dat" - a description'):
        assert v(line) is None, line


# ------------------------------------------------------------------------ permissions

@pytest.mark.parametrize("mode, umask, expected", [
    (0o600, 0o022, 0o600), (0o640, 0o022, 0o640), (0o644, 0o077, 0o600),
    (0o444, 0o022, 0o644), (0o604, 0o022, 0o604), (0o000, 0o022, 0o600)])
def test_a_copy_is_never_more_readable_than_its_file(deck, tmp_path, mode, umask, expected):
    """Each copy has its file's permission bits less the umask (its owner may read and
    write it, for the edits): a blade file the user keeps private stays private."""
    os.chmod(deck / BLADE, mode)
    old = os.umask(umask)
    try:
        fst = ofcase.copy_deck(deck / FST, tmp_path / "case")
    finally:
        os.umask(old)
    assert stat.S_IMODE((fst.parent / BLADE).stat().st_mode) == expected
    assert stat.S_IMODE(fst.stat().st_mode) == 0o644 & ~umask | 0o600


# ------------------------------------------------------------------------ --out

@pytest.mark.parametrize("where, refused", [
    ("deck", True), ("deck/run", True), ("deck/a/b/c", True), ("deck/..//deck/x", True),
    ("link_into_deck/run", True), ("deck_run", False), ("elsewhere/run", False),
    ("", False), ("deck/../run", False)])
def test_out_inside_the_decks_own_folder_is_refused(deck, tmp_path, where, refused):
    os.symlink(deck, tmp_path / "link_into_deck")
    out = tmp_path / where
    if refused:
        with pytest.raises(ConfigError) as exc:
            ofcase.check_out_outside_deck(out, deck / FST)
        assert exc.value.field == "--out" and str(deck) in str(exc.value)
        assert "\n" not in str(exc.value)
    else:
        ofcase.check_out_outside_deck(out, deck / FST)


def test_a_relative_out_inside_the_deck_is_refused(deck, monkeypatch):
    monkeypatch.chdir(deck)
    with pytest.raises(ConfigError, match="--out"):
        ofcase.check_out_outside_deck(Path("run"), Path(FST))


# ------------------------------------------------------------- deck against turbine file

NREL = turbine_file.load("nrel5mw")


@pytest.mark.parametrize("file, key, value, field", [
    (ED, "GBRatio", b"50", "GBRatio"), (ED, "GBRatio", b"0", "GBRatio"),
    (ED, "GBRatio", b"97.6", "GBRatio"), (ED, "TipRad", b"70", "TipRad"),
    (ED, "TipRad", b"63.4", "TipRad"), (ED, "GBRatio", b"fifty", "GBRatio"),
    (ED, "GBRatio", b"NaN", "GBRatio"), (ED, "TipRad", b"1e400", "TipRad"),
    (ED, "TipRad", b"-63", "TipRad")])
def test_a_deck_that_contradicts_its_turbine_file_is_refused(deck, file, key, value, field):
    """One line naming the deck's file, the key and both values, and the turbine file."""
    _set(deck / file, key, value)
    with pytest.raises(ConfigError) as exc:
        ofcase.check_deck_matches_turbine(deck / FST, NREL)
    text = str(exc.value)
    assert exc.value.field == field and file in text and "\n" not in text
    if "finite" not in text:
        assert NREL.path in text and str(NREL.values[{"GBRatio": "gearbox_ratio"}.get(
            key, "rotor_radius")])[:2] in text


def test_the_deck_gbratio_of_50_against_97_names_both(deck):
    _set(deck / ED, "GBRatio", b"50")
    with pytest.raises(ConfigError) as exc:
        ofcase.check_deck_matches_turbine(deck / FST, NREL)
    assert str(exc.value) == (
        f"{deck / ED}: GBRatio = 50.0 is not allowed: the turbine's gearbox_ratio = 97 "
        f"within 0.5% (the turbine file {NREL.path}: the deck and the turbine file "
        "describe different turbines; correct one, or import the turbine from its deck: "
        "wtftc turbine import)")


@pytest.mark.parametrize("file, key, value", [
    (ED, "TipRad", b"63.3"), (ED, "TipRad", b"62.7"), (ED, "GBRatio", b"97.0D0"),
    (ED, "GBRatio", b"9.7e1"), (DISCON, "PC_RefSpd", b"123.4"),
    (SD, "DLL_InFile", b'"unused"'), (SD, "DLL_InFile", b'"no_such_discon.in"')])
def test_a_deck_within_the_tolerance_or_without_rosco_is_accepted(deck, file, key, value):
    """0.5 % (DISCON.IN rounds its rated speed); no ROSCO DISCON.IN: no rated speed to
    compare, the gearbox ratio and radius are."""
    _set(deck / file, key, value)
    ofcase.check_deck_matches_turbine(deck / FST, NREL)


def test_the_rated_speed_is_the_decks_controllers(deck):
    _set(deck / DISCON, "PC_RefSpd", b"100.0")
    with pytest.raises(ConfigError, match="omega_g_rated = 1.26711") as exc:
        ofcase.check_deck_matches_turbine(deck / FST, NREL)
    assert DISCON in str(exc.value) and "PC_RefSpd / GBRatio" in str(exc.value)


def test_the_runs_own_values_are_what_the_deck_is_checked_against(deck):
    """A run whose configuration sets its gearbox ratio is checked with that value."""
    with pytest.raises(ConfigError, match="gearbox_ratio = 50"):
        ofcase.check_deck_matches_turbine(deck / FST, NREL, lambda k: 50.0 if k ==
                                          "gearbox_ratio" else NREL.values[k])


def test_the_built_in_decks_match_their_turbine_files():
    from wtftc import config

    for name in ("nrel5mw", "iea15mw"):
        t = turbine_file.load(name)
        ofcase.check_deck_matches_turbine(config.openfast_deck(t), t)


# --------------------------------------------------- editing a copy names the user's file

def test_a_key_missing_in_a_copy_is_refused_naming_the_users_file(deck, tmp_path):
    _edit(deck / ED, b"TTDspFA", b"TTDspXX")
    fst = ofcase.copy_deck(deck / FST, tmp_path / "case")
    ed = ofcase.module_file(fst, "EDFile")
    with pytest.raises(ConfigError) as exc:
        ofcase.set_values(ed, {"TTDspFA": "0"})
    assert str(deck / ED) in str(exc.value) and "TTDspFA" in str(exc.value)
    with pytest.raises(ConfigError, match="TTDspFA"):
        ofcase.get_value(ed, "TTDspFA")


def _cr_only(d, t):
    (d / FST).write_bytes((d / FST).read_bytes().replace(b"\n", b"\r"))


def _empty(d, t):
    (d / FST).write_bytes(b"")


def _ed_is_main(d, t):
    _set(d / FST, "EDFile", b'"' + FST.encode() + b'"')


@pytest.mark.parametrize("mutate, key", [(_cr_only, "TMax"), (_empty, "TMax"),
                                         (_ed_is_main, "RotSpeed")],
                         ids=["CR line endings", "empty main file", "EDFile the main file"])
def test_a_deck_copied_but_not_editable_is_refused_naming_the_users_file(
        deck, tmp_path, mutate, key):
    """What only the edit finds (OpenFAST's keys not where OpenFAST 5 has them) is one line
    naming the user's file and the key, never the run's temporary copy."""
    mutate(deck, tmp_path)
    fst = ofcase.copy_deck(deck / FST, tmp_path / "case")
    with pytest.raises(ConfigError) as exc:
        if key == "TMax":
            ofcase.set_values(fst, {"TMax": "2", "DT": "0.005"})
        else:
            ofcase.set_values(ofcase.module_file(fst, "EDFile"), {"RotSpeed": "12"})
    text = str(exc.value)
    assert str(deck / FST) in text and key in text and str(tmp_path / "case") not in text


def test_a_quoted_name_with_spaces_is_edited_by_its_key(deck, tmp_path):
    """The engine names its own controller input in ServoDyn's DLL_InFile: a deck's
    quoted name with spaces there is one value, its key found after it."""
    _module_names_with_spaces(deck, tmp_path)
    fst = ofcase.copy_deck(deck / FST, tmp_path / "case")
    sd = ofcase.module_file(fst, "ServoFile")
    assert ofcase.get_value(sd, "DLL_InFile") == "my discon.in"
    ofcase.set_values(sd, {"DLL_InFile": '"wtftc_plant.in"', "DLL_DT": "0.01"})
    assert ofcase.get_value(sd, "DLL_InFile") == "wtftc_plant.in"
    assert ofcase.check_deck_matches_turbine(deck / FST, NREL) is None


def test_a_main_file_without_a_module_line_is_refused_where_it_is_edited(deck, tmp_path):
    _edit(deck / FST, b"ServoFile", b"ServoFyle")
    fst = ofcase.copy_deck(deck / FST, tmp_path / "case")
    with pytest.raises(ConfigError, match="ServoFile") as exc:
        ofcase.module_file(fst, "ServoFile")
    assert str(deck / FST) in str(exc.value)


def test_a_latin1_deck_is_read_by_the_turbine_import(deck):
    """openfast-io reads the deck's text as its user wrote it (a "°" in ElastoDyn)."""
    _latin1(ED)(deck, None)
    _latin1(BLADE)(deck, None)
    read = openfast_deck.read(deck / FST)
    assert read.ed["GBRatio"] == 97 and read.discon.name == DISCON


def test_a_binary_elastodyn_is_one_line_in_the_turbine_import(deck):
    _nul_in(ED)(deck, None)
    with pytest.raises(ConfigError, match="NUL") as exc:
        openfast_deck.read(deck / FST)
    assert exc.value.field == "EDFile" and exc.value.where == str(deck / FST)


# ------------------------------------------------------------ end to end: `wtftc run`

def _turbine_for(deck: Path, folder: Path) -> Path:
    """The built-in NREL 5-MW's turbine file with ``deck`` as its OpenFAST deck."""
    src = Path(NREL.path)
    text = src.read_text(encoding="utf-8").replace(
        'openfast_deck = "rosco:Examples/Test_Cases/NREL-5MW/NREL-5MW.fst"',
        f'openfast_deck = "{deck / FST}"')
    assert str(deck / FST) in text
    folder.mkdir(exist_ok=True)
    shutil.copy(Path(NREL.cp_path), folder / Path(NREL.cp_path).name)
    (folder / "t.toml").write_text(text, encoding="utf-8")
    return folder / "t.toml"


def _run(turbine: Path, out: Path, capsys) -> tuple[int, list[str]]:
    from wtftc.cli import main

    capsys.readouterr()
    with time_limit(300):
        code = main(["run", "--engine", "openfast", "--turbine", str(turbine), "--controller",
                     "rosco", "--profile", "realistic", "--wind", "constant", "--wind-mean",
                     "16", "--t-final", "2", "--fault", "none", "--quiet", "--out", str(out)])
    return code, capsys.readouterr().err.splitlines()


def _hostile_but_valid(d: Path, t: Path) -> None:
    """Every change a user's editor or file system may make that leaves the deck's
    meaning as it was."""
    _latin1(ED)(d, t)
    _crlf(ED)(d, t)
    _bom(AD)(d, t)
    _crlf(FST)(d, t)
    _latin1(DISCON)(d, t)
    _description_names(d, t)
    _title_names(d, t)
    _unrelated("huge")(d, t)
    os.mkfifo(d / "a_fifo")
    os.symlink("loop", d / "loop")


def test_a_deck_as_users_write_it_runs_as_rosco_s_does(deck, tmp_path, capsys):
    """The same 2-s run on ROSCO's deck and on the hostile but valid copy: OpenFAST ends
    normally on both with the same rotor speed at every step; the run folder holds the
    named files only (no 300-MB file, no file a comment names), Latin-1 kept."""
    from wtftc.openfast import engine

    plain = tmp_path / "plain"
    shutil.copytree(deck, plain)
    _hostile_but_valid(deck, tmp_path)
    before = _tree(deck)
    code, err = _run(_turbine_for(plain, tmp_path / "t1"), tmp_path / "out1", capsys)
    assert code == 0, err
    code, err = _run(_turbine_for(deck, tmp_path / "t2"), tmp_path / "out2", capsys)
    assert code == 0, err
    a, b = (engine.read_outb(tmp_path / o / "openfast" / "NREL-5MW.outb") for o in
            ("out1", "out2"))
    assert len(a["Time"]) > 100 and (a["RotSpeed"] == b["RotSpeed"]).all()
    case = tmp_path / "out2" / "openfast"
    names = _copied(case)
    assert not {"unrelated", "secret.txt", "a_fifo", "loop"} & names
    assert sum(p.stat().st_size for p in case.rglob("*") if p.is_file()) < 10_000_000
    assert b"\xb0 (degrees)" in (case / ED).read_bytes()
    assert _tree(deck) == before


@pytest.mark.parametrize("mutate, words", [
    (_binary_fst, ["binary", FST]), (_loop((FST, "EDFile")), ["symbolic link loop", "EDFile"]),
    (_nul_in(ED), ["NUL", ED])], ids=["binary main file", "loop as EDFile", "binary ED"])
def test_a_hostile_deck_is_one_line_and_exit_code_2_in_run(deck, tmp_path, capsys, mutate,
                                                           words):
    mutate(deck, tmp_path)
    out = tmp_path / "out"
    code, err = _run(_turbine_for(deck, tmp_path / "t"), out, capsys)
    assert code == 2 and len(err) == 1 and err[0].startswith("wtftc: error: "), err
    assert all(w in err[0] for w in words), err
    assert not out.exists() and not list(tmp_path.glob(".out*"))


def test_a_deck_gbratio_of_50_is_refused_before_openfast_runs(deck, tmp_path, capsys):
    """`wtftc run --engine openfast` on a deck whose GBRatio contradicts the turbine file:
    one line naming both values, exit 2, no --out (it ran to 0 W before)."""
    _set(deck / ED, "GBRatio", b"50")
    code, err = _run(_turbine_for(deck, tmp_path / "t"), tmp_path / "out", capsys)
    assert code == 2 and len(err) == 1 and "GBRatio = 50" in err[0]
    assert "gearbox_ratio = 97" in err[0] and not (tmp_path / "out").exists()


#: every command that runs OpenFAST on a turbine's deck, without --out and --turbine
OUT_IN_DECK = {
    "run": ["run", "--engine", "openfast", "--controller", "pi", "--t-final", "2"],
    "compare": ["compare", "--engine", "openfast", "--controllers", "pi", "--faults", "none",
                "--winds", "steady_16", "--t-final", "30"],
    "validate": ["validate", "--t-final", "10"],
    "modes": ["modes"],
    "sweep": ["sweep", "{sweep}", "--engine", "openfast"],
}


@pytest.mark.parametrize("command", list(OUT_IN_DECK))
def test_out_inside_the_deck_is_refused_by_every_command_before_anything_is_written(
        deck, tmp_path, capsys, command):
    """An --out inside the deck's own folder, on every command that runs OpenFAST: one
    line naming --out, exit 2, nothing written in the deck's folder (a run once copied the
    deck into itself there until the path was too long)."""
    from wtftc.cli import main

    turbine = _turbine_for(deck, tmp_path / "t")
    sweep = tmp_path / "s.toml"
    sweep.write_text(f'turbine = "{turbine}"\ncontrollers = ["pi"]\nt_final_s = 10.0\n')
    before = _tree(deck)
    argv = [a.replace("{sweep}", str(sweep)) for a in OUT_IN_DECK[command]]
    if command != "sweep":
        argv += ["--turbine", str(turbine)]
    capsys.readouterr()
    with time_limit(120):
        code = main([*argv, "--quiet", "--out", str(deck / "run")])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and "--out" in err[0], err
    assert _tree(deck) == before
