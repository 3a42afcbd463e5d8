"""The closed loop: generated plant + Cp interpolant + generated controller, fixed-step RK4.

One CasADi function advances the whole loop by one RK4 step; ``mapaccum`` chains
``CHUNK`` steps into one compiled call (C, cached by hash like the generated code), and
the Python loop calls it chunk by chunk so that a progress bar moves and a divergence is
caught within one chunk. The controller sees only measured signals (rotor speed); the
plant state never enters it.

Per step k (from t_k to t_k + dt) the exogenous inputs are the wind at t_k, t_k + dt/2,
t_k + dt, and the fault inputs at t_k (held over the step). Outputs are reported at t_k
from the state z_k.
"""

from __future__ import annotations

import os
import platform
import re
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import casadi as ca
import numpy as np

from wtftc.artefacts import layout as lay
from wtftc.artefacts.loader import cache_dir, compiled_library, compiler, external_of
from wtftc.model import spline
from wtftc.model.faults import nominal_actuator
from wtftc.model.wind import ConstantWind, SampledWind
from wtftc.sim import specialise
from wtftc.sim.drivers import (
    LEAN_INPUTS,
    LEAN_OUTPUTS,
    REPORT_INPUTS,
    WIND_INPUTS,
    intervals_source,
    steps_source,
)
from wtftc.sim.rhs import PLANTS, Loop, fdi_params, output_spec, rhs_function, sensor_names
from wtftc.sim.sampled import interval_function

#: RK4 steps per compiled call, at most (:func:`chunk_steps`); 1000 before issue 19, when
#: the per-chunk Python work (the fault columns, the calls, the records) cost the physical
#: loop 6 % more
CHUNK = 4000
#: what a chunk's per-step buffers (the state rows it writes, outputs, per-step inputs) may
#: take: beyond about this the paper's loop (2 KB a step, every state written) got slower
#: with longer chunks, 5 % at 4000 steps
CHUNK_BYTES = 4 << 20


@cache
def chunk_steps(loop: Loop) -> int:
    """The steps of ``loop``'s chunk: CHUNK, or fewer (not under 1000) where their buffers
    would take more than CHUNK_BYTES. The state rows counted are those of the C drivers'
    lean record (:func:`lean_rows`), which is what a run writes a step unless it keeps
    every state: the paper's sampled loop went from 2000 steps to 4000 and ran 4-5 %
    faster (docs/performance.md)."""
    per_step = len(lean_rows(loop)[0]) + len(output_spec(loop.controller, loop.fdi,
                                                         loop.plant))
    per_step += 3 + sum(len(lay.names(g)) for g in ("actuator_faults", "sensor_faults",
                                                     "fault_inputs"))
    return max(1000, min(CHUNK, CHUNK_BYTES // (8 * per_step) // 500 * 500))


def rk4_step(rhs: ca.Function, exogenous: str = "wind", report: str = "out",
             fixed: dict | None = None, name: str = "rk4_step",
             shared: bool = True) -> ca.Function:
    """Classical RK4 over one step dt (Kutta 1901) of rhs's ``z_dot``: the ``exogenous``
    input at t, t + dt/2, t + dt (given as <exogenous>3), the other inputs held over the
    step; the ``report`` output at the start of the step. ``fixed``: inputs given as
    values, whole or by entry ({entry: value}: :mod:`wtftc.sim.specialise`) (a specialised
    step: :func:`chunk_function`), kept as inputs that are not read.

    ``shared``: written in SX, the four stages in one graph with their common work shared
    (what depends on the parameters alone, or on the wind at t + dt/2, is computed once a
    step: 7-10 % faster, issue 19), at four times the C for the compiler; else four calls
    of rhs (for a loop with the FDI's 95 states, whose stage-shared C takes gcc 5-6 s and
    runs no faster: docs/performance.md). The same numbers either way, bit for bit."""
    sym = ca.SX if shared else ca.MX
    if fixed and not shared:  # the values folded into the right-hand side itself
        ins = rhs.sx_in()
        given = [specialise.given(x, fixed.get(n)) for n, x in zip(rhs.name_in(), ins, strict=True)]
        rhs = ca.Function(f"{rhs.name()}_fixed", ins, ca.cse(rhs(*given)), rhs.name_in(),
                          rhs.name_out())
    z = sym.sym("z", rhs.sparsity_in("z"))
    w3 = sym.sym(f"{exogenous}3", 3)
    held = [n for n in rhs.name_in() if n not in ("z", exogenous)]
    others = {n: sym.sym(n, rhs.sparsity_in(n)) for n in held}
    dt = sym.sym("dt")
    values = {**others, **{n: specialise.given(others[n], v) for n, v in (fixed or {}).items()
                           if shared}}

    def f(zz, w):
        return rhs.call({"z": zz, exogenous: w, **values})

    first = f(z, w3[0])
    k1, out = first["z_dot"], first[report]
    k2 = f(z + dt / 2 * k1, w3[1])["z_dot"]
    k3 = f(z + dt / 2 * k2, w3[1])["z_dot"]
    k4 = f(z + dt * k3, w3[2])["z_dot"]
    z_next = z + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    outs = ca.cse([z_next, out]) if shared else [z_next, out]
    return ca.Function(name, [z, w3, *others.values(), dt], outs,
                       ["z", f"{exogenous}3", *held, "dt"], ["z_next", report])


def rk4_path(rhs, z0, t0: float, t1: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The same RK4 in NumPy for a Python right-hand side ``rhs(t, z)``, n steps from t0 to
    t1 (t1 < t0 runs backward): the times and the states, (n + 1) × len(z0). A non-finite
    state stops it with the time and the last finite state."""
    h = (t1 - t0) / n if n else 0.0
    ts = t0 + h * np.arange(n + 1)
    zs = np.empty((n + 1, np.size(z0)))
    z = zs[0] = np.asarray(z0, dtype=float)
    for k in range(n):
        t = ts[k]
        k1 = rhs(t, z)
        k2 = rhs(t + h / 2, z + h / 2 * k1)
        k3 = rhs(t + h / 2, z + h / 2 * k2)
        k4 = rhs(t + h, z + h * k3)
        z = z + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        if not np.all(np.isfinite(z)):
            raise FloatingPointError(f"diverged at t = {ts[k + 1]:.6g} s; last finite "
                                     f"state {zs[k].tolist()}")
        zs[k + 1] = z
    return ts, zs

#: flags of the closed-loop chunks (the verified generated functions keep CFLAGS):
#: -fno-semantic-interposition lets gcc inline CasADi's helpers (fmin, fmax, sq) instead of
#: calling them through the PLT; -fno-math-errno lets it treat sqrt, exp, ... as pure
#: functions (inline sqrtsd, no errno bookkeeping): 1.4-1.9× on the paper's loop;
#: -fno-trapping-math lets it compute both sides of a branch on doubles (no operation
#: traps here: nothing enables FP exceptions), 3-7 % (issue 35). All are bit-identical to
#: plain -O2: no operation is reordered, fused or replaced (docs/performance.md,
#: tests/test_bench.py)
LOOP_CFLAGS = ("-O2", "-fno-semantic-interposition", "-fno-math-errno", "-fno-trapping-math",
               "-fPIC", "-shared")

#: opt-in: -ffast-math's code generation (reassociation, reciprocals, no NaN/inf, no signed
#: zeros): 1.05-1.2× more on the loops (docs/performance.md); results differ at
#: 1e-12..1e-9 relative (not bit-identical to the default). Its component flags, not
#: -ffast-math itself: gcc (before 13) links crtfastmath.o into a -ffast-math library,
#: whose constructor turns on flush-to-zero and denormals-are-zero in the loading thread,
#: for the whole process from then on (numpy and every other chunk included;
#: tests/test_loop_codegen.py)
FAST_MATH_CFLAGS = ("-O2", "-fno-semantic-interposition", "-fno-math-errno",
                    "-fno-signed-zeros", "-fno-trapping-math", "-fassociative-math",
                    "-freciprocal-math", "-ffinite-math-only", "-fno-rounding-math",
                    "-fno-signaling-nans", "-fcx-limited-range", "-fexcess-precision=fast",
                    "-fPIC", "-shared")

#: where the CPU runs it (AVX2, BMI1/2, F16C, FMA, LZCNT, MOVBE: x86-64 CPUs since about
#: 2015), the loop chunks are built for x86-64-v3: 20 % faster on the paper's loop, 5 % on
#: the physical (the VEX encoding; docs/performance.md). FMA contraction stays off, on
#: every target, so that the chunks compute what CasADi's virtual machine computes, bit for
#: bit (aarch64's gcc would otherwise fuse a*b + c)
X86_64_V3 = {"avx", "avx2", "bmi1", "bmi2", "f16c", "fma", "abm", "movbe", "xsave"}


def _x86_64() -> bool:
    return platform.machine() in ("x86_64", "AMD64")


@cache
def arch_flags() -> tuple[str, ...]:
    """-ffp-contract=off, and -march=x86-64-v3 where this CPU has its instructions and the
    compiler takes the flag (the flags are part of the compile cache's key, so a shared
    cache never hands a v3 library to a CPU without them)."""
    flags = ("-ffp-contract=off",)
    if not _x86_64():
        return flags
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return flags
    line = next((x for x in info.splitlines() if x.startswith("flags")), "")
    cc = compiler()
    if not X86_64_V3 <= set(line.split()) or cc is None:
        return flags
    probe = subprocess.run([cc, "-march=x86-64-v3", "-x", "c", "-c", os.devnull, "-o",
                            os.devnull], capture_output=True)
    return ("-march=x86-64-v3", *flags) if probe.returncode == 0 else flags


def loop_flags(fast_math: bool = False) -> tuple[str, ...]:
    """The C flags of a loop chunk here: LOOP_CFLAGS (or FAST_MATH_CFLAGS) with
    :func:`arch_flags`."""
    base = FAST_MATH_CFLAGS if fast_math else LOOP_CFLAGS
    return (*base[:-2], *arch_flags(), *base[-2:])


def compiled(f: ca.Function, label: str, flags: tuple[str, ...] | None = None,
             quiet: bool = False) -> ca.Function:
    """f as generated C, compiled once and cached (or f itself, on CasADi's virtual
    machine, where compiling or caching is impossible: one warning per process)."""
    return _compile_function(f, label, flags, quiet)

#: the generated C's min and max helpers call libm's fmin and fmax, which gcc may not
#: inline under C's rules (a call through the PLT each: 6-8 % of a loop's time); inline,
#: with the same result for every pair of doubles, NaN and signed zeros included (glibc's
#: semantics on x86-64: a NaN argument gives the other one; tests/test_loop_codegen.py;
#: not applied elsewhere: aarch64's glibc orders -0 below +0)
INLINE_MINMAX = (("return fmax(x, y);", "return x > y ? x : (y != y ? x : y);"),
                 ("return fmin(x, y);", "return x < y ? x : (y != y ? x : y);"))


#: CasADi writes its branch-free select ``if_else_zero`` (an anti-windup's κ, an actuator
#: at its limit: every ``Piecewise`` of the derivation) as ``(c?x:0)``, which gcc compiles
#: to a branch where it may not assume that comparisons do not trap (its default); as a
#: mask, the same bits (x where c is nonzero, NaN included, else +0), without the branch:
#: 4.5 % of the physical loop's step, the paper's as before (issue 19)
SELECT = re.compile(r"\((a\d+)\?(a\d+):0\)")
SELECT_C = """
/* wtftc: (c?x:0) without a branch (wtftc.sim.integrate.SELECT) */
static inline casadi_real wtftc_select(casadi_real c, casadi_real x) {
  uint64_t bits, mask = -(uint64_t) (c != 0);
  memcpy(&bits, &x, sizeof bits);
  bits &= mask;
  memcpy(&x, &bits, sizeof x);
  return x;
}
"""
_SELECT_AFTER = "#define casadi_int long long int\n#endif\n"


def branch_free_selects(code: str) -> str:
    """CasADi's C ``code`` with its selects ``(c?x:0)`` written as SELECT_C's mask (left
    as they are where the code does not have the expected layout)."""
    if _SELECT_AFTER not in code or not SELECT.search(code):
        return code
    code = code.replace(_SELECT_AFTER, _SELECT_AFTER + "#include <stdint.h>\n#include <string.h>\n"
                        + SELECT_C, 1)
    return SELECT.sub(r"wtftc_select(\1, \2)", code)


def loop_source(f: ca.Function | list[ca.Function], folder: Path, label: str,
                extra_c: str = "") -> Path:
    """The C of a loop chunk's function(s) ``f`` in ``folder``: CasADi's code with the lean
    spline bodies (wtftc.model.spline.lean_c), the selects without branches (SELECT), the
    min and max helpers inlined (INLINE_MINMAX), then ``extra_c`` (C compiled into the same
    library: a driver calling them, the DISCON bridge, ...)."""
    cg = ca.CodeGenerator(f"{label}.c", {"with_header": False})
    for fn in f if isinstance(f, list) else [f]:
        cg.add(fn)
    code = branch_free_selects(spline.lean_c(cg.dump()))
    if _x86_64():  # aarch64's fmin/fmax order signed zeros
        for old, new in INLINE_MINMAX:
            code = code.replace(old, new)
    if extra_c:
        code += "\n" + extra_c
    path = folder / f"{label}.c"
    path.write_text(code)
    return path


def _compile_function(f: ca.Function, label: str, flags: tuple[str, ...] | None = None,
                      quiet: bool = False) -> ca.Function:
    """Generate C for f (:func:`loop_source`) and load it through the loader's verified
    compile cache; f itself where the loader cannot compile or cache it (the loader warns,
    once per process)."""
    so = loop_library([f], label, "", flags or loop_flags(), quiet)
    loaded = None if so is None else external_of(f.name(), so)
    return f if loaded is None else loaded

#: the inputs of a loop's step that change from step to step (the chunk takes one column
#: a step of each); the others are held over the chunk (one column)
PER_STEP = ("wind3", "actuator_faults", "sensor_faults", "ctrl_fault")

@cache
def chunk_function(loop: Loop, n: int = CHUNK, fast_math: bool = False,
                   quiet: bool = False, exact: bool = False,
                   switches: tuple[specialise.Switch, ...] = ()) -> ca.Function:
    """``n`` RK4 steps of ``loop`` in one compiled call (mapaccum over the step, or over
    the control interval of a sampled loop: n rounded down to whole intervals);
    ``fast_math``: compiled with FAST_MATH_CFLAGS instead of LOOP_CFLAGS; ``quiet``: no
    note when it is compiled; ``exact``: specialised for exact sensors without sensor
    faults (:func:`exact_sensors`), their inputs taken as the layout's defaults and not
    read (the same numbers as the general chunk given those values, bit for bit; a third
    fewer operations on the physical loop, its sampled loop's call 30 % shorter:
    docs/performance.md); ``switches``: specialised to these values of the controller's
    options (:mod:`wtftc.sim.specialise`: the options switched off folded away), likewise
    not read."""
    tag = "" if loop.fdi else "_nofdi"
    fixed = {"p_ctrl": dict(switches)} if switches else {}
    if exact:
        fixed |= {"p_sensors": lay.defaults("sensor_params"),
                  "sensor_faults": lay.defaults("sensor_faults")}
    if loop.sampled:
        tag += (f"_s{loop.interval}{'d' if loop.delay else ''}{'_exact' if exact else ''}"
                f"{specialise.tag(switches)}")
        m = max(1, n // loop.interval)
        label = f"loop_{loop.plant}_{loop.controller}{tag}_{loop.table_key}_{m * loop.interval}"
        fns, driver = intervals_source(loop, m, label, fixed, lean_rows(loop))
        return _driven(fns, driver, label, loop_flags(fast_math), quiet,
                       lambda: interval_function(loop).mapaccum(label, m))
    tag += ("_exact" if exact else "") + specialise.tag(switches)
    label = f"loop_{loop.plant}_{loop.controller}{tag}_{loop.table_key}_{n}"
    step = rk4_step(rhs_function(loop), fixed=fixed or None, name=f"{label}_step",
                    shared=not loop.fdi)
    return compiled_chunk(step, n, label, loop_flags(fast_math), quiet, lean=lean_rows(loop))


def compiled_chunk(step: ca.Function, n: int, label: str,
                   flags: tuple[str, ...] | None = None, quiet: bool = False,
                   extra_c: str = "", lean: tuple[tuple[int, ...], int] | None = None,
                   ) -> ca.Function:
    """``n`` steps of ``step`` in one compiled call (the C driver of
    :func:`wtftc.sim.drivers.steps_source` around the step's generated code, then
    ``extra_c``; ``lean``: its lean record's rows); where no compiler or cache is usable,
    the same steps through ``mapaccum`` on CasADi's virtual machine (the same numbers,
    per-step columns of the held inputs)."""
    state_step = _state_step(step)
    fns = [step] + ([state_step] if state_step is not None else [])
    return _driven(fns, steps_source(step, n, label, PER_STEP, state_step, lean) + extra_c,
                   label, flags or loop_flags(), quiet, lambda: step.mapaccum(label, n))


@cache
def lean_rows(loop: Loop) -> tuple[tuple[int, ...], int]:
    """The rows of the C drivers' lean record (wtftc.sim.drivers.LEAN_OUTPUTS) for
    ``loop``: those of METRIC_STATES it has, in that order, and the rotor speed's (the
    envelope's)."""
    names = loop.state_names()
    return tuple(names.index(s) for s in METRIC_STATES if s in names), Envelope.of(loop).row

#: the largest step (SX instructions) given a state-only twin: two bodies of the paper's
#: loop (9,600) alternating every few steps cost it 6 % in instruction fetch, where the
#: physical loop's (1,600 when measured; 3,948 with issue 34's observer and damper, 4,744
#: with the damper's low-pass and the observer's schedule, both off by default) gains 3 %
#: (docs/performance.md; not re-measured at 4,744)
STATE_STEP_MAX = 6000


def _state_step(step: ca.Function) -> ca.Function | None:
    """``step`` computing its next state alone (its report's own operations left out), for
    the steps whose report is not kept: the same inputs, the same next state bit for bit
    (the same operations on the same values). None for a step in MX (its calls compute
    their reports anyway) or one larger than STATE_STEP_MAX."""
    if not step.is_a("SXFunction") or step.n_instructions() > STATE_STEP_MAX:
        return None
    ins = step.sx_in()
    return ca.Function(f"{step.name()}_state", ins, [step.call(ins)[0]], step.name_in(),
                       [step.name_out(0)])


def _driven(fns: list[ca.Function], driver: str, label: str, flags: tuple[str, ...],
            quiet: bool, fallback) -> ca.Function:
    """The chunk ``label``: ``driver`` (C) compiled with the code of ``fns``, loaded; else
    ``fallback()`` (on CasADi's virtual machine)."""
    so = loop_library(fns, label, driver, flags, quiet)
    loaded = None if so is None else external_of(label, so)
    return fallback() if loaded is None else loaded


def loop_library(fns: list[ca.Function], label: str, extra_c: str, flags: tuple[str, ...],
                 quiet: bool = False) -> Path | None:
    """The compiled library of :func:`loop_source` (the code of ``fns``, then ``extra_c``),
    from the verified cache; None where no compiler or cache is usable (the loader warns,
    once per process)."""
    with tempfile.TemporaryDirectory() as tmp:
        c_path = loop_source(fns, Path(tmp), label, extra_c)
        note = None if quiet else (f"  compiling the {label} loop (once; cached in "
                                   f"{cache_dir()}) ...")
        return compiled_library(c_path, flags, note)


def exact_sensors(loop: Loop, runs: list[Run]) -> bool:
    """Whether every run has exact sensors (the layout's default sensor parameters: no
    noise, bias, resolution or lag) and no sensor fault: the specialised chunk then
    computes the same numbers."""
    default = lay.defaults("sensor_params")
    return all((r.p_sensors is None or np.array_equal(r.p_sensors, default))
               and (r.schedule is None or not r.schedule.has_sensor_faults)
               for r in runs)


def run_switches(loop: Loop, runs: list[Run]) -> tuple[specialise.Switch, ...]:
    """The switches of ``loop`` (:mod:`wtftc.sim.specialise`) its chunk for ``runs`` is
    specialised to."""
    return specialise.shared_switches(loop, [r.p_ctrl for r in runs])


class Buffered:
    """A CasADi function called through ``Function.buffer()`` on NumPy arrays it owns.

    Skips the DM conversion at the Python boundary (measured at about 65 ns an element:
    2 µs a step for the loop's outputs). Every array bound to the buffer stays referenced
    by this object for its whole life (a dropped one would corrupt the heap); calls copy
    the inputs in and return copies of the results, shaped as CasADi's (rows, columns).
    """

    def __init__(self, f: ca.Function):
        self.f = f
        self._buf, self._trigger = f.buffer()
        self._last: dict = {}  # (name, run) → the object last written with same=True
        # (input, run, runs) segments that may hold values other than zero, and those of
        # them a reset left to be zeroed unless written whole first (:meth:`reset`)
        self._dirty: set = set()
        self._stale: set = set()
        self._index = {n: i for i, n in enumerate(f.name_in())}  # (f.index_in: 1 µs a call)
        self._in = [np.zeros((f.size2_in(i), f.size1_in(i))) for i in range(f.n_in())]
        # (outputs uninitialised: a call writes every value that is read, and zeroing
        # a sampled chunk's 2.5 MB took 120 µs a run)
        self._out = [np.empty((f.size2_out(i), f.size1_out(i))) for i in range(f.n_out())]
        for i, a in enumerate(self._in):
            self._buf.set_arg(i, memoryview(a))
        for i, r in enumerate(self._out):
            self._buf.set_res(i, memoryview(r))

    def put(self, name: str, value, run: int = 0, n_runs: int = 1, same: bool = False) -> None:
        """Write input ``name`` of run ``run`` (of n_runs side by side) in place: ``value``
        is (rows, columns) of that run, or one column (rows,) held over its columns.
        ``same``: ``value`` is never changed in place, so when it is the very object last
        written here, the buffer already holds it and is left alone."""
        if same:
            if self._last.get((name, run)) is value:
                return
            self._last[(name, run)] = value
        else:
            self._last.pop((name, run), None)
        i = self._index[name]
        a = self._in[i]
        w = a.shape[0] // n_runs
        seg = a[run * w:(run + 1) * w]
        key = (i, run, n_runs)
        if self._stale:  # this segment is written whole: only those of the input cut
            # otherwise (another number of runs: a fill) that overlap it are zeroed first
            self._zero_stale({x for x in self._stale if x[0] == i and x[2] != n_runs})
            self._stale.discard(key)
        self._dirty.add(key)
        v = np.asarray(value, dtype=float)
        if v.ndim == 2 and v.shape[1] > 1:
            seg[...] = v.T
        else:
            seg[...] = v.reshape(1, -1)

    def put_head(self, name: str, value: np.ndarray, run: int = 0, n_runs: int = 1) -> None:
        """Write the first len(value) entries of run ``run``'s input ``name``, one column;
        the others are left as they were."""
        self._last.pop((name, run), None)
        i = self._index[name]
        if self._stale:
            self._zero_stale({x for x in self._stale if x[0] == i})
        self._dirty.add((i, run, n_runs))
        a = self._in[i]
        a[run * (a.shape[0] // n_runs), :len(value)] = value

    def nbytes(self) -> int:
        """The bytes of its input and output arrays."""
        return sum(a.nbytes for a in self._in) + sum(r.nbytes for r in self._out)

    def reset(self) -> None:
        """Every input zero, as a new Buffered's, when it is next read: what was written
        since the last reset is zeroed at the next evaluation, unless written whole before
        it (zeroing every input took 40-370 µs a run, most of it the fault inputs of every
        step that the first chunk writes anyway)."""
        self._stale = set(self._dirty)
        self._last.clear()

    def _zero_stale(self, which: set | None = None) -> None:
        """Zero the stale segments (of ``which`` only, given)."""
        for key in self._stale if which is None else self._stale & which:
            i, run, n_runs = key
            a = self._in[i]
            w = a.shape[0] // n_runs
            a[run * w:(run + 1) * w] = 0.0
            self._dirty.discard(key)
        self._stale = set() if which is None else self._stale - which

    def fill(self, name: str, value: float) -> None:
        """Every element of input ``name``, for every run, set to ``value`` (an input
        never written with ``same``)."""
        i = self._index[name]
        self._stale = {x for x in self._stale if x[0] != i}  # written whole
        self._in[i].fill(value)
        self._dirty.add((i, 0, 1))

    def evaluate(self) -> list[np.ndarray]:
        """Evaluate on the inputs in place; results as (rows, columns) views of the
        buffers, valid until the next evaluation."""
        if self._stale:
            self._zero_stale()
        self._trigger()
        return [r.T for r in self._out]

    def __call__(self, *args, copy: bool = True) -> list[np.ndarray]:
        """Results as (rows, columns) arrays; ``copy=False``: views of the buffers, valid
        until the next call (no copy of what the caller does not keep)."""
        self._last.clear()  # every input is written here, whole
        self._stale = set()
        self._dirty |= {(i, 0, 1) for i in range(len(self._in))}
        for a, x in zip(self._in, args, strict=True):
            x = np.asarray(x, dtype=float)
            cols, rows = a.shape
            k = x.size // rows if rows else 0
            if 0 < k < cols and x.size == rows * k and cols % k == 0:
                # k columns each repeated cols/k times, as a call of a mapped function
                # broadcasts an input given once per run (k = 1: once for all)
                a[...] = np.repeat(x.reshape((rows, k), order="F"), cols // k, axis=1).T
            else:
                a[...] = x.reshape((rows, cols), order="F").T
        self._trigger()
        return [r.T.copy() for r in self._out] if copy else [r.T for r in self._out]

@dataclass
class Result:
    t: np.ndarray
    outputs: np.ndarray  # (N, outputs): rhs.output_spec's columns
    z_final: np.ndarray
    diverged: dict | None
    wall_s: float
    steps: int
    config: dict = field(default_factory=dict)
    z: np.ndarray | None = None  # full state trajectory at the output times (N, n_z)
    #: the states the metrics read (METRIC_STATES present in the loop) at every step,
    #: (steps, k), row i at t = i dt; None where run_loops was told not to keep them
    full: np.ndarray | None = None
    full_names: list = field(default_factory=list)
    dt: float = 0.0  # the step of ``full``'s rows [s]
    schedule: object = None  # the plant's fault schedule (wtftc.model.faults.Schedule)
    names: list = field(default_factory=list)  # output names, in column order

    def column(self, name: str) -> np.ndarray:
        return self.outputs[:, self.names.index(name)]

    def state(self, name: str) -> np.ndarray:
        """One state of METRIC_STATES at every step (row i at t = i dt)."""
        return self.full[:, self.full_names.index(name)]

    @property
    def every_step(self) -> bool:
        """Whether the run kept METRIC_STATES at every step (``full``)."""
        return self.full is not None and len(self.full) > 1

    def series(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(times [s], values) of ``name``: the state at every step where the run kept it
        (``full``), else the output column of that name at the output times."""
        if self.every_step and name in self.full_names:
            return np.arange(len(self.full)) * self.dt, self.state(name)
        return self.t, self.column(name)


#: the states the metrics read at the simulation rate (wtftc.results.metrics: issue 31,
#: an output rate of 10 Hz lowered the shaft DEL by 5.4 %): the rotor and generator speeds,
#: the shaft's twist, the pitch angles, the tower top's deflection (the tower base's moment
#: is k_t x_t h) and the FDI's actuator latches; those a loop has are kept, every step.
#: 8 bytes each a step: a 600-s run at dt = 1 ms keeps 48 MB with all ten.
METRIC_STATES = ("omega_r", "theta_s", "omega_g", "beta_1", "beta_2", "beta_3", "tower_x",
                 "fdi_latch_1", "fdi_latch_2", "fdi_latch_3")


@dataclass
class Run:
    """The per-run inputs of one closed loop in a batch (see :func:`run_loops`)."""

    z0: np.ndarray
    wind: object  # wind(t) -> m/s
    schedule: object = None  # the plant's faults (wtftc.model.faults.Schedule) or None
    ctrl_schedule: object = None  # the faults eq (49) is told, or None (nominal)
    yd: np.ndarray | None = None  # reference and its derivatives
    p_ctrl: np.ndarray | None = None
    use_fdi: bool = False
    #: the plant's turbine parameters (model mismatch), None: the loop's (the controllers'
    #: and the FDI's model); the plant's Cp relative to the table's
    p_plant: np.ndarray | None = None
    cp_scale: float = 1.0
    #: the sensors' parameters (layout sensor_params: σ, bias, resolution, lag), None: ideal
    p_sensors: np.ndarray | None = None
    #: the seed of the sensor noise (a sampled loop): one stream per signal
    noise_seed: int = 0
    #: the FDI's parameters (its thresholds follow the run's sensors), None: exact sensors
    p_fdi: np.ndarray | None = None
    #: the test movement of blades resting at their stop, (amplitude rad, period s, width
    #: s), or None (a sampled loop only: docs/fdi.md)
    test_pulse: tuple | None = None


class ChunkHook:
    """Something outside the generated step that acts every ``steps`` steps of a single run
    (ROSCO's DISCON, wtftc.sim.rosco): :meth:`before` writes the inputs it holds over the
    next chunk (steps k .. stop - 1 are used), :meth:`after` reads the chunk just computed.
    ``function``: the chunk function to integrate with (None: the loop's own, of ``steps``
    steps a call)."""

    steps: int = CHUNK
    function: ca.Function | None = None

    def before(self, call: Buffered, k: int, stop: int) -> None:
        """Write held inputs (by name) before the chunk is evaluated."""

    def after(self, k: int, stop: int, z: np.ndarray, res: list[np.ndarray],
              out_names: list[str]) -> None:
        """k .. stop - 1: the steps just computed; z: the state at stop; res: the chunk's
        outputs (columns from step k on)."""


@cache
def _mapped(f: ca.Function, n_runs: int) -> ca.Function:
    """f evaluated for n_runs independent runs, side by side, in one call."""
    return f if n_runs == 1 else f.map(n_runs, "serial")


@dataclass(frozen=True)
class Envelope:
    """Where a run's rotor must stay (layout.json "envelope", derivation/layout.py): beyond
    ``high`` it has run away, below ``low`` it has stalled; either ends the run as lost."""

    row: int  # ω_r's row in the state
    low: float  # rad/s
    high: float  # rad/s

    @classmethod
    def of(cls, loop: Loop) -> Envelope:
        rated = loop.p_turbine[lay.index("turbine_params", "omega_g_rated")]
        env = lay.layout()["envelope"]
        return cls(lay.index(PLANTS[loop.plant]["states"], "omega_r"),
                   env["stall_under_rated"] * rated, env["overspeed_over_rated"] * rated)

    def outside(self, zz: np.ndarray) -> np.ndarray:
        w = zz[self.row]
        return (w > self.high) | (w < self.low)

    def left(self, zz: np.ndarray) -> bool:
        """Whether the rotor left the envelope anywhere in the finite states ``zz``
        (``outside(zz).any()`` without its temporaries)."""
        w = zz[self.row]
        return bool(w.max() > self.high or w.min() < self.low)

    def reason(self, w: float) -> str:
        env = lay.layout()["envelope"]
        if w > self.high:
            return (f"out of the operating envelope: ω_r = {w:.6g} rad/s, above "
                    f"{env['overspeed_over_rated']:g} × rated ({self.high:.4g} rad/s): the "
                    "rotor ran away")
        return (f"out of the operating envelope: ω_r = {w:.6g} rad/s, below "
                f"{env['stall_under_rated']:g} × rated ({self.low:.4g} rad/s): the rotor "
                "stalled")


@dataclass
class _Batch:
    """Runs advancing together: their states (n_z, n_runs) and what has been recorded."""

    runs: list[Run]
    names: list[str]
    out_names: list[str]
    z: np.ndarray
    keep_states: bool
    decimate: int
    envelope: Envelope | None = None
    full_rows: list = field(default_factory=list)  # the rows of METRIC_STATES kept
    dt: float = 0.0  # s: the step
    n_steps: int = 0  # the steps of a run: the size of ``fulls`` and of ``outs``' grid
    outs: list = field(default_factory=list)  # per run: the outputs on the grid, a row a step
    grid: list = field(default_factory=list)  # per run: the grid's steps recorded
    zs: list = field(default_factory=list)
    fulls: list = field(default_factory=list)  # per run: METRIC_STATES, a row a step
    diverged: list = field(default_factory=list)
    steps: list = field(default_factory=list)

    def __post_init__(self):
        n = len(self.runs)
        self.zs = [[] for _ in range(n)]
        self.fulls, self.outs, self.grid = [None] * n, [None] * n, [0] * n
        self.diverged, self.steps = [None] * n, [0] * n

    def record(self, b: int, zz: np.ndarray, oo: np.ndarray, k: int, m: int, dt: float,
               compact: bool = False) -> bool:
        """Keep run b's chunk (steps k .. k + m - 1): outputs on the decimated grid
        (``compact``: ``oo`` holds only those, in its first columns), the divergence if one
        happened (the run then stops at its last finite state). A compact chunk that looks
        wrong is not kept (False): its caller runs it again with every step's outputs, from
        which :func:`divergence` finds the step and what failed."""
        first, seen = self._seen(oo, k, m, compact)
        z_prev = self.z[:, b].copy()
        # |zz| <= 1e8 and finite outputs, without temporaries: max and min propagate NaN
        # (the comparison is then False)
        fine = zz.max() <= 1e8 and zz.min() >= -1e8 and _finite(seen)
        if not fine or (self.envelope is not None and self.envelope.left(zz)):
            if compact:
                return False
            i, self.diverged[b] = divergence(zz, oo, z_prev, self.names, self.out_names, k, dt,
                                             self.envelope)
            m = i + 1
        full = None
        if self.full_rows:
            full = np.empty((m, len(self.full_rows)))
            full[0] = z_prev[self.full_rows]
            full[1:] = zz[self.full_rows, :m - 1].T
        if self.keep_states:
            # the state before step i is z (i = 0) or zz[:, i-1]
            z_before = np.hstack([z_prev[:, None], zz[:, :m - 1]])
            self.zs[b].append(z_before[:, first::self.decimate].T.copy())
        # a diverged run is frozen at its last finite state (its column computes on,
        # unread, so that the batch keeps its shape)
        z_end = (zz[:, m - 2] if m > 1 else z_prev) if self.diverged[b] else zz[:, m - 1]
        self._keep(b, seen if compact else oo[:, first:m:self.decimate], k, m,
                   full, z_end)
        return True

    def record_lean(self, b: int, kept: np.ndarray, check: np.ndarray, oo: np.ndarray, k: int,
                    m: int, dt: float, compact: bool) -> bool:
        """:meth:`record` from a C driver's lean record (wtftc.sim.drivers.LEAN_OUTPUTS:
        ``kept``, the metrics' states before each step; ``check``, the state after the last
        and its checks): False where the chunk looks wrong, which its caller then runs
        again with every step's state and report."""
        nz = self.z.shape[0]
        first, seen = self._seen(oo, k, m, compact)
        bad, w_max, w_min = check[nz:nz + 3]
        env = self.envelope
        if bad or not _finite(seen) or (env is not None and (w_max > env.high
                                                             or w_min < env.low)):
            return False
        self._keep(b, seen if compact else seen[:, first::self.decimate], k, m,
                   kept[:, :m].T if self.full_rows else None, check[:nz])
        return True

    def _seen(self, oo: np.ndarray, k: int, m: int, compact: bool) -> tuple[int, np.ndarray]:
        """The first step of the chunk on the output grid, and the outputs the chunk
        computed (``compact``: those of the grid only, in the first columns)."""
        first = (-k) % self.decimate
        return first, oo[:, :len(range(first, m, self.decimate))] if compact else oo[:, :m]

    def _keep(self, b: int, grid: np.ndarray, k: int, m: int,
              full: np.ndarray | None, z_end: np.ndarray) -> None:
        """Keep run b's steps k .. k + m - 1: the outputs on the grid, the metrics' states
        (``full``, a row a step) and the state it ends at."""
        # written chunk by chunk into one array a run, read up to the grid's steps recorded
        # (a copy a chunk, stacked at the end: about 10 ns a step of the bench's sampled loop)
        if self.outs[b] is None:
            self.outs[b] = np.empty((len(range(0, self.n_steps, self.decimate)),
                                     grid.shape[0]))
        at = self.grid[b]
        self.outs[b][at:at + grid.shape[1]] = grid.T
        self.grid[b] = at + grid.shape[1]
        if full is not None:
            if self.fulls[b] is None:  # written chunk by chunk, read up to the steps run
                self.fulls[b] = np.empty((self.n_steps, len(self.full_rows)))
            self.fulls[b][k:k + m] = full
        self.steps[b] = k + m
        self.z[:, b] = z_end

    def _full(self, b: int) -> np.ndarray:
        """Run b's METRIC_STATES at the steps it ran."""
        if self.fulls[b] is None:
            return np.zeros((0, len(self.full_rows)))
        full = self.fulls[b]
        return full if self.steps[b] == len(full) else full[:self.steps[b]].copy()

    def _grid(self, b: int) -> tuple[np.ndarray, np.ndarray]:
        """Run b's times [s] and outputs on the grid, every ``decimate``-th step from 0 (as
        each chunk's steps: the same numbers)."""
        n = self.grid[b]
        t = np.arange(0, n * self.decimate, self.decimate) * self.dt
        if self.outs[b] is None:
            return t, np.zeros((0, len(self.out_names)))
        out = self.outs[b]
        return t, out if n == len(out) else out[:n].copy()

    def results(self, wall: float) -> list[Result]:
        grids = [self._grid(b) for b in range(len(self.runs))]
        return [Result(t=grids[b][0], outputs=grids[b][1],
                       z_final=self.z[:, b].copy(), diverged=self.diverged[b], wall_s=wall,
                       steps=self.steps[b], names=self.out_names,
                       z=np.vstack(self.zs[b]) if self.keep_states else None,
                       full=self._full(b) if self.full_rows else None,
                       full_names=[self.names[i] for i in self.full_rows], dt=self.dt)
                for b in range(len(self.runs))]


def _finite(a: np.ndarray) -> bool:
    """Whether every value of ``a`` is finite: a sum of finite values is finite unless it
    overflows, where the exact test decides."""
    return bool(np.isfinite(a.sum())) or bool(np.isfinite(a).all())


def _put_static(call: Buffered, loop: Loop, runs: list[Run], dt: float) -> None:
    """The inputs constant over a run, written once."""
    n_runs = len(runs)
    for b, r in enumerate(runs):
        call.put("yd", r.yd, b, n_runs)
        call.put("p_turbine", plant_params(loop, r), b, n_runs)
        call.put("cp_scale", [r.cp_scale], b, n_runs)
        call.put("p_sensors", lay.defaults("sensor_params") if r.p_sensors is None
                 else r.p_sensors, b, n_runs)
        call.put("p_ctrl", r.p_ctrl, b, n_runs)
        if loop.fdi:
            call.put("use_fdi", [float(r.use_fdi)], b, n_runs)
            call.put("p_fdi", fdi_params(loop) if r.p_fdi is None else r.p_fdi, b, n_runs)
        call.put("dt", [dt], b, n_runs)


def plant_params(loop: Loop, run: Run) -> np.ndarray:
    """The turbine parameters of ``run``'s plant: its own (model mismatch) or the loop's."""
    return np.asarray(loop.p_turbine if run.p_plant is None else run.p_plant, dtype=float)


def _nominal_inputs(loop: Loop, runs: list[Run]) -> list[dict[str, np.ndarray]]:
    """The fault inputs of a fault-free run (its plant's nominal actuator), as one column
    each, per run: built once per run_loops, not per chunk."""
    return [{"actuator_faults": nominal_actuator(plant_params(loop, r))[:, None],
             **{g: lay.defaults(g)[:, None] for g in ("sensor_faults", "fault_inputs")}}
            for r in runs]


def _noise_streams(loop: Loop, runs: list[Run], exact: bool = False,
                   ) -> list[list[np.random.Generator]]:
    """Per run, one generator per measured signal (deterministic from the run's noise
    seed, independent across signals): the draws of a signal do not depend on how the
    run is cut into chunks. None (an empty list a run) for a chunk specialised to exact
    sensors, which does not read its noise."""
    if not loop.sampled or exact:
        return [[] for _ in runs]
    return [[np.random.default_rng(np.random.SeedSequence(r.noise_seed, spawn_key=(7, k)))
             for k in range(len(sensor_names()))] for r in runs]


def _put_chunk(call: Buffered, nominal: list[dict], runs: list[Run], k: int, m: int, n_c: int,
               dt: float, loop: Loop, noise: list, held_cols: list[dict],
               exact: bool = False, window: int = 0) -> None:
    """Wind (:func:`_put_wind`); fault inputs per step, or one column held when they are
    constant over the chunk (the usual case). A sampled loop takes the sensor faults, eq
    (49)'s told fault and one noise draw per signal at each interval's start. ``held_cols``:
    per run, the held columns last computed and their time, reused while the schedules stay
    constant from then (issue 19: the schedules were most of this function's time; the same
    numbers, bit for bit). ``exact``: the chunk is specialised to exact sensors and does not
    read their faults, which are not written (a C driver's: the sampled loop's mapaccum,
    where there is no compiler, is not specialised)."""
    tk = (k + np.arange(n_c)) * dt
    faults = ("actuator_faults", "ctrl_fault") if exact else \
        ("actuator_faults", "sensor_faults", "ctrl_fault")
    n_runs = len(runs)
    _put_wind(call, runs, k, tk, dt, window)
    for b, r in enumerate(runs):
        # a run's faults constant over the chunk: one column (its own; the others' may not be)
        held = all(s is None or s.constant_between(tk[0], tk[m - 1])
                   for s in (r.schedule, r.ctrl_schedule))
        tf = tk[:1] if held else tk
        ts = tf[::loop.interval] if loop.sampled and not held else tf
        cols = _fault_columns(r, nominal[b], held_cols[b] if held else None, tf, ts)
        for name in faults:
            call.put(name, cols[name], b, n_runs, same=True)
        # a sampled loop's draws for the intervals this chunk uses, in order, and its test
        # movement: none drawn (exact sensors) and no movement leave the buffer's zeros
        if loop.sampled and noise[b]:
            used = -(-m // loop.interval)
            draws = np.zeros((len(noise[b]), n_c // loop.interval))
            draws[:, :used] = [g.standard_normal(used) for g in noise[b]]
            call.put("noise", draws, b, n_runs)
        if loop.sampled and r.test_pulse is not None and r.test_pulse[0] != 0:
            call.put("test_pulse", _pulse(r.test_pulse, tk[::loop.interval])[None, :], b,
                     n_runs)


def _put_wind(call: Buffered, runs: list[Run], k: int, tk: np.ndarray, dt: float,
              window: int) -> None:
    """Each run's wind over the chunk of steps at times ``tk`` (the first step k): its
    samples where the chunk's C driver interpolates them (wtftc.sim.drivers.WIND_INPUTS,
    room for ``window``; 0: none) and they fit, else the wind at t, t + dt/2, t + dt of
    every step (``wind3``)."""
    n_runs, t3 = len(runs), None
    for b, r in enumerate(runs):
        samples = _wind_samples(r.wind, tk[0], tk[-1] + dt, window) if window else None
        if samples is not None:
            for name, value in zip(WIND_INPUTS[:3], (k, dt, len(samples[0])), strict=True):
                call.put(name, [value], b, n_runs)
            call.put_head(WIND_INPUTS[3], samples[0], b, n_runs)
            call.put_head(WIND_INPUTS[4], samples[1], b, n_runs)
            continue
        if window:
            call.put(WIND_INPUTS[2], [0.0], b, n_runs)
        if t3 is None:
            # each step's t, t + dt/2, t + dt in a row, as the buffer lies: one evaluation
            # a run (written by stride: the broadcast sum took 6 times as long)
            t3 = np.empty(3 * tk.size)
            t3[0::3] = tk
            np.add(tk, dt / 2, out=t3[1::3])
            np.add(tk, dt, out=t3[2::3])
        w3 = np.broadcast_to(np.asarray(r.wind(t3), dtype=float), t3.shape)
        call.put("wind3", w3.reshape(-1, 3).T, b, n_runs)


def _wind_samples(wind, lo: float, hi: float, room: int,
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """The samples (times, speeds) of ``wind`` from which numpy.interp's numbers at every
    time in [lo, hi] follow, as the C drivers interpolate them: from the last at or before
    lo to the first after hi (or the ends); a constant wind as one sample. None where the
    wind is not samples or more than ``room`` are needed."""
    if type(wind) is ConstantWind:
        return np.zeros(1), np.full(1, float(wind.speed_mps))
    if type(wind) is not SampledWind or not wind.t_s.size:
        return None
    x = wind.t_s
    i = max(int(np.searchsorted(x, lo, side="right")) - 1, 0)
    j = min(int(np.searchsorted(x, hi, side="right")), x.size - 1)
    return (x[i:j + 1], wind.v_mps[i:j + 1]) if j - i + 1 <= room else None


def _fault_columns(r: Run, nominal: dict, held: dict | None, tf: np.ndarray,
                   ts: np.ndarray) -> dict[str, np.ndarray]:
    """A run's fault inputs over a chunk (plant actuators at ``tf``, sensors and eq (49)'s
    told fault at ``ts``). ``held`` (a chunk held constant): the cache of the columns last
    computed, reused while every schedule is constant from their time to ``tf[0]``."""
    s, c = r.schedule, r.ctrl_schedule
    if held is not None and "t" in held and all(
            x is None or x.constant_between(held["t"], tf[0]) for x in (s, c)):
        return held["cols"]
    told = lay.prefix("fault_inputs", of="actuator_faults")
    # a schedule without sensor faults gives the nominal rows (the layout's defaults)
    cols = {"actuator_faults": s.actuator(tf) if s else nominal["actuator_faults"],
            "sensor_faults": s.sensor(ts) if s and s.has_sensor_faults
            else nominal["sensor_faults"],
            "ctrl_fault": c.actuator(ts)[told] if c else nominal["fault_inputs"]}
    if held is not None:
        held.update(t=float(tf[0]), cols=cols)
    return cols


def _pulse(spec: tuple | None, t: np.ndarray) -> np.ndarray:
    """The test movement at the interval starts t: its amplitude during the first
    ``width`` seconds of every ``period``, else 0 (0 throughout without one)."""
    if spec is None or spec[0] == 0:
        return np.zeros(t.size)
    amplitude, period, width = spec
    # a small tolerance: an interval start on the pulse's end belongs after it
    return np.where(np.mod(t + 1e-9, period) < width, amplitude, 0.0)


def _event_steps(runs: list[Run], dt: float, every: int) -> list[int]:
    """The steps at which a lock "wherever the blade is" reads its blade's angle: its onset
    step, or in a sampled loop the start of the interval that holds it (chunks end on
    intervals)."""
    return sorted({int(round(e / dt)) // every * every for r in runs if r.schedule
                   for e in r.schedule.events()})


def _change_steps(runs: list[Run], dt: float, every: int, n_steps: int) -> list[int]:
    """Where a single run's chunks end so that none holds a change of its fault inputs
    (wtftc.model.faults.Schedule.changes): at the first step at or after each change, or
    in a sampled loop at the start of the interval that holds it and of the next one, so
    that the chunks around it pass one column (the fault inputs of a chunk holding a change
    are computed at every step). None for a batch: its runs' changes would cut every run's
    chunks, and each run is held on its own."""
    if len(runs) != 1:
        return []
    steps = set()
    for s in (runs[0].schedule, runs[0].ctrl_schedule):
        for c in s.changes() if s else []:
            k = max(0, int(np.floor(c / dt)))
            k += k * dt < c  # the first step at or after the change, as put_chunk's times
            start = k // every * every
            steps |= {start, start + every} if start != k else {k}
    return sorted(x for x in steps if 0 < x < n_steps)


def _bind_locks(runs: list[Run], k: int, dt: float, z: np.ndarray, pitch: slice,
                every: int = 1) -> None:
    """Bind "lock wherever the blade is" at its onset step (or its interval's start),
    from the current state."""
    for b, r in enumerate(runs):
        if r.schedule and k in _event_steps([r], dt, every):
            r.schedule.bind_current_angles(k * dt, z[pitch, b], dt, every)
            if r.ctrl_schedule is not None:
                r.ctrl_schedule.bind_current_angles(k * dt, z[pitch, b], dt, every)


def run_loops(loop: Loop, runs: list[Run], t_final: float, dt: float, decimate: int = 1,
              progress: bool = True, keep_states: bool = False, threads: int = 1,
              fast_math: bool = False, hook: ChunkHook | None = None,
              metric_states: bool = True, specialised: bool = True) -> list[Result]:
    """Integrate independent runs of one loop (same plant, controller, turbine, dt) together:
    each compiled chunk call advances all of them (``Function.map``).

    ``threads`` > 1: the runs are cut into that many shards, each advanced by a Python
    worker thread of its own (its own serial map and inputs): the compiled call releases
    the GIL, so one shard's Python work (wind, fault inputs, recording) overlaps the
    others' computing (issue 19: CasADi's thread map left that work serial).

    Every run gets the numbers it gets alone (the same compiled step, bit for bit); a run
    that diverges is recorded and frozen while the others go on. ``hook`` (a single run
    only): acts between chunks of ``hook.steps`` steps (see :class:`ChunkHook`).
    ``metric_states``: keep METRIC_STATES at every step (``Result.full``), which the
    metrics read; False saves their memory, and the metrics fall back to the outputs.
    ``specialised``: the chunk specialised to the controller's options where every run
    leaves them off (:func:`run_switches`; not with a hook); False: not specialised to
    them (the same numbers; exact sensors are still folded where every run has them).
    """
    if hook is not None and len(runs) != 1:
        raise ValueError("a chunk hook drives one run at a time")
    n_steps = int(round(t_final / dt))
    own = hook is None or hook.function is None  # the loop's own chunk
    exact = own and exact_sensors(loop, runs)
    f = chunk_function(loop, n=hook.steps if hook else chunk_steps(loop), fast_math=fast_math,
                       quiet=not progress, exact=exact,
                       # a hook may write any input: none is folded under one
                       switches=run_switches(loop, runs) if specialised and hook is None
                       else ()) \
        if own else hook.function
    shards = _shards(len(runs), threads)
    tracker = _Tracker(n_steps, dt, [len(s) for s in shards], progress)
    args = (loop, f, n_steps, dt, decimate, keep_states, metric_states, exact)
    if len(shards) == 1:
        batches = [_advance(*args, runs, hook, lambda k: tracker.tick(0, k))]
    else:
        batches = _in_threads(args, [[runs[i] for i in s] for s in shards], tracker)
    wall = tracker.end()
    return [r for b in batches for r in b.results(wall)]


def _shards(n_runs: int, threads: int) -> list[range]:
    """Contiguous shards of the runs, one per thread (at most one per run)."""
    n = max(1, min(threads, n_runs))
    cuts = [n_runs * i // n for i in range(n + 1)]
    return [range(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]


def _in_threads(args: tuple, shards: list[list[Run]], tracker: _Tracker) -> list[_Batch]:
    """Each shard advanced by a worker thread; their batches in shard order. The mapped
    functions are built here first (CasADi's construction is not to be raced)."""
    f = args[1]
    for s in shards:
        _mapped(f, len(s))
    out: list = [None] * len(shards)

    def work(i: int) -> None:
        try:
            out[i] = _advance(*args, shards[i], None, lambda k: tracker.tick(i, k))
        except BaseException as exc:  # noqa: BLE001 - re-raised on the calling thread
            out[i] = exc

    workers = [threading.Thread(target=work, args=(i,), daemon=True)
               for i in range(len(shards))]
    for w in workers:
        w.start()
    for w in workers:
        while w.is_alive():
            w.join(0.25)
            tracker.show()
    for o in out:
        if isinstance(o, BaseException):
            raise o
    return out


class _Tracker:
    """Progress over shards advancing at their own pace: each reports the step it reached,
    the calling thread prints (a bar on a terminal, one line at the end otherwise)."""

    def __init__(self, n_steps: int, dt: float, sizes: list[int], progress: bool):
        self.n, self.dt, self.sizes, self.progress = n_steps, dt, sizes, progress
        self.k = [0] * len(sizes)
        self.t0 = self.last = time.perf_counter()

    def tick(self, shard: int, k: int) -> None:
        self.k[shard] = k
        if len(self.sizes) == 1:
            self.show()

    def _mean_k(self) -> int:
        return sum(k * s for k, s in zip(self.k, self.sizes, strict=True)) // sum(self.sizes)

    def show(self) -> None:
        now = time.perf_counter()
        if self.progress and now - self.last > 0.5:
            _progress(self._mean_k(), self.n, self.dt, now - self.t0, runs=sum(self.sizes))
            self.last = now

    def end(self) -> float:
        wall = time.perf_counter() - self.t0
        if self.progress:
            _progress(self._mean_k(), self.n, self.dt, wall, end=True, runs=sum(self.sizes))
        return wall


def _advance(loop: Loop, f: ca.Function, n_steps: int, dt: float, decimate: int,
             keep_states: bool, metric_states: bool, exact: bool, runs: list[Run],
             hook: ChunkHook | None, tick) -> _Batch:
    """Advance ``runs`` side by side, chunk by chunk, to n_steps (or until all diverged);
    ``tick(k)`` after each chunk. ``exact``: ``f`` is specialised to exact sensors."""
    call = _take_buffer(f, len(runs))
    n_c, i_out = f.size2_out("out"), f.index_out("out")  # steps per chunk
    every = loop.interval if loop.sampled else 1
    batch = _Batch(runs, loop.state_names(),
                   [n for n, _ in output_spec(loop.controller, loop.fdi, loop.plant)],
                   np.column_stack([np.asarray(r.z0, dtype=float) for r in runs]),
                   keep_states, decimate, Envelope.of(loop))
    if metric_states:
        batch.full_rows = list(lean_rows(loop)[0])
    batch.n_steps, batch.dt = n_steps, dt
    events = _event_steps(runs, dt, every)
    cuts = sorted(set(events) | set(_change_steps(runs, dt, every, n_steps))) \
        if hook is None else events
    pitch = lay.block(PLANTS[loop.plant]["states"], "beta")
    _put_static(call, loop, runs, dt)
    nominal, noise = _nominal_inputs(loop, runs), _noise_streams(loop, runs, exact)
    held_cols: list[dict] = [{} for _ in runs]
    # a chunk with a C driver keeps only the reports on the output grid, and its lean
    # record in place of every step's state (wtftc.sim.drivers)
    driven = LEAN_INPUTS[0] in f.name_in()
    compact = driven and hook is None and decimate > 1
    lean = driven and hook is None and not keep_states and LEAN_OUTPUTS[0] in f.name_out()
    # a driver interpolating the wind's samples: room for how many
    window = f.size1_in(f.index_in(WIND_INPUTS[3])) if WIND_INPUTS[3] in f.name_in() else 0
    k = 0
    while k < n_steps and not all(batch.diverged):
        if k in events:  # a lock may bind its angle here: its columns change
            held_cols = [{} for _ in runs]
        _bind_locks(runs, k, dt, batch.z, pitch, every)
        # a hook's chunks end on multiples of its interval, whatever events cut them
        end = (k // n_c + 1) * n_c if hook is not None else k + n_c
        stop = min([n_steps, end] + [e for e in cuts if e > k])
        _put_chunk(call, nominal, runs, k, stop - k, n_c, dt, loop, noise, held_cols,
                   exact and driven, window)
        call.put("z", batch.z)
        if driven:
            _driver_modes(call, decimate if compact else 1,
                          (-k) % decimate if compact else 0, stop - k, lean)
        if hook is not None:
            hook.before(call, k, stop)
        res = _record_chunk(call, batch, loop, i_out, k, stop, dt, compact, lean)
        if hook is not None and not batch.diverged[0]:
            hook.after(k, stop, batch.z[:, 0], res, batch.out_names)
        k = stop
        tick(k)
    if call.nbytes() <= HELD_BYTES:
        _BUFFERS.held = (f, len(runs), call)
    return batch


#: per thread, the Buffered it last ran a chunk function through: (f, runs, Buffered)
_BUFFERS = threading.local()
#: the largest Buffered kept for the next run (its arrays' bytes, touched or not): a large
#: batch's buffers are let go with it
HELD_BYTES = 64 << 20


def _take_buffer(f: ca.Function, n_runs: int) -> Buffered:
    """``f`` mapped over n_runs in a Buffered whose inputs read zero: the one this thread
    last ran them through (:meth:`Buffered.reset`), or a new one. (A new one cost 136-235
    µs a run, most of it the first touch of its megabytes.) Taken, it is this caller's
    alone until it is held again."""
    held = getattr(_BUFFERS, "held", None)
    if held is not None and held[0] is f and held[1] == n_runs:
        _BUFFERS.held = None
        held[2].reset()
        return held[2]
    return Buffered(_mapped(f, n_runs))


def _driver_modes(call: Buffered, every: int, first: int, used: int, lean: bool) -> None:
    """A C driver's REPORT_INPUTS and LEAN_INPUTS: the report of every ``every``-th step from
    step ``first`` of the chunk (1, 0: every step's), its first ``used`` steps run, and
    the lean record in place of every step's state (``lean``)."""
    for name, value in zip(REPORT_INPUTS + LEAN_INPUTS, (every, first, used, lean),
                           strict=True):
        call.fill(name, float(value))


def _record_chunk(call: Buffered, batch: _Batch, loop: Loop, i_out: int, k: int, stop: int,
                  dt: float, compact: bool, lean: bool = False) -> list[np.ndarray]:
    """Evaluate the chunk (steps k .. stop - 1) and record every live run; where a compact
    or lean chunk (the reports on the output grid only; the lean record in place of every
    step's state) looks wrong for a run, evaluate it again with every step's report and
    state (the same states, bit for bit: the inputs are as they were) and record from
    there. The chunk's results."""
    res, n_c, b = call.evaluate(), call.f.size2_out(i_out) // len(batch.runs), 0
    i_kept = call.f.index_out(LEAN_OUTPUTS[0]) if lean else -1
    while b < len(batch.runs):
        # a sampled chunk's states after every plant step are its third output
        zz_all, oo_all = res[2] if loop.sampled else res[0], res[i_out]
        cols = slice(b * n_c, b * n_c + stop - k)  # views, valid until the next call
        if batch.diverged[b]:
            fine = True
        elif lean:
            fine = batch.record_lean(b, res[i_kept][:, cols], res[i_kept + 1][:, b],
                                     oo_all[:, cols], k, stop - k, dt, compact)
        else:
            fine = batch.record(b, zz_all[:, cols], oo_all[:, cols], k, stop - k, dt, compact)
        if not fine:
            _driver_modes(call, 1, 0, stop - k, False)
            res, compact, lean = call.evaluate(), False, False
            continue
        b += 1
    return res


def divergence(zz: np.ndarray, oo: np.ndarray, z_prev: np.ndarray, names: list[str],
               out_names: list[str], k: int, dt: float,
               envelope: Envelope | None = None) -> tuple[int, dict]:
    """The first step of a chunk that blew up, and its record.

    Column i of zz is the state after step k + i, column i of oo the outputs at the state
    before it (z_prev for i = 0). Step i is bad when that state is non-finite or beyond
    1e8, or when the outputs at its start are non-finite (the control law can fail before
    any state does: a state that is still finite then carries the NaN into the next step).
    A rotor leaving the ``envelope`` ends the run too (lost: run away or stalled). The record
    names every quantity that failed, the time at the end of the step, and the last finite
    state.
    """
    bad = ~np.all(np.isfinite(oo), axis=0) | ~np.all(np.isfinite(zz), axis=0)
    bad |= np.any(np.abs(zz) > 1e8, axis=0)
    left = envelope.outside(zz) if envelope is not None else np.zeros(zz.shape[1], bool)
    bad |= left
    i = int(np.argmax(bad))
    blew = [n for n, a in zip(names, zz[:, i], strict=True)
            if not np.isfinite(a) or abs(a) > 1e8]
    nan_out = [n for n, a in zip(out_names, oo[:, i], strict=True) if not np.isfinite(a)]
    parts = []
    if blew:
        parts.append("non-finite or |state| > 1e8 in " + ", ".join(blew[:8])
                     + (" ..." if len(blew) > 8 else ""))
    if nan_out:
        parts.append("non-finite outputs " + ", ".join(nan_out[:8])
                     + (" ..." if len(nan_out) > 8 else ""))
    if left[i] and not parts:
        parts.append(envelope.reason(float(zz[envelope.row, i])))
    before = zz[:, i - 1] if i > 0 else z_prev
    return i, {"t_s": float((k + i + 1) * dt), "reason": "; ".join(parts),
               "last_finite_state": {n: float(a) for n, a in zip(names, before, strict=True)}}

def _progress(k: int, n: int, dt: float, wall: float, end: bool = False, runs: int = 1,
              ) -> None:
    """A progress bar on a terminal; one summary line when stderr is a file or a pipe.
    ``runs``: a batch advancing that many runs together (the rate counts all of them)."""
    rate = runs * k * dt / max(wall, 1e-9)
    what = f"{runs} runs × " if runs > 1 else ""
    if not sys.stderr.isatty():
        if end:
            print(f"    {what}{k * dt:.1f} s simulated in {wall:.1f} s ({rate:.0f}× real time)",
                  file=sys.stderr, flush=True)
        return
    width = 30
    done = int(width * k / max(n, 1))
    print(f"\r    [{'#' * done}{'.' * (width - done)}] {what}{k * dt:7.1f}/{n * dt:.1f} s "
          f"simulated, {rate:6.0f}× real time", end="\n" if end else "", file=sys.stderr,
          flush=True)
