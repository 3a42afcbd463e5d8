"""Rotor performance tables Cp(TSR, pitch), Ct, Cq in the ROSCO/CCBlade text format.

The format is the one ``rosco.toolbox.utilities.write_rotor_performance`` writes
(``Cp_Ct_Cq.<turbine>.txt``): ``#`` header lines name the sections

    # Pitch angle vector, 36 entries - x axis (matrix columns) (deg)
    # TSR vector, 26 entries - y axis (matrix rows) (-)
    # Wind speed vector - z axis (m/s)
    # Power coefficient
    #  Thrust coefficient
    # Torque coefficient          (older files: "coefficent")

and the numbers follow each header; matrices have one row per TSR and one column per
pitch angle. Pitch is in degrees in the file and in radians here.

:func:`aero_torque_raw` and :func:`steady_pitch_raw` work on the raw table with bilinear
interpolation and no smoothing: they are the reference that any smooth interpolant used
by the simulator is checked against.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.resources
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.errors import ConfigError
from wtftc.files import MAX_TABLE_BYTES, read_user_bytes

__all__ = [
    "CpTable",
    "read_cp_table",
    "parse_cp_table",
    "write_cp_table",
    "nrel5mw_cp_table",
    "aero_torque_raw",
    "steady_pitch_raw",
    "NREL5MW_SOURCE",
]

NREL5MW_FILE = "Cp_Ct_Cq.NREL5MW.txt"
NREL5MW_SOURCE = "NREL 5-MW (ROSCO 2.10.6)"


@functools.cache
def _nrel5mw_air() -> tuple[float, float]:
    """The air density [kg/m^3] and rotor (tip) radius [m]: the layout's NREL 5-MW defaults,
    read when first needed (not at import: a damaged layout must not break ``wtftc --help``)."""
    tp = lay.values("turbine_params", lay.defaults("turbine_params"))
    return tp["air_density"], tp["rotor_radius"]


def _air(rho, radius) -> tuple[float, float]:
    """``rho`` and ``radius``, each None replaced by its NREL 5-MW default."""
    if rho is None or radius is None:
        d_rho, d_radius = _nrel5mw_air()
        rho = d_rho if rho is None else rho
        radius = d_radius if radius is None else radius
    return rho, radius


_FIELD = "cp_table"
_FORMAT = "the ROSCO Cp_Ct_Cq text format"

# Section key -> (pattern matched against a '#' header line, name used in messages).
_SECTIONS = {
    "pitch": (re.compile(r"pitch\s+angle\s+vector", re.I), "Pitch angle vector"),
    "tsr": (re.compile(r"\btsr\s+vector", re.I), "TSR vector"),
    "wind": (re.compile(r"wind\s+speed\s+vector", re.I), "Wind speed vector"),
    "cp": (re.compile(r"power\s+coeff?icient", re.I), "Power coefficient"),
    "ct": (re.compile(r"thrust\s+coeff?icient", re.I), "Thrust coefficient"),
    "cq": (re.compile(r"torque\s+coeff?ici?e?nt", re.I), "Torque coefficient"),
}
_ENTRIES = re.compile(r"(\d+)\s+entries", re.I)


@dataclass(frozen=True, eq=False)
class CpTable:
    """A rotor performance table on a (TSR, pitch) grid; arrays are read-only.

    ``eq=False``: two tables compare by identity (element-wise array comparison has no
    single truth value); compare the arrays with ``np.array_equal`` when you need to.
    """

    pitch_rad: np.ndarray  # (n_pitch,), strictly increasing (rad)
    tsr: np.ndarray  # (n_tsr,), strictly increasing (-)
    cp: np.ndarray  # (n_tsr, n_pitch): rows = TSR, columns = pitch (-)
    ct: np.ndarray | None  # same shape as cp, or None
    cq: np.ndarray | None  # same shape as cp, or None
    source: str  # path, or "NREL 5-MW (ROSCO 2.10.6)" for the packaged table
    sha256: str | None = None  # of the file's bytes, when read from a file
    wind_speed: np.ndarray | None = None  # the file's "Wind speed vector" (m/s), if any

    def __post_init__(self):
        pitch = _frozen(self.pitch_rad)
        tsr = _frozen(self.tsr)
        n = (tsr.size, pitch.size)
        for name, arr in (("pitch_rad", pitch), ("tsr", tsr)):
            if arr.ndim != 1 or arr.size < 2 or not np.all(np.isfinite(arr)):
                raise ValueError(f"CpTable.{name} must be a finite 1-D array of >= 2 values")
            if not np.all(np.diff(arr) > 0):
                raise ValueError(f"CpTable.{name} must be strictly increasing")
        object.__setattr__(self, "pitch_rad", pitch)
        object.__setattr__(self, "tsr", tsr)
        for name in ("cp", "ct", "cq"):
            val = getattr(self, name)
            if val is None and name != "cp":
                continue
            arr = _frozen(val)
            if arr.shape != n:
                raise ValueError(f"CpTable.{name} has shape {arr.shape}; expected {n} "
                                 "(rows = TSR, columns = pitch)")
            object.__setattr__(self, name, arr)
        if self.wind_speed is not None:
            object.__setattr__(self, "wind_speed", _frozen(np.atleast_1d(self.wind_speed)))

    def cp_max(self) -> tuple[float, float, float]:
        """(Cp_max, TSR, pitch in rad) at the largest tabulated Cp."""
        i, j = np.unravel_index(int(np.argmax(self.cp)), self.cp.shape)
        return float(self.cp[i, j]), float(self.tsr[i]), float(self.pitch_rad[j])

    def describe(self) -> dict:
        """JSON-serializable summary: source, file sha256, grid, Cp max and where."""
        cp_max, tsr_at, pitch_at = self.cp_max()
        return {
            "source": self.source,
            "sha256": self.sha256,
            "n_pitch": int(self.pitch_rad.size),
            "n_tsr": int(self.tsr.size),
            "pitch_min_deg": _deg(self.pitch_rad[0]),
            "pitch_max_deg": _deg(self.pitch_rad[-1]),
            "tsr_min": float(self.tsr[0]),
            "tsr_max": float(self.tsr[-1]),
            "wind_speed_m_s": (None if self.wind_speed is None
                               else [float(v) for v in self.wind_speed]),
            "has_ct": self.ct is not None,
            "has_cq": self.cq is not None,
            "cp_max": cp_max,
            "cp_max_tsr": tsr_at,
            "cp_max_pitch_deg": _deg(pitch_at),
            "cp_min": float(np.min(self.cp)),
        }


def _deg(rad) -> float:
    """Degrees for a summary, rounded to 1e-9 deg so that -5 rad->deg prints as -5.0."""
    return round(float(np.rad2deg(rad)), 9) + 0.0


def _frozen(a) -> np.ndarray:
    arr = np.array(a, dtype=float)  # a copy: the caller's array stays writable and unshared
    arr.setflags(write=False)
    return arr


# --------------------------------------------------------------------------- reading


def read_cp_table(path) -> CpTable:
    """Read a ROSCO/CCBlade ``Cp_Ct_Cq`` text file; :class:`ConfigError` on any defect."""
    where = str(path)
    p = Path(path)
    try:
        raw = read_user_bytes(p, _FIELD, MAX_TABLE_BYTES)
    except ConfigError as exc:
        raise ConfigError(_FIELD, where, f"{exc.allowed} in {_FORMAT}", where=where) from None
    except FileNotFoundError:
        raise ConfigError(_FIELD, where, f"an existing file in {_FORMAT}", where=where) from None
    except OSError as exc:
        raise ConfigError(_FIELD, where, f"a readable file in {_FORMAT} ({exc.strerror})",
                          where=where) from None
    return _parse(raw, source=where, where=where)


def parse_cp_table(raw: bytes, where: str) -> CpTable:
    """The table in a file's bytes ``raw`` (already read), as :func:`read_cp_table` reads
    it: what ``wtftc turbine import`` checks before it copies a table."""
    return _parse(raw, source=where, where=where)


@functools.lru_cache(maxsize=1)
def nrel5mw_cp_table() -> CpTable:
    """The NREL 5-MW table shipped with ROSCO 2.10.6, packaged in ``wtftc/data``."""
    res = importlib.resources.files("wtftc") / "data" / NREL5MW_FILE
    return _parse(res.read_bytes(), source=NREL5MW_SOURCE, where=f"wtftc/data/{NREL5MW_FILE}")


#: section key -> (header line number, declared entry count or None, [(line no, values)])
_Sections = dict[str, tuple[int, int | None, list[tuple[int, list[float]]]]]


#: no rotor extracts more than 16/27 of the wind's power (Betz 1920)
BETZ_LIMIT = 16.0 / 27.0


def _parse(raw: bytes, source: str, where: str) -> CpTable:
    """The table in a file's bytes ``raw``; :class:`ConfigError` naming ``where`` on any
    defect (the first one found, top to bottom)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise _bad(where, f"undecodable byte at offset {exc.start}",
                   f"a text file in {_FORMAT}") from None
    sections = _sections(text, where)
    for key in ("pitch", "tsr", "cp"):
        if key not in sections:
            raise _bad(where, f"no '{_SECTIONS[key][1]}' section", f"a file in {_FORMAT} with "
                       "'# Pitch angle vector', '# TSR vector' and '# Power coefficient'")
    pitch_deg = _vector(sections, "pitch", "deg", where)
    tsr = _vector(sections, "tsr", "", where)
    wind = _vector(sections, "wind", "m/s", where) if "wind" in sections else None
    shape = (tsr.size, pitch_deg.size)
    cp = _matrix(sections, "cp", shape, where)
    if cp.max() > BETZ_LIMIT:
        i, j = np.unravel_index(int(np.argmax(cp)), cp.shape)
        raise _bad(where, f"Cp = {cp[i, j]:g} at TSR {tsr[i]:g}, pitch {pitch_deg[j]:g} deg",
                   f"power coefficients at most the Betz limit 16/27 = {BETZ_LIMIT:.4f} "
                   "(negative ones are physical: ROSCO's NREL 5-MW table reaches -11.9 where "
                   "the rotor absorbs power)")
    if not cp.max() > 0:  # no operating point makes power: no rated wind, no trim
        raise _bad(where, f"the largest Cp = {cp.max():g}", "a table where the rotor makes "
                   "power somewhere (a positive power coefficient)")
    ct = _matrix(sections, "ct", shape, where)
    cq = _matrix(sections, "cq", shape, where)
    return CpTable(pitch_rad=np.deg2rad(pitch_deg), tsr=tsr, cp=cp, ct=ct, cq=cq,
                   source=source, sha256=hashlib.sha256(raw).hexdigest(), wind_speed=wind)


def _bad(where: str, found: str, allowed: str) -> ConfigError:
    return ConfigError(_FIELD, found, allowed, where=where)


def _sections(text: str, where: str) -> _Sections:
    """The sections of the file's text, by key: a '#' line naming a section opens it, and
    the numbers below it are its rows; any other '#' line (a title, a date) closes it."""
    sections: _Sections = {}
    current: str | None = None
    comment: tuple[int, str] | None = None  # the last '#' line that names no section
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("#"):
            key = next((k for k, (pat, _) in _SECTIONS.items() if pat.search(s)), None)
            if key is None:  # a comment (title, date): it opens no section and closes one
                current, comment = None, (lineno, s)
                continue
            if key in sections:
                raise _bad(where, f"a second '{_SECTIONS[key][1]}' section at line {lineno}",
                           "each section once")
            m = _ENTRIES.search(s)
            sections[key] = (lineno, int(m.group(1)) if m else None, [])
            current = key
            continue
        if current is None:
            found = (f"numbers at line {lineno} under the header {comment[1]!r} (line "
                     f"{comment[0]}), which names no known section" if comment else
                     f"numbers before any section header at line {lineno}")
            raise _bad(where, found, "'#' header lines naming each section ("
                       + ", ".join(repr(n) for _, n in _SECTIONS.values())
                       + "), then its numbers")
        sections[current][2].append((lineno, _numbers(s, lineno, where)))
    return sections


def _numbers(s: str, lineno: int, where: str) -> list[float]:
    """The finite numbers of a line below a section header."""
    values = []
    for tok in s.split():
        try:
            v = float(tok)
        except ValueError:
            raise _bad(where, f"non-numeric entry {tok!r} at line {lineno}",
                       "numbers only below a section header") from None
        if not math.isfinite(v):
            raise _bad(where, f"non-finite entry {tok!r} at line {lineno}", "finite numbers")
        values.append(v)
    return values


def _vector(sections: _Sections, key: str, unit: str, where: str) -> np.ndarray:
    """A vector section, its entries as many as its header declares; the pitch and TSR
    grids strictly increasing."""
    name = _SECTIONS[key][1]
    header, declared, rows = sections[key]
    vals = np.array([v for _, row in rows for v in row], dtype=float)
    if vals.size == 0:
        raise _bad(where, f"'{name}' (line {header}) is empty", "at least one number")
    if declared is not None and declared != vals.size:
        raise _bad(where, f"'{name}' has {vals.size} entries but its header says {declared}",
                   "as many entries as the header declares")
    if key != "wind" and (vals.size < 2 or not np.all(np.diff(vals) > 0)):
        k = int(np.argmax(np.diff(vals) <= 0)) if vals.size >= 2 else 0
        found = (f"'{name}' with {vals.size} entry" if vals.size < 2 else
                 f"'{name}' not strictly increasing: {vals[k]:g} then {vals[k + 1]:g} {unit}")
        raise _bad(where, found, "a strictly increasing grid of at least 2 values")
    return vals


def _matrix(sections: _Sections, key: str, shape: tuple[int, int],
            where: str) -> np.ndarray | None:
    """A matrix section of ``shape`` (one row per TSR, one column per pitch), or None if
    the file has none."""
    if key not in sections:
        return None
    name = _SECTIONS[key][1]
    header, _, rows = sections[key]
    n_tsr, n_pitch = shape
    expected = f"{n_tsr} rows (one per TSR) x {n_pitch} columns (one per pitch)"
    for lineno, row in rows:
        if len(row) != n_pitch:
            raise _bad(where, f"'{name}' row at line {lineno} has {len(row)} values",
                       f"{n_pitch} values per row (one per pitch); expected {expected}")
    if len(rows) != n_tsr:
        raise _bad(where, f"'{name}' matrix (line {header}) has {len(rows)} rows", f"{expected}")
    return np.array([row for _, row in rows], dtype=float)


# --------------------------------------------------------------------------- writing


def write_cp_table(table: CpTable, path, title: str = "wtftc") -> Path:
    """Write ``table`` in the ROSCO text format (pitch in degrees), round-trip exact.

    Numbers are written with 17 significant digits, so :func:`read_cp_table` gives back
    the same Cp/Ct/Cq/TSR values bit for bit and the pitch to one rounding of deg<->rad.
    """
    def row(vals) -> str:
        return "   ".join(f"{v:.17g}" for v in vals) + "\n"

    out = [f"# ----- Rotor performance tables for the {title} wind turbine -----\n\n",
           f"# Pitch angle vector, {table.pitch_rad.size} entries - x axis (matrix columns)"
           " (deg)\n", row(np.rad2deg(table.pitch_rad)),
           f"# TSR vector, {table.tsr.size} entries - y axis (matrix rows) (-)\n",
           row(table.tsr)]
    if table.wind_speed is not None:
        out += ["# Wind speed vector - z axis (m/s)\n", row(table.wind_speed)]
    for name, mat in (("Power", table.cp), ("Thrust", table.ct), ("Torque", table.cq)):
        if mat is not None:
            out += [f"\n# {name} coefficient\n\n", *(row(r) for r in mat)]
    p = Path(path)
    p.write_text("".join(out), encoding="utf-8")
    return p


# --------------------------------------------------------------------------- raw reference


def _cp_bilinear(table: CpTable, tsr: float, pitch_rad: float) -> float:
    """Cp by bilinear interpolation of the raw grid; ValueError outside it (no extrapolation)."""
    x, y = table.tsr, table.pitch_rad
    if not (x[0] <= tsr <= x[-1]):
        raise ValueError(f"tip-speed ratio {tsr:.6g} is outside the table's "
                         f"[{x[0]:g}, {x[-1]:g}] ({table.source})")
    if not (y[0] <= pitch_rad <= y[-1]):
        raise ValueError(f"pitch {math.degrees(pitch_rad):.6g} deg is outside the table's "
                         f"[{math.degrees(y[0]):g}, {math.degrees(y[-1]):g}] deg "
                         f"({table.source})")
    i = min(int(np.searchsorted(x, tsr, side="right")) - 1, x.size - 2)
    j = min(int(np.searchsorted(y, pitch_rad, side="right")) - 1, y.size - 2)
    u = (tsr - x[i]) / (x[i + 1] - x[i])
    w = (pitch_rad - y[j]) / (y[j + 1] - y[j])
    c = table.cp
    return float((1 - u) * ((1 - w) * c[i, j] + w * c[i, j + 1])
                 + u * ((1 - w) * c[i + 1, j] + w * c[i + 1, j + 1]))


def _check_positive(name: str, val: float) -> float:
    val = float(val)
    if not (math.isfinite(val) and val > 0):
        raise ValueError(f"{name} must be a finite positive number, got {val!r}")
    return val


def aero_torque(cp, omega_r, v_wind, rho=None, radius=None):
    """Aerodynamic rotor torque [N m, LSS] T = ½ ρ π R² v³ Cp / ω_r (Jonkman 2009; the
    derivation's aero_operating_point computes the same in the loop). ``rho``, ``radius``:
    the NREL 5-MW's when None."""
    rho, radius = _air(rho, radius)
    return 0.5 * rho * math.pi * radius**2 * v_wind**3 * cp / omega_r


def bisect(on_lo_side, lo: float, hi: float, n: int = 60) -> float:
    """The midpoint of [lo, hi] after halving it n times (or down to adjacent floats),
    keeping in it the point where ``on_lo_side(x)`` turns from true (at lo) to false."""
    for _ in range(n):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        lo, hi = (mid, hi) if on_lo_side(mid) else (lo, mid)
    return 0.5 * (lo + hi)


def aero_torque_raw(table: CpTable, omega_r, v_wind, pitch_rad, rho=None,
                    radius=None) -> float:
    """Aerodynamic rotor torque (N m, LSS) from the raw table, bilinear in (TSR, pitch).

    T = 0.5 rho pi R^2 v^3 Cp(lambda, beta) / omega_r with lambda = omega_r R / v.
    ValueError when lambda or the pitch falls outside the table (no extrapolation).
    """
    rho, radius = _air(rho, radius)
    omega_r = _check_positive("omega_r", omega_r)
    v_wind = _check_positive("v_wind", v_wind)
    rho = _check_positive("rho", rho)
    radius = _check_positive("radius", radius)
    tsr = omega_r * radius / v_wind
    return aero_torque(_cp_bilinear(table, tsr, float(pitch_rad)), omega_r, v_wind, rho, radius)


def steady_pitch_raw(table: CpTable, omega_r, torque, v_wind, rho=None,
                     radius=None) -> float:
    """The pitch (rad) above the Cp-optimal pitch at which aero_torque_raw equals ``torque``.

    At lambda = omega_r R / v the raw bilinear Cp is piecewise linear in pitch, so it peaks
    at a grid pitch beta_opt(lambda). Above it, the first grid interval where the torque
    falls through ``torque`` brackets the root (the lowest such pitch: the branch a pitch
    controller regulates on), which bisection then refines to machine precision.
    ValueError when there is no root in [beta_opt, table's largest pitch].
    """
    torque = float(torque)
    if not math.isfinite(torque):
        raise ValueError(f"torque must be finite, got {torque!r}")
    rho, radius = _air(rho, radius)
    # Checks omega_r, v_wind, rho, radius and that lambda lies in the table.
    aero_torque_raw(table, omega_r, v_wind, table.pitch_rad[0], rho, radius)

    def resid(beta: float) -> float:
        return aero_torque_raw(table, omega_r, v_wind, beta, rho, radius) - torque

    grid = table.pitch_rad
    r_grid = np.array([resid(b) for b in grid])
    k_opt = int(np.argmax(r_grid))  # torque is proportional to Cp at fixed lambda and v
    tsr = float(omega_r) * float(radius) / float(v_wind)
    if r_grid[k_opt] < 0:
        raise ValueError(
            f"no steady pitch: torque {torque:.6g} N m exceeds the largest aerodynamic torque "
            f"{r_grid[k_opt] + torque:.6g} N m at omega_r {float(omega_r):g} rad/s, wind "
            f"{float(v_wind):g} m/s (TSR {tsr:.4g}, pitch {math.degrees(grid[k_opt]):g} deg); "
            "the wind is below the speed at which this torque can be reached")
    if r_grid[k_opt] == 0:
        return float(grid[k_opt])
    below = np.nonzero(r_grid[k_opt + 1:] <= 0)[0]
    if below.size == 0:
        raise ValueError(
            f"no steady pitch: the aerodynamic torque at the table's largest pitch "
            f"{math.degrees(grid[-1]):g} deg is still {r_grid[-1] + torque:.6g} N m > "
            f"{torque:.6g} N m at omega_r {float(omega_r):g} rad/s, wind {float(v_wind):g} m/s "
            f"(TSR {tsr:.4g}); the root lies beyond the table's pitch range")
    hi_k = k_opt + 1 + int(below[0])
    if r_grid[hi_k] == 0:
        return float(grid[hi_k])
    # the interval halves each time: ~60 steps reach adjacent floats
    return bisect(lambda b: resid(b) > 0, float(grid[hi_k - 1]), float(grid[hi_k]), n=200)
