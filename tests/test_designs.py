"""Every controller derived as a ControllerDesign (the registry, via generated/layout.json):
its generated α̇_i against central differences of its α_i along its design model's closed
loop (wtftc.verify.designs). A new derived controller is checked here with no edit."""

import numpy as np
import pytest

from wtftc.verify import designs


def test_the_registry_has_derived_designs():
    assert "drivetrain" in designs.derived()
    with pytest.raises(KeyError, match="not derived as a ControllerDesign"):
        designs.DesignModel("pi")


@pytest.mark.parametrize("controller", designs.derived())
def test_alpha_dot_against_central_differences(controller):
    """d α_i/dt by central differences (states at t ± h by RK4 with steps ≤ 2e-4 s) falls to
    the generated total derivative at O(h²): fitted slope 1.9-2.1 over the truncation
    branch, below 1e-6 relative at the best h; at a point where the adaptation integrates
    (κ = 1) and every α̇_i is far from zero."""
    fd = designs.alpha_dot_fd(controller)
    assert fd.alphas and fd.kappa == 1.0
    assert np.all(np.abs(fd.alpha_dot) > 1e-6), fd.alpha_dot
    assert np.all((1.9 < fd.slopes) & (fd.slopes < 2.1)), (fd.slopes, fd.errors)
    assert np.all(fd.errors.min(axis=0) < 1e-6), fd.errors
    # the differences really converge: three decades of h buy about six of error
    assert np.all(fd.errors[0] > 1e4 * fd.errors.min(axis=0))
