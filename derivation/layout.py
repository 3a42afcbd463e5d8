"""The one authoritative ordering of states, inputs and parameters.

Everything that indexes a vector in wtftc reads this ordering from
``generated/layout.json``, which :mod:`derivation.generate` writes from this module.
Names follow the paper (Bakhshi & Alfi 2020); where the paper reuses a letter for two
things (paper-notes defect 6) the code uses distinct names:

* ``theta_hat_i``  fuzzy weight vectors (paper θ_i), ``theta_act_j`` actuator weights
  (paper θ_j of θᵀu), ``theta_s`` shaft torsion;
* ``mf_width``     Table 1's φ = 0.6 read as the Gaussian membership width (paper φ is
  also the regressor, here ``phi_i``);
* ``tau_young``    Table 1's τ = 0.2, the Young-inequality weight of eqs (24), (36)-(48);
  ``tau_b`` is the pitch time constant of eq (4);
* ``K_obs``        the observer gain K of eq (20); ``A_obs`` the observer matrix; the decay
  rate "A" of eq (51) is ``kappa``.

SI units everywhere (rad, rad/s, N m, kg m², s). The turbine's and the actuator benchmark's
numbers come from :mod:`derivation.nrel5mw`, which gives their sources; Table 1's stay here.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, replace

from derivation import nrel5mw

#: number of Gaussian memberships per fuzzy input (structural: sets the weight counts)
N_MF = 3
#: number of blade pitch actuators (eq (49) read as three blade actuators, paper-notes defect 9)
N_BLADES = 3
#: order of the strict-feedback chain, eqs (11)-(14)
N_CHAIN = 4


@dataclass(frozen=True)
class Entry:
    name: str
    default: float
    unit: str
    doc: str
    #: where verification draws random values of this entry, (low, high) in its unit;
    #: None: near the default (wtftc.verify.checks.random_inputs)
    sample: tuple[float, float] | None = None
    #: the physical range a value must lie in, (low, high, low_open, high_open), None for
    #: an unbounded end; the runtime refuses any value outside it (wtftc.config)
    valid: tuple | None = None

    def as_json(self) -> dict:
        out = {"name": self.name, "default": self.default, "unit": self.unit, "doc": self.doc}
        if self.valid:
            lo, hi, lo_open, hi_open = self.valid
            out["valid"] = {"min": lo, "max": hi, "min_open": lo_open, "max_open": hi_open}
        return out | ({"sample": list(self.sample)} if self.sample else {})


def rule_count(i: int) -> int:
    """Rules of the fuzzy system of chain step i (1-based): a full grid on x̂1..x̂i."""
    return N_MF**i


def split_by_rules(seq: Sequence) -> list:
    """``seq`` (the weights of every chain step, in order) cut into θ̂_1..θ̂_N_CHAIN."""
    out, k = [], 0
    for i in range(1, N_CHAIN + 1):
        out.append(seq[k:k + rule_count(i)])
        k += rule_count(i)
    return out


# --- plant states: eqs (1)-(4), pitch of eq (4) per blade (x4 = mean blade pitch) ---
#: the two-mass drivetrain's states, shared by the paper's plant and the NREL 5-MW
DRIVETRAIN_STATES = [
    Entry("omega_r", nrel5mw.RATED_SPEED, "rad/s", "rotor speed, x1 of eq (5)"),
    Entry("theta_s", 0.0, "rad", "drivetrain torsion angle, x2 of eq (6)"),
    Entry("omega_g", nrel5mw.RATED_SPEED, "rad/s",
          "generator speed referred to the LSS, x3 of eq (7)"),
]
PLANT_STATES = [
    *DRIVETRAIN_STATES,
    *[Entry(f"beta_{j}", 0.0, "rad", f"pitch angle of blade {j}; x4 = mean, eq (8)")
      for j in range(1, N_BLADES + 1)],
]

# --- controller states: fuzzy observer (21) and the adaptive weights (32), (37), (43), (49)
CONTROLLER_STATES = [
    Entry("xhat_1", nrel5mw.RATED_SPEED, "rad/s",
          "observer state x̂1 of eq (21), the estimate of ω_r"),
    *[Entry(f"xhat_{k}", 0.0, "-",
            f"observer state x̂{k} of eq (21) (formal, paper-notes defect 11)")
      for k in range(2, N_CHAIN + 1)],
    *[Entry(f"theta_hat_{i}[{m}]", 0.0, "-", f"fuzzy weight {m} of f̂{i}, eq (21)")
      for i in range(1, N_CHAIN + 1) for m in range(rule_count(i))],
]

# --- plant parameters: eq (10); the NREL 5-MW's values (referred to the low-speed shaft)
# and sources from its turbine file, wtftc/data/nrel5mw.toml ---
PLANT_PARAMS = [nrel5mw.entry(Entry, n, u) for n, u in (
    ("J_r", "kg m^2"), ("J_g", "kg m^2"), ("k_s", "N m/rad"), ("d_s", "N m s/rad"),
    ("tau_b", "s"))]

# --- fault parameters of eq (19), one per blade actuator (true plant) ---
#: (the sample ranges: where verification draws the fault estimates eq (49) is told)
FAULT_INPUTS = [
    *[Entry(f"rho_{j}", 1.0, "-", f"loss of effectiveness ρ of actuator {j}, eq (19)",
            sample=(0.5, 1.0)) for j in range(1, N_BLADES + 1)],
    *[Entry(f"lock_{j}", 0.0, "-", f"lock-in-place indicator σ of actuator {j}, eq (19)",
            sample=(0.0, 0.7)) for j in range(1, N_BLADES + 1)],
    *[Entry(f"ubar_{j}", 0.0, "rad", f"stuck command ū of actuator {j}, eq (19)",
            sample=(0.0, 0.3)) for j in range(1, N_BLADES + 1)],
]

# --- controller parameters: Table 1 and the design choices of docs/paper-notes.md ---
CONTROLLER_PARAMS = [
    # Table 1's K = [1 1 5 5] is not Hurwitz (paper-notes defect 1); the default places the
    # observer poles at -2, -3, -4, -5. The paper's values stay available by name.
    *[Entry(f"K_obs_{k}", v, "-", f"observer gain K{k} of eq (20)")
      for k, v in zip(range(1, 5), (14.0, 71.0, 154.0, 120.0), strict=True)],
    *[Entry(f"c_{k}", v, "-", f"backstepping gain c{k}, Table 1")
      for k, v in zip(range(1, 5), (6.0, 6.0, 12.0, 9.0), strict=True)],
    *[Entry(f"gamma_{k}", v, "-", f"learning rate γ{k}, Table 1")
      for k, v in zip(range(1, 5), (50.0, 10.0, 20.0, 20.0), strict=True)],
    *[Entry(f"r_{k}", 0.1, "-", f"σ-modification r{k} of the adaptive laws, Table 1")
      for k in range(1, 5)],
    Entry("tau_young", 0.2, "-", "Young-inequality weight τ of eqs (24), (36)-(49), Table 1"),
    Entry("mf_width", 0.6, "-", "Gaussian membership width on normalized inputs, Table 1's φ"),
    # centres evenly spread on [-1, 1] (for N_MF = 3: -1, 0, 1)
    *[Entry(f"mf_centre_{m}", -1.0 + 2.0 * (m - 1) / (N_MF - 1), "-",
            f"centre of membership {m} on normalized inputs")
      for m in range(1, N_MF + 1)],
    *[Entry(f"x_offset_{k}", v, "-", f"normalization offset of x̂{k}: z = (x̂ - offset)/scale")
      for k, v in zip(range(1, 5), (nrel5mw.RATED_SPEED, 0.0, 0.0, 0.0), strict=True)],
    *[Entry(f"x_scale_{k}", v, "-", f"normalization scale of x̂{k}")
      for k, v in zip(range(1, 5), (0.2, 1.0, 1.0, 1.0), strict=True)],
    Entry("tau_b_model", nrel5mw.PITCH_TIME_CONSTANT, "s",
          "pitch time constant the controller assumes: θ_j = 1/(3 τ_b) of θᵀu, eq (14)"),
    *[Entry(f"b_{j}", 1.0, "-", f"distribution b{j} of u0 to actuator {j}, eq (46)")
      for j in range(1, N_BLADES + 1)],
    Entry("control_sign", -1.0, "-",
          "sign s of the applied command v_j = s b_j u0: +1 as written (diverges, "
          "paper-notes defect 2), -1 corrected"),
    *[Entry(f"rho_hat_{j}", 1.0, "-", f"ρ of actuator {j} known to eq (49)")
      for j in range(1, N_BLADES + 1)],
    *[Entry(f"lock_hat_{j}", 0.0, "-", f"lock indicator of actuator {j} known to eq (49)")
      for j in range(1, N_BLADES + 1)],
    *[Entry(f"ubar_hat_{j}", 0.0, "rad", f"stuck command ū of actuator {j} known to eq (49)")
      for j in range(1, N_BLADES + 1)],
]

# --- simulator plants (derivation/turbine.py) ---
#: (the sample ranges: verification crosses the actuator's limits, beyond 0..90°)
NREL_STATES = [
    *[replace(e, sample=r) for e, r in zip(DRIVETRAIN_STATES, ((0.8, 1.6), (-0.01, 0.01),
                                                                (0.8, 1.6)), strict=True)],
    *[Entry(f"beta_{j}", 0.0, "rad", f"pitch angle of blade {j}", sample=(-0.1, 1.7))
      for j in range(1, N_BLADES + 1)],
    *[Entry(f"beta_rate_{j}", 0.0, "rad/s", f"pitch rate of blade {j}", sample=(-0.25, 0.25))
      for j in range(1, N_BLADES + 1)],
]
#: the tower plant's: the nrel5mw plant's, then the tower's first fore-aft mode
TOWER_STATES = [
    *NREL_STATES,
    Entry("tower_x", 0.0, "m", "tower-top fore-aft displacement (first mode)",
          sample=(-0.2, 0.8)),
    Entry("tower_v", 0.0, "m/s", "tower-top fore-aft velocity (first mode)",
          sample=(-1.0, 1.0)),
]
#: the tower_edge plant's: the tower plant's, then the blades' collective first edgewise
#: mode (derivation/turbine.py ``tower_edge_rhs``; issue 33)
TOWER_EDGE_STATES = [
    *TOWER_STATES,
    Entry("edge_q", 0.0, "m", "collective edgewise tip deflection of the blades (first mode)",
          sample=(-0.5, 1.5)),
    Entry("edge_v", 0.0, "m/s", "collective edgewise tip velocity (first mode)",
          sample=(-2.0, 2.0)),
]
#: the turbine's parameters after the plant's: names and units here, the NREL 5-MW's
#: values and sources from its turbine file (the baseline torque law: Jonkman 2009, 7.1,
#: its DISCON's VS_* constants referred to the LSS)
TURBINE_PARAMS = [*PLANT_PARAMS, *[nrel5mw.entry(Entry, n, u) for n, u in (
    ("air_density", "kg/m^3"), ("rotor_radius", "m"), ("gearbox_ratio", "-"),
    ("gen_torque_rated", "N m"), ("gen_constant_power", "-"), ("omega_g_rated", "rad/s"),
    ("gen_efficiency", "-"), ("omega_n_nominal", "rad/s"), ("zeta_nominal", "-"),
    ("pitch_min", "rad"), ("pitch_max", "rad"), ("pitch_rate_max", "rad/s"),
    ("gen_torque_law", "-"), ("vs_cut_in_speed", "rad/s"), ("vs_region2_speed", "rad/s"),
    ("vs_region2_k", "N m s^2/rad^2"), ("vs_rated_speed", "rad/s"), ("vs_slip", "-"),
    ("vs_rated_power", "W"), ("vs_max_torque", "N m"),
    ("tower_modal_mass", "kg"), ("tower_stiffness", "N/m"), ("tower_damping_ratio", "-"),
    ("tower_moment_arm", "m"),
    ("edge_modal_mass", "kg"), ("edge_stiffness", "N/m"), ("edge_damping_ratio", "-"),
    ("edge_coupling_cos", "kg m"), ("edge_coupling_sin", "kg m"), ("edge_torque_share", "1/m"),
    ("vs_constant_torque", "-"))]]
#: The physical range of every turbine parameter (docs/running.md, "Errors and exit codes").
#: Positive where the derivation declares the symbol positive (a zero inertia, stiffness,
#: time constant or slip divides by zero); upper limits only where physics sets one (air
#: density, blade length, an efficiency, a slip, a pitch angle); flags 0 or 1.
_POSITIVE = (0.0, None, True, True)
TURBINE_VALID = {
    **dict.fromkeys(("J_r", "J_g", "k_s", "d_s", "tau_b", "gearbox_ratio", "gen_torque_rated",
                     "omega_g_rated", "omega_n_nominal", "zeta_nominal", "pitch_rate_max",
                     "vs_cut_in_speed", "vs_region2_speed", "vs_region2_k", "vs_rated_speed",
                     "vs_rated_power", "vs_max_torque", "tower_modal_mass", "tower_stiffness",
                     "tower_moment_arm", "edge_modal_mass", "edge_stiffness",
                     "edge_coupling_cos", "edge_torque_share"), _POSITIVE),
    "tower_damping_ratio": (0.0, 1.0, True, False),  # structural: about 1 %
    "edge_damping_ratio": (0.0, 1.0, True, False),  # structural: about 0.5 %
    "edge_coupling_sin": (None, None, True, True),  # the twist's share: either sign
    "air_density": (0.0, 2.0, True, False),  # 1.225 at 15 °C, about 1.5 at -40 °C
    "rotor_radius": (0.0, 250.0, True, False),  # the largest rotors: about 155 m
    "gen_efficiency": (0.0, 1.0, True, False),
    "vs_slip": (0.0, 1.0, True, True),
    "pitch_min": (-math.pi / 2, math.pi / 2, False, False),  # ±90°
    "pitch_max": (-math.pi / 2, math.pi / 2, False, False),
    **dict.fromkeys(("gen_constant_power", "gen_torque_law", "vs_constant_torque"),
                    (0.0, 1.0, False, False)),
}
#: The physical range of a controller parameter, by its role: the name without the
#: controller's prefix (phys_, dt_, pi_) and blade or step number. Gains, rates, time
#: constants, inertias and widths are positive (each divides or sets a sign the design
#: relies on); σ-modifications and torques non-negative; pitch angles within ±90°; the
#: observer gain K (Table 1's is not even Hurwitz: paper-notes defect 1), centres, offsets
#: and b any finite number; the fault estimates of eq (49) in their own ranges.
_NONNEG = (0.0, None, False, True)
_ANY = (None, None, True, True)
_ANGLE = (-math.pi / 2, math.pi / 2, False, False)
CONTROLLER_VALID = {
    **dict.fromkeys(("c", "gamma", "theta_max", "inertia", "J_r", "J_g", "k_s", "d_s",
                     "gearbox_ratio", "tau_a", "dTdbeta_min", "rate_max", "mf_width", "x_scale",
                     "omega_n", "zeta", "tau_young", "tau_b_model", "obs_zeta", "ps_speed",
                     "td_corner"),
                    _POSITIVE),
    **dict.fromkeys(("sigma", "r", "gen_torque", "lpf_corner", "obs_omega", "td_gain",
                     "td_max", "td_lpf", "obs_omega_max"), _NONNEG),
    **dict.fromkeys(("K_obs", "mf_centre", "x_offset", "b"), _ANY),
    **dict.fromkeys(("pitch_min", "pitch_max", "ubar_hat", "ps_pitch", "obs_pitch_min",
                     "obs_pitch_max"), _ANGLE),
    "control_sign": (-1.0, 1.0, False, False),
    "actuator_model": (0.0, 1.0, False, False),
    "leak_nominal": (0.0, 1.0, False, False),
    "rho_hat": (0.0, 1.0, True, False),
    "lock_hat": (0.0, 1.0, False, False),
}


def controller_role(name: str) -> str:
    """``phys_c1`` → ``c``, ``gamma_3`` → ``gamma``, ``dt_theta_max`` → ``theta_max``."""
    return re.sub(r"_?\d+$", "", re.sub(r"^(phys|dt|pi)_", "", name))


def with_controller_ranges(entries: list[Entry]) -> list[Entry]:
    """The entries with their physical range from :data:`CONTROLLER_VALID` (by role);
    an entry whose role has none (a held external command) keeps ``valid`` unset."""
    return [replace(e, valid=CONTROLLER_VALID.get(controller_role(e.name), e.valid))
            for e in entries]


PLANT_PARAMS = [replace(e, valid=TURBINE_VALID[e.name]) for e in PLANT_PARAMS]
TURBINE_PARAMS = [replace(e, valid=TURBINE_VALID[e.name]) for e in TURBINE_PARAMS]

#: (the sample ranges exercise every fault, beyond those eq (49) is told)
_FAULT_SAMPLES = {"rho": (0.3, 1.0), "lock": (0.0, 1.0), "ubar": (0.0, 0.5)}
ACTUATOR_FAULTS = [
    *[replace(e, sample=_FAULT_SAMPLES[e.name.rsplit("_", 1)[0]]) for e in FAULT_INPUTS],
    *[Entry(f"omega_n_{j}", nrel5mw.ACTUATOR_OMEGA_N, "rad/s",
            f"actuator {j} natural frequency: {nrel5mw.ACTUATOR_OMEGA_N} nominal, "
            f"{nrel5mw.PRESSURE_DROP_OMEGA_N} hydraulic pressure drop, "
            f"{nrel5mw.AIR_IN_OIL_OMEGA_N} high air content in oil (Odgaard 2013)",
            sample=(3.0, 12.0)) for j in range(1, N_BLADES + 1)],
    *[Entry(f"zeta_{j}", nrel5mw.ACTUATOR_ZETA, "-",
            f"actuator {j} damping: {nrel5mw.ACTUATOR_ZETA} nominal, "
            f"{nrel5mw.PRESSURE_DROP_ZETA} pressure drop, {nrel5mw.AIR_IN_OIL_ZETA} air in oil",
            sample=(0.4, 1.0)) for j in range(1, N_BLADES + 1)],
]
#: the reference y_d and its first four derivatives, eqs (26), (37), (43), (49)
REFERENCE = [Entry(f"yd_{m}", 1.27 if m == 0 else 0.0, f"rad/s^{m + 1}" if m else "rad/s",
                   f"y_d^({m}), the rotor-speed reference and its derivative {m}")
             for m in range(5)]

#: parameters of the optimal weights θ*_i (eq (30) onwards) for Lyapunov evaluation
THETA_STAR = [Entry(f"theta_star_{i}[{m}]", 0.0, "-", f"optimal fuzzy weight {m} of f{i}")
              for i in range(1, N_CHAIN + 1) for m in range(rule_count(i))]

#: paper values of Table 1 that differ from the defaults, kept by name for tests and docs
PAPER_TABLE1 = {"K_obs": (1.0, 1.0, 5.0, 5.0)}

#: the operating envelope of a run (ours): a rotor beyond ``overspeed`` × rated speed has
#: run away (the campaign's largest peak that recovered was 1.27 × rated; an overspeed
#: protection trips near 1.2-1.3 ×), and one below ``stall`` × rated has stalled: either
#: run is recorded as lost at the first step outside, with the reason
#: (wtftc.sim.integrate.divergence). The stall floor sits below every controller's own
#: speed range: ROSCO's minimum rotor speed for the NREL 5-MW (VS_MinOMSpd, 0.357 rad/s)
#: is 0.28 × rated, and a floor of 0.3 × ended ROSCO's normal runs at 4 m/s (issue 31)
ENVELOPE = {"overspeed_over_rated": 2.0, "stall_under_rated": 0.2}

#: the pitch actuator's dynamics under the hydraulic faults, at full severity (Odgaard,
#: Stoustrup, Kinnaert 2013): the plant's fault inputs are built from these
HYDRAULIC_FAULTS = {
    "pressure_drop": {"omega_n": nrel5mw.PRESSURE_DROP_OMEGA_N,
                      "zeta": nrel5mw.PRESSURE_DROP_ZETA},
    "air_in_oil": {"omega_n": nrel5mw.AIR_IN_OIL_OMEGA_N, "zeta": nrel5mw.AIR_IN_OIL_ZETA},
}


def names(entries: list[Entry]) -> list[str]:
    return [e.name for e in entries]


def as_json() -> dict:
    """The layout as emitted to generated/layout.json."""
    groups = {
        "plant_states": PLANT_STATES,
        "controller_states": CONTROLLER_STATES,
        "plant_params": PLANT_PARAMS,
        "fault_inputs": FAULT_INPUTS,
        "controller_params": with_controller_ranges(CONTROLLER_PARAMS),
        "reference": REFERENCE,
        "theta_star": THETA_STAR,
        "nrel5mw_states": NREL_STATES,
        "tower_states": TOWER_STATES,
        "tower_edge_states": TOWER_EDGE_STATES,
        "turbine_params": TURBINE_PARAMS,
        "actuator_faults": ACTUATOR_FAULTS,
    }
    out: dict = {
        "n_mf": N_MF,
        "n_blades": N_BLADES,
        "n_chain": N_CHAIN,
        "hydraulic_faults": HYDRAULIC_FAULTS,
        "envelope": ENVELOPE,
        "rule_counts": [rule_count(i) for i in range(1, N_CHAIN + 1)],
        "paper_table1": {k: list(v) for k, v in PAPER_TABLE1.items()},
    }
    for key, entries in groups.items():
        out[key] = [e.as_json() for e in entries]
    return out
