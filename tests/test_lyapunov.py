"""Lyapunov terms: V̇ against ∇V·f, the observer's P, eq (51)'s bound, θ* fitting."""

import numpy as np
import pytest
from scipy.linalg import solve_continuous_lyapunov

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.verify import checks as verify
from wtftc.verify import lyapunov


@pytest.mark.parametrize("control_sign", [-1.0, 1.0])
def test_vdot_structured_form_equals_grad_V_dot_f(control_sign):
    """The exact identities behind eqs (22), (31), (36), (42), (48) hold at random states."""
    assert verify.vdot_identity_error(200, seed=3, control_sign=control_sign) < 1e-9


def test_table1_observer_gain_is_not_hurwitz():
    """paper-notes defect 1: s⁴+s³+s²+5s+5 has roots 0.740 ± 1.569j: no P > 0 exists."""
    res = lyapunov.observer_lyapunov(lay.paper_table1("K_obs"))
    assert not res.hurwitz and res.P is None
    unstable = res.eigenvalues[res.eigenvalues.real > 0]
    np.testing.assert_allclose(sorted(unstable, key=lambda z: z.imag),
                               [0.740 - 1.569j, 0.740 + 1.569j], atol=1e-3)
    assert np.any(res.P_eigenvalues < 0)  # the Lyapunov equation's solution is indefinite
    assert "NOT Hurwitz" in res.report()


def test_corrected_gain_places_poles_and_gives_P():
    res = lyapunov.observer_lyapunov([14, 71, 154, 120])
    assert res.hurwitz
    np.testing.assert_allclose(sorted(res.eigenvalues.real), [-5, -4, -3, -2], atol=1e-9)
    np.testing.assert_allclose(res.eigenvalues.imag, 0, atol=1e-9)
    assert np.all(np.linalg.eigvalsh(res.P) > 0)
    np.testing.assert_allclose(res.A.T @ res.P + res.P @ res.A, -np.eye(4), atol=1e-10)
    np.testing.assert_allclose(res.P, solve_continuous_lyapunov(res.A.T, -np.eye(4)),
                               rtol=1e-10, atol=1e-12)


def test_table1_does_not_give_the_bound_of_eq51():
    """paper-notes defect 8: r_i/(2γ_i) = 0.001..0.005 against 2/τ = 10."""
    b = lyapunov.decay_bound()
    assert not b.holds
    failing = [lab for lab, v in zip(b.labels, b.kappa_terms, strict=True) if v <= 0]
    assert len(failing) == 4 and all("γ" in lab for lab in failing)
    ok = lyapunov.decay_bound({"gamma": [0.01] * 4, "r": [1.0] * 4})
    assert ok.holds  # r - 4γ/τ = 1 - 0.2 > 0


def test_theta_star_fit_matches_lstsq():
    traj = verify.closed_loop_trajectory(t_final=1.0, dt=1e-3)
    n_p = len(lay.names("plant_states"))
    d1 = np.array([traj.signals.d1(t) for t in traj.t])
    theta, resid = lyapunov.fit_theta_star(traj.z[:, :n_p], traj.z[:, n_p:], d1, ridge=0.0)
    assert theta.size == len(lay.names("theta_star"))
    targets = np.array(load("strict_feedback_targets").map(len(traj.t))(
        traj.z[:, :n_p].T, d1[None, :], lay.defaults("plant_params"))[0])
    phi1 = np.array(load("fuzzy_regressors").map(len(traj.t))(
        traj.z[:, n_p:n_p + 4].T, lay.defaults("controller_params"))[0]).T
    ref = np.linalg.lstsq(phi1, targets[0], rcond=None)[0]
    np.testing.assert_allclose(theta[:phi1.shape[1]], ref, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(resid[0], np.sqrt(np.mean((phi1 @ ref - targets[0]) ** 2)),
                               rtol=1e-6)
