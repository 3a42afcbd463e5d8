"""One run's files: traces (CSV with units, Parquet), metrics.json, config.toml."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from wtftc.config import RunConfig, to_toml
from wtftc.sim import integrate, rhs


def write_outputs(out_dir: Path, rc: RunConfig, res: integrate.Result, m: dict) -> list[Path]:
    """Traces (CSV with units, Parquet), metrics.json and config.toml, each written atomically."""
    from wtftc.results.io import atomic_write_json, atomic_write_text, write_parquet

    out_dir = Path(out_dir)
    spec = rhs.output_spec(rc.controller, rc.loop.fdi, rc.plant)
    header = ["time_s"] + [n for n, _ in spec]
    units = ["s"] + [u for _, u in spec]
    data = np.column_stack([res.t, res.outputs])
    lines = ["# wtftc trace: " + json.dumps({"label": rc.label, "case": rc.case,
                                              "plant": rc.plant, "seed": rc.seed}),
             ",".join(f"{n} [{u}]" for n, u in zip(header, units, strict=True))]
    lines += [",".join(f"{x:.9g}" for x in row) for row in data]
    paths = [out_dir / "traces.csv", out_dir / "traces.parquet", out_dir / "metrics.json",
             out_dir / "config.toml"]
    atomic_write_text(paths[0], "\n".join(lines) + "\n")
    write_parquet(paths[1], dict(zip(header, data.T, strict=True)),
                  dict(zip(header, units, strict=True)))
    atomic_write_json(paths[2], m)
    atomic_write_text(paths[3], to_toml(rc.raw))
    return paths
