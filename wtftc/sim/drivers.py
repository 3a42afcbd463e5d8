"""C drivers of the loop chunks (issue 19): the loop over a chunk's steps written in C
around CasADi's generated step functions, in place of ``mapaccum``.

``mapaccum`` copies the state, the outputs and every input (the parameters included, one
column a step) at each step, and in the sampled loop repeats the held sample across the
interval's steps through MX copies; the drivers read the held inputs in place, write each
step's state straight into its column of the trajectory, and call the same generated
functions in the same order, so the numbers are the same, bit for bit
(tests/test_loop_codegen.py). Each driver is a CasADi external function (its interface:
:func:`_interface`), compiled into one library with the functions it calls.
"""

from __future__ import annotations

import casadi as ca

from wtftc.sim import sampled, specialise
from wtftc.sim.rhs import Loop

_INTERFACE = """
/* {name}: the chunk (wtftc.sim.drivers) */
static const char* {name}_names_in[{n_in}] = {{{names_in}}};
static const char* {name}_names_out[{n_out}] = {{{names_out}}};
/* dense patterns in CasADi's short form: rows, columns, 1 */
static const casadi_int {name}_sp[{n_in} + {n_out}][3] = {{{sp}}};

CASADI_SYMBOL_EXPORT casadi_int {name}_n_in(void) {{ return {n_in}; }}
CASADI_SYMBOL_EXPORT casadi_int {name}_n_out(void) {{ return {n_out}; }}
CASADI_SYMBOL_EXPORT const char* {name}_name_in(casadi_int i) {{
  return i >= 0 && i < {n_in} ? {name}_names_in[i] : 0;
}}
CASADI_SYMBOL_EXPORT const char* {name}_name_out(casadi_int i) {{
  return i >= 0 && i < {n_out} ? {name}_names_out[i] : 0;
}}
CASADI_SYMBOL_EXPORT const casadi_int* {name}_sparsity_in(casadi_int i) {{
  return i >= 0 && i < {n_in} ? {name}_sp[i] : 0;
}}
CASADI_SYMBOL_EXPORT const casadi_int* {name}_sparsity_out(casadi_int i) {{
  return i >= 0 && i < {n_out} ? {name}_sp[{n_in} + i] : 0;
}}
CASADI_SYMBOL_EXPORT int {name}_work(casadi_int *sz_arg, casadi_int* sz_res,
                                     casadi_int *sz_iw, casadi_int *sz_w) {{
  casadi_int a = 0, r = 0, i = 0, w = 0, a1, r1, i1, w1;
{work_calls}
  *sz_arg = {n_in} + a; *sz_res = {n_out} + r; *sz_iw = i; *sz_w = w + {scratch};
  return 0;
}}
"""

_WORK_CALL = """  {fn}_work(&a1, &r1, &i1, &w1);
  if (a1 > a) a = a1;
  if (r1 > r) r = r1;
  if (i1 > i) i = i1;
  if (w1 > w) w = w1;"""


def _interface(name: str, inputs: list[tuple[str, int, int]],
               outputs: list[tuple[str, int, int]], functions: list[str],
               scratch: str) -> str:
    """CasADi's external-function interface of the C function ``name``: inputs and
    outputs as (name, rows, columns), dense; its work the largest of ``functions``' plus
    ``scratch`` doubles (a C expression)."""
    return _INTERFACE.format(
        name=name, n_in=len(inputs), n_out=len(outputs),
        names_in=", ".join(f'"{n}"' for n, _, _ in inputs),
        names_out=", ".join(f'"{n}"' for n, _, _ in outputs),
        sp=", ".join(f"{{{r}, {c}, 1}}" for _, r, c in [*inputs, *outputs]),
        work_calls="\n".join(_WORK_CALL.format(fn=f) for f in functions), scratch=scratch)


def _max_work(functions: list[str]) -> str:
    """C statements: ww, the largest work of ``functions`` (the driver's scratch follows)."""
    return "\n".join(["  casadi_int ww = 0, a1, r1, i1, w1;"] + [
        f"  {f}_work(&a1, &r1, &i1, &w1);\n  if (w1 > ww) ww = w1;" for f in functions])


_STEPS = """
CASADI_SYMBOL_EXPORT int {name}(const casadi_real** arg, casadi_real** res, casadi_int* iw,
                                casadi_real* w, int mem) {{
  const casadi_int nz = {nz}, no = {no};
  const casadi_real** sarg = arg + {n_in} + {n_report};
  casadi_real** sres = res + {n_out};
  casadi_real *zbuf, *obuf;
  const casadi_real* z = arg[0];
  casadi_int k, j, every = 1, next = 0, col = 0, used = {n};
  int lean = 0;
{declarations}
{wind_declarations}
{max_work}
{modes}
{wind_modes}
  zbuf = w + ww;
  obuf = zbuf + 2 * nz;
  for (j = 1; j < {n_in}; j++) sarg[j] = arg[j];  /* the held inputs, once */
  for (k = 0; k < used; k++) {{
{per_step}
    sarg[0] = z;
{keep_before}
    sres[0] = res[0] && !lean ? res[0] + k * nz : zbuf + (k % 2) * nz;
{report_or_state}
    z = sres[0];
{watch_after}
  }}
{check_end}
  return 0;
}}
"""

def _report_or_state(step: str, state_step: str, col: str, scratch: str, indent: str) -> str:
    """C: step k's report into the next kept column where k is on the report grid (``step``),
    else the next state alone (``state_step``, its report into ``scratch``)."""
    lines = ["if (res[1] && k == next) {", f"  sres[1] = res[1] + {col}++ * no;",
             "  next += every;", f"  if ({step}(sarg, sres, iw, w, mem)) return 1;",
             "} else {", f"  sres[1] = {scratch};",
             f"  if ({state_step}(sarg, sres, iw, w, mem)) return 1;", "}"]
    return "\n".join(indent + x for x in lines)


#: the steps driver's inputs after the step's: which steps' reports it keeps
REPORT_INPUTS = ("out_every", "out_first")
#: then what it computes and writes: the steps it runs (``n_used``: the first of the
#: chunk's; 0 or left out: all) and, ``lean`` > 0, the lean record (LEAN_OUTPUTS) in place
#: of each step's state
LEAN_INPUTS = ("n_used", "lean")
#: then, for a step taking ``wind3``, the wind from its samples: ``wind_n`` > 0 samples
#: (times ``wind_t``, speeds ``wind_v``, in their first entries) from which the driver
#: interpolates the wind at t, t + dt/2, t + dt of each step, t = (wind_k0 + k) wind_dt for
#: the chunk's step k, as numpy.interp does (the same numbers, bit for bit, under the
#: default flags: tests/test_loop_codegen.py; the fast-math chunks drop its NaN
#: fallbacks), in place of reading ``wind3``; ``wind_n`` 0 or left out:
#: ``wind3`` is read
WIND_INPUTS = ("wind_k0", "wind_dt", "wind_n", "wind_t", "wind_v")
#: the room for samples beyond a chunk's steps: samples no closer than a step need at most
#: one a step, the one before the first and the one after the last (the wind's run is
#: interpolated in Python, ``wind3``, where its samples do not fit)
WIND_ROOM = 3
#: the drivers' outputs after the chunk's own: the rows ``keep`` of the state before each
#: step (the metrics' states), and the check: the state after the last step run, then 1
#: where any state after a step was non-finite or beyond 1e8 (0 else), then the largest
#: and the smallest value of row ``watch`` (the rotor speed) after a step
LEAN_OUTPUTS = ("kept", "check")

_MODES = """  /* the report of every out_every-th step from step out_first, in its first columns
   * (left out: every step's); the steps run; the lean record */
  if (arg[{a}] && arg[{a}][0] > 1) every = (casadi_int) arg[{a}][0];
  if (arg[{a} + 1] && arg[{a} + 1][0] > 0) next = (casadi_int) arg[{a} + 1][0];
  if (arg[{a} + 2] && arg[{a} + 2][0] > 0 && arg[{a} + 2][0] < used)
    used = (casadi_int) arg[{a} + 2][0];
  if (arg[{a} + 3] && arg[{a} + 3][0] > 0) lean = 1;"""

_WIND_MODES = """  /* the wind from its samples (WIND_INPUTS), when given: each step's three into
   * the scratch after the driver's own, as wind3 lies */
  if (arg[{a}] && arg[{a} + 1] && arg[{a} + 2] && arg[{a} + 2][0] > 0 && arg[{a} + 3]
      && arg[{a} + 4]) {{
    casadi_int wk0 = (casadi_int) arg[{a}][0], wn = (casadi_int) arg[{a} + 2][0], wj = 0;
    wind = w + ww + {offset};
    for (k = 0; k < used; k++)
      {name}_wind3(wk0 + k, arg[{a} + 1][0], arg[{a} + 3], arg[{a} + 4], wn, &wj,
                   wind + 3 * k);
  }}"""

#: numpy.interp's arithmetic (numpy/_core/src/multiarray/compiled_base.c, arr_interp, in
#: numpy 1.x and 2.x) for increasing times: held at the end samples outside them; a sample's
#: own speed at its time; else slope (f[i+1] - f[i]) / (x[i+1] - x[i]) times (t - x[i])
#: plus f[i], the other end's form where that is NaN. Its binary search is a walk from the
#: last step's sample (``j``), the step's times increasing
_WIND = """
static casadi_real {name}_interp(casadi_real t, const casadi_real* x, const casadi_real* f,
                                 casadi_int n, casadi_int* j) {{
  casadi_int i = *j;
  casadi_real s, r;
  if (t != t) return t;
  if (t < x[0]) return f[0];
  if (t > x[n - 1]) return f[n - 1];
  while (i + 1 < n && x[i + 1] <= t) i++;
  *j = i;
  if (i == n - 1 || x[i] == t) return f[i];
  s = (f[i + 1] - f[i]) / (x[i + 1] - x[i]);
  r = s * (t - x[i]) + f[i];
  if (r != r) {{
    r = s * (t - x[i + 1]) + f[i + 1];
    if (r != r && f[i] == f[i + 1]) r = f[i];
  }}
  return r;
}}

/* the wind at step k's t, t + dt/2 and t + dt into w, t = k dt (as run_loops's times) */
static void {name}_wind3(casadi_int k, casadi_real dt, const casadi_real* x,
                         const casadi_real* f, casadi_int n, casadi_int* j, casadi_real* w) {{
  casadi_real t = (casadi_real) k * dt;
  casadi_int i;
  w[0] = {name}_interp(t, x, f, n, j);
  i = *j;
  w[1] = {name}_interp(t + dt / 2, x, f, n, &i);
  w[2] = {name}_interp(t + dt, x, f, n, &i);
}}
"""

_WIND_DECLARATIONS = """  casadi_real* wind = 0;"""


def _extra_inputs(window: int) -> list[tuple[str, int, int]]:
    """The drivers' inputs after the step's, as (name, rows, columns): REPORT_INPUTS,
    LEAN_INPUTS, and WIND_INPUTS with room for ``window`` samples (0: none)."""
    one = [(x, 1, 1) for x in REPORT_INPUTS + LEAN_INPUTS]
    if not window:
        return one
    return one + [(x, 1, 1) for x in WIND_INPUTS[:3]] + [(x, window, 1)
                                                           for x in WIND_INPUTS[3:]]


def _wind_c(name: str, a: int, window: int, offset: str) -> dict[str, str]:
    """The C of the wind from its samples (WIND_INPUTS from arg[a], ``window`` of them at
    most; 0: none), its steps' values at ``offset`` in the scratch: its declarations and
    modes."""
    if not window:
        return {"wind_declarations": "", "wind_modes": ""}
    return {"wind_declarations": _WIND_DECLARATIONS,
            "wind_modes": _WIND_MODES.format(a=a, name=name, offset=offset)}


#: whether any of n values is non-finite or beyond 1e8 in magnitude: one integer comparison
#: a value on its bits (sign cleared, every NaN and infinity above 1e8's bits), vectorised
#: (-O2 left a loop of float comparisons scalar: 143 states a step, the paper's, cost its
#: sampled loop 26 %), and blind to the compiler's floating-point flags (-ffinite-math-only,
#: in the fast-math chunks, turns !(|x| <= 1e8) into |x| > 1e8, false for a NaN)
_BEYOND = """
#include <stdint.h>
#include <string.h>
__attribute__((optimize("tree-vectorize")))
static int {name}_beyond(const casadi_real* x, casadi_int n) {{
  casadi_int j;
  int bad = 0;
  for (j = 0; j < n; j++) {{
    uint64_t u;
    memcpy(&u, x + j, sizeof u);
    bad |= (u & 0x7fffffffffffffffULL) > 0x4197d78400000000ULL; /* the bits of 1e8 */
  }}
  return bad;
}}
"""

_LEAN_DECLARATIONS = """  static const casadi_int kept_rows[] = {{{rows}}};
  const casadi_int nk = {nk};
  casadi_real *kept = {kept}, *check = {check}, wmax = -HUGE_VAL, wmin = HUGE_VAL;
  int bad = 0;"""


def _lean_c(name: str, lean: tuple[tuple[int, ...], int] | None, n_out: int, before: str,
            after: str, indent: str, j: str) -> dict[str, str]:
    """The C of the lean record (``lean``: (keep, watch); LEAN_OUTPUTS, res[n_out] and the
    next; None: none, its pointers NULL): its declarations, the kept rows of the state
    ``before`` step k into column k of kept, the check of the state ``after`` it, and the
    check's column at the end (``j``: a free loop index)."""
    keep, watch = lean if lean is not None else ((), 0)
    i2 = indent + "  "
    return {
        "declarations": _LEAN_DECLARATIONS.format(
            rows=", ".join(map(str, keep)) or "0", nk=len(keep),
            kept=f"res[{n_out}]" if lean else "0", check=f"res[{n_out} + 1]" if lean else "0"),
        "keep_before": f"{indent}if (kept) for ({j} = 0; {j} < nk; {j}++) "
                       f"kept[k * nk + {j}] = {before}[kept_rows[{j}]];",
        "watch_after": "\n".join([
            f"{indent}if (check) {{",
            f"{i2}casadi_real v = {after}[{watch}];",
            f"{i2}bad |= {name}_beyond({after}, nz);",
            f"{i2}if (v > wmax) wmax = v;",
            f"{i2}if (v < wmin) wmin = v;",
            f"{indent}}}"]),
        "check_end": "\n".join([
            "  if (check && used > 0) {",
            f"    for ({j} = 0; {j} < nz; {j}++) check[{j}] = {after}[{j}];",
            "    check[nz] = bad; check[nz + 1] = wmax; check[nz + 2] = wmin;",
            "  }"])}


def steps_source(step: ca.Function, n: int, name: str, per_step: tuple[str, ...],
                 state_step: ca.Function | None = None,
                 lean: tuple[tuple[int, ...], int] | None = None) -> str:
    """C of the chunk ``name``: ``n`` steps of ``step`` (state in and out first, then its
    report) in a loop; the ``per_step`` inputs one column a step, the others held (one
    column); then REPORT_INPUTS: given, the report of every ``out_every``-th step from step
    ``out_first`` only, written to the report's first columns (the others are left as they
    were: a run recording every 40th step stores 1/40 of the reports); left out, every
    step's; then LEAN_INPUTS, and WIND_INPUTS where the step takes ``wind3``.
    ``state_step`` (the same inputs, the next state alone) takes the steps whose report is
    not kept. ``lean``: (keep, watch), the rows of LEAN_OUTPUTS (which follow the step's
    outputs); None: no LEAN_OUTPUTS. The code of the functions it calls must come before
    it."""
    ins, outs = step.name_in(), step.name_out()
    per = [int(x in per_step) for x in ins]
    nz, no = step.size1_in(0), step.size1_out(1)
    inputs = [(x, step.size1_in(i), n if per[i] else 1) for i, x in enumerate(ins)]
    outputs = [(x, step.size1_out(i), n) for i, x in enumerate(outs)] + _lean_outputs(
        lean, nz, n)
    called = [step.name()] + ([state_step.name()] if state_step is not None else [])
    window = n + WIND_ROOM if "wind3" in ins else 0
    extra = _extra_inputs(window)
    per_step = [f"    if (arg[{j}]) sarg[{j}] = arg[{j}] + k * {r};"
                for j, (_, r, _) in enumerate(inputs) if per[j]]
    if window:  # the wind from its samples where they are given
        j = ins.index("wind3")
        per_step.append(f"    if (wind) sarg[{j}] = wind + k * 3;")
    scratch = 3 * max(nz, no)
    return _interface(name, inputs + extra, outputs, called,
                      f"{scratch} + 3 * {n}" if window else str(scratch)) + \
        _BEYOND.format(name=name) + (_WIND.format(name=name) if window else "") + \
        _STEPS.format(name=name, n=n,
                      report_or_state=_report_or_state(step.name(), called[-1], "col",
                                                       "obuf", "    "),
                      n_in=len(ins), n_report=len(extra),
                      n_out=len(outputs), modes=_MODES.format(a=len(ins)),
                      per_step="\n".join(per_step), nz=nz, no=no, max_work=_max_work(called),
                      **_lean_c(name, lean, len(outs), "z", "z", "    ", "j"),
                      **_wind_c(name, len(ins) + len(REPORT_INPUTS + LEAN_INPUTS), window,
                                str(scratch)))


def _lean_outputs(lean: tuple[tuple[int, ...], int] | None, nz: int, n: int,
                  ) -> list[tuple[str, int, int]]:
    """LEAN_OUTPUTS as (name, rows, columns), or none without ``lean``."""
    if lean is None:
        return []
    return [(LEAN_OUTPUTS[0], len(lean[0]), n), (LEAN_OUTPUTS[1], nz + 3, 1)]


_INTERVALS = """
CASADI_SYMBOL_EXPORT int {name}(const casadi_real** arg, casadi_real** res, casadi_int* iw,
                                casadi_real* w, int mem) {{
  /* sizes: state, plant, controller, FDI, sensors, blades, held sample, measurements,
   * outputs; plant steps an interval, intervals a chunk */
  const casadi_int nz = {nz}, np = {np}, nc = {nc}, nf = {nf}, ns = {ns}, nb = {nb}, nh = {nh};
  const casadi_int nm = {nm}, no = {no}, n = {steps}, m = {m}, o = np + nc + nf;
  const casadi_real** sarg = arg + {n_in} + {n_report};
  casadi_real** sres = res + {n_out};
  casadi_real *zc, *xa, *xb, *fa, *fb, *xcn, *held, *va, *vn, *rd, *me, *col, *outs, *t;
  casadi_real T, dt = arg[{i_dt}] ? arg[{i_dt}][0] : 0;
  casadi_int j, i, k, q, every = 1, next = 0, reported = 0, used = n * m;
  int lean = 0;
{declarations}
{wind_declarations}
{max_work}
  /* the steps not on the report grid take the state-only plant step */
{modes}
{wind_modes}
  if (!arg[0]) return 1; /* no initial state */
  zc = w + ww; xa = zc + nz; xb = xa + np + ns; fa = xb + np + ns; fb = fa + nf;
  xcn = fb + nf; held = xcn + nc; va = held + nh; vn = va + nb; rd = vn + nb; me = rd + ns;
  col = me + nm; outs = col + nz;
  for (q = 0; q < nz; q++) zc[q] = arg[0][q];
  T = n * dt;
  t = zc;
  for (j = 0; j * n < used; j++) {{
    /* the sample at the interval's start */
{sample_args}
    sres[0] = xcn; sres[1] = held; sres[2] = va; sres[3] = vn; sres[4] = rd; sres[5] = me;
    if ({sample}(sarg, sres, iw, w, mem)) return 1;
    for (q = 0; q < np; q++) xa[q] = zc[q];
    for (q = 0; q < ns; q++) xa[np + q] = zc[o + q];
    for (q = 0; q < nf; q++) fa[q] = zc[np + nc + q];
    for (i = 0; i < n && j * n + i < used; i++) {{
      k = j * n + i;
{keep_before}
      /* the plant (and the sensors' lags) over one step of dt, the command held */
{plant_args}
      sres[0] = xb;
{report_or_state}
{fdi_call}
      /* the state after the step: the controller's as sampled until the last step */
      t = res[2] && !lean ? res[2] + k * nz : col;
      for (q = 0; q < np; q++) t[q] = xb[q];
      for (q = 0; q < nc; q++) t[np + q] = i < n - 1 ? zc[np + q] : xcn[q];
      for (q = 0; q < nf; q++) t[np + nc + q] = fb[q];
      for (q = 0; q < ns; q++) t[o + q] = xb[np + q];
      for (q = o + ns; q < nz; q++) t[q] = vn[q - o - ns];
      {{ casadi_real* s = xa; xa = xb; xb = s; s = fa; fa = fb; fb = s; }}
{watch_after}
    }}
    for (q = 0; q < nz; q++) zc[q] = t[q];
    if (res[0]) for (q = 0; q < nz; q++) res[0][j * nz + q] = zc[q];
  }}
{check_end}
  return 0;
}}
"""

_FDI_CALL = """      sarg[0] = fa; sarg[1] = va; sarg[2] = rd; sarg[3] = me;
      sarg[4] = arg[{i_p_fdi}]; sarg[5] = &dt;
      sres[0] = fb;
      if ({fdi}(sarg, sres, iw, w, mem)) return 1;"""


def _args(fn: ca.Function, given: dict[str, str], indent: str) -> str:
    """C statements pointing sarg[i] at each of fn's inputs (``given``: C expressions)."""
    return "\n".join(f"{indent}sarg[{i}] = {given[x]};" for i, x in enumerate(fn.name_in()))


def _interval_args(iv: ca.Function) -> tuple[dict[str, str], dict[str, str]]:
    """The C expressions the intervals driver passes the sample and the plant step for
    each input of the interval function ``iv``: the held inputs whole, the per-interval
    ones at interval j, the per-step ones at step k; the wind from its samples where
    they are given (``wind``), else from ``wind3``."""
    idx = {x: i for i, x in enumerate(iv.name_in())}

    def col(x: str, i: str) -> str:  # column i of input x (NULL: an input left out)
        return f"(arg[{idx[x]}] ? arg[{idx[x]}] + {i} * {iv.size1_in(idx[x])} : 0)"

    def wind(i: str) -> str:  # step i's wind3
        return f"(wind ? wind + {i} * 3 : {col('wind3', i)})"

    # the sample's wind: the first of wind3's at the interval's first plant step
    interval = {**{x: f"arg[{i}]" for x, i in idx.items()}, "z": "zc", "T": "&T",
                "wind": wind("j * n"), **{x: col(x, "j") for x in sampled.PER_INTERVAL}}
    plant = {**interval, "x": "xa", "v": "va", "held": "held",
             **{x: col(x, "k") for x in sampled.PER_STEP}, "wind3": wind("k")}
    return interval, plant


def intervals_source(loop: Loop, m: int, name: str,
                     fixed: dict[str, dict[int, float]] | None = None,
                     lean: tuple[tuple[int, ...], int] | None = None,
                     ) -> tuple[list[ca.Function], str]:
    """The functions of the sampled loop (sample, plant step, FDI step: their code comes
    first, in this order) and the C of the chunk ``name``: ``m`` control intervals, as
    :func:`wtftc.sim.sampled.interval_function` mapped by mapaccum computes them, with
    the same inputs (the held ones as one column) and outputs, then REPORT_INPUTS (as
    :func:`steps_source`'s: given, only the reports of the output grid are computed and
    written, the other plant steps taking the plant step's state-only twin, the same next
    state bit for bit); then LEAN_INPUTS, and LEAN_OUTPUTS after its own with ``lean`` (as
    :func:`steps_source`'s); ``fixed``: the functions specialised to these switch values
    (:func:`wtftc.sim.specialise.folded`)."""
    iv = sampled.interval_function(loop)
    sz = sampled._sizes(loop)
    parts = [("sample", sampled._sample(loop)), ("plant", sampled._plant_step(loop))]
    if loop.fdi:
        parts.append(("fdi", sampled._fdi_step(loop)))
    fns = [specialise.folded(f, fixed or {}, f"{name}_{part}") for part, f in parts]
    x = fns[1].sx_in()  # the plant step computing its next state alone (no report)
    fns.append(ca.Function(f"{name}_plant_state", x, [fns[1].call(x)[0]], fns[1].name_in(),
                           [fns[1].name_out(0)]))
    steps = loop.interval
    ins = iv.name_in()
    idx = {x: i for i, x in enumerate(ins)}
    cols = {x: steps * m if x in sampled.PER_STEP else
            m if x in sampled.PER_INTERVAL else 1 for x in ins}
    interval, plant = _interval_args(iv)
    inputs = [(x, iv.size1_in(i), cols[x]) for i, x in enumerate(ins)]
    extra = _extra_inputs(steps * m + WIND_ROOM)
    outputs = [("z_next", sz["z"], m), ("out", iv.size1_out(1), steps * m),
               ("z_steps", sz["z"], steps * m)] + _lean_outputs(lean, sz["z"], steps * m)
    scratch = (f"{sz['z']} * 2 + 2 * ({sz['p']} + {sz['s']}) + 2 * {sz['f']} + {sz['c']} + "
               f"{sampled._held_size(loop)} + 2 * {sz['b']} + {sz['s']} + {sz['m']} + "
               f"{iv.size1_out(1)}")  # then the wind's steps: 3 * steps * m
    body = _INTERVALS.format(
        name=name, n_in=len(ins), n_report=len(extra),
        n_out=len(outputs), modes=_MODES.format(a=len(ins)),
        report_or_state=_report_or_state(fns[1].name(), fns[-1].name(), "reported", "outs",
                                         "      "), i_dt=idx["dt"], nz=sz["z"], np=sz["p"],
        nc=sz["c"], nf=sz["f"] if loop.fdi else 0, ns=sz["s"], nb=sz["b"],
        nh=sampled._held_size(loop), nm=sz["m"], no=iv.size1_out(1), steps=steps, m=m,
        max_work=_max_work([f.name() for f in fns]), sample=fns[0].name(),
        sample_args=_args(fns[0], interval, "    "),
        plant_args=_args(fns[1], plant, "      "),
        fdi_call=_FDI_CALL.format(i_p_fdi=idx.get("p_fdi", -1), fdi=fns[2].name())
        if loop.fdi else "", **_lean_c(name, lean, 3, "t", "t", "      ", "q"),
        **_wind_c(name, len(ins) + len(REPORT_INPUTS + LEAN_INPUTS), steps * m + WIND_ROOM,
                  scratch))
    return fns, _interface(name, inputs + extra, outputs, [f.name() for f in fns],
                           f"{scratch} + 3 * {steps * m}") + _BEYOND.format(name=name) + \
        _WIND.format(name=name) + body
