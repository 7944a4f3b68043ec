"""The Python packages' layers go one way (docs/ARCHITECTURE.md): messages ← common ← {sim_hil, training}, the
simulator and training never import each other, and no module imports itself back through a circle. Read from
the code's own import statements (module level and inside functions alike)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("messages", "common", "sim_hil", "training")
# what each package may import from the others
ALLOWED = {"messages": set(), "common": {"messages"}, "sim_hil": {"messages", "common"},
           "training": {"messages", "common"}}


def _modules() -> dict[str, Path]:
    found = {}
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            found[name.removesuffix(".__init__")] = path
    return found


def _imports(modules: dict[str, Path]) -> dict[str, set[str]]:
    """module → the project modules it imports (a name resolves to the longest module it names)."""
    def resolve(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    edges = {}
    for module, path in modules.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets |= {resolve(f"{node.module}.{a.name}") for a in node.names}
            elif isinstance(node, ast.Import):
                targets |= {resolve(a.name) for a in node.names}
        edges[module] = {t for t in targets if t and t != module}
    return edges


def test_packages_import_only_the_layers_below():
    edges = _imports(_modules())
    wrong = sorted(f"{m} → {t}" for m, ts in edges.items() for t in ts
                   if t.split(".")[0] != m.split(".")[0] and t.split(".")[0] not in ALLOWED[m.split(".")[0]])
    assert not wrong, f"imports against the layers: {wrong}"


def test_no_import_circle():
    edges = _imports(_modules())
    state: dict[str, int] = {}   # 1: on the current path, 2: done

    def visit(module: str, path: list[str]):
        state[module] = 1
        for target in sorted(edges[module]):
            if state.get(target) == 1:
                raise AssertionError(f"import circle: {' → '.join(path[path.index(target):] + [target])}")
            if target not in state:
                visit(target, path + [target])
        state[module] = 2

    for module in sorted(edges):
        if module not in state:
            visit(module, [module])


def test_training_envs_import_nothing_of_training_above_them():
    """The envs are training's lowest layer: what their start banks need (experts, checkpoint reading) lives in
    training.envs, so the trainer, evaluations and recipes build on them and never the other way round."""
    edges = _imports(_modules())
    wrong = sorted(f"{m} → {t}" for m, ts in edges.items() if m.startswith("training.envs")
                   for t in ts if t.startswith("training") and not t.startswith("training.envs"))
    assert not wrong, f"training.envs reaching up: {wrong}"
