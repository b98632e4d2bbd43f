"""Paper tables: the papers' numbers beside ours, with the ratios.

Each table is built from a results folder (:func:`wbcbench.report.load_results`). It finds its
runs by scenario-name pattern and controller name, so scenarios and controllers added later are
picked up as they land; a table whose runs are missing says which runs to make instead of
failing. Absolute times are labelled with the machine they were measured on: the papers' from
:mod:`wbcbench.report.papers`, ours from the folder's provenance.

Timing values are from open-loop replay (``kind = timing``) and prefer, for each controller, the
paper's own solver when it was timed, else the default solver; hot mode before warm before cold.

One module per paper (``to_osf``, ``osf_hqp``, ``rc_lqp``, ``rqr``) beside the published numbers
in :mod:`wbcbench.report.papers`, and ``peers`` (kin_hqp beside pink and mink, no published
numbers) and ``walking`` (the walks, per robot); what they share is in ``common``.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

from wbcbench.report.load import Results, load_results
from wbcbench.report.tables.common import (
    PaperTable,
    _impl_of,
    _pick_timing,
    _robot_dof,
    impl_note,
    run_spec,
    scenario_spec,
)
from wbcbench.report.tables.osf_hqp import osf_hqp_backends, osf_hqp_table2, osf_hqp_table3
from wbcbench.report.tables.peers import peers_kinematic
from wbcbench.report.tables.rc_lqp import RC_LQP_COLUMNS, rc_lqp_dof, rc_lqp_table3
from wbcbench.report.tables.rqr import rqr_fig1
from wbcbench.report.tables.to_osf import (
    to_osf_cod_svd,
    to_osf_pinv,
    to_osf_s1,
    to_osf_s2,
    to_osf_s3,
    to_osf_s4,
    to_osf_table3,
)
from wbcbench.report.tables.walking import walking

__all__ = [
    "RC_LQP_COLUMNS",
    "TABLES",
    "PaperTable",
    "_impl_of",
    "_pick_timing",
    "_robot_dof",
    "build_tables",
    "impl_note",
    "run_spec",
    "scenario_spec",
    "write_tables",
]


TABLES: dict[str, Callable[[Results], PaperTable]] = {
    "to_osf_s1": to_osf_s1,
    "to_osf_pinv": to_osf_pinv,
    "to_osf_s2": to_osf_s2,
    "to_osf_s3": to_osf_s3,
    "to_osf_s4": to_osf_s4,
    "to_osf_cod_svd": to_osf_cod_svd,
    "to_osf_table3": to_osf_table3,
    "osf_hqp_table3": osf_hqp_table3,
    "osf_hqp_backends": osf_hqp_backends,
    "osf_hqp_table2": osf_hqp_table2,
    "rc_lqp_table3": rc_lqp_table3,
    "rc_lqp_dof": rc_lqp_dof,
    "rqr_fig1": rqr_fig1,
    "peers_kinematic": peers_kinematic,
    "walking": walking,
}


def build_tables(res: Results | str | Path) -> list[PaperTable]:
    """Every paper table from a results folder (or loaded results)."""
    if not isinstance(res, Results):
        res = load_results(res)
    out = []
    for name, fn in TABLES.items():
        try:
            out.append(fn(res))
        except Exception as exc:  # one table's bug must not hide the others
            out.append(PaperTable(name, name, "", None, missing=f"could not be built: {exc}"))
    return out


def write_tables(folder: str | Path) -> Path:
    """``tables/<name>.md`` and ``.csv`` for each table, and ``tables/papers.md`` with all."""
    res = load_results(folder)
    out = Path(folder) / "tables"
    out.mkdir(exist_ok=True)
    tables = build_tables(res)
    parts = [
        "# The papers' numbers beside ours",
        "",
        f"Our results: {res.machine}; wbcbench {res.provenance.get('wbcbench', '?')} @ "
        f"{res.provenance.get('git_commit', '?')}, {res.provenance.get('date', '?')}. "
        "Compare ratios; absolute times come from different CPUs and languages (the papers: C++).",
        "",
    ]
    from wbcbench.report.verdicts import markdown, verdicts

    verdict_frame = verdicts(tables, res)
    verdict_frame.to_csv(out / "verdicts.csv", index=False)
    (out / "verdicts.md").write_text(markdown(verdict_frame))
    parts.append(markdown(verdict_frame))
    for table in tables:
        md = table.markdown()
        (out / f"{table.name}.md").write_text(md)
        if table.frame is not None:
            table.frame.to_csv(out / f"{table.name}.csv", index=False)
        parts.append(md)
    path = out / "papers.md"
    path.write_text("\n".join(parts))
    from wbcbench.report.recommend import write_recommendations

    write_recommendations(folder, res)
    (out / "index.json").write_text(
        json.dumps(
            {t.name: {"title": t.title, "has_results": t.frame is not None} for t in tables},
            indent=2,
        )
        + "\n"
    )
    return path
