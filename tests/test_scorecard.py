"""`wtftc scorecard` end to end on a short matrix on wtftc's plant: the report, its
figures against the runs, resuming, and refusals."""

import json
import subprocess
import sys

import pytest

pytest.importorskip("distributed", reason="Dask: pip install 'wtftc[sweep]'")

from wtftc.campaign.scorecard import report, stats  # noqa: E402
from wtftc.campaign.sweep.store import read_results  # noqa: E402

SHORT = """annual_mean_mps = 10.0
turbulence_class = "B"
start_up_s = 10.0

[groups.normal_production]
iec = "1.2"
what = "two bins, a short run"
bin_width_mps = 6.0
cut_out_mps = 20.0
seeds = 2
scored_s = 30.0
overspeed_trip = 1.2

[groups.actuator_faults]
iec = "2.1"
what = "a lock and both runaways at one wind"
winds_mps = [16.0]
seeds = 2
scored_s = 30.0
onset_s = 5.0
blade = 1
types = ["lock", "runaway"]
rho = 0.5
angle_deg = "current"
severity = 1.0
runaway_targets_deg = [0.0, 90.0]
overspeed_trip = 1.2

[groups.sensor_faults]
iec = "2.1"
what = "a stuck pitch sensor and a rotor-speed gain at one wind"
winds_mps = [16.0]
seeds = 2
scored_s = 30.0
onset_s = 5.0
blade = 1
sensor = 1
types = ["pitch_sensor_stuck", "rotor_speed_sensor_gain"]
overspeed_trip = 1.2

[groups.sensor_faults.magnitudes]
pitch_sensor_stuck = 5.0
rotor_speed_sensor_gain = 1.1

[groups.deterministic]
iec = "1.4 and test bench"
what = "an EOG and a ramp at rated"
kinds = ["eog", "ramp"]
winds_from_rated_mps = [0.0]
scored_s = 30.0
event_s = 5.0
step_mps = 2.0
ramp_mps = 4.0
ramp_s = 20.0
ecd_sign = 1
turbine_class = "I"
overspeed_trip = 1.2

[groups.baseline_as_shipped]
iec = "1.2"
what = "the baseline as shipped at the upper bin"
near_mps = [14.0]
overspeed_trip = 1.2
"""


def wtftc(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "wtftc.cli", *map(str, args)],
                          capture_output=True, text=True, cwd=cwd)


@pytest.fixture(scope="module")
def card(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("scorecard")
    (tmp / "short.toml").write_text(SHORT)
    args = ("scorecard", "--engine", "wtftc", "--against", "pi", "--matrix",
            tmp / "short.toml", "--workers", 2, "--out", tmp / "out", "--quiet")
    p = wtftc(*args)
    assert p.returncode == 0, p.stderr
    return tmp, args, p


def test_the_report_holds_every_group_and_its_figures_are_the_runs(card):
    tmp, _, p = card
    out = tmp / "out"
    doc = json.loads((out / "scorecard.json").read_text())
    assert doc["controller"] == "aftc-nrel5mw" and doc["baseline"] == "pi"
    assert doc["engine"] == "wtftc" and doc["versions"]["wtftc"] and \
        doc["versions"]["generated_code_sha256"] == doc["generated_code_sha256"]
    assert (out / "scorecard.md").read_text() == p.stdout.split("written under")[0]
    assert set(doc["groups"]) == {"normal_production", "actuator_faults", "sensor_faults",
                                  "deterministic", "baseline_as_shipped"}
    # the RMS speed error's ratio (wind above rated), made again from the saved runs by
    # hand over the pairs that have it (the bin below rated has none)
    rows = read_results(out / "normal_production").to_pylist()
    pp, counts = stats.held_pairs([r for r in rows if r["controller"] == "aftc-nrel5mw"],
                                  [r for r in rows if r["controller"] == "pi"])
    assert counts["scenarios"] == 2 * 2 and len(pp) == counts["both_held"]
    import math

    key = "rms_speed_error_own_above_rated_rad_s"
    logs = [math.log(a[key] / b[key]) for a, b in pp if a[key] is not None]
    assert 0 < len(logs) < len(pp)
    got = next(m for m in doc["groups"]["normal_production"]["metrics"]
               if m["metric"] == key)
    assert got["ratio"] == pytest.approx(math.exp(sum(logs) / len(logs)), rel=1e-12)
    assert got["n_seeds"] == 2 and got["verdict"] == "not enough seeds"
    # the blades' direction changes per second, over the pairs where both turned (the
    # test bench's figure; a blade resting at fine below rated turns not at all: no ratio)
    key = "pitch_reversals_per_s"
    moved = [math.log(a[key] / b[key]) for a, b in pp if a[key] > 0 and b[key] > 0]
    got = next(m for m in doc["groups"]["normal_production"]["pitch"] if m["metric"] == key)
    assert moved and got["n_pairs"] == len(moved)
    assert got["ratio"] == pytest.approx(math.exp(sum(moved) / len(moved)), rel=1e-12)
    assert "## The blades' pitch direction changes" in p.stdout
    # every fault run counted in one outcome, none dropped
    faults = read_results(out / "actuator_faults").to_pylist()
    counted = sum(sum(n.values()) for cols in doc["groups"]["actuator_faults"]["outcomes"]
                  .values() for n in cols.values())
    assert counted == len(faults) == 1 * 2 * 3 * 2
    assert "| runaway_feather | aftc-nrel5mw |" in p.stdout
    # the self-contained page: every table of the Markdown, the per-bin figure inside it
    page = (out / "scorecard.html").read_text()
    tables = sum(line.startswith("|---") for line in
                 (out / "scorecard.md").read_text().splitlines())
    assert tables >= 3 and page.count("<table>") == tables
    assert page.count('src="data:image/png;base64,') == 2  # per bin, and the trade-off
    for stem in ("normal_production_per_bin", "normal_production_trade_off"):
        assert (out / "figures" / f"{stem}.pdf").stat().st_size > 0


def test_the_fdi_and_its_false_alarms_are_counted_from_the_runs(card):
    tmp, _, p = card
    out = tmp / "out"
    doc = json.loads((out / "scorecard.json").read_text())
    free = [r for r in read_results(out / "normal_production").to_pylist()
            if r["controller"] == "aftc-nrel5mw"]
    fa = doc["groups"]["normal_production"]["false_alarms"]
    assert set(fa) == {"aftc-nrel5mw"}  # the PI runs no FDI: no rate is made up for it
    alarms = sum(r["false_alarms"] for r in free)
    hours = len(free) * 30.0 / 3600.0
    assert fa["aftc-nrel5mw"]["alarms"] == alarms and fa["aftc-nrel5mw"]["hours"] == \
        pytest.approx(hours, rel=1e-12)
    assert fa["aftc-nrel5mw"]["per_hour_upper_95"] == pytest.approx(
        stats.upper_rate_bound(alarms, hours, 0.95), rel=1e-12)
    assert "## False alarms in the fault-free hours" in p.stdout
    faults = [r for r in read_results(out / "actuator_faults").to_pylist()
              if r["controller"] == "aftc-nrel5mw" and r["fault_type"] == "lock"]
    lock = doc["groups"]["actuator_faults"]["fdi"]["aftc-nrel5mw"]["lock"]
    assert lock["runs"] == len(faults) == 2
    assert lock["detected"] == sum(bool(r["fault_detected"]) for r in faults)
    delays = sorted(r["detection_delay_s"] for r in faults
                    if r["detection_delay_s"] is not None)
    assert lock["max_delay_s"] == (delays[-1] if delays else None)
    assert "pi" not in doc["groups"]["actuator_faults"]["fdi"]


def test_the_same_command_resumes_with_nothing_to_run(card):
    tmp, args, _ = card
    p = wtftc(*args)
    assert p.returncode == 0, p.stderr
    doc = json.loads((tmp / "out" / "scorecard.json").read_text())
    assert all(g["counts"]["scenarios"] for g in doc["groups"].values())
    assert report.markdown(doc) == (tmp / "out" / "scorecard.md").read_text()
    # both calls' wall times kept, the first one's (which ran everything) the longer
    walls = json.loads((tmp / "out" / "walls.json").read_text())
    for group, calls in walls.items():
        assert [c["workers"] for c in calls] == [2, 2]
        assert calls[0]["wall_s"] > calls[1]["wall_s"] > 0.0
        assert doc["groups"][group]["calls"] == calls
        assert f"over its 2 calls ({calls[0]['wall_s']:.0f} s on 2 workers" in p.stdout


@pytest.mark.parametrize("args, field", [
    (("--against", "nope"), "--against"),
    (("--preset", "nope"), "--preset"),
    (("--seeds", 0), "--seeds"),
    (("--against", '{ name = "x", preset = "pi", pi_lpf_corner = [3.0, 6.0] }'),
     "--against.pi_lpf_corner"),
])
def test_a_refusal_is_one_line_and_nothing_runs(tmp_path, args, field):
    p = wtftc("scorecard", "--engine", "wtftc", *args, "--out", tmp_path / "out")
    assert p.returncode == 2, p.stderr
    assert field in p.stderr and p.stderr.count("\n") == 1, p.stderr
    assert not (tmp_path / "out").exists()


def test_a_folder_that_is_not_a_scorecards_is_refused(tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "thesis.md").write_text("mine\n")
    p = wtftc("scorecard", "--engine", "wtftc", "--out", tmp_path / "out")
    assert p.returncode == 2 and "--out" in p.stderr
    assert sorted(x.name for x in (tmp_path / "out").iterdir()) == ["thesis.md"]


def test_a_faults_extremes_are_taken_after_its_onset():
    """The peak and the minimum rotor speed after the onset, against the run's own
    traces; none without a fault."""
    import numpy as np

    from wtftc import config
    from wtftc.artefacts import layout as lay
    from wtftc.campaign import cases
    from wtftc.results.metrics import metrics

    rc = config.make_config({"controller": {"preset": "physical-unaware"},
                             "profile": "realistic", "t_final_s": 40.0,
                             "wind": {"kind": "constant", "speed_mps": 16.0},
                             "fault": [{"blade": 1, "type": "runaway", "target_deg": 0.0,
                                        "onset_s": 32.0}]})
    res = cases.run(rc, progress=False)
    m = metrics(rc, res)
    rated = rc.p_turbine[lay.index("turbine_params", "omega_g_rated")]
    w, t = res.column("omega_r"), res.t
    after = w[t >= 32.0] / rated
    # the outputs at 50 Hz against the metrics from every step: the peak of the sampled
    # trace is at most the true one, and within what 20 ms of the rotor's slow motion moves
    assert after.max() <= m["overspeed_peak_over_rated_after_onset"] < after.max() + 1e-3
    assert after.min() >= m["speed_min_over_rated_after_onset"] > after.min() - 1e-3
    assert m["overspeed_peak_over_rated_after_onset"] <= m["overspeed_peak_over_rated"]
    assert np.isfinite(m["speed_min_over_rated_after_onset"])
    free = config.make_config({"controller": {"preset": "pi"}, "t_final_s": 35.0})
    assert metrics(free, cases.run(free, progress=False))[
        "overspeed_peak_over_rated_after_onset"] is None


def test_a_discon_library_is_scored_in_openfast_only(tmp_path):
    from wtftc.sim import rosco

    assert rosco.available() is None  # (make setup installs ROSCO's library)
    lib, deck = rosco.discon_library(), rosco.discon_path(rosco.NREL5MW_DISCON)
    table = f'{{ name = "own", design = "discon", library = "{lib}", input = "{deck}" }}'
    p = wtftc("scorecard", "--engine", "wtftc", "--against", table, "--out", tmp_path / "o")
    assert p.returncode == 2 and "--against.design = 'discon'" in p.stderr, p.stderr
    assert not (tmp_path / "o").exists()


def test_the_new_groups_are_paired_as_they_should_be(card):
    import math

    tmp, _, p = card
    out = tmp / "out"
    doc = json.loads((out / "scorecard.json").read_text())
    # the baseline as shipped, against its own normal-production runs at the same wind
    # and seed: the ratio by hand
    shipped = read_results(out / "baseline_as_shipped").to_pylist()
    assert {r["controller"] for r in shipped} == {"pi"} and len(shipped) == 2
    normal = {(r["mean_wind_mps"], r["seed"]): r
              for r in read_results(out / "normal_production").to_pylist()
              if r["controller"] == "pi"}
    logs = [math.log(normal[(r["mean_wind_mps"], r["seed"])]["pitch_adc"] / r["pitch_adc"])
            for r in shipped]
    got = next(m for m in doc["groups"]["baseline_as_shipped"]["metrics"]
               if m["metric"] == "pitch_adc")
    assert got["ratio"] == pytest.approx(math.exp(sum(logs) / len(logs)), rel=1e-12)
    assert "## What the benchmark's actuator and sensors cost `pi`" in p.stdout
    # one run per deterministic case and column, each case's ratio its two runs'
    det = read_results(out / "deterministic").to_pylist()
    assert sorted(r["wind_kind"] for r in det) == ["eog", "eog", "ramp", "ramp"]
    cases = doc["groups"]["deterministic"]["by_case"]
    assert set(cases) == {f"{k} at {det[0]['mean_wind_mps']:g} m/s" for k in ("eog", "ramp")}
    for kind in ("eog", "ramp"):
        a, b = (next(r for r in det if r["wind_kind"] == kind and r["controller"] == c)
                for c in ("aftc-nrel5mw", "pi"))
        peak = next(m for m in cases[f"{kind} at {a['mean_wind_mps']:g} m/s"]
                    if m["metric"] == "overspeed_peak_over_rated")
        assert peak["ratio"] == pytest.approx(a["overspeed_peak_over_rated"]
                                              / b["overspeed_peak_over_rated"], rel=1e-12)
    # the sensor faults: outcomes counted per type, the FDI judged in its column only
    sens = doc["groups"]["sensor_faults"]
    assert sum(sum(n.values()) for cols in sens["outcomes"].values()
               for n in cols.values()) == 2 * 2 * 2
    assert set(sens["fdi"]) == {"aftc-nrel5mw"}


def test_the_plan_counts_the_runs_and_runs_nothing(tmp_path):
    from wtftc.campaign.scorecard import matrix

    (tmp_path / "short.toml").write_text(SHORT)
    p = wtftc("scorecard", "--plan", "--matrix", tmp_path / "short.toml", "--seeds", 3,
              "--workers", 2, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    plan = matrix.plan(matrix.load(tmp_path / "short.toml"), None, 3)
    total = sum(g["runs_per_column"] * g["columns"] for g in plan.values())
    # bins × seeds × columns; fault labels (a lock, two runaways) × seeds × columns; sensor
    # types × seeds × columns; kinds × columns, no seeds; one bin × seeds, one column
    assert total == 2 * 3 * 2 + 3 * 3 * 2 + 2 * 3 * 2 + 2 * 2 + 1 * 3 * 1
    assert f"{total} runs;" in p.stdout
    for name, g in plan.items():
        assert any(line.split()[0] == name and line.split()[-3] == str(g["runs_per_column"])
                   for line in p.stdout.splitlines())
    assert sorted(x.name for x in tmp_path.iterdir()) == ["short.toml"]
    q = wtftc("scorecard", "--matrix", tmp_path / "short.toml", cwd=tmp_path)
    assert q.returncode == 2 and q.stderr.startswith("wtftc: error: --out = None")


def test_the_confirmed_outcomes_show_where_the_engines_part():
    held = dict.fromkeys(("failed", "failed_structurally", "brought_down", "tripped"), 0)
    doc = {"screen": 1, "groups": {"actuator_faults": {"confirmed": {"metrics": [], "outcomes": {
        "screen": {"runaway_feather": {"aftc": {**held, "tripped": 1, "held": 0}},
                   "lock": {"aftc": {**held, "held": 2}}},
        "openfast": {"runaway_feather": {"aftc": {**held, "brought_down": 1, "held": 0}},
                     "lock": {"aftc": {**held, "held": 2}}}}}}}}
    lines = report._confirmed_lines(doc)
    assert "| actuator_faults | runaway_feather | aftc | tripped 1 | brought_down 1 |" in lines
    assert not any("| lock |" in line for line in lines)  # held on both: not repeated


def test_ctrl_c_stops_a_scorecard_in_one_line_and_the_same_command_resumes(tmp_path):
    """SIGINT once the first group has saved runs: exit 130, one line saying where the
    finished runs are, no traceback; the same command then runs only what is missing
    and writes the report."""
    import signal
    import time

    (tmp_path / "short.toml").write_text(SHORT)
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "wtftc.cli", "scorecard", "--engine", "wtftc", "--against",
           "pi", "--matrix", str(tmp_path / "short.toml"), "--workers", "2", "--out",
           str(out), "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while proc.poll() is None and time.monotonic() < deadline and not list(
            (out / "actuator_faults").glob("runs/part-*.parquet")):
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err, err
    assert err.strip().splitlines()[-1].startswith("wtftc scorecard: interrupted (SIGINT)")
    assert not (out / "scorecard.json").exists()
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert (out / "scorecard.json").is_file()
