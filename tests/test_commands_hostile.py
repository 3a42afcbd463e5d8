"""Hostile input on the commands of the second engine: `wtftc validate`, `modes`,
`linearize`, and `run`, `compare`, `sweep` with `--engine openfast`.

Table-driven, as tests/test_bad_inputs.py: a row is (id, the command line, what its one
line must name, the files it needs). Each is refused before any work: exit code 2, one
line on stderr, ``wtftc: error: ...``, no traceback, no --out created, no file of the
test's folder changed, no program started (the compiled loop, OpenFAST, TurbSim and Dask
are replaced by stand-ins that fail the test if called) and no process left running. The
CLI runs in-process (``wtftc.cli.main``).

In the arguments and file texts, ``{tmp}`` is the test's folder and ``{name}`` the path of
the row's file ``name``; a file given as :data:`FIFO` or :data:`FOLDER` is made as one.
Then the defects of these commands, each with its own test.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import psutil
import pytest

from wtftc import cli, config, programs
from wtftc.campaign import cases
from wtftc.model import turbine_file
from wtftc.openfast import turbsim
from wtftc.sim import integrate

FIFO, FOLDER = object(), object()
BINARY = b"\x00\x01\xfe\xff" * 64
LATIN1 = "# vitesse du vent \xb0\nkind = 1\n".encode("latin-1")
NREL = turbine_file.load("nrel5mw")
TURBINE_TEXT = Path(NREL.path).read_text().replace(
    'cp_table = "Cp_Ct_Cq.NREL5MW.txt"', f'cp_table = "{NREL.cp_path}"')
DECK_LINE = 'openfast_deck = "rosco:Examples/Test_Cases/NREL-5MW/NREL-5MW.fst"'
DISCON_LINE = 'rosco_discon = "rosco:Examples/Test_Cases/NREL-5MW/DISCON.IN"'
assert DECK_LINE in TURBINE_TEXT and DISCON_LINE in TURBINE_TEXT


def turbine(deck: str | None = None, discon: str | None = None) -> str:
    """The NREL 5-MW's turbine file with its deck or its DISCON.IN named otherwise."""
    text = TURBINE_TEXT
    if deck is not None:
        text = text.replace(DECK_LINE, f"openfast_deck = {deck!r}".replace("'", '"'))
    if discon is not None:
        text = text.replace(DISCON_LINE, f"rosco_discon = {discon!r}".replace("'", '"'))
    return text


class Row(NamedTuple):
    id: str
    argv: tuple
    names: str  # what the one line must contain
    files: dict | None = None


OF = ("--engine", "openfast")
LONG = "n" * 250
SWEEP_OK = 't_final_s = 4.0\ncontrollers = ["pi"]\n[wind]\nmean_mps = 16.0\n'

VALIDATE = [
    Row("validate-t-final-nan", ("validate", "--t-final", "nan"), "t_final_s"),
    Row("validate-t-final-inf", ("validate", "--t-final", "inf"), "t_final_s"),
    Row("validate-t-final-negative", ("validate", "--t-final", "-5"), "t_final_s"),
    Row("validate-t-final-huge", ("validate", "--t-final", "1e300"), "t_final_s"),
    Row("validate-wind-mean-nan", ("validate", "--wind-mean", "nan"), "mean_mps"),
    Row("validate-wind-mean-negative", ("validate", "--wind-mean", "-3"), "mean_mps"),
    Row("validate-wind-mean-inf", ("validate", "--wind-mean", "inf"), "mean_mps"),
    Row("validate-wind-mean-huge", ("validate", "--wind-mean", "1e9"), "mean_mps"),
    Row("validate-wind-mean-word", ("validate", "--wind-mean", "fast"), "--wind-mean"),
    Row("validate-wind-file-without-path", ("validate", "--wind", "file"), "wind.path"),
    Row("validate-wind-file-missing", ("validate", "--wind-file", "{tmp}/nowhere.csv"),
        "nowhere.csv"),
    Row("validate-wind-file-folder", ("validate", "--wind-file", "{d}"), "wind", {"d": FOLDER}),
    Row("validate-wind-file-fifo", ("validate", "--wind-file", "{w.csv}"), "FIFO",
        {"w.csv": FIFO}),
    Row("validate-wind-file-binary", ("validate", "--wind-file", "{w.csv}"), "wind",
        {"w.csv": BINARY}),
    Row("validate-wind-file-with-ntm", ("validate", "--wind", "ntm", "--wind-file", "{w.csv}"),
        "wind.path", {"w.csv": "time_s,speed_mps\n0,16\n60,16\n"}),
    Row("validate-wind-file-with-mean", ("validate", "--wind-file", "{w.csv}", "--wind-mean",
                                         "16"), "mean_mps",
        {"w.csv": "time_s,speed_mps\n0,16\n60,16\n"}),
    Row("validate-wind-kind", ("validate", "--wind", "hurricane"), "kind"),
    Row("validate-plant-no-tower", ("validate", "--plant", "nrel5mw"), "--plant"),
    Row("validate-plant-unknown", ("validate", "--plant", "vestas"), "--plant"),
    Row("validate-controller-unknown", ("validate", "--controller", "lqr"), "controller"),
    Row("validate-seed-negative", ("validate", "--seed", "-1"), "--seed"),
    Row("validate-seed-64bit", ("validate", "--seed", str(2**64)), "seed"),
    Row("validate-case-3", ("validate", "--case", "3"), "--case"),
    Row("validate-rotor-wind", ("validate", "--rotor-wind", "hub"), "--rotor-wind"),
    Row("validate-turbine-missing", ("validate", "--turbine", "{tmp}/none.toml"), "turbine"),
    Row("validate-turbine-folder", ("validate", "--turbine", "{d}"), "turbine",
        {"d": FOLDER}),
    Row("validate-turbine-fifo", ("validate", "--turbine", "{t.toml}"), "FIFO",
        {"t.toml": FIFO}),
    Row("validate-turbine-latin1", ("validate", "--turbine", "{t.toml}"), "t.toml",
        {"t.toml": LATIN1}),
    Row("validate-out-file", ("validate", "--out", "{f.txt}"), "--out", {"f.txt": "mine\n"}),
    Row("validate-out-long", ("validate", "--out", "{tmp}/" + LONG), "at most 237 bytes"),
]

MODES = [
    Row("modes-azimuths-0", ("modes", "--azimuths", "0"), "--azimuths"),
    Row("modes-azimuths-negative", ("modes", "--azimuths", "-2"), "--azimuths"),
    Row("modes-azimuths-fraction", ("modes", "--azimuths", "2.5"), "--azimuths"),
    Row("modes-azimuths-37", ("modes", "--azimuths", "37"), "--azimuths"),
    Row("modes-azimuths-huge", ("modes", "--azimuths", "1000000000"), "--azimuths"),
    Row("modes-azimuths-nan", ("modes", "--azimuths", "nan"), "--azimuths"),
    Row("modes-winds-nan", ("modes", "--winds", "nan"), "--winds"),
    Row("modes-winds-inf", ("modes", "--winds", "inf"), "--winds"),
    Row("modes-winds-negative", ("modes", "--winds", "-16"), "--winds"),
    Row("modes-winds-huge", ("modes", "--winds", "1e9"), "--winds"),
    Row("modes-winds-61", ("modes", "--winds", "16", "61"), "--winds"),
    Row("modes-winds-below-rated", ("modes", "--winds", "8"), "--winds"),
    Row("modes-dofs-empty", ("modes", "--dofs", ""), "--dofs"),
    Row("modes-plant-paper", ("modes", "--plant", "paper"), "--plant"),
    Row("modes-turbine-device", ("modes", "--turbine", "/dev/null"), "turbine"),
    Row("modes-turbine-fifo", ("modes", "--turbine", "{t.toml}"), "FIFO", {"t.toml": FIFO}),
    Row("modes-turbine-no-deck", ("modes", "--turbine", "{t.toml}"), "--turbine",
        {"t.toml": TURBINE_TEXT.replace(DECK_LINE, "")}),
    Row("modes-out-file", ("modes", "--out", "{f.txt}"), "--out", {"f.txt": "mine\n"}),
    Row("modes-out-long", ("modes", "--out", "{tmp}/" + LONG), "at most 237 bytes"),
]

LINEARIZE = [
    Row("linearize-winds-nan", ("linearize", "--winds", "nan"), "--winds"),
    Row("linearize-winds-negative", ("linearize", "--winds", "-1"), "--winds"),
    Row("linearize-winds-inf", ("linearize", "--winds", "inf"), "--winds"),
    Row("linearize-controller-rosco", ("linearize", "--controller", "rosco"), "--controller"),
    Row("linearize-controller-unknown", ("linearize", "--controller", "lqr"), "controller"),
    Row("linearize-plant-unknown", ("linearize", "--plant", "vestas"), "--plant"),
    Row("linearize-config-missing", ("linearize", "--config", "{tmp}/none.toml"), "--config"),
    Row("linearize-config-folder", ("linearize", "--config", "{d}"), "--config",
        {"d": FOLDER}),
    Row("linearize-config-fifo", ("linearize", "--config", "{c.toml}"), "--config",
        {"c.toml": FIFO}),
    Row("linearize-config-binary", ("linearize", "--config", "{c.toml}"), "--config",
        {"c.toml": BINARY}),
    Row("linearize-config-engine-typo", ("linearize", "--config", "{c.toml}"), "engine",
        {"c.toml": 'engine = "openfest"\n'}),
    Row("linearize-out-long", ("linearize", "--out", "{tmp}/" + LONG), "at most 237 bytes"),
]

RUN = [
    Row("run-of-t-final-nan", ("run", *OF, "--t-final", "nan"), "t_final_s"),
    Row("run-of-t-final-negative", ("run", *OF, "--t-final", "-1"), "t_final_s"),
    Row("run-of-plant", ("run", *OF, "--plant", "tower_edge"), "plant"),
    Row("run-of-case-3", ("run", *OF, "--case", "3"), "case"),
    Row("run-of-profile-ideal", ("run", *OF, "--profile", "ideal"), "profile"),
    Row("run-of-control-interval-1", ("run", *OF, "--controller", "pi", "--control-interval",
                                      "1.0", "--t-final", "10"),
        "control_interval_s (--control-interval) = 1.0"),
    Row("run-of-control-interval-nan", ("run", *OF, "--control-interval", "nan"),
        "control_interval_s"),
    Row("run-of-control-interval-negative", ("run", *OF, "--control-interval", "-0.01"),
        "control_interval_s"),
    Row("run-of-control-interval-huge", ("run", *OF, "--control-interval", "1e9"),
        "control_interval_s"),
    Row("run-of-control-delay", ("run", *OF, "--control-delay"), "control_delay"),
    Row("run-of-wind-field-spectral", ("run", *OF, "--wind", "ntm", "--wind-field",
                                       "spectral"), "wind.field"),
    Row("run-of-wind-radius-negative", ("run", *OF, "--wind", "ntm", "--wind-radius", "-1"),
        "rotor_radius_m"),
    Row("run-of-seed-2-63", ("run", *OF, "--seed", str(2**63)), "seed"),
    Row("run-of-openfast-wind", ("run", "--config", "{c.toml}"), "openfast.wind",
        {"c.toml": 'engine = "openfast"\n[openfast]\nwind = "fog"\n'}),
    Row("run-of-openfast-actuator-word", ("run", "--config", "{c.toml}"), "openfast.actuator",
        {"c.toml": 'engine = "openfast"\n[openfast]\nactuator = "yes"\n'}),
    Row("run-of-openfast-not-a-table", ("run", "--config", "{c.toml}"), "openfast",
        {"c.toml": 'engine = "openfast"\nopenfast = 5\n'}),
    Row("run-of-openfast-extra-key", ("run", "--config", "{c.toml}"), "openfast",
        {"c.toml": 'engine = "openfast"\n[openfast]\ndeck = "x.fst"\n'}),
    Row("run-of-no-actuator-with-fault", ("run", "--config", "{c.toml}"), "openfast.actuator",
        {"c.toml": 'engine = "openfast"\ncase = 2\n[openfast]\nactuator = false\n'}),
    Row("run-of-openfast-table-native", ("run", "--config", "{c.toml}"), "openfast",
        {"c.toml": '[openfast]\nwind = "uniform"\n'}),
    Row("run-of-engine-list", ("run", "--config", "{c.toml}"), "engine",
        {"c.toml": 'engine = ["openfast"]\n'}),
    Row("run-of-deck-escapes-rosco", ("run", *OF, "--turbine", "{t.toml}"), "openfast_deck",
        {"t.toml": turbine(deck="rosco:../../../../etc/x.fst")}),
    Row("run-of-deck-absolute-rosco", ("run", *OF, "--turbine", "{t.toml}"), "openfast_deck",
        {"t.toml": turbine(deck="rosco:/etc/x.fst")}),
    Row("run-of-deck-package-rosco", ("run", *OF, "--turbine", "{t.toml}"), "openfast_deck",
        {"t.toml": turbine(deck="rosco:rosco/x.fst")}),
    Row("run-discon-escapes-rosco", ("run", "--controller", "rosco", "--turbine", "{t.toml}"),
        "rosco_discon", {"t.toml": turbine(discon="rosco:Examples/../../DISCON.IN")}),
    Row("run-of-deck-not-fst", ("run", *OF, "--turbine", "{t.toml}"), "openfast_deck",
        {"t.toml": turbine(deck="{tmp}/deck.txt")}),
    Row("run-of-out-long", ("run", *OF, "--out", "{tmp}/" + LONG), "at most 237 bytes"),
    Row("run-of-out-file", ("run", *OF, "--out", "{f.txt}"), "--out", {"f.txt": "mine\n"}),
]

COMPARE = [
    Row("compare-of-t-final-nan", ("compare", *OF, "--t-final", "nan"), "t-final"),
    Row("compare-of-t-final-short", ("compare", *OF, "--t-final", "5"), "t-final"),
    Row("compare-of-controllers", ("compare", *OF, "--controllers", "lqr"), "controllers"),
    Row("compare-of-winds", ("compare", *OF, "--winds", "hurricane"), "winds"),
    Row("compare-of-faults", ("compare", *OF, "--faults", "meteor"), "faults"),
    Row("compare-of-workers-0", ("compare", *OF, "--workers", "0"), "--workers"),
    Row("compare-of-plant", ("compare", *OF, "--plant", "tower"), "--plant"),
    Row("compare-of-out-long", ("compare", *OF, "--out", "{tmp}/" + LONG),
        "at most 237 bytes"),
]

SWEEP = [
    Row("sweep-of-file-missing", ("sweep", "{tmp}/none.toml", *OF), "SWEEP.toml"),
    Row("sweep-of-file-folder", ("sweep", "{d}", *OF), "SWEEP.toml", {"d": FOLDER}),
    Row("sweep-of-file-fifo", ("sweep", "{s.toml}", *OF), "SWEEP.toml", {"s.toml": FIFO}),
    Row("sweep-of-file-binary", ("sweep", "{s.toml}", *OF), "SWEEP.toml",
        {"s.toml": BINARY}),
    Row("sweep-of-t-final-nan", ("sweep", "{s.toml}", *OF), "t_final_s",
        {"s.toml": "t_final_s = nan\ncontrollers = [\"pi\"]\n"}),
    Row("sweep-of-t-final-inf", ("sweep", "{s.toml}", *OF), "t_final_s",
        {"s.toml": "t_final_s = inf\ncontrollers = [\"pi\"]\n"}),
    Row("sweep-of-wind-negative", ("sweep", "{s.toml}", *OF), "mean_mps",
        {"s.toml": SWEEP_OK.replace("16.0", "-16.0")}),
    Row("sweep-engine-unknown", ("sweep", "{s.toml}"), "engine",
        {"s.toml": 'engine = "fast"\n' + SWEEP_OK}),
    Row("sweep-engine-wrong-type", ("sweep", "{s.toml}"), "engine",
        {"s.toml": "engine = 1\n" + SWEEP_OK}),
    Row("sweep-of-plant", ("sweep", "{s.toml}", *OF), "plant",
        {"s.toml": 'plants = ["tower_edge"]\n' + SWEEP_OK}),
    Row("sweep-of-workers-0", ("sweep", "{s.toml}", *OF, "--workers", "0"), "--workers",
        {"s.toml": SWEEP_OK}),
    Row("sweep-of-confirm-out-alone", ("sweep", "{s.toml}", *OF, "--confirm-out", "{tmp}/c"),
        "--confirm-out", {"s.toml": SWEEP_OK}),
    Row("sweep-of-confirm-with-engine", ("sweep", "{s.toml}", *OF, "--confirm-openfast",
                                         "1"), "--engine", {"s.toml": SWEEP_OK}),
    Row("sweep-of-out-file", ("sweep", "{s.toml}", *OF, "--out", "{f.txt}"), "--out",
        {"s.toml": SWEEP_OK, "f.txt": "mine\n"}),
    Row("sweep-of-deck-escapes-rosco", ("sweep", "{s.toml}", *OF), "openfast_deck",
        {"s.toml": 'turbine = "{t.toml}"\n' + SWEEP_OK,
         "t.toml": turbine(deck="rosco:../../x.fst")}),
]


def _decks() -> list[Row]:
    """A turbine file whose deck's main file is a FIFO, a folder, missing, binary or
    empty, on each command that reads a deck (a FIFO once blocked the TurbSim field's
    hub height being read, before any check)."""
    kinds = {"fifo": FIFO, "folder": FOLDER, "missing": None, "binary": BINARY,
             "empty": "", "no-inflow": "---- a main file without its InflowFile line\n"}
    commands = {"run": ("run", *OF, "--controller", "pi", "--t-final", "10"),
                "run-ntm": ("run", *OF, "--controller", "pi", "--wind", "ntm",
                            "--t-final", "10"),
                "validate": ("validate", "--t-final", "10"),
                "modes": ("modes",),
                "sweep": ("sweep", "{s.toml}", *OF),
                "compare": ("compare", *OF, "--controllers", "pi", "--faults", "none",
                            "--winds", "steady_16", "--t-final", "30")}
    rows = []
    for cmd, argv in commands.items():
        for kind, content in kinds.items():
            files = {"t.toml": turbine(deck="{x.fst}" if content is not None
                                       else "{tmp}/none.fst")}
            if content is not None:
                files["x.fst"] = content
            if cmd == "sweep":
                files["s.toml"] = 'turbine = "{t.toml}"\n' + SWEEP_OK
            else:
                argv = (*argv, "--turbine", "{t.toml}") if "--turbine" not in argv else argv
            rows.append(Row(f"{cmd}-deck-{kind}", argv, "openfast_deck", files))
    return rows


ALL = VALIDATE + MODES + LINEARIZE + RUN + COMPARE + SWEEP + _decks()


def _materialize(row: Row, tmp: Path) -> list[str]:
    """Make the row's files; its command line with the paths filled in, and --out unless
    it gives its own."""
    named = dict(row.files or {})
    paths = {"{tmp}": str(tmp), **{"{" + n + "}": str(tmp / n) for n in named}}

    def fill(text: str) -> str:
        for key, val in paths.items():
            text = text.replace(key, val)
        return text

    for name, content in named.items():
        path = tmp / name
        if content is FIFO:
            os.mkfifo(path)
        elif content is FOLDER:
            path.mkdir()
        else:
            path.write_bytes(content if isinstance(content, bytes) else fill(content).encode())
    argv = [fill(a) for a in row.argv]
    if "--out" not in argv:
        argv += ["--out", str(tmp / "out")]
    return argv + (["--quiet"] if argv[0] in ("validate", "modes", "linearize", "run",
                                              "compare", "sweep") else [])


def _snapshot(tmp: Path) -> dict:
    """Every entry under ``tmp``: its kind, bytes (regular files) and mtime."""
    snap = {}
    for p in sorted(tmp.rglob("*")):
        st = p.lstat()
        data = p.read_bytes() if p.is_file() and not p.is_symlink() else None
        snap[str(p)] = (st.st_mode, data, st.st_mtime_ns)
    return snap


def _children() -> set[int]:
    """This process's descendants now (another test's may outlive it: only new ones
    count)."""
    return {p.pid for p in psutil.Process().children(recursive=True)}


@pytest.fixture
def nothing_runs(monkeypatch):
    """Every way to start work fails the test at once: the compiled loop, a program
    (OpenFAST, TurbSim), a TurbSim field, a Dask cluster."""
    def started(*a, **k):
        raise AssertionError("the input was accepted: work started")

    monkeypatch.setattr(integrate, "run_loops", started)
    monkeypatch.setattr(programs, "run", started)
    monkeypatch.setattr(turbsim, "generate", started)
    from wtftc.campaign import cluster

    monkeypatch.setattr(cluster, "client", started)


@pytest.mark.parametrize("row", [pytest.param(r, id=r.id) for r in ALL])
def test_hostile_input_is_one_line_before_any_work(row, tmp_path, capsys, nothing_runs):
    argv = _materialize(row, tmp_path)
    before, running = _snapshot(tmp_path), _children()
    try:
        code = cli.main(argv)
    except SystemExit as exc:  # argparse's refusals
        code = exc.code
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err
    assert "Traceback" not in err and len(lines) == 1, err
    assert lines[0].startswith("wtftc: error:") and row.names in lines[0], err
    assert len(lines[0]) < 2000, "one line, of a readable length"
    out = argv[argv.index("--out") + 1]
    assert _snapshot(tmp_path) == before, "a file of the test's folder changed"
    assert Path(out).exists() == (out in before), f"{out} was created"
    assert _children() <= running, "a process was left running"


def test_there_are_at_least_60_hostile_rows_with_distinct_ids():
    assert len(ALL) >= 60 and len({r.id for r in ALL}) == len(ALL)


@pytest.mark.parametrize("command", ["validate", "modes", "linearize", "run", "compare",
                                     "sweep"])
def test_help_of_each_command_works(command, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main([command, "--help"])
    assert exc.value.code == 0
    assert "--out" in capsys.readouterr().out


# --- the defects of these commands, each with the input that showed it


class Reached(Exception):
    """The command got past every check to the work (a stand-in for the work)."""


def test_validate_takes_a_wind_file_without_a_mean(tmp_path, monkeypatch):
    """`validate --wind file --wind-file W` was always refused: the default --wind-mean
    16 was passed with it, and a wind file has no mean_mps. A wind file given alone is the
    wind too. Both engines get the file's series."""
    seen = []

    def reached(rc, out_dir, progress=True):
        seen.append(rc)
        raise Reached

    monkeypatch.setattr(cases, "run_and_write", reached)
    w = tmp_path / "w.csv"
    w.write_text("time_s,speed_mps\n0,16\n100,17\n")
    for argv in (["--wind", "file", "--wind-file", str(w)], ["--wind-file", str(w)]):
        seen.clear()
        with pytest.raises(Reached):
            cli.main(["validate", *argv, "--t-final", "10", "--quiet", "--out",
                      str(tmp_path / "v")])
        assert seen[0].raw["engine"] == "openfast"
        assert seen[0].raw["wind"] == {"kind": "file", "path": str(w)}
        assert not (tmp_path / "v").exists()


def test_a_bad_out_is_refused_before_a_turbsim_field_is_made(tmp_path, capsys, monkeypatch):
    """`run` and `validate` with an NTM on TurbSim's field made the field (minutes on a
    large grid) and only then refused an --out that is a user's file."""
    made = []
    monkeypatch.setattr(turbsim, "make_field", lambda cfg: made.append(cfg))
    mine = tmp_path / "mine.txt"
    mine.write_text("my notes\n")
    for argv in (["run", *OF, "--wind", "ntm", "--wind-mean", "16"],
                 ["run", "--wind", "ntm", "--wind-field", "turbsim"], ["validate"]):
        assert cli.main([*argv, "--t-final", "10", "--quiet", "--out", str(mine)]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("wtftc: error: --out") and len(err.splitlines()) == 1, err
        assert made == [] and mine.read_text() == "my notes\n"


@pytest.mark.parametrize("size, refused", [(237, False), (238, True), (255, True)])
def test_a_long_out_is_refused_by_the_limit_of_its_hidden_sibling(size, refused, tmp_path,
                                                                   capsys, monkeypatch):
    """A folder name of 238-255 bytes is a valid name, but the run is built beside it in
    .<name>.<8 characters>.partial, 18 bytes longer: it ran to its end and was refused
    then, "(File name too long)" of the sibling. Now refused first, naming the limit;
    237 bytes pass this check (and get to the run)."""
    def reached(*a, **k):
        raise Reached

    monkeypatch.setattr(cases, "run_and_write", reached)
    out = tmp_path / ("o" * size)
    argv = ["run", "--t-final", "1", "--quiet", "--out", str(out)]
    if not refused:
        with pytest.raises(Reached):
            cli.main(argv)
        return
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert f"at most 237 bytes (this one's is {size})" in err and len(err.splitlines()) == 1


def test_a_rosco_path_that_leaves_rosco_examples_is_refused(tmp_path):
    """`rosco:<path>` named a file anywhere, "../.." leaving ROSCO's installed package
    tree: a copy of the DISCON.IN outside it was read as the turbine's. Now a path under
    rosco:Examples/ only, without '..'; the built-in turbines' paths pass."""
    from wtftc.errors import ConfigError
    from wtftc.sim.rosco import discon_path

    real = discon_path(NREL.rosco_discon)
    copy = tmp_path / "DISCON.IN"
    copy.write_bytes(real.read_bytes())
    root = discon_path("rosco:")
    escape = "rosco:" + os.path.relpath(copy, root)
    assert ".." in escape and discon_path(escape).resolve() == copy.resolve()
    t = tmp_path / "t.toml"
    t.write_text(turbine(discon=escape))
    with pytest.raises(ConfigError, match="ROSCO's installed examples") as exc:
        config.make_config({"turbine": str(t), "controller": "rosco"})
    assert exc.value.field == "rosco_discon" and exc.value.where == str(t)
    config.make_config({"turbine": "nrel5mw", "controller": "rosco"})
    config.make_config({"turbine": "iea15mw", "controller": "rosco"})


def test_control_interval_on_openfast_is_refused_by_its_own_name(tmp_path, capsys):
    """`control_interval_s = 1.0` in OpenFAST was refused as "fdi.align_rate_per_s = 5.0",
    a default the user never set. Now the interval is named, with the largest one the
    default alignment allows (0.2 s = 1 / 5 /s); an alignment rate the user gives is
    named as before."""
    cfg = tmp_path / "c.toml"
    cfg.write_text('engine = "openfast"\ncontroller = "pi"\ncontrol_interval_s = 1.0\n'
                   "t_final_s = 10.0\n")
    assert cli.main(["run", "--config", str(cfg), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("wtftc: error: control_interval_s = 1.0 is not allowed: at most "
                          "0.2 s with engine = openfast"), err
    cfg.write_text(cfg.read_text() + "[fdi]\nalign_rate_per_s = 2.0\n")
    assert cli.main(["run", "--config", str(cfg), "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.startswith("wtftc: error: fdi.align_rate_per_s = 2.0")


def test_modes_azimuths_in_a_meaningful_range(tmp_path, capsys, monkeypatch):
    """`modes --azimuths 1000000000` was accepted (a billion linearizations of one
    revolution); now 2 to 36, named with why, and 36 gets to the work."""
    from wtftc.campaign import modes

    def reached(*a, **k):
        raise Reached

    monkeypatch.setattr(modes, "run_modes", reached)
    assert cli.main(["modes", "--azimuths", "1000000000", "--out", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err
    assert "--azimuths = 1000000000 is not allowed: an integer in [2, 36]" in err
    with pytest.raises(Reached):
        cli.main(["modes", "--azimuths", "36", "--out", str(tmp_path / "m")])
    assert [modes.check_azimuths(n) for n in (2, 6, 36)] == [2, 6, 36]


@pytest.mark.parametrize("mean, noted", [(24.0, False), (27.0, True)])
def test_a_run_above_cut_out_says_so_on_stderr(mean, noted, tmp_path, capsys, monkeypatch):
    """A run whose mean wind is above its turbine's cut-out (25 m/s, the NREL 5-MW's) ran
    without a word; IEC 61400-1's power-production cases end at cut-out. It runs, with one
    line on stderr before any work; at 24 m/s nothing is said."""
    def reached(*a, **k):
        raise Reached

    monkeypatch.setattr(cases, "run_and_write", reached)
    with pytest.raises(Reached):
        cli.main(["run", "--controller", "pi", "--wind", "constant", "--wind-mean",
                  str(mean), "--t-final", "2", "--quiet", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    if not noted:
        assert err == ""
        return
    assert len(err.splitlines()) == 1 and err.startswith("note: ")
    assert "27 m/s, is above the turbine's cut-out, 25 m/s" in err


def test_compare_in_openfast_refuses_a_deck_every_cell_fails_on(tmp_path, capsys):
    """`compare --engine openfast` on a turbine whose deck OpenFAST stops on at its start
    (ElastoDyn's HubRad negative) ran every cell to the same failure; now the first cell's
    case is started before any (as a sweep's) and refused in one line, exit 2, no --out."""
    import shutil

    src = config.openfast_deck(NREL)
    deck = tmp_path / "deck"
    shutil.copytree(src.parent, deck)
    ed = deck / "NRELOffshrBsline5MW_Onshore_ElastoDyn.dat"
    text = ed.read_text()
    assert "        1.5   HubRad" in text
    ed.write_text(text.replace("        1.5   HubRad", "       -1.5   HubRad"))
    t = tmp_path / "t.toml"
    t.write_text(turbine(deck=str(deck / src.name)))
    out, running = tmp_path / "out", _children()
    assert cli.main(["compare", *OF, "--turbine", str(t), "--controllers", "pi", "--faults",
                     "none", "--winds", "steady_16", "--t-final", "30", "--quiet", "--out",
                     str(out)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines()
           if line.startswith("wtftc: error")]
    assert len(err) == 1 and "openfast_deck" in err[0] and "HubRad must not be negative" \
        in err[0], err
    assert not out.exists() and _children() <= running
