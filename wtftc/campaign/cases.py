"""The paper's three cases (and case 4, wtftc's FDI): single runs, batches, and `wtftc cases`.

Case 1: no fault. Case 2: a pitch actuator fault, the controller unaware. Case 3: the same
fault with eq (49) given the fault parameters (an oracle). Case 4: the fault detected and
estimated by wtftc's FDI (docs/fdi.md). Default fault (the paper's Fig. 6 gives no
numbers): blade 1 locked where it is, blades 2-3 at ρ = 0.5, all from t = 20 s.
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

from wtftc.config import CASES, RunConfig, make_config
from wtftc.errors import ConfigError
from wtftc.files import owned_folder
from wtftc.model.faults import Schedule
from wtftc.results.io import run_folder
from wtftc.results.metrics import metrics
from wtftc.results.tables import write_table
from wtftc.results.traces import write_outputs
from wtftc.sim import integrate, rhs, stability
from wtftc.sim.integrate import Result
from wtftc.sim.rhs import PLANTS
from wtftc.sim.sampled import sampled_state


def run(rc: RunConfig, progress: bool = True, keep_states: bool = False,
        openfast_dir: Path | None = None) -> Result:
    """One run of ``rc``: the compiled loop, or ROSCO driving it; with engine = openfast,
    OpenFAST with the case written into ``openfast_dir`` (a temporary folder, removed
    after, when None)."""
    if rc.raw.get("engine") == "openfast":
        return _run_openfast(rc, openfast_dir, progress)
    if not rc.uses_rosco:
        return run_batch([rc], progress=progress, keep_states=keep_states)[0]
    from wtftc.sim import rosco

    if rc.told_fault or rc.uses_fdi:
        raise ConfigError("case", rc.case, "1 or 2 with controller = rosco (ROSCO has no "
                          "fault accommodation)")
    inputs, _ = _prepare(rc, check=False)
    res = rosco.run(rc.loop, inputs, rc.t_final, rc.dt, rc.decimate, progress=progress,
                    discon=rc.rosco_discon, retune=rc.rosco_retune)
    res.config = {**rc.raw, "wind_resolved": rc.wind.describe(),
                  "fault_resolved": res.schedule.describe() if res.schedule else [],
                  "rosco": {"version": rosco.ROSCO_VERSION, "control_dt_s": rosco.CONTROL_DT}}
    return res


def _run_openfast(rc: RunConfig, folder: Path | None, progress: bool) -> Result:
    import tempfile

    from wtftc.openfast import engine

    if rc.uses_rosco and (rc.told_fault or rc.uses_fdi):
        raise ConfigError("case", rc.case, "1 or 2 with controller = rosco (ROSCO has no "
                          "fault accommodation)")
    if folder is not None:
        return engine.run(rc, folder, progress)
    with tempfile.TemporaryDirectory(prefix="wtftc-openfast-") as tmp:
        return engine.run(rc, Path(tmp), progress)


def run_batch(rcs: list[RunConfig], threads: int = 1, progress: bool = True,
              keep_states: bool = False) -> list[Result]:
    """Many independent runs of one loop in one compiled call per chunk (the Python API for
    seeds and fault cases): the same results as :func:`run` on each, bit for bit.

    The runs must share what the compiled loop is built for (:class:`wtftc.sim.rhs.Loop`:
    plant, controller, Cp table, turbine parameters) and dt, t_final and output decimation;
    wind, faults, seed, case and controller gains may differ. ``threads``: worker threads,
    each advancing its share of the runs (use the cores).
    """
    _check_batch(rcs, threads)
    first = rcs[0]
    prepared = [_prepare(rc) for rc in rcs]
    results = integrate.run_loops(first.loop, [r for r, _ in prepared], first.t_final,
                                  first.dt, decimate=first.decimate, progress=progress,
                                  keep_states=keep_states, threads=threads)
    for rc, res, (inputs, lam) in zip(rcs, results, prepared, strict=True):
        res.schedule = inputs.schedule
        res.config = {**rc.raw, "wind_resolved": rc.wind.describe(),
                      "fault_resolved": res.schedule.describe() if res.schedule else [],
                      "stability": {"max_abs_eigenvalue_1_s": lam, "dt_limit_s": 2.78 / lam}}
    return results


def _check_batch(rcs: list[RunConfig], threads: int) -> None:
    if not rcs:
        raise ConfigError("runs", "[]", "at least one run configuration")
    if threads < 1:
        raise ConfigError("threads", threads, "a positive integer")
    first = rcs[0]
    for i, rc in enumerate(rcs):
        if rc.library_controller:
            raise ConfigError(f"runs[{i}].controller", rc.controller,
                              "a generated controller (a DISCON library, ROSCO's or "
                              "another, runs one at a time)")
        for key in ("plant", "controller", "table_key", "dt", "t_final", "decimate"):
            if getattr(rc, key) != getattr(first, key):
                raise ConfigError(f"runs[{i}].{key}", getattr(rc, key),
                                  f"{getattr(first, key)!r}, as in runs[0]: a batch shares "
                                  "one compiled loop")
        if rc.loop != first.loop:
            raise ConfigError(f"runs[{i}].turbine", "different parameters",
                              "the turbine parameters of runs[0]")


def _prepare(rc: RunConfig, check: bool = True) -> tuple[integrate.Run, float | None]:
    """The loop's inputs for ``rc``: the trimmed initial state, the fault schedules of the
    plant and of eq (49) (case 3), whether the FDI feeds the accommodation (case 4); and,
    with ``check``, the largest |eigenvalue| at the start, dt refused beyond RK4's limit."""
    z0 = rc.initial_state()
    lam = None
    if check:
        lam = stability.stability_limit(rc.loop, z0, float(rc.wind(0.0)), rc.yd, rc.p_ctrl)
        stability.check_dt(rc.dt, lam)
        if rc.loop.sampled:
            stability.check_interval(rc.control_interval, stability.controller_limit(
                rc.loop, z0, float(rc.wind(0.0)), rc.yd, rc.p_ctrl))
    tp = rc.loop.p_turbine if rc.p_plant is None else rc.p_plant
    schedule = Schedule(copy.deepcopy(rc.faults), tp) if rc.faults else None
    # eq (49) is told the fault as the model knows it (the nominal actuator)
    ctrl_schedule = Schedule(copy.deepcopy(rc.faults), rc.loop.p_turbine) if rc.told_fault \
        else None
    return integrate.Run(sampled_state(rc.loop, z0), rc.wind, schedule, ctrl_schedule, rc.yd,
                         rc.p_ctrl, use_fdi=rc.uses_fdi, p_plant=rc.p_plant,
                         cp_scale=rc.cp_scale, p_sensors=rc.p_sensors,
                         noise_seed=rc.seed, p_fdi=rc.p_fdi, test_pulse=rc.test_pulse), lam


def run_and_write(rc: RunConfig, out_dir: Path, progress: bool = True):
    """``wtftc run``: one run, its files and figures; (result, metrics table, paths).

    The files go into a temporary sibling that replaces ``out_dir`` as a whole when all are
    written (results.io.run_folder): never a mix of two runs, never a stale file."""
    out_dir = Path(out_dir)
    with run_folder(out_dir) as tmp:
        res = run(rc, progress=progress, openfast_dir=tmp / "openfast")
        m = metrics(rc, res)
        paths = write_outputs(tmp, rc, res, m)
        paths += write_run_figures(tmp, rc, res, m)
        table = write_table(tmp, [m])
        paths += [tmp / "metrics.md", tmp / "metrics.csv"]
    return res, table, [out_dir / Path(p).relative_to(tmp) for p in paths]


def run_record(rc: RunConfig, res: Result, m: dict) -> dict:
    """What the figures of one run need, in one dict (wtftc.results.figures)."""
    return {"result": res, "metrics": m, "case": rc.case, "plant": rc.plant,
            "model": rc.model_name,
            "case_doc": CASES[rc.case], "schedule": res.schedule, "rc": rc,
            "onset": rc.onset, "gearbox_ratio": rc.param("gearbox_ratio"),
            "pitch_limits_deg": tuple(np.degrees([rc.param("pitch_min"),
                                                  rc.param("pitch_max")]))}


def write_run_figures(out_dir: Path, rc: RunConfig, res: Result, m: dict) -> list[Path]:
    """The figures of one run (``wtftc run``) under out_dir/figures/, PNG and PDF: rotor
    speed, control and pitch, the fault shape when there is a fault, and wtftc's fault
    detection when the run uses it (case 4)."""
    from wtftc.results import figures

    rec = run_record(rc, res, m)
    fdir = Path(out_dir) / "figures"
    paths = figures.rotor_speed(rec, fdir, "rotor_speed", rc.label)
    if not rc.library_controller:  # (a library's commands are not wtftc's outputs)
        paths += figures.control(rec, fdir, "control", rc.label)
    if res.schedule is not None:
        paths += figures.fault_shape(rec, fdir, "fault")
    if rc.uses_fdi:
        paths += figures.fdi(rec, fdir, "fdi")
    return paths


def run_cases(out_dir: Path, plants=tuple(PLANTS), overrides: dict | None = None,
              progress: bool = True, sign_as_written: bool = True) -> list[dict]:
    """The paper's three cases on each plant, figures and a metrics table under out_dir;
    then case 1 with the control sign as written (paper-notes defect 2), for a controller
    that has that sign. Every configuration is validated before the first run."""
    out_dir = Path(out_dir)
    over = overrides or {}
    configs = {plant: [make_config({**over, "plant": plant, "case": case}) for case in (1, 2, 3)]
               for plant in plants}
    # each plant's folder and labels: the plant's name, or on a turbine other than the
    # NREL 5-MW the turbine's (RunConfig.label)
    names = {plant: rcs[0].model_name for plant, rcs in configs.items()}
    sign_rc = None
    if sign_as_written and configs[plants[0]][0].signed:
        sign_rc = make_config({**over, "plant": plants[0], "case": 1, "control_sign": 1,
                               "label": f"{names[plants[0]]}_case1_sign_as_written"})
    with owned_folder(out_dir, "--out", command="cases", legacy=is_legacy_cases) as tmp:
        rows = _run_all(tmp, configs, names, sign_rc, plants[0], progress)
    return rows


def is_legacy_cases(out: Path) -> bool:
    """None is: a tree of many names in a folder without the marker cannot be told from a
    user's folder that holds such names (a review lost a thesis.md that way), so a folder
    an older wtftc wrote is refused like any other; remove it, or choose another --out."""
    return False


def _run_all(out_dir: Path, configs: dict, names: dict, sign_rc, first: str,
             progress: bool) -> list[dict]:
    rows = []
    for plant, rcs in configs.items():
        runs = []
        for rc in rcs:
            print(f"{names[plant]}, case {rc.case} ({CASES[rc.case]}): {rc.t_final:g} s at "
                  f"dt = {rc.dt:g} s", flush=True)
            res = run(rc, progress=progress, keep_states=True)
            m = metrics(rc, res)
            write_outputs(out_dir / names[plant] / f"case{rc.case}", rc, res, m)
            runs.append(run_record(rc, res, m))
            rows.append(m)
        _case_figures(runs, out_dir / names[plant])
    if sign_rc is not None:
        print(f"{names[first]}, case 1 with the control sign as written (s = +1)",
              flush=True)
        res = run(sign_rc, progress=progress)
        m = metrics(sign_rc, res)
        write_outputs(out_dir / names[first] / "case1_sign_as_written", sign_rc, res, m)
        rows.append(m)
    write_table(out_dir, rows)
    return rows


def _case_figures(runs: list[dict], plant_dir: Path) -> None:
    """The counterparts of the paper's Figs. 2-10 for cases 1-3 of one plant, the cases
    side by side, and (the paper's design) V(t) of eq (47) with eq (51)'s check."""
    from wtftc.results import figures
    from wtftc.results.io import atomic_write_json
    from wtftc.verify import lyapunov

    fdir = plant_dir / "figures"
    r1, r2, r3 = runs
    # the observer's estimates x̂: a design that reports them among its diagnostics
    observer = rhs.controllers()[r1["rc"].controller]["diag"][0] == "xhat_1"
    figures.wind(r1, fdir)
    figures.rotor_speed(r1, fdir, "fig03_rotor_speed_case1", "Fig. 3")
    figures.control(r1, fdir, "fig04_control_case1", "Fig. 4")
    if observer:
        figures.estimates(r1, fdir, "fig05_estimates_case1", "Fig. 5")
    figures.fault_shape(r2, fdir)
    figures.rotor_speed(r2, fdir, "fig07_rotor_speed_case2", "Fig. 7")
    figures.rotor_speed(r3, fdir, "fig08_rotor_speed_case3", "Fig. 8")
    figures.control(r3, fdir, "fig09_control_case3", "Fig. 9")
    if observer:
        figures.estimates(r3, fdir, "fig10_estimates_case3", "Fig. 10")
    figures.comparison(runs, fdir)
    if len(r1["result"].t) > 10 and r1["rc"].controller == "paper":  # V_4 is eq (47)'s
        V, bound, _ = lyapunov.along_run(r1["rc"], r1["result"])
        figures.lyapunov_figure(r1, V, r1["result"].t, bound, fdir)
        r1["metrics"]["eq51"] = {"holds": bound.holds, "report": bound.report()}
        atomic_write_json(plant_dir / "case1" / "metrics.json", r1["metrics"])
