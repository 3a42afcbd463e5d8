"""Generated CasADi functions against the SymPy derivation (lambdify), at 200 random points.

The references rebuild the fuzzy systems from the unfactored normalized firing strengths
and let SymPy differentiate them, so the generator's factorization, its derivative orders
and the SymPy → CasADi translation are all under test.

Tolerance: 1e-12 relative, per output element, to the larger of |value| and the magnitude
of the terms it sums (:func:`reference.magnitude`). Against |value| alone the bar cannot be
met by any double-precision evaluation where terms cancel: at random states α̇3 loses
about 1e-10 relative in both the generated code and SymPy's lambdify, measured against a
40-digit mpmath evaluation (docs/verification.md).
"""

import numpy as np
import pytest
import reference

from wtftc.artefacts.loader import layout_json, load
from wtftc.verify.checks import random_inputs

N_POINTS = 200
FUNCTIONS = sorted(layout_json()["functions"])


@pytest.mark.parametrize("name", FUNCTIONS)
def test_generated_matches_sympy(name):
    rng = np.random.default_rng(FUNCTIONS.index(name))
    f = load(name, "compiled")
    worst = {}
    for _ in range(N_POINTS):
        args = random_inputs(name, rng)
        got = f(**args)
        ref = reference.reference(name, args)
        for key in f.name_out():
            g = np.array(got[key]).reshape(-1, order="F")
            assert np.all(np.isfinite(g)), f"{name}.{key} is not finite at {args}"
            value, scale = ref[key]
            err = np.abs(g - value) / np.maximum(np.maximum(np.abs(value), scale), 1e-300)
            worst[key] = max(worst.get(key, 0.0), float(err.max()))
    assert set(worst) == set(f.name_out())
    bad = {k: v for k, v in worst.items() if v > 1e-12}
    assert not bad, f"{name}: relative error above 1e-12: {bad}"
