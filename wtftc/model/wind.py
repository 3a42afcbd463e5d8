"""Hub-height horizontal wind speed v(t) [m/s] for the closed loop.

``wind_from_config(cfg, t_final, seed)`` turns a ``[wind]`` table into a :class:`Wind`, a
callable ``t [s] -> v [m/s]`` (same shape as ``t``, float) with a JSON-able ``describe()``.
Kinds (fields, units and defaults in ``docs/wind.md``):

- ``constant``: ``speed_mps``.
- ``steps``: ``speed_mps`` until the first step, then ``steps = [[time_s, speed_mps], ...]``;
  right-continuous: at ``t = time_s`` the new speed already holds.
- ``paper_random``: the "random variation around 12 m/s" of Bakhshi & Alfi (2020), Fig. 2,
  for which the paper gives no numbers. Taken to be band-limited Gaussian noise: complex
  Gaussian Fourier coefficients (independent normal real and imaginary parts, so the
  process is Gaussian whatever the number of components) on the frequencies
  k/T, k = 1..K, k/T <= ``cutoff_hz``, i.e. white noise through an ideal low-pass, over a
  period T >= max(600 s, t_final + margin), then shifted and scaled so that the sample
  mean and standard deviation over that period are exactly ``mean_mps`` and ``std_mps``.
  A run shorter than 10 minutes is therefore the start of the same series whatever its
  length (the same seed gives the same wind), and a short run is not inflated to the full
  std. The defaults (1 m/s, 0.1 Hz) are ours; docs/wind.md says why this reading.
- ``ntm``: IEC 61400-1 ed. 3 normal turbulence model (6.3.1.3), longitudinal component at
  hub height, Kaimal spectrum (Annex B), synthesized by random phases and an inverse FFT
  (Shinozuka's spectral representation, as TurbSim does at a single point); see below.
  ``rotor_radius_m`` > 0 averages it over a rotor disk of that radius (rotor_average_gain);
  0, the default here, keeps the hub-height point. A run's configuration fills in its
  turbine's rotor radius when none is given (wtftc.config: the rotor-effective wind).
- ``eog``: IEC 61400-1 ed. 3 extreme operating gust (6.3.2.2), closed form.
- ``ecd``: IEC 61400-1 ed. 3 extreme coherent gust with direction change (6.3.2.5), closed
  form: the horizontal speed and its direction. wtftc's plants have no yaw: they take the
  rotor-normal component V cos θ (:meth:`Wind.__call__`); OpenFAST's uniform wind file gets
  the speed and the direction (:meth:`Wind.horizontal`, :meth:`Wind.direction`).
- ``ramp``: ``speed_mps`` until ``start_s``, linear to ``end_mps`` over ``duration_s``, held
  after (the ramp of NREL's controller test bench in WEIS, ``examples/19_controller_test_
  bench``: a start speed, a change and a duration).
- ``file``: an OpenFAST InflowWind uniform wind file (``.hh``/``.wnd``/anything not ``.csv``)
  or a CSV with a header ``time_s,speed_mps``; linear in time, held outside the range.

NTM synthesis. σ1 = I_ref (0.75 V_hub + 5.6), Λ1 = 42 m (hub height >= 60 m; the NREL 5-MW
hub is at 90 m), L_u = 8.1 Λ1, S_u(f) = 4 σ1² (L_u/V) / (1 + 6 f L_u/V)^(5/3). The series
is synthesized on a grid of step ``dt_s`` over a period T = N dt >= max(600 s,
t_final + 10 s) (at least the 10-min period over which IEC defines σ1; a short run is a
piece of a 10-min realization): Fourier amplitudes sqrt(2 S_u(f_k) Δf) on f_k = k/T,
k = 1..N/2 - 1 (no mean, no Nyquist term), phases uniform on [0, 2π) from
``numpy.random.default_rng(seed)``, ``numpy.fft.irfft``. With fixed amplitudes the variance
over the period is Σ S_u Δf whatever the phases; it falls short of σ1² by the spectral mass
below about 1/(2T) and above the Nyquist frequency (about 9 % of the variance for
T = 600 s at 12 m/s, because L_u/V ≈ 28 s; 2 % for T = 3610 s). **We rescale**: the
fluctuation is multiplied by one constant so that the standard deviation over the
synthesized period is exactly σ1 and its mean exactly V_hub (the same factor for every
seed, so the spectral shape is that of Kaimal on [1/T, f_Nyquist]). Over a run shorter
than T the realized mean and standard deviation are those of a window of a 10-min
realization and vary with the seed, as in a field record. Between grid points v(t) is
linear in t; outside [0, T) it is held.

Why numpy alone: a single-point Kaimal series is one irfft of a closed-form spectrum. The
PyPI turbulence generators build multi-point boxes: PyConTurb (DTU; Kaimal + IEC coherence,
the same random-phase irfft) needs pandas, scipy and h5py and seeds numpy's legacy global
generator; ``pyturbsim`` (a TurbSim port) has had no release since 2015; ``hipersim`` and
``drdmannturb`` are Mann-model generators. None adds anything at one point.

Every user mistake raises :class:`~wtftc.errors.ConfigError` naming the field
(``wind.<key>``), the value and what is allowed. The same configuration and seed give
bit-identical output.
"""

from __future__ import annotations

import hashlib
import math
import re
from pathlib import Path

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.errors import ConfigError
from wtftc.files import read_user_bytes

KINDS = ("constant", "steps", "paper_random", "ntm", "eog", "file", "ecd", "ramp")
#: where an NTM comes from ([wind] field): wtftc's own synthesis at one point (filtered
#: over the rotor), or read from TurbSim's full field, the one OpenFAST's engine uses
#: (wtftc.config resolves it: wtftc.model.wind_field)
NTM_FIELDS = ("spectral", "turbsim")
#: how a TurbSim field becomes the one wind the plant takes ([wind] rotor_wind): averaged
#: over the rotor disk, or as the three blades sample it turning (wtftc.model.wind_field)
ROTOR_WINDS = ("disk", "blades")
#: the fastest a rotor may turn [rad/s] (blade_speed_rad_s; 0: the turbine's own, below)
BLADE_SPEED_MAX = 10.0

#: IEC 61400-1 reference turbulence intensity I_ref by turbulence category (A+ is ed. 4)
I_REF = {"A+": 0.18, "A": 0.16, "B": 0.14, "C": 0.12}
#: IEC 61400-1 reference wind speed V_ref [m/s] by turbine class
V_REF = {"I": 50.0, "II": 42.5, "III": 37.5}
LAMBDA1_M = 42.0  # turbulence scale parameter Λ1 [m], hub height >= 60 m (IEC 6.3)
KAIMAL_LU_OVER_LAMBDA1 = 8.1  # L_u = 8.1 Λ1 (IEC Annex B, Table B.1)
EOG_T_S = 10.5  # EOG duration T [s] (IEC 6.3.2.2)
ECD_T_S = 10.0  # ECD rise time T [s] (IEC 6.3.2.5)
ECD_V_CG_MPS = 15.0  # ECD gust magnitude V_cg [m/s] (IEC 6.3.2.5)
#: the lowest ECD mean [m/s], exclusive: θ_cg = 720°/V_hub is 90° at 8 m/s, where V cos θ,
#: the wind wtftc's plants take, falls to 0 (below it, it would blow from behind)
ECD_MIN_MEAN_MPS = 8.0
V_MAX_MPS = 70.0  # upper bound of configured speeds: V_e50 of class I (1.4 × 50 m/s)
NTM_MIN_PERIOD_S = 600.0  # the 10-min period over which σ1 is defined
SYNTH_MARGIN_S = 10.0  # synthesized series extend this far past t_final
MAX_SAMPLES = 20_000_000  # 160 MB per array

_FIELDS = {
    "constant": {"speed_mps": 12.0},
    "steps": {"speed_mps": 12.0, "steps": None},
    "paper_random": {"mean_mps": 12.0, "std_mps": 1.0, "cutoff_hz": 0.1},
    "ntm": {"mean_mps": 12.0, "turbulence_class": "B", "dt_s": 0.05, "rotor_radius_m": 0.0,
            "field": "spectral", "rotor_wind": "disk", "blade_speed_rad_s": 0.0},
    "eog": {"mean_mps": 11.4, "start_s": 20.0, "turbine_class": "I", "turbulence_class": "B",
            "rotor_diameter_m": 126.0},
    "file": {"path": None},
    "ecd": {"mean_mps": 11.4, "start_s": 20.0, "sign": 1, "turbine_class": "I"},
    "ramp": {"speed_mps": 9.4, "end_mps": 13.4, "start_s": 20.0, "duration_s": 125.0},
}


def sigma1(mean_mps: float, turbulence_class: str) -> float:
    """NTM longitudinal standard deviation σ1 = I_ref (0.75 V_hub + 5.6) [m/s] (IEC 6.3.1.3)."""
    return I_REF[turbulence_class] * (0.75 * mean_mps + 5.6)


def kaimal_psd(f, mean_mps: float, sigma: float, length_m: float = 8.1 * 42.0) -> np.ndarray:
    """One-sided Kaimal PSD S_u(f) = 4σ²(L/V)/(1 + 6fL/V)^(5/3) [m²/s² per Hz] (IEC Annex B)."""
    tl = length_m / mean_mps
    return 4.0 * sigma**2 * tl / (1.0 + 6.0 * np.asarray(f, dtype=float) * tl) ** (5.0 / 3.0)


#: the coherence scale L_c = 8.1 Λ1 of IEC 61400-1 ed. 3, Annex B (eq. B.4)
COHERENCE_LC_M = 8.1 * LAMBDA1_M


def disk_distance_pdf(r, radius: float) -> np.ndarray:
    """The density of the distance between two points drawn uniformly on a disk of radius
    R ("disk line picking"): 4r/(πR²) [acos(r/2R) − (r/2R) √(1 − (r/2R)²)] on [0, 2R]."""
    x = np.clip(np.asarray(r, dtype=float) / (2.0 * radius), 0.0, 1.0)
    return 4.0 * np.asarray(r) / (math.pi * radius**2) * (np.arccos(x) - x * np.sqrt(1 - x * x))


def rotor_average_gain(f, mean_mps: float, radius: float, n: int = 400) -> np.ndarray:
    """|H(f)|², the ratio of the disk-averaged wind's spectrum to the point spectrum under
    the IEC exponential coherence Coh(r, f) = exp(−12 √((f r / V)² + (0.12 r / L_c)²))
    (IEC 61400-1 ed. 3, Annex B, eq. B.4): the coherence averaged over the distance r
    between two points of the rotor disk, ∫ Coh(r, f) p(r) dr (disk_distance_pdf),
    by the midpoint rule on n intervals of [0, 2R]."""
    dr = 2.0 * radius / n
    r = (np.arange(n) + 0.5) * dr
    w = disk_distance_pdf(r, radius) * dr
    f = np.asarray(f, dtype=float)[:, None]
    coh = np.exp(-12.0 * np.sqrt((f * r / mean_mps) ** 2 + (0.12 * r / COHERENCE_LC_M) ** 2))
    return coh @ w / w.sum()


def eog_gust_mps(mean_mps: float, turbine_class: str, turbulence_class: str,
                 rotor_diameter_m: float) -> float:
    """V_gust = min{1.35 (V_e1 - V_hub), 3.3 σ1 / (1 + 0.1 D/Λ1)}, V_e1 = 0.8·1.4·V_ref."""
    v_e1 = 0.8 * 1.4 * V_REF[turbine_class]
    s1 = sigma1(mean_mps, turbulence_class)
    return min(1.35 * (v_e1 - mean_mps), 3.3 * s1 / (1.0 + 0.1 * rotor_diameter_m / LAMBDA1_M))


class Wind:
    """A hub-height horizontal wind speed signal: ``wind(t)`` [m/s] for t [s]."""

    kind = "abstract"

    def __init__(self, parameters: dict, seed: int | None = None, derived: dict | None = None,
                 source: str | None = None):
        self._parameters, self._seed = parameters, seed
        self._derived, self._source = derived or {}, source

    def __call__(self, t) -> np.ndarray:
        return self._eval(np.asarray(t, dtype=float))

    def _eval(self, t: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def horizontal(self, t) -> np.ndarray:
        """The horizontal speed [m/s] at hub height, whatever its direction (an ECD's
        differs from the rotor-normal wind the plant takes: :class:`ECDWind`)."""
        return self(t)

    def direction(self, t) -> np.ndarray:
        """The wind's direction [rad] from the rotor's axis (0: along it; no kind but the
        ECD turns)."""
        return np.zeros(np.shape(np.asarray(t, dtype=float)))

    def describe(self) -> dict:
        """JSON-serializable record: kind, the resolved fields (defaults filled in: feed them
        back with the kind to :func:`wind_from_config` to rebuild this wind), seed (None if
        the kind is not random), derived quantities, source file (None if none)."""
        return {"kind": self.kind, "parameters": _jsonable(self._parameters), "seed": self._seed,
                "derived": _jsonable(self._derived), "source": self._source}


class ConstantWind(Wind):
    kind = "constant"

    def __init__(self, speed_mps: float, **kw):
        super().__init__(**kw)
        self.speed_mps = float(speed_mps)

    def _eval(self, t):
        return np.full(t.shape, self.speed_mps)


class StepWind(Wind):
    """Piecewise constant, right-continuous: v = speeds[i] for times[i-1] <= t < times[i]."""

    kind = "steps"

    def __init__(self, speed_mps: float, times, speeds, **kw):
        super().__init__(**kw)
        self.times = np.asarray(times, dtype=float)
        self.speeds = np.concatenate([[float(speed_mps)], np.asarray(speeds, dtype=float)])

    def _eval(self, t):
        return self.speeds[np.searchsorted(self.times, t, side="right")]


class SampledWind(Wind):
    """Linear interpolation of samples (t_k, v_k), held constant outside [t_0, t_last]."""

    def __init__(self, kind: str, t_s, v_mps, **kw):
        super().__init__(**kw)
        self.kind = kind
        self.t_s = np.ascontiguousarray(t_s, dtype=float)
        self.v_mps = np.ascontiguousarray(v_mps, dtype=float)

    def _eval(self, t):
        return np.asarray(np.interp(t, self.t_s, self.v_mps), dtype=float)


class EOGWind(Wind):
    """IEC EOG: V_hub - 0.37 V_gust sin(3πτ/T)(1 - cos(2πτ/T)) for τ = t - start in [0, T]."""

    kind = "eog"

    def __init__(self, mean_mps: float, v_gust_mps: float, start_s: float, **kw):
        super().__init__(**kw)
        self.mean_mps, self.v_gust_mps, self.start_s = mean_mps, v_gust_mps, start_s

    def _eval(self, t):
        x = (t - self.start_s) / EOG_T_S
        shape = np.sin(3.0 * np.pi * x) * (1.0 - np.cos(2.0 * np.pi * x))
        return np.where((x >= 0.0) & (x <= 1.0), self.mean_mps - 0.37 * self.v_gust_mps * shape,
                        self.mean_mps)


def ecd_direction_change_rad(mean_mps: float) -> float:
    """θ_cg [rad]: 180° below V_hub = 4 m/s, 720° / V_hub (V_hub in m/s) from 4 m/s to V_ref
    (IEC 61400-1 ed. 3, 6.3.2.5)."""
    return math.radians(180.0 if mean_mps < 4.0 else 720.0 / mean_mps)


class ECDWind(Wind):
    """IEC ECD (IEC 61400-1 ed. 3, 6.3.2.5): for τ = t - start in [0, T], T = 10 s,
    V = V_hub + 0.5 V_cg (1 - cos(π τ/T)) and θ = ±0.5 θ_cg (1 - cos(π τ/T)); before, V_hub
    and 0; after, V_hub + V_cg and ±θ_cg. Called, the rotor-normal component V cos θ: what a
    rotor that does not yaw takes along its axis (wtftc's plants have no yaw DOF)."""

    kind = "ecd"

    def __init__(self, mean_mps: float, start_s: float, sign: int, **kw):
        super().__init__(**kw)
        self.mean_mps, self.start_s, self.sign = mean_mps, start_s, sign
        self.theta_cg = ecd_direction_change_rad(mean_mps)

    def _rise(self, t) -> np.ndarray:
        """0.5 (1 - cos(π τ/T)) clipped to [0, 1]: the shape of both the speed's
        rise and the direction's (6.3.2.5)."""
        tau = np.clip((np.asarray(t, dtype=float) - self.start_s) / ECD_T_S, 0.0, 1.0)
        return 0.5 * (1.0 - np.cos(np.pi * tau))

    def horizontal(self, t) -> np.ndarray:
        return self.mean_mps + ECD_V_CG_MPS * self._rise(t)  # IEC 6.3.2.5, V(z, t)

    def direction(self, t) -> np.ndarray:
        return self.sign * self.theta_cg * self._rise(t)  # IEC 6.3.2.5, θ(t)

    def _eval(self, t):
        return self.horizontal(t) * np.cos(self.direction(t))


class RampWind(Wind):
    """``speed`` until ``start``, linear to ``end`` over ``duration``, then held."""

    kind = "ramp"

    def __init__(self, speed_mps: float, end_mps: float, start_s: float, duration_s: float,
                 **kw):
        super().__init__(**kw)
        self.speed_mps, self.end_mps = speed_mps, end_mps
        self.start_s, self.duration_s = start_s, duration_s

    def _eval(self, t):
        x = np.clip((t - self.start_s) / self.duration_s, 0.0, 1.0)
        return self.speed_mps + (self.end_mps - self.speed_mps) * x


# --------------------------------------------------------------------------- validation


def _jsonable(obj):
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    return obj


def _number(value, field: str, lo=None, hi=None, lo_open=True, unit="") -> float:
    """A finite int/float (not bool) in (lo, hi] (or [lo, hi] with lo_open=False)."""
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(value):
        raise ConfigError(field, value, f"a finite number{unit}")
    bad_lo = lo is not None and (value <= lo if lo_open else value < lo)
    if bad_lo or (hi is not None and value > hi):
        op = ">" if lo_open else ">="
        rng = (f"in {'(' if lo_open else '['}{lo:g}, {hi:g}]" if lo is not None and hi is not None
               else f"{op} {lo:g}" if lo is not None else f"<= {hi:g}")
        raise ConfigError(field, value, f"a number {rng}{unit}")
    return float(value)


def _choice(value, field: str, allowed) -> str:
    if not isinstance(value, str) or value not in allowed:
        raise ConfigError(field, value, "one of " + ", ".join(f'"{a}"' for a in allowed))
    return value


def _speed(value, field: str) -> float:
    return _number(value, field, lo=0.0, hi=V_MAX_MPS, unit=" [m/s]")


def field_default(kind: str, key: str):
    """The default of ``key`` in a ``[wind]`` table of ``kind`` (what an absent key means)."""
    return _FIELDS[kind][key]


def wind_from_config(cfg: dict, t_final: float, seed: int = 0, where: str = "wind") -> Wind:
    """Build the wind of a ``[wind]`` table (keys = fields, ``kind`` required).

    ``t_final`` [s] is the end of the run (random kinds synthesize over it plus a margin),
    ``seed`` an integer >= 0 for the random kinds, ``where`` the prefix of field names in
    error messages.
    """
    if not isinstance(cfg, dict):
        raise ConfigError(where, cfg, f"a table with kind = one of {', '.join(KINDS)}")
    if isinstance(t_final, bool) or not isinstance(t_final, int | float) \
            or not math.isfinite(t_final) or t_final <= 0:
        raise ConfigError("t_final_s", t_final, "a finite number > 0 [s]")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ConfigError("seed", seed, "an integer >= 0")
    kind = cfg.get("kind")
    if kind not in KINDS:
        raise ConfigError(f"{where}.kind", kind, "one of " + ", ".join(f'"{k}"' for k in KINDS))
    fields = _FIELDS[kind]
    for key in cfg:
        if key != "kind" and key not in fields:
            allowed = ", ".join(fields) or "none"
            if key in ("field", "rotor_radius_m", "rotor_wind", "blade_speed_rad_s"):
                raise ConfigError(f"{where}.{key}", cfg[key], f'a key of kind = "ntm" only '
                                  f'(this wind is kind = "{kind}", whose keys are: {allowed})')
            raise ConfigError(f"{where}.{key}", cfg[key],
                              f'no such field for kind = "{kind}" (fields: {allowed})')
    p = {k: cfg.get(k, d) for k, d in fields.items()}
    f = {k: f"{where}.{k}" for k in fields}
    t_final, seed = float(t_final), int(seed)
    if kind == "constant":
        v = _speed(p["speed_mps"], f["speed_mps"])
        return ConstantWind(v, parameters={"speed_mps": v})
    if kind == "steps":
        return _steps(p, f)
    if kind == "paper_random":
        return _paper_random(p, f, t_final, seed)
    if kind == "ntm":
        return _ntm(p, f, t_final, seed)
    if kind == "eog":
        return _eog(p, f, t_final)
    if kind == "ecd":
        return _ecd(p, f, t_final)
    if kind == "ramp":
        return _ramp(p, f, t_final)
    return _file(p["path"], f["path"])


def _start(value, field: str, t_final: float, what: str) -> float:
    start = _number(value, field, lo=0.0, lo_open=False, unit=" [s]")
    if start >= t_final:
        raise ConfigError(field, start, f"a time in [0, t_final_s = {t_final:g}) s, so that "
                                        f"{what} starts within the run")
    return start


def _ecd(p, f, t_final) -> ECDWind:
    tb = _choice(p["turbine_class"], f["turbine_class"], tuple(V_REF))
    mean = _number(p["mean_mps"], f["mean_mps"], lo=ECD_MIN_MEAN_MPS, hi=V_REF[tb],
                   unit=f" [m/s] (up to V_ref = {V_REF[tb]:g} m/s of turbine class {tb}; "
                        "above 8 m/s, where θ_cg = 720°/V_hub passes 90° and the "
                        "rotor-normal wind the plant takes would reach 0)")
    sign = p["sign"]
    if isinstance(sign, bool) or sign not in (1, -1):
        raise ConfigError(f["sign"], sign, "1 or -1: the direction change's sign")
    start = _start(p["start_s"], f["start_s"], t_final, "the gust")
    theta = ecd_direction_change_rad(mean)
    return ECDWind(mean, start, int(sign),
                   parameters={"mean_mps": mean, "start_s": start, "sign": int(sign),
                               "turbine_class": tb},
                   derived={"standard": "IEC 61400-1 ed. 3, 6.3.2.5 ECD", "T_s": ECD_T_S,
                            "V_cg_mps": ECD_V_CG_MPS, "theta_cg_deg": math.degrees(theta),
                            "rotor_normal": "the plant takes V cos(theta): it has no yaw",
                            "v_end_mps": mean + ECD_V_CG_MPS,
                            "v_end_rotor_normal_mps": (mean + ECD_V_CG_MPS) * math.cos(theta)})


def _ramp(p, f, t_final) -> RampWind:
    v0 = _speed(p["speed_mps"], f["speed_mps"])
    v1 = _speed(p["end_mps"], f["end_mps"])
    start = _start(p["start_s"], f["start_s"], t_final, "the ramp")
    duration = _number(p["duration_s"], f["duration_s"], lo=0.0, hi=36000.0, unit=" [s]")
    return RampWind(v0, v1, start, duration,
                    parameters={"speed_mps": v0, "end_mps": v1, "start_s": start,
                                "duration_s": duration},
                    derived={"rate_mps2": (v1 - v0) / duration})


def _steps(p, f) -> StepWind:
    v0 = _speed(p["speed_mps"], f["speed_mps"])
    steps = p["steps"]
    example = "a list of [time_s, speed_mps] pairs, e.g. [[20.0, 14.0], [40.0, 16.0]]"
    if not isinstance(steps, list) or not steps:
        raise ConfigError(f["steps"], steps, example)
    times, speeds = [], []
    for i, pair in enumerate(steps):
        fi = f"{f['steps']}[{i}]"
        if not isinstance(pair, list | tuple) or len(pair) != 2:
            raise ConfigError(fi, pair, "a [time_s, speed_mps] pair; " + example)
        t = _number(pair[0], fi + "[0]", lo=0.0, lo_open=False, unit=" [s]")
        if times and t <= times[-1]:
            raise ConfigError(fi + "[0]", pair[0],
                              f"a time > {times[-1]} s (step times strictly increasing)")
        times.append(t)
        speeds.append(_speed(pair[1], fi + "[1]"))
    pairs = [[t, v] for t, v in zip(times, speeds, strict=True)]
    return StepWind(v0, times, speeds, parameters={"speed_mps": v0, "steps": pairs})


def _grid(t_period: float, dt: float, field: str) -> int:
    """Even number of samples N with N dt >= t_period."""
    n = int(math.ceil(t_period / dt - 1e-9))
    n += n % 2
    if n > MAX_SAMPLES:
        raise ConfigError(field, dt, f"a step giving at most {MAX_SAMPLES} samples over "
                                     f"{t_period:g} s (this gives {n})")
    return n


def _check_positive(t, v, field, value, hint):
    k = int(np.argmin(v))
    if not np.all(np.isfinite(v)) or v[k] <= 0.0:
        raise ConfigError(field, value, f"a wind whose speed stays > 0; this one reaches "
                                        f"{v[k]:.3g} m/s at t = {t[k]:.3g} s ({hint})")


def _paper_random(p, f, t_final, seed) -> SampledWind:
    mean = _speed(p["mean_mps"], f["mean_mps"])
    std = _number(p["std_mps"], f["std_mps"], lo=0.0, hi=V_MAX_MPS,
                  unit=' [m/s] (use kind = "constant" for no variation)')
    fc = _number(p["cutoff_hz"], f["cutoff_hz"], lo=0.0, hi=10.0, unit=" [Hz]")
    dt = min(0.05, 1.0 / (20.0 * fc))  # >= 20 samples per period of the highest frequency
    n = _grid(max(NTM_MIN_PERIOD_S, t_final + SYNTH_MARGIN_S), dt, f["cutoff_hz"])
    period = n * dt
    k_max = min(int(math.floor(fc * period + 1e-9)), n // 2 - 1)
    if k_max < 1:
        raise ConfigError(f["cutoff_hz"], fc, f"at least 1/{period:g} s = {1 / period:.3g} Hz "
                                               "(the lowest frequency of the synthesized run)")
    rng = np.random.default_rng(seed)
    coef = np.zeros(n // 2 + 1, dtype=complex)
    coef[1:k_max + 1] = rng.standard_normal(k_max) + 1j * rng.standard_normal(k_max)
    x = np.fft.irfft(coef, n=n)
    t = np.arange(n) * dt
    v = mean + (x - x.mean()) * (std / x.std())
    run = t <= t_final + dt
    _check_positive(t[run], v[run], f["std_mps"], std, "lower std_mps or raise mean_mps")
    return SampledWind("paper_random", t, v, seed=seed,
                       parameters={"mean_mps": mean, "std_mps": std, "cutoff_hz": fc},
                       derived={"dt_s": dt, "synthesis_period_s": period,
                                "n_frequencies": k_max,
                                "normalization": "sample mean and std over the synthesis "
                                                 "period",
                                "run_mean_mps": float(v[run].mean()),
                                "run_std_mps": float(v[run].std())})


def rotor_radius_max_m() -> float:
    """The largest ``rotor_radius_m`` [m]: the largest rotor radius a turbine may have (the
    layout's range of turbine_params rotor_radius, derivation/layout.py), so that a run's
    default, its turbine's own radius (wtftc.config), is never refused."""
    entry = next(e for e in lay.layout()["turbine_params"] if e["name"] == "rotor_radius")
    return float(entry["valid"]["max"])


def _ntm(p, f, t_final, seed) -> SampledWind:
    mean = _speed(p["mean_mps"], f["mean_mps"])
    tc = _choice(p["turbulence_class"], f["turbulence_class"], tuple(I_REF))
    dt = _number(p["dt_s"], f["dt_s"], lo=0.0, hi=1.0, unit=" [s]")
    radius = _number(p["rotor_radius_m"], f["rotor_radius_m"], lo=0.0, hi=rotor_radius_max_m(),
                     lo_open=False, unit=" [m] (0: the hub-height point)")
    field = _choice(p["field"], f["field"], NTM_FIELDS)
    blades = _rotor_wind(p, f, field, radius)
    sig = sigma1(mean, tc)
    lu = KAIMAL_LU_OVER_LAMBDA1 * LAMBDA1_M
    n = _grid(max(NTM_MIN_PERIOD_S, t_final + SYNTH_MARGIN_S), dt, f["dt_s"])
    period = n * dt
    fk = np.arange(1, n // 2) / period
    amp = np.sqrt(2.0 * kaimal_psd(fk, mean, sig, lu) / period)
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0.0, 2.0 * np.pi, fk.size)
    coef = np.zeros(n // 2 + 1, dtype=complex)
    coef[1:n // 2] = 0.5 * n * amp * np.exp(1j * phase)
    x = np.fft.irfft(coef, n=n)
    scale = sig / x.std()  # the point series has σ1; the rotor average, less
    if radius > 0:
        coef[1:n // 2] *= np.sqrt(rotor_average_gain(fk, mean, radius))
        x = np.fft.irfft(coef, n=n)
    v = mean + (x - x.mean()) * scale
    t = np.arange(n) * dt
    _check_positive(t, v, f["mean_mps"], mean, "raise mean_mps or use a lower turbulence class")
    run = t <= t_final
    return SampledWind("ntm", t, v, seed=seed,
                       parameters={"mean_mps": mean, "turbulence_class": tc, "dt_s": dt}
                       | ({"rotor_radius_m": radius} if radius > 0 else {})
                       | ({"field": field} if field != "spectral" else {}) | blades,
                       derived={"standard": "IEC 61400-1 ed. 3, 6.3.1.3 NTM; Annex B Kaimal",
                                "I_ref": I_REF[tc], "sigma1_mps": sig, "Lambda1_m": LAMBDA1_M,
                                "L_u_m": lu, "synthesis_period_s": period,
                                "rescale_factor": float(scale),
                                "rescaled": "std over the synthesized period = sigma1",
                                "run_mean_mps": float(v[run].mean()),
                                "run_std_mps": float(v[run].std())})


def _rotor_wind(p, f, field: str, radius: float) -> dict:
    """The NTM's ``rotor_wind`` and ``blade_speed_rad_s``, as its parameters name them:
    nothing for the disk average (the default, so that earlier configurations and sweeps
    keep their parameters), else both. The blades' wind needs the TurbSim field and the
    rotor's radius; its speed 0 is for wtftc.config to fill in from the turbine."""
    how = _choice(p["rotor_wind"], f["rotor_wind"], ROTOR_WINDS)
    speed = _number(p["blade_speed_rad_s"], f["blade_speed_rad_s"], lo=0.0,
                    hi=BLADE_SPEED_MAX, lo_open=False, unit=" [rad/s] (0: the turbine's "
                    "operating speed at the mean wind)")
    if how == "disk":
        if speed:
            raise ConfigError(f["blade_speed_rad_s"], speed, 'a key of rotor_wind = "blades" '
                              "only (the disk average does not turn)")
        return {}
    if field != "turbsim" or radius <= 0:
        raise ConfigError(f["rotor_wind"], how, 'a wind the blades can sample: field = '
                          f'"turbsim" and rotor_radius_m > 0 (here field = "{field}", '
                          f'rotor_radius_m = {radius:g}); or rotor_wind = "disk"')
    return {"rotor_wind": how, "blade_speed_rad_s": speed}


def _eog(p, f, t_final) -> EOGWind:
    tb = _choice(p["turbine_class"], f["turbine_class"], tuple(V_REF))
    tc = _choice(p["turbulence_class"], f["turbulence_class"], tuple(I_REF))
    v_e1 = 0.8 * 1.4 * V_REF[tb]
    mean = _number(p["mean_mps"], f["mean_mps"], lo=0.0, hi=None, unit=" [m/s]")
    if mean >= v_e1:
        raise ConfigError(f["mean_mps"], mean, f"a speed in (0, V_e1 = {v_e1:g}) m/s for "
                                               f"turbine class {tb}")
    d = _number(p["rotor_diameter_m"], f["rotor_diameter_m"], lo=0.0, hi=500.0, unit=" [m]")
    start = _number(p["start_s"], f["start_s"], lo=0.0, lo_open=False, unit=" [s]")
    if start >= t_final:
        raise ConfigError(f["start_s"], start, f"a time in [0, t_final_s = {t_final:g}) s, so "
                                               "that the gust starts within the run")
    vg = eog_gust_mps(mean, tb, tc, d)
    v_min = mean - 0.37 * vg * 1.62 / math.sqrt(5.0)  # max of the shape: 1.62/√5
    if v_min <= 0:
        raise ConfigError(f["mean_mps"], mean, f"a mean whose gust dip stays > 0 m/s "
                                               f"(here {v_min:.3g} m/s)")
    return EOGWind(mean, vg, start,
                   parameters={"mean_mps": mean, "start_s": start, "turbine_class": tb,
                               "turbulence_class": tc, "rotor_diameter_m": d},
                   derived={"standard": "IEC 61400-1 ed. 3, 6.3.2.2 EOG", "T_s": EOG_T_S,
                            "V_gust_mps": vg, "V_e1_mps": v_e1,
                            "sigma1_mps": sigma1(mean, tc), "Lambda1_m": LAMBDA1_M,
                            "v_min_mps": v_min, "v_max_mps": mean + 0.74 * vg})


# --------------------------------------------------------------------------- files

_FORTRAN_REAL = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)[dD][+-]?\d+")


def _float(tok: str) -> float:
    if _FORTRAN_REAL.fullmatch(tok):
        tok = tok.replace("d", "e").replace("D", "e")
    val = float(tok)
    if not math.isfinite(val):
        raise ValueError(tok)
    return val


def _read_uniform(lines, fail) -> tuple[list, list, list, bool]:
    """InflowWind uniform wind rows: 8 columns (9 with upflow); v = column 2 + column 8."""
    times, speeds, rows, gust = [], [], [], False
    for no, line in lines:
        s = line.strip()
        if not s or s[0] in "!#%":
            continue
        toks = [x for x in re.split(r"[\s,]+", s) if x]
        if len(toks) < 8:
            fail(no, f"line {no} has {len(toks)} columns: {s[:60]!r}; InflowWind uniform wind "
                     "rows have 8 (or 9) numbers: time, horizontal speed, direction, vertical "
                     "speed, horizontal shear, power-law exponent, vertical linear shear, gust "
                     "speed[, upflow] (for two columns use a .csv with header time_s,speed_mps)")
        vals = []
        for tok in toks[:9]:
            try:
                vals.append(_float(tok))
            except ValueError:
                fail(no, f"line {no}: {tok!r} is not a finite number ({s[:60]!r})")
        times.append(vals[0])
        speeds.append(vals[1] + vals[7])
        rows.append(no)
        gust = gust or vals[7] != 0.0
    return times, speeds, rows, gust


def _read_csv(lines, fail) -> tuple[list, list, list]:
    """CSV: first non-blank line a header naming time_s and speed_mps; comma-separated."""
    header, times, speeds, rows = None, [], [], []
    for no, line in lines:
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        cells = [c.strip() for c in s.split(",")]
        if header is None:
            names = [c.lower() for c in cells]
            if "time_s" not in names or "speed_mps" not in names:
                fail(no, f"line {no} is {s[:60]!r}; the first line of a CSV wind file is a "
                         "header naming the columns time_s and speed_mps")
            header = (names.index("time_s"), names.index("speed_mps"), len(names))
            continue
        it, iv, ncol = header
        if len(cells) != ncol:
            fail(no, f"line {no} has {len(cells)} cells, the header {ncol}: {s[:60]!r}")
        try:
            times.append(_float(cells[it]))
            speeds.append(_float(cells[iv]))
        except ValueError:
            fail(no, f"line {no}: time_s/speed_mps not finite numbers ({s[:60]!r})")
        rows.append(no)
    return times, speeds, rows


#: the largest wind file read, in bytes and in lines (a 2-million-row file once took
#: 0.9 GB while being parsed)
MAX_FILE_BYTES = 100_000_000
MAX_FILE_LINES = 1_000_000


def _file(path, field: str) -> SampledWind:
    if not isinstance(path, str | Path) or not str(path):
        raise ConfigError(field, path, "the path of an OpenFAST uniform wind file (.hh, .wnd) "
                                       "or a CSV with columns time_s, speed_mps")
    p = Path(path)
    try:
        size = p.stat().st_size
        if size > MAX_FILE_BYTES:  # refused before it is read: about 0.45 kB of memory a row
            raise ConfigError(field, str(path), f"a wind file of at most {MAX_FILE_BYTES:,} "
                              f"bytes (this one: {size:,}; a 10-min series at 100 Hz is about "
                              "3 MB): resample it")
        raw = read_user_bytes(p, field, MAX_FILE_BYTES)  # a FIFO, a device: refused unread
    except OSError as exc:
        raise ConfigError(field, str(path), f"an existing, readable file ({exc.strerror})") \
            from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")

    def fail(no, msg):
        raise ConfigError(field, str(path), msg, where=f"{path}:{no}")

    n_lines = text.count("\n") + 1
    if n_lines > MAX_FILE_LINES:  # counted before any line is parsed
        raise ConfigError(field, str(path), f"a wind file of at most {MAX_FILE_LINES:,} lines "
                          f"(this one: {n_lines:,}; 10 min at 1 kHz is 600,000): resample it")
    lines = list(enumerate(text.splitlines(), start=1))
    is_csv = p.suffix.lower() == ".csv"
    if is_csv:
        times, speeds, rows = _read_csv(lines, fail)
        gust = False
    else:
        times, speeds, rows, gust = _read_uniform(lines, fail)
    if len(times) < 2:
        raise ConfigError(field, str(path), f"a wind file with at least 2 data rows (found "
                                            f"{len(times)})")
    t, v = np.asarray(times), np.asarray(speeds)
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        fail(rows[i], f"line {rows[i]}: time {t[i]:g} s is not after the previous row's "
                      f"{t[i - 1]:g} s (times must be strictly increasing)")
    what = "speed + gust speed" if gust else "speed"
    low = np.flatnonzero(v <= 0)
    if low.size:  # a calm has no tip-speed ratio ω_r R / v: the run would stop there
        i = int(low[0])
        fail(rows[i], f"line {rows[i]}: horizontal {what} {v[i]:g} m/s "
                      f"{'< 0' if v[i] < 0 else 'is zero'} (must be > 0, as every wind's)")
    high = np.flatnonzero(v > V_MAX_MPS)
    if high.size:
        i = int(high[0])
        fail(rows[i], f"line {rows[i]}: horizontal {what} {v[i]:g} m/s > {V_MAX_MPS:g} m/s "
                      "(the limit of every wind: V_e50 of IEC class I)")
    fmt = "csv" if is_csv else "inflowwind_uniform"
    resolved = str(p.resolve())
    return SampledWind("file", t, v, parameters={"path": str(path)}, source=resolved,
                       derived={"format": fmt, "sha256": hashlib.sha256(raw).hexdigest(),
                                "n_rows": int(t.size), "t_range_s": [float(t[0]), float(t[-1])],
                                "gust_column_added": bool(gust)})
