"""Pitch faults per blade, scheduled in time (Odgaard, Stoustrup & Kinnaert 2013; eq (19)).

A fault configuration is a list of tables, each:

    blade = 1            # 1..3
    type = "lock"        # see FAULT_TYPES
    onset_s = 20.0
    end_s = 1e9          # optional: the fault disappears at end_s
    ramp_s = 0.0         # 0: abrupt; > 0: linear transition over ramp_s at onset and end
    # type-specific: rho (loss_of_effectiveness), angle_deg or "current" (lock),
    #                severity (pressure_drop, air_in_oil), target_deg (runaway);
    #                sensor faults: see SENSOR_TYPES

Types: eq (19) ``lock`` (lock-in-place at a given angle, or ``angle_deg = "current"``:
wherever the blade is at onset) and ``loss_of_effectiveness`` (ρ); the benchmark's
``pressure_drop`` (ω_n 5.73 rad/s, ζ 0.45) and ``air_in_oil`` (ω_n 3.42 rad/s, ζ 0.9), at
full severity (1, the default) or part of the way from the nominal actuator (severity s in
(0, 1]: ω_n = ω_n0 + s (ω_n,fault − ω_n0), the same for ζ); a ``runaway`` (IEC 61400-1
DLC 2.1/2.2's control fault: the blade's actuator driven toward ``target_deg``, 0° fine
pitch by default or 90° feather, whatever the controller commands: eq (19)'s lock at the
target, the blade moving there at its actuator's speed, held to the rate limit);
and sensor faults on every measured signal (derivation/sensors.py): the pitch sensors'
``pitch_sensor_stuck|gain|offset|drift|precision`` (blade j), and the rotor and generator
speed sensors' ``rotor_speed_sensor_stuck|gain|offset`` and
``generator_speed_sensor_stuck|gain|offset`` (no blade; the generator speed on the
high-speed shaft); ``sensor = 1`` or ``2`` names which of the quantity's two sensors (m1,
m2, the benchmark's redundancy) fails, 1 by default. Types of the benchmark (Odgaard et
al. 2013: stuck, gain) and of FOWLTY (Peña-Sanchez et al. 2024: offset, drift, precision
degradation). The old names ``sensor_fixed`` and ``sensor_gain`` are aliases of
``pitch_sensor_stuck`` and ``pitch_sensor_gain``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.errors import ConfigError

#: actuator dynamics of the hydraulic faults at full severity (ω_n rad/s, ζ; Odgaard et al.
#: 2013, derivation/nrel5mw.py via generated/layout.json)
HYDRAULIC = {typ: (d["omega_n"], d["zeta"]) for typ, d in lay.layout()["hydraulic_faults"].items()}


@dataclass(frozen=True)
class FaultType:
    """What a fault type acts on, and the key of its fault table that sets how large it is."""

    acts_on: str  # "actuator" (the pitch actuator) or "sensor"
    magnitude: str  # the type-specific key of a fault table
    signal: str = ""  # a sensor fault's signal: "pitch" (per blade), "omega_r", "omega_g_hss"
    kind: str = ""  # a sensor fault's kind: stuck, gain, offset, drift, precision
    default: float = 0.0  # the magnitude's default, in the key's unit
    bounds: tuple = (None, None, False)  # (low, high, low_open) of the magnitude


#: the sensor faults' signals: name in the fault type → (measurement, degrees at the edge)
SENSOR_SIGNALS = {"pitch": ("beta_meas", True), "rotor_speed": ("omega_r", False),
                  "generator_speed": ("omega_g_hss", False)}
_SENSOR_KINDS = {  # kind → (key stem, default, bounds, pitch only)
    "stuck": ("value", 0.0, (None, None, False), False),
    "gain": ("gain", 1.2, (0.0, None, True), False),
    "offset": ("offset", 1.0, (None, None, False), False),
    "drift": ("rate", 0.01, (None, None, False), True),
    "precision": ("factor", 3.0, (0.0, None, True), True),
}


def _sensor_types() -> dict[str, FaultType]:
    out = {}
    for sig, (_, deg) in SENSOR_SIGNALS.items():
        for kind, (stem, default, bounds, pitch_only) in _SENSOR_KINDS.items():
            if pitch_only and sig != "pitch":
                continue
            unit = {"value": "_deg" if deg else "_rad_s", "offset": "_deg" if deg else "_rad_s",
                    "rate": "_deg_s", "gain": "", "factor": ""}[stem]
            out[f"{sig}_sensor_{kind}"] = FaultType("sensor", stem + unit, sig, kind, default,
                                                    bounds)
    return out


#: every fault type, the one list: `wtftc sweep` and `wtftc compare` derive theirs from it
TYPES = {
    "lock": FaultType("actuator", "angle_deg"),  # eq (19)
    "loss_of_effectiveness": FaultType("actuator", "rho"),  # eq (19)
    "pressure_drop": FaultType("actuator", "severity"),  # Odgaard et al. 2013
    "air_in_oil": FaultType("actuator", "severity"),  # Odgaard et al. 2013
    # IEC 61400-1 DLC 2.x: a pitch runaway toward fine pitch (0°, default) or feather
    "runaway": FaultType("actuator", "target_deg", default=0.0, bounds=(0.0, 90.0, False)),
    **_sensor_types(),
}
#: old names of sensor fault types, still read
ALIASES = {"sensor_fixed": "pitch_sensor_stuck", "sensor_gain": "pitch_sensor_gain"}
FAULT_TYPES = tuple(TYPES)
ACTUATOR_FAULT_TYPES = tuple(t for t, k in TYPES.items() if k.acts_on == "actuator")
SENSOR_FAULT_TYPES = tuple(t for t, k in TYPES.items() if k.acts_on == "sensor")


@dataclass
class Fault:
    blade: int  # 1-based; 0 for a speed sensor's fault
    type: str
    onset_s: float
    end_s: float = np.inf
    ramp_s: float = 0.0
    rho: float = 1.0
    angle: float | None = None  # rad; None = wherever the blade is at onset
    severity: float = 1.0  # pressure_drop, air_in_oil: fraction of the way to the fault's (ω_n, ζ)
    #: a sensor fault's magnitude in SI (stuck value, gain, offset, drift rate per s,
    #: noise factor)
    magnitude: float = 0.0
    #: a sensor fault's sensor: 1 or 2 (every quantity has two, m1 and m2: the benchmark's)
    sensor: int = 1

    def weight(self, t: np.ndarray) -> np.ndarray:
        """0 before onset, 1 while active, linear over ramp_s at both ends."""
        t = np.asarray(t, dtype=float)
        if self.ramp_s > 0:
            up = np.clip((t - self.onset_s) / self.ramp_s, 0.0, 1.0)
            down = np.clip((self.end_s - t) / self.ramp_s, 0.0, 1.0)
        else:
            up = (t >= self.onset_s).astype(float)
            down = (t < self.end_s).astype(float)
        return np.minimum(up, down)

    def describe(self) -> dict:
        d = {"blade": self.blade, "type": self.type, "onset_s": self.onset_s,
             "end_s": None if np.isinf(self.end_s) else self.end_s, "ramp_s": self.ramp_s}
        if self.type == "loss_of_effectiveness":
            d["rho"] = self.rho
        if self.type == "lock":
            d["angle_deg"] = "current" if self.angle is None else float(np.degrees(self.angle))
        if self.type == "runaway":
            d["target_deg"] = float(np.degrees(self.angle))
        ft = TYPES[self.type]
        if ft.acts_on == "sensor":
            if not self.blade:
                del d["blade"]
            d["sensor"] = self.sensor
            key = ft.magnitude
            d[key] = float(np.degrees(self.magnitude)) if "_deg" in key else self.magnitude
        if self.type in HYDRAULIC:
            d["severity"] = self.severity
        return d


def _num(tab: dict, key: str, where: str, default=None, lo=None, hi=None, lo_open=False):
    val = tab.get(key, default)
    if isinstance(val, bool) or not isinstance(val, int | float):
        raise ConfigError(f"{where}.{key}", val, "a number")
    val = float(val)
    if not np.isfinite(val):
        raise ConfigError(f"{where}.{key}", val, "a finite number")
    if lo is not None and (val <= lo if lo_open else val < lo):
        raise ConfigError(f"{where}.{key}", val, f"a number {'>' if lo_open else '>='} {lo}")
    if hi is not None and val > hi:
        raise ConfigError(f"{where}.{key}", val, f"a number <= {hi}")
    return val


def parse_faults(tables, where: str = "fault") -> list[Fault]:
    """Validate a list of fault tables (as read from TOML) into :class:`Fault` objects."""
    if tables is None:
        return []
    if isinstance(tables, dict):
        tables = [tables]
    if not isinstance(tables, list):
        raise ConfigError(where, tables, "a list of fault tables")
    return [_parse_fault(tab, f"{where}[{k}]") for k, tab in enumerate(tables)]


def _parse_fault(tab, w: str) -> Fault:
    if not isinstance(tab, dict):
        raise ConfigError(w, tab, "a table with blade, type, onset_s, ...")
    typ = tab.get("type")
    typ = ALIASES.get(typ, typ) if isinstance(typ, str) else typ
    if typ not in FAULT_TYPES:
        raise ConfigError(f"{w}.type", tab.get("type"), "one of " + ", ".join(FAULT_TYPES))
    ft = TYPES[typ]
    per_blade = ft.acts_on == "actuator" or ft.signal == "pitch"
    allowed = {"type", "onset_s", "end_s", "ramp_s", ft.magnitude} | (
        {"blade"} if per_blade else set()) | ({"sensor"} if ft.acts_on == "sensor" else set())
    for key in tab:
        if key not in allowed:
            raise ConfigError(f"{w}.{key}", tab[key],
                              f"a key of a {typ} fault: {', '.join(sorted(allowed))}"
                              + ("" if per_blade else " (a speed sensor has no blade)"))
    n_blades = lay.n_blades()
    blade = tab.get("blade") if per_blade else 0
    if per_blade and (isinstance(blade, bool) or not isinstance(blade, int)
                      or not 1 <= blade <= n_blades):
        raise ConfigError(f"{w}.blade", blade, f"an integer 1..{n_blades}")
    onset = _num(tab, "onset_s", w, 20.0, lo=0.0)
    end = _num(tab, "end_s", w, np.inf, lo=onset, lo_open=True) if "end_s" in tab else np.inf
    f = Fault(blade=blade, type=typ, onset_s=onset, end_s=end,
              ramp_s=_num(tab, "ramp_s", w, 0.0, lo=0.0))
    if typ == "loss_of_effectiveness":
        f.rho = _num(tab, "rho", w, 0.5, lo=0.0, hi=1.0, lo_open=True)
    elif typ == "lock":
        ang = tab.get("angle_deg", "current")
        if ang != "current":
            f.angle = np.radians(_num(tab, "angle_deg", w, lo=0.0, hi=90.0))
    elif typ == "runaway":
        f.angle = np.radians(_num(tab, "target_deg", w, ft.default, lo=0.0, hi=90.0))
    elif typ in HYDRAULIC:
        f.severity = _num(tab, "severity", w, 1.0, lo=0.0, hi=1.0, lo_open=True)
    else:
        f.sensor = tab.get("sensor", 1)
        if type(f.sensor) is not int or f.sensor not in (1, 2):
            raise ConfigError(f"{w}.sensor", f.sensor, "1 or 2 (every quantity has two "
                              "sensors, m1 and m2)")
        lo, hi, lo_open = ft.bounds
        val = _num(tab, ft.magnitude, w, ft.default, lo=lo, hi=hi, lo_open=lo_open)
        f.magnitude = np.radians(val) if "_deg" in ft.magnitude else val
    return f


#: the default fault of the paper's cases 2 and 3 (Fig. 6 gives no numbers; docs/cases.md)
DEFAULT_FAULT = [
    {"blade": 1, "type": "lock", "onset_s": 20.0, "angle_deg": "current"},
    {"blade": 2, "type": "loss_of_effectiveness", "onset_s": 20.0, "rho": 0.5},
    {"blade": 3, "type": "loss_of_effectiveness", "onset_s": 20.0, "rho": 0.5},
]


def _nominal_dynamics(p_turbine=None) -> tuple[float, float]:
    """The actuator's nominal (ω_n [rad/s], ζ) of a turbine (the layout's default one)."""
    tp = lay.vector("turbine_params") if p_turbine is None else np.asarray(p_turbine)
    return (float(tp[lay.index("turbine_params", "omega_n_nominal")]),
            float(tp[lay.index("turbine_params", "zeta_nominal")]))


def nominal_actuator(p_turbine=None) -> np.ndarray:
    """The actuator fault inputs of a fault-free turbine: ρ = 1, no lock, and the turbine's
    nominal ω_n, ζ on every blade (not the layout's: the run's turbine may change them)."""
    return Schedule([], p_turbine).actuator(np.zeros(1))[:, 0]


@dataclass
class Schedule:
    """Per-step fault inputs of the compiled loop, in the layout's order."""

    faults: list[Fault] = field(default_factory=list)
    #: the turbine parameters of the run: the actuator's nominal ω_n, ζ come from them
    p_turbine: tuple | None = None

    def events(self) -> list[float]:
        """Times at which a lock "wherever the blade is" must read the blade angle."""
        return sorted({f.onset_s for f in self.faults if f.type == "lock" and f.angle is None})

    @property
    def has_sensor_faults(self) -> bool:
        """Whether any fault acts on a sensor (its inputs are then not the nominal ones)."""
        return any(TYPES[f.type].acts_on == "sensor" for f in self.faults)

    def constant_between(self, a: float, b: float) -> bool:
        """Whether every fault input is the same at all times in [a, b] (no onset, end or
        ramp inside): the loop then passes one column for the whole chunk."""
        for f in self.faults:
            if f.type.endswith("_drift") and b >= f.onset_s and a < f.end_s:
                return False  # a drift grows all the time it is active
            if not (b < f.onset_s or a >= f.onset_s + f.ramp_s):
                return False
            if not (b < f.end_s - f.ramp_s or a >= f.end_s):
                return False
        return True

    def changes(self) -> list[float]:
        """The finite times at which a fault input starts or stops changing (onsets, ends
        and their ramps' other ends): constant between two of them, except while a drift
        is active (:meth:`constant_between`)."""
        times = {x for f in self.faults for x in (f.onset_s, f.onset_s + f.ramp_s,
                                                  f.end_s - f.ramp_s, f.end_s)}
        return sorted(x for x in times if np.isfinite(x))

    def bind_current_angles(self, t: float, beta: np.ndarray, dt: float, every: int = 1
                            ) -> None:
        """Lock "wherever the blade is": each such lock whose onset falls on the step at t
        (the step nearest its onset, on a grid of dt; in a sampled loop, of ``every``
        steps: the interval that holds the onset step) takes the angle beta of its blade.

        An onset need not lie on the grid (a sweep draws it at random); an unbound lock
        would command NaN, which the actuator's position clip turns into 0° in the plant.
        """
        step = int(round(t / dt))
        for f in self.faults:
            if (f.type == "lock" and f.angle is None
                    and int(round(f.onset_s / dt)) // every * every == step):
                f.angle = float(beta[f.blade - 1])

    def actuator(self, t: np.ndarray) -> np.ndarray:
        """(n_actuator_faults, len(t)): ρ_j, σ_j, ū_j, ω_n,j, ζ_j (layout actuator_faults)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        n = lay.n_blades()
        rho, lock, ubar = np.ones((n, t.size)), np.zeros((n, t.size)), np.zeros((n, t.size))
        wn0, z0 = _nominal_dynamics(self.p_turbine)
        wn, zt = np.full((n, t.size), wn0), np.full((n, t.size), z0)
        for f in self.faults:
            j, w = f.blade - 1, f.weight(t)
            if f.type == "loss_of_effectiveness":
                rho[j] = rho[j] * (1 - w) + f.rho * w
            elif f.type in ("lock", "runaway"):  # a runaway: locked onto its target
                lock[j] = np.maximum(lock[j], w)
                ubar[j] = np.where(w > 0, f.angle if f.angle is not None else np.nan, ubar[j])
            elif f.type in HYDRAULIC:
                wf, zf = HYDRAULIC[f.type]
                wf, zf = wn0 + f.severity * (wf - wn0), z0 + f.severity * (zf - z0)
                wn[j] = wn[j] * (1 - w) + wf * w
                zt[j] = zt[j] * (1 - w) + zf * w
        return _stacked("actuator_faults", t.size, rho=rho, lock=lock, ubar=ubar, omega_n=wn,
                        zeta=zt)

    def sensor(self, t: np.ndarray) -> np.ndarray:
        """(n_sensor_faults, len(t)): per measured signal its gain, offset, stuck weight,
        stuck value and noise factor (layout sensor_faults, derivation/sensors.py)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        names = [e["name"] for e in lay.layout()["sensors"]]
        rows = {k: {n: np.full(t.size, d) for n in names}
                for k, d in (("gain", 1.0), ("offset", 0.0), ("stuck", 0.0),
                             ("stuck_value", 0.0), ("noise_factor", 1.0))}
        for f in self.faults:
            ft = TYPES[f.type]
            if ft.acts_on != "sensor":
                continue
            base = SENSOR_SIGNALS[ft.signal][0]
            sig = (f"{base}_{f.blade}" if ft.signal == "pitch" else base) + f"_m{f.sensor}"
            w = f.weight(t)
            if ft.kind == "gain":
                rows["gain"][sig] = rows["gain"][sig] + (f.magnitude - 1) * w
            elif ft.kind == "offset":
                rows["offset"][sig] = rows["offset"][sig] + f.magnitude * w
            elif ft.kind == "drift":  # an offset growing from the onset
                grown = f.magnitude * np.clip(t - f.onset_s, 0.0, None)
                rows["offset"][sig] = rows["offset"][sig] + grown * (w > 0)
            elif ft.kind == "precision":
                rows["noise_factor"][sig] = rows["noise_factor"][sig] + (f.magnitude - 1) * w
            elif ft.kind == "stuck":
                rows["stuck"][sig] = np.maximum(rows["stuck"][sig], w)
                rows["stuck_value"][sig] = np.where(w > 0, f.magnitude, rows["stuck_value"][sig])
        order = lay.names("sensor_faults")
        out = np.empty((len(order), t.size))
        for i, name in enumerate(order):
            kind = next(k for k in ("stuck_value", "gain", "offset", "stuck", "noise_factor")
                        if name.startswith(k + "_"))
            out[i] = rows[kind][name[len(kind) + 1:]]
        return out

    def describe(self) -> list[dict]:
        return [f.describe() for f in self.faults]


def _stacked(group: str, n_t: int, **blocks: np.ndarray) -> np.ndarray:
    """(size of ``group``, n_t): each (n_blades, n_t) block at the rows of its numbered
    entries in the layout (``rho`` at ``rho_1..rho_3``, ...)."""
    size, rows = _rows(group, tuple(blocks))
    out = np.empty((size, n_t))
    for at, block in zip(rows, blocks.values(), strict=True):
        out[at] = block
    return out


@cache
def _rows(group: str, prefixes: tuple[str, ...]) -> tuple[int, list[slice]]:
    """The size of ``group`` and where each prefix's block sits; every row must be covered."""
    rows = [lay.block(group, prefix) for prefix in prefixes]
    given = np.zeros(lay.size(group), dtype=bool)
    for at in rows:
        given[at] = True
    if not given.all():
        missing = [n for n, g in zip(lay.names(group), given, strict=True) if not g]
        raise KeyError(f"{group}: no values for {', '.join(missing)}")
    return given.size, rows
