"""Load the generated CasADi functions: check, compile, cache, fall back.

* every artefact is checked against ``generated/manifest.json`` before use; a mismatch is
  refused with the file, both hashes and what to run;
* the C source of a group is compiled once with the system compiler into a cache keyed by
  the sha256 of the source, the compiler and the flags (``$WTFTC_CACHE``, default
  ``~/.cache/wtftc``), written atomically, and loaded with ``casadi.external``;
* where no compiler exists (or compiling fails), the serialized function runs on CasADi's
  virtual machine, with a warning: same numbers, slower.

This module never imports SymPy or ``derivation/``.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import tempfile
import warnings
from functools import cache
from pathlib import Path

import casadi as ca

#: compiler flags; part of the cache key
CFLAGS = ("-O2", "-fPIC", "-shared")


class GeneratedArtefactError(RuntimeError):
    """A generated artefact is missing, stale or tampered with."""


def generated_dir() -> Path:
    """Where the artefacts are read from: ``$WTFTC_GENERATED``; else the copy an installed
    package carries (``wtftc/_generated/``, put there by the build from ``generated/``);
    else, in a source checkout, ``generated/`` at the repository root, the one source that
    ``make regenerate`` writes."""
    env = os.environ.get("WTFTC_GENERATED")
    if env:
        return Path(env)
    package = Path(__file__).resolve().parent.parent
    installed = package / "_generated"
    return installed if (installed / "manifest.json").exists() else package.parent / "generated"


def cache_dir() -> Path:
    env = os.environ.get("WTFTC_CACHE")
    return Path(env) if env else Path.home() / ".cache" / "wtftc"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@cache
def manifest(folder: Path | None = None) -> dict:
    folder = folder or generated_dir()
    path = folder / "manifest.json"
    if not path.exists():
        raise GeneratedArtefactError(
            f"{path} is missing: the generated functions have not been built; in a source "
            "checkout run `make regenerate`; an installed wtftc carries them (reinstall it)")
    return json.loads(path.read_text())


def verified_path(filename: str, folder: Path | None = None) -> Path:
    """Path of an artefact whose sha256 matches the manifest; refuse anything else."""
    folder = folder or generated_dir()
    expected = manifest(folder)["artefacts"].get(filename)
    path = folder / filename
    if expected is None:
        raise GeneratedArtefactError(
            f"{filename} is not listed in {folder / 'manifest.json'}; run `make regenerate`")
    if not path.exists():
        raise GeneratedArtefactError(f"{path} is missing; run `make regenerate`")
    actual = _sha256(path)
    if actual != expected:
        raise GeneratedArtefactError(
            f"{path} does not match generated/manifest.json (sha256 {actual[:12]}…, "
            f"manifest says {expected[:12]}…): it was edited or is stale. Generated files "
            "must not be edited by hand; run `make regenerate`")
    return path


@cache
def layout_json(folder: Path | None = None) -> dict:
    return json.loads(verified_path("layout.json", folder).read_text())


def compiler() -> str | None:
    """The C compiler to use: ``$CC``, else cc or gcc on PATH, else None."""
    env = os.environ.get("CC")
    if env and not shutil.which(env):
        warnings.warn(f"$CC={env!r} is not an executable on PATH; trying cc and gcc",
                      RuntimeWarning, stacklevel=2)
    for cand in (env, "cc", "gcc"):
        if cand and shutil.which(cand):
            return shutil.which(cand)
    return None


def is_cached(c_path: Path, cc: str, flags: tuple[str, ...] = CFLAGS) -> bool:
    """Whether the compiled object of c_path is already in the cache."""
    return _cache_path(c_path, cc, flags).exists()


def _cache_path(c_path: Path, cc: str, flags: tuple[str, ...] = CFLAGS) -> Path:
    key = hashlib.sha256()
    key.update(c_path.read_bytes())
    key.update(" ".join((cc, *flags, ca.__version__)).encode())
    return cache_dir() / f"{c_path.stem}-{key.hexdigest()[:20]}.so"


def compile_cached(c_path: Path, cc: str, flags: tuple[str, ...] = CFLAGS) -> Path:
    """Compile c_path into the cache (atomically) unless already there; return the .so."""
    out = _cache_path(c_path, cc, flags)
    if out.exists():
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(suffix=".so", dir=out.parent)
    os.close(fd)
    try:
        proc = subprocess.run([cc, *flags, str(c_path), "-o", tmp, "-lm"],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            raise RuntimeError(f"{cc} failed on {c_path.name}:\n{proc.stderr[-2000:]}")
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return out


def _interpreted(name: str, folder: Path) -> ca.Function:
    text = verified_path(f"{name}.casadi", folder).read_text()
    payload = "".join(line for line in text.splitlines(keepends=True)
                      if not line.startswith("#")).strip()
    return ca.Function.deserialize(payload)


@cache
def load(name: str, mode: str = "auto", folder: Path | None = None) -> ca.Function:
    """The generated function ``name``.

    mode: "compiled" (C, fails if it cannot be built), "interpreted" (CasADi's virtual
    machine) or "auto" (compiled, else interpreted with a warning).
    """
    if mode not in ("auto", "compiled", "interpreted"):
        raise ValueError(f"mode={mode!r}: allowed are 'auto', 'compiled', 'interpreted'")
    folder = folder or generated_dir()
    functions = layout_json(folder)["functions"]
    if name not in functions:
        raise KeyError(f"no generated function {name!r}; available: {', '.join(sorted(functions))}")
    if mode == "interpreted":
        return _interpreted(name, folder)
    c_path = verified_path(functions[name]["c_file"], folder)
    cc = compiler()
    try:
        if cc is None:
            raise RuntimeError("no C compiler found (set $CC, or install gcc)")
        so = compile_cached(c_path, cc)
        return ca.external(name, str(so))
    except RuntimeError as exc:
        if mode == "compiled":
            raise
        warnings.warn(f"{exc}; running {name} on CasADi's virtual machine (same results, "
                      "slower)", RuntimeWarning, stacklevel=2)
        return _interpreted(name, folder)
