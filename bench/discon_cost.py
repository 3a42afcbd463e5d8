"""The exported DISCON libraries' cost per call, against ROSCO's ``libdiscon.so`` called
the same way (make bench; docs/discon.md): a small C harness (discon_harness.c) loads a
library with dlopen and calls DISCON N times at rated readings, no Python in between."""

from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path

from wtftc.export import discon

HERE = Path(__file__).resolve().parent
#: calls timed per repeat: the paper's design diverges in open loop at constant readings
#: after about 385 calls (its observer has no plant), so fewer than that
CALLS = 300


def _time(harness: Path, lib: Path, infile: Path, dt: float, swap: int, repeats: int,
          cwd: Path) -> float:
    """Best of ``repeats`` ns per call."""
    best = float("inf")
    for _ in range(repeats):
        done = subprocess.run([str(harness), str(lib), str(infile), repr(dt), str(swap),
                               str(CALLS)], capture_output=True, text=True, cwd=cwd,
                              timeout=300)
        if done.returncode != 0:
            raise RuntimeError(f"{lib.name}: {done.stderr.strip()[-300:]}")
        best = min(best, float(done.stdout.strip().splitlines()[-1]))
    return best


def call_costs(controllers=("physical", "paper"), repeats: int = 5) -> dict[str, str]:
    """Lines for the bench's summary: ns per DISCON call of each exported library (with
    its FDI) and of ROSCO's, and the share of a 10-ms interval."""
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        harness = tmp / "discon_harness"
        subprocess.run(["gcc", "-O2", "-o", str(harness), str(HERE / "discon_harness.c"),
                        "-ldl"], check=True, capture_output=True, timeout=120)
        for c in controllers:
            lib = discon.export(c, tmp / c)
            ns = _time(harness, lib / f"libwtftc_{c}.so", lib / f"wtftc_{c}.IN",
                       discon.CONTROL_DT, 500, repeats, tmp)
            out[f"DISCON call, libwtftc_{c}.so (with its FDI) [ns]"] = (
                f"{ns:,.0f} ({100 * ns * 1e-9 / discon.CONTROL_DT:.2f} % of a "
                f"{discon.CONTROL_DT * 1e3:.0f}-ms interval)")
        rosco_ns = _rosco(harness, tmp, repeats)
        if rosco_ns is not None:
            out["DISCON call, ROSCO 2.10.6 libdiscon.so (NREL 5-MW DISCON.IN) [ns]"] = \
                f"{rosco_ns:,.0f}"
    return out


def _rosco(harness: Path, tmp: Path, repeats: int) -> float | None:
    from wtftc.sim import rosco

    if rosco.available() is not None:
        return None
    infile = rosco.discon_copy(tmp)
    lib, _ = rosco._import()
    # ROSCO reads records up to 1018 (Ext_Interface = 1): a larger swap array
    return _time(harness, Path(lib.discon_lib_path), infile, discon.CONTROL_DT, 3000,
                 repeats, tmp)
