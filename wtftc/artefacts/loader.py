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
  warning per process naming ``CC`` or ``WTFTC_CACHE``: the same numbers, slower;
* a folder of several files built once for the OpenFAST engine (:func:`built_once`: its
  controller and plant libraries) is sealed with the size and sha256 of every file
  (:func:`wtftc.files.seal`), checked each time it is taken, and rebuilt with a note when
  damaged; the cache holding it is checked for what OpenFAST can read
  (:func:`openfast_cache_dir`).

This module never imports SymPy or ``derivation/``.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from functools import cache
from pathlib import Path

import casadi as ca

from wtftc import files
from wtftc.errors import ConfigError, EngineError

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


#: the longest path OpenFAST 5.0.0 reads from a line of an input file: ParseChVar
#: (modules/nwtc-library/src/NWTC_IO.f90) splits the line into words of
#: NWTC_SizeOfNumWord = 256 characters and cuts a longer one ("Value may be truncated"), so
#: that ServoDyn's DLL_FileName, the plant library in the cache, names no file
OPENFAST_PATH_CHARS = 256
#: room kept for the longest name wtftc puts under the cache that a deck line names:
#: "/plant_library-<20 hex digits>/libwtftc_plant.so" is 53 characters
CACHE_NAME_CHARS = 64
#: the longest cache folder the OpenFAST engine can use [bytes of its absolute path]
MAX_CACHE_CHARS = OPENFAST_PATH_CHARS - CACHE_NAME_CHARS
#: characters OpenFAST cannot read in a quoted path: its comment marks ('!', '#', '%' end a
#: line's input even inside quotes: CommChars, NWTC_IO.f90), the quotes, line breaks
OPENFAST_PATH_BAD = "!#%\"'\n\r"
#: where the cache is when WTFTC_CACHE is unset
DEFAULT_CACHE = "~/.cache/wtftc"


def cache_dir() -> Path:
    """wtftc's cache folder, absolute: ``$WTFTC_CACHE`` (``~`` expanded, a relative path
    taken from the current folder: OpenFAST runs in its case folder and must find the
    libraries by their absolute paths), else ``~/.cache/wtftc``. A WTFTC_CACHE that is
    empty or cannot be made absolute is a ConfigError naming it."""
    env = os.environ.get("WTFTC_CACHE")
    if env is None:  # (no HOME and no passwd entry leave "~": made absolute all the same)
        return Path(os.path.abspath(os.path.expanduser(DEFAULT_CACHE)))
    if not env.strip():
        raise ConfigError("WTFTC_CACHE", env, "a folder path (unset WTFTC_CACHE for the "
                          f"default, {DEFAULT_CACHE})")
    try:
        return Path(os.path.abspath(os.path.expanduser(env)))
    except OSError as exc:  # a relative path, and the current folder is gone
        raise ConfigError("WTFTC_CACHE", env, "a path that can be made absolute (the "
                          f"current folder cannot be found: {exc.strerror})") from None


def _cache_refusal(folder: Path, allowed: str) -> ConfigError:
    """A ConfigError naming WTFTC_CACHE as the user set it (or its default)."""
    env = os.environ.get("WTFTC_CACHE")
    if env is None:
        return ConfigError("WTFTC_CACHE", str(folder), f"{allowed}; WTFTC_CACHE is unset "
                           "and this is its default: set it to another folder")
    given = env if Path(env) == folder else f"{env} ({folder})"
    return ConfigError("WTFTC_CACHE", given, allowed)


def openfast_cache_dir() -> Path:
    """:func:`cache_dir`, checked for the OpenFAST engine, which reads libraries in it by
    their absolute paths from its decks: at most :data:`MAX_CACHE_CHARS` bytes, none of
    :data:`OPENFAST_PATH_BAD`, a folder that can be written (made if missing). A
    ConfigError naming WTFTC_CACHE otherwise, never a path cut short by OpenFAST."""
    folder = cache_dir()
    size = len(os.fsencode(folder))
    if size > MAX_CACHE_CHARS:
        raise _cache_refusal(folder, f"a folder path of at most {MAX_CACHE_CHARS} bytes "
                             f"(this one has {size}): OpenFAST cuts a path in its input "
                             f"files at {OPENFAST_PATH_CHARS} characters, and the plant "
                             "library's path lies inside it")
    bad = sorted({c for c in str(folder) if c in OPENFAST_PATH_BAD})
    if bad:
        raise _cache_refusal(folder, "a folder path without " + " ".join(map(repr, bad))
                             + " (OpenFAST cannot read them in a path of its input files)")
    writable_cache(folder)
    return folder


def writable_cache(folder: Path, make: bool = True) -> Path:
    """``folder`` (the cache or a folder inside it), made if missing (with ``make``; else
    only its nearest existing ancestor is checked, and nothing is made); a ConfigError
    naming WTFTC_CACHE, with what is wrong in words, where it is not a folder that can be
    written."""
    try:
        if make:
            folder.mkdir(parents=True, exist_ok=True)
        probe = folder
        while not make and not os.path.lexists(probe) and probe != probe.parent:
            probe = probe.parent
        if not probe.is_dir():
            raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR))
        if not os.access(probe, os.W_OK | os.X_OK):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))
    except OSError as exc:
        raise _cache_refusal(cache_dir(), "a folder that can be written "
                             f"({_why_not(folder, exc)})") from None
    return folder


def _why_not(folder: Path, exc: OSError) -> str:
    """Why ``folder`` cannot be written, in words naming the path at fault (never a
    temporary name: the first ancestor that exists)."""
    probe = folder
    while not probe.exists() and probe != probe.parent:
        if probe.is_symlink():
            return f"{probe} is a symbolic link that leads nowhere (dangling, or a loop)"
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        return f"{probe} is a file" if probe.is_file() else f"{probe} is not a folder"
    if exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return f"{probe} is not writable" + (" (a read-only file system)"
                                             if exc.errno == errno.EROFS else "")
    return f"{probe}: {exc.strerror or type(exc).__name__}"


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def generated_code_sha256() -> str:
    """The generated code's identity: 16 hex digits of the sha256 of the manifest's
    artefacts (what a campaign records in its sweep.json and an export in its header)."""
    code = manifest()["artefacts"]
    return hashlib.sha256(json.dumps(code, sort_keys=True).encode()).hexdigest()[:16]


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
_NOTED: set[tuple[Path, str]] = set()  # damaged entries already named on stderr, and how
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
        if heal:
            _remove_damaged(path)
            _note_damaged(path, damage, "deleting it and rebuilding" if not
                          os.path.lexists(path) else "it cannot be deleted here: delete "
                          "it by hand, or set WTFTC_CACHE to a folder that can be written")
    return None


def _note_damaged(path: Path, damage: str, what: str) -> None:
    """One line on stderr, once per process and entry: a damaged cache entry, and what is
    done or to do about it."""
    if (path, damage) not in _NOTED:
        _NOTED.add((path, damage))
        print(f"wtftc: {path} in WTFTC_CACHE is damaged ({damage}); {what}",
              file=sys.stderr, flush=True)


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
    """The cache cannot take a compiled object: named as the user set it, with the path at
    fault (never the temporary file that could not be made)."""
    env = os.environ.get("WTFTC_CACHE")
    where = (f"WTFTC_CACHE={env}" if env is not None else
             f"the compile cache {folder} (WTFTC_CACHE unset)")
    why = "it is a file" if folder.is_file() else _why_not(folder, exc)
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
        _clean_stale_objects(prefix.parent)
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


def _clean_stale_objects(folder: Path) -> None:
    """Remove the ``.building-*.part`` files of compiles that were killed: those unchanged
    for :data:`STALE_UNLOCKED_S` (a live compile writes its file within minutes; the
    compiler replaces the file, so a lock on it would not hold)."""
    with contextlib.suppress(OSError):
        for entry in os.scandir(folder):
            if entry.name.startswith(".building-") and entry.name.endswith(".part") and \
                    entry.is_file(follow_symlinks=False) and \
                    time.time() - entry.stat(follow_symlinks=False).st_mtime > STALE_UNLOCKED_S:
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)


def _digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()[:16]


def is_cached(c_path: Path, cc: str, flags: tuple[str, ...] = CFLAGS) -> bool:
    """Whether a verified compiled object of c_path is in the cache."""
    return _lookup(_cache_prefix(c_path, cc, flags), heal=False) is not None


def compile_cached(c_path: Path, cc: str, flags: tuple[str, ...] = CFLAGS) -> Path:
    """The verified .so of c_path: from the cache, rebuilt there if damaged, compiled once
    if missing. Raises CompileError (naming CC or WTFTC_CACHE) where that is impossible."""
    return _build(c_path, cc, flags, None)


#: the lock a build of :func:`built_once` holds in its temporary folder while it runs: a
#: temporary folder whose lock no process holds was left by a build that was killed
BUILD_LOCK = files.PARTIAL_LOCK
#: a temporary build folder without a lock file (made by an earlier wtftc) is taken as
#: left by a killed build once it has not changed for this long [s]
STALE_UNLOCKED_S = 3600.0


def built_once(folder: Path, name: str, make: Callable[[Path], None]) -> Path:
    """``folder/name``, built by ``make(tmp)`` into a fresh hidden folder beside ``folder``
    the first time, renamed into place whole and sealed (:func:`wtftc.files.seal`): a
    library of several sources compiled once per key (``folder`` names the key) into
    wtftc's cache, for the OpenFAST engine (the cache checked by
    :func:`openfast_cache_dir`).

    The entry is taken only while its seal holds; a damaged one (a file changed, removed
    or added, no seal) is rebuilt, with one line on stderr naming it. The hidden
    ``.<folder>-*`` folders that killed builds left are removed first, once no process
    holds their lock. Checks, removals and renames happen under a lock on the parent
    folder; the builds run outside it, and of concurrent builders the first to finish
    wins (the others' folders are discarded)."""
    folder = Path(folder)
    openfast_cache_dir()
    root = writable_cache(folder.parent)
    try:
        with _folder_locked(root):
            clean_stale_builds(root, folder.name)
            if _take(folder, name):
                return folder / name
            tmp, lock_fd = new_build_folder(root, folder.name)
    except OSError as exc:
        raise _cache_refusal(cache_dir(), f"a folder that can be written "
                             f"({_why_not(root, exc)})") from None
    try:
        _make_in(make, tmp, folder, name)
        with _folder_locked(root):
            os.unlink(tmp / BUILD_LOCK)
            if not _take(folder, name, quiet=True):
                os.chmod(tmp, 0o777 & ~files._umask())  # mkdtemp's 0700: a shared cache
                os.rename(tmp, folder)
                files.seal(folder)
    except OSError as exc:
        raise _cache_refusal(cache_dir(), f"a folder that can be written ({folder}: "
                             f"{exc.strerror or exc})") from None
    finally:
        os.close(lock_fd)
        shutil.rmtree(tmp, ignore_errors=True)
    return folder / name


@contextlib.contextmanager
def _folder_locked(root: Path):
    """An exclusive ``flock`` on the folder ``root`` while the block runs."""
    fd = os.open(root, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def new_build_folder(root: Path, stem: str) -> tuple[Path, int]:
    """A fresh hidden folder ``.<stem>-*`` in ``root`` and the descriptor of the lock
    held in it (not inherited by the programs the build runs)."""
    tmp = Path(tempfile.mkdtemp(prefix=f".{stem}-", dir=root))
    try:  # the lock is taken under another name, then renamed: a cleaner never finds it
        fd = os.open(tmp / f"{BUILD_LOCK}.new", os.O_CREAT | os.O_RDWR | os.O_CLOEXEC,
                     0o600)  # (clean_stale_builds) made but not yet held
        fcntl.flock(fd, fcntl.LOCK_EX)
        os.replace(tmp / f"{BUILD_LOCK}.new", tmp / BUILD_LOCK)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return tmp, fd


def clean_stale_builds(root: Path, stem: str, grace_s: float = STALE_UNLOCKED_S) -> None:
    """Remove the ``.<stem>-*`` folders in ``root`` whose lock no process holds (a build
    killed, even by SIGKILL: the kernel releases its lock), and those without a lock that
    have not changed for ``grace_s`` [s]."""
    for entry in os.scandir(root):
        if not entry.name.startswith(f".{stem}-") or not entry.is_dir(follow_symlinks=False):
            continue
        try:
            fd = os.open(Path(entry.path) / BUILD_LOCK,
                         os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
        except FileNotFoundError:
            if time.time() - entry.stat(follow_symlinks=False).st_mtime > grace_s:
                shutil.rmtree(entry.path, ignore_errors=True)
            continue
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            continue  # a live build
        else:
            shutil.rmtree(entry.path, ignore_errors=True)
        finally:
            os.close(fd)


def _entry_damage(folder: Path, name: str) -> str | None:
    """What is wrong with the built entry ``folder`` against its seal; None if whole."""
    if folder.is_symlink():
        return "a symbolic link, not the folder wtftc built"
    if not folder.is_dir():
        return "not a folder"
    damage = files.seal_damage(folder)
    if damage is None and not (folder / name).is_file():
        return f"{name} is missing"
    return damage


def _take(folder: Path, name: str, quiet: bool = False) -> bool:
    """Whether ``folder`` holds a whole entry; a damaged one is cleared away (named on
    stderr unless ``quiet``), so that it is built again."""
    if not os.path.lexists(folder):
        return False
    damage = _entry_damage(folder, name)
    if damage is None:
        return True
    done = _clear(folder)
    if done is None:
        raise _cache_refusal(cache_dir(), f"a folder that can be written ({folder} is "
                             f"damaged ({damage}) and cannot be deleted here: delete it)")
    if not quiet:
        _note_damaged(folder, damage, done)
    return False


def _clear(folder: Path) -> str | None:
    """Clear a damaged entry's name and say how; None where it cannot be. An entry that
    holds only what wtftc wrote (or an unsealed one, built by an earlier wtftc) is
    deleted; anything else there (a file, a link, files wtftc did not write) is moved
    aside whole to ``<name>.moved-*``, never deleted."""
    root = folder.parent
    try:
        if folder.is_dir() and not folder.is_symlink() and not _foreign(folder):
            trash = Path(tempfile.mkdtemp(prefix=f".{folder.name}-", dir=root))
            os.rename(folder, trash / folder.name)  # the name is free at once
            shutil.rmtree(trash, ignore_errors=True)
            done = "deleting it and rebuilding"
        else:
            aside = Path(tempfile.mkdtemp(prefix=f"{folder.name}.moved-", dir=root))
            os.rename(folder, aside / folder.name)
            done = f"moved it aside to {aside} (it holds what wtftc did not write); rebuilding"
        _clear_seal(folder)
    except OSError:
        return None
    return done


def _clear_seal(folder: Path) -> None:
    """Remove the seal beside ``folder``; anything else at its name (a folder) is moved
    aside whole."""
    seal = files.seal_path(folder)
    if seal.is_dir() and not seal.is_symlink():
        aside = Path(tempfile.mkdtemp(prefix=f"{seal.name}.moved-", dir=seal.parent))
        os.rename(seal, aside / seal.name)
    elif os.path.lexists(seal):
        seal.unlink()


def _foreign(folder: Path) -> bool:
    """Whether the sealed folder holds anything its seal does not list (a file, a folder,
    a link that wtftc did not write); False for a folder without a readable seal."""
    try:
        recorded = json.loads(files.seal_path(folder).read_text())
    except (OSError, ValueError):
        return False
    if not isinstance(recorded, dict):
        return False
    for top, dirs, names in os.walk(folder):
        for n in dirs + names:
            path = os.path.join(top, n)
            rel = os.path.relpath(path, folder) + (os.sep if n in dirs else "")
            if os.path.islink(path) or rel not in recorded:
                return True
    return False


def _make_in(make: Callable[[Path], None], tmp: Path, folder: Path, name: str) -> None:
    """``make(tmp)``, its refusals naming ``folder`` (where the entry will be), never the
    temporary folder deleted afterwards."""
    try:
        make(tmp)
    except (ConfigError, EngineError) as exc:
        renamed = _renamed(exc, str(tmp), str(folder))
        if renamed is None:
            raise
        raise renamed from None
    except OSError as exc:
        if exc.filename is None or not str(exc.filename).startswith(str(tmp)):
            raise
        raise _cache_refusal(cache_dir(), f"a folder that can be written (building "
                             f"{folder}: {exc.strerror or exc})") from None
    if not (tmp / name).is_file():
        raise EngineError(f"building {folder} in WTFTC_CACHE made no {name}")


def _renamed(exc: Exception, old: str, new: str) -> Exception | None:
    """``exc`` with ``old`` replaced by ``new`` in its message; None where it does not
    name ``old`` or cannot be remade so (a subclass with arguments of its own)."""
    if old not in str(exc):
        return None
    if type(exc) is ConfigError:
        value = exc.value.replace(old, new) if isinstance(exc.value, str) else exc.value
        return ConfigError(exc.field, value, exc.allowed.replace(old, new), exc.where)
    try:
        return type(exc)(str(exc).replace(old, new))
    except TypeError:
        return None


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
