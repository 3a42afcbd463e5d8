"""Fuzzing the inputs (issue 14): random mutations of a valid configuration and of a valid
wind file, deterministic seeds. Whatever the mutation, wtftc either accepts the input or
refuses it with a ConfigError naming a field in one line: never another exception (a
traceback), and through the CLI never a partial output folder.

600 configurations and 300 wind files go through the validation path (make_config, the
wind file reader); 40 configurations through `wtftc run` itself, with 0.2-s runs, where an
accepted one must write a whole run folder and a refused one nothing.
"""

import copy
import math

import numpy as np
import pytest

from wtftc import cli, config
from wtftc.errors import ConfigError
from wtftc.model.wind import wind_from_config
from wtftc.results.io import RUN_MARKERS

VALID = {
    "case": 2, "controller": "physical", "t_final_s": 0.2, "dt_s": 0.001, "seed": 3,
    "output_rate_hz": 50.0,
    "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"},
    "fault": [{"blade": 2, "type": "loss_of_effectiveness", "onset_s": 0.1, "rho": 0.5}],
    "turbine_params": {"J_r": 3.9e7, "pitch_rate_max": 0.14, "gen_torque_law": 1.0},
    "controller_params": {"phys_c1": 2.0},
    "initial": {"omega_r_offset_rad_s": 0.0},
}
#: what a mutation may put in a place: every kind of TOML value, and the edges of numbers
POOL = [0, -1, 1, 2, 0.5, -0.0, 1e-300, 1e300, 2**64, -2**63, math.nan, math.inf, -math.inf,
        True, False, "", "x", "1.0", "nrel5mw", "ntm", "lock", [], [1], [1.0, 2.0],
        [[1, 2]], {}, {"a": 1}, {"kind": "constant"}, "Ω", "a" * 300]


def _paths(obj, prefix=()):
    """Every place in a nested dict/list, as a tuple of keys and indices."""
    out = [prefix] if prefix else []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out += _paths(v, (*prefix, i))
    return out


def _mutate(cfg: dict, rng: np.random.Generator, edits: int | None = None) -> dict:
    """One to three random edits: half of the time a number scaled by 0.5-1.5 (plausible
    values, which reach the deep checks and the run), else a value from POOL, a deleted
    key or an unknown key."""
    cfg = copy.deepcopy(cfg)
    for _ in range(edits or int(rng.integers(1, 4))):
        paths = _paths(cfg)
        path = paths[int(rng.integers(len(paths)))]
        parent = cfg
        for key in path[:-1]:
            parent = parent[key]
        action = rng.random()
        leaf = parent[path[-1]]
        if action < 0.5 and isinstance(leaf, float):
            parent[path[-1]] = leaf * float(rng.uniform(0.5, 1.5))
        elif action < 0.8:
            parent[path[-1]] = copy.deepcopy(POOL[int(rng.integers(len(POOL)))])
        elif action < 0.9 and isinstance(parent, dict):
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[f"unknown_{int(rng.integers(100))}"] = 1.0
    return cfg


def _validate(raw: dict) -> bool:
    """make_config accepts raw (True) or raises ConfigError with a one-line message."""
    try:
        config.make_config(raw)
    except ConfigError as exc:
        assert "\n" not in str(exc), str(exc)
        return False
    return True


@pytest.mark.parametrize("block", range(6))
def test_mutated_configurations_are_accepted_or_refused_in_one_line(block):
    rng = np.random.default_rng(1000 + block)
    accepted = 0
    for _ in range(100):
        raw = _mutate(VALID, rng)
        try:
            accepted += _validate(raw)
        except AssertionError:
            raise
        except Exception as exc:  # noqa: BLE001 - the finding: say which input
            pytest.fail(f"{type(exc).__name__}: {exc}\nfrom {raw!r}")
    assert 5 <= accepted <= 95, accepted  # both sides of the validation are exercised


WIND = ["# time [s], horizontal speed [m/s] (OpenFAST uniform wind columns follow)",
        *[f"{t:.1f} {12 + 3 * math.sin(t):.3f} 0 0 0 0 0 0" for t in np.arange(0, 12, 0.5)]]
TOKENS = ["nan", "inf", "-1", "0", "1e9", "x", "", "12", "3.5", "1e-320", "--", "#", ",,"]


def _mutate_wind(rng: np.random.Generator) -> bytes:
    lines = list(WIND)
    for _ in range(int(rng.integers(1, 4))):
        i = int(rng.integers(len(lines)))
        action = rng.random()
        if action < 0.5:  # replace one token of a line
            toks = lines[i].split() or [""]
            toks[int(rng.integers(len(toks)))] = TOKENS[int(rng.integers(len(TOKENS)))]
            lines[i] = " ".join(toks)
        elif action < 0.65:
            del lines[i]
        elif action < 0.8:
            lines.insert(i, lines[int(rng.integers(len(lines)))])  # a duplicate time
        elif action < 0.9:
            lines[i], lines[-1] = lines[-1], lines[i]  # out of order
        else:
            return ("\n".join(lines)).encode()[: int(rng.integers(1, 400))] + b"\xff\xfe"
    return ("\n".join(lines) + "\n").encode()


@pytest.mark.parametrize("block", range(3))
def test_mutated_wind_files_are_accepted_or_refused_in_one_line(block, tmp_path):
    rng = np.random.default_rng(2000 + block)
    for n in range(100):
        path = tmp_path / f"w{n}.hh"
        data = _mutate_wind(rng)
        path.write_bytes(data)
        try:
            wind = wind_from_config({"kind": "file", "path": str(path)}, t_final=10.0)
            assert np.all(np.isfinite(wind(np.linspace(0, 10, 21))))
        except ConfigError as exc:
            assert "\n" not in str(exc)
        except Exception as exc:  # noqa: BLE001
            pytest.fail(f"{type(exc).__name__}: {exc}\nfrom {data!r}")


def test_mutated_runs_through_the_cli_write_a_whole_folder_or_nothing(tmp_path, capsys):
    from wtftc.results.io import atomic_write_text

    rng = np.random.default_rng(3000)
    accepted = refused = 0
    for n in range(40):
        raw = _mutate(VALID, rng, edits=1)
        cfg = tmp_path / f"c{n}.toml"
        try:
            atomic_write_text(cfg, config.to_toml(raw))
        except Exception:  # noqa: BLE001 - not expressible in TOML (a NaN key, ...)
            continue
        out = tmp_path / f"out{n}"
        try:
            code = cli.main(["run", "--config", str(cfg), "--out", str(out), "--quiet"])
        except SystemExit as exc:
            code = exc.code
        err = capsys.readouterr().err
        assert "Traceback" not in err, err
        if code == 2:
            refused += 1
            assert not out.exists() and len(err.strip().splitlines()) == 1, err
        else:
            accepted += 1
            assert code in (0, 3), (code, err)
            assert all((out / m).exists() for m in RUN_MARKERS)
    hidden = [p.name for p in tmp_path.iterdir() if p.name.startswith(".")]
    assert not hidden, hidden  # no temporary folder left behind
    assert accepted >= 5 and refused >= 5, (accepted, refused)
