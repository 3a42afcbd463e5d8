"""Atomic output: a file is either absent or complete, never half-written."""

from __future__ import annotations

import io
import json
import math
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from wtftc.errors import ConfigError
from wtftc.files import check_out_folder, check_writable_ancestor, owned_folder

#: what makes a folder a wtftc run folder, which a new run may replace as a whole
RUN_MARKERS = ("config.toml", "metrics.json")
#: everything a run folder may hold: a folder with anything else is not replaced
RUN_FILES = {*RUN_MARKERS, "traces.csv", "traces.parquet", "metrics.md", "metrics.csv",
             "figures"}


def _umask_mode() -> int:
    """0666 minus the process umask: what open() would have given the file."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def atomic_write_bytes(path: Path, data: bytes) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, _umask_mode())  # mkstemp creates 0600
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode())


def atomic_savez(path: Path, **arrays) -> None:
    """NumPy arrays as one .npz file (numpy.load reads it; MATLAB and others through
    their npz readers), written whole."""
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def atomic_write_json(path: Path, obj) -> None:
    atomic_write_text(path, json.dumps(_finite_or_null(obj), indent=1, sort_keys=True,
                                       allow_nan=False) + "\n")


def _finite_or_null(obj):
    """``obj`` with every NaN or infinite float as None: standard JSON (null), which every
    reader takes (a bare NaN is Python's extension; JavaScript's JSON.parse refuses it)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite_or_null(v) for v in obj]
    return obj


def atomic_savefig(fig, path: Path, **kwargs) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        fig.savefig(tmp, **kwargs)
        os.chmod(tmp, _umask_mode())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def ensure_writable_dir(path: Path, option: str = "--out", create: bool = True) -> Path:
    """Prove that path is (or can become) a writable folder; a clear error naming the option.

    With create=False nothing is created: the nearest existing ancestor must be a writable
    folder, so that a run can be refused before any output exists.
    """
    path = Path(path)
    if not str(path):
        raise ConfigError(option, "", "a folder name")
    if path.exists() and not path.is_dir():
        raise ConfigError(option, str(path), "a folder (this is a file)")
    if not create:
        check_writable_ancestor(path, option, str(path))
        return path
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-test.", dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ConfigError(option, str(path),
                          f"a folder that can be written ({exc.strerror})") from None
    return path


@contextmanager
def run_folder(out: Path, option: str = "--out") -> Iterator[Path]:
    """Write a run's files into a hidden temporary sibling of ``out`` and put it in place as
    a whole (wtftc.files.owned_folder): a run folder is never mixed from two runs nor left
    half-written, and an earlier run in ``out`` is replaced, stale files included. A folder
    holding anything wtftc did not write is refused, as is the current folder or one of its
    ancestors; run folders written before the marker existed are recognised by their files
    (:func:`is_legacy_run_folder`). Concurrent runs into one ``out`` swap in turn."""
    with owned_folder(out, option, command="run", legacy=is_legacy_run_folder) as tmp:
        yield tmp


def check_run_folder(out: Path, option: str = "--out") -> Path:
    """Refuse, before any work, an ``out`` that a run may not replace."""
    return check_out_folder(out, option, legacy=is_legacy_run_folder)


def is_legacy_run_folder(out: Path) -> bool:
    """A run folder of a wtftc from before the marker: exactly a run's files, each a regular
    file by its own name, its figures/ holding only a run's figures, and its metrics.json a
    run's (checked before the run and again under the lock, just before the swap). Anything
    else in it (a user's file, folder or link, at any depth) makes it the user's."""
    top = {p.name: p for p in out.iterdir()}
    if not set(top) <= RUN_FILES or not all(m in top for m in RUN_MARKERS):
        return False
    for name, p in top.items():
        if p.is_symlink() or not (p.is_dir() if name == "figures" else p.is_file()):
            return False
    if "figures" in top:
        for q in top["figures"].iterdir():
            if q.is_symlink() or not q.is_file() or q.name not in RUN_FIGURES:
                return False
    try:
        m = json.loads((out / "metrics.json").read_text())
    except (OSError, ValueError):
        return False
    return isinstance(m, dict) and {"label", "config", "case"} <= set(m)


#: the figures `wtftc run` writes (wtftc.campaign.cases.write_run_figures)
RUN_FIGURES = {f"{n}.{e}" for n in ("rotor_speed", "control", "fault", "fdi")
               for e in ("png", "pdf")}


def is_legacy_tree(out: Path, names: tuple[str, ...]) -> bool:
    """A folder of an older wtftc command that writes only the files ``names`` (regular
    expressions of whole names) at its top: exactly such regular files, nothing else."""
    import re

    for p in out.iterdir():
        if p.is_symlink() or not p.is_file() \
                or not any(re.fullmatch(n, p.name) for n in names):
            return False
    return True


def write_parquet(path: Path, columns: dict, units: dict) -> None:
    """A Parquet table (pyarrow), units in each field's metadata and in the schema's."""
    import pyarrow as pa

    fields = [pa.field(n, pa.float64(), metadata={"unit": units[n]}) for n in columns]
    schema = pa.schema(fields, metadata={"units": json.dumps(units)})
    table = pa.table({n: pa.array(v, pa.float64()) for n, v in columns.items()}, schema=schema)
    atomic_write_table(path, table)


def atomic_write_table(path: Path, table) -> None:
    """A pyarrow Table as one Parquet file, atomically (the name appears only when the file
    is complete; readers of a Parquet dataset skip the hidden temporary)."""
    import pyarrow.parquet as pq

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    os.close(fd)
    try:
        pq.write_table(table, tmp)
        os.chmod(tmp, _umask_mode())
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
