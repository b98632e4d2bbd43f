"""The package's import graph is layered: a package imports only the packages below it.

Every import counts, at module level or inside a function, and those only for type checking
too: a lazy import that climbs the layers is still a cycle, hidden.
"""

from __future__ import annotations

import ast
from pathlib import Path

import wbcbench

ROOT = Path(wbcbench.__file__).resolve().parent

#: wbcbench's packages (and top-level modules), lowest first
LAYERS: tuple[str, ...] = (
    "errors",
    "plugins",
    "robots",
    "dynamics",
    "_native",
    "qp",
    "tasks",
    "metrics",
    "scenarios",
    "controllers",
    "peers",
    "runs",
    "sim",
    "bench",
    "report",
    "api",
    "cli",
    "__init__",
    "__main__",
)


def package_of(module: str) -> str:
    """``wbcbench.qp.registry`` → ``qp``; ``wbcbench`` → ``__init__``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def imported(path: Path) -> set[str]:
    """The wbcbench modules a file imports, anywhere in it."""
    module = ".".join(path.relative_to(ROOT.parent).with_suffix("").parts)
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            if base == "wbcbench":  # from wbcbench import _native
                out |= {f"wbcbench.{alias.name}" for alias in node.names}
            else:
                out.add(base)
    return {m for m in out if m == "wbcbench" or m.startswith("wbcbench.")}


def edges() -> list[tuple[str, str, str]]:
    """``(file, importing package, imported package)`` for every import across packages."""
    out = []
    for path in sorted(ROOT.rglob("*.py")):
        here = package_of(".".join(path.relative_to(ROOT.parent).with_suffix("").parts))
        for target in imported(path):
            there = package_of(target)
            if there != here:
                out.append((str(path.relative_to(ROOT.parent)), here, there))
    return out


def test_every_package_is_in_a_layer() -> None:
    packages = {package_of(f"wbcbench.{p.stem}") for p in ROOT.glob("*.py")}
    packages |= {p.name for p in ROOT.iterdir() if (p / "__init__.py").exists()}
    assert packages <= set(LAYERS), packages - set(LAYERS)


def test_no_package_imports_a_package_above_it() -> None:
    upward = [
        f"{file}: {here} imports {there}"
        for file, here, there in edges()
        if LAYERS.index(there) > LAYERS.index(here)
    ]
    assert not upward, "\n".join(upward)


def test_the_check_sees_lazy_and_relative_imports() -> None:
    """The parser finds imports inside functions and type-checking blocks (not a vacuous pass)."""
    found = imported(ROOT / "runs.py")
    assert {"wbcbench.controllers.registry", "wbcbench.scenarios.load"} <= found
    assert ("wbcbench/api.py", "api", "bench") in edges()  # a lazy import inside run()
