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

from wtftc.artefacts import layout as lay
from wtftc.errors import ConfigError
from wtftc.model.turbine_import import line_key, read_discon
from wtftc.sim import integrate
from wtftc.sim.rhs import PLANTS, Loop

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


#: the turbine files' default: the NREL 5-MW's DISCON.IN of ROSCO's examples
NREL5MW_DISCON = "rosco:Examples/Test_Cases/NREL-5MW/DISCON.IN"


def discon_path(spec: str) -> Path:
    """A turbine file's ``rosco_discon``: ``rosco:<path>`` in the rosco package's tree (its
    wheel's Examples), else a path."""
    if spec.startswith("rosco:"):
        rosco, _ = _import()
        return Path(rosco.__file__).resolve().parent.parent / spec[len("rosco:"):]
    return Path(spec)


def retuned_gains(kp: np.ndarray, ki: np.ndarray, retune: tuple) -> tuple:
    """ROSCO's pitch PI gain schedule for another closed-loop target: ``retune`` = (ω_pc,
    ζ_pc, ω_pc0, ζ_pc0), the new target and the one the schedule was tuned for. ROSCO's
    toolbox (``ControllerTypes.second_order_PI``) sets K_p = (2ζω + A)/B and K_i = ω²/B
    on the plant's A and B at each scheduled point, so from the schedule for (ω0, ζ0):
    B = ω0²/K_i0, and K_p = K_p0 + 2(ζω − ζ0ω0)/B, K_i = K_i0 ω²/ω0², exactly."""
    w, z, w0, z0 = retune
    b = w0**2 / np.asarray(ki, float)
    return np.asarray(kp, float) + 2 * (z * w - z0 * w0) / b, np.asarray(ki, float) * w**2 / w0**2


def _retuned_line(line: str, key: str, values: dict, retune: tuple) -> str:
    kp, ki = (np.array(values[k].split(), float) for k in ("PC_GS_KP", "PC_GS_KI"))
    gains = dict(zip(("PC_GS_KP", "PC_GS_KI"), retuned_gains(kp, ki, retune), strict=True))
    return "   ".join(f"{g:.6e}" for g in gains[key]) + "   ! " + line.split("!", 1)[1]


def _discon_copy(tmp: Path, spec: str = NREL5MW_DISCON, retune: tuple | None = None) -> Path:
    """The turbine's DISCON.IN with logging off and the Cp file by absolute path (resolved
    against the DISCON.IN's folder when relative, as ROSCO does); with ``retune``, its
    pitch gain schedule for another closed-loop target (:func:`retuned_gains`)."""
    src = discon_path(spec)
    if not src.is_file():
        raise ConfigError("controller", "rosco", f"a rosco install with {src}")
    values = read_discon(src) if retune is not None else {}
    out = []
    for line in src.read_text().splitlines():
        key = line_key(line)
        if retune is not None and key in ("PC_GS_KP", "PC_GS_KI"):
            line = _retuned_line(line, key, values, retune)
        elif key == "LoggingLevel":
            line = "0" + line[line.index(" ") if " " in line.strip() else len(line):]
        elif key == "PerfFileName":
            cp = Path(line.split("!")[0].strip().strip('"').strip("'"))
            line = f'"{(src.parent / cp).resolve()}"    ! PerfFileName'
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


def run(loop: Loop, inputs: integrate.Run, t_final: float, dt: float, decimate: int = 1,
        progress: bool = True, discon: str | None = None,
        retune: tuple | None = None) -> integrate.Result:
    """Simulate one run (its plant, wind, faults) with ROSCO in the loop: ``loop`` is the
    ``external`` controller's, whose parameters are the held blade pitch commands;
    ``discon`` the turbine's DISCON.IN (a turbine file's ``rosco_discon``), its pitch
    gains retuned by ``retune`` (:func:`retuned_gains`)."""
    reason = available()
    if reason:
        raise ConfigError("controller", "rosco", reason)
    if not PLANTS[loop.plant]["loaded"]:
        raise ConfigError("plant", loop.plant, "nrel5mw or tower with controller = rosco "
                          "(ROSCO commands the generator torque the paper's plant does not "
                          "have)")
    n_sub = int(round(CONTROL_DT / dt))
    if n_sub < 1 or abs(n_sub * dt - CONTROL_DT) > 1e-12:
        raise ConfigError("dt_s", dt, f"a divisor of ROSCO's call interval {CONTROL_DT} s")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp, _quiet_stdout():
        cwd = os.getcwd()
        os.chdir(tmp)  # ROSCO writes next to sim_name; keep the user's folder clean
        try:
            hook = _Discon(Path(tmp), loop, inputs, n_sub, discon or NREL5MW_DISCON, retune)
            res = integrate.run_loops(loop, [inputs], t_final, dt, decimate, progress=False,
                                      hook=hook)[0]
            hook.close()
        finally:
            os.chdir(cwd)
    res.schedule = inputs.schedule
    res.wall_s = time.perf_counter() - t0
    if progress:
        print(f"    {res.steps * dt:.1f} s simulated with ROSCO in {res.wall_s:.1f} s "
              f"({res.steps * dt / max(res.wall_s, 1e-9):.0f}× real time)", file=sys.stderr)
    return res


class _Discon(integrate.ChunkHook):
    """ROSCO's DISCON, called every CONTROL_DT: between calls the compiled loop holds its
    blade pitch commands (the ``external`` controller's parameters) and its generator
    torque (the turbine's rated torque, constant-torque law)."""

    def __init__(self, tmp: Path, loop: Loop, inputs: integrate.Run, n_sub: int,
                 discon: str = NREL5MW_DISCON, retune: tuple | None = None):
        self.steps = n_sub
        self.dt = CONTROL_DT / n_sub
        self.wind = inputs.wind
        self.tp = lay.values("turbine_params", loop.p_turbine)
        self.p_turbine = np.array(loop.p_turbine)
        z0 = inputs.z0
        n_g = self.tp["gearbox_ratio"]
        pitch = z0[lay.block(PLANTS[loop.plant]["states"], "beta")]
        self.pitch = np.array(pitch, dtype=float)
        self.tq_hss = self.tp["gen_torque_rated"] / n_g
        self.state = None
        self.i_omega_g = lay.index(PLANTS[loop.plant]["states"], "omega_g")
        self.i_omega_r = lay.index(PLANTS[loop.plant]["states"], "omega_r")
        # the sensors' noise on what ROSCO reads (the loop's voted pitch carries the
        # pitch sensors' faults, bias and resolution): the mean of each quantity's two
        # sensors, σ/√2 (as the virtual sensors give the other controllers), one stream per
        # signal from the run's seed, a draw per call
        ps = lay.values("sensor_params", lay.defaults("sensor_params")
                        if inputs.p_sensors is None else inputs.p_sensors)
        self.sigma = {n: float(np.hypot(ps[f"sigma_{n}_m1"], ps[f"sigma_{n}_m2"])) / 2
                      for n in ("omega_r", "omega_g_hss",
                                *[f"beta_meas_{j}" for j in lay.blades()])}
        self.noise = {n: np.random.default_rng(np.random.SeedSequence(
            inputs.noise_seed, spawn_key=(11, k))) for k, n in enumerate(self.sigma)}
        omega_g = z0[self.i_omega_g]
        self.ci = _interface(tmp, float(np.degrees(self.pitch.mean())),
                             {"gen_speed": omega_g * n_g, "rot_speed": z0[self.i_omega_r],
                              "ws": float(self.wind(0.0)), "gen_torque": self.tq_hss},
                             discon, retune)

    def before(self, call: integrate.Buffered) -> None:
        pt = self.p_turbine.copy()
        pt[lay.index("turbine_params", "gen_torque_rated")] = \
            self.tq_hss * self.tp["gearbox_ratio"]  # ROSCO's torque, held
        pt[lay.index("turbine_params", "gen_constant_power")] = 0.0
        call.put("p_turbine", pt)
        call.put("p_ctrl", self.pitch)

    def _read(self, value: float, name: str) -> float:
        """A measurement as ROSCO reads it: ``value`` plus the sensor's noise."""
        sigma = self.sigma[name]
        return value + (sigma * self.noise[name].standard_normal() if sigma > 0 else 0.0)

    def after(self, k: int, z: np.ndarray, out: dict[str, float]) -> None:
        # the pitch as the loop measured it (with a pitch sensor's fault); the speeds at the
        # state reached, exact but for the noise (a speed sensor's fault, bias, resolution
        # and lag do not reach ROSCO: docs/sensors.md)
        beta_meas = [self._read(out[f"beta_meas_{j}"], f"beta_meas_{j}") for j in lay.blades()]
        self.state = {"iStatus": 1, "t": k * self.dt, "dt": CONTROL_DT,
                      "bld_pitch": float(np.mean(beta_meas)), "gen_torque": self.tq_hss,
                      "gen_speed": self._read(z[self.i_omega_g] * self.tp["gearbox_ratio"],
                                              "omega_g_hss"),
                      "gen_eff": self.tp["gen_efficiency"],
                      "rot_speed": self._read(z[self.i_omega_r], "omega_r"),
                      "ws": float(self.wind(k * self.dt)), "Y_MeasErr": 0.0,
                      "Yaw_fromNorth": 0.0}
        tq, _, _ = self.ci.call_controller(self.state)
        self.tq_hss = float(tq)
        # avrSWAP records 42-44: the blade pitch demands (C index n - 1)
        self.pitch = np.array([self.ci.avrSWAP[40 + j] for j in lay.blades()], float)

    def close(self) -> None:
        """The final call (iStatus = -1), then the library is released."""
        if self.state is not None:
            self.ci.call_controller({**self.state, "iStatus": -1})
        self.ci.kill_discon()


def _interface(tmp: Path, pitch_deg: float, init_state: dict, discon: str = NREL5MW_DISCON,
               retune: tuple | None = None):
    """ROSCO's ControllerInterface on a private DISCON.IN, its first call given the real
    initial state (the stock one assumes 1 rad/s and 10 m/s)."""
    rosco, ControllerInterface = _import()

    class _InitState(ControllerInterface):
        def call_discon(self):
            if self.avrSWAP[0] == 0:
                s = init_state
                self.avrSWAP[19], self.avrSWAP[20] = s["gen_speed"], s["rot_speed"]
                self.avrSWAP[26], self.avrSWAP[22] = s["ws"], s["gen_torque"]
            super().call_discon()

    ci = _InitState(rosco.discon_lib_path, param_filename=str(_discon_copy(tmp, discon, retune)),
                    DT=CONTROL_DT, pitch=pitch_deg, sim_name=str(tmp / "wtftc"),
                    avr_size=2000)
    if ci.aviFAIL.value < 0:
        raise ConfigError("controller", "rosco",
                          "a working ROSCO: " + ci.avcMSG.value.decode(errors="replace"))
    return ci
