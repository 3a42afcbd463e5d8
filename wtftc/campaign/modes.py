"""``wtftc modes``: wtftc's open-loop plant modes against OpenFAST's linearization
(issue 33 item 2; ours; docs/validation.md).

At each steady wind:

* **wtftc**: the operating point and open-loop plant A_p of ``wtftc linearize``
  (wtftc.campaign.linearize, the PI settling the loop; the plant alone is compared), its
  modes, each named by the participation of the plant's states (the layout's names):
  the pitch actuator's modes (``beta*``) left out, the drivetrain the mode where the
  generator swings against the shaft's twist (``omega_g`` against ``theta_s``), the tower
  the largest share of ``tower_*``;
* **OpenFAST**: the turbine's deck linearized at the same wind from wtftc's operating
  point (wtftc.openfast.linearization, cached), MBC3, averaged over the azimuths, the
  generator azimuth removed (wtftc.openfast.lin_modes), the drivetrain and the first tower
  fore-aft and side-to-side modes named by participation.

The frequencies are compared against issue 33's goal (within 3 %); the damping is shown
beside them. Every OpenFAST mode is listed too, with its dominant degrees of freedom.
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.campaign import linearize
from wtftc.errors import ConfigError
from wtftc.openfast import lin_modes
from wtftc.openfast import linearization as oflin
from wtftc.sim.rhs import PLANTS

#: the compared modes, in table order, with their names in the outputs
COMPARED = {"drivetrain": "drivetrain (generator against rotor)",
            "tower_fa": "1st tower fore-aft", "tower_ss": "1st tower side-to-side"}
#: the controller that settles wtftc's loop to its operating point (the plant is compared)
SETTLING_CONTROLLER = "pi"
#: the azimuths per wind `wtftc modes` accepts (OpenFAST's NLinTimes with CalcSteady, equally
#: spaced over one revolution): 2 at least (OpenFAST's least with CalcSteady); 36, one every
#: 10°, at most: the azimuth average of MBC3 keeps only the rotor's low harmonics, which a
#: few azimuths resolve (docs/validation.md: 6 against 12), and each is one more
#: linearization with its own .lin file (about 5 minutes on the IEA 15-MW)
AZIMUTH_RANGE = (2, 36)


def check_azimuths(n, flag: str = "--azimuths") -> int:
    """``n`` if it is a whole number of azimuths within :data:`AZIMUTH_RANGE`, else one
    line naming ``flag``."""
    lo, hi = AZIMUTH_RANGE
    if isinstance(n, bool) or not isinstance(n, int) or not lo <= n <= hi:
        raise ConfigError(flag, n, f"an integer in [{lo}, {hi}]: OpenFAST's CalcSteady "
                          f"linearizes at {lo} azimuths at least, and {hi} (every "
                          f"{360 // hi}°) already resolve what MBC3 keeps; each is one more "
                          "linearization")
    return n


def tower_plants() -> list[str]:
    """The plants with a tower (wtftc.sim.rhs.PLANTS), which ``wtftc modes`` compares."""
    return [p for p, d in PLANTS.items() if d.get("tower")]


def _share(m: dict, prefix: str) -> float:
    return sum(v for k, v in m["share"].items() if k.startswith(prefix))


def wtftc_modes(raw: dict, wind: float) -> tuple:
    """(operating point, every open-loop plant mode, the compared ones by name) of wtftc's
    plant ``raw["plant"]`` at ``wind`` [m/s]."""
    op = linearize.operating_point({**raw, "controller": SETTLING_CONTROLLER}, wind)
    names = lay.names(PLANTS[raw["plant"]]["states"])
    ms = lin_modes.modes(op.A_p, names)
    elastic = [m for m in ms if _share(m, "beta") < 0.5]
    i_t, i_g = names.index("theta_s"), names.index("omega_g")

    def ratio(m):  # twist / generator angle (the angle: ω_g's entry / λ)
        v = m["vector"]
        return complex(v[i_t] * m["eigenvalue"] / v[i_g]) if v[i_g] else 0j

    found = {"drivetrain": lin_modes.drivetrain(elastic, lambda m: m["share"]["theta_s"],
                                                ratio),
             "tower_fa": max((m for m in elastic if _share(m, "tower_") > 0),
                             key=lambda m: _share(m, "tower_"), default=None),
             "tower_ss": None}
    return op, ms, found


def guess(op, raw: dict, found: dict) -> oflin.Guess:
    """OpenFAST's start and targets from wtftc's operating point ``op``."""
    from wtftc import config
    states = PLANTS[raw["plant"]]["states"]
    rc = config.make_config({**raw, "controller": SETTLING_CONTROLLER})
    gear = rc.param("gearbox_ratio")
    f_max = max(m["f_hz"] for m in found.values() if m is not None)
    return oflin.Guess(omega_r=float(op.z[lay.index(states, "omega_r")]), pitch=op.pitch,
                       tower_x=float(op.z[lay.index(states, "tower_x")]),
                       torque_hss=rc.param("gen_torque_rated") / gear, gearbox=gear,
                       f_max=f_max)


def _mode_record(m: dict) -> dict:
    return {"f_hz": m["f_hz"], "zeta": m["zeta"],
            "dominant": [[n, round(p, 4)] for n, p in lin_modes.dominant(m)]}


def compare_rows(of_found: dict, wt_found: dict) -> list[dict]:
    """Per compared mode either model has: OpenFAST's and wtftc's frequency [Hz] and
    damping [-] (None where a model lacks the mode), the frequency difference wtftc /
    OpenFAST − 1 [%] and the verdict against the 3 % goal."""
    rows = []
    for key, label in COMPARED.items():
        o, w = of_found.get(key), wt_found.get(key)
        if o is None and w is None:
            continue
        diff = 100 * (w["f_hz"] / o["f_hz"] - 1) if o and w else None
        verdict = ("not in OpenFAST's model" if o is None else "not modelled by wtftc"
                   if w is None else "within 3 %" if abs(diff) <= 100 *
                   lin_modes.FREQUENCY_GOAL else "differs by more than 3 %")
        rows.append({"mode": key, "label": label,
                     "openfast_f_hz": o and o["f_hz"], "openfast_zeta": o and o["zeta"],
                     "wtftc_f_hz": w and w["f_hz"], "wtftc_zeta": w and w["zeta"],
                     "f_difference_pct": diff, "verdict": verdict})
    return rows


def one_wind(raw: dict, deck: Path, wind: float, dofs: str, n_az: int, out: Path,
             progress: bool) -> dict:
    """One wind's comparison; the .lin files copied into ``out/lin/<wind>mps/``."""
    if progress:
        print(f"  {wind:g} m/s: wtftc's operating point and plant modes", file=sys.stderr,
              flush=True)
    op, wt_all, wt_found = wtftc_modes(raw, wind)
    lin = oflin.linearize(deck, wind, dofs, n_az, guess(op, raw, wt_found), progress)
    A, names = lin_modes.averaged(lin_modes.read(lin.files))
    of_all = lin_modes.modes(A, names)
    of_found = lin_modes.find(of_all, names)
    keep = out / "lin" / f"{wind:g}mps"
    keep.mkdir(parents=True, exist_ok=True)
    for f in lin.files:
        shutil.copy2(f, keep / f.name)
    rows = compare_rows(of_found, wt_found)
    if progress:
        print("  " + f"{wind:g} m/s: " + "; ".join(
            f"{r['mode']} {r['f_difference_pct']:+.1f} %" for r in rows
            if r["f_difference_pct"] is not None), file=sys.stderr, flush=True)
    states = lay.names(PLANTS[raw["plant"]]["states"])
    return {"wind_mps": wind, "compare": rows,
            "openfast": {"pitch_deg": float(np.mean(lin.pitch_deg)),
                         "rotor_rpm": float(np.mean(lin.rotor_rpm)), "trim_s": lin.trim_s,
                         "wall_s": lin.wall_s, "cached": lin.cached,
                         "lin_files": [f"lin/{wind:g}mps/{f.name}" for f in lin.files],
                         "modes": [_mode_record(m) for m in of_all]},
            "wtftc": {"pitch_deg": float(np.degrees(op.pitch)),
                      "rotor_rpm": float(op.z[states.index("omega_r")] * 30 / np.pi),
                      "modes": [_mode_record(m) for m in wt_all]}}


CSV_HEAD = ("wind_mps,mode,openfast_f_hz,openfast_zeta,wtftc_f_hz,wtftc_zeta,"
            "f_difference_pct,verdict")


def _num(x) -> str:
    return "" if x is None else f"{float(x):.6g}"


def csv_text(winds: list[dict]) -> str:
    """modes.csv: one row per wind and compared mode, plain numbers (empty: absent)."""
    lines = [CSV_HEAD]
    for w in winds:
        lines += [",".join([_num(w["wind_mps"]), r["mode"], *(_num(r[k]) for k in (
            "openfast_f_hz", "openfast_zeta", "wtftc_f_hz", "wtftc_zeta",
            "f_difference_pct")), r["verdict"]]) for r in w["compare"]]
    return "\n".join(lines) + "\n"


def _md_cell(x, fmt: str) -> str:
    return "—" if x is None else format(x, fmt)


def markdown(doc: dict) -> str:
    """modes.md: the comparison per wind, then every OpenFAST mode."""
    md = [f"# Modes: {doc['turbine']}, wtftc plant `{doc['plant']}` against OpenFAST "
          f"{doc['openfast_version']} ({doc['dofs']} DOFs, {doc['azimuths']} azimuths)", "",
          "| wind [m/s] | mode | OpenFAST f [Hz] | OpenFAST ζ [-] | wtftc f [Hz] | "
          "wtftc ζ [-] | f difference [%] | verdict |", "|---|---|---|---|---|---|---|---|"]
    for w in doc["winds"]:
        md += [f"| {w['wind_mps']:g} | {r['label']} | {_md_cell(r['openfast_f_hz'], '.4f')} "
               f"| {_md_cell(r['openfast_zeta'], '.4f')} | {_md_cell(r['wtftc_f_hz'], '.4f')} "
               f"| {_md_cell(r['wtftc_zeta'], '.4f')} | "
               f"{_md_cell(r['f_difference_pct'], '+.1f')} | {r['verdict']} |"
               for r in w["compare"]]
    md += ["", "Operating points: " + "; ".join(
        f"{w['wind_mps']:g} m/s OpenFAST {w['openfast']['rotor_rpm']:.2f} rpm, pitch "
        f"{w['openfast']['pitch_deg']:.2f}° (wtftc {w['wtftc']['rotor_rpm']:.2f} rpm, "
        f"{w['wtftc']['pitch_deg']:.2f}°)" for w in doc["winds"]) + "."]
    for w in doc["winds"]:
        md += ["", f"## Every OpenFAST mode at {w['wind_mps']:g} m/s", "",
               "| f [Hz] | ζ [-] | dominant DOFs (participation) |", "|---|---|---|"]
        md += [f"| {m['f_hz']:.4f} | {m['zeta']:.4f} | " + ", ".join(
            f"{n} {p:.2f}" for n, p in m["dominant"]) + " |" for m in w["openfast"]["modes"]]
    return "\n".join(md) + "\n"


def run_modes(raw: dict, deck: Path, winds, dofs: str, n_az: int, out_dir,
              progress: bool = True) -> dict:
    """Every wind's comparison, written into ``out_dir`` (modes.json, modes.csv,
    modes.md, lin/): swapped in whole (wtftc.files.owned_folder)."""
    from wtftc.files import owned_folder
    from wtftc.openfast import install
    from wtftc.results.io import atomic_write_json, atomic_write_text

    check_azimuths(n_az, "azimuths")
    with owned_folder(out_dir, "--out", command="modes") as tmp:
        doc = {"turbine": raw.get("turbine", "nrel5mw"), "plant": raw["plant"],
               "dofs": dofs, "azimuths": n_az, "openfast_version": install.require().version,
               "frequency_goal_pct": 100 * lin_modes.FREQUENCY_GOAL,
               "winds": [one_wind(raw, deck, float(w), dofs, n_az, tmp, progress)
                         for w in winds]}
        atomic_write_json(tmp / "modes.json", json.loads(json.dumps(doc)))
        atomic_write_text(tmp / "modes.csv", csv_text(doc["winds"]))
        atomic_write_text(tmp / "modes.md", markdown(doc))
    return doc
