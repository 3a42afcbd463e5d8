"""The scorecard's case matrix as data (wtftc.campaign.scorecard.matrix): checked, the
same runs for every controller, and the runs the kept campaign made."""

from pathlib import Path

import pytest

from wtftc.campaign.scorecard import matrix
from wtftc.campaign.sweep import spec
from wtftc.errors import ConfigError
from wtftc.model import turbine_file

ROOT = Path(__file__).resolve().parents[1]


def _runs(raw: dict) -> list[dict]:
    return spec.expand(spec.parse_sweep(raw))[0]


def test_the_shipped_matrix_is_checked_and_names_its_hash():
    m = matrix.load()
    assert set(m["groups"]) == {"normal_production", "actuator_faults", "sensor_faults",
                                "deterministic", "baseline_as_shipped"}
    h = matrix.matrix_hash(m)
    assert len(h) == 16 and h == matrix.matrix_hash(matrix.load())
    edited = {**m, "annual_mean_mps": 8.5}
    assert matrix.matrix_hash(matrix.check(edited, "edited")) != h


@pytest.mark.parametrize("turbine", list(turbine_file.BUILTIN))
def test_the_bins_run_from_cut_in_to_cut_out(turbine):
    t = turbine_file.load(turbine)
    b = matrix.bins(matrix.load(), t)
    assert b[0] - 1.0 == pytest.approx(t.cut_in_wind_mps) and b[-1] + 1.0 <= 25.0
    steps = [y - x for x, y in zip(b[:-1], b[1:], strict=True)]
    assert len(b) == 11 and steps == pytest.approx([2.0] * 10)


def test_every_controller_runs_the_same_scenarios():
    """The test bench's check: one matrix, identical for every column."""
    m = matrix.load()
    for raw in matrix.sweeps(m, ["aftc-nrel5mw", "pi", "rosco"], None, "wtftc",
                             seeds=2).values():
        runs = _runs(raw)
        by = {}
        for r in runs:
            key = tuple((k, v) for k, v in sorted(r.items())
                        if k not in ("run_id", "controller", "config"))
            by.setdefault(r["controller"], set()).add(key)
        if raw["controllers"] == ["rosco"]:  # the baseline alone, as shipped
            assert len(by) == 1 and raw.get("host") == "as_shipped"
            continue
        assert len(by) == 3 and by["aftc-nrel5mw"] == by["pi"] == by["rosco"]


def test_the_groups_sizes_and_times():
    m = matrix.load()
    sw = matrix.sweeps(m, ["aftc-nrel5mw", "rosco"], None, "openfast", seeds=3)
    npp, faults = _runs(sw["normal_production"]), _runs(sw["actuator_faults"])
    assert len(npp) == 11 * 3 * 2  # bins × seeds × columns
    assert len(faults) == 4 * 3 * (4 + 2) * 2  # winds × seeds × (types, 2 runaways) × columns
    assert {r["config"]["t_final_s"] for r in npp} == {630.0}
    assert {r["onset_s"] for r in faults} == {40.0}
    # the shipped seeds without --seeds
    assert len(_runs(matrix.sweeps(m, ["rosco"], None, "openfast")["actuator_faults"])) \
        == 4 * 6 * 6


def test_the_committed_nrel5mw_card_holds_the_runs_the_matrix_makes():
    """results/scorecard_nrel5mw (`make scorecards`, 6 seeds, --screen 1): every group's
    screen is, run for run, what the matrix makes now (the same run ids, which hash each
    run's whole configuration), and every OpenFAST confirmation run is one of the
    matrix's OpenFAST runs. A change to the matrix or to what a run is fails here until
    the card is made again."""
    from wtftc.campaign.scorecard import run
    from wtftc.campaign.sweep import store

    card = ROOT / "results" / "scorecard_nrel5mw"
    cols = ["aftc-nrel5mw", "rosco"]
    screened = run._sweeps(matrix.load(), cols, "nrel5mw", "openfast", 6, 1)
    judged = matrix.sweeps(matrix.load(), cols, "nrel5mw", "openfast", seeds=6)
    for group, raw in screened.items():
        kept = store.read_results(card / group).column("run_id").to_pylist()
        assert sorted(kept) == sorted(r["run_id"] for r in _runs(raw)), group
        confirmed = card / f"{group}_openfast"
        if confirmed.is_dir():
            ids = set(store.read_results(confirmed).column("run_id").to_pylist())
            assert ids and ids <= {r["run_id"] for r in _runs(judged[group])}, group


@pytest.mark.parametrize("edit, field", [
    ({"typo": 1}, "typo"),
    ({"annual_mean_mps": 0.5}, "annual_mean_mps"),
    ({"turbulence_class": "Z"}, "turbulence_class"),
    ({"groups": {"normal_production": {"seeds": 0}}}, "groups.normal_production.seeds"),
    ({"groups": {"actuator_faults": {"types": ["lock", "gremlins"]}}},
     "groups.actuator_faults.types"),
    ({"groups": {"actuator_faults": {"onset_s": 95.0}}}, "groups.actuator_faults.onset_s"),
    ({"groups": {"actuator_faults": {"winds_mps": [50.0]}}},
     "groups.actuator_faults.winds_mps"),
    ({"groups": {"other": {}}}, "groups"),
    ({"start_up_s": 20.0}, "start_up_s"),
    ({"groups": {"sensor_faults": {"types": ["lock"]}}}, "groups.sensor_faults.types"),
    ({"groups": {"sensor_faults": {"magnitudes": {"pitch_sensor_stuck": 5.0}}}},
     "groups.sensor_faults.magnitudes"),
    ({"groups": {"sensor_faults": {"sensor": 3}}}, "groups.sensor_faults.sensor"),
    ({"groups": {"deterministic": {"kinds": ["eog", "ntm"]}}}, "groups.deterministic.kinds"),
    ({"groups": {"deterministic": {"seeds": 6}}}, "groups.deterministic.seeds"),
    ({"groups": {"deterministic": {"ramp_s": 200.0}}}, "groups.deterministic.ramp_s"),
    ({"groups": {"deterministic": {"ecd_sign": 0}}}, "groups.deterministic.ecd_sign"),
    ({"groups": {"deterministic": {"winds_from_rated_mps": [9.0]}}},
     "groups.deterministic.winds_from_rated_mps"),
    ({"groups": {"baseline_as_shipped": {"near_mps": []}}},
     "groups.baseline_as_shipped.near_mps"),
    ({"groups": {"baseline_as_shipped": {"seeds": 2}}}, "groups.baseline_as_shipped.seeds"),
    ({"groups": {"actuator_faults": {"scored_s": 30.0}}}, "start_up_s"),
])
def test_a_refused_matrix_names_its_key(tmp_path, edit, field):
    m = matrix.load()
    for k, v in edit.items():
        if k == "groups":
            for g, tab in v.items():
                m["groups"][g] = {**m["groups"].get(g, {}), **tab}
        else:
            m[k] = v
    with pytest.raises(ConfigError) as exc:
        matrix.check(m, "edited.toml")
    assert exc.value.field == field and exc.value.where == "edited.toml"


def test_the_sensor_fault_group_gives_each_type_its_magnitude():
    """Each sensor fault at the benchmark's or FOWLTY's magnitude, a speed sensor's scaled
    by its shaft's rated speed: on the NREL 5-MW, the benchmark's 1.4 rad/s and the
    FDI runs' 100 rad/s (docs/fdi.md), to the 1e-7 the fractions are written to."""
    m = matrix.load()
    runs = _runs(matrix.sweeps(m, ["pi"], None, "wtftc", seeds=2)["sensor_faults"])
    assert len(runs) == 10 * 2 * 2  # types × winds × seeds
    mag = {}
    for r in runs:
        tab = r["config"]["fault"][0]
        key = spec.MAGNITUDE[r["fault_type"]]
        mag[r["fault_type"]] = tab[key]
        assert tab["onset_s"] == 40.0 and tab.get("blade", 1) == 1 and "sensor" not in tab
    assert mag["pitch_sensor_stuck"] == 5.0 and mag["pitch_sensor_gain"] == 1.2
    assert mag["rotor_speed_sensor_gain"] == 1.1 and mag["generator_speed_sensor_gain"] == 0.9
    assert mag["rotor_speed_sensor_stuck"] == pytest.approx(1.4, rel=1e-7)
    assert mag["rotor_speed_sensor_offset"] == pytest.approx(0.1, rel=1e-7)
    assert mag["generator_speed_sensor_stuck"] == pytest.approx(100.0, rel=1e-7)
    assert mag["generator_speed_sensor_offset"] == pytest.approx(2.0, rel=1e-7)
    # on the IEA 15-MW the same fractions of its own rated speed (0.79168 rad/s, direct drive)
    iea = _runs(matrix.sweeps(m, ["pi"], "iea15mw", "wtftc", seeds=1)["sensor_faults"])
    stuck = {r["fault_type"]: r["sensor_value_rad_s"] for r in iea}
    assert stuck["rotor_speed_sensor_stuck"] == pytest.approx(1.1048765 * 0.79168, rel=1e-9)


@pytest.mark.parametrize("turbine, rated", [("nrel5mw", 11.4), ("iea15mw", 10.6)])
def test_the_deterministic_group_runs_each_wind_once_around_rated(turbine, rated):
    m = matrix.load()
    raw = matrix.sweeps(m, ["pi", "rosco"], turbine, "wtftc", seeds=6)["deterministic"]
    runs = _runs(raw)
    assert len(runs) == 4 * 3 * 2  # kinds × winds × columns, whatever --seeds says
    assert {r["seed"] for r in runs} == {0}
    got = {(r["wind_kind"], r["mean_wind_mps"]) for r in runs}
    winds = [round(rated + d, 6) for d in (-2.0, 0.0, 2.0)]
    assert got == {(k, v) for k in ("eog", "ecd", "steps", "ramp") for v in winds}
    at_rated = {r["wind_kind"]: r["config"]["wind"] for r in runs
                if r["mean_wind_mps"] == rated}
    assert at_rated["steps"] == {"kind": "steps", "speed_mps": round(rated - 1, 9),
                                 "steps": [[40.0, round(rated + 1, 9)]]}
    assert at_rated["ramp"]["speed_mps"] == round(rated - 2, 9)
    assert at_rated["ramp"]["end_mps"] == round(rated + 2, 9)
    assert at_rated["ecd"]["start_s"] == at_rated["eog"]["start_s"] == 40.0
    assert {r["config"]["t_final_s"] for r in runs} == {210.0}


def test_the_baseline_as_shipped_pairs_with_normal_production():
    """The baseline alone, as shipped, on normal-production scenarios: each of its runs is
    the baseline's normal-production run of the same bin and seed but for the host (its
    configuration's profile)."""
    m = matrix.load()
    sw = matrix.sweeps(m, ["pi", "rosco"], None, "wtftc", seeds=2)
    shipped, npp = _runs(sw["baseline_as_shipped"]), _runs(sw["normal_production"])
    assert {r["controller"] for r in shipped} == {"rosco"} and len(shipped) == 3 * 2
    base = {(r["mean_wind_mps"], r["seed"]): r for r in npp if r["controller"] == "rosco"}
    for r in shipped:
        twin = base[(r["mean_wind_mps"], r["seed"])]
        assert r["config"]["profile"] == "ideal" and twin["config"]["profile"] == "realistic"
        same = {k: v for k, v in r["config"].items() if k not in ("profile", "label")}
        assert same == {k: v for k, v in twin["config"].items()
                        if k not in ("profile", "label")}
    assert sorted({r["mean_wind_mps"] for r in shipped}) == [8.0, 14.0, 20.0]
    # in OpenFAST: exact sensors and no benchmark actuator
    of = _runs(matrix.sweeps(m, ["pi", "rosco"], None, "openfast",
                             seeds=1)["baseline_as_shipped"])[0]["config"]
    assert of["openfast"] == {"actuator": False} and set(of["sensors"].values()) == {0.0}


def test_plan_counts_every_groups_runs():
    p = matrix.plan(matrix.load(), seeds=6)
    assert {g: (v["columns"], v["runs_per_column"]) for g, v in p.items()} == {
        "normal_production": (2, 11 * 6), "actuator_faults": (2, 4 * 6 * 6),
        "sensor_faults": (2, 10 * 2 * 6), "deterministic": (2, 4 * 3),
        "baseline_as_shipped": (1, 3 * 6)}
    d = p["deterministic"]
    assert d["simulated_s_per_column"] == 12 * 210.0
    assert d["openfast_cpu_s"] == pytest.approx(2 * 12 * 210.0 * 0.43)
