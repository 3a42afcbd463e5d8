"""TurbSim full fields read back (issue 32 item 4): wtftc's own reader of the `.bts` format
against TurbSim's own hub-point file, its one-line refusals, and a native run that reads
the very field (the same cached file) the OpenFAST engine runs on (docs/openfast.md,
docs/wind.md)."""

import dataclasses
import math
import subprocess

import numpy as np
import pytest

from wtftc import config
from wtftc.errors import ConfigError, EngineError
from wtftc.model import wind_field as wf
from wtftc.openfast import engine, install, turbsim

#: a short class-B field at 16 m/s on the NREL 5-MW (13 x 13 points, 144.9 m wide)
FIELD = wf.Field(16.0, "B", 11, 90.0, 63.0, 10.0)
NATIVE = {"t_final_s": 10.0, "seed": 5,
          "wind": {"kind": "ntm", "mean_mps": 16.0, "field": "turbsim"}}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """TurbSim run on FIELD's input with its formatted hub-point file on (WrFHHTP: the
    hub's u, v, w to 1 mm/s, written from the same arrays as the .bts)."""
    folder = tmp_path_factory.mktemp("turbsim")
    text = FIELD.input_text().replace("False        WrFHHTP", "True         WrFHHTP")
    assert text != FIELD.input_text()
    (folder / "field.inp").write_text(text)
    subprocess.run([str(install.require().turbsim), "field.inp"], cwd=folder, check=True,
                   capture_output=True, stdin=subprocess.DEVNULL)
    return folder


def test_the_reader_gives_turbsims_own_hub_point_series(made):
    """The hub point of the grid (y = 0, z = 90 m, read bilinearly) is TurbSim's `.dat`
    series of u, v, w within the two roundings: the file's 3 decimals and half the int16
    quantum (1/slope) of the .bts."""
    ff = wf.read_bts(made / "field.bts")
    dat = np.loadtxt(made / "field.dat", skiprows=4)  # Time U Uh Ut V W ...
    n_t = math.ceil((10.0 + 144.9 / 16.0) / 0.05)  # TurbSim: UsableTime + width / uhub
    assert ff.u.shape == (n_t, 13, 13) and not ff.periodic and len(dat) == n_t
    assert ff.hub_height_m == 90.0 and ff.mean_mps == 16.0
    assert np.allclose(ff.y, np.linspace(-72.45, 72.45, 13), atol=1e-4)
    assert ff.z[6] == pytest.approx(90.0, abs=1e-4) and ff.z_tower[0] == ff.z[0]
    assert np.allclose(ff.t, dat[:, 0], atol=1e-6)
    for k, (field, col) in enumerate(((ff.u, 1), (ff.v, 4), (ff.w, 5))):
        tol = 0.0005 + 0.5 / ff.slope[k] + 1e-5
        assert np.abs(field[:, 6, 6] - dat[:, col]).max() <= tol
    assert np.abs(wf.rotor_series(ff, 0.0) - dat[:, 1]).max() <= 0.0005 + 0.5 / ff.slope[0] + 1e-5
    assert ff.time_shift_s == pytest.approx(72.45 / 16.0, abs=1e-5)


def test_a_cut_or_foreign_file_is_refused_in_one_line(made, tmp_path):
    cut = tmp_path / "cut.bts"
    raw = (made / "field.bts").read_bytes()
    for data, what in ((raw[:-100], "cut short"), (raw[:40], "header"),
                       (b"\x09\x00" + raw[2:], "file ID 9")):
        cut.write_bytes(data)
        with pytest.raises(EngineError) as exc:
            wf.read_bts(cut)
        assert str(cut) in str(exc.value) and what in str(exc.value)
        assert "\n" not in str(exc.value)


def test_the_rotor_average_weighs_the_disk_by_area():
    """u = z² [m/s] on a 1-m grid: the disk's mean is hub² + R²/4 (∫z² dA / πR²), plus at
    most the bilinear interpolant's excess dz²/4; u linear in y and z averages to the hub's."""
    y = np.arange(-40.0, 40.5, 1.0)
    z = 90.0 + y
    yy, zz = np.meshgrid(y, z)
    base = wf.FullField(None, False, np.zeros(1), y, z, None, None, None, 16.0, 90.0,
                        np.zeros(0), None, None, None, (1.0, 1.0, 1.0), "")
    quad = dataclasses.replace(base, u=(zz**2)[None])
    mean = wf.rotor_series(quad, 30.0)[0]
    assert 0 <= mean - (90.0**2 + 30.0**2 / 4) <= 0.25
    lin = dataclasses.replace(base, u=(3.0 + 0.1 * yy - 0.05 * (zz - 90.0))[None])
    assert wf.rotor_series(lin, 30.0)[0] == pytest.approx(3.0, abs=1e-12)
    with pytest.raises(ConfigError, match="wind.rotor_radius_m"):
        wf.rotor_series(quad, 41.0)


def _grid_field(u_of, t):
    """A FullField on a 1-m grid ±40 m around a 90-m hub, u = u_of(t, y, z) [m/s]."""
    y = np.arange(-40.0, 40.5, 1.0)
    z = 90.0 + y
    yy, zz = np.meshgrid(y, z)
    return wf.FullField(None, True, t, y, z, np.stack([u_of(tk, yy, zz - 90.0) for tk in t]),
                        None, None, 16.0, 90.0, np.zeros(0), None, None, None,
                        (1.0, 1.0, 1.0), "")


def test_the_blades_sample_the_field_along_their_span_as_they_turn():
    """Three radial lines of equal weights along the span, turning at Ω from blade 1
    upright: a wind ∝ r² reads R²/3 (the disk average, by area: R²/2); a wind linear in y
    and z cancels over the three blades; a frozen pattern r cos 3θ reads at 3P, its
    amplitude R/2, in phase with blade 1 (at 120° apart the three blades see it alike)."""
    R, omega = 30.0, 1.2
    t = np.linspace(0.0, 10.0, 201)
    quad = _grid_field(lambda tk, y, z: 0.01 * (y**2 + z**2), t)
    expected = 0.01 * R**2 * np.mean(((np.arange(wf.BLADE_POINTS) + 0.5) / wf.BLADE_POINTS)**2)
    # the bilinear interpolant's excess over a quadratic: at most dy²/4 per axis, 0.005 here
    assert np.allclose(wf.blade_series(quad, R, omega), expected, atol=0.006)
    assert expected == pytest.approx(0.01 * R**2 / 3, rel=1e-3)
    assert wf.rotor_series(quad, R)[0] == pytest.approx(0.01 * R**2 / 2, abs=0.006)
    lin = _grid_field(lambda tk, y, z: 3.0 + 0.1 * y - 0.05 * z, t)
    assert np.allclose(wf.blade_series(lin, R, omega), 3.0, atol=1e-12)
    # θ from upright towards +y: y = r sin θ, z = r cos θ; cos 3θ = 4 cos³θ - 3 cos θ
    tri = _grid_field(lambda tk, y, z: 4 * z**3 / np.maximum(y**2 + z**2, 1e-9) - 3 * z, t)
    got = wf.blade_series(tri, R, omega)
    assert np.allclose(got, R / 2 * np.cos(3 * omega * t), atol=0.02 * R / 2)
    with pytest.raises(ConfigError, match="wind.rotor_radius_m"):
        wf.blade_series(quad, 41.0, omega)


def test_the_blades_wind_is_a_choice_of_the_turbsim_ntm_only():
    """`rotor_wind = "blades"` needs the TurbSim field and a rotor; any other value, or a
    blade speed without it, is one line naming the field; the default adds no parameter
    (earlier configurations and sweep ids unchanged)."""
    from wtftc.model.wind import wind_from_config

    base = {"kind": "ntm", "mean_mps": 16.0, "rotor_radius_m": 63.0}
    for table, field in (({**base, "rotor_wind": "blades"}, "wind.rotor_wind"),
                         ({**base, "rotor_wind": "blade", "field": "turbsim"},
                          "wind.rotor_wind"),
                         ({**base, "rotor_wind": "blades", "field": "turbsim",
                           "rotor_radius_m": 0.0}, "wind.rotor_wind"),
                         ({**base, "blade_speed_rad_s": 1.0}, "wind.blade_speed_rad_s"),
                         ({**base, "rotor_wind": "blades", "field": "turbsim",
                           "blade_speed_rad_s": -1.0}, "wind.blade_speed_rad_s"),
                         ({"kind": "constant", "rotor_wind": "blades"}, "wind.rotor_wind")):
        with pytest.raises(ConfigError) as exc:
            wind_from_config(table, 30.0)
        assert exc.value.field == field, table
    assert "rotor_wind" not in wind_from_config(base, 30.0).describe()["parameters"]


def test_the_blades_turn_at_the_operating_speed_of_the_mean_wind():
    """The blade speed filled in: rated above rated, λ* v / R below (written into the
    saved configuration); a run on the blades' wind reads blade_series at the run's times."""
    from wtftc.config import blade_speed

    blades = {**NATIVE, "wind": {**NATIVE["wind"], "rotor_wind": "blades"}}
    turbsim.ensure_field(blades)  # as every command does first (a fresh cache has none)
    rc = config.make_config(blades)
    assert rc.raw["wind"]["blade_speed_rad_s"] == pytest.approx(rc.param("omega_g_rated"))
    slow = blade_speed(rc.loop.p_turbine, rc.loop.table, 8.0)
    assert slow == pytest.approx(rc.loop.table.cp_max()[1] * 8.0 / 63.0)
    assert 0.9 < slow < 1.0  # OpenFAST's mean at 8 m/s: 0.93-0.98 rad/s (docs/validation.md)
    ff = wf.read_bts(turbsim.make_field(NATIVE))
    t = np.linspace(0.0, 10.0, 401)
    expected = np.interp(t + ff.time_shift_s, ff.t,
                         wf.blade_series(ff, 63.0, rc.param("omega_g_rated")))
    assert np.allclose(rc.wind(t), expected, rtol=0, atol=1e-12)
    assert rc.wind.describe()["derived"]["series"].startswith("three blades turning")
    # an NTM without its mean takes the default's (12 m/s, above rated): rated speed
    plain = {**NATIVE, "wind": {"kind": "ntm", "field": "turbsim", "rotor_wind": "blades"}}
    turbsim.make_field(plain)
    assert config.make_config(plain).raw["wind"]["blade_speed_rad_s"] == pytest.approx(
        rc.param("omega_g_rated"))
    # a blade speed of 0 never reaches the field: the configuration fills it in
    desc = {**rc.wind.describe(), "parameters": {**rc.wind.describe()["parameters"],
                                                 "blade_speed_rad_s": 0.0}}
    field = wf.turbsim_field(desc, engine.deck_of(rc), 63.0, rc.t_final)
    with pytest.raises(ConfigError, match="wind.blade_speed_rad_s"):
        wf.field_wind(field, desc, rc.t_final)


def test_a_native_run_reads_the_openfast_engines_field():
    """`[wind] field = "turbsim"` on wtftc's plant: the same cached .bts an OpenFAST run of
    the same mean, class, seed, turbine and length makes, read as the rotor sees it: the
    disk average (the turbine's 63 m by default) or the hub point, InflowWind's time
    shift of half the grid's width over uhub."""
    path = turbsim.make_field(NATIVE)
    of = config.make_config({**NATIVE, "engine": "openfast", "profile": "realistic",
                             "wind": {"kind": "ntm", "mean_mps": 16.0}})
    assert wf.field_path(wf.turbsim_field(of.wind.describe(), engine.deck_of(of),
                                          of.param("rotor_radius"), of.t_final)) == path
    ff = wf.read_bts(path)
    t = np.linspace(0.0, 10.0, 401)
    for radius in (63.0, 0.0):
        rc = config.make_config({**NATIVE, "wind": {**NATIVE["wind"], "rotor_radius_m": radius}})
        assert rc.wind.describe()["source"] == str(path)
        expected = np.interp(t + ff.time_shift_s, ff.t, wf.rotor_series(ff, radius))
        assert np.allclose(rc.wind(t), expected, rtol=0, atol=1e-12)  # t ± shift: round-off
    from wtftc.campaign import cases

    res = cases.run(config.make_config(NATIVE), progress=False)
    assert np.allclose(res.column("wind"), np.interp(res.t + ff.time_shift_s, ff.t,
                                                     wf.rotor_series(ff, 63.0)), atol=1e-12)


def test_the_field_key_is_refused_naming_it(tmp_path, monkeypatch):
    for table, what in (({**NATIVE["wind"], "field": "pyconturb"}, '"spectral", "turbsim"'),
                        ({"kind": "constant", "field": "turbsim"}, "kind = \"ntm\" only")):
        with pytest.raises(ConfigError, match="wind.field") as exc:
            config.make_config({**NATIVE, "wind": table})
        assert what in str(exc.value)
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path))  # an empty cache: not made yet
    with pytest.raises(ConfigError, match="not there yet") as exc:
        config.make_config(NATIVE)
    assert "\n" not in str(exc.value)


def test_an_openfast_run_starts_from_its_own_field_and_every_command_makes_it(
        tmp_path, monkeypatch, capsys):
    """With engine = openfast and TurbSim's wind (the defaults), the configuration reads
    the same field for the operating point it starts from (`[wind] field` becomes
    "turbsim"); "spectral" there is refused in one line. `wtftc run --wind-field turbsim`
    makes the field first, into an empty cache, and the run's wind is the field's."""
    from wtftc.cli import main

    found = install.require()  # named, so that the empty cache below still finds it
    monkeypatch.setenv("OPENFAST", str(found.openfast))
    monkeypatch.setenv("TURBSIM", str(found.turbsim))
    monkeypatch.setenv("WTFTC_CACHE", str(tmp_path / "cache"))
    of = {**NATIVE, "engine": "openfast", "profile": "realistic",
          "wind": {"kind": "ntm", "mean_mps": 16.0}}
    assert turbsim.needs_field(of) and not turbsim.needs_field(
        {**of, "openfast": {"wind": "uniform"}})
    with pytest.raises(ConfigError, match="not there yet"):
        config.make_config(of)  # the field is not made by the configuration
    with pytest.raises(ConfigError, match="wind.field") as exc:
        config.make_config({**of, "wind": {**of["wind"], "field": "spectral"}})
    assert "uniform" in str(exc.value) and "\n" not in str(exc.value)
    out = tmp_path / "run"
    assert main(["run", "--controller", "pi", "--profile", "realistic", "--wind", "ntm",
                 "--wind-mean", "16", "--wind-field", "turbsim", "--t-final",
                 str(NATIVE["t_final_s"]), "--seed", str(NATIVE["seed"]), "--quiet", "--out",
                 str(out)]) == 0
    rc = config.make_config(of)  # now made: the OpenFAST run's own configuration reads it
    assert rc.raw["wind"]["field"] == "turbsim"
    saved = config.load_toml(out / "config.toml")
    assert saved["wind"]["field"] == "turbsim"
    assert rc.wind.describe()["source"] == config.make_config(saved).wind.describe()["source"]
