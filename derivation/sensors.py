"""The measurement chain: what a turbine's sensors make of the true signals (ours).

The controllers and the FDI see the measurements ``omega_r``, ``omega_g_hss`` and
``beta_meas_1..3`` (derivation/controllers.py). Each goes through, in this order (the
order of Bladed's "signal noise and discretisation", Bladed User Manual 4.x):

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
    return [Entry(f"{kind}_{name}", d, _unit(u, unit), f"{what} sensor {doc}", sample=s)
            for kind, (d, u, s, doc) in FAULT_KINDS.items()
            for name, unit, _, what in SIGNALS]


def param_entries() -> list[Entry]:
    return [Entry(f"{kind}_{name}", 0.0, _unit(u, unit), f"{what} sensor {doc}", sample=s,
                  valid=valid)
            for kind, (u, s, valid, doc) in PARAM_KINDS.items()
            for name, unit, _, what in SIGNALS]


#: the benchmark's noise σ per signal, by parameter name (the realistic profile's defaults)
BENCHMARK_SIGMA = {f"sigma_{name}": sigma for name, _, sigma, _ in SIGNALS}

true = sp.symbols([f"true_{n}" for n in NAMES], real=True)
lagged = sp.symbols([f"lagged_{n}" for n in NAMES], real=True)
noise = sp.symbols([f"noise_{n}" for n in NAMES], real=True)


def _sym(kind: str, name: str) -> sp.Symbol:
    return sp.Symbol(f"{kind}_{name}", real=True)


def _positive_or_one(x: sp.Symbol) -> sp.Expr:
    """x where x > 0, else 1e-300: a divisor that never is zero in the branch not taken
    (NumPy evaluates both branches of a Piecewise)."""
    return sp.Max(x, sp.Float(1e-300))


def lag_rhs() -> list[sp.Expr]:
    """ẏ = (x - y)/T_lag per signal; 0 without a lag (T_lag = 0)."""
    out = []
    for x, y, name in zip(true, lagged, NAMES, strict=True):
        tau = _sym("lag", name)
        out.append(sp.Piecewise(((x - y) / _positive_or_one(tau), tau > 0), (0, True)))
    return out


def measured() -> list[sp.Expr]:
    """The measurement of every signal (see the module docstring)."""
    out = []
    for x, y, n_k, name in zip(true, lagged, noise, NAMES, strict=True):
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

#: the controllers' model's gearbox ratio, an input of the speed estimate
gearbox = sp.Symbol("gearbox_ratio", positive=True)
measured_symbols = sp.symbols(NAMES, real=True)


def speed_estimate() -> sp.Expr:
    """The controllers' rotor speed: the inverse-variance weighted mean of the two speed
    sensors, ω̂ = (1 − w) ω_r,m + w ω_g,m/N, w = σ_r²/(σ_r² + (σ_g/N)²) (the
    minimum-variance combination of two unbiased measurements of one quantity; N the
    gearbox ratio). With σ_r = 0 (exact sensors): the rotor speed sensor alone, as before.
    The shaft's torsion, ω_g − ω_r, is the price (below 0.002 rad/s on the NREL 5-MW)."""
    m = dict(zip(NAMES, measured_symbols, strict=True))
    s_r, s_g = _sym("sigma", "omega_r"), _sym("sigma", "omega_g_hss") / gearbox
    # the two must agree within 4 standard deviations of their difference plus the
    # shaft's torsion; when they do not (a speed sensor stuck, scaled or offset), the
    # larger of the two is taken: the safe side, the controller then pitches for the
    # faster rotor and a single speed sensor's fault can slow the rotor (lose power) but
    # not run it away (ours; a max-select of redundant speed signals, as overspeed
    # protections do)
    w_r, w_g = m["omega_r"], m["omega_g_hss"] / gearbox
    agree = sp.Abs(w_g - w_r) <= CONSISTENCY_SIGMAS * sp.sqrt(s_r**2 + s_g**2) \
        + TORSION_ALLOWANCE
    w = s_r**2 / sp.Max(s_r**2 + s_g**2, sp.Float(1e-300))
    return sp.Piecewise((w_r, s_r <= 0), ((1 - w) * w_r + w * w_g, agree),
                        (sp.Max(w_r, w_g), True))
