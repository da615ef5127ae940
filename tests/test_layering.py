"""The architecture, checked from the source: data flows one way, the papers stay apart.

Parses every module of ``repro`` with :mod:`ast` (imports inside functions count too, so a
cycle cannot hide behind a lazy import) and checks:

* the library (the two papers' packages and the shared ground) never imports presentation,
  measurement or command-line layers, and never imports matplotlib, pyvista or ipywidgets
  at module level;
* the two papers share only the shared ground (errors, checks, io, data);
* no private name (``_x``) is imported from another module;
* the import graph of ``repro`` has no cycle.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "repro"

#: the shared ground both papers may use
SHARED = {"repro", "repro.errors", "repro.checks", "repro.io", "repro.data", "repro.processes"}
#: the two papers' library packages
PAPERS = ("repro.blendshapes", "repro.motion")
#: layers above the library: figures, measurements, ledger, user interface, command line
UPPER = (
    "repro.experiments",
    "repro.claims",
    "repro.bench",
    "repro.cli",
    "repro.__main__",
    "repro.ui",
)
PRESENTATION = ("matplotlib", "pyvista", "vtk", "ipywidgets", "IPython", "tqdm.notebook")


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, tuple[Path, ast.Module]]:
    out = {}
    for path in sorted(ROOT.rglob("*.py")):
        out[_module_name(path)] = (path, ast.parse(path.read_text(encoding="utf-8"), str(path)))
    return out


MODULES = _modules()


def _is_package(name: str) -> bool:
    return MODULES[name][0].name == "__init__.py" if name in MODULES else False


def _resolve(module: str, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".")
    if not _is_package(module):
        base = base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _imports(module: str, tree: ast.Module, *, typing_only_too: bool = False):
    """(target module, imported name or None, line, at module level?) for every import.

    Imports under ``if TYPE_CHECKING:`` are for annotations only (never run): skipped, except
    with ``typing_only_too`` (the cycle check: a circle of type-only imports is still a circle
    a reader has to untangle).
    """
    top = {id(n) for n in tree.body}
    typing_only = {
        id(sub)
        for node in ast.walk(tree)
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)
        for stmt in node.body
        for sub in ast.walk(stmt)
    }
    for node in ast.walk(tree):
        if id(node) in typing_only and not typing_only_too:
            continue
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, None, node.lineno, id(node) in top
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(module, node)
            for a in node.names:
                sub = f"{target}.{a.name}"
                if sub in MODULES:
                    yield sub, None, node.lineno, id(node) in top
                else:
                    yield target, a.name, node.lineno, id(node) in top


def _within(name: str, prefixes) -> bool:
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def _paper(name: str) -> str | None:
    return next((p for p in PAPERS if _within(name, [p])), None)


def _violations(rule) -> list[str]:
    out = []
    for module, (path, tree) in MODULES.items():
        for target, name, line, top in _imports(module, tree):
            why = rule(module, target, name, top)
            if why:
                out.append(f"{path.relative_to(ROOT.parent)}:{line}: {module} imports {target}"
                           f"{'.' + name if name else ''}: {why}")
    return out


def _library(module: str) -> bool:
    return _paper(module) is not None or module in SHARED - {"repro"}


def test_library_never_imports_upper_layers():
    def rule(module, target, name, top):
        if not _library(module):
            return None
        if _within(target, UPPER):
            return "the library must not import figures, claims, benchmarks, ui or the CLI"
        if top and _within(target, PRESENTATION):
            return "the library must not import presentation packages at module level"
        return None

    found = _violations(rule)
    assert not found, "\n".join(found)


def test_papers_share_only_errors_io_data():
    def rule(module, target, name, top):
        mine, theirs = _paper(module), _paper(target)
        if mine and theirs and mine != theirs:
            return "the two papers share only repro.errors, repro.io and repro.data"
        if module in SHARED - {"repro"} and theirs:
            return "the shared ground must not depend on either paper"
        return None

    found = _violations(rule)
    assert not found, "\n".join(found)


def test_no_private_name_imported_across_modules():
    def rule(module, target, name, top):
        if target.startswith("repro") and name and name.startswith("_") and not name.startswith("__"):
            return "private names stay in their module (make it public, or move it where both need it)"
        return None

    found = _violations(rule)
    assert not found, "\n".join(found)


def test_no_import_cycle():
    graph: dict[str, set[str]] = {m: set() for m in MODULES}
    for module, (_, tree) in MODULES.items():
        for target, _name, _line, _top in _imports(module, tree, typing_only_too=True):
            if target in MODULES and target != module:
                # a package's own __init__ importing its submodules is how packages work;
                # the reverse (a submodule importing its package) would make a cycle
                graph[module].add(target)
    # Tarjan's strongly connected components, iteratively
    index, low, on, stack, comps, counter = {}, {}, set(), [], [], [0]
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        comps.append(sorted(comp))
    assert comps == [], f"import cycles (type-only imports count): {comps}"


@pytest.mark.parametrize("bad", ["from repro.motion.io.bvh import _read_bytes", "from repro.ui.face_panel import X"])
def test_rules_detect_violations(bad, tmp_path):
    """The checks are not vacuous: a planted violation is found."""
    tree = ast.parse(bad)
    found = list(_imports("repro.blendshapes.model", tree))
    assert found, bad
    target, name, _, top = found[0]
    assert top
    assert (name or "").startswith("_") or _within(target, UPPER)
