"""The four papers' published numbers, with where each comes from.

This module is data: every value below is copied from the paper named in ``source`` (the plain
texts live in the project's ``papers/`` notes; DESIGN §8 lists them). Values the text extraction
lost are ``None`` with a note, never guessed. Units are the papers' own.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Paper:
    key: str
    short: str
    citation: str
    machine: str  # where the paper's times were measured
    solver: str


PAPERS: dict[str, Paper] = {
    "to_osf": Paper(
        "to_osf",
        "TO-OSF",
        "Lee et al., task-oriented operational space formulation, IEEE Access 2021",
        "3.4 GHz quad-core, 32 GB (V-REP / Vortex simulation), C++",
        "qpOASES",
    ),
    "osf_hqp": Paper(
        "osf_hqp",
        "OSF-HQP",
        "Lee, Ahn, Lee, Park, OSF-based HQP, IROS 2021",
        "i7-6700K 4.0 GHz quad-core (MuJoCo simulation, Table III); 3.7 GHz octa-core "
        "(robot, Table II), C++",
        "qpOASES",
    ),
    "rc_lqp": Paper(
        "rc_lqp",
        "RC-LQP",
        "Ahn et al., reduced-centroidal lexicographic QP",
        "i7-10700 (MuJoCo simulation), C++",
        "OSQP",
    ),
    "rqr_hqp": Paper(
        "rqr_hqp",
        "RQR-HQP",
        "Regularized-QR kinematic HQP on HRP-2",
        "Intel 540M 2.52 GHz notebook, C++",
        "own active set",
    ),
}


@dataclass(frozen=True)
class Value:
    """One published number."""

    paper: str
    table: str
    row: str
    column: str
    value: float | None
    unit: str
    source: str


def _v(paper: str, table: str, row: str, column: str, value: float | None, unit: str, src: str):
    return Value(paper, table, row, column, value, unit, src)


# TO-OSF §IV-A2, Scenario #1, mean error norms over t = 9–19 s (T1..T5 = Table 1's tasks)
TO_OSF_S1 = [
    _v("to_osf", "s1", "T1", "CoM position", 0.045, "mm", "TO-OSF §IV-A2"),
    _v("to_osf", "s1", "T2", "right-hand position", 0.281, "mm", "TO-OSF §IV-A2"),
    _v("to_osf", "s1", "T3", "trunk orientation", 0.0003, "rad", "TO-OSF §IV-A2"),
    _v("to_osf", "s1", "T4", "torso orientation", 0.0006, "rad", "TO-OSF §IV-A2"),
    _v("to_osf", "s1", "T5", "right-hand orientation", 0.0192, "rad", "TO-OSF §IV-A2"),
]
# TO-OSF §IV-A3, Fig. 6: pseudo-inverse instead of the dynamically consistent inverse
TO_OSF_PINV_PEAK_RHAND_ORI = _v(
    "to_osf", "pinv", "T5", "right-hand orientation peak", 0.988, "rad", "TO-OSF Fig. 6 caption"
)
# TO-OSF §IV-B3: identical weighting (H = 1e7 I) vs priority weighting, total amendment ratio
TO_OSF_S2_AMENDMENT_RATIO = _v(
    "to_osf",
    "s2",
    "total amendment",
    "priority / identical",
    7.5,
    "-",
    "TO-OSF §IV-B3 ('approximately 7.5 times smaller')",
)
# TO-OSF §IV-D, Fig. 14 (bounds stated in the text; the figure's points are not in the text)
TO_OSF_S4 = [
    _v("to_osf", "s4", "RT-thread QP", "upper bound up to 24 contact DoF", 0.5, "ms", "§IV-D"),
    _v("to_osf", "s4", "non-RT parameters", "upper bound", 2.0, "ms", "TO-OSF §IV-D"),
]
# TO-OSF §IV-D: COD vs SVD dynamically consistent inverse, 5 tasks, two feet
TO_OSF_COD_SVD = [
    _v("to_osf", "cod_svd", "cod", "parameters", 1.55, "ms", "TO-OSF §IV-D"),
    _v("to_osf", "cod_svd", "svd", "parameters", 4.27, "ms", "TO-OSF §IV-D"),
]
# TO-OSF §V, Table 3: HQP vs TO-OSF for 1..5 tasks (3 → 20 task DoF), double support.
# The table's values were lost in the text extraction: only the trend is stated (TO-OSF faster,
# more so as tasks are added).
TO_OSF_TABLE3_NOTE = (
    "Table 3's values are not in the extracted text; the paper states TO-OSF takes less time "
    "than HQP and the gap grows with the number of tasks."
)
TO_OSF_TABLE3: list[Value] = [
    _v("to_osf", "table3", f"{n} tasks", method, None, "ms", "TO-OSF Table 3 (values lost)")
    for n in range(1, 6)
    for method in ("hqp", "to_osf")
]

# OSF-HQP Table III (MuJoCo simulation), average solving time per level and total
OSF_HQP_TABLE3 = {
    "conventional": [1.416, 1.764, 1.380, 3.176, 1.527, 9.263],
    "proposed": [0.059, 0.068, 0.041, 0.099, 0.038, 0.303],
}
OSF_HQP_LEVELS = ["T1", "T2", "T3", "T4", "T5", "total"]
OSF_HQP_TABLE3_SOURCE = "OSF-HQP Table III"
# OSF-HQP Table II (robot experiment), proposed method per level
OSF_HQP_TABLE2 = {
    "min": [0.037, 0.041, 0.027, 0.070, 0.025, 0.205],
    "max": [0.146, 0.129, 0.072, 0.237, 0.063, 0.417],
    "average": [0.044, 0.055, 0.030, 0.097, 0.027, 0.253],
}
# OSF-HQP §V: OSF parameters in the RT thread (single thread) vs split
OSF_HQP_SINGLE_THREAD = [
    _v("osf_hqp", "single", "OSF parameters", "average", 0.64, "ms", "OSF-HQP §V"),
    _v("osf_hqp", "single", "single-thread total", "average", 0.94, "ms", "OSF-HQP §V"),
    _v("osf_hqp", "single", "speed-up vs conventional", "single thread", 9.8, "x", "OSF-HQP §V"),
    _v("osf_hqp", "single", "speed-up vs conventional", "split (QPs only)", 30.5, "x", "§V"),
]
# OSF-HQP §IV tracking (robot, 40 s): average error norms
OSF_HQP_TRACKING = [
    _v("osf_hqp", "tracking", "CoM", "position", 5.5, "mm", "OSF-HQP §IV"),
    _v("osf_hqp", "tracking", "pelvis", "orientation", 0.0237, "rad", "OSF-HQP §IV"),
    _v("osf_hqp", "tracking", "hands", "position", 35.0, "mm", "OSF-HQP §IV"),
    _v("osf_hqp", "tracking", "upper body", "orientation", 0.0459, "rad", "OSF-HQP §IV"),
]

# RC-LQP Table 3: computation time by support type [µs]
RC_LQP_TABLE3 = {
    ("double", "conventional"): {"avg": 2176, "max": 2473},
    ("double", "proposed"): {"avg": 981, "max": 1203, "dyn": 34, "LQP1": 579, "LQP2": 273},
    ("single", "conventional"): {"avg": 1834, "max": 2119},
    ("single", "proposed"): {"avg": 613, "max": 811, "dyn": 36, "LQP1": 243, "LQP2": 270},
}
RC_LQP_TABLE3_SOURCE = "RC-LQP Table 3"
# RC-LQP §5.3, Fig. 5: DoF scaling, double support [µs] (only the end points are in the text)
RC_LQP_DOF = {
    20: {"proposed": 571, "conventional": 754},
    45: {"proposed": 1319, "conventional": 4081},
}
RC_LQP_DOF_SOURCE = "RC-LQP §5.3 / Fig. 5"
# The authors' C++ (libdwbc), static state, warm OSQP: reduced / conventional step time per DoF
# (30 DoF measured where our family has 29). Constants: measured once, not by `make bench`.
RC_LQP_DOF_LIBDWBC = {20: 0.95, 25: 0.65, 30: 0.50, 33: 0.445, 39: 0.37, 45: 0.34}
#: where and when :data:`RC_LQP_DOF_LIBDWBC` was measured (a label for figures and tables)
RC_LQP_DOF_LIBDWBC_MEASURED = "2-core Intel Xeon VM, Nov. 2026"

# RQR-HQP Fig. 1: reduced QR vs full-size QR vs SVD against the problem size N (curves only)
RQR_FIG1_NOTE = (
    "Fig. 1 gives curves, not numbers: no significant difference between full-size and reduced "
    "QR at N = 40, a growing gain of the reduced QR for larger N, SVD slowest."
)
