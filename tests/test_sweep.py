"""`wtftc sweep`: sweep files, deterministic runs, Dask execution, kill and resume, summary."""

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases, sweep
from wtftc.errors import ConfigError
from wtftc.model.faults import ACTUATOR_FAULT_TYPES, SENSOR_FAULT_TYPES
from wtftc.results.metrics import metrics

ROOT = Path(__file__).resolve().parents[1]
BASE = {"t_final_s": 20.0, "controllers": ["paper"], "wind": {"mean_mps": 16.0},
        "fault": {"type": ["none", "lock"], "onset_s": 5.0}}


def wtftc(*args, **kw):
    return subprocess.run([sys.executable, "-m", "wtftc.cli", *map(str, args)],
                          capture_output=True, text=True, **kw)


def write_sweep(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize("change, key", [
    ({"colour": 1}, "colour"),
    ({"wind": {"gust": 3}}, "wind.gust"),
    ({"fault": {"type": "lock", "magnitude": 1}}, "fault.magnitude"),
    ({"controllers": []}, "controllers"),
    ({"controllers": ["lqr"]}, "controllers"),
    ({"wind": {"mean_mps": {"min": 18.0, "max": 12.0, "n": 3}}}, "wind.mean_mps.max"),
    ({"wind": {"mean_mps": {"min": 12.0, "max": 18.0}}}, "wind.mean_mps.n"),
    ({"wind": {"mean_mps": "fast"}}, "wind.mean_mps"),
    ({"wind": {"seed": 1.5}}, "wind.seed"),
    ({"wind": {"turbulence_class": "D"}}, "wind.turbulence_class"),
    ({"fault": {"type": "loss_of_effectiveness", "rho": -0.5}}, "fault.rho"),
    ({"fault": {"type": "loss_of_effectiveness", "rho": [0.5, 1.2]}}, "fault.rho"),
    ({"fault": {"type": "loss_of_effectiveness", "rho": 0.0}}, "fault.rho"),
    ({"fault": {"type": "air_in_oil", "severity": -1.0}}, "fault.severity"),
    ({"fault": {"type": "lock", "angle_deg": -5.0}}, "fault.angle_deg"),
    ({"fault": {"type": "lock", "blade": 4}}, "fault.blade"),
    ({"fault": {"type": "lock", "onset_s": 25.0}}, "fault.onset_s"),
    ({"mode": "latin"}, "mode"),
    ({"mode": "random"}, "samples"),
    ({"samples": 10}, "samples"),
    ({"batch_size": 0}, "batch_size"),
    ({"t_final_s": "1 min"}, "t_final_s"),
    ({"fault": {"type": "pitch_sensor_offset", "sensor": 3}}, "fault.sensor"),
    ({"fault_free_twins": True}, "fault_free_twins"),  # a grid
    ({"mode": "random", "samples": 2, "fault_free_twins": "yes"}, "fault_free_twins"),
])
def test_malformed_sweep_files_are_rejected_naming_the_key(change, key):
    with pytest.raises(ConfigError) as exc:
        sweep.parse_sweep({**BASE, **change})
    assert exc.value.field == key, str(exc.value)


def test_bad_sweep_file_on_the_command_line_exits_2_and_writes_nothing(tmp_path):
    f = write_sweep(tmp_path / "bad.toml", 'controllers = ["paper"]\n[fault]\n'
                    'type = "loss_of_effectiveness"\nrho = 1.5\n')
    p = wtftc("sweep", f, "--out", tmp_path / "res")
    assert p.returncode == 2
    assert "fault.rho = 1.5 is not allowed" in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "res").exists()


def test_runs_follow_from_the_sweep_file_deterministically():
    grid = sweep.parse_sweep({**BASE, "controllers": ["paper", "physical-plain"],
                              "fault": {"type": ["none", "lock"], "blade": [1, 2, 3],
                                        "onset_s": 5.0}})
    runs, dup = sweep.expand(grid)
    # the fault-free run does not depend on the blade: 2 controllers × (1 + 3 blades)
    assert len(runs) == 8 and dup == 4
    assert [r["run_id"] for r in runs] == [r["run_id"] for r in sweep.expand(grid)[0]]
    assert len({r["run_id"] for r in runs}) == 8
    rnd = {**BASE, "mode": "random", "samples": 6, "sampling_seed": 3,
           "wind": {"mean_mps": {"min": 12.0, "max": 20.0}, "seed": {"min": 0, "max": 999}},
           "fault": {"type": ["none", "lock", "air_in_oil"], "blade": {"min": 1, "max": 3},
                     "onset_s": {"min": 2.0, "max": 15.0}, "severity": {"min": 0.3, "max": 1}}}
    one = sweep.expand(sweep.parse_sweep(rnd))[0]
    two = sweep.expand(sweep.parse_sweep({**rnd, "controllers": ["paper", "pi"]}))[0]
    assert len(one) == 6 and len(two) == 12
    # scenarios do not depend on the controllers swept: each is run by every controller
    scen = [{k: r[k] for k in ("mean_wind_mps", "seed", "fault_type", "blade", "onset_s")}
            for r in two if r["controller"] == "paper"]
    assert scen == [{k: r[k] for k in scen[0]} for r in one]
    assert all(12 <= r["mean_wind_mps"] <= 20 for r in one)
    # every run's configuration is a valid run configuration, with its id as label
    rc = config.make_config(one[0]["config"])
    assert rc.label == f"sweep-{one[0]['run_id']}"


def test_the_sweeps_lists_are_the_one_lists():
    """Fault types, plants and turbulence classes come from where they are defined (one
    list each): a sweep offers each pitch actuator fault type, each plant of the loop."""
    from wtftc.model import wind
    from wtftc.sim import rhs

    assert sweep.FAULT_TYPES == ("none", *ACTUATOR_FAULT_TYPES, *SENSOR_FAULT_TYPES)
    assert sweep.PLANTS == tuple(rhs.PLANTS)
    assert sweep.TURBULENCE_CLASSES == tuple(wind.I_REF)
    with pytest.raises(ConfigError, match="one of none, lock, loss_of_effectiveness"):
        sweep.parse_sweep({**BASE, "fault": {"type": "sensor_gain"}})


def test_a_diverging_run_is_recorded_with_time_state_and_cause_and_a_bad_one_as_failed():
    sw = sweep.parse_sweep({**BASE, "fault": {"type": "none"}})
    ok = sweep.expand(sw)[0][0]
    diverging = json.loads(json.dumps(ok))
    from conftest import DIVERGING_RUN

    diverging["config"].update(DIVERGING_RUN)  # a gusty wind the paper's design diverges in
    diverging["run_id"] = "diverging"
    broken = json.loads(json.dumps(ok))
    broken["config"]["dt_s"] = 0.5  # beyond the loop's stability limit
    broken["run_id"] = "broken"
    out = sweep.run_task([ok, diverging, broken])
    rows = {r["run_id"]: r for r, _ in out}
    assert rows[ok["run_id"]]["status"] == "ok"
    assert 0 < rows[ok["run_id"]]["rms_speed_error_rad_s"] < 0.1  # the paper design, noisy
    d = rows["diverging"]
    assert d["status"] == "diverged" and 10 < d["diverged_at_s"] < 40
    assert "xhat_4" in d["cause"]
    assert d["cause"] and json.loads(d["diverged_state"])
    assert rows["broken"]["status"] == "failed" and "dt_s" in rows["broken"]["cause"]
    # the run that ran beside them is the run alone, bit for bit
    rc = config.make_config(ok["config"])
    alone = metrics(rc, cases.run(rc, progress=False))
    assert rows[ok["run_id"]]["rms_speed_error_rad_s"] == alone["rms_speed_error_rad_s"]


KILL_SWEEP = """
t_final_s = 20.0
batch_size = 1
controllers = ["paper"]
[wind]
mean_mps = [13.0, 15.0, 17.0, 19.0]
seed = [0, 1, 2, 3]
[fault]
type = ["none", "loss_of_effectiveness"]
blade = 2
onset_s = 5.0
rho = 0.6
"""


def _parts(out: Path) -> list[Path]:
    return list((out / "runs").glob("part-*.parquet")) if (out / "runs").exists() else []


def test_kill_and_resume_on_a_local_two_worker_cluster(tmp_path):
    """SIGTERM in the middle of a sweep on 2 local workers: every finished run is saved;
    the same command resumes, runs only what is missing, and no run is saved twice."""
    f = write_sweep(tmp_path / "kill.toml", KILL_SWEEP)
    out = tmp_path / "res"
    total = len(sweep.expand(sweep.load_sweep(f))[0])
    assert total == 32
    cmd = [sys.executable, "-m", "wtftc.cli", "sweep", str(f), "--out", str(out),
           "--workers", "2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while len(_parts(out)) < 3 and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted (SIGTERM)" in err
    saved = sweep.read_results(out).column("run_id").to_pylist()
    assert 3 <= len(saved) < total, "the sweep must be killed in the middle"
    assert len(set(saved)) == len(saved)
    assert not [p for p in (out / "runs").iterdir() if not p.name.startswith("part-")]
    assert not (out / "sweep.lock").exists(), "an interrupted sweep releases its folder"

    again = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert f"{len(saved)} already in" in again.stdout
    assert f"{total - len(saved)} runs done now, {total} of {total} saved" in again.stdout
    ids = sweep.read_results(out).column("run_id").to_pylist()
    assert sorted(ids) == sorted(r["run_id"] for r in sweep.expand(sweep.load_sweep(f))[0])
    # a third call finds nothing to do
    third = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert third.returncode == 0 and "0 to run" in third.stdout

    # a changed sweep file is refused for that folder, unless told to start anew
    write_sweep(f, KILL_SWEEP.replace("rho = 0.6", "rho = 0.7"))
    p = wtftc("sweep", f, "--out", out)
    assert p.returncode == 2 and "changed" in p.stderr and "--overwrite" in p.stderr
    assert sweep.read_results(out).num_rows == total


def test_example_sweep_on_an_existing_scheduler_and_its_summary(tmp_path):
    """examples/sweep_small.toml through --scheduler (a cluster started here, as a user's
    would be), the saved runs equal to runs alone, then --summary and --show."""
    from dask.distributed import LocalCluster

    out = tmp_path / "small"
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        p = wtftc("sweep", ROOT / "examples" / "sweep_small.toml", "--out", out,
                  "--scheduler", cluster.scheduler_address, "--traces", timeout=300)
    assert p.returncode == 0, p.stderr
    assert "32 of 32 saved" in p.stdout
    table = sweep.read_results(out)
    assert table.num_rows == 32 and set(table.column("status").to_pylist()) == {"ok"}
    assert table.schema.field("rms_speed_error_rad_s").metadata[b"unit"] == b"rad/s"
    rows = table.to_pylist()
    fdi = [r for r in rows if r["controller"] == "physical-plain" and r["fault_type"] != "none"]
    assert all(0 <= r["detection_delay_s"] < 2.0 and r["isolation_correct"] for r in fdi)
    assert all(r["false_alarms"] == 0 for r in rows)
    # any saved run re-runs alone to the same numbers, from its saved configuration
    r = rows[5]
    shown = wtftc("sweep", "--show", r["run_id"], "--out", out)
    assert shown.returncode == 0, shown.stderr
    (tmp_path / "one.toml").write_text(shown.stdout)
    rc = config.make_config(config.load_toml(tmp_path / "one.toml"))
    res = cases.run(rc, progress=False)
    assert metrics(rc, res)["rms_speed_error_rad_s"] == r["rms_speed_error_rad_s"]
    import pyarrow.parquet as pq

    tr = pq.read_table(out / "traces" / f"{r['run_id']}.parquet")
    np.testing.assert_array_equal(tr.column("omega_r").to_numpy(), res.column("omega_r"))

    s = wtftc("sweep", "--summary", out)
    assert s.returncode == 0, s.stderr
    assert "32 of 32 runs saved" in s.stdout
    assert "| physical-plain | lock | 4 | 0 | 0 |" in s.stdout
    assert {"rms_speed_error.png", "overspeed.png", "detection_delay.png"} <= {
        q.name for q in (out / "figures").iterdir()}
    assert (out / "summary.csv").read_text().count("\n") == 1 + 8


def test_unreachable_scheduler_is_a_clear_error(tmp_path):
    p = wtftc("sweep", ROOT / "examples" / "sweep_small.toml", "--out", tmp_path / "x",
              "--scheduler", "tcp://127.0.0.1:9", timeout=120)
    assert p.returncode == 2, p.stderr
    assert "--scheduler = 'tcp://127.0.0.1:9' is not allowed" in p.stderr
    assert "connection was refused" in p.stderr  # said at once, not after Dask's 10 s
    assert "Traceback" not in p.stderr
    assert not (tmp_path / "x").exists()  # refused before anything was written


def _answering_not_dask() -> tuple[socket.socket, threading.Thread]:
    """A local TCP server that answers every connection with bytes that are not Dask's."""
    server = socket.create_server(("127.0.0.1", 0))

    def serve():
        while True:
            try:
                conn, _ = server.accept()
            except OSError:  # closed
                return
            with conn:
                conn.sendall(b"\xff" * 64)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    return server, thread


@pytest.mark.parametrize("what", ["not_dask", "port"])
def test_a_scheduler_address_that_cannot_be_dask_is_a_clear_error(tmp_path, what):
    server = None
    if what == "not_dask":
        server, _ = _answering_not_dask()
        # Dask reads its reply as a frame of absurd length: a ValueError here, a
        # MemoryError behind a proxy that answered with more bytes
        address, said = f"tcp://127.0.0.1:{server.getsockname()[1]}", "tcp://HOST:PORT ("
    else:
        address, said = "tcp://127.0.0.1:99999999999999999999", "outside 1-65535"
    try:
        p = wtftc("sweep", ROOT / "examples" / "sweep_small.toml", "--out", tmp_path / "x",
                  "--scheduler", address, timeout=120)
    finally:
        if server is not None:
            server.close()
    assert p.returncode == 2, p.stderr
    assert f"--scheduler = '{address}' is not allowed" in p.stderr and said in p.stderr
    assert "Traceback" not in p.stderr
    assert not (tmp_path / "x").exists()


def test_summary_of_a_folder_that_is_not_a_sweep(tmp_path):
    p = wtftc("sweep", "--summary", tmp_path)
    assert p.returncode == 2 and "sweep's results folder" in p.stderr


def test_robustness_campaign_file_is_valid_and_large_enough():
    sw = sweep.load_sweep(ROOT / "examples" / "robustness.toml")
    runs, _ = sweep.expand(sw)
    generated = [r for r in runs if r["controller"] != "rosco"]
    assert len(generated) >= 1000
    # the benchmark's actuator faults (the DLC 2.x runaway has its own campaign,
    # examples/dlc2x.toml)
    benchmark = tuple(t for t in ACTUATOR_FAULT_TYPES if t != "runaway")
    assert {r["fault_type"] for r in runs} == {"none", *benchmark}
    assert {(r["fault_type"], r["blade"]) for r in runs if r["fault_type"] != "none"} == {
        (f, b) for f in benchmark for b in (1, 2, 3)}
    assert {r["turbulence_class"] for r in runs} == {"A", "B", "C"}
    assert os.path.getsize(ROOT / "examples" / "robustness.toml") < 4000


def test_hydraulic_fault_severity_moves_the_actuator_part_of_the_way():
    """severity s: ω_n = ω_n0 + s (ω_n,fault − ω_n0), the same for ζ (docs/running.md)."""
    from wtftc.model.faults import HYDRAULIC, Schedule, parse_faults

    full = Schedule(parse_faults([{"blade": 3, "type": "air_in_oil", "onset_s": 1.0}]))
    half = Schedule(parse_faults([{"blade": 3, "type": "air_in_oil", "onset_s": 1.0,
                                   "severity": 0.5}]))
    a_full, a_half = full.actuator([0.0, 2.0]), half.actuator([0.0, 2.0])
    wn, zeta = lay.index("actuator_faults", "omega_n_3"), lay.index("actuator_faults", "zeta_3")
    wn0, z0 = a_full[wn, 0], a_full[zeta, 0]  # before the onset: nominal
    assert (wn0, z0) == pytest.approx((11.11, 0.6))
    assert (a_full[wn, 1], a_full[zeta, 1]) == pytest.approx(HYDRAULIC["air_in_oil"])
    assert a_half[wn, 1] == pytest.approx(0.5 * (wn0 + HYDRAULIC["air_in_oil"][0]))
    assert a_half[zeta, 1] == pytest.approx(0.5 * (z0 + HYDRAULIC["air_in_oil"][1]))
    with pytest.raises(ConfigError, match="severity"):
        parse_faults([{"blade": 1, "type": "pressure_drop", "severity": 0.0}])


def test_a_sigterm_while_waiting_stops_the_sweep_not_a_task(monkeypatch, tmp_path):
    """The SIGTERM handler raises Interrupted wherever the main thread is; while it waits on
    a task's result that must stop the sweep, not be counted as a lost task (it once was:
    the sweep went on to the end and exited 1)."""
    import dask.distributed

    class Waiting:
        def result(self):
            raise sweep.Interrupted("SIGTERM")

    monkeypatch.setattr(dask.distributed, "as_completed", lambda futures: iter(futures))
    progress = sweep._Progress(2, 0, True)
    with pytest.raises(sweep.Interrupted, match="SIGTERM"):
        sweep._collect([Waiting(), Waiting()], tmp_path, set(), progress, quiet=True)


def test_a_sweep_too_large_to_list_is_refused_before_anything(tmp_path):
    """A grid of 2e10 runs once used 2 GB in 40 s without a word: now it is refused at
    once, with the axes' sizes, and nothing is written."""
    f = write_sweep(tmp_path / "huge.toml", 'mode = "grid"\nt_final_s = 5.0\n'
                    'controllers = ["physical-plain", "paper"]\n[wind]\n'
                    "mean_mps = { min = 12.0, max = 20.0, n = 100000 }\n"
                    "seed = { min = 0, max = 99999 }\n")
    t0 = time.monotonic()
    p = wtftc("sweep", f, "--out", tmp_path / "out", timeout=60)
    assert p.returncode == 2 and "20,000,000,000 runs" in p.stderr, p.stderr
    assert "wind.seed: 100000" in p.stderr and "Traceback" not in p.stderr
    assert time.monotonic() - t0 < 30 and not (tmp_path / "out").exists()


def test_a_fault_free_short_sweep_needs_no_onset(tmp_path):
    """The default onset (20 s) used to refuse a 5-s sweep without faults: a value the user
    never wrote. The default now fits the run."""
    sw = sweep.parse_sweep({"mode": "grid", "t_final_s": 5.0, "controllers": ["paper"]})
    runs, _ = sweep.expand(sw)
    assert len(runs) == 1 and runs[0]["fault_type"] == "none"


def test_overwrite_never_removes_a_folder_that_is_not_a_sweeps(tmp_path):
    """--overwrite used to rmtree any non-empty --out (even the current folder, --out "")."""
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    for out, cwd in ((mine, None), ("", mine), (".", mine)):
        p = wtftc("sweep", ROOT / "examples" / "sweep_small.toml", "--out", out,
                  "--overwrite", cwd=cwd, timeout=120)
        assert p.returncode == 2 and "--out" in p.stderr and "Traceback" not in p.stderr
        assert (mine / "notes.txt").read_text() == "keep me"


def test_a_damaged_sweep_json_is_one_line_and_overwrite_recovers(tmp_path):
    out = tmp_path / "d"
    out.mkdir()
    for text in ("not json", '{"a": 1}'):
        (out / "sweep.json").write_text(text)
        p = wtftc("sweep", ROOT / "examples" / "sweep_small.toml", "--out", out, timeout=120)
        assert p.returncode == 2 and "damaged" in p.stderr and "Traceback" not in p.stderr


def test_mismatch_is_an_axis_and_a_column():
    """[mismatch] factors sweep like any other key: drawn per scenario in random mode,
    passed to each run's configuration, and saved as mismatch_<key> columns; absent, the
    configuration has no mismatch (run ids of earlier sweeps unchanged)."""
    raw = {**BASE, "mode": "random", "samples": 3, "fault": {"type": "none"},
           "mismatch": {"inertia": {"min": 0.9, "max": 1.1}, "cp_scale": [0.95, 1.05]}}
    runs = sweep.expand(sweep.parse_sweep(raw))[0]
    for r in runs:
        mm = r["config"]["mismatch"]
        assert 0.9 <= mm["inertia"] <= 1.1 and mm["cp_scale"] in (0.95, 1.05)
        assert r["mismatch_inertia"] == mm["inertia"] and r["mismatch_shaft_stiffness"] == 1.0
    plain = sweep.expand(sweep.parse_sweep({**BASE, "fault": {"type": "none"}}))[0]
    assert all("mismatch" not in r["config"] for r in plain)
    rows = sweep.run_task(runs[:1])
    assert rows[0][0]["mismatch_inertia"] == runs[0]["mismatch_inertia"]
    with pytest.raises(ConfigError) as exc:
        sweep.parse_sweep({**raw, "mismatch": {"mass": 1.1}})
    assert exc.value.field == "mismatch.mass"


def test_fault_free_twins_pair_every_scenario_and_give_the_rms_ratio(tmp_path):
    """``fault_free_twins``: each random scenario runs again without its fault (same wind,
    seed, mismatch), and the summary gives each fault type's RMS error over its twin's;
    the sensor axis names the failed sensor (the fault_sensor column)."""
    text = """mode = "random"
samples = 3
sampling_seed = 2
t_final_s = 4.0
controllers = ["physical-plain"]
fault_free_twins = true
profile = "ideal"
[wind]
mean_mps = { min = 14.0, max = 18.0 }
seed = { min = 0, max = 9 }
[fault]
type = ["pitch_sensor_offset"]
onset_s = 1.0
sensor = 2
offset_deg = 2.0
[mismatch]
inertia = { min = 0.9, max = 1.1 }
"""
    path = write_sweep(tmp_path / "twins.toml", text)
    runs, _ = sweep.expand(sweep.load_sweep(path))
    faulty = [r for r in runs if r["fault_type"] != "none"]
    twins = [r for r in runs if r["fault_type"] == "none"]
    assert len(faulty) == len(twins) == 3
    for f, t in zip(faulty, twins, strict=True):
        same = ("mean_wind_mps", "seed", "turbulence_class", "mismatch_inertia")
        assert all(f[k] == t[k] for k in same) and f["fault_sensor"] == 2
        assert f["config"]["fault"][0]["sensor"] == 2
    out = tmp_path / "tw"
    sweep.run_sweep(path, out, workers=1, quiet=True)
    text = sweep.summarize(out)
    row = next(line for line in text.splitlines() if "pitch_sensor_offset" in line)
    ratio_median = float(row.strip("|").split("|")[-2])
    # a pitch sensor offset, excluded by the FDI: the run is its twin's, bit for bit
    # before the onset and within a few % after (ideal profile)
    assert 0.9 < ratio_median < 1.1


def test_a_folder_another_sweep_is_writing_to_is_refused_until_its_holder_is_gone(tmp_path):
    """Two sweeps into one folder each saved the other's runs again (issue 18's families:
    a second copy launched by mistake). A sweep holds its folder with an exclusive flock
    on sweep.lock (its pid and host in it): a second one is refused in one line naming the
    holder, the folder untouched even with --overwrite. The kernel drops the lock when the
    holder dies (killed here), so the folder is free again; a finished sweep removes its
    lock file."""
    out = tmp_path / "res"
    out.mkdir()
    holder = subprocess.Popen([sys.executable, "-c", (
        "import fcntl, os, socket, sys, time\n"
        f"fd = os.open({str(out / 'sweep.lock')!r}, os.O_CREAT | os.O_RDWR)\n"
        "fcntl.flock(fd, fcntl.LOCK_EX)\n"
        "os.write(fd, f'{os.getpid()} {socket.gethostname()}'.encode())\n"
        "print('held', flush=True)\n"
        "time.sleep(120)\n")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        for extra in ((), ("--overwrite",)):
            p = wtftc("sweep", ROOT / "examples" / "sweep_small.toml", "--out", out, *extra,
                      timeout=120)
            assert p.returncode == 2 and "Traceback" not in p.stderr
            assert f"process {holder.pid}" in p.stderr and "sweep.lock" in p.stderr
            assert sorted(c.name for c in out.iterdir()) == ["sweep.lock"]
    finally:
        holder.kill()
        holder.wait()
    # the holder is gone, its file left behind unlocked: the sweep takes the folder
    assert (out / "sweep.lock").exists()
    small = write_sweep(tmp_path / "one.toml", """
name = "one run"
mode = "grid"
t_final_s = 2.0
controllers = ["pi"]
""")
    p = wtftc("sweep", small, "--out", out, timeout=300)
    assert p.returncode == 0, p.stderr
    assert sweep.read_results(out).num_rows == 1
    assert not (out / "sweep.lock").exists()


@pytest.mark.parametrize("ctrl", ["rosco", "rosco-matched"])
def test_rosco_and_its_variants_are_refused_on_the_paper_plant(ctrl):
    """ROSCO's DISCON.IN is the NREL 5-MW's: a column of design rosco (rosco-matched
    retuned, allowed as an optional controller, too), on plant paper is refused when the
    sweep file is read, not run by run."""
    for raw in ({**BASE, "controllers": ["pi", ctrl], "plants": ["paper"]},
                {**BASE, "controllers": ["pi"], "optional_controllers": [ctrl],
                 "plants": ["paper"]}):
        with pytest.raises(ConfigError) as e:
            sweep.parse_sweep(raw)
        assert e.value.field == "plants" and ctrl in e.value.allowed


def test_the_last_progress_line_has_no_run_in_flight_and_no_negative_eta(capsys):
    """The watcher reports the runs in OpenFAST every few seconds; its last report can name
    a run the sweep has just saved. The final line once read "0 remaining (1 in OpenFAST
    at 310/330 s), ETA -121 s"."""
    progress = sweep._Progress(2, 1, quiet=False)
    progress.tty = False
    progress.show_running([(310.0, 330.0)])
    progress.update([{"status": "ok"}], end=True)
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert "2/2 runs: 1 ok" in last and "0 remaining," in last, last
    assert "in OpenFAST" not in last and "ETA 0 s" in last, last


def test_a_stop_whose_exception_was_swallowed_still_stops_the_collection(tmp_path,
                                                                          monkeypatch):
    """The SIGTERM handler's exception is lost where it lands in a finalizer (a
    ParquetWriter's __del__ swallowed one, and the sweep ran to its end): _collect checks
    the signal it recorded, before each task's results and after the last, and stops
    with it."""
    import dask.distributed

    from wtftc.campaign import sweep as sw

    monkeypatch.setattr(dask.distributed, "as_completed", iter)  # no cluster needed here

    class Never:  # a task whose results must not be read once the sweep is stopped
        def result(self):
            raise AssertionError("read after the stop")

    progress = sw._Progress(1, 0, True)
    for futures in ([], [Never()]):
        with pytest.raises(sw.Interrupted, match="SIGTERM"):
            sw._collect(futures, tmp_path, set(), progress, True, stopped=lambda: "SIGTERM")
    assert sw._collect([], tmp_path, set(), progress, True) == (0, 0)


# --- runs in OpenFAST: a run killed from outside, one past its time limit, a bad deck,
# --- and a resume while an earlier sweep's OpenFAST still runs


def _openfast_point(run_id: str = "r1") -> dict:
    sw = sweep.parse_sweep({"t_final_s": 4.0, "controllers": ["pi"], "engine": "openfast",
                            "wind": {"mean_mps": 16.0}})
    pt = sweep.expand(sw)[0][0]
    return {**pt, "run_id": run_id}


@pytest.mark.parametrize("error, status", [
    ("killed", "unfinished"),  # ProgramKilled: another's signal, not this run's failure
    ("busy", "unfinished"),  # FolderBusy: an earlier sweep's OpenFAST holds the folder
    ("timed out", "failed"),  # the time limit (programs.TimedOut): a failure, kept
])
def test_a_run_killed_from_outside_is_unfinished_and_a_timed_out_one_failed(
        error, status, tmp_path, monkeypatch):
    """In a task, a run whose OpenFAST another's signal ended (or whose case folder an
    earlier sweep's OpenFAST holds) is "unfinished": not saved, so that a plain resume
    runs it again. One past its time limit is "failed" with its cause, saved, and
    --retry-failed (drop_failed) takes it out to run again."""
    from wtftc.errors import EngineError, ProgramKilled
    from wtftc.programs import FolderBusy, TimedOut

    raised = {"killed": ProgramKilled("OpenFAST was ended by SIGKILL, not sent by wtftc"),
              "busy": FolderBusy("OpenFAST case folder", str(tmp_path), "a folder no other "
                                 "run is using"),
              "timed out": TimedOut("OpenFAST timed out after 140 s")}[error]
    assert isinstance(raised, EngineError) == (error != "busy")

    def run(rc, progress=True, keep_states=False, openfast_dir=None):
        raise raised

    monkeypatch.setattr(cases, "run", run)
    (row, tr), = sweep.run_task([_openfast_point()])
    assert row["status"] == status and type(raised).__name__ in row["cause"], row
    from wtftc.campaign.sweep import store

    out = tmp_path / "res"
    (out / "runs").mkdir(parents=True)
    done: set[str] = set()
    saved = store._save_batch(out, done, [(row, tr)])
    if status == "unfinished":
        assert saved == [] and done == set() and sweep.read_results(out).num_rows == 0
    else:
        assert done == {"r1"} and sweep.count_status(out)["failed"] == 1
        assert "timed out" in sweep.read_results(out).column("cause")[0].as_py()
        assert store.drop_failed(out) == 1 and sweep.read_results(out).num_rows == 0


FAKE_OPENFAST = """#!/bin/sh
# OpenFAST for a short case (TMax below 1 s: the sweep's check of its deck); ended by
# SIGKILL, as by another process or the machine, on any longer one
if [ "$1" = "-v" ]; then exec {real} "$@"; fi
case "$(awk '$2 == "TMax" {{print $1}}' "$1")" in
  0.*) exec {real} "$@" ;;
esac
kill -9 $$
"""


def _hold(lock: Path):
    """A process holding ``lock`` as an OpenFAST under wtftc.programs.folder_lock does."""
    holder = subprocess.Popen([sys.executable, "-c", (
        "import fcntl, os, time\n"
        f"fd = os.open({str(lock)!r}, os.O_CREAT | os.O_RDWR)\n"
        "fcntl.flock(fd, fcntl.LOCK_EX)\n"
        "os.ftruncate(fd, 0); os.pwrite(fd, f'{os.getpid()}'.encode(), 0)\n"
        "print('held', flush=True)\n"
        "time.sleep(120)\n")], stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    return holder


def test_a_killed_openfast_is_resumed_and_never_raced(tmp_path):
    """A sweep in OpenFAST whose OpenFAST is SIGKILLed by another (a stand-in OpenFAST
    that kills itself): its run is unfinished, not saved as failed, the sweep exits 1
    saying so. Resumed while an earlier sweep's OpenFAST still holds that run's case
    folder: refused in one line naming the process, nothing run. Once it is gone, a plain
    resume (no --retry-failed) runs it, in the real OpenFAST."""
    from wtftc.openfast import install
    from wtftc.programs import LOCK_NAME

    inst = install.require()
    fake = tmp_path / "bin" / "openfast"
    fake.parent.mkdir()
    fake.write_text(FAKE_OPENFAST.format(real=inst.openfast))
    fake.chmod(0o755)
    env = {**os.environ, "OPENFAST": str(fake), "TURBSIM": str(inst.turbsim)}
    f = write_sweep(tmp_path / "of.toml", 't_final_s = 4.0\ncontrollers = ["pi"]\n'
                    "[wind]\nmean_mps = 16.0\n")
    out = tmp_path / "res"
    p = wtftc("sweep", f, "--engine", "openfast", "--workers", 1, "--out", out,
              env=env, timeout=600)
    assert p.returncode == 1, p.stderr
    last = p.stdout.strip().splitlines()[-1]
    assert "0 of 1 saved" in last and "0 failed" in last and "1 unfinished" in last, last
    assert sweep.read_results(out).num_rows == 0
    (case,) = (out / "openfast").iterdir()
    holder = _hold(case / LOCK_NAME)
    try:
        p = wtftc("sweep", f, "--engine", "openfast", "--workers", 1, "--out", out,
                  timeout=600)
        err = p.stderr.strip().splitlines()
        assert p.returncode == 2 and len(err) == 1 and "Traceback" not in p.stderr, p.stderr
        assert f"process {holder.pid}" in err[0] and case.name in err[0], err
        assert sweep.read_results(out).num_rows == 0 and not (out / "sweep.lock").exists()
    finally:
        holder.kill()
        holder.wait()
    p = wtftc("sweep", f, "--engine", "openfast", "--workers", 1, "--out", out, timeout=600)
    assert p.returncode == 0, p.stderr
    assert [r["status"] for r in sweep.read_results(out).to_pylist()] == ["ok"]


def test_a_deck_every_run_would_fail_on_is_refused_before_the_first_run(tmp_path, capsys):
    """A turbine file whose deck OpenFAST stops on at its start (ElastoDyn's HubRad
    negative, which no check of wtftc's reads): the sweep writes the first run's case
    into a temporary folder, starts OpenFAST on it, and refuses in one line naming the
    turbine file's openfast_deck and OpenFAST's own reason, exit 2, before any run: no
    results folder."""
    import shutil

    from wtftc.cli import main
    from wtftc.model import turbine_file

    src = config.openfast_deck(turbine_file.load("nrel5mw"))
    deck = tmp_path / "deck"
    shutil.copytree(src.parent, deck)
    ed = deck / "NRELOffshrBsline5MW_Onshore_ElastoDyn.dat"
    text = ed.read_text()
    assert "        1.5   HubRad" in text
    ed.write_text(text.replace("        1.5   HubRad", "       -1.5   HubRad"))
    base = turbine_file.load("nrel5mw")
    tfile = tmp_path / "mine.toml"
    tfile.write_text(Path(base.path).read_text()
                     .replace('cp_table = "Cp_Ct_Cq.NREL5MW.txt"', f'cp_table = "{base.cp_path}"')
                     .replace('openfast_deck = "rosco:Examples/Test_Cases/NREL-5MW/NREL-5MW.fst"',
                              f'openfast_deck = "{deck / src.name}"'))
    f = write_sweep(tmp_path / "of.toml", f't_final_s = 4.0\ncontrollers = ["pi"]\n'
                    f'turbine = "{tfile}"\n[wind]\nmean_mps = [16.0, 18.0]\n')
    out = tmp_path / "res"
    assert main(["sweep", str(f), "--engine", "openfast", "--workers", "1", "--out",
                 str(out), "--quiet"]) == 2
    text = capsys.readouterr().err
    # (a cache entry rebuilt on the way says so in a line of its own)
    err = [line for line in text.splitlines() if not line.startswith("wtftc: rebuilt")
           and "is damaged" not in line]
    assert "Traceback" not in text and len(err) == 1, text
    assert "openfast_deck" in err[0] and str(tfile) in err[0], err
    assert "HubRad must not be negative" in err[0], err
    assert not out.exists()
