"""A gain-scheduled PI pitch controller: the plain baseline (not from the paper).

The standard above-rated design (Jonkman et al. 2009, section 7.2; ROSCO's pitch loop):
the rotor-speed error drives a PI on the collective pitch whose gains are scheduled on the
pitch sensitivity ∂T_aero/∂β, so that the closed rotor-speed loop
J ė = (∂T_aero/∂β) Δβ behaves as a second-order system of natural frequency ω_n and
damping ζ at every operating point:

    K_p = 2 ζ ω_n J / (-∂T_aero/∂β),      K_i = ω_n² J / (-∂T_aero/∂β)
    β_cmd = K_p e + x_I,   ẋ_I = K_i e     (e = ω_r - ω_ref, x_I in rad)

with J the drivetrain inertia on the LSS (rotor + generator). Anti-windup by conditional
integration: x_I stops integrating when β_cmd is at a pitch limit and e pushes it
further out. The same command goes to the three blades.

The speed it regulates may pass a first-order low-pass filter first (issue 34; ROSCO's
F_LPFType 1, F_LPFCornerFreq 1.5708 rad/s on the NREL 5-MW):

    ω̇_f = ω_c (ω_r - ω_f),   e = ω_f - ω_ref      (ω_c > 0; ω_f starts at the measured ω_r)

so that the drivetrain mode (1.7 Hz on the NREL 5-MW with its flexible blades,
docs/validation.md) and the sensor noise reach the pitch attenuated. ω_c = 0 (the default)
is no filter: e = ω_r - ω_ref, the PI as it was before issue 34, bit for bit.

Peak shaving (issue 34, ``pi_ps_pitch``, off by default): the command's lower limit rises
near rated from the stop to the stop + ``pi_ps_pitch``, on the speed the PI regulates
(:func:`derivation.design.pitch_floor`); the anti-windup reads that floor.
"""

from __future__ import annotations

import sympy as sp

from derivation import design, nrel5mw
from derivation.design import ControllerDesign
from derivation.layout import N_BLADES, Entry

omega_r, omega_g_hss = sp.symbols("omega_r omega_g_hss", real=True)
beta_meas = sp.symbols(f"beta_meas_1:{N_BLADES + 1}", real=True)
yd0 = sp.Symbol("yd_0", real=True)
dTdbeta = sp.Symbol("dT_dbeta", real=True)  # scheduled pitch sensitivity [N m/rad], < 0
x_I = sp.Symbol("pi_integrator", real=True)
w_f = sp.Symbol("pi_speed_filtered", real=True)
speed = sp.Symbol("pi_speed_used", real=True)  # ω_f with the filter, else ω_r

STATES = [Entry("pi_integrator", 0.0, "rad", "PI integrator x_I (pitch units)"),
          Entry("pi_speed_filtered", nrel5mw.RATED_SPEED, "rad/s",
                "the rotor speed through the low-pass filter, ω_f", sample=(1.1, 1.45))]
PARAMS = [
    Entry("pi_omega_n", nrel5mw.ROSCO_PC_OMEGA, "rad/s",
          "closed-loop natural frequency (ROSCO NREL5MW PC_omega)"),
    Entry("pi_zeta", nrel5mw.ROSCO_PC_ZETA, "-",
          "closed-loop damping ratio (ROSCO NREL5MW PC_zeta)"),
    Entry("pi_inertia", nrel5mw.DRIVETRAIN_INERTIA, "kg m^2",
          "drivetrain inertia on the LSS: J_r + N² J_g (Jonkman 2009)"),
    Entry("pi_pitch_min", nrel5mw.PITCH_MIN, "rad", "command lower limit"),
    Entry("pi_pitch_max", nrel5mw.PITCH_MAX, "rad", "command upper limit"),
    Entry("pi_dTdbeta_min", 1.0e5, "N m/rad",
          "smallest |∂T/∂β| used in the schedule (bounds the gains near rated)"),
    Entry("pi_lpf_corner", 0.0, "rad/s",
          "corner frequency ω_c of the first-order low-pass filter on the rotor speed; "
          "0: no filter (ROSCO NREL5MW F_LPFCornerFreq: 1.5708)", sample=(0.5, 6.0)),
    *design.peak_shaving_params("pi"),
]
wn, zeta, J, bmin, bmax, gmin, wc, ps_pitch, ps_speed = sp.symbols(
    "pi_omega_n pi_zeta pi_inertia pi_pitch_min pi_pitch_max pi_dTdbeta_min pi_lpf_corner "
    "pi_ps_pitch pi_ps_speed", real=True)


def derive() -> ControllerDesign:
    """The PI as a ControllerDesign: the same command to every blade (no accommodation)."""
    cmd, xI_dot, diag = law()
    # without the filter ω_f is unused; it still follows ω_r at 1 rad/s, so that the loop
    # has no zero eigenvalue (wtftc linearize would read one as marginally stable)
    rate = sp.Piecewise((wc, wc > 0), (1, True))
    return ControllerDesign(v=cmd, u0=cmd, x_dot=[xI_dot, rate * (omega_r - w_f)], diag=diag,
                            x0=[initial_integrator(), omega_r],
                            intermediates=[(speed, sp.Piecewise((w_f, wc > 0),
                                                                (omega_r, True)))])


def law():
    """(β_cmd, ẋ_I, diagnostics) of the PI above."""
    e = speed - yd0
    g = sp.Max(-dTdbeta, gmin)  # -∂T/∂β > 0 above rated
    kp = 2 * zeta * wn * J / g
    ki = wn**2 * J / g
    raw = kp * e + x_I
    floor = design.pitch_floor(bmin, ps_pitch, speed, ps_speed, yd0)  # the stop, or higher
    cmd = sp.Min(sp.Max(raw, floor), bmax)
    saturated_out = sp.Or(sp.And(raw >= bmax, e > 0), sp.And(raw <= floor, e < 0))
    xI_dot = sp.Piecewise((0, saturated_out), (ki * e, True))
    return cmd, xI_dot, [e, x_I, kp, ki]


def initial_integrator():
    """x_I at start: the measured mean pitch, so that the command starts where the blades are."""
    return sum(beta_meas) / N_BLADES
