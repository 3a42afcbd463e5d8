"""A minimal DISCON host for the tests: the records ServoDyn fills, one call
(wtftc.campaign.in_loop.Library, whose ``record`` returns aviFAIL and the message too), and
the fuzz driver of tests/test_discon_fuzz.py (``python tests/discon_host.py LIB CASES
RESULTS``: every case's calls in this process, its result one JSON line, written as it
goes so that a crash names its case)."""

from __future__ import annotations

import ctypes
import json
import sys
from pathlib import Path

import numpy as np

from wtftc.campaign.in_loop import SWAP, Library

#: the byte avcMSG is filled with before a call: what is still there was not written
CANARY = 0xA5
#: avcMSG's real size in the raw calls (larger than any #49 the tests give)
MSG_BUFFER = 8192
#: the demand records (1-based): #42-#45 pitch, #47 generator torque
DEMANDS = (42, 43, 44, 45, 47)


class Host(Library):
    """``call`` returns what came back, failures included (the tests look at them)."""

    def __init__(self, lib: Path, infile: Path, dt: float = 0.01):
        super().__init__(lib, infile, dt)

    def call(self, status: int, t: float, omega_r: float, omega_g_hss: float, pitch,
             first_log: int = 0) -> dict:
        return self.record(status, t, omega_r, omega_g_hss, pitch, first_log)

    def raw(self, status: float, t: float, omega_r: float, omega_g_hss: float, pitch,
            capacity: float) -> dict:
        """One call with #49 = ``capacity`` and an avcMSG of MSG_BUFFER bytes filled with
        CANARY: aviFAIL, every byte of avcMSG, the demands (#42-#45, #47)."""
        return raw_call(self.dll, self.swap, self.infile, status, t, self.dt,
                        (omega_r, omega_g_hss, *pitch), capacity, self.ptch_cntrl)


def raw_call(dll, swap: np.ndarray, infile: bytes, status: float, t: float, dt: float,
             readings, capacity: float, ptch_cntrl: float = 1.0) -> dict:
    s = swap
    s[0], s[1], s[2] = status, t, dt
    s[20], s[19], s[3], s[32], s[33] = readings
    s[27] = ptch_cntrl
    s[48] = capacity
    s[49] = len(infile) - 1
    s[62] = 0
    msg = ctypes.create_string_buffer(bytes([CANARY]) * MSG_BUFFER, MSG_BUFFER)
    fail = ctypes.c_int(7)
    outname = ctypes.create_string_buffer(b"wtftc-fuzz", 256)
    dll.DISCON(s.ctypes.data_as(ctypes.POINTER(ctypes.c_float)), ctypes.byref(fail),
               ctypes.c_char_p(infile), outname, msg)
    return {"fail": fail.value, "msg_bytes": msg.raw,
            "demands": [float(s[k - 1]) for k in DEMANDS]}


def message(out: dict) -> str:
    """The NUL-terminated message of a raw call ('' when none was written)."""
    raw = out["msg_bytes"]
    return raw[:raw.index(0)].decode("utf-8", "replace") if 0 in raw else ""


def run_cases(lib: Path, cases: Path, results: Path) -> None:
    """Each case of ``cases`` (JSON: infile, capacity, calls of [status, t, ω_r, ω_g,
    β1, β2, β3]) through a fresh first call; per call aviFAIL, the message, whether avcMSG
    was written only within #49 (its NUL too), and the demands."""
    dll = ctypes.CDLL(str(lib))
    dll.DISCON.restype = None
    swap = np.zeros(SWAP, dtype=np.float32)
    with open(results, "w") as out:
        for k, case in enumerate(json.loads(Path(cases).read_text())):
            out.write(json.dumps({"case": k, "start": True}) + "\n")
            out.flush()
            infile = case["infile"].encode("utf-8", "surrogateescape") + b"\0"
            calls = []
            for status, t, *readings in case["calls"]:
                got = raw_call(dll, swap, infile, status, t, case.get("dt", 0.01), readings,
                               case["capacity"])
                cap = int(case["capacity"]) if case["capacity"] >= 1 else 0
                raw = got["msg_bytes"]
                calls.append({"fail": got["fail"], "msg": message(got) if cap else "",
                              "msg_len": raw.index(0) if 0 in raw else len(raw),
                              "within": all(b == CANARY for b in raw[cap:]),
                              "terminated": cap == 0 or 0 in raw[:cap],
                              "untouched": all(b == CANARY for b in raw),
                              "demands": got["demands"]})
            out.write(json.dumps({"case": k, "calls": calls}) + "\n")
            out.flush()


if __name__ == "__main__":
    run_cases(Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3]))


__all__ = ["CANARY", "DEMANDS", "MSG_BUFFER", "SWAP", "Host", "message", "raw_call",
           "run_cases"]
