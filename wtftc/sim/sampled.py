"""The sampled loop: the controller and the FDI as a discrete-time system (ours).

Every control interval T = n·dt (``Loop.interval`` = n plant steps):

1. **Sample**: the sensors (derivation/sensors.py: lag, fault, bias, noise, resolution)
   read the plant at the interval's start; one standard-normal draw per signal, held
   over the interval, comes in as ``noise``.
2. **Command**: the controller computes v_k from its state and the samples; it is held
   over the interval (zero-order hold), or, with ``delay``, over the next one (v_{k-1}
   is applied now).
3. **Controller and FDI states**: advanced from t_k to t_k + T by one classical RK4 step
   of their own equations with the samples held (the measurements are a zero-order hold,
   as a DISCON call sees them). The error against the continuous loop is O(T): the
   measurements are held, not interpolated (tests/test_sampled.py measures it).
4. **Plant**: n RK4 steps of dt with the command held; the sensors' lag states advance
   with it (they are the sensors' physics, in continuous time).

Outputs are reported every plant step: the plant's true quantities at that step, the
controller's (measurements, command, FDI, diagnostics) as held from the last sample.
"""

from __future__ import annotations

from functools import cache

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.sim.reciprocals import with_shared_reciprocals
from wtftc.sim.rhs import (
    FDI_REPORTED,
    PLANTS,
    Loop,
    controller_block,
    loop_symbols,
    measure,
    measurement_index,
    output_row,
    plant_block,
    sensor_names,
    tower_acceleration,
    true_signals,
)

#: a blade whose command is within this of its lower stop rests there [rad] (0.1°)
REST_MARGIN = 0.0017453292519943296

#: the inputs of a sampled interval held per interval (one column), and per plant step
PER_INTERVAL = ("sensor_faults", "ctrl_fault", "noise", "test_pulse")
PER_STEP = ("wind3", "actuator_faults")


def _sizes(loop: Loop) -> dict[str, int]:
    n_p, n_c, n_f = loop.n_states
    n_s, n_b = len(sensor_names()), lay.n_blades()
    return {"p": n_p, "c": n_c, "f": n_f, "s": n_s, "b": n_b,
            "m": len(lay.layout()["measurements"]),
            "z": n_p + n_c + n_f + n_s + (n_b if loop.delay else 0)}


def _held_size(loop: Loop) -> int:
    n = _sizes(loop)
    fdi = len(FDI_REPORTED) * n["b"] + n["s"] if loop.fdi else 0
    return n["s"] + n["m"] + 1 + n["b"] + 1 + fdi + 4


def _unpack_held(loop: Loop, held: ca.SX) -> tuple[ca.SX, dict]:
    """The sensors' readings and the controller's outputs from the held vector (_sample's
    layout: readings, the virtual sensors' measurements, u0, v, sched, fdi outputs,
    diag)."""
    n = _sizes(loop)
    k = 0

    def take(size):
        nonlocal k
        k += size
        return held[k - size:k]

    readings, meas, u0, v, sched = take(n["s"]), take(n["m"]), take(1), take(n["b"]), take(1)
    fdi = [take(n["b"]) for _ in FDI_REPORTED] + [take(n["s"])] if loop.fdi else []
    diag = take(4)
    sensors = ca.vertcat(*[meas[measurement_index(f"beta_meas_{j}")] for j in lay.blades()])
    return readings, {"u0": u0, "v": v, "fdi": fdi, "diag": diag,
                      "m": {"meas": meas, "sensors": sensors, "sched": sched}}


def _sample(loop: Loop) -> ca.Function:
    """The sample at t_k: the command, the controller and FDI states at t_k + T, and the
    held outputs."""
    n = _sizes(loop)
    sym = loop_symbols(loop, n["z"])
    z, noise, T = sym["z"], ca.SX.sym("noise", n["s"]), ca.SX.sym("T")
    pulse = ca.SX.sym("test_pulse")  # [rad], this interval's test movement (0: none)
    xp = z[:n["p"]]
    o = n["p"] + n["c"] + n["f"]
    true = true_signals(loop, xp, sym["p_turbine"])
    readings = measure(true, z[o:o + n["s"]], noise, sym)
    # the tower damper's acceleration, sampled with the sensors, in the wind at t_k
    sym["tower_fa_acc"] = tower_acceleration(loop, xp, sym)

    xc, xf = z[n["p"]:n["p"] + n["c"]], z[n["p"] + n["c"]:o]
    ctl = controller_block(loop, xc, xf, readings, sym)
    m = ctl["m"]
    # a blade resting at its lower stop gets the test movement (docs/fdi.md, faults at
    # rest); the FDI's model follows the command the actuators get over the interval
    rest = loop.p_turbine[lay.index("turbine_params", "pitch_min")] + REST_MARGIN
    v_now = ctl["v"] + pulse * (ctl["v"] <= rest)
    v_applied = z[o + n["s"]:] if loop.delay else v_now
    xc_next = _rk4(lambda x: controller_block(loop, x, xf, readings, sym)["x_ctrl_dot"], xc,
                   T)
    held = ca.vertcat(readings, m["meas"], ctl["u0"], ctl["v"], m["sched"][0],
                      *ctl.get("fdi", []), ctl["diag"])
    assert held.numel() == _held_size(loop)
    names = ["z", "noise", "sensor_faults", "ctrl_fault", "yd", "p_turbine", "p_sensors",
             "p_ctrl", *(["use_fdi", "p_fdi"] if loop.fdi else []), "test_pulse", "T",
             "wind", "cp_scale"]
    args = {**sym, "noise": noise, "T": T, "test_pulse": pulse}
    xc_next, held = ca.cse([xc_next, held])
    # the command the actuators hold over the interval (and the FDI's model with them),
    # the one held for the next (with the delay), the sampled readings and measurements
    return with_shared_reciprocals(ca.Function(
        "sample", [args[k] for k in names], [xc_next, held, v_applied, v_now, readings,
                                             m["meas"]], names,
        ["xc_next", "held", "v_applied", "v_now", "readings", "meas"]), ("z", "noise"))


def _rk4(f, x, h):
    """One classical RK4 step of h of ẋ = f(x)."""
    k1 = f(x)
    k2 = f(x + h / 2 * k1)
    k3 = f(x + h / 2 * k2)
    k4 = f(x + h * k3)
    return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def _fdi_step(loop: Loop) -> ca.Function:
    """One RK4 step of h of the FDI, its command and its sample held. Its actuator model
    runs the actuators' own law, so the FDI takes the plant's steps (``loop.interval``
    steps of dt per interval, a mapaccum in the interval): one step of T missed the rate
    limit's corners by up to 2.7° under the paper design's chattering command, and the FDI
    alarmed on every blade. The held sample against the moving model adds a residual of
    the pitch rate × (t − t_k), which the threshold allows for (fdi_T_s)."""
    n = _sizes(loop)
    sym = loop_symbols(loop, 0)
    x, v, rd, meas, h = (ca.SX.sym("x_fdi", n["f"]), ca.SX.sym("v", n["b"]),
                         ca.SX.sym("readings", n["s"]), ca.SX.sym("meas", n["m"]),
                         ca.SX.sym("h"))
    fdi = load("fdi", "interpreted")

    def rate(y):
        return fdi(x_fdi=y, v=v, readings=rd, meas=meas, p_fdi=sym["p_fdi"])["x_fdi_dot"]

    names = ["x_fdi", "v", "readings", "meas", "p_fdi", "h"]
    args = {"x_fdi": x, "v": v, "readings": rd, "meas": meas, "h": h, **sym}
    return with_shared_reciprocals(ca.Function(
        "fdi_step", [args[k] for k in names], [_rk4(rate, x, h)], names, ["x_fdi_next"]),
        ("x_fdi", "v", "readings", "meas"))


def _plant_step(loop: Loop) -> ca.Function:
    """One RK4 step of dt of the plant and the sensors' lags, the command held; the
    outputs at the step's start."""
    n = _sizes(loop)
    sym = loop_symbols(loop, n["p"] + n["s"])
    x, w3, v, held, dt = (sym["z"], ca.SX.sym("wind3", 3), ca.SX.sym("v", n["b"]),
                          ca.SX.sym("held", _held_size(loop)), ca.SX.sym("dt"))
    lag = load("sensors", "interpreted")

    def f(xx, wind):
        s = {**sym, "wind": wind}
        pl = plant_block(loop, xx[:n["p"]], v, s)
        true = true_signals(loop, xx[:n["p"]], sym["p_turbine"])
        dl = lag(true_signals=true, x_lag=xx[n["p"]:], noise=ca.DM.zeros(n["s"]),
                 sensor_faults=sym["sensor_faults"], p_sensors=sym["p_sensors"])["x_lag_dot"]
        return ca.vertcat(pl["x_plant_dot"], dl), pl

    k1, pl = f(x, w3[0])
    k2 = f(x + dt / 2 * k1, w3[1])[0]
    k3 = f(x + dt / 2 * k2, w3[1])[0]
    k4 = f(x + dt * k3, w3[2])[0]
    x_next = x + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    readings, ctl = _unpack_held(loop, held)
    out = output_row(loop, x[:n["p"]], readings, ctl, pl, {**sym, "wind": w3[0]})
    x_next, out = ca.cse([x_next, out])
    names = ["x", "wind3", "actuator_faults", "p_turbine", "cp_scale", "sensor_faults",
             "p_sensors", "yd", "v", "held", "dt"]
    args = {**sym, "x": x, "wind3": w3, "v": v, "held": held, "dt": dt}
    return with_shared_reciprocals(ca.Function(
        "plant_step", [args[k] for k in names], [x_next, out], names, ["x_next", "out"]),
        ("x", "wind3"))


@cache
def interval_function(loop: Loop) -> ca.Function:
    """One control interval of ``loop`` (``loop.interval`` plant steps): z_next, the outputs
    of every plant step (n_out × n), and the state after every plant step (n_z × n: the
    controller's as sampled until the last column, which is z_next)."""
    n, steps = _sizes(loop), loop.interval
    sample, plant = _sample(loop), _plant_step(loop).mapaccum("plant_steps", steps)
    ins = {k: ca.MX.sym(k, sample.sparsity_in(k)) for k in sample.name_in()
           if k not in ("T", "wind")}
    ins |= {"wind3": ca.MX.sym("wind3", 3, steps),
            "actuator_faults": ca.MX.sym("actuator_faults", lay.size("actuator_faults"), steps),
            "cp_scale": ca.MX.sym("cp_scale"), "dt": ca.MX.sym("dt")}
    z = ins["z"]
    s = sample.call({**{k: ins[k] for k in sample.name_in() if k not in ("T", "wind")},
                     "T": steps * ins["dt"], "wind": ins["wind3"][0, 0]})
    o = n["p"] + n["c"] + n["f"]
    xps0 = ca.vertcat(z[:n["p"]], z[o:o + n["s"]])
    v_apply, v_new = s["v_applied"], s["v_now"]

    def rep(x):
        return ca.repmat(x, 1, steps)

    p = plant.call({"x": xps0, "wind3": ins["wind3"], "actuator_faults": ins["actuator_faults"],
                    **{k: rep(ins[k]) for k in ("p_turbine", "cp_scale", "sensor_faults",
                                                "p_sensors", "yd", "dt")},
                    "v": rep(v_apply), "held": rep(s["held"])})
    xs = p["x_next"]
    xc = z[n["p"]:n["p"] + n["c"]]
    ctrl_cols = [ca.horzcat(ca.repmat(xc, 1, steps - 1), s["xc_next"])]
    if loop.fdi:
        xf = z[n["p"] + n["c"]:o]
        ctrl_cols.append(_fdi_step(loop).mapaccum("fdi_steps", steps).call(
            {"x_fdi": xf, "v": rep(s["v_applied"]), "readings": rep(s["readings"]),
             "meas": rep(s["meas"]),
             "p_fdi": rep(ins["p_fdi"]), "h": rep(ins["dt"])})["x_fdi_next"])
    ctrl_cols = ca.vertcat(*ctrl_cols)
    held_v = [ca.repmat(v_new, 1, steps)] if loop.delay else []
    z_steps = ca.vertcat(xs[:n["p"], :], ctrl_cols, xs[n["p"]:, :], *held_v)
    z_next = z_steps[:, steps - 1]
    names = ["z", *PER_STEP, *[k for k in ins if k not in ("z", *PER_STEP)]]
    return ca.Function("interval", [ins[k] for k in names], [z_next, p["out"], z_steps],
                       names, ["z_next", "out", "z_steps"])


def sampled_state(loop: Loop, z0) -> np.ndarray:
    """A trimmed state (wtftc.sim.trim: plant, controller, FDI) extended to ``loop``'s: a
    sampled loop's sensor lags start at the true signals (in balance) and its held command
    at the blades' pitch. A continuous loop's is returned as it is."""
    z0 = np.asarray(z0, dtype=float)
    if not loop.sampled:
        return z0
    n = _sizes(loop)
    xp = z0[:n["p"]]
    states = PLANTS[loop.plant]["states"]
    gear = loop.p_turbine[lay.index("turbine_params", "gearbox_ratio")]
    true = {"omega_r": xp[lay.index(states, "omega_r")],
            "omega_g_hss": xp[lay.index(states, "omega_g")] * gear,
            **{f"beta_meas_{j}": xp[lay.index(states, f"beta_{j}")] for j in lay.blades()}}
    held = xp[lay.block(states, "beta")] if loop.delay else []
    lags = [true[s["measures"]] for s in lay.layout()["sensors"]]
    return np.concatenate([z0[:n["p"] + n["c"] + n["f"]], lags, held])
