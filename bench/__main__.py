"""``python -m bench``: time the closed loop through wtftc's paths and the alternatives."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from wtftc.errors import ConfigError


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m bench",
        description="Runs the paper's case 3 and the physical AFTC's on nrel5mw (NTM class B, "
                    "16 m/s, 60 s) through wtftc's compiled trajectory, its compiled step from "
                    "a Python loop, CasADi's virtual machine, a hand-written numba RK4, SymPy "
                    "lambdify in a Python RK4 loop and SciPy's solve_ivp, each at the step or "
                    "tolerance that matches a DOP853 reference at rtol 1e-12 (equal accuracy, "
                    "not equal dt), ROSCO's own rosco.toolbox.sim as a reference when rosco is "
                    "installed, then batches of runs on 1 and 2 threads and the build times. "
                    "Writes bench.md and bench.json into --out (docs/performance.md). Needs "
                    "the source tree and the 'bench' extra (numba, scipy): "
                    "pip install -e '.[bench]'. Takes about 3-5 minutes.")
    p.add_argument("--out", type=Path, default=Path("out/bench"),
                   help="output folder (default: out/bench)")
    p.add_argument("--loops", nargs="+", metavar="LOOP",
                   help="subset of loops: paper_case3, physical_case3 (default: both)")
    p.add_argument("--quick", action="store_true",
                   help="fewer repeats and shorter horizons for the slow methods (a smoke run)")
    args = p.parse_args(argv)
    try:
        from bench import runner

        runner.run(args.out, args.loops, quick=args.quick)
    except ConfigError as exc:
        print(f"bench: error: {exc}", file=sys.stderr)
        return 2
    print(f"written: {args.out}/bench.md, {args.out}/bench.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
