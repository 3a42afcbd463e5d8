"""Campaign columns as controller settings: the former controller names run as they were
defined, a sweep records its columns and reads them back, and a column refused is one
line naming it."""

import json
from pathlib import Path

import pytest

from wtftc import controller
from wtftc.campaign import compare
from wtftc.campaign.sweep import expand, load_sweep, parse_sweep
from wtftc.errors import ConfigError

#: the 21 controller names of the earlier wtftc (wtftc/campaign/compare.py at b2e8c34):
#: name → (design, case under a fault, (ω_n, ζ) target or None, [controller_params],
#: [turbine_params] beside the baseline torque law)
OLD = {
    "rosco": ("rosco", 2, None, {}, {}),
    "paper": ("paper", 3, None, {}, {}),
    "physical_fdi": ("physical", 4, None, {}, {}),
    "physical_known": ("physical", 3, None, {}, {}),
    "physical_unaccommodated": ("physical", 2, None, {}, {}),
    "drivetrain_fdi": ("drivetrain", 4, None, {}, {}),
    "pi": ("pi", 2, None, {}, {}),
    "paper_fdi": ("paper", 4, None, {}, {}),
    "physical_obs_fdi": ("physical", 4, None, {"phys_obs_omega": 6.0}, {}),
    "pi_lpf": ("pi", 2, None, {"pi_lpf_corner": 6.0}, {}),
    "physical_obs_ps_fdi": ("physical", 4, None,
                            {"phys_obs_omega": 6.0, "phys_ps_pitch": 0.0349}, {}),
    "pi_lpf_ps": ("pi", 2, None, {"pi_lpf_corner": 6.0, "pi_ps_pitch": 0.0349}, {}),
    "physical_obs45_ps_fdi": ("physical", 4, None,
                              {"phys_obs_omega": 4.5, "phys_ps_pitch": 0.0349}, {}),
    "physical_obs45_ps_td_fdi": ("physical", 4, None, {
        "phys_obs_omega": 4.5, "phys_ps_pitch": 0.0349, "phys_td_gain": 0.12}, {}),
    "rosco_matched": ("rosco", 2, (0.7, 0.85), {}, {}),
    "physical_obs45_ps_ct_fdi": ("physical", 4, None, {
        "phys_obs_omega": 4.5, "phys_ps_pitch": 0.0349}, {"vs_constant_torque": 1.0}),
    "physical_obs45_ps_td_ct_fdi": ("physical", 4, None, {
        "phys_obs_omega": 4.5, "phys_ps_pitch": 0.0349, "phys_td_gain": 0.12},
        {"vs_constant_torque": 1.0}),
    "pi_lpf_ps_ct": ("pi", 2, None, {"pi_lpf_corner": 6.0, "pi_ps_pitch": 0.0349},
                     {"vs_constant_torque": 1.0}),
    "physical_obs30_ps_td_ct_fdi": ("physical", 4, None, {
        "phys_obs_omega": 3.0, "phys_ps_pitch": 0.0349, "phys_td_gain": 0.12},
        {"vs_constant_torque": 1.0}),
    "physical_obs3to45_ps_td_ct_fdi": ("physical", 4, None, {
        "phys_obs_omega": 3.0, "phys_obs_omega_max": 4.5, "phys_ps_pitch": 0.0349,
        "phys_td_gain": 0.12}, {"vs_constant_torque": 1.0}),
    "physical_obs15_w04_ps_ct_fdi": ("physical", 4, (0.4, 0.85), {
        "phys_obs_omega": 1.5, "phys_ps_pitch": 0.0349}, {"vs_constant_torque": 1.0}),
}


def _old_run_keys(name: str, faulty: bool) -> dict:
    """The keys the earlier variant_config set for ``name`` (its other keys: the run's)."""
    design, case, tuning, params, turbine = OLD[name]
    cfg = {"controller": design, "case": case if faulty else 1}
    if tuning is not None:
        cfg["tuning"] = {"omega_n_rad_s": tuning[0], "zeta": tuning[1]}
    if params:
        cfg["controller_params"] = dict(params)
    if design != "rosco":
        cfg["turbine_params"] = {"gen_torque_law": 1.0, **turbine}
    return cfg


@pytest.mark.parametrize("name", sorted(OLD))
def test_a_former_name_runs_as_it_was_defined(name):
    ctrl = controller.lookup(name)
    for faulty in (False, True):
        assert ctrl.run_keys(faulty, torque_default=True) == _old_run_keys(name, faulty)
    assert compare.resolve_columns([name]) == {name: ctrl}


def test_every_former_name_is_listed():
    assert set(controller.former_names()) == set(OLD)


@pytest.mark.parametrize(("entries", "field", "value"), [
    (["pi", "fastest"], "controllers", "fastest"),
    ([{"name": "obs", "preset": "physical-plain", "phys_obs_omegaa": 3.0}],
     "controllers.obs.phys_obs_omegaa", 3.0),
    ([{"name": "obs", "design": "physical", "phys_obs_omega": [2.0, "x"]}],
     "controllers.obs.phys_obs_omega", "x"),
    ([{"name": "obs", "preset": "fastest"}], "controllers.obs.preset", "fastest"),
    ([{"preset": "pi"}], "controllers.name", None),
    (["pi", {"name": "pi", "preset": "pi-filtered"}], "controllers", "pi"),
    ([{"name": "obs", "preset": "physical-plain", "phys_obs_omega": [3.0, 3]}],
     "controllers", "obs[phys_obs_omega=3]"),
])
def test_a_column_refused_is_one_line_naming_it(entries, field, value):
    """An unknown name, a bad key or value, a table without a name, a name given twice
    (by hand or by a list's values): one ConfigError naming the column, from the
    resolver and from a sweep file alike."""
    for call in (lambda: compare.resolve_columns(entries),
                 lambda: parse_sweep({"controllers": entries})):
        with pytest.raises(ConfigError) as e:
            call()
        assert (e.value.field, e.value.value) == (field, value), e.value
        assert "\n" not in str(e.value)


def test_a_sweep_records_its_columns_and_its_summary_reads_them_back():
    """sweep.json keeps each column's settings written out: a folder whose file names a
    preset since changed, or gone, still resolves to the columns it ran."""
    from wtftc.campaign.sweep.summary import _sweep_of

    raw = {"controllers": [{"name": "obs", "preset": "aftc-nrel5mw",
                            "phys_obs_omega": [2.0, 3.0]}, "pi"],
           "optional_controllers": ["rosco"], "wind": {"mean_mps": 16.0}}
    sw = parse_sweep(raw)
    assert list(sw.columns) == ["obs[phys_obs_omega=2]", "obs[phys_obs_omega=3]", "pi",
                                "rosco"]
    rec = json.loads(json.dumps(sw.record()))
    meta = {"sweep": {**raw, "controllers": ["a-preset-gone"]}, **rec}
    back = _sweep_of(meta, Path("unused"))
    assert {c: v.run_keys(True, True) for c, v in back.columns.items()} == {
        c: v.run_keys(True, True) for c, v in sw.columns.items()}
    assert [pt["run_id"] for pt in expand(back)[0]] == [pt["run_id"] for pt in expand(sw)[0]]
    with pytest.raises(ConfigError) as e:  # without the record, the name is resolved
        _sweep_of({"sweep": meta["sweep"]}, Path("unused"))
    assert "a-preset-gone" in str(e.value)


def test_the_preset_option_replaces_a_sweep_files_controllers(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('controllers = ["pi", "paper"]\noptional_controllers = ["rosco"]\n')
    sw = load_sweep(path, preset="aftc-nrel5mw")
    assert list(sw.columns) == ["aftc-nrel5mw", "rosco"]
    with pytest.raises(ConfigError) as e:
        load_sweep(path, preset="fastest")
    assert (e.value.field, e.value.value) == ("--preset", "fastest")


def test_a_folder_resumes_only_with_the_columns_it_recorded(tmp_path):
    """A preset the sweep file names may change between two calls: the folder's recorded
    settings must be those the file resolves to now (a doc's words aside), else the
    resume is refused naming the column; a folder that recorded only names is not
    checked."""
    from wtftc.campaign.sweep import store

    sw = parse_sweep({"controllers": ["aftc-nrel5mw", "pi"]})
    rec = json.loads(json.dumps(sw.record()))
    store._check_same_columns(tmp_path, rec, sw, False)
    reworded = json.loads(json.dumps(rec))
    reworded["controllers"][1]["doc"] = "another text"
    store._check_same_columns(tmp_path, reworded, sw, False)
    store._check_same_columns(tmp_path, {"sweep": {}}, sw, False)
    changed = json.loads(json.dumps(rec))
    changed["controllers"][0]["phys_obs_omega"] = 2.5
    with pytest.raises(ConfigError) as e:
        store._check_same_columns(tmp_path, changed, sw, False)
    assert e.value.field == "--out" and "aftc-nrel5mw" in e.value.allowed
    store._check_same_columns(tmp_path, changed, sw, True)  # --overwrite


def test_columns_as_an_array_of_tables(tmp_path):
    """`[[controllers]]` entries are the same columns as inline tables."""
    path = tmp_path / "s.toml"
    path.write_text('t_final_s = 30.0\n[wind]\nmean_mps = 16.0\n'
                    '[[controllers]]\nname = "obs"\npreset = "physical-plain"\n'
                    'phys_obs_omega = [3.0, 4.5]\n[[controllers]]\nname = "base"\n'
                    'preset = "pi"\n')
    sw = load_sweep(path)
    assert list(sw.columns) == ["obs[phys_obs_omega=3]", "obs[phys_obs_omega=4.5]", "base"]
    assert dict(sw.columns["obs[phys_obs_omega=4.5]"].params) == {"phys_obs_omega": 4.5}
