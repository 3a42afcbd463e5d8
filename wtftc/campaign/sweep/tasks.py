"""One Dask task: a batch of runs of one compiled loop, or one run in OpenFAST, each to a
row of the dataset (and, asked, its traces). Workers import :func:`run_task` by this
module's path."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from wtftc import config
from wtftc.campaign import cases, tune
from wtftc.campaign.sweep.store import METRICS, UNFINISHED
from wtftc.errors import ProgramKilled
from wtftc.openfast.turbsim import ensure_field
from wtftc.programs import FolderBusy
from wtftc.results.metrics import fdi_ran, metrics, speed_series
from wtftc.sim import rhs


def _row(pt: dict, status: str, m: dict | None = None, cause: str | None = None,
         diverged: dict | None = None) -> dict:
    """The dataset's row of run ``pt`` (store.schema): its axis values, status, metrics ``m``,
    the FDI's detection, the divergence record and its configuration."""
    row = {k: v for k, v in pt.items() if k not in ("config", "twin_onset_s")}
    row.update({"status": status, "cause": cause, "diverged_at_s": None,
                "diverged_state": None, "detection_delay_s": None,
                "isolation_correct": None, "false_alarms": None, "fault_detected": None,
                "fault_correct": None,
                **{k: None for k, _ in METRICS}})
    if m is not None:
        row.update({k: m.get(k) for k, _ in METRICS})
    fdi = m["fdi"] if m is not None else None
    # (a faulty run of a column with wtftc's FDI runs in its case: config.FDI_CASE)
    uses_fdi = pt["config"].get("case") == config.FDI_CASE
    if fdi_ran(fdi):  # (not ROSCO in OpenFAST: its library has no FDI)
        delays = [b["detection_delay_s"] for b in fdi["blades"].values()
                  if b.get("detection_delay_s") is not None]
        if uses_fdi and pt["fault_type"] != "none":
            row["detection_delay_s"] = min(delays) if delays else None
        row["isolation_correct"] = bool(fdi["isolation_correct"])
        row["false_alarms"] = len(fdi["false_alarms"])
        if uses_fdi and fdi["faults"]:
            # the FDI's own account of the run's fault (metrics.fdi_report)
            entry = fdi["faults"][0]
            row["fault_detected"], row["fault_correct"] = entry["detected"], entry["correct"]
            row["detection_delay_s"] = entry["detection_delay_s"]
    if diverged:
        row["diverged_at_s"] = float(diverged["t_s"])
        row["cause"] = diverged.get("reason")
        row["diverged_state"] = json.dumps(diverged.get("last_finite_state"), default=float)
    row["config_json"] = json.dumps(pt["config"], sort_keys=True)
    return row


def run_task(points: list[dict], traces: bool = False, case_root: str | None = None
             ) -> list[tuple[dict, dict | None]]:
    """One Dask task: run ``points`` (one compiled loop) and return (row, traces) each.

    A run that diverges is a result (status "diverged", with its time, state and cause);
    one that raises is recorded as "failed" with the exception (OpenFAST past its time
    limit too), and the others still run. A run whose OpenFAST another's signal ended, or
    whose case folder another run holds, is "unfinished" (store.UNFINISHED): not saved,
    so that a resume runs it again.
    ``case_root``: the results folder's ``openfast/``, where a run in OpenFAST keeps its
    case, ``<case_root>/<run id>/`` (a worker that cannot see the results folder runs it
    in a temporary folder instead; a run in wtftc's own plants writes none).
    """
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # accuracy warnings would flood the workers' logs
        return _run_points(points, traces, case_root)


def case_folder(case_root: str | None, run_id: str) -> Path | None:
    """Where run ``run_id`` keeps its OpenFAST case: under ``case_root`` when this worker
    sees the results folder that holds it (its sweep.json), else None (a temporary)."""
    if case_root is None or not (Path(case_root).parent / "sweep.json").is_file():
        return None
    return Path(case_root) / run_id


def _run_points(points: list[dict], traces: bool, case_root: str | None = None
                ) -> list[tuple[dict, dict | None]]:
    rcs, out = [], []
    for pt in points:
        try:
            raw = tune.resolve(pt["config"])
            ensure_field(raw)  # made before the sweep: found in the cache (a remote worker
            rcs.append(config.make_config(raw))  # with another cache makes its own)
        except Exception as exc:  # noqa: BLE001 - recorded as the run's failure
            rcs.append(f"{type(exc).__name__}: {exc}")
    ok = [rc for rc in rcs if not isinstance(rc, str)]
    results: dict[int, object] = {}
    if ok and not ok[0].uses_rosco and len(ok) > 1:
        try:
            for rc, res in zip(ok, cases.run_batch(ok, progress=False), strict=True):
                results[id(rc)] = res
        except Exception:  # noqa: BLE001 - fall back to one at a time, to find which failed
            results = {}
    for pt, rc in zip(points, rcs, strict=True):
        if isinstance(rc, str):
            out.append((_row(pt, "failed", cause=rc), None))
            continue
        try:
            res = results.get(id(rc)) or cases.run(
                rc, progress=False, openfast_dir=case_folder(case_root, pt["run_id"]))
            m = metrics(rc, res)
        except (ProgramKilled, FolderBusy) as exc:  # not this run's failure: run it again
            out.append((_row(pt, UNFINISHED, cause=f"{type(exc).__name__}: {exc}"), None))
            continue
        except Exception as exc:  # noqa: BLE001
            out.append((_row(pt, "failed", cause=f"{type(exc).__name__}: {exc}"), None))
            continue
        if pt.get("twin_onset_s") is not None:  # a fault-free twin: scored over the
            # window its faulty twin is scored over after the fault (sweep fault_free_twins)
            t, w = speed_series(res)
            e = w[t >= pt["twin_onset_s"]] - rc.reference
            m["rms_speed_error_after_fault_rad_s"] = float(np.sqrt(np.mean(e**2))) \
                if e.size else None
        status = "diverged" if res.diverged else "ok"
        tr = None
        if traces:
            spec = rhs.output_spec(rc.controller, rc.loop.fdi, rc.plant)
            tr = {"time_s": (res.t, "s"), **{n: (res.column(n), u) for n, u in spec}}
        out.append((_row(pt, status, m, diverged=res.diverged), tr))
    return out
