"""A minimal DISCON host for the tests (ctypes): the records ServoDyn fills, one call."""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np

SWAP = 500


class Host:
    """Calls DISCON of ``lib`` the way ServoDyn does: a float32 avrSWAP, aviFAIL, the
    input file name with its length in #50 (without the NUL, as ROSCO's interface)."""

    def __init__(self, lib: Path, infile: Path, dt: float = 0.01):
        self.lib = ctypes.CDLL(str(lib))
        self.lib.DISCON.restype = None
        self.swap = np.zeros(SWAP, dtype=np.float32)
        self.fail = ctypes.c_int(0)
        self.infile = str(infile).encode() + b"\0"
        self.outname = ctypes.create_string_buffer(1024)
        self.msg = ctypes.create_string_buffer(1024)
        self.dt = dt

    def call(self, status: int, t: float, omega_r: float, omega_g_hss: float, pitch,
             first_log: int = 0) -> dict:
        s = self.swap
        s[0], s[1], s[2] = status, t, self.dt
        s[3], s[32], s[33] = pitch
        s[19], s[20] = omega_g_hss, omega_r
        s[48] = 1024  # avcMSG's capacity
        s[49] = len(self.infile) - 1
        s[62] = first_log
        self.lib.DISCON(s.ctypes.data_as(ctypes.POINTER(ctypes.c_float)),
                        ctypes.byref(self.fail), ctypes.c_char_p(self.infile),
                        self.outname, self.msg)
        return {"fail": self.fail.value, "msg": self.msg.value.decode(),
                "pitch": s[41:44].astype(float), "torque": float(s[46]),
                "n_log": int(s[64]),
                "log": s[first_log - 1:first_log - 1 + int(s[64])].astype(float)
                if first_log else np.zeros(0)}
