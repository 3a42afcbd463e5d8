"""The ``wtftc`` command line.

    wtftc verify [--out DIR]     check, compile and verify the generated controller code
    wtftc functions              list the generated functions, their inputs and sizes
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from wtftc.generated import GeneratedArtefactError


def _nonnegative_int(text: str) -> int:
    try:
        val = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if val < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {val}")
    return val


def _positive_int(text: str) -> int:
    try:
        val = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if val <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {val}")
    return val


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("wtftc")
    except PackageNotFoundError:
        return "unknown (not installed)"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="wtftc",
        description="wtftc: observer-based adaptive fuzzy backstepping fault-tolerant pitch "
                    "control of wind turbines (Bakhshi & Alfi 2020), derived in SymPy, "
                    "generated with CasADi, verified.",
        epilog="Simulation commands (run, cases) arrive with the closed-loop simulator.")
    p.add_argument("--version", action="version", version=f"wtftc {_version()}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    v = sub.add_parser(
        "verify", help="check, compile and verify the generated functions; write a summary",
        description="Checks generated/ against its manifest, compiles the C code, compares "
                    "compiled and interpreted results, checks the observer gain and eq (51), "
                    "verifies α̇1..α̇3 against central differences along a closed-loop RK4 run "
                    "and the structured V̇ against ∇V·f. Writes summary.json, summary.md and "
                    "alpha_dot_fd.png into --out.")
    v.add_argument("--out", type=Path, default=Path("out/verify"),
                   help="output folder (default: out/verify)")
    v.add_argument("--points", type=_positive_int, default=50,
                   help="random points per function for the comparisons (default: 50)")
    v.add_argument("--seed", type=_nonnegative_int, default=0,
                   help="random seed, an integer >= 0 (default: 0)")
    sub.add_parser("functions", help="list the generated functions with inputs, outputs, size")
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        if args.command == "verify":
            from wtftc.io import ensure_writable_dir
            from wtftc.report import run_verification, to_markdown

            ensure_writable_dir(args.out, "--out")
            print(f"wtftc verify → {args.out}/")
            summary = run_verification(args.out, n_points=args.points, seed=args.seed)
            print()
            print(to_markdown(summary))
            print(f"written: {args.out}/summary.json, summary.md, alpha_dot_fd.png")
            return 0
        if args.command == "functions":
            from wtftc.generated import layout_json

            for name, f in sorted(layout_json()["functions"].items()):
                ins = ", ".join(f"{i['name']}[{i['shape'][0]}x{i['shape'][1]}]"
                                for i in f["inputs"])
                outs = ", ".join(o["name"] for o in f["outputs"])
                print(f"{name}({ins}) -> ({outs})  {f['operations']} ops")
            return 0
    except GeneratedArtefactError as exc:
        print(f"wtftc: error: {exc}", file=sys.stderr)
        return 1
    except (ValueError, KeyError, OSError) as exc:
        print(f"wtftc: error: {exc}", file=sys.stderr)
        return 2
    return 2


if __name__ == "__main__":
    sys.exit(main())
