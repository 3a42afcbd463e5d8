"""TurbSim full fields: what sets one, where it is cached, and reading one back (issue 32
item 4; ours).

A field is set by its inputs (:class:`Field`: mean wind at hub height, IEC turbulence
class and model, seed, hub height, grid, time step and length) and cached once per input
text in wtftc's cache (``turbsim/<key>.bts``). ``wtftc.openfast.turbsim.generate`` runs
TurbSim to make it; this module only reads, so that wtftc's own plant (``[wind] field =
"turbsim"``, resolved by wtftc.config) and OpenFAST's InflowWind see the same file.

The reader (:func:`read_bts`) is ours, NumPy only: openfast-io's imports pandas, which
wtftc does not install. The format is TurbSim 5.0.0's ``WrBinTURBSIM``
(modules/turbsim/src/TS_FileIO.f90), as InflowWind's ``IfW_TurbSim_Init``
(modules/inflowwind/src/InflowWind_IO.f90) reads it, little-endian, no record markers:

- int16 ID: 7 a non-periodic field, 8 a periodic one;
- int32 nz, ny, ntwr, nt (grid points vertically, laterally, tower points, time steps);
- float32 dz, dy, dt, uhub, zhub, zbottom [m, m, s, m/s, m, m];
- float32 slope_u, offset_u, slope_v, offset_v, slope_w, offset_w;
- int32 nchar, then nchar bytes of description;
- per time step: int16 [3, ny, nz] in Fortran order (component fastest, then y, then z),
  then int16 [3, ntwr]; velocity = (count - offset) / slope [m/s].

The grid is y = -(ny-1) dy/2 ... +(ny-1) dy/2 across the wind (y positive to the left
looking downwind), z = zbottom + k dz; tower point k (0-based) is at y = 0,
z = zbottom - k dz (TSsubs.f90 ``CreateGrid``), the first one the grid's bottom centre.

**The time convention** (InflowWind, IfW_FlowField.f90 ``GetBoundsT``): the grid is
advected at uhub. A point at x (downwind, from the tower axis) at time t reads the grid at
t + (x0 - x)/uhub, x0 = half the grid's width for a non-periodic field (its leading edge
starts half a width ahead of the turbine), 0 for a periodic one; InflowWind interpolates
linearly in t, y and z. The rotor at x = 0 (where InflowWind reports ``Wind1VelX``) thus
sees at time t the grid's slice at t + :attr:`FullField.time_shift_s`.
"""

from __future__ import annotations

import hashlib
import math
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wtftc.artefacts.loader import cache_dir
from wtftc.errors import ConfigError, EngineError
from wtftc.files import MAX_INPUT_BYTES, decode_text, read_user_bytes, seal_damage, seal_path

#: the grid's points per side, and its size over the rotor's diameter
GRID_POINTS = 13
GRID_OVER_DIAMETER = 1.15
#: the field's time step [s]
FIELD_DT = 0.05
#: RandSeed1's range (TurbSim: a signed 32-bit integer)
SEED_MAX = 2**31 - 1
#: TurbSim's file IDs
NON_PERIODIC, PERIODIC = 7, 8


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
    """Where the field of ``f`` is cached (made there by wtftc.openfast.turbsim.generate)."""
    return cache_dir() / "turbsim" / f"{f.key()}.bts"


def deck_hub_height(fst: Path) -> float:
    """The hub height [m] an OpenFAST deck gives its wind: its InflowWind file's RefHt."""
    inflow = fst.parent / _deck_value(fst, "InflowFile")
    value = _deck_value(inflow, "RefHt")
    try:
        hub = float(value)
    except ValueError:
        hub = math.nan
    if not (math.isfinite(hub) and hub > 0):
        raise ConfigError("openfast_deck", str(inflow), f"an InflowWind file whose RefHt is "
                          f"a height > 0 [m] (it is {value!r})")
    return hub


def _deck_value(path: Path, key: str) -> str:
    """The value on ``path``'s line whose second word is ``key``; the deck read as a user's
    file (a FIFO, a folder, a link loop or an unreadable file refused in one line naming
    it) and decoded as its author wrote it (UTF-8, else Latin-1: a "°" in a comment is no
    error)."""
    data = read_user_bytes(path, "openfast_deck", MAX_INPUT_BYTES)  # a FIFO never blocks
    for line in decode_text(data).split("\n"):
        words = line.split()
        if len(words) >= 2 and words[1] == key:
            return words[0].strip('"')
    raise EngineError(f"{path}: no {key} line")


def turbsim_field(ntm: dict, deck: Path, rotor_radius_m: float, t_final_s: float) -> Field:
    """The field of an NTM wind (its ``describe()``: mean at hub height, class, seed) on a
    turbine of rotor radius ``rotor_radius_m`` [m] (the grid's size) whose OpenFAST deck is
    ``deck`` (the hub height: :func:`deck_hub_height`), for a run of ``t_final_s`` [s]. The
    one construction both engines use: the same run gets the same cached file."""
    par = ntm["parameters"]
    return Field(float(par["mean_mps"]), str(par["turbulence_class"]), int(ntm["seed"] or 0),
                 deck_hub_height(deck), float(rotor_radius_m), float(t_final_s))


# --------------------------------------------------------------------------- reading

_HEAD = struct.Struct("<h4i6f6fi")  # ID; nz, ny, ntwr, nt; dz..zbottom; slopes/offsets; nchar


@dataclass(frozen=True)
class FullField:
    """A TurbSim full field in SI: ``u``, ``v``, ``w`` [m/s] indexed [time, z, y];
    the tower points' ``u_tower``... [time, point]."""

    path: Path
    periodic: bool
    t: np.ndarray  # [s] the grid's time, k dt
    y: np.ndarray  # [m] lateral, 0 on the hub
    z: np.ndarray  # [m] height above the ground
    u: np.ndarray
    v: np.ndarray
    w: np.ndarray
    mean_mps: float  # uhub [m/s]
    hub_height_m: float
    z_tower: np.ndarray  # [m] the tower points' heights (y = 0)
    u_tower: np.ndarray
    v_tower: np.ndarray
    w_tower: np.ndarray
    slope: tuple[float, float, float]  # counts per m/s of u, v, w (quantum 1/slope)
    description: str

    @property
    def half_width_m(self) -> float:
        return float(self.y[-1])

    @property
    def time_shift_s(self) -> float:
        """How far ahead of the run's time the rotor (x = 0) reads the grid [s]: half the
        grid's width over uhub for a non-periodic field, 0 for a periodic one
        (InflowWind's InitXPosition)."""
        return 0.0 if self.periodic else self.half_width_m / self.mean_mps


class NotAField(EngineError):
    """A file that is not a TurbSim full field; ``what`` says why."""

    def __init__(self, path: Path, what: str):
        self.path, self.what = path, what
        super().__init__(f"{path} is not a TurbSim full field (.bts): {what}")


def _bad(path: Path, what: str) -> EngineError:
    return NotAField(path, what)


def _header(path: Path, raw: bytes) -> tuple:
    if len(raw) < _HEAD.size:
        raise _bad(path, f"{len(raw)} bytes, shorter than the {_HEAD.size}-byte header")
    h = _HEAD.unpack_from(raw)
    if h[0] not in (NON_PERIODIC, PERIODIC):
        raise _bad(path, f"file ID {h[0]} (TurbSim writes 7 or 8)")
    nz, ny, ntwr, nt = h[1:5]
    if nz < 2 or ny < 2 or ntwr < 0 or nt < 2:
        raise _bad(path, f"nz, ny, ntwr, nt = {nz}, {ny}, {ntwr}, {nt} (a grid of at least "
                   "2 x 2 points and 2 time steps)")
    dz, dy, dt, uhub, zhub, zbot = h[5:11]
    slopes, offsets = h[11:17:2], h[12:17:2]
    if not all(math.isfinite(x) and x > 0 for x in (dz, dy, dt, uhub, zhub)):
        raise _bad(path, f"dz, dy, dt, uhub, zhub = {dz:g}, {dy:g}, {dt:g}, {uhub:g}, "
                   f"{zhub:g} (each > 0)")
    if not all(math.isfinite(x) and x != 0 for x in slopes) \
            or not all(math.isfinite(x) for x in (zbot, *offsets)):
        raise _bad(path, f"scaling slopes {slopes} / offsets {offsets} (finite, slopes != 0)")
    nchar = h[17]
    if not 0 <= nchar <= len(raw):
        raise _bad(path, f"a description of {nchar} characters")
    return h[0], nz, ny, ntwr, nt, dz, dy, dt, uhub, zhub, zbot, slopes, offsets, nchar


def read_bts(path: Path) -> FullField:
    """The TurbSim binary full field at ``path`` (the module's format), in SI. A file that
    is not one, or is cut short, raises :class:`~wtftc.errors.EngineError` in one line
    naming it and what is wrong."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise _bad(path, exc.strerror or str(exc)) from None
    fid, nz, ny, ntwr, nt, dz, dy, dt, uhub, zhub, zbot, slopes, offsets, nchar = \
        _header(path, raw)
    start = _HEAD.size + nchar
    per_step = 3 * (ny * nz + ntwr)
    need = start + 2 * nt * per_step
    if len(raw) != need:
        raise _bad(path, f"{len(raw)} bytes where its header ({nt} steps of {ny} x {nz} "
                   f"points and {ntwr} tower points) says {need}"
                   + (" (cut short)" if len(raw) < need else ""))
    counts = np.frombuffer(raw, dtype="<i2", offset=start).reshape(nt, per_step)
    grid = counts[:, :3 * ny * nz].reshape(nt, nz, ny, 3)  # Fortran [3, ny, nz] per step
    tower = counts[:, 3 * ny * nz:].reshape(nt, ntwr, 3)
    s, o = np.asarray(slopes, np.float32), np.asarray(offsets, np.float32)
    vel = ((grid.astype(np.float32) - o) / s).astype(float)  # as InflowWind, in float32
    twr = ((tower.astype(np.float32) - o) / s).astype(float)
    half = 0.5 * (ny - 1) * dy
    return FullField(
        path=path, periodic=fid == PERIODIC, t=np.arange(nt) * float(dt),
        y=np.linspace(-half, half, ny), z=zbot + np.arange(nz) * float(dz),
        u=vel[..., 0], v=vel[..., 1], w=vel[..., 2], mean_mps=float(uhub),
        hub_height_m=float(zhub), z_tower=zbot - np.arange(ntwr) * float(dz),
        u_tower=twr[..., 0], v_tower=twr[..., 1], w_tower=twr[..., 2],
        slope=tuple(float(x) for x in slopes),
        description=raw[_HEAD.size:start].decode("latin-1").strip())


# --------------------------------------------------------------------------- series

#: the disk's quadrature: rings of equal area, points on each
DISK_RINGS, DISK_ANGLES = 48, 96


def _check_radius(ff: FullField, radius_m: float, what: str) -> None:
    """``radius_m`` [m] within the field's grid around the hub, else one line naming it."""
    if radius_m > min(ff.half_width_m, ff.hub_height_m - ff.z[0], ff.z[-1] - ff.hub_height_m):
        raise ConfigError("wind.rotor_radius_m", radius_m, f"{what} within the TurbSim "
                          f"field's grid ({ff.half_width_m:g} m each side of the hub)")


def _corners(ff: FullField, ys: np.ndarray, zs: np.ndarray):
    """The field's bilinear interpolant at the points (y, z) = (``ys``, hub height +
    ``zs``) [m], as InflowWind interpolates: the four grid corners ((z index, y index),
    share) of each point, the shares summing to 1 (points beyond the grid: its edge)."""
    fy = np.clip((ys - ff.y[0]) / (ff.y[1] - ff.y[0]), 0, len(ff.y) - 1)
    fz = np.clip((zs + ff.hub_height_m - ff.z[0]) / (ff.z[1] - ff.z[0]), 0, len(ff.z) - 1)
    iy, iz = np.minimum(fy.astype(int), len(ff.y) - 2), np.minimum(fz.astype(int), len(ff.z) - 2)
    by, bz = fy - iy, fz - iz
    return (((iz, iy), (1 - bz) * (1 - by)), ((iz, iy + 1), (1 - bz) * by),
            ((iz + 1, iy), bz * (1 - by)), ((iz + 1, iy + 1), bz * by))


def disk_weights(ff: FullField, radius_m: float) -> np.ndarray:
    """Weights W [z, y] (summing to 1) with Σ W u = the mean of the field's u over the disk
    of radius ``radius_m`` [m] centred on the hub (y = 0, z = hub height), each point of the
    disk weighing by its area: the field's rotor-effective wind, as wtftc's native NTM
    defines it (docs/wind.md: two points drawn uniformly on the disk). The field between
    grid points is bilinear in y and z (:func:`_corners`); the disk is sampled by
    DISK_RINGS rings of equal area x DISK_ANGLES points. ``radius_m`` 0: the hub point."""
    _check_radius(ff, radius_m, "a radius")
    if radius_m > 0:
        r = radius_m * np.sqrt((np.arange(DISK_RINGS) + 0.5) / DISK_RINGS)
        a = 2 * np.pi * (np.arange(DISK_ANGLES) + 0.5) / DISK_ANGLES
        ys, zs = np.outer(r, np.cos(a)).ravel(), np.outer(r, np.sin(a)).ravel()
    else:
        ys, zs = np.zeros(1), np.zeros(1)
    w = np.zeros((len(ff.z), len(ff.y)))
    for at, share in _corners(ff, ys, zs):
        np.add.at(w, at, share)
    return w / w.sum()


def rotor_series(ff: FullField, radius_m: float) -> np.ndarray:
    """The longitudinal wind [m/s] at each of the grid's times: at the hub (``radius_m``
    0, bilinear at y = 0, z = hub height) or averaged over the rotor disk
    (:func:`disk_weights`)."""
    return np.einsum("tzy,zy->t", ff.u, disk_weights(ff, radius_m))


#: the points along each blade of :func:`blade_series`: the midpoints of equal lengths
BLADE_POINTS = 40


def blade_series(ff: FullField, radius_m: float, speed_rad_s: float) -> np.ndarray:
    """The longitudinal wind [m/s] as the three blades sample the field, at each of the
    grid's times: each blade a radial line from the hub to ``radius_m`` [m], turning at
    ``speed_rad_s`` [rad/s] from blade 1 upright at the run's t = 0 (blades 2 and 3 at
    120° and 240°), its BLADE_POINTS points of equal span weighing alike; the mean over the
    three blades.

    Why equal weights along the span: a blade element's lift changes with the local wind
    in proportion to its chord times its speed, c Ω r, and a rotor designed for its best
    Cp has a chord about inverse to r, so each metre of span answers a gust about alike
    (the disk average weighs by area, ∝ r). Against OpenFAST (docs/validation.md) equal
    weights fitted the loads better than weights ∝ r. What this keeps that the disk
    average smooths away: the eddies a blade sweeps through as it turns, which put power
    at the tower's mode and at 3P (the sum of three blades cancels the other harmonics of
    a pattern fixed in space). The rotor speed is a constant (the operating point's): the
    azimuth does not follow the run's speed."""
    if radius_m <= 0:
        raise ConfigError("wind.rotor_radius_m", radius_m, "a radius > 0 for the blades")
    _check_radius(ff, radius_m, "a radius > 0")
    r = radius_m * (np.arange(BLADE_POINTS) + 0.5) / BLADE_POINTS
    t = run_times(ff)
    rows = np.arange(len(t))[:, None]
    total = np.zeros(len(t))
    for b in range(3):
        psi = speed_rad_s * t[:, None] + 2 * np.pi * b / 3  # from upright towards +y
        total += sum(share * ff.u[(rows, *at)]
                     for at, share in _corners(ff, r * np.sin(psi), r * np.cos(psi))
                     ).mean(axis=1)
    return total / 3


def run_times(ff: FullField) -> np.ndarray:
    """The run's times [s] at which the rotor (x = 0) reads the grid's slices: the grid's
    time less :attr:`FullField.time_shift_s` (InflowWind's convention, module docstring)."""
    return ff.t - ff.time_shift_s


def field_wind(f: Field, ntm: dict, t_final_s: float):
    """The NTM ``ntm`` (its ``describe()``, ``field = "turbsim"``) read from the cached field
    of ``f``: the longitudinal wind at the hub, averaged over the disk of the NTM's
    ``rotor_radius_m``, or as the blades sample it (``rotor_wind = "blades"``,
    :func:`blade_series`), at the times the rotor reads each slice (:func:`run_times`), linear
    in between. The field must be in the cache (wtftc.openfast.turbsim.generate makes it;
    the configuration cannot, being below the OpenFAST room)."""
    from wtftc.model.wind import SampledWind, _check_positive

    path = field_path(f)
    if not path.is_file():
        raise ConfigError("wind.field", "turbsim", f"a TurbSim field already made into "
                          f"wtftc's cache; {path} is not there yet (an OpenFAST run of this "
                          "configuration makes it, or wtftc.openfast.turbsim.make_field)")
    why = seal_damage(path)
    if why is not None:  # wtftc.openfast.turbsim.generate rebuilds it; here it is only read
        raise EngineError(f"{path} in WTFTC_CACHE is damaged ({why}): delete it and "
                          f"{seal_path(path)}, then run again (the field is made anew)")
    ff = read_bts(path)
    par = ntm["parameters"]
    radius = float(par.get("rotor_radius_m", 0.0))
    blades = par.get("rotor_wind") == "blades"
    speed = float(par.get("blade_speed_rad_s", 0.0))
    if blades and speed <= 0:  # wtftc.config fills it in from the turbine
        raise ConfigError("wind.blade_speed_rad_s", speed, "a rotor speed > 0 [rad/s] for "
                          "the blades' wind (wtftc.config fills it in from the turbine)")
    t = run_times(ff)
    v = blade_series(ff, radius, speed) if blades else rotor_series(ff, radius)
    series = (f"three blades turning at {speed:.6g} rad/s" if blades
              else "rotor disk average" if radius > 0 else "hub point")
    _check_positive(t, v, "wind.mean_mps", f.mean_mps, "raise mean_mps")
    run = (t >= 0) & (t <= t_final_s)
    return SampledWind("ntm", t, v, seed=ntm["seed"], parameters=ntm["parameters"],
                       source=str(path), derived={
                           "standard": "TurbSim 5.0.0 full field, IEC Kaimal with IEC "
                                       "coherence (IECKAI, 1-Ed3)",
                           "field_key": f.key(), "hub_height_m": ff.hub_height_m,
                           "grid": f"{len(ff.y)} x {len(ff.z)} points, "
                                   f"{2 * ff.half_width_m:.6g} m wide",
                           "series": series,
                           "time_shift_s": ff.time_shift_s,
                           "run_mean_mps": float(v[run].mean()),
                           "run_std_mps": float(v[run].std())})
