"""Pitch actuator fault detection, isolation and estimation (ours; the paper has none).

Per blade j, from what a turbine has: the pitch command v_j it sends and the measured
pitch β_m,j.

* **Model**: the nominal actuator (Odgaard et al. 2013), the same second-order law with
  the same limits as the plant's, driven by v_j: β̂̈ = ω0²(sat(v_j) - β̂) - 2ζ0ω0 β̂̇.
* **Residual** r_j = β_m,j - β̂_j, and its mean square over a window T_f:
  ė_j = (r_j² - e_j)/T_f.
* **Detection and isolation**: a latch D_j rises to 1 (rate k_D) once √e_j exceeds the
  threshold r_thr; the blade whose latch rises is the faulty one.
* **Estimation**: two least-squares fits over an exponentially weighted window T_w
  (sufficient statistics as states): β_m ≈ ρ₁ β̂ + c, which tells a lock (ρ₁ ≈ 0, c ≈ the
  stuck angle), and β_m ≈ ρ₀ β̂ through the origin, which estimates a loss of
  effectiveness (with the pitch varying over a few degrees, ρ₁ and c are nearly
  collinear and ρ₁ alone is poorly determined). After detection the accommodation is told
  σ̂_j = 1, ū_j = c_j when ρ₁ < ρ_lock, else σ̂_j = 0 and ρ̂_j = ρ₀ clipped to [ρ_min, 1];
  before detection, the nominal values.

The hydraulic faults (pressure drop, air in oil) change the dynamics, not the gain: a
bank of the benchmark's two faulty actuator models runs beside the nominal one, and
after a detection with ρ̂ ≈ 1 the model with the smallest residual gives (ω̂_n, ζ̂).
"""

from __future__ import annotations

import sympy as sp

from derivation import nrel5mw, turbine
from derivation.layout import Entry

v, beta_m = sp.symbols("v beta_m", real=True)
bh, bhd, e, D, q = sp.symbols("beta_hat beta_hat_rate mean_sq latch confidence", real=True)
S_bb, S_b, S_1, S_mb, S_m = sp.symbols("S_bb S_b S_1 S_mb S_m", real=True)
xd, R_m, R_h = sp.symbols("deriv_filter rate_msq_meas rate_msq_model", real=True)
# the model bank: the benchmark's hydraulic faults as alternative actuator models
bp, bpd, ep, ba, bad, ea = sp.symbols(
    "beta_pd beta_pd_rate mean_sq_pd beta_air beta_air_rate mean_sq_air", real=True)
STATE_SYMBOLS = [bh, bhd, e, D, q, S_bb, S_b, S_1, S_mb, S_m, xd, R_m, R_h,
                 bp, bpd, ep, ba, bad, ea]
PER_BLADE = ["beta_hat", "beta_hat_rate", "mean_sq", "latch", "confidence", "S_bb", "S_b",
             "S_1", "S_mb", "S_m", "deriv_filter", "rate_msq_meas", "rate_msq_model",
             "beta_pd", "beta_pd_rate", "mean_sq_pd", "beta_air", "beta_air_rate",
             "mean_sq_air"]
UNITS = ["rad", "rad/s", "rad^2", "-", "-", "rad^2", "rad", "-", "rad^2", "rad", "rad",
         "rad^2/s^2", "rad^2/s^2", "rad", "rad/s", "rad^2", "rad", "rad/s", "rad^2"]


def states(n_blades: int) -> list[Entry]:
    return [Entry(f"fdi_{n}_{j}", 0.0, u, f"FDI {n} of blade {j}")
            for j in range(1, n_blades + 1) for n, u in zip(PER_BLADE, UNITS, strict=True)]


PARAMS = [
    Entry("fdi_omega_n", nrel5mw.ACTUATOR_OMEGA_N, "rad/s",
          "nominal actuator natural frequency (Odgaard 2013)"),
    Entry("fdi_zeta", nrel5mw.ACTUATOR_ZETA, "-", "nominal actuator damping (Odgaard 2013)"),
    Entry("fdi_pitch_min", nrel5mw.PITCH_MIN, "rad", "actuator position limits, as the plant's"),
    Entry("fdi_pitch_max", nrel5mw.PITCH_MAX, "rad", ""),
    Entry("fdi_rate_max", nrel5mw.PITCH_RATE_MAX, "rad/s", "actuator rate limit, 8°/s"),
    Entry("fdi_T_f", 0.5, "s", "residual mean-square window"),
    Entry("fdi_r_thr", 0.0008726646259971648, "rad",
          "detection threshold on the residual RMS: 0.05°, an absolute pitch encoder's "
          "accuracy; the fault-free residual is below 1e-9 rad on nrel5mw (no sensor noise "
          "is simulated; docs/fdi.md)"),
    Entry("fdi_k_latch", 20.0, "1/s", "latch rise rate"),
    Entry("fdi_T_w", 2.0, "s", "least-squares window (exponential forgetting)"),
    Entry("fdi_rho_lock", 0.2, "-",
          "lock-in-place when the measured pitch rate's RMS is below this fraction of the "
          "model's (the blade does not follow its command)"),
    Entry("fdi_T_d", 0.05, "s", "time constant of the measured-pitch derivative filter"),
    Entry("fdi_omega_pd", nrel5mw.PRESSURE_DROP_OMEGA_N, "rad/s",
          "hydraulic pressure drop model ω_n (Odgaard 2013)"),
    Entry("fdi_zeta_pd", nrel5mw.PRESSURE_DROP_ZETA, "-",
          "hydraulic pressure drop model ζ (Odgaard 2013)"),
    Entry("fdi_omega_air", nrel5mw.AIR_IN_OIL_OMEGA_N, "rad/s",
          "high air content in oil model ω_n (Odgaard 2013)"),
    Entry("fdi_zeta_air", nrel5mw.AIR_IN_OIL_ZETA, "-",
          "high air content in oil model ζ (Odgaard 2013)"),
    Entry("fdi_rho_min", 0.3, "-", "smallest ρ̂ passed to the accommodation"),
    Entry("fdi_T_engage", 3.0, "s",
          "after detection, the accommodation is engaged linearly over this time (1.5 "
          "least-squares windows; chosen with T_w among (3, 4) × (2, 3) s on NTM B at 16 and "
          "20 m/s and the paper's wind: docs/fdi.md)"),
]
wn, zt, bmin, bmax, rmax, T_f, r_thr, k_D, T_w, rho_lock, rho_min, T_e, T_d = sp.symbols(
    "fdi_omega_n fdi_zeta fdi_pitch_min fdi_pitch_max fdi_rate_max fdi_T_f fdi_r_thr "
    "fdi_k_latch fdi_T_w fdi_rho_lock fdi_rho_min fdi_T_engage fdi_T_d", real=True)
w_pd, z_pd, w_air, z_air = sp.symbols("fdi_omega_pd fdi_zeta_pd fdi_omega_air fdi_zeta_air",
                                      real=True)


def actuator_model(b, bdot, w, z) -> list[sp.Expr]:
    """The plant's actuator law (derivation/turbine.py) on v_j clipped to the limits."""
    u = sp.Min(sp.Max(v, bmin), bmax)
    return turbine.limited_actuator(b, bdot, u, w, z, bmin, bmax, rmax)


def blade_rhs() -> list[sp.Expr]:
    """Time derivatives of one blade's FDI states."""
    rate, acc = actuator_model(bh, bhd, wn, zt)
    r = beta_m - bh
    latch = sp.Piecewise((k_D * (1 - D), e >= r_thr**2), (0, True))
    confidence = sp.Piecewise((1 / T_e, sp.And(D >= sp.Rational(1, 2), q < 1)), (0, True))
    stats = [bh * bh, bh, 1, beta_m * bh, beta_m]
    rate_meas = (beta_m - xd) / T_d  # filtered derivative of the measured pitch
    pd = actuator_model(bp, bpd, w_pd, z_pd)
    air = actuator_model(ba, bad, w_air, z_air)
    return [rate, acc, (r**2 - e) / T_f, latch, confidence,
            *[(x - s) / T_w for x, s in zip(stats, [S_bb, S_b, S_1, S_mb, S_m], strict=True)],
            rate_meas, (rate_meas**2 - R_m) / T_f, (rate**2 - R_h) / T_f,
            *pd, ((beta_m - bp) ** 2 - ep) / T_w, *air, ((beta_m - ba) ** 2 - ea) / T_w]


def dynamics_estimate() -> tuple[sp.Expr, sp.Expr]:
    """(ω̂_n, ζ̂): after detection of a fault that is neither a lock nor a loss of
    effectiveness (ρ̂ within 0.1 of 1), the bank model with the smallest residual
    (window T_w) when it explains the measurement better than the nominal one."""
    _, _, rho = estimates()
    hydraulic = sp.And(D >= sp.Rational(1, 2), sp.Not(is_locked()), sp.Abs(rho - 1) < 0.1)
    e_nom = e  # the nominal model's residual mean square (window T_f)
    pd_best = sp.And(hydraulic, ep < ea, ep < e_nom)
    air_best = sp.And(hydraulic, ea <= ep, ea < e_nom)
    w_hat = sp.Piecewise((w_pd, pd_best), (w_air, air_best), (wn, True))
    z_hat = sp.Piecewise((z_pd, pd_best), (z_air, air_best), (zt, True))
    return w_hat, z_hat


def estimates() -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """ρ₁, c of β_m ≈ ρ₁ β̂ + c (guarded against a flat β̂), and ρ₀ of β_m ≈ ρ₀ β̂."""
    det = S_1 * S_bb - S_b**2
    det = sp.Max(det, 1e-12)
    rho1 = (S_1 * S_mb - S_b * S_m) / det
    c = (S_m - rho1 * S_b) / sp.Max(S_1, 1e-9)
    rho0 = S_mb / sp.Max(S_bb, 1e-12)
    return rho1, c, rho0


def is_locked() -> sp.Expr:
    """The blade does not follow: measured rate RMS below ρ_lock × the model's (window T_f)."""
    return R_m < rho_lock**2 * R_h + sp.Rational(1, 10**12)


def accommodation() -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """(ρ̂, σ̂, ū) for eq (49)'s accommodation: nominal until the latch passes 0.5, then
    blended in with the confidence w = min(q, 1), which grows over T_engage: the early
    estimates still weigh pre-fault data, and acting on them destabilized the loop."""
    _, c, rho = estimates()
    detected = D >= sp.Rational(1, 2)
    locked = sp.And(detected, is_locked())
    w = sp.Min(sp.Max(q, 0), 1)
    rho_out = sp.Piecewise((1, sp.Not(detected)), (1, locked),
                           (1 + w * (sp.Min(sp.Max(rho, rho_min), 1) - 1), True))
    lock_out = sp.Piecewise((w, locked), (0, True))
    ubar_out = sp.Piecewise((sp.Min(sp.Max(c, bmin), bmax), locked), (0, True))
    return rho_out, lock_out, ubar_out


def initial(beta_meas0) -> list[sp.Expr]:
    """Model at the measured pitch, at rest; statistics of a fault-free past (ρ = 1, c = 0)
    with unit weight and a small spread so that the first estimates are defined."""
    b0 = beta_meas0
    spread = sp.Rational(1, 10**4)
    return [b0, 0, 0, 0, 0, b0**2 + spread, b0, 1, b0**2 + spread, b0, b0, 0, 0,
            b0, 0, 0, b0, 0, 0]
