"""Fuzzy logic systems f̂_i = θ̂_iᵀ φ_i(x̂1..x̂i) of eq (21), in SymPy.

Membership functions (Table 1's φ = 0.6 read as the width, paper-notes defect 6):

    μ_j(z) = exp(-(z - c_j)² / (2 w²)),    z_k = (x̂_k - offset_k) / scale_k

Rules form the full grid over the inputs x̂1..x̂i (triangular regressors, paper-notes
defect 7), with product inference and normalized firing strengths

    φ_m(z) = Π_k μ_{m_k}(z_k) / Σ_{m'} Π_k μ_{m'_k}(z_k).

On a full grid the denominator factors, Σ_{m'} Π_k μ = Π_k Σ_j μ_j(z_k), so

    φ_m(z) = Π_k ν_{m_k}(z_k),   ν_j(z) = μ_j(z) / Σ_l μ_l(z),

which is how the generator evaluates them; tests compare against the unfactored form.

To keep the backstepping expressions small (issue 2), the controller never expands
θ̂_iᵀφ_i. It uses two families of scalar symbols with known derivatives:

    L_i[α]    = θ̂_iᵀ ∂^α φ_i                    (α a multi-index over x̂1..x̂i)
    B_i[α, β] = (∂^α φ_i)ᵀ (∂^β φ_i)            (symmetric in α, β)

Along the closed loop, with θ̂̇_i = γ_i χ_i φ_i - r_i θ̂_i (eqs (32), (37), (43), (49)),

    d/dt L_i[α]    = Σ_k L_i[α + e_k] x̂̇_k + γ_i χ_i B_i[0, α] - r_i L_i[α]
    d/dt B_i[α, β] = Σ_k (B_i[α + e_k, β] + B_i[α, β + e_k]) x̂̇_k

and both factor over the inputs, so the generator builds them from the derivatives of
the one-dimensional ν_j derived here.
"""

from __future__ import annotations

import itertools
from functools import cache

import sympy as sp

from derivation.layout import N_MF

z = sp.Symbol("z", real=True)
mf_width = sp.Symbol("mf_width", positive=True)
mf_centre = sp.symbols(f"mf_centre_1:{N_MF + 1}", real=True)


def membership(j: int, zz=z) -> sp.Expr:
    """Gaussian membership μ_j on a normalized input (0-based j)."""
    return sp.exp(-((zz - mf_centre[j]) ** 2) / (2 * mf_width**2))


def normalized_membership(j: int) -> sp.Expr:
    """ν_j = μ_j / Σ_l μ_l written as 1 / Σ_l exp(log μ_l - log μ_j): the reference the
    generator's form (:func:`membership_values`, :func:`membership_derivatives`) is tested
    against.

    log μ_l - log μ_j = (c_l - c_j)(2z - c_j - c_l) / (2w²) is linear in z, so ν_j is a
    softmax of linear functions: identical to μ_j/Σμ_l (tests compare the two), but it
    cannot form 0/0 when every μ_l underflows (|z| ≳ 24 with w = 0.6), and its
    derivatives lose far less to cancellation away from the centres.
    """
    cj = mf_centre[j]
    return 1 / sp.Add(*[
        sp.exp((cl - cj) * (2 * z - cj - cl) / (2 * mf_width**2)) if l != j else sp.S.One
        for l, cl in enumerate(mf_centre)])


#: symbols of the evaluated form (see :func:`membership_derivatives`): ν_j, the centred
#: slopes ã_j and the moments M_r = Σ_l ν_l ã_l^r (M_0 = 1, M_1 = 0)
nu = sp.symbols(f"nu_1:{N_MF + 1}", real=True)
slope = sp.symbols(f"slope_1:{N_MF + 1}", real=True)


def moment(r: int) -> sp.Expr:
    """M_r = Σ_l ν_l ã_l^r: M_0 = Σ ν = 1 and M_1 = Σ ν ã = 0 exactly; a symbol above."""
    if r < 2:
        return (sp.S.One, sp.S.Zero)[r]
    return sp.Symbol(f"moment_{r}", real=True)


def _d_dz(e: sp.Expr, max_moment: int) -> sp.Expr:
    """d/dz of a polynomial in ν, ã, M_r by the rules of :func:`membership_derivatives`."""
    out = sp.S.Zero
    for j in range(N_MF):
        out += sp.diff(e, nu[j]) * nu[j] * slope[j] - sp.diff(e, slope[j]) * moment(2)
    for r in range(2, max_moment + 1):
        out += sp.diff(e, moment(r)) * (moment(r + 1) - r * moment(r - 1) * moment(2))
    return sp.expand(out)


@cache
def membership_derivatives(order: int) -> tuple[sp.Expr, ...]:
    """d^order ν_j / dz^order (j = 0..N_MF-1) as polynomials in ν, ã and M_2..M_order.

    With a_l = c_l / w² (log μ_l = a_l z + terms the normalization cancels), ā = Σ ν_l a_l
    and the centred slopes ã_j = a_j - ā, differentiating ν_j Σ_l μ_l = μ_j gives

        dν_j/dz = ν_j ã_j,
        dã_j/dz = -dā/dz = -Σ_l ν_l ã_l a_l = -M_2 - ā M_1 = -M_2,
        dM_r/dz = Σ_l (ν_l ã_l^{r+1} - r ν_l ã_l^{r-1} M_2) = M_{r+1} - r M_{r-1} M_2,

    so every derivative is a short polynomial of values computed once per input: no
    exponential beyond the N_MF of ν itself (the softmax form costs N_MF(N_MF-1), and its
    derivatives more). tests/test_precision.py checks these against
    ``sp.diff(normalized_membership(j), z, order)``.
    """
    if order == 0:
        return tuple(nu)
    return tuple(_d_dz(e, order) for e in membership_derivatives(order - 1))


def membership_values(zz, centres, width, exp, fmax) -> dict[str, object]:
    """Values of the symbols of :func:`membership_derivatives` at z = zz, for any
    arithmetic (``exp``/``fmax``: CasADi's, or mpmath's and ``max`` for tests):

        s_l = a_l (z - c_l/2)          (log μ_l up to a term common to all l)
        ν_l = e^{s_l - s_max} / Σ_m e^{s_m - s_max}     (no overflow, no 0/0 at any z)
        ã_l = Σ_{m≠l} ν_m (c_l - c_m) / w²             (= a_l - ā without its cancellation)
        M_r = Σ_l ν_l ã_l^r
    """
    inv_w2 = 1 / (width * width)
    s = [c * inv_w2 * (zz - c / 2) for c in centres]
    s_max = s[0]
    for v in s[1:]:
        s_max = fmax(s_max, v)
    e = [exp(v - s_max) for v in s]
    inv_total = 1 / sum(e[1:], e[0])
    nus = [v * inv_total for v in e]
    slopes = [sum(terms[1:], terms[0]) * inv_w2 for terms in
              ([nus[m] * (cj - cm) for m, cm in enumerate(centres) if m != j]
               for j, cj in enumerate(centres))]
    out = {f"nu_{j + 1}": v for j, v in enumerate(nus)}
    out.update({f"slope_{j + 1}": v for j, v in enumerate(slopes)})
    powers = list(slopes)
    for r in range(2, 6):  # M_2..M_5: membership_derivatives(n) needs M_2..M_n, n <= 5
        powers = [p * a for p, a in zip(powers, slopes, strict=True)]
        terms = [n_ * p for n_, p in zip(nus, powers, strict=True)]
        out[f"moment_{r}"] = sum(terms[1:], terms[0])
    return out


@cache
def normalized_membership_derivatives(order: int) -> tuple[sp.Expr, ...]:
    """d^order ν_j / dz^order of the softmax form (j = 0..N_MF-1): the reference for tests."""
    return tuple(sp.diff(normalized_membership(j), z, order) for j in range(N_MF))


def rule_multi_indices(n_inputs: int) -> list[tuple[int, ...]]:
    """Rule m ↔ (m_1, ..., m_i), first input slowest (the order of np.kron)."""
    return list(itertools.product(range(N_MF), repeat=n_inputs))


class RuleBase:
    """Symbols L_i[α], B_i[α, β] of the fuzzy system of chain step i (1-based)."""

    def __init__(self, i: int):
        self.i = i
        self._L: dict[tuple[int, ...], sp.Symbol] = {}
        self._B: dict[tuple[tuple[int, ...], tuple[int, ...]], sp.Symbol] = {}
        self._phi: dict[int, sp.Symbol] = {}

    def zero(self) -> tuple[int, ...]:
        return (0,) * self.i

    def L(self, alpha: tuple[int, ...] | None = None) -> sp.Symbol:
        alpha = self.zero() if alpha is None else tuple(alpha)
        if alpha not in self._L:
            self._L[alpha] = sp.Symbol(f"L{self.i}_" + "".join(map(str, alpha)), real=True)
        return self._L[alpha]

    def B(self, alpha: tuple[int, ...], beta: tuple[int, ...]) -> sp.Symbol:
        key = tuple(sorted((tuple(alpha), tuple(beta))))
        if key not in self._B:
            a, b = key
            self._B[key] = sp.Symbol(
                f"B{self.i}_" + "".join(map(str, a)) + "_" + "".join(map(str, b)), real=True)
        return self._B[key]

    def phi(self, m: int) -> sp.Symbol:
        """φ_i[m], the m-th regressor entry (0-based rule m), for adaptive laws."""
        if m not in self._phi:
            self._phi[m] = sp.Symbol(f"phi{self.i}_{m}", real=True)
        return self._phi[m]

    def symbols(self) -> dict[sp.Symbol, tuple]:
        """Every L/B symbol created so far → ("L", α) or ("B", α, β)."""
        out: dict[sp.Symbol, tuple] = {s: ("L", a) for a, s in self._L.items()}
        out.update({s: ("B", a, b) for (a, b), s in self._B.items()})
        return out

    def phi_symbols(self) -> dict[sp.Symbol, int]:
        return {s: m for m, s in self._phi.items()}

    def rate(self, sym: sp.Symbol, xhat_dot, chi, gamma, r, target=0) -> sp.Expr:
        """Time derivative of one L or B symbol along the closed loop (module docstring),
        for the adaptive law θ̂̇ = γ χ φ - r (θ̂ - target 1): a leakage toward a common
        weight ``target`` adds r·target·∂^α(Σ_m φ_m) to the rate of L_α, which is r·target
        for α = 0 and 0 for every other α (the normalized memberships sum to 1)."""
        kind = self.symbols()[sym]

        def shift(a, k):
            return tuple(n + (1 if q == k else 0) for q, n in enumerate(a))

        if kind[0] == "L":
            a = kind[1]
            toward = r * target if a == self.zero() and target != 0 else 0
            return (sum(self.L(shift(a, k)) * xhat_dot[k] for k in range(self.i))
                    + gamma * chi * self.B(self.zero(), a) - r * self.L(a) + toward)
        _, a, b = kind
        return sum((self.B(shift(a, k), b) + self.B(a, shift(b, k))) * xhat_dot[k]
                   for k in range(self.i))


def total_derivative(expr: sp.Expr, rates: dict, rule_base: RuleBase, xhat_dot, chi,
                     gamma, r, target=0) -> sp.Expr:
    """d/dt expr along the loop: Σ ∂expr/∂s · ṡ over its free symbols s, with ṡ from
    ``rates`` (symbol → rate) or, for the L/B symbols of ``rule_base``, from
    :meth:`RuleBase.rate` with the adaptive law θ̂̇ = γ χ φ - r (θ̂ - target 1). Symbols
    with neither are constants. Summed in symbol-name order, so the result is
    reproducible."""
    out = sp.S.Zero
    for s in sorted(expr.free_symbols, key=lambda q: q.name):
        if s in rates:
            rate = rates[s]
        elif s in rule_base.symbols():
            rate = rule_base.rate(s, xhat_dot, chi, gamma, r, target)
        else:
            continue
        out += sp.diff(expr, s) * rate
    return out


def reference_regressor(xhat, offsets, scales) -> list[sp.Expr]:
    """φ_i(x̂1..x̂i) in the unfactored textbook form, for tests (not for generation)."""
    zs = [(x - o) / s for x, o, s in zip(xhat, offsets, scales, strict=True)]
    firing = [sp.Mul(*[membership(j, zk) for j, zk in zip(m, zs, strict=True)])
              for m in rule_multi_indices(len(xhat))]
    total = sp.Add(*firing)
    return [w / total for w in firing]


def reference_regressor_derivative(xhat, offsets, scales, alpha) -> list[sp.Expr]:
    """∂^α φ_i of the unfactored regressor (α a multi-index over xhat), by SymPy: the
    slow, obvious way, for tests and for the benchmark's lambdify baseline."""
    out = []
    for p in reference_regressor(xhat, offsets, scales):
        for k, n in enumerate(alpha):
            if n:
                p = sp.diff(p, xhat[k], n)
        out.append(p)
    return out
