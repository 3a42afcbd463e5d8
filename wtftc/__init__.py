"""wtftc: fault-tolerant pitch control of wind turbines, derived in SymPy, generated with
CasADi, verified, simulated (Bakhshi & Alfi 2020 and what it lacks).

Rooms, each importing only the ones after it (docs/architecture.md)::

    cli → campaign → verify → results → config → sim → model → artefacts
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("wtftc")
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "unknown (not installed)"
