"""The scorecard's statistics: paired ratios against the baseline with a bootstrap
interval over seeds, the verdict, lifetime loads and energy split at rated wind, and the
upper bound of a false-alarm rate.

A ratio is a scale (0.5 is as far below 1 as 2 is above it), so a ratio over many paired
scenarios is the geometric mean of preset / baseline. The scenarios of one turbulence
seed share its wind and are not independent of each other; the seeds are. The interval is
therefore a cluster bootstrap over seeds (Davison and Hinkley, Bootstrap Methods and
their Application, 1997, section 3.8): a resample draws as many seeds as there are, with
replacement, and keeps every scenario of each seed drawn; the statistic is recomputed on
it, and the interval is the percentile interval of those statistics (each bound the
smallest resampled value whose cumulative probability reaches the tail's probability, or
one minus it: the inverted CDF). Where the distinct resamples of n seeds, C(2n − 1, n),
are no more than ``n_boot`` (n ≤ 7 at the default 2000), every one is enumerated with
its multinomial probability: the exact bootstrap distribution, the same on every
machine. Beyond, ``n_boot`` resamples are drawn from a generator seeded by ``seed``.

A plain percentile interval over few seeds is too narrow: it is as wide as a z interval
whose standard deviation divides by n, so the interval is widened to the expanded
percentile interval (:func:`expanded_tail`). Over 2 seeds either is the two seeds' range,
which holds the mean of a symmetric distribution half the time, and over 3 the range of
three, three times in four; from 4 seeds on the expanded interval holds it about as often
as its level says (tests/test_scorecard_stats.py measures both on simulated seeds). Below
:data:`MIN_SEEDS` seeds the interval is reported and the verdict is "not enough seeds".
"""

from __future__ import annotations

import math
from collections.abc import Callable
from itertools import combinations_with_replacement

import numpy as np

from wtftc.campaign.sweep import dlc, paired

#: the interval's confidence, as the scorecard reports it
LEVEL = 0.90
#: the fewest seeds a verdict rests on (module docstring)
MIN_SEEDS = 4
#: a verdict without an interval: no pair kept, or too few seeds
NO_PAIRS, FEW_SEEDS = "no pairs", "not enough seeds"


def verdict(low: float, high: float, lower_is_better: bool = True) -> str:
    """"better" when the interval [low, high] of the ratio preset / baseline lies wholly
    on the good side of 1 (below it where lower is better), "worse" on the other side,
    "tie" when it holds 1."""
    if low <= 1.0 <= high:
        return "tie"
    return "better" if (high < 1.0) == lower_is_better else "worse"


def _why_left_out(a, b) -> str | None:
    """Why a pair of values has no log ratio: "not_finite" (None, NaN, inf), "negative",
    "zero_both", "zero_preset", "zero_baseline"; None when it has one."""
    if a is None or b is None or not (math.isfinite(a) and math.isfinite(b)):
        return "not_finite"
    if a < 0 or b < 0:
        return "negative"
    if a == 0 or b == 0:
        return "zero_both" if a == b else "zero_preset" if a == 0 else "zero_baseline"
    return None


def has_ratio(a, b) -> bool:
    """Whether a pair of values has a log ratio (:func:`_why_left_out`)."""
    return _why_left_out(a, b) is None


def agreement(other: dict, screen_ratio: float | None) -> str | None:
    """How a confirmation's ratio (``other``: :func:`paired_ratio`'s) stands to the
    screen's over the same scenarios: "agrees" where its interval lies wholly on the
    screen's side of 1, "disagrees" wholly on the other, "holds 1" where it reaches 1 or
    has no interval (fewer than two seeds); None without both ratios."""
    if other.get("ratio") is None or screen_ratio is None:
        return None
    low, high = other.get("low"), other.get("high")
    if low is None or high is None or low <= 1.0 <= high:
        return "holds 1"
    return "agrees" if (high < 1.0) == (screen_ratio < 1.0) else "disagrees"


def paired_ratio(pairs, level: float = LEVEL, n_boot: int = 2000, seed: int = 0,
                 lower_is_better: bool = True, min_seeds: int = MIN_SEEDS,
                 expand: bool = True) -> dict:
    """The ratio preset / baseline of one metric over paired scenarios.

    ``pairs``: (turbulence seed, preset's value, baseline's value), one per scenario both
    held. Returns ``ratio`` (the geometric mean over the pairs kept), ``low`` and ``high``
    (the ``level`` cluster-bootstrap interval over seeds, module docstring; None below 2
    seeds), ``verdict`` (:func:`verdict`, or "not enough seeds" below ``min_seeds``, "no
    pairs" without one), ``n_pairs`` and ``n_seeds`` kept, ``left_out`` (the pairs without
    a log ratio) and ``left_out_why`` (their count by :func:`_why_left_out`'s reasons: at
    0 on both sides is the pitch ADC below rated, where neither pitches), ``method``
    ("exhaustive" or "monte carlo") and ``resamples``. ``expand``: the expanded percentile
    interval (:func:`bootstrap`). The same arguments give the same result."""
    why: dict[str, int] = {}
    logs: dict = {}
    for s, a, b in pairs:
        w = _why_left_out(a, b)
        if w is None:
            logs.setdefault(s, []).append(math.log(a / b))
        else:
            why[w] = why.get(w, 0) + 1
    seeds = sorted(logs)
    sums = np.array([sum(logs[s]) for s in seeds])
    counts = np.array([len(logs[s]) for s in seeds], dtype=float)
    out = {"ratio": None, "low": None, "high": None, "level": level, "verdict": NO_PAIRS,
           "n_pairs": int(counts.sum()), "n_seeds": len(seeds),
           "left_out": sum(why.values()), "left_out_why": why, "method": None,
           "resamples": 0}
    if not seeds:
        return out
    out["ratio"] = math.exp(sums.sum() / counts.sum())
    out["verdict"] = FEW_SEEDS
    if len(seeds) < 2:
        return out
    low, high, method, n = bootstrap(len(seeds), lambda c: np.exp((c @ sums) / (c @ counts)),
                                     level, n_boot, seed, expand)
    out.update(low=low, high=high, method=method, resamples=n)
    if len(seeds) >= min_seeds:
        out["verdict"] = verdict(low, high, lower_is_better)
    return out


def bootstrap(n: int, stat: Callable[[np.ndarray], np.ndarray], level: float = LEVEL,
              n_boot: int = 2000, seed: int = 0, expand: bool = True
              ) -> tuple[float, float, str, int]:
    """The ``level`` percentile interval of ``stat`` over the cluster-bootstrap resamples
    of ``n`` seeds (module docstring): (low, high, method, resamples); expanded
    (:func:`expanded_tail`) unless ``expand`` is False. ``stat`` takes the resamples as a
    (resamples, n) array of how many times each seed was drawn, and returns one value a
    resample."""
    if math.comb(2 * n - 1, n) <= n_boot:
        draws = np.array([np.bincount(c, minlength=n)
                          for c in combinations_with_replacement(range(n), n)], dtype=float)
        logp = (math.lgamma(n + 1) - np.sum([[math.lgamma(k + 1) for k in row]
                                             for row in draws], axis=1) - n * math.log(n))
        weights, method = np.exp(logp), "exhaustive"
    else:
        rng = np.random.default_rng(seed)
        draws = rng.multinomial(n, np.full(n, 1.0 / n), size=n_boot).astype(float)
        weights, method = np.full(n_boot, 1.0 / n_boot), "monte carlo"
    tail = expanded_tail(n, level) if expand else (1 - level) / 2
    low, high = quantiles(stat(draws), weights, (tail, 1 - tail))
    return low, high, method, len(draws)


def expanded_tail(n: int, level: float) -> float:
    """The tail probability of the expanded percentile interval (Hesterberg, What
    teachers should know about the bootstrap, The American Statistician 69(4), 2015,
    section 5): Φ(−√(n / (n − 1)) t_{(1+level)/2, n−1}) instead of (1 − level) / 2. A
    plain percentile interval is as narrow as a z interval with the divisor n in the
    standard deviation; this widens it to a t interval's with n − 1. 0.0137 for 6 seeds
    at 90 % (against 0.05)."""
    t = t_quantile((1 + level) / 2, n - 1)
    return 0.5 * math.erfc(math.sqrt(n / (n - 1)) * t / math.sqrt(2.0))


def quantiles(values, weights, probs) -> list[float]:
    """The inverted-CDF quantiles of a discrete distribution: for each p, the smallest
    value whose cumulative weight reaches p (weights summing to 1; a tolerance of 1e-12
    for their rounding)."""
    order = np.argsort(values, kind="stable")
    v, cum = np.asarray(values, dtype=float)[order], np.cumsum(np.asarray(weights)[order])
    return [float(v[min(int(np.searchsorted(cum, p - 1e-12)), len(v) - 1)]) for p in probs]


#: a lifetime figure's parts: every bin, the bins whose centre is below rated wind, and
#: those at or above it
PARTS = ("whole", "below", "above")


def lifetime_by_seed(rows, annual_mean_mps: float, bin_width_mps: float, m: float,
                     key_damage: str = "shaft_torque_damage_per_10min",
                     rated_wind_mps: float | None = None,
                     key_power: str = "mean_electrical_power_W") -> dict:
    """Seed → part (:data:`PARTS`; "whole" only without ``rated_wind_mps``) → the
    lifetime figures of that seed's fault-free runs held (status ok), by
    :func:`wtftc.campaign.sweep.dlc.lifetime`: ``del`` (MLife's lifetime DEL at 1 Hz of
    ``key_damage``, a damage per 10 minutes at Wöhler exponent ``m``), ``damage`` (del^m,
    the damage rate over calendar time: additive over bins and averaged over seeds, it is
    what the parts and the seeds pool), ``aep_Wh`` (from ``key_power``), ``bins`` and
    ``share_of_year``. A bin is the run's mean wind (runs of a seed in one bin averaged);
    a run without the key is left out; a part without bins is None. Bins go below or above
    by their centre: with 2-m/s bins the NREL 5-MW's (rated 11.4 m/s) 10 m/s is below,
    12 m/s above."""
    table = {"annual_mean_mps": annual_mean_mps, "bin_width_mps": bin_width_mps}
    runs: dict = {}
    for r in rows:
        if r["status"] == "ok" and r["fault_type"] == "none" and r.get(key_damage) is not None:
            runs.setdefault(r["seed"], {}).setdefault(round(r["mean_wind_mps"], 6), []).append(r)
    out = {}
    for s, by_bin in sorted(runs.items()):
        bins = {v: {"shaft_torque_damage_per_10min": float(np.mean([r[key_damage] for r in rs])),
                    "tower_base_damage_per_10min": None, "pitch_adc": 0.0,
                    "mean_electrical_power_W": float(np.mean([r[key_power] for r in rs]))}
                for v, rs in sorted(by_bin.items())}
        out[s] = {"whole": _part(bins, table, m)}
        if rated_wind_mps is not None:
            out[s]["below"] = _part({v: b for v, b in bins.items() if v < rated_wind_mps},
                                    table, m)
            out[s]["above"] = _part({v: b for v, b in bins.items() if v >= rated_wind_mps},
                                    table, m)
    return out


def _part(bins: dict, table: dict, m: float) -> dict | None:
    """dlc.lifetime's figures of ``bins`` (its shaft slot holds the damage asked for)."""
    if not bins:
        return None
    life = dlc.lifetime(bins, table, m)
    d = life["lifetime_shaft_del_1hz_Nm"]
    return {"del": d, "damage": d ** m, "aep_Wh": life["aep_Wh"], "bins": sorted(bins),
            "share_of_year": life["share_of_year"]}


def held_pairs(preset_rows, baseline_rows, trip: float = 1.2) -> tuple[list, dict]:
    """The (preset's run, baseline's run) of each scenario both ran
    (:func:`wtftc.campaign.sweep.paired.scenario`) and both held
    (:func:`wtftc.campaign.scorecard.outcome.classify`: a fault's extremes from its onset
    on), and the counts: ``scenarios`` both ran,
    ``failed`` (either run's status "failed": an error, not the rotor), ``both_held``,
    ``lost_by_preset``, ``lost_by_baseline``, ``unpaired`` (a scenario one side ran)."""
    from wtftc.campaign.scorecard.outcome import classify

    def held(r):  # (a fault's extremes from its onset on: outcome.classify)
        return classify(r, r.get("onset_s"), trip) == "held"

    base = {paired.scenario(r): r for r in baseline_rows}
    mine = {paired.scenario(r): r for r in preset_rows}
    pp = [(a, base[k]) for k, a in mine.items() if k in base]
    ok = [(a, b) for a, b in pp if "failed" not in (a["status"], b["status"])]
    both = [(a, b) for a, b in ok if held(a) and held(b)]
    return both, {"scenarios": len(pp), "failed": len(pp) - len(ok), "both_held": len(both),
                  "lost_by_preset": sum(not held(a) for a, _ in ok),
                  "lost_by_baseline": sum(not held(b) for _, b in ok),
                  "unpaired": len(set(mine) ^ set(base))}


def lifetime_ratio(preset_rows, baseline_rows, annual_mean_mps: float,
                   bin_width_mps: float, m: float,
                   key_damage: str = "shaft_torque_damage_per_10min",
                   rated_wind_mps: float | None = None, trip: float = 1.2,
                   level: float = LEVEL, n_boot: int = 2000, seed: int = 0,
                   min_seeds: int = MIN_SEEDS) -> dict:
    """The lifetime DEL and AEP of the preset against the baseline over the fault-free
    scenarios both held (:func:`held_pairs`, so both lifetimes cover the same seeds and
    bins), for each part (:data:`PARTS`): ``del`` and ``aep``, each {ratio, low, high,
    verdict, n_seeds, method, resamples}: the ratio of the pooled figures (the DEL's
    (Σ_s D_preset / Σ_s D_baseline)^(1/m) over the seeds s, D the damage rate: dlc.py's
    lifetime DEL ratio over the same bins), its cluster-bootstrap interval over seeds
    (:func:`bootstrap`) and verdict (lower is better for the DEL, higher for the AEP); and
    ``damage_share`` (preset, baseline): the part's share of the whole damage. ``counts``:
    :func:`held_pairs`' counts."""
    free = [[r for r in rows if r["fault_type"] == "none"] for rows in (preset_rows,
                                                                       baseline_rows)]
    both, counts = held_pairs(*free, trip)
    sides = [lifetime_by_seed([p[k] for p in both], annual_mean_mps, bin_width_mps, m,
                              key_damage, rated_wind_mps) for k in (0, 1)]
    out = {"counts": counts, "seeds": sorted(set(sides[0]) & set(sides[1]))}
    for part in PARTS if rated_wind_mps is not None else PARTS[:1]:
        seeds = [s for s in sorted(sides[0]) if s in sides[1] and sides[0][s][part]
                 and sides[1][s][part]]
        fig = {k: np.array([[side[s][part][k] for s in seeds] for side in sides])
               for k in ("damage", "aep_Wh")}
        whole = [sum(side[s]["whole"]["damage"] for s in seeds) for side in sides]
        out[part] = {
            "del": _pooled(fig["damage"], 1.0 / m, True, level, n_boot, seed, min_seeds),
            "aep": _pooled(fig["aep_Wh"], 1.0, False, level, n_boot, seed, min_seeds),
            "damage_share": tuple(float(fig["damage"][k].sum() / whole[k]) if whole[k]
                                  else None for k in (0, 1))}
    return out


def _pooled(x: np.ndarray, power: float, lower_is_better: bool, level: float, n_boot: int,
            seed: int, min_seeds: int) -> dict:
    """(Σ_s x_preset / Σ_s x_baseline)^power over the seeds (columns of ``x``, rows the
    preset's and the baseline's), with its interval and verdict as :func:`paired_ratio`."""
    n = x.shape[1]
    out = {"ratio": None, "low": None, "high": None, "verdict": NO_PAIRS, "n_seeds": n,
           "method": None, "resamples": 0}
    if n == 0 or not x[1].sum() > 0:
        return out
    out["ratio"] = float((x[0].sum() / x[1].sum()) ** power)
    out["verdict"] = FEW_SEEDS
    if n < 2:
        return out
    low, high, method, k = bootstrap(n, lambda c: ((c @ x[0]) / (c @ x[1])) ** power,
                                     level, n_boot, seed)
    out.update(low=low, high=high, method=method, resamples=k)
    if n >= min_seeds:
        out["verdict"] = verdict(low, high, lower_is_better)
    return out


def poisson_cdf(k: int, mu: float) -> float:
    """P(N ≤ k) for N ~ Poisson(mu): Σ_{i ≤ k} e^−mu mu^i / i!, summed in logs (the
    regularized upper incomplete gamma function Q(k + 1, mu))."""
    if mu <= 0.0:
        return 1.0
    terms = np.array([-mu + i * math.log(mu) - math.lgamma(i + 1) for i in range(k + 1)])
    top = float(terms.max())
    return min(1.0, math.exp(top) * float(np.sum(np.exp(terms - top))))


def upper_rate_bound(events: int, hours: float, level: float = 0.95) -> float:
    """The exact one-sided upper ``level`` confidence bound of a Poisson rate [per hour]
    from ``events`` seen in ``hours``: the mu with P(N ≤ events; mu) = 1 − level, over the
    hours (Garwood 1936; mu = χ²_level(2 events + 2) / 2, the gamma distribution's
    quantile). Solved by bisection on :func:`poisson_cdf`, which falls as mu grows, to a
    relative 1e-12: 3.00 / h for no event in one hour at 95 % (−ln 0.05)."""
    if isinstance(events, bool) or not isinstance(events, int) or events < 0:
        raise ValueError(f"upper_rate_bound needs a count of events >= 0, not {events!r}")
    if not hours > 0 or not 0.0 < level < 1.0:
        raise ValueError(f"upper_rate_bound needs hours > 0 and 0 < level < 1, not "
                         f"{hours!r}, {level!r}")
    lo, hi = 0.0, float(events) + 10.0 * math.sqrt(events + 1.0) + 10.0
    while poisson_cdf(events, hi) > 1.0 - level:
        lo, hi = hi, 2.0 * hi
    while hi - lo > 1e-12 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if poisson_cdf(events, mid) > 1.0 - level else (lo, mid)
    return 0.5 * (lo + hi) / hours


def t_quantile(p: float, df: int) -> float:
    """Student's t quantile: the t with P(T ≤ t) = ``p`` (0.5 < p < 1) at ``df`` degrees
    of freedom. With t = √df tan θ, P(T ≤ t) − ½ = c ∫₀^θ cos^(df−1) φ dφ, c = Γ((df+1)/2)
    / (√π Γ(df/2)): a smooth integral on [0, π/2) (64-point Gauss-Legendre), solved for θ
    by Newton's method (its derivative the integrand)."""
    if not 0.5 < p < 1.0 or df < 1:
        raise ValueError(f"t_quantile needs 0.5 < p < 1 and df >= 1, not {p}, {df}")
    c = math.exp(math.lgamma((df + 1) / 2) - math.lgamma(df / 2)) / math.sqrt(math.pi)
    x, w = np.polynomial.legendre.leggauss(64)

    def area(theta: float) -> float:
        phi = 0.5 * theta * (x + 1.0)
        return c * 0.5 * theta * float(np.sum(w * np.cos(phi) ** (df - 1)))

    theta = math.atan(2.0 / math.sqrt(df))
    for _ in range(100):
        step = (area(theta) - (p - 0.5)) / (c * math.cos(theta) ** (df - 1))
        theta = min(max(theta - step, 0.5 * theta), 0.5 * (theta + math.pi / 2))
        if abs(step) < 1e-15:
            break
    return math.sqrt(df) * math.tan(theta)
