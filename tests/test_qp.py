"""Problem, Solution, validity check and registry lookups of the QP layer."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import wbcbench.qp as qp
from wbcbench.errors import SolverError, UnknownNameError, UnofferedChoiceError, WbcBenchError
from wbcbench.qp import Problem, Solution, SolutionStatus, check_solution, make_solver
from wbcbench.qp.examples import random_qp, wbc_like_qp
from wbcbench.qp.validity import feasibility_margin, validated


def test_public_api() -> None:
    for name in (
        "Problem",
        "Solution",
        "SolutionStatus",
        "make_solver",
        "solve",
        "available_solvers",
        "all_solvers",
        "available_backends",
        "solver_class",
        "check_solution",
        "TIERS",
        "MODES",
    ):
        assert hasattr(qp, name), name
    assert qp.TIERS == ("default", "low", "mid", "high")
    assert qp.MODES == ("cold", "warm", "hot")


# ---- Problem ------------------------------------------------------------------------------
def test_problem_defaults_and_sizes() -> None:
    p = Problem(H=np.eye(3), g=np.ones(3))
    assert (p.n, p.n_eq, p.n_in) == (3, 0, 0)
    assert p.A.shape == (0, 3) and p.C.shape == (0, 3)
    assert p.lb is None and p.ub is None and not p.has_box
    p.validate()
    p = Problem(H=np.eye(3), g=np.ones(3), C=np.ones((2, 3)), u=np.ones(2))
    assert np.all(p.l == -np.inf)
    assert p.n_in == 2


def test_problem_save_load_round_trip(tmp_path: Path) -> None:
    p = random_qp(3)
    p.meta = {"controller": "hqp", "level": 2, "tick": np.int64(17), "w": np.float64(0.5)}
    path = tmp_path / "problem.npz"
    p.save(path)
    q = Problem.load(path)
    for key in ("H", "g", "A", "b", "C", "l", "u", "lb", "ub"):
        np.testing.assert_array_equal(getattr(q, key), getattr(p, key))
    assert q.name == p.name
    assert q.meta == {"controller": "hqp", "level": 2, "tick": 17, "w": 0.5}
    assert q.structure_key() == p.structure_key()


def test_problem_save_load_without_box(tmp_path: Path) -> None:
    p = random_qp(4, box=False)
    p.save(tmp_path / "p.npz")
    q = Problem.load(tmp_path / "p.npz")
    assert q.lb is None and q.ub is None
    np.testing.assert_array_equal(q.u, p.u)


def test_structure_key() -> None:
    p = random_qp(1)
    assert dataclasses.replace(p, g=p.g + 1.0).structure_key() == p.structure_key()
    assert dataclasses.replace(p, lb=None).structure_key() != p.structure_key()
    assert random_qp(1, n_in=7).structure_key() != p.structure_key()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"g": np.ones(4)}, "problem 'random_qp/0': H has shape (10, 10), expected (4, 4) (n=4)"),
        (
            {"H": np.full((10, 10), np.nan)},
            "problem 'random_qp/0': H has non-finite entries",
        ),
        ({"b": np.ones(2)}, "problem 'random_qp/0': b has shape (2,), expected (3,) (n=10)"),
        ({"H": np.triu(np.ones((10, 10)))}, "problem 'random_qp/0': H is not symmetric"),
        (
            {"l": np.full(6, 2.0), "u": np.full(6, 1.0)},
            "problem 'random_qp/0': l[0] = 2 > u[0] = 1",
        ),
    ],
)
def test_problem_validate_messages(change: dict[str, np.ndarray], message: str) -> None:
    p = dataclasses.replace(random_qp(0), **change)
    with pytest.raises(SolverError) as err:
        p.validate()
    assert str(err.value) == message
    assert err.value.problem is p


# ---- validity -----------------------------------------------------------------------------
def _kkt_solution(p: Problem) -> Solution:
    """Equality-constrained optimum by a direct KKT solve (an oracle independent of solvers)."""
    n, m = p.n, p.n_eq
    K = np.block([[p.H, p.A.T], [p.A, np.zeros((m, m))]])
    sol = np.linalg.solve(K, np.concatenate([-p.g, p.b]))
    return Solution(status=SolutionStatus.SOLVED, x=sol[:n], y=sol[n:], z=np.zeros(0))


def test_check_solution_against_direct_kkt() -> None:
    p = random_qp(5, n_in=0, box=False)
    p.validate()
    v = check_solution(p, _kkt_solution(p), tol=1e-9)
    assert v.ok, v
    assert v.primal_residual < 1e-12 and v.dual_residual is not None and v.dual_residual < 1e-12
    assert v.duality_gap is not None and v.duality_gap < 1e-10


def test_check_solution_sign_convention() -> None:
    # min ½x² − x s.t. x ≤ 0.5: optimum 0.5 with an upper-side multiplier z = +0.5.
    p = Problem(H=np.eye(1), g=-np.ones(1), C=np.eye(1), u=np.array([0.5]))
    good = Solution(
        status=SolutionStatus.SOLVED, x=np.array([0.5]), y=np.zeros(0), z=np.array([0.5])
    )
    assert check_solution(p, good, 1e-12).ok
    flipped = dataclasses.replace(good, z=np.array([-0.5]))
    v = check_solution(p, flipped, 1e-6)
    assert not v.ok and v.message.startswith("dual residual")


def test_validated_flags_a_wrong_solved_solution() -> None:
    p = random_qp(2)
    sol = make_solver("proxqp", tier="high").solve(p)
    assert sol.success
    assert validated(p, sol, tol=1e-6).status is SolutionStatus.SOLVED
    assert sol.x is not None
    wrong = dataclasses.replace(sol, x=sol.x + 0.1)
    assert wrong.status is SolutionStatus.SOLVED  # the solver's word is kept...
    checked = validated(p, wrong, tol=1e-6)
    assert checked.status is SolutionStatus.FAILED  # ...the check overrules it
    assert checked.message.startswith("reported solved but primal residual ")
    assert wrong.status is SolutionStatus.SOLVED  # not modified in place


def test_distance_to_reference() -> None:
    p = random_qp(2)
    sol = make_solver("proxqp", tier="high").solve(p)
    assert sol.x is not None
    v = check_solution(p, sol, 1e-8)
    assert v.distance_to(sol.x) == 0.0
    assert v.distance_to(sol.x + 0.25) == pytest.approx(0.25)


def test_feasibility_margin() -> None:
    """The largest t with every finite bound met with t (1 + |bound|) to spare: on 0 ≤ x ≤ 1,
    t ≤ x ≤ 1 − 2t gives 1/3; on 2 ≤ x ≤ 1 (infeasible), 2 + 3t ≤ x ≤ 1 − 2t gives −1/5; an
    equality written as two bounds leaves 0; with A x = b the bounds are met on that line."""
    H, g = np.eye(1), np.zeros(1)
    assert feasibility_margin(Problem(H, g, lb=np.zeros(1), ub=np.ones(1))) == pytest.approx(1 / 3)
    infeasible = Problem(H, g, C=np.ones((1, 1)), l=np.array([2.0]), u=np.array([1.0]))
    assert feasibility_margin(infeasible) == pytest.approx(-1 / 5)
    pinned = Problem(H, g, C=np.ones((1, 1)), l=np.array([0.5]), u=np.array([0.5]))
    assert abs(feasibility_margin(pinned)) <= 1e-12
    assert feasibility_margin(Problem(H, g)) == 1.0  # no finite bound: the cap
    # x0 + x1 = 1 with 0 ≤ x ≤ 1: x = (½, ½) leaves ½ − t ≥ t and ½ + 2t ≤ 1, so t = 1/4
    line = Problem(
        np.eye(2), np.zeros(2), A=np.ones((1, 2)), b=np.ones(1), lb=np.zeros(2), ub=np.ones(2)
    )
    assert feasibility_margin(line) == pytest.approx(1 / 4)


def test_check_solution_without_x() -> None:
    v = check_solution(random_qp(1), Solution(status=SolutionStatus.FAILED))
    assert not v.ok and v.primal_residual == np.inf and v.message == "no primal solution"


# ---- registry -----------------------------------------------------------------------------
def test_unknown_solver_message_lists_installed_names() -> None:
    installed = qp.available_solvers()
    with pytest.raises(UnknownNameError) as err:
        make_solver("gurobi_magic")
    assert str(err.value) == (
        "unknown solver 'gurobi_magic'; valid choices: "
        + ", ".join(sorted(installed))
        + " (wbcbench.qp.all_solvers() lists every backend with its availability and version)"
    )
    assert isinstance(err.value, KeyError)


def test_a_backend_whose_module_does_not_load_says_why(monkeypatch: pytest.MonkeyPatch) -> None:
    """Its library installed but its module not importable (eiquadprog without the native
    module): the reason names that, not a missing package."""
    from wbcbench.qp import registry

    entry = registry.BackendEntry("wbcbench.qp.backends.no_such_module", "Nope", "numpy")
    monkeypatch.setitem(registry.BACKENDS, "nope_backend", entry)
    info = next(i for i in qp.all_solvers() if i["name"] == "nope_backend")
    assert not info["available"]
    assert info["reason"] == (
        "package 'numpy' is installed, but the backend does not load: "
        "No module named 'wbcbench.qp.backends.no_such_module'"
    )
    with pytest.raises(UnknownNameError, match="'nope_backend' is a known backend but package"):
        make_solver("nope_backend")


def test_unknown_tier_and_mode_messages() -> None:
    with pytest.raises(UnknownNameError) as err:
        make_solver("proxqp", tier="ultra")
    assert str(err.value) == (
        "unknown tier 'ultra'; valid choices: default, high, low, mid (Tiers set absolute "
        "primal, dual and duality-gap tolerances: low 1e-3, mid 1e-6, high 1e-9; default "
        "keeps each solver's own settings)"
    )
    with pytest.raises(UnknownNameError) as err:
        make_solver("proxqp", mode="--hot")
    assert str(err.value) == (
        "unknown mode '--hot'; valid choices: cold, hot, warm (Modes: cold builds a fresh "
        "solver on every call, warm passes the previous solution as initial guess, hot keeps "
        "one solver and updates it in place)"
    )


def test_name_is_looked_up_before_the_tier() -> None:
    with pytest.raises(UnknownNameError) as err:
        make_solver("nope", tier="ultra")
    assert err.value.kind == "solver"


LIBDWBC_HINT = (
    "osqp_libdwbc is a fixed setting: tier default = libdwbc's OSQP settings (eps_abs = "
    "eps_rel = 1e-3, alpha = 1.0), mode hot = one persistent OSQP object per QP, warm-started "
    "from its previous solution and sent all its data every tick; `osqp` runs OSQP at any "
    "tier, mode or options"
)


def test_a_named_setting_rejects_another_tier_mode_or_option_naming_the_valid_ones() -> None:
    if "osqp_libdwbc" not in qp.available_solvers():
        pytest.skip("osqp not installed")
    with pytest.raises(UnofferedChoiceError) as err:
        make_solver("osqp_libdwbc", tier="low", mode="hot")
    assert str(err.value) == (
        f"osqp_libdwbc does not run at tier 'low'; valid choices: default ({LIBDWBC_HINT})"
    )
    assert isinstance(err.value, UnknownNameError)  # caught wherever a bad name is
    with pytest.raises(UnofferedChoiceError) as err:
        make_solver("osqp_libdwbc", mode="warm")
    assert str(err.value) == (
        f"osqp_libdwbc does not run at mode 'warm'; valid choices: hot ({LIBDWBC_HINT})"
    )
    with pytest.raises(UnofferedChoiceError, match="does not run at mode 'cold'"):
        make_solver("osqp_libdwbc")  # the default mode is cold
    with pytest.raises(WbcBenchError) as err:
        make_solver("osqp_libdwbc", mode="hot", alpha=1.6)
    assert str(err.value) == f"osqp_libdwbc takes no native options (got alpha): {LIBDWBC_HINT}"
    with pytest.raises(UnknownNameError) as err:  # an unknown tier is still that
        make_solver("osqp_libdwbc", tier="ultra", mode="hot")
    assert str(err.value).startswith("unknown tier 'ultra'")
    assert make_solver("osqp_libdwbc", mode="hot").mode == "hot"


def test_named_settings_are_listed_with_what_they_run_at_but_are_not_backends() -> None:
    if "osqp_libdwbc" not in qp.available_solvers():
        pytest.skip("osqp not installed")
    info = next(i for i in qp.all_solvers() if i["name"] == "osqp_libdwbc")
    assert info["named_setting"] and info["tiers"] == ("default",) and info["modes"] == ("hot",)
    assert "libdwbc" in info["summary"] and "RC-LQP" in info["summary"]
    assert info["version"] == next(i["version"] for i in qp.all_solvers() if i["name"] == "osqp")
    assert "osqp_libdwbc" not in qp.available_backends()
    assert set(qp.available_backends()) <= set(qp.available_solvers())
    assert all(i["summary"] for i in qp.all_solvers() if i["available"])


def test_all_solvers_reports_versions() -> None:
    infos = qp.all_solvers()
    names = [i["name"] for i in infos]
    assert names == sorted(names)
    assert {i["name"] for i in infos if i["available"]} == set(qp.available_solvers())
    for info in infos:
        if info["available"]:
            assert info["version"], info
        else:
            assert info["reason"], info


def test_one_shot_solve() -> None:
    p = random_qp(6)
    sol = qp.solve(p)
    assert sol.success and sol.solver == "proxqp" and sol.mode == "cold"
    assert check_solution(p, sol, tol=1e-4).ok


# ---- failures are rows, not crashes -------------------------------------------------------
def test_backend_exception_becomes_failed_solution(monkeypatch: pytest.MonkeyPatch) -> None:
    solver = make_solver("proxqp")

    def boom(*args: object, **kwargs: object) -> Solution:
        raise RuntimeError("native library exploded")

    monkeypatch.setattr(solver, "_solve_fresh", boom)
    p = random_qp(1)
    sol = solver.solve(p)
    assert sol.status is SolutionStatus.FAILED
    assert sol.message == "RuntimeError: native library exploded"
    assert sol.solver == "proxqp" and sol.x is None
    with pytest.raises(SolverError) as err:
        solver.solve(p, raise_on_failure=True)
    assert err.value.problem is p and err.value.solver == "proxqp"
    assert "native library exploded" in str(err.value)


def test_invalid_problem_is_a_failed_solution() -> None:
    p = dataclasses.replace(random_qp(0), H=np.full((10, 10), np.inf))
    sol = make_solver("osqp").solve(p)
    assert sol.status is SolutionStatus.FAILED
    assert sol.message == "SolverError: problem 'random_qp/0': H has non-finite entries"


def test_unknown_native_option_is_a_failed_solution() -> None:
    sol = make_solver("proxqp", bogus_setting=1).solve(random_qp(1))
    assert sol.status is SolutionStatus.FAILED
    assert sol.message == "ValueError: proxsuite has no setting 'bogus_setting'"


def test_wbc_like_problem_shape() -> None:
    p = wbc_like_qp()
    p.validate()
    assert (p.n, p.n_eq, p.n_in) == (70, 45, 60)
    eig = np.linalg.eigvalsh(p.H)
    assert eig.min() > -1e-9 and np.sum(eig > 1e-9 * eig.max()) < p.n  # PSD, rank-deficient
