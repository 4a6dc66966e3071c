"""The package's shape: dependencies between uqdrape's parts point one way, and no module
reaches into another's private names. Every import counts, including those inside
functions (lazy imports hide a cycle from Python, not from this test)."""

from __future__ import annotations

import ast
from pathlib import Path

import uqdrape

PACKAGE = Path(uqdrape.__file__).parent


def _module_name(path: Path, root: Path = PACKAGE) -> str:
    parts = path.relative_to(root.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, root: Path = PACKAGE):
    """(imported module, names) of every import statement in ``path``, relative ones resolved."""
    name = _module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, []
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module
            yield target, [alias.name for alias in node.names]


def _part(module: str) -> str | None:
    """The part of uqdrape a module belongs to: ``uqdrape.<part>`` (None outside uqdrape)."""
    parts = module.split(".")
    if parts[0] != "uqdrape":
        return None
    return parts[1] if len(parts) > 1 else "uqdrape"


def _graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {}
    for path in PACKAGE.rglob("*.py"):
        source = _part(_module_name(path))
        for target, names in _imports(path):
            # "from . import geometry" names a part through the package itself
            candidates = [target] + [f"{target}.{n}" for n in names] if target == "uqdrape" else [target]
            for module in candidates:
                part = _part(module)
                if part not in (None, source, "uqdrape", "__version__"):
                    graph.setdefault(source, set()).add(part)
    return graph


def _cycle(graph):
    """One dependency cycle as a list of parts, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_no_import_cycle_between_the_parts_of_uqdrape():
    graph = _graph()
    assert {"study", "ensemble", "stats", "sensitivity", "report", "drape"} <= set(graph)
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))


def test_the_flow_points_down_from_the_cli():
    """cli -> {api, workflow} -> {design, export, report, sensitivity, ensemble, stats} -> drape
    and study -> {geometry, material, stochastic}: the cli imports only the API, the workflow
    and the worker pool (started before anything heavy is imported), nothing below imports
    the API, the workflow or the cli, the solver imports none of the study-level parts, and
    sensitivity and report never open the ensemble's chunk store."""
    graph = _graph()
    assert graph["cli"] == {"api", "workflow", "pool"}
    for part, targets in graph.items():
        assert "cli" not in targets, part
        if part not in ("cli", "api", "uqdrape"):
            assert not targets & {"api", "workflow"}, part
    assert not graph.get("drape", set()) & {"study", "ensemble", "stats", "sensitivity", "report", "workflow"}
    # the names, the netCDF conventions, the measured points, the file reader/writer and
    # the argument error sit below every part; a reader of measured points may use the
    # file reader, which imports nothing
    for bottom in ("schema", "conventions", "experimental", "files", "errors"):
        assert graph.get(bottom, set()) <= {"files", "_version", "errors"} - {bottom}, bottom
    for part in ("sensitivity", "report"):
        assert "ensemble" not in graph.get(part, set()), part


def test_no_private_name_is_imported_from_another_module():
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        for target, names in _imports(path):
            if _part(target) is not None:
                offenders += [f"{_module_name(path)}: from {target} import {n}" for n in names
                              if n.startswith("_") and n != "__version__"]
    assert offenders == []


README = PACKAGE.parent / "docs" / "developer.md"  # the documentation's layout page
GRAPH_START, GRAPH_END = "<!-- import graph: tests/test_layout.py checks it -->", "<!-- end of import graph -->"


def _readme_graph() -> dict[str, set[str]]:
    """The import graph docs/developer.md draws: one ``part -> part, part`` line per importing part."""
    text = README.read_text(encoding="utf-8")
    block = text[text.index(GRAPH_START) + len(GRAPH_START):text.index(GRAPH_END)]
    graph, part = {}, None
    for line in block.splitlines():
        if "->" in line:  # a part and its targets; an indented line without "->" continues them
            part, _, line = line.partition("->")
            part = part.strip()
        if part is not None and line.strip() and not line.startswith("`"):
            graph.setdefault(part, set()).update(t.strip() for t in line.split(",") if t.strip())
    return graph


def test_the_import_graph_is_the_one_readme_draws():
    graph = _graph()
    print("\n".join(f"{part:12s} -> {', '.join(sorted(targets))}" for part, targets in sorted(graph.items())))
    assert graph == _readme_graph()


def test_the_study_spec_is_at_the_bottom():
    """Reading a study file drapes, analyses, samples an ensemble and reports nothing."""
    graph = _graph()
    below = set()
    todo = ["study"]
    while todo:  # everything the study layer reaches, directly or not
        for target in graph.get(todo.pop(), ()):
            if target not in below:
                below.add(target)
                todo.append(target)
    assert not below & {"drape", "stats", "sensitivity", "report", "ensemble", "design", "workflow", "export"}, below


def _module_graph(root: Path = PACKAGE) -> dict[str, set[str]]:
    """The import graph between the modules under the package folder ``root``, every
    import counted (those inside functions too): ``from p import name`` is an edge to the
    module ``p.name`` where that is a module, else to ``p`` itself (its ``__init__``)."""
    paths = {_module_name(path, root): path for path in root.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in paths.items():
        for target, names in _imports(path, root):
            for module in [f"{target}.{n}" if f"{target}.{n}" in paths else target for n in names] or [target]:
                if module in paths and module != name:
                    graph.setdefault(name, set()).add(module)
    return graph


def test_no_import_cycle_between_the_modules_of_uqdrape():
    graph = _module_graph()
    assert {"uqdrape.ensemble.run", "uqdrape.ensemble.storage", "uqdrape.workflow.run"} <= set(graph)
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))


def test_the_module_cycle_check_finds_a_cycle_hidden_in_a_function(tmp_path):
    """A planted circle a -> b -> a, b's import inside a function (as Python lets it
    pass at import time), is found; without it there is none."""
    package = tmp_path / "planted"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from .b import g\n\n\ndef f():\n    return g()\n")
    (package / "b.py").write_text("def g():\n    return 1\n")
    assert _cycle(_module_graph(package)) is None
    (package / "b.py").write_text("def g():\n    from . import a\n\n    return a\n")
    assert _cycle(_module_graph(package)) == ["planted.a", "planted.b", "planted.a"]
