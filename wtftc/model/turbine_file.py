"""Turbine files: one TOML file per turbine with every plant parameter (ours).

A turbine file holds every entry of the layout group ``turbine_params`` (the runtime
parameters of the generated plant, torque law and controllers' models: docs/turbines.md)
by its layout name, each with its value in the layout's unit, the unit, and its source,
and the path of the turbine's Cp_Ct_Cq table, relative to the file::

    name = "iea15mw"
    title = "IEA Wind 15-MW reference turbine (IEA-15-240-RWT)"
    cp_table = "Cp_Ct_Cq.IEA15MW.txt"

    [params]
    J_r = { value = 350673294.2, unit = "kg m^2", source = "ElastoDyn ..." }
    ...

The built-in turbines (``nrel5mw``, the default, and ``iea15mw``) ship in ``wtftc/data``;
any other is named by its path. Reading checks the structure (every parameter once, in
its unit, a finite number; the Cp table readable); the physical ranges are checked where
the run is configured (wtftc.config), which names the file too.
"""

from __future__ import annotations

import functools
import importlib.resources
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.errors import ConfigError
from wtftc.files import MAX_TABLE_BYTES, MAX_TOML_BYTES, check_user_file, read_user_text
from wtftc.model.cp_table import CpTable, read_cp_table

#: the turbines shipped with wtftc: name → file in wtftc/data
BUILTIN = {"nrel5mw": "nrel5mw.toml", "iea15mw": "iea15mw.toml"}
DEFAULT = "nrel5mw"


@dataclass(frozen=True, eq=False)
class Turbine:
    """A turbine file's content: ``values`` every turbine parameter by name (layout units),
    ``sources`` where each came from, the Cp table, and where the file is."""

    name: str
    title: str
    path: str
    values: dict
    sources: dict
    cp_path: str
    #: ROSCO's DISCON.IN tuned for this turbine (``controller = rosco``): a path relative
    #: to the turbine file, or ``rosco:<path>`` inside the installed rosco package's tree
    rosco_discon: str | None = None
    #: the pitch loop's closed-loop target (ω_pc [rad/s], ζ_pc) that DISCON.IN's gain
    #: schedule was tuned for (its tuning YAML's ``omega_pc``, ``zeta_pc``): what lets a
    #: run retune it (``[rosco]``, wtftc.sim.rosco.retuned_gains)
    rosco_tuning: tuple | None = None
    #: the turbine's OpenFAST deck, its main ``.fst`` (``--engine openfast``,
    #: wtftc.openfast): relative to the turbine file, or ``rosco:<path>`` in the rosco
    #: package's tree, as ``rosco_discon``
    openfast_deck: str | None = None
    #: the wind [m/s] from which the turbine makes power (its report's cut-in wind): where
    #: the Cp table's tip-speed ratios end before the rotor's slowest speed, a run at or
    #: above it still starts (wtftc.sim.trim.operating_point); None: not known, a start
    #: needs the table's ratios
    cut_in_wind_mps: float | None = None
    #: the controller preset wtftc recommends for this turbine (wtftc/data/presets.toml,
    #: wtftc.controller): what a run, an export and a comparison use unless told
    #: otherwise; None: the file names none
    recommended_preset: str | None = None

    def vector(self) -> np.ndarray:
        """The parameters in the layout's turbine_params order."""
        return np.array([self.values[n] for n in lay.names("turbine_params")], dtype=float)

    @functools.cached_property
    def table(self) -> CpTable:
        return read_cp_table(Path(self.cp_path))


def path_of(turbine: str) -> Path:
    """The file of a built-in turbine's name, or ``turbine`` as a path."""
    if turbine in BUILTIN:
        return Path(str(importlib.resources.files("wtftc") / "data" / BUILTIN[turbine]))
    path = Path(turbine)
    what = "a built-in turbine (" + ", ".join(BUILTIN) + ") or the path of a turbine file " \
        "(.toml; docs/turbines.md)"
    if path.suffix == ".toml" and not path.is_file():
        from wtftc.files import check_user_file

        try:  # says why: missing, a folder, a FIFO, a symlink loop...
            check_user_file(path, "turbine")
        except ConfigError as exc:
            raise ConfigError("turbine", turbine, f"{what}; {exc.allowed}") from None
    if path.suffix != ".toml" or not path.is_file():
        raise ConfigError("turbine", turbine, what)
    return path


@functools.cache
def load(turbine: str = DEFAULT) -> Turbine:
    """The turbine named ``turbine`` (a built-in name or a file's path), read once."""
    return read(path_of(turbine))


def read(path: Path) -> Turbine:
    """A turbine file; a ConfigError naming the file and the key on any defect."""
    return parse(read_user_text(path, "turbine", MAX_TOML_BYTES), Path(path))


def parse(text: str, path: Path, cp_must_exist: bool = True) -> Turbine:
    """A turbine file's ``text``, as read from ``path`` (its Cp table and rosco_discon
    relative to its folder): what :func:`read` checks, on text in memory
    (``wtftc turbine import`` checks what it will write before writing it; then the Cp
    table need not exist yet: ``cp_must_exist`` False)."""
    where = str(path)
    try:
        doc = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError) as exc:
        raise ConfigError("turbine", where, f"a readable TOML turbine file ({exc})") from None
    for key in ("name", "title", "cp_table"):
        if not isinstance(doc.get(key), str) or not doc[key]:
            raise ConfigError(key, doc.get(key), "a non-empty string", where=where)
    rosco = doc.get("rosco_discon")
    if rosco is not None and (not isinstance(rosco, str) or not rosco):
        raise ConfigError("rosco_discon", rosco, "the path of ROSCO's DISCON.IN for this "
                          "turbine (relative to the turbine file, or rosco:<path in the "
                          "rosco package's tree>)", where=where)
    values, sources = _params(doc.get("params"), where)
    cp = Path(doc["cp_table"])
    cp = cp if cp.is_absolute() else path.parent / cp
    if cp_must_exist:
        try:
            check_user_file(cp, "cp_table", MAX_TABLE_BYTES)
        except ConfigError as exc:
            raise ConfigError("cp_table", doc["cp_table"], f"a Cp_Ct_Cq file ({cp}: "
                              f"{exc.allowed}; relative paths are from the turbine file's "
                              "folder)", where=where) from None
    deck = doc.get("openfast_deck")
    if deck is not None and (not isinstance(deck, str) or not deck.endswith(".fst")):
        raise ConfigError("openfast_deck", deck, "the path of the turbine's OpenFAST main "
                          "input file (.fst; relative to the turbine file, or rosco:<path in "
                          "the rosco package's tree>)", where=where)
    rosco, deck = (s if s is None or s.startswith("rosco:") or Path(s).is_absolute()
                   else str(path.parent / s) for s in (rosco, deck))
    return Turbine(doc["name"], doc["title"], where, values, sources, str(cp), rosco,
                   _rosco_tuning(doc.get("rosco_tuning"), where), deck,
                   _cut_in_wind(doc.get("cut_in_wind_mps"), where),
                   _preset_name(doc.get("recommended_preset"), where))


def _preset_name(v, where: str) -> str | None:
    """``recommended_preset = "<name>"``, or None (a known name: wtftc.controller)."""
    if v is not None and (not isinstance(v, str) or not v):
        raise ConfigError("recommended_preset", v, "the name of a controller preset "
                          "(wtftc presets lists them)", where=where)
    return v


def _cut_in_wind(v, where: str) -> float | None:
    """``cut_in_wind_mps = 3.0``, or None."""
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v < 30:
        raise ConfigError("cut_in_wind_mps", v, "the turbine's cut-in wind in m/s, a number "
                          "above 0 and below 30", where=where)
    return float(v)


def _params(params, where: str) -> tuple[dict, dict]:
    """The [params] table: every turbine parameter once, in its unit, a finite number."""
    if not isinstance(params, dict):
        raise ConfigError("params", params, "a [params] table of every turbine parameter",
                          where=where)
    units = {e["name"]: e["unit"] for e in lay.layout()["turbine_params"]}
    unknown = sorted(set(params) - set(units))
    if unknown:
        raise ConfigError(f"params.{unknown[0]}", params[unknown[0]],
                          "one of the turbine parameters: " + ", ".join(units), where=where)
    values, sources = {}, {}
    for name, unit in units.items():
        values[name], sources[name] = _entry(params, name, unit, where)
    return values, sources


def _rosco_tuning(tab, where: str) -> tuple | None:
    """``rosco_tuning = { omega_pc_rad_s = 0.6, zeta_pc = 0.7 }``, or None."""
    if tab is None:
        return None
    want = "{ omega_pc_rad_s = <rad/s>, zeta_pc = <-> }, both positive"
    if not isinstance(tab, dict) or set(tab) != {"omega_pc_rad_s", "zeta_pc"}:
        raise ConfigError("rosco_tuning", tab, want, where=where)
    vals = tuple(tab[k] for k in ("omega_pc_rad_s", "zeta_pc"))
    if any(isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v < 100
           for v in vals):
        raise ConfigError("rosco_tuning", tab, want, where=where)
    return tuple(float(v) for v in vals)


#: run options a turbine file written before them may leave out: their value then
#: (the behaviour of the wtftc that wrote the file)
OPTIONAL = {"vs_constant_torque": (0.0, "the baseline torque law's region 3 at constant "
                                        "power (not in the file: the default)")}


def _entry(params: dict, name: str, unit: str, where: str) -> tuple[float, str]:
    e = params.get(name)
    field = f"params.{name}"
    if e is None and name in OPTIONAL:
        return OPTIONAL[name]
    if e is None:
        hint = (" (the blades' edgewise mode, new in wtftc's issue 33: `wtftc turbine "
                "import` writes it from the ElastoDyn blade file; docs/turbines.md)"
                if name.startswith("edge_") else "")
        raise ConfigError(field, "missing", f"every turbine parameter, in {unit}{hint}",
                          where=where)
    if not isinstance(e, dict) or set(e) - {"value", "unit", "source"} or "value" not in e:
        raise ConfigError(field, e, '{ value = <number>, unit = "...", source = "..." }',
                          where=where)
    v = e["value"]
    try:  # an integer beyond a float's range (10**400) is not finite either
        finite = not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)
    except OverflowError:
        finite = False
    if not finite:
        raise ConfigError(field, v, f"a finite number in {unit}", where=where)
    if e.get("unit", unit) != unit:
        raise ConfigError(f"{field}.unit", e["unit"], f"{unit!r} (the layout's unit)",
                          where=where)
    return float(v), str(e.get("source", ""))


def text(name: str, title: str, cp_table: str, values: dict, sources: dict,
         header: str = "", rosco_discon: str | None = None,
         openfast_deck: str | None = None) -> str:
    """A turbine file's text: every turbine parameter on one line, in the layout's order
    (every string a TOML string whatever it holds: :func:`toml_string`)."""
    lines = [f"# {_comment(ln)}".rstrip() for ln in header.splitlines()] + [
        f"name = {toml_string(name)}", f"title = {toml_string(title)}",
        f"cp_table = {toml_string(cp_table)}",
        *([f"rosco_discon = {toml_string(rosco_discon)}"] if rosco_discon else []),
        *([f"openfast_deck = {toml_string(openfast_deck)}"] if openfast_deck else []),
        "", "[params]"]
    for e in lay.layout()["turbine_params"]:
        n = e["name"]
        lines.append(f"{n} = {{ value = {float(values[n])!r}, unit = {toml_string(e['unit'])}, "
                     f"source = {toml_string(sources.get(n, ''))} }}")
    return "\n".join(lines) + "\n"


_ESCAPES = {'"': '\\"', "\\": "\\\\", "\b": "\\b", "\t": "\\t", "\n": "\\n", "\f": "\\f",
            "\r": "\\r"}


def toml_string(s: str) -> str:
    """``s`` as a TOML basic string: quotes, backslashes and control characters escaped
    (json.dumps is not TOML: it escapes a character beyond U+FFFF as a surrogate pair,
    which TOML refuses, and leaves DEL bare), a lone surrogate (a file name's undecodable
    byte) as U+FFFD."""
    out = []
    for ch in s:
        o = ord(ch)
        if ch in _ESCAPES:
            out.append(_ESCAPES[ch])
        elif o < 0x20 or o == 0x7F:
            out.append(f"\\u{o:04x}")
        elif 0xD800 <= o <= 0xDFFF:
            out.append("\\ufffd")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _comment(line: str) -> str:
    """A comment line's text: what TOML allows in a comment (no control characters)."""
    return "".join(ch if ch.isprintable() else "?" for ch in line)
