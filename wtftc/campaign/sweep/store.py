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
import stat
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wtftc.campaign.sweep import record
from wtftc.campaign.sweep.record import CASES, LOCK, PART, RECORD, Record
from wtftc.campaign.sweep.spec import MISMATCH_KEYS, SENSOR_MAGNITUDES, Sweep
from wtftc.errors import ConfigError
from wtftc.files import MAX_TOML_BYTES, read_user_text
from wtftc.model import turbine_file

#: the metrics kept per run: (key of wtftc.results.metrics.metrics, unit)
METRICS = [("rms_speed_error_rad_s", "rad/s"), ("max_abs_speed_error_rad_s", "rad/s"),
           ("rms_speed_error_after_fault_rad_s", "rad/s"), ("overspeed_peak_rad_s", "rad/s"),
           ("overspeed_peak_over_rated", "-"), ("pitch_rate_rms_deg_s", "deg/s"),
           ("actuator_travel_deg", "deg"), ("mean_electrical_power_W", "W"),
           ("wall_s", "s"),
           # what the regulation cost (issue 18, docs/loads.md)
           ("shaft_torque_del_1hz_Nm", "N m"), ("shaft_torque_damage_per_10min", "(N m)^m"),
           ("shaft_torque_max_abs_Nm", "N m"), ("shaft_torque_std_Nm", "N m"),
           ("pitch_adc", "-"), ("pitch_reversals", "-"),
           # WEIS's avg_pitch_travel and pitch_duty_cycle, by what they are (issue 31)
           ("pitch_travel_rate_deg_s", "deg/s"), ("pitch_reversals_per_s", "1/s"),
           # the start-up left out of every metric, and the rate they were computed at
           ("transient_s", "s"), ("metrics_rate_hz", "Hz"),
           ("rms_speed_error_own_above_rated_rad_s", "rad/s"),
           ("rms_speed_error_own_below_rated_rad_s", "rad/s"), ("time_above_1p1_rated_s", "s"),
           # on the tower plant (None on the others)
           ("tower_base_del_1hz_Nm", "N m"), ("tower_base_damage_per_10min", "(N m)^m"),
           ("tower_base_max_abs_Nm", "N m"),
           # a fault's extremes, from its onset on (None without a fault)
           ("overspeed_peak_over_rated_after_onset", "-"),
           ("speed_min_over_rated_after_onset", "-"),
           ("shaft_torque_max_abs_after_onset_Nm", "N m"),
           ("tower_base_max_abs_after_onset_Nm", "N m"),
           ("blade_root_flap_max_abs_after_onset_Nm", "N m"), ("energy_after_onset_J", "J"),
           # the blade root's flapwise bending from OpenFAST (None on wtftc's own plants)
           ("blade_root_flap_del_1hz_Nm", "N m"), ("blade_root_flap_damage_per_10min", "(N m)^m"),
           ("blade_root_flap_max_abs_Nm", "N m"),
           # WEIS's controller test bench's maximum pitch rate, and its 1P and 3P bands
           ("pitch_rate_max_abs_deg_s", "deg/s"),
           ("tower_base_1p_std_Nm", "N m"), ("tower_base_3p_std_Nm", "N m"),
           ("blade_root_flap_1p_std_Nm", "N m"), ("blade_root_flap_3p_std_Nm", "N m")]
STATUS = ("ok", "diverged", "failed")
#: a run whose external program (OpenFAST) was ended by a signal wtftc did not send, or
#: whose case folder another run held: neither a result nor a failure, so not saved; the
#: next resume runs it again (wtftc.errors.ProgramKilled, wtftc.programs.FolderBusy)
UNFINISHED = "unfinished"


#: what a run computes outside the generated code, numbered: raised when a change to the
#: Python side alters the results of a configuration that ran before (2: issue 34's
#: speed noise scaled to the turbine's shafts, wtftc.config._scale_speed_noise; 3: the
#: FDI's start-up alignment on by default on OpenFAST, wtftc.config.HOST_ALIGN_RATE; 4: a
#: run starts from its turbine's cut-in wind where the Cp table's ratios end, and the IEA
#: 15-MW's torque law at its mechanical rated power, wtftc.sim.trim, iea15mw.toml), so
#: that a results folder made before is not resumed into a mixed dataset
RUN_SEMANTICS = 4


def versions() -> dict:
    """What made the results: the versions of wtftc and its dependencies, and the hash of
    the generated code (its artefacts' hashes in the manifest: what the runs compute, not
    the derivation's sources, so an edit that leaves every artefact as it was, a comment or
    a refactor, does not stop a campaign from resuming)."""
    import casadi
    import dask
    import distributed
    import pyarrow

    from wtftc import __version__
    from wtftc.artefacts.loader import generated_code_sha256

    gen = generated_code_sha256()
    return {"wtftc": __version__, "python": platform.python_version(),
            "numpy": np.__version__, "casadi": casadi.__version__, "dask": dask.__version__,
            "distributed": distributed.__version__, "pyarrow": pyarrow.__version__,
            "generated_code_sha256": gen, "run_semantics": RUN_SEMANTICS}


def turbine_sha256(sw: Sweep) -> str:
    """The hash of what the sweep's turbine is made of: its turbine file and its Cp table,
    as bytes (a run's configuration names the turbine, not its values, so an edit of the
    file would otherwise resume a campaign on a different turbine)."""
    t = turbine_file.load(sw.turbine or turbine_file.DEFAULT)
    h = hashlib.sha256()
    for path in (t.path, t.cp_path):
        data = Path(path).read_bytes()
        h.update(len(data).to_bytes(8, "little") + data)
    return h.hexdigest()[:16]


def schema():
    """The dataset's columns, with units in the field metadata."""
    import pyarrow as pa

    def f(name, typ, unit=None):
        return pa.field(name, typ, metadata={"unit": unit} if unit else None)

    fields = [f("run_id", pa.string()), f("controller", pa.string()),
              f("plant", pa.string()), f("mean_wind_mps", pa.float64(), "m/s"),
              f("turbulence_class", pa.string()), f("wind_kind", pa.string()),
              f("seed", pa.int64()),
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


def read_results(out_dir: Path, option: str = "--out"):
    """Every saved run of a results folder as one pyarrow Table (empty if none). Each
    batch file is read as a regular file under a cap, and must be the one the sweep
    recorded (:mod:`record`): a batch damaged, edited or replaced since is refused in one
    line naming it (remove it, and the sweep runs its batch again)."""
    import pyarrow as pa

    tables = [table for _, _, table in _batches(Path(out_dir), option)]
    # (a column added since a batch was saved: null in its rows)
    return pa.concat_tables(tables, promote_options="default") if tables \
        else schema().empty_table()


def _batches(out_dir: Path, option: str, rec: Record | None = None):
    """(path relative to ``out_dir``, the file's bytes, its Table) of every batch file."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    runs = out_dir / "runs"
    try:
        names = sorted(p.name for p in runs.iterdir()) if not runs.is_symlink() else None
    except FileNotFoundError:
        return
    except OSError as exc:
        raise ConfigError(option, str(runs), f"a folder of batch files ({exc.strerror})") \
            from None
    if names is None:
        raise ConfigError(option, str(runs), "a folder of the results folder (this is a "
                          "symbolic link: wtftc never follows one)")
    if rec is None:
        rec = Record.open(out_dir, option) if (out_dir / RECORD).exists() else None
    for name in names:
        if not PART.fullmatch(name):
            continue
        path, rel = runs / name, f"runs/{name}"
        data = record.read_file(path, option)
        again = (f"remove it, and `wtftc sweep SWEEP.toml --out {out_dir}` runs its batch "
                 "again; nothing was written")
        if rec is not None and rec.exists and not rec.holds(rel, data) and not (
                rec.reload() and rec.holds(rel, data)):  # written since the record was read
            raise ConfigError(option, str(path), "a batch file as the sweep wrote it (this "
                              "one is not: damaged, edited or replaced since; " + again + ")")
        try:
            table = _conform(pq.ParquetFile(pa.BufferReader(data)).read(use_threads=False))
        except (pa.ArrowException, ValueError, KeyError, OSError) as exc:
            why = " ".join(str(exc).split())[:200]
            raise ConfigError(option, str(path), f"a Parquet batch of this sweep (it cannot "
                              f"be read: {why}; " + again + ")") from None
        yield rel, data, table


def _conform(table):
    """``table`` in the sweep's schema: its columns in the schema's order and types, one
    the schema has and the file lacks (a batch of an older wtftc) as nulls, one the schema
    lacks dropped. The file was read on this thread alone (ParquetFile, no thread pool):
    ``pq.read_table`` reads a buffer through Arrow's datasets, whose pool can hold the
    last reference to the Python bytes until interpreter exit, and dropping it then
    aborted the process ("terminate called without an active exception", 1 exit in 40
    on a loaded machine; tests/test_sweep.py's resumable sweeps caught it)."""
    import pyarrow as pa

    cols = []
    for field in schema():
        if field.name in table.column_names:
            cols.append(table.column(field.name).cast(field.type))
        else:
            cols.append(pa.nulls(table.num_rows, field.type))
    return pa.Table.from_arrays(cols, schema=schema())


def count_status(out_dir: Path) -> dict[str, int]:
    """How many saved runs of a results folder have each STATUS (ok, diverged, failed)."""
    counts = dict.fromkeys(STATUS, 0)
    for status in read_results(out_dir).column("status").to_pylist():
        counts[status] = counts.get(status, 0) + 1
    return counts


@dataclass
class Lock:
    """A held results folder: the lock file and its open descriptor (the kernel's lock
    lives as long as the descriptor, and dies with the process)."""
    path: Path
    fd: int
    record: Record | None = None  # the folder's record, for the writes while it is held


def claim(out_dir: Path) -> Lock:
    """Hold ``out_dir`` for this process: an exclusive ``flock`` on its lock file (pid and
    host written in it), or refuse naming the process that holds it. The kernel releases
    the lock when its process ends, however it ends, so a lock is never stale. Two sweeps
    writing one folder would each save the other's runs again. A file at the lock's name
    that is not a lock (a link, a FIFO, a user's text) is refused, untouched."""
    lock = Path(out_dir) / LOCK
    lock.parent.mkdir(parents=True, exist_ok=True)
    for _ in range(5):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_RDWR | os.O_NOFOLLOW | os.O_NONBLOCK
                         | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            raise ConfigError("--out", str(lock), "a sweep's lock file (it cannot be "
                              f"opened: {exc.strerror}; move it away)") from None
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode) or st.st_size > 300 or not _LOCK_TEXT.fullmatch(
                os.pread(fd, 300, 0).decode(errors="replace")):
            os.close(fd)
            raise ConfigError("--out", str(lock), "a sweep's lock file (this one is not: "
                              "wtftc never overwrites it: move it away; nothing was written)")
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


#: what a lock file holds: nothing yet, or "<pid> <host>"
_LOCK_TEXT = re.compile(r"(?:\d+ \S+\s*)?")


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
    dropped to run again (``retry_failed``, :func:`drop_failed`). Everything is checked
    before the lock file is made: a folder refused is left as it was."""
    out_dir = record.check_path(out_dir, "--out")
    files = record.scan(out_dir, "--out") if out_dir.exists() else []
    rec = Record.open(out_dir, "--out", files)
    _check_folder(out_dir, sw, overwrite, rec, files)
    lock = claim(out_dir)
    lock.record = rec
    try:
        done = _open(out_dir, sw, sweep_text, overwrite, rec, files)
        retried = drop_failed(out_dir, rec) if retry_failed else 0
        if retried:
            done = _saved_ids(out_dir, rec)
        return done, lock, retried
    except BaseException:
        release(lock)
        raise


def sweep_contents(out_dir: Path, rec: Record | None = None,
                   option: str = "--out") -> tuple[list[str], list[str]]:
    """(the files the sweep wrote in ``out_dir``, everything else in it), as paths
    relative to it (a folder as "<path>/"). The sweep's are those whose content its
    record lists (a folder without a record: those :func:`record.legacy` recognises), its
    record, its lock and its folders runs/, traces/, figures/; a symbolic link or special
    file anywhere is refused (:func:`record.scan`)."""
    files = record.scan(out_dir, option, folders=True)
    rec = rec if rec is not None else Record.open(
        out_dir, option, [f for f in files if not f.endswith("/")])
    ours, other = [], []
    for rel in files:
        mine = (rel in ("runs/", "traces/", "figures/", CASES + "/")
                or (rel.startswith(CASES + "/") and rel.endswith("/"))  # a case's folders
                or (rel == RECORD and rec.exists) or rel == LOCK or rec.ours(rel))
        (ours if mine else other).append(rel)
    return ours, other


def _open(out_dir: Path, sw: Sweep, sweep_text: str, overwrite: bool, rec: Record,
          files: list[str]) -> set[str]:
    """Begin or reopen the results folder (held): --overwrite deletes what the record
    lists; a resume, the temporaries a killed sweep left in runs/ and traces/ (``files``:
    the folder's files, scanned before it was held; only a sweep, holding it, makes those).
    Returns the run ids saved."""
    meta = out_dir / "sweep.json"
    if overwrite and os.path.lexists(meta):
        # only what the sweep wrote, each file checked against the record as it goes
        # (its lock kept: held); a file added since is left where it is, and its folder
        for rel in record.scan(out_dir, "--out"):
            if rel not in (LOCK, RECORD):
                rec.remove(rel)
        rec.forget()
        cases = [rel for rel in record.scan(out_dir, "--out", folders=True)
                 if rel.startswith(CASES + "/") and rel.endswith("/")]
        for sub in [*sorted(cases, reverse=True), CASES, "runs", "traces", "figures"]:
            with contextlib.suppress(OSError):  # absent, or not empty: kept
                (out_dir / sub).rmdir()
    else:  # what a killed sweep left half-written (its temporaries) goes
        for rel in files:
            if rel.startswith(("runs/.", "traces/.")):
                rec.remove(rel)
    record.real_subfolder(out_dir, "runs", "--out")
    if not os.path.lexists(meta):
        rec.write("sweep.toml", sweep_text.encode())
        rec.write("sweep.json", (json.dumps(
            {"sweep_id": sw.sweep_id, "sweep": json.loads(sw.text), "versions": versions(),
             # the columns' settings, every one written out: the summary reads them
             # without the presets file
             **sw.record(),
             "turbine_sha256": turbine_sha256(sw),
             "created": time.strftime("%Y-%m-%dT%H:%M:%S%z")}, indent=1, sort_keys=True)
            + "\n").encode())
    return _saved_ids(out_dir, rec)


def _saved_ids(out_dir: Path, rec: Record) -> set[str]:
    return {i for _, _, t in _batches(out_dir, "--out", rec)
            for i in t.column("run_id").to_pylist()}


def drop_failed(out_dir: Path, rec: Record | None = None) -> int:
    """Remove the runs saved as failed (status "failed": the run raised, its cause in the
    row) from the results of ``out_dir``, so that the sweep runs them again; returns how
    many. Each batch file holding one is rewritten without it, atomically under its own
    name, or removed if it held only failed runs: killed midway, a failed run is either
    still saved or missing, and a missing run is run again by any resume. A diverged run
    is a result (its time, state and cause), not a failure: it stays. Only a batch file
    as the sweep wrote it is rewritten (:func:`read_results` refuses any other)."""
    import pyarrow.compute as pc

    out_dir = Path(out_dir)
    rec = rec if rec is not None else Record.open(out_dir, "--out")
    n = 0
    for rel, _, table in _batches(out_dir, "--out", rec):  # its names listed first
        failed = pc.fill_null(pc.equal(table.column("status"), "failed"), False)
        k = pc.sum(failed.cast("int64")).as_py() or 0
        if not k:
            continue
        keep = table.filter(pc.invert(failed))
        if keep.num_rows:
            rec.write(rel, _parquet_bytes(keep))
        else:
            rec.remove(rel)
        n += k
    return n


def _parquet_bytes(table) -> bytes:
    import pyarrow as pa
    import pyarrow.parquet as pq

    buf = pa.BufferOutputStream()
    pq.write_table(table, buf)
    return buf.getvalue().to_pybytes()


def _check_folder(out_dir: Path, sw: Sweep, overwrite: bool, rec: Record,
                  files: list[str]) -> None:
    """Refuse a folder that is not this sweep's results folder (unless --overwrite of a
    sweep's results folder); the lock file alone does not make a folder ours. --overwrite
    deletes only what the sweep wrote (:func:`sweep_contents`): a results folder that
    also holds anything else is refused whole, nothing deleted."""
    meta = out_dir / "sweep.json"
    if not os.path.lexists(meta):
        if any(rel not in (LOCK, RECORD) and not rec.ours(rel) for rel in files):
            # never removed, even with --overwrite: it is not ours (a folder holding
            # only what a sweep killed before its sweep.json wrote begins anew)
            raise ConfigError("--out", str(out_dir), "an empty folder or a sweep's results "
                              "folder (this one holds other files; --overwrite removes only "
                              "a sweep's results folder)")
        return
    if overwrite:
        _, other = sweep_contents(out_dir, rec)
        if other:
            names = ", ".join(other[:3])
            raise ConfigError("--out", str(out_dir), "a sweep's results folder holding "
                              "only what a sweep wrote, for --overwrite to replace (this "
                              f"one also holds {len(other)} other: {names}"
                              + (", ..." if len(other) > 3 else "") + "; files not written "
                              "by wtftc, or edited since; nothing was deleted: move them "
                              "away, or --out another folder)")
    try:
        old = json.loads(read_user_text(meta, "--out", MAX_TOML_BYTES))
        if not isinstance(old["versions"], dict) or "sweep_id" not in old:
            raise TypeError("not a sweep's sweep.json")
    except (ConfigError, ValueError, KeyError, TypeError):
        if not overwrite:
            raise ConfigError("--out", str(out_dir), "a sweep's results folder with a "
                              "readable sweep.json (this one is damaged: move it away, or "
                              "--out another folder)") from None
        old = None
    if old is not None:
        _check_same_sweep(out_dir, old, sw.sweep_id, overwrite, sw.engine)
        _check_same_columns(out_dir, old, sw, overwrite)
        _check_same_turbine(out_dir, old, sw, overwrite)


def _check_same_columns(out_dir: Path, old: dict, sw: Sweep, overwrite: bool) -> None:
    """A results folder resumes only with its columns' settings as they were recorded (a
    preset the file names may have changed since; a folder that recorded only their
    names cannot be checked, and is not)."""
    if overwrite or "controllers" not in old:
        return

    def settings(rec: dict) -> list:  # every column's settings (a doc's words aside)
        return [{k: v for k, v in t.items() if k != "doc"} if isinstance(t, dict) else t
                for key in ("controllers", "optional_controllers") for t in rec.get(key, [])]

    now, was = settings(json.loads(json.dumps(sw.record()))), settings(old)
    if was != now:
        changed = [t.get("name") for t in now if t not in was]
        raise ConfigError("--out", str(out_dir), "results of the same controllers' settings: "
                          f"{', '.join(map(str, changed)) or 'a column'} changed since they "
                          "were made (a preset changed); --overwrite or --out a new folder")


def _check_same_turbine(out_dir: Path, old: dict, sw: Sweep, overwrite: bool) -> None:
    """A results folder resumes only on the turbine file and Cp table its runs were made
    with (a folder from before the hash was recorded cannot be checked, and is not)."""
    if overwrite or "turbine_sha256" not in old or old["turbine_sha256"] == turbine_sha256(sw):
        return
    name = sw.turbine or turbine_file.DEFAULT
    raise ConfigError("--out", str(out_dir), f"results of the same turbine: {name}'s turbine "
                      "file or its Cp table changed since they were made (a resumed "
                      "campaign would mix two turbines); --overwrite or --out a new folder")


def _check_same_sweep(out_dir: Path, old: dict, sweep_id: str, overwrite: bool,
                      engine: str = "wtftc") -> None:
    """A results folder resumes only the same sweep file, in the same engine, on the same
    generated code."""
    now = versions()
    was = old.get("sweep", {}).get("engine", "wtftc") if isinstance(old.get("sweep"), dict) \
        else "wtftc"
    if old["sweep_id"] != sweep_id and was != engine and not overwrite:
        raise ConfigError("--out", str(out_dir), f"the results folder of a sweep in {engine}: "
                          f"this one's runs are in {was} (resume it with --engine {was}); "
                          "pass --overwrite to discard those results, or --out a new folder")
    if old["sweep_id"] != sweep_id and not overwrite:
        raise ConfigError("--out", str(out_dir), "the results folder of the same sweep "
                          "file: it holds sweep " + old["sweep_id"] + ", this file is "
                          f"{sweep_id} (changed); pass --overwrite to discard those "
                          "results, or --out a new folder")
    if "generated_code_sha256" not in old["versions"] and not overwrite:
        raise ConfigError("--out", str(out_dir), "results this wtftc can check against its "
                          "code: these were made by an earlier wtftc, which recorded the "
                          "whole manifest's hash (generated_manifest_sha256), so they cannot "
                          "be resumed here; --overwrite or --out a new folder")
    if (old["versions"]["generated_code_sha256"]
            != now["generated_code_sha256"] and not overwrite):
        raise ConfigError("--out", str(out_dir), "results of the same generated code: "
                          "generated/ changed since they were made; --overwrite or "
                          "--out a new folder")
    made = old["versions"].get("run_semantics", 1)
    if made != now["run_semantics"] and not overwrite:
        raise ConfigError("--out", str(out_dir), f"results of this wtftc's runs: these were "
                          f"made under run semantics {made}, this wtftc's are "
                          f"{now['run_semantics']} (what a run computes changed outside the "
                          "generated code: docs/sweep.md); --overwrite or --out a new folder")


def _save_batch(out_dir: Path, done: set[str], results: list,
                rec: Record | None = None) -> list[dict]:
    """Write one finished task's runs: traces first (and a run's OpenFAST case, recorded as
    it is), then the metrics file that lists them, each recorded and written atomically
    (:meth:`Record.write`); runs already saved (a task a dying worker made Dask repeat)
    and runs left :data:`UNFINISHED` are dropped. Returns the rows written."""
    import pyarrow as pa

    out_dir = Path(out_dir)
    rec = rec if rec is not None else Record.open(out_dir, "--out")
    rows = []
    for row, tr in results:
        if row["run_id"] in done or row["status"] == UNFINISHED:
            continue
        if tr is not None:
            rec.write(f"traces/{row['run_id']}.parquet", _parquet_bytes(_trace_table(tr)))
        if (out_dir / CASES / row["run_id"]).is_dir():  # a run in OpenFAST: its case
            rec.adopt(f"{CASES}/{row['run_id']}")
        rows.append(row)
    if rows:
        ids = "".join(sorted(r["run_id"] for r in rows))
        name = f"part-{hashlib.sha256(ids.encode()).hexdigest()[:16]}.parquet"
        rec.write(f"runs/{name}", _parquet_bytes(pa.Table.from_pylist(rows, schema=schema())))
        done.update(r["run_id"] for r in rows)
    return rows


def _trace_table(tr: dict):
    """A run's traces ({name: (values, unit)}) as the Table wtftc.results.io.write_parquet
    makes: units in each field's metadata and in the schema's."""
    import pyarrow as pa

    units = {k: u for k, (_, u) in tr.items()}
    fields = [pa.field(n, pa.float64(), metadata={"unit": units[n]}) for n in tr]
    sch = pa.schema(fields, metadata={"units": json.dumps(units)})
    return pa.table({n: pa.array(v, pa.float64()) for n, (v, _) in tr.items()}, schema=sch)
