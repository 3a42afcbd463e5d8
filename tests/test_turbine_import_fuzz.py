"""Fuzzing `wtftc turbine import` and turbine files (issue 30), deterministic seeds.

ROSCO's NREL 5-MW deck (tests/nrel5mw_deck.py) is read once; each case changes one of its
files in memory (a value replaced by an edge or garbage, a line deleted, doubled or
swapped, the file cut short, bytes that are not text, a file name pointing at nothing, a
folder, a FIFO or /dev/zero, a DISCON.IN key doubled or lost) and runs the import
in-process (``wtftc.cli.main``) into a folder that already holds a user's file, and in
some cases a Cp table of the same name (the same bytes, or other bytes) or a turbine file
at --out's name. Whatever the mutation:

* exit 0, both files written, the turbine file read by every command's reader, its
  values inside the run's ranges and its Cp table readable; or exit 2 with one line on
  stderr and nothing written;
* never a traceback, never a hang (each case has 20 s);
* no file that was there before is touched (bytes and mtime), at --out or in the deck.

Then turbine files, mutated as text, through the reader every command uses
(``turbine_file.read``): a Turbine or a one-line ConfigError, never another exception.
About 940 cases in all.
"""

from __future__ import annotations

import os
import random
import re
import shutil
from pathlib import Path

import pytest
from nrel5mw_deck import (
    FILES,
    make_deck,
    originals,
    run_import,
    time_limit,
    untouched,
    user_folder,
)

from wtftc import config
from wtftc.errors import ConfigError
from wtftc.model import turbine_file
from wtftc.model.cp_table import read_cp_table

#: what a mutation puts where a value was: edges of numbers and things that are not one
EDGES = ["0", "-0", "-1", "1", "2", "3", "4", "-1e-12", "1e-300", "1e300", "1e400", "-1e400",
         "nan", "NaN", "inf", "-inf", "1e9", "99999999999", "100001", "abc", '"x"', "1,5",
         "0x1A", "True", "false", "1e", "--", ".", "1.5", "-90", "91", "1e-9", "default",
         '"unused"', "\u00bd", "1_000"]
#: what a file name may become
NAMES = ['"missing.dat"', '"."', '".."', '"/"', '"/dev/zero"', '"pipe"', '""', "unused",
         '"sub"', '"NREL-5MW.fst"', '"DISCON.IN"', '"../x/y.dat"', '"a b.dat"']
VALUE_LINE = re.compile(r"^(\s*)(\S+)(\s+\S)")


def _numeric(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _value(rng: random.Random, lines: list[str]) -> str:
    """A line's first word (its value) replaced: an edge, or the number scaled."""
    idx = [i for i, ln in enumerate(lines) if VALUE_LINE.match(ln)]
    i = rng.choice(idx)
    m = VALUE_LINE.match(lines[i])
    old = m[2]
    if _numeric(old) and rng.random() < 0.35:
        new = repr(float(old) * rng.choice([-1.0, 0.0, 1e-6, 0.5, 1.001, 2.0, 1e6]))
    else:
        new = rng.choice(EDGES)
    lines[i] = m[1] + new + lines[i][m.end(2):]
    return f"line {i + 1}: {old} -> {new}"


def _row(rng: random.Random, lines: list[str]) -> str:
    """One entry of a table row (a line of numbers only) replaced."""
    idx = [i for i, ln in enumerate(lines) if len(ln.split()) >= 3
           and all(_numeric(t) for t in ln.split())]
    if not idx:
        return _value(rng, lines)
    i = rng.choice(idx)
    row = lines[i].split()
    j = rng.randrange(len(row))
    old, row[j] = row[j], rng.choice(EDGES[:20] + ["-" + row[j], "1e-3"])
    lines[i] = "   ".join(row)
    return f"line {i + 1} column {j + 1}: {old} -> {row[j]}"


def _name(rng: random.Random, lines: list[str]) -> str:
    """A quoted file name replaced by a missing file, a folder, a FIFO, /dev/zero..."""
    idx = [i for i, ln in enumerate(lines) if ln.lstrip().startswith(('"', "'"))]
    if not idx:
        return _value(rng, lines)
    i = rng.choice(idx)
    m = re.match(r"^(\s*)(\S+)", lines[i])
    new = rng.choice(NAMES)
    lines[i] = m[1] + new + lines[i][m.end(2):]
    return f"line {i + 1}: {m[2]} -> {new}"


def _lines(rng: random.Random, lines: list[str]) -> str:
    """A line deleted, doubled, swapped with the next, blanked, or an END line dropped."""
    i = rng.randrange(len(lines))
    how = rng.choice(["delete", "double", "swap", "blank", "insert", "end"])
    if how == "delete":
        del lines[i]
    elif how == "double":
        lines.insert(i, lines[i])
    elif how == "swap" and i + 1 < len(lines):
        lines[i], lines[i + 1] = lines[i + 1], lines[i]
    elif how == "blank":
        lines[i] = ""
    elif how == "insert":
        lines.insert(i, rng.choice(["0", "x y z", "! a comment", "END", "---- x ----"]))
    else:
        ends = [k for k, ln in enumerate(lines) if ln.strip().startswith("END")]
        if ends:
            del lines[rng.choice(ends)]
    return f"{how} line {i + 1}"


def _whole(rng: random.Random, data: bytes) -> tuple[str, bytes]:
    """The file as bytes: cut short, emptied, binary bytes or a NUL put in, CRLF, BOM."""
    how = rng.choice(["cut", "cut", "empty", "binary", "nul", "crlf", "bom", "latin1",
                      "repeat"])
    k = rng.randrange(len(data) + 1)
    out = {"cut": data[:k], "empty": b"",
           "binary": data[:k] + bytes(rng.randrange(256) for _ in range(16)) + data[k:],
           "nul": data[:k] + b"\0" + data[k:], "crlf": data.replace(b"\n", b"\r\n"),
           "bom": b"\xef\xbb\xbf" + data, "latin1": data[:k] + b"\xe9" + data[k:],
           "repeat": data + data}[how]
    return f"{how} at byte {k}", out


def _discon(rng: random.Random, lines: list[str]) -> str:
    """A DISCON.IN key the import reads: its value changed, its line doubled (the same
    value or another), deleted, its key misspelt, or its '!' lost."""
    keys = ("PC_RefSpd", "VS_RtTq", "VS_RtPwr", "VS_GenEff", "PC_MinPit", "PC_MaxPit",
            "PC_MaxRat", "WE_RhoAir", "VS_MinOMSpd", "VS_Rgn2K", "VS_MaxTq",
            "WE_GearboxRatio", "WE_BladeRadius", "WE_Jtot", "PerfFileName")
    key = rng.choice(keys)
    i = next(k for k, ln in enumerate(lines) if re.search(rf"!\s*{key}\b", ln))
    value, rest = lines[i].split("!", 1)
    how = rng.choice(["value", "value", "value", "double", "double", "delete", "typo",
                      "bang"])
    if how == "value":
        new = rng.choice(EDGES + NAMES) if key == "PerfFileName" else rng.choice(EDGES)
        lines[i] = f"{new}   !{rest}"
    elif how == "double":
        lines.insert(rng.randrange(len(lines)), rng.choice([lines[i], f"1.0   !{rest}"]))
    elif how == "delete":
        del lines[i]
    elif how == "typo":
        lines[i] = lines[i].replace(key, key.lower(), 1)
    else:
        lines[i] = lines[i].replace("!", " ", 1)
    return f"{key}: {how}"


def mutate(rng: random.Random, which: str) -> tuple[str, bytes]:
    """One mutation of the deck's file ``which``: (what was done, the new bytes)."""
    data = originals()[which]
    if rng.random() < 0.18:
        return _whole(rng, data)
    lines = data.decode().splitlines()
    if which == "discon":
        op = rng.choice([_discon, _discon, _discon, _value, _lines, _name])
    elif which == "cp":
        op = rng.choice([_row, _row, _lines])
    else:
        op = rng.choice([_value, _value, _value, _row, _lines, _lines, _name])
    what = op(rng, lines)
    return what, ("\n".join(lines) + "\n").encode()


#: file → cases: every file the import reads (about 640 imports)
DECK_CASES = {"ed": 150, "blade": 70, "tower": 70, "fst": 50, "sd": 50, "discon": 190,
              "cp": 60}
#: what --out's folder holds besides the sentinel, by case number mod 8 (mostly nothing
#: else, so that most cases reach the end of the import)
OUT_STATES = ("sentinel",) * 4 + ("same table",) * 2 + ("other table", "turbine file")


def _out_folder(folder: Path, state: str) -> dict:
    extra = {"same table": {FILES["cp"]: originals()["cp"]},
             "other table": {FILES["cp"]: b"# a user's own table of the same name\n"},
             "turbine file": {"mine.toml": b"# a user's own turbine file\n"}}
    return user_folder(folder, extra.get(state))


def _check_written(out: Path) -> None:
    """An accepted import: the file every command reads, its table readable, and a run
    on it configured (`wtftc run --turbine FILE`'s checks: ranges, envelope)."""
    t = turbine_file.read(out / "mine.toml")
    read_cp_table(t.cp_path)
    config.make_config({"turbine": str(out / "mine.toml")})


@pytest.mark.parametrize("which", list(DECK_CASES))
def test_mutated_decks_are_imported_or_refused_cleanly(which, tmp_path, capsys):
    base = tmp_path / "base"
    make_deck(base)
    os.mkfifo(base / "pipe")
    (base / "sub").mkdir()
    rng = random.Random(f"turbine-import-{which}")
    outcomes = {0: 0, 2: 0}
    for case in range(DECK_CASES[which]):
        what, data = mutate(rng, which)
        deck = tmp_path / f"c{case}"
        fst = make_deck(deck, {which: data}, base=base)
        os.mkfifo(deck / "pipe")
        (deck / "sub").mkdir()
        before = {p.name: (p.stat().st_size, p.stat().st_mtime_ns) for p in deck.iterdir()
                  if p.is_file()}
        out = deck / "out"
        state = OUT_STATES[case % len(OUT_STATES)]
        snap = _out_folder(out, state)
        label = f"{which} case {case} ({what}; --out holds {state})"
        try:
            code, err = run_import(["--openfast", str(fst), "--name", "mine", "--out",
                                    str(out / "mine.toml")], capsys)
        except BaseException as exc:  # a traceback or a hang: the failure, with the case
            pytest.fail(f"{label}: {type(exc).__name__}: {exc}")
        assert not untouched(out, snap), label
        assert {p.name: (p.stat().st_size, p.stat().st_mtime_ns) for p in deck.iterdir()
                if p.is_file()} == before, label
        written = sorted(set(os.listdir(out)) - set(snap))
        if code == 0:
            assert state != "turbine file", label
            assert "mine.toml" in written and len(written) <= 2, (label, written)
            _check_written(out)
        else:
            assert code == 2 and len(err) == 1 and err[0].startswith("wtftc: error: "), \
                (label, err)
            assert written == [], (label, written, err)
        outcomes[code] += 1
        shutil.rmtree(deck)
    assert outcomes[0] > 0 and outcomes[2] > 0, outcomes  # both paths taken


# ---------------------------------------------------------------------- turbine files

TOML_EDGES = ["nan", "inf", "-inf", "1e400", "1" + "0" * 400, "-1.0", "0", "0.0", "1e-320",
              '"1.0"', "true", "[1.0]", "{ a = 1 }", "0x10", "1_000.5", "+2.5", "2024-01-01",
              '""', "-0.0", "9" * 30]
STRINGS = ['""', "1", "true", '"\\u0000"', '"/dev/zero"', '"."', '"nope.txt"',
           '"' + "x" * 5000 + '"', '"Cp_Ct_Cq.NREL5MW.txt"', "[]", '"\\ud800"', '"😀"']


def _toml(rng: random.Random, text: str) -> tuple[str, str]:
    """One mutation of a turbine file's text."""
    lines = text.splitlines()
    how = rng.choice(["value", "value", "value", "unit", "string", "delete", "double",
                      "swap", "cut", "nest", "extra", "table"])
    params = [i for i, ln in enumerate(lines) if "{ value = " in ln]
    i = rng.choice(params)
    if how == "value":
        lines[i] = re.sub(r"value = [^,]+", "value = " + rng.choice(TOML_EDGES), lines[i])
    elif how == "unit":
        lines[i] = re.sub(r'unit = "[^"]*"', rng.choice(['unit = "kg"', "unit = 1",
                                                         'unit = ""']), lines[i])
    elif how == "string":
        key = rng.choice(["name", "title", "cp_table", "rosco_discon"])
        k = next((j for j, ln in enumerate(lines) if ln.startswith(f"{key} =")), 0)
        lines[k] = f"{key} = {rng.choice(STRINGS)}"
    elif how == "delete":
        del lines[rng.randrange(len(lines))]
    elif how == "double":
        lines.insert(i, lines[i])
    elif how == "swap":
        k = rng.randrange(len(lines) - 1)
        lines[k], lines[k + 1] = lines[k + 1], lines[k]
    elif how == "cut":
        text = text[:rng.randrange(len(text))]
        return how, text
    elif how == "nest":
        lines.insert(0, "deep = " + "[" * 3000 + "]" * 3000)
    elif how == "extra":
        lines.insert(rng.randrange(len(lines)), rng.choice([
            "rosco_tuning = { omega_pc_rad_s = 0.6, zeta_pc = 1e400 }",
            "rosco_tuning = { omega_pc_rad_s = 0.6 }", "rosco_tuning = 5",
            "cut_in_wind_mps = -3.0", 'cut_in_wind_mps = "3"', "cut_in_wind_mps = nan",
            'J_x = { value = 1.0, unit = "-" }', "[params.J_r]", "params = 3"]))
    else:
        lines = [ln.replace("[params]", rng.choice(["[[params]]", "[param]", "[params.x]"]))
                 for ln in lines]
    return f"{how} at line {i + 1}", "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def turbine_texts(tmp_path_factory) -> list[str]:
    """The NREL 5-MW deck's turbine file as the import writes it (its Cp table beside it),
    and the shipped IEA 15-MW's (its Cp table named by absolute path)."""
    from wtftc.model import turbine_import

    fst = make_deck(tmp_path_factory.mktemp("imported") / "deck")
    imported = turbine_import.import_turbine(fst)
    nrel = turbine_import.render(imported, "n5", "NREL 5-MW, imported")
    iea = turbine_file.path_of("iea15mw")
    iea_text = iea.read_text().replace('cp_table = "', f'cp_table = "{iea.parent}/')
    return [nrel, iea_text]


def test_mutated_turbine_files_are_read_or_refused_in_one_line(turbine_texts, tmp_path):
    """300 mutated turbine files through every command's reader: a Turbine (whose values
    the run then checks, in one line too) or a ConfigError in one line naming the file."""
    rng = random.Random("turbine-file")
    folder = tmp_path / "t"
    snap = user_folder(folder, {FILES["cp"]: originals()["cp"]})
    outcomes = {"read": 0, "refused": 0}
    for case in range(300):
        what, text = _toml(rng, turbine_texts[case % 2])
        path = folder / f"case{case}.toml"
        path.write_bytes(text.encode("utf-8", "surrogatepass"))
        label = f"turbine file case {case} ({what})"
        try:
            with time_limit(10):
                t = turbine_file.read(path)
                config.check_turbine(t.vector())
            outcomes["read"] += 1
        except ConfigError as exc:
            assert "\n" not in str(exc) and exc.where in (str(path), None), (label, exc)
            outcomes["refused"] += 1
        except BaseException as exc:
            pytest.fail(f"{label}: {type(exc).__name__}: {exc}")
        path.unlink()
    assert not untouched(folder, snap)
    assert outcomes["read"] > 0 and outcomes["refused"] > 0, outcomes
