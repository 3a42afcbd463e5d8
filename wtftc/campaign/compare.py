"""`wtftc compare`: controllers × faults × winds on the NREL 5-MW plant, one table.

Every cell is one run of :mod:`wtftc.campaign.cases`; its exact configuration
(`config.toml`) and metrics (`metrics.json`) are written to
``<out>/<wind>/<fault>/<controller>/`` so that any cell re-runs alone with
``wtftc run --config <that config.toml>``. The cells run one after the other in this
process, or as Dask tasks (:func:`run_cell`; OpenFAST's, or asked with ``--workers`` or
``--scheduler``): the same table either way.
"""

from __future__ import annotations

import copy
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases, cluster, tune
from wtftc.errors import ConfigError, MissingExtra
from wtftc.files import owned_folder
from wtftc.model import turbine_file
from wtftc.openfast.turbsim import ensure_field
from wtftc.results.io import atomic_savefig, atomic_write_json, atomic_write_text
from wtftc.results.metrics import fdi_ran, metrics

ONSET_S = 20.0
#: the cases a variant runs in under a fault (config.CASES)
FDI_CASE, ORACLE_CASE, UNAWARE_CASE = config.FDI_CASE, config.ORACLE_CASE, config.UNAWARE_CASE


@dataclass(frozen=True)
class Variant:
    """A controller variant of the matrix: a registered controller and the case it runs in
    (config.CASES) when a fault is present; without a fault, every variant runs in case 1."""

    controller: str  # registered controller (generated/layout.json)
    fault_case: int
    doc: str
    #: the pitch loop's target mode (ω_n [rad/s], ζ), turned into the controller's own
    #: gains by wtftc.campaign.tune.resolve; None: its default gains (ROSCO: its deck's)
    tuning: tuple[float, float] | None = None
    #: the design's options other than its defaults, (name, value) of [controller_params]
    params: tuple[tuple[str, float], ...] = ()
    #: [turbine_params] beyond the baseline torque law every wtftc pitch controller runs
    #: with (variant_config), (name, value)
    turbine: tuple[tuple[str, float], ...] = ()

    @property
    def uses_fdi(self) -> bool:
        """Whether the variant detects faults itself, with wtftc's FDI (no oracle)."""
        return self.fault_case == FDI_CASE


CONTROLLERS = {
    "rosco": Variant("rosco", UNAWARE_CASE,
                     "NREL ROSCO 2.10.6 through its ControllerInterface (optional extra)"),
    "paper": Variant("paper", ORACLE_CASE,
                     "Bakhshi & Alfi, corrected sign, eq (49) told the fault"),
    "physical_fdi": Variant(
        "physical", FDI_CASE, "physical AFTC with wtftc's own FDI (no oracle)"),
    "physical_known": Variant("physical", ORACLE_CASE, "physical AFTC told the fault (oracle)"),
    "physical_unaccommodated": Variant(
        "physical", UNAWARE_CASE, "physical backstepping, no accommodation"),
    "drivetrain_fdi": Variant(
        "drivetrain", FDI_CASE, "drivetrain-chain AFTC (θ_s ← ω_r ← β ← u) with wtftc's own "
                                "FDI: the measured alternative"),
    "pi": Variant("pi", UNAWARE_CASE, "gain-scheduled PI baseline"),
}
#: every other controller derived as a ControllerDesign (eq (49)-style accommodation by
#: construction) joins the matrix with wtftc's own FDI, as <name>_fdi
CONTROLLERS |= {f"{c}_fdi": Variant(c, FDI_CASE, reg["doc"] + ", with wtftc's own FDI")
                for c, reg in lay.layout()["controllers"].items()
                if "checks" in reg and all(v.controller != c for v in CONTROLLERS.values())}
#: the paper's design with wtftc's FDI feeding its accommodation (issue 32's measured matrix)
CONTROLLERS["paper_fdi"] = Variant("paper", FDI_CASE, "Bakhshi & Alfi, corrected sign, eq "
                                   "(49) fed by wtftc's own FDI (no oracle)")
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
#: issue 34's options, run when named: the physical AFTC on its speed observer, the PI on
#: its low-passed speed, each also with peak shaving (docs/controllers.md)
ISSUE34 = {
    "physical_obs_fdi": Variant("physical", FDI_CASE, "physical AFTC on its speed observer "
                                "(ω_o 6 rad/s) with wtftc's own FDI",
                                params=(("phys_obs_omega", 6.0),)),
    "pi_lpf": Variant("pi", UNAWARE_CASE, "gain-scheduled PI on the rotor speed low-passed "
                      "at 6 rad/s", params=(("pi_lpf_corner", 6.0),)),
    "physical_obs_ps_fdi": Variant("physical", FDI_CASE, "physical AFTC on its speed observer "
                                   "(ω_o 6 rad/s) with peak shaving (2° near rated) and "
                                   "wtftc's own FDI",
                                   params=(("phys_obs_omega", 6.0), ("phys_ps_pitch", 0.0349))),
    "pi_lpf_ps": Variant("pi", UNAWARE_CASE, "gain-scheduled PI on the rotor speed low-passed "
                         "at 6 rad/s, with peak shaving (2° near rated)",
                         params=(("pi_lpf_corner", 6.0), ("pi_ps_pitch", 0.0349))),
    # the observer's corner that keeps 12 dB or more of gain margin on both turbines
    # (6 rad/s leaves the IEA 15-MW 3-5 dB; docs/controllers.md)
    "physical_obs45_ps_fdi": Variant("physical", FDI_CASE, "physical AFTC on its speed "
                                     "observer at 4.5 rad/s with peak shaving (2° near "
                                     "rated) and wtftc's own FDI",
                                     params=(("phys_obs_omega", 4.5),
                                             ("phys_ps_pitch", 0.0349))),
    # the same with its tower damper (0.12 rad s/m: the tower mode's ζ from 0.06 to 0.135
    # on wtftc's linear model at 16 m/s, 1.4 dB of gain margin spent; docs/controllers.md)
    "physical_obs45_ps_td_fdi": Variant("physical", FDI_CASE, "physical AFTC on its speed "
                                        "observer at 4.5 rad/s with peak shaving (2° near "
                                        "rated), its tower damper (0.12 rad s/m) and "
                                        "wtftc's own FDI",
                                        params=(("phys_obs_omega", 4.5),
                                                ("phys_ps_pitch", 0.0349),
                                                ("phys_td_gain", 0.12))),
    # the physical AFTC's dominant pitch-loop mode on its observer with peak shaving:
    # ω_n 0.60-0.73 rad/s, ζ 0.78-1.0 at 12-24 m/s (wtftc linearize, tower_edge, the
    # baseline torque law; docs/controllers.md): ROSCO's deck is tuned for 0.6, 0.7
    "rosco_matched": Variant("rosco", UNAWARE_CASE, "ROSCO 2.10.6 with its pitch PI retuned "
                             "to the physical AFTC's pitch-loop mode (0.7 rad/s, ζ 0.85)",
                             tuning=(0.7, 0.85)),
}


def _constant_torque(name: str) -> tuple[str, Variant]:
    """``name``'s variant with the baseline torque law's region 3 at constant torque
    instead of constant power (vs_constant_torque): in OpenFAST the constant-power law on
    the unfiltered generator speed drives the drivetrain mode (docs/controllers.md)."""
    v = ISSUE34[name]
    ct = (name[:-len("_fdi")] + "_ct_fdi") if name.endswith("_fdi") else name + "_ct"
    return ct, replace(v, doc=v.doc + "; constant torque above rated",
                       turbine=(("vs_constant_torque", 1.0),))


ISSUE34 |= dict(_constant_torque(n) for n in (
    "physical_obs45_ps_fdi", "physical_obs45_ps_td_fdi", "pi_lpf_ps"))
# the candidate with its observer at 3 rad/s: in OpenFAST the pitch moves 31-34 % less
# above rated than at 4.5 for 0-19 % more RMS error; on wtftc's linear model the pitch
# loop never reaches -180° at 12-24 m/s on either turbine (docs/controllers.md)
ISSUE34["physical_obs30_ps_td_ct_fdi"] = replace(
    ISSUE34["physical_obs45_ps_td_ct_fdi"],
    doc="physical AFTC on its speed observer at 3 rad/s with peak shaving (2° near rated), "
        "its tower damper (0.12 rad s/m), constant torque above rated and wtftc's own FDI",
    params=(("phys_obs_omega", 3.0), ("phys_ps_pitch", 0.0349), ("phys_td_gain", 0.12)))
# the candidate with its observer's corner scheduled on the mean pitch, 3 rad/s up to
# 0.30 rad (about 20 m/s on the NREL 5-MW), 4.5 from 0.38 rad (about 24 m/s): ω_o 3's low
# ADC where the wind is frequent, 4.5's hold in the strongest winds, where DLC 2.1 found
# ω_o 3's extreme speed above ROSCO's under the lock (docs/controllers.md)
ISSUE34["physical_obs3to45_ps_td_ct_fdi"] = replace(
    ISSUE34["physical_obs45_ps_td_ct_fdi"],
    doc="physical AFTC on its speed observer, its corner 3 rad/s rising to 4.5 with the mean "
        "pitch (0.30-0.38 rad), with peak shaving (2° near rated), its tower damper (0.12 "
        "rad s/m), constant torque above rated and wtftc's own FDI",
    params=(("phys_obs_omega", 3.0), ("phys_obs_omega_max", 4.5), ("phys_ps_pitch", 0.0349),
            ("phys_td_gain", 0.12)))
# the IEA 15-MW's candidate (docs/controllers.md, "The IEA 15-MW in OpenFAST"): its pitch
# loop retuned to 0.4 rad/s, ζ 0.85 (the NREL 5-MW's gains scaled put it at 0.69 rad/s,
# where in OpenFAST it limit-cycles with the tower), the observer at 1.5 rad/s, no tower
# damper (its high-passed acceleration drove the pitch at 0.3-1.6 Hz there), constant
# torque above rated
ISSUE34["physical_obs15_w04_ps_ct_fdi"] = Variant(
    "physical", FDI_CASE, "physical AFTC retuned to 0.4 rad/s, ζ 0.85, on its speed "
    "observer at 1.5 rad/s, with peak shaving (2° near rated), constant torque above rated "
    "and wtftc's own FDI", tuning=(0.4, 0.85),
    params=(("phys_obs_omega", 1.5), ("phys_ps_pitch", 0.0349)),
    turbine=(("vs_constant_torque", 1.0),))
CONTROLLERS |= ISSUE34
#: the matrix of a bare `wtftc compare`: what it was before issue 32's measured matrix
#: added paper_fdi and the steady and 12-m/s winds, which run when named (docs/compare.md)
DEFAULT_CONTROLLERS = tuple(c for c in CONTROLLERS if c != "paper_fdi" and c not in ISSUE34)
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


#: the plant of the matrix: the turbine on its flexible tower, so that the tower-base
#: loads are scored (docs/loads.md)
PLANT = "tower"


def cell_config(controller: str, fault: str, wind: str, t_final: float, dt: float,
                seed: int, profile: str = PROFILE, turbine: str | None = None,
                engine: str = "wtftc", plant: str = PLANT) -> dict:
    """One cell's run configuration, on ``plant`` (the tower plant by default). The
    turbulent wind is the rotor-effective one (averaged over the turbine's rotor disk:
    docs/wind.md). On a turbine other than the NREL 5-MW the gust of ``eog_rated`` comes
    at that turbine's rated wind (config.rated_wind_speed, to 0.01 m/s; the NREL 5-MW
    keeps Jonkman's 11.4 m/s). A tuned variant's target is resolved into its gains."""
    tab = WINDS[wind]
    t = turbine_file.load(turbine or turbine_file.DEFAULT)
    if turbine and turbine != turbine_file.DEFAULT and wind == "eog_rated":
        tab = {**tab, "mean_mps": round(config.rated_wind_speed(t.vector(), t.table), 2)}
    if tab["kind"] == "ntm":
        tab = {**tab, "rotor_radius_m": t.values["rotor_radius"]}
    cfg = variant_config(controller, FAULTS[fault], tab, t_final, dt, seed,
                         label=f"{wind}/{fault}/{controller}", profile=profile)
    where = {"plant": plant} if engine == "wtftc" else {"engine": engine}
    return tune.resolve(cfg | where | ({"turbine": turbine} if turbine else {}))


def variant_config(controller: str, faults: list | None, wind: dict, t_final: float,
                   dt: float, seed: int, label: str, profile: str = PROFILE) -> dict:
    """The run configuration of one controller variant (CONTROLLERS) under ``faults`` (a
    list of fault tables, or None) and ``wind`` (a wind table), in the measurement
    ``profile``: `wtftc compare`'s cells and `wtftc sweep`'s runs."""
    variant = CONTROLLERS[controller]
    name = variant.controller
    cfg = {"controller": name, "case": 1 if not faults else variant.fault_case,
           "wind": copy.deepcopy(wind), "t_final_s": t_final, "dt_s": dt,
           "seed": seed, "label": label, "profile": profile}
    if faults:
        cfg["fault"] = copy.deepcopy(faults)
    if variant.tuning is not None:  # resolved by the caller, on the run's turbine
        cfg["tuning"] = dict(zip(("omega_n_rad_s", "zeta"), variant.tuning, strict=True))
    if variant.params:
        cfg["controller_params"] = dict(variant.params)
    if name != "rosco":
        # ROSCO commands the generator torque itself; every other pitch controller runs with
        # the NREL 5-MW baseline variable-speed torque law (Jonkman 2009, 7.1), so that all
        # compete on the same plant with a standard torque controller (docs/compare.md)
        cfg["turbine_params"] = {"gen_torque_law": 1.0, **dict(variant.turbine)}
    return cfg


def _row(controller, fault, wind, m) -> dict:
    ran = fdi_ran(m["fdi"])  # not ROSCO in OpenFAST: its library has no FDI
    delays = [b.get("detection_delay_s") for b in m["fdi"]["blades"].values()
              if b.get("detection_delay_s") is not None] if ran else []
    row = {"controller": controller, "fault": fault, "wind": wind,
           **{k: m.get(k) for k, _, _ in COLUMNS if k not in COMPUTED},
           "detection_delay_s": min(delays) if delays and CONTROLLERS[controller].uses_fdi
           else None,
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
                plant: str = PLANT) -> list[dict]:
    """The matrix into ``out_dir``; its rows. Runs in OpenFAST are Dask tasks, on a local
    cluster of ``workers`` processes (default: the cores) or on ``scheduler``'s; the
    native engine's cells run in this process, on ``plant``, unless ``workers`` or
    ``scheduler`` is given."""
    from wtftc.sim import rosco

    ctrl_names = _check("controllers", controllers, CONTROLLERS, DEFAULT_CONTROLLERS)
    fault_names = _check("faults", faults, FAULTS)
    if engine == "openfast" and any(FAULTS[f] is not None for f in fault_names):
        _without_oracles(ctrl_names, bool(controllers))
    reason = rosco.available()
    if reason and "rosco" in ctrl_names:
        if controllers and "rosco" in controllers:
            raise ConfigError("controllers", "rosco", reason)
        print(f"note: {reason}; the matrix runs without it", flush=True)
        ctrl_names.remove("rosco")
    if turbine and "rosco" in ctrl_names and not controllers \
            and turbine_file.load(turbine).rosco_discon is None:
        print(f"note: {turbine}'s turbine file names no DISCON.IN for ROSCO (rosco_discon); "
              "the matrix runs without it", flush=True)
        ctrl_names.remove("rosco")
    wind_names = _check("winds", winds, WINDS, DEFAULT_WINDS)
    if t_final <= ONSET_S and any(FAULTS[f] is not None for f in fault_names):
        raise ConfigError("t-final", t_final, f"more than {ONSET_S:g} s, the faults' onset "
                          "(or --faults none)")
    # validate every cell before running any
    cells = {(w, f, c): cell_config(c, f, w, t_final, dt, seed, profile, turbine, engine,
                                    plant)
             for w in wind_names for f in fault_names for c in ctrl_names}
    for raw in cells.values():  # every cell checked before a TurbSim field is made
        config.check_before_field(raw)
    for raw in cells.values():
        ensure_field(raw)  # each TurbSim field a cell reads, made once, first
    configs = {key: config.make_config(raw) for key, raw in cells.items()}
    dask = _on_dask(engine, workers, scheduler)
    if engine == "openfast":
        _check_openfast(next(iter(cells.values())), turbine)
    # the cluster before the folder: a scheduler that cannot be reached leaves none
    cl, local = cluster.client(scheduler, workers or os.cpu_count() or 1) if dask \
        else (None, None)
    try:
        with owned_folder(out_dir, "--out", command="compare",
                          legacy=is_legacy_compare) as tmp:
            if cl is not None:
                rows = _run_cells_on_dask(tmp, cells, configs, progress,
                                          engine == "openfast", cl)
            else:
                rows = _run_cells(tmp, configs, progress, engine == "openfast")
            write_compare_table(tmp, rows)
            figure(tmp, rows, ctrl_names, fault_names, wind_names)
    finally:
        cluster.close(cl, local)
    return rows


def is_legacy_compare(out: Path) -> bool:
    """None is: a tree of many names in a folder without the marker cannot be told from a
    user's folder that holds such names (a review lost a thesis.md that way), so a folder
    an older wtftc wrote is refused like any other; remove it, or choose another --out."""
    return False


def _without_oracles(names: list[str], asked: bool) -> None:
    """OpenFAST runs no oracle (case 3: eq (49) told the fault inside wtftc's loop): such
    variants are refused when asked for, else left out of the matrix with a note."""
    oracles = [c for c in names if CONTROLLERS[c].fault_case == ORACLE_CASE]
    if oracles and asked:
        raise ConfigError("controllers", ",".join(oracles), "variants OpenFAST can run "
                          "under a fault: not those told the fault (case 3: "
                          + ", ".join(oracles) + ")")
    if oracles:
        print("note: with --engine openfast the matrix runs without the variants told the "
              "fault (" + ", ".join(oracles) + ")", flush=True)
    names[:] = [c for c in names if c not in oracles]


def run_cell(raw: dict, case_dir: str | None = None) -> dict:
    """One cell (``raw``: its configuration, :func:`cell_config`): its metrics. A run in
    OpenFAST keeps its case in ``case_dir`` when the cell's folder is there (a Dask worker
    that cannot see it runs the case in a temporary folder); the native engine writes none.
    Dask's workers import this function by its module's path."""
    rc = config.make_config(raw)
    where = Path(case_dir) if case_dir and Path(case_dir).parent.is_dir() else None
    return metrics(rc, cases.run(rc, progress=False, openfast_dir=where))


def _write_cell(out_dir: Path, key: tuple, rc, m: dict) -> dict:
    """A finished cell's metrics.json and config.toml; its row of the table."""
    w, f, c = key
    d = Path(out_dir) / w / f / c
    atomic_write_json(d / "metrics.json", m)
    atomic_write_text(d / "config.toml", config.to_toml(rc.raw))
    return _row(c, f, w, m)


def _run_cells(out_dir: Path, configs: dict, progress: bool,
               openfast: bool = False) -> list[dict]:
    """The cells one after the other in this process."""
    rows = []
    n = len(configs)
    for k, ((w, f, c), rc) in enumerate(configs.items(), 1):
        if progress:
            print(f"[{k}/{n}] {w} / {f} / {c}", flush=True)
        d = Path(out_dir) / w / f / c
        res = cases.run(rc, progress=False, openfast_dir=d / "openfast" if openfast else None)
        rows.append(_write_cell(out_dir, (w, f, c), rc, metrics(rc, res)))
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
                       openfast: bool, cl) -> list[dict]:
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
            rows[key] = _write_cell(out_dir, key, configs[key], fut.result())
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
