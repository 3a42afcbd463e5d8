"""The initial state of a run: the plant in balance, the controller and the FDI at rest."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.errors import ConfigError
from wtftc.model import aero
from wtftc.model.cp_table import aero_torque, bisect
from wtftc.model.faults import nominal_actuator
from wtftc.sim.rhs import PLANTS, Loop, controllers, rhs_function
from wtftc.sim.stability import _jacobian_function, fault_free_args


def trim(loop: Loop, p_ctrl: np.ndarray, wind0: float, omega_offset: float = 0.0,
         yd: np.ndarray | None = None, rosco: dict | None = None) -> np.ndarray:
    """Initial state: the plant at the operating point of the initial wind ``wind0`` [m/s]
    (:func:`operating_point`: above rated, rated speed (plus offset) and the pitch that
    balances rated torque; below rated, the torque law's equilibrium at the minimum pitch),
    the drivetrain twisted by the generator torque there, a tower bent by the thrust there
    (derivation/turbine.py ``thrust``); the controller and the FDI at rest on what they
    measure there.

    The paper plant has no generator torque: its balance is T_aero = 0 at rated speed
    (paper-notes defect 3).
    """
    tp = lay.values("turbine_params", loop.p_turbine)
    aero.schedule_points(loop.table, loop.p_turbine)  # a table with no pitch range: named
    omega, torque, beta0 = (operating_point(loop, wind0, omega_offset) if rosco is None
                            else rosco_operating_point(loop, wind0, rosco))
    plant = dict.fromkeys(lay.names(PLANTS[loop.plant]["states"]), 0.0)
    plant.update(omega_r=omega, theta_s=torque / tp["k_s"], omega_g=omega,
                 **{f"beta_{j}": beta0 for j in lay.blades()})
    if PLANTS[loop.plant].get("tower"):  # the tower bent by the steady thrust, at rest
        plant["tower_x"] = _thrust(loop, np.array(list(plant.values())), wind0) \
            / tp["tower_stiffness"]
    if PLANTS[loop.plant].get("edge"):  # the blades bent by the torque they carry:
        # q_e = κ T / (3 k_e), derivation/turbine.py tower_edge_rhs at rest
        plant["edge_q"] = tp["edge_torque_share"] * torque / (3 * tp["edge_stiffness"])
    # the controller and the FDI start from what they measure (init_<name>, generated)
    meas = {"omega_r": omega, "omega_g_hss": omega * tp["gearbox_ratio"],
            **{f"beta_meas_{j}": beta0 for j in lay.blades()}}
    meas0 = np.array([meas[m["name"]] for m in lay.layout()["measurements"]])
    sched0 = float(aero.pitch_sensitivity_schedule(loop.table, loop.p_turbine)(beta0))
    init = load(controllers()[loop.controller]["init"])
    # the runtime inputs: the schedule, and the tower at rest (no acceleration)
    xc = np.array(init(meas=meas0, sched=[sched0, 0.0], p_ctrl=p_ctrl)["x_ctrl0"]).ravel()
    x = np.concatenate([list(plant.values()), xc])
    if yd is not None and omega_offset == 0.0 and loop.controller != "external":
        x = closed_loop_rest(loop, x, wind0, yd, p_ctrl)
    beta0 = x[lay.block(PLANTS[loop.plant]["states"], "beta")]
    xf = np.array(load("init_fdi")(beta_meas=beta0)["x_fdi0"]).ravel()
    return np.concatenate([x, xf])


#: Newton's method on the closed loop's ż = 0 stops below this max |ż| [SI] (the
#: operating points rest to 1e-13 or better: wtftc.campaign.linearize.REST_TOLERANCE)
REST_TOLERANCE = 1e-9


def closed_loop_rest(loop: Loop, x: np.ndarray, wind: float, yd, p_ctrl) -> np.ndarray:
    """The plant and controller states ``x`` moved to where the continuous closed loop
    rests in constant ``wind``: Newton's method on ż = 0 with the exact Jacobian, from the
    plant's operating point with the controller at rest on its measurements. A controller
    may rest off the plant's point (the physical AFTC's σ-modification leaves rated speed
    +0.65 % and the pitch 0.11° lower at 25 m/s on the NREL 5-MW). Kept only where it
    converges near the start (speed within 5 %, pitch within 2°); else ``x`` as given."""
    loop0 = replace(loop, fdi=False)
    rhs, jac = rhs_function(loop0), _jacobian_function(loop0)
    args = {k: v for k, v in fault_free_args(loop0, wind, yd, p_ctrl).items()
            if k in rhs.name_in()}
    n = rhs.size1_in("z")
    z = np.array(x[:n], dtype=float)
    best, stalled = np.inf, 0
    for _ in range(30):
        f = np.array(rhs.call({**args, "z": z})["z_dot"]).ravel()
        if not np.all(np.isfinite(f)):
            return x
        size = np.abs(f).max()
        if size < REST_TOLERANCE:
            break
        # a loop that does not rest (the paper's design above rated) stops Newton early:
        # three steps without halving the residual (each step costs a Jacobian)
        stalled = 0 if size < 0.5 * best else stalled + 1
        best = min(best, size)
        if stalled >= 3:
            return x
        J = np.array(jac.call({**args, "z": z})["dz_dot_dz"])
        z = z - np.linalg.lstsq(J, f, rcond=None)[0]
    else:
        return x
    states = PLANTS[loop.plant]["states"]
    i_w, blk = lay.index(states, "omega_r"), lay.block(states, "beta")
    if abs(z[i_w] / x[i_w] - 1) > 0.05 or np.max(np.abs(z[blk] - x[blk])) > np.radians(2):
        return x
    return np.concatenate([z, x[n:]])


def start_wind(loop: Loop, wind0: float, wind_mean: float) -> float:
    """The wind whose operating point a run starts at: ``wind0``, or, where it has none
    with a variable-speed torque law but the run's mean wind ``wind_mean`` has one (a
    turbulent field's first second below cut-in: the NREL 5-MW at 2.7 m/s in a 4-m/s NTM,
    its region-1 speed beyond the Cp table's tip-speed ratios), the lowest wind between
    the two that has one (to 1 mm/s): the rotor turning slowly as the wind starts to carry
    it; the start-up window (30 s) is left out of every metric. A run whose mean wind has
    no point either (a constant wind below cut-in), or a fixed rated torque the wind cannot
    carry, is refused by :func:`operating_point`, naming the wind."""
    tp = lay.values("turbine_params", loop.p_turbine)

    def has_point(w: float) -> bool:
        try:
            operating_point(loop, w)
        except ConfigError:
            return False
        return True

    if (not PLANTS[loop.plant]["loaded"] or tp["gen_torque_law"] < 0.5
            or wind_mean <= wind0 or has_point(wind0) or not has_point(wind_mean)):
        return wind0  # as it is: its point, or operating_point's refusal naming it
    lo, hi = wind0, wind_mean
    while hi - lo > 1e-3:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if has_point(mid) else (mid, hi)
    return hi


def operating_point(loop: Loop, wind: float, omega_offset: float = 0.0) \
        -> tuple[float, float, float]:
    """(rotor speed [rad/s], generator torque [N m, LSS], pitch [rad]) where the rotor is
    at rest in the constant wind ``wind`` [m/s] (issue 31):

    * above rated (the rotor at rated speed and minimum pitch makes at least the torque law's
      torque there): rated speed plus ``omega_offset``, the torque law's torque, and the
      pitch that balances it (:func:`wtftc.model.aero.steady_pitch`);
    * below rated: the pitch at its minimum and the rotor speed where the aerodynamic torque
      equals the torque law's, the stable equilibrium of the largest speed (regions 1½, 2,
      2½ of the baseline law; ROSCO's region-2 law k ω² is the same by construction);
    * no equilibrium with the tip-speed ratio inside the Cp table: at or above the
      turbine's cut-in wind (``loop.cut_in_wind``, when known) with the variable-speed law,
      the equilibrium with Cp held at the table's edge, as the plant holds it (the IEA
      15-MW's slowest speed, 0.5236 rad/s, is a tip-speed ratio of 14.5, the table's last,
      at 4.33 m/s, and its rotor rests a little faster: the table ends below 4.45 m/s);
      else (below cut-in, or a fixed rated torque the wind cannot carry) a ConfigError
      naming the wind.

    The paper's unloaded plant balances T_aero = 0 at rated speed, as before.
    """
    tp = lay.values("turbine_params", loop.p_turbine)
    cp_fn = aero.cp_interpolant(loop.table)
    rho, R = tp["air_density"], tp["rotor_radius"]
    beta_min = max(tp["pitch_min"], 0.0) if PLANTS[loop.plant]["loaded"] else 0.0
    rated = tp["omega_g_rated"] + omega_offset
    if not PLANTS[loop.plant]["loaded"]:
        return rated, 0.0, aero.steady_pitch(cp_fn, rated, 0.0, wind, rho, R)
    t_gen = torque_law(loop)

    def excess(w: float) -> float:
        return aero_torque(float(cp_fn(w * R / wind, beta_min)), w, wind, rho, R) - t_gen(w)

    if excess(rated) >= 0:  # above rated: the pitch carries the excess
        torque = t_gen(rated)
        return rated, torque, aero.steady_pitch(cp_fn, rated, torque, wind, rho, R,
                                                (beta_min, float(loop.table.pitch_rad[-1])))
    lo = float(loop.table.tsr[0]) * wind / R
    w = _balance(excess, lo, min(float(loop.table.tsr[-1]) * wind / R, rated))
    if w is None and tp["gen_torque_law"] >= 0.5 and 0 < loop.cut_in_wind <= wind:
        # at or above cut-in, the rotor's slowest speed past the table's ratios (the IEA
        # 15-MW below 4.45 m/s): Cp held at the table's edge, as the plant holds it
        w = _balance(excess, lo, rated)
    if w is None:
        why = ("below the turbine's cut-in wind, "
               f"{loop.cut_in_wind:g} m/s"
               if wind < loop.cut_in_wind else "below cut-in, or a fixed rated torque "
               "(turbine_params.gen_torque_law = 0) the wind cannot carry")
        raise ConfigError("wind", wind, "an initial wind at which the rotor has an operating "
                          f"point: at {wind:g} m/s no rotor speed up to rated balances the "
                          "aerodynamic torque against the generator torque law with the tip-"
                          f"speed ratio inside the Cp table ({loop.table.tsr[0]:g}-"
                          f"{loop.table.tsr[-1]:g}): {why}")
    return w, t_gen(w), beta_min


def _balance(excess, lo: float, hi: float) -> float | None:
    """The rotor speed in [lo, hi] [rad/s] where ``excess`` (aerodynamic minus generator
    torque) crosses from deficit (slows) to excess (speeds up) going down from ``hi``: the
    stable equilibrium of the largest speed, or None."""
    grid = np.linspace(hi, lo, 400) if hi > lo else np.array([])
    f = np.array([excess(w) for w in grid])
    cross = np.nonzero((f[:-1] < 0) & (f[1:] >= 0))[0]
    if not len(cross):
        return None
    k = int(cross[0])
    return bisect(lambda x: excess(x) >= 0, float(grid[k + 1]), float(grid[k]))


def rosco_operating_point(loop: Loop, wind: float, discon: dict) -> tuple[float, float, float]:
    """(rotor speed [rad/s], generator torque [N m, LSS], pitch [rad]) where ROSCO's own
    laws rest in the constant ``wind`` (its DISCON.IN's values, ``discon``): below rated,
    tip-speed-ratio tracking at VS_TSRopt within [VS_MinOMSpd, PC_RefSpd] (VS_ControlMode
    2) at the fine pitch, PC_FinePit raised to the peak-shaving minimum PS_BldPitchMin at
    this wind (PS_Mode 1), the torque the aerodynamics then give; above rated, PC_RefSpd
    and the pitch that balances the rated torque, at least that minimum."""
    tp = lay.values("turbine_params", loop.p_turbine)
    cp_fn = aero.cp_interpolant(loop.table)
    rho, R, n_g = tp["air_density"], tp["rotor_radius"], tp["gearbox_ratio"]

    def num(key: str) -> np.ndarray:
        return np.array(discon[key].split(), dtype=float)

    rated = float(num("PC_RefSpd")[0]) / n_g
    beta = float(num("PC_FinePit")[0])
    if float(num("PS_Mode")[0]) > 0:
        beta = max(beta, float(np.interp(wind, num("PS_WindSpeeds"), num("PS_BldPitchMin"))))
    omega = float(np.clip(num("VS_TSRopt")[0] * wind / R, num("VS_MinOMSpd")[0] / n_g, rated))
    torque = aero_torque(float(cp_fn(omega * R / wind, beta)), omega, wind, rho, R)
    if torque <= tp["gen_torque_rated"]:
        return omega, torque, beta
    torque = tp["gen_torque_rated"]
    return rated, torque, aero.steady_pitch(cp_fn, rated, torque, wind, rho, R,
                                            (beta, float(loop.table.pitch_rad[-1])))


def torque_law(loop: Loop):
    """The generator torque [N m, LSS] the plant's law gives at a steady speed (generated
    ``generator_torque``); an external controller commands its own torque (its plant's law
    is 0: wtftc.campaign.in_loop), and the baseline law stands in for it (ROSCO has its own
    point, :func:`rosco_operating_point`)."""
    p = np.array(loop.p_turbine, dtype=float)
    if loop.controller == "external":
        p[lay.index("turbine_params", "gen_torque_law")] = 1.0
    fn = load("generator_torque")
    return lambda w: float(fn(omega_g=w, p_turbine=p)["T_gen"])


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
