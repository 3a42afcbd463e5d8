"""Is ``generated/`` what the derivation produces? ``python -m derivation.check_generated``.

Two checks, both failing with what to run:

* the sha256 of every derivation source against ``generated/manifest.json`` (instant);
* a full regeneration into a temporary folder, compared byte for byte, with a diff.
"""

from __future__ import annotations

import difflib
import hashlib
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FIX = "generated/ is stale: run `make regenerate` and commit generated/"


def stale_sources(root: Path = ROOT) -> list[str]:
    """Derivation sources whose sha256 differs from the manifest (or that it lacks): the
    modules and the NREL 5-MW's turbine file (derivation.generate.source_files)."""
    manifest_path = root / "generated" / "manifest.json"
    if not manifest_path.exists():
        return [f"{manifest_path} is missing"]
    recorded = json.loads(manifest_path.read_text())["sources"]
    current = {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
               for p in [*sorted((root / "derivation").glob("*.py")),
                         root / "wtftc" / "data" / "nrel5mw.toml"]}
    problems = []
    for path in sorted(set(recorded) | set(current)):
        if path not in current:
            problems.append(f"{path} is in the manifest but no longer exists")
        elif path not in recorded:
            problems.append(f"{path} is new since generated/ was built")
        elif recorded[path] != current[path]:
            problems.append(f"{path} changed since generated/ was built")
    return problems


def regeneration_diff(root: Path = ROOT, max_lines: int = 60) -> list[str]:
    """Regenerate into a temporary folder; describe every file that differs."""
    with tempfile.TemporaryDirectory() as tmp:
        proc = subprocess.run([sys.executable, "-m", "derivation.generate", tmp], cwd=root,
                              capture_output=True, text=True)
        if proc.returncode != 0:
            return [f"regeneration failed:\n{proc.stderr[-3000:]}"]
        fresh, committed = Path(tmp), root / "generated"
        names = sorted({p.name for p in fresh.iterdir()}
                       | {p.name for p in committed.iterdir() if p.is_file()})
        problems = []
        for name in names:
            a, b = committed / name, fresh / name
            if not b.exists():
                problems.append(f"generated/{name} is not produced by the derivation")
            elif not a.exists():
                problems.append(f"generated/{name} is missing")
            elif a.read_bytes() != b.read_bytes():
                diff = list(difflib.unified_diff(
                    a.read_text().splitlines(), b.read_text().splitlines(),
                    f"committed/{name}", f"regenerated/{name}", lineterm="", n=1))
                shown = [line[:160] for line in diff[:max_lines]]
                more = len(diff) - len(shown)
                problems.append(f"generated/{name} differs:\n" + "\n".join(shown)
                                + (f"\n... {more} more diff lines" if more > 0 else ""))
        return problems


def main() -> int:
    problems = stale_sources() + regeneration_diff()
    if problems:
        print("\n".join(problems))
        print(f"\n{FIX}")
        return 1
    print("generated/ matches the derivation (sources and every artefact, byte for byte)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
