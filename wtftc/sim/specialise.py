"""Loops specialised to the switches their runs share (issue 35).

Issue 34's options (the speed observer and its schedule, peak shaving, the tower damper
and its low-pass, the actuator model; the PI's filter and peak shaving) are controller
parameters that switch a part of the design on or off: a ``Piecewise`` on them computes
both branches at every call, and an option off still costs its operations (the physical
AFTC's RK4 step: 3,380 SX instructions with every option an input, 1,710 with them off
and folded in). A chunk for runs that all leave every option off
(:func:`shared_switches`) is built with those values as constants: CasADi folds each
switched-off branch away when it builds the graph. The inputs stay the same (the
switches are passed and not read), so nothing else changes.

The numbers are the general chunk's given those values: a folded branch is the same
operations on the same values. The identities CasADi applies as it folds that IEEE
arithmetic does not are 0·x = 0 (not so for an infinite or NaN x, where a run has
already diverged) and x + 0 = x (not so for the sign of a zero x, which the runs of
tests/test_specialise.py never meet: they compare in raw bits).
"""

from __future__ import annotations

import hashlib
from functools import cache

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.sim.rhs import Loop, controllers

#: controller parameters (by the end of their names) that switch a part of the design on
#: or off: derivation/physical.py, design.py, pi_baseline.py
CONTROLLER_SWITCHES = ("_obs_omega", "_obs_omega_max", "_ps_pitch", "_td_gain", "_td_lpf",
                       "_actuator_model", "_lpf_corner")

#: one switch folded into a chunk: (its entry in p_ctrl, its value)
Switch = tuple[int, float]


def switch_entries(loop: Loop) -> dict[int, float]:
    """The switches of ``loop``'s controller: their entries in p_ctrl, with their defaults
    (off)."""
    return dict(_switch_entries(loop.controller))


@cache
def _switch_entries(controller: str) -> dict[int, float]:
    """(from the layout, which is read once: found once a controller)"""
    group = controllers()[controller]["params"]
    names, defaults = lay.names(group), lay.defaults(group)
    return {i: float(defaults[i]) for i, n in enumerate(names) if n.endswith(CONTROLLER_SWITCHES)}


def shared_switches(loop: Loop, p_ctrl: list[np.ndarray | None]) -> tuple[Switch, ...]:
    """The switches a chunk for runs with these controller parameters is specialised to:
    all of them, where every run leaves them all off (their defaults); else none, so that
    one compiled chunk serves every option set and value of a loop. (Folding each option
    at its shared value, and the torque law and use_fdi too, made one chunk per option
    set and value: from an empty cache the test suite compiled 130 chunks instead of 91,
    for 3 % fewer operations in the bench's step than the options alone.)"""
    entries = switch_entries(loop)
    if not entries or any(p is None for p in p_ctrl):
        return ()
    at, off = list(entries), list(entries.values())
    if not all(np.array_equal(np.asarray(p, dtype=float)[at], off) for p in p_ctrl):
        return ()
    return tuple(sorted(entries.items()))


def tag(switches: tuple[Switch, ...]) -> str:
    """The part of a chunk's label naming its switches ('' for none)."""
    if not switches:
        return ""
    text = ";".join(f"p_ctrl[{i}]={v!r}" for i, v in switches)
    return "_sw" + hashlib.sha256(text.encode()).hexdigest()[:10]


def folded(f: ca.Function, fixed: dict, name: str | None = None) -> ca.Function:
    """The SX function ``f`` with the values of ``fixed`` ({input: {entry: value}} or
    {input: whole value}) as constants: the same inputs, those values passed and not
    read."""
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
