"""The NREL 5-MW reference turbine and the pitch-actuator benchmark: every number, once.

The turbine's values live in its turbine file, ``wtftc/data/nrel5mw.toml`` (referred to
the low-speed shaft, each with its unit and source; docs/turbines.md); this module reads
them for the derivation, which never retypes one. The actuator benchmark's fault values
and the PI baseline's targets stay here, with their sources.

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

import tomllib
from pathlib import Path

# --- the turbine: its turbine file, wtftc/data/nrel5mw.toml (values referred to the LSS,
# in the layout's units, each with its source: Jonkman 2009, Odgaard 2013) ---
TURBINE_FILE = Path(__file__).resolve().parent.parent / "wtftc" / "data" / "nrel5mw.toml"
_PARAMS = tomllib.loads(TURBINE_FILE.read_text(encoding="utf-8"))["params"]


def entry(make, name: str, unit: str):
    """The layout entry ``make(name, value, unit, source)`` of a turbine parameter, its
    value and source from the turbine file (whose unit must be ``unit``)."""
    e = _PARAMS[name]
    if e["unit"] != unit:
        raise ValueError(f"{TURBINE_FILE}: params.{name} in {e['unit']!r}, not {unit!r}")
    return make(name, float(e["value"]), unit, e["source"])


def _value(name: str) -> float:
    return float(_PARAMS[name]["value"])


ROTOR_RADIUS = _value("rotor_radius")  # m, tip radius (126 m rotor diameter)
AIR_DENSITY = _value("air_density")  # kg/m^3
GEARBOX_RATIO = _value("gearbox_ratio")  # -, HSS/LSS speed ratio
ROTOR_INERTIA = _value("J_r")  # kg m^2, rotor (blades and hub) about the LSS
GEN_INERTIA_LSS = _value("J_g")  # kg m^2, N² J_g: the generator's 534.116 kg m² on the HSS
SHAFT_STIFFNESS = _value("k_s")  # N m/rad, equivalent drive-shaft torsional spring (LSS)
SHAFT_DAMPING = _value("d_s")  # N m s/rad, equivalent drive-shaft torsional damping (LSS)
GEN_EFFICIENCY = _value("gen_efficiency")  # -, 94.4 %
RATED_SPEED = _value("omega_g_rated")  # rad/s, rated rotor speed, 122.90967/97 = 1.26711
RATED_GEN_TORQUE_LSS = _value("gen_torque_rated")  # N m, 43,093.55 N m (HSS) × 97
PITCH_MIN = _value("pitch_min")  # rad, 0°
PITCH_MAX = _value("pitch_max")  # rad, 90°
PITCH_RATE_MAX = _value("pitch_rate_max")  # rad/s, 8°/s
ACTUATOR_OMEGA_N = _value("omega_n_nominal")  # rad/s, the benchmark's nominal actuator
ACTUATOR_ZETA = _value("zeta_nominal")  # -
#: s, the nominal actuator's first-order equivalent 2ζ/ω_n = 0.10801 s, rounded (ours):
#: the paper's pitch time constant τ_b of eq (4), which gives no value
PITCH_TIME_CONSTANT = _value("tau_b")

# --- the pitch actuator benchmark's faults (Odgaard 2009, 2013) ---
PRESSURE_DROP_OMEGA_N = 5.73  # rad/s, hydraulic pressure drop fault
PRESSURE_DROP_ZETA = 0.45  # -, hydraulic pressure drop fault
AIR_IN_OIL_OMEGA_N = 3.42  # rad/s, high air content in the oil fault
AIR_IN_OIL_ZETA = 0.9  # -, high air content in the oil fault

# --- the PI baseline's targets (ROSCO, NREL-5MW tuning) ---
ROSCO_PC_OMEGA = 0.6  # rad/s, PC_omega: closed-loop natural frequency of the pitch PI
ROSCO_PC_ZETA = 0.7  # -, PC_zeta: closed-loop damping ratio of the pitch PI

# --- computed ---
DRIVETRAIN_INERTIA = ROTOR_INERTIA + GEN_INERTIA_LSS  # kg m^2, J_r + N² J_g
#: rad, the steady shaft twist T_g/k_s at rated torque (0.0048178), rounded: a start value
RATED_SHAFT_TWIST = 4.818e-3
