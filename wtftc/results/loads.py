"""Fatigue and duty figures of a run (issue 18): damage-equivalent loads by rainflow
counting, the pitch actuator's duty cycle, travel and reversals.

The rainflow counting is the `rainflow` package's (ASTM E1049-85, half cycles counted as
0.5; a maintained implementation rather than our own). The damage-equivalent load of a
load history with rainflow ranges S_i counted n_i times, for a Wöhler exponent m, is the
constant range that, applied N_eq times, does the same Palmgren-Miner damage:

    DEL = (Σ n_i S_i^m / N_eq)^(1/m)

quoted at an equivalent frequency of 1 Hz over the run, N_eq = T (seconds). The damage
per 10 minutes, Σ n_i S_i^m × 600 s / T, is what adds up over the wind bins of a design
load case (a lifetime DEL weights it by the wind distribution); a run of 10 minutes has
its DEL at 1 Hz equal to (damage per 10 min / 600)^(1/m).
"""

from __future__ import annotations

import numpy as np
import rainflow

#: the seconds of the reference period of a fatigue figure (IEC 61400-1 DLC 1.2 runs)
TEN_MINUTES_S = 600.0
#: the blade root's Wöhler exponent m: 10 for a composite blade, the slope WEIS gives its
#: blade-root channels RootMyb1-3 (weis/aeroelasticse/runFAST_pywrapper.py,
#: fatigue_channels_default, beside 4 for the tower base and the shaft)
BLADE_WOHLER_EXPONENT = 10.0
#: the half-width of a spectral band around n × the rotor frequency, a fraction of its
#: centre: ±10 % holds the rotor frequency as the speed wanders about its mean above rated
#: (the overspeed trip is at +20 %), and the 1P, 2P and 3P bands stay apart
BAND_HALF_WIDTH = 0.1
#: a pitch reversal is counted when the blade turns back by more than this [rad]: 0.1°,
#: above the sensors' resolution and the actuator's jitter under noise
REVERSAL_HYSTERESIS = np.radians(0.1)


def turning_points(series: np.ndarray) -> np.ndarray:
    """The series' first value, its local extrema (a plateau counted once) and its last
    value: all that rainflow counting and the play operator of :func:`reversals` see (both
    are rate-independent: between two extrema the series is monotone). A series at 1 kHz
    shrinks some hundredfold, and the Python loops that follow run over the extrema only."""
    x = np.asarray(series, dtype=float)
    if x.size < 3:
        return x
    s = np.sign(np.diff(x))
    moving = np.flatnonzero(s)  # steps that change the value
    if moving.size == 0:
        return x[[0, -1]]
    turn = moving[1:][s[moving[1:]] != s[moving[:-1]]]  # a step against the last one
    return np.concatenate([x[:1], x[turn], x[-1:]])


def damage_sum(series: np.ndarray, m: float) -> float:
    """Σ n_i S_i^m over the series' rainflow cycles (ranges S_i, counts n_i: 0.5 or 1)."""
    full = np.asarray(series, dtype=float)
    x = turning_points(full)
    if x.size < 3:  # a monotone series: the package counts its half cycle on 3 points
        x = full     # or more only (none on 2), so it gets the series itself
    if x.size < 2:
        return 0.0
    return float(sum(n * s**m for s, n in rainflow.count_cycles(x)))


def del_1hz(series: np.ndarray, duration_s: float, m: float) -> float:
    """The damage-equivalent load range at 1 Hz over ``duration_s``, in the series' unit."""
    if duration_s <= 0:
        raise ValueError(f"duration_s = {duration_s}: a positive duration")
    return (damage_sum(series, m) / duration_s) ** (1.0 / m)


def damage_per_10min(series: np.ndarray, duration_s: float, m: float) -> float:
    """Σ n_i S_i^m scaled to 10 minutes: the damage a DLC adds over its wind bins."""
    return damage_sum(series, m) * TEN_MINUTES_S / duration_s


def fatigue(series: np.ndarray, duration_s: float, m: float) -> dict:
    """DEL at 1 Hz, damage per 10 minutes, the Wöhler exponent and the largest |value|."""
    x = np.asarray(series, dtype=float)
    return {"del_1hz": del_1hz(x, duration_s, m),
            "damage_per_10min": damage_per_10min(x, duration_s, m),
            "wohler_exponent": m, "max_abs": float(np.max(np.abs(x)))}


def reversals(beta: np.ndarray, hysteresis: float = REVERSAL_HYSTERESIS) -> int:
    """How often the pitch turns back by more than ``hysteresis`` (rad): the direction
    changes of the series through a play (backlash) operator of that width, which keeps
    x − h ≤ y ≤ x and so ignores jitter smaller than h."""
    x = turning_points(beta)
    if x.size < 2:
        return 0
    y, direction, count = x[0], 0, 0
    for value in x[1:]:
        new = max(value - hysteresis, min(value, y))
        if new != y:
            step = 1 if new > y else -1
            count += direction == -step
            direction, y = step, new
    return count


def pitch_duty(beta: np.ndarray, dt: float, rate_max: float,
               hysteresis: float = REVERSAL_HYSTERESIS) -> dict:
    """The pitch actuator's duty, the blades' mean (``beta``: (samples, blades) in rad at
    the interval ``dt``):

    - ``adc``: the actuator duty cycle, the mean |β̇| over the rate limit, as TU Delft's
      IPC studies define it (Hummel, Kober & Mulders, Wind Energ. Sci. 2025,
      doi:10.5194/wes-2024-153) [-];
    - ``travel_rate_deg_s``: the mean |β̇| itself, what WEIS reports as
      ``avg_pitch_travel`` (its output declares deg/s) [deg/s];
    - ``travel_deg``: the angle each blade travelled [deg];
    - ``reversals``: each blade's turns back by more than the hysteresis (:func:`reversals`);
      per second it is WEIS's ``pitch_duty_cycle`` (declared deg/s there, a count per
      second in fact) [-].
    """
    b = np.atleast_2d(np.asarray(beta, dtype=float))
    if b.shape[0] < 2:
        return {"adc": 0.0, "travel_rate_deg_s": 0.0, "travel_deg": 0.0, "reversals": 0.0}
    steps = np.abs(np.diff(b, axis=0))
    return {"adc": float(np.mean(steps) / dt / rate_max),
            "travel_rate_deg_s": float(np.degrees(np.mean(steps) / dt)),
            "travel_deg": float(np.degrees(np.mean(np.sum(steps, axis=0)))),
            "reversals": float(np.mean([reversals(b[:, j], hysteresis)
                                        for j in range(b.shape[1])]))}


def band_std(series: np.ndarray, dt: float, f_low: float, f_high: float) -> float | None:
    """The standard deviation of a series' content between ``f_low`` and ``f_high`` [Hz],
    in the series' unit: the square root of its one-sided power spectral density summed
    over the band's bins. The density is the periodogram of the whole series, its mean
    removed, under a Hann window w (Welch's estimate with one segment; Welch, IEEE Trans.
    Audio Electroacoust. 15(2), 1967), normalised so that its sum over every bin is the
    windowed variance Σ (x w)² / Σ w² (Parseval):

        σ_band² = Σ_{f_low ≤ f_k ≤ f_high} c_k |X_k|² / (N Σ w²),   X = rfft(x w)

    with c_k = 2 but at 0 Hz and at the Nyquist frequency (1 there). A sine of amplitude A
    inside the band, a few bins from its edges, gives A/√2. None for fewer than 4 samples
    or a band that holds no bin (a window shorter than 1 / the band's width)."""
    x = np.asarray(series, dtype=float)
    n = x.size
    if n < 4 or not f_high > f_low:
        return None
    w = np.hanning(n)
    spec = np.abs(np.fft.rfft((x - x.mean()) * w)) ** 2
    f = np.fft.rfftfreq(n, dt)
    c = np.full(f.size, 2.0)
    c[0] = 1.0
    if n % 2 == 0:
        c[-1] = 1.0
    band = (f >= f_low) & (f <= f_high)
    if not band.any():
        return None
    return float(np.sqrt(np.sum(c[band] * spec[band]) / (n * np.sum(w**2))))


def harmonic_std(series: np.ndarray, dt: float, f_rotor: float, n: int,
                 half_width: float = BAND_HALF_WIDTH) -> float | None:
    """:func:`band_std` in the band n f_rotor (1 ± ``half_width``) [Hz]: the content at
    nP, the rotor frequency f_rotor = mean ω_r / 2π (None where the rotor stands)."""
    if not f_rotor > 0:
        return None
    return band_std(series, dt, n * f_rotor * (1 - half_width), n * f_rotor * (1 + half_width))
