"""``wtftc turbine import``: a turbine file from an OpenFAST deck and a ROSCO DISCON.IN.

The OpenFAST deck is read with ``openfast-io`` (NREL's maintained reader and writer of
OpenFAST input files, PyPI ``openfast-io``; optional extra ``wtftc[import]``): the main
file, ElastoDyn and its blade file, and ServoDyn. The DISCON.IN is read here, line by
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
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np

from wtftc.errors import ConfigError

#: the benchmark actuator (Odgaard 2013), the default of a turbine whose deck has none
ACTUATOR = {"omega_n_nominal": 11.11, "zeta_nominal": 0.6}


def _reader(fst: Path):
    try:
        from openfast_io.FAST_reader import InputReader_OpenFAST
    except ImportError as exc:
        raise ConfigError("--openfast", str(fst), "openfast-io installed: pip install "
                          f"'wtftc[import]' ({exc})") from None
    f = InputReader_OpenFAST()
    f.FAST_InputFile, f.FAST_directory = fst.name, str(fst.parent)
    return f


def read_deck(fst: Path) -> tuple[dict, dict]:
    """(values, sources) of the deck's ElastoDyn: inertias, drivetrain, gearbox, radius."""
    if not fst.is_file():
        raise ConfigError("--openfast", str(fst), "an OpenFAST main input file (.fst)")
    f = _reader(fst)
    f.read_MainInput()
    ed_file = Path(os.path.realpath(fst.parent / f.fst_vt["Fst"]["EDFile"]))
    f.read_ElastoDyn(str(ed_file))
    ed = f.fst_vt["ElastoDyn"]
    blade_file = ed_file.parent / ed["BldFile1"]
    f.read_ElastoDynBlade(str(blade_file), 0)
    bl = f.fst_vt["ElastoDynBlade"][0]
    j_rotor = rotor_inertia(ed, bl)
    tower_file = ed_file.parent / ed["TwrFile"]
    f.read_ElastoDynTower(str(tower_file))
    tower, tower_sources = tower_mode(ed, bl, f.fst_vt["ElastoDynTower"], tower_file.name)
    n = float(ed["GBRatio"])
    src = ed_file.name
    values = {"J_r": j_rotor, "J_g": float(ed["GenIner"]) * n**2, "k_s": float(ed["DTTorSpr"]),
              "d_s": float(ed["DTTorDmp"]), "gearbox_ratio": n,
              "rotor_radius": float(ed["TipRad"])}
    sources = {
        "J_r": f"{src}: {ed['NumBl']} blades' BMassDen × AdjBlMs of {blade_file.name} about "
               f"the rotor axis (HubRad {ed['HubRad']} m to TipRad {ed['TipRad']} m, "
               f"precone) + HubIner {ed['HubIner']} kg m²",
        "J_g": f"{src}: GenIner {ed['GenIner']} kg m² (HSS) × GBRatio²",
        "k_s": f"{src}: DTTorSpr", "d_s": f"{src}: DTTorDmp", "gearbox_ratio": f"{src}: GBRatio",
        "rotor_radius": f"{src}: TipRad"}
    values.update(tower)
    sources.update({k: f"{src}, {v}" for k, v in tower_sources.items()})
    return values, sources


def tower_mode(ed: dict, blade: dict, tower: dict, name: str) -> tuple[dict, dict]:
    """The tower's first fore-aft mode from ElastoDyn [SI]: the mode shape φ(h) =
    Σ TwFAM1Sh(k) h^k (k = 2..6, h the height fraction over the flexible tower, φ(1) = 1),
    modal mass m_t = m_RNA + ∫ μ φ² dz (the rotor-nacelle assembly at the top: hub,
    nacelle, yaw bearing and blades), modal stiffness k_t = ∫ EI (φ'')² dz (Rayleigh's
    quotient: an assumed shape overestimates the frequency; the tower-top inertia is
    left out), damping ratio TwrFADmp(1), and the moment arm of the rotor over the tower
    base, TowerHt + Twr2Shft - TowerBsHt."""
    height = float(ed["TowerHt"]) - float(ed["TowerBsHt"])
    frac = np.asarray(tower["HtFract"], float)
    h = np.linspace(0.0, 1.0, 20001)
    mu = np.interp(h, frac, np.asarray(tower["TMassDen"], float)) * float(tower["AdjTwMa"])
    ei = np.interp(h, frac, np.asarray(tower["TwFAStif"], float)) * float(tower["AdjFASt"])
    c = [float(x) for x in tower["TwFAM1Sh"]]
    phi = sum(ck * h ** (k + 2) for k, ck in enumerate(c))
    curv = sum(ck * (k + 2) * (k + 1) * h**k for k, ck in enumerate(c)) / height**2
    r = float(ed["HubRad"]) + np.asarray(blade["BlFract"], float) * (
        float(ed["TipRad"]) - float(ed["HubRad"]))
    m_blade = float(np.trapezoid(np.asarray(blade["BMassDen"], float), r)) * float(
        blade.get("AdjBlMs", 1.0))
    rna = (float(ed["HubMass"]) + float(ed["NacMass"]) + float(ed.get("YawBrMass", 0.0))
           + float(ed["NumBl"]) * m_blade)
    mass = rna + height * float(np.trapezoid(mu * phi**2, h))
    values = {"tower_modal_mass": mass,
              "tower_stiffness": height * float(np.trapezoid(ei * curv**2, h)),
              "tower_damping_ratio": float(tower["TwrFADmp1"]) / 100.0,
              "tower_moment_arm": float(ed["TowerHt"]) + float(ed["Twr2Shft"])
              - float(ed["TowerBsHt"])}
    f1 = math.sqrt(values["tower_stiffness"] / mass) / (2 * math.pi)
    sources = {
        "tower_modal_mass": f"{name}: rotor-nacelle assembly {rna:.6g} kg (HubMass, NacMass, "
                            "YawBrMass, NumBl × blade mass) + ∫ TMassDen × AdjTwMa × φ² dz, "
                            "φ the TwFAM1Sh mode shape",
        "tower_stiffness": f"{name}: ∫ TwFAStif × AdjFASt × φ''² dz (Rayleigh's quotient: "
                           f"first fore-aft frequency {f1:.4f} Hz, an upper bound)",
        "tower_damping_ratio": f"{name}: TwrFADmp(1) / 100",
        "tower_moment_arm": "TowerHt + Twr2Shft - TowerBsHt"}
    return values, sources


def rotor_inertia(ed: dict, blade: dict) -> float:
    """Blades and hub about the rotor axis [kg m²], from ElastoDyn's blade mass
    distribution (linear between stations, integrated on a fine grid)."""
    frac, mass = np.asarray(blade["BlFract"], float), np.asarray(blade["BMassDen"], float)
    hub, tip = float(ed["HubRad"]), float(ed["TipRad"])
    r = hub + frac * (tip - hub)
    precone = math.radians(float(ed.get("PreCone(1)", ed.get("PreCone1", 0.0))))
    rr = np.linspace(r[0], r[-1], 20001)
    m = np.interp(rr, r, mass) * float(blade.get("AdjBlMs", 1.0))
    return float(ed["NumBl"]) * float(np.trapezoid(m * (rr * math.cos(precone)) ** 2, rr)) \
        + float(ed["HubIner"])


_LINE = re.compile(r"^\s*(?P<value>[^!]*?)\s*!\s*(?P<key>[A-Za-z_][A-Za-z0-9_]*)")


def line_key(line: str) -> str | None:
    """The key of a DISCON.IN line (``value ! Key - comment``), or None."""
    m = _LINE.match(line)
    return m["key"] if m else None


def read_discon(path: Path) -> dict[str, str]:
    """Key → value text of a ROSCO DISCON.IN (``value ! Key - comment`` lines)."""
    if not path.is_file():
        raise ConfigError("--rosco", str(path), "a ROSCO DISCON.IN file")
    out = {}
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        m = _LINE.match(line)
        if m and m["value"]:
            out[m["key"]] = m["value"].strip()
    return out


def _number(d: dict, key: str, path: Path) -> float:
    if key not in d:
        raise ConfigError(key, "missing", "a value in the DISCON.IN", where=str(path))
    try:
        return float(d[key].split()[0])
    except ValueError:
        raise ConfigError(key, d[key], "a number", where=str(path)) from None


def from_discon(path: Path, gear: float) -> tuple[dict, dict, Path, dict]:
    """(values, sources, Cp file, the raw numbers read) from a DISCON.IN, referred to the
    LSS by ``gear``."""
    d = read_discon(path)
    g = {k: _number(d, k, path) for k in (
        "PC_RefSpd", "VS_RtTq", "VS_RtPwr", "VS_GenEff", "PC_MinPit", "PC_MaxPit",
        "PC_MaxRat", "WE_RhoAir", "VS_MinOMSpd", "VS_Rgn2K", "VS_MaxTq", "WE_GearboxRatio",
        "WE_BladeRadius", "WE_Jtot")}
    if abs(g["WE_GearboxRatio"] - gear) > 5e-3 * gear:  # DISCON.IN rounds it (BAR-10)
        raise ConfigError("WE_GearboxRatio", g["WE_GearboxRatio"],
                          f"the deck's GBRatio {gear:g} within 0.5 % (the files contradict)",
                          where=str(path))
    name = path.name
    values = {"omega_g_rated": g["PC_RefSpd"] / gear, "gen_torque_rated": g["VS_RtTq"] * gear,
              "gen_efficiency": g["VS_GenEff"] / 100.0, "pitch_min": g["PC_MinPit"],
              "pitch_max": g["PC_MaxPit"], "pitch_rate_max": g["PC_MaxRat"],
              "air_density": g["WE_RhoAir"], "vs_cut_in_speed": g["VS_MinOMSpd"] / gear,
              "vs_region2_k": g["VS_Rgn2K"] * gear**3, "vs_rated_power": g["VS_RtPwr"],
              "vs_max_torque": g["VS_MaxTq"] * gear}
    keys = {"omega_g_rated": "PC_RefSpd / GBRatio", "gen_torque_rated": "VS_RtTq × GBRatio",
            "gen_efficiency": "VS_GenEff / 100", "pitch_min": "PC_MinPit",
            "pitch_max": "PC_MaxPit", "pitch_rate_max": "PC_MaxRat", "air_density": "WE_RhoAir",
            "vs_cut_in_speed": "VS_MinOMSpd / GBRatio", "vs_region2_k": "VS_Rgn2K × GBRatio³",
            "vs_rated_power": "VS_RtPwr", "vs_max_torque": "VS_MaxTq × GBRatio"}
    sources = {k: f"{name}: {v}" for k, v in keys.items()}
    cp = d.get("PerfFileName", "").strip().strip('"').strip("'")
    if not cp:
        raise ConfigError("PerfFileName", "missing", "the Cp_Ct_Cq file", where=str(path))
    cp_path = Path(cp) if Path(cp).is_absolute() else path.parent / cp
    return values, sources, cp_path, g


def servodyn_discon(fst: Path) -> Path:
    """The DISCON.IN the deck's ServoDyn names (DLL_InFile)."""
    f = _reader(fst)
    f.read_MainInput()
    f.read_ServoDyn()
    return Path(os.path.normpath(fst.parent / f.fst_vt["ServoDyn"]["DLL_InFile"]))


def discon_only(discon: Path) -> None:
    """A DISCON.IN alone cannot describe the plant: refused naming what it lacks (its
    values are read first, so that a bad file is named for what is wrong with it)."""
    d = read_discon(discon)
    from_discon(discon, _number(d, "WE_GearboxRatio", discon))
    raise ConfigError("params.J_r, J_g, k_s, d_s", "missing", f"{discon.name} gives the "
                      "total inertia WE_Jtot only and no drivetrain stiffness or damping: "
                      "give the OpenFAST deck with --openfast (ElastoDyn has them)",
                      where=str(discon))


def import_turbine(fst: Path, discon: Path | None = None) -> tuple[dict, dict, Path, Path]:
    """(values, sources, Cp file) of every turbine parameter from the deck and its
    DISCON.IN (and its path): the actuator is the benchmark's (Odgaard 2013: no deck
    gives one), the torque law's region-2 and rated-speed corners in the NREL 5-MW's
    proportions."""
    values, sources = read_deck(fst)
    discon = discon or servodyn_discon(fst)
    v2, s2, cp, g = from_discon(discon, values["gearbox_ratio"])
    values.update(v2)
    sources.update(s2)
    if abs(g["WE_BladeRadius"] - values["rotor_radius"]) > 5e-3 * values["rotor_radius"]:
        raise ConfigError("WE_BladeRadius", g["WE_BladeRadius"], "the deck's TipRad "
                          f"{values['rotor_radius']:g} m within 0.5 % (the files contradict)",
                          where=str(discon))
    total = values["J_r"] + values["J_g"]
    if not 0.7 <= g["WE_Jtot"] / total <= 1.3:
        raise ConfigError("WE_Jtot", g["WE_Jtot"], f"within 30 % of the deck's J_r + J_g = "
                          f"{total:.6g} kg m² (the files contradict; an ElastoDyn blade file "
                          "in the older format with a PitchAxis column is misread by "
                          "openfast-io 5: docs/turbines.md)", where=str(discon))
    sources["J_r"] += (f"; {discon.name}'s WE_Jtot {g['WE_Jtot']:.6g} kg m² differs from "
                       f"J_r + J_g = {total:.6g} by {100 * (g['WE_Jtot'] / total - 1):+.1f} %")
    on, zeta = ACTUATOR["omega_n_nominal"], ACTUATOR["zeta_nominal"]
    nrel = "the NREL 5-MW's proportions (Jonkman 2009, 7.1)"
    values.update({
        "omega_n_nominal": on, "zeta_nominal": zeta, "tau_b": 2 * zeta / on,
        "gen_constant_power": 0.0, "gen_torque_law": 0.0, "vs_slip": 0.1,
        "vs_region2_speed": values["vs_cut_in_speed"] * (91.21091 / 70.16224),
        "vs_rated_speed": values["omega_g_rated"] * (121.6805 / 122.90967)})
    sources.update({
        "omega_n_nominal": "the benchmark's hydraulic actuator (Odgaard 2013): the deck "
                           "has no actuator model (docs/turbines.md)",
        "zeta_nominal": "the benchmark's hydraulic actuator (Odgaard 2013)",
        "tau_b": "2ζ/ω_n of the actuator (its first-order equivalent)",
        "gen_constant_power": "constant torque above rated (a run option)",
        "gen_torque_law": "rated torque (a run option; 1: the baseline law below)",
        "vs_slip": f"10 %, {nrel}",
        "vs_region2_speed": f"VS_MinOMSpd × 91.21091/70.16224, {nrel}",
        "vs_rated_speed": f"rated speed × 121.6805/122.90967, {nrel}"})
    return values, sources, cp, discon


def write(out: Path, name: str, title: str, values: dict, sources: dict, cp: Path,
          header: str = "", rosco_discon: str | None = None) -> Path:
    """The turbine file ``out`` (.toml) and beside it a copy of its Cp table, each written
    whole (a temporary file renamed into place); read back to check it."""
    from wtftc.model import turbine_file

    if out.suffix != ".toml":
        raise ConfigError("--out", str(out), "a turbine file name ending in .toml")
    if not cp.is_file():
        raise ConfigError("PerfFileName", str(cp), "an existing Cp_Ct_Cq file")
    out.parent.mkdir(parents=True, exist_ok=True)
    for target, data in ((out.parent / cp.name, cp.read_bytes()),
                         (out, turbine_file.text(name, title, cp.name, values, sources,
                                                 header, rosco_discon).encode())):
        tmp = target.with_name(f".{target.name}.tmp")
        tmp.write_bytes(data)
        os.replace(tmp, target)
    turbine_file.read(out)
    return out
