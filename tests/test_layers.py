"""The package's layers import downward only, and no module imports itself back through
others (docs/architecture.md). White-box: reads every source file's imports with ``ast``,
including the ones inside functions."""

import ast
from pathlib import Path

import diracvi

ROOT = Path(diracvi.__file__).parent

#: the layer of each part of the package, lowest first; a module may import its own
#: subpackage and any lower layer, nothing beside or above it
LAYERS = {
    "errors": 0,
    "status": 0,
    "runtime": 1,
    "model": 2,
    "discretization": 3,
    "components": 3,  # parts build models: they know no rule
    "solvers": 4,
    "dirac": 4,
    "driver": 5,
    "sweeps": 6,
    "spice": 7,
    "problems": 7,
    "plotting": 7,
    "__init__": 7.5,  # the public names (re-exports); the tools below are its users
    "reproduce": 8,
    "bench": 8.5,  # reads the paper's numbers from reproduce
    "cli": 9,
}


def _module(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports() -> dict[str, set[str]]:
    """``{module: every diracvi module it imports}`` (``from x import name`` counts as
    ``x.name`` when that is a module)."""
    files = {_module(p): p for p in ROOT.rglob("*.py")}
    graph = {}
    for name, path in files.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - node.level + 1]
                    target = ".".join(base + ([node.module] if node.module else []))
                else:
                    target = node.module or ""
                for alias in node.names:
                    sub = f"{target}.{alias.name}"
                    deps.add(sub if sub in files else target)
            elif isinstance(node, ast.Import):
                deps.update(a.name for a in node.names)
        graph[name] = {d for d in deps if d in files and d != name}
    return graph


def _layer(module: str) -> str:
    parts = module.split(".")
    return "__init__" if len(parts) == 1 else parts[1]


def test_every_part_of_the_package_has_a_layer():
    assert {_layer(m) for m in _imports()} <= set(LAYERS)


def test_layers_import_downward_only():
    wrong = [
        f"{module} -> {dep}"
        for module, deps in _imports().items()
        for dep in deps
        if _layer(dep) != _layer(module) and LAYERS[_layer(dep)] >= LAYERS[_layer(module)]
    ]
    assert not wrong, "imports sideways or upward:\n" + "\n".join(sorted(wrong))


def test_no_import_circle_anywhere():
    graph = _imports()
    state: dict[str, int] = {}  # 1 on the path, 2 done
    circles = []

    def visit(node, path):
        state[node] = 1
        for dep in sorted(graph[node]):
            # a package's __init__ re-exports its modules: importing the package is
            # importing them, so only edges out of __init__ files into their own
            # package are skipped
            if node == dep.rpartition(".")[0] and _is_package(node):
                continue
            if state.get(dep) == 1:
                circles.append(" -> ".join([*path[path.index(dep) :], dep]))
            elif dep not in state:
                visit(dep, [*path, dep])
        state[node] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert not circles, "import circles:\n" + "\n".join(circles)


def _is_package(module: str) -> bool:
    return (ROOT.parent / module.replace(".", "/") / "__init__.py").exists()


def test_command_modules_do_not_import_each_other():
    # each command of the CLI lives in its own module and shares only cli/common.py;
    # cli/main.py registers them
    shared = {"diracvi.cli", "diracvi.cli.main", "diracvi.cli.common"}
    wrong = [
        f"{module} -> {dep}"
        for module, deps in _imports().items()
        if module.startswith("diracvi.cli.") and module not in shared
        for dep in deps
        if dep.startswith("diracvi.cli") and dep != "diracvi.cli.common"
    ]
    assert not wrong, "\n".join(wrong)
