"""A run in OpenFAST (``--engine openfast``, issue 32; ours).

:func:`run` writes the case (wtftc.openfast.case) into ``folder``, builds or finds the
controller library (ROSCO's ``libdiscon.so`` with the turbine's DISCON.IN, any DISCON
library with its input file, or the run's controller exported as wtftc exports it,
``wtftc export discon``), runs OpenFAST there
and reads its binary output and the plant library's records back into an
:class:`wtftc.sim.integrate.Result` with the native engine's output columns, so that the
same metrics, traces and figures follow. A column OpenFAST has no counterpart of (the
drivetrain's twist, Cp, the controller's internal signals) is NaN.

Units at the edge: OpenFAST reports rpm, degrees and kN(m); everything here is SI.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import time
from contextlib import suppress
from pathlib import Path

import numpy as np

from wtftc import files, programs
from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import cache_dir
from wtftc.config import openfast_deck
from wtftc.errors import ConfigError, EngineError
from wtftc.model import turbine_file
from wtftc.model.faults import Schedule
from wtftc.model.wind_field import turbsim_field
from wtftc.openfast import case as ofcase
from wtftc.openfast import install, plant_library, turbsim
from wtftc.sim import integrate, rhs
from wtftc.sim.rhs import PLANTS

RPM = math.pi / 30
#: how the native output columns are filled from OpenFAST's channels: name → (channel,
#: scale to SI)
FROM_OUTB = {"omega_r": ("RotSpeed", RPM), "beta_1": ("BldPitch1", math.pi / 180),
             "beta_2": ("BldPitch2", math.pi / 180), "beta_3": ("BldPitch3", math.pi / 180),
             "wind": ("Wind1VelX", 1.0), "tower_x": ("TTDspFA", 1.0),
             "M_tower": ("TwrBsMyt", 1e3), "thrust": ("RotThrust", 1e3)}
#: the FDI channels a wtftc library logs (wtftc.export.discon.LOGGED, per blade)
LOGGED = ("latch", "rho_hat", "c_hat")


def deck_of(rc) -> Path:
    """The run's turbine's OpenFAST deck (its main file)."""
    deck = openfast_deck(turbine_file.load(rc.raw.get("turbine", turbine_file.DEFAULT)))
    if deck is None:
        raise ConfigError("turbine", rc.raw.get("turbine", turbine_file.DEFAULT),
                          "a turbine whose file names its OpenFAST deck (openfast_deck = "
                          "\"<main>.fst\"; docs/openfast.md) with engine = openfast")
    return deck


def controller_library(rc, folder: Path) -> tuple[Path, Path]:
    """(library, its input file) of the run's controller, in ``folder``: ROSCO's with the
    turbine's DISCON.IN (retuned as the run says), a DISCON library wtftc did not build
    with its input file (controller = "discon": both where they are, each checked against
    the sha256 the run keeps), or the run's controller exported."""
    folder.mkdir(parents=True, exist_ok=True)
    if rc.uses_discon:
        from wtftc.controller import discon_files

        files = dict(discon_files(rc.raw["discon"], "discon"))
        return Path(files["library"]), Path(files["input"])
    if rc.uses_rosco:
        from wtftc.sim import rosco

        return rosco.discon_library(), rosco.discon_copy(folder, rc.rosco_discon
                                                         or rosco.NREL5MW_DISCON,
                                                         rc.rosco_retune)
    from wtftc.export import discon

    if rc.controller not in discon.exportable():
        raise ConfigError("controller", rc.controller, "rosco or one of "
                          + ", ".join(discon.exportable()) + " with engine = openfast")
    # the plant library puts the benchmark actuator in: no rate limit on the demands;
    # without it the blades take the demands, each within the turbine's rate limit
    actuator = rc.raw["openfast"]["actuator"]
    return _cached_library(rc, folder), discon.write_input(
        rc, folder / f"wtftc_{rc.controller}.IN", demand_rate_limit=0 if actuator else 1)


def _cached_library(rc, folder: Path) -> Path:
    """The run's controller library, its sources written into ``folder`` and compiled
    once per distinct sources into wtftc's cache (a campaign compiles each controller
    once; the parameter values are the .IN's)."""
    import hashlib

    from wtftc.artefacts.loader import built_once, cache_dir, compiler
    from wtftc.export import discon

    sources = discon.write_sources(rc, folder)
    key = hashlib.sha256(b"".join(p.read_bytes() for p in sources)).hexdigest()[:20]
    name = f"libwtftc_{rc.controller}.so"
    cc = compiler() or "gcc"

    def make(tmp: Path) -> None:
        discon.compile_library(discon.compile_command(folder, rc.controller, cc,
                                                      lib=tmp / name), cc)
        discon.check_library(tmp / name, cc)

    shutil.copy2(built_once(cache_dir() / f"discon-{key}", name, make), folder / name)
    return folder / name


def _wind(rc, inflow: Path, folder: Path) -> None:
    """InflowWind's wind: a TurbSim full field for an NTM wind (``[openfast] wind =
    "turbsim"``, the default: the run's mean at hub height, class and seed; the field a
    native run with ``[wind] field = "turbsim"`` reads), else the run's series as a
    uniform wind file."""
    desc = rc.wind.describe()
    hub = float(ofcase.get_value(inflow, "RefHt"))
    if desc["kind"] == "ntm" and rc.raw["openfast"]["wind"] == "turbsim":
        bts = turbsim.generate(turbsim_field(desc, deck_of(rc), rc.param("rotor_radius"),
                                             rc.t_final))
        shutil.copy2(bts, folder / "wtftc_wind.bts")
        ofcase.set_values(inflow, {"WindType": "3", "FileName_BTS": '"wtftc_wind.bts"'})
        return
    ofcase.write_wind(folder / "wtftc_wind.uni", rc.t_final, rc.wind)
    ofcase.set_values(inflow, {"WindType": "2", "Filename_Uni": '"wtftc_wind.uni"',
                               "RefHt_Uni": f"{hub:g}"})


def interval_of(rc) -> float:
    """The controller library's call interval [s]: the run's control interval (ROSCO's
    own, 5 ms, for controller = rosco)."""
    return rc.control_interval or float(rc.raw["control_interval_s"])


def prepare(rc, folder: Path) -> ofcase.Case:
    """The case of ``rc`` written into ``folder`` (the run folder's ``openfast/``)."""
    if any(float(rc.p_sensors[lay.index("sensor_params", n)]) > 0
           for n in lay.names("sensor_params") if n.startswith("lag_")):
        raise ConfigError("sensors", rc.raw.get("sensors"), "no sensor lag with engine = "
                          "openfast (the plant library's sensors have none)")
    folder = Path(folder).resolve()  # OpenFAST runs in it: every path it reads absolute
    deck = deck_of(rc)
    fst = ofcase.copy_deck(deck, folder)  # (reads every file: a bad one named first)
    ofcase.check_deck_matches_turbine(
        deck, turbine_file.load(rc.raw.get("turbine", turbine_file.DEFAULT)), rc.param)
    dt, dll_dt = ofcase.steps(interval_of(rc))
    ofcase.set_values(fst, {"TMax": f"{rc.t_final:.9g}", "DT": f"{dt:.9g}",
                            "OutFileFmt": "2", "DT_Out": '"default"', "Echo": "False"})
    ed = ofcase.module_file(fst, "EDFile")
    ofcase.clamp_fixed_bottom(fst, ed)
    z0 = rc.initial_state()
    states = PLANTS["tower"]["states"]
    ofcase.initial_conditions(ed, z0[lay.index(states, "omega_r")],
                              z0[lay.block(states, "beta")], z0[lay.index(states, "tower_x")])
    ofcase.set_outlist(ed, ofcase.ELASTODYN_CHANNELS)
    for module in (ed, ofcase.module_file(fst, "AeroFile")):
        ofcase.no_node_outputs(module)
    _wind(rc, ofcase.module_file(fst, "InflowFile"), folder)
    lib, infile = controller_library(rc, folder / "controller")
    records = folder / "wtftc_plant_records.bin"
    # every path of the case relative to it, so that it reruns by hand once moved (the
    # run folder is written beside its final name and renamed into place)
    settings = plant_library.Settings(lib, infile, records, rc.p_turbine, rc.p_sensors,
                                      rc.faults if rc.faults else (), base=folder,
                                      actuator=rc.raw["openfast"]["actuator"],
                                      interval=dll_dt)
    steps = dll_dt / plant_library.ACTUATOR_DT
    if abs(steps - round(steps)) > 1e-9:  # the largest step that divides the interval whole
        settings.actuator_dt = dll_dt / math.ceil(steps)
    n_calls = int(round(rc.t_final / dll_dt)) + 2
    settings.noise = folder / "wtftc_noise.bin"
    settings.noise_columns = plant_library.noise_table(
        rc.seed, n_calls, dll_dt, Schedule(list(rc.faults), tuple(rc.p_turbine))
        if rc.faults else None, settings.noise)
    plant_in = settings.write(folder / "wtftc_plant.in")
    servo = ofcase.module_file(fst, "ServoFile")
    ofcase.set_values(servo, {
        "DLL_FileName": f'"{plant_library.build()}"',
        "DLL_InFile": f'"{os.path.relpath(plant_in, servo.parent)}"',
        "DLL_DT": f"{dll_dt:.9g}", "Ptch_Cntrl": "1"})
    return ofcase.Case(folder, fst, dt, dll_dt, plant_in, records)


#: what OpenFAST prints when a run ends well
NORMAL_END = "OpenFAST terminated normally"
#: the width at which OpenFAST wraps a message, breaking a word that does not fit
WRAP = 98


def simulate(case: ofcase.Case, progress: bool = True) -> tuple[float, str | None]:
    """OpenFAST on the case, in its folder (its screen output in ``openfast.log``):
    (wall time [s], None) when it ends normally, else OpenFAST's own message, one line.
    An output left in the folder by an earlier run is removed first, so that what is read
    after is this run's. Ctrl-C stops OpenFAST with it."""
    with suppress(FileNotFoundError):
        case.outb.unlink()
    wall, abort, _ = simulate_in(case.folder, case.fst)
    return wall, abort


def simulate_in(folder: Path, fst: Path, watch=None, every_s: float = 5.0
                ) -> tuple[float, str | None, str]:
    """OpenFAST on the main file ``fst`` in ``folder`` (its screen output in
    ``openfast.log``): (wall time [s], None or OpenFAST's message, one line, the screen
    output). ``watch(text)``, if given, is called every ``every_s`` with the screen output
    so far. OpenFAST runs under wtftc.programs' control: in its own process group, stopped
    with wtftc (Ctrl-C, SIGTERM, an exception, wtftc killed), within a time limit of
    :func:`wtftc.programs.openfast_limit_s` of the case's TMax (TimedOut past it), the
    folder locked meanwhile (FolderBusy for a second run into it); killed by a signal of
    another's, it raises ProgramKilled (the run is unfinished)."""
    folder = Path(folder)
    exe = install.require().openfast
    log = folder / "openfast.log"
    try:
        t_max = float(ofcase.get_value(Path(fst), "TMax"))
    except (EngineError, ConfigError, ValueError, OSError):
        t_max = 0.0
    limit = programs.openfast_limit_s(t_max)
    prog = programs.Program("OpenFAST", limit, f"{programs.OPENFAST_START_S:g} s + "
                            f"{programs.OPENFAST_PER_SIMULATED_S:g} x TMax = {t_max:g} s, or "
                            f"${programs.TIMEOUT_ENV}", f"rerun the case by hand in "
                            f"{folder} to see where it hangs, or set "
                            f"{programs.TIMEOUT_ENV} for a longer limit")
    look = (lambda: watch(_log_text(log))) if watch else None
    with programs.folder_lock(folder, "OpenFAST case folder") as lock:
        done = programs.run([str(exe), Path(fst).name], folder, log, prog, look, every_s,
                            pass_fds=(lock,))
    text = done.text()
    if NORMAL_END in text and done.code == 0:
        return done.wall_s, None, text
    return done.wall_s, abort_message(text, done.code, log), text


def _log_text(log: Path) -> str:
    try:
        return files.decode_text(log.read_bytes())
    except OSError:
        return ""


def abort_message(text: str, code: int, log: Path | None = None) -> str:
    """OpenFAST's reason for stopping, on one line, from its screen output: the lines from
    its last error line on (a message wraps over several), bells and blanks dropped; the
    signal that ended it, if one did; never empty (where OpenFAST said nothing, where its
    screen output is)."""
    text = re.sub(r"[\x00-\x08\x0b-\x1f]", " ", text.replace("\r", "\n"))
    lines = [ln.strip() for ln in text.split("\n") if ln.strip()]
    # OpenFAST's messages name their routine's path (FAST_Solution0:...:Routine: message);
    # a warning can come first, the error that stopped it is the last one
    sig = programs.signal_name(code)
    paths = [i for i, ln in enumerate(lines) if re.match(r"[A-Za-z_0-9]+:[A-Za-z_0-9]+:", ln)]
    first = paths[-1] if paths and not sig else None
    if first is None:  # ended by a crash: its runtime's words, never a warning before it
        first = next((i for i, ln in enumerate(lines) if re.search(
            r"signal|segmentation|floating.point|backtrace|abort" if sig else
            r"error|abort|strike|wtftc|fail|invalid", ln, re.IGNORECASE)), None)
    why = _unwrapped(lines[first:first + MESSAGE_LINES]) if first is not None else ""
    head = f"OpenFAST stopped (exit code {code}{f', {sig}' if sig else ''})"
    where = f"; its screen output is in {log}" if log is not None else ""
    if not why:
        return f"{head} with no message{where}"
    why = " ".join(why.split())
    if len(why) > MESSAGE_CHARS:
        why = why[:MESSAGE_CHARS] + f"... (cut{where or ''})"
    return f"{head}: {why}"


#: how much of OpenFAST's message the reason keeps: lines, characters
MESSAGE_LINES, MESSAGE_CHARS = 12, 2000


def _unwrapped(block_lines: list[str]) -> str:
    """One message from OpenFAST's lines: up to its closing lines, each line joined to the
    one before it with a space, or without one where the one before filled the width at
    which OpenFAST wraps (98 characters, a word broken where it does not fit)."""
    block: list[str] = []
    for ln in block_lines:
        if block and re.match(r"OpenFAST encountered|Aborting OpenFAST", ln):
            break
        block.append(ln)
    why = ""
    for k, ln in enumerate(block):
        cut = k and len(block[k - 1]) >= WRAP
        why += ("" if cut else " ") + ln
    return why.strip()


def read_outb(path: Path) -> dict[str, np.ndarray]:
    """OpenFAST's binary output as channel → series (openfast-io's FASTOutputFile)."""
    from openfast_io.FAST_output_reader import FASTOutputFile

    try:
        f = FASTOutputFile(str(path))
    except Exception as exc:  # noqa: BLE001 - struct.error, MemoryError: a cut or foreign file
        raise EngineError(f"OpenFAST's output {path} cannot be read ({type(exc).__name__}: "
                          f"{exc}): delete it and run the case again") from None
    return {n: f.data[:, i].astype(float) for i, n in enumerate(f.info["attribute_names"])}


def _held(t_rec: np.ndarray, x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """A series recorded at the calls ``t_rec``, held until the next call, at times ``t``."""
    i = np.searchsorted(t_rec, t + 1e-9, side="right") - 1
    return x[np.clip(i, 0, len(x) - 1)]


def _fine(rc, ch: dict, rec: dict) -> tuple[np.ndarray, dict]:
    """The metric series at every OpenFAST step (Result.full): the rotor and generator
    speeds, the blades, the low-speed shaft's torque, the tower base's moment and the
    blades' root flapwise bending moments (RootMyb1-3, ``blade_root_flap_j`` [N m]) as
    OpenFAST computes them, the FDI's latches as the library logged them."""
    t = ch["Time"]
    n_g = rc.param("gearbox_ratio")
    fine = {"omega_r": ch["RotSpeed"] * RPM, "omega_g": ch["GenSpeed"] * RPM / n_g,
            **{f"beta_{j}": np.radians(ch[f"BldPitch{j}"]) for j in lay.blades()},
            "tower_x": ch["TTDspFA"], "shaft_torque": ch["RotTorq"] * 1e3,
            "tower_moment": ch["TwrBsMyt"] * 1e3,
            **{f"blade_root_flap_{j}": ch[f"RootMyb{j}"] * 1e3 for j in lay.blades()}}
    for j in lay.blades():
        if f"latch_{j}" in rec:
            fine[f"fdi_latch_{j}"] = _held(rec["t"], rec[f"latch_{j}"], t)
    return t, fine


def _named_records(rc, rec: dict) -> dict:
    """The records with the controller's logged channels named (a wtftc library logs the
    FDI's latch, ρ̂ and ĉ per blade; ROSCO logs none)."""
    n_log = sum(k.startswith("logged_") for k in rec)
    if rc.loop.fdi and n_log == len(LOGGED) * lay.n_blades():
        k = 1
        for what in LOGGED:
            for j in lay.blades():
                rec[f"{what}_{j}"] = rec.pop(f"logged_{k}")
                k += 1
    return rec


def _outputs(rc, ch: dict, rec: dict, rows: np.ndarray, names: list[str]) -> np.ndarray:
    """The native engine's output columns at the rows ``rows`` of OpenFAST's output; NaN
    where OpenFAST has no counterpart."""
    t = ch["Time"][rows]
    n_g, eta = rc.param("gearbox_ratio"), rc.param("gen_efficiency")
    col = {k: ch[c][rows] * s for k, (c, s) in FROM_OUTB.items()}
    col.update(omega_g_hss=ch["GenSpeed"][rows] * RPM, T_gen=ch["GenTq"][rows] * 1e3 * n_g,
               P_gen=ch["GenPwr"][rows] * 1e3 / eta,  # the metrics multiply by η
               omega_r_meas=_held(rec["t"], rec["read_omega_r"], t))
    for j in lay.blades():
        col[f"beta_meas_{j}"] = _held(rec["t"], rec[f"read_beta_{j}"], t)
        col[f"v_{j}"] = col[f"pitch_cmd_{j}"] = _held(rec["t"], rec[f"v_{j}"], t)
        for what in LOGGED:
            if f"{what}_{j}" in rec:
                col[f"fdi_{what}_{j}"] = _held(rec["t"], rec[f"{what}_{j}"], t)
    # the library logs no u0: the mean of the blade demands stands for the mean pitch command
    col["u0"] = np.mean([col[f"v_{j}"] for j in lay.blades()], axis=0)
    col["y_d"] = np.full(len(rows), rc.reference)
    out = np.full((len(rows), len(names)), np.nan)
    for i, n in enumerate(names):
        if n in col:
            out[:, i] = col[n]
    return out


def _check_length(case: ofcase.Case, ch: dict, t_final: float, whole: bool) -> None:
    """An output that is not this case's is refused: more time than its TMax, or more rows
    than its steps (DT_Out is DT), or times not rising from 0 by DT; or, where OpenFAST
    said it ended normally (``whole``), fewer rows than its steps."""
    t = ch.get("Time")
    if t is None or len(t) == 0:
        return  # the channels' check names it
    rows = int(math.floor(t_final / case.dt + 1e-6)) + 1
    tol = 1e-6 * max(1.0, t_final) + 1e-3 * case.dt
    steady = bool(np.all(np.isfinite(t))) and abs(float(t[0])) <= tol and not (
        len(t) > 1 and np.any(np.abs(np.diff(t) - case.dt) > tol))
    bad = (f"{len(t)} rows for a case of {rows}" if len(t) > rows else
           f"time up to {float(np.max(t)):.9g} s past the case's TMax = {t_final:.9g} s"
           if float(np.max(t)) > t_final + tol else
           "times that do not rise from 0 by the case's DT" if not steady else
           f"{len(t)} rows for a case of {rows}, and OpenFAST said it ended normally"
           if whole and len(t) < rows else None)
    if bad is not None:
        raise EngineError(f"{case.outb} is not this case's output ({bad}): delete it and "
                          "run the case again")


def result(rc, case: ofcase.Case, wall: float, abort: str | None) -> integrate.Result:
    """The run as a Result with the native engine's columns; an abort of OpenFAST, or the
    rotor leaving wtftc's envelope, is a lost run (``diverged``) ending there."""
    if not case.outb.is_file():
        raise EngineError(abort or f"OpenFAST wrote no output ({case.outb})")
    ch = read_outb(case.outb)
    _check_length(case, ch, rc.t_final, abort is None)
    missing = [c for c in (*ofcase.ELASTODYN_CHANNELS, *ofcase.OTHER_CHANNELS, "Time")
               if c not in ch]
    if missing:
        raise EngineError(f"{case.outb} lacks the channel(s) {', '.join(missing)}: the "
                          "deck's AeroDyn, InflowWind or ServoDyn OutList must have them")
    rec = _named_records(rc, plant_library.read_records(case.records))
    t, fine = _fine(rc, ch, rec)
    env = integrate.Envelope.of(rc.loop)
    w = fine["omega_r"]
    out_of = np.nonzero((w > env.high) | (w < env.low))[0]
    end = int(out_of[0]) + 1 if len(out_of) else len(t)
    diverged = None
    if len(out_of) or abort:
        reason = env.reason(float(w[end - 1])) if len(out_of) else abort
        diverged = {"t_s": float(t[end - 1]), "reason": reason, "last_finite_state": {
            k: float(v[end - 1]) for k, v in fine.items()}}
    t = t[:end]
    fine = {k: v[:end] for k, v in fine.items()}
    every = max(1, int(round(rc.decimate * rc.dt / case.dt)))
    rows = np.arange(0, end, every)
    names = [n for n, _ in rhs.output_spec(rc.controller, rc.loop.fdi, rc.plant)]
    return integrate.Result(
        t=t[rows], outputs=_outputs(rc, ch, rec, rows, names), z_final=np.array([]),
        diverged=diverged, wall_s=wall, steps=int(round(t[-1] / rc.dt)),
        full=np.column_stack(list(fine.values())), full_names=list(fine), dt=case.dt,
        schedule=Schedule(list(rc.faults), tuple(rc.p_turbine)) if rc.faults else None,
        names=names)


def kept_failure(exc: EngineError, case: Path, keep: Path) -> EngineError:
    """``exc`` (of its own class) saying where the failed case and OpenFAST's screen output
    are kept: the case folder moved to ``keep`` (a failure before, of the same case,
    replaced), so that the removal of the folder it was in takes neither."""
    log = keep / "openfast.log"
    try:
        keep.parent.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(keep, ignore_errors=True)
        shutil.move(str(case), str(keep))
    except OSError:
        return exc
    where = (f"OpenFAST's screen output is in {log}" if log.is_file() else
             "OpenFAST did not run")
    said = str(exc).replace(str(case), str(keep))  # the paths it names, where they are now
    kept = type(exc)(f"{said}; {where} (the case, to rerun by hand: {keep})")
    kept.__cause__ = exc.__cause__
    return kept


def _failed_case_home(rc) -> Path:
    """Where a failed case of a run being written beside its --out is kept (that folder is
    removed, and the message would name files no longer there): the cache's
    ``openfast_failed/<label>-<time>-<process>``."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    return cache_dir() / "openfast_failed" / f"{rc.label}-{stamp}-{os.getpid()}"


def run(rc, folder: Path, progress: bool = True) -> integrate.Result:
    """``rc`` in OpenFAST, its case and outputs in ``folder``, which no other run may use
    meanwhile (wtftc.programs.folder_lock, from writing the case to reading its output).
    Where ``folder`` lies in a folder being written (``.<name>.*.partial``, removed when
    the run fails), a failed case is kept in the cache and the message says where."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    with programs.folder_lock(folder, "OpenFAST case folder"):
        case = prepare(rc, folder)
        try:
            wall, abort = simulate(case, progress)
            res = result(rc, case, wall, abort)
        except EngineError as exc:
            if not any(p.name.endswith(".partial") for p in folder.resolve().parents):
                raise
            raise kept_failure(exc, case.folder, _failed_case_home(rc)) from None
    res.config = {**rc.raw, "wind_resolved": rc.wind.describe(),
                  "fault_resolved": res.schedule.describe() if res.schedule else [],
                  "openfast": {"version": install.VERSION, "dt_s": case.dt,
                               "dll_dt_s": case.dll_dt, "wall_s": wall,
                               # the main file within the run folder (the folder is made
                               # under a temporary name, then renamed)
                               "case": f"{Path(folder).name}/{case.fst.name}"}}
    return res
