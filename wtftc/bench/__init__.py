"""`wtftc bench`: the same closed loop through wtftc's paths and the alternatives.

The baselines (lambdify, numba) live here and are never used by wtftc itself. The
lambdify baseline needs the source tree (derivation/ beside wtftc/):
:func:`require_source_tree` puts it on the import path or says what is missing.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def require_source_tree() -> Path:
    """The repository root with derivation/, importable; a clear error without it."""
    if not (ROOT / "derivation" / "__init__.py").exists():
        raise RuntimeError(f"the benchmark's lambdify baseline needs wtftc's source tree "
                           f"(derivation/ in {ROOT}); run it from a clone of the repository")
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    return ROOT
