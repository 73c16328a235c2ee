"""No import circle between our modules: every ``import`` (also one inside a function)
is an edge, and the graph of our five packages must have no cycle."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {
    "sideslip_msgs_py": ROOT / "sideslip_msgs_py" / "sideslip_msgs_py",
    "sideslip_sim": ROOT / "sideslip_sim" / "sideslip_sim",
    "sideslip_bags": ROOT / "sideslip_bags" / "sideslip_bags",
    "sideslip_estimator": ROOT / "sideslip_estimator" / "sideslip_estimator",
    "sideslip_training": ROOT / "training" / "sideslip_training",
}


def _modules() -> dict[str, Path]:
    mods = {}
    for package, folder in PACKAGES.items():
        for file in folder.rglob("*.py"):
            parts = [package, *file.relative_to(folder).with_suffix("").parts]
            if parts[-1] == "__init__":
                parts = parts[:-1]
            mods[".".join(parts)] = file
    return mods


def _targets(module: str, file: Path, node: ast.AST, mods: dict[str, Path]) -> list[str]:
    if isinstance(node, ast.Import):
        names = [a.name for a in node.names]
    else:
        assert isinstance(node, ast.ImportFrom)
        if node.level:
            base = module.split(".")
            if file.name != "__init__.py":
                base = base[:-1]
            base = base[: len(base) - (node.level - 1)]
            package = ".".join(base + ([node.module] if node.module else []))
        else:
            package = node.module or ""
        names = [f"{package}.{a.name}" for a in node.names]
    out = []
    for name in names:
        while name and name not in mods:  # a function or class: its module
            name = name.rpartition(".")[0]
        if name and name != module:
            out.append(name)
    return out


def import_graph() -> dict[str, set[str]]:
    mods = _modules()
    graph: dict[str, set[str]] = {m: set() for m in mods}
    for module, file in mods.items():
        for node in ast.walk(ast.parse(file.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import | ast.ImportFrom):
                graph[module].update(_targets(module, file, node, mods))
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in graph:
        if v not in index:
            visit(v)
    return found


def test_no_module_imports_itself_back_through_others() -> None:
    graph = import_graph()
    assert len(graph) > 50  # the walk found the packages
    assert cycles(graph) == []


def test_bag_tools_import_only_the_contract_among_our_packages() -> None:
    """sideslip_bags stands beside the simulator: neither imports the other."""
    graph = import_graph()
    for module, targets in graph.items():
        package = module.split(".")[0]
        used = {t.split(".")[0] for t in targets} - {package}
        if package == "sideslip_bags":
            assert used <= {"sideslip_msgs_py"}, f"{module} imports {sorted(used)}"
        if package == "sideslip_sim":
            assert "sideslip_bags" not in used, f"{module} imports the bag tools"


def test_the_cycle_finder_finds_a_cycle() -> None:
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
