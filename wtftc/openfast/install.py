"""Find or get OpenFAST 5.0.0 and TurbSim (issue 32, ``make openfast``, ``wtftc openfast get``).

The order, first found wins:

1. ``$OPENFAST`` (and ``$TURBSIM``, else the ``turbsim`` beside it or on PATH): the user
   names the program, so one that does not print its version is taken as given; one that
   prints another major version is refused. ``$TURBSIM``, when set, is the TurbSim of
   whatever OpenFAST is found;
2. ``openfast`` on PATH, if it says it is 5.x;
3. the copy wtftc installed before, in its cache folder (``$WTFTC_CACHE``, default
   ``~/.cache/wtftc``) under ``openfast/5.0.0/``: its program folder and its record
   ``install.json`` are sealed when installed (:func:`wtftc.files.seal`) and checked each
   time; damaged, it is named with ``wtftc openfast get``, which installs it again;
4. the prebuilt archive (``openfast-5.0.0-linux-x86_64.tar.gz``, checked by its SHA-256)
   in an archive folder: ``--archives``, ``$WTFTC_OPENFAST_ARCHIVES``, the work area's
   ``shared/openfast/`` beside the repository, or ``/work/shared/openfast`` (a damaged
   copy is named and passed over). Its runtime libraries (gfortran's, LAPACK, BLAS) are
   installed with apt when missing and apt can;
5. a build from the source archive in the same folders (about 17 minutes on 2 cores), or
   from a shallow clone of the v5.0.0 tag for a user with internet.

A variable that names nothing usable (empty, missing, a folder, not executable, a program
that cannot be started) is a :class:`wtftc.errors.ConfigError` naming it (exit code 2); a
program that starts and fails, or anything missing, is said in one line
(:class:`wtftc.errors.EngineError`, exit code 4) with the command that gets it. A
program's ``-v`` is read in any encoding, in a process group of its own that is killed
whole after it. The programs are never installed outside wtftc's cache folder; apt installs
system libraries only where the user runs as root (a CI machine, a container).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import re
import select
import shutil
import signal
import stat
import subprocess
import tarfile
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from wtftc import files
from wtftc.artefacts.loader import cache_dir, clean_stale_builds, new_build_folder, writable_cache
from wtftc.errors import ConfigError, EngineError

VERSION = "5.0.0"
MAJOR = 5
#: the archives the machines here keep (shared/openfast/README.md), by SHA-256
PREBUILT = ("openfast-5.0.0-linux-x86_64.tar.gz",
            "1b371bf66adf7ec7f00ab1f02b065a8dac5aa9726f5b79aa8022a74e3fdd092a")
SOURCE = ("openfast-5.0.0-src.tar.gz",
          "33fd8918373278e00fc394865d50bd76d6c5496eb39ced38c7518dff036e6469")
#: the Debian packages the prebuilt binaries load, and those a build needs
RUNTIME_PACKAGES = ("libgfortran5", "liblapack3", "libblas3")
BUILD_PACKAGES = ("gfortran", "liblapack-dev", "libblas-dev", "cmake", "make")
GIT_URL = "https://github.com/OpenFAST/openfast.git"
#: cmake options of the build (shared/openfast/README.md): double precision, no tests,
#: no C++ API, no FAST.Farm
CMAKE_OPTIONS = ("-DCMAKE_BUILD_TYPE=Release", "-DBUILD_TESTING=OFF", "-DDOUBLE_PRECISION=ON",
                 "-DBUILD_OPENFAST_CPP_API=OFF", "-DBUILD_FASTFARM=OFF")
#: how long ``<program> -v`` may take [s], and how much of its output is read [bytes]
_PROBE_TIMEOUT_S = 60.0
_PROBE_BYTES = 1 << 20
#: the hidden temporary folders of ``get`` in :func:`home` (an archive being unpacked, a
#: source tree being built), each holding a lock while in use; a killed ``get`` leaves
#: them, and the next one removes them
_UNPACK, _BUILD_TREE = "unpack", "build-tree"


@dataclass(frozen=True)
class Install:
    """Where OpenFAST and TurbSim are, and how wtftc found them."""

    openfast: Path
    turbsim: Path
    version: str  # "5.0.0", or "5.x (not printed)" for a build that does not say
    source: str  # how it was found: "$OPENFAST", "PATH", "cache", "prebuilt ...", "built ..."

    def describe(self) -> str:
        return (f"OpenFAST {self.version}: {self.openfast}\nTurbSim: {self.turbsim}\n"
                f"found by: {self.source}")


def home() -> Path:
    """wtftc's own copy: ``<cache>/openfast/5.0.0`` with ``bin/openfast``, ``bin/turbsim``."""
    return cache_dir() / "openfast" / VERSION


def archive_folders(extra: Path | None = None) -> list[Path]:
    """Where the archives are looked for, in order. ``--archives`` (``extra``) and
    ``$WTFTC_OPENFAST_ARCHIVES`` must name folders: a ConfigError naming them otherwise."""
    folders = [_archive_folder("--archives", str(extra))] if extra is not None else []
    env = os.environ.get("WTFTC_OPENFAST_ARCHIVES")
    if env is not None:
        folders.append(_archive_folder("WTFTC_OPENFAST_ARCHIVES", env))
    repo = Path(__file__).resolve().parents[2]
    folders += [repo.parent / "shared" / "openfast", Path("/work/shared/openfast")]
    seen, out = set(), []
    for f in folders:
        key = str(f.resolve()) if f.exists() else str(f)
        if key not in seen:
            seen.add(key)
            out.append(f)
    return out


def _archive_folder(field: str, value: str) -> Path:
    """The folder of archives that ``field`` names; a ConfigError where it names none."""
    allowed = f"a folder holding {PREBUILT[0]} or {SOURCE[0]}"
    if not value.strip():
        raise ConfigError(field, value, f"{allowed} (unset it to use the default folders)")
    try:
        folder = Path(os.path.abspath(os.path.expanduser(value)))
        st = os.stat(folder)
    except OSError as exc:  # (an environment variable or argument holds no NUL byte)
        why = ("there is no folder there" if isinstance(exc, FileNotFoundError) else
               "a symbolic link loop" if exc.errno == errno.ELOOP else
               exc.strerror or type(exc).__name__)
        raise ConfigError(field, value, f"{allowed} ({why})") from None
    if not stat.S_ISDIR(st.st_mode):
        raise ConfigError(field, value, f"{allowed} (this is not a folder)")
    return folder


@dataclass(frozen=True)
class Probe:
    runs: bool
    version: str | None  # "5.0.0" as printed, None where it prints none
    missing_library: str | None  # "liblapack.so.3" when the loader cannot find it
    message: str  # the program's last words, one line, when it does not run
    started: bool = True  # False: it could not be started at all (not a program)


def _output(cmd: list[str], timeout: float) -> tuple[int | None, bytes]:
    """The exit code (None: stopped at ``timeout`` or at :data:`_PROBE_BYTES` of output)
    and the output (standard output and error) of ``cmd``, run in a process group of its
    own that is killed whole at the end: nothing it started is left running."""
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, start_new_session=True)
    out, code, deadline = bytearray(), None, time.monotonic() + timeout
    try:
        fd = proc.stdout.fileno()
        while len(out) < _PROBE_BYTES and time.monotonic() < deadline:
            exited = proc.poll() is not None  # before reading: all it wrote is in the pipe
            if select.select([fd], [], [], 0 if exited else 0.05)[0]:
                chunk = os.read(fd, 1 << 16)
                if chunk:
                    out += chunk
                    continue
                with contextlib.suppress(subprocess.TimeoutExpired):  # the end of its output
                    proc.wait(max(0.0, deadline - time.monotonic()))
                code = proc.returncode
                break
            if exited:  # ended, all its output read (a child of its own may hold the pipe
                code = proc.returncode  # open: not waited for)
                break
    finally:
        with contextlib.suppress(OSError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        proc.stdout.close()
    return code, bytes(out[:_PROBE_BYTES])


def _one_line(text: str, limit: int = 200) -> str:
    """``text`` as one printable line of at most ``limit`` characters."""
    flat = " ".join(text.split())
    flat = "".join(c if c.isprintable() else "?" for c in flat)
    return flat if len(flat) <= limit else flat[:limit] + "..."


def probe(exe: Path, banner: str = "OpenFAST") -> Probe:
    """Run ``exe -v`` and read what it says (in any encoding): whether it runs, its
    version, a library the dynamic loader cannot find."""
    limit = _PROBE_TIMEOUT_S
    try:
        code, raw = _output([str(exe), "-v"], limit)
    except (OSError, ValueError) as exc:
        why = getattr(exc, "strerror", None) or str(exc)
        return Probe(False, None, None, why, started=False)
    text = files.decode_text(raw)
    lib = re.search(r"error while loading shared libraries: ([^:\s]+)", text)
    if lib:
        return Probe(False, None, lib.group(1), _one_line(lib.group(0)))
    if banner not in text:
        last = [line.strip() for line in text.splitlines() if line.strip()]
        why = (f"`{exe} -v` did not end within {limit:g} s or printed more "
               f"than {_PROBE_BYTES} bytes (stopped)" if code is None else
               _one_line(last[-1]) if last else f"exit code {code}, no output")
        return Probe(False, None, None, why)
    ver = re.search(r"OpenFAST-v(\d+\.\d+\.\d+)", text) if banner == "OpenFAST" else None
    return Probe(True, ver.group(1) if ver else None, None, "")


def _major(version: str | None) -> int | None:
    return int(version.split(".")[0]) if version else None


def _named_program(var: str, what: str) -> Path | None:
    """The program ``$var`` names, as an absolute path (OpenFAST and TurbSim run in other
    folders); None where ``var`` is unset. A ConfigError naming ``var`` where it names no
    executable file: empty, missing, a folder, not executable, not on PATH."""
    env = os.environ.get(var)
    if env is None:
        return None
    allowed = f"the path of an executable {what} program"
    if not env.strip():
        raise ConfigError(var, env, f"{allowed} (unset {var} to let wtftc find one)")
    if os.sep not in env:  # a bare name: looked up on PATH, as a shell does
        found = shutil.which(env)
        if found is None:
            raise ConfigError(var, env, f"{allowed} (there is no {env} on PATH)")
        env_path = Path(found)
    else:
        env_path = Path(os.path.abspath(os.path.expanduser(env)))
    try:
        st = os.stat(env_path)
    except OSError as exc:  # (an environment variable holds no NUL byte)
        why = ("there is no file there" if isinstance(exc, FileNotFoundError | NotADirectoryError)
               else "a symbolic link loop" if exc.errno == errno.ELOOP else
               exc.strerror or type(exc).__name__)
        raise ConfigError(var, env, f"{allowed} ({why})") from None
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError(var, env, f"{allowed} (this is "
                          f"{'a folder' if stat.S_ISDIR(st.st_mode) else 'not a regular file'})")
    if not os.access(env_path, os.X_OK):
        raise ConfigError(var, env, f"{allowed} (it is not executable: chmod +x it)")
    return env_path


def _probed(var: str, exe: Path, banner: str) -> Probe:
    """``exe`` (named by ``$var``) probed: one that cannot be started is a ConfigError
    naming ``var``; one that starts and fails, an EngineError (its own failure)."""
    p = probe(exe, banner)
    if not p.started:
        raise ConfigError(var, os.environ.get(var), f"an executable {banner} program that "
                          f"can be started ({p.message})")
    if not p.runs:
        raise EngineError(f"{var}={os.environ.get(var)} does not run: {p.message}")
    return p


@dataclass(frozen=True)
class Damaged:
    """wtftc's own install in the cache, damaged: ``where`` (a folder or its record) and
    what is wrong (:func:`wtftc.files.seal_damage`)."""

    where: Path
    why: str

    def message(self) -> str:
        return (f"wtftc's OpenFAST {VERSION} in WTFTC_CACHE is damaged: {self.where} "
                f"({self.why}); run `wtftc openfast get` to install it again")


def find(log: Callable[[str], None] = lambda s: None) -> Install | None:
    """OpenFAST 5.x already here (steps 1-3 of the module's order), or None. Refuses in one
    line a ``$OPENFAST`` or ``$TURBSIM`` that names no program (ConfigError), does not run
    (EngineError) or is another major version, and wtftc's own install when damaged."""
    found = _find(log)
    if isinstance(found, Damaged):
        raise EngineError(found.message())
    return found


def _find(log: Callable[[str], None]) -> Install | Damaged | None:
    exe = _named_program("OPENFAST", "OpenFAST")
    ts_env = _named_program("TURBSIM", "TurbSim")
    if exe is not None:
        p = _probed("OPENFAST", exe, "OpenFAST")
        if p.version and _major(p.version) != MAJOR:
            raise ConfigError("OPENFAST", os.environ["OPENFAST"], f"an OpenFAST {MAJOR}.x "
                              f"program (this one is OpenFAST {p.version}; unset OPENFAST "
                              f"to let wtftc get {VERSION})")
    if ts_env is not None:
        _probed("TURBSIM", ts_env, "TurbSim")
    if exe is not None:
        return Install(exe, ts_env or _turbsim_beside(exe, "$OPENFAST"),
                       p.version or f"{MAJOR}.x (not printed; taken as given by $OPENFAST)",
                       "$OPENFAST")
    on_path = shutil.which("openfast")
    if on_path:
        p = probe(Path(on_path))
        if p.runs and _major(p.version) == MAJOR:
            return Install(Path(on_path), ts_env or _turbsim_beside(Path(on_path), "PATH"),
                           p.version, "PATH")
        log(f"openfast on PATH ({on_path}) not used: "
            + (p.message if not p.runs else f"it is {p.version}" if p.version
               else "it does not print its version (set OPENFAST to use it)"))
    cached = _cached()
    return replace(cached, turbsim=ts_env) if ts_env and isinstance(cached, Install) else cached


def _turbsim_beside(exe: Path, how: str) -> Path:
    """The TurbSim beside ``exe``, else on PATH, that runs."""
    for cand in [exe.parent / "turbsim"] + \
            ([Path(w)] if (w := shutil.which("turbsim")) else []):
        if cand.is_file() and probe(cand, "TurbSim").runs:
            return cand
    raise EngineError(f"OpenFAST found by {how} ({exe}) but no TurbSim that runs: set "
                      "TURBSIM to its path, or put turbsim beside openfast")


def _record() -> Path:
    return home() / "install.json"


def _cached() -> Install | Damaged | None:
    """wtftc's own install (:func:`home`), when its record and its program folder match
    their seals and both programs run; Damaged where a seal does not hold. An install
    without seals (made by an earlier wtftc) whose programs run is sealed as it is."""
    rec = _record()
    if not os.path.lexists(rec):
        return None
    sealed = os.path.lexists(files.seal_path(rec))
    damage = files.seal_damage(rec) if sealed else None
    if damage:
        return Damaged(rec, damage)
    try:
        data = json.loads(rec.read_text())
        inst = Install(_in_home(data["openfast"], "openfast"),
                       _in_home(data["turbsim"], "turbsim"), str(data["version"]),
                       "cache: " + str(data["source"]))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        return Damaged(rec, f"not a record of wtftc's install ({type(exc).__name__})")
    folder = inst.openfast.parent.parent
    if inst.turbsim.parent.parent != folder:
        return Damaged(rec, "it names programs in two folders")
    legacy = not sealed and not files.seal_path(folder).exists()
    if not legacy and not sealed:
        return Damaged(rec, "no checksum recorded beside it")
    damage = None if legacy else files.seal_damage(folder)
    if damage:
        return Damaged(folder, damage)
    if not (probe(inst.openfast).runs and probe(inst.turbsim, "TurbSim").runs):
        return None
    if legacy:  # the programs run as they are: sealed now, checked from now on
        with contextlib.suppress(OSError):
            files.seal(folder)
            files.seal(rec)
    return inst


def _in_home(recorded, program: str) -> Path:
    """The program a record names, in :func:`home` (``prebuilt/bin/openfast``; an earlier
    wtftc recorded absolute paths: their last three parts, so that a cache copied
    elsewhere uses its own copy); a ValueError for any other path."""
    parts = Path(recorded).parts[-3:]
    if len(parts) != 3 or parts[0] not in ("prebuilt", "built") or parts[1:] != ("bin",
                                                                                program):
        raise ValueError(f"{recorded!r} is not where wtftc installs {program}")
    return home().joinpath(*parts)


def get(archives: Path | None = None, log: Callable[[str], None] = print,
        allow_build: bool = True) -> Install:
    """OpenFAST 5.0.0 and TurbSim, found or installed into :func:`home` (the module's
    order; a damaged install there is named in one line and installed again); raises
    EngineError, one line, when none can be had."""
    if home().is_dir():  # what a killed `get` left, once no process holds it
        for stem in (_UNPACK, _BUILD_TREE):
            clean_stale_builds(home(), stem)
    found = _find(log)
    if isinstance(found, Install):
        return found
    if isinstance(found, Damaged):
        log(f"wtftc: {found.where} in WTFTC_CACHE is damaged ({found.why}); installing "
            f"OpenFAST {VERSION} there again")
    writable_cache(home(), make=False)
    folders = archive_folders(archives)
    pre, bad = _archive(folders, *PREBUILT, log)
    why_not = []
    if pre is not None:
        inst = _from_prebuilt(pre, log)
        if isinstance(inst, Install):
            return _remember(inst)
        why_not.append(inst)
    else:
        why_not += bad or [f"no {PREBUILT[0]} in " + ", ".join(map(str, folders))]
    if not allow_build:
        raise EngineError("OpenFAST 5.0.0 not found and not installed: " + "; ".join(why_not))
    src, bad = _archive(folders, *SOURCE, log)
    if src is None and bad:
        raise EngineError(f"OpenFAST {VERSION} cannot be built: " + "; ".join(bad) + " (put "
                          f"the right {SOURCE[0]} there, or remove it to build from the "
                          "v5.0.0 tag)")
    log(f"building OpenFAST {VERSION} from {src or GIT_URL + ' (tag v5.0.0)'} "
        "(about 17 minutes on 2 cores): " + "; ".join(why_not))
    return _remember(_build(src, log))


def _archive(folders: list[Path], name: str, sha256: str,
             log: Callable[[str], None]) -> tuple[Path | None, list[str]]:
    """The first archive ``name`` in ``folders`` whose SHA-256 is ``sha256``, and what is
    wrong with each one passed over on the way (each said in one line as it is passed)."""
    bad: list[str] = []
    for f in folders:
        path = f / name
        if not os.path.lexists(path):
            continue
        if not path.is_file():
            why = f"{path} is not a regular file"
        else:
            try:
                digest = files.file_sha256(path)
            except OSError as exc:
                why = f"{path} cannot be read ({exc.strerror or type(exc).__name__})"
            else:
                if digest == sha256:
                    return path, bad
                why = (f"{path} is not the archive wtftc expects (SHA-256 {digest[:16]}..., "
                       f"expected {sha256[:16]}...): a damaged or other copy")
        bad.append(why)
        log(f"wtftc: {why}; looking further")
    return None, bad


def _unpack(archive: Path, into: Path) -> Path:
    """The archive unpacked into a fresh hidden folder beside ``into`` and renamed to it
    (no half-unpacked copy is ever at ``into``); its ``openfast-5.0.0/`` top folder's
    content. The folder holds a lock while in use, so that a killed ``get`` leaves
    nothing the next one does not remove."""
    into.parent.mkdir(parents=True, exist_ok=True)
    tmp, lock = new_build_folder(into.parent, _UNPACK)
    try:
        with tarfile.open(archive) as tar:
            tar.extractall(tmp, filter="data")
        top = tmp / f"openfast-{VERSION}"
        if not top.is_dir():
            raise EngineError(f"{archive} does not hold openfast-{VERSION}/")
        _discard(into)
        top.rename(into)
    except (tarfile.TarError, EOFError, OSError) as exc:
        if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT,
                                                      errno.EACCES, errno.EROFS):
            raise ConfigError("WTFTC_CACHE", str(cache_dir()), "a folder with room to "
                              f"install OpenFAST ({exc.strerror})") from None
        raise EngineError(f"{archive} cannot be unpacked ({_one_line(str(exc))})") from None
    finally:
        os.close(lock)
        shutil.rmtree(tmp, ignore_errors=True)
    return into


def _discard(folder: Path) -> None:
    """Remove wtftc's own earlier program folder in its cache, and its seal."""
    if folder.is_symlink() or folder.is_file():
        folder.unlink()
    elif folder.exists():
        shutil.rmtree(folder)
    with contextlib.suppress(FileNotFoundError):
        files.seal_path(folder).unlink()


def _from_prebuilt(archive: Path, log: Callable[[str], None]) -> Install | str:
    """The prebuilt binaries unpacked, sealed and checked; a reason (str) where they do
    not run."""
    dest = home() / "prebuilt"
    log(f"unpacking {archive} into {dest}")
    _unpack(archive, dest)
    files.seal(dest)
    exe, ts = dest / "bin" / "openfast", dest / "bin" / "turbsim"
    p = probe(exe)
    if p.missing_library:
        log(f"the prebuilt OpenFAST needs {p.missing_library}: installing "
            + " ".join(RUNTIME_PACKAGES) + " with apt")
        why = _apt(RUNTIME_PACKAGES)
        if why:
            raise EngineError(f"the prebuilt OpenFAST needs {p.missing_library} ({why}): "
                              "run `apt-get install -y " + " ".join(RUNTIME_PACKAGES)
                              + "` as root, then `make openfast` again")
        p = probe(exe)
    if not p.runs:
        return f"the prebuilt binary does not run here ({p.message})"
    if not probe(ts, "TurbSim").runs:
        return "the prebuilt TurbSim does not run here"
    return Install(exe, ts, VERSION, f"prebuilt archive {archive}")


def _apt(packages: tuple[str, ...]) -> str | None:
    """apt-get install ``packages``; None when done, else why not (one line)."""
    if not shutil.which("apt-get"):
        return "apt-get is not on this machine"
    if os.geteuid() != 0:
        return "apt-get needs root"
    cmd = ["apt-get", "install", "-y", "--no-install-recommends", *packages]
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    for attempt in (0, 1):
        done = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if done.returncode == 0:
            return None
        if attempt == 0:  # a fresh machine may have empty package lists
            subprocess.run(["apt-get", "update"], capture_output=True, env=env)
    last = [ln for ln in (done.stderr or done.stdout).splitlines() if ln.strip()]
    return f"apt-get install failed: {last[-1].strip() if last else done.returncode}"


def _build(src: Path | None, log: Callable[[str], None]) -> Install:
    """OpenFAST and TurbSim built from the source archive (or the v5.0.0 tag) in a hidden
    folder of :func:`home` (locked while in use, removed after) into :func:`home`
    ``/built``, sealed."""
    need = [t for t in ("gfortran", "cmake", "make") if not shutil.which(t)]
    if need:
        why = _apt(BUILD_PACKAGES)
        need = [t for t in ("gfortran", "cmake", "make") if not shutil.which(t)]
        if need:
            raise EngineError(f"building OpenFAST needs {', '.join(need)} and LAPACK ({why}):"
                              " apt-get install -y " + " ".join(BUILD_PACKAGES))
    dest = home() / "built"
    home().mkdir(parents=True, exist_ok=True)
    tree, lock = new_build_folder(home(), _BUILD_TREE)
    try:
        work = _source_tree(src, tree / f"openfast-{VERSION}")
        build = work / "build"
        build.mkdir(exist_ok=True)
        _compile(build, log)
        _discard(dest)
        (dest / "bin").mkdir(parents=True)
        exe, ts = dest / "bin" / "openfast", dest / "bin" / "turbsim"
        shutil.copy2(build / "glue-codes" / "openfast" / "openfast", exe)
        shutil.copy2(build / "modules" / "turbsim" / "turbsim", ts)
        files.seal(dest)
    finally:
        os.close(lock)
        shutil.rmtree(tree, ignore_errors=True)
    if not probe(exe).runs:
        raise EngineError(f"the OpenFAST just built does not run: {probe(exe).message}")
    return Install(exe, ts, VERSION, f"built from {src or GIT_URL}")


def _source_tree(src: Path | None, work: Path) -> Path:
    """OpenFAST's source at ``work``: the source archive unpacked, else the v5.0.0 tag
    cloned."""
    if src is not None:
        return _unpack(src, work)
    if not shutil.which("git"):
        raise EngineError("no OpenFAST source archive and no git to clone the v5.0.0 "
                          f"tag: put {SOURCE[0]} in $WTFTC_OPENFAST_ARCHIVES")
    done = subprocess.run(["git", "clone", "--depth", "1", "--branch", "v5.0.0",
                           GIT_URL, str(work)], capture_output=True, text=True)
    if done.returncode != 0:
        raise EngineError(f"cloning {GIT_URL} failed: {done.stderr.strip()[-200:]}")
    return work


def _compile(build: Path, log: Callable[[str], None]) -> None:
    """cmake and make in ``build``: openfast and turbsim."""
    for cmd in (["cmake", "..", *CMAKE_OPTIONS],
                ["make", f"-j{os.cpu_count() or 1}", "openfast", "turbsim"]):
        log("  " + " ".join(cmd))
        done = subprocess.run(cmd, cwd=build, capture_output=True, text=True,
                              errors="replace")
        if done.returncode != 0:
            tail = " ".join((done.stderr or done.stdout).strip().splitlines()[-3:])
            if "lapack" in tail.lower() or "blas" in tail.lower():
                tail += " (LAPACK missing: apt-get install -y liblapack-dev libblas-dev)"
            raise EngineError(f"building OpenFAST failed at `{' '.join(cmd)}`: {tail}")


def _remember(inst: Install) -> Install:
    """The record of wtftc's install (its programs' paths relative to :func:`home`, so
    that a cache copied elsewhere still finds them), written whole and sealed."""
    rec = {"openfast": str(inst.openfast.relative_to(home())),
           "turbsim": str(inst.turbsim.relative_to(home())),
           "version": inst.version, "source": inst.source}
    path = _record()
    try:
        files.write_files_together({path: (json.dumps(rec, indent=1) + "\n").encode()})
        files.seal(path)
    except OSError as exc:
        raise ConfigError("WTFTC_CACHE", str(cache_dir()), f"a folder where wtftc can write "
                          f"{path} ({exc.strerror or type(exc).__name__})") from None
    return inst


def require() -> Install:
    """OpenFAST for a run: found (never installed here), or one line saying how to get it
    (wtftc's own install damaged: which folder, and to run `wtftc openfast get`)."""
    inst = find()
    if inst is None:
        raise EngineError(f"OpenFAST {VERSION} is not installed: run `make openfast` in "
                          "wtftc's repository or `wtftc openfast get` (docs/openfast.md); "
                          "or set OPENFAST to an openfast 5.x")
    return inst
