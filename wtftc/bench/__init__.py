"""`wtftc bench`: the same closed loop through wtftc's paths and the alternatives.

The baselines (lambdify, numba) live here and are never used by wtftc itself. The
lambdify baseline needs the source tree (derivation/ beside wtftc/):
:func:`require_source_tree` puts it on the import path or says what is missing.
"""

from __future__ import annotations

import sys
from pathlib import Path

from wtftc.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]


def require_source_tree() -> Path:
    """The repository root with derivation/, importable; a clear error without it."""
    if not (ROOT / "derivation" / "__init__.py").exists():
        raise ConfigError("source tree", str(ROOT), "a clone of the wtftc repository "
                          "(the bench's lambdify baseline needs derivation/ beside wtftc/)")
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    return ROOT
