"""The paper's three cases through the Python API, with a small metrics table.

Case 1: no fault. Case 2: a pitch fault, the controller unaware. Case 3: the same fault told
to the accommodation of eq (49). The fault is the paper's default (blade 1 locked where it
is, blades 2 and 3 at half effectiveness), moved to 4 s so that a 10-s run shows it; the
wind is IEC NTM class B at 16 m/s, above rated, so that the pitch system is at work.

The same as `wtftc cases` (every case on both plants, 60 s, all figures) in a few lines.
More: docs/cases.md (the cases, figure by figure) and docs/running.md (the configuration).

    python examples/01_paper_cases.py [OUT_DIR]     # default out/examples/01_paper_cases
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # headless: files only
import matplotlib.pyplot as plt  # noqa: E402

from wtftc.campaign.cases import run  # noqa: E402
from wtftc.config import CASES, make_config  # noqa: E402
from wtftc.model.faults import DEFAULT_FAULT  # noqa: E402
from wtftc.results.metrics import metrics  # noqa: E402
from wtftc.results.tables import write_table  # noqa: E402

ONSET_S = 4.0
BASE = {"controller": "paper", "t_final_s": 10.0,
        "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"}}


def main(out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    fault = [{**f, "onset_s": ONSET_S} for f in DEFAULT_FAULT]
    fig, ax = plt.subplots(figsize=(7, 3.5))
    rows = []
    print(f"{'case':<28} {'RMS ω error [rad/s]':>20} {'after fault [rad/s]':>20} "
          f"{'peak ω/rated [-]':>17} {'mean power [MW]':>16}")
    for case in (1, 2, 3):
        rc = make_config({**BASE, "case": case, "label": f"case{case}",
                          **({"fault": fault} if case > 1 else {})})
        res = run(rc, progress=False)
        m = metrics(rc, res)
        rows.append(m)
        after = m["rms_speed_error_after_fault_rad_s"]
        print(f"{case} {CASES[case]:<26} {m['rms_speed_error_rad_s']:20.4f} "
              f"{'—' if after is None else f'{after:.4f}':>20} "
              f"{m['overspeed_peak_over_rated']:17.3f} "
              f"{m['mean_electrical_power_W'] / 1e6:16.3f}")
        ax.plot(res.t, res.column("omega_r"), label=f"case {case}: {CASES[case]}")
    ax.plot(res.t, res.column("y_d"), "k--", lw=1, label="reference y_d")
    ax.axvline(ONSET_S, color="0.5", ls=":", lw=1)
    ax.set(xlabel="time [s]", ylabel="rotor speed ω_r [rad/s]")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "rotor_speed.png", dpi=120)
    write_table(out_dir, rows)  # metrics.md and metrics.csv: every column, with units
    print(f"written: {out_dir / 'metrics.md'}, {out_dir / 'metrics.csv'}, "
          f"{out_dir / 'rotor_speed.png'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/examples") / Path(__file__).stem)
