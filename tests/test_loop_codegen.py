"""The loop chunk's code generation (issue 19): what it changes for speed leaves every
number as it was."""

import os
import platform
import struct
import subprocess
from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from wtftc import config
from wtftc.artefacts.loader import compiled_external, compiler
from wtftc.campaign import cases
from wtftc.sim import integrate

SPECIAL = [0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 1e-310, -3.5, 2.0**1023]


def _bits(x: float) -> int:
    return struct.unpack("<q", struct.pack("<d", x))[0]


def test_inlined_min_and_max_are_libms_for_every_pair_of_special_doubles(tmp_path):
    """The inlined helpers (INLINE_MINMAX) against the same function compiled as CasADi
    writes it, calling the C library's fmin and fmax: the same bits for signed zeros,
    infinities, NaN (either side), subnormals, on every ordered pair. (CasADi's virtual
    machine is not the reference here: it gives +0 for max(0, -0) where libm gives -0.)"""
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    f = ca.Function("wtftc_test_minmax_inlined", [x, y], [ca.fmax(x, y), ca.fmin(x, y)])
    text = integrate.loop_source(f, tmp_path, "inlined").read_text()
    x86 = platform.machine() in ("x86_64", "AMD64")  # inlined there only
    assert ("return fmax(x, y);" not in text and "return fmin(x, y);" not in text) == x86
    inlined = integrate.compiled(f, "wtftc_test_minmax_inlined", quiet=True)
    g = ca.Function("wtftc_test_minmax_libm", [x, y], [ca.fmax(x, y), ca.fmin(x, y)])
    cg = ca.CodeGenerator("libm_minmax.c", {"with_header": False})
    cg.add(g)
    cg.generate(str(tmp_path) + "/")
    assert "return fmax(x, y);" in (tmp_path / "libm_minmax.c").read_text()
    libm = compiled_external(g.name(), tmp_path / "libm_minmax.c", integrate.loop_flags())
    assert inlined.is_a("External") and libm.is_a("External")
    for a in SPECIAL:
        for b in SPECIAL:
            got = [float(v) for v in inlined(a, b)]
            want = [float(v) for v in libm(a, b)]
            assert [_bits(v) for v in got] == [_bits(v) for v in want], (a, b, got, want)


def test_the_rk4_step_shares_work_across_its_stages():
    """The step in SX with common subexpressions shared: fewer operations than four
    evaluations of the right-hand side, the same numbers (the loop tests below)."""
    from wtftc.sim.rhs import rhs_function

    loop = config.make_config({"controller": "physical", "case": 3}).loop
    rhs = rhs_function(loop)
    step = integrate.rk4_step(rhs)
    assert step.is_a("SXFunction")
    assert step.n_instructions() < 4 * rhs.expand().n_instructions()


def _runs(raw: dict, exact: bool, monkeypatch) -> list:
    monkeypatch.setattr(integrate, "exact_sensors", lambda loop, runs: exact)
    return cases.run(config.make_config(raw), progress=False)


@pytest.mark.parametrize("raw", [
    {"controller": "physical", "case": 4, "t_final_s": 25.0,
     "fault": [{"type": "lock", "blade": 1, "onset_s": 12.31},
               {"type": "loss_of_effectiveness", "blade": 3, "rho": 0.5, "onset_s": 6.0}]},
    {"controller": "paper", "case": 3, "t_final_s": 25.0, "plant": "tower"},
    # sampled: the sensors' lags, noise and faults folded away, no noise drawn
    {"controller": "physical", "case": 4, "t_final_s": 25.0, "control_interval_s": 0.01,
     "fault": [{"type": "lock", "blade": 2, "onset_s": 8.0}]},
])
def test_the_chunk_specialised_for_exact_sensors_gives_the_general_ones_numbers(
        raw, monkeypatch):
    """Exact sensors and no sensor fault: the specialised chunk (their inputs folded to
    the layout's defaults) and the general one, bit for bit, FDI monitor included."""
    fast = _runs(raw, True, monkeypatch)
    general = _runs(raw, False, monkeypatch)
    np.testing.assert_array_equal(fast.outputs, general.outputs)
    np.testing.assert_array_equal(fast.z_final, general.z_final)


def test_the_specialised_chunk_is_chosen_only_where_it_is_exact():
    def inputs(raw):
        rc = config.make_config({"controller": "physical", "case": 2, "t_final_s": 30.0,
                                 **raw})
        return rc.loop, cases._prepare(rc)[0]

    loop, run = inputs({})
    assert integrate.exact_sensors(loop, [run])
    noisy = inputs({"sensors": {"pitch_bias_deg": 0.1}})
    assert not integrate.exact_sensors(noisy[0], [run, noisy[1]])
    faulty = inputs({"fault": [{"type": "rotor_speed_sensor_offset", "sensor": 2,
                                "onset_s": 5.0}]})
    assert not integrate.exact_sensors(faulty[0], [run, faulty[1]])
    realistic = inputs({"profile": "realistic"})  # noisy sensors
    assert not integrate.exact_sensors(*realistic[:1], [realistic[1]])
    exact_sampled = inputs({"control_interval_s": 0.01})
    assert exact_sampled[0].sampled
    assert integrate.exact_sensors(*exact_sampled[:1], [exact_sampled[1]])


def test_a_held_column_is_written_again_once_another_one_was():
    """Buffered.put(same=True) skips only the very object it last wrote there."""
    u = ca.SX.sym("u", 2)
    call = integrate.Buffered(ca.Function("f", [u], [2 * u]).map(3))
    held, other = np.array([1.0, 2.0]), np.array([[5.0, 6.0, 7.0], [0.0, 0.0, 0.0]])
    call.put("i0", held, same=True)
    assert call.evaluate()[0][0].tolist() == [2.0, 2.0, 2.0]
    call.put("i0", other)
    call.put("i0", held, same=True)  # the held object again, after another one
    assert call.evaluate()[0][0].tolist() == [2.0, 2.0, 2.0]


def test_the_fast_math_chunk_leaves_the_process_denormals_alone():
    """The opt-in -ffast-math chunk (FAST_MATH_CFLAGS) is built without crtfastmath.o,
    whose constructor turned on flush-to-zero for the whole process once it was loaded:
    every later computation, numpy's and the default chunks' included, then lost its
    subnormals (found when this file's min/max test failed after the bench's fast-math
    test in the same session)."""
    tiny = np.array([1e-310])
    assert (tiny * 1.0)[0] != 0.0
    loop = config.make_config({"controller": "physical", "case": 3}).loop
    f = integrate.chunk_function(loop, n=10, fast_math=True, quiet=True)
    assert f.is_a("External")
    assert (tiny * 1.0)[0] != 0.0


def test_loop_flags_follow_the_cpu_and_never_contract(monkeypatch):
    """-ffp-contract=off on every target (aarch64's gcc fuses a*b + c by default, which
    would part the chunks from CasADi's virtual machine); x86-64-v3 only on a CPU that
    lists all its instructions (here: read from /proc/cpuinfo) and with a compiler that
    takes the flag (an older gcc, or a CC that refuses it, builds for the baseline)."""
    integrate.arch_flags.cache_clear()
    monkeypatch.setattr(platform, "machine", lambda: "aarch64")
    assert integrate.arch_flags() == ("-ffp-contract=off",)
    integrate.arch_flags.cache_clear()
    monkeypatch.undo()
    flags = integrate.loop_flags()
    assert "-ffp-contract=off" in flags and flags[-2:] == ("-fPIC", "-shared")
    cpu = Path("/proc/cpuinfo").read_text() if Path("/proc/cpuinfo").exists() else ""
    line = next((x for x in cpu.splitlines() if x.startswith("flags")), "")
    has_v3 = integrate.X86_64_V3 <= set(line.split())
    cc = compiler()
    takes = cc is not None and subprocess.run(
        [cc, "-march=x86-64-v3", "-x", "c", "-c", os.devnull, "-o", os.devnull],
        capture_output=True).returncode == 0
    assert ("-march=x86-64-v3" in flags) == (has_v3 and takes)


@pytest.mark.parametrize("raw", [
    {"controller": "physical", "case": 4, "profile": "realistic", "t_final_s": 12.0,
     "fault": [{"type": "lock", "blade": 1, "onset_s": 6.31},
               {"type": "pitch_sensor_offset", "blade": 2, "onset_s": 3.0}]},
    {"controller": "paper", "case": 3, "control_interval_s": 0.01, "control_delay": True,
     "t_final_s": 12.0, "plant": "tower",
     "fault": [{"type": "loss_of_effectiveness", "blade": 3, "rho": 0.5, "onset_s": 5.0}]},
    {"controller": "pi", "case": 2, "t_final_s": 12.0,
     "fault": [{"type": "rotor_speed_sensor_gain", "sensor": 1, "onset_s": 4.0}]},
])
def test_the_c_drivers_are_mapaccum_bit_for_bit(raw, monkeypatch):
    """The chunks' C drivers (wtftc.sim.drivers: the sampled loop's intervals, the
    continuous loop's steps) against the same functions chained by CasADi's mapaccum,
    both compiled: a realistic (noisy, sampled, FDI) run with a lock and a sensor fault,
    a sampled run with the command delayed on the tower, a continuous run with a speed
    sensor's fault; the drivers' lean record (wtftc.sim.drivers.LEAN_OUTPUTS) against
    the states of every step that mapaccum gives."""
    rc = config.make_config(raw)
    integrate.chunk_function.cache_clear()
    driven = cases.run(rc, progress=False)

    def mapaccum(fns, driver, label, flags, quiet, fallback):
        return integrate._compile_function(fallback(), f"{label}_mapaccum", flags, quiet)

    monkeypatch.setattr(integrate, "_driven", mapaccum)
    integrate.chunk_function.cache_clear()
    try:
        chained = cases.run(rc, progress=False)
    finally:
        integrate.chunk_function.cache_clear()
    assert driven.diverged is None
    np.testing.assert_array_equal(driven.outputs, chained.outputs)
    np.testing.assert_array_equal(driven.z_final, chained.z_final)
    # the metrics' states at every step: the drivers' lean record against mapaccum's states
    assert driven.every_step and driven.full.shape == chained.full.shape
    np.testing.assert_array_equal(driven.full, chained.full)


def test_the_stage_shared_step_and_four_calls_of_the_rhs_agree_bit_for_bit(monkeypatch):
    """rk4_step's two forms (SX with the stages' common work shared, as loops without the
    FDI run; four calls of the right-hand side, as loops with it run): the same numbers,
    on the bench's paper loop (case 3 fault, no FDI), 25 s at 2 ms."""
    from bench import runner
    from bench.problem import LOOPS, Problem

    p = Problem("paper_case3", *LOOPS["paper_case3"], t_final=25.0)
    orig = integrate.rk4_step
    results = []
    for shared in (True, False):
        monkeypatch.setattr(integrate, "rk4_step",
                            lambda *a, shared=shared, **k: orig(*a, **{**k, "shared": shared}))
        integrate.chunk_function.cache_clear()
        results.append(runner.rk4_default(p, 2e-3, 25.0))
    integrate.chunk_function.cache_clear()
    np.testing.assert_array_equal(results[0].outputs, results[1].outputs)
    assert results[0].diverged is None


def _actuator(minimise: bool, monkeypatch) -> ca.Function:
    """The benchmark actuator's [β̇, β̈] (derivation/turbine.py) translated to SX, its
    conditions minimised or as SymPy writes them."""
    import sympy as sp

    from derivation import casadi_build, turbine

    if not minimise:
        monkeypatch.setattr(casadi_build, "minimal_logic", lambda c: c)
    names = "b w u wn zt bmin bmax rmax"
    syms = sp.symbols(names, real=True)
    x = ca.SX.sym("x", len(syms))
    tr = casadi_build.Translator({s.name: x[i] for i, s in enumerate(syms)})
    out = ca.vertcat(*[tr(e) for e in turbine.limited_actuator(*syms)])
    monkeypatch.undo()
    return ca.Function("actuator", [x], [out])


def test_minimised_conditions_are_the_same_truth_function(monkeypatch):
    """minimal_logic (derivation/casadi_build.py): SymPy's conjunctive form of the
    actuator's limits (four clauses, seven logical operations) becomes the two-term sum it
    means, and the translated actuator gives the same bits on every combination of values
    at, inside and outside its limits, signed zeros, infinities and NaN included."""
    import itertools

    import sympy as sp

    from derivation.casadi_build import minimal_logic

    a, b, c, d = sp.symbols("a b c d", real=True)
    cnf = (((a >= 1) | (b <= 0)) & ((a >= 1) | (c < 0)) & ((b <= 0) | (c > 0))
           & ((c > 0) | (c < 0)))
    small = minimal_logic(cnf)
    assert sp.count_ops(small) < sp.count_ops(cnf)
    atoms = sorted(cnf.atoms(sp.core.relational.Relational), key=sp.default_sort_key)
    for values in itertools.product([False, True], repeat=len(atoms)):
        truth = dict(zip(atoms, map(sp.S, values), strict=True))
        assert bool(cnf.xreplace(truth)) == bool(small.xreplace(truth))
    f, g = _actuator(True, monkeypatch), _actuator(False, monkeypatch)
    assert f.n_instructions() < g.n_instructions()
    pitch = [-0.1, 0.0, -0.0, 0.5, np.pi / 2, 1.6, np.nan]
    rate = [-0.2, -0.14, -0.0, 0.0, 0.14, 0.2, np.inf, -np.inf, np.nan]
    command = [-1.0, 0.0, 0.3, 1.6, np.nan]
    for b_, w_, u_ in itertools.product(pitch, rate, command):
        point = [b_, w_, u_, 11.1, 0.6, 0.0, np.pi / 2, 0.14]
        x, y = np.array(f(point)).ravel(), np.array(g(point)).ravel()
        assert [_bits(v) for v in x] == [_bits(v) for v in y], point


def _divisions(f: ca.Function) -> int:
    return sum(f.instruction_id(k) == ca.OP_DIV for k in range(f.n_instructions()))


def test_shared_reciprocals_replace_divisions_by_what_a_step_holds():
    """wtftc.sim.reciprocals: x/d with d held over the step becomes x·(1/d), 1/d from a
    call CasADi does not fold back into a division; a d used otherwise too keeps its
    divisions; a d that changes within the step (the state, the wind) is left alone."""
    from wtftc.sim.reciprocals import with_shared_reciprocals

    x, w, p, q = (ca.SX.sym(n) for n in "xwpq")
    f = ca.Function("f", [x, w, p, q],
                    [ca.vertcat(x / p, w / p, x / (2 * p), x / q, x * q, x / w)],
                    ["z", "wind", "p", "q"], ["o"])
    g = with_shared_reciprocals(f, ("z", "wind"))
    # x/p, w/p: one reciprocal of p, x/(2p) one of 2p; x/q keeps its division (q is also
    # multiplied); x/w is by the wind
    assert _divisions(f) == 5 and _divisions(g) == 2
    assert sum(g.instruction_id(k) == ca.OP_CALL for k in range(g.n_instructions())) == 2
    point = [0.7, 1.3, 3.0, 0.1]
    np.testing.assert_allclose(np.array(g(*point)), np.array(f(*point)), rtol=4e-16, atol=0)
    # the Jacobian through the call (the stability check and linearize take it)
    args = [ca.SX.sym(n) for n in "xwpq"]
    jg = ca.Function("jg", args, [ca.jacobian(g(*args), ca.vertcat(*args))])
    jf = ca.Function("jf", args, [ca.jacobian(f(*args), ca.vertcat(*args))])
    np.testing.assert_allclose(np.array(jg(*point)), np.array(jf(*point)), rtol=1e-14)


def test_the_loops_divide_less_and_compute_the_same_to_rounding():
    """The physical AFTC's right-hand side: 51 divisions a stage before, 30 with the
    shared reciprocals; ż the same to a few ulps at random states (the compiled chunk is
    still the virtual machine's to rounding: tests/test_bench.py)."""
    from dataclasses import replace

    from wtftc.sim.rhs import _closed_loop_rhs, rhs_function

    rc = config.make_config({"controller": "physical"})
    loop = replace(rc.loop, fdi=False)
    before, after = _closed_loop_rhs(loop), rhs_function(loop)
    assert _divisions(after) <= _divisions(before) - 20
    rng = np.random.default_rng(4)
    for _ in range(20):
        vals = [rng.uniform(0.5, 1.5, before.nnz_in(i)) for i in range(before.n_in())]
        vals[before.index_in("p_turbine")] = np.asarray(loop.p_turbine)
        vals[before.index_in("p_ctrl")] = np.asarray(rc.p_ctrl)
        a, b = before(*vals)[0], after(*vals)[0]
        np.testing.assert_allclose(np.array(b), np.array(a), rtol=1e-14, atol=1e-300)


def test_the_steps_driver_keeps_the_reports_asked_for():
    """REPORT_INPUTS: every 4th step's report from step 1 lands in the report's first
    columns, the same bits as that step's report when every step's is kept; the states of
    every step as before. LEAN_INPUTS: the first 600 steps run, their lean record the
    same bits as the states of every step."""
    from dataclasses import replace

    from bench import runner
    from bench.problem import LOOPS, Problem

    p = Problem("physical_case3", *LOOPS["physical_case3"])
    loop = replace(p.config.loop, fdi=False)
    f = integrate.chunk_function(loop, n=1000, quiet=True, exact=True)
    assert f.name_in()[-9:] == list(integrate.REPORT_INPUTS + integrate.LEAN_INPUTS
                                    + integrate.WIND_INPUTS)
    w3, af, sf, ck = runner.step_inputs(p, 0.001, 1000)
    args = dict(z=p.z0, wind3=w3, actuator_faults=af, sensor_faults=sf, ctrl_fault=ck,
                yd=p.yd, p_turbine=loop.p_turbine, p_ctrl=p.config.p_ctrl, cp_scale=1.0,
                dt=0.001)
    call = integrate.Buffered(f)
    for name, value in args.items():
        call.put(name, value)
    z_all, o_all, _, _ = (a.copy() for a in call.evaluate())
    integrate._driver_modes(call, 4, 1, 1000, False)
    z_some, o_some, _, _ = call.evaluate()
    np.testing.assert_array_equal(z_some, z_all)
    np.testing.assert_array_equal(o_some[:, :250], o_all[:, 1::4])
    # the lean record of the first 600 steps: the metrics' rows of the state before each
    # step, the state after the last, nothing out of bounds, the rotor speed's extremes
    integrate._driver_modes(call, 4, 1, 600, True)
    _, _, kept, check = call.evaluate()
    rows, watch = integrate.lean_rows(loop)
    before = np.hstack([p.z0[:, None], z_all[:, :599]])
    np.testing.assert_array_equal(kept[:, :600], before[list(rows)])
    nz = len(p.z0)
    np.testing.assert_array_equal(check[:nz, 0], z_all[:, 599])
    assert list(check[nz:, 0]) == [0.0, z_all[watch, :600].max(), z_all[watch, :600].min()]


@pytest.mark.parametrize("raw", [
    "diverging",  # blows up (tests/conftest.py)
    {"control_sign": 1, "t_final_s": 12.0, "output_rate_hz": 50.0,  # stalls: envelope
     "turbine_params": {"gen_torque_law": 0.0}},
    {"controller": "physical", "t_final_s": 25.0, "case": 3},  # runs through
])
def test_runs_keeping_only_their_output_grid_are_the_runs_keeping_every_report(raw,
                                                                              monkeypatch):
    """The default chunk keeps the reports of the output grid only; a chunk that looks
    wrong is run again with every step's report, so that a divergence is found at the
    same step with the same record: the same outputs, times, final state and divergence
    as the chunk keeping every report."""
    from conftest import DIVERGING_RUN

    rc = config.make_config(DIVERGING_RUN if raw == "diverging" else raw)
    assert rc.decimate > 1
    compact = cases.run(rc, progress=False)
    monkeypatch.setattr(integrate, "LEAN_INPUTS", ("not_an_input", "not_an_input"))
    full = cases.run(rc, progress=False)
    np.testing.assert_array_equal(compact.outputs, full.outputs)
    np.testing.assert_array_equal(compact.t, full.t)
    np.testing.assert_array_equal(compact.z_final, full.z_final)
    assert compact.diverged == full.diverged
    assert (compact.diverged is None) == (raw not in ("diverging",) and "control_sign" not in
                                          str(raw))


def test_a_small_step_gets_a_state_only_twin_and_a_large_one_does_not():
    """integrate._state_step: the physical loop's step (4,744 SX instructions) gets a twin
    computing the next state alone, for the steps whose report is not kept, and it gives
    the step's next state bit for bit; the paper's (9,600: two bodies alternating cost it
    instruction fetch) and a step in MX do not."""
    from dataclasses import replace

    from bench.problem import LOOPS, Problem
    from wtftc.sim.rhs import rhs_function

    steps = {}
    for name in ("physical_case3", "paper_case3"):
        loop = replace(Problem(name, *LOOPS[name]).config.loop, fdi=False)
        steps[name] = integrate.rk4_step(rhs_function(loop))
    twin = integrate._state_step(steps["physical_case3"])
    assert twin is not None and twin.n_out() == 1
    assert twin.n_instructions() < steps["physical_case3"].n_instructions()
    assert integrate._state_step(steps["paper_case3"]) is None
    assert integrate._state_step(integrate.rk4_step(rhs_function(
        replace(Problem("physical_case3", "physical", "nrel5mw").config.loop, fdi=False)),
        shared=False)) is None
    rng = np.random.default_rng(5)
    step = steps["physical_case3"]
    for _ in range(5):
        vals = [rng.uniform(0.5, 1.5, step.nnz_in(i)) for i in range(step.n_in())]
        np.testing.assert_array_equal(np.array(twin(*vals)), np.array(step(*vals)[0]))


def test_branch_free_selects_are_casadis_selects_bit_for_bit(tmp_path):
    """integrate.SELECT: CasADi's ``(c?x:0)`` written as a mask gives CasADi's bits on
    every pair of special doubles (c: zero of either sign, NaN, infinities, subnormals;
    x the same), against CasADi's own C; the loops' code has them (the physical loop's
    rate limits and anti-windup)."""
    c, x = ca.SX.sym("c"), ca.SX.sym("x")
    f = ca.Function("wtftc_test_select", [c, x], [ca.if_else(c, x, 0)])
    text = integrate.loop_source(f, tmp_path, "select").read_text()
    assert "wtftc_select(" in text and "?" not in text.split("wtftc_select(")[-1]
    masked = integrate.compiled(f, "wtftc_test_select", quiet=True)
    cg = ca.CodeGenerator("own_select.c", {"with_header": False})
    cg.add(f)
    cg.generate(str(tmp_path) + "/")
    assert "?" in (tmp_path / "own_select.c").read_text()
    own = compiled_external(f.name(), tmp_path / "own_select.c", integrate.loop_flags())
    for a in SPECIAL:
        for b in SPECIAL:
            assert _bits(float(masked(a, b))) == _bits(float(own(a, b))), (a, b)


def test_minimal_logic_keeps_what_sympy_would_rewrite_on_the_way_back():
    """Where SymPy's constructors would rewrite the minimised form's comparisons (a
    complementary pair folded to true, a negation turned into the opposite comparison:
    not the same for NaN), or the form is a constant, the condition is kept as written."""
    import sympy as sp

    from derivation.casadi_build import minimal_logic

    x, y = sp.symbols("x y", real=True)
    folded = ((x <= 0) & (y > 1)) | ((x > 0) & (y > 1))  # would become y > 1
    assert minimal_logic(folded) == folded
    negated = ~((y > 0) | ((x > 0) & (y > 0)))  # would become y <= 0
    got = minimal_logic(negated)
    assert got.atoms(sp.core.relational.Relational) <= negated.atoms(
        sp.core.relational.Relational)


def test_shared_reciprocals_leave_a_function_with_a_sparse_input_alone():
    from wtftc.sim.reciprocals import with_shared_reciprocals

    x = ca.SX.sym("x")
    p = ca.SX.sym("p", ca.Sparsity.triplet(3, 1, [0, 2], [0, 0]))
    f = ca.Function("f", [x, p], [x / p[0] + x * p[2]], ["z", "p"], ["o"])
    assert with_shared_reciprocals(f, ("z",)) is f


def test_a_single_runs_chunks_end_around_its_fault_changes():
    """integrate._change_steps: the first step at or after each change (onset, the ramp's
    end, the fault's end), or in a sampled loop the interval that holds it and the next;
    none for a batch, whose runs are held each on its own."""
    from wtftc.model.faults import Fault, Schedule

    s = Schedule([Fault(blade=1, type="loss_of_effectiveness", onset_s=6.31, end_s=9.0,
                        ramp_s=0.5, rho=0.5)])
    assert s.changes() == [6.31, 6.81, 8.5, 9.0]
    run = integrate.Run(np.zeros(1), lambda t: t, s)
    # dt = 0.01: 6.31 / 0.01 is 630.999..., the step at or after it is 631
    assert integrate._change_steps([run], 0.01, 1, 10_000) == [631, 681, 850, 900]
    # intervals of 20 steps: 631 is in the one from 620, 681 in the one from 680
    assert integrate._change_steps([run], 0.01, 20, 10_000) == [620, 640, 680, 700, 840,
                                                                860, 900]
    assert integrate._change_steps([run], 0.01, 1, 700) == [631, 681]
    assert integrate._change_steps([run, run], 0.01, 1, 10_000) == []


@pytest.mark.parametrize("raw", [
    {"controller": "physical", "case": 4, "profile": "realistic", "t_final_s": 12.0,
     "fault": [{"type": "loss_of_effectiveness", "blade": 2, "rho": 0.4, "onset_s": 3.317,
                "ramp_s": 1.2, "end_s": 9.9},
               {"type": "pitch_sensor_offset", "blade": 2, "onset_s": 5.005}]},
    {"controller": "pi", "case": 2, "t_final_s": 12.0,
     "fault": [{"type": "lock", "blade": 3, "onset_s": 4.0004}]},
])
def test_chunks_cut_at_fault_changes_give_the_uncut_runs_numbers(raw, monkeypatch):
    """A run whose chunks end around its fault changes (each chunk's faults then one
    column) against the same run cut only every chunk's length: outputs, the metrics'
    states and the final state, in raw bits."""
    rc = config.make_config(raw)
    cut = cases.run(rc, progress=False)
    monkeypatch.setattr(integrate, "_change_steps", lambda *a: [])
    uncut = cases.run(rc, progress=False)
    assert cut.diverged is None and cut.steps == uncut.steps
    for name in ("outputs", "full", "z_final"):
        a, b = getattr(cut, name), getattr(uncut, name)
        np.testing.assert_array_equal(a.view(np.uint64), b.view(np.uint64), err_msg=name)


@pytest.mark.parametrize("fast_math", [False, True])
def test_the_lean_check_flags_a_nan_state_whatever_the_flags(fast_math):
    """The drivers' check of every state after every step (drivers._BEYOND) on its bits: a
    NaN state is flagged in the default chunk and in the fast-math one, where
    -ffinite-math-only would turn a floating-point comparison into one a NaN passes; the
    rotor speed still in its bounds."""
    from dataclasses import replace

    from bench.problem import LOOPS, Problem

    p = Problem("physical_case3", *LOOPS["physical_case3"])
    loop = replace(p.config.loop, fdi=False)
    f = integrate.chunk_function(loop, n=1000, quiet=True, exact=True, fast_math=fast_math)
    call = integrate.Buffered(f)
    w3, af, sf, ck = __import__("bench.runner", fromlist=["x"]).step_inputs(p, 0.001, 1000)
    for name, value in dict(wind3=w3, actuator_faults=af, sensor_faults=sf, ctrl_fault=ck,
                            yd=p.yd, p_turbine=loop.p_turbine, p_ctrl=p.config.p_ctrl,
                            cp_scale=1.0, dt=0.001).items():
        call.put(name, value)
    nz, (_, watch) = len(p.z0), integrate.lean_rows(loop)
    for z0, bad in ((p.z0, 0.0), (np.where(np.arange(nz) == nz - 1, np.nan, p.z0), 1.0)):
        call.put("z", z0)
        integrate._driver_modes(call, 10, 0, 5, True)
        check = call.evaluate()[3][:, 0]
        assert check[nz] == bad
        assert np.isfinite(check[watch]) and np.isfinite(check[nz + 1:]).all()


def _winds(dt: float) -> dict:
    """Winds for the drivers' interpolation: samples every 25 steps from 0.5 s to 9 s, some
    on a step's time, some on its midpoint (numpy.interp's exact hits), held outside them;
    samples a third of a step apart (too many for a chunk's window: wind3 from Python); a
    constant wind (one sample)."""
    from wtftc.model.wind import ConstantWind, SampledWind

    k = np.arange(250, 4500, 25)
    t = np.sort(np.concatenate([k * dt, (k[::3] + 12) * dt + dt / 2]))
    v = np.random.default_rng(5).uniform(8.0, 20.0, t.size)
    fine = np.arange(0.0, 12.0, dt / 3)
    return {"samples": SampledWind("file", t, v, parameters={}),
            "finer than a step": SampledWind("file", fine, 14.0 + np.sin(fine),
                                             parameters={}),
            "constant": ConstantWind(14.0, parameters={})}


@pytest.mark.parametrize("interval", [None, 0.01])
def test_the_drivers_interpolate_the_winds_samples_as_numpy_does(interval, monkeypatch):
    """The C drivers' wind from its samples (wtftc.sim.drivers.WIND_INPUTS) against
    numpy.interp's in Python (``wind3``), continuous and sampled: outputs, the metrics'
    states and the final state in raw bits, for samples with exact hits and held ends, for
    samples too fine for the chunk's window (which take Python's) and for a constant
    wind."""
    raw = {"controller": "physical", "case": 4, "t_final_s": 12.0,
           "fault": [{"type": "lock", "blade": 2, "onset_s": 5.0}],
           **({"control_interval_s": interval} if interval else {})}
    rc = config.make_config(raw)
    run = cases._prepare(rc, check=False)[0]
    for name, wind in _winds(rc.dt).items():
        one = replace(run, wind=wind)
        room = integrate.chunk_function(rc.loop).size1_in(integrate.WIND_INPUTS[3])
        in_c = integrate._wind_samples(wind, 0.0, 7.0, room) is not None
        assert in_c == (name != "finer than a step")
        with monkeypatch.context() as m:
            if name == "samples":  # the chunks as they are used: none on a fault change
                m.setattr(integrate, "_change_steps", lambda *a: [])
            c = integrate.run_loops(rc.loop, [one], 12.0, rc.dt, progress=False)[0]
            m.setattr(integrate, "WIND_INPUTS", ("none",) * 5)
            py = integrate.run_loops(rc.loop, [one], 12.0, rc.dt, progress=False)[0]
        assert c.diverged is None and c.steps == py.steps
        for part in ("outputs", "full", "z_final"):
            a, b = getattr(c, part), getattr(py, part)
            np.testing.assert_array_equal(a.view(np.uint64), b.view(np.uint64),
                                          err_msg=f"{name}: {part}")


def test_a_buffer_another_run_left_gives_a_new_buffers_numbers():
    """integrate._take_buffer: a run through the inputs another run of the same chunk left
    (a test movement, noise, a sensor fault, another wind) gets the numbers a new buffer
    gives it, in raw bits: the inputs it leaves unwritten are zero again."""
    base = {"controller": "physical", "case": 4, "profile": "realistic", "t_final_s": 8.0,
            "fault": [{"type": "lock", "blade": 1, "onset_s": 3.0}]}
    first = config.make_config({**base, "seed": 3, "fdi": {"test_pulse_deg": 1.0},
                                "wind": {"kind": "constant", "speed_mps": 18.0},
                                "fault": [{"type": "pitch_sensor_offset", "blade": 2,
                                           "onset_s": 1.0}]})
    second = config.make_config(base)
    assert first.test_pulse and not second.test_pulse
    integrate._BUFFERS.held = None
    new = cases.run(second, progress=False)
    held = integrate._BUFFERS.held
    cases.run(first, progress=False)
    assert integrate._BUFFERS.held[2] is held[2]  # the same buffer, taken again
    reused = cases.run(second, progress=False)
    for part in ("outputs", "full", "z_final"):
        a, b = getattr(reused, part), getattr(new, part)
        np.testing.assert_array_equal(a.view(np.uint64), b.view(np.uint64), err_msg=part)


def test_a_reset_buffer_reads_zero_wherever_it_was_not_written_since():
    """Buffered.reset: each run's segment of each input reads zero at the next evaluation
    unless written since, whole (put), in part (put_head: the rest zero) or for every run
    (fill)."""
    u, v = ca.SX.sym("u", 3), ca.SX.sym("v", 2)
    call = integrate.Buffered(ca.Function("f", [u, v], [u * 1, v * 1], ["u", "v"],
                                          ["a", "b"]).map(2))
    call.put("u", [1.0, 2.0, 3.0], 0, 2)
    call.put("u", [4.0, 5.0, 6.0], 1, 2)
    call.fill("v", 7.0)
    a, b = call.evaluate()
    assert a.tolist() == [[1, 4], [2, 5], [3, 6]] and b.tolist() == [[7, 7], [7, 7]]
    call.reset()
    call.put("u", [9.0, 9.0, 9.0], 1, 2)  # run 1 whole, run 0 not written
    call.put_head("v", [8.0], 0, 2)  # run 0's first entry; filled before: the rest zero
    a, b = call.evaluate()
    assert a.tolist() == [[0, 9], [0, 9], [0, 9]] and b.tolist() == [[8, 0], [0, 0]]
    call.reset()
    call.fill("v", 1.0)
    a, b = call.evaluate()
    assert a.tolist() == [[0, 0]] * 3 and b.tolist() == [[1, 1], [1, 1]]
