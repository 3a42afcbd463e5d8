"""The PI baseline's pitch-loop target on each turbine (wtftc.config): the (ω_n, ζ) its
turbine file's reference deck tunes ROSCO's pitch PI to (``rosco_tuning``), so that the
baseline is tuned as the field tunes that turbine; a run's own value wins; a turbine file
without one keeps the layout's default, the NREL 5-MW's target."""

from pathlib import Path

from wtftc import config
from wtftc.artefacts import layout as lay
from wtftc.model import turbine_file


def _target(cfg: dict) -> tuple[float, float]:
    rc = config.make_config(cfg)
    v = lay.values("pi_params", rc.p_ctrl)
    return v["pi_omega_n"], v["pi_zeta"]


def test_the_pi_takes_its_turbines_reference_target():
    defaults = lay.values("pi_params", lay.defaults("pi_params"))
    nrel = turbine_file.load("nrel5mw").rosco_tuning
    iea = turbine_file.load("iea15mw").rosco_tuning
    assert nrel == (defaults["pi_omega_n"], defaults["pi_zeta"])  # bit for bit
    assert iea != nrel
    assert _target({"controller": {"preset": "pi"}}) == nrel
    assert _target({"controller": {"preset": "pi"}, "turbine": "iea15mw"}) == iea
    assert _target({"controller": {"preset": "pi", "pi_omega_n": 0.35},
                    "turbine": "iea15mw"}) == (0.35, iea[1])


def test_a_turbine_file_without_a_reference_target_keeps_the_default(tmp_path):
    src = turbine_file.path_of("iea15mw")
    text = Path(src).read_text("utf-8")
    assert "\nrosco_tuning = " in text
    kept = "\n".join(line for line in text.splitlines()
                     if not line.startswith("rosco_tuning = "))
    mine = tmp_path / "iea15mw_untuned.toml"
    mine.write_text(kept, "utf-8")
    for f in Path(src).parent.glob("*"):  # the files it names beside it (its Cp table)
        if f.is_file() and f.name != Path(src).name and f.name in text:
            (tmp_path / f.name).write_bytes(f.read_bytes())
    defaults = lay.values("pi_params", lay.defaults("pi_params"))
    assert _target({"controller": {"preset": "pi"}, "turbine": str(mine)}) == \
        (defaults["pi_omega_n"], defaults["pi_zeta"])
