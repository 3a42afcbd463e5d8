"""Shared reciprocals: divisions by what a step holds constant, as multiplications.

A loop's right-hand side divides by quantities that do not change within a step: inertias,
time constants, the accommodation's gain Σ(1 - σ̂_j)ρ̂_j, sensor lags. Each such division
sits on the step's critical path (a double division is 13-15 cycles where a
multiplication is 3-4), four times a step in RK4. :func:`with_shared_reciprocals` computes
1/d once and multiplies: the physical AFTC's RK4 step goes from 109 to 69 divisions and
its loop is 11 % faster (issue 19, docs/performance.md).

CasADi folds ``x * (1/d)`` back into ``x / d`` when it builds the graph, so the reciprocal
is the output of a small function called from the graph, ``wtftc_reciprocal``, which
CasADi keeps as a call and does not look into: ``x * call(d)`` stays a multiplication. The
virtual machine and the compiled code evaluate the same graph, so they still agree bit
for bit; against the division, ``x * (1/d)`` differs by at most an ulp or so of the
product (about one case in three). What that does to trajectories (measured on the bench's
loops, 60 s): the physical AFTC's ω_r moves by at most 7e-16 relative (the ulps are
mostly lost when dt·k is added to the state); the paper's design, whose high-gain
adaptive loop amplifies any difference (a 1-ulp change of ω_r(0) grows to 1e-4 over 60 s,
docs/performance.md), by 5e-4, the same as any rounding change there.

A quantity gets a shared reciprocal only when it is used as a divisor and nowhere else in
the step (those used otherwise too keep their divisions: the multiplications they would
save do not pay for a second value).
"""

from __future__ import annotations

from collections import defaultdict
from functools import cache

import casadi as ca


@cache
def reciprocal() -> ca.Function:
    """1/d as a function the graph calls and CasADi does not fold into a division."""
    d = ca.SX.sym("d")
    return ca.Function("wtftc_reciprocal", [d], [1 / d], ["d"], ["one_over_d"],
                       {"never_inline": True})


def _divisor_only(g: ca.Function) -> list[int]:
    """Elements of g's second input used as divisors and in no other way."""
    uses: dict[int, set[str]] = defaultdict(set)
    held: dict[int, int | None] = {}  # work slot -> element of the second input it holds
    for k in range(g.n_instructions()):
        op, out, ins = g.instruction_id(k), g.instruction_output(k), g.instruction_input(k)
        if op == ca.OP_INPUT:
            held[out[0]] = ins[1] if ins[0] == 1 else None
            continue
        args = [ins[0]] if op == ca.OP_OUTPUT else [a for a in ins if a >= 0]
        if op == ca.OP_CONST:
            args = []
        for j, a in enumerate(args):
            if held.get(a) is not None:
                uses[held[a]].add("div" if op == ca.OP_DIV and j == 1 else "other")
        if op != ca.OP_OUTPUT:
            for o in out:
                held[o] = None
    return sorted(i for i, u in uses.items() if u == {"div"})


def with_shared_reciprocals(f: ca.Function, varying: tuple[str, ...]) -> ca.Function:
    """f (an SX function) with every division by a quantity of its inputs other than
    ``varying`` (the state, the wind) computed as a multiplication by its reciprocal (the
    same inputs and outputs)."""
    ins, names = f.sx_in(), f.name_in()
    if not all(x.is_dense() and x.is_column() for x in ins):
        return f  # the rewrite below indexes elements as nonzeros: dense columns only
    held = [i for i, n in enumerate(names) if n not in varying]
    par = ca.vertcat(*[ins[i] for i in held])
    ret, syms, parts = ca.extract_parametric(f.call(ins), par)
    cand = ca.vertcat(par, *syms)  # the held inputs' elements, then the parametric parts
    n_par = par.numel()
    rest = ca.vertcat(*[ins[i] for i in range(len(ins)) if i not in held])
    recip = set(_divisor_only(ca.Function("uses", [rest, cand], ret)))
    old, new = [], []
    for i in range(cand.numel()):
        value = cand[i] if i < n_par else parts[i - n_par]
        if i in recip:  # d -> 1/(1/d): CasADi turns x/(1/r) into x*r
            old.append(cand[i])
            new.append(1 / reciprocal()(value))
        elif i >= n_par:  # the other parametric parts back in place
            old.append(cand[i])
            new.append(value)
    out = ca.cse(ca.substitute(list(ret), [ca.vertcat(*old)], [ca.vertcat(*new)]))
    return ca.Function(f.name(), ins, out, names, f.name_out())
