"""The closed loop's right-hand side: generated plant + Cp lookup + generated controller + FDI.

The controller sees only measured signals; the plant state never enters it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cache

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.model import tuning
from wtftc.model.aero import cp_loop_function, sched_loop_function
from wtftc.model.cp_table import CpTable, nrel5mw_cp_table
from wtftc.sim.reciprocals import with_shared_reciprocals

#: the plants, the one list; ``loaded``: a generator torque carries the rotor (the paper's
#: eq (3) has none: paper-notes defect 3)
PLANTS = {
    "nrel5mw": {"function": "turbine_nrel5mw", "states": "nrel5mw_states", "loaded": True,
                "doc": "NREL 5-MW: two-mass drivetrain, generator torque, 2nd-order "
                       "limited actuators (default)"},
    "tower": {"function": "turbine_tower", "states": "tower_states", "loaded": True,
              "tower": True, "per_blade": True,
              "doc": "the nrel5mw plant on a flexible tower: first fore-aft mode, rotor "
                     "thrust from Ct, the rotor in the wind relative to the tower top, "
                     "each blade's share of Cp and Ct at its own pitch"},
    "tower_edge": {"function": "turbine_tower_edge", "states": "tower_edge_states",
                   "loaded": True, "tower": True, "per_blade": True, "edge": True,
                   "doc": "the tower plant with edgewise-flexible blades: their first "
                          "edgewise mode, collective, in series with the shaft (ElastoDyn's "
                          "drivetrain mode; issue 33, docs/validation.md)"},
    "paper": {"function": "turbine_paper", "states": "plant_states", "loaded": False,
              "doc": "eqs (1)-(4) as printed: UNLOADED, no generator torque "
                     "(paper-notes defect 3)"},
}

#: per-step outputs common to every controller, with units; per blade j; then y_d and the
#: controller's four diagnostics (named in generated/layout.json, e.g. x̂1..x̂4 for the
#: paper's design)
_PLANT_OUTPUTS = [("omega_r", "rad/s"), ("theta_s", "rad"), ("omega_g_hss", "rad/s"),
                  ("omega_r_meas", "rad/s")]
_BLADE_OUTPUTS = [("beta", "rad"), ("beta_meas", "rad")]
_LOOP_OUTPUTS = [("u0", "rad")]
_COMMAND_OUTPUTS = [("v", "rad")]
_AERO_OUTPUTS = [("wind", "m/s"), ("tsr", "-"), ("cp", "-"), ("T_aero", "N m"),
                 ("T_gen", "N m"), ("P_gen", "W"), ("dT_dbeta", "N m/rad"), ("y_d", "rad/s")]
_FDI_OUTPUTS = [("fdi_latch", "-"), ("fdi_rho_hat", "-"), ("fdi_c_hat", "rad"),
                ("fdi_residual_rms", "rad"), ("fdi_omega_n_hat", "rad/s"),
                ("fdi_zeta_hat", "-"), ("fdi_threshold", "rad")]
#: the tower plant's, after every other common output
_TOWER_OUTPUTS = [("tower_x", "m"), ("tower_v", "m/s"), ("thrust", "N"), ("M_tower", "N m"),
                  ("ct", "-")]
#: the FDI function's outputs reported per blade, in _FDI_OUTPUTS' order
FDI_REPORTED = tuple(n.removeprefix("fdi_") for n, _ in _FDI_OUTPUTS)


def _per_blade(spec: list[tuple[str, str]]) -> list[tuple[str, str]]:
    return [(f"{n}_{j}", u) for n, u in spec for j in lay.blades()]


def common_outputs(fdi: bool = True, plant: str = "nrel5mw") -> list[tuple[str, str]]:
    """The per-step outputs every loop on ``plant`` reports, in column order, with units."""
    out = (_PLANT_OUTPUTS + _per_blade(_BLADE_OUTPUTS) + _LOOP_OUTPUTS
           + _per_blade(_COMMAND_OUTPUTS) + _AERO_OUTPUTS
           + [(f"sensor_{s['name']}", s["unit"]) for s in lay.layout()["sensors"]])
    if fdi:
        out += (_per_blade(_FDI_OUTPUTS)
                + [(f"fdi_excluded_{s['name']}", "-") for s in lay.layout()["sensors"]])
    return out + (_TOWER_OUTPUTS if PLANTS[plant].get("tower") else [])


def controllers() -> dict:
    """The registered controllers (derivation/controllers.py, via generated/layout.json)."""
    return lay.layout()["controllers"]


def output_spec(controller: str, fdi: bool = True,
                plant: str = "nrel5mw") -> list[tuple[str, str]]:
    return list(_output_spec(controller, fdi, plant))


@cache
def _output_spec(controller: str, fdi: bool, plant: str) -> tuple[tuple[str, str], ...]:
    """(looked up several times a run, from the layout, which is read once: built once)"""
    reg = controllers()[controller]
    return tuple(common_outputs(fdi, plant) + list(zip(reg["diag"], reg["diag_units"],
                                                       strict=True)))


def state_names(plant: str, controller: str = "paper") -> list[str]:
    return (lay.names(PLANTS[plant]["states"]) + lay.names(controllers()[controller]["states"])
            + lay.names("fdi_states"))


@dataclass(frozen=True)
class Loop:
    """What one compiled closed loop is built for, resolved once (wtftc.config) and handed
    down: every run of a batch shares it. Hashable: the compiled functions are cached by it
    (the Cp table by its key, the turbine parameters by value).

    ``interval``: 0, the controller and the FDI in continuous time inside the RK4 step (the
    paper's loop); n > 0, sampled every n plant steps (zero-order hold, wtftc.sim.sampled);
    ``delay``: the command of a sample applied one interval later; ``cut_in_wind``: the
    turbine's cut-in wind [m/s] (its file's ``cut_in_wind_mps``; 0: not known), which only
    sets where a run may start (wtftc.sim.trim.operating_point), not what is compiled.
    """

    plant: str
    controller: str
    table: CpTable = field(compare=False, repr=False)
    table_key: str = "nrel5mw"
    p_turbine: tuple = ()
    fdi: bool = True
    interval: int = 0
    delay: bool = False
    cut_in_wind: float = field(default=0.0, compare=False)

    @classmethod
    def default(cls, plant: str = "nrel5mw", controller: str = "paper", fdi: bool = True,
                p_turbine=None, interval: int = 0, delay: bool = False) -> Loop:
        """The loop on the packaged NREL 5-MW Cp table and the layout's turbine."""
        pt = lay.vector("turbine_params") if p_turbine is None else p_turbine
        return cls(plant, controller, nrel5mw_cp_table(), "nrel5mw",
                   tuple(float(x) for x in pt), fdi, interval, delay)

    def with_controller(self, controller: str, fdi: bool | None = None) -> Loop:
        return replace(self, controller=controller, fdi=self.fdi if fdi is None else fdi)

    @property
    def sampled(self) -> bool:
        return self.interval > 0

    @property
    def label(self) -> str:
        timing = f"_s{self.interval}{'d' if self.delay else ''}" if self.sampled else ""
        return (f"{self.plant}_{self.controller}{'' if self.fdi else '_nofdi'}{timing}_"
                f"{self.table_key}")

    @property
    def n_states(self) -> tuple[int, int, int]:
        """(plant, controller, FDI) state counts."""
        return (lay.size(PLANTS[self.plant]["states"]),
                lay.size(controllers()[self.controller]["states"]),
                lay.size("fdi_states") if self.fdi else 0)

    def state_names(self) -> list[str]:
        """The loop's state, in order: plant, controller, FDI; sampled: then the sensors'
        lag states and (with ``delay``) the command held for the next interval."""
        return list(_loop_state_names(self))

    def _state_names(self) -> list[str]:
        n_f = self.n_states[2]
        out = state_names(self.plant, self.controller)
        out = out[:len(out) - lay.size("fdi_states") + n_f]
        if self.sampled:
            out += [f"sensor_lag_{n}" for n in sensor_names()]
            out += [f"v_held_{j}" for j in lay.blades()] if self.delay else []
        return out


@cache
def _loop_state_names(loop: Loop) -> tuple[str, ...]:
    """(looked up several times a run: built once a loop)"""
    return tuple(loop._state_names())


def sensor_names() -> list[str]:
    """The sensors, two per measured quantity (derivation/sensors.py)."""
    return [e["name"] for e in lay.layout()["sensors"]]


def controller_block(loop: Loop, xc, xf, readings, sym: dict, v_applied=None) -> dict:
    """The FDI, the virtual sensors and the controller on the sensors' ``readings``: the
    command, the controller's and the FDI's state derivatives, the measurements the
    controller saw (``m``) and the reported outputs. The FDI's model is driven by
    ``v_applied`` (a sampled loop: the command held on the actuators), by default the
    controller's command."""
    reg = controllers()[loop.controller]
    n_s = len(sensor_names())
    if loop.fdi:
        # the FDI's outputs depend on its states only (no algebraic loop): the sensors it
        # excludes, the fault it tells the accommodation
        p_fdi = sym["p_fdi"]
        fdi = load("fdi", "interpreted")
        fd0 = fdi(x_fdi=xf, v=ca.DM.zeros(lay.n_blades()), readings=readings,
                  meas=ca.DM.zeros(len(lay.layout()["measurements"])), p_fdi=p_fdi)
        known = (1 - sym["use_fdi"]) * sym["ctrl_fault"] + sym["use_fdi"] * fd0["known_fault"]
        excluded = sym["use_fdi"] * fd0["excluded"]
    else:
        known, excluded = sym["ctrl_fault"], ca.DM.zeros(n_s)
    known = _lock_within_table(loop, known)
    m = virtual(loop, readings, excluded, sym)
    c = load(reg["function"], "interpreted")(
        x_ctrl=xc, meas=m["meas"], yd=sym["yd"], sched=m["sched"], p_ctrl=sym["p_ctrl"],
        known_fault=known)
    out = {"v": c["v"], "u0": c["u0"], "diag": c["diag"], "x_ctrl_dot": c["x_ctrl_dot"],
           "m": m}
    if loop.fdi:
        fd = fdi(x_fdi=xf, v=c["v"] if v_applied is None else v_applied, readings=readings,
                 meas=m["meas"], p_fdi=p_fdi)
        out["x_fdi_dot"] = fd["x_fdi_dot"]
        out["fdi"] = [fd0[k] for k in FDI_REPORTED] + [fd0["excluded"]]
    return out


def _lock_within_table(loop: Loop, known):
    """The fault told to eq (49)'s accommodation, a locked blade's angle ū_j taken no
    farther than the Cp table's last pitch (ours; issue 18). The accommodation's
    v = (3U − Σ σ̂ ū)/Σ(1 − σ̂)ρ̂ is the mean-pitch model's inverse, linear in ū: told of a
    blade at 90° (a runaway to feather) it put the healthy blades 37° finer than U, and
    on a rotor whose blades each give their share at their own pitch (the tower plant,
    a real rotor) the peak at 24 m/s reached 1.32 × rated told the truth (case 3, default
    gains; 1.46 × in a tuned DLC 2.1 scenario) where the unaware controller held 1.04.
    Beyond the table's last pitch the controllers' model knows nothing of the blade's
    torque, and the per-blade plant reads it there (docs/loads.md). On the mean-pitch
    plants eq (49) with the true ū was the plant's exact inverse; for ū beyond the table
    (only a lock or runaway past 30°) the bound departs from it."""
    top = float(np.max(loop.table.pitch_rad))
    return ca.vertcat(*[ca.fmin(known[k], top) if n.startswith("ubar_") else known[k]
                        for k, n in enumerate(lay.names("fault_inputs"))])


def plant_block(loop: Loop, xp, v, sym: dict) -> dict:
    """The plant driven by the commands v: its state derivative and its true outputs. The
    tables are read at the rotor's (λ, β̄), or on a ``per_blade`` plant (the tower's) as
    the mean of each blade's (λ, β_j) (:func:`_rotor_table`); on the tower plant in the
    wind relative to the tower top (generated ``rotor_inflow``)."""
    spec = PLANTS[loop.plant]
    pf = load(spec["function"], "interpreted")
    pt, wind = sym["p_turbine"], sym["wind"]
    x_aero = xp[lay.prefix("plant_states", of=spec["states"])]
    if spec.get("edge"):  # the blades' speed includes their edgewise motion
        inflow = load("edge_inflow", "interpreted")(x_plant=xp, wind=wind, p_turbine=pt)
        w_rotor = inflow["wind_rel"]
        x_aero = ca.vertcat(inflow["omega_aero"], x_aero[1:])
    elif spec.get("tower"):
        w_rotor = load("rotor_inflow", "interpreted")(x_plant=xp, wind=wind)["wind_rel"]
    else:
        w_rotor = wind
    op = load("aero_operating_point", "interpreted")(x_plant=x_aero, wind=w_rotor,
                                                      p_turbine=pt)
    # the plant's Cp: the table's, scaled by the model mismatch (1: none)
    cp = sym["cp_scale"] * _rotor_table(loop, xp, op)
    args = {"x_plant": xp, "v": v, "wind": wind, "cp": cp,
            "actuator_faults": sym["actuator_faults"], "p_turbine": pt}
    out = {"tsr": op["tsr"], "cp": cp}
    if spec.get("tower"):
        args["ct"] = out["ct"] = _rotor_table(loop, xp, op, "ct")
    p = pf(**args)
    out |= {k: p[k] for k in ("x_plant_dot", "T_aero", "T_gen", "P_gen")}
    if spec.get("tower"):
        out["tower"] = [xp[lay.index(spec["states"], "tower_x")],
                        xp[lay.index(spec["states"], "tower_v")], p["thrust"], p["M_tower"],
                        out["ct"]]
    return out


def _rotor_table(loop: Loop, xp, op: dict, quantity: str = "cp") -> ca.SX:
    """The rotor's Cp (or Ct): the table at (λ, β̄), or on a ``per_blade`` plant the mean
    of the table at each blade's (λ, β_j): each blade carries a third of the rotor's
    torque and thrust at its own pitch (ours; docs/loads.md, "Per-blade aerodynamics").
    Equal when the blades are: fault-free, the same to rounding. A feathered blade is read
    at the table's largest pitch (the grid clips it: 30° on the NREL 5-MW's)."""
    fn = _cp_function(loop, quantity)
    spec = PLANTS[loop.plant]
    if not spec.get("per_blade"):
        return fn(op["tsr"], op["beta_mean"])
    betas = xp[lay.block(spec["states"], "beta")]
    return sum(fn(op["tsr"], betas[j]) for j in range(lay.n_blades())) / lay.n_blades()


@cache
def _cp_function(loop: Loop, quantity: str = "cp") -> ca.Function:
    """The Cp (or Ct) interpolant of the loop's table (built once per loop)."""
    return cp_loop_function(loop.table, quantity)


def output_row(loop: Loop, xp, readings, ctl: dict, pl: dict, sym: dict) -> ca.SX:
    """The reported outputs, in output_spec's order: ``ctl["m"]`` the measurements the
    controller saw (the virtual sensors), ``readings`` every sensor's."""
    states, m = PLANTS[loop.plant]["states"], ctl["m"]
    out = [xp[lay.index(states, "omega_r")], xp[lay.index(states, "theta_s")],
           m["meas"][measurement_index("omega_g_hss")],
           m["meas"][measurement_index("omega_r")], xp[lay.block(states, "beta")],
           m["sensors"], ctl["u0"], ctl["v"], sym["wind"], pl["tsr"], pl["cp"], pl["T_aero"],
           pl["T_gen"], pl["P_gen"], m["sched"][0], sym["yd"][lay.index("reference", "yd_0")],
           readings]
    return ca.vertcat(*out, *ctl.get("fdi", []), *pl.get("tower", []), ctl["diag"])


def _closed_loop_rhs(loop: Loop) -> ca.Function:
    """ż = f(z, wind, faults, reference, parameters): z = [plant states, controller states,
    FDI states] (the continuous loop, ``loop.interval = 0``).

    The controller sees only the measurements [ω_r, ω_g, β_meas,j]: the sensors
    (derivation/sensors.py: faults, bias, resolution; no noise or lag in continuous time)
    voted by the virtual sensors, and the pitch-scheduled sensitivity; the plant state
    never enters it.
    ``loop.fdi = False`` leaves the FDI out (no FDI states, no ``use_fdi`` input, no fdi_*
    outputs): the loop of cases 1-3 without the monitor, as the benchmark runs it.
    """
    n_p, n_c, n_f = loop.n_states
    sym = loop_symbols(loop, n_p + n_c + n_f)
    z = sym["z"]
    xp, xc, xf = z[:n_p], z[n_p:n_p + n_c], z[n_p + n_c:]
    true = true_signals(loop, xp, sym["p_turbine"])
    readings = measure(true, true, ca.DM.zeros(true.numel()), sym)
    sym["tower_fa_acc"] = tower_acceleration(loop, xp, sym)
    ctl = controller_block(loop, xc, xf, readings, sym)
    pl = plant_block(loop, xp, ctl["v"], sym)
    names = ["z", "wind", *_INPUT_GROUPS, "p_ctrl", "cp_scale"] + (
        ["use_fdi", "p_fdi"] if loop.fdi else [])
    zdot = ca.vertcat(pl["x_plant_dot"], ctl["x_ctrl_dot"], *([ctl["x_fdi_dot"]] if loop.fdi
                                                              else []))
    out = output_row(loop, xp, readings, ctl, pl, sym)
    assert out.numel() == len(output_spec(loop.controller, loop.fdi, loop.plant))
    # one pass of common-subexpression elimination over the assembled loop: the plant, the
    # controller and the FDI share the measured quantities and the aerodynamics
    zdot, out = ca.cse([zdot, out])
    return ca.Function("rhs", [sym[n] for n in names], [zdot, out], names, ["z_dot", "out"])


def loop_symbols(loop: Loop, n_z: int) -> dict[str, ca.SX]:
    """The symbolic inputs of a loop's functions, by name."""
    reg = controllers()[loop.controller]
    return {"z": ca.SX.sym("z", n_z), "wind": ca.SX.sym("wind"),
            **{n: ca.SX.sym(n, lay.size(g)) for n, g in _INPUT_GROUPS.items()},
            "p_ctrl": ca.SX.sym("p_ctrl", lay.size(reg["params"])),
            # the plant's Cp relative to the table's (model mismatch; 1: none)
            "cp_scale": ca.SX.sym("cp_scale"),
            # 1: the accommodation is fed by the FDI, 0: by ctrl_fault
            "use_fdi": ca.SX.sym("use_fdi"),
            # the FDI's parameters, per run (its thresholds follow the run's sensors)
            "p_fdi": ca.SX.sym("p_fdi", lay.size("fdi_params"))}


#: the loop's inputs that are layout groups, in input order after z and wind
_INPUT_GROUPS = {"actuator_faults": "actuator_faults", "sensor_faults": "sensor_faults",
                 "ctrl_fault": "fault_inputs", "yd": "reference",
                 "p_turbine": "turbine_params", "p_sensors": "sensor_params"}


def fdi_params(loop: Loop) -> np.ndarray:
    """The FDI's parameters for exact sensors, its actuator model the run's turbine's
    nominal one (ω_n, ζ): the FDI is designed for the turbine it watches (its defaults are
    the NREL 5-MW's), with the controller's own settings (derivation/controllers.py,
    ``fdi``). Its noise threshold is set per run (wtftc.sim.fdi)."""
    p = lay.vector("fdi_params", tuning.turbine_params_of("fdi_params", loop.p_turbine))
    tp = lay.values("turbine_params", loop.p_turbine)
    p[lay.index("fdi_params", "fdi_omega_n")] = tp["omega_n_nominal"]
    p[lay.index("fdi_params", "fdi_zeta")] = tp["zeta_nominal"]
    p[lay.index("fdi_params", "fdi_gearbox_ratio")] = tp["gearbox_ratio"]
    # what the controller's design takes in place of the FDI's defaults (the registry's)
    for name, value in controllers()[loop.controller].get("fdi", {}).items():
        p[lay.index("fdi_params", name)] = value
    return p


def true_signals(loop: Loop, xp: ca.SX, pt: ca.SX) -> ca.SX:
    """What each sensor measures, exactly, in the sensors' order: ω_r, ω_g on the HSS,
    β_j."""
    states = PLANTS[loop.plant]["states"]
    values = {"omega_r": xp[lay.index(states, "omega_r")],
              "omega_g_hss": xp[lay.index(states, "omega_g")]
              * pt[lay.index("turbine_params", "gearbox_ratio")],
              **{f"beta_meas_{j}": xp[lay.index(states, f"beta_{j}")] for j in lay.blades()}}
    return ca.vertcat(*[values[s["measures"]] for s in lay.layout()["sensors"]])


def measure(true: ca.SX, x_lag: ca.SX, noise: ca.SX, sym: dict) -> ca.SX:
    """Every sensor's reading (generated ``sensors``: lag, fault, bias, noise,
    resolution)."""
    return load("sensors", "interpreted")(
        true_signals=true, x_lag=x_lag, noise=noise, sensor_faults=sym["sensor_faults"],
        p_sensors=sym["p_sensors"])["meas"]


def virtual(loop: Loop, readings: ca.SX, excluded: ca.SX, sym: dict) -> dict:
    """What the controller sees: the sensors voted, those the FDI excluded left out
    (generated ``virtual_sensors``, derivation/sensors.py; with exact sensors the rotor
    speed sensor alone and every pitch sensor's reading, bit for bit), the measured
    pitches, and the ∂T_aero/∂β schedule at the measured mean pitch (the controllers'
    model: the nominal turbine and table, whatever the plant). ``sym`` may give the
    gearbox ratio (``gearbox_ratio``) and the schedule (``sched_fn``: mean pitch →
    ∂T/∂β) as runtime values, as an exported library does (wtftc/export/discon.py)."""
    gear = sym.get("gearbox_ratio", loop.p_turbine[lay.index("turbine_params",
                                                              "gearbox_ratio")])
    meas = load("virtual_sensors", "interpreted")(
        readings=readings, excluded=excluded, p_sensors=sym["p_sensors"],
        gearbox_ratio=gear)["meas"]
    sensors = ca.vertcat(*[meas[measurement_index(f"beta_meas_{j}")] for j in lay.blades()])
    sched_fn = sym.get("sched_fn") or sched_loop_function(loop.table,
                                                          np.array(loop.p_turbine))
    return {"meas": meas, "sensors": sensors,
            "sched": ca.vertcat(sched_fn(ca.sum1(sensors) / lay.n_blades()),
                                sym["tower_fa_acc"])}


def tower_acceleration(loop: Loop, xp, sym: dict) -> ca.SX:
    """The tower-top fore-aft acceleration the tower damper reads (derivation/design.py,
    ``tower_fa_acc``): the plant's, exactly (an ideal accelerometer, as OpenFAST's
    avrSWAP #53), in ``sym["wind"]``; 0 on a plant without a tower. The blades' commands
    drive only the actuators' states, so the acceleration is the same whatever they are."""
    spec = PLANTS[loop.plant]
    if not spec.get("tower"):
        return ca.DM(0.0)
    rates = plant_block(loop, xp, ca.DM.zeros(lay.n_blades()), sym)["x_plant_dot"]
    return rates[lay.index(spec["states"], "tower_v")]


def measurement_index(name: str) -> int:
    """Where ``name`` sits in the controllers' measurement vector (generated/layout.json)."""
    names = [e["name"] for e in lay.layout()["measurements"]]
    if name not in names:
        raise KeyError(f"{name!r} is not a measurement; allowed: {', '.join(names)}")
    return names.index(name)


@cache
def rhs_function(loop: Loop) -> ca.Function:
    """The closed-loop right-hand side of ``loop`` (built once per loop), its divisions by
    what a step holds constant computed as multiplications by shared reciprocals
    (wtftc.sim.reciprocals)."""
    return with_shared_reciprocals(_closed_loop_rhs(loop), ("z", "wind"))
