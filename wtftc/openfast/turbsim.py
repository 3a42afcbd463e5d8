"""TurbSim full fields for OpenFAST runs in turbulence (issue 32 item 4; ours).

A field is set by its inputs: mean wind at hub height, IEC turbulence class and model
(NTM, or ETM of a turbine class), seed, hub height, grid (points and size), time step and
length. Each is generated once, into wtftc's cache (``turbsim/<key>.bts``, the key a hash
of the input file's text), and shared by every run and Dask worker that asks for it; a
field is written beside its final name and renamed into place, never half-written.

TurbSim's cost grows steeply with its grid (shared/openfast/README.md: 263 s for a 110-s
field on 31 × 31 points, 9 s for 600 s on 13 × 13). The default grid is 13 × 13 points over
a square 15 % wider than the rotor, and the tower's points below it (AeroDyn's tower
influence reads the wind down to the ground): the rotor-scale eddies the controller and
the loads respond to, at a cost of seconds.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from wtftc.artefacts.loader import cache_dir
from wtftc.errors import ConfigError, EngineError
from wtftc.openfast import install

#: the grid's points per side, and its size over the rotor's diameter
GRID_POINTS = 13
GRID_OVER_DIAMETER = 1.15
#: the field's time step [s]
FIELD_DT = 0.05
#: RandSeed1's range (TurbSim: a signed 32-bit integer)
SEED_MAX = 2**31 - 1


@dataclass(frozen=True)
class Field:
    """What sets a field (TurbSim's inputs)."""

    mean_mps: float  # at hub height
    turbulence_class: str  # IEC "A", "B", "C"
    seed: int
    hub_height_m: float
    rotor_radius_m: float
    t_final_s: float
    wind_type: str = "NTM"  # TurbSim's IEC_WindType
    points: int = GRID_POINTS
    dt_s: float = FIELD_DT

    def input_text(self) -> str:
        """The TurbSim input file (v2 format, IEC Kaimal model with IEC coherence)."""
        if not 0 <= self.seed <= SEED_MAX:
            raise ConfigError("wind.seed", self.seed, f"an integer in [0, {SEED_MAX}] for "
                              "TurbSim (RandSeed1)")
        size = GRID_OVER_DIAMETER * 2 * self.rotor_radius_m
        if size / 2 >= self.hub_height_m:
            size = 1.9 * self.hub_height_m  # TurbSim: the grid stays above the ground
        rows = [
            ("False", "Echo"), (str(self.seed), "RandSeed1"), ("RANLUX", "RandSeed2"),
            ("False", "WrBHHTP"), ("False", "WrFHHTP"), ("False", "WrADHH"),
            ("True", "WrADFF"), ("False", "WrBLFF"), ("True", "WrADTWR"),
            ("False", "WrFMTFF"), ("False", "WrACT"), ("True", "Clockwise"),
            ("0", "ScaleIEC"), (None, "Turbine/Model Specifications"),
            (str(self.points), "NumGrid_Z"), (str(self.points), "NumGrid_Y"),
            (f"{self.dt_s:g}", "TimeStep"), (f"{self.t_final_s:g}", "AnalysisTime"),
            (f"{self.t_final_s:g}", "UsableTime"), (f"{self.hub_height_m:g}", "HubHt"),
            (f"{size:.6g}", "GridHeight"), (f"{size:.6g}", "GridWidth"),
            ("0", "VFlowAng"), ("0", "HFlowAng"), (None, "Meteorological Boundary Conditions"),
            ('"IECKAI"', "TurbModel"), ('"unused"', "UserFile"), ('"1-Ed3"', "IECstandard"),
            (f'"{self.turbulence_class}"', "IECturbc"), (f'"{self.wind_type}"', "IEC_WindType"),
            ("default", "ETMc"), ('"PL"', "WindProfileType"), ('"unused"', "ProfileFile"),
            (f"{self.hub_height_m:g}", "RefHt"), (f"{self.mean_mps:.9g}", "URef"),
            ("default", "ZJetMax"), ("default", "PLExp"), ("default", "Z0"),
            (None, "Non-IEC Meteorological Boundary Conditions"),
            ("default", "Latitude"), ("0.05", "RICH_NO"), ("default", "UStar"),
            ("default", "ZI"), ("default", "PC_UW"), ("default", "PC_UV"), ("default", "PC_VW"),
            (None, "Spatial Coherence Parameters"),
            ("default", "SCMod1"), ("default", "SCMod2"), ("default", "SCMod3"),
            ("default", "InCDec1"), ("default", "InCDec2"), ("default", "InCDec3"),
            ("default", "CohExp"), (None, "Coherent Turbulence Scaling Parameters"),
            ('"unused"', "CTEventPath"), ('"Random"', "CTEventFile"), ("true", "Randomize"),
            ("1.0", "DistScl"), ("0.5", "CTLy"), ("0.5", "CTLz"), ("30.0", "CTStartTime"),
        ]
        out = ["---------TurbSim v2.00.* Input File------------------------",
               "written by wtftc (wtftc.openfast.turbsim)",
               "---------Runtime Options-----------------------------------"]
        for value, key in rows:
            out += ["", f"--------{key}-------"] if value is None else [f"{value:<12} {key}"]
        return "\n".join(out) + "\n==================================================\n"

    def key(self) -> str:
        return hashlib.sha256(self.input_text().encode()).hexdigest()[:20]


def field_path(f: Field) -> Path:
    return cache_dir() / "turbsim" / f"{f.key()}.bts"


def generate(f: Field) -> Path:
    """The field's ``.bts``, generated by TurbSim once into the cache."""
    path = field_path(f)
    if path.is_file():
        return path
    exe = install.require().turbsim
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".turbsim-", dir=path.parent))
    try:
        (tmp / "field.inp").write_text(f.input_text())
        done = subprocess.run([str(exe), "field.inp"], cwd=tmp, capture_output=True,
                              text=True, stdin=subprocess.DEVNULL)
        made = tmp / "field.bts"
        if done.returncode != 0 or not made.is_file():
            last = [ln.strip() for ln in (done.stdout + done.stderr).splitlines()
                    if ln.strip()][-3:]
            raise EngineError(f"TurbSim failed (exit code {done.returncode}): "
                              + " ".join(last))
        os.replace(made, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return path
