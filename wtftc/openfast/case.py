"""An OpenFAST case written from a run's configuration (issue 32; ours).

The turbine's deck (its ``openfast_deck``) is copied into the run folder's ``openfast/``
and edited there, so that a user can rerun it by hand (``openfast <name>.fst`` in that
folder):

* the main file: TMax, DT (DLL_DT a whole multiple of it), binary output at every step;
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
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wtftc.errors import ConfigError, EngineError

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


def copy_deck(fst: Path, folder: Path) -> Path:
    """The deck's folder copied into ``folder`` (its files name each other relative to
    it); the copied main file."""
    if not fst.is_file():
        raise ConfigError("openfast_deck", str(fst), "an OpenFAST main input file (.fst) "
                          "that exists")
    shutil.copytree(fst.parent, folder, dirs_exist_ok=True,
                    ignore=shutil.ignore_patterns("*.outb", "*.out", "*.sum", "*.ech",
                                                  "*.dbg*", "__pycache__"))
    return folder / fst.name


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
