"""The measurement chain: what a turbine's sensors make of the true signals (ours).

Every measured quantity (``omega_r``, ``omega_g_hss``, ``beta_meas_1..3``) has two sensors,
m1 and m2 (the benchmark's redundancy); the FDI reads all ten, and the controllers read
the quantities voted from them (``virtual_sensors``, derivation/controllers.py's
measurements). Each sensor's reading goes through, in this order (the order of Bladed's
"signal noise and discretisation", Bladed User Manual 4.x):

1. a first-order **lag** ẏ = (x - y)/T_lag (T_lag = 0: no lag; the state is then unused);
2. a **sensor fault** (Odgaard et al. 2013; Peña-Sanchez et al. 2024): gain g, offset o
   (a drift is an offset growing in time, set by the schedule), and stuck at a value
   (weight s in [0, 1], 1 = stuck);
3. a constant **bias** b and Gaussian **noise** σ·k·n (n a standard normal draw held over
   the control interval, k the fault's noise factor: precision degradation);
4. **quantization** to the resolution q (q = 0: none): q·⌊m/q + ½⌋.

    m = Q_q( (1 - s)·(g·y + o + b + k σ n) + s·value )

The noise draws come from the runtime (deterministic from the run's seed); this function
only scales them. No derivative of this chain enters a controller's α̇: the controllers
differentiate their own states, never a measurement.
"""

from __future__ import annotations

import sympy as sp

from derivation.layout import Entry

#: the measured signals, in the controllers' measurement order, with units and the
#: benchmark's noise σ (Odgaard, Stoustrup & Kinnaert 2013, Table/benchmark script
#: FDIBenchMarkData.m: pitch 0.2°, rotor speed 0.025 rad/s, generator speed 0.05 rad/s on
#: the HSS; docs/sensors.md)
SIGNALS = [
    ("omega_r", "rad/s", 0.004 * 2 * 3.141592653589793, "rotor speed"),
    ("omega_g_hss", "rad/s", 0.05, "generator speed (high-speed shaft)"),
    ("beta_meas_1", "rad", 0.2 * 3.141592653589793 / 180, "pitch of blade 1"),
    ("beta_meas_2", "rad", 0.2 * 3.141592653589793 / 180, "pitch of blade 2"),
    ("beta_meas_3", "rad", 0.2 * 3.141592653589793 / 180, "pitch of blade 3"),
]
NAMES = [s[0] for s in SIGNALS]
#: every quantity is measured by two sensors, m1 and m2, as in the benchmark (Odgaard,
#: Stoustrup & Kinnaert 2013, Section 2: β_i,m1, β_i,m2, ω_r,m1, ω_r,m2, ω_g,m1, ω_g,m2);
#: the sensors in order: every signal's m1, then every signal's m2
SENSORS = [(f"{name}_m{k}", name, unit, sigma, what)
           for k in (1, 2) for name, unit, sigma, what in SIGNALS]
SENSOR_NAMES = [s[0] for s in SENSORS]

#: per-signal fault inputs (time-varying, from the fault schedule): kind → (default, unit
#: suffix or "-", sample range, doc)
FAULT_KINDS = {
    "gain": (1.0, "-", (0.8, 1.2), "gain (fault: ≠ 1)"),
    "offset": (0.0, None, (-0.05, 0.05), "offset (fault: ≠ 0; a drift grows it in time)"),
    "stuck": (0.0, "-", (0.0, 1.0), "stuck weight (1: reads stuck_value)"),
    "stuck_value": (0.0, None, (0.0, 0.5), "the value a stuck sensor reads"),
    "noise_factor": (1.0, "-", (0.5, 3.0), "noise multiplier (precision degradation: > 1)"),
}
#: per-signal sensor parameters (constant over a run, the [sensors] table): kind →
#: (unit suffix or None: the signal's unit, sample range, valid range, doc)
PARAM_KINDS = {
    "sigma": (None, (0.0, 0.05), (0.0, None, False, False), "Gaussian noise σ"),
    "bias": (None, (-0.02, 0.02), None, "constant bias"),
    "resolution": (None, (0.0, 0.01), (0.0, None, False, False),
                   "quantization step (0: none)"),
    "lag": ("s", (0.0, 0.2), (0.0, None, False, False),
            "first-order lag time constant (0: none)"),
}


def _unit(suffix, signal_unit):
    return signal_unit if suffix is None else suffix


def fault_entries() -> list[Entry]:
    return [Entry(f"{kind}_{name}", d, _unit(u, unit), f"{what} sensor {name[-2:]} {doc}",
                  sample=s)
            for kind, (d, u, s, doc) in FAULT_KINDS.items()
            for name, _, unit, _, what in SENSORS]


def param_entries() -> list[Entry]:
    return [Entry(f"{kind}_{name}", 0.0, _unit(u, unit), f"{what} sensor {name[-2:]} {doc}",
                  sample=s, valid=valid)
            for kind, (u, s, valid, doc) in PARAM_KINDS.items()
            for name, _, unit, _, what in SENSORS]


#: the benchmark's noise σ per signal, by parameter name (the realistic profile's defaults)
BENCHMARK_SIGMA = {f"sigma_{name}": sigma for name, _, _, sigma, _ in SENSORS}

#: per sensor: the true signal it measures, its lag state, its noise draw
true = sp.symbols([f"true_{n}" for n in SENSOR_NAMES], real=True)
lagged = sp.symbols([f"lagged_{n}" for n in SENSOR_NAMES], real=True)
noise = sp.symbols([f"noise_{n}" for n in SENSOR_NAMES], real=True)


def _sym(kind: str, name: str) -> sp.Symbol:
    return sp.Symbol(f"{kind}_{name}", real=True)


def _positive_or_one(x: sp.Symbol) -> sp.Expr:
    """x where x > 0, else 1e-300: a divisor that never is zero in the branch not taken
    (NumPy evaluates both branches of a Piecewise)."""
    return sp.Max(x, sp.Float(1e-300))


def lag_rhs() -> list[sp.Expr]:
    """ẏ = (x - y)/T_lag per sensor; 0 without a lag (T_lag = 0)."""
    out = []
    for x, y, name in zip(true, lagged, SENSOR_NAMES, strict=True):
        tau = _sym("lag", name)
        out.append(sp.Piecewise(((x - y) / _positive_or_one(tau), tau > 0), (0, True)))
    return out


def measured() -> list[sp.Expr]:
    """The reading of every sensor (see the module docstring)."""
    out = []
    for x, y, n_k, name in zip(true, lagged, noise, SENSOR_NAMES, strict=True):
        s = {k: _sym(k, name) for k in (*FAULT_KINDS, *PARAM_KINDS)}
        seen = sp.Piecewise((y, s["lag"] > 0), (x, True))
        reading = s["gain"] * seen + s["offset"] + s["bias"] + s["noise_factor"] * s["sigma"] * n_k
        m = (1 - s["stuck"]) * reading + s["stuck"] * s["stuck_value"]
        q = s["resolution"]
        out.append(sp.Piecewise((q * sp.floor(m / _positive_or_one(q) + sp.Rational(1, 2)),
                                 q > 0), (m, True)))
    return out


#: the speed estimate's consistency test: |ω_g/N − ω_r| within this many standard
#: deviations of the difference, plus the shaft's torsion [rad/s] (below 0.002 rad/s on the
#: NREL 5-MW in turbulence; 0.01 leaves room for a softer shaft)
CONSISTENCY_SIGMAS = 4
TORSION_ALLOWANCE = sp.Rational(1, 100)
#: two sensors of one quantity agree within 4 standard deviations of their difference,
#: their resolutions, and this floor: 0.1° on the pitch (twice an absolute encoder's
#: accuracy), 0.01 rad/s on the rotor speed (in rotor units on the generator's)
PITCH_AGREEMENT = sp.pi / 1800
SPEED_AGREEMENT = sp.Rational(1, 100)

#: the controllers' model's gearbox ratio, an input of the virtual sensors
gearbox = sp.Symbol("gearbox_ratio", positive=True)
#: the sensors' readings, and per sensor the FDI's verdict: ≥ 1/2 excluded (its latch)
readings = sp.symbols(SENSOR_NAMES, real=True)
excluded = sp.symbols([f"excluded_{n}" for n in SENSOR_NAMES], real=True)


def _pair(name: str, floor: sp.Expr):
    """(m1, m2, excluded m1, excluded m2, agreement tolerance) of a quantity's two
    sensors."""
    r = dict(zip(SENSOR_NAMES, readings, strict=True))
    x = dict(zip(SENSOR_NAMES, excluded, strict=True))
    a, b = f"{name}_m1", f"{name}_m2"
    tol = CONSISTENCY_SIGMAS * sp.sqrt(_sym("sigma", a)**2 + _sym("sigma", b)**2) \
        + _sym("resolution", a) + _sym("resolution", b) + floor
    return r[a], r[b], x[a], x[b], tol


def _voted(name: str, floor: sp.Expr, ref: sp.Expr) -> sp.Expr:
    """One quantity from its two sensors (a virtual sensor, ours): the one the FDI has not
    excluded; else their mean when they agree; else, before the FDI has decided, the one
    closer to ``ref`` (an estimate of the quantity from the other sensors). Two identical
    readings give that reading, bit for bit."""
    x1, x2, e1, e2, tol = _pair(name, floor)
    half = sp.Rational(1, 2)
    return sp.Piecewise((x2, e1 >= half), (x1, e2 >= half),
                        ((x1 + x2) / 2, sp.Abs(x1 - x2) <= tol),
                        (x1, sp.Abs(x1 - ref) <= sp.Abs(x2 - ref)), (x2, True))


def _mean(name: str) -> sp.Expr:
    x1, x2, *_ = _pair(name, 0)
    return (x1 + x2) / 2


#: the two voted speeds, intermediate symbols of virtual_sensors (SymPy would fold one
#: Piecewise into the other's conditions)
voted_rotor, voted_gen = sp.symbols("voted_omega_r voted_omega_g_hss", real=True)


def virtual_sensors() -> tuple[dict[sp.Symbol, sp.Expr], list[sp.Expr]]:
    """The controllers' measurements [ω̂_r, ω_g, β_1..3] from the ten sensors, and the
    intermediate voted speeds they are written in.

    * Each pitch: its two sensors voted (_voted), the reference the mean of the other
      blades' sensors (collective pitch; it matters only while two sensors disagree and
      the FDI has not yet excluded one).
    * The generator speed: its two sensors voted, the reference the rotor's sensors × N;
      the rotor speed's pair likewise against the generator's / N.
    * The rotor speed the controllers get: the inverse-variance weighted mean of the two
      voted speeds, ω̂ = (1 − w) ω_r + w ω_g/N, w = σ_r²/(σ_r² + (σ_g/N)²) (the
      minimum-variance combination of two unbiased measurements of one quantity). With
      σ_r = 0 (exact sensors): the rotor's speed sensors alone, as before. When the two
      voted speeds disagree by more than 4σ + 0.01 rad/s (both sensors of one quantity
      failed), the larger: the safe side (a max-select, as overspeed protections do).
    """
    n_b = len(NAMES) - 2
    betas = [f"beta_meas_{j}" for j in range(1, n_b + 1)]
    pitch = [_voted(b, PITCH_AGREEMENT, sum(_mean(o) for o in betas if o != b) / (n_b - 1))
             for b in betas]
    voted = {voted_rotor: _voted("omega_r", SPEED_AGREEMENT, _mean("omega_g_hss") / gearbox),
             voted_gen: _voted("omega_g_hss", SPEED_AGREEMENT * gearbox,
                               _mean("omega_r") * gearbox)}
    w_r, g = voted_rotor, voted_gen
    s_r = _sym("sigma", "omega_r_m1")
    s_g = _sym("sigma", "omega_g_hss_m1") / gearbox
    w_g = g / gearbox
    agree = sp.Abs(w_g - w_r) <= CONSISTENCY_SIGMAS * sp.sqrt(s_r**2 + s_g**2) \
        + TORSION_ALLOWANCE
    w = s_r**2 / sp.Max(s_r**2 + s_g**2, sp.Float(1e-300))
    omega = sp.Piecewise((w_r, s_r <= 0), ((1 - w) * w_r + w * w_g, agree),
                         (sp.Max(w_r, w_g), True))
    return voted, [omega, g, *pitch]
