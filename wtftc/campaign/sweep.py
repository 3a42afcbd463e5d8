"""`wtftc sweep`: grid and Monte Carlo campaigns on Dask distributed, resumable.

A sweep file (TOML) names the controller variants of `wtftc compare`, the plants, and the
values or ranges of mean wind speed, turbulence class, wind seed, fault type, faulty blade,
magnitude (ρ, stuck angle, hydraulic severity) and onset time; every run's full
configuration follows from it deterministically, with a stable run id (a hash of that
configuration). Runs go to Dask in batches (one task each); every finished batch is
written at once, atomically, as one Parquet file of the results folder's dataset
``runs/``, so that an interrupted sweep loses no finished run and the same command
resumes with what is missing. docs/sweep.md.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import platform
import shutil
import signal
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wtftc import config
from wtftc.campaign import cases
from wtftc.campaign.compare import CONTROLLERS
from wtftc.errors import ConfigError
from wtftc.results.metrics import metrics
from wtftc.sim import rhs

TOP_KEYS = {"name", "mode", "samples", "sampling_seed", "t_final_s", "dt_s", "output_rate_hz",
            "batch_size", "controllers", "optional_controllers", "plants", "wind", "fault"}
WIND_KEYS = {"mean_mps", "turbulence_class", "seed"}
FAULT_KEYS = {"type", "blade", "onset_s", "rho", "angle_deg", "severity"}
FAULT_TYPES = ("none", "lock", "loss_of_effectiveness", "pressure_drop", "air_in_oil")
TURBULENCE_CLASSES = ("A+", "A", "B", "C")
PLANTS = ("nrel5mw", "paper")
#: the fault table key each fault type reads its magnitude from
MAGNITUDE = {"lock": "angle_deg", "loss_of_effectiveness": "rho", "pressure_drop": "severity",
             "air_in_oil": "severity"}
#: the metrics kept per run: (key in metrics.metrics, unit)
METRICS = [("rms_speed_error_rad_s", "rad/s"), ("max_abs_speed_error_rad_s", "rad/s"),
           ("rms_speed_error_after_fault_rad_s", "rad/s"), ("overspeed_peak_rad_s", "rad/s"),
           ("overspeed_peak_over_rated", "-"), ("pitch_rate_rms_deg_s", "deg/s"),
           ("actuator_travel_deg", "deg"), ("mean_electrical_power_W", "W"),
           ("wall_s", "s")]
STATUS = ("ok", "diverged", "failed")


# ---------------------------------------------------------------------------- sweep file

@dataclass(frozen=True)
class Axis:
    """One swept quantity: discrete ``values``, or a ``range`` (lo, hi) with ``n`` grid
    points (grid mode) or uniform draws (random mode)."""
    key: str
    values: tuple | None = None
    range: tuple | None = None
    n: int | None = None
    integer: bool = False

    def grid(self) -> list:
        if self.values is not None:
            return list(self.values)
        lo, hi = self.range
        if self.integer:
            return list(range(int(lo), int(hi) + 1))
        return [float(v) for v in np.linspace(lo, hi, self.n)]

    def draw(self, rng: np.random.Generator):
        if self.values is not None:
            return self.values[int(rng.integers(len(self.values)))]
        lo, hi = self.range
        if self.integer:
            return int(rng.integers(int(lo), int(hi) + 1))
        return float(rng.uniform(lo, hi))


@dataclass
class Sweep:
    raw: dict  # the parsed sweep file
    text: str  # its canonical form (sorted JSON), hashed into sweep_id
    mode: str
    samples: int | None
    sampling_seed: int
    t_final: float
    dt: float
    output_rate_hz: float
    batch_size: int
    axes: list[Axis]

    @property
    def sweep_id(self) -> str:
        return hashlib.sha256(self.text.encode()).hexdigest()[:16]


def _is_num(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _check_value(key: str, v, kind: str, lo=None, hi=None, lo_open=False, choices=None):
    if choices is not None:
        if v not in choices:
            raise ConfigError(key, v, "one of " + ", ".join(map(str, choices)))
        return v
    if kind == "int":
        if isinstance(v, bool) or not isinstance(v, int):
            raise ConfigError(key, v, "an integer")
    elif kind == "angle":
        if v == "current":
            return v
        if not _is_num(v):
            raise ConfigError(key, v, '"current" or an angle in [0, 90] degrees')
    elif not _is_num(v):
        raise ConfigError(key, v, "a finite number")
    if (lo is not None and (v <= lo if lo_open else v < lo)) or (hi is not None and v > hi):
        left = "(" if lo_open else "["
        raise ConfigError(key, v, f"a value in {left}{lo}, {hi}]")
    return float(v) if kind in ("float", "angle") else v


def _axis(key: str, spec, kind: str, mode: str, **bounds) -> Axis:
    """A list of values, a scalar, or a range table {min, max, n} (n: grid mode only;
    integer ranges take every integer in [min, max])."""
    if isinstance(spec, dict):
        if "choices" in bounds or kind == "angle":
            raise ConfigError(key, spec, "a list of values (this key has no range form)")
        extra = set(spec) - {"min", "max", "n"}
        if extra:
            raise ConfigError(f"{key}.{sorted(extra)[0]}", spec[sorted(extra)[0]],
                              "a key of a range: min, max, n")
        for k in ("min", "max"):
            if k not in spec:
                raise ConfigError(f"{key}.{k}", None, f"a {k} for the range")
        lo = _check_value(f"{key}.min", spec["min"], kind, **bounds)
        hi = _check_value(f"{key}.max", spec["max"], kind, **bounds)
        if hi < lo:
            raise ConfigError(f"{key}.max", hi, f"at least {key}.min = {lo} (an empty range)")
        n = None
        if kind != "int":
            if mode == "grid":
                n = spec.get("n")
                if isinstance(n, bool) or not isinstance(n, int) or n < 1:
                    raise ConfigError(f"{key}.n", n, "an integer >= 1: the number of grid "
                                      "points (grid mode)")
                if n == 1 and hi != lo:
                    raise ConfigError(f"{key}.n", n, "at least 2 for a range with min < max")
            elif "n" in spec:
                raise ConfigError(f"{key}.n", spec["n"], "no n in random mode (values are "
                                  "drawn uniformly from [min, max])")
        elif "n" in spec:
            raise ConfigError(f"{key}.n", spec["n"], "no n for an integer range (every "
                              "integer in [min, max])")
        return Axis(key, range=(lo, hi), n=n, integer=kind == "int")
    values = spec if isinstance(spec, list) else [spec]
    if not values:
        raise ConfigError(key, spec, "at least one value (an empty list sweeps nothing)")
    checked = tuple(_check_value(key, v, kind, **bounds) for v in values)
    if len(set(checked)) != len(checked):
        raise ConfigError(key, spec, "distinct values")
    return Axis(key, values=checked, integer=kind == "int")


def parse_sweep(raw: dict) -> Sweep:
    """Validate a sweep file's content before anything runs: each error names the key."""
    if not isinstance(raw, dict):
        raise ConfigError("sweep", raw, "a TOML table")
    for key in raw:
        if key not in TOP_KEYS:
            raise ConfigError(key, raw[key], "a sweep key: " + ", ".join(sorted(TOP_KEYS)))
    mode = raw.get("mode", "grid")
    if mode not in ("grid", "random"):
        raise ConfigError("mode", mode, '"grid" (every combination) or "random" (samples '
                          "draws)")
    samples = raw.get("samples")
    if mode == "random":
        if isinstance(samples, bool) or not isinstance(samples, int) or not 1 <= samples <= 10**6:
            raise ConfigError("samples", samples, "an integer in [1, 1000000]: the number of "
                          "random scenarios (random mode)")
    elif samples is not None:
        raise ConfigError("samples", samples, 'only with mode = "random"')
    sampling_seed = _check_value("sampling_seed", raw.get("sampling_seed", 0), "int", lo=0)
    t_final = _check_value("t_final_s", raw.get("t_final_s", 60.0), "float", lo=0, hi=36000,
                           lo_open=True)
    dt = _check_value("dt_s", raw.get("dt_s", 1e-3), "float", lo=0, hi=0.1, lo_open=True)
    rate = _check_value("output_rate_hz", raw.get("output_rate_hz", 10.0), "float", lo=0,
                        hi=1e6, lo_open=True)
    batch = _check_value("batch_size", raw.get("batch_size", 8), "int", lo=1, hi=10000)
    if "controllers" not in raw:
        raise ConfigError("controllers", None, "a list of controller variants: "
                          + ", ".join(CONTROLLERS))
    wind = raw.get("wind", {})
    fault = raw.get("fault", {"type": "none"})
    for tab, name, keys in ((wind, "wind", WIND_KEYS), (fault, "fault", FAULT_KEYS)):
        if not isinstance(tab, dict):
            raise ConfigError(name, tab, "a table")
        for key in tab:
            if key not in keys:
                raise ConfigError(f"{name}.{key}", tab[key],
                                  f"a key of [{name}]: " + ", ".join(sorted(keys)))
    ctrl = _axis("controllers", raw["controllers"], "str", mode, choices=tuple(CONTROLLERS))
    if "optional_controllers" in raw:  # run where installed (ROSCO), skipped elsewhere
        optional = _axis("optional_controllers", raw["optional_controllers"], "str", mode,
                         choices=("rosco",))
        from wtftc.sim import rosco

        extra = tuple(c for c in optional.values if c not in ctrl.values)
        if extra and rosco.available() is None:
            ctrl = Axis("controllers", values=ctrl.values + extra)
    axes = [
        ctrl,
        _axis("plants", raw.get("plants", "nrel5mw"), "str", mode, choices=PLANTS),
        _axis("wind.mean_mps", wind.get("mean_mps", 16.0), "float", mode, lo=3.0, hi=40.0),
        _axis("wind.turbulence_class", wind.get("turbulence_class", "B"), "str", mode,
              choices=TURBULENCE_CLASSES),
        _axis("wind.seed", wind.get("seed", 0), "int", mode, lo=0),
        _axis("fault.type", fault.get("type", "none"), "str", mode, choices=FAULT_TYPES),
        _axis("fault.blade", fault.get("blade", 1), "int", mode, lo=1, hi=3),
        _axis("fault.onset_s", fault.get("onset_s", 20.0), "float", mode, lo=0.0,
              hi=t_final, lo_open=False),
        _axis("fault.rho", fault.get("rho", 0.5), "float", mode, lo=0.0, hi=1.0,
              lo_open=True),
        _axis("fault.angle_deg", fault.get("angle_deg", "current"), "angle", mode, lo=0.0,
              hi=90.0),
        _axis("fault.severity", fault.get("severity", 1.0), "float", mode, lo=0.0, hi=1.0,
              lo_open=True),
    ]
    by_key = {a.key: a for a in axes}
    onsets = by_key["fault.onset_s"]
    faulty = set(by_key["fault.type"].values) != {"none"}
    if faulty and max(onsets.grid() if onsets.values else [onsets.range[1]]) >= t_final:
        raise ConfigError("fault.onset_s", list(onsets.values or onsets.range),
                          f"onsets before t_final_s = {t_final:g} s")
    if "rosco" in (by_key["controllers"].values or ()) and "paper" in (
            by_key["plants"].values or ()):
        raise ConfigError("plants", "paper", "nrel5mw only when controllers include rosco "
                          "(ROSCO's DISCON.IN is tuned for the NREL 5-MW)")
    canonical = json.dumps({**raw, "mode": mode, "sampling_seed": sampling_seed,
                            "t_final_s": t_final, "dt_s": dt, "output_rate_hz": rate,
                            "batch_size": batch}, sort_keys=True)
    return Sweep(raw=raw, text=canonical, mode=mode, samples=samples,
                 sampling_seed=sampling_seed, t_final=t_final, dt=dt, output_rate_hz=rate,
                 batch_size=batch, axes=axes)


def load_sweep(path: Path) -> Sweep:
    return parse_sweep(config.load_toml(Path(path)))


# ---------------------------------------------------------------------------- the runs

def _point(sw: Sweep, values: dict) -> dict:
    """One run: the axis values that matter for it (the rest None) and its configuration."""
    ftype = values["fault.type"]
    p = {"controller": values["controllers"], "plant": values["plants"],
         "mean_wind_mps": float(values["wind.mean_mps"]),
         "turbulence_class": values["wind.turbulence_class"], "seed": int(values["wind.seed"]),
         "fault_type": ftype, "blade": None, "onset_s": None, "rho": None,
         "stuck_angle_deg": None, "severity": None}
    faults = None
    if ftype != "none":
        p["blade"], p["onset_s"] = int(values["fault.blade"]), float(values["fault.onset_s"])
        tab = {"blade": p["blade"], "type": ftype, "onset_s": p["onset_s"]}
        mag = MAGNITUDE[ftype]
        tab[mag] = values[f"fault.{mag}"]
        p[{"angle_deg": "stuck_angle_deg", "rho": "rho", "severity": "severity"}[mag]] = (
            str(tab[mag]) if mag == "angle_deg" else float(tab[mag]))
        faults = [tab]
    from wtftc.campaign.compare import variant_config

    wind = {"kind": "ntm", "mean_mps": p["mean_wind_mps"],
            "turbulence_class": p["turbulence_class"]}
    cfg = variant_config(p["controller"], faults, wind, sw.t_final, sw.dt, p["seed"], "")
    cfg.update(plant=p["plant"], output_rate_hz=sw.output_rate_hz)
    run_id = hashlib.sha256(json.dumps(cfg, sort_keys=True).encode()).hexdigest()[:16]
    cfg["label"] = f"sweep-{run_id}"
    return {"run_id": run_id, **p, "config": cfg}


def expand(sw: Sweep) -> tuple[list[dict], int]:
    """Every run of the sweep, in a fixed order, duplicates removed (a fault-free run does
    not depend on blade, onset or magnitude); returns (runs, number of duplicates).

    Grid: every combination of every axis. Random: ``samples`` scenarios (wind, seed and
    fault drawn from their axes with ``sampling_seed``), each run with every controller
    and plant."""
    keys = [a.key for a in sw.axes]
    if sw.mode == "grid":
        combos = (dict(zip(keys, vals, strict=True))
                  for vals in itertools.product(*(a.grid() for a in sw.axes)))
    else:
        # random scenarios (wind, seed, fault), each run by every controller on every plant:
        # a paired comparison, and the draws do not depend on which controllers are swept
        rng = np.random.default_rng(sw.sampling_seed)
        crossed, drawn = sw.axes[:2], sw.axes[2:]
        scenarios = [{a.key: a.draw(rng) for a in drawn} for _ in range(sw.samples)]
        combos = ({**sc, **dict(zip(keys[:2], cp, strict=True))} for sc in scenarios
                  for cp in itertools.product(*(a.grid() for a in crossed)))
    runs, seen, dup = [], set(), 0
    for values in combos:
        pt = _point(sw, values)
        if pt["run_id"] in seen:
            dup += 1
            continue
        seen.add(pt["run_id"])
        runs.append(pt)
    return runs, dup


def batches(runs: list[dict], size: int) -> list[list[dict]]:
    """Runs grouped into tasks of at most ``size``, each of one compiled loop (controller
    and plant), so that a task advances its runs in one call (cases.run_batch)."""
    groups: dict[tuple, list] = {}
    for r in runs:
        groups.setdefault((r["controller"], r["plant"]), []).append(r)
    per_group = [[g[i:i + size] for i in range(0, len(g), size)] for g in groups.values()]
    # interleaved, so that the rate (and the ETA) mixes the fast loops with the slow ones
    return [b for row in itertools.zip_longest(*per_group) for b in row if b is not None]


def _row(pt: dict, status: str, m: dict | None = None, cause: str | None = None,
         diverged: dict | None = None) -> dict:
    row = {k: v for k, v in pt.items() if k != "config"}
    row.update({"status": status, "cause": cause, "diverged_at_s": None,
                "diverged_state": None, "detection_delay_s": None,
                "isolation_correct": None, "false_alarms": None,
                **{k: None for k, _ in METRICS}})
    if m is not None:
        row.update({k: m.get(k) for k, _ in METRICS})
        fdi = m["fdi"]
        delays = [b["detection_delay_s"] for b in fdi["blades"].values()
                  if b.get("detection_delay_s") is not None]
        if CONTROLLERS[pt["controller"]][1] == 4 and pt["fault_type"] != "none":
            row["detection_delay_s"] = min(delays) if delays else None
        row["isolation_correct"] = bool(fdi["isolation_correct"])
        row["false_alarms"] = len(fdi["false_alarms"])
    if diverged:
        row["diverged_at_s"] = float(diverged["t_s"])
        row["cause"] = diverged.get("reason")
        row["diverged_state"] = json.dumps(diverged.get("last_finite_state"), default=float)
    row["config_json"] = json.dumps(pt["config"], sort_keys=True)
    return row


def run_task(points: list[dict], traces: bool = False) -> list[tuple[dict, dict | None]]:
    """One Dask task: run ``points`` (one compiled loop) and return (row, traces) each.

    A run that diverges is a result (status "diverged", with its time, state and cause);
    one that raises is recorded as "failed" with the exception, and the others still run.
    """
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # accuracy warnings would flood the workers' logs
        return _run_points(points, traces)


def _run_points(points: list[dict], traces: bool) -> list[tuple[dict, dict | None]]:

    rcs, out = [], []
    for pt in points:
        try:
            rcs.append(config.make_config(pt["config"]))
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
            res = results.get(id(rc)) or cases.run(rc, progress=False)
            m = metrics(rc, res)
        except Exception as exc:  # noqa: BLE001
            out.append((_row(pt, "failed", cause=f"{type(exc).__name__}: {exc}"), None))
            continue
        status = "diverged" if res.diverged else "ok"
        tr = None
        if traces:
            spec = rhs.output_spec(rc.controller)
            tr = {"time_s": (res.t, "s"), **{n: (res.column(n), u) for n, u in spec}}
        out.append((_row(pt, status, m, diverged=res.diverged), tr))
    return out


# ---------------------------------------------------------------------------- the results

def _versions() -> dict:
    import casadi
    import dask
    import distributed
    import pyarrow

    from wtftc.artefacts.loader import manifest
    from wtftc import __version__

    gen = hashlib.sha256(json.dumps(manifest(), sort_keys=True).encode()).hexdigest()[:16]
    return {"wtftc": __version__, "python": platform.python_version(),
            "numpy": np.__version__, "casadi": casadi.__version__, "dask": dask.__version__,
            "distributed": distributed.__version__, "pyarrow": pyarrow.__version__,
            "generated_manifest_sha256": gen}


def _schema():
    import pyarrow as pa

    def f(name, typ, unit=None):
        return pa.field(name, typ, metadata={"unit": unit} if unit else None)

    fields = [f("run_id", pa.string()), f("controller", pa.string()),
              f("plant", pa.string()), f("mean_wind_mps", pa.float64(), "m/s"),
              f("turbulence_class", pa.string()), f("seed", pa.int64()),
              f("fault_type", pa.string()), f("blade", pa.int64()),
              f("onset_s", pa.float64(), "s"), f("rho", pa.float64(), "-"),
              f("stuck_angle_deg", pa.string(), "deg"), f("severity", pa.float64(), "-"),
              f("status", pa.string()), f("cause", pa.string()),
              f("diverged_at_s", pa.float64(), "s"), f("diverged_state", pa.string()),
              f("detection_delay_s", pa.float64(), "s"), f("isolation_correct", pa.bool_()),
              f("false_alarms", pa.int64())]
    fields += [f(k, pa.float64(), u) for k, u in METRICS]
    fields += [f("config_json", pa.string())]
    return pa.schema(fields)


def read_results(out_dir: Path):
    """Every saved run of a results folder as one pyarrow Table (empty if none)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    parts = sorted((Path(out_dir) / "runs").glob("part-*.parquet"))
    if not parts:
        return _schema().empty_table()
    return pa.concat_tables([pq.read_table(p, schema=_schema()) for p in parts])


def _prepare(out_dir: Path, sw: Sweep, sweep_text: str, overwrite: bool) -> set[str]:
    """Create or reopen a results folder; return the run ids already saved in it."""
    from wtftc.results.io import atomic_write_json, atomic_write_text

    out_dir = Path(out_dir)
    meta = out_dir / "sweep.json"
    if out_dir.exists() and any(out_dir.iterdir()):
        if not meta.exists():
            if not overwrite:
                raise ConfigError("--out", str(out_dir), "an empty folder or a sweep's results "
                                  "folder (it holds other files; --overwrite clears it)")
        else:
            old = json.loads(meta.read_text())
            versions = _versions()
            if old["sweep_id"] != sw.sweep_id and not overwrite:
                raise ConfigError("--out", str(out_dir), "the results folder of the same sweep "
                                  "file: it holds sweep " + old["sweep_id"] + ", this file is "
                                  f"{sw.sweep_id} (changed); pass --overwrite to discard those "
                                  "results, or --out a new folder")
            if (old["versions"]["generated_manifest_sha256"]
                    != versions["generated_manifest_sha256"] and not overwrite):
                raise ConfigError("--out", str(out_dir), "results of the same generated code: "
                                  "generated/ changed since they were made; --overwrite or "
                                  "--out a new folder")
        if overwrite:
            shutil.rmtree(out_dir)
    (out_dir / "runs").mkdir(parents=True, exist_ok=True)
    if not meta.exists():
        atomic_write_text(out_dir / "sweep.toml", sweep_text)
        atomic_write_json(meta, {"sweep_id": sw.sweep_id, "sweep": json.loads(sw.text),
                                 "versions": _versions(),
                                 "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")})
    return set(read_results(out_dir).column("run_id").to_pylist())


def _save_batch(out_dir: Path, done: set[str], results: list) -> list[dict]:
    """Write one finished task's runs: traces first, then the metrics file that lists
    them, atomically; runs already saved (a task a dying worker made Dask repeat) are
    dropped. Returns the rows written."""
    import pyarrow as pa

    from wtftc.results.io import atomic_write_table, write_parquet

    rows = []
    for row, tr in results:
        if row["run_id"] in done:
            continue
        if tr is not None:
            write_parquet(Path(out_dir) / "traces" / f"{row['run_id']}.parquet",
                          {k: v for k, (v, _) in tr.items()}, {k: u for k, (_, u) in tr.items()})
        rows.append(row)
    if rows:
        ids = "".join(sorted(r["run_id"] for r in rows))
        name = f"part-{hashlib.sha256(ids.encode()).hexdigest()[:16]}.parquet"
        atomic_write_table(Path(out_dir) / "runs" / name,
                           pa.Table.from_pylist(rows, schema=_schema()))
        done.update(r["run_id"] for r in rows)
    return rows


class _Progress:
    def __init__(self, total: int, already: int, quiet: bool):
        self.total, self.already, self.quiet = total, already, quiet
        self.counts = dict.fromkeys(STATUS, 0)
        self.t0 = time.perf_counter()
        self.tty = sys.stderr.isatty()

    def update(self, rows: list[dict], lost: int = 0, end: bool = False) -> None:
        for r in rows:
            self.counts[r["status"]] += 1
        if self.quiet:
            return
        n = sum(self.counts.values())
        left = self.total - self.already - n - lost
        wall = time.perf_counter() - self.t0
        eta = f"{left * wall / n:.0f} s" if n else "?"
        line = (f"[sweep] {self.already + n}/{self.total} runs: {self.counts['ok']} ok, "
                f"{self.counts['diverged']} diverged, {self.counts['failed']} failed"
                + (f", {lost} lost" if lost else "")
                + f", {left} remaining, {n / max(wall, 1e-9):.2f} runs/s, ETA {eta}")
        if self.tty and not end:
            print("\r" + line, end="", file=sys.stderr, flush=True)
        else:
            print(("\r" if self.tty else "") + line, file=sys.stderr, flush=True)


def _client(scheduler: str | None, workers: int):
    import logging

    from dask.distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout="10s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise ConfigError("--scheduler", scheduler, "the address of a running Dask "
                              f"scheduler, tcp://HOST:PORT ({type(exc).__name__}: {exc})"
                              ) from None
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=":0", silence_logs=logging.ERROR)
    return Client(cluster), cluster


class Interrupted(Exception):
    """Ctrl-C or SIGTERM: the sweep stopped; what finished is saved."""


def run_sweep(sweep_path: Path, out_dir: Path, workers: int = 2, scheduler: str | None = None,
              traces: bool = False, overwrite: bool = False, quiet: bool = False) -> dict:
    """Run (or resume) a sweep into out_dir; returns counts of what this call did."""
    from dask.distributed import as_completed

    sweep_path = Path(sweep_path)
    sw = load_sweep(sweep_path)
    runs, dup = expand(sw)
    for pt in runs:  # every run's configuration is valid before any runs
        if pt["controller"] != "rosco":  # ROSCO's availability is checked below
            config.make_config(pt["config"])
    if any(pt["controller"] == "rosco" for pt in runs):
        from wtftc.sim import rosco

        reason = rosco.available()
        if reason:
            raise ConfigError("controllers", "rosco", reason)
    skipped = [c for c in sw.raw.get("optional_controllers", []) if c not in sw.axes[0].values]
    if skipped and not quiet:
        from wtftc.sim import rosco

        print(f"note: optional controllers {', '.join(skipped)} skipped: {rosco.available()}",
              flush=True)
    done = _prepare(out_dir, sw, sweep_path.read_text(), overwrite)
    todo = [pt for pt in runs if pt["run_id"] not in done]
    if not quiet:
        print(f"sweep {sw.sweep_id} ({sw.mode}): {len(runs)} runs"
              + (f" ({dup} duplicate draws dropped)" if dup else "")
              + (f", {len(runs) - len(todo)} already in {out_dir}" if len(todo) < len(runs)
                 else "") + f", {len(todo)} to run in batches of {sw.batch_size}", flush=True)
    summary = {"runs": len(runs), "already": len(runs) - len(todo), "ran": 0, "lost": 0}
    if not todo:
        return summary
    progress = _Progress(len(runs), len(runs) - len(todo), quiet)

    def _stop(signum, frame):
        raise Interrupted(signal.Signals(signum).name)

    old = signal.signal(signal.SIGTERM, _stop)
    client, cluster = _client(scheduler, workers)
    try:
        if not quiet:
            n_workers = len(client.scheduler_info()["workers"])
            print(f"Dask: {scheduler or 'local cluster'}, {n_workers} workers", flush=True)
        futures = [client.submit(run_task, b, traces, pure=False)
                   for b in batches(todo, sw.batch_size)]
        lost = 0
        for fut in as_completed(futures):
            try:
                results = fut.result()
            except Exception as exc:  # noqa: BLE001 - a worker died: the runs stay missing
                lost += 1
                if not quiet:
                    print(f"\n[sweep] a task was lost ({type(exc).__name__}: {exc}); its runs "
                          "stay missing: run the same command again to retry them",
                          file=sys.stderr)
                continue
            rows = _save_batch(out_dir, done, results)
            summary["ran"] += len(rows)
            progress.update(rows, lost)
        summary["lost"] = lost
        if progress.tty:
            progress.update([], lost, end=True)  # end the line the carriage returns rewrote
    except KeyboardInterrupt:
        raise Interrupted("SIGINT") from None
    finally:
        signal.signal(signal.SIGTERM, old)
        client.close()
        if cluster is not None:
            cluster.close()
    return summary


# ---------------------------------------------------------------------------- summary

def summarize(out_dir: Path) -> str:
    """The summary table (Markdown, printed) and figures of a results folder:
    summary.md, summary.csv, and under figures/ the distributions of RMS speed error,
    overspeed and detection delay, per controller and fault type."""
    from wtftc.results.io import atomic_write_text

    out_dir = Path(out_dir)
    if not (out_dir / "sweep.json").exists():
        raise ConfigError("--summary", str(out_dir), "a sweep's results folder (with sweep.json)")
    meta = json.loads((out_dir / "sweep.json").read_text())
    table = read_results(out_dir)
    rows = table.to_pylist()
    sw = parse_sweep(meta["sweep"])
    n_all = len(expand(sw)[0])
    groups: dict[tuple, list] = {}
    for r in rows:
        groups.setdefault((r["controller"], r["fault_type"]), []).append(r)
    cols = ["controller", "fault", "runs", "diverged", "failed",
            "RMS ω error median [rad/s]", "RMS ω error p95 [rad/s]", "RMS ω error max [rad/s]",
            "peak ω / rated max [-]", "detection delay median [s]",
            "detection delay max [s]", "undetected", "false alarms"]
    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    csv = [",".join(c.replace(",", ";") for c in cols)]

    def q(vals, p):
        return float(np.percentile(vals, p)) if vals else None

    for (c, f), rs in sorted(groups.items(), key=lambda kv: (
            list(CONTROLLERS).index(kv[0][0]), FAULT_TYPES.index(kv[0][1]))):
        good = [r for r in rs if r["status"] != "failed"]
        rms = [r["rms_speed_error_rad_s"] for r in good]
        peak = [r["overspeed_peak_over_rated"] for r in good]
        fdi = CONTROLLERS[c][1] == 4 and f != "none"
        delays = [r["detection_delay_s"] for r in good if r["detection_delay_s"] is not None]
        vals = [c, f, len(rs), sum(r["status"] == "diverged" for r in rs),
                sum(r["status"] == "failed" for r in rs), q(rms, 50), q(rms, 95),
                max(rms) if rms else None, max(peak) if peak else None,
                q(delays, 50) if fdi else None, max(delays) if fdi and delays else None,
                (len(good) - len(delays)) if fdi else None,
                sum(r["false_alarms"] or 0 for r in good if CONTROLLERS[c][1] == 4)]
        fmt = ["{}", "{}", "{}", "{}", "{}", "{:.4f}", "{:.4f}", "{:.4f}", "{:.3f}", "{:.2f}",
               "{:.2f}", "{}", "{}"]
        cells = ["—" if v is None else f_.format(v) for v, f_ in zip(vals, fmt, strict=True)]
        lines.append("| " + " | ".join(cells) + " |")
        csv.append(",".join("" if v is None else str(v) for v in vals))
    bad = [r for r in rows if r["status"] != "ok"]
    head = [f"# Sweep {meta['sweep_id']}: {len(rows)} of {n_all} runs saved",
            "", f"Results folder `{out_dir}`; made with "
            + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()) + ".", ""]
    tail = ["", f"## Failed or diverged runs: {len(bad)}", ""]
    if bad:
        tail += ["| run id | controller | fault | wind [m/s] | class | seed | status | at [s] "
                 "| cause |", "|---|---|---|---|---|---|---|---|---|"]
        for r in bad:
            at = "—" if r["diverged_at_s"] is None else f"{r['diverged_at_s']:.3f}"
            tail.append(f"| {r['run_id']} | {r['controller']} | {r['fault_type']} | "
                        f"{r['mean_wind_mps']:.2f} | {r['turbulence_class']} | {r['seed']} | "
                        f"{r['status']} | {at} | {(r['cause'] or '').replace('|', '/')} |")
        tail += ["", "Each run re-runs alone: `wtftc sweep --show RUN_ID --out DIR > run.toml`, "
                 "then `wtftc run --config run.toml` (its configuration is also the dataset's "
                 "`config_json`)."]
    text = "\n".join(head + lines + tail) + "\n"
    atomic_write_text(out_dir / "summary.md", text)
    atomic_write_text(out_dir / "summary.csv", "\n".join(csv) + "\n")
    if rows:
        _figures(out_dir, rows)
    return text


def _figures(out_dir: Path, rows: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from wtftc.results.io import atomic_savefig

    ctrls = [c for c in CONTROLLERS if any(r["controller"] == c for r in rows)]
    faults = [f for f in FAULT_TYPES if any(r["fault_type"] == f for r in rows)]
    specs = [("rms_speed_error_rad_s", "RMS rotor-speed error [rad/s]", "rms_speed_error"),
             ("overspeed_peak_over_rated", "peak rotor speed / rated [-]", "overspeed")]
    for key, label, name in specs:
        fig, ax = plt.subplots(figsize=(max(7, 1.2 * len(faults) * len(ctrls) / 2), 4.5))
        width = 0.8 / len(ctrls)
        for k, c in enumerate(ctrls):
            data, pos = [], []
            for i, f in enumerate(faults):
                v = [r[key] for r in rows if r["controller"] == c and r["fault_type"] == f
                     and r[key] is not None and r["status"] != "failed"]
                if v:
                    data.append(v)
                    pos.append(i + (k - (len(ctrls) - 1) / 2) * width)
            if data:
                bp = ax.boxplot(data, positions=pos, widths=width * 0.9, patch_artist=True,
                                manage_ticks=False, flierprops={"markersize": 2},
                                medianprops={"color": "k"})
                for b in bp["boxes"]:
                    b.set_facecolor(f"C{k}")
                ax.plot([], [], "s", color=f"C{k}", label=c)
        ax.set_xticks(range(len(faults)), faults, fontsize=8)
        ax.set_ylabel(label)
        ax.set_xlabel("fault type")
        ax.grid(alpha=0.3, axis="y")
        ax.legend(fontsize=8)
        ax.set_title(f"{label.split(' [')[0]}: distribution over the sweep's runs", fontsize=9)
        fig.tight_layout()
        for ext in ("png", "pdf"):
            atomic_savefig(fig, out_dir / "figures" / f"{name}.{ext}", dpi=120)
        plt.close(fig)
    fdi_rows = [r for r in rows if CONTROLLERS[r["controller"]][1] == 4
                and r["fault_type"] != "none" and r["detection_delay_s"] is not None]
    fig, ax = plt.subplots(figsize=(7, 4))
    for k, f in enumerate(f for f in faults if f != "none"):
        v = [r["detection_delay_s"] for r in fdi_rows if r["fault_type"] == f]
        if v:
            ax.hist(v, bins=30, alpha=0.6, color=f"C{k}", label=f"{f} ({len(v)} runs)")
    ax.set_xlabel("detection delay [s]")
    ax.set_ylabel("runs [-]")
    ax.grid(alpha=0.3)
    if fdi_rows:
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no detected faults (no FDI controller, or no fault, in the sweep)",
                ha="center", va="center", transform=ax.transAxes)
    ax.set_title("Detection delay of wtftc's FDI (controllers with their own detection)",
                 fontsize=9)
    fig.tight_layout()
    for ext in ("png", "pdf"):
        atomic_savefig(fig, out_dir / "figures" / f"detection_delay.{ext}", dpi=120)
    plt.close(fig)


def show_run(out_dir: Path, run_id: str) -> str:
    """A saved run's configuration as TOML, for `wtftc run --config`."""
    table = read_results(out_dir)
    for r in table.to_pylist():
        if r["run_id"] == run_id:
            return config.to_toml(json.loads(r["config_json"]))
    raise ConfigError("--show", run_id, f"the run id of a run saved in {out_dir}")


