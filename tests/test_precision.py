"""Accuracy far outside the membership grid, against a 40-digit evaluation.

Normalized Gaussian memberships saturate away from their centres; written as μ_j/Σμ_l
their derivatives cancel catastrophically and, once every μ_l underflows (|z| ≳ 24 for
width 0.6), form 0/0. The generator uses a max-shifted softmax of linear functions with
its derivatives as polynomials (:func:`derivation.fuzzy.membership_derivatives`); this
test holds it to 1e-12 relative
against mpmath at 40 digits (textbook form, unfactored, evaluated by SymPy) where the
textbook form in double precision loses about 1e-10 (|z| ≤ 6) or returns NaN (|z| = 40).
"""

import mpmath
import numpy as np
import pytest
import reference as R
import sympy as sp

from derivation import backstepping as bs
from wtftc.artefacts.loader import load
from wtftc.verify.checks import random_inputs, relative_error


def _alpha_dot_exact(vals):
    d = bs.derive()
    exact = {k: mpmath.mpf(v) for k, v in vals.items()}

    def dphi(i, alpha):
        f, names = R.dphi_function(i, tuple(alpha), "mpmath")
        return f(*[exact[n] for n in names])

    for rb in d.rule_bases:
        for sym, kind in rb.symbols().items():
            if kind[0] == "L":
                th = [exact[f"theta_hat_{rb.i}[{m}]"] for m in range(R.dlay.rule_count(rb.i))]
                dp = dphi(rb.i, kind[1])
                exact[sym.name] = mpmath.fsum(t * p for t, p in zip(th, dp, strict=True))
            else:
                exact[sym.name] = mpmath.fsum(
                    p * q for p, q in zip(dphi(rb.i, kind[1]), dphi(rb.i, kind[2]), strict=True))
    syms = sorted(set().union(*[e.free_symbols for e in d.alpha_dot_full]),
                  key=lambda s: s.name)
    f = sp.lambdify(syms, d.alpha_dot_full, modules="mpmath")
    return np.array([float(x) for x in f(*[exact[s.name] for s in syms])])


@pytest.mark.parametrize("z_span", [6.0, 40.0, 1000.0])
def test_alpha_dot_far_from_centres_matches_40_digits(z_span):
    rng = np.random.default_rng(7)
    with mpmath.workdps(40):
        for _ in range(3):
            args = random_inputs("alpha_derivatives", rng, z_span=z_span)
            got = np.array(load("alpha_derivatives")(**args)["alpha_dot_full"]).reshape(-1)
            assert np.all(np.isfinite(got))
            exact = _alpha_dot_exact(R.named_values(args))
            assert relative_error(got, exact) < 1e-12


@pytest.mark.parametrize("zz", ["0.3", "-2.7", "11.5", "40", "-25"])
def test_membership_derivative_polynomials_equal_the_softmax_derivatives(zz):
    """The generator evaluates d^n ν_j/dz^n as polynomials in ν, the centred slopes and
    their moments (fuzzy.membership_derivatives, one exp per membership); SymPy's own
    derivatives of the softmax form, both at 40 digits, must agree to 1e-30 relative."""
    from derivation import fuzzy

    centres, width = ["-1", "0", "1.3"], "0.6"
    with mpmath.workdps(40):
        vals = fuzzy.membership_values(mpmath.mpf(zz), [mpmath.mpf(c) for c in centres],
                                       mpmath.mpf(width), mpmath.exp, max)
        at = {sp.Symbol(k, real=True): sp.Float(str(v), 40) for k, v in vals.items()}
        point = {fuzzy.z: sp.Float(zz, 40), fuzzy.mf_width: sp.Float(width, 40),
                 **{c: sp.Float(v, 40) for c, v in zip(fuzzy.mf_centre, centres, strict=True)}}
        for order in range(5):
            ref = [e.evalf(40, subs=point) for e in fuzzy.normalized_membership_derivatives(order)]
            got = [e.evalf(40, subs=at) for e in fuzzy.membership_derivatives(order)]
            for g, r in zip(got, ref, strict=True):
                assert abs(g - r) <= 1e-30 * abs(r), (order, g, r)
