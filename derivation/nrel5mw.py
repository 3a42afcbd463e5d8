"""The NREL 5-MW reference turbine and the pitch-actuator benchmark: every number, once.

Each constant carries its unit and its source; derivation/ imports them from here and
never retypes one. HSS values are as published (high-speed shaft); the model works on the
low-speed shaft (LSS), so the values referred to it are computed at the end, with the
gearbox ratio.

Sources:

* Jonkman, Butterfield, Musial, Scott (2009), "Definition of a 5-MW Reference Wind
  Turbine for Offshore System Development", NREL/TP-500-38060 ("Jonkman 2009"): the
  turbine, and its baseline controller (section 7.1 torque, section 7.2 pitch, with the
  DISCON source whose names are given as VS_*);
* Odgaard, Stoustrup, Kinnaert (2009), "Fault tolerant control of wind turbines: a
  benchmark model", IFAC SAFEPROCESS, and (2013) "Fault-tolerant control of wind
  turbines: a benchmark model", IEEE Trans. Control Syst. Technol. 21(4) ("Odgaard
  2013"): the second-order hydraulic pitch actuator and its faults;
* ROSCO (NREL's reference open-source controller), its NREL-5MW tuning: the PI baseline's
  closed-loop targets.

The paper's own numbers (Table 1 of Bakhshi & Alfi 2020) are not the turbine's: they stay
in derivation/layout.py.
"""

from __future__ import annotations

import math

# --- the turbine (Jonkman 2009) ---
ROTOR_RADIUS = 63.0  # m, tip radius (126 m rotor diameter)
AIR_DENSITY = 1.225  # kg/m^3, the air density of the aerodynamic model
GEARBOX_RATIO = 97.0  # -, HSS/LSS speed ratio
ROTOR_INERTIA = 38_759_228.0  # kg m^2, rotor (blades and hub) about the LSS
GEN_INERTIA_HSS = 534.116  # kg m^2, generator inertia about the HSS
SHAFT_STIFFNESS = 8.67637e8  # N m/rad, equivalent drive-shaft torsional spring (LSS)
SHAFT_DAMPING = 6.215e6  # N m s/rad, equivalent drive-shaft torsional damping (LSS)
GEN_EFFICIENCY = 0.944  # -, electrical generator efficiency, 94.4 %
RATED_GEN_SPEED_HSS = 122.90967  # rad/s, rated generator speed (1173.7 rpm)
RATED_GEN_TORQUE_HSS = 43_093.55  # N m, rated generator torque (region 3, section 7.1)
PITCH_MIN = 0.0  # rad, blade pitch lower limit, 0° (section 7.2)
PITCH_MAX = math.pi / 2  # rad, blade pitch upper limit, 90° (section 7.2)
PITCH_RATE_MAX = math.radians(8.0)  # rad/s, blade pitch rate limit, 8°/s (section 7.2)

# --- the baseline variable-speed torque law (Jonkman 2009, section 7.1; DISCON names) ---
VS_CUT_IN_SPEED_HSS = 70.16224  # rad/s, VS_CtInSp: generator cut-in speed (670 rpm)
VS_REGION2_SPEED_HSS = 91.21091  # rad/s, VS_Rgn2Sp: start of region 2 (871 rpm)
VS_REGION2_K_HSS = 2.332287  # N m/(rad/s)^2, VS_Rgn2K: optimal-mode gain
VS_RATED_SPEED_HSS = 121.6805  # rad/s, VS_RtGnSp: rated speed of the torque law
VS_SLIP = 0.10  # -, VS_SlPc: region 2½ generator slip, 10 %
VS_RATED_POWER = 5296610.0  # W, VS_RtPwr: rated mechanical power
VS_MAX_TORQUE_HSS = 47402.91  # N m, VS_MaxTq: maximum generator torque

# --- the pitch actuator benchmark (Odgaard 2009, 2013) ---
ACTUATOR_OMEGA_N = 11.11  # rad/s, nominal natural frequency
ACTUATOR_ZETA = 0.6  # -, nominal damping ratio
PRESSURE_DROP_OMEGA_N = 5.73  # rad/s, hydraulic pressure drop fault
PRESSURE_DROP_ZETA = 0.45  # -, hydraulic pressure drop fault
AIR_IN_OIL_OMEGA_N = 3.42  # rad/s, high air content in the oil fault
AIR_IN_OIL_ZETA = 0.9  # -, high air content in the oil fault
#: s, the nominal actuator's first-order equivalent 2ζ/ω_n = 0.10801 s, rounded (ours):
#: the paper's pitch time constant τ_b of eq (4), which gives no value
PITCH_TIME_CONSTANT = 0.108

# --- the PI baseline's targets (ROSCO, NREL-5MW tuning) ---
ROSCO_PC_OMEGA = 0.6  # rad/s, PC_omega: closed-loop natural frequency of the pitch PI
ROSCO_PC_ZETA = 0.7  # -, PC_zeta: closed-loop damping ratio of the pitch PI

# --- referred to the LSS (computed, in this order, so the floats never change) ---
GEN_INERTIA_LSS = GEN_INERTIA_HSS * GEARBOX_RATIO**2  # kg m^2, N² J_g
DRIVETRAIN_INERTIA = ROTOR_INERTIA + GEN_INERTIA_LSS  # kg m^2, J_r + N² J_g
RATED_GEN_TORQUE_LSS = RATED_GEN_TORQUE_HSS * GEARBOX_RATIO  # N m
RATED_SPEED = RATED_GEN_SPEED_HSS / GEARBOX_RATIO  # rad/s, rated rotor speed, 1.26711
#: rad, the steady shaft twist T_g/k_s at rated torque (0.0048178), rounded: a start value
RATED_SHAFT_TWIST = 4.818e-3
