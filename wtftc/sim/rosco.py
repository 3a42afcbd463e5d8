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
import ctypes
import os
import sys
import tempfile
import time
import types
from functools import cache
from pathlib import Path

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts import loader
from wtftc.errors import ConfigError
from wtftc.files import MAX_TOML_BYTES, read_user_text
from wtftc.model.turbine_import import line_key, read_discon
from wtftc.sim import integrate
from wtftc.sim.rhs import PLANTS, Loop, output_spec, rhs_function

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


def discon_values(spec: str | None = None) -> dict[str, str]:
    """Key → value text of the turbine's DISCON.IN (``rosco_discon``; default the NREL
    5-MW's of ROSCO's examples)."""
    return read_discon(discon_path(spec or NREL5MW_DISCON), "rosco_discon")


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


def discon_copy(tmp: Path, spec: str = NREL5MW_DISCON, retune: tuple | None = None) -> Path:
    """The turbine's DISCON.IN with logging off and the Cp file by absolute path (resolved
    against the DISCON.IN's folder when relative, as ROSCO does); with ``retune``, its
    pitch gain schedule for another closed-loop target (:func:`retuned_gains`)."""
    src = discon_path(spec)
    if spec.startswith("rosco:") and not src.is_file():
        raise ConfigError("controller", "rosco", f"a rosco install with {src}")
    text = read_user_text(src, "rosco_discon", MAX_TOML_BYTES)  # a FIFO, a folder: refused
    values = read_discon(src) if retune is not None else {}
    out = []
    for line in text.splitlines():
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
        retune: tuple | None = None, compiled: bool = True) -> integrate.Result:
    """Simulate one run (its plant, wind, faults) with ROSCO in the loop: ``loop`` is the
    ``external`` controller's, whose parameters are the held blade pitch commands;
    ``discon`` the turbine's DISCON.IN (a turbine file's ``rosco_discon``), its pitch
    gains retuned by ``retune`` (:func:`retuned_gains`). ``compiled``: DISCON called from
    inside the compiled loop (:func:`compiled_chunk`; from Python every CONTROL_DT where
    no C compiler is usable, or with False)."""
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
    chunk = compiled_chunk(loop) if compiled else None
    with tempfile.TemporaryDirectory() as tmp, _quiet_stdout():
        cwd = os.getcwd()
        os.chdir(tmp)  # ROSCO writes next to sim_name; keep the user's folder clean
        hook = None
        try:
            args = (Path(tmp), loop, inputs, n_sub)
            d = discon or NREL5MW_DISCON
            hook = _CompiledDiscon(*args, chunk, d, retune) if chunk else \
                _Discon(*args, d, retune)
            res = integrate.run_loops(loop, [inputs], t_final, dt, decimate, progress=False,
                                      hook=hook)[0]
        finally:
            if hook is not None:
                hook.close()
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
        # the run's plant (its own parameters under a model mismatch), its torque ROSCO's;
        # what ROSCO reads (HSS speed, efficiency) is that plant's too, as in the compiled
        # loop (_discon_step)
        self.p_turbine = integrate.plant_params(loop, inputs).copy()
        self.tp = lay.values("turbine_params", self.p_turbine)
        self.p_turbine[lay.index("turbine_params", "gen_constant_power")] = 0.0
        z0 = inputs.z0
        n_g = self.tp["gearbox_ratio"]
        pitch = z0[lay.block(PLANTS[loop.plant]["states"], "beta")]
        self.pitch = np.array(pitch, dtype=float)
        # the torque at the run's operating point (wtftc.sim.trim: the drivetrain twisted
        # by it), on the HSS: ROSCO starts from it as the plant does (issue 31)
        states = PLANTS[loop.plant]["states"]
        self.tq_hss = self.tp["k_s"] * float(z0[lay.index(states, "theta_s")]) / n_g
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
        self._open(tmp, float(np.degrees(self.pitch.mean())),
                   {"gen_speed": omega_g * n_g, "rot_speed": z0[self.i_omega_r],
                    "ws": float(self.wind(0.0)), "gen_torque": self.tq_hss}, discon, retune)

    def _open(self, tmp: Path, pitch_deg: float, init_state: dict, discon: str,
              retune: tuple | None) -> None:
        """ROSCO's first call (iStatus = 0) on the initial state."""
        self.ci = _interface(tmp, pitch_deg, init_state, discon, retune)

    def before(self, call: integrate.Buffered, k: int, stop: int) -> None:
        pt = self.p_turbine.copy()
        pt[lay.index("turbine_params", "gen_torque_rated")] = \
            self.tq_hss * self.tp["gearbox_ratio"]  # ROSCO's torque, held
        call.put("p_turbine", pt)
        call.put("p_ctrl", self.pitch)

    def _read(self, value: float, name: str) -> float:
        """A measurement as ROSCO reads it: ``value`` plus the sensor's noise."""
        sigma = self.sigma[name]
        return value + (sigma * self.noise[name].standard_normal() if sigma > 0 else 0.0)

    def after(self, k: int, stop: int, z: np.ndarray, res: list[np.ndarray],
              out_names: list[str]) -> None:
        if stop % self.steps == 0:
            self._call(stop, z, dict(zip(out_names, res[1][:, stop - k - 1], strict=True)))

    def _call(self, k: int, z: np.ndarray, out: dict[str, float]) -> None:
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

    ci = _InitState(rosco.discon_lib_path, param_filename=str(discon_copy(tmp, discon, retune)),
                    DT=CONTROL_DT, pitch=pitch_deg, sim_name=str(tmp / "wtftc"),
                    avr_size=2000)
    if ci.aviFAIL.value < 0:
        raise ConfigError("controller", "rosco",
                          "a working ROSCO: " + ci.avcMSG.value.decode(errors="replace"))
    return ci


# --- ROSCO at compiled speed (issue 19) ---
#: the DISCON bridge: a CasADi external function the compiled loop calls every step,
#: calling DISCON at the end of each control interval (wtftc/sim/discon_bridge.c)
BRIDGE = Path(__file__).with_name("discon_bridge.c")
#: the chunk's "discon" input, one column a step: whether DISCON is called at the step's
#: end, the time then, the wind ROSCO reads (start-up only), the noise on each reading
DISCON_ROWS = ("call", "t_s", "wind_mps", *[f"noise_beta_meas_{j}" for j in lay.blades()],
               "noise_omega_g_hss", "noise_omega_r")
#: what the bridge holds between calls: the blade pitch commands [rad], the torque [N m, HSS]
HELD = 4


def _discon_step(loop: Loop, bridge: ca.Function) -> ca.Function:
    """One RK4 step of the ``external`` loop, its blade pitch commands and generator torque
    held from the last DISCON call, then the bridge: DISCON called at an interval's end on
    what ROSCO reads (the blades' measured pitch at the step's start, the speeds reached)."""
    step = integrate.rk4_step(rhs_function(loop), shared=not loop.fdi)
    ins = {n: ca.MX.sym(n, step.sparsity_in(n)) for n in step.name_in()}
    held, dis = ca.MX.sym("held", HELD), ca.MX.sym("discon", len(DISCON_ROWS))
    tp = ins["p_turbine"]
    i_tq, i_ng, i_eff = (lay.index("turbine_params", n)
                         for n in ("gen_torque_rated", "gearbox_ratio", "gen_efficiency"))
    pt = ca.vertcat(tp[:i_tq], held[3] * tp[i_ng], tp[i_tq + 1:])  # ROSCO's torque, held
    r = step.call({**ins, "p_turbine": pt, "p_ctrl": held[:3]})
    z, out = r["z_next"], r["out"]
    names = [n for n, _ in output_spec(loop.controller, loop.fdi, loop.plant)]
    row = {n: DISCON_ROWS.index(n) for n in DISCON_ROWS}
    beta = [out[names.index(f"beta_meas_{j}")] + dis[row[f"noise_beta_meas_{j}"]]
            for j in lay.blades()]
    states = PLANTS[loop.plant]["states"]
    meas = ca.vertcat(dis[row["call"]], dis[row["t_s"]], CONTROL_DT,
                      ((beta[0] + beta[1]) + beta[2]) / 3,
                      z[lay.index(states, "omega_g")] * tp[i_ng] + dis[row["noise_omega_g_hss"]],
                      z[lay.index(states, "omega_r")] + dis[row["noise_omega_r"]],
                      dis[row["wind_mps"]], tp[i_eff], held[3])
    rest = [n for n in step.name_in() if n != "z"]
    return ca.Function("discon_step", [ins["z"], held, dis, *[ins[n] for n in rest]],
                       [z, bridge(meas, held), out], ["z", "held", "discon", *rest],
                       ["z_next", "held_next", "out"])


#: steps per compiled call of ROSCO in the loop: 1000 (the FDI's 95 states and the
#: bridge's inputs a step; 317× real time in the bench's run against 300× at 2000 or 4000)
CHUNK = 1000


@cache
def compiled_chunk(loop: Loop, n: int = CHUNK) -> tuple[ca.Function, Path] | None:
    """``n`` steps of ROSCO in the loop in one compiled call, the bridge compiled into the
    same library (whose DISCON state it holds), and that library's path; None where no C
    compiler or cache is usable (the caller then calls ROSCO from Python)."""
    bridge = loader.compiled_external("wtftc_discon", BRIDGE, integrate.loop_flags())
    if bridge is None:
        return None
    chunk = _discon_step(loop, bridge).mapaccum(f"rosco_{loop.plant}", n, 2)
    label = f"rosco_{loop.plant}_{loop.table_key}_{'' if loop.fdi else 'nofdi_'}{n}"
    so = integrate.loop_library([chunk], label, BRIDGE.read_text(), integrate.loop_flags())
    loaded = None if so is None else loader.external_of(chunk.name(), so)
    return None if loaded is None else (loaded, so)


class _CompiledDiscon(_Discon):
    """ROSCO's DISCON called by the compiled loop through the bridge (no Python between
    calls): the same readings, noise draws and record as :class:`_Discon`, whose set-up it
    shares; Python writes each chunk's call steps, times, winds and noise beforehand."""

    def __init__(self, tmp: Path, loop: Loop, inputs: integrate.Run, n_sub: int,
                 chunk: tuple[ca.Function, Path], discon: str = NREL5MW_DISCON,
                 retune: tuple | None = None):
        self.function, so = chunk
        self.n_c = self.function.size2_out("out")
        self.lib = ctypes.CDLL(str(so))  # the library the chunk runs in: its DISCON state
        self.lib.wtftc_discon_message.restype = ctypes.c_char_p
        super().__init__(tmp, loop, inputs, n_sub, discon, retune)
        self.held = np.append(self.pitch, self.tq_hss)

    def _open(self, tmp: Path, pitch_deg: float, init_state: dict, discon: str,
              retune: tuple | None) -> None:
        param, sim = str(discon_copy(tmp, discon, retune)), str(tmp / "wtftc")
        record = _first_record(pitch_deg, init_state, param, sim)
        fail = self.lib.wtftc_discon_open(
            str(discon_library()).encode(), param.encode(), sim.encode(),
            record.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), record.size)
        if fail < 0:
            msg = self.lib.wtftc_discon_message().decode(errors="replace")
            self.lib.wtftc_discon_close()
            raise ConfigError("controller", "rosco", f"a working ROSCO: {msg}")

    def before(self, call: integrate.Buffered, k: int, stop: int) -> None:
        reached = k + 1 + np.arange(self.n_c)  # the step each column ends on
        calls = (reached % self.steps == 0) & (reached <= stop)
        cols = np.zeros((len(DISCON_ROWS), self.n_c))
        t = reached[calls] * self.dt  # as _Discon: the step reached times CONTROL_DT / n_sub
        cols[0, calls], cols[1, calls] = 1.0, t
        cols[2, calls] = [float(self.wind(x)) for x in t]
        for name, sigma in self.sigma.items():  # each signal's stream, a draw per call
            if sigma > 0:
                cols[DISCON_ROWS.index(f"noise_{name}"), calls] = \
                    sigma * self.noise[name].standard_normal(t.size)
        call.put("discon", cols)
        call.put("held", self.held)
        call.put("p_turbine", self.p_turbine)

    def after(self, k: int, stop: int, z: np.ndarray, res: list[np.ndarray],
              out_names: list[str]) -> None:
        self.held = res[1][:, stop - k - 1].copy()
        if self.lib.wtftc_discon_fail() < 0:  # ROSCO reported an error (aviFAIL < 0)
            msg = self.lib.wtftc_discon_message().decode(errors="replace").strip()
            raise ConfigError("controller", "rosco", f"a ROSCO that runs: it failed by "
                              f"t = {stop * self.dt:.3f} s ({msg or 'no message'})")

    def close(self) -> None:
        """The final call (iStatus = -1), then the library is released."""
        self.lib.wtftc_discon_close()


def discon_library() -> Path:
    """ROSCO's libdiscon.so, as its ControllerInterface loads it."""
    rosco, _ = _import()
    return Path(rosco.discon_lib_path)


def _first_record(pitch_deg: float, s: dict, param: str, sim: str) -> np.ndarray:
    """avrSWAP for DISCON's first call (iStatus = 0), field for field as ROSCO's
    ControllerInterface.init_discon writes it, with the real initial state (:func:`_interface`)."""
    a = np.zeros(2000)
    a[2], a[60], a[82], a[27], a[0] = CONTROL_DT, 3, 0, 1, 0
    a[3] = a[32] = a[33] = pitch_deg * np.deg2rad(1)
    a[48], a[49], a[50], a[51] = 500, len(param), len(sim.encode("utf-8")), 500
    a[19], a[20], a[26], a[22] = s["gen_speed"], s["rot_speed"], s["ws"], s["gen_torque"]
    return a
