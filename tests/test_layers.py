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


# training's packages from the bottom up (training/README.md, docs/ARCHITECTURE.md): a package imports only its own
# layer and those before it. core: checkpoints, curves, overrides, networks, the PPOExtension interface; export:
# brax params → artifacts; evaluation: rollouts of artifacts; distill: teachers, DAgger and the student's PPO
# fine-tune; imitation: DAgger from the planner and RL from its policy; ppo: the trainer, which picks among
# distill's and imitation's extensions; recipes: the stages of a shipped policy; the root: the CLI.
TRAINING_LAYERS = ("envs", "core", "export", "planner", "evaluation", "distill", "imitation", "ppo", "recipes", "")
MAX_TRAINING_LAZY_IMPORTS = 50


def _training_layer(module: str) -> int:
    parts = module.split(".")
    package = parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] in TRAINING_LAYERS) else ""
    return TRAINING_LAYERS.index(package)


def test_training_packages_import_only_the_layers_below():
    edges = _imports(_modules())
    for module in edges:
        if module.startswith("training."):
            assert module.split(".")[1] in TRAINING_LAYERS or module.count(".") == 1, \
                f"{module}: in no layer of TRAINING_LAYERS"
    wrong = sorted(f"{m} → {t}" for m, ts in edges.items() if m.startswith("training")
                   for t in ts if t.startswith("training") and _training_layer(t) > _training_layer(m))
    assert not wrong, f"training imports reaching up a layer: {wrong}"


def _function_imports(path: Path) -> list[int]:
    """Line numbers of the import statements inside functions of the file."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            found += [n.lineno for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom))]
    return sorted(set(found))


def test_training_imports_inside_functions_are_few_and_say_why():
    """An import inside a function hides a dependency from the module's head; each one left says why (e.g. keeping
    JAX out of the CLI's --help, an optional package, a backend chosen before pyplot loads)."""
    lazy = {path: _function_imports(path) for path in (ROOT / "training").rglob("*.py")}
    count = sum(len(lines) for lines in lazy.values())
    assert count <= MAX_TRAINING_LAZY_IMPORTS, f"{count} imports inside functions in training/"
    silent = []
    for path, lines in lazy.items():
        text = path.read_text().split("\n")
        silent += [f"{path.relative_to(ROOT)}:{n}" for n in lines
                   if "#" not in text[n - 1] and not text[n - 2].strip().startswith("#")]
    assert not silent, f"imports inside functions without a comment saying why: {silent}"


def test_layer_check_sees_an_upward_import():
    """The layer rule itself: an evaluation module importing the trainer is caught."""
    assert _training_layer("training.evaluation.batch") < _training_layer("training.ppo.train")
    assert _training_layer("training.cli") == len(TRAINING_LAYERS) - 1
    assert _training_layer("training.envs.starts.fallen") == 0
