"""A tiny sweep on a local Dask cluster, and its summary: 2 controllers × 2 wind seeds ×
(no fault, blade 2 locked where it is), 5 s each: 8 runs, one worker.

A sweep file names what varies (here written into the output folder; a larger one:
examples/sweep_small.toml); every run's configuration and id follow from it. Results land
as Parquet (one file per finished batch, so an interrupted sweep resumes with what is
missing). The same from the command line: `wtftc sweep FILE --out DIR --workers 1`, then
`wtftc sweep --summary DIR`. More: docs/sweep.md.

    python examples/05_small_sweep.py [OUT_DIR]     # default out/examples/05_small_sweep
"""

import sys
from pathlib import Path

from wtftc.campaign import sweep

SWEEP = """\
name = "tiny"
mode = "grid"
t_final_s = 5.0
output_rate_hz = 10.0
batch_size = 4
controllers = ["physical-plain", "paper"]

[wind]
mean_mps = 16.0
turbulence_class = "B"
seed = [0, 1]

[fault]
type = ["none", "lock"]
blade = 2
onset_s = 2.0
angle_deg = "current"
"""


def main(out_dir: Path) -> None:
    try:
        import distributed  # noqa: F401 - Dask runs the sweep
    except ImportError:
        sys.exit("this example needs Dask: pip install 'wtftc[sweep]' (make setup has it)")
    out_dir.mkdir(parents=True, exist_ok=True)
    sweep_file = out_dir / "tiny_sweep.toml"
    sweep_file.write_text(SWEEP)
    results = out_dir / "results"
    # overwrite: start afresh each time (without it, the same command resumes)
    counts = sweep.run_sweep(sweep_file, results, workers=1, overwrite=True)
    print(f"{counts['ran']} of {counts['runs']} runs done")
    print(sweep.summarize(results), end="")  # also summary.md, summary.csv, figures/
    rows = sweep.read_results(results).to_pylist()
    print(f"{'controller':<14} {'seed':>4} {'fault':<6} {'status':<8} {'RMS ω error [rad/s]':>20}")
    for r in sorted(rows, key=lambda r: (r["controller"], r["seed"], r["fault_type"])):
        print(f"{r['controller']:<14} {r['seed']:4d} {r['fault_type']:<6} {r['status']:<8} "
              f"{r['rms_speed_error_rad_s']:20.4f}")


if __name__ == "__main__":  # the guard matters here: Dask's workers start new processes
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/examples") / Path(__file__).stem)
