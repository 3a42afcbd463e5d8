"""Load the generated CasADi functions: check, compile, cache, fall back.

* every artefact is checked against ``generated/manifest.json`` before use; a mismatch is
  refused with the file, both hashes and what to run;
* the C source of a group is compiled once with the system compiler into a cache keyed by
  the sha256 of the source, the compiler and the flags (``$WTFTC_CACHE``, default
  ``~/.cache/wtftc``): built into a temporary file and renamed into place, its size and
  sha256 recorded in its name; both are checked before ``casadi.external`` loads it (a
  truncated object would kill the process with SIGBUS), and a damaged one is deleted and
  rebuilt, with a note;
* where compiling or caching is impossible (no compiler, ``$CC`` failing, a cache that
  cannot be written), the serialized function runs on CasADi's virtual machine, with one
  warning per process naming ``CC`` or ``WTFTC_CACHE``: the same numbers, slower.

This module never imports SymPy or ``derivation/``.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import warnings
from collections.abc import Callable
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


class CompileError(RuntimeError):
    """Compiling or caching is impossible here; the message names ``CC`` or
    ``WTFTC_CACHE`` and the reason."""

    def __init__(self, reason: str, culprit: str | None = None):
        super().__init__(reason)
        if culprit is not None:  # remembered: this process does not try it again
            _BROKEN[culprit] = reason


class CompilerWarning(RuntimeWarning):
    """Compiled code is not used as asked (the virtual machine instead, or another
    compiler than ``$CC``); given once per process, on one line."""


#: what this process found it cannot use ("CC <path>", "WTFTC_CACHE <folder>") and why
_BROKEN: dict[str, str] = {}
_WARNED: set[str] = set()
_NOTED: set[Path] = set()  # damaged objects already named on stderr
_VM = "; running on CasADi's virtual machine instead (the same numbers, slower)"


def _warn_once(message: str) -> None:
    """A CompilerWarning, once per process and message, on one line (no source line)."""
    if message not in _WARNED:
        _WARNED.add(message)
        warnings.warn_explicit(message, CompilerWarning, "wtftc", 0, module=__name__)


def _find_compiler() -> tuple[str | None, str | None]:
    """(the compiler, what to tell the user): ``$CC``, else cc or gcc on PATH."""
    env = os.environ.get("CC")
    if env and shutil.which(env):
        return shutil.which(env), None
    found = next((shutil.which(c) for c in ("cc", "gcc") if shutil.which(c)), None)
    if env:
        return found, (f"CC={env} is not an executable on PATH; " + (
            f"compiling with {found} instead" if found else "neither are cc and gcc: no C "
            "compiler found"))
    return found, None if found else ("no C compiler found: CC is not set, and neither cc "
                                      "nor gcc is on PATH (set CC, or install gcc)")


def compiler() -> str | None:
    """The C compiler to use: ``$CC``, else cc or gcc on PATH, else None. A ``$CC`` that is
    not an executable is named in a warning (once) when cc or gcc is used instead."""
    cc, problem = _find_compiler()
    if cc and problem:
        _warn_once(problem)
    return cc


def _no_compiler() -> CompileError:
    return CompileError(_find_compiler()[1] or "no C compiler found (set CC, or install gcc)")


def _cache_prefix(c_path: Path, cc: str, flags: tuple[str, ...] = CFLAGS) -> Path:
    """``<cache>/<stem>-<key>``: key, the sha256 of the source, compiler, flags, CasADi."""
    key = hashlib.sha256()
    key.update(c_path.read_bytes())
    key.update(" ".join((cc, *flags, ca.__version__)).encode())
    return cache_dir() / f"{c_path.stem}-{key.hexdigest()[:20]}"


def _damage(path: Path, record: str) -> str | None:
    """What is wrong with the cached object ``path``, whose name ends in the ``record``
    made when it was built (``<size>-<sha256[:16]>``); None if nothing."""
    size, _, digest = record.partition("-")
    if not size.isdigit() or len(digest) != 16:
        return "no size and sha256 recorded in its name"
    try:
        data = path.read_bytes()
    except OSError as exc:
        return f"unreadable: {exc.strerror}"
    if len(data) != int(size):
        return f"{len(data)} bytes, {size} when it was built"
    actual = _digest(data)
    return None if actual == digest else f"sha256 {actual}…, {digest}… when it was built"


def _lookup(prefix: Path, heal: bool = True) -> Path | None:
    """The cached object of ``prefix`` whose size and sha256 match those recorded in its
    name; damaged ones are deleted, with a note on stderr, when ``heal``."""
    try:
        names = sorted(n for n in os.listdir(prefix.parent)
                       if n.startswith(prefix.name + "-") and n.endswith(".so"))
    except OSError:
        return None
    for name in names:
        path = prefix.parent / name
        damage = _damage(path, name[len(prefix.name) + 1:-len(".so")])
        if damage is None:
            return path
        if heal and path not in _NOTED:
            _NOTED.add(path)
            print(f"wtftc: {path} in WTFTC_CACHE is damaged ({damage}); deleting it and "
                  "rebuilding", file=sys.stderr, flush=True)
        if heal:
            _remove_damaged(path)
    return None


def _remove_damaged(path: Path) -> None:
    """Clear a damaged cache entry's name: a file is deleted (wtftc wrote it); a folder
    sitting there is removed when empty, else moved aside whole (``<name>.moved-<n>``), so
    that the name heals and nothing a user may have put inside is deleted."""
    if path.is_dir() and not path.is_symlink():
        try:
            path.rmdir()
        except OSError:
            with contextlib.suppress(OSError):
                aside = Path(tempfile.mkdtemp(prefix=f"{path.name}.moved-", dir=path.parent))
                os.replace(path, aside / path.name)
                print(f"wtftc: moved the folder at {path} aside to {aside}",
                      file=sys.stderr, flush=True)
        return
    with contextlib.suppress(OSError):
        path.unlink()


def _cache_error(folder: Path, exc: OSError) -> CompileError:
    env = os.environ.get("WTFTC_CACHE")
    where = f"WTFTC_CACHE={env}" if env else f"the compile cache {folder} (WTFTC_CACHE unset)"
    why = ("it is a file" if folder.is_file() else
           f"{exc.strerror or exc}: {exc.filename or folder}")
    return CompileError(f"{where} is not a writable folder ({why})", f"WTFTC_CACHE {folder}")


def _cc_error(cc: str, what: str) -> CompileError:
    env = os.environ.get("CC")
    if env and shutil.which(env) == cc:
        return CompileError(f"CC={env} {what}", f"CC {cc}")
    return CompileError(f"the C compiler {cc} {what}; set CC to a working one", f"CC {cc}")


def _run_compiler(cc: str, flags: tuple[str, ...], c_path: Path, out: Path) -> None:
    try:
        proc = subprocess.run([cc, *flags, str(c_path), "-o", str(out), "-lm"],
                              capture_output=True, text=True)
    except OSError as exc:
        raise _cc_error(cc, f"cannot be run ({exc.strerror or exc})") from None
    if proc.returncode != 0:
        lines = [line.strip() for line in proc.stderr.splitlines() if line.strip()]
        detail = next((line for line in lines if "error" in line), lines[-1] if lines else
                      "no output")
        raise _cc_error(cc, f"failed on {c_path.name} (exit status {proc.returncode}: "
                            f"{detail[:200]})")


def _build(c_path: Path, cc: str, flags: tuple[str, ...], announce: str | None) -> Path:
    """The verified object of c_path from the cache, else compiled into a temporary file,
    named by its size and sha256, renamed into place (atomic: a concurrent build of the
    same source renames an object of its own, verified the same way)."""
    prefix = _cache_prefix(c_path, cc, flags)
    found = _lookup(prefix)
    if found is not None:
        return found
    for culprit in (f"CC {cc}", f"WTFTC_CACHE {prefix.parent}"):
        if culprit in _BROKEN:
            raise CompileError(_BROKEN[culprit])
    try:
        prefix.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(prefix=".building-", suffix=".part", dir=prefix.parent)
        os.close(fd)
    except OSError as exc:
        raise _cache_error(prefix.parent, exc) from None
    tmp = Path(name)
    try:
        if announce:
            print(announce, file=sys.stderr, flush=True)
        _run_compiler(cc, flags, c_path, tmp)
        data = tmp.read_bytes()
        if not data:
            raise _cc_error(cc, f"wrote nothing for {c_path.name}")
        out = prefix.parent / f"{prefix.name}-{len(data)}-{_digest(data)}.so"
        try:
            mask = os.umask(0)
            os.umask(mask)
            os.chmod(tmp, 0o777 & ~mask)  # mkstemp's 0600: readable by a shared cache's users
            os.replace(tmp, out)
        except OSError as exc:
            raise _cache_error(prefix.parent, exc) from None
    finally:
        with contextlib.suppress(OSError):
            tmp.unlink()
    return out


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def is_cached(c_path: Path, cc: str, flags: tuple[str, ...] = CFLAGS) -> bool:
    """Whether a verified compiled object of c_path is in the cache."""
    return _lookup(_cache_prefix(c_path, cc, flags), heal=False) is not None


def compile_cached(c_path: Path, cc: str, flags: tuple[str, ...] = CFLAGS) -> Path:
    """The verified .so of c_path: from the cache, rebuilt there if damaged, compiled once
    if missing. Raises CompileError (naming CC or WTFTC_CACHE) where that is impossible."""
    return _build(c_path, cc, flags, None)


def built_once(folder: Path, name: str, make: Callable[[Path], None]) -> Path:
    """``folder/name``, built by ``make(tmp)`` into a fresh hidden folder beside ``folder``
    the first time and renamed into place whole (never half-built; a concurrent builder's
    folder, renamed first, is taken as it is): a library of several sources compiled once
    per key (``folder`` names the key) into wtftc's cache."""
    out = Path(folder) / name
    if out.is_file():
        return out
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}-", dir=folder.parent))
    try:
        make(tmp)
        try:
            tmp.rename(folder)
        except OSError:  # another process built it first
            if not out.is_file():
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out


def compiled_library(c_path: Path, flags: tuple[str, ...] = CFLAGS,
                     announce: str | None = None) -> Path | None:
    """The verified library of c_path, compiled through the cache (``announce`` printed
    before compiling); None where compiling or caching is impossible, with one warning per
    process naming CC or WTFTC_CACHE."""
    try:
        cc = compiler()
        if cc is None:
            raise _no_compiler()
        return _build(c_path, cc, flags, announce)
    except CompileError as exc:
        _warn_once(f"{exc}{_VM}")
        return None


def compiled_external(name: str, c_path: Path, flags: tuple[str, ...] = CFLAGS,
                      announce: str | None = None) -> ca.Function | None:
    """The function ``name`` of c_path, compiled through the cache and loaded with
    ``casadi.external`` (``announce`` printed before compiling); None where compiling or
    caching is impossible, with one warning per process naming CC or WTFTC_CACHE."""
    so = compiled_library(c_path, flags, announce)
    return None if so is None else external_of(name, so)


def external_of(name: str, so: Path) -> ca.Function | None:
    """The function ``name`` of the compiled library ``so`` (``casadi.external``); None
    where it cannot be loaded, with one warning per process."""
    try:
        return ca.external(name, str(so))
    except RuntimeError as exc:
        first = str(exc).strip().splitlines()[0][:200] if str(exc).strip() else "no message"
        _warn_once(f"{so} in WTFTC_CACHE could not be loaded ({first}){_VM}")
        return None


def _interpreted(name: str, folder: Path) -> ca.Function:
    text = verified_path(f"{name}.casadi", folder).read_text()
    payload = "".join(line for line in text.splitlines(keepends=True)
                      if not line.startswith("#")).strip()
    return ca.Function.deserialize(payload)


@cache
def load(name: str, mode: str = "auto", folder: Path | None = None) -> ca.Function:
    """The generated function ``name``.

    mode: "compiled" (C; raises CompileError if it cannot be built), "interpreted"
    (CasADi's virtual machine) or "auto" (compiled, else interpreted with one warning
    per process).
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
    if mode == "compiled":
        cc = compiler()
        if cc is None:
            raise _no_compiler()
        return ca.external(name, str(compile_cached(c_path, cc)))
    f = compiled_external(name, c_path)
    return f if f is not None else _interpreted(name, folder)
