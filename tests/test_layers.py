"""flowkit's modules in layers: no module imports one of a higher layer, and no import circle.

Each module's imports are read with ``ast`` (those inside functions too, relative ones resolved;
``from P import name`` counts as importing the module ``P.name`` where there is one, else ``P``).
Imports by a name computed at run time (``importlib.import_module``, ``python -m``) are not seen.
Each module gets the layer of the longest name in ``LAYERS`` that is the module or a package
above it (the package root only names itself); a module no entry places fails the test, so that
a new package is placed when it is added.
"""

from __future__ import annotations

import ast
from pathlib import Path

import flowkit

ROOT = "flowkit"

# lowest first; a module may import its own layer and the layers below it
LAYERS = (
    # compiling and running kernels: flowkit's use of numba, its disk cache, the second compile
    # process and its table, threads; every kernel above builds on them
    ("runtime", ("flowkit.jit", "flowkit.numba_private", "flowkit.numba_cache",
                 "flowkit.compile_notice", "flowkit.parallel_compile", "flowkit.helper_sigs",
                 "flowkit.threads")),
    # the types the rest share: a field (its grid, storage, bricks and interpolant), lines and
    # why they stopped, the integrators' columns; and the PyVista bridge that Lines calls
    ("core", ("flowkit.fields.grid", "flowkit.fields.field", "flowkit.fields.stored",
              "flowkit.fields.bricks", "flowkit.fields.interp", "flowkit.lines",
              "flowkit.integrate.reasons", "flowkit.integrate.schema", "flowkit.io.pyvista_io")),
    ("io", ("flowkit.io",)),
    ("fields", ("flowkit.fields", "flowkit.datasets")),
    ("integrate", ("flowkit.integrate",)),
    # seed points and specs (integrate.seeds, at the path users import) draw from seeding.data
    ("seeding", ("flowkit.seeding", "flowkit.integrate.seeds")),
    ("render", ("flowkit.render",)),
    ("api", (ROOT,)),  # `import flowkit`: flowkit.trace, flowkit.Field, ...
    ("distributed", ("flowkit.distributed",)),
    ("scene", ("flowkit.scene",)),
    ("view", ("flowkit.view",)),
    # commands, and the tooling that compiles or traces through everything below
    ("cli", ("flowkit.cli", "flowkit.__main__", "flowkit.distributed.cli", "flowkit.warmup",
             "flowkit.write_helper_sigs")),
)

def modules(folder: Path, root: str) -> dict[str, tuple[Path, bool]]:
    """Dotted name -> (file, is a package) for every module of the package in ``folder``."""
    out = {}
    for path in sorted(folder.rglob("*.py")):
        parts = [root, *path.relative_to(folder).with_suffix("").parts]
        package = parts[-1] == "__init__"
        out[".".join(parts[:-1] if package else parts)] = (path, package)
    return out


def imports(folder: Path, root: str) -> dict[str, dict[str, int]]:
    """module -> {module of the package it imports: first line that does}."""
    mods = modules(folder, root)

    def known(name: str) -> str | None:  # the module itself, else the package it is a name of
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for name, (path, package) in mods.items():
        here = name if package else name.rpartition(".")[0]
        found = {}
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = here.split(".")[:len(here.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base
                           for a in node.names]
            else:
                continue
            for t in targets:
                if t.split(".")[0] == root and (m := known(t)) and m != name:
                    found.setdefault(m, node.lineno)
        graph[name] = found
    return graph


def circles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's, iterative)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    for start, targets in graph.items():
        if start in index:
            continue
        work = [(start, iter(targets))]
        index[start] = low[start] = len(index)
        stack.append(start)
        on.add(start)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(graph[w])))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while not comp or comp[-1] != v:
                        comp.append(stack.pop())
                        on.discard(comp[-1])
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def layer_of(name: str, layers=LAYERS, root: str = ROOT) -> int | None:
    best = None
    for rank, (_, keys) in enumerate(layers):
        for key in keys:
            if (name == key or (key != root and name.startswith(key + "."))) and (
                    best is None or len(key) > len(best[1])):
                best = (rank, key)
    return None if best is None else best[0]


def upward(graph, layers=LAYERS, root: str = ROOT) -> list[str]:
    """Each import of a module of a higher layer, as a line naming both."""
    name = [n for n, _ in layers]
    out = []
    for m, targets in sorted(graph.items()):
        for t, line in sorted(targets.items()):
            a, b = layer_of(m, layers, root), layer_of(t, layers, root)
            if a is not None and b is not None and a < b:
                out.append(f"{m} ({name[a]}) imports {t} ({name[b]}), line {line}")
    return out


def _describe(circle, graph) -> str:
    edges = [f"{m}:{graph[m][t]} -> {t}" for m in circle for t in sorted(graph[m]) if t in circle]
    return "circle " + ", ".join(circle) + "\n    " + "\n    ".join(edges)


GRAPH = imports(Path(flowkit.__file__).parent, ROOT)


def test_every_module_has_a_layer_and_every_entry_a_module():
    unplaced = sorted(m for m in GRAPH if layer_of(m) is None)
    assert not unplaced, f"modules without a layer (add them to LAYERS): {unplaced}"
    stale = [k for _, keys in LAYERS for k in keys if k not in GRAPH]
    assert not stale, f"LAYERS names what is not a module: {stale}"


def test_no_module_imports_a_higher_layer():
    bad = upward(GRAPH)
    assert not bad, "imports from a lower layer into a higher one:\n" + "\n".join(bad)


def test_no_import_circle():
    found = circles(GRAPH)
    assert not found, "import circles:\n" + "\n".join(_describe(c, GRAPH) for c in found)


def test_the_checks_catch_an_upward_import_and_a_circle(tmp_path):
    """On a made-up package: a low module that imports a high one inside a function, and a
    relative import back."""
    pkg = tmp_path / "pkg"
    (pkg / "top").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "top" / "__init__.py").write_text("from .view import show\n")
    (pkg / "top" / "view.py").write_text("from ..low import helper\n\ndef show():\n    pass\n")
    (pkg / "low.py").write_text("def helper():\n    from pkg.top import show\n")
    graph = imports(pkg, "pkg")
    assert graph["pkg.low"] == {"pkg.top": 2} and graph["pkg.top.view"] == {"pkg.low": 1}
    layers = (("low", ("pkg.low",)), ("top", ("pkg.top", "pkg")))
    assert upward(graph, layers, "pkg") == ["pkg.low (low) imports pkg.top (top), line 2"]
    assert circles(graph) == [["pkg.low", "pkg.top", "pkg.top.view"]]
