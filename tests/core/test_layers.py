"""The package's import graph: no circle, and no arrow from a lower layer to a higher one.

From the bottom: ``core`` (bpy-free: the method) and ``version`` (one constant); the worker processes (``worker``,
``preview_worker``) and ``farm`` (bpy-free: the stages of a farm job); ``blender`` (the
add-on, which reaches ``farm`` in ``blender.farm``); the package's top, whose
``register`` Blender calls; ``cli``, the command line; ``__main__``, which only dispatches.
Every import counts, the ones inside functions and those only type checkers read too.
"""

import ast
import pathlib

PACKAGE = "keyframe_implicit"
SOURCE = pathlib.Path(__file__).resolve().parents[2] / PACKAGE


def _modules():
    """{module name: path} of every module of the package."""
    found = {}
    for path in SOURCE.rglob("*.py"):
        parts = (PACKAGE,) + path.relative_to(SOURCE).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def _imports(name, path, modules):
    """The package's modules ``name`` imports."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    targets = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{anchor}.{base}" if base else anchor
            targets += [f"{base}.{alias.name}" for alias in node.names]
    found = set()
    for target in targets:
        while target and target not in modules:  # a name imported from a module: the module
            target = target.rpartition(".")[0]
        if target and target != name:
            found.add(target)
    return found


def _graph():
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def _cycle(graph):
    """One circle of imports as a list of modules, or None."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = "done"
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def _in(name, *packages):
    return any(name == p or name.startswith(p + ".") for p in packages)


def _arrows(graph, source, allowed):
    """Imports of modules in ``source`` that go outside ``allowed``."""
    return sorted((a, b) for a, b_set in graph.items() if _in(a, source)
                  for b in b_set if not _in(b, *allowed))


def test_the_graph_is_read_whole():
    graph = _graph()
    assert f"{PACKAGE}.core.fields.sdf" in graph and f"{PACKAGE}.cli.farm" in graph
    assert f"{PACKAGE}.core.fields.mesh" in graph[f"{PACKAGE}.core.fields.sdf"]
    assert f"{PACKAGE}.cli.farm" in graph[f"{PACKAGE}.__main__"]  # imported in a function


def test_no_module_imports_itself_through_others():
    assert _cycle(_graph()) is None, " -> ".join(_cycle(_graph()))


def test_the_core_imports_nothing_above_it():
    assert _arrows(_graph(), f"{PACKAGE}.core", [f"{PACKAGE}.core"]) == []


def test_the_farm_and_the_workers_stay_below_blender_and_the_command_line():
    graph = _graph()
    below = [f"{PACKAGE}.core", f"{PACKAGE}.farm", f"{PACKAGE}.worker", f"{PACKAGE}.version"]
    assert _arrows(graph, f"{PACKAGE}.farm", below) == []
    assert _arrows(graph, f"{PACKAGE}.worker", below) == []
    assert _arrows(graph, f"{PACKAGE}.preview_worker", below) == []


def test_only_main_imports_the_command_line_and_nothing_imports_main():
    graph = _graph()
    users = {a for a, b_set in graph.items() for b in b_set if _in(b, f"{PACKAGE}.cli")}
    assert users - {f"{PACKAGE}.__main__"} <= {m for m in graph if _in(m, f"{PACKAGE}.cli")}
    assert not [a for a, b_set in graph.items() if f"{PACKAGE}.__main__" in b_set]
