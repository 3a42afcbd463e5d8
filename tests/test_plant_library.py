"""The plant-side actuator, fault and sensor library (issue 32, wtftc.openfast.plant_library).

The library is called through ctypes as ServoDyn calls it, around a scripted controller
library (demands that are a known function of time, the readings it gets logged back).
Its blades are checked against wtftc's own actuator model: the generated
``pitch_actuator`` (itself checked against the actuator rows of wtftc's plants), RK4 at
the same step, fault inputs from wtftc.model.faults.Schedule."""

from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path

import numpy as np
import pytest

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import compiler, load
from wtftc.model.faults import Schedule, parse_faults
from wtftc.openfast import plant_library as pl

SWAP = 500
#: a controller whose demands are a known function of time (steps beyond the rate and
#: position limits, a ramp), that logs the readings it was handed (#21, #20, #4, #33, #34)
SCRIPTED = r"""
#include <math.h>
#include <string.h>
void DISCON(float *s, int *fail, char *in, char *out, char *msg) {
    double t = s[1];
    double d1 = t < 0.5 ? 0.05 : (t < 1.2 ? 0.60 : 0.10);
    double d2 = 0.02 + 0.3 * t;
    double d3 = t < 1.0 ? -0.2 : 1.9;
    s[41] = (float)d1; s[42] = (float)d2; s[43] = (float)d3; s[44] = (float)d1;
    s[46] = 1234.5f;
    int first = (int)s[62];
    if (first >= 1) {
        s[first - 1] = s[20]; s[first] = s[19];
        s[first + 1] = s[3]; s[first + 2] = s[32]; s[first + 3] = s[33];
        s[64] = 5.0f;
    }
    *fail = strlen(in) > 0 ? 0 : -1;
}
"""
INTERVAL = 0.01
T_END = 2.0


def demands(t: float) -> np.ndarray:
    return np.array([0.05 if t < 0.5 else (0.60 if t < 1.2 else 0.10), 0.02 + 0.3 * t,
                     -0.2 if t < 1.0 else 1.9], dtype=np.float32).astype(float)


@pytest.fixture(scope="module")
def scripted(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("scripted")
    (folder / "scripted.c").write_text(SCRIPTED)
    lib = folder / "libscripted.so"
    subprocess.run([compiler(), "-O2", "-shared", "-fPIC", "-o", str(lib),
                    str(folder / "scripted.c")], check=True)
    return lib


def _drive(tmp: Path, scripted: Path, faults: list[dict], noise_seed: int | None,
           sigma: float = 0.0, omega=lambda t: 1.2 + 0.01 * t) -> dict:
    """Call the library as ServoDyn would, every INTERVAL from 0 to T_END."""
    p_t = lay.defaults("turbine_params")
    p_s = lay.defaults("sensor_params").copy()
    for name in lay.names("sensor_params"):
        if name.startswith("sigma_"):
            p_s[lay.index("sensor_params", name)] = sigma
    sched = Schedule(parse_faults(faults), tuple(p_t))
    n_calls = int(round(T_END / INTERVAL)) + 1
    settings = pl.Settings(scripted, scripted, tmp / "records.bin", p_t, p_s, sched.faults)
    if noise_seed is not None:
        settings.noise = tmp / "noise.bin"
        settings.noise_columns = pl.noise_table(noise_seed, n_calls, INTERVAL, sched,
                                                settings.noise)
    infile = settings.write(tmp / "plant.in")
    dll = ctypes.CDLL(str(pl.build()))
    swap = np.zeros(SWAP, dtype=np.float32)
    fail = ctypes.c_int(0)
    name = str(infile).encode() + b"\0"
    msg = ctypes.create_string_buffer(1024)
    out = ctypes.create_string_buffer(1024)
    seen = []
    for k in range(n_calls):
        t = k * INTERVAL
        swap[0] = 0 if k == 0 else (-1 if k == n_calls - 1 else 1)
        swap[1], swap[2] = t, INTERVAL
        if k == 0:
            swap[3] = swap[32] = swap[33] = 0.1
        swap[19], swap[20] = omega(t) * 97.0, omega(t)
        swap[27], swap[48], swap[49], swap[62] = 1, 1024, len(name) - 1, 165
        dll.DISCON(swap.ctypes.data_as(ctypes.POINTER(ctypes.c_float)), ctypes.byref(fail),
                   ctypes.c_char_p(name), out, msg)
        assert fail.value == 0, msg.value
        seen.append(swap[[41, 42, 43, 44, 46]].astype(float))
    return {"records": pl.read_records(tmp / "records.bin"), "returned": np.array(seen),
            "schedule": sched, "p_turbine": p_t, "p_sensors": p_s, "n_calls": n_calls}


def _reference_blades(run: dict, beta0: float = float(np.float32(0.1))) -> np.ndarray:
    """wtftc's actuator: RK4 at ACTUATOR_DT on the generated pitch_actuator, the demand of
    each call held until the next (OpenFAST hands the first pitch as a float), fault
    inputs from Schedule at each step's start, a lock "where the blade is" bound as the
    sampled loop binds it."""
    f = load("pitch_actuator")
    sched, p_t = run["schedule"], run["p_turbine"]
    h, every = pl.ACTUATOR_DT, int(round(INTERVAL / pl.ACTUATOR_DT))
    x = np.array([beta0] * 3 + [0.0] * 3)
    out = [x[:3].copy()]
    for k in range(1, run["n_calls"]):
        v = demands((k - 1) * INTERVAL)
        first = (k - 1) * every
        sched.bind_current_angles(first * h, x[:3], h, every)
        afs = sched.actuator((first + np.arange(every)) * h)
        for i in range(every):
            af = afs[:, i]

            def rate(y, v=v, af=af):
                return np.array(f(y, v, af, p_t)).ravel()

            k1 = rate(x)
            k2 = rate(x + h / 2 * k1)
            k3 = rate(x + h / 2 * k2)
            k4 = rate(x + h * k3)
            x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(x[:3].copy())
    return np.array(out)


def test_pitch_actuator_is_the_actuator_rows_of_the_plants():
    """The generated function the library integrates against the tower plant's own
    actuator rows, at random states, demands and faults."""
    f, plant = load("pitch_actuator"), load("turbine_tower")
    names = lay.names("tower_states")
    rows = [names.index(n) for n in (*[f"beta_{j}" for j in lay.blades()],
                                      *[f"beta_rate_{j}" for j in lay.blades()])]
    rng = np.random.default_rng(3)
    p_t = lay.defaults("turbine_params")
    for _ in range(200):
        z = np.array([rng.uniform(*e["sample"]) for e in lay.layout()["tower_states"]])
        v = rng.uniform(-0.3, 1.8, 3)
        af = np.concatenate([rng.uniform(0.2, 1, 3), rng.integers(0, 2, 3),
                             rng.uniform(0, 1, 3), rng.uniform(3, 12, 3),
                             rng.uniform(0.4, 0.9, 3)])
        own = np.array(f(z[rows], v, af, p_t)).ravel()
        whole = np.array(plant(z, v, 11.0, 0.4, 0.6, af, p_t)[0]).ravel()[rows]
        assert np.array_equal(own, whole)


def test_fault_free_blades_follow_wtftcs_actuator_to_1e9_rad(tmp_path, scripted):
    run = _drive(tmp_path, scripted, [], None)
    rec = run["records"]
    ref = _reference_blades(run)
    blades = np.column_stack([rec[f"beta_{j}"] for j in lay.blades()])
    assert np.max(np.abs(blades - ref)) < 1e-9
    # the rate limit and the position limits were reached: the test covers them
    tp = lay.values("turbine_params", run["p_turbine"])
    speed = np.abs(np.diff(blades, axis=0)) / INTERVAL
    assert tp["pitch_rate_max"] * 0.999 < speed.max() <= tp["pitch_rate_max"] * (1 + 1e-9)
    # held at the position limit, within one step's travel (RK4 steps onto the stop)
    step = tp["pitch_rate_max"] * pl.ACTUATOR_DT
    assert blades.min() >= tp["pitch_min"] - step
    assert np.sum(np.abs(blades[:, 2] - tp["pitch_min"]) < step) > 10
    # OpenFAST gets the blades where the actuator holds them, not the demands
    assert np.allclose(run["returned"][:, :3], blades.astype(np.float32), atol=1e-7)
    assert np.all(run["returned"][:, 4] == pytest.approx(1234.5))


@pytest.mark.parametrize("fault", [
    {"type": "loss_of_effectiveness", "blade": 1, "onset_s": 0.3, "rho": 0.4},
    {"type": "lock", "blade": 2, "onset_s": 0.523, "angle_deg": "current"},
    {"type": "lock", "blade": 1, "onset_s": 0.7, "angle_deg": 5.0, "ramp_s": 0.2},
    {"type": "runaway", "blade": 3, "onset_s": 0.4, "target_deg": 90.0},
    {"type": "pressure_drop", "blade": 1, "onset_s": 0.2, "severity": 0.7},
    {"type": "air_in_oil", "blade": 2, "onset_s": 0.1, "end_s": 1.5},
])
def test_actuator_faults_act_as_in_wtftcs_plant_to_1e9_rad(tmp_path, scripted, fault):
    run = _drive(tmp_path, scripted, [fault], None)
    rec = run["records"]
    ref = _reference_blades(run)
    blades = np.column_stack([rec[f"beta_{j}"] for j in lay.blades()])
    assert np.max(np.abs(blades - ref)) < 1e-9
    clean = np.column_stack([_drive(tmp_path, scripted, [], None)["records"][f"beta_{j}"]
                             for j in lay.blades()])
    j = fault["blade"] - 1
    assert np.max(np.abs(blades[:, j] - clean[:, j])) > 2e-3  # the fault moved the blade


def test_a_sensor_fault_and_the_noise_reach_the_controller(tmp_path, scripted):
    """A gain fault on rotor-speed sensor 1 from 1 s: the controller's logged reading is
    the mean of the two sensors, (1.2 ω + ω)/2 without noise; with noise the readings carry
    the draws of the run's seed, the same on a second run."""
    fault = {"type": "rotor_speed_sensor_gain", "onset_s": 1.0, "gain": 1.2}
    run = _drive(tmp_path, scripted, [fault], 0, sigma=0.0)
    rec = run["records"]
    t, omega = rec["t"], 1.2 + 0.01 * rec["t"]
    seen = rec["logged_1"]  # what the controller read in #21 (float32)
    expect = np.where(t >= 1.0, 1.1 * omega, omega)
    assert np.max(np.abs(seen - expect.astype(np.float32))) < 1e-6
    assert np.array_equal(rec["read_omega_r"].astype(np.float32), seen.astype(np.float32))
    noisy = _drive(tmp_path, scripted, [], 5, sigma=0.01)["records"]
    again = _drive(tmp_path, scripted, [], 5, sigma=0.01)["records"]
    err = noisy["read_omega_r"] - (1.2 + 0.01 * noisy["t"])
    assert 0.004 < np.std(err) < 0.01  # the mean of two sensors of σ 0.01: σ/√2
    assert np.array_equal(noisy["read_omega_r"], again["read_omega_r"])


def test_export_with_actuator_puts_the_plant_library_beside_the_controller(tmp_path,
                                                                           monkeypatch):
    """Issue 32 item 6: `export discon --with-actuator` (here the PI, built at -O0) adds
    libwtftc_plant.so and its settings, every path relative to them, and the ServoDyn lines
    name the plant library. Called as ServoDyn calls it from another folder (OpenFAST runs
    in the deck's), it loads the controller beside it, writes its records there, and the
    blades move no faster than the turbine's pitch_rate_max while the controller's own
    .IN leaves the rate to the actuator (demand_rate_limit 0)."""
    from tests.discon_host import Host
    from wtftc.export import discon

    out = discon.export("pi", tmp_path / "exp", opt="-O0", with_actuator=pl.add_to_export)
    names = {p.name for p in out.iterdir()}
    assert {pl.LIBRARY, pl.SETTINGS, "libwtftc_pi.so", "wtftc_pi.IN"} <= names
    settings = (out / pl.SETTINGS).read_text()
    assert "controller_library libwtftc_pi.so" in settings and str(tmp_path) not in settings
    assert f'"{pl.LIBRARY}"' in (out / "servodyn_snippet.txt").read_text()
    assert "demand_rate_limit" in (out / "wtftc_pi.IN").read_text()
    infile = (out / "wtftc_pi.IN").read_text()
    assert [ln.split()[1] for ln in infile.splitlines()
            if ln.startswith("demand_rate_limit")] == ["0.0"]
    elsewhere = tmp_path / "deck"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    host = Host(out / pl.LIBRARY, out / pl.SETTINGS)
    rate = lay.defaults("turbine_params")[lay.index("turbine_params", "pitch_rate_max")]
    pitch = np.full(3, 0.20)
    blades = []
    for k in range(200):  # 2 s at 1.15 x rated rotor speed: the PI pitches to feather
        got = host.call(0 if k == 0 else 1, k * INTERVAL, 1.15 * 1.26711,
                        1.15 * 1.26711 * 97.0, pitch)
        assert got["fail"] == 0, got["msg"]
        pitch = np.asarray(got["pitch"], dtype=float)
        blades.append(pitch)
    host.call(-1, 2.0, 1.26711, 1.26711 * 97.0, pitch)
    b = np.array(blades)
    assert np.ptp(b[:, 0]) > 0.05  # the blades moved
    assert np.abs(np.diff(b, axis=0)).max() <= rate * INTERVAL * (1 + 1e-5) + 1e-6
    records = pl.read_records(out / pl.RECORDS)
    assert len(records["t"]) >= 199 and not list(elsewhere.iterdir())
    # the exported settings edited by hand: refused at the next first call, naming it
    text = (out / pl.SETTINGS).read_text()
    (out / pl.SETTINGS).write_text(_bad(text, "p_turbine", "pitch_rate_max", "0"))
    got = Host(out / pl.LIBRARY, out / pl.SETTINGS).call(0, 0.0, 1.26711, 122.9, pitch)
    assert got["fail"] == -1 and "p_turbine.pitch_rate_max = 0 is not allowed: a number > 0 " \
        "[rad/s]" in got["msg"]


# -- the real OpenFAST on a settings file the library refuses ---------------------------

def _bad(text: str, key: str, index: str | None, token: str) -> str:
    """``text`` with the value of ``key`` (its number ``index``, a layout name, for a
    vector) set to ``token``; key ``fault``: the line ``fault <token>`` added."""
    if key == "fault":
        return text + f"fault {token}\n"
    out = []
    for ln in text.splitlines():
        words = ln.split()
        if words and words[0] == key:
            k = 1 if index is None else 1 + lay.index(pl.VECTORS[key], index)
            words[k] = token
            ln = " ".join(words)
        out.append(ln)
    return "\n".join(out) + "\n"


@pytest.fixture(scope="module")
def of_case(tmp_path_factory):
    """A 2-s OpenFAST case of the PI at 16 m/s (the controller built once for the module)."""
    from wtftc import config
    from wtftc.openfast import engine

    rc = config.make_config({"engine": "openfast", "profile": "realistic", "controller": "pi",
                             "case": 1, "t_final_s": 2.0,
                             "wind": {"kind": "constant", "speed_mps": 16.0}})
    case = engine.prepare(rc, tmp_path_factory.mktemp("of") / "case")
    return case, case.plant_settings.read_text()


@pytest.mark.parametrize("key, index, token, said", [
    ("p_turbine", "air_density", "-5", "p_turbine.air_density = -5 is not allowed: a number "
     "in (0, 2] [kg/m^3]"),
    ("p_turbine", "pitch_min", "1.5707963267948966", "p_turbine.pitch_min = 1.57079633 is "
     "not allowed: p_turbine.pitch_min < p_turbine.pitch_max"),
    ("actuator_dt", None, "1e9", "actuator_dt = 1e+09 is not allowed"),
    ("fault", None, "1 1 nan inf 0.0 0.5 0.0", "fault[0].onset_s = nan is not allowed"),
])
def test_openfast_stops_with_the_librarys_refusal_and_never_ends_normally(of_case, key,
                                                                         index, token, said):
    """A settings file edited by hand (as docs/discon.md invites): OpenFAST stops at the
    library's first call with its line, one line naming the key, the value and the
    range, and never prints "terminated normally"."""
    from wtftc.openfast import engine

    case, text = of_case
    case.plant_settings.write_text(_bad(text, key, index, token))
    try:
        _, abort = engine.simulate(case, progress=False)
    finally:
        case.plant_settings.write_text(text)
    log = (case.folder / "openfast.log").read_text(errors="replace")
    assert abort is not None and "\n" not in abort
    assert "wtftc plant library: " in abort and said in abort, abort
    assert engine.NORMAL_END not in log


def test_a_refused_settings_file_is_one_line_and_exit_code_4_from_wtftc_run(
        tmp_path, monkeypatch, capsys):
    """Through `wtftc run --engine openfast`, with Python's own check of the settings
    bypassed (a file that differs from what was checked): OpenFAST stops at the first
    call, and wtftc says so in one line with OpenFAST's exit code 4."""
    from wtftc.cli import main

    text = pl.Settings.text
    monkeypatch.setattr(pl.Settings, "text", lambda self: _bad(
        text(self), "p_turbine", "zeta_nominal", "-0.6"))
    code = main(["run", "--engine", "openfast", "--controller", "pi", "--profile",
                 "realistic", "--wind", "constant", "--wind-mean", "16", "--t-final", "2",
                 "--fault", "none", "--quiet", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 4 and err.count("\n") == 1, err
    assert "p_turbine.zeta_nominal = -0.6 is not allowed: a number > 0" in err
    assert not (tmp_path / "run").exists()
