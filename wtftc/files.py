"""The two safety rules of every command, in one place (issue 30):

* **What a user may hand us** (:func:`read_user_bytes`, :func:`read_user_text`,
  :func:`check_user_file`): a regular file under a size cap. A directory, a FIFO, a device
  (``/dev/zero``), a symlink loop or a file too large is refused in one line naming the
  option, before a byte is read, so nothing hangs and nothing reads to exhaustion.
* **What wtftc wrote** (:func:`owned_folder`, :func:`write_files_together`): a command that
  writes a folder builds it in a hidden sibling and swaps it in whole. It may replace a
  folder only when that folder is empty or holds exactly what wtftc wrote there, as its
  marker file ``.wtftc-written`` lists it (path, size and sha256 of every file); anything
  else, a user's file added, a listed file changed, is refused in one line and nothing is
  touched. A command never deletes a file it did not write.

A killed command leaves its hidden ``.<name>.*.partial`` sibling behind; the next command
into the same folder removes it, once its lock shows that no process holds it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import errno
import fcntl
import hashlib
import json
import os
import shutil
import signal
import stat
import tempfile
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from wtftc.errors import ConfigError

#: the marker of a folder wtftc wrote: JSON {"written_by": command, "files": {path:
#: "<size> <sha256>"}}: a file edited since, even to the same size, makes it the user's
MARKER = ".wtftc-written"
#: the lock a folder under construction holds while its command runs
PARTIAL_LOCK = ".wtftc-partial"
#: the largest file wtftc reads from a user (a 600-s wind file at 1 kHz is ~10 MB)
MAX_INPUT_BYTES = 256 * 1024 * 1024
#: the largest TOML file (a configuration, a sweep, a turbine file) wtftc reads
MAX_TOML_BYTES = 16 * 1024 * 1024
#: the largest Cp/Ct/Cq table (the IEA 15-MW's is 0.3 MB)
MAX_TABLE_BYTES = 64 * 1024 * 1024


# --------------------------------------------------------------------- what a user hands us

def _describe(mode: int) -> str:
    for test, what in ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return what
    return "not a regular file"


def check_user_file(path, field: str, max_bytes: int = MAX_INPUT_BYTES) -> Path:
    """``path`` as a Path if it is a regular file of at most ``max_bytes``; a ConfigError
    naming ``field`` otherwise (missing, a folder, a FIFO, a device, a symlink loop,
    unreadable, too large). Never opens the file, so a FIFO cannot block."""
    p = Path(path)
    if not str(path):
        raise ConfigError(field, "", "a file name")
    try:
        st = os.stat(p)
    except OSError as exc:
        if exc.errno in (errno.ENOENT, errno.ENOTDIR):
            raise ConfigError(field, str(path), "an existing file (there is none)") from None
        why = ("a symbolic link loop" if exc.errno == errno.ELOOP else
               exc.strerror or type(exc).__name__)
        raise ConfigError(field, str(path), f"a readable regular file ({why})") from None
    except ValueError:  # an embedded NUL byte
        raise ConfigError(field, str(path), "a file name without NUL bytes") from None
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError(field, str(path), f"a regular file (this is {_describe(st.st_mode)})")
    if st.st_size > max_bytes:
        raise ConfigError(field, str(path), f"a file of at most {max_bytes} bytes (this one "
                          f"has {st.st_size})")
    return p


def read_user_bytes(path, field: str, max_bytes: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of a user's regular file, checked as :func:`check_user_file` before and
    after opening (opened non-blocking: a FIFO swapped in meanwhile cannot hang us)."""
    p = check_user_file(path, field, max_bytes)
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise ConfigError(field, str(path), f"a readable regular file ({exc.strerror})") \
            from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise ConfigError(field, str(path), f"a regular file (this is "
                              f"{_describe(st.st_mode)})")
        chunks, total = [], 0
        while True:
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            total += len(chunk)
            if total > max_bytes:
                raise ConfigError(field, str(path), f"a file of at most {max_bytes} bytes")
            chunks.append(chunk)
    except OSError as exc:
        raise ConfigError(field, str(path), f"a readable regular file ({exc.strerror})") \
            from None
    finally:
        os.close(fd)
    return b"".join(chunks)


def read_user_text(path, field: str, max_bytes: int = MAX_INPUT_BYTES,
                   encoding: str = "utf-8") -> str:
    """A user's text file (UTF-8 by default; a BOM is dropped); a binary file is refused
    naming the field and the byte offset where decoding failed."""
    data = read_user_bytes(path, field, max_bytes)
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise ConfigError(field, str(path), f"a {encoding} text file (byte {exc.start} "
                          "cannot be decoded: a binary file?)") from None
    if "\x00" in text:
        raise ConfigError(field, str(path), "a text file (it holds NUL bytes: a binary file?)")
    return text.removeprefix("\ufeff")


def decode_text(data: bytes) -> str:
    """A user's text as they wrote it: UTF-8 (a BOM dropped), else Latin-1, which decodes
    any byte (an OpenFAST deck written on Windows with a "°" in a comment). For files
    whose words are ASCII where they matter; a refusal, where the content does matter,
    is the reader's."""
    try:
        return data.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError:
        return data.decode("latin-1")


# ---------------------------------------------------------------------- what wtftc caches

#: the seal of a cache entry lies beside it: ``<entry>.sha256``, JSON {path: "<size>
#: <sha256>"} of the file, or of every file under the folder ("." for a file entry)
SEAL_SUFFIX = ".sha256"


def seal_path(entry: Path) -> Path:
    entry = Path(entry)
    return entry.with_name(entry.name + SEAL_SUFFIX)


def _seal_listing(entry: Path) -> dict[str, str] | None:
    if entry.is_file():
        return {".": f"{entry.stat().st_size} {file_sha256(entry)}"}
    return _listing(entry) if entry.is_dir() else None


def seal(entry: Path) -> None:
    """Record ``entry``'s size and sha256 (a folder: of every file under it) beside it,
    once it is whole: :func:`seal_damage` checks them when it is read. The seal is written
    to a temporary and renamed into place."""
    entry = Path(entry)
    listing = _seal_listing(entry)
    if listing is None:
        raise OSError(f"{entry} is not a file or a folder of regular files")
    target = seal_path(entry)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(listing, fh, indent=0, sort_keys=True)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
    except BaseException:
        with suppress(OSError):
            os.unlink(tmp)
        raise


def seal_damage(entry: Path) -> str | None:
    """What is wrong with the cache entry ``entry`` against its seal; None when it is
    whole. A missing seal, a file changed (even at the same size), added or removed is
    damage."""
    entry = Path(entry)
    try:
        recorded = json.loads(read_user_bytes(seal_path(entry), "seal", 1 << 24))
    except ConfigError as exc:  # missing, a FIFO, a folder...: never opened to block
        return ("no checksum recorded beside it" if not os.path.lexists(seal_path(entry))
                else f"its checksum file is unreadable ({exc.allowed})")
    except ValueError as exc:
        return f"its checksum file is unreadable ({exc})"
    try:
        found = _seal_listing(entry)
    except OSError as exc:
        return f"unreadable ({exc.strerror or exc})"
    if found is None:
        return "missing" if not entry.exists() else "not a regular file or folder"
    if not isinstance(recorded, dict) or not all(isinstance(v, str)
                                                 for v in recorded.values()):
        return "its checksum file is not a listing"
    if ("." in recorded) != ("." in found):
        return "a folder where a file was written" if entry.is_dir() else \
            "a file where a folder was written"
    for name in sorted(set(recorded) | set(found)):
        if name not in found:
            return f"{name} is missing"
        if name not in recorded:
            return f"{name} was added"
        if found[name] != recorded[name]:
            (a, _, x), (b, _, y) = found[name].partition(" "), recorded[name].partition(" ")
            what = "" if name == "." else f"{name}: "
            return (f"{what}{a} bytes, {b} when written" if a != b else
                    f"{what}sha256 {x[:12]}…, {y[:12]}… when written")
    return None


# ---------------------------------------------------------------------- what wtftc wrote

def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _listing(folder: Path) -> dict[str, str] | None:
    """Every file under ``folder`` (relative path: "<size> <sha256>") and every folder
    (path with a trailing separator: "folder"), the marker left out; None when it holds
    anything but regular files and folders (a symlink, a FIFO...)."""
    out: dict[str, str] = {}
    for root, dirs, files in os.walk(folder, followlinks=False):
        for name in dirs:
            full = os.path.join(root, name)
            if os.path.islink(full):
                return None
            out[os.path.relpath(full, folder) + os.sep] = "folder"  # an empty one counts
        for name in files:
            full = os.path.join(root, name)
            st = os.lstat(full)
            if not stat.S_ISREG(st.st_mode):
                return None
            rel = os.path.relpath(full, folder)
            if rel != MARKER:
                out[rel] = f"{st.st_size} {file_sha256(full)}"
    return out


def file_sha256(path) -> str:
    """The sha256 of the file at ``path``, read in 1-MB chunks (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def written_by_wtftc(folder: Path) -> bool:
    """Whether ``folder`` holds exactly what its marker says wtftc wrote there."""
    try:
        listed = json.loads((Path(folder) / MARKER).read_text())["files"]
        found = _listing(Path(folder))
    except (OSError, ValueError, KeyError, TypeError):
        return False
    return isinstance(listed, dict) and found == listed


def _replaceable(out: Path, legacy: Callable[[Path], bool] | None) -> bool:
    try:
        if not any(out.iterdir()):
            return True
    except OSError:
        return False
    return written_by_wtftc(out) or (legacy is not None and legacy(out))


def check_out_folder(out, option: str = "--out",
                     legacy: Callable[[Path], bool] | None = None) -> Path:
    """Refuse, in one line naming ``option``, an output folder that wtftc may not replace:
    the current folder or one above it, a file, a symlink loop, or a folder holding
    anything wtftc did not write there (``legacy`` recognises folders written before the
    marker existed). Nothing is created."""
    if not str(out):
        raise ConfigError(option, "", "a folder name")
    out = Path(os.path.normpath(out))  # r/figures/.. is r: checked as it will be swapped
    try:
        real = out.resolve()
        exists = out.exists()
    except (OSError, RuntimeError) as exc:  # RuntimeError: a symlink loop (Python 3.11)
        raise ConfigError(option, str(out), f"a folder that can be reached ({exc})") from None
    if real in (Path.cwd().resolve(), *Path.cwd().resolve().parents):
        raise ConfigError(option, str(out), "a folder of its own (not the current folder or "
                          "one that contains it)")
    if out.is_symlink():  # swapping would replace the user's link, not its target's files
        raise ConfigError(option, str(out), "a folder, not a symbolic link (give the folder "
                          "it points to)" if exists else "a folder (this is a dangling "
                          "symbolic link)")
    if exists and not out.is_dir():
        raise ConfigError(option, str(out), "a folder (this is a file)")
    if exists and not _replaceable(out, legacy):
        raise ConfigError(option, str(out), "a new folder, an empty one or one that wtftc "
                          "wrote (this one holds files wtftc did not write; nothing was "
                          "written or deleted)")
    check_writable_ancestor(real, option, str(out))
    return out


def check_writable_ancestor(path: Path, option: str, given: str) -> None:
    """Refuse, naming ``option`` and the ``given`` path, a ``path`` whose nearest existing
    ancestor is not a folder this process may create entries in."""
    probe = Path(path)
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir() or not os.access(probe, os.W_OK | os.X_OK):
        raise ConfigError(option, given, f"a folder that can be written ({probe} is not a "
                          "writable folder)")


def _clean_stale(parent: Path, name: str) -> None:
    """Remove the hidden siblings of ``name`` that a killed command left: folders named
    ``.<name>.*.partial`` whose lock no process holds, or holding only what wtftc wrote."""
    for p in parent.glob(f".{name}.*.partial"):
        if p.is_symlink() or not p.is_dir():
            continue
        lock = p / PARTIAL_LOCK
        if lock.is_file() and not lock.is_symlink():
            try:
                fd = os.open(lock, os.O_RDONLY)
            except OSError:
                continue
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)  # a live command's folder
                continue
            shutil.rmtree(p, ignore_errors=True)
            os.close(fd)
        elif written_by_wtftc(p):  # an old folder swapped out, its removal interrupted
            shutil.rmtree(p, ignore_errors=True)


def write_marker(folder: Path, command: str) -> None:
    """List every file of ``folder`` in its marker (call when the folder is complete)."""
    listing = _listing(folder) or {}
    (Path(folder) / MARKER).write_text(json.dumps(
        {"written_by": f"wtftc {command}", "files": listing}, indent=1, sort_keys=True)
        + "\n")


_libc = None


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux renameat2 RENAME_EXCHANGE); False if unsupported."""
    global _libc
    if _libc is None:
        _libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
    fn = getattr(_libc, "renameat2", None)
    if fn is None:
        return False
    at_fdcwd, exchange = -100, 2
    rc = fn(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), exchange)
    if rc == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), str(b))


@contextmanager
def owned_folder(out, option: str = "--out", command: str = "",
                 legacy: Callable[[Path], bool] | None = None) -> Iterator[Path]:
    """Yield a hidden sibling of ``out`` to write into; when the block ends normally, list
    its files in the marker and swap it in place of ``out`` as a whole (atomically where
    the file system allows). ``out`` is checked first (:func:`check_out_folder`) and again
    just before the swap, under a lock on its parent, so a file a user adds meanwhile is
    never deleted. A failure or an interrupt leaves ``out`` as it was and no litter; the
    new folder keeps the mode of the one it replaces (else 0777 minus the umask)."""
    out = check_out_folder(out, option, legacy)
    parent = out.parent if str(out.parent) else Path(".")
    made = [p for p in (parent, *parent.parents) if not p.exists()]
    try:
        parent.mkdir(parents=True, exist_ok=True)
        _clean_stale(parent, out.name)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=parent))
    except OSError as exc:
        raise ConfigError(option, str(out),
                          f"a folder that can be written ({exc.strerror})") from None
    lock_fd = os.open(tmp / PARTIAL_LOCK, os.O_CREAT | os.O_RDWR, 0o600)
    fcntl.flock(lock_fd, fcntl.LOCK_EX)
    done = False
    try:
        yield tmp
        os.unlink(tmp / PARTIAL_LOCK)
        write_marker(tmp, command)
        _swap_in(tmp, out, parent, option, legacy)
        done = True
    finally:
        os.close(lock_fd)
        shutil.rmtree(tmp, ignore_errors=True)
        for p in made if not done else ():
            try:
                p.rmdir()
            except OSError:
                break


def _swap_in(tmp: Path, out: Path, parent: Path, option: str, legacy) -> None:
    fd = os.open(parent, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        check_out_folder(out, option, legacy)  # again: out may have changed meanwhile
        mode = (out.stat().st_mode & 0o7777) if out.is_dir() else 0o777 & ~_umask()
        os.chmod(tmp, mode)  # mkdtemp makes 0700
        swap_folder(tmp, out)
    finally:
        fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)


def swap_folder(new: Path, out: Path) -> None:
    """Put the complete folder ``new`` in place of ``out`` (which may be missing) in one
    step where the file system allows (RENAME_EXCHANGE; a reader sees the old folder or
    the new one, never none), leaving the old contents at ``new`` for the caller to
    remove. The caller has checked that ``out`` may be replaced."""
    new, out = Path(new), Path(out)
    if not out.exists():
        os.rename(new, out)
        return
    if _exchange(new, out):
        return
    parent = out.parent if str(out.parent) else Path(".")
    old = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=parent))
    os.rename(out, old / out.name)
    os.rename(new, out)
    os.rename(old / out.name, new)
    old.rmdir()


# ------------------------------------------------------------------------- single files

def check_new_file(path, option: str, overwrite: bool = False,
                   ours: Callable[[Path], bool] | None = None) -> Path:
    """Refuse to write ``path`` where a file is already there, unless ``overwrite`` is
    given or ``ours(path)`` recognises it as one wtftc wrote; also refuse a folder, a
    special file and a path inside the installed package's own data."""
    p = Path(path)
    if not str(path):
        raise ConfigError(option, "", "a file name")
    try:
        real = p.resolve()
    except (OSError, RuntimeError) as exc:
        raise ConfigError(option, str(p), f"a path that can be reached ({exc})") from None
    package = Path(__file__).resolve().parent
    if real == package or package in real.parents:
        raise ConfigError(option, str(p), f"a path outside the installed wtftc package "
                          f"({package}): its own data is never written")
    if p.is_symlink() and not p.exists():
        raise ConfigError(option, str(p), "a file (this is a dangling symbolic link)")
    if p.exists():
        if not p.is_file():
            raise ConfigError(option, str(p), f"a regular file (this is "
                              f"{_describe(p.stat().st_mode)})")
        if not overwrite and not (ours is not None and ours(p)):
            raise ConfigError(option, str(p), "a new file (it exists; give --overwrite to "
                              "replace it; nothing was written)")
    return p


def write_files_together(files: dict[Path, bytes]) -> None:
    """Write several files all or none: each into a hidden temporary beside it first, then
    renamed into place; a rename that fails puts back what the earlier ones replaced."""
    tmps: list[tuple[str, Path]] = []
    mode = 0o666 & ~_umask()
    try:
        for path, data in files.items():
            path = Path(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
            tmps.append((tmp, path))
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
            os.chmod(tmp, mode)
        backups: list[tuple[Path, str | None]] = []
        try:
            for tmp, path in tmps:
                backup = None
                if path.exists():
                    fd, backup = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".old",
                                                  dir=path.parent)
                    os.close(fd)
                    os.replace(path, backup)
                backups.append((path, backup))
                os.replace(tmp, path)
        except BaseException:
            for path, backup in reversed(backups):
                with suppress(OSError):
                    if backup is not None:
                        os.replace(backup, path)
                    else:
                        path.unlink()
            raise
        for _, backup in backups:
            if backup is not None:
                with suppress(OSError):
                    os.unlink(backup)
    finally:
        for tmp, _ in tmps:
            with suppress(OSError):
                os.unlink(tmp)


@contextmanager
def sigterm_as_interrupt():
    """Meanwhile SIGTERM raises KeyboardInterrupt, so that what is running is stopped and
    what it wrote is cleaned up as on Ctrl-C (only in the main thread, where Python takes
    signals)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
