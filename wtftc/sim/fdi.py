"""The FDI's thresholds from the sensors' noise and a target false-alarm rate (ours).

The FDI (derivation/fdi.py) tests the mean square e of its filtered residual r_f:

* r_f is the residual β_m − β̂ through a first-order low-pass of time constant T_r. The
  pitch sensor's noise (σ, one draw per control interval T, held) passes it with the
  variance σ_f² = σ² (1 − a)/(1 + a), a = exp(−T/T_r) (≈ σ² T / (2 T_r)), and a
  correlation exp(−|τ|/T_r).
* e is r_f² through a first-order window T_f: its mean is σ_f². Its tail lies at or a
  little below that of σ_f² χ²_ν/ν with ν = 1 + T_f/T_r degrees of freedom: on 2·10⁷
  samples of the filter pair at T = 0.01 s, T_r = 0.2 s, T_f = 0.5 s the model's
  quantiles are above the sampled ones by 10, 6, 6 and 2 % at 1e-3, 1e-4, 1e-5 and 1e-6
  (tests/test_fdi_noise.py). Matching the mean and the variance instead (ν = 1 +
  2T_f/T_r, exact for them) underestimates the tail, by 30 % at 1e-6, and the first
  fault-free campaign with it came within 5 % of alarming.
* The threshold is h = σ_f² Q_ν(1 − α)/ν, with α the probability of exceeding it at one
  sample allowed by the target: α = (alarms per hour) × T / 3600 s (an excursion may be
  as short as one sample). Q is the χ²
  quantile by the Wilson–Hilferty approximation (Wilson & Hilferty 1931), which in these
  tails errs high, on the safe side (tests/test_fdi_noise.py). SciPy is not a dependency
  of the package for one quantile.

The model-uncertainty allowance (δ on the actuator's time constant, δ_sat at the rate
limit) is added by the FDI itself, since it grows with the model's pitch rate. The target
is checked, not assumed: docs/fdi.md reports the alarms measured over 100 simulated
fault-free hours.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np

from wtftc.artefacts import layout as lay

#: default target: 1e-3 false alarms per hour (one in 1000 h, ten times fewer than the
#: goal of none in 100 h would need on average)
TARGET_ALARMS_PER_HOUR = 1e-3


def chi2_quantile(nu: float, p: float) -> float:
    """The p-quantile of χ² with ν degrees of freedom (Wilson–Hilferty)."""
    z = NormalDist().inv_cdf(p)
    c = 2.0 / (9.0 * nu)
    return nu * max(1.0 - c + z * math.sqrt(c), 0.0) ** 3


def noise_threshold(sigma: float, interval: float, T_r: float, T_f: float,
                    alarms_per_hour: float) -> float:
    """h [rad²]: the threshold on e for pitch noise σ [rad] sampled every ``interval`` [s]
    (0: continuous, exact sensors: 0)."""
    if sigma <= 0 or interval <= 0:
        return 0.0
    a = math.exp(-interval / T_r)
    var_f = sigma**2 * (1 - a) / (1 + a)
    nu = 1.0 + T_f / T_r
    alpha = min(alarms_per_hour * interval / 3600.0, 0.5)
    return var_f * chi2_quantile(nu, 1.0 - alpha) / nu


def run_params(base: np.ndarray, p_sensors: np.ndarray, interval: float,
               alarms_per_hour: float = TARGET_ALARMS_PER_HOUR,
               delta: float | None = None, delta_sat: float | None = None) -> np.ndarray:
    """The FDI's parameters of one run: ``base`` (wtftc.sim.rhs.fdi_params) with the
    noise thresholds of the run's sensors (the pitch's: the noisiest pitch sensor's σ; each
    pair test's: the σ of its two sensors' difference) and, if given, the
    model-uncertainty allowances δ and δ_sat (at the rate limit)."""
    p = np.array(base, dtype=float)
    values = lay.values("fdi_params", p)
    sens = lay.values("sensor_params", p_sensors)

    def threshold(s):
        return noise_threshold(s, interval, values["fdi_T_r"], values["fdi_T_f"],
                               alarms_per_hour)

    def pair(name):
        return math.hypot(sens[f"sigma_{name}_m1"], sens[f"sigma_{name}_m2"])

    pitches = [f"beta_meas_{j}" for j in lay.blades()]
    sigma = max(sens[f"sigma_{b}_m{k}"] for b in pitches for k in (1, 2))
    p[lay.index("fdi_params", "fdi_thr2_noise")] = threshold(sigma)
    p[lay.index("fdi_params", "fdi_thr2_pair")] = threshold(max(pair(b) for b in pitches))
    for name in ("omega_r", "omega_g_hss"):
        p[lay.index("fdi_params", f"fdi_thr2_{name}")] = threshold(pair(name))
    p[lay.index("fdi_params", "fdi_var_noise")] = sigma**2 if interval > 0 else 0.0
    p[lay.index("fdi_params", "fdi_T_s")] = interval
    for name, value in (("fdi_delta", delta), ("fdi_delta_rate_limited", delta_sat)):
        if value is not None:
            p[lay.index("fdi_params", name)] = value
    return p
