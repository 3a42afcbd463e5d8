"""Pitch faults per blade, scheduled in time (Odgaard, Stoustrup & Kinnaert 2013; eq (19)).

A fault configuration is a list of tables, each:

    blade = 1            # 1..3
    type = "lock"        # see FAULT_TYPES
    onset_s = 20.0
    end_s = 1e9          # optional: the fault disappears at end_s
    ramp_s = 0.0         # 0: abrupt; > 0: linear transition over ramp_s at onset and end
    # type-specific: rho (loss_of_effectiveness), angle_deg or "current" (lock),
    #                severity (pressure_drop, air_in_oil), value_deg (sensor_fixed),
    #                gain (sensor_gain)

Types: eq (19) ``lock`` (lock-in-place at a given angle, or ``angle_deg = "current"``:
wherever the blade is at onset) and ``loss_of_effectiveness`` (ρ); the benchmark's
``pressure_drop`` (ω_n 5.73 rad/s, ζ 0.45) and ``air_in_oil`` (ω_n 3.42 rad/s, ζ 0.9), at
full severity (1, the default) or part of the way from the nominal actuator (severity s in
(0, 1]: ω_n = ω_n0 + s (ω_n,fault − ω_n0), the same for ζ);
pitch sensor ``sensor_fixed`` and ``sensor_gain`` faults.
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

    acts_on: str  # "actuator" (the pitch actuator) or "sensor" (the pitch sensor)
    magnitude: str  # the type-specific key of a fault table


#: every fault type, the one list: `wtftc sweep` and `wtftc compare` derive theirs from it
TYPES = {
    "lock": FaultType("actuator", "angle_deg"),  # eq (19)
    "loss_of_effectiveness": FaultType("actuator", "rho"),  # eq (19)
    "pressure_drop": FaultType("actuator", "severity"),  # Odgaard et al. 2013
    "air_in_oil": FaultType("actuator", "severity"),  # Odgaard et al. 2013
    "sensor_fixed": FaultType("sensor", "value_deg"),
    "sensor_gain": FaultType("sensor", "gain"),
}
FAULT_TYPES = tuple(TYPES)
ACTUATOR_FAULT_TYPES = tuple(t for t, k in TYPES.items() if k.acts_on == "actuator")


@dataclass
class Fault:
    blade: int  # 1-based
    type: str
    onset_s: float
    end_s: float = np.inf
    ramp_s: float = 0.0
    rho: float = 1.0
    angle: float | None = None  # rad; None = wherever the blade is at onset
    value: float = 0.0  # rad, sensor_fixed
    gain: float = 1.0  # sensor_gain
    severity: float = 1.0  # pressure_drop, air_in_oil: fraction of the way to the fault's (ω_n, ζ)

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
        if self.type == "sensor_fixed":
            d["value_deg"] = float(np.degrees(self.value))
        if self.type == "sensor_gain":
            d["gain"] = self.gain
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
    n_blades = lay.n_blades()
    out = []
    for k, tab in enumerate(tables):
        w = f"{where}[{k}]"
        if not isinstance(tab, dict):
            raise ConfigError(w, tab, "a table with blade, type, onset_s, ...")
        typ = tab.get("type")
        if typ not in FAULT_TYPES:
            raise ConfigError(f"{w}.type", typ, "one of " + ", ".join(FAULT_TYPES))
        allowed = {"blade", "type", "onset_s", "end_s", "ramp_s", TYPES[typ].magnitude}
        for key in tab:
            if key not in allowed:
                raise ConfigError(f"{w}.{key}", tab[key],
                                  f"a key of a {typ} fault: {', '.join(sorted(allowed))}")
        blade = tab.get("blade")
        if isinstance(blade, bool) or not isinstance(blade, int) or not 1 <= blade <= n_blades:
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
        elif typ == "sensor_fixed":
            f.value = np.radians(_num(tab, "value_deg", w, 0.0, lo=-90.0, hi=90.0))
        elif typ == "sensor_gain":
            f.gain = _num(tab, "gain", w, 1.2, lo=0.0, lo_open=True)
        elif typ in HYDRAULIC:
            f.severity = _num(tab, "severity", w, 1.0, lo=0.0, hi=1.0, lo_open=True)
        out.append(f)
    return out


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

    def constant_between(self, a: float, b: float) -> bool:
        """Whether every fault input is the same at all times in [a, b] (no onset, end or
        ramp inside): the loop then passes one column for the whole chunk."""
        for f in self.faults:
            if not (b < f.onset_s or a >= f.onset_s + f.ramp_s):
                return False
            if not (b < f.end_s - f.ramp_s or a >= f.end_s):
                return False
        return True

    def bind_current_angles(self, t: float, beta: np.ndarray, dt: float) -> None:
        """Lock "wherever the blade is": each such lock whose onset falls on the step at t
        (the step nearest its onset, on a grid of dt) takes the angle beta of its blade.

        An onset need not lie on the grid (a sweep draws it at random); an unbound lock
        would command NaN, which the actuator's position clip turns into 0° in the plant.
        """
        step = int(round(t / dt))
        for f in self.faults:
            if f.type == "lock" and f.angle is None and int(round(f.onset_s / dt)) == step:
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
            elif f.type == "lock":
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
        """(n_sensor_faults, len(t)): gain_j, fixed_j, value_j (layout sensor_faults)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        n = lay.n_blades()
        gain, fixed, value = np.ones((n, t.size)), np.zeros((n, t.size)), np.zeros((n, t.size))
        for f in self.faults:
            j, w = f.blade - 1, f.weight(t)
            if f.type == "sensor_gain":
                gain[j] = 1 + (f.gain - 1) * w
            elif f.type == "sensor_fixed":
                fixed[j] = np.maximum(fixed[j], w)
                value[j] = np.where(w > 0, f.value, value[j])
        return _stacked("sensor_faults", t.size, sensor_gain=gain, sensor_fixed=fixed,
                        sensor_value=value)

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
