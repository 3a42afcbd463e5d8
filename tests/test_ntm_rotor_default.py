"""A run's NTM is the rotor-effective wind of its turbine unless it says otherwise (issue 31,
item 4): `wtftc run --wind ntm` and a config file's ``[wind] kind = "ntm"`` without
``rotor_radius_m`` average the turbulence over the turbine's rotor disk, as the load
campaigns do; ``rotor_radius_m = 0`` (``--wind-radius 0``) keeps the hub-height point. The
radius used is written into the saved configuration (docs/wind.md)."""

import json
import tomllib

import numpy as np
import pytest

from wtftc import cli, config
from wtftc.campaign import sweep
from wtftc.errors import ConfigError
from wtftc.model import wind

#: the grid the NTM is synthesized on: 600 s (its 10-min period) at the default dt_s
T = np.arange(0.0, 600.0, 0.05)
NTM_16 = {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"}


def _rc(**over):
    return config.make_config({"t_final_s": 5.0, **over})


def _run_args(*argv):
    """A `wtftc run` command line as the configuration it gives."""
    return cli._run_overrides(cli.build_parser().parse_args(["run", *argv]))


@pytest.mark.parametrize("turbine, radius", [("nrel5mw", 63.0), ("iea15mw", 120.97)])
def test_the_default_ntm_is_the_turbines_rotor_average_bit_for_bit(turbine, radius):
    """Without rotor_radius_m the NTM is the one with rotor_radius_m = the turbine's rotor
    radius (the NREL 5-MW's 63 m, the IEA 15-MW's 120.97 m), sample for sample, and the
    run's configuration says so."""
    default = _rc(turbine=turbine, wind=NTM_16)
    given = _rc(turbine=turbine, wind={**NTM_16, "rotor_radius_m": radius})
    assert default.param("rotor_radius") == radius
    assert np.array_equal(default.wind(T), given.wind(T))
    assert default.raw["wind"] == given.raw["wind"] == {**NTM_16, "rotor_radius_m": radius}
    assert default.wind.describe() == given.wind.describe()


def test_rotor_radius_zero_keeps_the_hub_height_point_whose_spread_is_larger():
    """rotor_radius_m = 0 is the point series of the wind model's own default, and at
    16 m/s class B its standard deviation over the 10-min period is σ1 = 2.46 m/s; the
    NREL 5-MW's disk average has 0.66 of it, the IEA 15-MW's larger disk 0.55."""
    point = _rc(wind={**NTM_16, "rotor_radius_m": 0})
    assert np.array_equal(point.wind(T), wind.wind_from_config(NTM_16, 5.0)(T))
    assert point.raw["wind"]["rotor_radius_m"] == 0
    assert point.wind(T).std() == pytest.approx(wind.sigma1(16.0, "B"), rel=1e-9)
    nrel, iea = _rc(wind=NTM_16), _rc(turbine="iea15mw", wind=NTM_16)
    assert nrel.wind(T).std() < 0.7 * point.wind(T).std()
    assert iea.wind(T).std() < 0.9 * nrel.wind(T).std()
    assert nrel.wind(T).mean() == pytest.approx(16.0, abs=1e-9)


def test_turbine_params_rotor_radius_is_the_one_averaged_over():
    """The radius is the run's turbine's as the run has it, overrides included."""
    rc = _rc(wind=NTM_16, turbine_params={"rotor_radius": 50.0})
    assert rc.raw["wind"]["rotor_radius_m"] == 50.0


@pytest.mark.parametrize("tab", [{"kind": "paper_random"}, {"kind": "constant"},
                                 {"kind": "eog", "start_s": 1.0},
                                 {"kind": "steps", "steps": [[1.0, 13.0]]}])
def test_other_winds_are_left_as_given(tab):
    """Only the NTM has a rotor average: no other kind gains the field."""
    assert "rotor_radius_m" not in _rc(wind=tab).raw["wind"]


def test_the_command_line_default_and_its_wind_radius_option(tmp_path, capsys):
    """`--wind ntm` leaves the radius to the turbine; `--wind-radius R` [m] sets it, over a
    config file's [wind] too; 0 is the point."""
    assert "rotor_radius_m" not in _run_args("--wind", "ntm")["wind"]
    rc = _rc(**_run_args("--wind", "ntm", "--wind-mean", "16"))
    assert rc.raw["wind"]["rotor_radius_m"] == 63.0
    assert _run_args("--wind", "ntm", "--wind-radius", "0")["wind"] == {
        "kind": "ntm", "rotor_radius_m": 0.0}
    cfg = tmp_path / "run.toml"
    cfg.write_text('[wind]\nkind = "ntm"\nmean_mps = 14.0\nrotor_radius_m = 63.0\n')
    assert _run_args("--config", str(cfg), "--wind-radius", "0")["wind"] == {
        "kind": "ntm", "mean_mps": 14.0, "rotor_radius_m": 0.0}
    with pytest.raises(SystemExit):
        cli.main(["run", "--help"])
    assert "--wind-radius METERS" in capsys.readouterr().out


def test_the_saved_configuration_records_the_radius_and_re_runs_to_the_same_wind(tmp_path):
    """config.toml and metrics.json's config say the radius used, the default's and an
    explicit 0 alike; the saved config.toml builds the same wind."""
    for argv, radius in (((), 63.0), (("--wind-radius", "0"), 0.0)):
        out = tmp_path / f"r{radius:g}"
        assert cli.main(["run", "--wind", "ntm", "--wind-mean", "16", "--t-final", "2",
                         *argv, "--out", str(out), "--quiet"]) == 0
        saved = tomllib.loads((out / "config.toml").read_text())
        assert saved["wind"]["rotor_radius_m"] == radius
        metrics = json.loads((out / "metrics.json").read_text())
        assert metrics["config"]["wind"]["rotor_radius_m"] == radius
        again = config.make_config(saved)
        first = config.make_config(_run_args("--wind", "ntm", "--wind-mean", "16",
                                             "--t-final", "2", *argv))
        assert np.array_equal(again.wind(T), first.wind(T))


@pytest.mark.parametrize("value", [-1.0, 251.0, float("nan"), True, "63", [63.0]])
def test_a_bad_radius_is_refused_naming_it(value):
    with pytest.raises(ConfigError) as exc:
        _rc(wind={**NTM_16, "rotor_radius_m": value})
    assert exc.value.field == "wind.rotor_radius_m"


def test_a_radius_for_another_kind_or_from_the_command_line_is_refused_naming_it():
    with pytest.raises(ConfigError) as exc:
        _rc(**_run_args("--wind-radius", "40"))  # the default wind is the paper's
    assert exc.value.field == "wind.rotor_radius_m"
    with pytest.raises(ConfigError) as exc:
        _rc(**_run_args("--wind", "ntm", "--wind-radius", "-3"))
    assert exc.value.field == "wind.rotor_radius_m"


def test_every_turbines_radius_is_a_valid_rotor_radius_m():
    """The largest radius a turbine may have (the layout's range, 250 m) is accepted, so
    that no turbine's default is refused; a sweep's [wind] rotor_radius_m has the same
    range."""
    assert wind.rotor_radius_max_m() == config.TURBINE_RANGES["rotor_radius"][1] == 250.0
    w = wind.wind_from_config({**NTM_16, "rotor_radius_m": 250.0}, 5.0)
    assert w(T).std() < wind.sigma1(16.0, "B")
    assert sweep.parse_sweep({"controllers": ["pi"],
                              "wind": {"rotor_radius_m": 250.0}}).rotor_radius == 250.0


def test_show_gives_an_older_sweeps_run_its_point_series(tmp_path, monkeypatch):
    """A sweep saved before issue 31 stored its runs' NTM without rotor_radius_m, which was
    the hub-height point; `wtftc sweep --show` writes it out as 0, so that `wtftc run
    --config` re-runs the point series and not the rotor average; a newer run's value is
    kept."""
    import pyarrow as pa

    from wtftc.campaign.sweep import summary

    old = {"controller": "pi", "wind": {"kind": "ntm", "mean_mps": 12.0}}
    new = {"controller": "pi", "wind": {"kind": "ntm", "mean_mps": 12.0,
                                        "rotor_radius_m": 63.0}}
    table = pa.table({"run_id": ["old", "new"],
                      "config_json": [json.dumps(old), json.dumps(new)]})
    monkeypatch.setattr(summary, "read_results", lambda *a, **k: table)
    shown = tomllib.loads(summary.show_run(tmp_path, "old"))
    assert shown["wind"]["rotor_radius_m"] == 0.0
    assert tomllib.loads(summary.show_run(tmp_path, "new"))["wind"]["rotor_radius_m"] == 63.0
