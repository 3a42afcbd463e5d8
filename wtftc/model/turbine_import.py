"""``wtftc turbine import``: a turbine file from an OpenFAST deck and a ROSCO DISCON.IN.

The OpenFAST deck is read with ``openfast-io`` (NREL's maintained reader and writer of
OpenFAST input files, PyPI ``openfast-io``; optional extra ``wtftc[import]``), each file
first read and checked as a user's file (:mod:`wtftc.model.openfast_deck`): the main file,
ElastoDyn, its blade and tower files, and ServoDyn. The DISCON.IN is read here, line by
line (``value ! Key - comment``, ROSCO's format): ROSCO's own reader
(``rosco.toolbox.utilities.read_DISCON``) imports WISDEM, about 1.4 GB, for one function.

From the deck (ElastoDyn): the gearbox ratio ``GBRatio``, the generator's inertia
``GenIner`` (HSS, referred to the LSS by GBRatio²), the drivetrain's ``DTTorSpr`` and
``DTTorDmp``, the tip radius ``TipRad``, the tower's first fore-aft mode (its tower
file: :func:`tower_mode`), and the rotor inertia: the blades' mass
distribution (``BMassDen`` × ``AdjBlMs`` along ``BlFract`` from ``HubRad`` to ``TipRad``,
about the rotor axis with the precone) times ``NumBl``, plus ``HubIner``; ElastoDyn
computes it so (its .sum file's rotor inertia). From DISCON.IN: the rated speed
``PC_RefSpd``, torque ``VS_RtTq`` and power ``VS_RtPwr``, the generator efficiency
``VS_GenEff``, the pitch limits ``PC_MinPit``/``PC_MaxPit`` and rate ``PC_MaxRat``, the
air density ``WE_RhoAir``, the torque law's ``VS_MinOMSpd``, ``VS_Rgn2K``, ``VS_MaxTq``,
and the Cp table ``PerfFileName``. Values both files give (gearbox ratio, radius) must
agree; ``WE_Jtot`` is compared with the deck's inertia and the difference recorded.

Every value is checked where it is read, naming its file and key (what the computation
needs: a positive gearbox ratio and tower height, blade and tower stations in order, a
mode shape with φ(1) = 1, non-negative masses), and the result again with the checks a
turbine file gets from every command (:func:`write`, before anything is written); a
result refused there is blamed on the file and key it came from.
"""

from __future__ import annotations

import math
import re
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wtftc.errors import ConfigError
from wtftc.files import (
    MAX_TABLE_BYTES,
    check_new_file,
    read_user_bytes,
    read_user_text,
    write_files_together,
)
from wtftc.model import openfast_deck
from wtftc.model.cp_table import CpTable, parse_cp_table
from wtftc.model.openfast_deck import number, numbers

#: the benchmark actuator (Odgaard 2013), the default of a turbine whose deck has none
ACTUATOR = {"omega_n_nominal": 11.11, "zeta_nominal": 0.6}
#: a turbine's short name: what the built-in ones look like (nrel5mw, iea15mw)
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
#: the longest title (one line)
MAX_TITLE = 200


@dataclass
class Imported:
    """A turbine read from its files, not yet written: every parameter (layout units),
    its source text, its origin (the file, the key(s) and the value there: what a value
    refused later is blamed on), the Cp table (path, bytes, parsed) and the DISCON.IN."""

    values: dict
    sources: dict
    origins: dict
    cp: Path
    cp_bytes: bytes
    table: CpTable
    discon: Path
    fst: Path | None = None  # the deck read: the turbine file's openfast_deck


# ------------------------------------------------------------------------------ the deck

def read_deck(fst: Path) -> tuple[dict, dict]:
    """(values, sources) of the deck's ElastoDyn: inertias, drivetrain, gearbox, radius,
    the tower's first fore-aft mode."""
    values, sources, _ = _deck_values(openfast_deck.read(fst, servo=False))
    return values, sources


def _elastodyn(deck: openfast_deck.Deck) -> dict:
    """ElastoDyn's numbers wtftc uses, each checked (file, key, value, range)."""
    ed, f = deck.ed, deck.ed_file
    g = {"GBRatio": number(ed, "GBRatio", f, 0, low_open=True),
         "NumBl": number(ed, "NumBl", f, 1, 3),
         "TipRad": number(ed, "TipRad", f, 0, low_open=True, unit="m")}
    g["HubRad"] = number(ed, "HubRad", f, 0, g["TipRad"], high_open=True, unit="m")
    g["PreCone(1)"] = number(ed, "PreCone(1)", f, -90, 90, True, True, "deg")
    for key in ("GenIner", "HubIner", "HubMass", "NacMass", "YawBrMass"):
        g[key] = number(ed, key, f, 0, unit="kg m^2" if "Iner" in key else "kg")
    for key in ("DTTorSpr", "DTTorDmp", "Twr2Shft", "TowerBsHt", "OverHang", "NacCMxn",
                "NacCMzn"):
        g[key] = number(ed, key, f)  # their ranges: the turbine's (k_s, d_s, moment arm)
    g["TowerHt"] = number(ed, "TowerHt", f)
    if not g["TowerHt"] > g["TowerBsHt"]:
        raise ConfigError("TowerHt", g["TowerHt"], f"a height above TowerBsHt = "
                          f"{g['TowerBsHt']:g} m (the flexible tower is TowerHt - TowerBsHt "
                          "long)", where=str(f))
    return g


def _stations(d: dict, key: str, where: Path, count: str) -> np.ndarray:
    """A station column (BlFract, HtFract; ``count`` stations): from 0 to 1, strictly
    increasing."""
    number(d, count, where, 2)
    x = numbers(d, key, where, 0.0, 1.0, increasing=True)
    if len(x) < 2 or x[0] != 0.0 or x[-1] != 1.0:
        raise ConfigError(key, x if len(x) < 6 else f"{x[0]:g} ... {x[-1]:g}",
                          "at least 2 stations, from 0 to 1 (as ElastoDyn requires)",
                          where=str(where))
    return np.asarray(x)


def _blade(deck: openfast_deck.Deck, g: dict) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(radius r [m], mass density [kg/m], AdjBlMs, the blade's mass [kg])."""
    bl, f = deck.blade, deck.blade_file
    frac = _stations(bl, "BlFract", f, "NBlInpSt")
    try:
        mass = np.asarray(numbers(bl, "BMassDen", f, 0.0, unit="kg/m"))
    except ConfigError as exc:
        raise ConfigError(exc.field, exc.value, f"{exc.allowed} (an ElastoDyn blade file in "
                          "the older format, with a PitchAxis column, is read one column off "
                          "by openfast-io 5: docs/turbines.md)", where=exc.where) from None
    adj = number(bl, "AdjBlMs", f, 0, low_open=True)
    r = g["HubRad"] + frac * (g["TipRad"] - g["HubRad"])
    m_blade = float(np.trapezoid(mass, r)) * adj
    if not (math.isfinite(m_blade) and m_blade > 0):
        raise ConfigError("BMassDen", f"a blade of {m_blade:g} kg", "a blade of positive, "
                          "finite mass (BMassDen × AdjBlMs along the blade)", where=str(f))
    return r, mass, adj, m_blade


def rotor_inertia(g: dict, r: np.ndarray, mass: np.ndarray, adj: float) -> float:
    """Blades and hub about the rotor axis [kg m²], from ElastoDyn's blade mass
    distribution ``mass`` × ``adj`` [kg/m] at radii ``r`` (linear between stations,
    integrated on a fine grid), NumBl blades at the precone, plus HubIner."""
    precone = math.radians(g["PreCone(1)"])
    rr = np.linspace(r[0], r[-1], 20001)
    m = np.interp(rr, r, mass) * adj
    return g["NumBl"] * float(np.trapezoid(m * (rr * math.cos(precone)) ** 2, rr)) \
        + g["HubIner"]


def _deck_values(deck: openfast_deck.Deck) -> tuple[dict, dict, dict]:
    """(values, sources, origins) of the deck's ElastoDyn. Extreme values overflow to
    infinity quietly (no NumPy warning on stderr): the turbine's checks refuse them,
    naming the key they came from."""
    with np.errstate(all="ignore"):
        return _deck_values_of(deck)


def _deck_values_of(deck: openfast_deck.Deck) -> tuple[dict, dict, dict]:
    g = _elastodyn(deck)
    r, mass, adj, m_blade = _blade(deck, g)
    n, ed, src = g["GBRatio"], deck.ed_file, deck.ed_file.name
    values = {"J_r": rotor_inertia(g, r, mass, adj), "J_g": g["GenIner"] * n * n,
              "k_s": g["DTTorSpr"], "d_s": g["DTTorDmp"], "gearbox_ratio": n,
              "rotor_radius": g["TipRad"]}
    sources = {
        "J_r": f"{src}: {g['NumBl']:g} blades' BMassDen × AdjBlMs of {deck.blade_file.name} "
               f"about the rotor axis (HubRad {g['HubRad']:g} m to TipRad {g['TipRad']:g} m, "
               f"precone) + HubIner {g['HubIner']:g} kg m²",
        "J_g": f"{src}: GenIner {g['GenIner']:g} kg m² (HSS) × GBRatio²",
        "k_s": f"{src}: DTTorSpr", "d_s": f"{src}: DTTorDmp", "gearbox_ratio": f"{src}: GBRatio",
        "rotor_radius": f"{src}: TipRad"}
    origins = {"J_r": (deck.blade_file, "BMassDen, AdjBlMs", m_blade),
               "J_g": (ed, "GenIner", g["GenIner"]), "k_s": (ed, "DTTorSpr", g["DTTorSpr"]),
               "d_s": (ed, "DTTorDmp", g["DTTorDmp"]), "gearbox_ratio": (ed, "GBRatio", n),
               "rotor_radius": (ed, "TipRad", g["TipRad"])}
    for mode in (tower_mode(deck, g, m_blade, values["J_r"]), edge_mode(deck, g)):
        values.update(mode[0])
        sources.update({k: f"{src}, {v}" for k, v in mode[1].items()})
        origins.update(mode[2])
    return values, sources, origins


def _mode_shape(d: dict, f: Path, key: str = "TwFAM1Sh",
                what: str = "first fore-aft") -> list[float]:
    """A mode shape's coefficients of x² .. x⁶ (TwFAM1Sh, BldEdgSh): finite, summing to 1
    (φ(1) = 1; ElastoDyn refuses any other)."""
    c = numbers(d, key, f)
    if not abs(sum(c) - 1.0) <= 1e-3:
        raise ConfigError(f"{key}(2:6)", c, f"coefficients of the {what} mode shape "
                          f"that sum to 1 (φ(1) = 1, as ElastoDyn requires; these sum to "
                          f"{sum(c):g})", where=str(f))
    return c


def edge_mode(deck: openfast_deck.Deck, g: dict) -> tuple[dict, dict, dict]:
    """The blade's first edgewise mode from ElastoDyn's blade file [SI], per blade, as the
    ``tower_edge`` plant needs it (derivation/turbine.py ``tower_edge_rhs``): the mode
    shape φ(x) = Σ BldEdgSh(k) x^k (x the fraction of the flexible blade from HubRad to
    TipRad, φ(1) = 1), modal mass m_e = ∫ μ φ² dr (BMassDen × AdjBlMs), stiffness
    k_e = ∫ EI φ''² dr (EdgStff × AdjEdSt, as ElastoDyn computes it), damping BldEdDmp(1),
    the couplings to the rotor's rotation ∫ μ r φ cos τ dr and ∫ μ r φ sin τ dr (r the
    distance from the rotor axis with the precone, τ the structural twist StrcTwst), and
    the edge's share of the aerodynamic torque κ = ∫ r φ dr / ∫ r² dr (a tangential load
    proportional to r). (values, sources, origins)."""
    bl, f, name = deck.blade, deck.blade_file, deck.blade_file.name
    frac = _stations(bl, "BlFract", f, "NBlInpSt")
    length = g["TipRad"] - g["HubRad"]
    x = np.linspace(0.0, 1.0, 20001)
    r = (g["HubRad"] + x * length) * math.cos(math.radians(g["PreCone(1)"]))
    mu = np.interp(x, frac, numbers(bl, "BMassDen", f, 0.0, unit="kg/m")) * number(
        bl, "AdjBlMs", f, 0, low_open=True)
    ei = np.interp(x, frac, numbers(bl, "EdgStff", f, 0.0, unit="N m^2")) * number(
        bl, "AdjEdSt", f, 0, low_open=True)
    twist = np.radians(np.interp(x, frac, numbers(bl, "StrcTwst", f, -90, 90, unit="deg")))
    c = _mode_shape(bl, f, "BldEdgSh", "first edgewise")
    phi = sum(ck * x ** (k + 2) for k, ck in enumerate(c))
    curv = sum(ck * (k + 2) * (k + 1) * x**k for k, ck in enumerate(c)) / (length * length)
    values = {"edge_modal_mass": length * float(np.trapezoid(mu * phi**2, x)),
              "edge_stiffness": length * float(np.trapezoid(ei * curv**2, x)),
              "edge_damping_ratio": number(bl, "BldEdDmp1", f, 0, 100, unit="%") / 100.0,
              "edge_coupling_cos": length * float(np.trapezoid(mu * r * phi * np.cos(twist), x)),
              "edge_coupling_sin": length * float(np.trapezoid(mu * r * phi * np.sin(twist), x)),
              "edge_torque_share": float(np.trapezoid(r * phi, x) / np.trapezoid(r * r, x))}
    f1 = (math.sqrt(values["edge_stiffness"] / values["edge_modal_mass"]) / (2 * math.pi)
          if values["edge_stiffness"] > 0 and values["edge_modal_mass"] > 0 else math.nan)
    sources = {
        "edge_modal_mass": f"{name}: ∫ BMassDen × AdjBlMs × φ² dr, φ the BldEdgSh mode shape",
        "edge_stiffness": f"{name}: ∫ EdgStff × AdjEdSt × φ''² dr (the blade's first edgewise "
                          f"frequency alone, clamped, not rotating: {f1:.4f} Hz)",
        "edge_damping_ratio": f"{name}: BldEdDmp(1) / 100",
        "edge_coupling_cos": f"{name}: ∫ BMassDen × AdjBlMs × r × φ × cos(StrcTwst) dr, r "
                             "from the rotor axis at the precone",
        "edge_coupling_sin": f"{name}: ∫ BMassDen × AdjBlMs × r × φ × sin(StrcTwst) dr",
        "edge_torque_share": f"{name}: ∫ r φ dr / ∫ r² dr (a tangential load ∝ r)"}
    origins = {"edge_modal_mass": (f, "BMassDen, AdjBlMs, BldEdgSh", values["edge_modal_mass"]),
               "edge_stiffness": (f, "EdgStff, AdjEdSt, BldEdgSh", values["edge_stiffness"]),
               "edge_damping_ratio": (f, "BldEdDmp(1)", values["edge_damping_ratio"] * 100),
               "edge_coupling_cos": (f, "BMassDen, StrcTwst, BldEdgSh",
                                     values["edge_coupling_cos"]),
               "edge_coupling_sin": (f, "BMassDen, StrcTwst, BldEdgSh",
                                     values["edge_coupling_sin"]),
               "edge_torque_share": (f, "BldEdgSh", values["edge_torque_share"])}
    return values, sources, origins


#: standard gravity [m/s²] (ElastoDyn's default, OpenFAST's .fst Gravity)
GRAVITY = 9.80665


def tower_mode(deck: openfast_deck.Deck, g: dict, m_blade: float, j_rotor: float
               ) -> tuple[dict, dict, dict]:
    """The tower's first fore-aft mode from ElastoDyn [SI], as its equations have it with
    the tower's one mode (issue 33; docs/validation.md): the mode shape φ(h) =
    Σ TwFAM1Sh(k) h^k (k = 2..6, h the height fraction over the flexible tower, φ(1) = 1).

    - Modal mass m_t = ∫ μ φ² dz + the rotor-nacelle assembly carried by the tower top as
      it moves and tilts by φ'(H): each of its masses (yaw bearing at the top, rotor at
      OverHang and Twr2Shft, nacelle at NacCMxn and NacCMzn) weighs m [(1 + z φ'(H))² +
      (x φ'(H))²], the rotor's inertia about its tilt axis J_r/2 weighs φ'(H)².
    - Modal stiffness k_t = ∫ EI (φ'')² dz - g ∫ m_above(z) φ'² dz: bending less gravity's
      destiffening under the tower above z and the assembly on top.
    - Damping ratio TwrFADmp(1); the moment arm of the rotor over the tower base,
      TowerHt + Twr2Shft - TowerBsHt.

    On both shipped turbines the result is OpenFAST's rigid-blade linearization within
    1.3 % (Rayleigh's quotient alone: +6 % and +12 %). (values, sources, origins)."""
    tw, f, name = deck.tower, deck.tower_file, deck.tower_file.name
    height = g["TowerHt"] - g["TowerBsHt"]
    frac = _stations(tw, "HtFract", f, "NTwInpSt")
    h = np.linspace(0.0, 1.0, 20001)
    mu = np.interp(h, frac, numbers(tw, "TMassDen", f, 0.0, unit="kg/m")) * number(
        tw, "AdjTwMa", f, 0, low_open=True)
    ei = np.interp(h, frac, numbers(tw, "TwFAStif", f, 0.0, unit="N m^2")) * number(
        tw, "AdjFASt", f, 0, low_open=True)
    c = _mode_shape(tw, f)
    phi = sum(ck * h ** (k + 2) for k, ck in enumerate(c))
    slope = sum(ck * (k + 2) * h ** (k + 1) for k, ck in enumerate(c)) / height
    curv = sum(ck * (k + 2) * (k + 1) * h**k for k, ck in enumerate(c)) / (height * height)
    rna = g["HubMass"] + g["NacMass"] + g["YawBrMass"] + g["NumBl"] * m_blade
    top = _tower_top_mass(g, m_blade, j_rotor, float(slope[-1]))
    tower_above = height * (np.trapezoid(mu, h) - np.concatenate(
        [[0.0], np.cumsum((mu[1:] + mu[:-1]) / 2 * np.diff(h))]))
    mass = top + height * float(np.trapezoid(mu * phi**2, h))
    bending = height * float(np.trapezoid(ei * curv**2, h))
    gravity = height * float(np.trapezoid(GRAVITY * (rna + tower_above) * slope**2, h))
    stiffness = bending - gravity
    values = {"tower_modal_mass": mass, "tower_stiffness": stiffness,
              "tower_damping_ratio": number(tw, "TwrFADmp1", f, 0, 100, unit="%") / 100.0,
              "tower_moment_arm": g["TowerHt"] + g["Twr2Shft"] - g["TowerBsHt"]}
    f1 = (math.sqrt(stiffness / mass) / (2 * math.pi) if stiffness > 0 and mass > 0
          else math.nan)
    sources = {
        "tower_modal_mass": f"{name}: ∫ TMassDen × AdjTwMa × φ² dz, φ the TwFAM1Sh mode "
                            f"shape, + the rotor-nacelle assembly ({rna:.6g} kg: HubMass, "
                            f"NacMass, YawBrMass, NumBl × blade mass) moving and tilting with "
                            f"the tower top: {top:.6g} kg (OverHang, Twr2Shft, NacCMxn, "
                            "NacCMzn, the rotor inertia)",
        "tower_stiffness": f"{name}: ∫ TwFAStif × AdjFASt × φ''² dz ({bending:.6g} N/m) less "
                           f"gravity's destiffening g ∫ m_above φ'² dz ({gravity:.6g} N/m); "
                           f"first fore-aft frequency {f1:.4f} Hz",
        "tower_damping_ratio": f"{name}: TwrFADmp(1) / 100",
        "tower_moment_arm": "TowerHt + Twr2Shft - TowerBsHt"}
    origins = {"tower_modal_mass": (f, "TMassDen, AdjTwMa", mass),
               "tower_stiffness": (f, "TwFAStif, AdjFASt, TwFAM1Sh", stiffness),
               "tower_damping_ratio": (f, "TwrFADmp(1)", values["tower_damping_ratio"] * 100),
               "tower_moment_arm": (deck.ed_file, "TowerHt, Twr2Shft, TowerBsHt",
                                    values["tower_moment_arm"])}
    return values, sources, origins


def _tower_top_mass(g: dict, m_blade: float, j_rotor: float, slope: float) -> float:
    """The tower top's share of the first fore-aft mode's modal mass [kg]: each mass of
    the rotor-nacelle assembly at (x downwind, z up) from the tower top moves by
    (1 + z φ') horizontally and x φ' vertically per unit of top displacement, φ' the mode's
    slope there [1/m]; the rotor (hub and blades at OverHang, Twr2Shft) also turns about its
    tilt axis, J_r / 2 for a rotor of three or more blades."""
    parts = ((g["YawBrMass"], 0.0, 0.0),
             (g["HubMass"] + g["NumBl"] * m_blade, g["OverHang"], g["Twr2Shft"]),
             (g["NacMass"], g["NacCMxn"], g["NacCMzn"]))
    return (sum(m * ((1 + z * slope) ** 2 + (x * slope) ** 2) for m, x, z in parts)
            + j_rotor / 2 * slope**2)


# ------------------------------------------------------------------------------ DISCON.IN

_LINE = re.compile(r"^\s*(?P<value>[^!]*?)\s*!\s*(?P<key>[A-Za-z_][A-Za-z0-9_]*)")
#: the DISCON.IN keys the import reads
DISCON_KEYS = ("PC_RefSpd", "VS_RtTq", "VS_RtPwr", "VS_GenEff", "PC_MinPit", "PC_MaxPit",
               "PC_MaxRat", "WE_RhoAir", "VS_MinOMSpd", "VS_Rgn2K", "VS_MaxTq",
               "WE_GearboxRatio", "WE_BladeRadius", "WE_Jtot")


def line_key(line: str) -> str | None:
    """The key of a DISCON.IN line (``value ! Key - comment``), or None."""
    m = _LINE.match(line)
    return m["key"] if m else None


def read_discon(path: Path, field: str = "--rosco", where: str | None = None
                ) -> dict[str, str]:
    """Key → value text of a ROSCO DISCON.IN (``value ! Key - comment`` lines), read as a
    user's file; ``field`` and ``where`` name what gave its path (an option, or a file and
    key). A key given twice is refused (ROSCO reads the first; which one was meant?)."""
    try:
        text = read_user_text(path, field, openfast_deck.MAX_DECK_BYTES)
    except ConfigError as exc:
        raise ConfigError(field, exc.value, f"{exc.allowed} (a ROSCO DISCON.IN)",
                          where=where) from None
    out: dict[str, str] = {}
    line_of: dict[str, int] = {}
    for n, line in enumerate(text.splitlines(), 1):
        m = _LINE.match(line)
        if not (m and m["value"]):
            continue
        key, value = m["key"], m["value"].strip()
        if key in out:
            raise ConfigError(key, value, f"each key once: line {line_of[key]} gives it as "
                              f"{out[key]!r} and line {n} again (ROSCO reads the first; "
                              "delete the one not meant)", where=str(path))
        out[key], line_of[key] = value, n
    return out


def _number(d: dict, key: str, path: Path) -> float:
    if key not in d:
        raise ConfigError(key, "missing", "a value in the DISCON.IN", where=str(path))
    try:
        v = float(d[key].split()[0])
    except (ValueError, IndexError):
        raise ConfigError(key, d[key], "a number", where=str(path)) from None
    if not math.isfinite(v):
        raise ConfigError(key, d[key], "a finite number", where=str(path))
    return v


def _check_rated(g: dict, path: Path) -> None:
    """VS_GenEff a percentage, and the rated torque the law reaches, VS_RtPwr / (VS_GenEff
    / 100) / PC_RefSpd, VS_RtTq's to 1 % (ROSCO's tuning computes it so; an efficiency
    written as a fraction, 0.944 for 94.4, would otherwise pass 100 × the power)."""
    eff = g["VS_GenEff"]
    if not 0 < eff <= 100:
        raise ConfigError("VS_GenEff", eff, "the generator efficiency in percent, in (0, "
                          "100]", where=str(path))
    if g["PC_RefSpd"] > 0 and g["VS_RtTq"] > 0:
        law = g["VS_RtPwr"] / (eff / 100.0) / g["PC_RefSpd"]
        if not _agrees(law, g["VS_RtTq"], 0.01):
            raise ConfigError("VS_RtTq", g["VS_RtTq"], "VS_RtPwr / (VS_GenEff / 100) / "
                              f"PC_RefSpd within 1 % ({law:.6g} N m: the files contradict, "
                              "or VS_GenEff is not in percent)", where=str(path))


def _agrees(a: float, b: float, rel: float) -> bool:
    """|a - b| <= rel |b|, False for NaN (every comparison with NaN is)."""
    return abs(a - b) <= rel * abs(b)


#: turbine parameter → (the DISCON.IN key it comes from, how)
_FROM_DISCON = {
    "omega_g_rated": ("PC_RefSpd", "PC_RefSpd / GBRatio"),
    "gen_torque_rated": ("VS_RtTq", "VS_RtTq × GBRatio"),
    "gen_efficiency": ("VS_GenEff", "VS_GenEff / 100"),
    "pitch_min": ("PC_MinPit", "PC_MinPit"), "pitch_max": ("PC_MaxPit", "PC_MaxPit"),
    "pitch_rate_max": ("PC_MaxRat", "PC_MaxRat"), "air_density": ("WE_RhoAir", "WE_RhoAir"),
    "vs_cut_in_speed": ("VS_MinOMSpd", "VS_MinOMSpd / GBRatio"),
    "vs_region2_k": ("VS_Rgn2K", "VS_Rgn2K × GBRatio³"),
    "vs_rated_power": ("VS_RtPwr", "VS_RtPwr / (VS_GenEff / 100): ROSCO's rated power is "
                       "electrical, the law's mechanical"),
    "vs_max_torque": ("VS_MaxTq", "VS_MaxTq × GBRatio")}


def from_discon(path: Path, gear: float, d: dict | None = None
                ) -> tuple[dict, dict, Path, dict]:
    """(values, sources, Cp file, the raw numbers read) from a DISCON.IN (its key → text
    ``d``, read if not given), referred to the LSS by ``gear``."""
    d = read_discon(path) if d is None else d
    g = {k: _number(d, k, path) for k in DISCON_KEYS}
    if not _agrees(g["WE_GearboxRatio"], gear, 5e-3):  # DISCON.IN rounds it (BAR-10)
        raise ConfigError("WE_GearboxRatio", g["WE_GearboxRatio"],
                          f"the deck's GBRatio {gear:g} within 0.5 % (the files contradict)",
                          where=str(path))
    _check_rated(g, path)
    values = {"omega_g_rated": g["PC_RefSpd"] / gear, "gen_torque_rated": g["VS_RtTq"] * gear,
              "gen_efficiency": g["VS_GenEff"] / 100.0, "pitch_min": g["PC_MinPit"],
              "pitch_max": g["PC_MaxPit"], "pitch_rate_max": g["PC_MaxRat"],
              "air_density": g["WE_RhoAir"], "vs_cut_in_speed": g["VS_MinOMSpd"] / gear,
              "vs_region2_k": g["VS_Rgn2K"] * gear * gear * gear,
              "vs_rated_power": g["VS_RtPwr"] / (g["VS_GenEff"] / 100.0),
              "vs_max_torque": g["VS_MaxTq"] * gear}
    sources = {k: f"{path.name}: {how}" for k, (_, how) in _FROM_DISCON.items()}
    cp = d.get("PerfFileName", "").strip().strip('"').strip("'")
    if not cp:
        raise ConfigError("PerfFileName", "missing", "the Cp_Ct_Cq file", where=str(path))
    cp_path = Path(cp) if Path(cp).is_absolute() else path.parent / cp
    return values, sources, cp_path, g


def discon_only(discon: Path) -> None:
    """A DISCON.IN alone cannot describe the plant: refused naming what it lacks (its
    values are read first, so that a bad file is named for what is wrong with it)."""
    d = read_discon(discon)
    from_discon(discon, _number(d, "WE_GearboxRatio", discon), d)
    raise ConfigError("params.J_r, J_g, k_s, d_s", "missing", f"{discon.name} gives the "
                      "total inertia WE_Jtot only and no drivetrain stiffness or damping: "
                      "give the OpenFAST deck with --openfast (ElastoDyn has them)",
                      where=str(discon))


# ------------------------------------------------------------------------------ together

def _cross_check(values: dict, g: dict, discon: Path, blade_file: Path) -> None:
    """What both files give must agree (NaN agrees with nothing)."""
    radius = values["rotor_radius"]
    if not _agrees(g["WE_BladeRadius"], radius, 5e-3):
        raise ConfigError("WE_BladeRadius", g["WE_BladeRadius"], f"the deck's TipRad "
                          f"{radius:g} m within 0.5 % (the files contradict)",
                          where=str(discon))
    total = values["J_r"] + values["J_g"]
    if not (total > 0 and 0.7 <= g["WE_Jtot"] / total <= 1.3):
        raise ConfigError("WE_Jtot", g["WE_Jtot"], f"within 30 % of the deck's J_r + J_g = "
                          f"{total:.6g} kg m² (J_r from {blade_file.name}'s BMassDen × "
                          "AdjBlMs and ElastoDyn's HubIner, J_g from its GenIner: the files "
                          "contradict; an ElastoDyn blade file in the older format with a "
                          "PitchAxis column is misread by openfast-io 5: docs/turbines.md)",
                          where=str(discon))


def _cp(cp: Path, discon: Path) -> tuple[bytes, CpTable]:
    """The Cp table's bytes, read as a user's file and parsed as every command parses it
    (a table with NaN, a row short, a binary file: refused naming the file)."""
    try:
        raw = read_user_bytes(cp, "PerfFileName", MAX_TABLE_BYTES)
    except ConfigError as exc:
        raise ConfigError("PerfFileName", exc.value, f"{exc.allowed} (the Cp_Ct_Cq file)",
                          where=str(discon)) from None
    table = parse_cp_table(raw, str(cp))
    if not table.cp_max()[0] > 0:
        raise ConfigError("cp_table", f"Cp at most {table.cp_max()[0]:g}", "a table with a "
                          "positive power coefficient somewhere (a rotor that makes power)",
                          where=str(cp))
    return raw, table


def _defaults(values: dict, sources: dict) -> None:
    """The actuator (the benchmark's: Odgaard 2013, no deck gives one) and the torque
    law's region-2 and rated-speed corners in the NREL 5-MW's proportions."""
    on, zeta = ACTUATOR["omega_n_nominal"], ACTUATOR["zeta_nominal"]
    nrel = "the NREL 5-MW's proportions (Jonkman 2009, 7.1)"
    values.update({
        "omega_n_nominal": on, "zeta_nominal": zeta, "tau_b": 2 * zeta / on,
        "gen_constant_power": 0.0, "gen_torque_law": 0.0, "vs_constant_torque": 0.0,
        "vs_slip": 0.1,
        "vs_region2_speed": values["vs_cut_in_speed"] * (91.21091 / 70.16224),
        "vs_rated_speed": values["omega_g_rated"] * (121.6805 / 122.90967)})
    sources.update({
        "omega_n_nominal": "the benchmark's hydraulic actuator (Odgaard 2013): the deck "
                           "has no actuator model (docs/turbines.md)",
        "zeta_nominal": "the benchmark's hydraulic actuator (Odgaard 2013)",
        "tau_b": "2ζ/ω_n of the actuator (its first-order equivalent)",
        "gen_constant_power": "constant torque above rated (a run option)",
        "gen_torque_law": "rated torque (a run option; 1: the baseline law below)",
        "vs_constant_torque": "the baseline law's region 3 at constant power (a run option; "
                              "1: constant torque)",
        "vs_slip": f"10 %, {nrel}",
        "vs_region2_speed": f"VS_MinOMSpd × 91.21091/70.16224, {nrel}",
        "vs_rated_speed": f"rated speed × 121.6805/122.90967, {nrel}"})


def import_turbine(fst: Path, discon: Path | None = None) -> Imported:
    """Every turbine parameter from the deck and its DISCON.IN (``discon``, else the one
    ServoDyn's ``DLL_InFile`` names), and the Cp table; nothing written."""
    deck = openfast_deck.read(fst, servo=discon is None)
    values, sources, origins = _deck_values(deck)
    field, where = ("--rosco", None) if discon is not None else ("DLL_InFile",
                                                                  str(deck.sd_file))
    discon = discon if discon is not None else deck.discon
    d = read_discon(discon, field, where)
    v2, s2, cp, g = from_discon(discon, values["gearbox_ratio"], d)
    values.update(v2)
    sources.update(s2)
    origins.update({k: (discon, key, g[key]) for k, (key, _) in _FROM_DISCON.items()})
    origins["vs_region2_speed"] = origins["vs_cut_in_speed"]
    origins["vs_rated_speed"] = origins["omega_g_rated"]
    _cross_check(values, g, discon, deck.blade_file)
    total = values["J_r"] + values["J_g"]
    sources["J_r"] += (f"; {discon.name}'s WE_Jtot {g['WE_Jtot']:.6g} kg m² differs from "
                       f"J_r + J_g = {total:.6g} by {100 * (g['WE_Jtot'] / total - 1):+.1f} %")
    _defaults(values, sources)
    raw, table = _cp(cp, discon)
    return Imported(values, sources, origins, cp, raw, table, discon, Path(fst))


# ------------------------------------------------------------------------------ writing

def check_out(out: Path, overwrite: bool = False) -> Path:
    """``--out``: a turbine file name (.toml) outside the installed package, not an
    existing file unless ``overwrite``, in a folder that exists or can be made."""
    if not str(out) or out.suffix != ".toml" or out.name == ".toml":
        raise ConfigError("--out", str(out), "a turbine file name ending in .toml")
    check_new_file(out, "--out", overwrite)
    probe = out.absolute().parent
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    if not probe.is_dir():
        raise ConfigError("--out", str(out), f"a file in a folder ({probe} is not a folder)")
    return out


def _text_arg(value: str, option: str, pattern: re.Pattern | None, allowed: str) -> str:
    ok = (pattern.fullmatch(value) if pattern is not None else
          0 < len(value) <= MAX_TITLE and value.isprintable() and value == value.strip())
    if not ok:
        raise ConfigError(option, value, allowed)
    return value


def _utf8(path: Path, field: str) -> str:
    """A path written into the turbine file: text that reads back as the same path."""
    s = str(path)
    try:
        s.encode("utf-8")
    except UnicodeEncodeError:
        raise ConfigError(field, s, "a path that is UTF-8 text (the turbine file names "
                          "it)") from None
    return s


def render(imp: Imported, name: str, title: str, header: str = "") -> str:
    """The turbine file's text (nothing written)."""
    from wtftc.model import turbine_file

    _text_arg(name, "--name", NAME, "a short name: 1-64 letters, digits, '_', '.' or '-', "
              "starting with a letter or digit (like nrel5mw)")
    _text_arg(title, "--title", None, f"one line of 1-{MAX_TITLE} printable characters")
    cp_name = _utf8(Path(imp.cp.name), "PerfFileName")
    return turbine_file.text(name, title, cp_name, imp.values, imp.sources, header,
                             _utf8(imp.discon.resolve(), "DLL_InFile"),
                             _utf8(imp.fst.resolve(), "--openfast") if imp.fst else None)


def _blamed(exc: ConfigError, imp: Imported, tmp: str, out: Path) -> ConfigError:
    """A refusal of the turbine file that would be written (``tmp``: its temporary copy)
    blamed on the file and key(s) its value came from, with the value there; any other
    refusal named on ``out``, never on the temporary copy."""
    name = exc.field.split(".", 1)[-1]
    allowed = exc.allowed
    if exc.field == "reference_rad_s":  # a run regulates to the rated speed by default
        name, allowed = "omega_g_rated", f"a rated speed a run can regulate to, {allowed}"
    if name not in imp.origins:
        where = str(out) if exc.where in (tmp, None) else exc.where
        return ConfigError(exc.field, exc.value, f"{allowed} (in the turbine file this "
                           "import would write)", where=where)
    path, keys, raw = imp.origins[name]
    pair = re.match(r"(\w+) < (\w+) ", allowed)
    if pair and pair[2] in imp.origins and imp.origins[pair[2]][0] == path:
        _, high_keys, high_raw = imp.origins[pair[2]]
        low_keys, low_raw = imp.origins[pair[1]][1:]
        return ConfigError(f"{low_keys}, {high_keys}", (low_raw, high_raw),
                           f"{low_keys} < {high_keys} (the turbine's {pair[1]} < {pair[2]})",
                           where=str(path))
    verb = "is" if allowed.startswith("a ") else "satisfies"
    value = f"{exc.value:.6g}" if isinstance(exc.value, float) else repr(exc.value)
    return ConfigError(keys, raw, f"a value for which the turbine's {name} (from {keys}; "
                       f"here {value}) {verb} {allowed}", where=str(path))


def validate(imp: Imported, text: str, out: Path, check=None) -> None:
    """The turbine file ``text`` read as every command reads one
    (:func:`wtftc.model.turbine_file.parse`), then given to ``check`` (a function of a
    turbine file's path: the CLI's is ``wtftc.config.make_config`` on it, what
    ``wtftc run --turbine FILE`` checks) as a copy with its table in a private temporary
    folder, never in the user's. A refusal names the file and key a value came from."""
    from wtftc.model import turbine_file

    turbine_file.parse(text, out, cp_must_exist=False)
    if check is None:
        return
    with tempfile.TemporaryDirectory(prefix="wtftc-import-") as tmp:
        path = Path(tmp) / out.name
        path.write_text(text, encoding="utf-8")
        (Path(tmp) / imp.cp.name).write_bytes(imp.cp_bytes)
        try:
            check(path)
        except ConfigError as exc:
            raise _blamed(exc, imp, str(path), out) from None


def _tables_users(folder: Path, table: str) -> list[Path]:
    """The turbine files in ``folder`` whose cp_table is ``table`` (beside them)."""
    import tomllib

    users = []
    for t in sorted(folder.glob("*.toml")) if folder.is_dir() else ():
        try:
            doc = tomllib.loads(read_user_text(t, "--out", 16 * 1024 * 1024))
        except (ConfigError, tomllib.TOMLDecodeError):
            continue
        if doc.get("cp_table") == table:
            users.append(t)
    return users


def write(out: Path, imp: Imported, name: str, title: str, header: str = "",
          overwrite: bool = False, check=None) -> tuple[Path, Path]:
    """The turbine file ``out`` (.toml) and beside it a copy of its Cp table, validated
    first (:func:`validate`), then written together or not at all
    (:func:`wtftc.files.write_files_together`). Never into the installed package; an
    existing file is replaced only with ``overwrite`` (a table with the same bytes is
    shared, untouched). (turbine file, table)."""
    check_out(out, overwrite)
    table = out.parent / imp.cp.name
    if table.name == out.name:
        raise ConfigError("--out", str(out), f"a name other than the Cp table's "
                          f"({imp.cp.name}, copied beside it)")
    text = render(imp, name, title, header)
    validate(imp, text, out, check)

    def same(p: Path) -> bool:
        return p.stat().st_size == len(imp.cp_bytes) and p.read_bytes() == imp.cp_bytes

    files = {check_out(out, overwrite): text.encode("utf-8")}
    users = [t.name for t in _tables_users(out.parent, table.name) if t.name != out.name]
    if users and table.is_file() and not same(table):  # --overwrite never reaches it
        raise ConfigError("--out", str(out), f"a folder where the Cp table {table.name} is "
                          f"this turbine's alone ({', '.join(sorted(users))} uses the one "
                          "there, with other values; import into another folder; nothing "
                          "was written)")
    check_new_file(table, "--out (the Cp table copied beside it)", overwrite, ours=same)
    if not (table.is_file() and same(table)):
        files[table] = imp.cp_bytes
    write_files_together(files)
    return out, table
