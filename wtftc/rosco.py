"""ROSCO in the loop: NREL's reference controller on the same plant, wind and faults.

Optional extra: ``pip install 'wtftc[rosco]'`` (the ``rosco`` 2.10.6 wheel, which ships
``libdiscon.so``, ``ControllerInterface`` and the NREL 5-MW ``DISCON.IN``). ROSCO is called
through ``rosco.toolbox.control_interface.ControllerInterface`` every ``CONTROL_DT``; in
between, the compiled loop advances the plant (and wtftc's FDI, as a monitor) with the
``external`` controller holding ROSCO's blade pitch commands, and the generator torque
held at ROSCO's command. ROSCO sees what a turbine measures: rotor and generator speed,
blade pitch, generator torque; its wind input is used only at start-up (its own wind
estimator runs on the Cp table).

Gotchas handled here (see the research notes in docs/controllers.md): the avrSWAP array
is sized 2000 (DISCON.IN has Ext_Interface = 1, ROSCO reads indices up to 1018); the
initialization call is given the real initial state (the stock one assumes 1 rad/s and
10 m/s); a private copy of DISCON.IN turns logging off and points at the Cp file by
absolute path; one instance per process at a time.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import time
import types
from pathlib import Path

import numpy as np

from wtftc import layout as lay
from wtftc import simulate as sim
from wtftc.errors import ConfigError

ROSCO_VERSION = "2.10.6"
CONTROL_DT = 0.005  # ROSCO's call interval [s] (OpenFAST's NREL 5-MW case uses 0.00625)
INSTALL = "pip install 'wtftc[rosco]'  (the rosco 2.10.6 wheel)"


def available() -> str | None:
    """None if ROSCO can be used here, else the reason (with what to install)."""
    try:
        _import()
    except Exception as exc:  # noqa: BLE001 - any import failure means "not available"
        return f"ROSCO is not available ({type(exc).__name__}: {exc}); install it with {INSTALL}"
    return None


def _import():
    # unbuffered Fortran output, so that ROSCO's prints land while stdout is silenced
    # (gfortran reads this when the library loads)
    os.environ.setdefault("GFORTRAN_UNBUFFERED_PRECONNECTED", "y")
    try:
        import wisdem  # noqa: F401
    except ImportError:
        # ControllerInterface's module imports a wisdem type table it does not use for
        # control; without the (large) wisdem install, a stand-in module suffices
        for name in ("wisdem", "wisdem.inputs", "wisdem.inputs.validation"):
            sys.modules.setdefault(name, types.ModuleType(name))
        sys.modules["wisdem.inputs.validation"].simple_types = None
    import rosco
    from rosco.toolbox.control_interface import ControllerInterface

    return rosco, ControllerInterface


def _discon_copy(tmp: Path) -> Path:
    """The packaged NREL 5-MW DISCON.IN with logging off and the Cp file by absolute path."""
    rosco, _ = _import()
    case = Path(rosco.__file__).resolve().parent.parent / "Examples" / "Test_Cases" / "NREL-5MW"
    src = case / "DISCON.IN"
    if not src.exists():
        raise ConfigError("controller", "rosco", f"a rosco install with {src}")
    out = []
    for line in src.read_text().splitlines():
        key = line.split("!")[-1].strip().split(" ")[0] if "!" in line else ""
        if key == "LoggingLevel":
            line = "0" + line[line.index(" ") if " " in line.strip() else len(line):]
        elif key == "PerfFileName":
            line = f'"{case / "Cp_Ct_Cq.NREL5MW.txt"}"    ! PerfFileName'
        out.append(line)
    path = tmp / "DISCON.IN"
    path.write_text("\n".join(out) + "\n")
    return path


@contextlib.contextmanager
def _quiet_stdout():
    """ROSCO's Fortran prints a banner and a status line every 10 s to file descriptor 1."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
        try:
            yield
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)


def run(rc, progress: bool = True) -> sim.Result:
    """Simulate rc (its plant, wind, faults) with ROSCO in the loop."""
    reason = available()
    if reason:
        raise ConfigError("controller", "rosco", reason)
    if rc.plant != "nrel5mw":
        raise ConfigError("plant", rc.plant, "nrel5mw with controller = rosco (ROSCO commands "
                          "the generator torque the paper's plant does not have)")
    n_sub = int(round(CONTROL_DT / rc.dt))
    if n_sub < 1 or abs(n_sub * rc.dt - CONTROL_DT) > 1e-12:
        raise ConfigError("dt_s", rc.dt, f"a divisor of ROSCO's call interval {CONTROL_DT} s")
    rosco, ControllerInterface = _import()

    class _InitState(ControllerInterface):
        init_state = None

        def call_discon(self):
            if self.avrSWAP[0] == 0 and self.init_state:
                s = self.init_state
                self.avrSWAP[19], self.avrSWAP[20] = s["gen_speed"], s["rot_speed"]
                self.avrSWAP[26], self.avrSWAP[22] = s["ws"], s["gen_torque"]
            super().call_discon()

    from wtftc.cases import trim
    from wtftc.faults import Schedule

    z = trim(rc)
    get = dict(zip(lay.names("turbine_params"), rc.p_turbine, strict=True))
    N = get["gearbox_ratio"]
    i_tq = lay.index("turbine_params", "gen_torque_rated")
    i_cp = lay.index("turbine_params", "gen_constant_power")
    tq_hss = get["gen_torque_rated"] / N
    pitch = np.array(z[3:6], dtype=float)
    f = sim.chunk_function(rc.plant, "external", rc.table_key, rc.table, tuple(rc.p_turbine),
                           n=n_sub)
    yd = np.zeros(len(lay.names("reference")))
    yd[0] = rc.reference
    schedule = Schedule([*rc.faults]) if rc.faults else None
    ck = np.tile(lay.defaults("fault_inputs")[:, None], (1, n_sub))
    names = sim.state_names(rc.plant, "external")
    out_names = [n for n, _ in sim.output_spec("external")]
    n_steps = int(round(rc.t_final / rc.dt))
    outs, ts = [], []
    diverged = None
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp, _quiet_stdout():
        cwd = os.getcwd()
        os.chdir(tmp)  # ROSCO writes next to sim_name; keep the user's folder clean
        try:
            ci = _InitState(rosco.discon_lib_path, param_filename=str(_discon_copy(Path(tmp))),
                            DT=CONTROL_DT, pitch=float(np.degrees(pitch.mean())),
                            sim_name=str(Path(tmp) / "wtftc"), avr_size=2000,
                            init_state={"gen_speed": z[2] * N, "rot_speed": z[0],
                                        "ws": float(rc.wind(0.0)), "gen_torque": tq_hss})
            if ci.aviFAIL.value < 0:
                raise ConfigError("controller", "rosco",
                                  "a working ROSCO: " + ci.avcMSG.value.decode(errors="replace"))
            events = [int(round(e / rc.dt)) for e in (schedule.events() if schedule else [])]
            k = 0
            while k < n_steps:
                for e in events:
                    if k <= e < k + n_sub:
                        schedule.bind_current_angles(e * rc.dt, z[3:6], rc.dt)
                tk = (k + np.arange(n_sub)) * rc.dt
                w3 = np.vstack([rc.wind(tk), rc.wind(tk + rc.dt / 2), rc.wind(tk + rc.dt)])
                af = schedule.actuator(tk) if schedule else np.tile(
                    lay.defaults("actuator_faults")[:, None], (1, n_sub))
                sf = schedule.sensor(tk) if schedule else np.tile(
                    lay.defaults("sensor_faults")[:, None], (1, n_sub))
                pt = rc.p_turbine.copy()
                pt[i_tq], pt[i_cp] = tq_hss * N, 0.0  # ROSCO's torque, held
                zz, oo = f(z, w3, af, sf, ck, yd, pt, pitch, 0.0, rc.dt)
                zz, oo = np.array(zz), np.array(oo)
                mb = n_sub
                if not (np.abs(zz).max() <= 1e8 and np.isfinite(oo).all()):
                    i, diverged = sim.divergence(zz, oo, z, names, out_names, k, rc.dt)
                    mb = i + 1
                sel = k + np.arange(mb)
                keep = sel % rc.decimate == 0
                outs.append(oo[:, :mb][:, keep].T)
                ts.append(sel[keep] * rc.dt)
                if diverged:
                    k += mb
                    break
                z = zz[:, -1]
                k += n_sub
                out_now = dict(zip(sim.output_spec("external"), oo[:, -1], strict=True))
                beta_meas = [out_now[(f"beta_meas_{j}", "rad")] for j in (1, 2, 3)]
                state = {"iStatus": 1, "t": k * rc.dt, "dt": CONTROL_DT,
                         "bld_pitch": float(np.mean(beta_meas)), "gen_torque": tq_hss,
                         "gen_speed": z[2] * N, "gen_eff": get["gen_efficiency"],
                         "rot_speed": z[0], "ws": float(rc.wind(k * rc.dt)),
                         "Y_MeasErr": 0.0, "Yaw_fromNorth": 0.0}
                tq, _, _ = ci.call_controller(state)
                tq_hss = float(tq)
                pitch = np.array([ci.avrSWAP[41], ci.avrSWAP[42], ci.avrSWAP[43]], float)
            state["iStatus"] = -1
            ci.call_controller(state)
            ci.kill_discon()
        finally:
            os.chdir(cwd)
    wall = time.perf_counter() - t0
    res = sim.Result(t=np.concatenate(ts) if ts else np.zeros(0),
                     outputs=np.vstack(outs) if outs else np.zeros((0, len(sim.output_spec(
                         "external")))), z_final=z, diverged=diverged, wall_s=wall, steps=k,
                     names=out_names, schedule=schedule)
    if progress:
        print(f"    {k * rc.dt:.1f} s simulated with ROSCO in {wall:.1f} s "
              f"({k * rc.dt / max(wall, 1e-9):.0f}× real time)", file=sys.stderr)
    return res
