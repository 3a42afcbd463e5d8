"""OpenFAST's linearization of a turbine's deck at a steady wind (issue 33 item 2; ours).

The deck is copied (wtftc.openfast.case.copy_deck) and edited to linearize the open-loop
turbine above rated, at the periodic steady state OpenFAST finds by itself:

* the main file: ``Linearize``, ``CalcSteady`` with ``TrimCase 3`` (the collective pitch
  trimmed to hold the rotor speed at ElastoDyn's initial ``RotSpeed``: above rated only),
  ``TrimTol`` 1e-3 (1e-4 never converged: the trim loop itself wanders ±0.05°),
  ``TrimGain`` 0.001 rad/(rad/s), the trim's extra tower and blade damping (not in the
  linear model), ``NLinTimes`` azimuths equally spaced in one revolution; the tower
  clamped at its base (no substructure), as wtftc's tower plant is;
* ElastoDyn: the degrees of freedom of ``dofs`` (:data:`DOF_SETS`), the initial rotor
  speed, pitch and tower-top displacement of wtftc's own operating point;
* ServoDyn: no DISCON library (OpenFAST cannot linearize one): ``PCMode 0``,
  ``VSContrl 1`` with the rated torque above 99 % of the rated generator speed (constant
  torque at the operating point, as wtftc's plant), and ``PitNeut`` the expected pitch
  (OpenFAST 5.0 commands it with PCMode 0, not ElastoDyn's BlPitch: left at 0° the trim
  drove the pitch to −96° and OpenFAST stopped);
* AeroDyn: quasi-steady equilibrium-wake BEM (``Wake_Mod 1``, ``DBEMT_Mod 0``,
  ``UA_Mod 0``, no nacelle drag): no aerodynamic states, as wtftc's Cp/Ct tables;
* InflowWind: steady uniform wind, no shear (``WindType 1``, ``PLexp 0``).

The ``.lin`` files are cached in wtftc's cache (``openfast_lin/<key>/``), the key a hash
of the written case's files (the deck's contents, the wind, the DOFs, the azimuths, the
initial conditions rounded) and OpenFAST's version: a second call is instant. A trim that
does not converge (OpenFAST: "Steady state not found", then one forced linearization) is
:class:`TrimNotConverged`, never cached or used.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from wtftc import files
from wtftc.artefacts.loader import built_once, cache_dir
from wtftc.errors import EngineError
from wtftc.openfast import case as ofcase
from wtftc.openfast import engine, install

#: ElastoDyn's degrees of freedom: "rigid" is wtftc's plant (generator, shaft twist,
#: first tower fore-aft mode; blades rigid, MBC3 the identity), "full" every blade, tower
#: and drivetrain DOF (yaw, teeter and platform off)
_ALL = ("FlapDOF1", "FlapDOF2", "EdgeDOF", "TeetDOF", "DrTrDOF", "GenDOF", "YawDOF",
        "TwFADOF1", "TwFADOF2", "TwSSDOF1", "TwSSDOF2")
DOF_SETS = {
    "rigid": ("GenDOF", "DrTrDOF", "TwFADOF1"),
    "full": ("FlapDOF1", "FlapDOF2", "EdgeDOF", "DrTrDOF", "GenDOF", "TwFADOF1", "TwFADOF2",
             "TwSSDOF1", "TwSSDOF2"),
}
#: azimuths per operating point by default: rigid, no rotating state, 2 (OpenFAST's least
#: with CalcSteady); full, 6 (docs/validation.md: against 12)
AZIMUTHS = {"rigid": 2, "full": 6}
#: TrimTol, TrimGain [rad/(rad/s)], Twr_Kdmp [N/(m/s)], Bld_Kdmp [N/(m/s)]
TRIM = {"TrimCase": "3", "TrimTol": "0.001", "TrimGain": "0.001", "Twr_Kdmp": "100000",
        "Bld_Kdmp": "10000"}
#: the trim's longest simulated time: this many rotor revolutions, at least TRIM_MIN_S
TRIM_REVOLUTIONS, TRIM_MIN_S = 25, 90.0
#: ω·DT at the fastest mode kept at most this (ElastoDyn's ABM4; the IEA 15-MW's direct-
#: drive shaft is 31 Hz: DT 5 ms gives 0.98, marginal)
OMEGA_DT_MAX = 0.5
NOT_FOUND = "Steady state not found"


class TrimNotConverged(EngineError):
    """OpenFAST's trim found no steady state within TMax: its linearization is not used."""


@dataclass(frozen=True)
class Guess:
    """wtftc's operating point, OpenFAST's start and targets: rotor speed [rad/s] (the
    trim's target), pitch [rad], tower-top fore-aft displacement [m], generator torque on
    the high-speed shaft [N m], gearbox ratio [-], the fastest mode to resolve [Hz]."""

    omega_r: float
    pitch: float
    tower_x: float
    torque_hss: float
    gearbox: float
    f_max: float


@dataclass
class Lin:
    """One operating point's linearization: its .lin files (in the cache), the pitch [deg]
    and rotor speed [rpm] at each, the simulated time of the trim [s], OpenFAST's wall
    time when it ran [s], whether it came from the cache."""

    files: list[Path]
    pitch_deg: list[float]
    rotor_rpm: list[float]
    trim_s: float
    wall_s: float
    cached: bool


def _main_file(fst: Path, wind: float, n_az: int, g: Guess, dt0: float) -> None:
    n = max(1, math.ceil(dt0 * 2 * math.pi * g.f_max / OMEGA_DT_MAX - 1e-9))
    period = 2 * math.pi / g.omega_r
    ofcase.set_values(fst, {
        "Echo": "False", "TMax": f"{max(TRIM_MIN_S, TRIM_REVOLUTIONS * period):.6g}",
        "DT": f"{dt0 / n:.9g}", "OutFileFmt": "2", "DT_Out": '"default"',
        "Linearize": "True", "CalcSteady": "True", "NLinTimes": str(n_az),
        "LinInputs": "1", "LinOutputs": "0", "LinOutJac": "False", "LinOutMod": "False",
        "WrVTK": "0", **TRIM})


def _modules(fst: Path, wind: float, dofs: str, g: Guess) -> None:
    ed, sd = ofcase.module_file(fst, "EDFile"), ofcase.module_file(fst, "ServoFile")
    ofcase.clamp_fixed_bottom(fst, ed)
    pitch_deg = f"{math.degrees(g.pitch):.2f}"
    ofcase.set_values(ed, {**{k: str(k in DOF_SETS[dofs]) for k in _ALL},
                           "RotSpeed": f"{g.omega_r * 30 / math.pi:.6g}",
                           "TTDspFA": f"{g.tower_x:.3f}",
                           **{f"BlPitch({j})": pitch_deg for j in (1, 2, 3)}})
    ofcase.set_outlist(ed, ofcase.ELASTODYN_CHANNELS)
    ofcase.no_node_outputs(ed)
    ofcase.no_node_outputs(ofcase.module_file(fst, "AeroFile"))
    rated_rpm = 0.99 * g.omega_r * g.gearbox * 30 / math.pi
    ofcase.set_values(sd, {
        "PCMode": "0", "VSContrl": "1", "GenModel": "1", "GenTiStr": "True",
        "GenTiStp": "True", "TimGenOn": "0", "TimGenOf": "9999.9", "HSSBrMode": "0",
        "YCMode": "0", "VS_RtGnSp": f"{rated_rpm:.6g}", "VS_RtTq": f"{g.torque_hss:.8g}",
        "VS_Rgn2K": f"{0.8 * g.torque_hss / rated_rpm ** 2:.6g}", "VS_SlPc": "10",
        **{f"PitNeut({j})": pitch_deg for j in (1, 2, 3)}})
    ofcase.set_values(ofcase.module_file(fst, "AeroFile"), {
        "Wake_Mod": "1", "DBEMT_Mod": "0", "UA_Mod": "0", "NacelleDrag": "False"})
    ofcase.set_values(ofcase.module_file(fst, "InflowFile"), {
        "WindType": "1", "HWindSpeed": f"{wind:.6g}", "PLexp": "0"})


def write_case(deck: Path, folder: Path, wind: float, dofs: str, n_az: int,
               g: Guess) -> Path:
    """The linearization case of ``deck`` at ``wind`` [m/s] written into ``folder``; its
    main file."""
    fst = ofcase.copy_deck(Path(deck), folder)
    _main_file(fst, wind, n_az, g, float(ofcase.get_value(fst, "DT")))
    _modules(fst, wind, dofs, g)
    return fst


def case_key(fst: Path, version: str) -> str:
    """The hash of every file the case's main file names, to the end (by its path within
    the case), and OpenFAST's version."""
    h = hashlib.sha256(f"openfast {version}\n".encode())
    root = fst.resolve().parent
    for path, (data, _) in sorted(ofcase._deck_files(fst).items()):
        h.update(f"{path.relative_to(root).as_posix()} {len(data)}\n".encode())
        h.update(data)
    return h.hexdigest()[:24]


#: OpenFAST's line at each linearization: simulated time, rotor speed [rpm], pitch [deg]
_LINE = re.compile(r"Performing linearization (\d+) at simulation time ([-0-9.eE+]+) s\. "
                   r"\(RotSpeed=([-0-9.eE+]+) rpm, BldPitch1=([-0-9.eE+]+) deg\)")
_TIME = re.compile(r"Time: ([0-9.]+) of ([0-9.]+) seconds")


def _watcher(label: str, n_az: int):
    seen = {"line": ""}

    def watch(text: str) -> None:
        lins = _LINE.findall(text)
        times = _TIME.findall(text)
        line = (f"  {label}: linearizing at azimuth {len(lins)} of {n_az}" if lins else
                f"  {label}: trimming, {times[-1][0]} of at most {times[-1][1]} s "
                "simulated" if times else f"  {label}: starting OpenFAST")
        if line != seen["line"]:
            print(line, file=sys.stderr, flush=True)
            seen["line"] = line
    return watch


def _run(fst: Path, out: Path, label: str, n_az: int, progress: bool) -> None:
    """OpenFAST on the case ``fst``; its .lin files, screen output and a record of the
    operating points into ``out``."""
    wall, abort, text = engine.simulate_in(fst.parent, fst,
                                           _watcher(label, n_az) if progress else None)
    if NOT_FOUND in text:
        raise TrimNotConverged(
            f"{label}: OpenFAST's trim (TrimCase 3, pitch; TrimTol {TRIM['TrimTol']}) found "
            f"no steady state within TMax = {ofcase.get_value(fst, 'TMax')} s ('{NOT_FOUND}'"
            "): its linearization is not used. The pitch trim needs a wind above rated")
    if abort:
        raise EngineError(f"{label}: {abort}")
    lins = sorted(fst.parent.glob(f"{fst.stem}.*.lin"), key=lambda p: int(p.suffixes[-2][1:]))
    rows = _LINE.findall(text)
    if len(lins) != n_az or len(rows) != n_az:
        raise EngineError(f"{label}: OpenFAST wrote {len(lins)} .lin files, {n_az} expected")
    for p in lins:
        shutil.copy2(p, out / p.name)
    (out / "openfast.log").write_text(text)
    (out / "lin.json").write_text(json.dumps({
        "files": [p.name for p in lins], "wall_s": wall, "trim_s": float(rows[0][1]),
        "rotor_rpm": [float(r[2]) for r in rows], "pitch_deg": [float(r[3]) for r in rows]},
        indent=1) + "\n")


def linearize(deck: Path, wind: float, dofs: str, n_az: int, g: Guess,
              progress: bool = True) -> Lin:
    """OpenFAST's linearization of ``deck`` at ``wind`` [m/s] with the DOFs ``dofs`` at
    ``n_az`` azimuths (≥ 2), from wtftc's operating point ``g``: from the cache, else run
    (a few minutes) and cached."""
    inst = install.require()
    root = cache_dir() / "openfast_lin"
    root.mkdir(parents=True, exist_ok=True)
    label = f"{wind:g} m/s, {dofs} DOFs"
    with files.sigterm_as_interrupt():  # a killed run leaves no work folder in the cache
        work = Path(tempfile.mkdtemp(prefix=".work-", dir=root))
        try:
            fst = write_case(deck, work / "case", wind, dofs, n_az, g)
            folder = root / case_key(fst, inst.version)
            # reported as cached only when whole: a damaged entry is about to be rebuilt
            cached = folder.is_dir() and files.seal_damage(folder) is None
            try:
                built_once(folder, "lin.json",
                           lambda tmp: _run(fst, tmp, label, n_az, progress))
            except EngineError as exc:
                raise engine.kept_failure(exc, fst.parent, root / f"failed-{folder.name}") from None
        finally:
            shutil.rmtree(work, ignore_errors=True)
    rec = json.loads((folder / "lin.json").read_text())
    return Lin([folder / f for f in rec["files"]], rec["pitch_deg"], rec["rotor_rpm"],
               rec["trim_s"], rec["wall_s"], cached)
