"""Turbine plants for the closed-loop simulator, in SymPy.

Two plants share one interface (states, blade commands v_j, hub-height wind, the power
coefficient cp evaluated by the runtime's Cp(λ, β) interpolant, per-blade faults):

* ``paper``   eqs (1)-(4) exactly as printed, d1 = T_aero / J_r, no generator torque.
              Unloaded (paper-notes defect 3): its only steady state has T_aero = 0. Kept to
              reproduce the paper. Eq (4) per blade, with eq (19) faults.
* ``nrel5mw`` two-mass drivetrain referred to the low-speed shaft (eqs (1)-(3) plus the
              generator torque -T_g/J_g that eq (3) lacks), generator torque above rated
              (constant torque or constant power), and three second-order blade pitch
              actuators (Odgaard et al. 2013 benchmark) with position and rate limits.
* ``tower``   the ``nrel5mw`` plant on a flexible tower: its first fore-aft bending mode
              (one modal mass, stiffness and damping at the tower top), driven by the
              rotor thrust ½ ρ π R² v_rel² Ct(λ, β̄), the rotor seeing the wind relative
              to the moving tower top, v_rel = v - ẋ_t (issue 18; docs/loads.md).
* ``tower_edge`` the ``tower`` plant with edgewise-flexible blades: the blades' first
              edgewise mode, collective (all three blades alike), in series with the
              shaft, as ElastoDyn has it (issue 33; docs/validation.md). The mode that
              OpenFAST's generator speed shows at 1.68 Hz on the NREL 5-MW, where the
              rigid rotor's two-mass drivetrain has 2.22 Hz.

The aerodynamic torque T_aero = ½ ρ π R² v³ Cp(λ, β̄) / ω_r with λ = ω_r R / v and
β̄ the mean blade pitch (rigid rotor, uniform inflow); Cp comes in as the input ``cp``.
"""

from __future__ import annotations

import sympy as sp

from derivation import plant
from derivation.layout import N_BLADES

J = range(1, N_BLADES + 1)

# --- inputs common to both plants ---
wind = sp.Symbol("wind", positive=True)  # hub-height wind speed [m/s]
cp = sp.Symbol("cp", real=True)  # power coefficient at (λ, β̄), from the interpolant
ct = sp.Symbol("ct", real=True)  # thrust coefficient at (λ, β̄), from the interpolant
v = plant.v  # blade pitch commands [rad]
# per-blade actuator faults (time-varying inputs of the step)
rho, lock, ubar = plant.rho, plant.lock, plant.ubar  # eq (19)
omega_n = sp.symbols("omega_n_1:4", positive=True)  # actuator natural frequency [rad/s]
zeta = sp.symbols("zeta_1:4", positive=True)  # actuator damping ratio [-]
ACTUATOR_FAULTS = [*rho, *lock, *ubar, *omega_n, *zeta]
# the sensors (noise, faults, lag, resolution) are derivation/sensors.py

# --- parameters ---
air_density = sp.Symbol("air_density", positive=True)  # [kg/m^3]
rotor_radius = sp.Symbol("rotor_radius", positive=True)  # [m]
gearbox_ratio = sp.Symbol("gearbox_ratio", positive=True)  # [-]
gen_torque_rated = sp.Symbol("gen_torque_rated", positive=True)  # LSS [N m]
gen_constant_power = sp.Symbol("gen_constant_power", real=True)  # 0 torque, 1 power
vs_constant_torque = sp.Symbol("vs_constant_torque", real=True)  # the law's region 3
omega_n0 = sp.Symbol("omega_n_nominal", positive=True)  # nominal actuator [rad/s]
zeta0 = sp.Symbol("zeta_nominal", positive=True)
pitch_min = sp.Symbol("pitch_min", real=True)  # [rad]
pitch_max = sp.Symbol("pitch_max", real=True)  # [rad]
pitch_rate_max = sp.Symbol("pitch_rate_max", positive=True)  # [rad/s]
omega_g_rated = sp.Symbol("omega_g_rated", positive=True)  # LSS-referred [rad/s]
# the baseline variable-speed torque law (values and sources: nrel5mw.py, layout.py)
gen_torque_law = sp.Symbol("gen_torque_law", real=True)  # 0 fixed, 1 baseline law
vs_cut_in_speed, vs_region2_speed, vs_rated_speed = sp.symbols(
    "vs_cut_in_speed vs_region2_speed vs_rated_speed", positive=True)  # LSS [rad/s]
vs_region2_k = sp.Symbol("vs_region2_k", positive=True)  # LSS [N m s^2/rad^2]
vs_slip = sp.Symbol("vs_slip", positive=True)  # [-]
vs_rated_power = sp.Symbol("vs_rated_power", positive=True)  # [W]
vs_max_torque = sp.Symbol("vs_max_torque", positive=True)  # LSS [N m]

# the tower's first fore-aft mode (values and sources: the turbine files, docs/loads.md)
tower_modal_mass = sp.Symbol("tower_modal_mass", positive=True)  # [kg]
tower_stiffness = sp.Symbol("tower_stiffness", positive=True)  # modal [N/m]
tower_damping_ratio = sp.Symbol("tower_damping_ratio", positive=True)  # [-]
tower_moment_arm = sp.Symbol("tower_moment_arm", positive=True)  # rotor over base [m]

# the blades' first edgewise mode, per blade (values and sources: the turbine files; the
# integrals over the ElastoDyn blade file: wtftc.model.turbine_import.edge_mode)
edge_modal_mass = sp.Symbol("edge_modal_mass", positive=True)  # m_e = ∫ μ φ² dr [kg]
edge_stiffness = sp.Symbol("edge_stiffness", positive=True)  # k_e = ∫ EI φ''² dr [N/m]
edge_damping_ratio = sp.Symbol("edge_damping_ratio", positive=True)  # structural [-]
edge_coupling_cos = sp.Symbol("edge_coupling_cos", positive=True)  # ∫ μ r φ cos τ dr [kg m]
edge_coupling_sin = sp.Symbol("edge_coupling_sin", real=True)  # ∫ μ r φ sin τ dr [kg m]
edge_torque_share = sp.Symbol("edge_torque_share", positive=True)  # κ = ∫rφ/∫r² [1/m]

# --- states ---
beta = plant.beta
beta_rate = sp.symbols("beta_rate_1:4", real=True)  # blade pitch rates [rad/s]
omega_r, theta_s, omega_g = plant.omega_r, plant.theta_s, plant.omega_g

tower_x = sp.Symbol("tower_x", real=True)  # tower-top fore-aft displacement [m]
tower_v = sp.Symbol("tower_v", real=True)  # tower-top fore-aft velocity [m/s]

PAPER_STATES = [omega_r, theta_s, omega_g, *beta]
NREL_STATES = [omega_r, theta_s, omega_g, *beta, *beta_rate]
TOWER_STATES = [*NREL_STATES, tower_x, tower_v]

edge_q = sp.Symbol("edge_q", real=True)  # collective edgewise tip deflection [m]
edge_v = sp.Symbol("edge_v", real=True)  # its rate [m/s]
TOWER_EDGE_STATES = [*TOWER_STATES, edge_q, edge_v]


def tip_speed_ratio(w: sp.Expr = wind) -> sp.Expr:
    """λ = ω_r R / v (on the tower plant v is the relative wind v_rel)."""
    return omega_r * rotor_radius / w


def relative_wind() -> sp.Expr:
    """v_rel = v - ẋ_t: the wind the rotor sees from the moving tower top (a rigid rotor
    at the tower top, the shaft's tilt and overhang neglected)."""
    return wind - tower_v


def thrust(w: sp.Expr = wind) -> sp.Expr:
    """F_T = ½ ρ π R² v² Ct(λ, β̄) (Ct from the turbine's Cp_Ct_Cq table)."""
    return air_density * sp.pi * rotor_radius**2 * w**2 * ct / 2


def tower_damping() -> sp.Expr:
    """The modal damping c_t = 2 ζ_t √(k_t m_t) [N s/m]."""
    return 2 * tower_damping_ratio * sp.sqrt(tower_stiffness * tower_modal_mass)


def tower_base_moment() -> sp.Expr:
    """The tower-base fore-aft bending moment, quasi-static: the tower's elastic force at
    the top k_t x_t times the height of the rotor over the tower base (docs/loads.md)."""
    return tower_stiffness * tower_x * tower_moment_arm


def mean_pitch() -> sp.Expr:
    """β̄: the effective pitch of a rigid rotor, the mean of the blades (x4 of eq (8))."""
    return sum(beta) / N_BLADES


def aero_torque(w: sp.Expr = wind) -> sp.Expr:
    """T_aero = P_aero / ω_r = ½ ρ π R² v³ Cp / ω_r."""
    return air_density * sp.pi * rotor_radius**2 * w**3 * cp / (2 * omega_r)


def baseline_torque_law() -> sp.Expr:
    """The NREL 5-MW baseline variable-speed torque law on the LSS (Jonkman et al. 2009,
    section 7.1): 0 below cut-in; region 1½ the line from cut-in to k ω² at the start of
    region 2; region 2 k ω² (optimal tip-speed ratio); region 2½ the line through the
    synchronous speed ω_rated/(1 + slip) that reaches P_rated/ω_rated at ω_rated; region 3
    constant power P_rated/ω (Jonkman's), or with ``vs_constant_torque`` 1 constant torque
    P_rated/ω_g,rated, the same torque at the speed the pitch regulates to, hence the same
    operating point (issue 34: constant power on the unfiltered generator speed, dT/dω =
    -P/ω², takes damping from the drivetrain mode; docs/controllers.md), which the region-2½
    line meets just below its ω_rated; capped at the maximum torque. Written as one continuous
    min/max expression of ω_g: regions by speed only (the original also enters region 3
    when the pitch exceeds 1°), and without its torque-rate limit of 15 kN m/s (HSS)."""
    w = omega_g
    k, w_ci, w_r2 = vs_region2_k, vs_cut_in_speed, vs_region2_speed
    w_sync = vs_rated_speed / (1 + vs_slip)
    region15 = k * w_r2**2 / (w_r2 - w_ci) * (w - w_ci)
    region2 = k * w**2
    region25 = vs_rated_power / vs_rated_speed / (vs_rated_speed - w_sync) * (w - w_sync)
    region3 = sp.Piecewise((vs_rated_power / omega_g_rated, vs_constant_torque > 0.5),
                           (vs_rated_power / w, True))
    law = sp.Max(sp.Min(region15, region2), region25)
    return sp.Min(vs_max_torque, sp.Max(0, sp.Min(region3, law)))


def generator_torque() -> sp.Expr:
    """T_g on the LSS: rated torque, or constant power P = T_rated ω_rated
    (gen_torque_law = 0), or the baseline variable-speed law (gen_torque_law = 1)."""
    const_power = gen_torque_rated * omega_g_rated / omega_g
    fixed = (1 - gen_constant_power) * gen_torque_rated + gen_constant_power * const_power
    return (1 - gen_torque_law) * fixed + gen_torque_law * baseline_torque_law()


def commanded_input(j: int) -> sp.Expr:
    """Eq (19) on blade j's command, then clipped to the actuator's position range."""
    u = plant.actuator_input(v[j], rho[j], lock[j], ubar[j])
    return sp.Min(sp.Max(u, pitch_min), pitch_max)


def paper_rhs() -> list[sp.Expr]:
    """Eqs (1)-(4) as printed, d1 = T_aero/J_r; eq (4)'s τ_b scaled per blade by a fault.

    A hydraulic fault changes blade j's time constant to τ_b · (2ζ_j/ω_n,j)/(2ζ_0/ω_n,0):
    the first-order equivalent of the benchmark's second-order change.
    """
    rhs = plant.paper_rhs()
    d1 = aero_torque() / plant.J_r
    out = [e.subs(plant.d1, d1) for e in rhs[:3]]
    for j in range(N_BLADES):
        tau_j = plant.tau_b * (2 * zeta[j] / omega_n[j]) / (2 * zeta0 / omega_n0)
        out.append((commanded_input(j) - beta[j]) / tau_j)  # (4)
    return out


def limited_actuator(b, w, u, wn, zt, b_min, b_max, r_max) -> list[sp.Expr]:
    """[β̇, β̈] of the benchmark's pitch actuator (Odgaard et al. 2013) with limits:

    β̈ = ω_n² (u - β) - 2 ζ ω_n β̇ on the rate state w; the blade rate is w held within
    ±r_max (w stops growing outward at the limit) and the blade stops at [b_min, b_max].
    Written once: the plant and the FDI's model bank both use it.
    """
    rate = sp.Min(sp.Max(w, -r_max), r_max)
    rate = sp.Piecewise((0, sp.And(b >= b_max, rate > 0)), (0, sp.And(b <= b_min, rate < 0)),
                        (rate, True))
    acc = wn**2 * (u - b) - 2 * zt * wn * w
    acc = sp.Piecewise((0, sp.And(w >= r_max, acc > 0)), (0, sp.And(w <= -r_max, acc < 0)),
                       (acc, True))
    return [rate, acc]


def pitch_actuator_rhs() -> list[sp.Expr]:
    """[β̇_1..3, β̈_1..3] of the three pitch actuators alone, exactly the actuator rows of
    :func:`nrel5mw_rhs` (and the tower plant's): the plant-side actuator library that
    OpenFAST runs (wtftc.openfast, issue 32) integrates these, so that a fault acts there
    as it does in wtftc's own plant."""
    rates, accels = [], []
    for j in range(N_BLADES):
        rate, acc = limited_actuator(beta[j], beta_rate[j], commanded_input(j), omega_n[j],
                                     zeta[j], pitch_min, pitch_max, pitch_rate_max)
        rates.append(rate)
        accels.append(acc)
    return rates + accels


def nrel5mw_rhs(w: sp.Expr = wind) -> list[sp.Expr]:
    """Two-mass drivetrain on the LSS with generator torque, and 2nd-order actuators.

    J_r ω̇_r = T_aero - k_s θ_s - d_s (ω_r - ω_g)          (eq (1), F ω_r = T_aero/J_r)
    θ̇_s = ω_r - ω_g                                          (eq (2))
    J_g ω̇_g = k_s θ_s + d_s (ω_r - ω_g) - T_g                (eq (3) + the missing -T_g)
    β̈_j = ω_n,j² (u_j - β_j) - 2 ζ_j ω_n,j β̇_j               (Odgaard et al. 2013)

    with u_j eq (19) clipped to [pitch_min, pitch_max]; the blade rate is held within
    ±pitch_rate_max (the rate state stops growing outward at the limit) and the blade
    stops at the position limits.
    """
    J_r, J_g, k_s, d_s = plant.J_r, plant.J_g, plant.k_s, plant.d_s
    out = [
        (aero_torque(w) - k_s * theta_s - d_s * (omega_r - omega_g)) / J_r,
        omega_r - omega_g,
        (k_s * theta_s + d_s * (omega_r - omega_g) - generator_torque()) / J_g,
    ]
    return out + pitch_actuator_rhs()


def tower_rhs() -> list[sp.Expr]:
    """The ``nrel5mw`` plant in the relative wind v_rel, and the tower's first fore-aft
    mode (one degree of freedom at the tower top, Jonkman 2009 section 6 for the mode):

    ẋ_t = v_t
    m_t v̇_t = F_T(v_rel) - c_t v_t - k_t x_t
    """
    w = relative_wind()
    force = thrust(w) - tower_damping() * tower_v - tower_stiffness * tower_x
    return nrel5mw_rhs(w) + [tower_v, force / tower_modal_mass]


def edge_coupling(b: sp.Expr) -> sp.Expr:
    """S(β) = ∫ μ r φ cos(β + τ) dr [kg m]: how much of a blade's edgewise mode moves in
    the rotor plane, where rotation moves it. The mode φ(r) turns with the structural
    twist τ(r) and the pitch β; cos(β + τ) = cos β cos τ - sin β sin τ splits the integral
    into two constants of the blade (Jonkman 2009's ElastoDyn blade, twist and mode
    shape). At the NREL 5-MW's 12° above rated it is 0.96 of the flat blade's."""
    return edge_coupling_cos * sp.cos(b) - edge_coupling_sin * sp.sin(b)


def aero_speed() -> sp.Expr:
    """ω_a = ω_r + κ q̇_e: the blades' speed as the aerodynamic torque sees it. With the
    tangential load taken proportional to the radius, the load's virtual work on the
    blades is T_aero (δθ_r + κ δq_e), κ = ∫ r φ dr / ∫ r² dr (ours: the reduced plant's
    one assumption on the load's spanwise shape; it gives the edge mode its aerodynamic
    damping from the Cp table's slope)."""
    return omega_r + edge_torque_share * edge_v


def edge_aero_torque() -> sp.Expr:
    """T_aero on the tower_edge plant: in the wind relative to the tower top, at the
    blades' speed ω_a (:func:`aero_speed`)."""
    return aero_torque(relative_wind()).subs(omega_r, aero_speed())


def tower_edge_rhs() -> list[sp.Expr]:
    """The ``tower`` plant with the blades' first edgewise mode, collective, in series with
    the shaft (Lagrange's equations with ElastoDyn's kinematics and one blade mode, Jonkman
    2005, FAST User's Guide). A blade element at radius r moves in the rotor plane by
    r θ_r + φ(r) cos(β + τ) q_e, the mode turning with the pitch and the twist, so

    T = ½ J_r ω_r² + ω_r Σ_j (S_j q̇_e + S'_j β̇_j q_e) + ½ · 3 m_e q̇_e² (+ O(q_e² β̇²))
    V = ½ · 3 k_e q_e² + ½ k_s θ_s²

    with S_j = S(β_j) (:func:`edge_coupling`), S'_j = dS/dβ. In the edge equation the
    pitch-rate terms cancel exactly (d/dt ∂T/∂q̇_e brings ω_r Σ S'_j β̇_j, ∂T/∂q_e takes it
    away); in the rotor equation they are 2 Σ S'_j β̇_j q̇_e + Σ (S'_j β̈_j + S''_j β̇_j²) q_e,
    under 1 % of the rated torque at the 8°/s rate limit and left out. What stays:

    J_r ω̇_r + Σ S_j q̈_e = T_aero - k_s θ_s - d_s (ω_r - ω_g)
    Σ S_j ω̇_r + 3 m_e q̈_e = κ T_aero - 3 k_e q_e - 3 c_e q̇_e

    with c_e = 2 ζ_e √(k_e m_e) and the aerodynamic torque at the blades' speed ω_a
    (:func:`aero_speed`). J_r is the rigid rotor's inertia (hub and blades); the mass
    matrix is positive definite because the blade's rigid inertia ∫ μ r² dr exceeds S²/m_e
    (Cauchy-Schwarz). Also left out: the edge mode's centrifugal stiffening (about 1 % in
    frequency at rated speed), its out-of-plane share in the thrust and the flap modes."""
    base = tower_rhs()
    t_aero = edge_aero_torque()
    s_sum = sum(edge_coupling(b) for b in beta)
    c_e = 2 * edge_damping_ratio * sp.sqrt(edge_stiffness * edge_modal_mass)
    J_r, k_s, d_s = plant.J_r, plant.k_s, plant.d_s
    f_rotor = t_aero - k_s * theta_s - d_s * (omega_r - omega_g)
    f_edge = edge_torque_share * t_aero - 3 * edge_stiffness * edge_q - 3 * c_e * edge_v
    det = 3 * edge_modal_mass * J_r - s_sum**2
    omega_r_dot = (3 * edge_modal_mass * f_rotor - s_sum * f_edge) / det
    edge_v_dot = (J_r * f_edge - s_sum * f_rotor) / det
    return [omega_r_dot, *base[1:], edge_v, edge_v_dot]


def generator_power() -> sp.Expr:
    """Mechanical power at the generator shaft, T_g ω_g (efficiency applied at the edge)."""
    return generator_torque() * omega_g
