"""The ``wtftc`` command line.

    wtftc cases [--out DIR]      the paper's three cases on both plants: figures, metrics table
    wtftc run [options]          one run: traces (CSV, Parquet), metrics.json, config.toml
    wtftc verify [--out DIR]     check, compile and verify the generated controller code
    wtftc functions              list the generated functions, their inputs and sizes
    wtftc sweep SWEEP.toml       a grid or Monte Carlo campaign on Dask, resumable (--summary)
"""

from __future__ import annotations

import os

#: BLAS on one thread unless the environment says otherwise, set before numpy loads it: the
#: loops are single-threaded compiled code, and numpy's OpenBLAS keeps a worker thread
#: spinning between its calls (7.8 % of the bench process's perf samples were in it) on the
#: cores a run or a batch's second worker needs (docs/performance.md). Dask's sweep workers
#: set the same themselves.
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
for _name in BLAS_THREADS:
    os.environ.setdefault(_name, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from wtftc import __version__  # noqa: E402
from wtftc.artefacts.loader import GeneratedArtefactError  # noqa: E402
from wtftc.errors import ConfigError, EngineError, MissingExtra  # noqa: E402


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, as every other user mistake:
    ``wtftc: error: ...`` and exit code 2 (argparse's default prints the usage first)."""

    def error(self, message: str):
        self.exit(2, f"wtftc: error: {message} (see {self.prog} --help)\n")


#: what reading a damaged generated artefact raises (JSON that does not parse, or that
#: lacks the tables it should hold); a missing or edited one is a GeneratedArtefactError
_DAMAGED = (OSError, ValueError, KeyError, TypeError, AttributeError)
_UNREADABLE = (GeneratedArtefactError, *_DAMAGED)


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


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(
        prog="wtftc",
        description="wtftc: observer-based adaptive fuzzy backstepping fault-tolerant pitch "
                    "control of wind turbines (Bakhshi & Alfi 2020), derived in SymPy, "
                    "generated with CasADi, verified.",
        epilog="Start with `wtftc cases` (the paper's three cases) or `wtftc run --help`. "
               "Docs: docs/running.md, docs/cases.md, docs/paper-notes.md.")
    p.add_argument("--version", action="version", version=f"wtftc {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    _add_verify(sub)
    _add_run(sub)
    _add_compare(sub)
    _add_sweep(sub)
    _add_cases(sub)
    _add_export(sub)
    _add_turbine(sub)
    _add_linearize(sub)
    _add_modes(sub)
    _add_openfast(sub)
    _add_validate(sub)
    _add_presets(sub)
    _add_scorecard(sub)
    return p


def _add_validate(sub) -> None:
    v = sub.add_parser(
        "validate", help="one controller and scenario on both engines: OpenFAST and wtftc's "
                         "plant, side by side (docs/validation.md)",
        description="Runs the controller in OpenFAST 5.0.0 (the turbine's deck, the benchmark "
                    "actuator, wtftc's sensors and faults) and on wtftc's --plant, on the "
                    "same TurbSim field for an NTM (its rotor-effective and its hub-height "
                    "series), with the same seed. Writes OUT/openfast/, OUT/wtftc/, "
                    "OUT/wtftc_hub/ (run folders), validation.json and validation.md (each "
                    "figure on each engine, wtftc / OpenFAST, a verdict against its "
                    "tolerance) and time_series and spectra figures.",
        epilog="Example: wtftc validate --controller rosco --wind-mean 16 --t-final 60 "
               "--out out/validate_rosco16")
    _add_preset(v, "validate")
    v.add_argument("--controller", help="rosco (default) or a registered controller that "
                   "exports (pi, physical, paper, drivetrain), with its default settings")
    v.add_argument("--case", type=int, choices=(1, 2, 4),
                   help="1 no fault (default), 2 a fault the controller is not told of, "
                        "4 wtftc's FDI finds it")
    v.add_argument("--turbine", help=TURBINE_HELP)
    v.add_argument("--wind", help="wind kind (default ntm, class B; file with "
                   "--wind-file): constant, steps, ntm, eog, file")
    v.add_argument("--wind-mean", type=float,
                   help="mean (or constant) wind speed at hub height [m/s] (default 16; "
                        "none with --wind file: the file gives the wind)")
    v.add_argument("--wind-file", type=Path, help="OpenFAST .hh/.wnd or CSV (time_s, "
                   "speed_mps)")
    v.add_argument("--fault", choices=("default", "none"),
                   help="default: blade 1 locked, blades 2-3 ρ = 0.5 from 20 s (cases 2, 4)")
    v.add_argument("--t-final", type=float, default=60.0,
                   help="simulated time [s] (default 60)")
    v.add_argument("--seed", type=_nonnegative_int, default=0, help="random seed (default 0)")
    v.add_argument("--plant", default="tower_edge", help="wtftc's plant, one with a tower: "
                   "tower_edge (default; the blades' edgewise mode, validated against "
                   "OpenFAST in docs/validation.md) or tower (rigid blades)")
    v.add_argument("--rotor-wind", choices=("blades", "disk"), default="blades",
                   help="the NTM field as wtftc's plant takes it: blades (default; as the "
                        "three blades sample it turning, whose loads agree best with "
                        "OpenFAST's) or disk (its average over the rotor disk, as campaigns "
                        "take it by default); docs/wind.md")
    v.add_argument("--out", type=Path, required=True,
                   help="output folder: new, empty or an earlier validation's")
    v.add_argument("--quiet", action="store_true", help="no progress")


def _cmd_validate(args) -> int:
    from wtftc.campaign import tune, validate

    _check_out_name(args.out)
    if args.wind is None:  # a wind file given alone is the wind
        args.wind = "file" if args.wind_file is not None else "ntm"
    if args.wind_mean is None and args.wind != "file":
        args.wind_mean = VALIDATE_WIND_MPS
    if args.preset is None and args.controller is None:
        args.controller = "rosco"
    raw = tune.resolve(_pick_controller(args, _run_overrides(args)))
    _check_out_beside_deck(args.out, raw.get("turbine"))
    _on_the_baseline_torque_law(raw)  # as compare runs them
    from wtftc.campaign.modes import tower_plants

    plant = _plant(args.plant, "--plant", tower_plants())
    doc = validate.run_validate(raw, args.out, progress=not args.quiet, plant=plant,
                                rotor_wind=args.rotor_wind)
    counts = {}
    for row in doc["metrics"].values():
        counts[row["verdict"]] = counts.get(row["verdict"], 0) + 1
    print(", ".join(f"{n} {k}" for k, n in sorted(counts.items())) + " (wtftc against "
          f"OpenFAST); written: {args.out}/validation.json, validation.md, time_series.png, "
          "spectra.png, openfast/, wtftc/")
    return 0


def _design_of(raw: dict):
    """The design a configuration runs: its [controller] table's, or its controller."""
    from wtftc import controller

    tab = raw.get("controller")
    return controller.parse(tab).design if isinstance(tab, dict) else tab


def _on_the_baseline_torque_law(raw: dict) -> None:
    """Every design but ROSCO on the baseline torque law unless its settings say
    otherwise (wtftc.controller.Controller.run_keys' torque_default)."""
    from wtftc import controller

    tab = raw.get("controller")
    if isinstance(tab, dict):
        c = controller.parse(tab)
        if c.design not in controller.LIBRARIES and "gen_torque_law" not in dict(c.torque) \
                and "gen_torque_law" not in (raw.get("turbine_params") or {}):
            raw["controller"] = {**tab, "gen_torque_law": 1.0}
    elif tab not in controller.LIBRARIES:
        raw.setdefault("turbine_params", {"gen_torque_law": 1.0})


#: `wtftc validate`'s mean wind by default [m/s]: above rated on both built-in turbines
VALIDATE_WIND_MPS = 16.0
#: what a command adds to its --out folder's name while it builds it beside, in a hidden
#: sibling (wtftc.files.owned_folder: ".<name>.<8 random characters>.partial")
PARTIAL_EXTRA = len("..12345678.partial")


def _check_out_name(out: Path, option: str = "--out") -> None:
    """Refuse, before any work, an ``out`` whose name the hidden sibling it is built in
    could not have: a file name holds at most NAME_MAX bytes (255 on Linux's file
    systems), the sibling's :data:`PARTIAL_EXTRA` more."""
    out = Path(os.path.normpath(out))
    probe = out.parent
    while not probe.is_dir() and probe != probe.parent:
        probe = probe.parent
    try:
        name_max = os.pathconf(probe, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    size, limit = len(os.fsencode(out.name)), name_max - PARTIAL_EXTRA
    if size > limit:
        raise ConfigError(option, str(out), f"a folder whose name is at most {limit} bytes "
                          f"(this one's is {size}): wtftc builds it beside, as .<name>.<8 "
                          f"characters>.partial, {PARTIAL_EXTRA} bytes longer, and a file "
                          f"name holds at most {name_max} bytes here")


def _note(line: str | None) -> None:
    """A note about the input that is not a refusal, on stderr (one line)."""
    if line:
        print(line, file=sys.stderr, flush=True)


def _add_openfast(sub) -> None:
    o = sub.add_parser(
        "openfast", help="get OpenFAST 5.0.0 and TurbSim (the second engine), or say where",
        description="OpenFAST is the field's aeroelastic simulator; wtftc runs its "
                    "controllers in it (docs/openfast.md). `get` finds OpenFAST 5.x "
                    "($OPENFAST, then PATH, then wtftc's cache) or installs it into wtftc's "
                    "cache folder from the prebuilt archive (its runtime libraries with apt "
                    "where missing), else builds it from the source archive.")
    os_ = o.add_subparsers(dest="openfast_command", metavar="ACTION", required=True)
    g = os_.add_parser("get", help="find or install OpenFAST 5.0.0 and TurbSim; print where")
    g.add_argument("--archives", type=Path, metavar="DIR",
                   help="a folder holding openfast-5.0.0-linux-x86_64.tar.gz and/or "
                        "openfast-5.0.0-src.tar.gz (default: $WTFTC_OPENFAST_ARCHIVES, "
                        "then the work area's shared/openfast/)")
    g.add_argument("--no-build", action="store_true",
                   help="never build from source (a build takes about 17 minutes)")
    os_.add_parser("where", help="where OpenFAST and TurbSim are; exit 4 when not installed")


def _add_verify(sub) -> None:
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


TURBINE_HELP = ("a built-in turbine (nrel5mw, the default; iea15mw) or a turbine file's "
                "path (.toml; docs/turbines.md)")


def _add_wind_arguments(r) -> None:
    """`wtftc run`'s wind options (docs/wind.md)."""
    r.add_argument("--wind", help="wind kind: constant, steps, paper_random, ntm, eog, file")
    r.add_argument("--wind-mean", type=float, help="mean/constant wind speed [m/s]")
    r.add_argument("--wind-file", type=Path, help="OpenFAST .hh/.wnd or CSV (time_s, speed_mps)")
    r.add_argument("--wind-radius", type=float, metavar="METERS",
                   help="ntm: the radius [m] of the rotor disk the turbulence is averaged "
                        "over (default: the turbine's rotor radius, the rotor-effective wind; "
                        "0: the hub-height point, docs/wind.md)")
    r.add_argument("--wind-field", choices=("spectral", "turbsim"),
                   help="ntm: spectral (wtftc's own synthesis, the default on wtftc's "
                        "plant) or turbsim (read from the TurbSim full field OpenFAST runs "
                        "in, made first: the engines then share their wind; the default "
                        "with --engine openfast)")


def _add_run(sub) -> None:
    r = sub.add_parser(
        "run", help="simulate one case: traces, metrics, figures and a config you can re-run",
        description="Simulate one closed-loop run with fixed-step RK4. Options override the "
                    "TOML --config file, which overrides the defaults (the turbine's "
                    "recommended controller preset with wtftc's FDI in the realistic "
                    "profile on the tower_edge plant, no fault, the paper's random wind "
                    "around 12 m/s, 60 s at dt = 1 ms). Writes traces.csv (units in the "
                    "header), traces.parquet, metrics.json, config.toml and figures/ (PNG, PDF; "
                    "the FDI's in case 4) into --out.",
        epilog="Example: wtftc run --fault default --wind ntm --wind-mean 16 --t-final 60 "
               "--out out/ntm16. Config file keys: case, plant, controller, [controller] "
               "(preset, design, accommodation and the design's settings: "
               "docs/controllers.md), t_final_s, dt_s, seed, output_rate_hz, control_sign, "
               "reference_rad_s, turbine, cp_table, label, profile, control_interval_s, "
               "control_delay, [sensors], "
               "[mismatch], [fdi], [wind] (kind = constant | steps | paper_random | ntm | eog | "
               "file, ...), [[fault]] (blade, type, onset_s, ...), [controller_params], "
               "[turbine_params], [initial]. See docs/running.md.")
    r.add_argument("--config", type=Path, help="TOML configuration file")
    r.add_argument("--case", type=int, choices=(1, 2, 3, 4),
                   help="1 no fault, 2 fault with the controller unaware, 3 fault known to "
                        "eq (49), 4 fault detected by wtftc's FDI")
    r.add_argument("--plant", help="tower_edge (default with a preset or a [controller] "
                   "table: the tower plant "
                   "with the blades' edgewise mode in series with the shaft, OpenFAST's "
                   "drivetrain mode; docs/validation.md), nrel5mw (default with --controller; "
                   "two-mass drivetrain), tower (nrel5mw on a flexible tower: thrust, "
                   "tower-base moment, Cp and Ct per blade) or paper (eqs (1)-(4), unloaded)")
    _add_preset(r, "run")
    r.add_argument("--controller", help=_controller_help())
    r.add_argument("--turbine", help=TURBINE_HELP)
    _add_wind_arguments(r)
    r.add_argument("--fault", choices=("default", "none"),
                   help="default: blade 1 locked, blades 2-3 ρ = 0.5 from 20 s (with a "
                        "preset: run in its accommodation's case; else cases 2, 3, 4)")
    r.add_argument("--t-final", type=float, help="simulated time [s] (default 60)")
    r.add_argument("--dt", type=float, help="RK4 step [s] (default 0.001)")
    r.add_argument("--seed", type=_nonnegative_int, help="random seed (default 0)")
    r.add_argument("--sign", type=int, choices=(-1, 1),
                   help="control sign: -1 corrected (default), +1 as written (pitches the "
                        "wrong way and stalls the rotor: paper-notes defect 2)")
    r.add_argument("--profile", choices=("ideal", "realistic"),
                   help="realistic (default with a preset or a [controller] table): 100 Hz "
                        "sampled controller, the benchmark's sensor noise, the baseline "
                        "torque law; ideal (default with --controller): continuous-time "
                        "controller, exact sensors, the paper's world (docs/sensors.md)")
    r.add_argument("--control-interval", type=float, metavar="SECONDS",
                   help="controller and FDI sampling interval [s], a multiple of --dt; 0: "
                        "continuous time (default of the ideal profile)")
    r.add_argument("--control-delay", action="store_true",
                   help="apply each command one control interval late")
    r.add_argument("--engine", choices=("wtftc", "openfast"),
                   help="wtftc (default): wtftc's own plants; openfast: OpenFAST 5.0 with "
                        "the turbine's deck, the controller as a DISCON library behind "
                        "wtftc's pitch actuator and sensors (needs --profile realistic; the "
                        "case is kept in OUT/openfast/; docs/openfast.md)")
    r.add_argument("--out", type=Path, default=Path("out/run"),
                   help="output folder (default: out/run under the current folder)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")


def _add_compare(sub) -> None:
    k = sub.add_parser(
        "compare", help="controllers × faults × winds on a turbine: one table, figures",
        description="Runs every combination of controller column (by default the "
                    "turbine's recommended preset, the pi preset and rosco when installed), "
                    "fault (none, loss_of_effectiveness, lock, pressure_drop, air_in_oil, "
                    "runaway; from 20 s) and wind (paper_random_12, ntm_B_16, eog_rated) and "
                    "writes compare.md, compare.csv, compare.png/pdf, and each cell's "
                    "config.toml and metrics.json under <out>/<wind>/<fault>/<controller>/ "
                    "(re-run one with wtftc run --config). Named only: the winds steady_16, "
                    "steady_20, ntm_B_12. With --engine openfast the cells are Dask tasks (a "
                    "local cluster of --workers processes, or --scheduler's). ROSCO needs the "
                    "optional extra: pip install 'wtftc[rosco]'. docs/compare.md.",
        epilog="Example: wtftc compare --controllers aftc-nrel5mw pi-filtered rosco "
               "'{ name = \"obs\", preset = \"aftc-nrel5mw\", phys_obs_omega = [2.0, 4.0] }' "
               "--faults none lock --winds ntm_B_16 --out out/cmp")
    k.add_argument("--out", type=Path, default=Path("results/compare"), help="output folder")
    _add_preset(k, "compare")
    k.add_argument("--controllers", nargs="+", metavar="COLUMN",
                   help="the columns instead: presets (wtftc presets) or TOML inline tables "
                        "'{ name = ..., preset or design = ..., settings }', a setting given "
                        "as a list making one column per value (docs/controllers.md)")
    k.add_argument("--faults", nargs="+", help="subset of faults")
    k.add_argument("--winds", nargs="+", help="subset of winds")
    k.add_argument("--turbine", help=TURBINE_HELP)
    k.add_argument("--t-final", type=float, default=60.0, help="simulated time per run [s]")
    k.add_argument("--seed", type=_nonnegative_int, default=0, help="random seed")
    k.add_argument("--profile", choices=("realistic", "ideal"), default="realistic",
                   help="realistic (default): 100 Hz sampled control, the benchmark's sensor "
                        "noise; ideal: continuous time, exact sensors (docs/sensors.md)")
    k.add_argument("--engine", choices=("wtftc", "openfast"), default="wtftc",
                   help="wtftc (default): wtftc's tower plant; openfast: OpenFAST 5.0 on the "
                        "turbine's deck, each cell's case under <wind>/<fault>/<controller>/"
                        "openfast/ (the variants told the fault are left out; "
                        "docs/openfast.md)")
    k.add_argument("--plant",
                   help="wtftc's plant with --engine wtftc, one with a tower: tower_edge "
                        "(default: the blades' edgewise mode, validated against OpenFAST in "
                        "docs/validation.md) or tower")
    k.add_argument("--workers", type=_positive_int,
                   help="the cells as Dask tasks on a local cluster of this many processes "
                        f"(default with --engine openfast: the cores, {os.cpu_count()}; "
                        "without it the cells run one after the other)")
    k.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="the cells as Dask tasks on an existing cluster")
    k.add_argument("--quiet", action="store_true", help="no progress lines")


def _add_sweep(sub) -> None:
    w = sub.add_parser(
        "sweep", help="a grid or Monte Carlo campaign on Dask, resumable; its summary",
        description="Runs every run of SWEEP.toml (controllers, plants, mean wind, "
                    "turbulence class, seeds, fault type, blade, magnitude and onset, as a "
                    "grid or N random draws; docs/sweep.md) on Dask: a local cluster of "
                    "--workers processes, or the cluster of --scheduler. Each finished batch "
                    "is saved at once as a Parquet file of <out>/runs/; interrupted (Ctrl-C, "
                    "SIGTERM, a worker lost), the same command resumes with what is missing "
                    "(and, with --retry-failed, the runs that failed). "
                    "A changed sweep file is refused for an existing results folder. "
                    "--summary DIR prints the summary table and writes summary.md, "
                    "summary.csv and figures/ (distributions per controller and fault, "
                    "detection delays, every failed or diverged run).",
        epilog="Examples: wtftc sweep examples/sweep_small.toml --out out/sweep_small; "
               "wtftc sweep --summary out/sweep_small; wtftc sweep examples/robustness.toml "
               "--scheduler tcp://10.0.0.5:8786. Needs Dask: pip install 'wtftc[sweep]'.")
    w.add_argument("sweep_file", nargs="?", type=Path, metavar="SWEEP.toml",
                   help="the sweep file (see examples/)")
    w.add_argument("--out", type=Path,
                   help="results folder (default: out/sweep/<sweep file name>)")
    _add_preset(w, "sweep")
    w.add_argument("--workers", type=_positive_int, default=os.cpu_count() or 1,
                   help="processes of the local cluster (default: the number of cores, "
                        f"{os.cpu_count()})")
    w.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run on an existing Dask cluster instead of a local one")
    w.add_argument("--engine", choices=("wtftc", "openfast"),
                   help="every run's engine (default: the sweep file's engine key, else "
                        "wtftc); openfast: OpenFAST 5.0 on the turbine's deck, one run a "
                        "task, each run's case kept in <out>/openfast/<run id>/ "
                        "(docs/openfast.md)")
    w.add_argument("--traces", action="store_true",
                   help="also save each run's traces, <out>/traces/<run id>.parquet")
    w.add_argument("--overwrite", action="store_true",
                   help="discard what --out holds (another sweep's results) and start anew; "
                        "deletes only what a sweep wrote there, and refuses a folder that "
                        "holds anything else")
    w.add_argument("--retry-failed", action="store_true",
                   help="run again the runs saved as failed (they raised: the cause is in "
                        "the results), instead of keeping them; diverged runs are results "
                        "and stay")
    w.add_argument("--confirm-openfast", type=_positive_int, metavar="N",
                   help="screen, then confirm: run the sweep on wtftc's plant (its [wind] "
                        "field = \"turbsim\", the fields OpenFAST runs on), then its N "
                        "scenarios that matter most (every lost one, then the worst extreme "
                        "overspeed, shaft DEL and tower-base DEL in turn) again in OpenFAST, "
                        "every controller of each, and write both engines side by side with "
                        "their ranking agreement, confirm.md in --confirm-out")
    w.add_argument("--confirm-out", type=Path, metavar="DIR",
                   help="the OpenFAST runs' results folder of --confirm-openfast (default: "
                        "<--out>_openfast)")
    w.add_argument("--summary", type=Path, metavar="DIR",
                   help="summarize a results folder instead of running")
    w.add_argument("--show", metavar="RUN_ID",
                   help="print one saved run's configuration (TOML for wtftc run --config) "
                        "from --out")
    w.add_argument("--quiet", action="store_true", help="no progress lines")


def _add_cases(sub) -> None:
    c = sub.add_parser(
        "cases", help="the paper's three cases on both plants, figures and a metrics table",
        description="Runs cases 1-3 on nrel5mw and on the paper's plant (plus case 1 with the "
                    "control sign as written), writes each run's traces and metrics, the "
                    "counterparts of the paper's Figs. 2-10, a comparison figure, V(t), and "
                    "metrics.md / metrics.csv into --out.")
    c.add_argument("--out", type=Path, default=Path("results"), help="output folder")
    c.add_argument("--t-final", type=float, help="simulated time per run [s] (default 60)")
    c.add_argument("--dt", type=float, help="RK4 step [s] (default 0.001)")
    c.add_argument("--seed", type=_nonnegative_int, help="random seed (default 0)")
    c.add_argument("--plant", action="append", choices=tuple(_plants()),
                   help="the plants (repeatable; default nrel5mw and paper, the paper's "
                        "cases); with another --turbine than nrel5mw: nrel5mw only (the "
                        "paper's plant is its own)")
    c.add_argument("--turbine", help=TURBINE_HELP)
    c.add_argument("--quiet", action="store_true", help="no progress bar")


def _add_export(sub) -> None:
    e = sub.add_parser(
        "export", help="a controller as a DISCON library for OpenFAST (docs/discon.md)",
        description="Builds a controller configuration, with wtftc's FDI, as a Bladed-style "
                    "DISCON shared library (plain C, built with --cc), its input file of "
                    "every parameter (its header names the preset, the turbine and the "
                    "generated code's hash), the ServoDyn lines to paste and a README of "
                    "how to put it into a deck, into --out. Default: the turbine's "
                    "recommended preset.",
        epilog="Example: wtftc export discon --preset aftc-iea15mw --turbine iea15mw "
               "--with-actuator --out discon/iea")
    e.add_argument("target", choices=("discon",), help="what to export")
    _add_preset(e, "export")
    e.add_argument("--config", type=Path, help="a TOML run configuration: its [controller] "
                   "table (or controller and controller_params), turbine, turbine_params, "
                   "sensors and fdi make the library; the scenario's keys are named in "
                   "its header and left out")
    e.add_argument("--controller", help="a registered design with its default settings: "
                   "physical, pi, paper or drivetrain")
    e.add_argument("--turbine", help=TURBINE_HELP)
    e.add_argument("--out", type=Path, required=True,
                   help="output folder: new, empty or an earlier export's, replaced whole; "
                        "a folder holding anything else is refused")
    e.add_argument("--cc", default="gcc",
                   help="the C compiler (default gcc); stopped with every process it "
                        "started on Ctrl-C, SIGTERM or after 600 s")
    e.add_argument("--interval", type=float,
                   help="the call interval DLL_DT [s] the library is built for (default: "
                        "--config's control_interval_s, else 0.01; a multiple of 0.001 in "
                        "(0, 1])")
    e.add_argument("--with-actuator", action="store_true",
                   help="also emit libwtftc_plant.so, the benchmark pitch actuator the "
                        "controller is designed for, for a host without one (OpenFAST's "
                        "decks): ServoDyn calls it and it calls the controller")


def _cmd_export(args) -> int:
    from wtftc.campaign import tune
    from wtftc.config import load_toml
    from wtftc.export import discon

    cfg = load_toml(args.config, "--config") if args.config else {}
    if args.controller is not None:
        if args.preset is not None:
            raise ConfigError("--preset", args.preset, "--preset or --controller, not both "
                              "(a preset names its design)")
        cfg["controller"] = {"design": args.controller}
    if args.turbine:
        cfg["turbine"] = args.turbine
    cfg = tune.resolve(_pick_controller(args, cfg, default_preset=True, scenario=False))
    hook = None
    if args.with_actuator:
        from wtftc.openfast import plant_library

        hook = plant_library.add_to_export
    out = discon.export(cfg, args.out, cc=args.cc, interval=args.interval,
                        with_actuator=hook)
    rc = discon.run_config(cfg, args.interval)
    names = [n for n in discon.written(out) if not n.endswith((".c", ".h"))]
    print(f"written under {out}/: {', '.join(names)} (call interval "
          f"{rc.control_interval:g} s)")
    print("\n".join(discon.header(rc, cfg)))
    return 0


def _run_overrides(args) -> dict:
    from wtftc.config import load_toml

    cfg = load_toml(args.config, "--config") if getattr(args, "config", None) else {}
    simple = {"case": "case", "plant": "plant",
              "t_final": "t_final_s", "dt": "dt_s", "seed": "seed", "sign": "control_sign",
              "profile": "profile", "control_interval": "control_interval_s",
              "turbine": "turbine", "engine": "engine"}
    for attr, key in simple.items():
        val = getattr(args, attr, None)
        if val is not None:
            cfg[key] = val
    wind = dict(cfg.get("wind", {})) if isinstance(cfg.get("wind"), dict) else cfg.get("wind")
    radius = getattr(args, "wind_radius", None)
    field = getattr(args, "wind_field", None)
    if getattr(args, "wind", None) or getattr(args, "wind_mean", None) is not None \
            or getattr(args, "wind_file", None) or radius is not None or field:
        wind = {} if not isinstance(wind, dict) else wind
        if args.wind:
            wind = {"kind": args.wind}
        if args.wind_file:
            wind.setdefault("kind", "file")
            wind["path"] = str(args.wind_file)
        if args.wind_mean is not None:
            kind = wind.get("kind", "paper_random")
            wind.setdefault("kind", kind)
            wind["speed_mps" if kind in ("constant", "steps") else "mean_mps"] = args.wind_mean
        if radius is not None:
            wind.setdefault("kind", "paper_random")  # the default kind: it refuses the field
            wind["rotor_radius_m"] = radius
        if field:
            wind.setdefault("kind", "paper_random")  # the default kind: it refuses the field
            wind["field"] = field
        cfg["wind"] = wind
    if getattr(args, "control_delay", False):
        cfg["control_delay"] = True
    if getattr(args, "fault", None) == "none":
        cfg["fault"] = []
    return cfg


def _controller_help() -> str:
    """The --controller help: the registered controllers, or where to find them when the
    generated artefacts cannot be read (``--help`` works all the same)."""
    try:
        regs = "; ".join(f"{k}: {v['doc']}" for k, v in _controllers().items())
    except _UNREADABLE:
        regs = "the registered controllers (docs/controllers.md; the generated artefacts " \
               "cannot be read now: run a command for the reason)"
    return regs + ("; rosco: NREL's ROSCO (pip install 'wtftc[rosco]'). A design with its "
                   "default settings, in the paper's world unless --profile says otherwise "
                   "(the default is the turbine's recommended --preset)")


def _controllers() -> dict:
    """The registered controllers for the help text (external is internal plumbing)."""
    from wtftc.sim.rhs import controllers

    return {k: v for k, v in controllers().items() if k != "external"}


def _add_preset(p, command: str) -> None:
    """The --preset option of ``command``."""
    p.add_argument("--preset", metavar="NAME", help=_preset_help(command))


def _preset_help(command: str) -> str:
    """The --preset help: the shipped presets, or where to find them when the generated
    artefacts cannot be read (``--help`` works all the same)."""
    default = {"run": "the turbine's recommended preset (aftc-nrel5mw on the NREL 5-MW, "
                      "aftc-iea15mw on the IEA 15-MW)",
               "validate": "--controller's design", "linearize": "the turbine's "
               "recommended preset", "tune": "--controller's design",
               "export": "the turbine's recommended preset",
               "compare": "the turbine's recommended preset, as the column beside pi and "
                          "rosco", "sweep": "the sweep file's controllers",
               "scorecard": "the turbine's recommended preset"}.get(command, "")
    try:
        from wtftc.controller import presets

        names = ", ".join(presets())
    except _UNREADABLE:
        names = "wtftc presets lists them"
    return (f"a controller preset: {names} (docs/controllers.md); none with --controller"
            + (f". Default: {default}" if default else ""))


def _pick_controller(args, cfg: dict, default_preset: bool = False,
                     scenario: bool = True) -> dict:
    """``cfg`` with the controller the options ask for (:func:`_controller_options`);
    with ``default_preset``, the turbine's recommended preset where nothing names a
    controller; with ``scenario``, a table's run defaults and --fault
    (:func:`_scenario_options`)."""
    _controller_options(args, cfg)
    if default_preset and "controller" not in cfg \
            and not {"controller_params", "tuning"} & set(cfg):
        from wtftc import controller
        from wtftc.model import turbine_file

        turbine = cfg.get("turbine", turbine_file.DEFAULT)
        name, note = controller.recommended(turbine_file.load(turbine)) \
            if isinstance(turbine, str) else (controller.FALLBACK_PRESET, None)
        _note(note)
        cfg["controller"] = {"preset": name}
    _note_turbine_of_preset(cfg)
    if scenario:
        _scenario_options(args, cfg)
    return cfg


#: what a configuration holds of its controller beside ``controller`` (a saved run's
#: flat keys): replaced with it by --preset or --controller
CONTROLLER_KEYS = ("controller_params", "tuning", "controller_preset", "rosco")


def _controller_options(args, cfg: dict) -> None:
    """--preset (as a [controller] table) or --controller, refused together, each
    replacing the controller of --config: its settings, its torque law and, unless --case
    is given, its case (a preset's accommodation sets it)."""
    from wtftc import controller

    preset, design = getattr(args, "preset", None), getattr(args, "controller", None)
    if preset is not None and design is not None:
        raise ConfigError("--preset", preset, "--preset or --controller, not both (a "
                          "preset names its design)")
    if preset is None and design is None:
        return
    if preset is not None:
        controller.preset(preset)  # an unknown name named as --preset
    cfg.pop("controller_preset", None)
    if preset is None and cfg.get("controller") == design:
        return  # the design --config names: its settings kept
    for key in CONTROLLER_KEYS:
        cfg.pop(key, None)
    if preset is not None and getattr(args, "case", None) is None:
        cfg.pop("case", None)
    if isinstance(cfg.get("turbine_params"), dict):
        cfg["turbine_params"] = {k: v for k, v in cfg["turbine_params"].items()
                                 if k not in controller.torque_keys()}
    cfg["controller"] = {"preset": preset} if preset is not None else design


def _note_turbine_of_preset(cfg: dict) -> None:
    """A note when a preset tuned for one turbine runs on another."""
    from wtftc import controller
    from wtftc.model import turbine_file

    tab = cfg.get("controller")
    name = tab.get("preset") if isinstance(tab, dict) else None
    if not isinstance(name, str) or name not in controller.presets():
        return
    tuned = controller.presets()[name].tuned_for
    try:  # (a turbine file that cannot be read is refused where the run is configured)
        turbine = turbine_file.load(cfg.get("turbine", turbine_file.DEFAULT))
    except ConfigError:
        return
    if tuned and tuned != turbine.name and turbine.recommended_preset != name:
        _note(f"note: preset {name} is tuned for the {tuned}; this run's turbine is "
              f"{turbine.name} (its recommended preset: wtftc presets)")


def _scenario_options(args, cfg: dict) -> None:
    """A [controller] table runs as its settings were measured: the realistic profile
    and the tower_edge plant unless given; --fault default puts the default fault in
    (the accommodation then sets the case); without a table, --fault default needs a
    case with a fault."""
    import copy

    from wtftc.model.faults import DEFAULT_FAULT

    if isinstance(cfg.get("controller"), dict):
        # sampled control and the benchmark's sensors, on the plant validated against
        # OpenFAST (docs/validation.md)
        cfg.setdefault("profile", "realistic")
        if cfg.get("engine", "wtftc") == "wtftc":
            cfg.setdefault("plant", "tower_edge")
        if getattr(args, "fault", None) == "default":
            cfg.setdefault("fault", copy.deepcopy(DEFAULT_FAULT))
    elif getattr(args, "fault", None) == "default" and cfg.get("case", 1) == 1 \
            and not cfg.get("fault"):
        raise ConfigError("--fault", "default", "a run with a fault: with a design (or a "
                          "saved run's configuration) give its case, --case 2 (unaware), 3 "
                          "(told the fault) or 4 (wtftc's FDI); with a preset its "
                          "accommodation sets it")


def _describe_controller(raw: dict) -> str:
    """What a run's controller is, for its first line: the preset, or the design."""
    name = raw.get("controller_preset")
    return f"preset {name} ({raw['controller']})" if name else raw["controller"]


def _plants() -> dict:
    from wtftc.sim.rhs import PLANTS

    return PLANTS


def _cmd_sweep(args) -> int:
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise MissingExtra("wtftc sweep", "Dask", "sweep", "dask and distributed") from None
    from wtftc.campaign import sweep

    if args.summary is not None:
        print(sweep.summarize(args.summary))
        extra = "".join(f", {n}" for n in ("summary_dlc.csv", "summary_paired.csv",
                                                 "summary_tuning.csv")
                        if (Path(args.summary) / n).exists())
        print(f"written: {args.summary}/summary.md, summary.csv, summary_cost.csv{extra}, "
              "figures/")
        return 0
    if args.show is not None:
        if args.out is None:
            raise ConfigError("--out", None, "the results folder that holds run " + args.show)
        print(sweep.show_run(args.out, args.show), end="")
        return 0
    if args.sweep_file is None:
        raise ConfigError("SWEEP.toml", None, "a sweep file to run (or --summary DIR)")
    from wtftc.config import load_toml
    from wtftc.results.io import ensure_writable_dir

    load_toml(args.sweep_file, "SWEEP.toml")  # unreadable: refused naming it, before any work
    out = args.out or Path("out/sweep") / args.sweep_file.stem
    ensure_writable_dir(out, "--out", create=False)
    if args.confirm_openfast is not None:
        return _confirm(args, out)
    if args.confirm_out is not None:
        raise ConfigError("--confirm-out", str(args.confirm_out), "given with "
                          "--confirm-openfast N only")
    try:
        done = sweep.run_sweep(args.sweep_file, out, workers=args.workers,
                               scheduler=args.scheduler, traces=args.traces,
                               overwrite=args.overwrite, quiet=args.quiet,
                               retry_failed=args.retry_failed, engine=args.engine,
                               preset=args.preset)
    except sweep.Interrupted as exc:
        n = sweep.read_results(out).num_rows
        print(f"\nwtftc sweep: interrupted ({exc}); {n} finished runs are saved in {out}; "
              "run the same command to resume", file=sys.stderr)
        return 130
    counts = sweep.count_status(out)
    n = sum(counts.values())
    print(f"{done['ran']} runs done now, {n} of {done['runs']} saved in {out}"
          + (f"; {done['lost']} batches lost to workers, run again to retry them"
             if done["lost"] else "")
          + f"; {counts['failed']} failed" + (" (their causes: wtftc sweep --summary; run "
                                              "again with --retry-failed to retry them)"
                                              if counts["failed"] else "")
          + (f"; {done['unfinished']} unfinished (OpenFAST ended by a signal wtftc did not "
             "send, or its case folder in use: not saved; run the same command again to "
             "run them)" if done.get("unfinished") else "")
          + f". Summary: wtftc sweep --summary {out}")
    return 0 if n == done["runs"] else 1


def _confirm(args, out: Path) -> int:
    """``wtftc sweep --confirm-openfast N``: screen on wtftc's plant, confirm in OpenFAST."""
    from wtftc.campaign import sweep
    from wtftc.results.io import ensure_writable_dir

    for flag, value, given in (("--engine", args.engine, args.engine not in (None, "wtftc")),
                               ("--traces", True, args.traces)):
        if given:
            raise ConfigError(flag, value, "left out with --confirm-openfast (the screen runs "
                              "on wtftc's plant, the confirmation in OpenFAST, no traces)")
    if args.confirm_out is not None:
        ensure_writable_dir(args.confirm_out, "--confirm-out", create=False)
    try:
        done = sweep.run_confirm(args.sweep_file, out, args.confirm_openfast, args.confirm_out,
                                 workers=args.workers, scheduler=args.scheduler,
                                 overwrite=args.overwrite, quiet=args.quiet,
                                 retry_failed=args.retry_failed, preset=args.preset)
    except sweep.Interrupted as exc:
        print(f"\nwtftc sweep: interrupted ({exc}); the finished runs are saved in {out} "
              "and its confirmation folder; run the same command to resume", file=sys.stderr)
        return 130
    except sweep.Incomplete as exc:
        print(f"wtftc sweep: the screen is incomplete ({exc}: tasks were lost); nothing is "
              "picked from part of it: run the same command again", file=sys.stderr)
        return 1
    print(done["report"], end="")
    print(f"written: {done['confirm_out']}/confirm.md, confirm.csv, confirm.json; "
          f"{done['screen']['runs']} screen runs in {out}, {done['confirmed']} of "
          f"{done['confirm_runs']} confirmation runs in {done['confirm_out']}"
          + ("" if done["confirmed"] == done["confirm_runs"] else
             " (tasks were lost: run the same command again)"))
    return 0 if done["confirmed"] == done["confirm_runs"] else 1


def _cmd_verify(args) -> int:
    from wtftc.files import check_out_folder, owned_folder
    from wtftc.verify.report import is_legacy_verify, run_verification, to_markdown

    check_out_folder(args.out, "--out", legacy=is_legacy_verify)
    print(f"wtftc verify → {args.out}/")
    with owned_folder(args.out, "--out", command="verify", legacy=is_legacy_verify) as tmp:
        summary = run_verification(tmp, n_points=args.points, seed=args.seed)
    print()
    print(to_markdown(summary))
    print(f"written: {args.out}/summary.json, summary.md, alpha_dot_fd.png")
    return 0


def _check_out_beside_deck(out: Path | None, turbine: str | None) -> None:
    """``--out`` outside the OpenFAST deck's own folder of ``turbine`` (a run copies the
    deck's files into it), before any work."""
    from wtftc import config
    from wtftc.model import turbine_file
    from wtftc.openfast import case as ofcase

    turbine = turbine_file.load(turbine or turbine_file.DEFAULT)
    deck = config.openfast_deck(turbine)
    if out is None or deck is None:
        return
    try:
        ofcase.check_out_outside_deck(Path(out), deck)
    except ConfigError:
        config.check_deck(turbine)  # a deck that cannot run is the first thing to say
        raise


def _cmd_run(args) -> int:
    from wtftc import config
    from wtftc.campaign import cases, tune
    from wtftc.openfast.turbsim import ensure_field
    from wtftc.results.io import check_run_folder

    _check_out_name(args.out)
    check_run_folder(args.out, "--out")  # before any work, a TurbSim field too
    raw = tune.resolve(_pick_controller(args, _run_overrides(args), default_preset=True))
    config.check_before_field(raw)  # refused before a TurbSim field is made
    if raw.get("engine") == "openfast":
        from wtftc.openfast import install

        _check_out_beside_deck(args.out, raw.get("turbine"))
        install.require()  # OpenFAST missing: said before any work or line of output
    ensure_field(raw)  # a TurbSim field the run reads, made first
    rc = config.make_config(raw)
    rc.initial_state()  # a wind with no operating point: refused before the first line
    _note(config.cut_out_note(rc))
    where = (f"OpenFAST 5.0.0 ({rc.raw.get('turbine', 'nrel5mw')}'s deck)"
             if rc.raw.get("engine") == "openfast" else f"{rc.plant}, at dt = {rc.dt:g} s")
    print(f"{rc.label}: {_describe_controller(rc.raw)}, case {rc.case} "
          f"({config.CASES[rc.case]}) on {where}, {rc.t_final:g} s")
    res, table, paths = cases.run_and_write(rc, args.out, progress=not args.quiet)
    print(table)
    if res.diverged:
        print(f"DIVERGED at t = {res.diverged['t_s']:.4f} s: {res.diverged['reason']}")
    print("written: " + ", ".join(str(p) for p in paths))
    return 3 if res.diverged else 0


def _cmd_cases(args) -> int:
    from wtftc import config
    from wtftc.campaign import cases
    from wtftc.files import check_out_folder
    from wtftc.model.faults import DEFAULT_FAULT

    over = _run_overrides(args)
    other = over.get("turbine", "nrel5mw") != "nrel5mw"
    plants = tuple(args.plant) if args.plant else ("nrel5mw",) if other else ("nrel5mw",
                                                                             "paper")
    onset = min(f["onset_s"] for f in DEFAULT_FAULT)
    if args.t_final is not None and not args.t_final > onset:  # the cases' fixed fault
        raise ConfigError("--t-final", args.t_final, f"more than {onset:g} s, the onset of "
                          "the cases' fault (cases 2 and 3)")
    config.make_config({**over, "plant": plants[0]})  # validate before any work
    check_out_folder(args.out, "--out", legacy=cases.is_legacy_cases)
    cases.run_cases(args.out, plants, over, progress=not args.quiet)
    print()
    print((args.out / "metrics.md").read_text(), end="")
    print(f"written under {args.out}/: metrics.md, metrics.csv, <plant>/case<N>/, "
          "<plant>/figures/")
    return 0


def _cmd_compare(args) -> int:
    from wtftc.campaign import compare
    from wtftc.campaign.modes import tower_plants
    from wtftc.files import check_out_folder

    _check_out_name(args.out)
    plant = compare.PLANT if args.plant is None else _plant(
        args.plant, "--plant", tower_plants(), " (the plants with a tower: compare scores the "
        "tower-base loads)")
    if args.plant is not None and args.engine == "openfast":
        raise ConfigError("--plant", args.plant, "no --plant with --engine openfast "
                          "(OpenFAST runs the turbine's deck)")
    check_out_folder(args.out, "--out", legacy=compare.is_legacy_compare)
    if args.engine == "openfast":
        _check_out_beside_deck(args.out, args.turbine)
    columns = compare.entries_from_text(args.controllers) if args.controllers else None
    compare.run_compare(args.out, columns, args.faults, args.winds,
                        t_final=args.t_final, seed=args.seed, progress=not args.quiet,
                        profile=args.profile, turbine=args.turbine,
                        engine=args.engine, workers=args.workers,
                        scheduler=args.scheduler, plant=plant, preset=args.preset)
    print((args.out / "compare.md").read_text(), end="")
    print(f"written under {args.out}/: compare.md, compare.csv, compare.png, "
          "<wind>/<fault>/<controller>/{config.toml,metrics.json}")
    return 0


def _add_turbine(sub) -> None:
    t = sub.add_parser(
        "turbine", help="turbine files: import one from OpenFAST and ROSCO files, show one",
        description="A turbine file (TOML) holds every plant parameter with its unit and "
                    "source, and names its Cp table (docs/turbines.md). Run any command on "
                    "it with --turbine FILE.")
    ts = t.add_subparsers(dest="turbine_command", metavar="ACTION", required=True)
    i = ts.add_parser(
        "import", help="a turbine file from an OpenFAST deck (and its ROSCO DISCON.IN)",
        description="Reads the deck's ElastoDyn and blade files (with openfast-io: pip "
                    "install 'wtftc[import]') and the DISCON.IN its ServoDyn names (or "
                    "--rosco), and writes --out with every value's file and key, and a copy "
                    "of the Cp table beside it.",
        epilog="Example: wtftc turbine import --openfast IEA-15-240-RWT-Monopile.fst "
               "--name iea15mw --out turbines/iea15mw.toml")
    i.add_argument("--openfast", type=Path, metavar="MAIN.fst",
                   help="the OpenFAST main input file (needed: ElastoDyn holds the "
                        "inertias and the drivetrain)")
    i.add_argument("--rosco", type=Path, metavar="DISCON.IN",
                   help="ROSCO's input file (default: the one ServoDyn's DLL_InFile names)")
    i.add_argument("--name", required=True, help="the turbine's short name")
    i.add_argument("--title", help="a one-line description (default: the name)")
    i.add_argument("--out", type=Path, required=True,
                   help="the turbine file (.toml); the Cp table is copied beside it. Never "
                        "inside the installed wtftc package")
    i.add_argument("--overwrite", action="store_true",
                   help="replace an existing turbine file, or the Cp table of the same "
                        "name beside it when no other turbine file there uses it (refused "
                        "without it; a table with the same bytes is shared)")
    s = ts.add_parser("show", help="a turbine's parameters, units and sources")
    s.add_argument("turbine", help=TURBINE_HELP)
    u = ts.add_parser(
        "tune", help="a controller's gains from a desired closed-loop mode (ω_n, ζ)",
        description="Chooses the gains so that the speed loop's dominant mode on the exact "
                    "linear model (wtftc linearize) at --wind has natural frequency "
                    "--omega-n and damping --zeta: the PI by its pole placement, the "
                    "physical AFTC by solving for c1 (c2 = --c2-ratio × c1) and γ. Prints "
                    "the gains, the turbine's facts and the achieved mode and margins; "
                    "--out writes a run configuration (wtftc run --config). "
                    "docs/turbines.md, 'Tuning'.",
        epilog="Example: wtftc turbine tune --turbine iea15mw --controller physical "
               "--omega-n 1.0 --zeta 0.8 --out iea_physical.toml")
    u.add_argument("--turbine", help=TURBINE_HELP)
    _add_preset(u, "tune")
    u.add_argument("--controller", help="physical (default) or pi, from its default "
                   "settings")
    u.add_argument("--omega-n", type=float, default=0.6,
                   help="natural frequency of the dominant mode [rad/s] (default 0.6, "
                        "ROSCO's NREL 5-MW PC_omega)")
    u.add_argument("--zeta", type=float, default=0.7,
                   help="its damping ratio [-] (default 0.7, ROSCO's NREL 5-MW PC_zeta)")
    u.add_argument("--wind", type=float, default=16.0,
                   help="the design wind [m/s] (default 16)")
    u.add_argument("--c2-ratio", type=float, default=2.0,
                   help="the physical AFTC's c2/c1 (default 2; 3 before issue 18: the "
                        "sensor noise reaches the pitch with a gain ∝ c1 c2)")
    u.add_argument("--out", type=Path, help="write the run configuration (TOML) here (an "
                   "existing file only if an earlier tuning wrote it, or with --overwrite)")
    u.add_argument("--overwrite", action="store_true",
                   help="replace an existing --out file that wtftc did not write")


def _cmd_turbine(args) -> int:
    from wtftc.artefacts import layout
    from wtftc.model import turbine_file

    if args.turbine_command == "tune":
        return _turbine_tune(args)
    if args.turbine_command == "show":
        t = turbine_file.load(args.turbine)
        units = {e["name"]: e["unit"] for e in layout.layout()["turbine_params"]}
        print(f"{t.name}: {t.title}\nfile: {t.path}\nCp table: {t.cp_path}")
        for n, v in t.values.items():
            print(f"  {n:<20s} {v:>16.8g} {units[n]:<14s} {t.sources[n]}")
        return 0
    from wtftc import config
    from wtftc.model import turbine_import

    turbine_import.check_out(args.out, args.overwrite)  # before any file is read
    if args.openfast is None:
        if args.rosco is None:
            raise ConfigError("--openfast", None, "the OpenFAST deck's main file (and "
                              "optionally --rosco DISCON.IN)")
        turbine_import.discon_only(args.rosco)
    imported = turbine_import.import_turbine(args.openfast, args.rosco)
    header = (f"wtftc turbine file (docs/turbines.md), imported by wtftc turbine import "
              f"from {args.openfast.name}.\nValues referred to the low-speed shaft, in "
              "the layout's units, each with its file and key.")
    # checked first as `wtftc run --turbine FILE` checks it, then both files written
    # together or neither (issue 30)
    out, table = turbine_import.write(args.out, imported, args.name, args.title or args.name,
                                      header, overwrite=args.overwrite,
                                      check=lambda p: config.make_config({"turbine": str(p)}))
    print(f"written: {out} and {table}")
    return 0


def _turbine_tune(args) -> int:
    try:
        import control  # noqa: F401
    except ImportError:
        raise MissingExtra("wtftc turbine tune", "python-control", "linear",
                           "the control package") from None
    from wtftc import config
    from wtftc.campaign import tune
    from wtftc.files import check_new_file, write_files_together

    if args.out:  # refused before the work: a user's file, a folder, the package's data
        check_new_file(args.out, "--out", args.overwrite, ours=_written_by_tune)
    if args.preset is not None and args.controller is not None:
        raise ConfigError("--preset", args.preset, "--preset or --controller, not both (a "
                          "preset names its design)")
    r = tune.tune(args.controller or "physical", args.turbine, args.omega_n, args.zeta,
                  args.wind, args.c2_ratio, preset=args.preset)
    a = r["achieved"]
    what = f"preset {args.preset}" if args.preset else args.controller or "physical"
    print(f"{what} on {args.turbine or 'nrel5mw'}: gains for a dominant mode of "
          f"{args.omega_n:g} rad/s, ζ {args.zeta:g} at {args.wind:g} m/s")
    for k, v in r["gains"].items():
        print(f"  {k:<18s} {v:.6g}")
    print("facts of the turbine (from its file):")
    for k, v in r["facts"].items():
        print(f"  {k:<18s} {v:.6g}")
    print(f"achieved on the exact linear model: ω_n {a['dominant_omega_n_rad_s']:.4g} rad/s, "
          f"ζ {a['dominant_damping']:.3g}; gain margin {a['gain_margin_dB']:.3g} dB, phase "
          f"margin {a['phase_margin_deg']:.3g}° at {a['gain_crossover_rad_s']:.3g} rad/s; "
          f"least-damped mode {a['least_damped_omega_n_rad_s']:.4g} rad/s, "
          f"ζ {a['least_damped_damping']:.3g}")
    tune.check_stable(r, args.omega_n, args.zeta, args.wind)  # an unstable design: exit 2
    if args.out:
        check_new_file(args.out, "--out", args.overwrite, ours=_written_by_tune)  # again
        body = (f"{TUNE_HEADER} "
                + (f"--preset {args.preset}" if args.preset
                   else f"--controller {args.controller or 'physical'}")
                + f" --omega-n {args.omega_n:g} "
                f"--zeta {args.zeta:g} --wind {args.wind:g} --c2-ratio {args.c2_ratio:g}\n"
                + config.to_toml(r["raw"])).encode()
        write_files_together({args.out: body + _tune_seal(body)})
        print(f"written: {args.out} (wtftc run --config {args.out})")
    return 0


#: the first line of every run configuration `wtftc turbine tune --out` writes
TUNE_HEADER = "# wtftc turbine tune"


def _tune_seal(body: bytes) -> bytes:
    """The last line of a configuration `turbine tune` writes: the sha256 of what it wrote
    above it, so that a file edited since is told from one it wrote."""
    import hashlib

    return f"# wtftc sha256 {hashlib.sha256(body).hexdigest()}\n".encode()


def _written_by_tune(path: Path) -> bool:
    """Whether ``path`` is a configuration `turbine tune` wrote and nobody edited since (its
    first line and its seal), which a new tuning may replace without --overwrite."""
    try:
        with open(path, "rb") as fh:
            data = fh.read(1 << 20)
    except OSError:
        return False
    body, _, seal = data.rstrip(b"\n").rpartition(b"\n")
    body += b"\n"
    return body.startswith((TUNE_HEADER + " ").encode()) and seal + b"\n" == _tune_seal(body)


def _add_linearize(sub) -> None:
    k = sub.add_parser(
        "linearize", help="exact linear models of the closed loop across wind speeds",
        description="At each wind the closed loop (case 1, continuous time, exact sensors) "
                    "is run in constant wind until it rests; there the generated plant and "
                    "controller are differentiated exactly (CasADi AD): the open-loop plant, "
                    "the controller, the closed loop, its modes (ω_n, ζ) and the pitch "
                    "loop's gain and phase margins (python-control). Writes linearize.md/"
                    ".csv (the summary), modes.csv, linear_<wind>mps.npz (the matrices) and "
                    "linearize.png/pdf into --out. Needs python-control: pip install "
                    "'wtftc[linear]'.",
        epilog="Example: wtftc linearize --controller pi --turbine iea15mw --winds 12 16 20")
    k.add_argument("--config", help="TOML run configuration (a saved run's config.toml "
                   "too): its controller, turbine, plant, controller_params and "
                   "turbine_params (a design's options, e.g. phys_obs_omega) are used, the "
                   "rest named in a note; the flags below override it")
    _add_preset(k, "linearize")
    k.add_argument("--controller",
                   help="a registered controller, with its default settings")
    k.add_argument("--turbine", help=TURBINE_HELP)
    k.add_argument("--plant", help="the plant model, a name of wtftc.sim.rhs.PLANTS: nrel5mw "
                   "(the default), tower, paper, ...")
    k.add_argument("--winds", type=float, nargs="+", metavar="MPS",
                   help="wind speeds [m/s] (default 12 14 ... 24)")
    k.add_argument("--out", type=Path, default=Path("out/linearize"), help="output folder")
    k.add_argument("--quiet", action="store_true", help="no progress lines")


def _cmd_linearize(args) -> int:
    try:
        import control  # noqa: F401
    except ImportError:
        raise MissingExtra("wtftc linearize", "python-control", "linear",
                           "the control package") from None
    from wtftc import config
    from wtftc.campaign import linearize
    from wtftc.files import check_out_folder

    _check_out_name(args.out)
    raw = _linearize_config(args)
    if _design_of(raw) == "rosco":  # it ran, and its "model" was the loop without it
        raise ConfigError("--controller", "rosco", "a controller generated by wtftc, one of "
                          + ", ".join(linearize.linearizable()) + " (ROSCO is an external "
                          "DISCON library: nothing here can differentiate it)")
    if args.plant is not None:
        raw["plant"] = _plant(args.plant, "--plant")
    config.make_config(raw)  # validate before any work
    winds = _winds(args.winds or linearize.WINDS)
    check_out_folder(args.out, "--out", legacy=linearize.is_legacy_linearize)
    try:
        linearize.run_linearize(raw, winds, args.out, progress=not args.quiet)
    except linearize.NotAtRest as exc:  # no operating point there: nothing is written
        raise ConfigError("--winds", exc.value, exc.allowed) from None
    print((args.out / "linearize.md").read_text(), end="")
    print(f"written under {args.out}/: linearize.md, linearize.csv, modes.csv, "
          "linear_<wind>mps.npz, linearize.png/pdf")
    return 0


#: what `wtftc linearize --config` reads (the rest of a run's configuration has no meaning
#: for a loop linearized at rest in constant wind with exact sensors: named in a note)
LINEARIZE_KEYS = ("controller", "turbine", "plant", "controller_params", "turbine_params",
                  "cp_table")


def _linearize_config(args) -> dict:
    """The configuration `wtftc linearize` builds its loop from: --config's keys that mean
    something there, the flags over them. The whole file is checked as a run configuration
    (a saved run's config.toml is welcome; a misspelt key is refused); what a loop at rest
    in constant wind with exact sensors does not read is named in a note."""
    from wtftc import config
    from wtftc.campaign import tune

    cfg = config.load_toml(args.config, "--config") if args.config else {}
    ignored = sorted(k for k in cfg if k not in (*LINEARIZE_KEYS, "label", "tuning",
                                                 "controller_preset"))
    if args.controller is not None:
        cfg["controller"] = args.controller
    if args.turbine:
        cfg["turbine"] = args.turbine
    cfg = tune.resolve(_pick_controller(args, cfg, default_preset=True, scenario=False))
    if args.config:
        config.make_config(dict(cfg))
    if ignored and not args.quiet:
        print(f"note: {args.config}: linearize reads {', '.join(LINEARIZE_KEYS)}; not used "
              f"here: {', '.join(ignored)}")
    return {k: cfg[k] for k in LINEARIZE_KEYS if k in cfg}


def _plant(name: str, flag: str, plants=None, why: str = "") -> str:
    """``name`` if it is one of ``plants`` (default: every plant of wtftc.sim.rhs.PLANTS),
    else one line naming the flag (and ``why`` those)."""
    from wtftc.sim.rhs import PLANTS

    allowed = list(plants if plants is not None else PLANTS)
    if name not in allowed:
        raise ConfigError(flag, name, "one of " + ", ".join(allowed) + why)
    return name


def _winds(winds, lo: float = 0.0) -> list[float]:
    """Wind speeds [m/s] each in (lo, 60], else one line naming --winds (``lo`` > 0: the
    turbine's rated wind, which the range then names)."""
    for w in winds:
        if not (lo < w <= 60):
            raise ConfigError("--winds", w, f"wind speeds in ({lo:.4g}, 60] m/s" + (
                " (above the turbine's rated wind: OpenFAST's trim holds the rotor speed "
                "with the pitch)" if lo > 0 else ""))
    return list(winds)


def _add_modes(sub) -> None:
    m = sub.add_parser(
        "modes", help="wtftc's plant modes against OpenFAST's linearization of the turbine's "
                      "deck (docs/validation.md)",
        description="At each steady wind OpenFAST 5.0.0 linearizes the turbine's deck "
                    "(CalcSteady, pitch trim, open loop; cached: a second call is instant), "
                    "its .lin files are taken to the fixed frame (MBC3) and averaged over "
                    "the azimuths; its drivetrain and tower modes are named by participation "
                    "and compared with the open-loop modes of wtftc's --plant at its own "
                    "operating point (wtftc linearize). Writes modes.json, modes.csv, "
                    "modes.md and lin/ (the .lin files) into --out. On the NREL 5-MW a "
                    "rigid-DOF wind takes about a minute, a full one a few; on the IEA "
                    "15-MW each azimuth takes about 5 minutes.",
        epilog="Example: wtftc modes --winds 16 --dofs rigid --out out/modes_rigid")
    m.add_argument("--turbine", help=TURBINE_HELP)
    m.add_argument("--winds", type=float, nargs="+", metavar="MPS", default=[16.0],
                   help="steady wind speeds above rated [m/s] (default 16)")
    m.add_argument("--plant", help="wtftc's plant, one with a tower (default: tower with "
                   "--dofs rigid, its like-for-like; tower_edge with --dofs full, whose "
                   "blades have their edgewise mode)")
    m.add_argument("--dofs", default="rigid", help="OpenFAST's degrees of freedom: rigid "
                   "(generator, drivetrain twist, 1st tower fore-aft: wtftc's plant; the "
                   "default) or full (every blade, tower and drivetrain DOF)")
    m.add_argument("--azimuths", type=_positive_int, help="azimuths per wind (default 2 "
                   "for rigid, 6 for full; 2 to 36)")
    m.add_argument("--out", type=Path, default=Path("out/modes"), help="output folder: new, "
                   "empty or an earlier `wtftc modes` output")
    m.add_argument("--quiet", action="store_true", help="no progress lines")


def _cmd_modes(args) -> int:
    import importlib.util

    from wtftc import config
    from wtftc.artefacts.loader import openfast_cache_dir
    from wtftc.campaign import modes
    from wtftc.files import check_out_folder
    from wtftc.model import turbine_file
    from wtftc.openfast import case as ofcase
    from wtftc.openfast import install
    from wtftc.openfast.linearization import AZIMUTHS, DOF_SETS

    _check_out_name(args.out)
    plant = args.plant or ("tower" if args.dofs == "rigid" else "tower_edge")
    raw = {"plant": _plant(plant, "--plant", modes.tower_plants()),
           **({"turbine": args.turbine} if args.turbine else {})}
    if args.dofs not in DOF_SETS:
        raise ConfigError("--dofs", args.dofs, "one of " + ", ".join(DOF_SETS))
    n_az = modes.check_azimuths(AZIMUTHS[args.dofs] if args.azimuths is None
                                else args.azimuths)
    rc = config.make_config({**raw, "controller": modes.SETTLING_CONTROLLER})
    rated = config.rated_wind_speed(rc.loop.p_turbine, rc.loop.table)
    winds = _winds(args.winds, lo=rated)  # OpenFAST's trim holds the speed by pitch
    if importlib.util.find_spec("openfast_io") is None:
        raise MissingExtra("wtftc modes", "openfast-io 5.0.0", None,
                           "OpenFAST's .lin reader", config.OPENFAST_PACKAGES)
    install.require()
    openfast_cache_dir()
    name = raw.get("turbine", turbine_file.DEFAULT)
    deck = config.check_deck(turbine_file.load(name))
    if deck is None:
        raise ConfigError("--turbine", name, "a turbine whose file names its OpenFAST deck "
                          "(openfast_deck; docs/turbines.md)")
    ofcase.check_out_outside_deck(args.out, deck)
    ofcase.check_deck_matches_turbine(deck, turbine_file.load(name))
    check_out_folder(args.out, "--out")
    try:
        modes.run_modes(raw, deck, winds, args.dofs, n_az, args.out, not args.quiet)
    except modes.linearize.NotAtRest as exc:  # no wtftc operating point: nothing written
        raise ConfigError("--winds", exc.value, exc.allowed) from None
    print((args.out / "modes.md").read_text().split("\n\n## ")[0])
    print(f"written under {args.out}/: modes.md, modes.csv, modes.json, lin/")
    return 0


def _cmd_functions(args) -> int:
    from wtftc.artefacts.loader import layout_json

    for name, f in sorted(layout_json()["functions"].items()):
        ins = ", ".join(f"{i['name']}[{i['shape'][0]}x{i['shape'][1]}]" for i in f["inputs"])
        outs = ", ".join(o["name"] for o in f["outputs"])
        print(f"{name}({ins}) -> ({outs})  {f['operations']} ops")
    return 0


def _cmd_openfast(args) -> int:
    from wtftc.openfast import install

    if args.openfast_command == "get":
        inst = install.get(args.archives, allow_build=not args.no_build,
                           log=lambda line: print(line, file=sys.stderr))
    else:
        inst = install.require()
    print(inst.describe())
    return 0


def _add_presets(sub) -> None:
    p = sub.add_parser(
        "presets", help="the controller presets: what each is for, its settings",
        description="Lists the shipped controller presets (wtftc/data/presets.toml), the "
                    "named settings that --preset runs, exports and compares, and which "
                    "turbine recommends which; with NAME, that preset's [controller] table, "
                    "to copy into a configuration and change. docs/controllers.md.",
        epilog="Example: wtftc presets aftc-nrel5mw")
    p.add_argument("name", nargs="?", metavar="NAME", help="a preset to show in full")


def _cmd_presets(args) -> int:
    from wtftc import config, controller
    from wtftc.model import turbine_file

    table = controller.presets()
    recommends = {}
    for t in turbine_file.BUILTIN:
        recommends.setdefault(turbine_file.load(t).recommended_preset, []).append(t)
    if args.name is None:
        for name, c in table.items():
            by = f" (recommended for {', '.join(recommends[name])})" \
                if name in recommends else ""
            print(f"{name}: {c.design}, accommodation {c.accommodation}{by}\n    {c.doc}")
        return 0
    c = controller.preset(args.name, "NAME")
    by = f", recommended for {', '.join(recommends[args.name])}" \
        if args.name in recommends else ""
    print(f"# preset {args.name}{by}: {c.doc}\n"
          + config.to_toml({"controller": {k: v for k, v in c.table().items()
                                           if k != "doc"}}), end="")
    return 0


def _add_scorecard(sub) -> None:
    p = sub.add_parser(
        "scorecard", help="a controller against ROSCO over the design load cases, with "
                          "intervals: the report a control engineer asks for",
        description="Runs the case matrix (wtftc/data/scorecard.toml: normal power "
                    "production from cut-in to cut-out, every pitch actuator fault and "
                    "the sensor faults at several winds, deterministic gusts, steps and "
                    "ramps around rated, and the baseline as its deck ships it) for the "
                    "controller and its baseline, the same runs for both, each group a "
                    "resumable sweep on Dask under --out, then writes scorecard.md, "
                    "scorecard.json and scorecard.html: each metric's ratio to the "
                    "baseline, paired by scenario, with a bootstrap interval over the seeds "
                    "and a verdict (a tie where it holds 1). docs/scorecard.md.",
        epilog="Examples: wtftc scorecard --plan; wtftc scorecard --screen 10 --out "
               "out/card; wtftc scorecard --turbine iea15mw --out out/card_iea")
    _add_preset(p, "scorecard")
    p.add_argument("--config", type=Path, help="a TOML file whose [controller] table is the "
                   "controller scored")
    p.add_argument("--against", default="rosco", metavar="PRESET", help="the baseline: a "
                   "preset, or a TOML inline table '{ name = ..., preset or design = ... }', "
                   "also any DISCON library: '{ name = \"mine\", design = \"discon\", "
                   "library = \"/abs/libdiscon.so\", input = \"/abs/DISCON.IN\" }' "
                   "(OpenFAST only; default rosco, at the deck's tuning)")
    p.add_argument("--turbine", help=TURBINE_HELP)
    p.add_argument("--engine", choices=("openfast", "wtftc"), default="openfast",
                   help="openfast (default): OpenFAST 5.0 on the turbine's deck behind the "
                        "benchmark actuator; wtftc: the validated tower_edge plant")
    p.add_argument("--seeds", type=_positive_int, help="turbulence seeds per case "
                   "(default: the matrix's, 6)")
    p.add_argument("--screen", type=_positive_int, metavar="N", help="with --engine "
                   "openfast: run every case on wtftc's tower_edge plant (on TurbSim's "
                   "fields), then in OpenFAST the scenarios that decide each verdict, at "
                   "least N a group, and report both engines side by side")
    p.add_argument("--plan", action="store_true", help="print each group's runs, simulated "
                   "time and OpenFAST's cost, and run nothing (with --out, a card's folder: "
                   "at the rate its OpenFAST runs measured)")
    p.add_argument("--matrix", type=Path, help="another case matrix file (default: the "
                   "shipped one)")
    p.add_argument("--workers", type=_positive_int, default=os.cpu_count() or 1,
                   help=f"processes of the local Dask cluster (default: the cores, "
                        f"{os.cpu_count()})")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run on an existing Dask cluster")
    p.add_argument("--out", type=Path, help="the scorecard's folder: new, empty, or an "
                   "earlier scorecard's, which it resumes (needed but with --plan)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")


def _scorecard_plan(args, turbine: str | None) -> int:
    """``wtftc scorecard --plan``: each group's runs and their cost, nothing run; at the
    rate a card's OpenFAST runs measured where --out is one, else the NREL 5-MW's."""
    from wtftc.campaign.scorecard import cost, matrix

    m = matrix.load(args.matrix)
    measured, where = None, "an estimate for the NREL 5-MW; --out a card's folder for its own"
    if args.out is not None and args.out.is_dir():
        made_for = cost.card_turbine(args.out)
        if made_for is not None and made_for != str(turbine or "nrel5mw"):
            raise ConfigError("--out", str(args.out), f"a card of the --turbine planned "
                              f"({turbine or 'nrel5mw'}); this one is {made_for}'s")
        measured = cost.measured_in(args.out) if made_for is not None else None
        where = (f"measured over the {measured['runs']} OpenFAST runs in {args.out}"
                 if measured else f"no OpenFAST run of a card in {args.out}: an estimate "
                 "for the NREL 5-MW")
    rate = measured["wall_per_simulated_s"] if measured else matrix.OPENFAST_WALL_PER_SIM_S
    plan = matrix.plan(m, turbine, args.seeds, wall_per_sim_s=rate)
    print(f"{'group':<20} {'DLC':<19} {'columns':>7} {'runs/column':>11} "
          f"{'simulated/column [h]':>20} {'OpenFAST CPU [h]':>16}")
    for name, g in plan.items():
        print(f"{name:<20} {g['iec']:<19} {g['columns']:>7} {g['runs_per_column']:>11} "
              f"{g['simulated_s_per_column'] / 3600:>20.2f} {g['openfast_cpu_s'] / 3600:>16.2f}")
    runs = sum(g["runs_per_column"] * g["columns"] for g in plan.values())
    wall = cost.projection(plan, rate, (args.workers,))[args.workers]
    print(f"{runs} runs; in OpenFAST at {rate:.3g} s of wall a simulated second ({where}), "
          f"about {wall / 3600:.1f} h on {args.workers} worker{'s' * (args.workers != 1)}, "
          "each group's runs in rounds of the workers. With --screen N every run is on "
          "wtftc's plant (minutes, after the TurbSim fields), then the scenarios that "
          "decide each verdict in OpenFAST.")
    return 0


def _cmd_scorecard(args) -> int:
    from wtftc.campaign import compare
    from wtftc.campaign.scorecard import report, run
    from wtftc.config import load_toml

    try:
        import distributed  # noqa: F401
    except ImportError:
        raise MissingExtra("wtftc scorecard", "Dask", "sweep", "dask and distributed") \
            from None
    cfg = load_toml(args.config, "--config") if args.config else {}
    if args.preset is not None and "controller" in cfg:
        raise ConfigError("--preset", args.preset, "--preset or --config's [controller], "
                          "not both")
    args.controller = None
    cfg = _pick_controller(args, cfg if args.turbine is None else {**cfg,
                                                                    "turbine": args.turbine},
                           default_preset=True, scenario=False)
    tab = cfg["controller"]
    candidate = tab["preset"] if isinstance(tab, dict) and set(tab) == {"preset"} else tab
    if not isinstance(candidate, str | dict):
        raise ConfigError("--config", str(args.config), "a [controller] table")
    against = compare.entries_from_text([args.against])[0]
    if args.plan:
        return _scorecard_plan(args, cfg.get("turbine"))
    if args.out is None:
        raise ConfigError("--out", None, "the scorecard's folder (or --plan to see what "
                          "it would run)")
    _check_out_name(args.out)
    from wtftc.campaign import sweep

    try:
        result = run.run_scorecard(candidate, args.out, cfg.get("turbine"), against,
                                   args.engine, args.seeds, args.workers, args.scheduler,
                                   args.matrix, args.quiet, args.screen)
    except (sweep.Interrupted, KeyboardInterrupt) as exc:
        print(f"\nwtftc scorecard: interrupted ({exc or 'SIGINT'}); the finished runs are "
              f"saved under {args.out}; run the same command to resume", file=sys.stderr)
        return 130
    except sweep.Incomplete as exc:
        print(f"wtftc scorecard: a screen is incomplete ({exc}: tasks were lost); nothing "
              "is picked from part of it: run the same command again", file=sys.stderr)
        return 1
    text = report.write(args.out, result, cfg.get("turbine"))
    print(text, end="")
    print(f"written under {args.out}/: scorecard.md, scorecard.json, and each group's "
          "results folder")
    return 0


COMMANDS = {"validate": _cmd_validate, "verify": _cmd_verify, "run": _cmd_run, "cases": _cmd_cases,
            "compare": _cmd_compare, "sweep": _cmd_sweep, "functions": _cmd_functions,
            "export": _cmd_export, "turbine": _cmd_turbine, "linearize": _cmd_linearize,
            "modes": _cmd_modes, "openfast": _cmd_openfast, "presets": _cmd_presets,
            "scorecard": _cmd_scorecard}


#: every top-level table of layout.json the runtime reads: artefacts generated by an older
#: wtftc lack some (hydraulic_faults, envelope, ...) and are refused here, in one line
LAYOUT_KEYS = ("functions", "controllers", "turbine_params", "measurements", "reference",
               "fault_inputs", "actuator_faults", "sensor_faults", "fdi_params",
               "hydraulic_faults", "envelope", "n_blades", "n_chain", "sensors")


def _check_artefacts() -> None:
    """Read the generated artefacts' manifest and layout before any work: one missing,
    damaged or stale is a GeneratedArtefactError naming the file (the loader refuses a
    missing or edited one; here also one that does not parse or lacks its tables)."""
    from wtftc.artefacts import loader

    folder = loader.generated_dir()
    for name, read, keys in (("manifest.json", loader.manifest, ("artefacts",)),
                             ("layout.json", loader.layout_json, LAYOUT_KEYS)):
        try:
            data = read()
        except _DAMAGED as exc:
            data, why = None, _one_line(exc) or type(exc).__name__
        else:
            missing = [k for k in keys if not isinstance(data, dict) or k not in data]
            why = ("made by another version of wtftc: no " + ", ".join(missing) if
                   isinstance(data, dict) and missing else
                   "not a JSON object with " + ", ".join(keys))
        if not isinstance(data, dict) or any(k not in data for k in keys):
            raise GeneratedArtefactError(
                f"{folder / name} is damaged ({why}); in a source checkout run `make "
                "regenerate`; an installed wtftc carries its own (reinstall it)")


def _one_line(text) -> str:
    """``text`` (or an exception's message) on one line."""
    return " ".join(line.strip() for line in str(text).splitlines() if line.strip())


def _artefact_message(exc: GeneratedArtefactError) -> str:
    env = os.environ.get("WTFTC_GENERATED")
    return f"WTFTC_GENERATED={env}: {exc}" if env else str(exc)


#: a configuration field and the flag that sets it: a refusal of a value given by the flag
#: names both (``t_final_s (--t-final) = 0.0 is not allowed: ...``)
FLAG_OF = {"t_final_s": "--t-final", "dt_s": "--dt", "seed": "--seed",
           "wind.mean_mps": "--wind-mean", "wind.speed_mps": "--wind-mean",
           "wind.path": "--wind-file", "wind.rotor_radius_m": "--wind-radius",
           "wind.field": "--wind-field", "control_interval_s": "--control-interval",
           "plant": "--plant", "controller": "--controller", "turbine": "--turbine",
           "case": "--case", "profile": "--profile", "wind.kind": "--wind"}


def _refusal(exc: ConfigError, argv: list[str]) -> str:
    """The refusal on one line; when its field is set by a flag given in ``argv``, the flag
    beside the field."""
    flag = FLAG_OF.get(exc.field)
    given = flag is not None and any(a == flag or a.startswith(flag + "=") for a in argv)
    given = given or (exc.field == "wind.path" and exc.value is None and "--wind" in argv)
    if not given or exc.where:
        return _one_line(exc)
    return _one_line(ConfigError(f"{exc.field} ({flag})", exc.value, exc.allowed))


def _check_paths_are_text(args) -> None:
    """Every path option holds text: a name with bytes that are not UTF-8 (the shell
    passes them as they are) cannot go into wtftc's records (config.toml, Parquet,
    OpenFAST's input files), so it is refused first, naming the option."""
    for name, value in vars(args).items():
        if isinstance(value, Path):
            try:
                str(value).encode("utf-8")
            except UnicodeEncodeError:
                raise ConfigError("--" + name.replace("_", "-"), os.fsencode(value).decode(
                    "utf-8", "backslashreplace"), "a path that is UTF-8 text") from None


def main(argv: list[str] | None = None) -> int:
    """Exit codes (docs/running.md, "Errors and exit codes"): 0 done; 2 refused input, one
    line naming the field; 3 a run diverged; 1 a sweep with runs still missing; 4 an external
    program (OpenFAST, TurbSim) missing or failing; 130
    interrupted."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        _check_paths_are_text(args)
        _check_artefacts()
        return COMMANDS[args.command](args)
    except ConfigError as exc:
        print(f"wtftc: error: {_refusal(exc, sys.argv[1:] if argv is None else argv)}",
              file=sys.stderr)
    except GeneratedArtefactError as exc:
        print(f"wtftc: error: {_one_line(_artefact_message(exc))}", file=sys.stderr)
    except EngineError as exc:
        print(f"wtftc: error: {_one_line(exc)}", file=sys.stderr)
        return 4
    except BrokenPipeError:  # the reader stopped (wtftc functions | head): not an error
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - so that exit's flush is quiet
        return 0
    except OSError as exc:  # a file that cannot be read or written
        print(f"wtftc: error: {_one_line(exc)}", file=sys.stderr)
    except KeyboardInterrupt:
        print("\nwtftc: interrupted", file=sys.stderr)
        return 130
    return 2


if __name__ == "__main__":
    sys.exit(main())
