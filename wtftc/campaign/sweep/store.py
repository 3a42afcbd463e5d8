"""The results folder: the Parquet dataset ``runs/`` (one file per finished batch, written
atomically), the traces, the sweep file and its record, and reopening it to resume."""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import platform
import re
import socket
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wtftc.campaign.sweep.spec import MISMATCH_KEYS, SENSOR_MAGNITUDES, Sweep
from wtftc.errors import ConfigError

#: the metrics kept per run: (key of wtftc.results.metrics.metrics, unit)
METRICS = [("rms_speed_error_rad_s", "rad/s"), ("max_abs_speed_error_rad_s", "rad/s"),
           ("rms_speed_error_after_fault_rad_s", "rad/s"), ("overspeed_peak_rad_s", "rad/s"),
           ("overspeed_peak_over_rated", "-"), ("pitch_rate_rms_deg_s", "deg/s"),
           ("actuator_travel_deg", "deg"), ("mean_electrical_power_W", "W"),
           ("wall_s", "s"),
           # what the regulation cost (issue 18, docs/loads.md)
           ("shaft_torque_del_1hz_Nm", "N m"), ("shaft_torque_damage_per_10min", "(N m)^m"),
           ("shaft_torque_max_abs_Nm", "N m"), ("pitch_adc", "-"), ("pitch_reversals", "-"),
           ("rms_speed_error_own_above_rated_rad_s", "rad/s"),
           ("rms_speed_error_own_below_rated_rad_s", "rad/s"), ("time_above_1p1_rated_s", "s"),
           # on the tower plant (None on the others)
           ("tower_base_del_1hz_Nm", "N m"), ("tower_base_damage_per_10min", "(N m)^m"),
           ("tower_base_max_abs_Nm", "N m")]
STATUS = ("ok", "diverged", "failed")


def versions() -> dict:
    """What made the results: the versions of wtftc and its dependencies, and the hash of
    the generated code's manifest."""
    import casadi
    import dask
    import distributed
    import pyarrow

    from wtftc import __version__
    from wtftc.artefacts.loader import manifest

    gen = hashlib.sha256(json.dumps(manifest(), sort_keys=True).encode()).hexdigest()[:16]
    return {"wtftc": __version__, "python": platform.python_version(),
            "numpy": np.__version__, "casadi": casadi.__version__, "dask": dask.__version__,
            "distributed": distributed.__version__, "pyarrow": pyarrow.__version__,
            "generated_manifest_sha256": gen}


def schema():
    """The dataset's columns, with units in the field metadata."""
    import pyarrow as pa

    def f(name, typ, unit=None):
        return pa.field(name, typ, metadata={"unit": unit} if unit else None)

    fields = [f("run_id", pa.string()), f("controller", pa.string()),
              f("plant", pa.string()), f("mean_wind_mps", pa.float64(), "m/s"),
              f("turbulence_class", pa.string()), f("seed", pa.int64()),
              f("fault_type", pa.string()), f("blade", pa.int64()),
              f("fault_sensor", pa.int64()),
              f("onset_s", pa.float64(), "s"), f("rho", pa.float64(), "-"),
              f("stuck_angle_deg", pa.string(), "deg"), f("severity", pa.float64(), "-"),
              *[f(f"sensor_{k}", pa.float64(), u) for k, (_, _, _, u) in SENSOR_MAGNITUDES.items()],
              f("runaway_target_deg", pa.float64(), "deg"),
              f("tuning_omega_n_rad_s", pa.float64(), "rad/s"), f("tuning_zeta", pa.float64(), "-"),
              f("fault_detected", pa.bool_()), f("fault_correct", pa.bool_()),
              f("status", pa.string()), f("cause", pa.string()),
              f("diverged_at_s", pa.float64(), "s"), f("diverged_state", pa.string()),
              f("detection_delay_s", pa.float64(), "s"), f("isolation_correct", pa.bool_()),
              f("false_alarms", pa.int64())]
    fields += [f(f"mismatch_{k}", pa.float64(), "-") for k in MISMATCH_KEYS]
    fields += [f(k, pa.float64(), u) for k, u in METRICS]
    fields += [f("config_json", pa.string())]
    return pa.schema(fields)


def read_results(out_dir: Path):
    """Every saved run of a results folder as one pyarrow Table (empty if none)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    parts = sorted((Path(out_dir) / "runs").glob("part-*.parquet"))
    if not parts:
        return schema().empty_table()
    return pa.concat_tables([pq.read_table(p, schema=schema()) for p in parts])


def count_status(out_dir: Path) -> dict[str, int]:
    """How many saved runs of a results folder have each STATUS (ok, diverged, failed)."""
    counts = dict.fromkeys(STATUS, 0)
    for status in read_results(out_dir).column("status").to_pylist():
        counts[status] = counts.get(status, 0) + 1
    return counts


#: the file a sweep holds in its results folder while it writes there
LOCK = "sweep.lock"


@dataclass
class Lock:
    """A held results folder: the lock file and its open descriptor (the kernel's lock
    lives as long as the descriptor, and dies with the process)."""
    path: Path
    fd: int


def claim(out_dir: Path) -> Lock:
    """Hold ``out_dir`` for this process: an exclusive ``flock`` on its lock file (pid and
    host written in it), or refuse naming the process that holds it. The kernel releases
    the lock when its process ends, however it ends, so a lock is never stale. Two sweeps
    writing one folder would each save the other's runs again."""
    lock = Path(out_dir) / LOCK
    lock.parent.mkdir(parents=True, exist_ok=True)
    for _ in range(5):
        fd = os.open(lock, os.O_CREAT | os.O_RDWR, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").split()
            os.close(fd)
            who = f"process {holder[0]} on {holder[1]}" if len(holder) == 2 else "a sweep"
            raise ConfigError("--out", str(out_dir), "a results folder no other sweep is "
                              f"writing to: {who} holds it ({lock}); wait for it to end "
                              "or --out another folder") from None
        try:
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if not same:  # the holder removed the file as we opened it: take the new one
            os.close(fd)
            continue
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()} {socket.gethostname()}\n".encode(), 0)
        return Lock(lock, fd)
    raise ConfigError("--out", str(out_dir), f"a folder whose {LOCK} can be held")


def release(lock: Lock | None) -> None:
    """Give the folder back: remove the lock file (while still holding it, so no one
    holds the removed file), then drop the lock."""
    if lock is not None:
        lock.path.unlink(missing_ok=True)
        os.close(lock.fd)


def _prepare(out_dir: Path, sw: Sweep, sweep_text: str, overwrite: bool,
             retry_failed: bool = False) -> tuple[set[str], Lock, int]:
    """Create or reopen a results folder and hold it (:func:`claim`); return the run ids
    already saved in it, the lock to :func:`release`, and how many failed runs were
    dropped to run again (``retry_failed``, :func:`drop_failed`)."""
    out_dir = Path(out_dir)
    if out_dir.resolve() in (Path.cwd(), *Path.cwd().parents):
        raise ConfigError("--out", str(out_dir), "a folder of its own (not the current folder "
                          "or one that contains it)")
    _check_folder(out_dir, sw, overwrite)
    lock = claim(out_dir)
    try:
        done = _open(out_dir, sw, sweep_text, overwrite)
        retried = drop_failed(out_dir) if retry_failed else 0
        if retried:
            done = set(read_results(out_dir).column("run_id").to_pylist())
        return done, lock, retried
    except BaseException:
        release(lock)
        raise


#: what a sweep writes in its results folder, and so all that --overwrite deletes: these
#: files at the top (the sweep file, its record, the lock, the summary's tables) and, in
#: runs/, traces/ and figures/, each batch's runs, each run's traces (named by its run
#: id) and the summary's figures (FIGURES); the hidden temporaries that a killed
#: sweep's atomic writes left (".<name>.<8 random>", a figure's ".<stem>.<8 random>.<ext>")
#: are its too. Anything else is a user's.
SWEEP_FILES = ("sweep.toml", "sweep.json", LOCK, "summary.md", "summary.csv",
               "summary_cost.csv", "summary_dlc.csv", "summary_tuning.csv")
#: every figure the summary writes, figures/<name>.png and .pdf (summary._save writes
#: no other: a name missing here would be taken for a user's file)
FIGURES = ("rms_speed_error", "overspeed", "detection_delay", "dlc_bins", "dlc21_extremes",
           "tradeoff_fault_free", "tradeoff_faulted")
_HEX16 = "[0-9a-f]{16}"
_TEMP = "[a-z0-9_]{8}"  # tempfile.mkstemp's random part


def _sweep_names() -> dict[str | None, re.Pattern]:
    """Folder (None: the top) → the pattern of the names a sweep writes there."""

    def names(alternatives: str) -> re.Pattern:
        return re.compile(rf"(?:{alternatives})|\.(?:{alternatives})\.{_TEMP}")

    figures = "|".join(map(re.escape, FIGURES))
    return {None: names("|".join(map(re.escape, SWEEP_FILES))),
            "runs": names(rf"part-{_HEX16}\.parquet"),
            "traces": names(rf"{_HEX16}\.parquet"),
            "figures": re.compile(rf"(?:{figures})\.(?:png|pdf)|\.(?:{figures})\.{_TEMP}"
                                  r"\.(?:png|pdf)")}


def sweep_contents(out_dir: Path) -> tuple[list[Path], list[Path]]:
    """(the files a sweep wrote in ``out_dir``, everything else in it). Only regular files
    of the names a sweep writes (:func:`_sweep_names`) are the sweep's; a symbolic link,
    a folder, a file of another name is not (never followed, never deleted)."""
    pattern = _sweep_names()
    ours, other = [], []
    for child in sorted(Path(out_dir).iterdir()):
        if child.name in pattern and child.is_dir() and not child.is_symlink():
            for f in sorted(child.iterdir()):
                mine = (f.is_file() and not f.is_symlink()
                        and pattern[child.name].fullmatch(f.name) is not None)
                (ours if mine else other).append(f)
        elif child.is_file() and not child.is_symlink() and \
                pattern[None].fullmatch(child.name):
            ours.append(child)
        else:
            other.append(child)
    return ours, other


def _open(out_dir: Path, sw: Sweep, sweep_text: str, overwrite: bool) -> set[str]:
    from wtftc.results.io import atomic_write_json, atomic_write_text

    meta = out_dir / "sweep.json"
    if overwrite and meta.exists():
        # only what a sweep wrote (its lock kept: held), after _check_folder found nothing
        # else; a file added since is left where it is, and so is its folder
        ours, _ = sweep_contents(out_dir)
        for f in ours:
            if f.name != LOCK or f.parent != out_dir:
                f.unlink(missing_ok=True)
        for sub in ("runs", "traces", "figures"):
            with contextlib.suppress(OSError):  # absent, or not empty: kept
                (out_dir / sub).rmdir()
    (out_dir / "runs").mkdir(parents=True, exist_ok=True)
    if not meta.exists():
        atomic_write_text(out_dir / "sweep.toml", sweep_text)
        atomic_write_json(meta, {"sweep_id": sw.sweep_id, "sweep": json.loads(sw.text),
                                 "versions": versions(),
                                 "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")})
    return set(read_results(out_dir).column("run_id").to_pylist())


def drop_failed(out_dir: Path) -> int:
    """Remove the runs saved as failed (status "failed": the run raised, its cause in the
    row) from the results of ``out_dir``, so that the sweep runs them again; returns how
    many. Each batch file holding one is rewritten without it, atomically under its own
    name, or removed if it held only failed runs: killed midway, a failed run is either
    still saved or missing, and a missing run is run again by any resume. A diverged run
    is a result (its time, state and cause), not a failure: it stays."""
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    from wtftc.results.io import atomic_write_table

    n = 0
    for part in sorted((Path(out_dir) / "runs").glob("part-*.parquet")):
        table = pq.read_table(part, schema=schema())
        failed = pc.fill_null(pc.equal(table.column("status"), "failed"), False)
        k = pc.sum(failed.cast("int64")).as_py() or 0
        if not k:
            continue
        keep = table.filter(pc.invert(failed))
        if keep.num_rows:
            atomic_write_table(part, keep)
        else:
            part.unlink()
        n += k
    return n


def _check_folder(out_dir: Path, sw: Sweep, overwrite: bool) -> None:
    """Refuse a folder that is not this sweep's results folder (unless --overwrite of a
    sweep's results folder); the lock file alone does not make a folder ours. --overwrite
    deletes only what a sweep wrote (:func:`sweep_contents`): a results folder that also
    holds anything else is refused whole, nothing deleted."""
    meta = out_dir / "sweep.json"
    if out_dir.exists() and any(c.name != LOCK for c in out_dir.iterdir()):
        if not meta.exists():  # never removed, even with --overwrite: it is not ours
            raise ConfigError("--out", str(out_dir), "an empty folder or a sweep's results "
                              "folder (this one holds other files; --overwrite removes only "
                              "a sweep's results folder)")
        if overwrite:
            _, other = sweep_contents(out_dir)
            if other:
                names = ", ".join(str(p.relative_to(out_dir)) for p in other[:3])
                raise ConfigError("--out", str(out_dir), "a sweep's results folder holding "
                                  "only what a sweep wrote, for --overwrite to replace (this "
                                  f"one also holds {len(other)} other: {names}"
                                  + (", ..." if len(other) > 3 else "") + "; nothing was "
                                  "deleted: move them away, or --out another folder)")
        try:
            if not meta.is_file():
                raise OSError("not a regular file")
            old = json.loads(meta.read_text())
            old["sweep_id"], old["versions"]["generated_manifest_sha256"]  # noqa: B018
        except (OSError, ValueError, KeyError, TypeError):
            if not overwrite:
                raise ConfigError("--out", str(out_dir), "a sweep's results folder with a "
                                  "readable sweep.json (this one is damaged; --overwrite "
                                  "discards it)") from None
            old = None
        if old is not None:
            _check_same_sweep(out_dir, old, sw.sweep_id, overwrite)


def _check_same_sweep(out_dir: Path, old: dict, sweep_id: str, overwrite: bool) -> None:
    """A results folder resumes only the same sweep file on the same generated code."""
    now = versions()
    if old["sweep_id"] != sweep_id and not overwrite:
        raise ConfigError("--out", str(out_dir), "the results folder of the same sweep "
                          "file: it holds sweep " + old["sweep_id"] + ", this file is "
                          f"{sweep_id} (changed); pass --overwrite to discard those "
                          "results, or --out a new folder")
    if (old["versions"]["generated_manifest_sha256"]
            != now["generated_manifest_sha256"] and not overwrite):
        raise ConfigError("--out", str(out_dir), "results of the same generated code: "
                          "generated/ changed since they were made; --overwrite or "
                          "--out a new folder")


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
                           pa.Table.from_pylist(rows, schema=schema()))
        done.update(r["run_id"] for r in rows)
    return rows
