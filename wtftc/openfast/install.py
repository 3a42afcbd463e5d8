"""Find or get OpenFAST 5.0.0 and TurbSim (issue 32, ``make openfast``, ``wtftc openfast get``).

The order, first found wins:

1. ``$OPENFAST`` (and ``$TURBSIM``, else the ``turbsim`` beside it or on PATH): the user
   names the program, so one that does not print its version is taken as given; one that
   prints another major version is refused;
2. ``openfast`` on PATH, if it says it is 5.x;
3. the copy wtftc installed before, in its cache folder (``$WTFTC_CACHE``, default
   ``~/.cache/wtftc``) under ``openfast/5.0.0/``, if it still runs;
4. the prebuilt archive (``openfast-5.0.0-linux-x86_64.tar.gz``, checked by its SHA-256)
   in an archive folder: ``--archives``, ``$WTFTC_OPENFAST_ARCHIVES``, the work area's
   ``shared/openfast/`` beside the repository, or ``/work/shared/openfast``. Its runtime
   libraries (gfortran's, LAPACK, BLAS) are installed with apt when missing and apt can;
5. a build from the source archive in the same folders (about 17 minutes on 2 cores), or
   from a shallow clone of the v5.0.0 tag for a user with internet.

Anything missing is said in one line (:class:`wtftc.errors.EngineError`) with the command
that gets it. The programs are never installed outside wtftc's cache folder; apt installs
system libraries only where the user runs as root (a CI machine, a container).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
import tarfile
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from wtftc.artefacts.loader import cache_dir
from wtftc.errors import EngineError

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
_PROBE_TIMEOUT_S = 60.0


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
    """Where the archives are looked for, in order."""
    folders = [extra] if extra is not None else []
    env = os.environ.get("WTFTC_OPENFAST_ARCHIVES")
    if env:
        folders.append(Path(env))
    repo = Path(__file__).resolve().parents[2]
    folders += [repo.parent / "shared" / "openfast", Path("/work/shared/openfast")]
    seen, out = set(), []
    for f in folders:
        key = str(f.resolve()) if f.exists() else str(f)
        if key not in seen:
            seen.add(key)
            out.append(f)
    return out


@dataclass(frozen=True)
class Probe:
    runs: bool
    version: str | None  # "5.0.0" as printed, None where it prints none
    missing_library: str | None  # "liblapack.so.3" when the loader cannot find it
    message: str  # the program's last words, one line, when it does not run


def probe(exe: Path, banner: str = "OpenFAST") -> Probe:
    """Run ``exe -v`` and read what it says: whether it runs, its version, a library the
    dynamic loader cannot find."""
    try:
        out = subprocess.run([str(exe), "-v"], capture_output=True, text=True,
                             timeout=_PROBE_TIMEOUT_S, stdin=subprocess.DEVNULL)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return Probe(False, None, None, str(exc))
    text = out.stdout + out.stderr
    lib = re.search(r"error while loading shared libraries: ([^:\s]+)", text)
    if lib:
        return Probe(False, None, lib.group(1), lib.group(0))
    if banner not in text:
        last = [line.strip() for line in text.splitlines() if line.strip()]
        return Probe(False, None, None, last[-1] if last else f"exit code {out.returncode}")
    ver = re.search(r"OpenFAST-v(\d+\.\d+\.\d+)", text) if banner == "OpenFAST" else None
    return Probe(True, ver.group(1) if ver else None, None, "")


def _major(version: str | None) -> int | None:
    return int(version.split(".")[0]) if version else None


def find(log: Callable[[str], None] = lambda s: None) -> Install | None:
    """OpenFAST 5.x already here (steps 1-3 of the module's order), or None. Refuses in one
    line a ``$OPENFAST`` that does not run or is another major version."""
    env = os.environ.get("OPENFAST")
    if env:
        exe = Path(env)
        p = probe(exe)
        if not p.runs:
            raise EngineError(f"OPENFAST={env} does not run: {p.message}")
        if p.version and _major(p.version) != MAJOR:
            raise EngineError(f"OPENFAST={env} is OpenFAST {p.version}; wtftc needs "
                              f"{MAJOR}.x (unset OPENFAST to let wtftc get {VERSION})")
        return Install(exe, _turbsim_beside(exe, "$OPENFAST"),
                       p.version or f"{MAJOR}.x (not printed; taken as given by $OPENFAST)",
                       "$OPENFAST")
    on_path = shutil.which("openfast")
    if on_path:
        p = probe(Path(on_path))
        if p.runs and _major(p.version) == MAJOR:
            return Install(Path(on_path), _turbsim_beside(Path(on_path), "PATH"),
                           p.version, "PATH")
        log(f"openfast on PATH ({on_path}) not used: "
            + (p.message if not p.runs else f"it is {p.version}" if p.version
               else "it does not print its version (set OPENFAST to use it)"))
    return _cached()


def _turbsim_beside(exe: Path, how: str) -> Path:
    env = os.environ.get("TURBSIM")
    for cand in ([Path(env)] if env else []) + [exe.parent / "turbsim"] + \
            ([Path(w)] if (w := shutil.which("turbsim")) else []):
        if cand.is_file() and probe(cand, "TurbSim").runs:
            return cand
    raise EngineError(f"OpenFAST found by {how} ({exe}) but no TurbSim that runs: set "
                      "TURBSIM to its path, or put turbsim beside openfast")


def _record() -> Path:
    return home() / "install.json"


def _cached() -> Install | None:
    try:
        rec = json.loads(_record().read_text())
        inst = Install(Path(rec["openfast"]), Path(rec["turbsim"]), rec["version"],
                       "cache: " + rec["source"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if probe(inst.openfast).runs and probe(inst.turbsim, "TurbSim").runs:
        return inst
    return None


def get(archives: Path | None = None, log: Callable[[str], None] = print,
        allow_build: bool = True) -> Install:
    """OpenFAST 5.0.0 and TurbSim, found or installed into :func:`home` (the module's
    order); raises EngineError, one line, when none can be had."""
    found = find(log)
    if found is not None:
        return found
    folders = archive_folders(archives)
    pre = _archive(folders, *PREBUILT)
    why_not = []
    if pre is not None:
        inst = _from_prebuilt(pre, log)
        if isinstance(inst, Install):
            return _remember(inst)
        why_not.append(inst)
    else:
        why_not.append(f"no {PREBUILT[0]} in " + ", ".join(map(str, folders)))
    if not allow_build:
        raise EngineError("OpenFAST 5.0.0 not found and not installed: " + "; ".join(why_not))
    src = _archive(folders, *SOURCE)
    log(f"building OpenFAST {VERSION} from {src or GIT_URL + ' (tag v5.0.0)'} "
        "(about 17 minutes on 2 cores): " + "; ".join(why_not))
    return _remember(_build(src, log))


def _archive(folders: list[Path], name: str, sha256: str) -> Path | None:
    for f in folders:
        path = f / name
        if path.is_file():
            digest = hashlib.sha256(path.read_bytes()).hexdigest()
            if digest == sha256:
                return path
            raise EngineError(f"{path} is not the archive wtftc expects (SHA-256 {digest[:16]}"
                              f"..., expected {sha256[:16]}...): a damaged or other copy")
    return None


def _unpack(archive: Path, into: Path) -> Path:
    """The archive unpacked into a fresh folder beside ``into`` and renamed to it (no
    half-unpacked copy is ever at ``into``); its ``openfast-5.0.0/`` top folder's content."""
    into.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".unpack-", dir=into.parent))
    try:
        with tarfile.open(archive) as tar:
            tar.extractall(tmp, filter="data")
        top = tmp / f"openfast-{VERSION}"
        if not top.is_dir():
            raise EngineError(f"{archive} does not hold openfast-{VERSION}/")
        if into.exists():
            shutil.rmtree(into)  # wtftc's own earlier copy (in its cache), unusable
        top.rename(into)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return into


def _from_prebuilt(archive: Path, log: Callable[[str], None]) -> Install | str:
    """The prebuilt binaries unpacked and checked; a reason (str) where they do not run."""
    dest = home() / "prebuilt"
    log(f"unpacking {archive} into {dest}")
    _unpack(archive, dest)
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
    """OpenFAST and TurbSim built from the source archive (or the v5.0.0 tag) into
    :func:`home` ``/built``."""
    need = [t for t in ("gfortran", "cmake", "make") if not shutil.which(t)]
    if need:
        why = _apt(BUILD_PACKAGES)
        need = [t for t in ("gfortran", "cmake", "make") if not shutil.which(t)]
        if need:
            raise EngineError(f"building OpenFAST needs {', '.join(need)} and LAPACK ({why}):"
                              " apt-get install -y " + " ".join(BUILD_PACKAGES))
    dest = home() / "built"
    work = home() / "build-tree"
    if work.exists():
        shutil.rmtree(work)
    if src is not None:
        _unpack(src, work)
    else:
        if not shutil.which("git"):
            raise EngineError("no OpenFAST source archive and no git to clone the v5.0.0 "
                              f"tag: put {SOURCE[0]} in $WTFTC_OPENFAST_ARCHIVES")
        done = subprocess.run(["git", "clone", "--depth", "1", "--branch", "v5.0.0",
                               GIT_URL, str(work)], capture_output=True, text=True)
        if done.returncode != 0:
            raise EngineError(f"cloning {GIT_URL} failed: {done.stderr.strip()[-200:]}")
    build = work / "build"
    build.mkdir(exist_ok=True)
    for cmd in (["cmake", "..", *CMAKE_OPTIONS],
                ["make", f"-j{os.cpu_count() or 1}", "openfast", "turbsim"]):
        log("  " + " ".join(cmd))
        done = subprocess.run(cmd, cwd=build, capture_output=True, text=True)
        if done.returncode != 0:
            tail = " ".join((done.stderr or done.stdout).strip().splitlines()[-3:])
            if "lapack" in tail.lower() or "blas" in tail.lower():
                tail += " (LAPACK missing: apt-get install -y liblapack-dev libblas-dev)"
            raise EngineError(f"building OpenFAST failed at `{' '.join(cmd)}`: {tail}")
    (dest / "bin").mkdir(parents=True, exist_ok=True)
    exe, ts = dest / "bin" / "openfast", dest / "bin" / "turbsim"
    shutil.copy2(build / "glue-codes" / "openfast" / "openfast", exe)
    shutil.copy2(build / "modules" / "turbsim" / "turbsim", ts)
    shutil.rmtree(work, ignore_errors=True)
    if not probe(exe).runs:
        raise EngineError(f"the OpenFAST just built does not run: {probe(exe).message}")
    return Install(exe, ts, VERSION, f"built from {src or GIT_URL}")


def _remember(inst: Install) -> Install:
    rec = {k: str(v) for k, v in asdict(inst).items()}
    path = _record()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(rec, indent=1) + "\n")
    os.replace(tmp, path)
    return inst


def require() -> Install:
    """OpenFAST for a run: found (never installed here), or one line saying how to get it."""
    inst = find()
    if inst is None:
        raise EngineError(f"OpenFAST {VERSION} is not installed: run `make openfast` in "
                          "wtftc's repository or `wtftc openfast get` (docs/openfast.md); "
                          "or set OPENFAST to an openfast 5.x")
    return inst
