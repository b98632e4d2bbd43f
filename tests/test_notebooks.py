"""Every notebook in notebooks/ executes on the curated reference results (so none rots), with
matplotlib's inline backend as Jupyter gives it: every figure renders as a picture, the tables
as tables, the verdicts come first and the conclusion last."""

from __future__ import annotations

import re
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
REFERENCE = ROOT / "results" / "reference"


def test_there_is_a_notebook_per_paper_one_for_the_solvers_and_one_for_robustness() -> None:
    names = {p.name for p in NOTEBOOKS}
    assert {
        "to_osf_lee2021.ipynb",
        "osf_hqp_lee2021.ipynb",
        "rc_lqp_ahn.ipynb",
        "rqr_hqp.ipynb",
        "solver_comparison.ipynb",
        "robustness.ipynb",
    } <= names


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_executes(path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """From another working directory and without WBCBENCH_RESULTS: each notebook finds the
    curated results relative to the package."""
    assert (REFERENCE / "runs.csv").exists(), "results/reference is missing: run `make reference`"
    monkeypatch.delenv("WBCBENCH_RESULTS", raising=False)
    monkeypatch.delenv("MPLBACKEND", raising=False)  # the kernel's own: inline
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(
        nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()
    code = [cell for cell in nb.cells if cell.cell_type == "code"]
    outputs = [o for cell in code for o in cell.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    # the notebook loaded the results and printed what it found
    assert any("runs measured on" in o.get("text", "") for o in outputs)

    def markdown(cell: nbformat.NotebookNode) -> str:
        return "".join(o.get("data", {}).get("text/markdown", "") for o in cell.get("outputs", []))

    # opens with its verdicts (a Markdown table), ends with a conclusion drawn from them
    assert re.search(r"## Verdicts?\n", markdown(code[0])), "the first cell shows no verdicts"
    assert markdown(code[-1]).strip(), "the last cell draws no conclusion"
    # every cell that draws a figure shows it as a picture
    for cell in code:
        if "def " not in cell.source and re.search(r"figure\(|plt\.show\(\)", cell.source):
            assert any("image/png" in o.get("data", {}) for o in cell.get("outputs", [])), (
                f"no picture from: {cell.source.splitlines()[0]}"
            )
    # tables render as tables (Markdown pipes), never as printed text
    assert any("|---" in markdown(cell) or "|:--" in markdown(cell) for cell in code)
    assert not any("|:--" in o.get("text", "") for o in outputs), "a table printed as text"
