"""The layout's boundaries, asserted on the source (static import graph) and at run time.

Layers, lowest first: ``hybrid`` (hybrid automata), ``analysis`` (generic
verification tools), ``visnav`` (the case model), ``visnav.studies`` and
``visnav.fuzzing`` (studies and fuzzing of the case), ``visnav.verification``
(the case as a verification problem: its box comes from the campaign study, its
supervisor variants from the fuzzing), ``visnav.app`` (the application: the only
code that prints, writes files or imports matplotlib).
A module may import its own layer and the layers below, never above; the
project's import graph (module-level and function-level imports alike) has no
circle.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("hybrid", "analysis", "visnav")

LAYERS = {
    "hybrid": 0,
    "analysis": 1,
    "visnav": 2,
    "visnav.studies": 3,
    "visnav.fuzzing": 3,
    "visnav.verification": 4,
    "visnav.app": 5,
}
"""Rank of each layer; a module imports only modules of a lower rank or of its own layer."""

WRITING_METHODS = {"write_text", "write_bytes", "mkdir", "touch", "unlink", "rmdir", "savefig", "to_csv"}
"""Method names that write to the file system (outside ``visnav.app`` they are forbidden)."""
WRITING_MODULES = {"os": {"replace", "rename", "unlink", "remove", "makedirs", "mkdir", "fdopen", "fsync", "write",
                          "open"},
                   "shutil": None, "tempfile": None, "fcntl": None}
"""Modules whose functions (all of them when ``None``) write to the file system."""


def _modules() -> dict[str, Path]:
    out = {}
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            parts = path.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            out[name] = path
    return out


MODULES = _modules()


def _layer(module: str) -> str:
    for layer in sorted(LAYERS, key=len, reverse=True):
        if module == layer or module.startswith(layer + "."):
            return layer
    raise AssertionError(f"{module} belongs to no layer")


def _imports(module: str, path: Path) -> set[str]:
    """Project modules imported anywhere in ``path`` (absolute and relative, module and function level)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                prefix = ".".join(base + ([node.module] if node.module else []))
            else:
                prefix = node.module or ""
            names = [prefix] + [f"{prefix}.{alias.name}" for alias in node.names]
        else:
            continue
        for name in names:
            while name and name not in MODULES:
                name = name.rpartition(".")[0]
            if name and name != module:
                found.add(name)
    return found


GRAPH = nx.DiGraph()
for _name, _path in MODULES.items():
    GRAPH.add_node(_name)
    for _target in _imports(_name, _path):
        GRAPH.add_edge(_name, _target)


def test_the_layout_has_the_packages_the_readme_names():
    for package in ("hybrid", "analysis", "visnav", "visnav.studies", "visnav.fuzzing", "visnav.app"):
        assert package in MODULES, package


@pytest.mark.parametrize("module", sorted(MODULES))
def test_nothing_imports_upward(module):
    rank = LAYERS[_layer(module)]
    upward = sorted(t for t in GRAPH.successors(module)
                    if LAYERS[_layer(t)] > rank or (LAYERS[_layer(t)] == rank and _layer(t) != _layer(module)))
    assert not upward, f"{module} ({_layer(module)}) imports {upward}"


def test_the_import_graph_has_no_circle():
    # a package's __init__ re-exporting its modules is not a circle of the code
    code = GRAPH.copy()
    for name in MODULES:
        if MODULES[name].name == "__init__.py":
            code.remove_edges_from([(name, t) for t in list(code.successors(name)) if t.startswith(name + ".")])
            code.remove_edges_from([(s, name) for s in list(code.predecessors(name)) if s.startswith(name + ".")])
    cycles = list(nx.simple_cycles(code))
    assert not cycles, f"import circles: {cycles[:5]}"


def _calls(path: Path) -> list[tuple[int, str]]:
    """``(line, what)`` of the calls in ``path`` that print, write files or use matplotlib."""
    tree = ast.parse(path.read_text(), filename=str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            mods = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            out += [(node.lineno, f"import {m}") for m in mods if m.split(".")[0] == "matplotlib"]
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        name = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""
        if name == "print":
            out.append((node.lineno, "print()"))
        elif isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) and func.value.id in WRITING_MODULES:
            names = WRITING_MODULES[func.value.id]
            if names is None or name in names:
                out.append((node.lineno, f"{func.value.id}.{name}()"))
        elif isinstance(func, ast.Attribute) and name in WRITING_METHODS:
            out.append((node.lineno, f".{name}()"))
        elif name == "open":
            mode = node.args[1] if len(node.args) > 1 else next((k.value for k in node.keywords if k.arg == "mode"), None)
            if mode is not None and not (isinstance(mode, ast.Constant) and isinstance(mode.value, str)
                                         and set(mode.value) <= set("rbt")):
                out.append((node.lineno, "open() for writing"))
    return out


@pytest.mark.parametrize("module", sorted(m for m in MODULES if _layer(m) != "visnav.app"))
def test_only_the_application_prints_writes_files_or_plots(module):
    found = _calls(MODULES[module])
    assert not found, f"{module} (a library module) " + ", ".join(f"line {n}: {w}" for n, w in found)


@pytest.mark.parametrize("package, forbidden", [
    ("hybrid", ("visnav", "analysis", "matplotlib")),
    ("analysis", ("visnav", "matplotlib")),
    ("visnav.simulation", ("matplotlib", "visnav.app")),
    ("visnav.studies.loop_analysis", ("matplotlib", "visnav.app")),
    ("visnav.fuzzing", ("matplotlib", "visnav.app")),
])
def test_import_does_not_pull_upper_layers(package, forbidden):
    """At run time too (a library that imports a plotting package drags it into every user's process)."""
    code = (
        f"import sys, {package}; bad = [m for m in {forbidden!r} if m in sys.modules]; "
        "print(','.join(bad)); sys.exit(1 if bad else 0)"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert proc.returncode == 0, f"{package} imported {proc.stdout.strip()} {proc.stderr[-500:]}"


FACES = ("hybrid", "analysis.verify", "analysis.stl", "analysis.reach")
"""Packages whose ``__init__`` is a face: the names a user needs, and exactly those."""


@pytest.mark.parametrize("face", FACES)
def test_each_face_exports_exactly_its_public_names(face):
    import importlib
    from types import ModuleType

    module = importlib.import_module(face)
    public = {n for n, v in vars(module).items() if not n.startswith("_") and not isinstance(v, ModuleType)}
    lazy = set(getattr(module, "_LAZY", {}))  # names loaded on first use (hybrid's executors)
    assert len(module.__all__) == len(set(module.__all__)), f"{face}.__all__ repeats a name"
    assert set(module.__all__) - lazy == public - lazy, (
        f"{face}: public but not in __all__: {sorted(public - set(module.__all__))}; in __all__ but not defined: "
        f"{sorted(set(module.__all__) - public - lazy)}")
    for name in lazy & set(module.__all__):
        getattr(module, name)


def test_a_users_verification_needs_two_modules_the_worked_example_imports_from_hybrid_and_the_face():
    tree = ast.parse((ROOT / "examples" / "thermostat.py").read_text())
    modules = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module}
    modules |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    assert modules - {"__future__"} == {"hybrid", "analysis.verify"}


CLI_VOCABULARY = ("EXIT_", "--budget", "--seed", "--method", "--out", "--json", "--workers", "--variant", "--scenario",
                  "--requirement", "exit code")
"""Words of the command line: flags and exit codes belong to ``visnav.app`` alone."""
CLI_ALLOWED = {"analysis.testing"}
"""The pytest entry point's failure message says how to reproduce the search and replay its counterexample
with the command line (``visnav verify ... --seed ...``): a user-facing instruction, not a behaviour."""


def test_no_cli_vocabulary_below_the_application():
    offenders = []
    for module, path in MODULES.items():
        if module.startswith("visnav.app") or module in CLI_ALLOWED:
            continue
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Name) and node.id.startswith("EXIT_") or (
                    isinstance(node, ast.Constant) and isinstance(node.value, str)
                    and any(w in node.value for w in CLI_VOCABULARY[1:]) and not _is_docstring(tree, node)):
                offenders.append(f"{module}:{node.lineno}: {getattr(node, 'id', None) or node.value[:60]!r}")
    assert not offenders, "CLI words below visnav.app:\n" + "\n".join(offenders[:40])


def _is_docstring(tree: ast.AST, node: ast.Constant) -> bool:
    for parent in ast.walk(tree):
        body = getattr(parent, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr) and body[0].value is node:
            return True
    return False
