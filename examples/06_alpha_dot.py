"""A generated function loaded and evaluated: the paper's virtual inputs α_1..α_3 and their
analytic time derivatives α̇_i (`alpha_derivatives`), checked against central finite
differences of α_i at one point of the closed loop (`closed_loop_paper` gives the motion).

Along the closed loop ż = f(z, t), d/dt α(z, y_d(t)) is the limit of
[α(z + h ż, y_d(t + h)) − α(z − h ż, y_d(t − h))] / 2h, with an error falling as h².
Functions are called by input name; `wtftc functions` lists every one with its inputs and
outputs, and `wtftc.artefacts.layout` gives each vector's names, units and defaults.
More: docs/verification.md (what is checked, and how), docs/paper-notes.md (eqs (26)-(49)).

    python examples/06_alpha_dot.py [OUT_DIR]       # default out/examples/06_alpha_dot
"""

import sys
from pathlib import Path

import numpy as np

from wtftc.artefacts import layout
from wtftc.artefacts.loader import load

T_S = 0.5  # the time of the point [s]
AMP_RAD_S, FREQ_RAD_S = 0.02, 0.8  # a moving reference, so that every ẏ_d term counts


def reference(t_s: float) -> np.ndarray:
    """y_d(t) = y_rated + a sin(ωt) [rad/s] and its first four derivatives."""
    a, w = AMP_RAD_S, FREQ_RAD_S
    s, c = np.sin(w * t_s), np.cos(w * t_s)
    y0 = layout.defaults("reference")[0]  # rated rotor speed
    return np.array([y0 + a * s, a * w * c, -a * w**2 * s, -a * w**3 * c, a * w**4 * s])


def main(out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    closed_loop, alpha_fn = load("closed_loop_paper"), load("alpha_derivatives")
    p_plant = layout.defaults("plant_params")
    p_ctrl = layout.defaults("controller_params")
    no_fault = layout.defaults("fault_inputs")
    n_plant = layout.size("plant_states")
    # the point: the plant 3 % below its default speed, the observer on it, small weights
    z = np.concatenate([layout.defaults("plant_states"), layout.defaults("controller_states")])
    z[0] *= 0.97
    z[n_plant + layout.index("controller_states", "xhat_1")] = z[0]  # x̂1 = ω_r
    weights = slice(n_plant + layout.block("controller_states", "xhat").stop, z.size)
    z[weights] = 0.01 * np.random.default_rng(0).standard_normal(z[weights].size)
    out = closed_loop(z=z, d1=0.0, yd=reference(T_S), fault=no_fault, p_plant=p_plant,
                      p_ctrl=p_ctrl)
    z_dot, y_dot = np.array(out["z_dot"]).ravel(), float(out["ydot"])

    def alpha(zz, t_s):
        res = alpha_fn(x_ctrl=zz[n_plant:], y=zz[0], yd=reference(t_s), p_ctrl=p_ctrl,
                       ydot=y_dot)
        return {k: np.array(v).ravel() for k, v in res.items()}

    at = alpha(z, T_S)
    analytic = at["alpha_dot_full"]
    print("α   =", np.array2string(at["alpha"], precision=6))
    print("α̇   =", np.array2string(analytic, precision=6), "(analytic, alpha_dot_full)")
    lines = ["h_s,rel_error_1,rel_error_2,rel_error_3"]
    for h_s in (1e-2, 1e-3, 1e-4):
        fd = (alpha(z + h_s * z_dot, T_S + h_s)["alpha"]
              - alpha(z - h_s * z_dot, T_S - h_s)["alpha"]) / (2 * h_s)
        rel = np.abs(fd - analytic) / np.abs(analytic)
        print(f"h = {h_s:.0e} s: central difference {np.array2string(fd, precision=6)}, "
              f"relative error {np.array2string(rel, precision=2)}")
        lines.append(f"{h_s:g}," + ",".join(f"{e:.6g}" for e in rel))
    # what the controller can compute: ẏ replaced by the observer's estimate ẏ̂
    gap = at["alpha_dot_comp"] - analytic
    print("α̇_comp − α̇ =", np.array2string(gap, precision=6),
          f"= ∂α/∂y (ẏ̂ − ẏ), ẏ̂ − ẏ = {at['ydot_hat'][0] - y_dot:.3e} rad/s²")
    (out_dir / "alpha_dot_fd.csv").write_text("\n".join(lines) + "\n")
    print(f"written: {out_dir / 'alpha_dot_fd.csv'}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/examples") / Path(__file__).stem)
