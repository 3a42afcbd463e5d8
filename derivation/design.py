"""What a controller module hands to the generator: SymPy expressions only.

A controller derived in SymPy (derivation/drivetrain.py, say) returns a
:class:`ControllerDesign`; :func:`derivation.controllers.from_design` translates it into the
uniform ``ctrl_<name>``/``init_<name>`` functions. The symbols it may use are bound by name:

* the measurements ``omega_r``, ``omega_g_hss``, ``beta_meas_1..3``;
* the reference ``yd_0..yd_4`` (y_d and its derivatives), the schedule ``dT_dbeta`` and
  the tower-top fore-aft acceleration ``tower_fa_acc`` (the runtime's inputs ``sched``);
* the eq (49) fault estimates ``rho_hat_j``, ``lock_hat_j``, ``ubar_hat_j``;
* its own states and parameters, by their layout names;
* the fuzzy symbols L/B/φ of its rule base (inputs: the named measurements, signals or
  states), or of several rule bases on nested inputs (the paper's f̂_i(x̂1..x̂i));
* ``signals``, bound in order before the rule base, so that they may feed it (a filtered
  speed the design uses in place of a measurement);
* ``intermediates``, bound in order (an anti-windup switch κ used by later expressions).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from derivation import fuzzy, nrel5mw
from derivation.layout import N_MF, Entry, rule_count


@dataclass
class ControllerDesign:
    #: the command of each free blade [rad], or one command per blade (a list)
    v: sp.Expr | list[sp.Expr]
    u0: sp.Expr  # the controller's scalar (mean pitch) command [rad]
    x_dot: list[sp.Expr]  # controller state derivatives, in state order
    diag: list[sp.Expr]  # four diagnostics
    x0: list[sp.Expr]  # initial controller state from the measurements
    #: the fuzzy approximator, if the design has one: its rule base, the measurement, signal
    #: or state names feeding it (in order) and the state names of its weights θ̂ (rule order)
    rule_base: fuzzy.RuleBase | None = None
    fuzzy_inputs: list[str] = field(default_factory=list)
    weights: list[str] = field(default_factory=list)
    #: several rule bases instead of one: rule base i reads the first i fuzzy inputs
    #: (triangular regressors) and its weights are weight_groups[i - 1]
    rule_bases: list[fuzzy.RuleBase] = field(default_factory=list)
    weight_groups: list[list[str]] = field(default_factory=list)
    signals: list[tuple[sp.Symbol, sp.Expr]] = field(default_factory=list)
    intermediates: list[tuple[sp.Symbol, sp.Expr]] = field(default_factory=list)
    #: named expressions for verification (α_i, α̇_i full and computable, ...), and the
    #: extra inputs they need (true derivatives the controller cannot measure)
    checks: dict[str, sp.Expr] = field(default_factory=dict)
    check_inputs: list[sp.Symbol] = field(default_factory=list)

    def fuzzy_systems(self) -> tuple[list[fuzzy.RuleBase], list[list[str]]]:
        """The rule bases and their weights' state names, one or several; refused where
        rule base k is not the one on the first k inputs, or its weights are not one per
        rule (the generator pairs them by position and picks the inputs by number)."""
        if self.rule_base is not None and self.rule_bases:
            raise ValueError("a design has rule_base or rule_bases, not both")
        bases, groups = (([self.rule_base], [self.weights]) if self.rule_base is not None
                         else (self.rule_bases, self.weight_groups))
        if len(bases) != len(groups) or any(
                rb.i != k + 1 or len(g) != rule_count(rb.i)
                for k, (rb, g) in enumerate(zip(bases, groups, strict=False))):
            raise ValueError("rule base k (1-based) must read the first k fuzzy inputs, with "
                             f"N_MF**k weights: got {[rb.i for rb in bases]} and "
                             f"{[len(g) for g in groups]} weights")
        return bases, groups


N_BLADES = 3
rho_hat = sp.symbols(f"rho_hat_1:{N_BLADES + 1}", real=True)
lock_hat = sp.symbols(f"lock_hat_1:{N_BLADES + 1}", real=True)
ubar_hat = sp.symbols(f"ubar_hat_1:{N_BLADES + 1}", real=True)


def free_blade_command(u_mean: sp.Expr) -> sp.Expr:
    """Eq (49)'s accommodation for three blades: the free blades get
    v = (3U - Σ σ̂_j ū_j) / Σ (1 - σ̂_j) ρ̂_j, so that the mean effective input is U.

    The divisor is kept ≥ 0.3: with every blade reported locked no authority is left, and
    dividing by ~0 would only turn a misdiagnosis into a divergence.
    """
    lock_sum = sum(lh * ub for lh, ub in zip(lock_hat, ubar_hat, strict=True))
    gain = sp.Max(sum((1 - lh) * rh for lh, rh in zip(lock_hat, rho_hat, strict=True)),
                  sp.Rational(3, 10))
    return (N_BLADES * u_mean - lock_sum) / gain


def freeze(command, beta_mean, tau, pitch_min, pitch_max, rate_max, push, theta_norm2,
           theta_dot_dir, theta_max, rate_test=None) -> sp.Expr:
    """κ: 0 (adaptation frozen) when the pitch command is saturated in position, or in
    the rate (command - β̄)/τ of the first-order actuator model, and the error ``push``
    (> 0: overspeed, more pitch wanted) drives it further out; or when |θ̂| is at its
    bound and the update points outward (projection onto |θ̂| ≤ θ_max). Else 1.
    ``rate_test``, if given, is the condition under which the rate test applies (a design
    that may assume no actuator model has no rate of its own to test)."""
    rate = (command - beta_mean) / tau
    rate_out = [sp.And(rate >= rate_max, push > 0), sp.And(rate <= -rate_max, push < 0)]
    if rate_test is not None:  # the rate is a first-order model's: only where there is one
        rate_out = [sp.And(rate_test, sp.Or(*rate_out))]
    sat_out = sp.Or(sp.And(command >= pitch_max, push > 0),
                    sp.And(command <= pitch_min, push < 0), *rate_out)
    proj_out = sp.And(theta_norm2 >= theta_max**2, theta_dot_dir > 0)
    return sp.Piecewise((0, sp.Or(sat_out, proj_out)), (1, True))


def pitch_floor(pitch_min, ps_pitch, speed, ps_speed, reference) -> sp.Expr:
    """Peak shaving (issue 34): the command's lower limit, the pitch stop raised near rated.

    Near rated the blades sit at the stop, where the thrust peaks and ∂T/∂β is smallest;
    in OpenFAST the physical AFTC and the PI limit-cycle there with the tower (0.25 Hz,
    the pitch bouncing off the stop; docs/controllers.md). ROSCO raises its floor with an
    estimated wind (PS_Mode). Without a wind estimate the floor is scheduled on the speed
    the design regulates: below rated the torque law holds the rotor at λ* (ω_r ∝ v) up to
    region 2½, so the floor is the stop there (no loss of Cp), and it rises linearly from
    ``ps_speed`` to ``ps_pitch`` above the stop at the reference speed, and stays."""
    rise = sp.Min(sp.Max((speed - ps_speed) / (reference - ps_speed), 0), 1)
    return pitch_min + ps_pitch * rise


def peak_shaving_params(prefix: str) -> list[Entry]:
    """The two parameters of :func:`pitch_floor`, off by default."""
    return [
        Entry(f"{prefix}_ps_pitch", 0.0, "rad",
              "peak shaving: the pitch floor above the stop at the reference speed, rising "
              f"from the stop at {prefix}_ps_speed; 0: none (as before issue 34)",
              sample=(0.0, 0.05)),
        Entry(f"{prefix}_ps_speed", nrel5mw.RATED_SPEED / 1.1, "rad/s",
              "peak shaving: the rotor speed from which the floor rises (the torque law's "
              "region 2½ starts at ω_rated/(1 + slip), slip 10 %: Jonkman 2009)"),
    ]


#: the tower-top fore-aft acceleration [m/s^2]: a runtime input beside the ∂T/∂β schedule
#: (the plant's in wtftc, avrSWAP #53 in a DISCON host; 0 on a plant without a tower),
#: read by the tower damper only; not a sensor, the FDI does not vote on it
tower_fa_acc = sp.Symbol("tower_fa_acc", real=True)


def tower_damper(prefix: str) -> tuple[sp.Expr, sp.Expr, sp.Expr, sp.Expr]:
    """Tower fore-aft damping (issue 34), ROSCO's structure (ForeAftDamping, ROSCO 2.x:
    the acceleration high-passed, integrated, times a gain, added to every blade's pitch):
    the high-pass at ω_h followed by the integrator is the lag ŝ̇ = a_f − ω_h ŝ, whose ŝ
    follows the tower-top speed above ω_h; Δβ = clip(K ŝ, ±Δβ_max). Pitching to feather
    while the tower moves downwind lowers the thrust against the motion: damping.

    a_f is the acceleration a low-passed at ω_f, ȧ_f = ω_f (a − a_f) (ours; issue 34), or
    a itself when ω_f = 0 (as before the filter; a_f then decays at 1/s, unused, so that
    ``wtftc linearize`` sees no zero eigenvalue, as the speed observer's states off).
    Added to the desired pitch α1 of a backstepping design, Δβ enters α̇1 exactly: the
    design's z2 tracks it, rather than fight it as a disturbance on β̄. Its rate K ŝ̇
    holds a_f; unfiltered, that is the measured acceleration itself, which the command's
    inversion of the actuator lag (τ_a α̇1) passed on with a gain of K τ_a at every
    frequency the accelerometer sees (on the IEA 15-MW in OpenFAST: pitch activity at
    0.3-1.6 Hz; docs/controllers.md). The low-pass leaves α̇1 a function of states only.
    The clip's rate is written out (K ŝ̇ inside the clip, 0 on it), not left to SymPy,
    whose derivative of Min/Max is a Heaviside with a value at 0 of its own choosing.

    Returns (Δβ, its rate, the rate of ŝ, the rate of a_f)."""
    gain, corner, limit, lpf = sp.symbols(
        f"{prefix}_td_gain {prefix}_td_corner {prefix}_td_max {prefix}_td_lpf", real=True)
    s_hat, a_f = sp.symbols(f"{prefix}_td_speed {prefix}_td_acc", real=True)
    acc = sp.Piecewise((a_f, lpf > 0), (tower_fa_acc, True))
    s_rate = acc - corner * s_hat
    pitch = gain * s_hat
    return (sp.Min(sp.Max(pitch, -limit), limit),
            sp.Piecewise((gain * s_rate, sp.Abs(pitch) < limit), (0, True)), s_rate,
            sp.Piecewise((lpf * (tower_fa_acc - a_f), lpf > 0), (-a_f, True)))


def tower_damper_params(prefix: str) -> list[Entry]:
    """The parameters of :func:`tower_damper`, off by default (gain 0)."""
    return [
        Entry(f"{prefix}_td_gain", 0.0, "rad s/m",
              "tower damper: pitch per tower-top fore-aft speed (ROSCO's FA_KI); 0: none "
              "(as before)", sample=(0.0, 0.1)),
        Entry(f"{prefix}_td_corner", 0.2, "rad/s",
              "tower damper: the acceleration's high-pass corner (ROSCO's "
              "FA_HPFCornerFreq), below the first tower mode (2 rad/s on the NREL 5-MW, "
              "1.5 on the IEA 15-MW: wtftc/data)", sample=(0.1, 0.5)),
        Entry(f"{prefix}_td_max", 0.0349, "rad",
              "tower damper: the largest pitch it adds or takes, 2° (ROSCO's FA_IntSat)",
              sample=(0.01, 0.1)),
        Entry(f"{prefix}_td_lpf", 0.0, "rad/s",
              "tower damper: the acceleration's low-pass corner ω_f (ours; issue 34), above "
              "the first tower mode; 0: none, the acceleration as measured (as before; its "
              "rate then reaches the command through the actuator-lag inversion)",
              sample=(2.0, 10.0)),
    ]


def actuator_and_fuzzy_params(prefix: str) -> list[Entry]:
    """The parameters a pitch backstepping design shares: the actuator model and limits
    its anti-windup tests, and the memberships of its f̂(ω_r)."""
    return [
        Entry(f"{prefix}_tau_a", nrel5mw.PITCH_TIME_CONSTANT, "s",
              "actuator first-order equivalent 2ζ/ω_n (Odgaard 2013)"),
        Entry(f"{prefix}_pitch_min", nrel5mw.PITCH_MIN, "rad", "pitch command lower limit"),
        Entry(f"{prefix}_pitch_max", nrel5mw.PITCH_MAX, "rad", "pitch command upper limit"),
        Entry(f"{prefix}_dTdbeta_min", 1.0e5, "N m/rad", "smallest |∂T/∂β| used (bounds 1/b)"),
        Entry(f"{prefix}_rate_max", nrel5mw.PITCH_RATE_MAX, "rad/s",
              "actuator rate limit, for the anti-windup (the turbine's pitch_rate_max: "
              "the NREL 5-MW's 8°/s by default, Jonkman 2009)"),
        Entry("mf_width", 0.6, "-", "Gaussian membership width on normalized ω_r"),
        *[Entry(f"mf_centre_{m}", -1.0 + 2.0 * (m - 1) / (N_MF - 1), "-",
                f"centre of membership {m}") for m in range(1, N_MF + 1)],
        Entry("x_offset_1", nrel5mw.RATED_SPEED, "rad/s", "normalization offset of ω_r (rated)"),
        Entry("x_scale_1", 0.1, "rad/s", "normalization scale of ω_r"),
    ]
