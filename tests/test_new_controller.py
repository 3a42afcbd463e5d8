"""A controller is one derivation module and one registry entry (docs/controllers.md).

tests/toy_design.py, known to no other file, is registered in a temporary copy of
derivation.controllers.REGISTRY; the generator writes a complete generated/ into a
temporary folder; with WTFTC_GENERATED pointing there, its functions are checked against
SymPy (tests/reference.py, which iterates over the registry), its α̇1 against central
differences on its design model (wtftc.verify.designs), and `wtftc run --controller toy`
simulates 2 s. The repository's generated/ is not touched.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent

REGISTER = """
import sys
sys.path[:0] = [{root!r}, {tests!r}]
from derivation import controllers
import toy_design
controllers.REGISTRY = {{**controllers.REGISTRY, "toy": controllers.Controller.derived(
    "toy", "test-only: physical chain without anti-windup", toy_design,
    [("z1", "rad/s"), ("z2", "rad"), ("alpha1", "rad"), ("f_hat", "rad/s^2")])}}
"""

GENERATE = REGISTER + """
from pathlib import Path
from derivation import generate
generate.write(Path({out!r}))
"""

CHECK = REGISTER + """
import json
import numpy as np
import reference
from wtftc.artefacts.loader import load
from wtftc.verify import designs
from wtftc.verify.checks import random_inputs

rng = np.random.default_rng(0)
worst = {{}}
for name in ("ctrl_toy", "init_toy", "alpha_toy", "closed_loop_toy_model"):
    f = load(name)
    for _ in range(20):
        args = random_inputs(name, rng)
        got, ref = f(**args), reference.reference(name, args)
        for k in f.name_out():
            value, scale = ref[k]
            g = np.array(got[k]).reshape(-1, order="F")
            err = np.abs(g - value) / np.maximum(np.maximum(np.abs(value), scale), 1e-300)
            worst[f"{{name}}.{{k}}"] = max(worst.get(f"{{name}}.{{k}}", 0.0), float(err.max()))
fd = designs.alpha_dot_fd("toy")
from wtftc.campaign import compare
print(json.dumps({{"derived": designs.derived(), "sympy_worst": worst,
                  "compare": [compare.resolve_columns([{{"name": "toy", "design": "toy"}}])[
                      "toy"].design, compare.resolve_columns([{{"name": "toy", "design": "toy"}}])[
                      "toy"].accommodation],
                  "alphas": fd.alphas, "slopes": fd.slopes.tolist(),
                  "best": fd.errors.min(axis=0).tolist(), "alpha_dot": fd.alpha_dot.tolist()}}))
"""


def _python(code: str, env: dict) -> str:
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    return p.stdout


@pytest.fixture(scope="module")
def toy_generated(tmp_path_factory):
    out = tmp_path_factory.mktemp("generated")
    before = {p.name: p.read_bytes() for p in (ROOT / "generated").iterdir()}
    _python(GENERATE.format(root=str(ROOT), tests=str(ROOT / "tests"), out=str(out)),
            dict(os.environ))
    assert {p.name: p.read_bytes() for p in (ROOT / "generated").iterdir()} == before
    env = {**os.environ, "WTFTC_GENERATED": str(out),
           "WTFTC_CACHE": str(tmp_path_factory.mktemp("cache"))}
    return out, env


def test_the_new_controller_is_generated_and_listed(toy_generated):
    out, _ = toy_generated
    layout = json.loads((out / "layout.json").read_text())
    toy = layout["controllers"]["toy"]
    assert toy["checks"] == "alpha_toy" and toy["model"]["function"] == "closed_loop_toy_model"
    assert [e["name"] for e in layout["toy_states"]] == [f"toy_theta_hat[{m}]" for m in range(3)]
    assert {"ctrl_toy", "init_toy", "alpha_toy", "closed_loop_toy_model"} <= set(
        layout["functions"])
    # everything the repository generates is generated again, unchanged
    committed = json.loads((ROOT / "generated" / "layout.json").read_text())
    assert set(committed["functions"]) < set(layout["functions"])


def test_the_new_controller_matches_sympy_and_its_alpha_dot_converges(toy_generated):
    _, env = toy_generated
    res = json.loads(_python(CHECK.format(root=str(ROOT), tests=str(ROOT / "tests")),
                             env).strip().splitlines()[-1])
    assert "toy" in res["derived"] and "drivetrain" in res["derived"]
    # wtftc compare --controllers '{ name = "toy", design = "toy" }': with wtftc's FDI
    assert res["compare"] == ["toy", "fdi"]
    bad = {k: v for k, v in res["sympy_worst"].items() if v > 1e-12}
    assert not bad, bad
    assert res["alphas"] == ["alpha1"]
    assert abs(res["alpha_dot"][0]) > 1e-6
    assert 1.9 < res["slopes"][0] < 2.1, res
    assert res["best"][0] < 1e-6, res


def test_the_new_controller_runs(toy_generated, tmp_path):
    _, env = toy_generated
    p = subprocess.run([sys.executable, "-m", "wtftc.cli", "run", "--controller", "toy",
                        "--t-final", "2", "--out", str(tmp_path / "run")],
                       capture_output=True, text=True, env=env, cwd=tmp_path, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert m["diverged"] is None or m["diverged"] is False, m["diverged"]
    assert np.isfinite(m["rms_speed_error_rad_s"]) and m["rms_speed_error_rad_s"] < 0.05
