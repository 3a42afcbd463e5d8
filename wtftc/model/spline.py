"""Lean evaluation of the Cp(λ, β) B-spline on a uniform table grid.

CasADi's ``bspline`` interpolant (:func:`wtftc.model.aero.cp_interpolant`) evaluates through
its generic N-dimensional de Boor routine: a search of the knot vector, loops over the
dimensions, about 300 ns a call in the generated C, four calls per RK4 step (measured in
``make bench``: most of the physical AFTC's step). On a uniform table grid the knot span
follows from one floor, and the tensor-product cubic spline is 16 coefficients weighted by
two sets of 4 basis values (Cox-de Boor in the triangular form of Piegl & Tiller's
BasisFuns). Written here in CasADi MX, whose parametric indexing (``get_nz`` with a
symbolic index) generates a plain array lookup in C, on the very knots and coefficients
CasADi solved for when it built the interpolant: the same spline, evaluated another way
(agreement to rounding, 1e-15; tests/test_spline.py).

A spline, not an equation of the paper: nothing here is derived, it is table lookup.
"""

from __future__ import annotations

import re

import casadi as ca
import numpy as np


def c_constants(fn: ca.Function) -> tuple[str, dict[str, np.ndarray]]:
    """CasADi's generated C of fn and its constant arrays (printed with 17 significant
    digits: exact round trip), by name."""
    cg = ca.CodeGenerator("wtftc_extract.c", {"with_header": False})
    cg.add(fn)
    code = cg.dump()
    arrays = {}
    for kind, name, body in re.findall(
            r"static const casadi_(real|int) (casadi_[cs]\d+)\[\d+\]\s*=\s*\{([^}]*)\};", code):
        vals = [t for t in body.replace("\n", " ").split(",") if t.strip()]
        arrays[name] = np.array([float(t) for t in vals] if kind == "real"
                                else [int(t) for t in vals])
    return code, arrays


def not_a_knot(x: np.ndarray) -> np.ndarray:
    """Cubic not-a-knot knot vector on the grid x (x_2 and x_{n-1} are not knots)."""
    x = np.asarray(x, dtype=float)
    return np.concatenate([[x[0]] * 4, x[2:-2], [x[-1]] * 4])


def spline_data(interpolant: ca.Function, x: np.ndarray, y: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(knots in x, knots in y, coefficients c[i_x + n_x i_y]) of a 2-D cubic not-a-knot
    'bspline' interpolant on the grid x × y, read from the constants of CasADi's own code
    for it: the coefficients CasADi solved for, to the last bit."""
    code, arr = c_constants(interpolant)
    m = re.search(r"nd_boor_eval\)?\(\s*[^,]+,\s*2\s*,\s*(casadi_c\d+)\s*,\s*(casadi_s\d+)\s*,"
                  r"\s*(casadi_s\d+)\s*,\s*(casadi_s\d+)\s*,\s*(casadi_c\d+)", code)
    if m is None:
        raise RuntimeError("no 2-D casadi_nd_boor_eval call in CasADi's code for the "
                           "interpolant: the extraction needs updating for this CasADi")
    knots, offset, degree, strides, coef = (arr[g] for g in m.groups())
    kx, ky = knots[offset[0]:offset[1]], knots[offset[1]:offset[2]]
    if (list(degree) != [3, 3] or list(strides) != [1, len(x)] or coef.size != len(x) * len(y)
            or not np.array_equal(kx, not_a_knot(x)) or not np.array_equal(ky, not_a_knot(y))):
        raise RuntimeError("CasADi's spline is not the cubic not-a-knot tensor spline on the "
                           "table grid")
    return kx.copy(), ky.copy(), coef.copy()


def is_uniform(x: np.ndarray, rtol: float = 1e-9) -> bool:
    d = np.diff(np.asarray(x, dtype=float))
    return len(x) >= 4 and bool(np.all(np.abs(d - d[0]) <= rtol * abs(d[0])))


def _cell_basis(knots: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """B[c, a, k]: on data cell c, x = grid[c] + h τ (τ in [0, 1]), the a-th of the 4 cubic
    B-splines nonzero there is Σ_k B[c, a, k] τ^k (Cox-de Boor recursion carried out on
    polynomials in τ)."""
    from numpy.polynomial import Polynomial as P

    n = len(grid)
    h = float(grid[1] - grid[0])
    out = np.zeros((n - 1, 4, 4))
    for c in range(n - 1):
        i = min(max(c - 1, 0), n - 4)  # first basis function: span [knots[i+3], knots[i+4]]
        x = P([float(grid[c]), h])  # x(τ)
        # degree 0: only the span's indicator, N_{i+3,0} = 1
        basis = {i + 3: P([1.0])}
        for p in (1, 2, 3):
            new = {}
            for k in range(i + 3 - p, i + 4):
                term = P([0.0])
                if k in basis and knots[k + p] > knots[k]:
                    term = term + (x - knots[k]) * basis[k] / (knots[k + p] - knots[k])
                if k + 1 in basis and knots[k + p + 1] > knots[k + 1]:
                    term = term + (knots[k + p + 1] - x) * basis[k + 1] / (
                        knots[k + p + 1] - knots[k + 1])
                new[k] = term
            basis = new
        for a in range(4):
            co = basis[i + a].coef
            out[c, a, :len(co)] = co
    return out


def cell_coefficients(kx, ky, coef, x, y) -> np.ndarray:
    """C[c_y, c_x, k, l]: on cell (c_x, c_y) the spline is Σ_kl C τ^k σ^l with τ, σ the
    local coordinates in [0, 1]."""
    bx, by = _cell_basis(kx, x), _cell_basis(ky, y)
    nx = len(x)
    c2 = coef.reshape(len(y), nx)  # c2[i_y, i_x]
    out = np.zeros((len(y) - 1, nx - 1, 4, 4))
    for cy in range(len(y) - 1):
        j = min(max(cy - 1, 0), len(y) - 4)
        for cx in range(nx - 1):
            i = min(max(cx - 1, 0), nx - 4)
            block = c2[j:j + 4, i:i + 4]  # [b, a]
            out[cy, cx] = bx[cx].T @ block.T @ by[cy]  # Σ_ab N_a(τ) N_b(σ) c[b, a]
    return out


def fast_cp(interpolant: ca.Function, x: np.ndarray, y: np.ndarray,
            name: str = "cp") -> ca.Function:
    """cp(tsr, beta) as :func:`wtftc.model.aero.cp_interpolant` (inputs clipped to the grid),
    evaluated as the bicubic polynomial of the cell holding (tsr, beta); x, y the uniform
    table grids. Never inlined: its lookups have no SX form, so an SX caller keeps a call."""
    kx, ky, coef = spline_data(interpolant, x, y)
    table = cell_coefficients(kx, ky, coef, x, y).ravel()
    nx, ny = len(x), len(y)
    hx, hy = float(x[1] - x[0]), float(y[1] - y[0])
    lam, beta = ca.MX.sym("tsr"), ca.MX.sym("beta")
    lam_c = ca.fmin(ca.fmax(lam, float(x[0])), float(x[-1]))
    beta_c = ca.fmin(ca.fmax(beta, float(y[0])), float(y[-1]))
    cx = ca.fmin(ca.floor((lam_c - float(x[0])) * (1 / hx)), nx - 2)
    cy = ca.fmin(ca.floor((beta_c - float(y[0])) * (1 / hy)), ny - 2)
    tau = (lam_c - (float(x[0]) + cx * hx)) * (1 / hx)
    sig = (beta_c - (float(y[0]) + cy * hy)) * (1 / hy)
    cm = ca.MX(ca.DM(table))
    base = (cy * (nx - 1) + cx) * 16
    out = 0
    for k in (3, 2, 1, 0):  # Horner in τ of Horner in σ
        row = 0
        for m in (3, 2, 1, 0):
            row = row * sig + cm.get_nz(False, base + (4 * k + m))
        out = out * tau + row
    return ca.Function(name, [lam, beta], [out], ["tsr", "beta"], [name],
                       {"never_inline": True})


def fast_linear(grid: np.ndarray, values: np.ndarray, name: str, in_name: str,
                out_name: str) -> ca.Function:
    """Linear interpolation on a uniform grid, held beyond its ends, with the arithmetic of
    CasADi's 'linear' interpolant ((1 - a) v_j + a v_j+1, a = (x - g_j)/(g_j+1 - g_j)),
    the interval found by one floor instead of a search."""
    grid, values = np.asarray(grid, dtype=float), np.asarray(values, dtype=float)
    n = len(grid)
    h = float(grid[1] - grid[0])
    x = ca.MX.sym(in_name)
    xc = ca.fmin(ca.fmax(x, float(grid[0])), float(grid[-1]))
    j = ca.fmin(ca.fmax(ca.floor((xc - float(grid[0])) * (1 / h)), 0), n - 2)
    g, v = ca.MX(ca.DM(grid)), ca.MX(ca.DM(values))
    g0, g1 = g.get_nz(False, j), g.get_nz(False, j + 1)
    a = (xc - g0) / (g1 - g0)
    out = (1 - a) * v.get_nz(False, j) + a * v.get_nz(False, j + 1)
    return ca.Function(name, [x], [out], [in_name], [out_name], {"never_inline": True})
