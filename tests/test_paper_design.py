"""The paper's design as a ControllerDesign (issue 34, item 4): the uniform ctrl_paper and
init_paper are built by derivation.controllers.from_design, like every other design, and
they compute what the paper's own generated ``controller`` (eqs (21)-(49)) computes.

``ctrl_paper`` against ``controller`` is exact (bit for bit): the port translates the same
SymPy expressions through the same fuzzy evaluator, and γ_i χ_i is bound before it meets
φ_i, as the former build path formed it. ``init_paper``'s x̂4(0) = β̄ is (β1+β2+β3)·(1/3),
the translator's form of a mean, where the former path divided by 3: within two units in
the last place, equal pitch angles included (docs/paper-notes.md, "Build path").
"""

import numpy as np

from derivation import controllers, paper_design
from wtftc.artefacts.loader import layout_json, load
from wtftc.verify.checks import random_inputs


def test_the_paper_is_a_registered_controller_design():
    c = controllers.REGISTRY["paper"]
    assert c.design is paper_design
    assert (c.states_group, c.params_group) == ("controller_states", "controller_params")
    d = paper_design.derive()
    assert len(d.rule_bases) == 4 and [len(g) for g in d.weight_groups] == [3, 9, 27, 81]
    assert len(d.x_dot) == len(paper_design.STATES) and len(d.v) == 3


def test_ctrl_paper_is_the_papers_controller_bit_for_bit():
    ctrl, paper = load("ctrl_paper", "compiled"), load("controller", "compiled")
    names = [e["name"] for e in layout_json()["controller_params"]]
    i0 = names.index("rho_hat_1")
    rng = np.random.default_rng(34)
    for _ in range(300):
        a = random_inputs("ctrl_paper", rng)
        got = ctrl(**a)
        p_eff = np.asarray(a["p_ctrl"], float).ravel().copy()
        p_eff[i0:i0 + 9] = np.asarray(a["known_fault"], float).ravel()
        y = float(np.asarray(a["meas"]).ravel()[0])
        ref = paper(x_ctrl=a["x_ctrl"], y=y, yd=a["yd"], p_ctrl=p_eff)
        for key in ("v", "x_ctrl_dot", "u0"):
            assert np.array_equal(np.asarray(got[key]), np.asarray(ref[key])), key
        assert np.array_equal(np.asarray(got["diag"]).ravel(),
                              np.asarray(a["x_ctrl"], float).ravel()[:4])


def test_init_paper_starts_the_observer_at_rest_on_the_measurements():
    init = load("init_paper", "compiled")
    rng = np.random.default_rng(35)
    for _ in range(300):
        a = random_inputs("init_paper", rng)
        meas = np.asarray(a["meas"], float).ravel()
        x0 = np.asarray(init(**a)["x_ctrl0"]).ravel()
        assert np.array_equal(x0[[0, 1, 2]], [meas[0], 0.0, meas[0]])
        assert abs(x0[3] - meas[2:].sum() / 3) <= 2 * np.spacing(meas[2:].sum() / 3)
        assert not x0[4:].any()


def test_rule_bases_and_their_weights_must_pair_up():
    """The generator pairs rule base k with weight group k by position and reads its
    inputs by number: a design whose bases are out of order, or whose groups are not one
    weight per rule, is refused where it is built."""
    import pytest

    from derivation import design, fuzzy

    d = paper_design.derive()
    bad = [design.ControllerDesign(v=d.v, u0=d.u0, x_dot=d.x_dot, diag=d.diag, x0=d.x0,
                                   rule_bases=rbs, weight_groups=groups)
           for rbs, groups in ((d.rule_bases[::-1], d.weight_groups),
                               (d.rule_bases, [g[:-1] for g in d.weight_groups]),
                               (d.rule_bases[:3], d.weight_groups))]
    bad.append(design.ControllerDesign(v=d.v, u0=d.u0, x_dot=d.x_dot, diag=d.diag, x0=d.x0,
                                       rule_base=fuzzy.RuleBase(1), weights=d.weight_groups[0],
                                       rule_bases=d.rule_bases, weight_groups=d.weight_groups))
    for b in bad:
        with pytest.raises(ValueError):
            b.fuzzy_systems()
    assert d.fuzzy_systems() == (d.rule_bases, d.weight_groups)
