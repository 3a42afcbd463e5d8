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
