"""The engines side by side (make bench; docs/performance.md, docs/openfast.md): wall time
per simulated second of one scenario in OpenFAST 5.0.0 (ROSCO called by ServoDyn directly,
and through wtftc's plant-side actuator library: the library's own cost), and on wtftc's
tower plant (ROSCO in the loop, and the physical AFTC's sampled loop): the speed-up a user
buys by screening on wtftc's plant.

The scenario: NREL 5-MW, steady 16 m/s, the realistic profile, 60 s, fault-free. The
OpenFAST runs alternate (direct, library, direct, ...) so that a load change on the
machine falls on both alike; best of ``repeats`` each.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from wtftc import config
from wtftc.openfast import case as ofcase
from wtftc.openfast import engine, install

#: the scenario's length [s]
T_FINAL = 60.0
SCENARIO = {"profile": "realistic", "wind": {"kind": "constant", "speed_mps": 16.0},
            "t_final_s": T_FINAL, "case": 1}


def _openfast_pair(tmp: Path, repeats: int) -> tuple[float, float]:
    """Best wall time [s] of ROSCO in OpenFAST called directly, and through the plant
    library, on the same case."""
    rc = config.make_config({**SCENARIO, "engine": "openfast", "controller": "rosco"})
    through = engine.prepare(rc, tmp / "through")
    direct = engine.prepare(rc, tmp / "direct")
    lib, infile = engine.controller_library(rc, tmp / "direct" / "controller")
    ofcase.set_values(ofcase.module_file(direct.fst, "ServoFile"),
                      {"DLL_FileName": f'"{lib}"', "DLL_InFile": f'"{infile}"'})
    best = {"direct": float("inf"), "through": float("inf")}
    for _ in range(repeats):
        for name, c in (("direct", direct), ("through", through)):
            wall, abort = engine.simulate(c, progress=False)
            if abort is not None:
                raise RuntimeError(f"OpenFAST ({name}) stopped: {abort}")
            best[name] = min(best[name], wall)
    return best["direct"], best["through"]


def _native(controller: str, repeats: int) -> float:
    from wtftc.campaign import cases

    raw = {**SCENARIO, "plant": "tower", "controller": controller}
    if controller != "rosco":
        raw["turbine_params"] = {"gen_torque_law": 1.0}
    rc = config.make_config(raw)
    cases.run(rc, progress=False)  # compiled and cached first
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        cases.run(rc, progress=False)
        best = min(best, time.perf_counter() - t0)
    return best


def rows(repeats: int = 3) -> dict[str, str]:
    """Lines for the bench's summary; a note instead when OpenFAST is not installed."""
    if install.find() is None:
        return {"engines": "OpenFAST is not installed (make openfast): no engine rows"}
    with tempfile.TemporaryDirectory() as tmp:
        direct, through = _openfast_pair(Path(tmp), repeats)
    tower_rosco = _native("rosco", repeats)
    tower_physical = _native("physical", repeats)
    per_s = {"OpenFAST, ROSCO direct": direct, "OpenFAST, ROSCO through libwtftc_plant.so":
             through, "wtftc tower plant, ROSCO in the loop": tower_rosco,
             "wtftc tower plant, physical AFTC (sampled, realistic)": tower_physical}
    out = {f"engine: {k} [s wall per simulated s]": f"{v / T_FINAL:.4f} "
           f"({T_FINAL / v:,.1f}x real time)" for k, v in per_s.items()}
    out["engine: the plant library's cost (through / direct OpenFAST wall)"] = \
        f"{through / direct:.3f} (goal < 1.05)"
    out["engine: speed-up of wtftc's tower plant over OpenFAST (ROSCO, same scenario)"] = \
        f"{through / tower_rosco:,.0f}x"
    return out
