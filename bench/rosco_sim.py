"""A point of reference for `make bench`: ROSCO's own simple simulator, timed.

What is measured: ``rosco.toolbox.sim.Sim.sim_ws_series`` (ROSCO 2.10.6) driving ROSCO's
compiled controller (``libdiscon.so`` with the packaged NREL 5-MW ``DISCON.IN``, through
``ControllerInterface``) on the NREL 5-MW, over the benchmark's wind sampled on the
simulator's time grid. The clock covers ``sim_ws_series`` only: the wind array is built
beforehand (ROSCO's API takes arrays), and loading the library and reading ``DISCON.IN``
(a fresh ``ControllerInterface`` per run, as ``Sim`` unloads the library at the end) is
reported apart as ``setup_s_median``.

Why it is a reference point and not an equal-accuracy comparison: ``Sim`` is a 1-DOF rigid
drivetrain (rotor speed only, no shaft compliance, no pitch actuator, no faults) advanced by
explicit Euler at a fixed step, ``dt = 0.025`` s as in ROSCO's example 04 (``Sim`` passes
its step to the controller through ``avrSWAP``: ``DISCON.IN`` has no DT of its own, so the
controller runs at the simulator's step). Each step looks up Cp and Cq by building a SciPy
``RectBivariateSpline`` over the whole table and makes one ctypes call into the controller;
that is what the number is dominated by. wtftc's loops integrate a stiffer multi-state
model (drivetrain torsion, pitch actuators, the controller's own states) to 1e-6 of a
DOP853 reference; ROSCO's Euler step is not held to any accuracy target.

The turbine: rosco 2.10.6 ships no turbine pickle (example 04 loads one written by example
01), and ``Turbine.load_from_fast`` needs ``openfast_io`` ~5, which cannot read the v4 input
deck rosco ships. So :func:`turbine` builds ``Turbine`` from the turbine_params of ROSCO's
tuning file ``Examples/Tune_Cases/NREL5MW.yaml`` and sets what ``Sim`` uses the way
``load_from_fast`` does, from the files of ``Examples/Test_Cases/NREL-5MW``: TipRad, GBRatio,
GBoxEff, GenIner (ElastoDyn), GenEff (ServoDyn), AirDens (AeroDyn), J = rotor_inertia +
GenIner·GBRatio², and Cp/Cq from ``Cp_Ct_Cq.NREL5MW.txt`` through ROSCO's ``load_from_txt``
and ``RotorPerformance``. (J equals ``DISCON.IN``'s WE_Jtot; wtftc's own J_r is 0.2 % larger.)

Optional: ``pip install 'wtftc[rosco]'`` (or the ``--no-deps`` install of docs/controllers.md);
``rosco.toolbox.sim`` imports ``pandas`` and ``openfast_io``, which the simple simulator does
not use: where they are missing, stand-ins are placed for the import only and removed after.
"""

from __future__ import annotations

import math
import os
import statistics
import sys
import tempfile
import time
import types
from pathlib import Path

import numpy as np

from wtftc.sim import rosco as _rosco

SIM_DT = 0.025  # ROSCO's example 04 step [s]
NOTE = ("ROSCO 2.10.6 rosco.toolbox.sim.Sim: 1-DOF rigid rotor, explicit Euler at fixed dt, "
        "Cp/Cq spline rebuilt each step, libdiscon.so (NREL 5-MW DISCON.IN) called every step; "
        "not wtftc's model, not held to wtftc's accuracy target")


def available() -> str | None:
    """None when ROSCO's simple simulator can run here, else a one-line reason."""
    reason = _rosco.available()
    if reason:
        return reason
    try:
        _import_sim()
        case = _case_dir()
    except Exception as exc:  # noqa: BLE001 - any failure means "not usable"
        return (f"rosco.toolbox.sim is not usable ({type(exc).__name__}: {exc}); "
                f"install {_rosco.INSTALL}")
    missing = [p.name for p in (case / "DISCON.IN", case / "Cp_Ct_Cq.NREL5MW.txt", _tune_file())
               if not p.exists()]
    if missing:
        return f"the rosco install lacks {', '.join(missing)}; install {_rosco.INSTALL}"
    return None


def _import_sim():
    """rosco.toolbox.sim.Sim, RotorPerformance, load_from_txt, Turbine (with stand-ins for
    the modules the simple simulator imports but does not use)."""
    rosco, ci = _rosco._import()  # stubs wisdem where it is absent
    wisdem_inputs = sys.modules.get("wisdem.inputs")
    if wisdem_inputs is not None and not hasattr(wisdem_inputs, "load_yaml"):
        # rosco.toolbox.utilities imports wisdem.inputs.load_yaml at module level
        from rosco.toolbox.ofTools.util.FileTools import load_yaml

        wisdem_inputs.load_yaml = load_yaml
    import importlib.util

    added = []
    for name in ("pandas", "openfast_io"):
        if name not in sys.modules and importlib.util.find_spec(name) is None:
            sys.modules[name] = types.ModuleType(name)
            added.append(name)
    if "openfast_io" in added:
        from rosco.toolbox.ofTools.util import FileTools

        sys.modules["openfast_io"].FileTools = FileTools
    try:
        from rosco.toolbox import sim as rsim
        from rosco.toolbox import turbine as rturb
        from rosco.toolbox.utilities import load_from_txt
    finally:
        for name in added:
            del sys.modules[name]
    return rosco, ci, rsim.Sim, rturb.Turbine, rturb.RotorPerformance, load_from_txt


def _case_dir() -> Path:
    import rosco

    return Path(rosco.__file__).resolve().parent.parent / "Examples" / "Test_Cases" / "NREL-5MW"


def _tune_file() -> Path:
    return _case_dir().parent.parent / "Tune_Cases" / "NREL5MW.yaml"


def _values(path: Path) -> dict[str, str]:
    """The `value  Key  - description` lines of an OpenFAST input file."""
    out = {}
    for line in path.read_text(errors="replace").splitlines():
        parts = line.split()
        if len(parts) >= 2:
            out.setdefault(parts[1], parts[0].strip('"'))
    return out


def turbine():
    """ROSCO's ``Turbine`` for the NREL 5-MW with what ``Sim`` uses (see the module doc)."""
    import yaml

    _, _, _, Turbine, RotorPerformance, load_from_txt = _import_sim()
    case = _case_dir()
    params = dict(yaml.safe_load(_tune_file().read_text())["turbine_params"])
    params.setdefault("TSR_operational", None)
    fst = _values(case / "NREL-5MW.fst")
    ed = _values(case / fst["EDFile"])
    sd = _values(case / fst["ServoFile"])
    ad = _values(case / fst["AeroFile"])
    with _rosco._quiet_stdout():
        t = Turbine(params)
        pitch, tsr, cp, ct, cq = load_from_txt(str(case / "Cp_Ct_Cq.NREL5MW.txt"))
    # as Turbine.load_from_fast sets them
    t.TipRad = t.rotor_radius = float(ed["TipRad"])
    t.Ng = float(ed["GBRatio"])
    t.GBoxEff = float(ed["GBoxEff"])
    t.generator_inertia = float(ed["GenIner"])
    t.GenEff = float(sd["GenEff"])
    t.rho = float(ad.get("AirDens", fst.get("AirDens")))
    t.J = t.rotor_inertia + t.generator_inertia * t.Ng**2
    t.rated_torque = t.rated_power / (t.GenEff / 100 * t.rated_rotor_speed * t.Ng)
    t.pitch_initial_rad, t.TSR_initial = pitch, tsr
    t.Cp_table, t.Ct_table, t.Cq_table = cp, ct, cq
    t.Cp = RotorPerformance(cp, pitch, tsr)
    t.Ct = RotorPerformance(ct, pitch, tsr)
    t.Cq = RotorPerformance(cq, pitch, tsr)
    return t


def trim_pitch_deg(turb, ws: float) -> float:
    """Blade pitch [deg] where ``Sim``'s aerodynamic torque at rated rotor speed equals the
    rated generator torque (its own equation and Cp table); 0 below rated."""
    from scipy.optimize import brentq

    R, om = turb.rotor_radius, turb.rated_rotor_speed
    tsr = om * R / ws
    need = turb.Ng * turb.rated_torque / (turb.GBoxEff / 100)

    def excess(beta):
        cp = float(turb.Cp.interp_surface(beta, tsr))
        return 0.5 * turb.rho * math.pi * R**3 * cp / tsr * ws**2 - need

    hi = float(np.max(turb.pitch_initial_rad))
    if excess(0.0) <= 0 or excess(hi) >= 0:
        return 0.0
    return math.degrees(brentq(excess, 0.0, hi, xtol=1e-10))


def _with_init_state(ControllerInterface):
    """ControllerInterface whose initialization call sees the simulator's initial state
    (the stock one passes 1 rad/s, 10 m/s and zero torque, which starts ROSCO's filters and
    integrators there: a 10 s start-up transient from a trimmed turbine). As in
    wtftc/sim/rosco.py; the calls during the run are ROSCO's own."""

    class _InitState(ControllerInterface):
        init_state = None

        def call_discon(self):
            if self.avrSWAP[0] == 0 and self.init_state:
                rot, ws, tq, ng = self.init_state
                self.avrSWAP[19], self.avrSWAP[20] = rot * ng, rot
                self.avrSWAP[26], self.avrSWAP[22] = ws, tq
            super().call_discon()

    return _InitState


def run(wind, t_final: float, dt: float = SIM_DT, turb=None):
    """One ``sim_ws_series`` run from rated rotor speed and the trim pitch at wind(0).

    Returns ``(sim, wall_s, setup_s)``: ROSCO's ``Sim`` with its arrays (``t_array``,
    ``rot_speed`` [rad/s], ``bld_pitch`` [rad], ``gen_torque`` [N m], ...), the wall time
    of ``sim_ws_series`` and that of the controller's set-up.
    """
    rosco, ControllerInterface, Sim, *_ = _import_sim()
    turb = turb if turb is not None else turbine()
    n = int(round(t_final / dt))
    t = np.arange(n + 1) * dt
    ws = np.asarray(wind(t), dtype=float) * np.ones_like(t)
    pitch0 = trim_pitch_deg(turb, float(ws[0]))
    rpm0 = turb.rated_rotor_speed * 60 / (2 * math.pi)
    with tempfile.TemporaryDirectory() as tmp, _rosco._quiet_stdout():
        cwd = os.getcwd()
        os.chdir(tmp)  # ROSCO writes next to sim_name
        try:
            t0 = time.perf_counter()
            ci = _with_init_state(ControllerInterface)(
                rosco.discon_lib_path, param_filename=str(_rosco.discon_copy(Path(tmp))),
                DT=dt, pitch=pitch0, sim_name=str(Path(tmp) / "sim"), avr_size=2000,
                init_state=(turb.rated_rotor_speed, float(ws[0]), turb.rated_torque, turb.Ng))
            setup = time.perf_counter() - t0
            if ci.aviFAIL.value < 0:
                raise RuntimeError("ROSCO failed to start: "
                                   + ci.avcMSG.value.decode(errors="replace"))
            s = Sim(turb, ci)
            t0 = time.perf_counter()
            s.sim_ws_series(t, ws, rotor_rpm_init=rpm0, init_pitch=pitch0, make_plots=False)
            wall = time.perf_counter() - t0
        finally:
            os.chdir(cwd)
    return s, wall, setup


def time_rosco_sim(wind, t_final: float, dt: float = SIM_DT, repeats: int = 3) -> dict:
    """Wall time of ROSCO's simple simulator over t_final simulated seconds, repeated.

    One untimed warm-up run first (imports, first library load, SciPy). Times are per run
    of t_final; ``realtime`` is simulated seconds per wall second at the median.
    """
    reason = available()
    if reason:
        raise RuntimeError(reason)
    turb = turbine()
    run(wind, min(t_final, 1.0), dt, turb)  # warm-up
    walls, setups = [], []
    steps = 0
    for _ in range(max(1, int(repeats))):
        s, wall, setup = run(wind, t_final, dt, turb)
        walls.append(wall)
        setups.append(setup)
        steps = len(s.t_array) - 1  # Sim skips index 0 (the initial state)
    med = statistics.median(walls)
    diverged = not (np.all(np.isfinite(s.rot_speed)) and np.all(np.isfinite(s.bld_pitch)))
    return {
        "method": "rosco_sim",
        "wall_s_median": med,
        "wall_s_min": min(walls),
        "wall_s_max": max(walls),
        "repeats": len(walls),
        "setup_s_median": statistics.median(setups),
        "t_final_s": steps * dt,
        "dt": dt,
        "steps": steps,
        "ns_per_step": med / steps * 1e9,
        "realtime": steps * dt / med,
        "diverged": bool(diverged),
        "rosco_version": _rosco.ROSCO_VERSION,
        "note": NOTE,
    }
