"""What a sweep wrote in its results folder, and so all that it may replace (issue 30).

A results folder grows batch by batch (a sweep resumes), so it cannot be built aside and
swapped in whole as :mod:`wtftc.files` does for the other commands. It keeps a record
instead, ``.wtftc-sweep-written``: one JSON line per file written, appended *before* the
file appears under its name (a hidden temporary, then a rename)::

    {"path":"runs/part-0123456789abcdef.parquet","size":5120,"sha256":"9f2c...",
     "temp":"runs/.part-0123456789abcdef.parquet.1a2b3c4d.partial"}

A file is the sweep's when its content (size and sha256) is one the record lists for its
path, or, for a temporary a killed sweep left, when it is empty or complete. Only such a
file is overwritten or deleted (``--overwrite``, ``--summary``, ``--retry-failed``);
anything else is the user's: a file added, a listed file edited or damaged. Appending a
line costs what writing the file does (it is hashed once, from memory, as it is written);
nothing is re-hashed to resume, and each batch read is checked against its line.

A symbolic link or a special file (a FIFO, a device) anywhere in the folder is refused
before anything is read or written (:func:`scan`): none is ever followed or opened.

A folder written before the record existed (no record, a ``sweep.json``) is recognised
strictly: only files of the exact names a sweep writes, of the kind each name says (a
Parquet file that starts and ends with its magic, a PNG, a PDF, the summary's Markdown
and CSV headers, a sweep.json that parses) are the sweep's, and they are recorded when
wtftc next writes there (:meth:`Record.open`)."""

from __future__ import annotations

import errno
import hashlib
import json
import os
import re
import secrets
import stat
import tomllib
from pathlib import Path

from wtftc.errors import ConfigError
from wtftc.files import MAX_TOML_BYTES, read_user_bytes

#: the record of what the sweep and its summary wrote in the results folder
RECORD = ".wtftc-sweep-written"
#: the largest record read (a line is ~190 bytes: 5 million files)
MAX_RECORD_BYTES = 1 << 30
#: the largest batch file or trace read back (a batch of runs is a few kB)
MAX_PART_BYTES = 256 * 1024 * 1024
#: the file a sweep holds in its results folder while it writes there
LOCK = "sweep.lock"
#: the folder of the runs' OpenFAST cases, <this>/<run id>/ (engine = "openfast")
CASES = "openfast"
#: the files a sweep (and its summary) writes at the top of its results folder
SWEEP_FILES = ("sweep.toml", "sweep.json", LOCK, "summary.md", "summary.csv",
               "summary_cost.csv", "summary_dlc.csv", "summary_tuning.csv",
               "summary_paired.csv")
#: every figure the summary writes, figures/<name>.png and .pdf
FIGURES = ("rms_speed_error", "overspeed", "detection_delay", "dlc_bins", "dlc21_extremes",
           "paired_tradeoff",
           "tradeoff_fault_free", "tradeoff_faulted")
#: a batch of the dataset, runs/<this>
PART = re.compile(r"part-[0-9a-f]{16}\.parquet")
_TRACE = re.compile(r"[0-9a-f]{16}\.parquet")
_HEX64 = re.compile(r"[0-9a-f]{64}")
_EMPTY = f"0 {hashlib.sha256(b'').hexdigest()}"
#: the summary's CSV files by the first words of their header (a folder without a record)
_CSV_HEADS = {"summary.csv": ("controller,fault,runs,diverged,failed,",),
              "summary_cost.csv": ("controller,fault,runs,",),
              "summary_dlc.csv": ("controller,mean_wind_mps,runs,bin_probability,",
                                  "controller,fault,runs,lost,held,"),
              "summary_tuning.csv": ("condition,controller,omega_n_rad_s,zeta,runs",),
              "summary_paired.csv": ("controller,reference,fault,scenarios,failed,both_held,",)}
_MAGIC = {".parquet": (b"PAR1", b"PAR1"), ".png": (b"\x89PNG\r\n\x1a\n", b"IEND\xaeB`\x82"),
          ".pdf": (b"%PDF-", b"%%EOF")}


# ----------------------------------------------------------------- the folder's paths

def check_path(folder, option: str, must_exist: bool = False) -> Path:
    """``folder`` as a results folder path, or a refusal in one line naming ``option``: a
    symbolic link loop, a dangling link, a file, the current folder or one above it."""
    out = Path(folder)
    what = None
    try:
        st = os.stat(out)
    except OSError as exc:
        st = None
        if exc.errno == errno.ELOOP:
            what = "a folder that can be reached (this is a symbolic link loop)"
        elif exc.errno == errno.ENOTDIR:
            what = "a folder inside folders (a file stands in its path)"
        elif exc.errno != errno.ENOENT:
            what = f"a folder that can be reached ({exc.strerror})"
        elif os.path.islink(out):
            what = "a folder (this is a dangling symbolic link)"
        elif must_exist:
            what = "a sweep's results folder (with sweep.json; there is no such folder)"
    except ValueError:  # an embedded NUL byte
        what = "a folder name without NUL bytes"
    if what is None and st is not None and not stat.S_ISDIR(st.st_mode):
        what = "a folder (this is a file)"
    if what is None:
        try:
            real, cwd = out.resolve(), Path.cwd().resolve()
        except (OSError, RuntimeError):  # RuntimeError: a loop (Python 3.11)
            what = "a folder that can be reached (a symbolic link loop in its path)"
        else:
            if real in (cwd, *cwd.parents):
                what = ("a folder of its own (not the current folder or one that contains "
                        "it)")
    if what is not None:
        raise ConfigError(option, str(out), what)
    return out


def scan(folder: Path, option: str, folders: bool = False) -> list[str]:
    """Every regular file under ``folder`` (paths relative to it, sorted; with
    ``folders``, every folder too, as "<path>/"); a symbolic link or a special file
    anywhere is refused naming it, before anything is read."""
    folder = Path(folder)
    files: list[str] = []
    for root, dirs, names in os.walk(folder, followlinks=False):
        for name in sorted(dirs + names):
            full = os.path.join(root, name)
            mode = os.lstat(full).st_mode
            rel = os.path.relpath(full, folder)
            if stat.S_ISLNK(mode):
                raise ConfigError(option, str(folder), "a results folder without symbolic "
                                  f"links ({rel} is one; wtftc never follows one, never "
                                  "removes one: move it away; nothing was read, written or "
                                  "deleted)")
            if stat.S_ISREG(mode):
                files.append(rel)
            elif stat.S_ISDIR(mode):
                if folders:
                    files.append(rel + "/")
            else:
                raise ConfigError(option, str(folder), "a results folder of regular files "
                                  f"and folders ({rel} is {_describe(mode)}: move it away; "
                                  "nothing was read, written or deleted)")
    return sorted(files)


def _describe(mode: int) -> str:
    for test, what in ((stat.S_ISFIFO, "a FIFO (named pipe)"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return what
    return "not a regular file"


def read_file(path: Path, option: str, max_bytes: int = MAX_PART_BYTES) -> bytes:
    """A file of the results folder: a regular file (never a symbolic link followed)
    under ``max_bytes``, else a refusal naming it (:func:`wtftc.files.read_user_bytes`)."""
    try:
        if stat.S_ISLNK(os.lstat(path).st_mode):
            raise ConfigError(option, str(path), "a regular file of the results folder (this "
                              "is a symbolic link: wtftc never follows one)")
    except FileNotFoundError:
        pass
    return read_user_bytes(path, option, max_bytes)


def real_subfolder(folder: Path, name: str, option: str) -> Path:
    """``folder/name`` as a folder of its own, made if missing; a file or a symbolic link
    there is refused."""
    sub = Path(folder) / name
    try:
        sub.mkdir(exist_ok=True)
        real = stat.S_ISDIR(os.lstat(sub).st_mode)
    except OSError as exc:
        raise ConfigError(option, str(sub), f"a folder that can be made ({exc.strerror})") \
            from None
    if not real:
        raise ConfigError(option, str(sub), "a folder of the results folder (this is a file "
                          "or a symbolic link: move it away; nothing was written)")
    return sub


def _sha256_of(path: Path) -> tuple[int, str] | None:
    """(size, sha256) of the regular file at ``path``, never following a link or opening a
    FIFO; None if it is not one."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        h, n = hashlib.sha256(), 0
        while chunk := os.read(fd, 1 << 20):
            h.update(chunk)
            n += len(chunk)
        return n, h.hexdigest()
    finally:
        os.close(fd)


# ------------------------------------------------------------------------- the record

class Record:
    """The record of a results folder: path → the contents ("<size> <sha256>") the sweep
    wrote there, temporary → the content it was to hold. :meth:`open` it, ask
    :meth:`ours`, and :meth:`write` through it."""

    def __init__(self, folder: Path, option: str):
        self.folder, self.option = Path(folder), option
        self.files: dict[str, set[str]] = {}
        self.temps: dict[str, str] = {}
        self.pending: list[str] = []  # a folder without a record: what it adopts
        self.exists = False
        self._verdicts: dict[str, tuple[tuple, bool]] = {}

    # ..................................................................... reading it

    @classmethod
    def open(cls, folder: Path, option: str, files: list[str] | None = None) -> Record:
        """The folder's record; a folder without one but with a sweep.json (written before
        the record existed) adopts the files it recognises strictly (:func:`legacy`), in
        memory until something is written there; an empty or new folder, none."""
        rec = cls(folder, option)
        if not rec.reload() and os.path.lexists(rec.folder / "sweep.json"):
            for rel in files if files is not None else scan(rec.folder, option):
                if legacy(rec.folder, rel):
                    size_sha = _sha256_of(rec.folder / rel)
                    if size_sha is not None:
                        rec._add(rel, *size_sha)
                        rec.pending.append(_line(rel, *size_sha))
        return rec

    def reload(self) -> bool:
        """Read the record file again (a sweep writing the folder meanwhile appends to
        it); whether there is one."""
        path = self.folder / RECORD
        if not os.path.lexists(path):
            return False
        self._parse(read_file(path, self.option, MAX_RECORD_BYTES), path)
        self.exists = True
        return True

    def _parse(self, data: bytes, path: Path) -> None:
        lines = data.split(b"\n")
        for k, raw in enumerate(lines, 1):
            if not raw.strip():
                continue
            try:
                e = json.loads(raw)
                rel, size, sha = e["path"], e["size"], e["sha256"]
                temp = e.get("temp")
                if not (_rel_ok(rel) and type(size) is int and size >= 0
                        and isinstance(sha, str) and _HEX64.fullmatch(sha)
                        and (temp is None or _rel_ok(temp))):
                    raise ValueError
            except (ValueError, KeyError, TypeError):
                if k == len(lines):  # a line cut short by a crash as it was appended
                    continue
                raise ConfigError(self.option, str(path), "the record of what a sweep wrote, "
                                  f"one JSON line per file (line {k} is not one: remove the "
                                  "record, and wtftc recognises the sweep's files by their "
                                  "names and kinds)") from None
            self._add(rel, size, sha, temp)

    def _add(self, rel: str, size: int, sha: str, temp: str | None = None) -> None:
        self.files.setdefault(rel, set()).add(f"{size} {sha}")
        if temp is not None:
            self.temps[temp] = f"{size} {sha}"

    def ours(self, rel: str) -> bool:
        """Whether the file at ``rel`` holds content the sweep wrote there (a temporary:
        also empty); never follows a link. Remembered while the file is unchanged."""
        allowed = set(self.files.get(rel, ()))
        if rel in self.temps:
            allowed |= {self.temps[rel], _EMPTY}
        if not allowed:
            return False
        try:
            st = os.lstat(self.folder / rel)
        except OSError:
            return False
        if not stat.S_ISREG(st.st_mode):
            return False
        key = (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)
        seen = self._verdicts.get(rel)
        if seen is not None and seen[0] == key:
            return seen[1]
        verdict = False
        if any(a.split(" ")[0] == str(st.st_size) for a in allowed):
            size_sha = _sha256_of(self.folder / rel)
            verdict = size_sha is not None and "{} {}".format(*size_sha) in allowed
        self._verdicts[rel] = (key, verdict)
        return verdict

    def holds(self, rel: str, data: bytes) -> bool:
        """Whether ``data``, read from ``rel``, is content the sweep wrote there."""
        return f"{len(data)} {hashlib.sha256(data).hexdigest()}" in self.files.get(rel, ())

    def refuse_unless_ours(self, rels, field: str | None = None) -> None:
        """Refuse, in one line naming the first, files at ``rels`` that exist and are not
        the sweep's (a user's of the same name, or one edited since)."""
        for rel in rels:
            if os.path.lexists(self.folder / rel) and not self.ours(rel):
                raise ConfigError(field or self.option, str(self.folder), "a results folder "
                                  f"whose {rel} is the one wtftc wrote there (this {rel} is "
                                  "not: a user's file of that name, or one edited since; "
                                  "wtftc never overwrites it: move it away; nothing was "
                                  "written)")

    # ..................................................................... writing it

    def _append(self, line: str) -> None:
        path = self.folder / RECORD
        flags = os.O_RDWR | os.O_APPEND | os.O_NOFOLLOW | os.O_CLOEXEC
        data = line.encode()
        fd = None
        if self.pending:  # adopt a folder written before the record: all at once
            try:
                fd = os.open(path, flags | os.O_CREAT | os.O_EXCL, 0o666)
                data = "".join(self.pending).encode() + data
            except FileExistsError:
                pass  # another wtftc adopted it meanwhile
            self.pending = []
        if fd is None:
            fd = os.open(path, flags | os.O_CREAT, 0o666)
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise ConfigError(self.option, str(path), "a regular file")
            size = os.fstat(fd).st_size
            if size and os.pread(fd, 1, size - 1) != b"\n":  # a line cut short: end it
                data = b"\n" + data
            os.write(fd, data)
        finally:
            os.close(fd)
        self.exists = True

    def write(self, rel: str, data: bytes) -> Path:
        """Write ``data`` at ``rel`` (its folder made if missing), atomically: recorded
        first, then a hidden temporary made exclusively, then renamed into place. A file
        there that is not the sweep's is refused, untouched."""
        self.refuse_unless_ours([rel])
        path = self.folder / rel
        parent = path.parent
        if parent != self.folder:
            real_subfolder(self.folder, os.path.relpath(parent, self.folder), self.option)
        size, sha = len(data), hashlib.sha256(data).hexdigest()
        while True:
            temp = parent / f".{path.name}.{secrets.token_hex(4)}.partial"
            temp_rel = os.path.relpath(temp, self.folder)
            self._append(_line(rel, size, sha, temp_rel))
            self._add(rel, size, sha, temp_rel)
            try:
                fd = os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW
                             | os.O_CLOEXEC, 0o666)
            except FileExistsError:
                continue
            break
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
            os.replace(temp, path)
        except BaseException:
            try:
                os.unlink(temp)
            except OSError:
                pass
            raise
        return path

    def adopt(self, folder_rel: str) -> int:
        """Record every file of the folder ``folder_rel`` as the sweep's, with the content
        it holds now: a run's OpenFAST case, written in place by OpenFAST and wtftc's
        case writer on a worker (its absolute paths keep it where it was made), recorded
        when its run is saved. A symbolic link or a special file there is refused
        (:func:`scan`). Returns how many files."""
        folder = self.folder / folder_rel
        lines = []
        for rel in scan(folder, self.option):
            size_sha = _sha256_of(folder / rel)
            if size_sha is not None:
                path = os.path.join(folder_rel, rel)
                self._add(path, *size_sha)
                lines.append(_line(path, *size_sha))
        if lines:
            self._append("".join(lines))
        return len(lines)

    def remove(self, rel: str) -> bool:
        """Delete the file at ``rel`` if it is the sweep's; whether it was."""
        if not self.ours(rel):
            return False
        os.unlink(self.folder / rel)
        return True

    def forget(self) -> None:
        """Delete the record itself (``--overwrite``, once the files it lists are gone)."""
        path = self.folder / RECORD
        if os.path.lexists(path) and stat.S_ISREG(os.lstat(path).st_mode):
            os.unlink(path)
        self.files, self.temps, self.pending, self.exists = {}, {}, [], False
        self._verdicts.clear()


def _rel_ok(rel) -> bool:
    return (isinstance(rel, str) and bool(rel) and not os.path.isabs(rel)
            and ".." not in Path(rel).parts)


def _line(rel: str, size: int, sha: str, temp: str | None = None) -> str:
    e = {"path": rel, "size": size, "sha256": sha}
    if temp is not None:
        e["temp"] = temp
    return json.dumps(e, separators=(",", ":")) + "\n"


# ------------------------------------------------ folders written before the record

_OLD_TEMP = r"\.(?P<name>{})\.[a-z0-9_]{{8}}"  # tempfile.mkstemp's names


def _legacy_name(rel: str) -> tuple[str, bool] | None:
    """(the name a sweep writes, whether ``rel`` is a hidden temporary of it), or None."""
    parts = Path(rel).parts
    if len(parts) == 1:
        top = "|".join(map(re.escape, (n for n in SWEEP_FILES if n != LOCK)))
        if re.fullmatch(top, rel):
            return rel, False
        m = re.fullmatch(_OLD_TEMP.format(top), rel)
        return (m["name"], True) if m else None
    if len(parts) != 2:
        return None
    sub, name = parts
    if sub in ("runs", "traces"):
        pat = PART.pattern if sub == "runs" else _TRACE.pattern
        if re.fullmatch(pat, name):
            return name, False
        m = re.fullmatch(_OLD_TEMP.format(pat), name)
        return (m["name"], True) if m else None
    if sub == "figures":
        figs = "|".join(map(re.escape, FIGURES))
        m = re.fullmatch(rf"(?:{figs})\.(?:png|pdf)", name)
        if m:
            return name, False
        m = re.fullmatch(rf"\.(?P<stem>{figs})\.[a-z0-9_]{{8}}\.(?P<ext>png|pdf)", name)
        return (f"{m['stem']}.{m['ext']}", True) if m else None
    return None


def legacy(folder: Path, rel: str) -> bool:
    """Whether ``rel`` in a results folder without a record is a file a sweep wrote there:
    one of the exact names it writes (or the hidden temporary of one), a regular file of
    the kind that name says; a temporary may be empty or cut short, never of another kind."""
    named = _legacy_name(rel)
    if named is None:
        return False
    name, temp = named
    path = Path(folder) / rel
    try:
        st = os.lstat(path)
        if not stat.S_ISREG(st.st_mode) or st.st_size > MAX_PART_BYTES:
            return False
        if temp and st.st_size == 0:
            return True
        suffix = Path(name).suffix
        if suffix in _MAGIC:
            head, tail = _MAGIC[suffix]
            with open(path, "rb", opener=_nofollow) as fh:
                first = fh.read(len(head))
                fh.seek(max(0, st.st_size - 64))
                last = fh.read().rstrip()
            return first == head and (temp or last.endswith(tail))
        if st.st_size > MAX_TOML_BYTES:
            return False
        with open(path, "rb", opener=_nofollow) as fh:
            text = fh.read().decode("utf-8")
    except (OSError, UnicodeDecodeError):
        return False
    return _legacy_text(name, text, temp)


def _legacy_text(name: str, text: str, temp: bool) -> bool:
    if temp:  # cut short: its beginning says what it is
        return (name == "sweep.toml" or text.startswith(("{", "# Sweep "))
                or text.startswith(_CSV_HEADS.get(name, ("\0",))))
    if name == "sweep.toml":
        try:
            tomllib.loads(text)
        except tomllib.TOMLDecodeError:
            return False
        return True
    if name == "sweep.json":
        try:
            meta = json.loads(text)
        except ValueError:
            return False
        return (isinstance(meta, dict) and isinstance(meta.get("sweep_id"), str)
                and isinstance(meta.get("sweep"), dict)
                and isinstance(meta.get("versions"), dict))
    if name == "summary.md":
        return (re.match(r"# Sweep \S+: \d+ of \d+ runs saved\n", text) is not None
                and "\n## Failed or diverged runs: " in text)
    return text.startswith(_CSV_HEADS[name]) and text.endswith("\n")


def _nofollow(path, flags):
    return os.open(path, flags | os.O_NOFOLLOW | os.O_NONBLOCK)
