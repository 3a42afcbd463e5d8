"""ROSCO in the loop (make bench; issue 19): one run of ROSCO 2.10.6's libdiscon.so on
wtftc's NREL 5-MW plant (the FDI as a monitor, as ``wtftc run --controller rosco`` runs
it), DISCON called every 5 ms from inside the compiled loop (the bridge, the default)
against the same run with DISCON called from Python through ROSCO's ControllerInterface
(the adapter it replaced): wall time, multiple of real time, and whether the two runs
are the same bit for bit."""

from __future__ import annotations

import time

import numpy as np

from wtftc import config
from wtftc.campaign import cases

#: the bench's run: IEC NTM class B at 16 m/s, 60 s, the realistic sensors' noise (what
#: ROSCO reads in the campaigns), the default dt of 1 ms
RUN = {"controller": "rosco", "case": 1, "profile": "realistic", "seed": 0,
       "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"}}


def _once(rc, compiled: bool):
    from wtftc.sim import rosco

    inputs, _ = cases._prepare(rc)
    t0 = time.perf_counter()
    res = rosco.run(rc.loop, inputs, rc.t_final, rc.dt, rc.decimate, progress=False,
                    compiled=compiled)
    return time.perf_counter() - t0, res


def rows(quick: bool = False, repeats: int = 3) -> tuple[list[list[str]], str] | None:
    """The table's rows (method, horizon, wall, × real time, time ratio) and a note on
    the two paths' agreement; None where ROSCO is not installed."""
    from wtftc.sim import rosco

    if rosco.available() is not None:
        return None
    t_final = 20.0 if quick else 60.0
    rc = config.make_config({**RUN, "t_final_s": t_final})
    _once(rc, True)  # compile (cached) and load before timing
    timed = {}
    for compiled in (True, False):
        runs = [_once(rc, compiled) for _ in range(repeats)]
        timed[compiled] = (float(np.median([w for w, _ in runs])), runs[0][1])
    (fast, a), (slow, b) = timed[True], timed[False]
    same = np.array_equal(a.outputs, b.outputs)
    diff = float(np.max(np.abs(a.outputs - b.outputs))) if a.outputs.shape == \
        b.outputs.shape else float("nan")
    out = [["ROSCO in the loop: DISCON called from the compiled loop (default)",
            f"{t_final:g}", f"{fast:.3f}", f"{t_final / fast:,.0f}", "1.00"],
           ["ROSCO in the loop: DISCON through ControllerInterface from Python",
            f"{t_final:g}", f"{slow:.3f}", f"{t_final / slow:,.0f}", f"{slow / fast:.2f}"]]
    note = ("the same run bit for bit" if same else
            f"the runs differ: largest output difference {diff:.3g}")
    return out, note


def markdown(got: tuple | None) -> list[str]:
    """The bench report's section from :func:`rows` (empty where ROSCO is not installed)."""
    if got is None:
        return []
    table, note = got
    head = ["method", "horizon [s]", "wall [s]", "× real time", "time ratio to default"]
    lines = ["### ROSCO in the loop", "",
             "ROSCO 2.10.6's libdiscon.so (NREL 5-MW DISCON.IN) every 5 ms on wtftc's NREL "
             "5-MW plant, FDI monitor on, realistic sensor noise, NTM B 16 m/s, dt = 1 ms, "
             f"median of 3; {note}.", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in table]
    return lines + [""]
