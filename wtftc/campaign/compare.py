"""`wtftc compare`: controllers × faults × winds on a turbine, one table.

Each column is a controller's settings (wtftc.controller.Controller) under a name: a
preset, or a table of [controller] keys (:func:`resolve_columns`); by default the
turbine's recommended preset, the PI baseline and ROSCO. Every cell is one run of
:mod:`wtftc.campaign.cases`; its exact configuration (`config.toml`) and metrics
(`metrics.json`) are written to
``<out>/<wind>/<fault>/<controller>/`` so that any cell re-runs alone with
``wtftc run --config <that config.toml>``. The cells run one after the other in this
process, or as Dask tasks (:func:`run_cell`; OpenFAST's, or asked with ``--workers`` or
``--scheduler``): the same table either way.
"""

from __future__ import annotations

import copy
import itertools
import os
import re
from pathlib import Path

import numpy as np

from wtftc import config, controller
from wtftc.campaign import cases, cluster, tune
from wtftc.controller import Controller
from wtftc.errors import ConfigError, MissingExtra
from wtftc.files import owned_folder
from wtftc.model import turbine_file
from wtftc.openfast.turbsim import ensure_field
from wtftc.results.io import atomic_savefig, atomic_write_json, atomic_write_text
from wtftc.results.metrics import fdi_ran, metrics

ONSET_S = 20.0


#: the matrix's faults from ONSET_S: each pitch actuator fault type of model/faults.py (the
#: one list; tests/test_compare.py checks that none is missing), in the table's order, with
#: its blade and magnitude (the hydraulic faults at full severity, their default)
_FAULT_ON = {"loss_of_effectiveness": (2, {"rho": 0.5}), "lock": (1, {"angle_deg": "current"}),
             "pressure_drop": (2, {}), "air_in_oil": (2, {}),
             "runaway": (1, {"target_deg": 0.0})}
FAULTS = {"none": None} | {typ: [{"blade": blade, "type": typ, **magnitude, "onset_s": ONSET_S}]
                           for typ, (blade, magnitude) in _FAULT_ON.items()}
WINDS = {
    "paper_random_12": {"kind": "paper_random"},
    "ntm_B_16": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"},
    "eog_rated": {"kind": "eog", "mean_mps": 11.4, "start_s": 30.0},
    "steady_16": {"kind": "constant", "speed_mps": 16.0},
    "steady_20": {"kind": "constant", "speed_mps": 20.0},
    "ntm_B_12": {"kind": "ntm", "mean_mps": 12.0, "turbulence_class": "B"},
}
#: the columns of a bare `wtftc compare` beside the turbine's recommended preset: the PI
#: baseline and the field's reference (docs/compare.md)
BASELINES = ("pi", "rosco")
#: a column's name: a letter or digit first, then these (it names a folder of the matrix)
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+=,\[\]-]{0,159}")


def is_rosco(ctrl: Controller) -> bool:
    """Whether a column runs ROSCO (its deck's tuning or a retuned one)."""
    return ctrl.design == "rosco"


def _value_text(v) -> str:
    """A swept value as a column's name shows it: 3, 4.5, 0.0349, [1,2]."""
    if isinstance(v, list):
        return "[" + ",".join(_value_text(x) for x in v) + "]"
    if isinstance(v, float) and v.is_integer() and abs(v) < 1e15:
        return str(int(v))
    return repr(v)


def _swept(tab: dict, field: str) -> list[str]:
    """The keys of a column's table given as a list of values, each a column: a design
    parameter, a torque option or a tuning key (a numbered parameter, itself a list, is
    swept as a list of lists)."""
    design = tab.get("design")
    if design is None and isinstance(tab.get("preset"), str):
        design = controller.preset(tab["preset"], f"{field}.preset").design
    if not isinstance(design, str) or design not in controller.designs():
        return []  # parse names what is wrong
    own = controller.design_params(design)
    numbered = {n.rsplit("_", 1)[0] for n in own if n.rsplit("_", 1)[-1].isdigit()}
    keys = set(own) | set(controller.torque_keys()) | set(controller.TUNING_KEYS)
    return [k for k, v in tab.items() if isinstance(v, list) and v and (
        (k in keys and k not in numbered) or (k in numbered and isinstance(v[0], list)))]


def _table_columns(tab: dict, field: str) -> list[tuple[str, Controller]]:
    """A column's table (``name`` and [controller] keys): one column, or one per value of
    each key given as a list (their product), named ``<name>[key=value,...]``."""
    name = tab.get("name")
    if not isinstance(name, str) or not NAME.fullmatch(name):
        raise ConfigError(f"{field}.name", name, "a column's name: a letter or digit, then "
                          "letters, digits, _ . + - = , [ ] (at most 160)")
    where = f"{field}.{name}"
    settings = {k: v for k, v in tab.items() if k != "name"}
    swept = _swept(settings, where)
    out = []
    for values in itertools.product(*(settings[k] for k in swept)):
        one = settings | dict(zip(swept, values, strict=True))
        label = name + ("[" + ",".join(f"{k}={_value_text(v)}" for k, v in
                                       zip(swept, values, strict=True)) + "]" if swept else "")
        out.append((label, controller.parse(one, where)))
    return out


def resolve_columns(entries, field: str = "controllers") -> dict[str, Controller]:
    """The columns of a matrix or a sweep, name → settings, in the order given: each entry
    a name (a preset, or a name earlier wtftc versions used: wtftc.controller.lookup) or a
    table with ``name`` and [controller] keys (preset, design, accommodation, settings),
    where a setting given as a list makes one column per value. A name given twice is
    refused naming it."""
    if isinstance(entries, str | dict):
        entries = [entries]
    if not isinstance(entries, list | tuple) or not entries:
        raise ConfigError(field, entries, "a list of controllers: preset names ("
                          + ", ".join(controller.presets()) + ") or tables with a name and "
                          "[controller] keys (docs/controllers.md)")
    out: dict[str, Controller] = {}
    for entry in entries:
        if isinstance(entry, dict):
            pairs = _table_columns(entry, field)
        elif isinstance(entry, str):
            pairs = [(entry, controller.lookup(entry, field))]
        else:
            raise ConfigError(field, entry, "a preset's name or a table with a name and "
                              "[controller] keys")
        for name, ctrl in pairs:
            if name in out:
                raise ConfigError(field, name, "distinct column names: this one is given "
                                  "twice (name each table differently)")
            out[name] = ctrl
    return out


def column_tables(columns: dict[str, Controller]) -> list[dict]:
    """Columns as the list of tables that resolves to them again without the presets file
    (every setting written out): what a sweep's record keeps."""
    return [{"name": name, **ctrl.table()} for name, ctrl in columns.items()]


def entries_from_text(texts) -> list:
    """Command-line column entries: a name as it is, ``{...}`` a TOML inline table
    (``{ name = "obs", preset = "aftc-nrel5mw", phys_obs_omega = [2, 3] }``)."""
    import tomllib

    out = []
    for text in texts or ():
        if text.lstrip().startswith("{"):
            try:
                out.append(tomllib.loads(f"c = {text}")["c"])
            except tomllib.TOMLDecodeError as exc:
                raise ConfigError("--controllers", text, f"a TOML inline table ({exc})") \
                    from None
        else:
            out.append(text)
    return out


def default_columns(turbine, preset: str | None = None, note=print) -> dict[str, Controller]:
    """A bare matrix's columns: ``preset`` (default: the turbine's recommended one, its
    note printed where the turbine file names none), the PI baseline and ROSCO."""
    if preset is None:
        preset, why = controller.recommended(turbine)
        if why:
            note(f"note: {why}")
    else:
        controller.preset(preset)
    return resolve_columns(list(dict.fromkeys((preset, *BASELINES))))


DEFAULT_WINDS = ("paper_random_12", "ntm_B_16", "eog_rated")
COLUMNS = [
    ("rms_speed_error_rad_s", "RMS ω error [rad/s]", "{:.4f}"),
    ("max_abs_speed_error_rad_s", "max abs ω error [rad/s]", "{:.4f}"),
    ("overspeed_peak_over_rated", "peak ω / rated [-]", "{:.3f}"),
    ("pitch_rate_rms_deg_s", "pitch-rate RMS [deg/s]", "{:.2f}"),
    ("actuator_travel_deg", "travel [deg]", "{:.0f}"),
    ("mean_electrical_power_W", "mean power [MW]", "{:.3f}"),
    # what the regulation cost (issue 18, docs/loads.md)
    ("shaft_torque_del_1hz_Nm", "shaft DEL 1 Hz [MN m]", "{:.3f}"),
    ("tower_base_del_1hz_Nm", "tower-base DEL 1 Hz [MN m]", "{:.2f}"),
    ("pitch_adc", "pitch ADC [-]", "{:.3f}"),
    ("pitch_reversals", "pitch reversals [-]", "{:.0f}"),
    # WEIS's avg_pitch_travel and pitch_duty_cycle by what they are (docs/loads.md)
    ("pitch_travel_rate_deg_s", "pitch travel rate [deg/s]", "{:.3f}"),
    ("pitch_reversals_per_s", "pitch reversals [1/s]", "{:.3f}"),
    ("rms_speed_error_own_above_rated_rad_s", "RMS ω error, own ref., above rated [rad/s]",
     "{:.4f}"),
    ("rms_speed_error_own_below_rated_rad_s", "RMS ω error, own ref., below rated [rad/s]",
     "{:.4f}"),
    ("detection_delay_s", "detection delay [s]", "{:.2f}"),
    ("diverged_at_s", "diverged at [s]", "{:.2f}"),
]


#: the columns computed per row; the others are metrics.json's as they are
COMPUTED = ("detection_delay_s", "diverged_at_s")


def _check(kind: str, names, allowed: dict, default=None) -> list[str]:
    names = list(names) if names else list(default or allowed)
    for n in names:
        if n not in allowed:
            raise ConfigError(kind, n, "one of " + ", ".join(allowed))
    return names


#: the measurement profile campaigns run by default (docs/sensors.md): 100 Hz sampled
#: control, the benchmark's sensor noise, the baseline torque law
PROFILE = "realistic"


#: the plant of the matrix: the turbine on its flexible tower with the blades' edgewise
#: mode, the plant validated against OpenFAST (docs/validation.md), so that the
#: tower-base loads are scored (docs/loads.md)
PLANT = "tower_edge"


def cell_config(name: str, fault: str, wind: str, t_final: float, dt: float, seed: int,
                profile: str = PROFILE, turbine: str | None = None, engine: str = "wtftc",
                plant: str = PLANT, ctrl: Controller | None = None) -> dict:
    """One cell's run configuration: column ``name``, its settings ``ctrl`` (default: the
    preset or former name ``name``, wtftc.controller.lookup), on ``plant``. The
    turbulent wind is the rotor-effective one (averaged over the turbine's rotor disk:
    docs/wind.md). On a turbine other than the NREL 5-MW the gust of ``eog_rated`` comes
    at that turbine's rated wind (config.rated_wind_speed, to 0.01 m/s; the NREL 5-MW
    keeps Jonkman's 11.4 m/s). A column's [tuning] target is resolved into its gains."""
    tab = WINDS[wind]
    t = turbine_file.load(turbine or turbine_file.DEFAULT)
    if turbine and turbine != turbine_file.DEFAULT and wind == "eog_rated":
        tab = {**tab, "mean_mps": round(config.rated_wind_speed(t.vector(), t.table), 2)}
    if tab["kind"] == "ntm":
        tab = {**tab, "rotor_radius_m": t.values["rotor_radius"]}
    ctrl = controller.lookup(name) if ctrl is None else ctrl
    cfg = variant_config(ctrl, FAULTS[fault], tab, t_final, dt, seed,
                         label=f"{wind}/{fault}/{name}", profile=profile)
    where = {"plant": plant} if engine == "wtftc" else {"engine": engine}
    return tune.resolve(cfg | where | ({"turbine": turbine} if turbine else {}))


def variant_config(ctrl: Controller, faults: list | None, wind: dict, t_final: float,
                   dt: float, seed: int, label: str, profile: str = PROFILE) -> dict:
    """The run configuration of column ``ctrl`` under ``faults`` (a list of fault tables,
    or None) and ``wind`` (a wind table), in the measurement ``profile``: `wtftc
    compare`'s cells and `wtftc sweep`'s runs. Every design but ROSCO runs with the
    baseline variable-speed torque law unless it sets its own (Controller.run_keys), so
    that all compete with a standard torque controller (docs/compare.md); a [tuning]
    target is resolved by the caller, on the run's turbine."""
    keys = ctrl.run_keys(bool(faults), torque_default=True)
    cfg = {"controller": keys.pop("controller"), "case": keys.pop("case"),
           "wind": copy.deepcopy(wind), "t_final_s": t_final, "dt_s": dt,
           "seed": seed, "label": label, "profile": profile}
    if faults:
        cfg["fault"] = copy.deepcopy(faults)
    return cfg | keys


def _row(name: str, fault: str, wind: str, m: dict, uses_fdi: bool) -> dict:
    ran = fdi_ran(m["fdi"])  # not ROSCO in OpenFAST: its library has no FDI
    delays = [b.get("detection_delay_s") for b in m["fdi"]["blades"].values()
              if b.get("detection_delay_s") is not None] if ran else []
    row = {"controller": name, "fault": fault, "wind": wind,
           **{k: m.get(k) for k, _, _ in COLUMNS if k not in COMPUTED},
           "detection_delay_s": min(delays) if delays and uses_fdi else None,
           "diverged_at_s": m["diverged"]["t_s"] if m["diverged"] else None,
           "false_alarms": len(m["fdi"]["false_alarms"]) if ran else None}
    return row


def _check_openfast(raw: dict, turbine: str | None) -> None:
    """OpenFAST installed, the turbine's deck readable, and its case (the cell ``raw``'s)
    started, before any folder is made: a deck every cell would fail on is one line."""
    from wtftc.campaign.sweep import preflight
    from wtftc.openfast import install

    install.require()
    config.check_deck(turbine_file.load(turbine or turbine_file.DEFAULT))
    preflight.check_deck(raw)


def run_compare(out_dir: Path, controllers=None, faults=None, winds=None, t_final=60.0,
                dt=1e-3, seed=0, progress=True, profile: str = PROFILE,
                turbine: str | None = None, engine: str = "wtftc",
                workers: int | None = None, scheduler: str | None = None,
                plant: str = PLANT, preset: str | None = None) -> list[dict]:
    """The matrix into ``out_dir``; its rows. ``controllers``: its columns, a list of
    entries (:func:`resolve_columns`) or a dict name → Controller; without them, the
    turbine's recommended preset (or ``preset``), the PI baseline and ROSCO
    (:func:`default_columns`). Runs in OpenFAST are Dask tasks, on a local cluster of
    ``workers`` processes (default: the cores) or on ``scheduler``'s; the native engine's
    cells run in this process, on ``plant``, unless ``workers`` or ``scheduler`` is given."""
    fault_names = _check("faults", faults, FAULTS)
    columns = _columns(controllers, preset, turbine, engine == "openfast" and any(
        FAULTS[f] is not None for f in fault_names))
    wind_names = _check("winds", winds, WINDS, DEFAULT_WINDS)
    if t_final <= ONSET_S and any(FAULTS[f] is not None for f in fault_names):
        raise ConfigError("t-final", t_final, f"more than {ONSET_S:g} s, the faults' onset "
                          "(or --faults none)")
    # validate every cell before running any
    cells = {(w, f, c): cell_config(c, f, w, t_final, dt, seed, profile, turbine, engine,
                                    plant, ctrl)
             for w in wind_names for f in fault_names for c, ctrl in columns.items()}
    for raw in cells.values():  # every cell checked before a TurbSim field is made
        config.check_before_field(raw)
    for raw in cells.values():
        ensure_field(raw)  # each TurbSim field a cell reads, made once, first
    configs = {key: config.make_config(raw) for key, raw in cells.items()}
    dask = _on_dask(engine, workers, scheduler)
    if engine == "openfast":
        _check_openfast(next(iter(cells.values())), turbine)
    fdi = {c: ctrl.uses_fdi for c, ctrl in columns.items()}
    # the cluster before the folder: a scheduler that cannot be reached leaves none
    cl, local = cluster.client(scheduler, workers or os.cpu_count() or 1) if dask \
        else (None, None)
    try:
        with owned_folder(out_dir, "--out", command="compare",
                          legacy=is_legacy_compare) as tmp:
            if cl is not None:
                rows = _run_cells_on_dask(tmp, cells, configs, progress,
                                          engine == "openfast", cl, fdi)
            else:
                rows = _run_cells(tmp, configs, progress, engine == "openfast", fdi)
            write_compare_table(tmp, rows)
            figure(tmp, rows, list(columns), fault_names, wind_names)
    finally:
        cluster.close(cl, local)
    return rows


def _columns(controllers, preset: str | None, turbine: str | None,
             faulty_openfast: bool) -> dict[str, Controller]:
    """The matrix's columns: those asked for, or :func:`default_columns`; ROSCO left out
    with a note where it cannot run and was not asked for (refused where it was), and the
    columns told the fault under OpenFAST's faults likewise (:func:`_without_oracles`)."""
    from wtftc.sim import rosco

    asked = bool(controllers)
    if asked and preset is not None:
        raise ConfigError("--preset", preset, "either --preset (the candidate beside "
                          + " and ".join(BASELINES) + ") or --controllers, not both")
    t = turbine_file.load(turbine or turbine_file.DEFAULT)
    columns = dict(controllers) if isinstance(controllers, dict) else (
        resolve_columns(controllers) if asked
        else default_columns(t, preset, lambda m: print(m, flush=True)))
    if faulty_openfast:
        if preset is not None and columns.get(preset) is not None \
                and columns[preset].accommodation == "known":
            raise ConfigError("--preset", preset, "a preset OpenFAST can run under a fault: "
                              "not one told the fault (accommodation = known)")
        _without_oracles(columns, asked)
    roscos = [c for c, ctrl in columns.items() if is_rosco(ctrl)]
    reason = rosco.available() if roscos else None
    if reason is None and roscos and t.rosco_discon is None:
        reason = (f"{t.name}'s turbine file names no DISCON.IN for ROSCO (rosco_discon)")
    if reason:
        if asked:
            raise ConfigError("controllers", roscos[0], reason)
        print(f"note: {reason}; the matrix runs without {', '.join(roscos)}", flush=True)
        columns = {c: ctrl for c, ctrl in columns.items() if c not in roscos}
    return columns


def is_legacy_compare(out: Path) -> bool:
    """None is: a tree of many names in a folder without the marker cannot be told from a
    user's folder that holds such names (a review lost a thesis.md that way), so a folder
    an older wtftc wrote is refused like any other; remove it, or choose another --out."""
    return False


def _without_oracles(columns: dict[str, Controller], asked: bool) -> None:
    """OpenFAST runs no oracle (accommodation "known": eq (49) told the fault inside
    wtftc's loop): such columns are refused when asked for, else left out of the matrix
    with a note."""
    oracles = [c for c, ctrl in columns.items() if ctrl.accommodation == "known"]
    if oracles and asked:
        raise ConfigError("controllers", ",".join(oracles), "controllers OpenFAST can run "
                          "under a fault: not those told the fault (accommodation = known: "
                          + ", ".join(oracles) + ")")
    if oracles:
        print("note: with --engine openfast the matrix runs without the controllers told "
              "the fault (" + ", ".join(oracles) + ")", flush=True)
    for c in oracles:
        del columns[c]


def run_cell(raw: dict, case_dir: str | None = None) -> dict:
    """One cell (``raw``: its configuration, :func:`cell_config`): its metrics. A run in
    OpenFAST keeps its case in ``case_dir`` when the cell's folder is there (a Dask worker
    that cannot see it runs the case in a temporary folder); the native engine writes none.
    Dask's workers import this function by its module's path."""
    rc = config.make_config(raw)
    where = Path(case_dir) if case_dir and Path(case_dir).parent.is_dir() else None
    return metrics(rc, cases.run(rc, progress=False, openfast_dir=where))


def _write_cell(out_dir: Path, key: tuple, rc, m: dict, fdi: dict[str, bool]) -> dict:
    """A finished cell's metrics.json and config.toml; its row of the table (``fdi``:
    column → whether it runs wtftc's FDI)."""
    w, f, c = key
    d = Path(out_dir) / w / f / c
    atomic_write_json(d / "metrics.json", m)
    atomic_write_text(d / "config.toml", config.to_toml(rc.raw))
    return _row(c, f, w, m, fdi[c])


def _run_cells(out_dir: Path, configs: dict, progress: bool, openfast: bool,
               fdi: dict[str, bool]) -> list[dict]:
    """The cells one after the other in this process."""
    rows = []
    n = len(configs)
    for k, ((w, f, c), rc) in enumerate(configs.items(), 1):
        if progress:
            print(f"[{k}/{n}] {w} / {f} / {c}", flush=True)
        d = Path(out_dir) / w / f / c
        res = cases.run(rc, progress=False, openfast_dir=d / "openfast" if openfast else None)
        rows.append(_write_cell(out_dir, (w, f, c), rc, metrics(rc, res), fdi))
    return rows


def _on_dask(engine: str, workers: int | None, scheduler: str | None) -> bool:
    """Whether the cells are Dask tasks: OpenFAST's (one after the other, with a note,
    where Dask is not installed), or asked for with --workers or --scheduler."""
    dask = engine == "openfast" or workers is not None or scheduler is not None
    if dask and scheduler is None:
        try:
            import distributed  # noqa: F401
        except ImportError:
            if engine != "openfast" or workers is not None:
                raise MissingExtra("--workers", "Dask", "sweep",
                                   "dask and distributed") from None
            print("note: Dask is not installed (pip install 'wtftc[sweep]'): the cells run "
                  "one after the other", flush=True)
            return False
    return dask


def _run_cells_on_dask(out_dir: Path, cells: dict, configs: dict, progress: bool,
                       openfast: bool, cl, fdi: dict[str, bool]) -> list[dict]:
    """Each cell a Dask task (:func:`run_cell`), its files written here as it ends; the
    rows in the matrix's order, as :func:`_run_cells` gives them. A cell that raises stops
    the matrix with its error, as it does run in this process."""
    import time

    from dask.distributed import as_completed

    dirs = {key: Path(out_dir).resolve().joinpath(*key) for key in cells}
    for d in dirs.values():
        d.mkdir(parents=True, exist_ok=True)
    rows, pending, t0 = {}, set(cells), time.time()

    def tick():  # the runs in OpenFAST, every 30 s
        running = cluster.in_flight([dirs[k] / "openfast" for k in list(pending)], t0)
        if running:
            print(f"[compare] {len(rows)}/{len(cells)} cells done; "
                  + cluster.describe(running), flush=True)

    watcher = cluster.Watcher(tick, 30.0)
    try:
        futures = {cl.submit(run_cell, raw, str(dirs[key] / "openfast") if openfast
                             else None, pure=False): key for key, raw in cells.items()}
        if progress and openfast:
            watcher.start()
        for fut in as_completed(list(futures)):
            key = futures[fut]
            rows[key] = _write_cell(out_dir, key, configs[key], fut.result(), fdi)
            pending.discard(key)
            if progress:
                print(f"[{len(rows)}/{len(cells)}] {' / '.join(key)}", flush=True)
    finally:
        watcher.stop()
    return [rows[key] for key in cells]


#: the columns shown in the Markdown table in MW and MN m (the CSV keeps W and N m)
MEGA = {"mean_electrical_power_W", "shaft_torque_del_1hz_Nm", "tower_base_del_1hz_Nm"}


def _fmt(v, fmt, key=""):
    return "—" if v is None else fmt.format(v / 1e6 if key in MEGA else v)


def _alarms(row: dict, none: str) -> str:
    """The false alarms of a row; ``none`` where no FDI ran (ROSCO in OpenFAST)."""
    return none if row["false_alarms"] is None else str(row["false_alarms"])


def write_compare_table(out_dir: Path, rows: list[dict]) -> str:
    head = ["wind", "fault", "controller"] + [h for _, h, _ in COLUMNS] + ["false alarms"]
    md = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        md.append("| " + " | ".join([r["wind"], r["fault"], r["controller"]]
                                    + [_fmt(r[k], f, k) for k, _, f in COLUMNS]
                                    + [_alarms(r, "—")]) + " |")
    csv = [",".join(["wind", "fault", "controller"] + [k for k, _, _ in COLUMNS]
                    + ["false_alarms"])]
    for r in rows:
        csv.append(",".join([r["wind"], r["fault"], r["controller"]]
                            + ["" if r[k] is None else f"{r[k]:.6g}" for k, _, _ in COLUMNS]
                            + [_alarms(r, "")]))
    text = "\n".join(md) + "\n"
    atomic_write_text(Path(out_dir) / "compare.md", text)
    atomic_write_text(Path(out_dir) / "compare.csv", "\n".join(csv) + "\n")
    return text


def figure(out_dir: Path, rows, ctrl_names, fault_names, wind_names) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(wind_names), 1, figsize=(10, 3.2 * len(wind_names)),
                             squeeze=False)
    width = 0.8 / len(ctrl_names)
    for ax, w in zip(axes[:, 0], wind_names, strict=True):
        for i, c in enumerate(ctrl_names):
            vals, hatch = [], []
            for f in fault_names:
                r = next(r for r in rows if r["wind"] == w and r["fault"] == f
                         and r["controller"] == c)
                vals.append(r["rms_speed_error_rad_s"])
                hatch.append(r["diverged_at_s"] is not None)
            x = np.arange(len(fault_names)) + (i - (len(ctrl_names) - 1) / 2) * width
            bars = ax.bar(x, vals, width, label=c)
            for b, h in zip(bars, hatch, strict=True):
                if h:
                    b.set_hatch("xx")
        ax.set_xticks(np.arange(len(fault_names)), fault_names, fontsize=8)
        ax.set_ylabel("RMS ω error [rad/s]")
        ax.set_title(f"wind: {w} (hatched: diverged)", fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=len(ctrl_names), fontsize=8)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.25 / len(wind_names)))
    for ext in ("png", "pdf"):
        atomic_savefig(fig, Path(out_dir) / f"compare.{ext}", dpi=120)
    plt.close(fig)
