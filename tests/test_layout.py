"""The package's layers: imports point down only (cli → plotting → timedomain → spectrum → steady,
dynamics → core), and no module imports itself back through others."""
import ast
import os

import pytest

import slippulse

PKG = os.path.dirname(slippulse.__file__)
#: rank of each subpackage; a module may import from a lower rank, or from its own subpackage
LAYER = {"core": 0, "steady": 1, "dynamics": 1, "spectrum": 2, "timedomain": 3, "plotting": 4,
         "cli": 5, "__main__": 6}                    # ``python -m slippulse``: the entry point, above cli


def _modules():
    out = {}
    for root, _, files in os.walk(PKG):
        for f in files:
            if f.endswith(".py"):
                rel = os.path.relpath(os.path.join(root, f), PKG)[:-3].replace(os.sep, ".")
                out[rel.removesuffix(".__init__") if rel != "__init__" else ""] = \
                    os.path.join(root, f)
    return out


def _imports(name, path, known):
    """Dotted names (relative to slippulse) of the package modules that ``name`` imports,
    function-level imports included."""
    is_pkg = path.endswith("__init__.py")
    here = name.split(".") if is_pkg else name.split(".")[:-1]
    deps = set()
    for node in ast.walk(ast.parse(open(path, encoding="utf-8").read())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[: len(here) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            elif (node.module or "").startswith("slippulse"):
                mod = node.module[len("slippulse."):] if node.module != "slippulse" else ""
            else:
                continue
            for a in node.names:
                cand = f"{mod}.{a.name}" if mod else a.name
                deps.add(cand if cand in known else mod)
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("slippulse."):
                    deps.add(a.name[len("slippulse."):])
    return {d for d in deps if d in known and d != name}


@pytest.fixture(scope="module")
def graph():
    mods = _modules()
    return {m: _imports(m, p, mods) for m, p in mods.items()}


def test_every_module_sits_in_a_layer(graph):
    loose = [m for m in graph if m and m.split(".")[0] not in LAYER]
    assert loose == [], f"modules outside the layers {sorted(LAYER)}: {loose}"


def test_imports_point_down_only(graph):
    bad = []
    for m, deps in graph.items():
        if not m:                                  # the package root re-exports core names
            assert all(d.split(".")[0] == "core" for d in deps), deps
            continue
        sub = m.split(".")[0]
        for d in deps:
            top = d.split(".")[0] if d else ""
            if top == sub or d == "":              # the root (``__version__``) imports core only
                continue
            if top not in LAYER or LAYER[top] >= LAYER[sub]:
                bad.append(f"{m} -> {d}")
    assert bad == []


def test_no_import_circle(graph):
    seen, stack, circles = {}, [], []

    def visit(u):
        seen[u] = 1
        stack.append(u)
        for v in sorted(graph[u]):
            if seen.get(v) == 1:
                circles.append(stack[stack.index(v):] + [v])
            elif v not in seen:
                visit(v)
        stack.pop()
        seen[u] = 2

    for u in sorted(graph):
        if u not in seen:
            visit(u)
    # a package __init__ importing its own modules is not a circle of code
    circles = [c for c in circles if not any(x == "" or x in LAYER for x in c)]
    assert circles == []


def test_the_checker_sees_an_upward_import(tmp_path):
    """The graph builder finds function-level and relative imports (so the tests above can fail)."""
    src = tmp_path / "m.py"
    src.write_text("def f():\n    from ..plotting.steady import fig1\n    from . import seeding\n")
    known = {"plotting.steady", "timedomain.seeding", "timedomain.m"}
    assert _imports("timedomain.m", str(src), known) == {"plotting.steady", "timedomain.seeding"}
