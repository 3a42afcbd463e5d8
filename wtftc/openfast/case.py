"""An OpenFAST case written from a run's configuration (issue 32; ours).

The turbine's deck (its ``openfast_deck``) is copied into the run folder's ``openfast/``,
with every file it names wherever that lives (its names rewritten to the copies), and
edited there, so that a user can rerun it by hand (``openfast <name>.fst`` in that
folder):

* the main file: TMax, DT (DLL_DT a whole multiple of it), binary output at every step,
  and no substructure (the tower clamped at its base, as wtftc's tower plant is);
* ElastoDyn: the initial rotor speed, blade pitch and tower-top fore-aft displacement of
  the run's operating point (issue 31), and the output channels the metrics need;
* InflowWind: the run's wind as a uniform wind file (WindType 2), the same series
  wtftc's own plant gets: hub-height or rotor-effective, uniform over the rotor, no shear;
* ServoDyn: ``libwtftc_plant.so`` (wtftc.openfast.plant_library) as its DISCON library,
  which calls the run's controller library through wtftc's pitch actuator and sensors.

An OpenFAST input line is ``value  Key  - description``; a key is edited by its value
only, the rest of its line kept.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import stat
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wtftc.errors import ConfigError, EngineError
from wtftc.files import MAX_INPUT_BYTES, check_user_file, read_user_bytes

#: ElastoDyn's output channels the results read (its OutList is replaced by these);
#: AeroDyn's, InflowWind's and ServoDyn's lists of the deck are kept
ELASTODYN_CHANNELS = ("BldPitch1", "BldPitch2", "BldPitch3", "RotSpeed", "GenSpeed",
                      "TTDspFA", "RotTorq", "TwrBsMyt", "RotThrust")
#: the channels read from the other modules' lists (the decks of ROSCO's examples have them)
OTHER_CHANNELS = ("Wind1VelX", "GenPwr", "GenTq")
#: the wind file's sample interval [s] (InflowWind interpolates linearly between rows)
WIND_DT = 0.02
#: OpenFAST's largest step [s] (the NREL 5-MW deck's 0.00625 rounded down to divide the
#: 0.01-s and 0.005-s control intervals)
MAX_DT = 0.005


def _value_line(line: str, value: str) -> str:
    """``line`` with its value (first word) replaced by ``value``."""
    words = line.split()
    key = words[1]
    return f"{value:>14}   {key}{line[line.index(key, len(words[0])) + len(key):]}"


def set_values(path: Path, values: dict[str, str]) -> None:
    """Each ``Key`` of ``values`` given its value, in the file at ``path``; a key missing
    or given twice is refused naming the file."""
    lines = path.read_text().split("\n")
    seen = dict.fromkeys(values, 0)
    for i, line in enumerate(lines):
        words = line.split()
        if len(words) >= 2 and words[1] in values:
            lines[i] = _value_line(line, values[words[1]])
            seen[words[1]] += 1
    wrong = [k for k, n in seen.items() if n != 1]
    if wrong:
        raise EngineError(f"{path}: the key(s) {', '.join(wrong)} not found once (an "
                          "OpenFAST 5.0 input file has each on one line)")
    path.write_text("\n".join(lines))


def get_value(path: Path, key: str) -> str:
    """The value (first word, quotes removed) of ``Key`` in the file at ``path``."""
    for line in path.read_text().split("\n"):
        words = line.split()
        if len(words) >= 2 and words[1] == key:
            return words[0].strip('"')
    raise EngineError(f"{path}: no {key} line")


def set_outlist(path: Path, channels: tuple[str, ...]) -> None:
    """ElastoDyn's OutList replaced by ``channels``."""
    lines = path.read_text().split("\n")
    start = next((i for i, ln in enumerate(lines) if ln.split()[:1] == ["OutList"]
                  or (len(ln.split()) > 1 and ln.split()[1] == "OutList")), None)
    end = next((i for i in range(start + 1 if start is not None else 0, len(lines))
                if lines[i].strip().upper().startswith("END")), None)
    if start is None or end is None:
        raise EngineError(f"{path}: no OutList ... END block")
    lines[start + 1:end] = [f'"{c}"' for c in channels]
    path.write_text("\n".join(lines))


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


def check_deck_folder(deck: Path) -> None:
    """The deck's folder holds only regular files and folders (a symlink is followed only
    when it stays inside the folder): a FIFO, a device, a socket, a dangling symlink or
    one pointing outside is refused in one line before anything is copied (copying a FIFO
    blocks; a link outside would copy what the deck does not hold)."""
    root = deck.resolve()
    for here, dirs, files in os.walk(deck):
        for name in dirs + files:
            entry = Path(here) / name
            st = entry.lstat()
            if stat.S_ISLNK(st.st_mode):
                target = entry.resolve()
                if not target.exists() or not target.is_relative_to(root):
                    raise ConfigError("openfast_deck", str(entry), "a deck folder of "
                                      "regular files (a symlink pointing outside it, or "
                                      "to nothing, is refused)")
                st = target.stat()
            if not (stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode)):
                raise ConfigError("openfast_deck", str(entry), "a deck folder of regular "
                                  "files (a FIFO, device or socket is refused)")


def _tokens(line: str) -> list[tuple[int, int, str]]:
    """The words of ``line`` that may name a file: each quoted string (start, end of its
    text, the text), and the first word when unquoted (an ``@`` include prefix dropped)."""
    out = [(m.start(1), m.end(1), m.group(1)) for m in re.finditer(r'"([^"]*)"', line)]
    first = re.match(r"\s*@?([^\s\"!@]+)", line)
    if first and not any(a <= first.start(1) < b + 1 for a, b, _ in out):
        out.append((first.start(1), first.end(1), first.group(1)))
    return sorted(out)


def references(path: Path, text: str) -> list[tuple[int, int, int, Path]]:
    """Every file ``text`` (the file at ``path``) names, as OpenFAST resolves it (a
    relative path against the naming file's folder): (line, start, end, the file). A name
    that is no file ("default", a channel name) is not one; one naming a FIFO, a device
    or a socket is refused."""
    found = []
    for i, line in enumerate(text.split("\n")):
        for a, b, word in _tokens(line):
            if not word or word.lower() in ("none", "unused", "default"):
                continue
            try:
                target = (path.parent / word).resolve()
                st = target.stat()
            except (OSError, ValueError):
                continue
            if stat.S_ISDIR(st.st_mode):
                continue
            check_user_file(target, "openfast_deck", MAX_INPUT_BYTES)
            found.append((i, a, b, target))
    return found


def _deck_files(fst: Path) -> dict[Path, tuple[bytes, list]]:
    """Every file the main file names, and those they name, to the end: each file's bytes
    and its references (a binary file, a wind field or a library, is not read for
    names)."""
    files: dict[Path, tuple[bytes, list]] = {}
    todo = [fst.resolve()]
    while todo:
        path = todo.pop()
        if path in files:
            continue
        data = read_user_bytes(path, "openfast_deck", MAX_INPUT_BYTES)
        refs = [] if b"\0" in data else references(path, data.decode("latin-1"))
        files[path] = (data, refs)
        todo += [r[3] for r in refs]
    return files


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
    fst = fst.resolve()
    deck = deck.resolve()
    taken = {p.name for p in deck.iterdir()}
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


def copy_deck(fst: Path, folder: Path) -> Path:
    """The deck copied into ``folder``, so that it runs from there: its folder (regular
    files only: :func:`check_deck_folder`), and every file its files name wherever it
    lives (``../`` of another example, an absolute path), each name rewritten to the
    copy's relative path (:func:`_destinations`); the copied main file."""
    if not fst.is_file():
        raise ConfigError("openfast_deck", str(fst), "an OpenFAST main input file (.fst) "
                          "that exists")
    check_deck_folder(fst.parent)
    files = _deck_files(fst)
    folder = Path(folder).resolve()
    shutil.copytree(fst.parent, folder, dirs_exist_ok=True,
                    ignore=shutil.ignore_patterns("*.outb", "*.out", "*.sum", "*.ech",
                                                  "*.dbg*", "__pycache__"))
    dest = _destinations(fst, files, fst.parent, folder)
    for path, (data, refs) in files.items():
        out = dest[path]
        out.parent.mkdir(parents=True, exist_ok=True)
        if not refs:
            out.write_bytes(data)
            continue
        lines = data.decode("latin-1").split("\n")
        for i, a, b, target in sorted(refs, key=lambda r: (r[0], -r[1])):
            new = Path(os.path.relpath(dest[target], out.parent)).as_posix()
            lines[i] = lines[i][:a] + new + lines[i][b:]
        out.write_bytes("\n".join(lines).encode("latin-1"))
    return dest[fst.resolve()]


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
    if any(ln.split()[1:2] == ["BldNd_BladesOut"] for ln in path.read_text().split("\n")):
        set_values(path, {"BldNd_BladesOut": "0"})


def clamp_fixed_bottom(fst: Path, ed: Path) -> None:
    """The case clamped at the tower's base: no sea state, hydrodynamics, substructure,
    mooring or ice, and ElastoDyn's platform fixed (a land deck is unchanged)."""
    set_values(fst, SUBSTRUCTURE_OFF)
    set_values(ed, PLATFORM_FIXED)


def module_file(fst: Path, key: str) -> Path:
    """The file the main file's ``key`` (EDFile, ServoFile, InflowFile) names."""
    return fst.parent / get_value(fst, key)


def write_wind(path: Path, t_final: float, wind) -> None:
    """The run's wind as InflowWind's uniform wind file: speed every WIND_DT s, no
    direction, no shear, no gust."""
    t = np.arange(0.0, t_final + 2 * WIND_DT, WIND_DT)
    u = np.broadcast_to(np.asarray(wind(t), dtype=float), t.shape)
    head = ["! wtftc: the run's wind (uniform over the rotor), docs/openfast.md",
            "! Time  Wind  Wind  Vert.  Horiz.  Pwr.Law  Lin.Vert.  Gust",
            "! (s)  (m/s)  (deg)  (m/s)  (-)  (-)  (-)  (m/s)"]
    rows = [f"{a:.4f} {b:.6f} 0 0 0 0 0 0" for a, b in zip(t, u, strict=True)]
    path.write_text("\n".join(head + rows) + "\n")


def initial_conditions(ed: Path, omega_r: float, beta: np.ndarray, tower_x: float) -> None:
    """ElastoDyn's initial rotor speed [rpm], blade pitch [deg] and tower-top fore-aft
    displacement [m]."""
    set_values(ed, {"RotSpeed": f"{omega_r * 30 / math.pi:.9g}",
                    "TTDspFA": f"{tower_x:.9g}",
                    **{f"BlPitch({j + 1})": f"{math.degrees(b):.9g}"
                       for j, b in enumerate(beta)}})
