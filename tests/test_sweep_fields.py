"""A sweep makes the TurbSim fields its runs read before the runs, several at a time
(wtftc.campaign.sweep._make_fields): every field once per run that reads one, at most
``jobs`` at once, and a failure raised, not lost."""

import threading
import time

import pytest

pytest.importorskip("distributed", reason="Dask: pip install 'wtftc[sweep]'")

from wtftc.campaign import sweep  # noqa: E402
from wtftc.errors import EngineError  # noqa: E402


def ntm(seed):
    return {"wind": {"kind": "ntm", "mean_mps": 12.0, "seed": seed, "field": "turbsim"}}


class Recorder:
    """ensure_field's stand-in: how many ran at once, and which."""

    def __init__(self, fail_seed=None):
        self.lock, self.now, self.most, self.seen = threading.Lock(), 0, 0, []
        self.fail_seed = fail_seed

    def __call__(self, raw):
        with self.lock:
            self.now += 1
            self.most = max(self.most, self.now)
            self.seen.append(raw["wind"]["seed"])
        time.sleep(0.05)
        with self.lock:
            self.now -= 1
        if raw["wind"]["seed"] == self.fail_seed:
            raise EngineError("TurbSim stopped")


@pytest.mark.parametrize("jobs", [1, 2, 3])
def test_the_fields_are_made_jobs_at_a_time_and_each_run_gets_its_own(monkeypatch, capsys,
                                                                       jobs):
    rec = Recorder()
    monkeypatch.setattr(sweep, "ensure_field", rec)
    raws = [ntm(s) for s in range(7)] + [{"wind": {"kind": "constant"}}]
    sweep._make_fields(raws, jobs, quiet=False)
    assert sorted(rec.seen) == list(range(7))  # the constant wind reads no field
    assert rec.most == min(jobs, 7)
    assert "TurbSim fields: 7 of 7 runs' ready" in capsys.readouterr().out


def test_a_field_that_fails_is_raised_after_the_others_end(monkeypatch):
    rec = Recorder(fail_seed=2)
    monkeypatch.setattr(sweep, "ensure_field", rec)
    with pytest.raises(EngineError, match="TurbSim stopped"):
        sweep._make_fields([ntm(s) for s in range(6)], 2, quiet=True)
    assert rec.now == 0  # none left running
