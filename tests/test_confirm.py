"""Screen on wtftc's plant, confirm in OpenFAST (issue 35 item 4): `wtftc sweep
--confirm-openfast N`. Which scenarios are chosen (synthetic rows), what is refused, and
one short screen (4 runs of 12 s) with its worst scenario confirmed in OpenFAST (2 runs):
`make test` gets OpenFAST first."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import pytest

from wtftc.campaign import sweep
from wtftc.campaign.sweep import confirm

TRIP = 1.2


def _row(controller, wind, peak, shaft=1.0e6, tower=1.0e7, status="ok"):
    return {"controller": controller, "mean_wind_mps": wind, "turbulence_class": "B",
            "seed": 0, "fault_type": "none", "blade": None, "fault_sensor": None,
            "onset_s": None, "status": status, "overspeed_peak_over_rated": peak,
            "shaft_torque_del_1hz_Nm": shaft, "tower_base_del_1hz_Nm": tower}


def test_lost_scenarios_come_first_then_the_worst_of_each_metric_in_turn():
    rows = [_row("a", 10.0, 1.05, shaft=9e6), _row("b", 10.0, 1.04),
            _row("a", 12.0, 1.10), _row("b", 12.0, 1.09, tower=9e7),
            _row("a", 14.0, 1.21), _row("b", 14.0, 1.02),        # lost by a: past the trip
            _row("a", 16.0, 1.01), _row("b", 16.0, 1.00, status="diverged"),  # lost by b
            _row("a", 18.0, 1.08, shaft=5e6), _row("b", 18.0, 1.07, tower=5e7)]
    chosen = confirm.pick(rows, 10, TRIP)
    winds = [k[2] for k, _ in chosen]  # (fault, wind kind, mean wind, ...)
    # lost (by their peak: 14 then 16); then in turn: peak #1 (14, taken), shaft #1 (10),
    # tower #1 (12); peak #2 (12, taken), shaft #2 (18)
    assert winds == [14.0, 16.0, 10.0, 12.0, 18.0]
    assert [w for _, w in chosen] == ["lost by a", "lost by b", "worst shaft DEL (#1)",
                                      "worst tower-base DEL (#1)", "worst shaft DEL (#2)"]
    assert [k[2] for k, _ in confirm.pick(rows, 3, TRIP)] == [14.0, 16.0, 10.0]
    assert [k[2] for k, _ in confirm.pick(rows, 1, TRIP)] == [14.0]  # N caps the lost too


def test_a_failed_run_is_not_lost_and_each_fault_size_is_its_own_scenario():
    """A run that raised (failed: an error, not the rotor) is not a lost scenario; two
    locks at different angles are two scenarios, named apart, and a lost run's metrics are
    not ranked."""
    lock = {"fault_type": "lock", "blade": 1, "onset_s": 40.0}
    rows = [{**_row("a", 12.0, 1.01, status="failed"), **lock, "stuck_angle_deg": "current"},
            {**_row("b", 12.0, 1.02), **lock, "stuck_angle_deg": "current"},
            {**_row("a", 12.0, 1.05), **lock, "stuck_angle_deg": "5.0"},
            {**_row("b", 12.0, 1.25), **lock, "stuck_angle_deg": "5.0"}]
    chosen = confirm.pick(rows, 5, TRIP)
    assert [w for _, w in chosen][0] == "lost by b" and len(chosen) == 2
    assert not any(w.startswith("lost by a") for _, w in chosen)
    names = {confirm.describe(r) for r in rows}
    assert len(names) == 2 and all("stuck_angle_deg" in n for n in names), names
    assert [confirm.state(r, TRIP) for r in rows] == ["failed", "yes", "yes", "lost"]
    on = [{confirm.scenario(r): {} for r in rows}]
    for r in rows:
        on[0][confirm.scenario(r)][r["controller"]] = r
    table = confirm._agreement(on * 2, [confirm.scenario(r) for r in rows[::2]], TRIP)
    peak = [t for t in table if t["metric"] == "overspeed_peak_over_rated"]
    assert len(peak) == 2 and all(t["missing"] == 1 for t in peak)  # failed, lost: unranked


def wtftc(*args, **kw):
    return subprocess.run([sys.executable, "-m", "wtftc.cli", *map(str, args)],
                          capture_output=True, text=True, **kw)


SCREEN = """t_final_s = 12.0
plants = ["tower"]
controllers = ["pi", "physical-plain"]
[wind]
mean_mps = [14.0, 18.0]
rotor_radius_m = 63.0
seed = 0
field = "turbsim"
"""


@pytest.mark.parametrize("text,args,field", [
    (SCREEN.replace('field = "turbsim"\n', ""), (), "wind.field"),
    (SCREEN.replace('"turbsim"', '"bogus"'), (), "wind.field"),
    (SCREEN.replace('plants = ["tower"]\n', 'engine = "openfast"\n'), (), "--confirm-openfast"),
    (SCREEN, ("--traces",), "--traces"),
    (SCREEN, ("--confirm-openfast", 0), "--confirm-openfast"),
    (SCREEN.replace('["tower"]', '["tower", "tower_edge"]'), (), "plants"),
    (SCREEN + "[mismatch]\nJ_r = 1.1\n", (), "mismatch"),
])
def test_what_cannot_be_screened_and_confirmed_is_refused_in_one_line(tmp_path, text, args,
                                                                       field):
    f = tmp_path / "s.toml"
    f.write_text(text)
    extra = args if args and args[0] == "--confirm-openfast" else ("--confirm-openfast", 1,
                                                                   *args)
    p = wtftc("sweep", f, "--out", tmp_path / "out", *extra, timeout=120)
    assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
    assert field in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "out").exists() and not (tmp_path / "out_openfast").exists()
    alone = wtftc("sweep", f, "--out", tmp_path / "o2", "--confirm-out", tmp_path / "c",
                  timeout=120)
    assert alone.returncode == 2 and "--confirm-out" in alone.stderr


def test_the_worst_scenario_of_a_screen_is_rerun_in_openfast_on_the_same_field(tmp_path):
    """4 runs on wtftc's tower plant, the worst extreme overspeed's scenario (no run lost
    in 12 s) again in OpenFAST with both controllers: the OpenFAST runs are the very runs a
    sweep of the same file in OpenFAST makes (the same ids), the screen read the TurbSim
    field, the report's cells are both folders' metrics, and a second call runs nothing
    and writes the same report but for its wall times."""
    f = tmp_path / "s.toml"
    f.write_text(SCREEN)
    out, conf = tmp_path / "screen", tmp_path / "screen_openfast"
    p = wtftc("sweep", f, "--out", out, "--confirm-openfast", 1, "--workers", 2, timeout=900)
    assert p.returncode == 0, p.stderr
    screen = sweep.read_results(out).to_pylist()
    assert len(screen) == 4 and all(r["status"] == "ok" for r in screen)
    assert all(json.loads(r["config_json"])["wind"]["field"] == "turbsim" for r in screen)
    worst = max(screen, key=lambda r: r["overspeed_peak_over_rated"])["mean_wind_mps"]
    rows = sweep.read_results(conf).to_pylist()
    assert sorted(r["controller"] for r in rows) == ["physical-plain", "pi"]
    assert {r["mean_wind_mps"] for r in rows} == {worst}
    assert all(r["plant"] == "openfast" and r["status"] == "ok" for r in rows)
    of = confirm.openfast_sweep(sweep.load_sweep(f).raw)
    ids = {pt["run_id"] for pt in sweep.expand(of)[0] if pt["mean_wind_mps"] == worst}
    assert {r["run_id"] for r in rows} == ids
    table = list(csv.DictReader((conf / "confirm.csv").open()))
    assert len(table) == 4  # 2 controllers × 2 engines
    for r in screen + rows:
        if r["mean_wind_mps"] != worst:
            continue
        eng = "openfast" if r["plant"] == "openfast" else "wtftc"
        cell = next(t for t in table if t["controller"] == r["controller"]
                    and t["engine"] == eng)
        assert float(cell["overspeed_peak_over_rated [-]"]) == r["overspeed_peak_over_rated"]
        assert float(cell["shaft_torque_del_1hz_Nm [N m]"]) == r["shaft_torque_del_1hz_Nm"]
        assert cell["outcome"] == "yes"
    report = (conf / "confirm.md").read_text()
    for c in ("pi", "physical-plain"):  # each cell: wtftc's value, then OpenFAST's
        mine = next(r for r in screen if r["controller"] == c and r["mean_wind_mps"] == worst)
        of_ = next(r for r in rows if r["controller"] == c)
        line = next(ln for ln in report.splitlines() if f"| {c} |" in ln)
        assert f"| yes / yes | {mine['overspeed_peak_over_rated']:.3f} / " \
            f"{of_['overspeed_peak_over_rated']:.3f} |" in line, line
    assert f"{worst:g} m/s NTM B, seed 0, none" in report and "Ranking agreement" in report
    again = wtftc("sweep", f, "--out", out, "--confirm-openfast", 1, timeout=300)
    assert again.returncode == 0, again.stderr
    assert "0 to run" in again.stdout and "4 already in" in again.stdout
    assert "2 already in" in again.stdout
    # the same report but its wall times
    assert (conf / "confirm.md").read_text().split("\n")[3:] == report.split("\n")[3:]


def test_the_field_changes_the_screens_ids_but_not_openfasts():
    """``[wind] field = "turbsim"`` is a different wind on wtftc's plant (new run ids);
    OpenFAST reads the TurbSim field either way, so its runs keep the ids of the same file
    without it (a confirmation shares its runs with a plain OpenFAST sweep)."""
    import tomllib

    raw = tomllib.loads(SCREEN)
    plain = {**raw, "wind": {k: v for k, v in raw["wind"].items() if k != "field"}}

    def ids(r):
        return [pt["run_id"] for pt in sweep.expand(sweep.parse_sweep(r))[0]]

    assert not set(ids(raw)) & set(ids(plain))
    assert ids(confirm.openfast_sweep(raw).raw | {"engine": "openfast"}) == ids(
        confirm.openfast_sweep(plain).raw | {"engine": "openfast"})
    assert all(pt["config"]["wind"]["field"] == "turbsim"
               for pt in sweep.expand(sweep.parse_sweep(raw))[0])


def test_the_screen_examples_openfast_twin_is_the_openfast_example():
    """examples/dlc21_screen.toml: 384 runs on tower_edge, each reading its TurbSim field,
    as its header says; its OpenFAST twin's runs at seeds 0-1 are, id for id, those of
    examples/dlc21_openfast_obs3to45.toml: a confirmation runs what that campaign runs."""
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent / "examples"
    sw = sweep.load_sweep(root / "dlc21_screen.toml")
    runs, _ = sweep.expand(sw)
    ours = [r for r in runs if r["controller"] == "aftc-nrel5mw"]
    assert len(ours) == 192 and {r["plant"] for r in runs} == {"tower_edge"}
    assert all(r["config"]["wind"]["field"] == "turbsim" for r in runs)
    twin = {pt["run_id"] for pt in sweep.expand(confirm.openfast_sweep(sw.raw))[0]
            if pt["seed"] <= 1}
    kept = {pt["run_id"] for pt in sweep.expand(
        sweep.load_sweep(root / "dlc21_openfast_obs3to45.toml"))[0]}
    assert twin == kept and len(twin) in (48, 96)  # ROSCO's where it is installed


def test_a_confirmation_folder_that_is_not_a_sweeps_is_refused_before_the_screen(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text(SCREEN)
    other = tmp_path / "notes"
    other.mkdir()
    (other / "mine.txt").write_text("a user's file")
    p = wtftc("sweep", f, "--out", tmp_path / "out", "--confirm-openfast", 1,
              "--confirm-out", other, timeout=120)
    assert p.returncode == 2 and p.stderr.count("\n") == 1, p.stderr
    assert p.stderr.startswith("wtftc: error: --confirm-out") and "Traceback" not in p.stderr
    assert not (tmp_path / "out").exists()  # nothing screened
    assert sorted(x.name for x in other.iterdir()) == ["mine.txt"]
