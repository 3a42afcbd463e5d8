"""The initial state of a run: the plant in balance, the controller and the FDI at rest."""

from __future__ import annotations

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.model import aero
from wtftc.model.faults import nominal_actuator
from wtftc.sim.rhs import PLANTS, Loop, controllers


def trim(loop: Loop, p_ctrl: np.ndarray, wind0: float, omega_offset: float = 0.0) -> np.ndarray:
    """Initial state: rated speed (plus offset), drivetrain at rest under rated torque,
    blades at the pitch that balances it at the initial wind ``wind0`` [m/s], a tower
    bent by the thrust there (derivation/turbine.py ``thrust``); the
    controller and the FDI at rest on what they measure there.

    The paper plant has no generator torque: its balance is T_aero = 0 (paper-notes defect 3).
    """
    tp = lay.values("turbine_params", loop.p_turbine)
    omega = tp["omega_g_rated"] + omega_offset
    loaded = PLANTS[loop.plant]["loaded"]
    torque = tp["gen_torque_rated"] if loaded else 0.0
    beta0 = aero.steady_pitch(aero.cp_interpolant(loop.table), omega, torque, wind0,
                              tp["air_density"], tp["rotor_radius"])
    plant = dict.fromkeys(lay.names(PLANTS[loop.plant]["states"]), 0.0)
    plant.update(omega_r=omega, theta_s=torque / tp["k_s"], omega_g=omega,
                 **{f"beta_{j}": beta0 for j in lay.blades()})
    if PLANTS[loop.plant].get("tower"):  # the tower bent by the steady thrust, at rest
        plant["tower_x"] = _thrust(loop, np.array(list(plant.values())), wind0) \
            / tp["tower_stiffness"]
    # the controller and the FDI start from what they measure (init_<name>, generated)
    meas = {"omega_r": omega, "omega_g_hss": omega * tp["gearbox_ratio"],
            **{f"beta_meas_{j}": beta0 for j in lay.blades()}}
    meas0 = np.array([meas[m["name"]] for m in lay.layout()["measurements"]])
    sched0 = float(aero.pitch_sensitivity_schedule(loop.table, loop.p_turbine)(beta0))
    init = load(controllers()[loop.controller]["init"])
    xc = np.array(init(meas=meas0, sched=sched0, p_ctrl=p_ctrl)["x_ctrl0"]).ravel()
    beta_meas = [meas[f"beta_meas_{j}"] for j in lay.blades()]
    xf = np.array(load("init_fdi")(beta_meas=beta_meas)["x_fdi0"]).ravel()
    return np.concatenate([list(plant.values()), xc, xf])


def _thrust(loop: Loop, xp: np.ndarray, wind0: float) -> float:
    """The generated plant's thrust (derivation/turbine.py ``thrust``) with the tower at
    rest, Ct read at the operating point the generated ``aero_operating_point`` gives."""
    states = PLANTS[loop.plant]["states"]
    op = load("aero_operating_point")(x_plant=xp[lay.prefix("plant_states", of=states)],
                                      wind=wind0, p_turbine=loop.p_turbine)
    ct = aero.cp_interpolant(loop.table, "ct")(op["tsr"], op["beta_mean"])
    out = load(PLANTS[loop.plant]["function"])(
        x_plant=xp, v=xp[lay.block(states, "beta")], wind=wind0, cp=0.0, ct=ct,
        actuator_faults=nominal_actuator(loop.p_turbine), p_turbine=loop.p_turbine)
    return float(out["thrust"])
