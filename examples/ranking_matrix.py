"""The ranking test: do wtftc's reduced plants rank the controllers as OpenFAST does? Run
from the repository, one engine a call, then the ranking:

    python examples/ranking_matrix.py openfast OUT/openfast      # 36 runs: 50 min, 2 workers
    python examples/ranking_matrix.py tower_edge OUT/tower_edge  # 36 runs: 4.5 min, 1 process
    python examples/ranking_matrix.py tower OUT/tower            # 36 runs: 4.3 min
    python examples/ranking_matrix.py tower_edge_blades OUT/tower_edge_blades  # the same,
                                                   # on the blades' wind (docs/wind.md)
    python examples/ranking_matrix.py rank OUT                   # OUT/ranking.md, .json

The NREL 5-MW; ROSCO, the PI and the physical AFTC (with wtftc's FDI where a fault is
present: the preset physical-plain), each at two tunings: its default (ROSCO its deck's
(ω_n, ζ) = (0.6, 0.7), the PI the same, the physical AFTC its hand gains, (0.74, 0.72))
and a faster target (0.9, 0.7) for all three (``*_fast``: the columns' tables set the
pitch loop's target mode, solved by wtftc.campaign.tune.resolve);
× NTM class B at 8, 12, 16 and 20 m/s fault-free, a runaway of blade 1 to 0° at 16 m/s
and blade 1 locked where it is at 12 m/s (both from 20 s); seed 0, 120 s, the realistic
profile. Every NTM cell of every engine reads the same TurbSim field (OpenFAST's wind).
Each engine's matrix is three `compare` trees (fault_free/, runaway_16/, lock_12/).
The wall times above were measured on 2 cores shared with another developer's OpenFAST
runs (load average 4-7), the native runs beside the OpenFAST ones.
"""

import json
import sys
import time
from pathlib import Path

from wtftc.campaign import compare, ranking

T_FINAL_S, SEED = 120.0, 0
FAST = (0.9, 0.7)  # the second tuning: the pitch loop's target (ω_n [rad/s], ζ)
#: the columns: each controller at its default tuning and at FAST (a [controller] table)
BASE = {"rosco": "rosco", "pi": "pi", "physical_fdi": "physical-plain"}
CONTROLLERS = [*({"name": n, "preset": p} for n, p in BASE.items()),
               *({"name": f"{n}_fast", "preset": p, "omega_n_rad_s": FAST[0], "zeta": FAST[1]}
                 for n, p in BASE.items())]
#: the three compare trees: winds × one fault each
PARTS = {"fault_free": (["ntm_B_8", "ntm_B_12", "ntm_B_16", "ntm_B_20"], "none"),
         "runaway_16": (["ntm_B_16"], "runaway"), "lock_12": (["ntm_B_12"], "lock")}
ENGINES = {"openfast": ("openfast", compare.PLANT), "tower_edge": ("wtftc", "tower_edge"),
           "tower": ("wtftc", "tower"), "tower_edge_blades": ("wtftc", "tower_edge")}
#: the engines whose NTM cells read the field as the blades sample it (the others: the disk)
BLADES = ("tower_edge_blades",)
#: wtftc's plants ranked against OpenFAST, those run so far (a folder under OUT)
PLANTS = ("tower_edge_blades", "tower_edge", "tower")


def register() -> None:
    """The matrix's winds (every NTM on the TurbSim field)."""
    for v in (8.0, 20.0):
        compare.WINDS[f"ntm_B_{v:g}"] = {"kind": "ntm", "mean_mps": v, "turbulence_class": "B"}
    for name, table in compare.WINDS.items():
        if table["kind"] == "ntm":
            compare.WINDS[name] = {**table, "field": "turbsim"}


def run(which: str, out: Path) -> None:
    engine, plant = ENGINES[which]
    if which in BLADES:
        for name, table in compare.WINDS.items():
            if table["kind"] == "ntm":
                compare.WINDS[name] = {**table, "rotor_wind": "blades"}
    walls = {}
    for part, (winds, fault) in PARTS.items():
        t0 = time.time()
        compare.run_compare(out / part, controllers=CONTROLLERS, faults=[fault], winds=winds,
                            t_final=T_FINAL_S, seed=SEED, engine=engine, plant=plant,
                            workers=2 if engine == "openfast" else None)
        walls[part] = time.time() - t0
        print(f"{which} {part}: {walls[part]:.0f} s wall", flush=True)
    (out / "wall_s.json").write_text(json.dumps(walls, indent=1) + "\n")


#: the tunings ranked apart as well: three controllers at a time
TUNINGS = {"default": ["rosco", "pi", "physical_fdi"],
           "fast": ["rosco_fast", "pi_fast", "physical_fdi_fast"]}
#: the metrics' tables in the units shown: key → (scale, format)
SHOWN = {"rms_speed_error_rad_s": (1.0, "{:.4f}"), "shaft_torque_del_1hz_Nm": (1e6, "{:.2f}"),
         "tower_base_del_1hz_Nm": (1e6, "{:.1f}"), "pitch_adc": (1.0, "{:.2f}"),
         "overspeed_peak_over_rated": (1.0, "{:.3f}")}


def _only(table: dict, ctrls: list[str]) -> dict:
    return {s: {c: m for c, m in cells.items() if c in ctrls} for s, cells in table.items()}


def rank(out: Path) -> None:
    """Each plant against OpenFAST, the six variants together and each tuning's three
    apart: OUT/ranking.md and OUT/ranking.json."""
    tables = {e: ranking.read_compare([out / e / p for p in PARTS]) for e in ENGINES
              if (out / e).is_dir()}
    md, js = [], {}
    for plant in (p for p in PLANTS if p in tables):
        rows = ranking.agreement_table(tables[plant], tables["openfast"])
        js[plant] = {"all": {"rows": rows, "summary": ranking.summary(rows)}}
        md += [f"## {plant} against OpenFAST: the six variants", "",
               ranking.summary_markdown(rows), ""]
        for tuning, ctrls in TUNINGS.items():
            sub = ranking.agreement_table(_only(tables[plant], ctrls),
                                          _only(tables["openfast"], ctrls))
            js[plant][tuning] = {"rows": sub, "summary": ranking.summary(sub)}
            md += [f"### {tuning} tuning alone ({', '.join(ctrls)})", "",
                   ranking.summary_markdown(sub), ""]
        md += [f"### every order, {plant} against OpenFAST", "",
               ranking.rows_markdown(rows, plant, "OpenFAST"), ""]
    md += ["## The values: " + " / ".join(tables), ""]
    for metric, (scale, fmt) in SHOWN.items():
        md += [f"### {ranking.NAMES[metric]} ({metric})", "",
               ranking.values_markdown(tables, metric, scale, fmt), ""]
    (out / "ranking.md").write_text("\n".join(md))
    (out / "ranking.json").write_text(json.dumps(js, indent=1) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    register()
    if sys.argv[1] == "rank":
        rank(Path(sys.argv[2]))
    else:
        run(sys.argv[1], Path(sys.argv[2]))
