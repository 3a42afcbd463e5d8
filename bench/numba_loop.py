"""The hand-written numba baseline of ``make bench``: the same RK4 closed loop as wtftc.

What it reproduces: ``wtftc.sim.rhs.rhs_function(loop)`` (nrel5mw, the paper's or the
physical controller) with ``use_fdi = 0`` (the FDI states do not act on the plant or the
controller then, so they are left out), integrated by the fixed-step RK4 of
``wtftc.sim.integrate.rk4_step`` with the exogenous inputs fed as
``wtftc.sim.integrate.run_loops`` feeds its compiled chunks: the wind at t_k,
t_k + dt/2, t_k + dt, the faults at t_k held over the step, and a blade locked "wherever
it is" bound to the blade angle at its onset step.

Written by hand for numba, never by printing SymPy: the plant of derivation/turbine.py
(``nrel5mw_rhs``), the cubic B-spline Cp(λ, β) on the coefficients CasADi solved for
(Cox-de Boor), the linear pitch-sensitivity schedule, and two controllers:

* ``physical`` (derivation/physical.py): α1, its computable α̇1 in closed form, the
  anti-windup κ and eq (49)-style accommodation;
* ``paper`` (derivation/backstepping.py, observer.py, fuzzy.py; Bakhshi & Alfi 2020,
  eqs (21)-(49)): the computable α̇1..α̇3 are Lie derivatives along the controller's own
  vector field (ẏ replaced by ẏ̂ = x̂2 + f̂1), evaluated by truncated Taylor series of
  that field's flow (Taylor-mode differentiation): if ż = f(z) then d/dt h(z(t)) = L_f h,
  so α̇1 = [α1]_1, α̇2 = [α2]_1 (which needs [α1]_2) and α̇3 = [α3]_1 (which needs [α2]_2
  and [α1]_3), where [q]_n is the t^n coefficient of q(z(t)). The fuzzy regressors enter
  through the series of ν(z_k(t)) (Faà di Bruno to order 3) and their Kronecker products
  (φ_i = ν(z_1) ⊗ ... ⊗ ν(z_i), the factorisation of derivation/fuzzy.py).

The sampled loop of ``wtftc.sim.sampled`` (``simulate_sampled_<controller>``, the bench's
row beside wtftc's compiled sampled loop) reuses the same pieces: every ``interval`` steps a
sample reads the plant (exact sensors, the faults at that step), takes the command from the
controller's state and holds it over the interval (no delay), and advances the controller's
own state over T = interval·dt by one RK4 step with the readings held; the plant alone takes
the RK4 steps of dt in between, with the wind and the actuator faults of each step. Without
the FDI, like the continuous loop.

Written for speed the way numba wants it: one flat scratch array with C-style offsets and
no array views in the hot path (numba reference-counts each one), small helpers inlined
at numba's level, the rhs inlined into the RK4 loop at a single call site; IEEE arithmetic
throughout (no fastmath), like the -O2 C that CasADi generates for wtftc.

Used only by the benchmark; wtftc never imports it. ``prepare`` extracts everything from
wtftc (parameters, the B-spline knots and coefficients as CasADi built them, the
schedule's breakpoints, the trimmed initial state, the per-step wind and faults) and
``run`` integrates in one numba call::

    prep = prepare("paper", config.make_config({"case": 3, "controller": "paper"}))
    t, z = run(prep)          # z[:, 0] is ω_r at the output times t
    t, z = run(prep, interval=10)  # the controller sampled every 10 steps
"""

from __future__ import annotations

import copy
import re
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from wtftc.artefacts import layout as lay
from wtftc.model import spline

#: numba options: IEEE arithmetic (no fastmath: same rounding rules as the C of CasADi),
#: and C semantics for a division by zero (no Python exception checks in the hot loop)
JIT = {"error_model": "numpy", "fastmath": False, "cache": False}
#: helpers taking arrays are inlined at numba's level (a call boundary costs the reference
#: counting of every array passed: as much as the arithmetic of the physical rhs); the
#: scalar-heavy _interval, _basis and the large _ctrl_paper are left to LLVM, which runs them
#: faster (measured) and compiles _ctrl_paper in a third of the time
INLINE = {**JIT, "inline": "always"}


# --- the layout, read from generated/layout.json (never retyped) ---------------------------

def _family(group: str, prefix: str, n: int, suffix: str = "") -> int:
    """Index of ``prefix_1<suffix>``; checks that ``prefix_1..prefix_n`` (each with the
    suffix) are consecutive."""
    names = lay.names(group)
    i0 = names.index(f"{prefix}_1{suffix}")
    assert names[i0:i0 + n] == [f"{prefix}_{k}{suffix}" for k in range(1, n + 1)], (
        group, prefix)
    return i0


_L = lay.layout()
N_MF = int(_L["n_mf"])
N_BLADES = int(_L["n_blades"])
assert N_BLADES == 3 and int(_L["n_chain"]) == 4, "written for 3 blades and eqs (11)-(14)"
RULES = [N_MF ** i for i in range(1, 5)]
assert list(lay.rule_counts()) == RULES

# plant states (nrel5mw)
_S = lay.names("nrel5mw_states")
assert _S[:3] == ["omega_r", "theta_s", "omega_g"]
assert _S[3:6] == [f"beta_{j}" for j in (1, 2, 3)]
assert _S[6:9] == [f"beta_rate_{j}" for j in (1, 2, 3)]
N_P = len(_S)

# turbine parameters
_TP = {n: lay.index("turbine_params", n) for n in lay.names("turbine_params")}
T_JR, T_JG, T_KS, T_DS = _TP["J_r"], _TP["J_g"], _TP["k_s"], _TP["d_s"]
T_RHO_AIR, T_R = _TP["air_density"], _TP["rotor_radius"]
T_TGR, T_CPW, T_WGR = _TP["gen_torque_rated"], _TP["gen_constant_power"], _TP["omega_g_rated"]
T_PMIN, T_PMAX, T_RMAX = _TP["pitch_min"], _TP["pitch_max"], _TP["pitch_rate_max"]

# exogenous inputs
A_RHO = _family("actuator_faults", "rho", 3)
A_LOCK = _family("actuator_faults", "lock", 3)
A_UBAR = _family("actuator_faults", "ubar", 3)
A_WN = _family("actuator_faults", "omega_n", 3)
A_ZETA = _family("actuator_faults", "zeta", 3)
S_GAIN = _family("sensor_faults", "gain_beta_meas", 3, "_m1")
S_OFFSET = _family("sensor_faults", "offset_beta_meas", 3, "_m1")
S_FIXED = _family("sensor_faults", "stuck_beta_meas", 3, "_m1")
S_VALUE = _family("sensor_faults", "stuck_value_beta_meas", 3, "_m1")
K_RHO = _family("fault_inputs", "rho", 3)
K_LOCK = _family("fault_inputs", "lock", 3)
K_UBAR = _family("fault_inputs", "ubar", 3)
assert lay.names("reference") == [f"yd_{m}" for m in range(5)]

# physical controller parameters
_PP = {n: lay.index("physical_params", n) for n in lay.names("physical_params")}
Q_C1, Q_C2, Q_GAM, Q_SIG = _PP["phys_c1"], _PP["phys_c2"], _PP["phys_gamma"], _PP["phys_sigma"]
Q_THMAX, Q_J, Q_TG, Q_TAU = (_PP["phys_theta_max"], _PP["phys_inertia"],
                             _PP["phys_gen_torque"], _PP["phys_tau_a"])
Q_BMIN, Q_BMAX, Q_GMIN, Q_RMAX = (_PP["phys_pitch_min"], _PP["phys_pitch_max"],
                                  _PP["phys_dTdbeta_min"], _PP["phys_rate_max"])
Q_W, Q_OFF, Q_SC = _PP["mf_width"], _PP["x_offset_1"], _PP["x_scale_1"]
Q_CEN = _family("physical_params", "mf_centre", N_MF)
Q_TDC = _PP["phys_td_corner"]
N_C_PHYSICAL = len(lay.names("physical_states"))
# the weights, then the speed observer's ω̂_r, η (off), then the tower damper's ŝ and its
# low-passed acceleration a_f (off)
assert N_C_PHYSICAL == N_MF + 4

# paper controller parameters (eq (49)'s ρ̂, σ̂, ū are replaced by the known_fault input)
P_K = _family("controller_params", "K_obs", 4)
P_C = _family("controller_params", "c", 4)
P_GAM = _family("controller_params", "gamma", 4)
P_R = _family("controller_params", "r", 4)
P_TAU = lay.index("controller_params", "tau_young")
P_W = lay.index("controller_params", "mf_width")
P_CEN = _family("controller_params", "mf_centre", N_MF)
P_OFF = _family("controller_params", "x_offset", 4)
P_SC = _family("controller_params", "x_scale", 4)
P_TAUB = lay.index("controller_params", "tau_b_model")
P_B = _family("controller_params", "b", 3)
P_SIGN = lay.index("controller_params", "control_sign")
_CS = lay.names("controller_states")
N_C_PAPER = len(_CS)
assert _CS[:4] == [f"xhat_{k}" for k in range(1, 5)] and N_C_PAPER == 4 + sum(RULES)
TH1, TH2, TH3, TH4 = 4, 4 + RULES[0], 4 + RULES[0] + RULES[1], 4 + sum(RULES[:3])
N = N_MF
N2, N3, N4 = RULES[1], RULES[2], RULES[3]
#: absolute positions in z = [plant, controller] of the paper controller's states
Z_XHAT, Z_TH1, Z_TH2, Z_TH3, Z_TH4 = (N_P, N_P + TH1, N_P + TH2, N_P + TH3, N_P + TH4)

#: the rhs scratch: one flat float64 array, C-style offsets. The hot path creates no array
#: views (numba reference-counts every view, which cost more than the arithmetic here)
W_NUD = 0                       # nud[k, n, j] = d^n ν_j/dz^n at input k: (k*4 + n)*N + j
W_G = W_NUD + 16 * N            # g[k, n, j] = t^n coefficient of ν_j(z_k(t)), same layout
W_X = W_G + 16 * N              # X[k, n] = t^n coefficient of x̂_k(t): k*4 + n
W_PHI1 = W_X + 16               # φ1 series, order n entry m: n*N + m (orders 0-3)
W_PHI2 = W_PHI1 + 4 * N         # n*N² + m (orders 0-2)
W_PHI3 = W_PHI2 + 3 * N2        # n*N³ + m (orders 0-1)
W_PHI4 = W_PHI3 + 2 * N3        # m (order 0)
W_TH1 = W_PHI4 + N4             # θ̂1 series (orders 0-3), layout of φ1
W_TH2 = W_TH1 + 4 * N           # θ̂2 series (orders 0-2)
W_TH3 = W_TH2 + 3 * N2          # θ̂3 series (orders 0-1)
W_SIZE = W_TH3 + 2 * N3


# --- small numerical helpers ---------------------------------------------------------------

@njit(**INLINE)
def _fmax(x, y):
    """C fmax: the number when one argument is NaN (as CasADi's fmax)."""
    return x if x > y or y != y else y


@njit(**INLINE)
def _fmin(x, y):
    return x if x < y or y != y else y


@njit(**JIT)
def _interval(x, grid, lo, ng):
    """Index i of grid[lo + i] <= x < grid[lo + i + 1], within [0, ng - 2] (CasADi's
    casadi_low on a strictly increasing grid of ng points), by bisection."""
    if ng < 3 or not x >= grid[lo + 1]:
        return 0
    if x >= grid[lo + ng - 2]:
        return ng - 2
    a, b = 1, ng - 2  # grid[lo + a] <= x < grid[lo + b]
    while b - a > 1:
        m = (a + b) // 2
        if x >= grid[lo + m]:
            a = m
        else:
            b = m
    return a


@njit(**JIT)
def _basis(x, knots):
    """(i, N_i, N_i+1, N_i+2, N_i+3): the 4 nonzero cubic B-splines at x and the index of
    the first (Cox-de Boor in the triangular form of Piegl & Tiller's BasisFuns, 6
    divisions); the knot span [knots[i + 3], knots[i + 4]) holds x, the last one x = end."""
    i = _interval(x, knots, 3, knots.shape[0] - 6)
    s = i + 3
    left1 = x - knots[s]
    left2 = x - knots[s - 1]
    left3 = x - knots[s - 2]
    right1 = knots[s + 1] - x
    right2 = knots[s + 2] - x
    right3 = knots[s + 3] - x
    t = 1.0 / (right1 + left1)           # degree 1
    n0 = right1 * t
    n1 = left1 * t
    t = n0 / (right1 + left2)            # degree 2
    m0 = right1 * t
    saved = left2 * t
    t = n1 / (right2 + left1)
    m1 = saved + right2 * t
    m2 = left1 * t
    t = m0 / (right1 + left3)            # degree 3
    b0 = right1 * t
    saved = left3 * t
    t = m1 / (right2 + left2)
    b1 = saved + right2 * t
    saved = left2 * t
    t = m2 / (right3 + left1)
    b2 = saved + right3 * t
    b3 = left1 * t
    return i, b0, b1, b2, b3


@njit(**INLINE)
def cp_spline(lam, beta, kx, ky, coef):
    """Cp(λ, β): the tensor-product cubic B-spline of CasADi's 'bspline' interpolant with
    its coefficients coef[i_λ + n_λ i_β], inputs clipped to the grid
    (wtftc.model.aero.cp_interpolant)."""
    lam = _fmin(_fmax(lam, kx[0]), kx[kx.shape[0] - 1])
    beta = _fmin(_fmax(beta, ky[0]), ky[ky.shape[0] - 1])
    i, x0, x1, x2, x3 = _basis(lam, kx)
    j, y0, y1, y2, y3 = _basis(beta, ky)
    n = kx.shape[0] - 4
    c = (j * n) + i
    r0 = x0 * coef[c] + x1 * coef[c + 1] + x2 * coef[c + 2] + x3 * coef[c + 3]
    c += n
    r1 = x0 * coef[c] + x1 * coef[c + 1] + x2 * coef[c + 2] + x3 * coef[c + 3]
    c += n
    r2 = x0 * coef[c] + x1 * coef[c + 1] + x2 * coef[c + 2] + x3 * coef[c + 3]
    c += n
    r3 = x0 * coef[c] + x1 * coef[c + 1] + x2 * coef[c + 2] + x3 * coef[c + 3]
    return y0 * r0 + y1 * r1 + y2 * r2 + y3 * r3


@njit(**INLINE)
def sched_linear(beta, grid, values):
    """∂T_aero/∂β from the linear schedule, held beyond its ends
    (wtftc.model.aero.pitch_sensitivity_schedule)."""
    n = grid.shape[0]
    x = _fmin(_fmax(beta, grid[0]), grid[n - 1])
    j = _interval(x, grid, 0, n)
    a = (x - grid[j]) / (grid[j + 1] - grid[j])
    return (1.0 - a) * values[j] + a * values[j + 1]


@njit(**INLINE)
def _nu_derivatives(z, pc, i_cen, width, nmax, ws, o):
    """ws[o + n*N + j] = d^n ν_j/dz^n (n <= nmax <= 3) of the normalized Gaussian
    memberships ν_j = μ_j/Σ_l μ_l (derivation/fuzzy.py); centres pc[i_cen:i_cen + N].

    ν is a softmax of s_l = a_l z + const, a_l = c_l/w² (the -z²/2w² of log μ cancels),
    evaluated with the largest s_l subtracted (no overflow at any z). With the moments
    m_r = Σ_l ã_l^r ν_l of the slopes ã_l = a_l - Σ_l a_l ν_l (a shift leaves the softmax
    unchanged and keeps the sums small), Leibniz on ν_j Σ_l e^{s_l} = e^{s_j} gives
        D^n ν_j = ã_j^n ν_j - Σ_{k<n} C(n, k) D^k ν_j m_{n-k}.
    """
    inv_w2 = 1.0 / (width * width)
    smax = -np.inf
    for l in range(N):
        c = pc[i_cen + l]
        s = c * inv_w2 * (z - 0.5 * c)
        ws[o + l] = s
        if s > smax:
            smax = s
    tot = 0.0
    for l in range(N):
        e = np.exp(ws[o + l] - smax)
        ws[o + l] = e
        tot += e
    inv_tot = 1.0 / tot
    m1 = 0.0
    for l in range(N):
        ws[o + l] *= inv_tot
        m1 += pc[i_cen + l] * inv_w2 * ws[o + l]
    if nmax == 0:
        return
    mom1 = 0.0
    mom2 = 0.0
    mom3 = 0.0
    for l in range(N):
        at = pc[i_cen + l] * inv_w2 - m1
        nu = ws[o + l]
        mom1 += at * nu
        mom2 += at * at * nu
        mom3 += at * at * at * nu
    for j in range(N):
        at = pc[i_cen + j] * inv_w2 - m1
        nu = ws[o + j]
        d1 = at * nu - nu * mom1
        ws[o + N + j] = d1
        if nmax >= 2:
            d2 = at * at * nu - (nu * mom2 + 2.0 * d1 * mom1)
            ws[o + 2 * N + j] = d2
            if nmax >= 3:
                ws[o + 3 * N + j] = at * at * at * nu - (nu * mom3 + 3.0 * d1 * mom2
                                                         + 3.0 * d2 * mom1)


# --- plant: derivation/turbine.py nrel5mw_rhs ----------------------------------------------

@njit(**INLINE)
def _measure(z, sf):
    """Pitch sensors (turbine.measured_pitch): gain fault, or stuck at a fixed value (sensor
    m1's faults; the bench's runs have none, and the two sensors of a blade then read the
    same: the virtual sensor's mean is that reading)."""
    b1 = ((1.0 - sf[S_FIXED]) * (sf[S_GAIN] * z[3] + sf[S_OFFSET])
          + sf[S_FIXED] * sf[S_VALUE])
    b2 = ((1.0 - sf[S_FIXED + 1]) * (sf[S_GAIN + 1] * z[4] + sf[S_OFFSET + 1])
          + sf[S_FIXED + 1] * sf[S_VALUE + 1])
    b3 = ((1.0 - sf[S_FIXED + 2]) * (sf[S_GAIN + 2] * z[5] + sf[S_OFFSET + 2])
          + sf[S_FIXED + 2] * sf[S_VALUE + 2])
    return b1, b2, b3


@njit(**INLINE)
def _actuator(j, b, w, v, af, b_min, b_max, r_max):
    """(β̇_j, β̈_j): eq (19) on the command, clipped to the position range; the limited
    2nd-order actuator (turbine.limited_actuator, Odgaard et al. 2013)."""
    rho = af[A_RHO + j]
    u = rho * v + af[A_LOCK + j] * (af[A_UBAR + j] - rho * v)
    u = _fmin(_fmax(u, b_min), b_max)
    rate = _fmin(_fmax(w, -r_max), r_max)
    if (b >= b_max and rate > 0.0) or (b <= b_min and rate < 0.0):
        rate = 0.0
    wn = af[A_WN + j]
    acc = wn * wn * (u - b) - 2.0 * af[A_ZETA + j] * wn * w
    if (w >= r_max and acc > 0.0) or (w <= -r_max and acc < 0.0):
        acc = 0.0
    return rate, acc


@njit(**INLINE)
def _plant(z, v1, v2, v3, wind, cp, af, pt, zdot, o):
    """ż[0:9] into zdot[o:o + 9]: two-mass drivetrain with generator torque, three
    limited pitch actuators."""
    w_r, th_s, w_g = z[0], z[1], z[2]
    R = pt[T_R]
    t_aero = pt[T_RHO_AIR] * np.pi * R * R * (wind * wind * wind) * cp / (2.0 * w_r)
    cpw = pt[T_CPW]
    t_gen = (1.0 - cpw) * pt[T_TGR] + cpw * pt[T_TGR] * pt[T_WGR] / w_g
    shaft = pt[T_KS] * th_s + pt[T_DS] * (w_r - w_g)
    zdot[o] = (t_aero - shaft) / pt[T_JR]
    zdot[o + 1] = w_r - w_g
    zdot[o + 2] = (shaft - t_gen) / pt[T_JG]
    b_min, b_max, r_max = pt[T_PMIN], pt[T_PMAX], pt[T_RMAX]
    zdot[o + 3], zdot[o + 6] = _actuator(0, z[3], z[6], v1, af, b_min, b_max, r_max)
    zdot[o + 4], zdot[o + 7] = _actuator(1, z[4], z[7], v2, af, b_min, b_max, r_max)
    zdot[o + 5], zdot[o + 8] = _actuator(2, z[5], z[8], v3, af, b_min, b_max, r_max)


@njit(**INLINE)
def _cp_at(z, wind, pt, kx, ky, coef):
    """Cp at the true (λ, β̄) (the generated aero_operating_point)."""
    lam = z[0] * pt[T_R] / wind
    beta_mean = (z[3] + z[4] + z[5]) / 3.0
    return cp_spline(lam, beta_mean, kx, ky, coef)


@njit(**INLINE)
def rhs_plant(z, v1, v2, v3, wind, af, pt, kx, ky, coef, zdot, o):
    """ż[0:9] of the plant alone, driven by the commands v1..v3 (the sampled loop's plant
    step: sampled._plant_step), into zdot[o:o + 9]."""
    _plant(z, v1, v2, v3, wind, _cp_at(z, wind, pt, kx, ky, coef), af, pt, zdot, o)


# --- controller "physical": derivation/physical.py -----------------------------------------

@njit(**INLINE)
def _ctrl_physical(z, bm1, bm2, bm3, yd, sched, pc, kf, zdot, o, ws):
    """v (all three blades) and θ̂̇ (into zdot) of the physical design."""
    c1, c2, gam, sig = pc[Q_C1], pc[Q_C2], pc[Q_GAM], pc[Q_SIG]
    J, tau = pc[Q_J], pc[Q_TAU]
    b_min, b_max = pc[Q_BMIN], pc[Q_BMAX]
    omega_r = z[0]
    sc = pc[Q_SC]
    _nu_derivatives((omega_r - pc[Q_OFF]) / sc, pc, Q_CEN, pc[Q_W], 1, ws, W_NUD)
    F = 0.0      # f̂ = θ̂ᵀφ(ω_r)            (L1_0)
    F1 = 0.0     # θ̂ᵀ ∂φ/∂ω_r              (L1_1)
    B00 = 0.0    # φᵀφ                      (B1_0_0)
    th2 = 0.0    # |θ̂|²
    for m in range(N):
        th = z[N_P + m]
        F += th * ws[W_NUD + m]
        F1 += th * ws[W_NUD + N + m]
        B00 += ws[W_NUD + m] * ws[W_NUD + m]
        th2 += th * th
    F1 /= sc
    G = -_fmax(-sched, pc[Q_GMIN])           # ∂T/∂β ≤ -gmin < 0
    b = G / J
    h0 = -pc[Q_TG] / J
    beta_bar = (bm1 + bm2 + bm3) / 3.0
    z1 = omega_r - yd[0]
    alpha1 = (-c1 * z1 - h0 - F + yd[1]) / b
    z2 = beta_bar - alpha1
    w_dot_hat = b * beta_bar + h0 + F        # ω̇_r → b β̄ + h0 + f̂, ḃ → 0
    base = -(c1 + F1) * w_dot_hat + c1 * yd[1] + yd[2]
    adapt = gam * z1 * B00 - sig * F         # d/dt f̂ from θ̂̇ (times κ)
    # κ from the command with κ = 1: position and rate saturation, projection bound
    rate1 = -c2 * z2 - b * z1 + (base - adapt) / b    # (U1 - β̄)/τ_a
    U1 = beta_bar + tau * rate1
    r_max = pc[Q_RMAX]
    sat = ((U1 >= b_max and z1 > 0.0) or (U1 <= b_min and z1 < 0.0)
           or (rate1 >= r_max and z1 > 0.0) or (rate1 <= -r_max and z1 < 0.0))
    th_max = pc[Q_THMAX]
    proj = th2 >= th_max * th_max and gam * z1 * F - sig * th2 > 0.0
    kappa = 0.0 if (sat or proj) else 1.0
    U = beta_bar + tau * (-c2 * z2 - b * z1 + (base - kappa * adapt) / b)
    lock_sum = 0.0
    gain = 0.0
    for j in range(3):
        lock_sum += kf[K_LOCK + j] * kf[K_UBAR + j]
        gain += (1.0 - kf[K_LOCK + j]) * kf[K_RHO + j]
    gain = _fmax(gain, 0.3)
    for m in range(N):
        zdot[o + N_P + m] = kappa * (gam * z1 * ws[W_NUD + m] - sig * z[N_P + m])
    # the speed observer off (phys_obs_omega = 0, the default): ω̂_r follows ω_r at 1 rad/s,
    # its innovation η decays at 1/s
    zdot[o + N_P + N] = omega_r - z[N_P + N]
    zdot[o + N_P + N + 1] = -z[N_P + N + 1]
    # the tower damper off (phys_td_gain = 0, the default; no tower: no acceleration): its
    # state decays at the high-pass corner
    zdot[o + N_P + N + 2] = -pc[Q_TDC] * z[N_P + N + 2]
    # and its acceleration's low-pass off (phys_td_lpf = 0, the default): a_f decays at 1/s
    zdot[o + N_P + N + 3] = -z[N_P + N + 3]
    return (3.0 * _fmin(_fmax(U, b_min), b_max) - lock_sum) / gain


@njit(**INLINE)
def ctrl_physical(z, sf, ck, yd, pc, sb, sg, ws, zdot, o):
    """The physical design on the plant state z's sensors: the commands v1..v3 (one for
    every blade) and θ̂̇ (into zdot[o + N_P:])."""
    b1, b2, b3 = _measure(z, sf)
    sched = sched_linear((b1 + b2 + b3) / 3.0, sb, sg)
    v = _ctrl_physical(z, b1, b2, b3, yd, sched, pc, ck, zdot, o, ws)
    return v, v, v


@njit(**INLINE)
def rhs_physical(z, wind, af, sf, ck, yd, pt, pc, kx, ky, coef, sb, sg, ws, zdot, o):
    """ż = [plant, θ̂] of the closed loop with the physical controller, into
    zdot[o:o + n]."""
    cp = _cp_at(z, wind, pt, kx, ky, coef)
    v1, v2, v3 = ctrl_physical(z, sf, ck, yd, pc, sb, sg, ws, zdot, o)
    _plant(z, v1, v2, v3, wind, cp, af, pt, zdot, o)


# --- controller "paper": derivation/backstepping.py, observer.py, fuzzy.py -----------------

@njit(**INLINE)
def _kron2(ws, ou, ov, out, acc):
    """ws[out + a*N + b] (+)= ws[ou + a] ws[ov + b]."""
    for a in range(N):
        u = ws[ou + a]
        for b in range(N):
            if acc:
                ws[out + a * N + b] += u * ws[ov + b]
            else:
                ws[out + a * N + b] = u * ws[ov + b]


@njit(**INLINE)
def _kron3(ws, ou, ov, ow, out, acc):
    """ws[out + (a*N + b)*N + c] (+)= ws[ou + a] ws[ov + b] ws[ow + c]."""
    for a in range(N):
        for b in range(N):
            uv = ws[ou + a] * ws[ov + b]
            k = out + (a * N + b) * N
            for c in range(N):
                if acc:
                    ws[k + c] += uv * ws[ow + c]
                else:
                    ws[k + c] = uv * ws[ow + c]


@njit(**INLINE)
def _series_dot(ws, oth, ophi, size, n):
    """t^n coefficient of θ̂(t)ᵀφ(t): Σ_{a+b=n} θ_a·φ_b (series at ws[o + order*size])."""
    s = 0.0
    for a in range(n + 1):
        t = oth + a * size
        p = ophi + (n - a) * size
        for m in range(size):
            s += ws[t + m] * ws[p + m]
    return s


@njit(**INLINE)
def _adapt_series(ws, oth, ophi, size, n, chi0, chi1, chi2, gamma, r):
    """θ̂'s t^(n+1) coefficient from θ̂̇ = γ χ φ - r θ̂ (n <= 2, χ's coefficients given):
    [γ Σ_a χ_a φ_{n-a} - r θ_n] / (n + 1)."""
    inv = 1.0 / (n + 1)
    for m in range(size):
        s = chi0 * ws[ophi + n * size + m]
        if n >= 1:
            s += chi1 * ws[ophi + (n - 1) * size + m]
        if n >= 2:
            s += chi2 * ws[ophi + (n - 2) * size + m]
        ws[oth + (n + 1) * size + m] = (gamma * s - r * ws[oth + n * size + m]) * inv


@njit(**INLINE)
def _series_order0(z, pc, ws):
    """Order 0: θ̂_1..3 into the workspace, the memberships of x̂1..x̂4 (with their
    z-derivatives as far as each input needs) and φ_1..4; returns f̂_1..4 = θ̂ᵀφ (eq (21))."""
    for m in range(N):
        ws[W_TH1 + m] = z[Z_TH1 + m]
    for m in range(N2):
        ws[W_TH2 + m] = z[Z_TH2 + m]
    for m in range(N3):
        ws[W_TH3 + m] = z[Z_TH3 + m]
    for k in range(4):
        ws[W_X + 4 * k] = z[Z_XHAT + k]
        zk = (z[Z_XHAT + k] - pc[P_OFF + k]) / pc[P_SC + k]
        _nu_derivatives(zk, pc, P_CEN, pc[P_W], 3 - k, ws, W_NUD + 4 * N * k)
        for j in range(N):
            ws[W_G + 4 * N * k + j] = ws[W_NUD + 4 * N * k + j]
    G0, G1, G2, G3 = W_G, W_G + 4 * N, W_G + 8 * N, W_G + 12 * N  # input k, order 0
    for j in range(N):
        ws[W_PHI1 + j] = ws[G0 + j]
    _kron2(ws, G0, G1, W_PHI2, False)
    _kron3(ws, G0, G1, G2, W_PHI3, False)
    for a in range(N3):
        p3 = ws[W_PHI3 + a]
        for b in range(N):
            ws[W_PHI4 + a * N + b] = p3 * ws[G3 + b]
    F4_0 = 0.0
    for m in range(N4):
        F4_0 += z[Z_TH4 + m] * ws[W_PHI4 + m]
    return (_series_dot(ws, W_TH1, W_PHI1, N, 0), _series_dot(ws, W_TH2, W_PHI2, N2, 0),
            _series_dot(ws, W_TH3, W_PHI3, N3, 0), F4_0)


@njit(**INLINE)
def _series_order1(ws, pc, X01, X11, X21):
    """Order 1 of the memberships of x̂1..x̂3 (rates X_k1) and of φ_1..3."""
    for k, xk1 in ((0, X01), (1, X11), (2, X21)):
        zk1 = xk1 / pc[P_SC + k]
        ko = 4 * N * k
        for j in range(N):
            ws[W_G + ko + N + j] = ws[W_NUD + ko + N + j] * zk1
    G0, G1, G2 = W_G, W_G + 4 * N, W_G + 8 * N      # input k, order 0
    H0, H1, H2 = W_G + N, W_G + 5 * N, W_G + 9 * N  # input k, order 1
    for j in range(N):
        ws[W_PHI1 + N + j] = ws[H0 + j]
    _kron2(ws, H0, G1, W_PHI2 + N2, False)
    _kron2(ws, G0, H1, W_PHI2 + N2, True)
    _kron3(ws, H0, G1, G2, W_PHI3 + N3, False)
    _kron3(ws, G0, H1, G2, W_PHI3 + N3, True)
    _kron3(ws, G0, G1, H2, W_PHI3 + N3, True)


@njit(**INLINE)
def _series_order2(ws, pc, X01, X02, X11, X12):
    """Order 2 of the memberships of x̂1, x̂2 and of φ_1, φ_2."""
    for k, xk1, xk2 in ((0, X01, X02), (1, X11, X12)):
        zk1 = xk1 / pc[P_SC + k]
        zk2 = xk2 / pc[P_SC + k]
        ko = 4 * N * k
        for j in range(N):
            ws[W_G + ko + 2 * N + j] = (ws[W_NUD + ko + N + j] * zk2
                                        + 0.5 * ws[W_NUD + ko + 2 * N + j] * zk1 * zk1)
    G0, G1 = W_G, W_G + 4 * N                       # input k, order 0
    H0, H1 = W_G + N, W_G + 5 * N                   # input k, order 1
    I0, I1 = W_G + 2 * N, W_G + 6 * N               # input k, order 2
    for j in range(N):
        ws[W_PHI1 + 2 * N + j] = ws[I0 + j]
    _kron2(ws, I0, G1, W_PHI2 + 2 * N2, False)
    _kron2(ws, H0, H1, W_PHI2 + 2 * N2, True)
    _kron2(ws, G0, I1, W_PHI2 + 2 * N2, True)


@njit(**INLINE)
def _series_order3(ws, pc, X01, X02, X03):
    """Order 3 of φ_1 (only what α1 needs)."""
    s0 = pc[P_SC]
    z1, z2, z3 = X01 / s0, X02 / s0, X03 / s0
    for j in range(N):
        ws[W_PHI1 + 3 * N + j] = (ws[W_NUD + N + j] * z3 + ws[W_NUD + 2 * N + j] * z1 * z2
                                  + ws[W_NUD + 3 * N + j] * z1 * z1 * z1 / 6.0)


@njit(**INLINE)
def _eq49_terms(pc, kf):
    """Σ σ_j θ_j ū_j and Σ (1 - σ_j) ρ_j θ_j b_j of eq (49) with the fault it is told;
    θ_j = 1/(3 τ_b) of θᵀu (eq (14))."""
    theta_act = 1.0 / (3.0 * pc[P_TAUB])
    lock_sum = 0.0
    gain = 0.0
    for j in range(3):
        lock_sum += kf[K_LOCK + j] * theta_act * kf[K_UBAR + j]
        gain += (1.0 - kf[K_LOCK + j]) * kf[K_RHO + j] * theta_act * pc[P_B + j]
    return lock_sum, gain


@njit(**INLINE)
def _write_ctrl_rates(z, zdot, o, ws, pc, X01, X11, X21, x4_dot, chi4_0):
    """ẋ_ctrl = [x̂̇ (21), θ̂̇_1..4] into zdot[o + N_P:]."""
    g4, r4 = pc[P_GAM + 3], pc[P_R + 3]
    zdot[o + Z_XHAT] = X01
    zdot[o + Z_XHAT + 1] = X11
    zdot[o + Z_XHAT + 2] = X21
    zdot[o + Z_XHAT + 3] = x4_dot
    for m in range(N):
        zdot[o + Z_TH1 + m] = ws[W_TH1 + N + m]
    for m in range(N2):
        zdot[o + Z_TH2 + m] = ws[W_TH2 + N2 + m]
    for m in range(N3):
        zdot[o + Z_TH3 + m] = ws[W_TH3 + N3 + m]
    for m in range(N4):
        zdot[o + Z_TH4 + m] = g4 * chi4_0 * ws[W_PHI4 + m] - r4 * z[Z_TH4 + m]


@njit(**JIT)
def _ctrl_paper(z, y, yd, pc, kf, zdot, o, ws):
    """u0 of eq (49) and ẋ_ctrl = [x̂̇ (21), θ̂̇_1..4] (into zdot[o + N_P:]); returns u0.

    Taylor coefficients [q]_n of every quantity along the flow of the controller's own
    vector field (y with rate ẏ̂ = x̂2 + f̂1, y_d with its derivatives), built order by order
    in the order the backstepping needs them.
    """
    K1, K2, K3 = pc[P_K], pc[P_K + 1], pc[P_K + 2]
    c1, c2 = pc[P_C], pc[P_C + 1]
    g1, g2, g3 = pc[P_GAM], pc[P_GAM + 1], pc[P_GAM + 2]
    r1, r2, r3 = pc[P_R], pc[P_R + 1], pc[P_R + 2]
    tau = pc[P_TAU]
    # --- order 0: memberships (and their z-derivatives, as far as each input needs)
    F1_0, F2_0, F3_0, F4_0 = _series_order0(z, pc, ws)
    x1, x2, x3, x4 = z[Z_XHAT], z[Z_XHAT + 1], z[Z_XHAT + 2], z[Z_XHAT + 3]
    e1_0 = y - x1                                   # e1 = y - x̂1
    chi1_0 = y - yd[0]                              # (26)
    a1_0 = -c1 * chi1_0 - 2.0 * chi1_0 - F1_0       # (32)
    chi2_0 = x2 - a1_0 - yd[1]                      # (31)
    # --- order 1 of the states: their rates, eq (21) and the adaptive laws
    Y1 = x2 + F1_0                                  # ẏ̂ = x̂2 + f̂1
    X01 = -K1 * x1 + x2 + K1 * y + F1_0
    X11 = -K2 * x1 + x3 + K2 * y + F2_0
    X21 = -K3 * x1 + x4 + K3 * y + F3_0
    _adapt_series(ws, W_TH1, W_PHI1, N, 0, chi1_0, 0.0, 0.0, g1, r1)
    _adapt_series(ws, W_TH2, W_PHI2, N2, 0, chi2_0, 0.0, 0.0, g2, r2)
    _series_order1(ws, pc, X01, X11, X21)
    F1_1 = _series_dot(ws, W_TH1, W_PHI1, N, 1)
    F2_1 = _series_dot(ws, W_TH2, W_PHI2, N2, 1)
    chi1_1 = Y1 - yd[1]
    a1_1 = -c1 * chi1_1 - 2.0 * chi1_1 - F1_1       # α̇1 (computable) = [α1]_1
    e1_1 = Y1 - X01
    a2_0 = -c2 * chi2_0 - chi1_0 + a1_1 - F2_0 - K2 * e1_0 - tau * chi2_0  # (37)
    chi3_0 = x3 - a2_0 - yd[2]                      # (36)
    _adapt_series(ws, W_TH3, W_PHI3, N3, 0, chi3_0, 0.0, 0.0, g3, r3)
    F3_1 = _series_dot(ws, W_TH3, W_PHI3, N3, 1)
    chi2_1 = X11 - a1_1 - yd[2]
    first = (X01, X11, X21, Y1, F1_1, F2_1, F3_0, F3_1, F4_0, chi1_0, chi1_1, chi2_0,
             chi2_1, chi3_0, e1_0, e1_1)
    return _ctrl_paper_orders23(z, y, yd, pc, kf, zdot, o, ws, first)


@njit(**INLINE)
def _ctrl_paper_orders23(z, y, yd, pc, kf, zdot, o, ws, first):
    """Orders 2 and 3 of the series, α̇2 and α̇3 (computable), u0 of eq (49) and the
    controller's rates, from the order-0/1 quantities ``first`` of :func:`_ctrl_paper`."""
    (X01, X11, X21, Y1, F1_1, F2_1, F3_0, F3_1, F4_0, chi1_0, chi1_1, chi2_0, chi2_1, chi3_0,
     e1_0, e1_1) = first
    K1, K2, K3, K4 = pc[P_K], pc[P_K + 1], pc[P_K + 2], pc[P_K + 3]
    c1, c2, c3, c4 = pc[P_C], pc[P_C + 1], pc[P_C + 2], pc[P_C + 3]
    g1, g2, r1, r2 = pc[P_GAM], pc[P_GAM + 1], pc[P_R], pc[P_R + 1]
    tau = pc[P_TAU]
    x1, x4 = z[Z_XHAT], z[Z_XHAT + 3]
    # --- order 2
    Y2 = (X11 + F1_1) / 2.0
    X02 = (-K1 * X01 + X11 + K1 * Y1 + F1_1) / 2.0
    X12 = (-K2 * X01 + X21 + K2 * Y1 + F2_1) / 2.0
    _adapt_series(ws, W_TH1, W_PHI1, N, 1, chi1_0, chi1_1, 0.0, g1, r1)
    _adapt_series(ws, W_TH2, W_PHI2, N2, 1, chi2_0, chi2_1, 0.0, g2, r2)
    _series_order2(ws, pc, X01, X02, X11, X12)
    F1_2 = _series_dot(ws, W_TH1, W_PHI1, N, 2)
    F2_2 = _series_dot(ws, W_TH2, W_PHI2, N2, 2)
    chi1_2 = Y2 - yd[2] / 2.0
    a1_2 = -c1 * chi1_2 - 2.0 * chi1_2 - F1_2
    e1_2 = Y2 - X02
    a2_1 = (-c2 * chi2_1 - chi1_1 + 2.0 * a1_2 - F2_1 - K2 * e1_1
            - tau * chi2_1)                         # α̇2 (computable) = [α2]_1
    a3_0 = -c3 * chi3_0 - chi2_0 + a2_1 - K3 * e1_0 - F3_0 - tau * chi3_0  # (43)
    chi4_0 = x4 - a3_0 - yd[3]                      # (45)
    chi2_2 = X12 - a1_2 - yd[3] / 2.0
    chi3_1 = X21 - a2_1 - yd[3]
    # --- order 3 (only what α1 needs)
    Y3 = (X12 + F1_2) / 3.0
    X03 = (-K1 * X02 + X12 + K1 * Y2 + F1_2) / 3.0
    _adapt_series(ws, W_TH1, W_PHI1, N, 2, chi1_0, chi1_1, chi1_2, g1, r1)
    _series_order3(ws, pc, X01, X02, X03)
    F1_3 = _series_dot(ws, W_TH1, W_PHI1, N, 3)
    chi1_3 = Y3 - yd[3] / 6.0
    a1_3 = -c1 * chi1_3 - 2.0 * chi1_3 - F1_3
    a2_2 = -c2 * chi2_2 - chi1_2 + 3.0 * a1_3 - F2_2 - K2 * e1_2 - tau * chi2_2
    a3_1 = (-c3 * chi3_1 - chi2_1 + 2.0 * a2_2 - K3 * e1_1 - F3_1
            - tau * chi3_1)                         # α̇3 (computable) = [α3]_1
    # --- eq (49): u0 with the fault eq (49) is told
    lock_sum, gain = _eq49_terms(pc, kf)
    u0 = (-chi3_0 - c4 * chi4_0 - K4 * e1_0 - F4_0 + a3_1 + yd[4] - tau * chi4_0
          - lock_sum) / gain
    _write_ctrl_rates(z, zdot, o, ws, pc, X01, X11, X21,
                      -K4 * x1 + K4 * y + F4_0 + (lock_sum + gain * u0), chi4_0)
    return u0


@njit(**INLINE)
def ctrl_paper(z, sf, ck, yd, pc, sb, sg, ws, zdot, o):
    """The paper's design on the plant state z's rotor speed (y = ω_r: the pitch sensors
    and the schedule are not its inputs): the commands v_j = sign b_j u0 of eq (14) and
    ẋ_ctrl (into zdot[o + N_P:])."""
    u0 = _ctrl_paper(z, z[0], yd, pc, ck, zdot, o, ws)
    s = pc[P_SIGN]
    return s * pc[P_B] * u0, s * pc[P_B + 1] * u0, s * pc[P_B + 2] * u0


@njit(**INLINE)
def rhs_paper(z, wind, af, sf, ck, yd, pt, pc, kx, ky, coef, sb, sg, ws, zdot, o):
    """ż = [plant, x̂, θ̂_1..4] of the closed loop with the paper's controller, into
    zdot[o:o + n]."""
    cp = _cp_at(z, wind, pt, kx, ky, coef)
    v1, v2, v3 = ctrl_paper(z, sf, ck, yd, pc, sb, sg, ws, zdot, o)
    _plant(z, v1, v2, v3, wind, cp, af, pt, zdot, o)


# --- the whole simulation in one call ------------------------------------------------------

@njit(**INLINE)
def _bind_and_keep(k, z, bind_step, bound, out, decimate, n):
    """At step k: a "current" lock binds its blade's angle; every ``decimate`` steps the
    state is kept, or False if it left |z| <= 1e8 (the run stops there)."""
    for j in range(3):
        if bind_step[j] == k:
            bound[j] = z[3 + j]
    if k % decimate == 0:
        for i in range(n):
            if not abs(z[i]) <= 1e8:
                return False
        out[k // decimate] = z
    return True


@njit(**INLINE)
def _inputs_at(k, af_all, sf_all, ck_all, bound, af, sf, ck):
    """Fault rows of step k; a NaN stuck command (lock "wherever the blade is") takes the
    blade angle bound at its onset step."""
    for i in range(af.shape[0]):
        af[i] = af_all[k, i]
    for i in range(sf.shape[0]):
        sf[i] = sf_all[k, i]
    for i in range(ck.shape[0]):
        ck[i] = ck_all[k, i]
    for j in range(3):
        if af[A_UBAR + j] != af[A_UBAR + j]:
            af[A_UBAR + j] = bound[j]
        if ck[K_UBAR + j] != ck[K_UBAR + j]:
            ck[K_UBAR + j] = bound[j]


def _rk4_loop(rhs):
    """The simulation loop with rhs inlined (a factory: one compiled loop per controller)."""

    @njit(**JIT)
    def simulate(z0, wind3, af_all, sf_all, ck_all, bind_step, yd, pt, pc, kx, ky, coef, sb,
                 sg, dt, n_steps, decimate):
        """Classical RK4 (Kutta 1901) over n_steps of dt, as wtftc.sim.integrate.rk4_step.

        wind3[k] = wind at t_k, t_k + dt/2, t_k + dt; af_all, sf_all, ck_all[k] = actuator,
        sensor and eq-(49) fault rows at t_k (held over the step); bind_step[j] = step at
        which blade j's "current" lock reads the blade angle (-1: none).
        Returns (states before every ``decimate``-th step, number of steps done): the run
        stops early, like wtftc's, at a non-finite state or |state| > 1e8 (checked at the
        output steps).
        """
        n = z0.shape[0]
        n_out = (n_steps + decimate - 1) // decimate
        out = np.empty((n_out, n))
        z = z0.copy()
        K = np.empty(4 * n)  # k1..k4 of RK4, one after the other
        zt = np.empty(n)
        ws = np.zeros(W_SIZE)
        af = np.empty(af_all.shape[1])
        sf = np.empty(sf_all.shape[1])
        ck = np.empty(ck_all.shape[1])
        bound = np.full(3, np.nan)
        h6 = dt / 6.0
        done = 0
        for k in range(n_steps):
            if not _bind_and_keep(k, z, bind_step, bound, out, decimate, n):
                break
            _inputs_at(k, af_all, sf_all, ck_all, bound, af, sf, ck)
            for i in range(n):
                zt[i] = z[i]
            # one call site (the rhs is inlined): k1 at (t, z), k2 and k3 at t + dt/2 from
            # z + dt/2 k1 and z + dt/2 k2, k4 at t + dt from z + dt k3
            for s in range(4):
                if s > 0:
                    h = dt if s == 3 else dt / 2.0
                    for i in range(n):
                        zt[i] = z[i] + h * K[(s - 1) * n + i]
                w = wind3[k, 0] if s == 0 else (wind3[k, 2] if s == 3 else wind3[k, 1])
                rhs(zt, w, af, sf, ck, yd, pt, pc, kx, ky, coef, sb, sg, ws, K, s * n)
            for i in range(n):
                z[i] = z[i] + h6 * (((K[i] + 2.0 * K[n + i]) + 2.0 * K[2 * n + i])
                                    + K[3 * n + i])
            done = k + 1
        return out[:(done + decimate - 1) // decimate], done

    return simulate


#: simulate_<controller>(z0, wind3, af, sf, ck, bind_step, yd, p_turbine, p_ctrl, knots λ,
#: knots β, coef, sched pitch, sched ∂T/∂β, dt, n_steps, decimate) -> (z, steps done)
simulate_physical = _rk4_loop(rhs_physical)
simulate_paper = _rk4_loop(rhs_paper)


# --- the sampled loop (wtftc.sim.sampled): the controller at interval starts -----------------

@njit(**INLINE)
def _plant_step(z, zt, K, v1, v2, v3, w0, wh, w1, af, pt, kx, ky, coef, dt):
    """One RK4 step of dt of the plant alone, the commands held (sampled._plant_step; the
    sensors' lag states it also carries are constant with exact sensors and left out):
    z[:N_P] advanced in place, the wind at t, t + dt/2 and t + dt."""
    for i in range(N_P):
        zt[i] = z[i]
    for s in range(4):  # one call site of the (inlined) rhs, as in _rk4_loop
        if s > 0:
            h = dt if s == 3 else dt / 2.0
            for i in range(N_P):
                zt[i] = z[i] + h * K[(s - 1) * N_P + i]
        w = w0 if s == 0 else (w1 if s == 3 else wh)
        rhs_plant(zt, v1, v2, v3, w, af, pt, kx, ky, coef, K, s * N_P)
    h6 = dt / 6.0
    for i in range(N_P):
        z[i] = z[i] + h6 * (((K[i] + 2.0 * K[N_P + i]) + 2.0 * K[2 * N_P + i])
                            + K[3 * N_P + i])


def _sample_fn(ctrl):
    """The sample at t_k with the controller ``ctrl`` (ctrl_physical or ctrl_paper) inlined."""

    @njit(**INLINE)
    def sample(z, zt, K, xc_next, sf, ck, yd, pc, sb, sg, ws, T):
        """sampled._sample: the commands at t_k from the controller's state and the plant's
        readings at t_k (returned, held over the interval), and the controller's state at
        t_k + T by one classical RK4 step of T of its own equations with those readings
        held (into xc_next[N_P:]). The plant part of zt stays at t_k throughout."""
        n = z.shape[0]
        for i in range(n):
            zt[i] = z[i]
        v1 = v2 = v3 = 0.0
        for s in range(4):
            if s > 0:
                h = T if s == 3 else T / 2.0
                for i in range(N_P, n):
                    zt[i] = z[i] + h * K[(s - 1) * n + i]
            c1, c2, c3 = ctrl(zt, sf, ck, yd, pc, sb, sg, ws, K, s * n)
            if s == 0:  # the command at the controller's state at t_k
                v1, v2, v3 = c1, c2, c3
        h6 = T / 6.0
        for i in range(N_P, n):
            xc_next[i] = z[i] + h6 * (((K[i] + 2.0 * K[n + i]) + 2.0 * K[2 * n + i])
                                      + K[3 * n + i])
        return v1, v2, v3

    return sample


def _sampled_loop(ctrl):
    """The sampled simulation loop with ``ctrl`` inlined (one compiled loop per controller)."""
    sample = _sample_fn(ctrl)

    @njit(**JIT)
    def simulate(z0, wind3, af_all, sf_all, ck_all, bind_step, yd, pt, pc, kx, ky, coef, sb,
                 sg, dt, n_steps, decimate, interval):
        """wtftc.sim.sampled's loop without the FDI, exact sensors, no delay: every
        ``interval`` steps a sample (sf_all, ck_all at its step; the command held, the
        controller's state advanced over T = interval·dt), then RK4 steps of dt of the plant
        (wind3 and af_all per step). The states kept are as run_loops records them: the
        controller's as sampled until the interval ends. bind_step: as in _rk4_loop, on
        interval starts. Returns (states before every ``decimate``-th step, steps done)."""
        n = z0.shape[0]
        out = np.empty(((n_steps + decimate - 1) // decimate, n))
        z = z0.copy()
        xc_next = z0.copy()  # the controller's state at the next sample: xc_next[N_P:]
        K = np.empty(4 * n)
        zt = np.empty(n)
        ws = np.zeros(W_SIZE)
        af = np.empty(af_all.shape[1])
        sf = np.empty(sf_all.shape[1])
        ck = np.empty(ck_all.shape[1])
        bound = np.full(3, np.nan)
        T = interval * dt
        v1 = v2 = v3 = 0.0
        done = 0
        for k in range(n_steps):
            if k % interval == 0:  # the interval just ended: its controller state
                for i in range(N_P, n):
                    z[i] = xc_next[i]
            if not _bind_and_keep(k, z, bind_step, bound, out, decimate, n):
                break
            _inputs_at(k, af_all, sf_all, ck_all, bound, af, sf, ck)
            if k % interval == 0:
                v1, v2, v3 = sample(z, zt, K, xc_next, sf, ck, yd, pc, sb, sg, ws, T)
            _plant_step(z, zt, K, v1, v2, v3, wind3[k, 0], wind3[k, 1], wind3[k, 2], af, pt,
                        kx, ky, coef, dt)
            done = k + 1
        return out[:(done + decimate - 1) // decimate], done

    return simulate


#: simulate_sampled_<controller>(the arguments of simulate_<controller>, interval)
simulate_sampled_physical = _sampled_loop(ctrl_physical)
simulate_sampled_paper = _sampled_loop(ctrl_paper)


# --- everything the numba code needs, extracted from wtftc ---------------------------------

RHS = {"physical": rhs_physical, "paper": rhs_paper}
SIMULATE = {"physical": simulate_physical, "paper": simulate_paper}
SIMULATE_SAMPLED = {"physical": simulate_sampled_physical, "paper": simulate_sampled_paper}


@dataclass
class StepInputs:
    """Exogenous inputs per RK4 step, as wtftc.sim.integrate.run_loops feeds its chunks."""

    wind3: np.ndarray       # (n_steps, 3): wind at t_k, t_k + dt/2, t_k + dt
    af: np.ndarray          # (n_steps, n actuator_faults) at t_k
    sf: np.ndarray          # (n_steps, n sensor_faults) at t_k
    ck: np.ndarray          # (n_steps, n fault_inputs): what eq (49) is told at t_k
    bind_step: np.ndarray   # (3,) int64: step of blade j's "current" lock, -1 for none


@dataclass
class Prepared:
    """Everything ``simulate_<controller>`` needs, extracted from wtftc (float64 arrays)."""

    controller: str
    config: object          # the config.RunConfig it came from
    z0: np.ndarray          # plant + controller states (the FDI's left out)
    yd: np.ndarray
    p_turbine: np.ndarray
    p_ctrl: np.ndarray
    cp_knots_tsr: np.ndarray
    cp_knots_pitch: np.ndarray
    cp_coef: np.ndarray     # coef[i_tsr + n_tsr * i_pitch]
    sched_pitch: np.ndarray
    sched_dTdbeta: np.ndarray
    dt: float               # the configuration's step, duration and output interval
    n_steps: int
    decimate: int
    _inputs: dict = field(default_factory=dict, repr=False)

    @property
    def rhs(self):
        return RHS[self.controller]

    @property
    def simulate(self):
        """The compiled loop of this controller: ``prep.simulate(*prep.args())``."""
        return SIMULATE[self.controller]

    def loop(self, interval: int = 0):
        """The compiled loop of this controller, continuous (``interval`` 0) or sampled every
        ``interval`` steps: ``prep.loop(n)(*prep.args(..., interval=n))``."""
        return SIMULATE_SAMPLED[self.controller] if interval else SIMULATE[self.controller]

    def inputs(self, dt: float | None = None, n_steps: int | None = None) -> StepInputs:
        """Per-step inputs for n_steps of dt (default: the configuration's), built once."""
        dt = self.dt if dt is None else float(dt)
        n_steps = self.n_steps if n_steps is None else int(n_steps)
        key = (dt, n_steps)
        if key not in self._inputs:
            self._inputs[key] = step_inputs(self.config, dt, n_steps)
        return self._inputs[key]

    def args(self, n_steps: int | None = None, dt: float | None = None,
             decimate: int | None = None, interval: int = 0) -> tuple:
        """Arguments of ``prep.loop(interval)``: the configuration's run, or n_steps of dt
        with states kept every ``decimate`` steps; sampled every ``interval`` steps (> 0),
        a "current" lock then binds at the start of the interval that holds its onset
        step, as in run_loops."""
        dt = self.dt if dt is None else float(dt)
        n = self.n_steps if n_steps is None else int(n_steps)
        u = self.inputs(dt, max(n, 1))
        bind = u.bind_step
        if interval:
            bind = np.where(bind >= 0, bind // interval * interval, bind)
        args = (self.z0, u.wind3, u.af, u.sf, u.ck, bind, self.yd, self.p_turbine,
                self.p_ctrl, self.cp_knots_tsr, self.cp_knots_pitch, self.cp_coef,
                self.sched_pitch, self.sched_dTdbeta, dt, n,
                self.decimate if decimate is None else int(decimate))
        return (*args, int(interval)) if interval else args

    def closed_loop_rhs(self, z, wind, af, sf, ck) -> np.ndarray:
        """ż at one state and one set of inputs (for tests)."""
        zdot = np.zeros(len(self.z0))
        c = np.ascontiguousarray
        self.rhs(c(z, dtype=float), float(wind), c(af, dtype=float), c(sf, dtype=float),
                 c(ck, dtype=float), self.yd, self.p_turbine, self.p_ctrl, self.cp_knots_tsr,
                 self.cp_knots_pitch, self.cp_coef, self.sched_pitch, self.sched_dTdbeta,
                 np.zeros(W_SIZE), zdot, 0)
        return zdot


def cp_spline_data(table) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(knots λ, knots β, coefficients) of wtftc.model.aero.cp_interpolant(table): the
    coefficients CasADi solved for when it built the interpolant, to the last bit."""
    from wtftc.model.aero import cp_interpolant

    return spline.spline_data(cp_interpolant(table), table.tsr, table.pitch_rad)


def sched_data(table, p_turbine: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Breakpoints (pitch [rad], ∂T/∂β [N m/rad]) of wtftc's pitch-sensitivity schedule,
    read from CasADi's code for it (computed once by wtftc)."""
    from wtftc.model.aero import pitch_sensitivity_schedule

    code, arr = spline.c_constants(pitch_sensitivity_schedule(table, p_turbine))
    m = re.search(r"casadi_interpn\(\s*[^,]+,\s*1\s*,\s*(casadi_c\d+)\s*,\s*casadi_s\d+\s*,"
                  r"\s*(casadi_c\d+)", code)
    if m is None:
        raise RuntimeError("no 1-D casadi_interpn call in CasADi's code for the schedule")
    grid, values = arr[m.group(1)], arr[m.group(2)]
    if grid.size != values.size or not np.all(np.diff(grid) > 0):
        raise RuntimeError("unexpected schedule breakpoints in CasADi's code")
    return grid.copy(), values.copy()


def wind_rows(wind, dt: float, n_steps: int) -> np.ndarray:
    """(n_steps, 3): the wind at t_k, t_k + dt/2 and t_k + dt of every step."""
    tk = np.arange(n_steps) * dt
    return np.column_stack([wind(tk), wind(tk + dt / 2), wind(tk + dt)])


def step_inputs(rc, dt: float, n_steps: int) -> StepInputs:
    """The wind at t_k, t_k + dt/2, t_k + dt and the fault rows at t_k of
    wtftc.sim.integrate.run_loops (the plant's schedule; eq (49)'s in case 3, nominal otherwise),
    with a lock "wherever the blade is" left NaN for the loop to bind at its onset step."""
    from wtftc.model.faults import Schedule, nominal_actuator

    tk = np.arange(n_steps) * dt
    wind3 = wind_rows(rc.wind, dt, n_steps)
    tp = rc.loop.p_turbine
    schedule = Schedule(copy.deepcopy(rc.faults), tp) if rc.faults else None
    ctrl_schedule = Schedule(copy.deepcopy(rc.faults), tp) if rc.told_fault else None
    nominal = lay.defaults("fault_inputs")
    af = (schedule.actuator(tk) if schedule
          else np.tile(nominal_actuator(tp)[:, None], (1, n_steps)))
    sf = (schedule.sensor(tk) if schedule
          else np.tile(lay.defaults("sensor_faults")[:, None], (1, n_steps)))
    ck = (ctrl_schedule.actuator(tk)[lay.prefix("fault_inputs", of="actuator_faults")]
          if ctrl_schedule
          else np.tile(nominal[:, None], (1, n_steps)))
    bind = np.full(3, -1, dtype=np.int64)
    for f in schedule.faults if schedule else []:
        if f.type == "lock" and f.angle is None:
            if bind[f.blade - 1] >= 0:
                raise ValueError("two 'current' locks on one blade: not supported here")
            bind[f.blade - 1] = int(round(f.onset_s / dt))
    c = np.ascontiguousarray
    return StepInputs(wind3=c(wind3, dtype=float), af=c(af.T, dtype=float),
                      sf=c(sf.T, dtype=float), ck=c(ck.T, dtype=float), bind_step=bind)


def prepare(controller: str, config) -> Prepared:
    """Everything ``simulate_<controller>`` needs for runs of a wtftc configuration (a
    ``config.RunConfig`` or a dict for ``config.make_config``), computed by wtftc itself."""
    from wtftc.config import RunConfig, make_config

    rc = config if isinstance(config, RunConfig) else make_config(
        {**config, "controller": controller})
    if rc.controller != controller:
        raise ValueError(f"config is for controller {rc.controller!r}, not {controller!r}")
    if controller not in RHS:
        raise ValueError(f"controller {controller!r}: written for {', '.join(RHS)}")
    if rc.plant != "nrel5mw":
        raise ValueError(f"plant {rc.plant!r}: written for nrel5mw")
    if rc.uses_fdi:
        raise ValueError("case 4 needs the FDI, which this baseline leaves out")
    table = rc.table
    n_c = N_C_PHYSICAL if controller == "physical" else N_C_PAPER
    z0 = rc.initial_state()[:N_P + n_c]
    yd = np.zeros(len(lay.names("reference")))
    yd[0] = rc.reference
    kx, ky, coef = cp_spline_data(table)
    sb, sg = sched_data(table, rc.p_turbine)
    c = np.ascontiguousarray
    prep = Prepared(controller=controller, config=rc, z0=c(z0, dtype=float), yd=yd,
                    p_turbine=c(rc.p_turbine, dtype=float), p_ctrl=c(rc.p_ctrl, dtype=float),
                    cp_knots_tsr=kx, cp_knots_pitch=ky, cp_coef=coef, sched_pitch=sb,
                    sched_dTdbeta=sg, dt=float(rc.dt), n_steps=int(round(rc.t_final / rc.dt)),
                    decimate=int(rc.decimate))
    prep.inputs()  # the configuration's run, built now rather than in a timed call
    return prep


def run(prep: Prepared, n_steps: int | None = None,
        interval: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(t, z): the configuration's run (with the controller sampled every ``interval``
    steps: > 0); output times [s] and the states (plant, then controller) at them. One
    numba call."""
    z, _ = prep.loop(interval)(*prep.args(n_steps, interval=interval))
    t = np.arange(z.shape[0]) * prep.decimate * prep.dt
    return t, z


def omega_trajectory(prep: Prepared, problem=None, dt: float | None = None,
                     t_final: float | None = None, every: int | None = None,
                     interval: int = 0, wind_inside: bool = False) -> np.ndarray:
    """ω_r [rad/s] every ``every`` steps of dt from t = 0 over [0, t_final) (defaults: the
    configuration's), in one numba call, the controller sampled every ``interval`` steps
    (> 0; 0: continuous); the per-step inputs of a new dt are built on the first call and
    reused, but with ``wind_inside`` the wind at each step's three times is evaluated in
    this call, as wtftc's run_loops does in the call the bench times (the fault rows,
    constant between onsets, stay built: run_loops writes one column per chunk for them).
    ``problem`` (the benchmark's) is not needed: the inputs come from prep's
    configuration, the one the problem was made from."""
    dt = prep.dt if dt is None else float(dt)
    n = prep.n_steps if t_final is None else int(round(t_final / dt))
    args = prep.args(n, dt, every, interval)
    if wind_inside:
        args = (args[0], wind_rows(prep.config.wind, dt, n), *args[2:])
    z, _ = prep.loop(interval)(*args)
    return z[:, 0].copy()
