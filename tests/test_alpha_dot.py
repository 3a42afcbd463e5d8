"""α̇_i against central differences of α_i along closed-loop RK4 trajectories.

The analytic α̇_i (total derivative along the closed loop, ẏ from the plant) must agree
with (α_i(t+h) - α_i(t-h))/2h with an error falling as O(h²) over h = 1e-2 .. 1e-5, and
below 1e-6 relative at the best h. The computable α̇_i (ẏ → ẏ̂ = x̂2 + f̂1) differs from the
full one by exactly ∂α_i/∂y (ẏ̂ - ẏ).
"""

import numpy as np
import pytest

from wtftc.verify import checks as verify


@pytest.fixture(scope="module", params=[0.5, 1.7], ids=["t=0.5s", "t=1.7s"])
def fd(request):
    return verify.alpha_dot_fd(t_point=request.param)


def test_error_falls_as_h_squared(fd):
    assert fd.errors.shape == (len(fd.h), 3)
    np.testing.assert_allclose(fd.slopes, 2.0, atol=0.1)


def test_error_below_1e6_at_best_h(fd):
    assert np.all(fd.errors.min(axis=0) < 1e-6)
    # the analytic value is not trivially small, and the reference moves (y_d' ≠ 0)
    assert np.all(np.abs(fd.alpha_dot) > 1e-3)
    assert verify.Signals().amp > 0


def test_computable_part_differs_by_exactly_the_ydot_term(fd):
    assert np.all(np.abs(fd.ydot_term) > 1e-6), "the ẏ term must be exercised"
    np.testing.assert_allclose(fd.comp_minus_full, fd.ydot_term, rtol=1e-10, atol=1e-13)

