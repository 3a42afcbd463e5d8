"""Loops specialised to the switches their runs share (issue 35).

Options such as issue 34's speed observer, peak shaving and tower damper, the generator's
torque law or the FDI's feed are parameters that switch a part of the loop on or off: a
``Piecewise`` on them computes both branches at every call, and an option off still costs
its operations (the physical AFTC's RK4 step: 3,380 SX instructions with every option
symbolic, 1,710 with the options of the bench's run folded in). A chunk specialised to the
switches its batch's runs share (:func:`shared_switches`) is built with those values as
constants: CasADi folds each switched-off branch away when it builds the graph. The inputs
stay the same (the switches are passed and not read), so nothing else changes.

The numbers are the general chunk's given those values, bit for bit, wherever they are
finite: a folded branch is the same operations on the same values, and the one identity
CasADi applies that IEEE arithmetic does not, 0·x = 0, differs only for an infinite or
NaN x, where a run has already diverged (tests/test_specialise.py).
"""

from __future__ import annotations

import hashlib

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.sim.rhs import Loop, controllers

#: controller parameters (by the end of their names) that switch a part of the design on
#: or off: derivation/physical.py, design.py, pi_baseline.py
CONTROLLER_SWITCHES = ("_obs_omega", "_obs_omega_max", "_ps_pitch", "_td_gain", "_td_lpf",
                       "_actuator_model", "_lpf_corner")
#: turbine parameters that switch the generator's torque law (derivation/turbine.py)
TURBINE_SWITCHES = ("gen_torque_law", "gen_constant_power", "vs_constant_torque")

#: one switch folded into a chunk: (the step's input, the entry, its value)
Switch = tuple[str, int, float]


def switch_entries(loop: Loop) -> dict[str, dict[int, float]]:
    """The switches of ``loop``'s step, by input, with their defaults (off): the entries
    of p_ctrl and p_turbine, and use_fdi (an FDI loop's)."""
    group = controllers()[loop.controller]["params"]
    ctrl, ctrl_default = lay.names(group), lay.defaults(group)
    turbine, turbine_default = lay.names("turbine_params"), lay.defaults("turbine_params")
    out = {"p_ctrl": {i: float(ctrl_default[i]) for i, n in enumerate(ctrl)
                      if n.endswith(CONTROLLER_SWITCHES)},
           "p_turbine": {turbine.index(n): float(turbine_default[turbine.index(n)])
                         for n in TURBINE_SWITCHES}}
    if loop.fdi:
        out["use_fdi"] = {0: 0.0}
    return out


def shared_switches(loop: Loop, values: dict[str, list[np.ndarray]]) -> tuple[Switch, ...]:
    """The switches a chunk for these runs is specialised to (``values``: each input's
    value per run), sorted: the torque law's and use_fdi, where every run gives them
    alike (two values each in practice: 0 or 1); the controller's options only all
    together, where every run leaves them all off (their defaults). A batch with an
    option on keeps every option an input, so one compiled chunk serves all the option
    sets and values of a loop: specialised per set, the test suite's runs had made 38
    more chunks from an empty cache (129 against 91)."""
    shared = []
    for name, entries in switch_entries(loop).items():
        if any(v is None for v in values[name]):
            continue
        rows = np.array([np.atleast_1d(np.asarray(v, dtype=float)) for v in values[name]])
        if name == "p_ctrl":
            if all(np.all(rows[:, i] == d) for i, d in entries.items()):
                shared += [(name, i, d) for i, d in entries.items()]
            continue
        for i in entries:
            column = rows[:, i]
            if np.isfinite(column[0]) and np.all(column == column[0]):
                shared.append((name, i, float(column[0])))
    return tuple(sorted(shared))


def tag(switches: tuple[Switch, ...]) -> str:
    """The part of a chunk's label naming its switches ('' for none)."""
    if not switches:
        return ""
    text = ";".join(f"{n}[{i}]={v!r}" for n, i, v in switches)
    return "_sw" + hashlib.sha256(text.encode()).hexdigest()[:10]


def by_input(switches: tuple[Switch, ...]) -> dict[str, dict[int, float]]:
    """The switches as {input: {entry: value}}."""
    out: dict[str, dict[int, float]] = {}
    for name, i, v in switches:
        out.setdefault(name, {})[i] = v
    return out


def folded(f: ca.Function, fixed: dict, name: str | None = None) -> ca.Function:
    """The SX function ``f`` with the values of ``fixed`` ({input: {entry: value}} or
    {input: whole value}) as constants: the same inputs, those values passed and not
    read."""
    if not fixed:
        return f if name is None else ca.Function(name, f.sx_in(), f.call(f.sx_in()),
                                                  f.name_in(), f.name_out())
    ins = f.sx_in()
    values = [given(x, fixed.get(n)) for n, x in zip(f.name_in(), ins, strict=True)]
    return ca.Function(name or f.name(), ins, f.call(values), f.name_in(), f.name_out())


def given(x: ca.SX, value) -> ca.SX:
    """The input x given ``value``: None (x itself), {entry: value} (those entries) or the
    whole value."""
    if value is None:
        return x
    if not isinstance(value, dict):
        return ca.SX(ca.DM(value))
    return ca.vertcat(*[ca.SX(value[i]) if i in value else x[i] for i in range(x.numel())])
