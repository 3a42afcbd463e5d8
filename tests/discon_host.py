"""A minimal DISCON host for the tests: the records ServoDyn fills, one call
(wtftc.export.in_loop.Library, whose ``record`` returns aviFAIL and the message too)."""

from __future__ import annotations

from pathlib import Path

from wtftc.export.in_loop import SWAP, Library


class Host(Library):
    """``call`` returns what came back, failures included (the tests look at them)."""

    def __init__(self, lib: Path, infile: Path, dt: float = 0.01):
        super().__init__(lib, infile, dt)

    def call(self, status: int, t: float, omega_r: float, omega_g_hss: float, pitch,
             first_log: int = 0) -> dict:
        return self.record(status, t, omega_r, omega_g_hss, pitch, first_log)


__all__ = ["SWAP", "Host"]
