"""`wtftc sweep`: grid and Monte Carlo campaigns on Dask distributed, resumable.

A sweep file (TOML) names its controllers (presets, or tables of their settings: the
columns of `wtftc compare`), the plants, and the
values or ranges of mean wind speed, turbulence class, wind seed, fault type, faulty blade,
magnitude (ρ, stuck angle, hydraulic severity) and onset time; every run's full
configuration follows from it deterministically, with a stable run id (a hash of that
configuration). Runs go to Dask in batches (one task each); every finished batch is
written at once, atomically, as one Parquet file of the results folder's dataset
``runs/``, so that an interrupted sweep loses no finished run and the same command
resumes with what is missing. With ``engine = "openfast"`` every run is a task of its own,
its OpenFAST case kept in the results folder's ``openfast/<run id>/``. docs/sweep.md.

The package, one job a module; this one drives Dask (cluster, progress, interruption):

* ``spec``: the sweep file, its validation, the runs and their batches;
* ``tasks``: one Dask task, runs to rows (what the workers import);
* ``store``: the results folder, its Parquet dataset and resuming;
* ``record``: what the sweep wrote there, so all that it may replace;
* ``summary``: the summary table, figures and a saved run's configuration.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from pathlib import Path

from wtftc import config
from wtftc.campaign import cluster
from wtftc.campaign.sweep import confirm, preflight
from wtftc.campaign.sweep.record import CASES, check_path
from wtftc.campaign.sweep.spec import (
    FAULT_TYPES,
    PLANTS,
    TURBULENCE_CLASSES,
    Axis,
    Sweep,
    batches,
    expand,
    load_sweep,
    parse_sweep,
)
from wtftc.campaign.sweep.store import (
    METRICS,
    STATUS,
    UNFINISHED,
    _prepare,
    _save_batch,
    count_status,
    read_results,
    release,
    schema,
    versions,
)
from wtftc.campaign.sweep.summary import show_run, summarize
from wtftc.campaign.sweep.tasks import run_task
from wtftc.errors import ConfigError
from wtftc.files import MAX_TOML_BYTES, read_user_text
from wtftc.model import turbine_file
from wtftc.openfast.turbsim import ensure_field

__all__ = ["FAULT_TYPES", "METRICS", "PLANTS", "STATUS", "TURBULENCE_CLASSES", "Axis",
           "Incomplete", "Interrupted", "Sweep", "batches", "count_status", "expand", "load_sweep",
           "parse_sweep", "read_results", "run_confirm", "run_sweep", "run_task", "schema",
           "show_run", "summarize", "versions"]


class _Progress:
    def __init__(self, total: int, already: int, quiet: bool):
        self.total, self.already, self.quiet = total, already, quiet
        self.counts = dict.fromkeys((*STATUS, UNFINISHED), 0)
        self.lost = 0
        self.t0 = time.perf_counter()
        self.since = time.time()  # (wall clock: the case folders' logs written since)
        self.tty = sys.stderr.isatty()
        #: the runs in OpenFAST now: (simulated, total) seconds each (cluster.in_flight)
        self.running: list[tuple[float, float]] = []
        self.lock = threading.Lock()  # the watcher's thread prints too

    def update(self, rows: list[dict], lost: int = 0, end: bool = False) -> None:
        with self.lock:
            for r in rows:
                self.counts[r["status"]] += 1
            self.lost = lost
            if not self.quiet:
                self._print(end)

    def show_running(self, running: list[tuple[float, float]]) -> None:
        """The runs in flight, from the watcher's thread: a line now (a terminal's is
        rewritten)."""
        with self.lock:
            self.running = running
            if not self.quiet and (running or self.tty):
                self._print(False)

    def _print(self, end: bool) -> None:
        n = sum(self.counts.values())
        left = self.total - self.already - n - self.lost
        wall = time.perf_counter() - self.t0
        # a run in flight counts by the share it has simulated (OpenFAST's long runs); the
        # watcher's last report may still name a run just saved: none is left in flight
        running = self.running if left > 0 else []
        part = min(sum(t / total for t, total in running), left)
        eta = f"{(left - part) * wall / (n + part):.0f} s" if n + part > 0 else "?"
        line = (f"[sweep] {self.already + n}/{self.total} runs: {self.counts['ok']} ok, "
                f"{self.counts['diverged']} diverged, {self.counts['failed']} failed"
                + (f", {self.counts[UNFINISHED]} unfinished" if self.counts[UNFINISHED]
                   else "")
                + (f", {self.lost} lost" if self.lost else "")
                + f", {left} remaining"
                + (f" ({cluster.describe(running)})" if running else "")
                + f", {n / max(wall, 1e-9):.2f} runs/s, ETA {eta}")
        if self.tty and not end:
            print("\r" + line, end="", file=sys.stderr, flush=True)
        else:
            print(("\r" if self.tty else "") + line, file=sys.stderr, flush=True)


#: how often the runs in flight are looked at [s]: on a terminal, and in a log
WATCH_TTY_S, WATCH_LOG_S = 2.0, 30.0


def _watch(progress: _Progress, case_root: Path, todo: list[dict], done: set[str]):
    """A thread that shows the OpenFAST runs in flight (their case folders' logs) every
    few seconds; it shows nothing where no run keeps a case (the native engine)."""
    ids = [pt["run_id"] for pt in todo]

    def tick():
        if case_root.is_dir():
            present = {p.name for p in case_root.iterdir()}
            progress.show_running(cluster.in_flight(
                [case_root / i for i in ids if i in present and i not in done],
                progress.since))

    return cluster.Watcher(tick, WATCH_TTY_S if progress.tty else WATCH_LOG_S)


class Interrupted(Exception):
    """Ctrl-C or SIGTERM: the sweep stopped; what finished is saved."""


def _make_fields(raws: list[dict], jobs: int, quiet: bool) -> None:
    """Each TurbSim field the runs read, made into the cache before the runs, ``jobs``
    at a time (TurbSim is a program of its own, so threads suffice; a field two runs
    share is made once, under its key's lock: wtftc.openfast.turbsim.generate); its
    progress on stdout. The first failure is raised once the fields under way end."""
    from concurrent.futures import ThreadPoolExecutor

    from wtftc.openfast.turbsim import needs_field

    todo = [raw for raw in raws if needs_field(raw)]
    if not todo:
        return
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max(1, jobs)) as pool:
        for i, _ in enumerate(pool.map(ensure_field, todo), 1):
            if not quiet and (i == len(todo) or i % 10 == 0):
                print(f"TurbSim fields: {i} of {len(todo)} runs' ready "
                      f"({time.perf_counter() - t0:.0f} s)", flush=True)


def _check_runs(sw: Sweep, runs: list[dict], quiet: bool, jobs: int = 1) -> None:
    """Every run's configuration is valid, and ROSCO installed where it runs, before any
    runs; the optional controllers skipped are noted. The TurbSim fields are made
    ``jobs`` at a time (:func:`_make_fields`)."""
    def uses_rosco(pt: dict) -> bool:  # ROSCO, at its deck's tuning or retuned
        return sw.columns[pt["controller"]].design == "rosco"

    # (a [tuning] target is solved where the run runs: one out of reach fails that run,
    # with its cause)
    raws = [(pt, {k: v for k, v in pt["config"].items() if k != "tuning"}) for pt in runs]
    for pt, raw in raws:  # every run checked before a TurbSim field is made
        if not uses_rosco(pt):  # ROSCO's availability is checked below
            config.check_before_field(raw)
    _make_fields([raw for _, raw in raws], jobs, quiet)
    above = None
    for pt, raw in raws:
        if not uses_rosco(pt):
            above = above or config.cut_out_note(config.make_config(raw))
    if above:  # one line for the sweep: the first such run's
        print(f"{above} (and any other run above it)", file=sys.stderr, flush=True)
    if any(uses_rosco(pt) for pt in runs):
        from wtftc.sim import rosco

        reason = rosco.available()
        if reason:
            first = next(pt["controller"] for pt in runs if uses_rosco(pt))
            raise ConfigError("controllers", first, reason)
    if sw.engine == "openfast":  # OpenFAST itself, in one line (exit code 4)
        from wtftc.openfast import install

        install.require()
        first = next((pt for pt in runs if not uses_rosco(pt)), runs[0] if runs else None)
        if first is not None:  # the deck, before any run (preflight.check_deck)
            preflight.check_deck({k: v for k, v in first["config"].items()
                                  if k != "tuning"})
    skipped = [c for c in sw.optional if c not in sw.axis("controllers").values]
    if skipped and not quiet:
        from wtftc.sim import rosco

        print(f"note: optional controllers {', '.join(skipped)} skipped: {rosco.available()}",
              flush=True)


def _collect(futures: list, out_dir: Path, done: set[str], progress: _Progress,
             quiet: bool, rec=None, stopped=lambda: None) -> tuple[int, int]:
    """Save each task's runs as it finishes; returns (runs saved, tasks lost). ``stopped()``:
    the signal that asked the sweep to stop, or None; checked between tasks, since the
    signal handler's exception is lost where it lands in a finalizer (a ParquetWriter's
    __del__ swallowed one, and a SIGTERMed sweep ran to its end)."""
    from dask.distributed import as_completed

    ran = lost = 0
    for fut in as_completed(futures):
        if stopped():
            raise Interrupted(stopped())
        try:
            results = fut.result()
        except Interrupted:  # SIGTERM while waiting: the sweep stops, not this task
            raise
        except Exception as exc:  # noqa: BLE001 - a worker died: the runs stay missing
            lost += 1
            if not quiet:
                print(f"\n[sweep] a task was lost ({type(exc).__name__}: {exc}); its runs "
                      "stay missing: run the same command again to retry them",
                      file=sys.stderr)
            continue
        rows = _save_batch(out_dir, done, results, rec)
        ran += len(rows)
        # a run whose OpenFAST another's signal ended is not saved: a resume runs it
        progress.update(rows + [r for r, _ in results if r["status"] == UNFINISHED], lost)
    if stopped():
        raise Interrupted(stopped())
    if progress.tty:
        progress.update([], lost, end=True)  # end the line the carriage returns rewrote
    return ran, lost


def _check_out_beside_decks(out_dir: Path, runs: list[dict]) -> None:
    """``--out`` outside the deck folder of every turbine the runs use in OpenFAST (each
    run copies its deck's files under ``--out``), before any run."""
    from wtftc.openfast import case as ofcase

    for name in dict.fromkeys(pt["config"].get("turbine", turbine_file.DEFAULT)
                              for pt in runs):
        deck = config.openfast_deck(turbine_file.load(name))
        if deck is not None:
            ofcase.check_out_outside_deck(Path(out_dir), deck)


def run_sweep(sweep_path: Path, out_dir: Path, workers: int = 2, scheduler: str | None = None,
              traces: bool = False, overwrite: bool = False, quiet: bool = False,
              retry_failed: bool = False, engine: str | None = None,
              preset: str | None = None) -> dict:
    """Run (or resume) a sweep into out_dir; returns counts of what this call did.
    ``retry_failed``: the runs saved as failed (they raised) are run again, not kept.
    ``engine`` (``--engine``): every run's engine, where the sweep file names none;
    ``preset`` (``--preset``): that preset in place of the file's controllers."""
    import distributed  # noqa: F401 - Dask is needed: fail before anything is written

    sweep_path = Path(sweep_path)
    check_path(out_dir, "--out")  # a link loop, a dangling link, a file: before any work
    sw = load_sweep(sweep_path, engine, preset)
    runs, dup = expand(sw)
    _check_runs(sw, runs, quiet, workers if scheduler is None else 2)
    if sw.engine == "openfast":
        _check_out_beside_decks(out_dir, runs)
    # a remote scheduler first: one that cannot be reached leaves nothing in out_dir
    client, local = cluster.client(scheduler, workers) if scheduler else (None, None)
    try:
        text = read_user_text(sweep_path, "SWEEP.toml", MAX_TOML_BYTES)
        done, lock, retried = _prepare(out_dir, sw, text, overwrite,
                                       retry_failed)
    except BaseException:
        cluster.close(client, local)
        raise
    if sw.engine == "openfast":
        _check_idle(out_dir, runs, done, client, local, lock)
    try:
        return _run_todo(sw, runs, dup, done, out_dir, client, local,
                         scheduler, workers, traces, quiet, retried, lock.record)
    finally:
        release(lock)


def _check_idle(out_dir: Path, runs: list[dict], done: set[str], client, local, lock) -> None:
    """No run still to do is in an earlier sweep's OpenFAST (preflight.check_idle); else
    the cluster is closed and the folder released before the refusal."""
    try:
        preflight.check_idle(out_dir, Path(out_dir).resolve() / CASES,
                             [pt["run_id"] for pt in runs if pt["run_id"] not in done])
    except BaseException:
        cluster.close(client, local)
        release(lock)
        raise


class Incomplete(Exception):
    """A screen with runs missing (tasks lost): nothing is picked from part of it."""


def run_confirm(sweep_path: Path, out_dir: Path, n: int, confirm_out: Path | None = None,
                workers: int = 2, scheduler: str | None = None, overwrite: bool = False,
                quiet: bool = False, retry_failed: bool = False,
                preset: str | None = None, pick=None) -> dict:
    """``--confirm-openfast N`` (wtftc.campaign.sweep.confirm): the sweep on wtftc's plant
    into ``out_dir``, then its ``n`` scenarios that matter most (``pick(rows, n, trip)``'s,
    default confirm.pick's) in OpenFAST into
    ``confirm_out`` (default: ``<out_dir>_openfast``), then the report, confirm.md there.
    Both folders are checked before anything runs, and resume as a sweep's do. Raises
    Incomplete when the screen has runs missing. Returns both calls' counts, the report,
    where, and whether every confirmation run is saved. ``preset``: as run_sweep's."""
    sweep_path = Path(sweep_path)
    sw = load_sweep(sweep_path, preset=preset)
    confirm.check_screen(sw, n)
    sw_of = confirm.openfast_sweep(sw.raw)
    confirm_out = Path(confirm_out or f"{Path(out_dir)}_openfast")
    if confirm_out.resolve() == Path(out_dir).resolve():
        raise ConfigError("--confirm-out", str(confirm_out), "a folder other than --out")
    text = read_user_text(sweep_path, "SWEEP.toml", MAX_TOML_BYTES)
    _confirm_folder(confirm_out, sw_of, text, overwrite, retry_failed)  # before the screen
    t0 = time.perf_counter()
    screen = run_sweep(sweep_path, out_dir, workers, scheduler, overwrite=overwrite,
                       quiet=quiet, retry_failed=retry_failed, preset=preset)
    walls = {"screen": time.perf_counter() - t0}
    saved = read_results(out_dir).to_pylist()
    if len({r["run_id"] for r in saved}) < screen["runs"]:
        raise Incomplete(f"{len(saved)} of {screen['runs']} screen runs saved in {out_dir}")
    trip = confirm.trip_of(sw)
    chosen = (pick or confirm.pick)(saved, n, trip)
    runs = confirm.confirm_runs(sw_of, chosen)
    if not quiet:
        print(f"confirming {len(chosen)} scenarios in OpenFAST ({len(runs)} runs): "
              + "; ".join(why for _, why in chosen), flush=True)
    _check_runs(sw_of, runs, quiet, workers if scheduler is None else 2)
    from wtftc.openfast import install

    install.require()
    client, local = cluster.client(scheduler, workers) if scheduler else (None, None)
    t0 = time.perf_counter()
    try:
        done, lock, retried = _confirm_folder(confirm_out, sw_of, text, False, retry_failed,
                                              hold=True)
    except BaseException:
        cluster.close(client, local)
        raise
    _check_idle(confirm_out, runs, done, client, local, lock)
    try:
        checked = _run_todo(sw_of, runs, 0, done, confirm_out, client, local, scheduler,
                            workers, False, quiet, retried, lock.record)
        walls["confirm"] = time.perf_counter() - t0
        report = confirm.report(Path(out_dir), confirm_out, chosen, trip, walls)
    finally:
        release(lock)
    have = {r["run_id"] for r in read_results(confirm_out).to_pylist()}
    return {"screen": screen, "confirm": checked, "report": report,
            "confirm_out": confirm_out, "confirm_runs": len(runs),
            "confirmed": sum(pt["run_id"] in have for pt in runs)}


def _confirm_folder(folder: Path, sw_of, text: str, overwrite: bool, retry_failed: bool,
                    hold: bool = False):
    """The confirmation's results folder opened as a sweep's (refusals name --confirm-out),
    and released at once unless ``hold``."""
    try:
        check_path(folder, "--confirm-out")
        done, lock, retried = _prepare(folder, sw_of, text, overwrite, retry_failed)
    except ConfigError as exc:
        if exc.field != "--out":
            raise
        raise ConfigError("--confirm-out", exc.value, exc.allowed, exc.where) from None
    if hold:
        return done, lock, retried
    release(lock)
    return None


def _run_todo(sw, runs, dup, done, out_dir, client, local, scheduler, workers, traces,
              quiet, retried: int = 0, rec=None) -> dict:
    """The runs of ``runs`` not in ``done``, on Dask, saved into ``out_dir`` as they end."""
    todo = [pt for pt in runs if pt["run_id"] not in done]
    if not quiet:
        print(f"sweep {sw.sweep_id} ({sw.mode}): {len(runs)} runs"
              + (f" ({dup} duplicate draws dropped)" if dup else "")
              + (f", {len(runs) - len(todo)} already in {out_dir}" if len(todo) < len(runs)
                 else "") + f", {len(todo)} to run "
              + (f"in batches of {sw.batch_size}" if sw.batch_size > 1 else "one a task")
              + (f" ({retried} that had failed, run again: --retry-failed)" if retried
                 else ""), flush=True)
    summary = {"runs": len(runs), "already": len(runs) - len(todo), "ran": 0, "lost": 0,
               "retried": retried, "unfinished": 0}
    if not todo:
        cluster.close(client, local)
        return summary
    progress = _Progress(len(runs), len(runs) - len(todo), quiet)

    asked: list[str] = []  # the signal that asked the sweep to stop, kept for _collect

    def _stop(signum, frame):
        asked.append(signal.Signals(signum).name)
        raise Interrupted(asked[-1])

    old = signal.signal(signal.SIGTERM, _stop)
    # where a run in OpenFAST keeps its case, absolute: the workers run elsewhere
    case_root = Path(out_dir).resolve() / CASES
    watcher = _watch(progress, case_root, todo, done)
    try:
        if client is None:
            client, local = cluster.client(None, workers)
        if not quiet:
            n_workers = len(client.scheduler_info()["workers"])
            print(f"Dask: {scheduler or 'local cluster'}, {n_workers} worker"
                  f"{'' if n_workers == 1 else 's'}", flush=True)
        futures = [client.submit(run_task, b, traces, str(case_root), pure=False)
                   for b in batches(todo, sw.batch_size)]
        if not quiet:
            watcher.start()
        summary["ran"], summary["lost"] = _collect(futures, out_dir, done, progress, quiet,
                                                   rec, lambda: asked[0] if asked else None)
        summary["unfinished"] = progress.counts[UNFINISHED]
    except KeyboardInterrupt:
        raise Interrupted("SIGINT") from None
    finally:
        watcher.stop()
        signal.signal(signal.SIGTERM, old)
        cluster.close(client, local)
    return summary
