"""`make bench`: the same closed loop through wtftc's paths and the alternatives.

Lives beside wtftc/, not inside it: the baselines (numba, SymPy lambdify, SciPy, ROSCO's
own simulator) need the source tree (derivation/) and the 'bench' extra, and the installed
package never imports them. Run it with ``make bench`` or ``python -m bench --help`` from
the repository root.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

# BLAS on one thread, before numpy loads it, as the wtftc command sets it (wtftc/cli.py):
# OpenBLAS's idle worker threads spin on the cores the timed loops and batches use
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

ROOT = Path(__file__).resolve().parents[1]


def require_source_tree() -> Path:
    """The repository root, importable (derivation/ for the lambdify baseline)."""
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    return ROOT
