"""Lyapunov analysis on the generated functions: eqs (22)-(25) and (50)-(52).

* :func:`observer_lyapunov`  P of AᵀP + PA = -Q, and whether A is Hurwitz (a P > 0
  exists only then; Table 1's K = [1 1 5 5] fails, paper-notes defect 1);
* :func:`fit_theta_star`     the optimal weights θ*_i by least squares of f_i(X) + d_i
  on the regressors φ_i(x̂) along a trajectory;
* :func:`decay_bound`        the decay-rate candidates of eq (51) and ζ of eq (52).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import load
from wtftc.sim.rhs import PLANTS


@dataclass
class ObserverLyapunov:
    K: np.ndarray
    A: np.ndarray
    eigenvalues: np.ndarray
    routh: np.ndarray  # Routh-Hurwitz conditions, all > 0 ⇔ Hurwitz
    hurwitz: bool
    P: np.ndarray | None  # None when A is not Hurwitz (no P > 0 exists)
    P_eigenvalues: np.ndarray  # of the (unique) solution of the Lyapunov equation

    def report(self) -> str:
        eig = ", ".join(_fmt_complex(z) for z in self.eigenvalues)
        if self.hurwitz:
            return (f"K = {self.K.tolist()}: A is Hurwitz (eigenvalues {eig}); "
                    f"P > 0 with eigenvalues {np.array2string(self.P_eigenvalues, precision=4)}")
        bad = [k + 1 for k, v in enumerate(self.routh) if v <= 0]
        return (f"K = {self.K.tolist()}: A is NOT Hurwitz (eigenvalues {eig}; Routh-Hurwitz "
                f"condition(s) {bad} fail). AᵀP + PA = -Q has no positive definite solution "
                f"(its solution has eigenvalues "
                f"{np.array2string(self.P_eigenvalues, precision=4)}), so the Lyapunov "
                "argument of eqs (22)-(25) does not apply.")


def _fmt_complex(z: complex) -> str:
    if abs(z.imag) < 1e-12:
        return f"{z.real:.4g}"
    return f"{z.real:.4g}{z.imag:+.4g}j"


def observer_lyapunov(K, Q=None) -> ObserverLyapunov:
    K = np.asarray(K, dtype=float).reshape(-1)
    Q = np.eye(K.size) if Q is None else np.asarray(Q, dtype=float)
    out = load("observer_lyapunov")(K_obs=K, Q=Q)
    A = np.array(out["A_obs"])
    routh = np.array(out["routh"]).reshape(-1)
    P = np.array(out["P"])
    hurwitz = bool(np.all(routh > 0))
    return ObserverLyapunov(
        K=K, A=A, eigenvalues=np.linalg.eigvals(A), routh=routh, hurwitz=hurwitz,
        P=P if hurwitz else None, P_eigenvalues=np.linalg.eigvalsh((P + P.T) / 2))


def fit_theta_star(x_plant, x_ctrl, d1, p_plant=None, p_ctrl=None, ridge: float = 1e-10):
    """θ*_i = argmin Σ_t (f_i(X_t) + d_i,t - θᵀφ_i(x̂_t))² + ridge |θ|², for i = 1..4.

    x_plant (N, n_plant), x_ctrl (N, n_ctrl), d1 (N,) are samples along a trajectory. The
    targets f_i(X) + d_i come from eqs (11)-(18); φ_i from the generated regressors.
    Returns the stacked θ* in the layout's ``theta_star`` order and the RMS fit residual
    of each f_i (the ε_i of eq (29), measured).
    """
    x_plant = np.atleast_2d(np.asarray(x_plant, dtype=float))
    x_ctrl = np.atleast_2d(np.asarray(x_ctrl, dtype=float))
    d1 = np.asarray(d1, dtype=float).reshape(-1)
    n = x_plant.shape[0]
    if x_ctrl.shape[0] != n or d1.size != n:
        raise ValueError(f"x_plant, x_ctrl and d1 need the same number of samples; got "
                         f"{n}, {x_ctrl.shape[0]}, {d1.size}")
    pp = lay.vector("plant_params", p_plant)
    pc = lay.vector("controller_params", p_ctrl)
    targets_fn = load("strict_feedback_targets").map(n)
    phi_fn = load("fuzzy_regressors").map(n)
    targets = np.array(targets_fn(x_plant=x_plant.T, d1=d1[None, :], p_plant=pp)["f_plus_d"])
    xhat = x_ctrl[:, lay.block("controller_states", "xhat")].T
    out = phi_fn(xhat=xhat, p_ctrl=pc)
    phis = [np.array(out[f"phi_{i}"]) for i in range(1, lay.layout()["n_chain"] + 1)]
    thetas, residuals = [], []
    for i, phi in enumerate(phis):
        Phi = phi.T
        lhs = Phi.T @ Phi + ridge * np.eye(Phi.shape[1])
        theta = np.linalg.solve(lhs, Phi.T @ targets[i])
        thetas.append(theta)
        residuals.append(float(np.sqrt(np.mean((Phi @ theta - targets[i]) ** 2))))
    return np.concatenate(thetas), np.array(residuals)


@dataclass
class DecayBound:
    kappa_terms: np.ndarray
    labels: list[str]
    zeta_theta: float

    @property
    def holds(self) -> bool:
        return bool(np.all(self.kappa_terms > 0))

    def report(self) -> str:
        bad = [f"{lab} = {v:.4g}" for lab, v in zip(self.labels, self.kappa_terms, strict=True)
               if v <= 0]
        if not bad:
            return (f"eq (51) holds with κ ≤ {self.kappa_terms.min():.4g} (before the observer "
                    f"term 2q/λmax(P)); ζ (θ* part of eq (52)) = {self.zeta_theta:.4g}")
        return ("eq (51) does NOT follow from eq (50): the θ̃ᵀθ̃ coefficients need "
                "r_i/(2γ_i) > 2/τ (1/τ for i = 1), but " + "; ".join(bad))


def decay_bound(p_ctrl=None, theta_star=None) -> DecayBound:
    pc = lay.vector("controller_params", p_ctrl)
    ts = lay.defaults("theta_star") if theta_star is None else np.asarray(theta_star, float)
    out = load("lyapunov_bound")(p_ctrl=pc, theta_star=ts)
    labels = lay.layout()["kappa_labels"]
    return DecayBound(np.array(out["kappa_terms"]).reshape(-1), labels,
                      float(out["zeta_theta"]))


def along_run(rc, res):
    """V_4(t) of eq (47) along a run of the paper's design (``res`` kept its states), with
    θ* fitted on the run itself, and eq (51)'s check: (V, bound, observer analysis)."""
    n_p, n_c, _ = rc.loop.n_states
    x_plant = res.z[:, lay.prefix("plant_states", of=PLANTS[rc.plant]["states"])]
    x_ctrl = res.z[:, n_p:n_p + n_c]
    d1 = res.column("T_aero") / rc.param("J_r")
    p_plant = rc.p_turbine[lay.prefix("plant_params", of="turbine_params")]
    theta_star, _ = fit_theta_star(x_plant, x_ctrl, d1, lay.values("plant_params", p_plant),
                                   lay.values("controller_params", rc.p_ctrl))
    obs = observer_lyapunov(rc.p_ctrl[lay.block("controller_params", "K_obs")])
    n_chain = lay.layout()["n_chain"]
    P = obs.P if obs.hurwitz else np.eye(n_chain)
    n = len(res.t)
    fault = (res.schedule.actuator(res.t)[lay.prefix("fault_inputs", of="actuator_faults")]
             if res.schedule
             else np.tile(lay.defaults("fault_inputs")[:, None], (1, n)))
    yd = np.tile(rc.yd[:, None], (1, n))
    V = np.array(load("lyapunov").map(n)(
        x_plant=x_plant.T, x_ctrl=x_ctrl.T, d1=d1[None, :], yd=yd, fault=fault,
        theta_star=theta_star, P=P, p_plant=p_plant, p_ctrl=rc.p_ctrl)["V"])
    bound = decay_bound(lay.values("controller_params", rc.p_ctrl), theta_star)
    return V[-1], bound, obs
