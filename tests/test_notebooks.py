"""Every notebook in notebooks/ executes on the curated reference results (so none rots)."""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
REFERENCE = ROOT / "results" / "reference"


def test_there_is_a_notebook_per_paper_and_one_for_the_solvers() -> None:
    names = {p.name for p in NOTEBOOKS}
    assert {
        "to_osf_lee2021.ipynb",
        "osf_hqp_lee2021.ipynb",
        "rc_lqp_ahn.ipynb",
        "rqr_hqp.ipynb",
        "solver_comparison.ipynb",
    } <= names


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_executes(path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """From another working directory and without WBCBENCH_RESULTS: each notebook finds the
    curated results relative to the package."""
    assert (REFERENCE / "runs.csv").exists(), "results/reference is missing: run `make reference`"
    monkeypatch.delenv("WBCBENCH_RESULTS", raising=False)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(
        nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()
    outputs = [o for cell in nb.cells if cell.cell_type == "code" for o in cell.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    # the notebook loaded the results and printed what it found
    assert any("runs measured on" in o.get("text", "") for o in outputs)
