"""One integrity rule for what wtftc caches for the OpenFAST engine, and what its users
name: WTFTC_CACHE, the folders built once into it (the controller and plant libraries,
linearizations), wtftc's own OpenFAST install there, and OPENFAST, TURBSIM and
WTFTC_OPENFAST_ARCHIVES.

* WTFTC_CACHE is made absolute and checked for what OpenFAST reads: a path in a line of
  its input files is cut at 256 characters (ParseChVar's words, NWTC_IO.f90) and ends at a
  '!', '#' or '%' even inside quotes; anything else unusable is one line naming
  WTFTC_CACHE, exit code 2;
* an entry is sealed (size and sha256 of each file) when built and checked when taken: a
  damaged one is rebuilt once, with one line naming it; what wtftc did not write is moved
  aside, never deleted; the temporary folders of killed builds are removed on next use;
* the same for wtftc's OpenFAST install: damaged, `require` names the folder and `wtftc
  openfast get`, which installs it again with one line;
* a variable that names nothing usable is refused in one line naming it (exit code 2); a
  program that starts and fails is exit code 4; a damaged archive followed by a valid one
  is passed over with a line.

Every test that damages a cache uses a private WTFTC_CACHE (tmp_path): the shared cache at
~/.cache/wtftc is only read (its OpenFAST runs the end-to-end cases).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest

from wtftc import files
from wtftc.artefacts import loader
from wtftc.cli import main
from wtftc.errors import ConfigError, EngineError
from wtftc.openfast import install

LIB = bytes(range(256)) * 40  # what the fake build writes: 10 kB of known bytes
ENTRY = "lib-0123456789abcdef0123"


def _make(calls: list):
    """A build of a library folder: ``lib.so`` and a source in a subfolder."""
    def make(tmp: Path) -> None:
        calls.append(tmp)
        (tmp / "lib.so").write_bytes(LIB)
        (tmp / "src").mkdir()
        (tmp / "src" / "lib.c").write_text("int lib;\n")
    return make


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


# ------------------------------------------------------------------ WTFTC_CACHE's values

def _file(tmp: Path) -> str:
    (tmp / "afile").write_text("mine\n")
    return str(tmp / "afile")


def _fifo(tmp: Path) -> str:
    os.mkfifo(tmp / "fifo")
    return str(tmp / "fifo")


def _dangling(tmp: Path) -> str:
    (tmp / "dangling").symlink_to(tmp / "nowhere")
    return str(tmp / "dangling")


def _loop(tmp: Path) -> str:
    (tmp / "loop").symlink_to(tmp / "loop")
    return str(tmp / "loop")


def _sized(tmp: Path, n: int, fill: str = "x") -> str:
    """An absolute path of exactly ``n`` bytes under ``tmp``."""
    base = str(tmp / "c") + os.sep
    k = (n - len(os.fsencode(base))) // len(fill.encode())
    path = base + fill * k
    path += "x" * (n - len(os.fsencode(path)))
    assert len(os.fsencode(path)) == n
    return path


#: (id, WTFTC_CACHE from tmp_path, what the refusal says: a regex)
REFUSED_CACHES = [
    ("empty", lambda t: "", r"a folder path \(unset WTFTC_CACHE"),
    ("blank", lambda t: "   ", r"a folder path \(unset WTFTC_CACHE"),
    ("a_file", _file, r"afile is a file"),
    ("under_a_file", lambda t: _file(t) + "/cache", r"afile is a file"),
    ("deep_under_a_file", lambda t: _file(t) + "/a/b/c", r"afile is a file"),
    ("a_fifo", _fifo, r"fifo is not a folder"),
    ("dev_null", lambda t: "/dev/null", r"/dev/null is not a folder"),
    ("under_dev_null", lambda t: "/dev/null/cache", r"/dev/null is not a folder"),
    ("proc", lambda t: "/proc/wtftc-cache", r"a folder that can be written"),
    ("dangling_link", _dangling, r"dangling is a symbolic link that leads nowhere"),
    ("link_loop", _loop, r"loop is a symbolic link that leads nowhere"),
    ("longer_than_openfast_reads", lambda t: _sized(t, loader.MAX_CACHE_CHARS + 1),
     rf"at most {loader.MAX_CACHE_CHARS} bytes \(this one has {loader.MAX_CACHE_CHARS + 1}\)"),
    ("multibyte_too_long", lambda t: _sized(t, loader.MAX_CACHE_CHARS + 2, "é"),  # fewer
     rf"this one has {loader.MAX_CACHE_CHARS + 2}"),                               # letters
    ("far_too_long", lambda t: str(t) + "/" + "y" * 1100, r"OpenFAST cuts a path"),
    ("hash", lambda t: str(t / "my#cache"), r"without '#'"),
    ("bang", lambda t: str(t / "my!cache"), r"without '!'"),
    ("percent", lambda t: str(t / "50%"), r"without '%'"),
    ("double_quote", lambda t: str(t / 'a"b'), r"""without '"'"""),
    ("single_quote", lambda t: str(t / "a'b"), r"""without "'\""""),
    ("newline", lambda t: str(t / "a\nb"), r"without '\\n'"),
    ("carriage_return", lambda t: str(t / "a\rb"), r"without '\\r'"),
    ("several_marks", lambda t: str(t / "#a!b%"), r"without '!' '#' '%'"),
]


@pytest.mark.parametrize("value, says", [r[1:] for r in REFUSED_CACHES],
                         ids=[r[0] for r in REFUSED_CACHES])
def test_an_unusable_wtftc_cache_is_one_line_naming_it(tmp_path, monkeypatch, value, says):
    given = value(tmp_path)
    monkeypatch.setenv("WTFTC_CACHE", given)
    before = sorted(p.name for p in tmp_path.iterdir())
    calls = []
    with pytest.raises(ConfigError) as caught:
        loader.built_once(loader.cache_dir() / ENTRY, "lib.so", _make(calls))
    message = str(caught.value)
    assert caught.value.field == "WTFTC_CACHE" and "\n" not in message
    assert re.search(says, message), message
    assert "[Errno" not in message and f".{ENTRY}-" not in message
    assert not calls and sorted(p.name for p in tmp_path.iterdir()) == before
    if (tmp_path / "afile").exists():
        assert (tmp_path / "afile").read_text() == "mine\n"


@pytest.mark.parametrize("value", ["", "   ", "afile", "afile/cache", "fifo", "/dev/null"])
def test_an_unusable_wtftc_cache_makes_openfast_get_exit_2(tmp_path, monkeypatch, capsys,
                                                          value):
    """`wtftc openfast get` names WTFTC_CACHE, exit code 2, no Errno text, nothing made."""
    monkeypatch.chdir(tmp_path)
    _file(tmp_path)
    _fifo(tmp_path)
    monkeypatch.setenv("WTFTC_CACHE", value)
    monkeypatch.delenv("OPENFAST", raising=False)
    monkeypatch.delenv("TURBSIM", raising=False)
    monkeypatch.setenv("PATH", "/usr/bin:/bin")
    code = main(["openfast", "get", "--no-build"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "WTFTC_CACHE" in err, err
    assert "[Errno" not in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "fifo"]


#: (id, WTFTC_CACHE from tmp_path (run in tmp_path), the folder it means)
ACCEPTED_CACHES = [
    ("relative", lambda t: "rel/cache", lambda t: t / "rel" / "cache"),
    ("dot_relative", lambda t: "./c", lambda t: t / "c"),
    ("dotdot", lambda t: "a/../b", lambda t: t / "b"),
    ("tilde", lambda t: "~/c", lambda t: t / "home" / "c"),
    ("trailing_slash", lambda t: str(t / "c") + "/", lambda t: t / "c"),
    ("space", lambda t: str(t / "my cache"), lambda t: t / "my cache"),
    ("non_ascii", lambda t: str(t / "cachée"), lambda t: t / "cachée"),
    ("a_link_to_a_folder", lambda t: (t / "real").mkdir() or (t / "ln").symlink_to(
        t / "real") or str(t / "ln"), lambda t: t / "ln"),
    ("exactly_the_longest", lambda t: _sized(t, loader.MAX_CACHE_CHARS),
     lambda t: Path(_sized(t, loader.MAX_CACHE_CHARS))),
]


@pytest.mark.parametrize("value, means", [r[1:] for r in ACCEPTED_CACHES],
                         ids=[r[0] for r in ACCEPTED_CACHES])
def test_a_usable_wtftc_cache_is_made_absolute(tmp_path, monkeypatch, value, means):
    (tmp_path / "home").mkdir()
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("WTFTC_CACHE", value(tmp_path))
    folder = loader.cache_dir()
    assert folder.is_absolute() and folder == means(tmp_path)
    calls = []
    out = loader.built_once(folder / ENTRY, "lib.so", _make(calls))
    assert out.is_absolute() and out.read_bytes() == LIB and len(calls) == 1
    assert files.seal_damage(folder / ENTRY) is None


def test_a_relative_cache_whose_folder_is_gone_is_one_line(tmp_path, monkeypatch):
    gone = tmp_path / "gone"
    gone.mkdir()
    monkeypatch.chdir(gone)
    gone.rmdir()
    monkeypatch.setenv("WTFTC_CACHE", "cache")
    with pytest.raises(ConfigError, match="WTFTC_CACHE = 'cache' .* current folder cannot be"):
        loader.cache_dir()


def test_an_unset_cache_is_the_default_and_named_as_such(tmp_path, monkeypatch):
    monkeypatch.delenv("WTFTC_CACHE", raising=False)
    monkeypatch.setenv("HOME", str(_file(tmp_path)))  # ~/.cache/wtftc under a file
    assert loader.cache_dir() == tmp_path / "afile" / ".cache" / "wtftc"
    with pytest.raises(ConfigError, match="WTFTC_CACHE is unset and this is its default"):
        loader.built_once(loader.cache_dir() / ENTRY, "lib.so", _make([]))


# ------------------------------------------------------------------ damaged entries

def _flip(path: Path, at: int | None = None) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2 if at is None else at] ^= 0x01
    path.write_bytes(bytes(data))


def _mine(entry: Path, rel: str) -> Path:
    """A file of the user's in the entry (to be moved aside with it, never deleted)."""
    (entry / rel).parent.mkdir(parents=True, exist_ok=True)
    (entry / rel).write_text("the user's\n")
    return Path(rel)


#: (id, damage(entry) -> a path of the user's inside it, or None; moved aside or deleted)
DAMAGES = [
    ("truncated", lambda e: (e / "lib.so").write_bytes(LIB[:100]) and None, False),
    ("emptied", lambda e: (e / "lib.so").write_bytes(b"") and None, False),
    ("one_bit_flipped", lambda e: _flip(e / "lib.so"), False),
    ("first_byte_flipped", lambda e: _flip(e / "lib.so", 0), False),
    ("source_changed", lambda e: (e / "src" / "lib.c").write_text("int lib; \n") and None,
     False),
    ("library_removed", lambda e: (e / "lib.so").unlink(), False),
    ("source_removed", lambda e: (e / "src" / "lib.c").unlink(), False),
    ("subfolder_removed", lambda e: shutil.rmtree(e / "src"), False),
    ("all_emptied", lambda e: [shutil.rmtree(e), e.mkdir()] and None, False),
    ("seal_removed", lambda e: files.seal_path(e).unlink(), False),
    ("seal_garbage", lambda e: files.seal_path(e).write_bytes(b"\xff\x00garbage") and None,
     False),
    ("seal_a_list", lambda e: files.seal_path(e).write_text("[]") and None, False),
    ("seal_lists_more", lambda e: files.seal_path(e).write_text(json.dumps(
        {**json.loads(files.seal_path(e).read_text()), "other.so": "1 00"})) and None, False),
    ("seal_a_folder", lambda e: [files.seal_path(e).unlink(), files.seal_path(e).mkdir()]
     and None, False),
    ("file_added", lambda e: _mine(e, "notes.txt"), True),
    ("file_added_deep", lambda e: _mine(e, "src/extra/notes.txt"), True),
    ("folder_added", lambda e: (e / "mine").mkdir() or Path("mine"), True),
    ("library_now_a_link", lambda e: [(e / "lib.so").unlink(), (e / "lib.so").symlink_to(
        "/bin/sh")] and None, True),
    ("library_now_a_folder", lambda e: [(e / "lib.so").unlink(), (e / "lib.so").mkdir()]
     and None, True),
    ("fifo_added", lambda e: os.mkfifo(e / "pipe"), True),
    ("entry_now_a_file", lambda e: [shutil.rmtree(e), e.write_text("the user's\n")]
     and None, True),
    ("entry_now_a_link", lambda e: [os.rename(e, e.with_name("elsewhere")),
                                    e.symlink_to(e.with_name("elsewhere"))] and None, True),
]


@pytest.mark.parametrize("damage, moved", [r[1:] for r in DAMAGES], ids=[r[0] for r in DAMAGES])
def test_a_damaged_entry_is_rebuilt_once_with_one_line(cache, capsys, damage, moved):
    calls = []
    entry = loader.cache_dir() / ENTRY
    out = loader.built_once(entry, "lib.so", _make(calls))
    capsys.readouterr()
    users = damage(entry)
    assert loader.built_once(entry, "lib.so", _make(calls)) == out
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and f"{entry} in WTFTC_CACHE is damaged (" in err[0], err
    assert len(calls) == 2 and out.read_bytes() == LIB and files.seal_damage(entry) is None
    aside = sorted(cache.glob(f"{ENTRY}.moved-*"))
    assert bool(aside) == moved and ("moved it aside to" in err[0]) == moved, err
    if moved:  # kept whole where the line says
        assert str(aside[0]) in err[0]
        assert os.path.lexists(aside[0] / ENTRY)
        if isinstance(users, Path):
            kept = aside[0] / ENTRY / users
            assert kept.is_dir() or kept.read_text() == "the user's\n"
    else:
        assert "deleting it and rebuilding" in err[0]
    assert loader.built_once(entry, "lib.so", _make(calls)) == out  # then taken quietly
    assert capsys.readouterr().err == "" and len(calls) == 2
    assert _hidden(cache) == []  # no temporary folder left


def test_a_damaged_entry_that_cannot_be_removed_says_what_to_delete(cache, monkeypatch):
    entry = loader.cache_dir() / ENTRY
    loader.built_once(entry, "lib.so", _make([]))
    _flip(entry / "lib.so")
    monkeypatch.setattr(loader, "_clear", lambda folder: None)  # a read-only cache (root
    with pytest.raises(ConfigError) as caught:                    # writes anyway)
        loader.built_once(entry, "lib.so", _make([]))
    assert f"{entry} is damaged (lib.so: sha256" in str(caught.value)
    assert "delete it" in str(caught.value) and caught.value.field == "WTFTC_CACHE"


def test_two_processes_taking_a_damaged_entry_at_once_rebuild_it_once(cache):
    entry = loader.cache_dir() / ENTRY
    loader.built_once(entry, "lib.so", _make([]))
    _flip(entry / "lib.so")
    code = ("import sys, time\nfrom pathlib import Path\nfrom wtftc.artefacts import loader\n"
            "def make(t):\n time.sleep(0.5); (t / 'lib.so').write_bytes(bytes(range(256)) * 40)"
            "\nprint(loader.built_once(Path(sys.argv[1]), 'lib.so', make))")
    procs = [subprocess.Popen([sys.executable, "-c", code, str(entry)], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outs = [p.communicate(timeout=120) for p in procs]
    assert all(p.returncode == 0 for p in procs), outs
    lines = [line for _, err in outs for line in err.splitlines()]
    assert len(lines) == 1 and "is damaged" in lines[0], lines
    assert files.seal_damage(entry) is None and (entry / "lib.so").read_bytes() == LIB
    assert _hidden(cache) == []


# ------------------------------------------------------------- killed builds' folders

def _killed_build(cache: Path) -> Path:
    """A build killed with SIGKILL in the middle: its temporary folder stays."""
    code = ("import sys, time\nfrom pathlib import Path\nfrom wtftc.artefacts import loader\n"
            "def make(t):\n (t / 'half').write_text('x'); print(t, flush=True); time.sleep(60)"
            "\nloader.built_once(Path(sys.argv[1]), 'lib.so', make)")
    proc = subprocess.Popen([sys.executable, "-c", code, str(cache / ENTRY)],
                            stdout=subprocess.PIPE, text=True)
    tmp = Path(proc.stdout.readline().strip())
    proc.kill()
    proc.wait()
    proc.stdout.close()
    assert tmp.is_dir() and tmp.name.startswith(f".{ENTRY}-")
    return tmp


def test_a_killed_builds_folder_is_removed_on_next_use(cache):
    tmp = _killed_build(cache)
    out = loader.built_once(cache / ENTRY, "lib.so", _make([]))
    assert not tmp.exists() and out.read_bytes() == LIB and _hidden(cache) == []


def test_a_live_builds_folder_is_left_alone(cache):
    """A build in another process holds its lock: its folder is kept while it runs."""
    code = ("import sys\nfrom pathlib import Path\nfrom wtftc.artefacts import loader\n"
            "def make(t):\n print(t, flush=True); sys.stdin.readline(); "
            "(t / 'lib.so').write_bytes(b'other')"
            "\nprint(loader.built_once(Path(sys.argv[1]), 'lib.so', make), flush=True)")
    proc = subprocess.Popen([sys.executable, "-c", code, str(cache / "other-1")],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    live = Path(proc.stdout.readline().strip())
    (cache / f".{'other-1'}-stale").mkdir()  # no lock, fresh: left too
    loader.built_once(cache / "other-0", "lib.so", _make([]))  # another entry
    loader.clean_stale_builds(cache, "other-1")
    assert live.is_dir() and (cache / ".other-1-stale").is_dir()
    proc.stdin.write("go\n")
    proc.stdin.close()
    assert proc.stdout.readline().strip() == str(cache / "other-1" / "lib.so")
    assert proc.wait(timeout=60) == 0 and not live.exists()


#: (id, what is put in the cache beside the entry, whether the next use removes it)
LEFTOVERS = [
    ("unlocked_old", lambda c: _aged(c / f".{ENTRY}-old", 2 * loader.STALE_UNLOCKED_S), True),
    ("unlocked_fresh", lambda c: _aged(c / f".{ENTRY}-new", 0), False),
    ("lock_not_held", lambda c: _locked_folder(c / f".{ENTRY}-dead"), True),
    ("a_file_named_so", lambda c: _written(c / f".{ENTRY}-file"), False),
    ("a_link_named_so", lambda c: (c / f".{ENTRY}-link").symlink_to(_aged(
        c / "target", 2 * loader.STALE_UNLOCKED_S)) or c / f".{ENTRY}-link", False),
    ("another_entrys", lambda c: _locked_folder(c / ".other-1-dead"), False),
]


def _written(path: Path) -> Path:
    path.write_text("x")
    return path


def _aged(folder: Path, age_s: float) -> Path:
    folder.mkdir()
    (folder / "half").write_text("x")
    then = time.time() - age_s
    os.utime(folder, (then, then))
    return folder


def _locked_folder(folder: Path) -> Path:
    folder.mkdir()
    (folder / loader.BUILD_LOCK).write_text("")
    return folder


@pytest.mark.parametrize("put, removed", [r[1:] for r in LEFTOVERS],
                         ids=[r[0] for r in LEFTOVERS])
def test_leftovers_beside_an_entry(cache, put, removed):
    cache.mkdir()
    left = put(cache)
    loader.built_once(cache / ENTRY, "lib.so", _make([]))
    assert os.path.lexists(left) != removed
    if left.is_symlink():
        assert (cache / "target" / "half").read_text() == "x"  # never followed


# --------------------------------------------------- what a build's failures are named by

#: (id, a failing make(tmp), the error's type, what its message must say)
FAILING_MAKES = [
    ("config_error_naming_tmp", lambda t: _raise(ConfigError("--cc", "gcc", f"{t}/x.c:1: "
                                                               "error")), ConfigError, "/x.c:1"),
    ("engine_error_naming_tmp", lambda t: _raise(EngineError(f"{t}/lin.json missing")),
     EngineError, "lin.json missing"),
    ("disk_full", lambda t: _raise(OSError(28, "No space left on device", str(t / "a.so"))),
     ConfigError, "No space left on device"),
    ("writes_nothing", lambda t: None, EngineError, "made no lib.so"),
    ("writes_a_folder", lambda t: (t / "lib.so").mkdir(), EngineError, "made no lib.so"),
]


def _raise(exc: Exception):
    raise exc


@pytest.mark.parametrize("make, kind, says", [r[1:] for r in FAILING_MAKES],
                         ids=[r[0] for r in FAILING_MAKES])
def test_a_failing_build_names_the_entry_never_its_deleted_temporary(cache, make, kind, says):
    entry = loader.cache_dir() / ENTRY
    with pytest.raises(kind) as caught:
        loader.built_once(entry, "lib.so", make)
    assert type(caught.value) is kind and says in str(caught.value)
    assert f".{ENTRY}-" not in str(caught.value) and "\n" not in str(caught.value)
    assert not entry.exists() and _hidden(cache) == []


def test_an_interrupted_build_leaves_nothing(cache):
    with pytest.raises(KeyboardInterrupt):
        loader.built_once(cache / ENTRY, "lib.so", lambda t: _raise(KeyboardInterrupt()))
    assert sorted(cache.iterdir()) == []


def test_an_unwritable_compile_cache_names_the_folder_never_a_temporary_file(tmp_path,
                                                                            monkeypatch):
    monkeypatch.setenv("WTFTC_CACHE", _file(tmp_path) + "/cache")
    with pytest.raises(loader.CompileError) as caught:
        loader.compile_cached(loader.verified_path("plant.c"), loader.compiler())
    message = str(caught.value)
    assert "WTFTC_CACHE=" in message and "afile is a file" in message
    assert ".building-" not in message and "[Errno" not in message


# ------------------------------------------------------------ wtftc's OpenFAST install

@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """OpenFAST installed from the prebuilt archive into a private cache, as `wtftc openfast
    get` does on a fresh machine (the archive folders: shared/openfast beside the
    repository, /work/shared/openfast); copied for each test that damages it."""
    root = tmp_path_factory.mktemp("installed")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("WTFTC_CACHE", str(root / "cache"))
        for var in ("OPENFAST", "TURBSIM", "WTFTC_OPENFAST_ARCHIVES"):
            mp.delenv(var, raising=False)
        mp.setenv("PATH", "/usr/bin:/bin")
        install.get(log=lambda s: None, allow_build=False)
    return root / "cache"


@pytest.fixture
def fresh(installed, tmp_path, monkeypatch):
    """A copy of the installed cache, private to the test: its home()."""
    shutil.copytree(installed, tmp_path / "cache", symlinks=True)
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path / "cache"))
    for var in ("OPENFAST", "TURBSIM", "WTFTC_OPENFAST_ARCHIVES"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("PATH", "/usr/bin:/bin")
    return install.home()


def _reseal(path: Path, text: str) -> None:
    path.write_text(text)
    files.seal(path)


#: (id, damage(home) done to the install, the part named: "prebuilt" or "install.json")
INSTALL_DAMAGES = [
    ("openfast_flipped", lambda h: _flip(h / "prebuilt" / "bin" / "openfast"), "prebuilt"),
    ("openfast_truncated", lambda h: os.truncate(h / "prebuilt" / "bin" / "openfast", 4096),
     "prebuilt"),
    ("turbsim_flipped", lambda h: _flip(h / "prebuilt" / "bin" / "turbsim"), "prebuilt"),
    ("turbsim_removed", lambda h: (h / "prebuilt" / "bin" / "turbsim").unlink(), "prebuilt"),
    ("license_removed", lambda h: (h / "prebuilt" / "LICENSE").unlink(), "prebuilt"),
    ("file_added", lambda h: (h / "prebuilt" / "bin" / "extra").write_text("x"), "prebuilt"),
    ("openfast_a_link", lambda h: [(h / "prebuilt" / "bin" / "openfast").unlink(),
                                   (h / "prebuilt" / "bin" / "openfast").symlink_to("/bin/true")],
     "prebuilt"),
    ("folder_removed", lambda h: shutil.rmtree(h / "prebuilt"), "prebuilt"),
    ("folder_seal_removed", lambda h: files.seal_path(h / "prebuilt").unlink(), "prebuilt"),
    ("folder_seal_garbage", lambda h: files.seal_path(h / "prebuilt").write_text("{"),
     "prebuilt"),
    ("record_edited", lambda h: (h / "install.json").write_text(
        (h / "install.json").read_text().replace("5.0.0", "5.0.1")), "install.json"),
    ("record_seal_removed", lambda h: files.seal_path(h / "install.json").unlink(),
     "install.json"),
    ("record_garbage_resealed", lambda h: _reseal(h / "install.json", "\x00\xff not json"),
     "install.json"),
    ("record_names_bin_sh", lambda h: _reseal(h / "install.json", json.dumps(
        {"openfast": "/bin/sh", "turbsim": "/bin/sh", "version": "5.0.0", "source": "x"})),
     "install.json"),
    ("record_a_list", lambda h: _reseal(h / "install.json", "[]"), "install.json"),
    ("record_now_a_folder", lambda h: [(h / "install.json").unlink(),
                                       (h / "install.json").mkdir()], "install.json"),
]


@pytest.mark.parametrize("damage, part", [r[1:] for r in INSTALL_DAMAGES],
                         ids=[r[0] for r in INSTALL_DAMAGES])
def test_a_damaged_install_is_named_with_wtftc_openfast_get(fresh, capsys, damage, part):
    damage(fresh)
    with pytest.raises(EngineError) as caught:
        install.require()
    message = str(caught.value)
    assert f"{fresh / part} (" in message and "run `wtftc openfast get`" in message, message
    assert "WTFTC_CACHE" in message and "\n" not in message
    assert main(["openfast", "where"]) == 4
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is damaged" in err and "Traceback" not in err


@pytest.mark.parametrize("damage", ["openfast_flipped", "folder_seal_removed",
                                    "record_garbage_resealed", "folder_removed"])
def test_openfast_get_installs_a_damaged_install_again_with_one_line(fresh, damage):
    dict((r[0], r[1]) for r in INSTALL_DAMAGES)[damage](fresh)
    said = []
    inst = install.get(log=said.append, allow_build=False)
    damaged = [line for line in said if "is damaged" in line]
    assert len(damaged) == 1 and "WTFTC_CACHE" in damaged[0], said
    assert inst.openfast == fresh / "prebuilt" / "bin" / "openfast"
    assert install.require().openfast == inst.openfast  # sealed again: taken
    assert files.seal_damage(fresh / "prebuilt") is None
    assert files.seal_damage(fresh / "install.json") is None
    assert install.get(log=said.append) == install.require()  # found, nothing said again
    assert [line for line in said if "is damaged" in line] == damaged


def test_an_install_of_an_earlier_wtftc_without_seals_is_sealed_as_it_runs(fresh):
    """Installed before seals existed, with absolute paths in its record: taken when both
    programs run, and sealed from then on."""
    rec = json.loads((fresh / "install.json").read_text())
    rec = {**rec, "openfast": "/somewhere/else/openfast/5.0.0/prebuilt/bin/openfast",
           "turbsim": "/somewhere/else/openfast/5.0.0/prebuilt/bin/turbsim"}
    (fresh / "install.json").write_text(json.dumps(rec))
    for p in (fresh / "install.json", fresh / "prebuilt"):
        files.seal_path(p).unlink()
    inst = install.require()
    assert inst.openfast == fresh / "prebuilt" / "bin" / "openfast"
    assert files.seal_damage(fresh / "prebuilt") is None
    _flip(fresh / "prebuilt" / "bin" / "turbsim")
    with pytest.raises(EngineError, match="is damaged"):
        install.require()


def test_openfast_get_removes_what_a_killed_get_left(fresh):
    dead = _locked_folder(fresh / ".unpack-killed")
    tree = _locked_folder(fresh / ".build-tree-killed")
    (tree / "openfast-5.0.0").mkdir()
    install.get(log=lambda s: None, allow_build=False)
    assert not dead.exists() and not tree.exists()


def test_a_turbsim_named_by_the_user_is_taken_over_the_installed_one(fresh, tmp_path,
                                                                     monkeypatch):
    ts = _fake(tmp_path / "mine", "turbsim", "TurbSim")
    monkeypatch.setenv("TURBSIM", str(ts))
    assert install.require().turbsim == ts


# ---------------------------------------------- OPENFAST, TURBSIM: what the user names

def _fake(folder: Path, name: str, banner: str = "OpenFAST-v5.0.0", body: str = "") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    exe = folder / name
    exe.write_text(f"#!/bin/sh\n{body or f'echo {banner!r}'}\n")
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    return exe


def _pair(folder: Path, body: str = "", banner: str = "OpenFAST-v5.0.0") -> str:
    """An openfast (of ``body`` or printing ``banner``) with a turbsim beside it."""
    _fake(folder, "turbsim", "TurbSim")
    return str(_fake(folder, "openfast", banner, body))


def _raw(folder: Path, name: str, data: bytes, mode: int = 0o755) -> str:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(data)
    (folder / name).chmod(mode)
    return str(folder / name)


@pytest.fixture
def bare(tmp_path, monkeypatch):
    """No OpenFAST anywhere: an empty cache, no OPENFAST or TURBSIM, a PATH of its own,
    a short probe time limit."""
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path / "cache"))
    for var in ("OPENFAST", "TURBSIM", "WTFTC_OPENFAST_ARCHIVES"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("PATH", str(tmp_path / "bin") + os.pathsep + "/usr/bin:/bin")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setattr(install, "_PROBE_TIMEOUT_S", 1.0)
    monkeypatch.chdir(tmp_path)
    return tmp_path


HANG = "echo $$ > \"$0.pid\"; sleep 30 & echo $! > \"$0.child\"; wait"

#: (id, {variable: value from tmp_path}, exit code, what stderr's line says)
NAMED = [
    ("openfast_empty", {"OPENFAST": lambda t: ""}, 2, "OPENFAST = '' is not allowed"),
    ("openfast_blank", {"OPENFAST": lambda t: "  "}, 2, "OPENFAST = '  ' is not allowed"),
    ("openfast_missing", {"OPENFAST": lambda t: str(t / "no" / "openfast")}, 2,
     "there is no file there"),
    ("openfast_under_a_file", {"OPENFAST": lambda t: _file(t) + "/openfast"}, 2,
     "there is no file there"),
    ("openfast_a_folder", {"OPENFAST": lambda t: str(t)}, 2, "this is a folder"),
    ("openfast_dev_null", {"OPENFAST": lambda t: "/dev/null"}, 2, "not a regular file"),
    ("openfast_a_fifo", {"OPENFAST": _fifo}, 2, "not a regular file"),
    ("openfast_link_loop", {"OPENFAST": _loop}, 2, "symbolic link loop"),
    ("openfast_dangling", {"OPENFAST": _dangling}, 2, "there is no file there"),
    ("openfast_not_executable", {"OPENFAST": lambda t: _raw(t, "of", b"#!/bin/sh\n", 0o644)},
     2, "it is not executable"),
    ("openfast_no_shebang", {"OPENFAST": lambda t: _raw(t, "of", b"echo OpenFAST\n")}, 2,
     "Exec format error"),
    ("openfast_binary_garbage", {"OPENFAST": lambda t: _raw(t, "of", bytes(range(256)))}, 2,
     "Exec format error"),
    ("openfast_missing_interpreter", {"OPENFAST": lambda t: _raw(
        t, "of", b"#!/nonexistent/sh\n")}, 2, "can be started"),
    ("openfast_bare_name_not_on_path", {"OPENFAST": lambda t: "no-such-openfast"}, 2,
     "no no-such-openfast on PATH"),
    ("openfast_version_4", {"OPENFAST": lambda t: _pair(t / "of4", banner="OpenFAST-v4.0.1")},
     2, "this one is OpenFAST 4.0.1"),
    ("openfast_version_6", {"OPENFAST": lambda t: _pair(t / "of6", banner="OpenFAST-v6.2.0")},
     2, "this one is OpenFAST 6.2.0"),
    ("openfast_fails_silently", {"OPENFAST": lambda t: _pair(t / "f", "exit 3")}, 4,
     "does not run: exit code 3, no output"),
    ("openfast_prints_latin1", {"OPENFAST": lambda t: _pair(t / "f", r"printf 'd\351j\340 vu\n'")},
     4, "does not run: déjà vu"),
    ("openfast_prints_binary", {"OPENFAST": lambda t: _pair(
        t / "f", r"printf '\377\376\000\001\033[31mboom\n'")}, 4, "does not run:"),
    ("openfast_prints_escapes", {"OPENFAST": lambda t: _pair(t / "f", r"printf '\033[2J'")},
     4, r"does not run: \?\[2J"),
    ("openfast_missing_library", {"OPENFAST": lambda t: _pair(
        t / "f", "echo 'openfast: error while loading shared libraries: libxyz.so.9: cannot "
        "open shared object file'; exit 127")}, 4, "libxyz.so.9"),
    ("openfast_floods", {"OPENFAST": lambda t: _pair(t / "f", "yes garbage")}, 4,
     "printed more than"),
    ("openfast_hangs", {"OPENFAST": lambda t: _pair(t / "f", HANG)}, 4, "did not end within"),
    ("openfast_crashes", {"OPENFAST": lambda t: _pair(t / "f", "kill -SEGV $$")}, 4,
     "does not run"),
    ("turbsim_empty", {"OPENFAST": lambda t: _pair(t / "ok"), "TURBSIM": lambda t: ""}, 2,
     "TURBSIM = '' is not allowed"),
    ("turbsim_missing", {"OPENFAST": lambda t: _pair(t / "ok"),
                         "TURBSIM": lambda t: str(t / "nope")}, 2, "TURBSIM = "),
    ("turbsim_a_folder", {"OPENFAST": lambda t: _pair(t / "ok"), "TURBSIM": lambda t: str(t)},
     2, "this is a folder"),
    ("turbsim_not_executable", {"OPENFAST": lambda t: _pair(t / "ok"), "TURBSIM": lambda t:
                                _raw(t, "ts", b"#!/bin/sh\necho TurbSim\n", 0o600)}, 2,
     "TURBSIM = .*it is not executable"),
    ("turbsim_dev_null", {"OPENFAST": lambda t: _pair(t / "ok"), "TURBSIM": lambda t:
                          "/dev/null"}, 2, "TURBSIM = '/dev/null'"),
    ("turbsim_no_banner", {"OPENFAST": lambda t: _pair(t / "ok"), "TURBSIM": lambda t:
                           str(_fake(t / "ts", "turbsim", "nothing here"))}, 4,
     "TURBSIM=.* does not run: nothing here"),
    ("turbsim_prints_latin1", {"OPENFAST": lambda t: _pair(t / "ok"), "TURBSIM": lambda t:
                               str(_fake(t / "ts", "turbsim", body=r"printf '\351\n'"))}, 4,
     "TURBSIM=.* does not run: é"),
    ("turbsim_hangs", {"OPENFAST": lambda t: _pair(t / "ok"), "TURBSIM": lambda t:
                       str(_fake(t / "ts", "turbsim", body=HANG))}, 4, "did not end within"),
    ("turbsim_bad_without_openfast", {"TURBSIM": lambda t: str(t / "nope")}, 2, "TURBSIM = "),
    ("openfast_bad_and_turbsim_bad", {"OPENFAST": lambda t: "", "TURBSIM": lambda t: ""}, 2,
     "OPENFAST = ''"),
]


@pytest.mark.parametrize("env, code, says", [r[1:] for r in NAMED], ids=[r[0] for r in NAMED])
def test_a_program_named_by_the_user_is_checked_in_one_line(bare, monkeypatch, capsys, env,
                                                            code, says):
    for var, value in env.items():
        monkeypatch.setenv(var, value(bare))
    started = time.monotonic()
    assert main(["openfast", "where"]) == code
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert re.search(says, err), err
    assert err.isprintable() or err[:-1].isprintable()
    assert time.monotonic() - started < 10
    for pid_file in [*bare.rglob("*.pid"), *bare.rglob("*.child")]:  # nothing left running
        pid = int(pid_file.read_text())
        deadline = time.monotonic() + 2
        while _alive(pid) and time.monotonic() < deadline:
            time.sleep(0.02)
        assert not _alive(pid), f"{pid_file.name}: process {pid} still running"


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, ended but not yet reaped, does not)."""
    try:
        stat_line = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat_line.rsplit(")", 1)[1].split()[0] != "Z"


#: (id, {variable: value from tmp_path}, what the found install must be)
NAMED_OK = [
    ("relative_path", {"OPENFAST": lambda t: (_pair(t / "rel"), "rel/openfast")[1]},
     lambda t, i: i.openfast == t / "rel" / "openfast" and i.openfast.is_absolute()),
    ("bare_name_on_path", {"OPENFAST": lambda t: (_pair(t / "bin"), "openfast")[1]},
     lambda t, i: i.openfast == t / "bin" / "openfast"),
    ("tilde", {"OPENFAST": lambda t: (_pair(t / "home" / "of"), "~/of/openfast")[1]},
     lambda t, i: i.openfast == t / "home" / "of" / "openfast"),
    ("latin1_banner", {"OPENFAST": lambda t: _pair(
        t / "f", r"printf ' OpenFAST-v5.0.0 \251 NREL\n'")}, lambda t, i: i.version == "5.0.0"),
    ("banner_then_a_child_holding_its_output", {"OPENFAST": lambda t: _pair(
        t / "f", "echo OpenFAST-v5.0.0; (sleep 30; echo late) &")},
     lambda t, i: i.version == "5.0.0"),
    ("turbsim_elsewhere", {"OPENFAST": lambda t: _pair(t / "ok"), "TURBSIM": lambda t:
                           (_fake(t / "ts", "ts", "TurbSim"), "ts/ts")[1]},
     lambda t, i: i.turbsim == t / "ts" / "ts"),
]


@pytest.mark.parametrize("env, check", [r[1:] for r in NAMED_OK], ids=[r[0] for r in NAMED_OK])
def test_a_usable_program_named_by_the_user_is_taken_by_its_absolute_path(bare, monkeypatch,
                                                                         env, check):
    for var, value in env.items():
        monkeypatch.setenv(var, value(bare))
    started = time.monotonic()
    found = install.find()
    assert time.monotonic() - started < 5  # a child holding the output is not waited for
    assert found.openfast.is_absolute() and found.turbsim.is_absolute()
    assert check(bare, found)


# --------------------------------------------------------------- archives

def _damaged_archive(folder: Path, data: bytes | None = None) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    real = Path("/work/shared/openfast") / install.PREBUILT[0]
    path = folder / install.PREBUILT[0]
    path.write_bytes(data if data is not None else real.read_bytes()[:100_000])
    return folder


def test_a_damaged_archive_is_passed_over_when_a_valid_one_follows(bare, monkeypatch,
                                                                   capsys):
    """Before: `openfast get` stopped at the first damaged archive."""
    monkeypatch.setenv("WTFTC_OPENFAST_ARCHIVES", str(_damaged_archive(bare / "arch")))
    assert main(["openfast", "get", "--no-build"]) == 0
    err = capsys.readouterr().err.splitlines()
    noted = [line for line in err if "not the archive wtftc expects" in line]
    assert len(noted) == 1 and str(bare / "arch") in noted[0] and "looking further" in noted[0]
    assert install.require().openfast.is_relative_to(bare / "cache")


#: (id, archive folders from tmp_path (each holding something at the archive's name))
ONLY_DAMAGED = [
    ("garbage", lambda t: [_damaged_archive(t / "a", b"not an archive")]),
    ("truncated", lambda t: [_damaged_archive(t / "a")]),
    ("empty", lambda t: [_damaged_archive(t / "a", b"")]),
    ("two_damaged", lambda t: [_damaged_archive(t / "a", b"x"), _damaged_archive(t / "b")]),
    ("a_folder_at_its_name", lambda t: [(t / "a" / install.PREBUILT[0]).mkdir(parents=True)
                                        or t / "a"]),
    ("a_dangling_link", lambda t: [(t / "a").mkdir() or (t / "a" / install.PREBUILT[0])
                                   .symlink_to(t / "nowhere") or t / "a"]),
]


@pytest.mark.parametrize("folders", [r[1] for r in ONLY_DAMAGED], ids=[r[0] for r in ONLY_DAMAGED])
def test_only_damaged_archives_are_each_named(bare, monkeypatch, capsys, folders):
    made = folders(bare)
    monkeypatch.setattr(install, "archive_folders", lambda extra=None: made)
    assert main(["openfast", "get", "--no-build"]) == 4
    err = capsys.readouterr().err.splitlines()
    assert err[-1].startswith("wtftc: error: OpenFAST 5.0.0 not found and not installed")
    for f in made:
        assert str(f / install.PREBUILT[0]) in err[-1]
    assert len(err) == 1 + len(made) and "Traceback" not in "".join(err)
    assert not (bare / "cache").exists()


def test_a_damaged_source_archive_is_named_not_built_around(bare, monkeypatch):
    made = [_damaged_archive(bare / "a")]
    (made[0] / install.PREBUILT[0]).rename(made[0] / install.SOURCE[0])
    monkeypatch.setattr(install, "archive_folders", lambda extra=None: made)
    monkeypatch.setattr(install, "_build", lambda *a: pytest.fail("built"))
    with pytest.raises(EngineError, match=r"cannot be built: .*openfast-5\.0\.0-src\.tar\.gz "
                       r"is not the archive"):
        install.get(log=lambda s: None, allow_build=True)


#: (id, option or variable, value from tmp_path)
ARCHIVE_FOLDERS = [
    ("env_empty", "WTFTC_OPENFAST_ARCHIVES", lambda t: ""),
    ("env_missing", "WTFTC_OPENFAST_ARCHIVES", lambda t: str(t / "none")),
    ("env_a_file", "WTFTC_OPENFAST_ARCHIVES", _file),
    ("env_dev_null", "WTFTC_OPENFAST_ARCHIVES", lambda t: "/dev/null"),
    ("env_link_loop", "WTFTC_OPENFAST_ARCHIVES", _loop),
    ("option_missing", "--archives", lambda t: str(t / "none")),
    ("option_a_file", "--archives", _file),
]


@pytest.mark.parametrize("field, value", [r[1:] for r in ARCHIVE_FOLDERS],
                         ids=[r[0] for r in ARCHIVE_FOLDERS])
def test_an_archive_folder_that_names_no_folder_is_refused(bare, monkeypatch, capsys, field,
                                                          value):
    given = value(bare)
    if field == "--archives":
        args = ["openfast", "get", "--no-build", "--archives", given]
    else:
        monkeypatch.setenv(field, given)
        args = ["openfast", "get", "--no-build"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{field} = " in err and "Traceback" not in err
    assert not (bare / "cache").exists()


# ------------------------------------------------------- end to end: OpenFAST in the cache

@pytest.fixture(scope="module")
def programs():
    """OpenFAST and TurbSim as installed for everyone (read only), for a private cache."""
    return install.require()


def _openfast_run(cwd: Path, cache: str, out: Path, programs) -> subprocess.CompletedProcess:
    env = {**os.environ, "WTFTC_CACHE": cache, "OPENFAST": str(programs.openfast),
           "TURBSIM": str(programs.turbsim)}
    return subprocess.run([sys.executable, "-m", "wtftc.cli", "run", "--engine", "openfast",
                           "--controller", "pi", "--wind", "constant", "--wind-mean", "16",
                           "--t-final", "1", "--quiet", "--out", str(out)], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=900)


def _metrics(out: Path) -> dict:
    """The run's metrics without what the wall clock gives."""
    m = json.loads((out / "metrics.json").read_text())
    m.get("config", {}).get("openfast", {}).pop("wall_s", None)
    return {k: v for k, v in m.items() if k not in ("realtime_factor", "wall_s")}


def test_a_relative_cache_of_the_longest_length_runs_openfast_and_heals_its_library(
        tmp_path, programs):
    """Before: a relative WTFTC_CACHE made every OpenFAST run fail (exit 4, "The dynamic
    library ./cache/plant_library-... could not be loaded"), since OpenFAST runs in its
    case folder. Here the relative cache's absolute path is the longest allowed. Then the
    plant library is damaged by one bit: the next run names it, rebuilds it, and gives the
    same numbers."""
    absolute = _sized(tmp_path, loader.MAX_CACHE_CHARS)
    relative = os.path.relpath(absolute, tmp_path)
    first = _openfast_run(tmp_path, relative, tmp_path / "run1", programs)
    assert first.returncode == 0, first.stderr
    (plant,) = Path(absolute).glob("plant_library-*/libwtftc_plant.so")
    assert files.seal_damage(plant.parent) is None
    _flip(plant)
    second = _openfast_run(tmp_path, relative, tmp_path / "run2", programs)
    assert second.returncode == 0, second.stderr
    noted = [line for line in second.stderr.splitlines() if "is damaged" in line]
    assert len(noted) == 1 and str(plant.parent) in noted[0] and "WTFTC_CACHE" in noted[0]
    assert _metrics(tmp_path / "run2") == _metrics(tmp_path / "run1")
    assert not [p for p in Path(absolute).iterdir() if p.name.startswith(".plant_library")]


@pytest.mark.parametrize("value", [lambda t: _sized(t, loader.OPENFAST_PATH_CHARS - 46),
                                   lambda t: str(t / "my#cache")], ids=["cut_by_servodyn", "hash"])
def test_a_cache_openfast_cannot_read_is_refused_before_it_runs(tmp_path, programs, value):
    """Before: OpenFAST cut the plant library's path at 256 characters (or at a '#') and
    stopped, exit 4, naming a path cut short. Now: one line naming WTFTC_CACHE, exit 2."""
    p = _openfast_run(tmp_path, value(tmp_path), tmp_path / "run", programs)
    assert p.returncode == 2, p.stderr
    last = p.stderr.strip().splitlines()[-1]
    assert last.startswith("wtftc: error: WTFTC_CACHE = ") and "OpenFAST" in last
    assert "Traceback" not in p.stderr and not (tmp_path / "run").exists()


def test_a_seal_names_a_folder_and_a_file_swapped(tmp_path):
    """An entry sealed as a file found as a folder (or the other way) is named as such
    ("`.` is missing" before), and any other change as what it is."""
    from wtftc import files

    f = tmp_path / "x.bts"
    f.write_bytes(b"123")
    files.seal(f)
    assert files.seal_damage(f) is None
    f.unlink()
    f.mkdir()
    assert files.seal_damage(f) == "a folder where a file was written"
    g = tmp_path / "lib"
    g.mkdir()
    (g / "a.so").write_bytes(b"1")
    files.seal(g)
    (g / "a.so").unlink()
    g.rmdir()
    g.write_bytes(b"x")
    assert files.seal_damage(g) == "a file where a folder was written"
    # a seal that is not a listing of strings, or no regular file, is damage, never a
    # traceback or a hang
    files.seal_path(f).write_text('{".": 3}')
    assert files.seal_damage(f) == "its checksum file is not a listing"
    files.seal_path(f).unlink()
    os.mkfifo(files.seal_path(f))
    assert "unreadable" in files.seal_damage(f)
