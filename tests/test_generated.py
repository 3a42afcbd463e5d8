"""generated/ is reproducible, guarded against staleness and tampering, and loadable."""

import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from derivation import check_generated, plant
from wtftc.artefacts import loader as gen
from wtftc.verify import checks as verify

ROOT = Path(__file__).resolve().parent.parent


def test_regeneration_is_byte_identical_and_matches_the_committed_files():
    assert check_generated.stale_sources() == []
    assert check_generated.regeneration_diff() == []


def test_every_generated_file_has_the_do_not_edit_header():
    for p in sorted((ROOT / "generated").iterdir()):
        head = p.read_text()[:300]
        assert "generated from derivation/" in head and "do not edit" in head, p.name
        assert "20" + "26" not in head  # no date stamp


@pytest.fixture
def tree_copy(tmp_path):
    for d in ("derivation", "generated"):
        shutil.copytree(ROOT / d, tmp_path / d, ignore=shutil.ignore_patterns("__pycache__"))
    # the NREL 5-MW's turbine file: the derivation's turbine defaults (docs/turbines.md)
    (tmp_path / "wtftc" / "data").mkdir(parents=True)
    shutil.copy(ROOT / "wtftc" / "data" / "nrel5mw.toml", tmp_path / "wtftc" / "data")
    return tmp_path


def test_editing_a_coefficient_is_detected_with_what_to_run(tree_copy):
    src = tree_copy / "derivation" / "backstepping.py"
    text = src.read_text()
    assert "alpha1 = -c[0] * chi1 - 2 * chi1 - F[0]" in text
    src.write_text(text.replace("- 2 * chi1 -", "- 3 * chi1 -"))
    assert check_generated.stale_sources(tree_copy) == [
        "derivation/backstepping.py changed since generated/ was built"]
    # the regeneration itself runs once, in the command a user runs (regeneration_diff)
    proc = subprocess.run([sys.executable, "-m", "derivation.check_generated"], cwd=tree_copy,
                          capture_output=True, text=True)
    assert proc.returncode == 1
    assert "generated/controller.c differs:" in proc.stdout
    assert "derivation/backstepping.py changed since generated/ was built" in proc.stdout
    assert "run `make regenerate`" in proc.stdout and "@@" in proc.stdout


def test_tampered_artefact_is_refused(tree_copy):
    folder = tree_copy / "generated"
    c = folder / "controller.c"
    c.write_text(c.read_text().replace("casadi_real", "casadi_real ", 1))
    with pytest.raises(gen.GeneratedArtefactError, match="run `make regenerate`"):
        gen.load("controller", "compiled", folder)
    # other groups still load
    assert gen.load("plant_paper", "compiled", folder).name() == "plant_paper"


def test_missing_manifest_is_a_clear_error(tmp_path):
    with pytest.raises(gen.GeneratedArtefactError, match="manifest.json is missing"):
        gen.load("controller", "auto", tmp_path)


def test_falls_back_to_the_virtual_machine_without_a_compiler(tree_copy, monkeypatch):
    monkeypatch.setattr(gen, "compiler", lambda: None)
    with pytest.warns(RuntimeWarning, match="virtual machine"):
        f = gen.load("plant_paper", "auto", tree_copy / "generated")
    assert f.class_name() != "External"
    with pytest.raises(RuntimeError, match="no C compiler"):
        gen.load("controller", "compiled", tree_copy / "generated")


def test_compiled_and_interpreted_agree_to_1e12():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a compiler is present here: no fallback allowed
        worst = verify.compiled_vs_interpreted(n_points=30, seed=1)
    assert set(worst) == set(gen.layout_json()["functions"])
    assert max(worst.values()) <= 1e-12


def test_compiled_code_is_cached_by_hash(tmp_path, monkeypatch):
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path))
    so = gen.compile_cached(gen.verified_path("plant.c"), gen.compiler())
    assert so.parent == tmp_path and so.suffix == ".so"
    mtime = so.stat().st_mtime_ns
    assert gen.compile_cached(gen.verified_path("plant.c"), gen.compiler()) == so
    assert so.stat().st_mtime_ns == mtime  # reused, not rebuilt


def test_strict_feedback_rewriting_is_the_same_vector_field():
    """Eqs (1)-(4) (x4 = mean blade pitch) and eqs (11)-(18) agree identically."""
    assert plant.strict_feedback_residual() == [0, 0, 0, 0]


def test_strict_feedback_check_detects_a_wrong_f2(monkeypatch):
    """The identity check has teeth: eq (16) with x1 - x3 instead of x1 - 2 x3 fails."""
    original = plant.strict_feedback_f

    def wrong(X):
        f = original(X)
        f[1] = X[0] - X[2]
        return f

    monkeypatch.setattr(plant, "strict_feedback_f", wrong)
    res = plant.strict_feedback_residual()
    assert res[1] != 0 and res[0] == res[2] == res[3] == 0


def test_generated_plant_matches_strict_feedback_numerically():
    rng = np.random.default_rng(5)
    f = gen.load("plant_paper")
    t = gen.load("strict_feedback_targets")
    for _ in range(20):
        a = verify.random_inputs("plant_paper", rng)
        a["fault"][:, 0] = [1, 1, 1, 0, 0, 0, 0, 0, 0]  # no fault: u_j = v_j
        out = f(**a)
        X = np.array(out["X"]).ravel()
        fpd = np.array(t(x_plant=a["x_plant"], d1=a["d1"], p_plant=a["p_plant"])["f_plus_d"])
        fpd = fpd.ravel()
        xdot = np.array(out["x_plant_dot"]).ravel()
        tau_b = float(a["p_plant"][4, 0])
        chain = np.array([fpd[0] + X[1], fpd[1] + X[2], fpd[2] + X[3],
                          fpd[3] + np.mean(a["v"]) / tau_b])
        np.testing.assert_allclose([*xdot[:3], xdot[3:].mean()], chain, rtol=1e-12,
                                   atol=1e-12)
