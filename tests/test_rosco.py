"""ROSCO in the loop (optional extra). Skipped only when rosco is absent, with the reason."""

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.results.metrics import metrics
from wtftc.sim import rosco

REASON = rosco.available()
needs_rosco = pytest.mark.skipif(REASON is not None, reason=REASON or "")


@needs_rosco
def test_rosco_holds_rated_at_constant_wind():
    """Constant 16 m/s from the trim: ROSCO keeps rated speed, the trim pitch and rated torque,
    which checks the adapter's units (HSS speed and torque, radians) end to end."""
    rc = config.make_config({"controller": "rosco", "t_final_s": 20.0,
                            "wind": {"kind": "constant", "speed_mps": 16.0}})
    res = cases.run(rc, progress=False)
    m = metrics(rc, res)
    assert m["diverged"] is None
    assert m["max_abs_speed_error_rad_s"] < 1e-4
    np.testing.assert_allclose(res.column("beta_1")[-1], res.column("beta_1")[0], atol=1e-4)
    np.testing.assert_allclose(res.column("T_gen")[-1], rc.p_turbine[
        lay.index("turbine_params", "gen_torque_rated")], rtol=1e-4)


@needs_rosco
def test_rosco_regulates_turbulence_and_the_fdi_monitors_it():
    rc = config.make_config({"controller": "rosco", "case": 2, "t_final_s": 40.0,
                            "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"},
                            "fault": [{"blade": 2, "type": "loss_of_effectiveness",
                                       "rho": 0.5, "onset_s": 10.0}]})
    res = cases.run(rc, progress=False)
    m = metrics(rc, res)
    assert m["diverged"] is None and m["overspeed_peak_over_rated"] < 1.2
    assert m["fdi"]["isolation_correct"] and m["fdi"]["blades"]["2"]["detected_at_s"] > 10.0


def test_missing_rosco_is_a_clear_error(monkeypatch):
    from wtftc.errors import ConfigError

    monkeypatch.setattr(rosco, "available", lambda: "ROSCO is not available (test); install "
                        "it with " + rosco.INSTALL)
    with pytest.raises(ConfigError, match=r"wtftc\[rosco\]"):
        config.make_config({"controller": "rosco"})


def test_rosco_has_no_accommodation_cases():
    if REASON:
        pytest.skip(REASON)
    from wtftc.errors import ConfigError

    rc = config.make_config({"controller": "rosco", "case": 3, "t_final_s": 30.0})
    with pytest.raises(ConfigError, match="no fault accommodation"):
        cases.run(rc, progress=False)


def _both_paths(raw: dict) -> tuple:
    """One run with DISCON called from inside the compiled loop (the default) and through
    ROSCO's Python ControllerInterface every 5 ms (the adapter it replaces)."""
    rc = config.make_config(raw)
    out = []
    for compiled in (True, False):
        inputs, _ = cases._prepare(rc)
        out.append(rosco.run(rc.loop, inputs, rc.t_final, rc.dt, rc.decimate,
                             progress=False, compiled=compiled))
    return rc, out


@needs_rosco
def test_discon_inside_the_compiled_loop_is_the_python_adapter_bit_for_bit():
    """Issue 19: the bridge writes the avrSWAP fields ControllerInterface writes, rounded to
    float32 as it rounds them, with the same noise draws in the same order, so DISCON reads
    the same bits and the run is the same, not merely within float32: on the tower, with
    the realistic sensors' noise and a lock off the step grid (which cuts a chunk inside a
    control interval)."""
    rc, (fast, ref) = _both_paths({
        "controller": "rosco", "plant": "tower", "profile": "realistic", "case": 2,
        "t_final_s": 30.0, "seed": 3,
        "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"},
        "fault": [{"type": "lock", "blade": 1, "onset_s": 10.3712}]})
    assert fast.diverged is None and fast.steps == ref.steps == 30_000
    np.testing.assert_array_equal(fast.outputs, ref.outputs)
    np.testing.assert_array_equal(fast.z_final, ref.z_final)
    # ROSCO's pitch really moved the blades it holds (not a frozen command)
    assert np.ptp(fast.column("beta_2")) > np.radians(2.0)
    # DISCON was called once per 5-ms interval, not at every step, nor at the steps a
    # chunk computes beyond the last one used
    _, so = rosco.compiled_chunk(rc.loop)
    import ctypes
    assert ctypes.CDLL(str(so)).wtftc_discon_calls() == 30.0 / rosco.CONTROL_DT


@needs_rosco
def test_rosco_runs_on_the_plant_of_a_model_mismatch():
    """The plant's own parameters under [mismatch] (the adapter once put the loop's nominal
    ones back every interval, so ROSCO's runs ignored a mismatch)."""
    base = {"controller": "rosco", "case": 1, "t_final_s": 10.0,
            "wind": {"kind": "constant", "speed_mps": 16.0}}
    nominal = cases.run(config.make_config(base), progress=False)
    heavy = cases.run(config.make_config({**base, "mismatch": {"air_density": 1.1}}),
                      progress=False)
    # 10 % more aerodynamic power at rated: ROSCO pitches further to feather
    assert heavy.column("beta_1")[-1] > nominal.column("beta_1")[-1] + np.radians(0.5)
