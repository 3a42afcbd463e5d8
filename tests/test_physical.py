"""The physically consistent AFTC (derivation/physical.py): α̇1 verified, closed loop measured."""

import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.campaign import cases
from wtftc.results.metrics import metrics

SCHED = np.array([-9.0e6])  # ∂T/∂β [N m/rad], NREL 5-MW near 12 m/s


def _signals(t):
    w, a = 0.7, 0.01
    yd = np.array([1.26711 + a * np.sin(w * t), a * w * np.cos(w * t),
                   -a * w**2 * np.sin(w * t), -a * w**3 * np.cos(w * t), a * w**4 * np.sin(w * t)])
    # residual f = d: its mean balances rated torque near 0.17 rad of pitch (-h0 - b β)
    return yd, 0.13 + 0.02 * np.sin(1.1 * t)


def _rk4(f, z, t0, t1, n, pc):
    h = (t1 - t0) / n
    for k in range(n):
        t = t0 + k * h

        def rhs(tt, zz):
            yd, d = _signals(tt)
            return np.array(f(z=zz, d=d, yd=yd, sched=SCHED, p_ctrl=pc)["z_dot"]).ravel()

        k1 = rhs(t, z)
        k2 = rhs(t + h / 2, z + h / 2 * k1)
        k3 = rhs(t + h / 2, z + h / 2 * k2)
        k4 = rhs(t + h, z + h * k3)
        z = z + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return z


def _alpha(z, t, pc, omega_dot=None):
    yd, d = _signals(t)
    meas = np.array([z[0], 0.0, z[1], z[1], z[1]])
    loop = load("closed_loop_physical_model")(z=z, d=d, yd=yd, sched=SCHED, p_ctrl=pc)
    wdot = float(loop["omega_dot"]) if omega_dot is None else omega_dot
    out = load("alpha_physical")(x_ctrl=z[2:], meas=meas, yd=yd, sched=SCHED, p_ctrl=pc,
                                 omega_dot=wdot, b_dot=0.0)
    return {k: float(v) for k, v in out.items()}


def test_alpha1_dot_against_central_differences():
    """Along the design-model closed loop (ḃ = 0, ω̇ from the model): O(h²), < 1e-6 at best h;
    the computable α̇1 is the full one with ω̇ replaced by its estimate."""
    pc = lay.defaults("physical_params")
    z0 = np.array([1.28, 0.2, 0.12, 0.14, 0.11])  # above rated, pitch well inside its range
    t0 = 1.0
    z = _rk4(load("closed_loop_physical_model"), z0, 0.0, t0, 1000, pc)
    a = _alpha(z, t0, pc)
    assert a["kappa"] == 1.0 and abs(a["alpha1_dot_full"]) > 1e-3
    hs = np.array([1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5])
    err = []
    f = load("closed_loop_physical_model")
    for h in hs:
        n = max(1, int(np.ceil(h / 2e-4)))
        ap = _alpha(_rk4(f, z, t0, t0 + h, n, pc), t0 + h, pc)["alpha1"]
        am = _alpha(_rk4(f, z, t0, t0 - h, n, pc), t0 - h, pc)["alpha1"]
        err.append(abs((ap - am) / (2 * h) - a["alpha1_dot_full"]) / abs(a["alpha1_dot_full"]))
    slope = np.polyfit(np.log(hs), np.log(err), 1)[0]
    assert 1.9 < slope < 2.1, (err, slope)
    assert min(err) < 1e-6
    with_hat = _alpha(z, t0, pc, omega_dot=a["omega_dot_hat"])
    assert with_hat["alpha1_dot_full"] == pytest.approx(a["alpha1_dot_comp"], rel=1e-13)
    assert abs(a["alpha1_dot_comp"] - a["alpha1_dot_full"]) > 1e-6  # the ω̇ term is exercised


def _run(**over):
    rc = config.make_config({"controller": "physical", "t_final_s": 60.0,
                            "wind": {"kind": "ntm", "mean_mps": 16.0, "turbulence_class": "B"},
                            **over})
    res = cases.run(rc, progress=False)
    return rc, res, metrics(rc, res)


def test_regulates_and_accommodates_a_known_fault():
    """NTM class B at 16 m/s: RMS within 2 % of rated (measured 1.5 %); with the default
    fault known to the accommodation, within 20 % of the fault-free figure (measured +6 %),
    and better after the fault than with the fault unknown (measured 0.0168 vs 0.0316
    rad/s)."""
    rc, _, m1 = _run(case=1)
    _, _, m2 = _run(case=2)
    _, _, m3 = _run(case=3)
    assert all(m["diverged"] is None for m in (m1, m2, m3))
    assert m1["rms_speed_error_rad_s"] < 0.02 * rc.reference
    assert m3["rms_speed_error_rad_s"] < 1.2 * m1["rms_speed_error_rad_s"]
    assert m3["rms_speed_error_after_fault_rad_s"] < m2["rms_speed_error_after_fault_rad_s"]


@pytest.mark.parametrize("mean", [12.0, 14.0])
def test_rotor_is_never_lost_from_below_rated(mean):
    """0.05 rad/s below rated at start, NTM class B, actuator limits active: no overspeed
    above 1.2× rated (measured 1.037 and 1.046) and no loss of the rotor (ω_r stays above
    0.7× rated; measured 0.735 at 12 m/s, where the wind itself falls below rated)."""
    rc, res, m = _run(initial={"omega_r_offset_rad_s": -0.05},
                      wind={"kind": "ntm", "mean_mps": mean, "turbulence_class": "B"})
    assert m["diverged"] is None
    assert m["overspeed_peak_over_rated"] < 1.2
    assert res.column("omega_r").min() > 0.7 * rc.reference
