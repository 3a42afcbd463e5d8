"""IEC 61400-1 DLC 2.x pieces (issue 18): the pitch runaway, a control fault that drives a
blade toward fine pitch or feather at its actuator's speed, whatever is commanded."""

from __future__ import annotations

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.campaign import cases
from wtftc.errors import ConfigError
from wtftc.model import faults
from wtftc.results.metrics import metrics


def test_a_runaway_is_a_lock_onto_its_target():
    """eq (19)'s lock with ū the target: fine pitch (0°) by default, 90° feather."""
    fine, feather = faults.parse_faults([
        {"blade": 1, "type": "runaway", "onset_s": 5.0},
        {"blade": 3, "type": "runaway", "onset_s": 5.0, "target_deg": 90.0}])
    assert fine.angle == 0.0 and feather.angle == pytest.approx(np.pi / 2)
    act = faults.Schedule([fine, feather]).actuator(np.array([4.0, 6.0]))
    lock = dict(zip(lay.names("actuator_faults"), act, strict=True))
    assert list(lock["lock_1"]) == [0.0, 1.0] and list(lock["lock_3"]) == [0.0, 1.0]
    assert lock["ubar_1"][1] == 0.0 and lock["ubar_3"][1] == pytest.approx(np.pi / 2)
    assert fine.describe()["target_deg"] == 0.0


@pytest.mark.parametrize("target", [-1.0, 91.0, "fine"])
def test_a_runaway_target_outside_the_pitch_range_is_refused(target):
    with pytest.raises(ConfigError, match="target_deg"):
        faults.parse_faults([{"blade": 1, "type": "runaway", "target_deg": target}])


def test_a_runaway_to_fine_pitch_runs_at_the_rate_limit_and_is_found_as_a_lock():
    """At 16 m/s blade 1 is near 11°; from 20 s it runs to 0° at the 8°/s limit (within
    the actuator's start-up) whatever the physical AFTC commands, and the FDI isolates it
    as a lock on blade 1; the rotor is held (peak below 1.15 × rated)."""
    rc = config.make_config({
        "controller": "physical", "case": 4, "t_final_s": 40.0, "output_rate_hz": 100.0,
        "wind": {"kind": "ntm", "mean_mps": 16.0}, "turbine_params": {"gen_torque_law": 1.0},
        "fault": [{"blade": 1, "type": "runaway", "onset_s": 20.0}]})
    res = cases.run(rc, progress=False)
    m = metrics(rc, res)
    b1 = np.degrees(res.column("beta_1"))
    start = b1[np.searchsorted(res.t, 20.0)]
    reached = res.t[np.argmax((res.t > 20.0) & (b1 < 0.01))]
    assert start > 8.0
    assert reached - 20.0 == pytest.approx(start / 8.0, abs=0.25)
    assert b1[-1] == pytest.approx(0.0, abs=1e-6)
    f = m["fdi"]["faults"][0]
    assert f["detected"] and f["isolated_blade"] == 1 and f["identified_type"] == "lock"
    assert f["correct"]
    assert m["overspeed_peak_over_rated"] < 1.15 and m["diverged"] is None
