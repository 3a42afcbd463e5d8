"""A sweep's deterministic winds ([wind] kind: eog, ecd, steps, ramp around mean_mps, one
run each), its host = "as_shipped", and a fault magnitude given per fault type
(wtftc.campaign.sweep.spec); one ECD run on wtftc's plant and one in OpenFAST."""

import numpy as np
import pytest

from wtftc.campaign import sweep
from wtftc.campaign.sweep import spec
from wtftc.errors import ConfigError

BASE = {"controllers": ["pi"], "t_final_s": 60.0}


def _runs(raw: dict) -> list[dict]:
    return spec.expand(spec.parse_sweep({**BASE, **raw}))[0]


def test_kinds_cross_the_means_once_each_and_ntm_keeps_its_seeds():
    runs = _runs({"wind": {"kind": ["ntm", "ecd"], "mean_mps": [10.0, 14.0],
                           "seed": [0, 1, 2], "event_s": 20.0}})
    ntm = [r for r in runs if r["wind_kind"] == "ntm"]
    ecd = [r for r in runs if r["wind_kind"] == "ecd"]
    assert len(ntm) == 2 * 3 and len(ecd) == 2  # the ECD draws nothing: one run a mean
    assert {r["seed"] for r in ecd} == {0} and {r["turbulence_class"] for r in ecd} == {None}
    assert ecd[0]["config"]["wind"] == {"kind": "ecd", "mean_mps": 10.0, "start_s": 20.0,
                                        "sign": 1, "turbine_class": "I"}
    # the NTM's runs are those of the same sweep without a kind (their run ids)
    plain = _runs({"wind": {"mean_mps": [10.0, 14.0], "seed": [0, 1, 2]}})
    assert {r["run_id"] for r in ntm} == {r["run_id"] for r in plain}


def test_the_eog_takes_the_turbines_rotor():
    r, = _runs({"turbine": "iea15mw", "wind": {"kind": "eog", "mean_mps": 12.0}})
    assert r["config"]["wind"]["rotor_diameter_m"] == pytest.approx(2 * 120.97, rel=1e-3)


@pytest.mark.parametrize("wind, field", [
    ({"kind": "gust"}, "wind.kind"),
    ({"kind": "ecd", "seed": [0, 1]}, "wind.seed"),
    ({"kind": "steps", "rotor_radius_m": 63.0}, "wind.rotor_radius_m"),
    ({"step_mps": 2.0}, "wind.step_mps"),  # a deterministic wind's key on an NTM
    ({"kind": "ramp", "ramp_s": 0.0}, "wind.ramp_s"),
    ({"kind": "ramp", "event_s": 60.0}, "wind.event_s"),
    ({"kind": "steps", "mean_mps": 4.0, "step_mps": 9.0}, "wind.step_mps"),
    ({"kind": "ecd", "sign": 0}, "wind.sign"),
    ({"kind": "ecd", "mean_mps": 7.0}, "wind.mean_mps"),
    ({"kind": "eog", "turbine_class": "IV"}, "wind.turbine_class"),
])
def test_a_refused_wind_names_its_key(wind, field):
    with pytest.raises(ConfigError) as exc:
        spec.parse_sweep({**BASE, "wind": wind})
    assert exc.value.field == field


def test_a_magnitude_per_fault_type():
    runs = _runs({"fault": {"type": ["pitch_sensor_gain", "rotor_speed_sensor_gain"],
                            "gain": {"pitch_sensor_gain": 1.2,
                                     "rotor_speed_sensor_gain": 1.1}}})
    assert {r["fault_type"]: r["sensor_gain"] for r in runs} == {
        "pitch_sensor_gain": 1.2, "rotor_speed_sensor_gain": 1.1}
    for fault, field in (({"type": "pitch_sensor_gain", "gain": {"lock": 1.2}},
                          "fault.gain.lock"),
                         ({"type": ["pitch_sensor_gain", "generator_speed_sensor_gain"],
                           "gain": {"pitch_sensor_gain": 1.2}}, "fault.gain"),
                         ({"type": "pitch_sensor_gain", "gain": {"pitch_sensor_gain": -1}},
                          "fault.gain.pitch_sensor_gain")):
        with pytest.raises(ConfigError) as exc:
            spec.parse_sweep({**BASE, "fault": fault})
        assert exc.value.field == field


def test_as_shipped_is_fault_free_and_exact():
    r, = _runs({"host": "as_shipped"})
    assert r["config"]["profile"] == "ideal"
    with pytest.raises(ConfigError) as exc:
        spec.parse_sweep({**BASE, "host": "as_shipped", "fault": {"type": "lock"}})
    assert exc.value.field == "host"
    with pytest.raises(ConfigError) as exc:
        spec.parse_sweep({**BASE, "host": "bench"})
    assert exc.value.field == "host"


def test_an_ecd_run_on_wtftcs_plant_sees_the_rotor_normal_wind():
    """The run finishes on wtftc's plant, and its wind is V cos θ of the IEC ECD (the plant
    has no yaw), to the last bits of the closed form."""
    from wtftc.model.wind import wind_from_config

    pt, = _runs({"t_final_s": 8.0, "wind": {"kind": "ecd", "mean_mps": 12.0,
                                            "event_s": 2.0}})
    (row, _), = sweep.run_task([pt])
    assert row["status"] == "ok", row
    t = np.linspace(0.0, 8.0, 801)
    v = wind_from_config(pt["config"]["wind"], 8.0)(t)
    tau = np.clip((t - 2.0) / 10.0, 0.0, 1.0)
    rise = 0.5 * (1 - np.cos(np.pi * tau))
    expected = (12.0 + 15.0 * rise) * np.cos(np.radians(60.0) * rise)
    np.testing.assert_allclose(v, expected, rtol=1e-14)


def test_an_ecd_reaches_inflowwind_with_its_direction(tmp_path):
    """One short OpenFAST run (4 s) under an ECD from 0.5 s: InflowWind's wind at the hub,
    as OpenFAST reports it, is the ECD's speed turned by its direction, u = V cos θ along
    the rotor's axis (the wind wtftc's plant takes) and v = -V sin θ across it. 1e-3 m/s:
    the file's 0.02-s rows interpolated and the outputs' float32 (6e-5 m/s measured)."""
    import subprocess
    import sys

    from openfast_io.FAST_output_reader import FASTOutputFile

    from wtftc.openfast import install

    install.require()
    (tmp_path / "ecd.toml").write_text('engine = "openfast"\nt_final_s = 4.0\n[wind]\n'
                                       'kind = "ecd"\nmean_mps = 12.0\nstart_s = 0.5\n')
    p = subprocess.run([sys.executable, "-m", "wtftc.cli", "run", "--config",
                        tmp_path / "ecd.toml", "--fault", "none", "--out", tmp_path / "out",
                        "--quiet"], capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    f = FASTOutputFile(str(tmp_path / "out" / "openfast" / "NREL-5MW.outb"))
    ch = dict(zip(f.info["attribute_names"], f.data.T, strict=True))
    t = ch["Time"]
    rise = 0.5 * (1 - np.cos(np.pi * np.clip((t - 0.5) / 10.0, 0.0, 1.0)))
    v, theta = 12.0 + 15.0 * rise, np.radians(720.0 / 12.0) * rise
    assert t[-1] == pytest.approx(4.0) and theta[-1] > np.radians(15.0)  # turned 16°
    np.testing.assert_allclose(ch["Wind1VelX"], v * np.cos(theta), atol=1e-3)
    np.testing.assert_allclose(ch["Wind1VelY"], -v * np.sin(theta), atol=1e-3)
