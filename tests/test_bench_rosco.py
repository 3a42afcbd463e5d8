"""ROSCO's simple simulator as the benchmark's reference point (bench/rosco_sim.py).

Skipped only when rosco is absent, with the reason (``pytest -rs`` prints it)."""

import math

import numpy as np
import pytest

from bench import rosco_sim
from wtftc.artefacts import layout as lay

REASON = rosco_sim.available()
needs_rosco = pytest.mark.skipif(REASON is not None, reason=REASON or "")
RATED_RPM = 12.1


def constant(v):
    return lambda t: np.full_like(np.asarray(t, dtype=float), v)


@needs_rosco
def test_turbine_is_the_nrel5mw_rosco_was_tuned_for():
    """The hand-built Turbine matches ROSCO's DISCON.IN (its inertia, radius, gearbox, air)
    and wtftc's NREL 5-MW where the two models share a parameter."""
    t = rosco_sim.turbine()
    discon = {}
    for line in (rosco_sim._case_dir() / "DISCON.IN").read_text().splitlines():
        if "!" in line and line.split("!")[0].strip():
            discon[line.split("!")[1].split()[0]] = line.split("!")[0].strip()
    assert t.J == pytest.approx(float(discon["WE_Jtot"]), rel=1e-9)
    assert t.rotor_radius == float(discon["WE_BladeRadius"])
    assert t.Ng == float(discon["WE_GearboxRatio"])
    assert t.rho == float(discon["WE_RhoAir"])
    assert t.GenEff == pytest.approx(float(discon["VS_GenEff"]))
    assert t.rated_torque == pytest.approx(float(discon["VS_RtTq"]), rel=1e-4)
    p = dict(zip(lay.names("turbine_params"), lay.defaults("turbine_params"), strict=True))
    assert t.rotor_radius == p["rotor_radius"] and t.Ng == p["gearbox_ratio"]
    assert t.rho == p["air_density"] and t.GenEff / 100 == pytest.approx(p["gen_efficiency"])
    assert t.rated_rotor_speed == pytest.approx(p["omega_g_rated"])


@needs_rosco
def test_rosco_sim_regulates_rated_speed_at_16mps():
    """Constant 16 m/s from the trim: ROSCO's 1-DOF Sim with libdiscon.so stays at rated
    rotor speed, pitched well out of region 2, with rated generator torque."""
    s, wall, setup = rosco_sim.run(constant(16.0), 20.0)
    assert wall > 0 and setup > 0
    assert len(s.t_array) == 801 and s.t_array[1] == pytest.approx(rosco_sim.SIM_DT)
    rpm = s.rot_speed * 60 / (2 * math.pi)
    pitch = np.degrees(s.bld_pitch)
    assert np.all(np.isfinite(rpm)) and np.all(np.isfinite(pitch))
    assert rpm[0] == pytest.approx(RATED_RPM, rel=1e-3)
    settled = s.t_array >= 5.0
    assert np.all(np.abs(rpm[settled] / RATED_RPM - 1) < 0.01)
    assert np.all(np.abs(rpm / RATED_RPM - 1) < 0.05)
    assert np.all(pitch[1:] > 5.0) and np.all(pitch < 20.0)
    rated_tq = rosco_sim.turbine().rated_torque
    np.testing.assert_allclose(s.gen_torque[settled], rated_tq, rtol=0.01)
    # ends where it started: the trim pitch is ROSCO's own operating point
    assert pitch[-1] == pytest.approx(rosco_sim.trim_pitch_deg(rosco_sim.turbine(), 16.0),
                                      abs=0.2)


@needs_rosco
def test_timing_dict_is_finite_and_consistent():
    r = rosco_sim.time_rosco_sim(constant(16.0), 5.0, repeats=2)
    for k in ("wall_s_median", "wall_s_min", "wall_s_max", "ns_per_step", "realtime",
              "setup_s_median"):
        assert math.isfinite(r[k]) and r[k] > 0, k
    assert r["repeats"] == 2 and r["dt"] == rosco_sim.SIM_DT
    assert r["steps"] == 200 and r["t_final_s"] == pytest.approx(5.0)
    assert r["wall_s_min"] <= r["wall_s_median"] <= r["wall_s_max"]
    assert r["realtime"] == pytest.approx(5.0 / r["wall_s_median"], rel=1e-12)
    assert r["ns_per_step"] == pytest.approx(r["wall_s_median"] / 200 * 1e9, rel=1e-12)
    assert r["diverged"] is False
    assert "1-DOF" in r["note"] and "Euler" in r["note"]


def test_missing_rosco_gives_a_reason(monkeypatch):
    from wtftc.sim import rosco

    monkeypatch.setattr(rosco, "available", lambda: "ROSCO is not available (test); install "
                        "it with " + rosco.INSTALL)
    reason = rosco_sim.available()
    assert reason and "wtftc[rosco]" in reason and "\n" not in reason
    with pytest.raises(RuntimeError, match=r"wtftc\[rosco\]"):
        rosco_sim.time_rosco_sim(constant(16.0), 1.0, repeats=1)
