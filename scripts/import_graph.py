"""The packages' import graph: cycles, arrows against the layers, and the largest modules and functions.

Every ``import`` of the packages' own modules counts, at module level or inside a function (a lazy
import still ties the two modules together). The layers, lowest first, and the arrows they forbid are
in ``RULES``; a module may import anything below it and nothing above. ``REACH_RULES`` forbid a
chain of imports (e.g. the runtime reaching torch through a module that imports it lazily).
``tests/tactile_learn/test_import_graph.py`` holds the repository to these rules.

    python scripts/import_graph.py                 # report; exit 1 on a cycle, forbidden arrow or chain
    python scripts/import_graph.py --dot graph.dot # also the graph for Graphviz (dot -Tsvg graph.dot)
    python scripts/import_graph.py --sizes 15      # the 15 largest modules and functions
"""

from __future__ import annotations

import argparse
import ast
import fnmatch
import sys
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from synth.io import atomic_write_json

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("synth", "tactile_learn")

#: (importer pattern, imported pattern, why it is forbidden); patterns are fnmatch over dotted names.
#: Importers matching ``EXEMPT`` of the imported pattern are allowed (the CLI's own modules).
RULES: tuple[tuple[str, str, str], ...] = (
    ("synth*", "tactile_learn*", "synth is the physics layer: it knows nothing of learning"),
    ("synth*", "torch*", "synth is numpy/scipy only"),
    ("tactile_learn.*", "tactile_learn.cli*", "only the CLI imports the CLI"),
    ("tactile_learn.estimators*", "tactile_learn.tasks*", "estimators sit below tasks"),
    ("tactile_learn.estimators*", "tactile_learn.methods", "estimators sit below the method loader"),
    ("tactile_learn.estimators.classical*", "torch*", "classical estimators run without torch"),
    ("tactile_learn.runtime*", "torch*", "a deployment installs numpy and onnxruntime only"),
    ("tactile_learn.validation*", "tactile_learn.tasks*", "input checks sit below tasks"),
    ("tactile_learn.*", "torch*", "torch only where training and export happen"),
)
#: importers allowed an arrow that a rule's imported pattern forbids (patterns over dotted names)
EXEMPT: dict[str, tuple[str, ...]] = {
    "tactile_learn.cli*": ("tactile_learn.cli*",),  # the CLI's own modules
    "torch*": (  # training, export and the torch-eager bench backend; never the runtime or classical path
        "tactile_learn.train*",
        "tactile_learn.export",
        "tactile_learn.checkpoints",
        "tactile_learn.distributed",
        "tactile_learn.torch_estimator",
        "tactile_learn.nets*",
        "tactile_learn.bench",
        "tactile_learn.sweep",
        "tactile_learn.object_tomography",  # fitting a learned object's template: training time
        "tactile_learn.learn_object",  # renders, fine-tunes and exports a learned object
    ),
}
#: (start pattern, target pattern, why): no chain of imports from ``start`` may reach ``target``,
#: lazy imports included (a function-level import still runs in a deployment that calls it)
REACH_RULES: tuple[tuple[str, str, str], ...] = (
    ("tactile_learn.runtime*", "torch*", "a deployment installs numpy and onnxruntime only"),
    ("tactile_learn.estimators.classical*", "torch*", "classical estimators run without torch"),
    ("synth*", "tactile_learn*", "synth is the physics layer: it knows nothing of learning"),
)


@dataclass
class Module:
    name: str
    path: Path
    lines: int
    imports: dict[str, bool] = field(default_factory=dict)  # imported module -> lazy (inside a function)
    functions: list[tuple[str, int]] = field(default_factory=list)  # (qualified name, lines)


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(target: str, known: set[str]) -> str:
    """The longest known module that ``target`` names or lies in (``synth.scene.load_scene`` ->
    ``synth.scene``); external names keep their top-level package."""
    parts = target.split(".")
    for n in range(len(parts), 0, -1):
        candidate = ".".join(parts[:n])
        if candidate in known:
            return candidate
    return parts[0]


def _imports(tree: ast.Module, name: str, is_package: bool) -> Iterable[tuple[str, bool]]:
    """(dotted target, lazy) for every import statement; ``from a import b`` yields ``a.b``."""
    lazy_nodes: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            lazy_nodes.update(id(n) for n in ast.walk(node) if n is not node)
    for node in ast.walk(tree):
        lazy = id(node) in lazy_nodes
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, lazy
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative import: anchor at this module's package
                base = name.split(".") if is_package else name.split(".")[:-1]
                base = base[: len(base) - (node.level - 1)]
                prefix = ".".join([*base, node.module] if node.module else base)
            else:
                prefix = node.module or ""
            if node.module and node.module.split(".")[0] == "typing":
                continue
            for alias in node.names:
                yield f"{prefix}.{alias.name}", lazy


def _functions(tree: ast.Module) -> list[tuple[str, int]]:
    out = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                qual = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    out.append((qual, (child.end_lineno or child.lineno) - child.lineno + 1))
                visit(child, qual + ".")

    visit(tree, "")
    return out


def _in_type_checking(tree: ast.Module) -> set[int]:
    """Nodes under ``if TYPE_CHECKING:``: annotations only, never executed."""
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                skip.update(id(n) for n in ast.walk(child))
    return skip


def build(root: Path = ROOT, packages: Iterable[str] = PACKAGES) -> dict[str, Module]:
    """Every module of ``packages`` (folders under ``root``) with its imports and function sizes."""
    paths = sorted(p for pkg in packages for p in (root / pkg).rglob("*.py"))
    known = {module_name(p, root) for p in paths}
    modules: dict[str, Module] = {}
    for path in paths:
        text = path.read_text(encoding="utf-8")
        tree = ast.parse(text)
        name = module_name(path, root)
        mod = Module(name, path, len(text.splitlines()), functions=_functions(tree))
        skip = _in_type_checking(tree)
        typed_only = {
            alias.name if isinstance(n, ast.Import) else f"{n.module}.{alias.name}"
            for n in ast.walk(tree)
            if id(n) in skip and isinstance(n, ast.Import | ast.ImportFrom)
            for alias in n.names
        }
        for target, lazy in _imports(tree, name, path.name == "__init__.py"):
            if target in typed_only:
                continue
            dest = _resolve(target, known)
            if dest == name:
                continue
            # an eager import wins over a lazy one of the same module
            mod.imports[dest] = mod.imports.get(dest, True) and lazy
        modules[name] = mod
    return modules


def cycles(modules: dict[str, Module]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = [0]

    def strong(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in modules[v].imports:
            if w not in modules:
                continue
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    sys.setrecursionlimit(max(10_000, sys.getrecursionlimit()))
    for v in sorted(modules):
        if v not in index:
            strong(v)
    return sorted(found)


def violations(
    modules: dict[str, Module],
    rules: Iterable[tuple[str, str, str]] = RULES,
    exempt: dict[str, tuple[str, ...]] | None = None,
) -> list[tuple[str, str, str]]:
    """(importer, imported, rule) for every arrow that ``rules`` forbid."""
    exempt = EXEMPT if exempt is None else exempt
    out = []
    for mod in modules.values():
        for dest in mod.imports:
            for src_pat, dst_pat, why in rules:
                if any(fnmatch.fnmatchcase(mod.name, allowed) for allowed in exempt.get(dst_pat, ())):
                    continue
                if fnmatch.fnmatchcase(mod.name, src_pat) and fnmatch.fnmatchcase(dest, dst_pat):
                    out.append((mod.name, dest, why))
    return sorted(out)


def reach_violations(
    modules: dict[str, Module], rules: Iterable[tuple[str, str, str]] = REACH_RULES
) -> list[tuple[str, str, str]]:
    """(start, chain of imports ``a -> b -> target``, rule) for every module matching a rule's
    start pattern from which some chain of imports, lazy ones included, reaches its target."""
    out = []
    for src_pat, dst_pat, why in rules:
        for start in sorted(m for m in modules if fnmatch.fnmatchcase(m, src_pat)):
            parent: dict[str, str] = {start: ""}
            queue = [start]
            hit = None
            while queue and hit is None:  # breadth first: the shortest chain is the one reported
                current = queue.pop(0)
                for dest in sorted(modules[current].imports if current in modules else ()):
                    if dest in parent:
                        continue
                    parent[dest] = current
                    if fnmatch.fnmatchcase(dest, dst_pat):
                        hit = dest
                        break
                    queue.append(dest)
            if hit is not None:
                chain = [hit]
                while parent[chain[-1]]:
                    chain.append(parent[chain[-1]])
                out.append((start, " -> ".join(reversed(chain)), why))
    return sorted(out)


def dot(modules: dict[str, Module]) -> str:
    lines = ["digraph imports {", "  rankdir=BT; node [shape=box, fontsize=10];"]
    for mod in sorted(modules.values(), key=lambda m: m.name):
        for dest, lazy in sorted(mod.imports.items()):
            if dest in modules:
                style = " [style=dashed]" if lazy else ""
                lines.append(f'  "{mod.name}" -> "{dest}"{style};')
    lines.append("}")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dot", help="write the graph in Graphviz format to this file")
    parser.add_argument("--json", help="write cycles, violations and sizes as JSON to this file")
    parser.add_argument("--sizes", type=int, default=10, help="how many of the largest modules/functions to list")
    args = parser.parse_args(argv)

    modules = build()
    found_cycles = cycles(modules)
    bad = violations(modules)
    reached = reach_violations(modules)
    n_edges = sum(1 for m in modules.values() for d in m.imports if d in modules)
    largest_modules = sorted(((m.lines, m.name) for m in modules.values()), reverse=True)[: args.sizes]
    largest_functions = sorted(((n, f"{m.name}:{f}") for m in modules.values() for f, n in m.functions), reverse=True)[
        : args.sizes
    ]

    print(f"{len(modules)} modules, {n_edges} internal imports")
    print(f"cycles: {len(found_cycles)}")
    for comp in found_cycles:
        print("  " + " <-> ".join(comp))
    print(f"forbidden arrows: {len(bad)}")
    for src, dst, why in bad:
        print(f"  {src} -> {dst}  ({why})")
    print(f"forbidden chains: {len(reached)}")
    for _start, chain, why in reached:
        print(f"  {chain}  ({why})")
    print("largest modules (lines):")
    for n, name in largest_modules:
        print(f"  {n:5d}  {name}")
    print("largest functions (lines):")
    for n, name in largest_functions:
        print(f"  {n:5d}  {name}")
    if args.dot:
        Path(args.dot).write_text(dot(modules), encoding="utf-8")
    if args.json:
        report = {
            "cycles": found_cycles,
            "violations": [list(v) for v in bad],
            "chains": [list(v) for v in reached],
            "largest_modules": largest_modules,
            "largest_functions": largest_functions,
        }
        atomic_write_json(args.json, report)
    return 1 if found_cycles or bad or reached else 0


if __name__ == "__main__":
    raise SystemExit(main())
