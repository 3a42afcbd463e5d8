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

import hashlib
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
    grid = (float(x[0]), float(x[-1]), hx, 1 / hx, nx, float(y[0]), float(y[-1]), hy, 1 / hy, ny)
    fname = f"{name}_{hashlib.sha256(np.array([*grid, *table]).tobytes()).hexdigest()[:12]}"
    LEAN_C[fname] = _lean_cell_c(table, *grid)
    return ca.Function(fname, [lam, beta], [out], ["tsr", "beta"], [name],
                       {"never_inline": True})


#: lean C bodies of the spline functions built here, by function name (unique: it carries
#: a hash of the grid and the table), for :func:`lean_c`
LEAN_C: dict[str, str] = {}

_LEAN_CELL = """  /* wtftc.model.spline: fast_cp's operations in the order of CasADi's code
   * for it (the same bits), the 16 coefficients read from one integer base (issue 19) */
  static const casadi_real table[{size}] = {{{table}}};
  casadi_real lam = arg[0] ? arg[0][0] : 0, beta = arg[1] ? arg[1][0] : 0;
  casadi_real lc, bc, cx, cy, tau, sig, b, r3, r2, r1, r0, out;
  const casadi_real* c;
  bc = casadi_fmin({y1}, casadi_fmax({y0}, beta));
  cy = casadi_fmin({cy_max}, floor({ihy} * {bc_off}));
  lc = casadi_fmin({x1}, casadi_fmax({x0}, lam));
  cx = casadi_fmin({cx_max}, floor({ihx} * {lc_off}));
  b = 16. * ({row} * cy + cx);
  sig = {ihy} * (bc - {y_cell});
  tau = {ihx} * (lc - {x_cell});
  if (!(b >= 0 && b <= {last})) {{ /* CasADi's lookup gives NaN off the table */
    if (res[0]) res[0][0] = casadi_nan;
    return 0;
  }}
  c = table + (casadi_int) b;
  r3 = ((c[15] * sig + c[14]) * sig + c[13]) * sig + c[12];
  r2 = ((c[11] * sig + c[10]) * sig + c[9]) * sig + c[8];
  r1 = ((c[7] * sig + c[6]) * sig + c[5]) * sig + c[4];
  r0 = ((c[3] * sig + c[2]) * sig + c[1]) * sig + c[0];
  out = ((r3 * tau + r2) * tau + r1) * tau + r0;
  if (res[0]) res[0][0] = out;
  return 0;"""


def _lean_cell_c(table: np.ndarray, x0: float, x1: float, hx: float, ihx: float, nx: int,
                 y0: float, y1: float, hy: float, ihy: float, ny: int) -> str:
    """The body of fast_cp's function in C (doubles printed to round trip exactly), with
    the simplifications CasADi makes where a grid starts at 0 (v - 0 is v, 0 + v is v)."""
    r = repr

    def offset(v: str, origin: float) -> str:  # v - origin
        return v if origin == 0 else f"({v} - {r(origin)})"

    def cell(origin: float, h: float, c: str) -> str:  # origin + h c
        return f"({r(h)} * {c})" if origin == 0 else f"({r(origin)} + {r(h)} * {c})"

    return _LEAN_CELL.format(size=table.size, table=", ".join(map(r, map(float, table))),
                             x0=r(x0), x1=r(x1), ihx=r(ihx), cx_max=r(float(nx - 2)),
                             y0=r(y0), y1=r(y1), ihy=r(ihy), cy_max=r(float(ny - 2)),
                             bc_off=offset("bc", y0), lc_off=offset("lc", x0),
                             y_cell=cell(y0, hy, "cy"), x_cell=cell(x0, hx, "cx"),
                             row=r(float(nx - 1)), last=r(float(table.size - 16)))


#: the lean bodies are inlined into their callers (4 calls an RK4 step, through pointer
#: arrays the caller fills: inlined, the values stay in registers)
INLINED = "static inline __attribute__((always_inline)) "


def lean_c(code: str) -> str:
    """CasADi's C ``code`` with the body of each function of LEAN_C it holds replaced by
    the lean one (its comment line names it: ``/* name:(...)->(...) */``)."""
    for fname, body in LEAN_C.items():
        head = re.compile(r"/\* " + re.escape(fname) + r":\([^\n]*\*/\n"
                          r"static int casadi_f\d+\(const casadi_real\*\* arg, casadi_real\*\* "
                          r"res, casadi_int\* iw, casadi_real\* w, int mem\) \{\n")
        m = head.search(code)
        if m is None:
            continue
        end = code.index("\n}\n", m.end())
        start = code.index("static int casadi_f", m.start())
        code = code[:start] + INLINED + code[start + len("static "):m.end()] + body + \
            code[end:]
    return code


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
    fname = f"{name}_{hashlib.sha256(np.concatenate([grid, values]).tobytes()).hexdigest()[:12]}"
    LEAN_C[fname] = _lean_linear_c(grid, values, h)
    return ca.Function(fname, [x], [out], [in_name], [out_name], {"never_inline": True})


_LEAN_LINEAR = """  /* wtftc.model.spline: fast_linear's operations in the order of CasADi's code
   * for it (the same bits), the interval's entries read from one integer index (issue 19) */
  static const casadi_real grid[{n}] = {{{grid}}};
  static const casadi_real values[{n}] = {{{values}}};
  casadi_real x = arg[0] ? arg[0][0] : 0, xc, j, a, out;
  casadi_int i;
  xc = casadi_fmin({g1}, casadi_fmax({g0}, x));
  j = casadi_fmin({j_max}, casadi_fmax(0., floor({ih} * {xc_off})));
  if (!(j >= 0 && j <= {j_max})) {{ /* CasADi's lookup gives NaN off the table */
    if (res[0]) res[0][0] = casadi_nan;
    return 0;
  }}
  i = (casadi_int) j;
  a = (xc - grid[i]) / (grid[i + 1] - grid[i]);
  out = (1. - a) * values[i] + a * values[i + 1];
  if (res[0]) res[0][0] = out;
  return 0;"""


def _lean_linear_c(grid: np.ndarray, values: np.ndarray, h: float) -> str:
    """The body of fast_linear's function in C (as :func:`_lean_cell_c`)."""
    r = repr
    g0 = float(grid[0])
    return _LEAN_LINEAR.format(n=grid.size, grid=", ".join(map(r, map(float, grid))),
                               values=", ".join(map(r, map(float, values))), g0=r(g0),
                               g1=r(float(grid[-1])), ih=r(1 / h),
                               j_max=r(float(grid.size - 2)),
                               xc_off="xc" if g0 == 0 else f"(xc - {r(g0)})")
