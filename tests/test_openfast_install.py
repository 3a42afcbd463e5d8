"""Finding and getting OpenFAST 5.0.0 (issue 32, wtftc.openfast.install, `make openfast`).

Fake programs stand in for a user's own OpenFAST of another version; the real prebuilt
archive (shared/openfast/) is unpacked into a fresh cache, as on a fresh machine."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from wtftc.cli import main
from wtftc.errors import ConfigError, EngineError
from wtftc.openfast import install


def _fake(folder: Path, name: str, banner: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    exe = folder / name
    exe.write_text(f"#!/bin/sh\necho ' {banner}'\n")
    exe.chmod(exe.stat().st_mode | stat.S_IXUSR)
    return exe


@pytest.fixture
def bare(tmp_path, monkeypatch):
    """No OpenFAST anywhere: an empty cache, no $OPENFAST, a PATH without openfast, no
    archive folder."""
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("OPENFAST", raising=False)
    monkeypatch.delenv("TURBSIM", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path / "bin") + os.pathsep + "/usr/bin:/bin")
    monkeypatch.setattr(install, "archive_folders", lambda extra=None: [tmp_path / "none"])
    return tmp_path


def test_nothing_installed_is_one_line_with_the_command_that_gets_it(bare, capsys):
    with pytest.raises(EngineError, match=r"make openfast.*wtftc openfast get"):
        install.require()
    assert main(["openfast", "where"]) == 4
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_another_major_version_on_path_is_passed_over_and_named(bare):
    _fake(bare / "bin", "openfast", "OpenFAST-v4.1.2")
    said = []
    assert install.find(said.append) is None
    assert "it is 4.1.2" in said[0]


def test_openfast_named_by_the_user_of_another_version_is_refused(bare, monkeypatch):
    monkeypatch.setenv("OPENFAST", str(_fake(bare / "of4", "openfast", "OpenFAST-v4.0.0")))
    with pytest.raises(ConfigError, match=r"OPENFAST = .* an OpenFAST 5\.x program \(this one "
                       r"is OpenFAST 4\.0\.0"):
        install.find()


def test_openfast_named_by_the_user_that_prints_no_version_is_taken_as_given(bare, monkeypatch):
    exe = _fake(bare / "mine", "openfast", "OpenFAST-HEAD-HASH-NOTFOUND")
    ts = _fake(bare / "mine", "turbsim", "TurbSim")
    monkeypatch.setenv("OPENFAST", str(exe))
    found = install.find()
    assert (found.openfast, found.turbsim, found.source) == (exe, ts, "$OPENFAST")
    assert "not printed" in found.version


def test_a_version_5_on_path_without_turbsim_is_refused_naming_turbsim(bare):
    _fake(bare / "bin", "openfast", "OpenFAST-v5.0.0")
    with pytest.raises(EngineError, match="no TurbSim that runs: set TURBSIM"):
        install.find()


def test_an_archive_with_other_bytes_is_refused_not_unpacked(bare, monkeypatch):
    folder = bare / "archives"
    folder.mkdir()
    (folder / install.PREBUILT[0]).write_bytes(b"not the archive")
    monkeypatch.setattr(install, "archive_folders", lambda extra=None: [folder])
    with pytest.raises(EngineError, match="not the archive wtftc expects"):
        install.get(log=lambda s: None, allow_build=False)
    assert not install.home().exists()


def test_no_archive_and_no_build_says_where_it_looked(bare):
    with pytest.raises(EngineError, match=r"no openfast-5\.0\.0-linux-x86_64\.tar\.gz in .*none"):
        install.get(log=lambda s: None, allow_build=False)


def test_the_prebuilt_archive_installs_into_the_cache_and_runs(tmp_path, monkeypatch):
    """The real archive, as `make openfast` gets it on a fresh machine: unpacked into the
    cache, both programs run, and the next call finds the cached copy."""
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("OPENFAST", raising=False)
    monkeypatch.setenv("PATH", "/usr/bin:/bin")
    inst = install.get(log=lambda s: None, allow_build=False)
    assert inst.version == "5.0.0" and inst.openfast.is_relative_to(tmp_path / "cache")
    assert install.probe(inst.openfast).runs and install.probe(inst.turbsim, "TurbSim").runs
    again = install.find()
    assert again.openfast == inst.openfast and again.source.startswith("cache: prebuilt")
    assert not [p for p in install.home().parent.iterdir() if p.name.startswith(".unpack")]
