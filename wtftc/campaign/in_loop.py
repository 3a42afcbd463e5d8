"""An exported DISCON library driving wtftc's NREL 5-MW plant (ours): the check that the
library behaves as the controller does inside wtftc.

The compiled loop runs the ``external`` controller, whose parameters are the held blade
pitch commands, and the plant's generator torque held at the library's demand; every
control interval the library is called through ctypes, as ServoDyn calls it, with what a
turbine measures (the exact rotor and generator speeds and blade pitches: one reading per
quantity), and its commands are held over the next interval (wtftc/sim/rosco.py does the
same with ROSCO's library).
"""

from __future__ import annotations

import ctypes
import time
from pathlib import Path

import numpy as np

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.errors import ConfigError
from wtftc.sim import integrate
from wtftc.sim.rhs import PLANTS

SWAP = 500


class Library:
    """One DISCON library called through ctypes with a float32 avrSWAP of 500 records."""

    def __init__(self, lib: Path, infile: Path, dt: float):
        self.dll = ctypes.CDLL(str(lib))
        self.dll.DISCON.restype = None
        self.swap = np.zeros(SWAP, dtype=np.float32)
        self.fail = ctypes.c_int(0)
        self.infile = str(infile).encode() + b"\0"
        self.outname = ctypes.create_string_buffer(1024)
        self.msg = ctypes.create_string_buffer(1024)
        self.dt = dt
        self.ptch_cntrl = 1  # #28: individual pitch, as the library needs

    def record(self, status: int, t: float, omega_r: float, omega_g_hss: float, pitch,
               first_log: int = 0) -> dict:
        """One call with these measurements (the records ServoDyn fills): what came back,
        aviFAIL and the message included."""
        s = self.swap
        s[0], s[1], s[2] = status, t, self.dt
        s[3], s[32], s[33] = pitch
        s[19], s[20] = omega_g_hss, omega_r
        s[27] = self.ptch_cntrl
        s[48] = 1024  # avcMSG's capacity
        s[49] = len(self.infile) - 1
        s[62] = first_log
        self.dll.DISCON(s.ctypes.data_as(ctypes.POINTER(ctypes.c_float)),
                        ctypes.byref(self.fail), ctypes.c_char_p(self.infile),
                        self.outname, self.msg)
        n_log = int(s[64])
        return {"fail": self.fail.value, "msg": self.msg.value.decode(errors="replace"),
                "pitch": s[41:44].astype(float), "torque": float(s[46]), "n_log": n_log,
                "log": s[first_log - 1:first_log - 1 + n_log].astype(float)
                if first_log else np.zeros(0)}

    def call(self, status: int, t: float, omega_r: float, omega_g_hss: float, pitch
             ) -> tuple[np.ndarray, float]:
        """(pitch demands [rad], generator torque demand [N m, HSS]); a failure raises
        with the library's message."""
        out = self.record(status, t, omega_r, omega_g_hss, pitch)
        if out["fail"] < 0:
            raise ConfigError("library", "DISCON", out["msg"])
        return out["pitch"], out["torque"]


class ViaRosco:
    """The same calls through ROSCO's own ``ControllerInterface`` (pip ``rosco``): its
    avrSWAP of 500 float32 records, its string handling (#50 without the NUL) and its call
    sequence. Two things are set around it, as wtftc/sim/rosco.py does for ROSCO's
    library: the first call (made by the interface's constructor) gets the real initial
    state, not its hard-coded 1 rad/s, and every call gets each blade's own pitch in #4,
    #33 and #34 (``call_controller`` writes one collective pitch to all three)."""

    def __init__(self, lib: Path, infile: Path, dt: float, folder: Path):
        from wtftc.sim.rosco import _import

        _, controller_interface = _import()
        self.dt, self.lib, self.infile, self.folder = dt, lib, infile, folder
        self.ci, self.measured = None, None

        class _Blades(controller_interface):
            def call_discon(inner):
                m = self.measured
                s = inner.avrSWAP
                s[0], s[1], s[2] = m["status"], m["t"], dt
                s[3], s[32], s[33] = m["pitch"]
                s[19], s[20] = m["omega_g_hss"], m["omega_r"]
                super().call_discon()

        self.cls = _Blades

    def call(self, status: int, t: float, omega_r: float, omega_g_hss: float, pitch
             ) -> tuple[np.ndarray, float]:
        self.measured = {"status": status, "t": t, "omega_r": omega_r,
                         "omega_g_hss": omega_g_hss, "pitch": list(pitch)}
        if status == 0:  # the constructor makes the first call
            self.ci = self.cls(str(self.lib), param_filename=str(self.infile), DT=self.dt,
                               pitch=float(np.degrees(np.mean(pitch))),
                               sim_name=str(self.folder / "wtftc"), avr_size=SWAP)
        else:
            self.ci.call_discon()
        if self.ci.aviFAIL.value < 0:
            raise ConfigError("library", "DISCON", self.ci.avcMSG.value.decode(
                errors="replace"))
        s = self.ci.avrSWAP
        if status == -1:
            self.ci.kill_discon()
        return np.array(s[41:44], dtype=float), float(s[46])


class _Hook(integrate.ChunkHook):
    """The library every ``steps`` plant steps; its commands held in between."""

    def __init__(self, lib: Library, loop, z0: np.ndarray, steps: int):
        self.lib, self.steps = lib, steps
        states = PLANTS[loop.plant]["states"]
        self.i_r, self.i_g = lay.index(states, "omega_r"), lay.index(states, "omega_g")
        self.i_beta = lay.block(states, "beta")
        self.p_turbine = np.array(loop.p_turbine)
        self.gear = self.p_turbine[lay.index("turbine_params", "gearbox_ratio")]
        self.pitch, self.torque = self._call(0, 0.0, z0)

    def _call(self, status: int, t: float, z: np.ndarray):
        return self.lib.call(status, t, z[self.i_r], z[self.i_g] * self.gear, z[self.i_beta])

    def before(self, call: integrate.Buffered, k: int, stop: int) -> None:
        pt = self.p_turbine.copy()
        pt[lay.index("turbine_params", "gen_torque_rated")] = self.torque * self.gear
        pt[lay.index("turbine_params", "gen_constant_power")] = 0.0
        pt[lay.index("turbine_params", "gen_torque_law")] = 0.0  # the library's torque
        call.put("p_turbine", pt)
        call.put("p_ctrl", self.pitch)

    def after(self, k: int, stop: int, z: np.ndarray, res: list[np.ndarray],
              out_names: list[str]) -> None:
        if stop % self.steps == 0:  # an interval's end: the library's next call
            self.pitch, self.torque = self._call(1, stop * self.lib.dt / self.steps, z)


def run(lib: Path, infile: Path, raw: dict, interval: float,
        rosco_folder: Path | None = None) -> integrate.Result:
    """The plant of run configuration ``raw`` (its wind, faults, dt, duration; its
    controller is replaced by the library) driven by ``lib`` every ``interval`` s, called
    through plain ctypes or, given ``rosco_folder`` (where ROSCO's interface may write),
    through ROSCO's ControllerInterface."""
    rc = config.make_config({**raw, "controller": "rosco", "case": 1 if not raw.get(
        "fault") else 2, "control_interval_s": 0.0, "profile": "ideal", "sensors": {}})
    steps = int(round(interval / rc.dt))
    if steps < 1 or abs(steps * rc.dt - interval) > 1e-12:
        raise ConfigError("dt_s", rc.dt, f"a divisor of the library's interval {interval} s")
    inputs, _ = cases._prepare(rc, check=False)
    t0 = time.perf_counter()
    library = Library(lib, infile, interval) if rosco_folder is None else \
        ViaRosco(lib, infile, interval, rosco_folder)
    hook = _Hook(library, rc.loop, inputs.z0, steps)
    res = integrate.run_loops(rc.loop, [inputs], rc.t_final, rc.dt, rc.decimate,
                              progress=False, hook=hook)[0]
    library.call(-1, rc.t_final, 0.0, 0.0, [0.0, 0.0, 0.0])
    res.schedule = inputs.schedule
    res.wall_s = time.perf_counter() - t0
    return res
