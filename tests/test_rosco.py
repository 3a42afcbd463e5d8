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
