"""Every wbcbench name a README example or a notebook uses is public and documented: exported
by its module's ``__all__``, not private, and (functions and classes) with a docstring."""

from __future__ import annotations

import ast
import importlib
import inspect
import json
import re
from pathlib import Path

import pytest

import wbcbench

ROOT = Path(__file__).resolve().parents[1]


def python_sources() -> dict[str, str]:
    """The code of the README's python blocks and of every notebook's code cells."""
    out = {}
    readme = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", readme, flags=re.S)
    out["README.md"] = "\n".join(blocks)
    for path in sorted((ROOT / "notebooks").glob("*.ipynb")):
        cells = json.loads(path.read_text())["cells"]
        code = ["".join(c["source"]) for c in cells if c["cell_type"] == "code"]
        out[path.name] = "\n".join(line for c in code for line in c.splitlines())
    return out


def used_names(source: str) -> set[tuple[str, str]]:
    """``(module, name)`` for ``from wbcbench… import name`` and ``wbcbench.name`` uses."""
    out: set[tuple[str, str]] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("wbcbench"):
            out |= {(node.module or "", alias.name) for alias in node.names}
        elif (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id == "wbcbench"
        ):
            out.add(("wbcbench", node.attr))
    return out


USES = sorted({use for source in python_sources().values() for use in used_names(source)})


def test_the_examples_use_wbcbench() -> None:
    assert ("wbcbench", "run") in USES and ("wbcbench", "make_controller") in USES
    assert any(module.startswith("wbcbench.report") for module, _ in USES)


@pytest.mark.parametrize(("module", "name"), USES)
def test_every_used_name_is_public_and_documented(module: str, name: str) -> None:
    if (module, name) == ("wbcbench", "__file__"):  # where the clone is
        return
    mod = importlib.import_module(module)
    assert not name.startswith("_"), f"{module}.{name} is private"
    assert name in getattr(mod, "__all__", ()), f"{module}.{name} is not in its __all__"
    obj = getattr(mod, name)
    if inspect.isfunction(obj) or inspect.isclass(obj):
        assert inspect.getdoc(obj), f"{module}.{name} has no docstring"
    assert inspect.getdoc(mod), f"{module} has no docstring"


def test_the_top_level_exports_resolve() -> None:
    for name in wbcbench.__all__:
        obj = getattr(wbcbench, name)
        assert inspect.getdoc(obj), name
