"""A run driven by a wind file: an OpenFAST InflowWind uniform wind file (.hh) written here
(a ramp from 13 to 18 m/s with a 2-m/s gust riding on it), then one run of the paper's
design on it, with what `wtftc run` writes (traces with units, metrics, config, figures).

InflowWind rows: time, horizontal speed, direction, vertical speed, horizontal shear,
power-law exponent, vertical linear shear, gust speed; wtftc takes speed + gust speed at
hub height, held outside the file's range. More: docs/wind.md (kind "file"),
docs/running.md (the files of a run).

    python examples/03_wind_file.py [OUT_DIR]       # default out/examples/03_wind_file
"""

import sys
from pathlib import Path

import numpy as np

from wtftc.campaign.cases import run_and_write
from wtftc.config import make_config

HEADER = """! OpenFAST InflowWind uniform wind file, written by wtftc's examples/03_wind_file.py
! Time   Wind    Wind    Vert.   Horiz.  Pwr.Law  Lin.Vert.  Gust
!        Speed   Dir     Speed   Shear   Vert.Shr Shear      Speed
! (s)    (m/s)   (deg)   (m/s)   (-)     (-)      (-)        (m/s)
"""


def write_hh(path: Path) -> None:
    """Ramp 13 -> 18 m/s over 2-8 s, plus a 2-m/s gust (gust column) over 4-6 s."""
    t_s = np.arange(0.0, 10.5, 0.5)
    speed_mps = np.interp(t_s, [2.0, 8.0], [13.0, 18.0])
    gust_mps = np.where((t_s > 4.0) & (t_s < 6.0), 2.0, 0.0)
    rows = [f"{t:6.2f} {v:7.3f} 0.0 0.0 0.0 0.2 0.0 {g:5.2f}"
            for t, v, g in zip(t_s, speed_mps, gust_mps, strict=True)]
    path.write_text(HEADER + "\n".join(rows) + "\n")


def main(out_dir: Path) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    wind_path = out_dir / "ramp_gust.hh"
    write_hh(wind_path)
    # an absolute path, so that the saved config.toml re-runs from any folder
    rc = make_config({"case": 1, "t_final_s": 10.0, "label": "wind_file",
                      "wind": {"kind": "file", "path": str(wind_path.resolve())}})
    res, table, paths = run_and_write(rc, out_dir / "run", progress=False)
    wind = rc.wind.describe()
    print(f"wind file {wind_path}: {wind['derived']['n_rows']} rows, "
          f"{wind['derived']['t_range_s'][0]:g}..{wind['derived']['t_range_s'][1]:g} s, "
          f"sha256 {wind['derived']['sha256'][:12]}")
    wind_mps = res.column("wind")
    print(f"wind seen by the rotor: {wind_mps.min():.2f} .. {wind_mps.max():.2f} m/s")
    print(table, end="")
    print("written:", ", ".join(str(p) for p in paths if p.suffix != ".pdf"))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("out/examples") / Path(__file__).stem)
