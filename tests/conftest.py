import os
import signal
import stat
import sys
from contextlib import contextmanager
from pathlib import Path

# BLAS on one thread, before numpy loads it, as the wtftc command sets it (wtftc/cli.py)
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

ROOT = Path(__file__).resolve().parent.parent
for p in (ROOT, ROOT / "tests"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

#: A run of the paper's design (corrected sign, no fault) that diverges for real: a gusty
#: class-A wind just above rated, found by the robustness campaign (docs/robustness.md,
#: run 0bd66619d0a10c50). Started at its wind's operating point (issue 31), x̂4 passes 1e8
#: at about 14 s; means 12.4, 12.44 and 12.5 m/s all diverge between 14.1 and 14.6 s
#: (from rated speed, before: between 27.9 and 30.8 s), so the case does not hang on one
#: rounding.
DIVERGING_RUN = {"controller": "paper", "case": 1, "seed": 86762, "t_final_s": 40.0,
                 "wind": {"kind": "ntm", "mean_mps": 12.5, "turbulence_class": "A"},
                 "turbine_params": {"gen_torque_law": 1.0}}


def snapshot(folder: Path) -> dict:
    """Every path under folder with its bytes (files) and mode: what 'untouched' means in
    the tests of the output-folder rule (issue 30)."""
    out = {".": stat.S_IMODE(folder.stat().st_mode)}
    for p in sorted(folder.rglob("*")):
        out[str(p.relative_to(folder))] = (p.read_bytes() if p.is_file() else None,
                                           stat.S_IMODE(p.lstat().st_mode))
    return out


@contextmanager
def no_hang(seconds: int = 30):
    """Fail, not hang, if the block reads a FIFO or a device to exhaustion."""
    def _alarm(signum, frame):
        raise AssertionError(f"hung for {seconds} s on a special file")

    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
