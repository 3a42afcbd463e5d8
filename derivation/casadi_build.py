"""SymPy → CasADi SX, and the fuzzy quantities L_i, B_i, φ_i built from :mod:`fuzzy`.

No equation is written here: expressions come from the derivation modules; this module
only translates them node by node (shared subexpressions stay shared) and evaluates the
factorized fuzzy sums described in :mod:`derivation.fuzzy`.
"""

from __future__ import annotations

import itertools
import sys

import casadi as ca
import sympy as sp
from sympy.logic.boolalg import ITE

from derivation import fuzzy
from derivation.layout import N_MF

sys.setrecursionlimit(max(10_000, sys.getrecursionlimit()))


#: conditions with more comparisons than this are translated as written (the minimisation
#: is exponential in them)
MAX_LOGIC_ATOMS = 8


def minimal_logic(cond: sp.Basic) -> sp.Basic:
    """``cond`` as the shortest of itself and its minimal sum and product of its comparisons.

    SymPy merges a Piecewise's branches of equal value into one condition in conjunctive
    form: the actuator's rate limit ``(β ≥ β_max ∧ r > 0) ∨ (β ≤ β_min ∧ r < 0)`` arrives
    as four clauses of seven logical operations, each a double-valued operation in the
    generated C on the loop's critical path. The minimisation is pure Boolean algebra
    (Quine-McCluskey, each comparison an independent atom, no knowledge of what it
    compares), so the result is the same truth function: equal for every input, NaN
    included, and the generated code computes the same numbers bit for bit (issue 19).
    """
    if not isinstance(cond, sp.logic.boolalg.BooleanFunction):
        return cond
    atoms = sorted(cond.atoms(sp.core.relational.Relational), key=sp.default_sort_key)
    if not atoms or len(atoms) > MAX_LOGIC_ATOMS:
        return cond
    names = sp.symbols(f"_logic_atom0:{len(atoms)}")
    b = cond.xreplace(dict(zip(atoms, names, strict=True)))
    if b.atoms(sp.core.relational.Relational):  # a comparison of booleans: leave it
        return cond
    forms = [b, sp.simplify_logic(b, form="dnf", force=True),
             sp.simplify_logic(b, form="cnf", force=True)]
    best = min(forms, key=lambda x: (sp.count_ops(x), forms.index(x)))
    out = best.xreplace(dict(zip(names, atoms, strict=True)))
    # SymPy's constructors may rewrite the comparisons on the way back (¬(x > 0) as
    # x ≤ 0, (x ≤ 0) ∨ (x > 0) as true), which is not the same for NaN: keep the result
    # only where it is the same function of the very same comparisons
    if out in (sp.true, sp.false) or not out.atoms(sp.core.relational.Relational) <= set(atoms):
        return cond
    for values in itertools.product((sp.false, sp.true), repeat=len(atoms)):
        truth = dict(zip(atoms, values, strict=True))
        if bool(cond.xreplace(truth)) != bool(out.xreplace(truth)):
            return cond
    return out


class Translator:
    """Translate SymPy expressions into CasADi SX, memoizing every node."""

    def __init__(self, symbols: dict[str, ca.SX]):
        self.symbols = symbols
        self.memo: dict[sp.Basic, ca.SX] = {}

    def __call__(self, expr) -> ca.SX:
        expr = sp.sympify(expr)
        hit = self.memo.get(expr)
        if hit is not None:
            return hit
        out = self._translate(expr)
        self.memo[expr] = out
        return out

    def _translate(self, e: sp.Basic) -> ca.SX:
        for part in (self._atom, self._arithmetic, self._function, self._logic):
            out = part(e)
            if out is not None:
                return out
        raise NotImplementedError(f"cannot translate {type(e).__name__}: {e}")

    def _atom(self, e: sp.Basic) -> ca.SX | None:
        if e.is_Symbol:
            try:
                return self.symbols[e.name]
            except KeyError:
                raise KeyError(f"no CasADi symbol for SymPy symbol {e.name!r}") from None
        if e.is_Integer or e.is_Float:
            return ca.SX(float(e))
        if e.is_Rational:
            return ca.SX(float(e.p)) / float(e.q)
        if e is sp.pi:
            return ca.SX(float(sp.pi))
        return None

    def _arithmetic(self, e: sp.Basic) -> ca.SX | None:
        if e.is_Add:
            terms = [self(a) for a in e.args]
            out = terms[0]
            for t in terms[1:]:
                out = out + t
            return out
        if e.is_Mul:
            coeff, rest = e.as_coeff_Mul()
            factors = [self(a) for a in sp.Mul.make_args(rest)]
            out = factors[0]
            for f in factors[1:]:
                out = out * f
            if coeff == -1:
                return -out
            if coeff != 1:
                return self(coeff) * out
            return out
        if e.is_Pow:
            return self._power(*e.args)
        return None

    def _power(self, base: sp.Basic, ex: sp.Basic) -> ca.SX:
        b = self(base)
        if ex.is_Integer:
            n = int(ex)
            if n == 1:
                return b
            if n == -1:
                return 1 / b
            if n == 2:
                return b**2
            if n == -2:
                return 1 / b**2
            return b ** n
        if ex == sp.Rational(1, 2):
            return ca.sqrt(b)
        return b ** self(ex)

    def _function(self, e: sp.Basic) -> ca.SX | None:
        if isinstance(e, sp.exp):
            return ca.exp(self(e.args[0]))
        if isinstance(e, sp.Abs):
            return ca.fabs(self(e.args[0]))
        if isinstance(e, sp.cos):
            return ca.cos(self(e.args[0]))
        if isinstance(e, sp.sin):
            return ca.sin(self(e.args[0]))
        if isinstance(e, sp.floor):
            return ca.floor(self(e.args[0]))
        if isinstance(e, sp.Min):
            return self._fold(ca.fmin, e.args)
        if isinstance(e, sp.Max):
            return self._fold(ca.fmax, e.args)
        if isinstance(e, sp.Piecewise):
            out = None
            for val, cond in reversed(e.args):
                if cond is sp.true:
                    out = self(val)
                else:
                    if out is None:
                        raise NotImplementedError(f"Piecewise without a default: {e}")
                    out = ca.if_else(self(minimal_logic(cond)), self(val), out)
            return out
        return None

    def _logic(self, e: sp.Basic) -> ca.SX | None:
        if isinstance(e, sp.And):
            return self._fold(ca.logic_and, e.args)
        if isinstance(e, sp.Or):
            return self._fold(ca.logic_or, e.args)
        if isinstance(e, sp.Not):
            return ca.logic_not(self(e.args[0]))
        if isinstance(e, ITE):  # a relation on a Piecewise, as SymPy folds it
            return ca.if_else(self(e.args[0]), self(e.args[1]), self(e.args[2]))
        rel = {sp.GreaterThan: ca.ge, sp.StrictGreaterThan: ca.gt,
               sp.LessThan: ca.le, sp.StrictLessThan: ca.lt}
        for cls, fn in rel.items():
            if isinstance(e, cls):
                return fn(self(e.lhs), self(e.rhs))
        return None

    def _fold(self, fn, args):
        out = self(args[0])
        for a in args[1:]:
            out = fn(out, self(a))
        return out


class FuzzyEvaluator:
    """Numerical (SX) values of ν_j^(n), L_i[α], B_i[α, β] and φ_i at one x̂."""

    def __init__(self, xhat: ca.SX, params: dict[str, ca.SX], thetas: list[ca.SX]):
        self.thetas = thetas
        n_in = xhat.numel()
        self.scales = [params[f"x_scale_{k}"] for k in range(1, n_in + 1)]
        self._tr = []
        centres = [params[f"mf_centre_{m}"] for m in range(1, N_MF + 1)]
        for k in range(n_in):
            zk = (xhat[k] - params[f"x_offset_{k + 1}"]) / self.scales[k]
            vals = fuzzy.membership_values(zk, centres, params["mf_width"], ca.exp, ca.fmax)
            self._tr.append(Translator(vals))
        self._nu: dict[tuple[int, int], ca.SX] = {}

    def nu(self, k: int, order: int) -> ca.SX:
        """∂^order/∂x̂_k^order of [ν_1..ν_N] at input k (0-based), scale included: the
        polynomials of :func:`fuzzy.membership_derivatives` (N_MF exponentials per input,
        shared by every order)."""
        key = (k, order)
        if key not in self._nu:
            exprs = fuzzy.membership_derivatives(order)
            vec = ca.vertcat(*[self._tr[k](e) for e in exprs])
            self._nu[key] = vec / self.scales[k] ** order if order else vec
        return self._nu[key]

    def L(self, i: int, alpha: tuple[int, ...]) -> ca.SX:
        """θ̂_iᵀ ∂^α φ_i: contract the weight tensor one input at a time (last input first)."""
        t = self.thetas[i - 1]
        for k in reversed(range(i)):
            t = ca.mtimes(ca.reshape(t, N_MF, t.numel() // N_MF).T, self.nu(k, alpha[k]))
        return t

    def B(self, i: int, alpha: tuple[int, ...], beta: tuple[int, ...]) -> ca.SX:
        """(∂^α φ_i)ᵀ(∂^β φ_i) = Π_k ν^(α_k)(z_k)ᵀ ν^(β_k)(z_k)."""
        out = ca.SX(1.0)
        for k in range(i):
            out = out * ca.dot(self.nu(k, alpha[k]), self.nu(k, beta[k]))
        return out

    def phi(self, i: int) -> ca.SX:
        """φ_i = ν(z_1) ⊗ ... ⊗ ν(z_i), rule order of :func:`fuzzy.rule_multi_indices`."""
        out = self.nu(0, 0)
        for k in range(1, i):
            out = ca.kron(out, self.nu(k, 0))
        return out

    def symbol_values(self, rule_bases: list[fuzzy.RuleBase]) -> dict[str, ca.SX]:
        """SX for every L/B/φ symbol the derivation created."""
        out = {}
        for rb in rule_bases:
            for sym, kind in rb.symbols().items():
                if kind[0] == "L":
                    out[sym.name] = self.L(rb.i, kind[1])
                else:
                    out[sym.name] = self.B(rb.i, kind[1], kind[2])
            for sym, m in rb.phi_symbols().items():
                out[sym.name] = self.phi(rb.i)[m]
        return out


def joint_cse(outs: list) -> list:
    """Common subexpressions eliminated across all outputs together (ca.cse on each output
    alone leaves the work they share duplicated: ctrl_paper 3959 operations that way, 1827
    jointly; the same arithmetic, bit for bit)."""
    sx = [i for i, o in enumerate(outs) if isinstance(o, ca.SX)]
    shared = ca.cse([ca.densify(outs[i]) for i in sx])
    outs = list(outs)
    for i, o in zip(sx, shared, strict=True):
        outs[i] = o
    return outs
