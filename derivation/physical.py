"""A physically consistent adaptive fuzzy backstepping AFTC (ours, not the paper's).

Chain of relative degree 2, ω_r ← β̄ ← u (the simpler of the two chains in the design
notes; the other, through θ_s, is derivation/drivetrain.py). The design model:

    J ω̇_r = T_aero(ω_r, β̄, v_wind) - T_g        (rigid drivetrain on the LSS)
    τ_a β̄̇ = u - β̄                               (the actuators' first-order equivalent)

with T_aero = G β̄ + (T_aero - G β̄): G = ∂T_aero/∂β < 0 is scheduled from the Cp table
(the `sched` input), the rest is the unknown aerodynamic residual, approximated by a
fuzzy system f̂ = θ̂ᵀφ(ω_r) (memberships as in derivation/fuzzy.py). With b = G/J and
h0 = -T_g/J (constant generator torque, known to the controller):

    z1 = ω_r - y_d,            ż1 = b β̄ + h0 + f - ẏ_d
    α1 = (-c1 z1 - h0 - f̂ + ẏ_d) / b                         (desired mean pitch)
    z2 = β̄ - α1,               ż2 = (u - β̄)/τ_a - α̇1
    U  = β̄ + τ_a (-c2 z2 - b z1 + α̇1)                        (mean pitch command)
    θ̂̇ = κ (γ z1 φ - σ θ̂)                                     (adaptation)

V = ½z1² + ½z2² + θ̃ᵀθ̃/(2γ) gives V̇ = -c1 z1² - c2 z2² + z1 ε + σ θ̃ᵀθ̂ - z2 (α̇1 - α̇1c) for
κ = 1. α̇1 is the total derivative of α1 (SymPy); ω̇_r is not measured, so the controller
uses the computable part with ω̇_r → b β̄ + h0 + f̂, and ḃ (the schedule's rate) → 0; both
remainders are generated. Anti-windup: κ = 0 (conditional integration) when U is at a
pitch position limit, or asks for a pitch rate (U - β̄)/τ_a beyond the rate limit, and z1
pushes it further out; or when |θ̂| is at its bound and the update points outward
(projection onto the ball |θ̂| ≤ θ_max). Accommodation (eq (49)'s structure
for three blades): the free blades get v = (3U - Σ σ̂_j ū_j) / Σ (1 - σ̂_j) ρ̂_j, so that
the mean of the effective blade inputs is U.

Three options of issue 34 (all off by default: the design above, bit for bit):

* **A speed observer** (``phys_obs_omega`` ω_o > 0). The measured ω_r carries the
  drivetrain mode (1.7 Hz on the NREL 5-MW) and the sensor noise; fed back through z1 and
  α̇1 they drive the drivetrain (docs/controllers.md). The design then runs on the state
  ω̂_r of the model-based observer

      ω̂̇_r = b β̄ + h0 + f̂(ω̂_r) + L η,   η̇ = 2ζ_o ω_o (ω_r - ω̂_r - η),   L = ω_o/(2ζ_o)

  whose error e = ω_r - ω̂_r is a second-order loop (ω_o, ζ_o) driven by f - f̂. z1 =
  ω̂_r - y_d, f̂ = θ̂ᵀφ(ω̂_r), and α̇1 is the total derivative through ω̂̇_r, which the
  controller computes exactly (only ḃ is left out): the measured ω_r reaches U only through
  η's rate. The weights adapt on χ = L η / c1 (the size z1 had at rest): θ̂̇ = κ (γ χ φ -
  σ θ̂). With V = ½z1² + ½z2² + V_o(e, η) + θ̃ᵀθ̃/(2γ'), the θ̃ terms cancel for an
  adaptation on e (the error system from θ̃ᵀφ to e is strictly positive real), not on η
  (relative degree 2): adapting on η is a measured choice (lower loads, docs/controllers.md)
  outside that argument. ż1 = -c1 z1 + b z2 + L η, the last term the observer's bounded
  error. Off (ω_o = 0), ω̂_r follows ω_r and η decays at 1/s, unused, so that
  ``wtftc linearize`` sees no zero eigenvalue. Its corner may be scheduled on the
  measured mean pitch (``phys_obs_omega_max`` > 0: :func:`observer_corner`).
* **Peak shaving** (``phys_ps_pitch`` > 0): the command's lower limit rises from the stop
  near rated, scheduled on the speed the design regulates (:func:`pitch_floor`).
* **Where the weights leak** (``phys_leak_nominal`` λ in [0, 1]; 0 by default, the law
  above): θ̂̇ = κ (γ χ φ - σ (θ̂ - λ θ0)), θ0 = -h0 - b β̄ the residual at an equilibrium
  on the measured pitch; λ = 1 rests the loop at the reference (:func:`derive`).
* **No actuator model** (``phys_actuator_model`` = 0), for a host whose blades take the
  command as given (OpenFAST's ServoDyn without an actuator, issue 22): relative degree 1,
  U = α1. Inverting a lag τ_a that is not there is what made the design unstable there.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import sympy as sp

from derivation import design as design_
from derivation import fuzzy, nrel5mw
from derivation.layout import N_BLADES, N_MF, Entry

omega_r = sp.Symbol("omega_r", real=True)
beta_meas = sp.symbols(f"beta_meas_1:{N_BLADES + 1}", real=True)
yd = sp.symbols("yd_0:3", real=True)
dT_dbeta = sp.Symbol("dT_dbeta", real=True)
omega_dot = sp.Symbol("omega_dot", real=True)  # true ω̇_r (unmeasured), for the full α̇1
b_dot = sp.Symbol("b_dot", real=True)  # true rate of b = G/J (unmeasured)
kappa = sp.Symbol("kappa", real=True)  # 1 integrate, 0 frozen (anti-windup), set by the generator
omega_hat = sp.Symbol("phys_speed_hat", real=True)  # the observer's ω̂_r
eta = sp.Symbol("phys_innovation", real=True)  # its filtered innovation η
speed = sp.Symbol("phys_speed_used", real=True)  # the rule base's input: ω̂_r or ω_r

STATES = [*[Entry(f"phys_theta_hat[{m}]", 0.0, "rad/s^2", f"fuzzy weight {m} of f̂(ω_r)",
                  sample=(-0.5, 1.0))
            for m in range(N_MF)],
          Entry("phys_speed_hat", nrel5mw.RATED_SPEED, "rad/s",
                "the speed observer's rotor speed ω̂_r", sample=(1.1, 1.45)),
          Entry("phys_innovation", 0.0, "rad/s",
                "the speed observer's filtered innovation η", sample=(-0.02, 0.02)),
          Entry("phys_td_speed", 0.0, "m/s",
                "the tower damper's fore-aft speed estimate ŝ: the tower-top acceleration "
                "high-passed and integrated", sample=(-0.3, 0.3)),
          Entry("phys_td_acc", 0.0, "m/s^2",
                "the tower damper's low-passed fore-aft acceleration a_f (0 at the start: "
                "the filter's output rises, the command takes no step)", sample=(-1.0, 1.0))]
PARAMS = [
    # c1, c2, γ chosen among (1, 4, 0.5), (2, 6, 0.5), (2, 6, 2), (3, 8, 1) on 60 s of NTM
    # class B at 16 m/s: (2, 6, 2) had the lowest RMS speed error (docs/controllers.md)
    Entry("phys_c1", 2.0, "1/s", "backstepping gain c1 (speed error)"),
    Entry("phys_c2", 6.0, "1/s", "backstepping gain c2 (pitch error)"),
    Entry("phys_gamma", 2.0, "-", "adaptation rate γ"),
    Entry("phys_sigma", 0.01, "1/s", "σ-modification of the adaptive law"),
    Entry("phys_leak_nominal", 0.0, "-",
          "where the σ-modification leaks the weights: toward this fraction of the "
          "equilibrium residual θ0 = -h0 - b β̄ (1: the speed rests at the reference); "
          "0: toward 0, the textbook law, whose rest z1 = σ f̂ / (γ Σφ²) is an offset "
          "above the reference", sample=(0.0, 1.0)),
    Entry("phys_theta_max", 2.0, "rad/s^2", "projection bound |θ̂| ≤ θ_max"),
    Entry("phys_inertia", nrel5mw.DRIVETRAIN_INERTIA, "kg m^2",
          "drivetrain inertia on the LSS, J_r + N² J_g (Jonkman 2009)"),
    Entry("phys_gen_torque", nrel5mw.RATED_GEN_TORQUE_LSS, "N m",
          "generator torque on the LSS above rated (constant torque, Jonkman 2009)"),
    *design_.actuator_and_fuzzy_params("phys"),
    Entry("phys_obs_omega", 0.0, "rad/s",
          "natural frequency ω_o of the speed observer the design runs on; "
          "0: none, the measured ω_r (as before issue 34)", sample=(3.0, 9.0)),
    Entry("phys_obs_zeta", 0.7, "-", "damping ratio ζ_o of the speed observer",
          sample=(0.5, 1.0)),
    Entry("phys_obs_omega_max", 0.0, "rad/s",
          "the observer's corner scheduled on the measured mean pitch: ω_o rises linearly "
          "from phys_obs_omega at phys_obs_pitch_min to this at phys_obs_pitch_max "
          "(observer_corner); 0: none, ω_o constant (as before)", sample=(3.0, 9.0)),
    Entry("phys_obs_pitch_min", 0.30, "rad",
          "the mean pitch where the observer's corner starts to rise (17°: about 20 m/s "
          "on the NREL 5-MW)", sample=(0.0, 0.2)),
    Entry("phys_obs_pitch_max", 0.38, "rad",
          "the mean pitch from which the corner is phys_obs_omega_max (22°: about 24 m/s "
          "on the NREL 5-MW)", sample=(0.25, 0.4)),
    *design_.peak_shaving_params("phys"),
    *design_.tower_damper_params("phys"),
    Entry("phys_actuator_model", 1.0, "-",
          "1: the design inverts the first-order actuator τ_a; 0: none (a host whose "
          "blades take the command as given): U = α1", sample=(1.0, 1.0)),
]
(c1, c2, gam, sig, th_max, J, T_g, tau_a, bmin, bmax, gmin, rmax, w_obs, z_obs,
 act, ps_pitch, ps_speed, leak) = sp.symbols(
    "phys_c1 phys_c2 phys_gamma phys_sigma phys_theta_max phys_inertia phys_gen_torque "
    "phys_tau_a phys_pitch_min phys_pitch_max phys_dTdbeta_min phys_rate_max phys_obs_omega "
    "phys_obs_zeta phys_actuator_model phys_ps_pitch phys_ps_speed phys_leak_nominal",
    real=True)
w_obs_max, obs_bmin, obs_bmax = sp.symbols(
    "phys_obs_omega_max phys_obs_pitch_min phys_obs_pitch_max", real=True)
observing = w_obs > 0
with_actuator = act > sp.Rational(1, 2)
td_pitch = sp.Symbol("td_pitch", real=True)  # the tower damper's Δβ, until substituted


@dataclass
class PhysicalDesign:
    rule_base: fuzzy.RuleBase
    b: sp.Expr = sp.S.Zero
    h0: sp.Expr = sp.S.Zero
    z1: sp.Expr = sp.S.Zero
    z2: sp.Expr = sp.S.Zero
    alpha1: sp.Expr = sp.S.Zero
    alpha1_dot_full: sp.Expr = sp.S.Zero
    alpha1_dot_comp: sp.Expr = sp.S.Zero
    U: sp.Expr = sp.S.Zero
    v_free: sp.Expr = sp.S.Zero
    omega_dot_hat: sp.Expr = sp.S.Zero
    adapt_gain: sp.Expr = sp.S.Zero  # γ z1 (times φ) of the adaptive law
    observer_rate: sp.Expr = sp.S.Zero  # ω̂̇_r of the speed observer


def beta_mean() -> sp.Expr:
    return sum(beta_meas) / N_BLADES


def observer_corner() -> sp.Expr:
    """The observer's corner ω_o (issue 34): phys_obs_omega, or with phys_obs_omega_max > 0
    scheduled on the measured mean pitch, a proxy of the wind above rated: linear from
    ω_o at β̄ ≤ β_min to ω_o,max at β̄ ≥ β_max. A lower corner moves the pitch less (ADC)
    and a higher one holds the rotor closer in the strongest winds, where the extreme
    overspeed of a fault is made (docs/controllers.md). α1 holds no ω_o, and α̇1 takes
    the rate of ω̂_r from the observer's equation as the controller computes it, so the
    schedule leaves α̇1 exact: no rate of ω_o enters."""
    ramp = sp.Min(sp.Max((beta_mean() - obs_bmin) / (obs_bmax - obs_bmin), 0), 1)
    return sp.Piecewise((w_obs + (w_obs_max - w_obs) * ramp, w_obs_max > 0), (w_obs, True))


L_obs = observer_corner() / (2 * z_obs)  # the innovation's gain into ω̂̇_r
L_eta = 2 * z_obs * observer_corner()  # the innovation filter's corner


@cache
def chain() -> PhysicalDesign:
    """The design on the measured ω_r, and on the observer's ω̂_r, joined by one switch at
    the top (so that the design without the observer is the same expression as before)."""
    rb = fuzzy.RuleBase(1)  # f̂: the input x̂_1 of the rule base is the speed used
    d = PhysicalDesign(rule_base=rb)
    g = -sp.Max(-dT_dbeta, gmin)  # G ≤ -gmin < 0 above rated
    b_sym = sp.Symbol("b_sched", real=True)  # b as a symbol: its rate is b_dot
    d.b = g / J
    d.h0 = -T_g / J
    omega_dot_hat = b_sym * beta_mean() + d.h0 + rb.L()
    observer = omega_dot_hat + L_obs * eta
    measured = _branch(rb, b_sym, d.h0, omega_r, omega_dot, omega_dot_hat, None)
    observed = _branch(rb, b_sym, d.h0, omega_hat, observer, observer, L_obs / c1 * eta)
    for name in ("z1", "alpha1", "alpha1_dot_full", "alpha1_dot_comp", "adapt_gain"):
        joined = sp.Piecewise((observed[name], observing), (measured[name], True))
        setattr(d, name, joined.subs(b_sym, d.b))
    d.omega_dot_hat = omega_dot_hat.subs(b_sym, d.b)
    d.observer_rate = observer.subs(b_sym, d.b)
    d.z2 = sp.Piecewise((beta_mean() - observed["alpha1"], observing),
                        (beta_mean() - measured["alpha1"], True)).subs(b_sym, d.b)
    d.U = sp.Piecewise((observed["U"].subs(b_sym, d.b), sp.And(observing, with_actuator)),
                       (measured["U"].subs(b_sym, d.b), with_actuator), (d.alpha1, True))
    u_clip = sp.Min(sp.Max(d.U, pitch_floor()), bmax)
    d.v_free = design_.free_blade_command(u_clip)
    return d


def _branch(rb, b_sym, h0, w, rate_full, rate_comp, chi) -> dict:
    """z1, α1, α̇1 (full and computable), the adaptive law's γ χ and U of the design run on
    the speed w (ω_r or ω̂_r) of rate ``rate_full`` (``rate_comp`` what the controller
    computes of it); the weights adapt on χ (z1 if None)."""
    x2 = beta_mean()
    z1 = w - yd[0]
    chi = z1 if chi is None else chi
    alpha1 = (-c1 * z1 - h0 - rb.L() + yd[1]) / b_sym + td_pitch
    # total derivative along the loop: the speed, y_d, the weights (through L/B), b, the
    # tower damper's pitch (its rate is computed from the measured acceleration: exact)
    damper, damper_rate, *_ = design_.tower_damper("phys")
    rates = {w: omega_dot, yd[0]: yd[1], yd[1]: yd[2], b_sym: b_dot, td_pitch: damper_rate}
    target = leak * (-h0 - b_sym * x2)  # the leakage's target weight, leak·θ0 (derive)
    full = fuzzy.total_derivative(alpha1, rates, rb, [omega_dot], chi, kappa * gam,
                                  kappa * sig, target)
    # rb.rate may have created symbols L1_1, B1_0_0 used above: all generated by the caller
    comp = full.subs({omega_dot: rate_comp, b_dot: 0})
    full = full.subs(omega_dot, rate_full)
    U = x2 + tau_a * (-c2 * (x2 - alpha1) - b_sym * z1 + comp)
    alpha1, full, comp, U = (e.subs(td_pitch, damper) for e in (alpha1, full, comp, U))
    return {"z1": z1, "alpha1": alpha1, "alpha1_dot_full": full, "alpha1_dot_comp": comp,
            "adapt_gain": gam * chi, "U": U}


WEIGHTS = [e.name for e in STATES[:N_MF]]
theta = sp.symbols(WEIGHTS, real=True)
#: the design model of the α̇1 checks (design_model): start at the defaults, random
#: verification inputs in the sample ranges
MODEL_STATES = [
    Entry("dm_omega_r", 1.28, "rad/s", "rotor speed ω_r", sample=(1.1, 1.45)),
    Entry("dm_beta", 0.2, "rad", "mean blade pitch β̄", sample=(0.0, 0.4)),
]
#: the aerodynamic residual d: its mean balances rated torque near 0.17 rad of pitch
MODEL_RESIDUAL = Entry("dm_residual", 0.13, "rad/s^2", "aerodynamic residual d",
                       sample=(0.11, 0.15))


@cache
def derive() -> design_.ControllerDesign:
    """The design as the generator takes it: κ (anti-windup, projection) bound first, then
    the adaptive law θ̂̇ = κ (γ z1 φ - σ (θ̂ - θ_L)), the commands, and the checks of α̇1.

    θ_L = phys_leak_nominal · θ0, θ0 = -h0 - b β̄ the residual f at an equilibrium on the
    measured pitch (:func:`initial_residual`). Toward 0 (the textbook σ-modification,
    Ioannou & Sun 1996, 8.4.1), a rest has γ χ φ_m = σ θ̂_m for every rule, so f̂ = f
    needs χ = σ f / (γ Σφ²) ≠ 0: the speed rests above the reference. Toward θ0, a rest
    with f̂ = θ0 = f has χ = 0. The leakage keeps its bound: with θ̃ = θ̂ - θ*, σ θ̃ᵀ(θ̂ -
    θ_L) ≥ σ/2 (|θ̃|² - |θ* - θ_L 1|²), bounded as θ0 is (b, h0 and β̄ are)."""
    d = chain()
    theta_norm2, theta_dot_dir = sp.symbols("theta_norm2 theta_dot_dir", real=True)
    toward = leak * initial_residual()
    return design_.ControllerDesign(
        rule_base=d.rule_base, fuzzy_inputs=[speed.name], weights=WEIGHTS,
        v=d.v_free, u0=d.U,
        x_dot=[*[kappa * (d.adapt_gain * d.rule_base.phi(m) - sig * (t - toward))
                 for m, t in enumerate(theta)],
               sp.Piecewise((d.observer_rate, observing), (omega_r - omega_hat, True)),
               sp.Piecewise((L_eta * (omega_r - omega_hat - eta), observing), (-eta, True)),
               *design_.tower_damper("phys")[2:]],
        diag=[d.z1, d.z2, d.alpha1, kappa], x0=[*[initial_residual()] * N_MF, omega_r, 0, 0, 0],
        signals=[(speed, sp.Piecewise((omega_hat, observing), (omega_r, True)))],
        intermediates=[(theta_norm2, sum(t**2 for t in theta)),
                       (theta_dot_dir, d.adapt_gain * d.rule_base.L()
                        - sig * (theta_norm2 - toward * sum(theta))),
                       (kappa, freeze_conditions(d, theta_norm2, theta_dot_dir))],
        checks={"alpha1": d.alpha1, "alpha1_dot_full": d.alpha1_dot_full,
                "alpha1_dot_comp": d.alpha1_dot_comp, "omega_dot_hat": d.omega_dot_hat,
                "kappa": kappa},
        check_inputs=[omega_dot, b_dot])


def design_model(d_sym: sp.Symbol) -> dict:
    """ω̇_r = b β̄ + h0 + d (d the exogenous residual), τ_a β̄̇ = U - β̄ (β̄ last: its rate is
    the caller's); the three blades at β̄, measured exactly; b from the schedule, ḃ = 0."""
    d = chain()
    w, bb = sp.symbols([e.name for e in MODEL_STATES], real=True)
    w_dot = d.b * bb + d.h0 + d_sym
    return {"states": [w, bb], "rates": [w_dot], "beta_mean": bb, "tau": tau_a,
            "meas": {"omega_r": w, "omega_g_hss": sp.S.Zero,  # not used by the design
                     **{f"beta_meas_{j}": bb for j in range(1, N_BLADES + 1)}},
            "true_rates": {"omega_dot": w_dot, "b_dot": sp.S.Zero}}


def freeze_conditions(d: PhysicalDesign, theta_norm2, theta_dot_dir) -> sp.Expr:
    """κ = 0 when the command is saturated and z1 pushes it out, or |θ̂| is at its bound
    and the update points outward; else 1. The saturation test uses the command computed
    with κ = 1 (U itself contains κ through α̇1)."""
    return design_.freeze(d.U.subs(kappa, 1), beta_mean(), tau_a, pitch_floor(), bmax, rmax,
                          d.z1, theta_norm2, theta_dot_dir, th_max, rate_test=with_actuator)


def pitch_floor() -> sp.Expr:
    """The command's lower limit: the stop, raised near rated by peak shaving
    (:func:`derivation.design.pitch_floor`) on the speed the design regulates."""
    return design_.pitch_floor(bmin, ps_pitch, speed, ps_speed, yd[0])


def initial_residual() -> sp.Expr:
    """f at an equilibrium on the measured pitch: 0 = b β̄ + h0 + f  ⇒  f = -h0 - b β̄."""
    d = chain()
    return -d.h0 - d.b * beta_mean()
