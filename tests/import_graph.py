"""The package's import graph by pipeline stage, and the rules it keeps.

Run ``python tests/import_graph.py`` to print the graph (the listing in ARCHITECTURE.md);
``tests/test_layout.py`` checks the rules: no module over 600 lines, no import cycle, and no import
from a later stage into an earlier one.
"""

from __future__ import annotations

import ast
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: stages in data-flow order; a module may import only from its own stage or earlier ones.
#: ``kernels`` and ``runtime`` (quiet Warp start-up, graph capture, progress lines) come first;
#: ``centerline`` and ``surface`` are siblings; ``extract`` reads meshes into scenes; ``bench``,
#: ``batch`` and ``cli`` sit on top.
STAGES = {
    "kernels": 0,
    "runtime": 0,
    "version": 0,
    "scene": 1,
    "model": 2,
    "centerline": 3,
    "surface": 3,
    "extract": 3,
    "sim": 4,
    "io": 5,
    "batch": 6,
    "bench": 6,
    "cli": 7,
    "__main__": 7,
    "__init__": 7,
}


def modules() -> dict[str, pathlib.Path]:
    """Dotted module name (``warp_tube.x.y``) -> file, for the package and its kernels."""
    out = {}
    for path in sorted((ROOT / "warp_tube").rglob("*.py")):
        rel = path.relative_to(ROOT / "warp_tube").with_suffix("")
        parts = [p for p in rel.parts if p != "__init__"] if rel.name == "__init__" else list(rel.parts)
        out[".".join(["warp_tube", *parts])] = path
    for path in sorted((ROOT / "kernels").glob("*.py")):
        name = "warp_tube.kernels" if path.stem == "__init__" else f"warp_tube.kernels.{path.stem}"
        out[name] = path
    return out


def imports(name: str, path: pathlib.Path, known: set[str]) -> set[str]:
    """Modules of the package that ``name`` imports (at any depth in the file)."""
    is_pkg = path.name == "__init__.py"
    package = name if is_pkg else name.rpartition(".")[0]
    found = set()
    tree = ast.parse(path.read_text())
    # imports for type checkers only (``if TYPE_CHECKING:``) do not run: not part of the graph
    typing_only = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            typing_only.update(id(n) for stmt in node.body for n in ast.walk(stmt))
    for node in ast.walk(tree):
        if id(node) in typing_only:
            continue
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            candidates = [target] + [f"{target}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            candidates = [a.name for a in node.names]
        else:
            continue
        for c in candidates:
            if c in known and c != name:
                found.add(c)
    return found


def stage(name: str) -> str:
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {name: imports(name, path, known) for name, path in mods.items()}


def stage_graph() -> dict[str, set[str]]:
    """Stage -> the stages it imports from."""
    out: dict[str, set[str]] = {}
    for a, targets in graph().items():
        out.setdefault(stage(a), set()).update(stage(b) for b in targets if stage(b) != stage(a))
    return out


def cycles() -> list[list[str]]:
    """Import cycles between modules (each as the list of modules on it)."""
    g = graph()
    seen, stack, on_stack, found = set(), [], set(), []

    def visit(n):
        seen.add(n)
        stack.append(n)
        on_stack.add(n)
        for m in sorted(g[n]):
            if m in on_stack:
                found.append(stack[stack.index(m):] + [m])
            elif m not in seen:
                visit(m)
        stack.pop()
        on_stack.discard(n)

    for n in sorted(g):
        if n not in seen:
            visit(n)
    return found


def backward_imports() -> list[str]:
    """Imports from a later stage into an earlier one, as 'a -> b' lines."""
    bad = []
    for a, targets in graph().items():
        for b in targets:
            # a package's __init__ re-exporting its own modules is not an import across stages
            if STAGES[stage(b)] > STAGES[stage(a)]:
                bad.append(f"{a} -> {b}")
    return sorted(bad)


def long_modules(limit: int = 600) -> list[str]:
    return [f"{n} ({len(p.read_text().splitlines())} lines)" for n, p in modules().items()
            if len(p.read_text().splitlines()) > limit]


def main() -> int:
    sg = stage_graph()
    order = sorted(sg, key=lambda s: (STAGES[s], s))
    print("stage (rank): imports from")
    for s in order:
        deps = sorted(sg[s], key=lambda d: (STAGES[d], d))
        print(f"  {s} ({STAGES[s]}): {', '.join(deps) if deps else '-'}")
    problems = cycles() + backward_imports() + long_modules()
    for p in problems:
        print("problem:", p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
