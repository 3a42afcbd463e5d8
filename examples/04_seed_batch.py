"""Turbulent-wind seeds as one batch: six IEC NTM class-B realizations at 16 m/s, the
physical AFTC told the default fault (case 3), advanced together in one compiled call per
chunk (`run_batch`; each result is the run alone, bit for bit), then the mean and standard
deviation of the RMS rotor-speed error across seeds.

A batch shares one compiled loop: plant, controller, Cp table, turbine parameters, dt,
t_final and output rate; wind, seed, faults, case and gains may differ. More: README.md
(Python API), docs/wind.md (NTM), docs/performance.md (batches).

    python examples/04_seed_batch.py [OUT_DIR]      # default out/examples/04_seed_batch
"""

import sys
from pathlib import Path

import numpy as np

from wtftc.campaign.cases import run_batch
from wtftc.config import make_config
from wtftc.model.faults import DEFAULT_FAULT
from wtftc.results.metrics import metrics

SEEDS = range(6)
BASE = {"case": 3, "controller": "physical", "t_final_s": 10.0,
        "fault": [{**f, "onset_s": 4.0} for f in DEFAULT_FAULT],
        "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"}}


def main(out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    rcs = [make_config({**BASE, "seed": s, "label": f"seed{s}"}) for s in SEEDS]
    runs = run_batch(rcs, threads=2, progress=False)
    rms_rad_s = np.array([metrics(rc, r)["rms_speed_error_rad_s"]
                          for rc, r in zip(rcs, runs, strict=True)])
    lines = ["seed,rms_speed_error_rad_s,mean_wind_mps,std_wind_mps"]
    print(f"{'seed':>4} {'RMS ω error [rad/s]':>20} {'wind mean [m/s]':>16} "
          f"{'wind std [m/s]':>15}")
    for s, rms, r in zip(SEEDS, rms_rad_s, runs, strict=True):
        wind_mps = r.column("wind")
        print(f"{s:4d} {rms:20.4f} {wind_mps.mean():16.2f} {wind_mps.std():15.2f}")
        lines.append(f"{s},{rms:.6g},{wind_mps.mean():.6g},{wind_mps.std():.6g}")
    print(f"RMS ω error over {len(rms_rad_s)} seeds: mean {rms_rad_s.mean():.4f} rad/s, "
          f"std {rms_rad_s.std(ddof=1):.4f} rad/s")
    (out_dir / "seeds.csv").write_text("\n".join(lines) + "\n")
    print(f"written: {out_dir / 'seeds.csv'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/examples") / Path(__file__).stem)
