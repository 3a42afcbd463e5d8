"""The house rules that a read of the code would otherwise have to check (docs/architecture.md):

* imports inside wtftc/ run one way, down the rooms, and form no cycle (lazy imports
  inside functions included);
* the runtime imports neither SymPy nor derivation/ nor bench/;
* no function is longer than a screen (60 lines, docstring included).
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "wtftc"
#: the rooms, top to bottom: a module may import its own room and the rooms below it
ROOMS = ["cli", "campaign", "openfast", "export", "verify", "results", "config", "controller",
         "sim", "model",
         "artefacts", "programs", "files", "errors"]
MAX_LINES = 60


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _room(module: str) -> str:
    parts = module.split(".")
    return "errors" if len(parts) == 1 else parts[1]  # wtftc itself: the version only


def _imports(path: Path) -> set[str]:
    """Every wtftc module that ``path`` imports, at the top or inside a function."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module:
            base = node.module
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                out.add(sub if (ROOT / Path(*sub.split("."))).with_suffix(".py").exists()
                        or (ROOT / Path(*sub.split("."))).is_dir() else base)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


def _graph() -> dict[str, set[str]]:
    modules = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    return {m: {i for i in _imports(p) if i in modules and i != m} for m, p in modules.items()}


def test_imports_run_down_the_rooms():
    wrong = [f"{m} ({_room(m)}) imports {i} ({_room(i)})"
             for m, deps in _graph().items() for i in deps
             if ROOMS.index(_room(i)) < ROOMS.index(_room(m))]
    assert not wrong, "imports against the arrows of docs/architecture.md:\n" + "\n".join(wrong)


def test_no_import_cycle():
    graph = _graph()
    state: dict[str, int] = {}
    cycles = []

    def visit(m, stack):
        state[m] = 1
        for i in sorted(graph[m]):
            if state.get(i) == 1:
                cycles.append(" -> ".join(stack[stack.index(i):] + [i]))
            elif i not in state:
                visit(i, stack + [i])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_the_runtime_imports_no_derivation_sympy_or_bench():
    bad = [f"{p.relative_to(ROOT)}: {i}" for p in PACKAGE.rglob("*.py") for i in _imports(p)
           if i.split(".")[0] in ("sympy", "derivation", "bench")]
    assert not bad, bad


@pytest.mark.parametrize("folder", ["wtftc", "derivation", "bench", "examples"])
def test_no_function_longer_than_a_screen(folder):
    long = []
    for path in sorted((ROOT / folder).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_LINES:
                    long.append(f"{path.relative_to(ROOT)}:{node.lineno} {node.name} ({n} lines)")
    assert not long, f"functions over {MAX_LINES} lines:\n" + "\n".join(long)


def test_the_rules_see_a_violation(tmp_path):
    """The import reader finds lazy imports and submodule imports (the rules are not
    vacuous): cases imports the simulator inside a function, and the sim room's modules."""
    graph = _graph()
    assert "wtftc.sim.rosco" in graph["wtftc.campaign.cases"]  # imported inside run()
    assert "wtftc.sim.integrate" in graph["wtftc.campaign.cases"]
    assert ROOMS.index(_room("wtftc.campaign.cases")) < ROOMS.index(_room("wtftc.sim.rosco"))
