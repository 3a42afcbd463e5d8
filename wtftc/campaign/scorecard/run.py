"""`wtftc scorecard`: a controller against its baseline over the case matrix
(:mod:`wtftc.campaign.scorecard.matrix`), each group of cases a sweep of its own in the
scorecard's folder, run on Dask and resumed as a sweep is.

The folder::

    <out>/.wtftc-scorecard         the folder's marker (a folder without it, not empty,
                                   is refused)
    <out>/sweeps/<group>.toml      each group's sweep file, as run
    <out>/<group>/                 each group's results (a sweep's results folder)

Run again with the same arguments, a scorecard resumes where it stopped; with other
arguments, each group's sweep refuses the folder it would change (docs/sweep.md).
"""

from __future__ import annotations

import time
from pathlib import Path

from wtftc.errors import ConfigError

#: the marker of a scorecard's folder
MARKER = ".wtftc-scorecard"


def column(entry, field: str) -> dict:
    """A column of the scorecard as a sweep's controller table: a preset's name, or a
    [controller] table with its ``name`` (default ``field`` without its dashes); one
    column, so no setting given as a list."""
    from wtftc import controller

    if isinstance(entry, str):
        controller.preset(entry, field)
        return {"name": entry, "preset": entry}
    if not isinstance(entry, dict):
        raise ConfigError(field, entry, "a preset's name or a [controller] table")
    listed = sorted(k for k, v in entry.items() if isinstance(v, list))
    if listed:
        raise ConfigError(f"{field}.{listed[0]}", entry[listed[0]], "one value: a "
                          "scorecard scores one controller (compare or sweep take lists)")
    name = entry.get("name", field.lstrip("-"))
    # every setting written out (a library's absolute paths and hashes too), so that each
    # resume runs what the first call ran
    return {"name": name, **controller.parse({k: v for k, v in entry.items()
                                              if k != "name"}, field).table()}


def prepare(out: Path) -> Path:
    """``out`` made, or an earlier scorecard's (its marker), or new; any other folder
    that holds anything is refused, naming --out."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError("--out", str(out), "a folder (this is a file)")
    if out.is_dir() and any(out.iterdir()) and not (out / MARKER).is_file():
        raise ConfigError("--out", str(out), "a new or empty folder, or an earlier "
                          "scorecard's (it has no .wtftc-scorecard marker: not one)")
    (out / "sweeps").mkdir(parents=True, exist_ok=True)
    (out / MARKER).touch()
    return out


def write_sweep(out: Path, group: str, raw: dict) -> Path:
    """The group's sweep file, written whole (wtftc.results.io.atomic_write_text)."""
    from wtftc.config import to_toml
    from wtftc.results.io import atomic_write_text

    path = out / "sweeps" / f"{group}.toml"
    atomic_write_text(path, f"# wtftc scorecard: the {group} group's sweep\n" + to_toml(raw))
    return path


#: where a screened group's OpenFAST confirmation goes, beside its screen
CONFIRMED = "{group}_openfast"


def _sweeps(m: dict, columns: list, turbine: str | None, engine: str, seeds: int | None,
            screen: int | None) -> dict[str, dict]:
    """Each group's sweep; screened, on wtftc's plant and TurbSim's fields (those its
    OpenFAST confirmation runs on)."""
    from wtftc.campaign.scorecard import matrix

    if screen is not None and engine != "openfast":
        raise ConfigError("--screen", screen, "with --engine openfast: the screen runs on "
                          "wtftc's plant, then OpenFAST confirms the scenarios that decide")
    raws = matrix.sweeps(m, columns, turbine, "wtftc" if screen else engine, seeds)
    if screen is not None:
        for raw in raws.values():
            raw["wind"]["field"] = "turbsim"
    return raws


#: each call's wall time per group, kept across resumed calls
WALLS = "walls.json"


def log_wall(out: Path, group: str, wall_s: float, workers: int,
             screen: int | None) -> list[dict]:
    """Every call's wall time on ``group`` so far, this one's appended and the file
    written whole: a scorecard run over several calls (resumed) reports them all."""
    import json

    from wtftc.results.io import atomic_write_text

    path = Path(out) / WALLS
    calls = json.loads(path.read_text("utf-8")) if path.is_file() else {}
    calls.setdefault(group, []).append({"wall_s": wall_s, "workers": workers,
                                        "screen": screen, "at": time.strftime(
                                            "%Y-%m-%dT%H:%M:%SZ", time.gmtime())})
    atomic_write_text(path, json.dumps(calls, indent=1))
    return calls[group]


def deciding(group: str, cand: str, base: str):
    """The screen's choice of what OpenFAST confirms in ``group``: the scenarios that
    decide its verdicts (wtftc.campaign.scorecard.screen.decisive)."""
    from wtftc.campaign.scorecard import screen

    return lambda rows, n, trip: screen.decisive(rows, n, trip, group, cand, base)


def run_scorecard(candidate, out: Path, turbine: str | None = None, against="rosco",
                  engine: str = "openfast", seeds: int | None = None, workers: int = 2,
                  scheduler: str | None = None, matrix_path: Path | None = None,
                  quiet: bool = False, screen: int | None = None) -> dict:
    """Every group of the matrix for ``candidate`` and ``against`` (each a preset's name
    or a [controller] table) on ``turbine`` in ``engine``; each group's counts and wall
    time. ``screen`` N: each group on wtftc's tower_edge plant, then the scenarios that
    decide its verdicts, at least N, in OpenFAST (:func:`deciding`) into
    ``<group>_openfast``.
    Everything is checked before the first run: the columns, the matrix, every group's
    sweep (its runs too)."""
    from wtftc.campaign import sweep
    from wtftc.campaign.scorecard import matrix
    from wtftc.campaign.sweep import confirm, spec

    cand, base = column(candidate, "controller"), column(against, "--against")
    for tab, field in ((cand, "controller"), (base, "--against")):
        if tab.get("design") == "discon" and (engine != "openfast" or screen is not None):
            raise ConfigError(f"{field}.design", "discon", "a DISCON library runs in "
                              "OpenFAST only: --engine openfast, without --screen")
    if cand["name"] == base["name"]:
        base = {**base, "name": f"{base['name']} (baseline)"}
    m = matrix.load(matrix_path)
    raws = _sweeps(m, [cand, base], turbine, engine, seeds, screen)
    for raw in raws.values():
        sw = spec.parse_sweep(raw)
        spec.expand(sw)  # every run checked before any
        if screen is not None:
            confirm.check_screen(sw, screen)
    out = prepare(out)
    done = {}
    for group, raw in raws.items():
        if not quiet:
            print(f"[scorecard] {group} (DLC {m['groups'][group]['iec']})", flush=True)
        t0, path = time.perf_counter(), write_sweep(out, group, raw)
        # (a group of one column, the baseline as shipped, has no verdict to confirm:
        # screened, it runs on the screen alone)
        counts = sweep.run_sweep(path, out / group, workers, scheduler, quiet=quiet) \
            if screen is None or len(raw["controllers"]) < 2 else sweep.run_confirm(
                path, out / group, screen, out / CONFIRMED.format(group=group), workers,
                scheduler, quiet=quiet, pick=deciding(group, cand["name"], base["name"]))
        done[group] = {**counts, "wall_s": time.perf_counter() - t0}
        done[group]["calls_wall_s"] = log_wall(out, group, done[group]["wall_s"], workers,
                                               screen)
    return {"matrix": m, "matrix_hash": matrix.matrix_hash(m), "columns": [cand, base],
            "groups": done, "screen": screen, "engine": engine, "seeds": seeds}
