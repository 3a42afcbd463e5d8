"""The installed package, as a user gets it: a wheel built from this checkout, installed
into a fresh virtual environment, runs a 2-second simulation from a folder outside the
checkout, and gives the same traces as the source tree, byte for byte.

Dependencies come from pip's cache (or the index) as for any user; the compiled loop comes
from the shared compile cache, keyed by the sha256 of its C source, so the run is quick.
"""

import json
import os
import shutil
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

import pytest

from wtftc import cli

ROOT = Path(__file__).resolve().parent.parent


#: left out of the copy the wheel is built from: what the checkout holds beside its sources
NOT_SOURCES = {".venv", ".git", "out", "results", "build", ".pytest_cache", ".ruff_cache"}


def _ignored(folder: str, names: list[str]) -> set[str]:
    top = NOT_SOURCES if Path(folder) == ROOT else set()
    return {n for n in names if n in top or n == "__pycache__" or n.endswith(".egg-info")}


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel built from this checkout, as `pip wheel .` builds it, from a copy of it: the
    build writes its egg-info beside the sources, where a wtftc another test starts from
    the checkout (under pytest-xdist, at the same time) reads its version."""
    dist, src = tmp_path_factory.mktemp("dist"), tmp_path_factory.mktemp("src") / "wtftc"
    shutil.copytree(ROOT, src, ignore=_ignored)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(dist),
                    str(src)], check=True, capture_output=True)
    (path,) = dist.glob("wtftc-*.whl")
    return path


@pytest.fixture(scope="module")
def installed(wheel, tmp_path_factory) -> Path:
    """The bin/ folder of a fresh virtual environment with the wheel installed (by this
    environment's pip, pointed at it with --python: the same install, without the 3 s of
    bootstrapping a pip of its own)."""
    tmp = tmp_path_factory.mktemp("venv")
    venv.create(tmp / "venv", with_pip=False)
    bin_dir = tmp / "venv" / "bin"
    subprocess.run([sys.executable, "-m", "pip", "--python", str(bin_dir / "python"),
                    "install", "-q", str(wheel)], check=True, capture_output=True)
    return bin_dir


def _clean_env() -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "WTFTC_GENERATED")}
    env["MPLBACKEND"] = "Agg"
    return env


def test_the_wheel_carries_the_generated_artefacts_and_no_benchmark(wheel):
    """Every artefact of generated/manifest.json is in the wheel (as wtftc/_generated/),
    byte for byte, and nothing of bench/ or derivation/ is."""
    manifest = json.loads((ROOT / "generated" / "manifest.json").read_text())
    zf = zipfile.ZipFile(wheel)
    names = set(zf.namelist())
    for a in manifest["artefacts"]:
        if f"wtftc/_generated/{a}" in names:
            assert zf.read(f"wtftc/_generated/{a}") == (ROOT / "generated" / a).read_bytes()
    missing = [a for a in manifest["artefacts"] if f"wtftc/_generated/{a}" not in names]
    assert not missing, f"artefacts missing from the wheel: {missing}"
    assert "wtftc/_generated/manifest.json" in names
    # the C sources compiled at run time: the DISCON export's and ROSCO's bridge
    assert {"wtftc/sim/discon_bridge.c", "wtftc/export/discon_interface.c"} <= names
    assert not [n for n in names if n.startswith(("bench/", "derivation/", "tests/"))]


def test_installed_wtftc_runs_outside_the_checkout_as_the_source_tree_does(installed,
                                                                           tmp_path):
    work = tmp_path / "elsewhere"
    work.mkdir()
    args = ["run", "--t-final", "2", "--out", "out", "--quiet"]
    proc = subprocess.run([str(installed / "wtftc"), *args], cwd=work, env=_clean_env(),
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # the installed package read its own artefacts, not the checkout's
    where = subprocess.run([str(installed / "python"), "-c",
                            "from wtftc.artefacts.loader import generated_dir; "
                            "print(generated_dir())"], cwd=work, env=_clean_env(),
                           capture_output=True, text=True, check=True).stdout.strip()
    assert Path(where).parts[-2:] == ("wtftc", "_generated")
    assert not Path(where).is_relative_to(ROOT)
    # the same numbers as the source tree's run
    assert cli.main([*args[:-2], str(tmp_path / "tree"), "--quiet"]) == 0
    assert (work / "out" / "traces.csv").read_bytes() == \
        (tmp_path / "tree" / "traces.csv").read_bytes()
    for name in ("metrics.json", "config.toml", "figures/rotor_speed.png"):
        assert (work / "out" / name).stat().st_size > 0


def test_installed_wtftc_imports_without_the_source_tree(installed, tmp_path):
    """Every room imports in the installed package; bench/ (which needs the source tree)
    is not part of it."""
    code = ("import importlib; "
            "[importlib.import_module(m) for m in ('wtftc.cli', 'wtftc.campaign.cases', "
            "'wtftc.campaign.compare', 'wtftc.campaign.sweep', 'wtftc.verify.report', "
            "'wtftc.sim.rosco')]; "
            "import importlib.util as u; print(u.find_spec('bench'), u.find_spec('derivation'))")
    out = subprocess.run([str(installed / "python"), "-c", code], cwd=tmp_path,
                         env=_clean_env(), capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "None None"
    help_ = subprocess.run([str(installed / "wtftc"), "--help"], cwd=tmp_path,
                           env=_clean_env(), capture_output=True, text=True)
    assert help_.returncode == 0 and "verify" in help_.stdout
