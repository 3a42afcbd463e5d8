"""`wtftc turbine import`: issue 30's defects 2 and 5, each by name, on ROSCO's NREL 5-MW
deck with one file changed (tests/nrel5mw_deck.py).

Defect 5: a malformed deck is refused in one line naming the file and key, the value and
what is allowed (exit 2, never a traceback, nothing written); values every other command
refuses are refused before anything is written; NaN fails the cross-checks; a key given
twice in DISCON.IN is refused with both lines; a refusal names the real culprit.
Defect 2: never into the package's data, never over a file without --overwrite, both
files or neither, validated before anything is written.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest
from nrel5mw_deck import FILES, SENTINEL, make_deck, originals, run_import, untouched, user_folder

from wtftc import config
from wtftc.model import turbine_file
from wtftc.model.cp_table import read_cp_table


def value(key: str, new: str):
    """Put ``new`` in place of the value of ``key``'s line (``value Key`` in OpenFAST
    files, ``value ! Key`` in DISCON.IN)."""
    pattern = re.compile(rf"^(\s*)\S+(\s+(?:!\s*)?{re.escape(key)}(?=[\s-]|$))", re.M)

    def edit(text: str) -> str:
        out, n = pattern.subn(rf"\g<1>{new}\g<2>", text, count=1)
        assert n == 1, key
        return out
    return edit


def chain(*edits):
    def edit(text: str) -> str:
        for e in edits:
            text = e(text)
        return text
    return edit


def zero_mode_shape(text: str) -> str:
    out, n = re.subn(r"^(\s*)\S+(\s+TwFAM1Sh\()", r"\g<1>0.0\g<2>", text, flags=re.M)
    assert n == 5
    return out


def blade_row(k: int, column: int, new: str):
    """The blade file's k-th station row with its ``column`` replaced."""
    def edit(text: str) -> str:
        lines = text.splitlines()
        start = next(i for i, ln in enumerate(lines) if "BMassDen" in ln and "BlFract" in ln)
        row = lines[start + 2 + k].split()
        row[column] = new
        lines[start + 2 + k] = "   ".join(row)
        return "\n".join(lines) + "\n"
    return edit


def cp_entry(new: str):
    """The Cp table with its first power coefficient replaced by ``new``."""
    def edit(text: str) -> str:
        lines = text.splitlines()
        k = next(i for i, ln in enumerate(lines) if ln.startswith("# Power coefficient"))
        k = next(i for i in range(k + 1, len(lines)) if lines[i].strip())
        row = lines[k].split()
        lines[k] = "   ".join([new, *row[1:]])
        return "\n".join(lines) + "\n"
    return edit


def lines(n: int):
    return lambda text: "\n".join(text.splitlines()[:n]) + "\n"


def without_end(text: str) -> str:
    return "\n".join(ln for ln in text.splitlines() if not ln.strip().startswith("END"))


def twice(key: str, new: str):
    return lambda text: text + f"{new}   ! {key} - given again\n"


ED, DISCON, BLADE, TOWER = "ed", "discon", "blade", "tower"
#: defect → (file, edit of its text (or {file: edit}), options, words the one line must
#: hold, words it must not hold). Before the fix each of these was a traceback, a hang, a
#: file written, or a refusal blaming another file or an option not given.
DEFECTS = {
    # --- defect 5: tracebacks
    "zero gearbox ratio (ZeroDivisionError)": ({ED: value("GBRatio", "0"),
                                                DISCON: value("WE_GearboxRatio", "0")}, None,
                                               [], [FILES["ed"], "GBRatio = 0.0", "> 0"], []),
    "negative tower height (math domain error)": (ED, value("TowerHt", "-10"), [],
                                                  [FILES["ed"], "TowerHt = -10.0",
                                                   "TowerBsHt"], []),
    "inverted tower (math domain error)": (ED, value("TowerBsHt", "100"), [],
                                           [FILES["ed"], "TowerHt = 87.6", "TowerBsHt = 100"],
                                           []),
    "non-numeric value (ValueError)": (ED, value("GBRatio", "ninety-seven"), [],
                                       [FILES["ed"], "GBRatio = 'ninety-seven'",
                                        "a number"], []),
    "non-numeric count (ValueError)": (ED, value("NumBl", "three"), [],
                                       [FILES["ed"], "NumBl = 'three'", "an integer",
                                        "line 45"], []),
    "empty file (IndexError)": (ED, lambda t: "", [], [FILES["ed"], "empty"], []),
    "truncated file (IndexError)": (ED, lines(60), [], [FILES["ed"], "line 61",
                                                        "ends early"], []),
    "truncated blade file (IndexError)": (BLADE, lines(30), [], [FILES["blade"], "line 31",
                                                                 "ends early"], []),
    "output list without END (a hang)": (ED, without_end, [], [FILES["ed"], "END"], []),
    "binary file (UnicodeDecodeError)": (ED, lambda t: b"\x7fELF\x02\x01\x01\xff\xfe" * 50,
                                         [], [FILES["fst"], "EDFile", "binary"], []),
    "station count of 10^10 (MemoryError)": (BLADE, value("NBlInpSt", "10000000000"), [],
                                             [FILES["blade"], "NBlInpSt", "100000"], []),
    # --- defect 5: files every other command then refused
    "negative PC_RefSpd": (DISCON, value("PC_RefSpd", "-122.9"), [],
                           [FILES["discon"], "PC_RefSpd = -122.9", "omega_g_rated", "> 0"],
                           []),
    "PC_MinPit > PC_MaxPit": (DISCON, chain(value("PC_MinPit", "0.5"),
                                            value("PC_MaxPit", "0.2")), [],
                              [FILES["discon"], "PC_MinPit, PC_MaxPit = (0.5, 0.2)",
                               "PC_MinPit < PC_MaxPit"], []),
    "VS_GenEff 150": (DISCON, value("VS_GenEff", "150"), [],
                      [FILES["discon"], "VS_GenEff = 150.0", "in percent, in (0, 100]"], []),
    "WE_RhoAir 0": (DISCON, value("WE_RhoAir", "0"), [],
                    [FILES["discon"], "WE_RhoAir = 0.0", "(0, 2]"], []),
    "DTTorSpr 0": (ED, value("DTTorSpr", "0"), [], [FILES["ed"], "DTTorSpr = 0.0", "k_s"], []),
    "zero tower mode shape": (TOWER, zero_mode_shape, [],
                              [FILES["tower"], "TwFAM1Sh(2:6)", "sum to 1"], []),
    "negative drivetrain damping": (ED, value("DTTorDmp", "-6215000"), [],
                                    [FILES["ed"], "DTTorDmp = -6215000.0", "d_s"], []),
    "negative tower damping": (TOWER, value("TwrFADmp(1)", "-1"), [],
                               [FILES["tower"], "TwrFADmp(1) = -1.0", "[0, 100]"], []),
    "negative HubIner": (ED, value("HubIner", "-115926"), [],
                         [FILES["ed"], "HubIner = -115926.0", ">= 0"], []),
    "Cp table with NaN": ("cp", cp_entry("nan"), [],
                          [FILES["cp"], "non-finite entry 'nan'"], []),
    # --- defect 5: NaN past the cross-checks, a key twice, the wrong culprit
    "WE_GearboxRatio nan": (DISCON, value("WE_GearboxRatio", "nan"), [],
                            [FILES["discon"], "WE_GearboxRatio = 'nan'", "finite"], []),
    "WE_BladeRadius nan": (DISCON, value("WE_BladeRadius", "NaN"), [],
                           [FILES["discon"], "WE_BladeRadius", "finite"], []),
    "a key twice in DISCON.IN": (DISCON, twice("PC_RefSpd", "100.0"), [],
                                 [FILES["discon"], "PC_RefSpd = '100.0'", "line 67",
                                  "line 248", "ROSCO reads the first"], []),
    "negative blade mass adjustment blamed on the blade file": (
        BLADE, value("AdjBlMs", "-1"), [], [FILES["blade"], "AdjBlMs = -1.0"], ["WE_Jtot"]),
    "negative blade mass density blamed on the blade file": (
        BLADE, blade_row(3, 2, "-100"), [], [FILES["blade"], "BMassDen[4] = -100.0"],
        ["WE_Jtot"]),
    "NaN blade mass density blamed on the blade file": (
        BLADE, blade_row(0, 2, "nan"), [], [FILES["blade"], "BMassDen[1] = nan"], ["WE_Jtot"]),
    "bad DLL_InFile blamed on ServoDyn, not --rosco": (
        "sd", value("DLL_InFile", '"no_such_DISCON.IN"'), [],
        [FILES["sd"], "DLL_InFile", "no_such_DISCON.IN"], ["--rosco"]),
    # --- defect 2: refused only after the files existed
    "DTTorDmp nan": (ED, value("DTTorDmp", "nan"), [], [FILES["ed"], "DTTorDmp = nan",
                                                        "finite"], []),
    "DTTorSpr inf": (ED, value("DTTorSpr", "inf"), [], [FILES["ed"], "DTTorSpr = inf",
                                                        "finite"], []),
    "PC_RefSpd 1e400": (DISCON, value("PC_RefSpd", "1e400"), [],
                        [FILES["discon"], "PC_RefSpd = '1e400'", "finite"], []),
    "empty --name": (None, None, ["--name", ""], ["--name = ''"], []),
    "emoji --name": (None, None, ["--name", "\U0001f600"], ["--name = '\U0001f600'"], []),
    "blank --title": (None, None, ["--title", " "], ["--title = ' '"], []),
}


@pytest.mark.parametrize("defect", list(DEFECTS))
def test_a_named_defect_is_refused_in_one_line_and_nothing_is_written(defect, tmp_path,
                                                                       capsys):
    which, edit, options, words, absent = DEFECTS[defect]
    edits = which if isinstance(which, dict) else {which: edit} if which else {}
    changed = {}
    for key, e in edits.items():
        new = e(originals()[key].decode())
        changed[key] = new if isinstance(new, bytes) else new.encode()
    fst = make_deck(tmp_path / "deck", changed)
    deck_before = sorted(os.listdir(tmp_path / "deck"))
    out = tmp_path / "out"
    snap = user_folder(out)
    argv = ["--openfast", str(fst), "--name", "mine", "--out", str(out / "mine.toml")]
    code, err = run_import([*argv, *options], capsys)
    assert code == 2 and len(err) == 1 and err[0].startswith("wtftc: error: "), err
    for w in words:
        assert w in err[0], (w, err[0])
    for w in absent:
        assert w not in err[0], (w, err[0])
    assert sorted(os.listdir(out)) == [SENTINEL] and not untouched(out, snap)
    assert sorted(os.listdir(tmp_path / "deck")) == deck_before


@pytest.mark.parametrize("kind", ["fifo", "folder", "dev_zero"])
@pytest.mark.parametrize("which,key", [("ed", "EDFile"), ("blade", "BldFile(1)"),
                                       ("tower", "TwrFile"), ("sd", "ServoFile"),
                                       ("discon", "DLL_InFile"), ("cp", "PerfFileName")])
def test_a_special_file_in_the_deck_is_refused_unread(which, key, kind, tmp_path, capsys):
    """A FIFO, a folder or /dev/zero where the deck names a file: refused in one line
    naming the key and the file that names it, before a byte is read (a FIFO would block,
    /dev/zero never end)."""
    fst = make_deck(tmp_path / "deck")
    target = fst.parent / FILES[which]
    target.unlink()
    if kind == "fifo":
        os.mkfifo(target)
    elif kind == "folder":
        target.mkdir()
    else:
        target.symlink_to("/dev/zero")
    out = tmp_path / "out"
    snap = user_folder(out)
    code, err = run_import(["--openfast", str(fst), "--name", "mine", "--out",
                            str(out / "mine.toml")], capsys, seconds=10)
    assert code == 2 and len(err) == 1, err
    assert f"{key} = " in err[0] and "regular file" in err[0], err[0]
    assert sorted(os.listdir(out)) == [SENTINEL] and not untouched(out, snap)


def test_a_bad_rosco_option_is_blamed_on_the_option(tmp_path, capsys):
    fst = make_deck(tmp_path / "deck")
    code, err = run_import(["--openfast", str(fst), "--rosco", str(tmp_path / "nope.IN"),
                            "--name", "x", "--out", str(tmp_path / "out" / "x.toml")], capsys)
    assert code == 2 and len(err) == 1 and "--rosco = " in err[0] and "nope.IN" in err[0]
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------------- defect 2

def _import(fst: Path, out: Path, capsys, *options: str) -> tuple[int, list[str]]:
    return run_import(["--openfast", str(fst), "--name", out.stem, "--out", str(out),
                       *options], capsys)


def test_an_import_writes_a_file_every_command_accepts(tmp_path, capsys):
    """The unchanged deck: both files written, the turbine file read by every command's
    reader and accepted by a run's configuration, the table the deck's byte for byte."""
    fst = make_deck(tmp_path / "deck")
    out = tmp_path / "out"
    snap = user_folder(out)
    code, err = _import(fst, out / "n5.toml", capsys)
    assert code == 0, err
    assert sorted(os.listdir(out)) == sorted([SENTINEL, "n5.toml", FILES["cp"]])
    t = turbine_file.read(out / "n5.toml")
    assert Path(t.cp_path).read_bytes() == originals()["cp"]
    rc = config.make_config({"turbine": str(out / "n5.toml"), "controller": "pi"})
    assert np.array_equal(rc.p_turbine, t.vector()) and not untouched(out, snap)
    assert read_cp_table(t.cp_path).cp.shape == (26, 36)


def test_a_cp_table_of_the_same_name_is_never_replaced_silently(tmp_path, capsys):
    """Issue 30: importing a second turbine into the same folder replaced the first one's
    table. A table of the same name with other bytes is refused (exit 2, nothing
    written) unless --overwrite; one with the same bytes is shared, untouched."""
    out = tmp_path / "out"
    snap = user_folder(out)
    first = make_deck(tmp_path / "a")
    assert _import(first, out / "a.toml", capsys)[0] == 0
    table = out / FILES["cp"]
    kept = (table.read_bytes(), table.stat().st_mtime_ns)
    assert _import(first, out / "b.toml", capsys)[0] == 0  # the same table: shared
    assert (table.read_bytes(), table.stat().st_mtime_ns) == kept
    other = cp_entry("0.0001")(originals()["cp"].decode()).encode()
    assert other != originals()["cp"]
    second = make_deck(tmp_path / "c", {"cp": other})
    # another turbine's table is never replaced, --overwrite or not (the review reached
    # the original defect through the --overwrite an earlier message recommended)
    for extra in ((), ("--overwrite",)):
        code, err = _import(second, out / "c.toml", capsys, *extra)
        assert code == 2 and len(err) == 1 and FILES["cp"] in err[0], err
        assert "a.toml, b.toml uses the one there" in err[0] and "another folder" in err[0]
        assert (table.read_bytes(), table.stat().st_mtime_ns) == kept
        assert sorted(os.listdir(out)) == sorted([SENTINEL, "a.toml", "b.toml", FILES["cp"]])
    # a turbine's own table, used by no other file, is replaced with --overwrite only
    solo = tmp_path / "solo"
    assert _import(first, solo / "a.toml", capsys)[0] == 0
    code, err = _import(second, solo / "a.toml", capsys)
    assert code == 2 and "--overwrite" in err[0]
    assert _import(second, solo / "a.toml", capsys, "--overwrite")[0] == 0
    assert (solo / FILES["cp"]).read_bytes() == other
    assert not untouched(out, snap)


def test_an_existing_turbine_file_is_replaced_only_with_overwrite(tmp_path, capsys):
    fst = make_deck(tmp_path / "deck")
    out = tmp_path / "out"
    user_folder(out)
    (out / "mine.toml").write_text("# my own turbine file\n")
    code, err = _import(fst, out / "mine.toml", capsys)
    assert code == 2 and len(err) == 1 and "--out = " in err[0] and "--overwrite" in err[0]
    assert (out / "mine.toml").read_text() == "# my own turbine file\n"
    assert not (out / FILES["cp"]).exists()
    code, err = _import(fst, out / "mine.toml", capsys, "--overwrite")
    assert code == 0, err
    assert turbine_file.read(out / "mine.toml").name == "mine"


def _package_data() -> dict:
    data = Path(turbine_file.__file__).resolve().parent.parent / "data"
    return {p.name: p.read_bytes() for p in sorted(data.iterdir()) if p.is_file()}


@pytest.mark.parametrize("where", ["data/new.toml", "data/nrel5mw.toml", "new.toml",
                                   "link/new.toml"])
def test_never_into_the_installed_package(where, tmp_path, capsys):
    """Issue 30: `--out` inside wtftc/data replaced the built-in NREL 5-MW table, and the
    next default run used it. Refused anywhere inside the package, with --overwrite too,
    also through a symbolic link; the package's data unchanged."""
    package = Path(turbine_file.__file__).resolve().parent.parent
    (tmp_path / "link").symlink_to(package / "data")
    out = (tmp_path if where.startswith("link") else package) / where
    before = _package_data()
    code, err = _import(make_deck(tmp_path / "deck"), out, capsys, "--overwrite")
    assert code == 2 and len(err) == 1 and "outside the installed wtftc package" in err[0]
    assert _package_data() == before and not (package / "new.toml").exists()


def test_both_files_or_neither(tmp_path, capsys, monkeypatch):
    """A failure while the two files are put in place (here the second rename) leaves
    neither: the folder holds the user's files only."""
    fst = make_deck(tmp_path / "deck")
    out = tmp_path / "out"
    snap = user_folder(out)
    real, calls = os.replace, []

    def flaky(src, dst, *args, **kwargs):
        calls.append(dst)
        if len([c for c in calls if not str(c).endswith(".old")]) == 2 \
                and Path(dst).parent == out:
            raise OSError(28, "No space left on device", str(dst))
        return real(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", flaky)
    code, err = _import(fst, out / "mine.toml", capsys)
    monkeypatch.undo()
    assert code == 2 and len(err) == 1 and "No space left" in err[0], err
    assert sorted(os.listdir(out)) == [SENTINEL] and not untouched(out, snap)


def test_the_checks_come_before_the_folder(tmp_path, capsys):
    """A refused import does not even create --out's folder."""
    fst = make_deck(tmp_path / "deck", {"ed": value("GBRatio", "0")(
        originals()["ed"].decode()).encode()})
    code, _ = _import(fst, tmp_path / "new" / "sub" / "x.toml", capsys)
    assert code == 2 and not (tmp_path / "new").exists()
