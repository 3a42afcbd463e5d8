"""The compile cache verifies what it loads, heals what is damaged, and falls back to
CasADi's virtual machine, with one warning naming CC or WTFTC_CACHE, where compiling or
caching is impossible: never a traceback, never SIGBUS, the same numbers.

A shared object is never loaded in this process before it is damaged: a file truncated
under a live mapping kills the process with SIGBUS, which is what the loader's check
prevents for files damaged before they are loaded.
"""

import json
import os
import shutil
import subprocess
import sys
import time
import warnings
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from wtftc.artefacts import loader
from wtftc.sim import integrate

#: metrics that depend on the wall clock, not on the numbers
TIMING = ("realtime_factor", "wall_s")


def _damage_truncate(so: Path) -> None:
    so.write_bytes(so.read_bytes()[: so.stat().st_size // 2])


def _damage_empty(so: Path) -> None:
    so.write_bytes(b"")


def _damage_garbage(so: Path) -> None:
    so.write_bytes(np.random.default_rng(0).bytes(so.stat().st_size))


def _damage_unrecorded(so: Path) -> None:
    """An object whose name carries no size and sha256 (as a sidecar gone missing)."""
    so.rename(so.with_name(so.name.rsplit("-", 2)[0] + "-unrecorded.so"))


def _plant_values(so: Path) -> np.ndarray:
    f = ca.external("plant_paper", str(so))
    rng = np.random.default_rng(1)
    args = [rng.uniform(0.5, 1.5, f.sparsity_in(i).shape) for i in range(f.n_in())]
    return np.concatenate([np.ravel(np.array(v)) for v in f.call(args)])


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("CC", raising=False)
    return tmp_path / "cache"


@pytest.mark.parametrize("damage", [_damage_truncate, _damage_empty, _damage_garbage,
                                    _damage_unrecorded])
def test_a_damaged_object_is_deleted_and_rebuilt(cache, tmp_path, capsys, damage):
    c_path, cc = loader.verified_path("plant.c"), loader.compiler()
    so = loader.compile_cached(c_path, cc)
    before = tmp_path / "before" / so.name  # a private copy: the cached file is never mapped
    before.parent.mkdir()
    shutil.copy(so, before)
    damage(so)
    assert not loader.is_cached(c_path, cc)
    capsys.readouterr()
    healed = loader.compile_cached(c_path, cc)
    note = capsys.readouterr().err.splitlines()
    assert len(note) == 1 and "WTFTC_CACHE" in note[0] and "is damaged" in note[0]
    assert str(cache) in note[0]
    assert loader.is_cached(c_path, cc) and [p.name for p in cache.iterdir()] == [healed.name]
    assert np.array_equal(_plant_values(healed), _plant_values(before))
    mtime = healed.stat().st_mtime_ns
    assert loader.compile_cached(c_path, cc) == healed and healed.stat().st_mtime_ns == mtime
    assert capsys.readouterr().err == ""  # healed once, then reused quietly


def test_a_damaged_object_that_cannot_be_deleted_says_to_delete_it(cache, capsys,
                                                                   monkeypatch):
    c_path, cc = loader.verified_path("plant.c"), loader.compiler()
    so = loader.compile_cached(c_path, cc)
    _damage_truncate(so)
    monkeypatch.setattr(loader, "_remove_damaged", lambda path: None)  # a read-only cache
    capsys.readouterr()
    assert not loader.is_cached(c_path, cc)
    loader._lookup(loader._cache_prefix(c_path, cc))
    (note,) = capsys.readouterr().err.splitlines()
    assert f"{so} in WTFTC_CACHE is damaged (" in note and "delete it by hand" in note


def test_a_killed_compiles_part_file_is_removed_on_next_use(cache):
    """A compile killed (SIGKILL) leaves its ``.building-*.part``: removed by the next
    compile into the cache once it is older than any live compile; a fresh one is kept."""
    cache.mkdir()
    old, fresh = cache / ".building-old.part", cache / ".building-new.part"
    for p in (old, fresh):
        p.write_bytes(b"half an object")
    then = time.time() - 2 * loader.STALE_UNLOCKED_S
    os.utime(old, (then, then))
    loader.compile_cached(loader.verified_path("plant.c"), loader.compiler())
    assert not old.exists() and fresh.exists()


def test_two_processes_compiling_at_once_both_get_a_verified_object(cache):
    code = ("from wtftc.artefacts import loader as L; "
            "print(L.compile_cached(L.verified_path('plant.c'), L.compiler()))")
    procs = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate() for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    assert all(Path(out.strip()).exists() for out, _ in outs)
    assert loader.is_cached(loader.verified_path("plant.c"), loader.compiler())
    assert not [p for p in cache.iterdir() if not p.name.endswith(".so")]  # no temp files


def test_an_unusable_cache_falls_back_once_and_strict_mode_says_why(cache, monkeypatch):
    cache.write_text("a file, not a folder")
    c_path = loader.verified_path("plant.c")
    with pytest.warns(loader.CompilerWarning) as caught:
        assert loader.compiled_external("plant_paper", c_path) is None
        assert loader.compiled_external("plant_paper", c_path) is None
    assert len(caught) == 1
    assert "WTFTC_CACHE" in str(caught[0].message) and "virtual machine" in str(
        caught[0].message)
    with pytest.raises(loader.CompileError, match="WTFTC_CACHE=.* is not a writable folder"):
        loader.compile_cached(c_path, loader.compiler())
    # the runtime's loops: the uncompiled function itself, the same numbers
    x = ca.SX.sym("x", 2)
    f = ca.Function("cache_probe", [x], [ca.sin(x) * ca.exp(x[0])])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = integrate.compiled(f, "cache_probe", quiet=True)
    assert g is f


# ---- end to end: `wtftc run` in a subprocess (the loaded functions are cached per process)

def _run(out: Path, cache: Path, **env) -> tuple[subprocess.CompletedProcess, dict]:
    environ = {k: v for k, v in os.environ.items() if k != "CC"}
    environ.update(WTFTC_CACHE=str(cache), **env)
    p = subprocess.run([sys.executable, "-m", "wtftc.cli", "run", "--t-final", "1",
                        "--quiet", "--out", str(out)], capture_output=True, text=True,
                       env=environ)
    metrics = json.loads((out / "metrics.json").read_text()) if p.returncode == 0 else {}
    return p, {k: v for k, v in metrics.items() if k not in TIMING}


@pytest.fixture(scope="module")
def compiled_run(tmp_path_factory):
    """A compiled run from an empty cache: the cache it filled and its metrics."""
    root = tmp_path_factory.mktemp("compiled")
    p, metrics = _run(root / "out", root / "cache")
    assert p.returncode == 0, p.stderr
    return root / "cache", metrics


def test_a_truncated_loop_object_is_rebuilt_not_sigbus(compiled_run, tmp_path):
    """Before the check: every later run died with SIGBUS (exit 135), no message."""
    cache = tmp_path / "cache"
    shutil.copytree(compiled_run[0], cache)
    (loop,) = cache.glob("loop_*.so")
    _damage_truncate(loop)
    p, metrics = _run(tmp_path / "out", cache)
    assert p.returncode == 0, p.stderr
    notes = [line for line in p.stderr.splitlines() if "is damaged" in line]
    assert len(notes) == 1 and loop.name in notes[0] and "WTFTC_CACHE" in notes[0]
    assert "Traceback" not in p.stderr
    assert metrics == compiled_run[1]


def _unwritable(tmp_path: Path) -> Path:
    """A cache folder that cannot be written: mode 0o500, or, where that does not stop
    writes (root), a path under a regular file, which fails for root too."""
    folder = tmp_path / "readonly"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        (folder / "probe").write_text("")
    except OSError:
        return folder
    (folder / "probe").unlink()
    folder.chmod(0o700)
    (tmp_path / "a_file").write_text("")
    return tmp_path / "a_file" / "cache"


@pytest.mark.parametrize("case", ["cache_is_a_file", "cache_unwritable", "cc_false",
                                  "cc_writes_nothing", "cc_missing"])
def test_compiling_or_caching_impossible_runs_with_one_warning(compiled_run, tmp_path,
                                                                 case):
    cache, env, names = tmp_path / "cache", {}, "WTFTC_CACHE"
    if case == "cache_is_a_file":
        cache.write_text("")
    elif case == "cache_unwritable":
        cache = _unwritable(tmp_path)
    else:
        cc = {"cc_false": "/bin/false", "cc_writes_nothing": "/bin/true"}.get(case,
                                                                          "/nonexistent/cc")
        env, names = {"CC": cc}, "CC"
        if case == "cc_missing":  # cc is used instead, from the compiled run's cache
            shutil.copytree(compiled_run[0], cache)
    try:
        p, metrics = _run(tmp_path / "out", cache, **env)
    finally:
        if cache.name == "readonly":
            cache.chmod(0o700)
    assert p.returncode == 0, p.stderr
    assert "Traceback" not in p.stderr
    lines = p.stderr.strip().splitlines()
    warned = [line for line in lines if "CompilerWarning" in line]
    assert len(warned) == 1 and f"{names}=" in warned[0], p.stderr
    assert all(line in warned or line.startswith("  compiling") for line in lines), p.stderr
    assert metrics == compiled_run[1]  # the virtual machine: bit-identical here
