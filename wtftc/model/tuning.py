"""Controller parameters from a turbine file (ours; docs/turbines.md).

A controller's parameters are of two kinds. Facts of the turbine it runs on (its
inertias, drivetrain, rated torque and speed, pitch limits and rate limit, actuator time
constant) are taken from the turbine file here, so that a controller runs on any turbine
without new code. Design choices (the backstepping gains c, γ, the memberships) keep
their layout defaults (the PI's closed-loop ω_n and ζ are the turbine file's reference
target where it gives one: wtftc.config): the designs are normalised by
the scheduled ∂T/∂β and the inertia, so their closed-loop poles do not depend on the
turbine (docs/turbines.md says where that stops being true).

Each fact is scaled from the NREL 5-MW's so that, for the NREL 5-MW itself, the
parameters are the layout defaults bit for bit (tested): quantities the design reads as
physical are set to the turbine's; thresholds and normalisations that carry a unit are
scaled by the ratio of the turbine's rated value to the NREL 5-MW's.
"""

from __future__ import annotations

import numpy as np

from wtftc.artefacts import layout as lay


def _facts(tp: dict, ref: dict) -> dict[str, float]:
    """Role → value for the turbine values ``tp`` (``ref``: the NREL 5-MW's)."""
    speed = tp["omega_g_rated"] / ref["omega_g_rated"]
    torque = tp["gen_torque_rated"] / ref["gen_torque_rated"]
    return {"inertia": tp["J_r"] + tp["J_g"], "gen_torque": tp["gen_torque_rated"],
            "tau_a": tp["tau_b"], "pitch_min": tp["pitch_min"], "pitch_max": tp["pitch_max"],
            "rate_max": tp["pitch_rate_max"], "J_r": tp["J_r"], "J_g": tp["J_g"],
            "k_s": tp["k_s"], "d_s": tp["d_s"], "gearbox_ratio": tp["gearbox_ratio"],
            "tau_b_model": tp["tau_b"], "x_offset_1": tp["omega_g_rated"],
            # a unit of speed or of ∂T/∂β: scaled with the turbine's rated speed, torque
            "x_scale_1": speed, "dTdbeta_min": torque, "ps_speed": speed}


#: roles whose layout default is multiplied by the fact (the others are set to it)
_SCALED = ("x_scale_1", "dTdbeta_min", "ps_speed")
#: the controller prefixes of layout names (derivation: phys_, dt_, pi_, fdi_)
_PREFIXES = ("phys_", "dt_", "pi_", "fdi_")


def _role(name: str) -> str:
    for p in _PREFIXES:
        if name.startswith(p):
            return name[len(p):]
    return name


def turbine_params_of(group: str, p_turbine: np.ndarray) -> dict[str, float]:
    """The parameters of layout group ``group`` (a controller's or ``fdi_params``) that are
    facts of the turbine ``p_turbine``, by name."""
    tp = lay.values("turbine_params", p_turbine)
    ref = lay.values("turbine_params", lay.defaults("turbine_params"))
    facts, defaults = _facts(tp, ref), lay.values(group, lay.defaults(group))
    out = {}
    for name, default in defaults.items():
        role = _role(name)
        if role in facts:
            out[name] = default * facts[role] if role in _SCALED else facts[role]
    return out
