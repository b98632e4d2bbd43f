"""ProxQP gives the same bits for the same QP in every run: repeated in one process while the
heap moves, and in another process (proxsuite's generic build, see
``wbcbench.qp.proxsuite_build``)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from wbcbench.qp import Problem, make_solver, proxsuite_build

SCRIPT = """
import sys
import numpy as np
from tests.test_proxqp_bits import answers
sys.stdout.write(answers(churn=False).hex())
"""


def problems() -> list[Problem]:
    """Strictly convex QPs with equalities and active inequalities (40 variables)."""
    rng = np.random.default_rng(11)
    out = []
    for _ in range(8):
        n, n_eq, n_in = 40, 6, 30
        M = rng.standard_normal((n, n))
        x0 = rng.standard_normal(n)
        A = rng.standard_normal((n_eq, n))
        C = rng.standard_normal((n_in, n))
        out.append(
            Problem(
                H=M @ M.T + 1e-3 * np.eye(n),
                g=rng.standard_normal(n),
                A=A,
                b=A @ x0,
                C=C,
                l=np.full(n_in, -np.inf),
                u=C @ x0 + rng.uniform(-0.5, 0.1, n_in),
            )
        )
    return out


def answers(churn: bool) -> bytes:
    held = []
    out = b""
    rng = np.random.default_rng(0)
    for problem in problems():
        for _ in range(3 if churn else 1):
            if churn:  # move the heap: the vectorised builds' answers depend on where it is
                held.append(np.empty(int(rng.integers(1, 5000))))
            x = make_solver("proxqp", tier="mid").solve(problem).x
            out += x.tobytes()
    return out


def test_the_same_qp_gives_the_same_bits_in_every_run() -> None:
    here = answers(churn=True)
    n = len(problems())
    size = len(here) // (3 * n)
    repeats = [here[i * size : (i + 1) * size] for i in range(3 * n)]
    assert all(repeats[3 * k] == repeats[3 * k + j] for k in range(n) for j in (1, 2))
    assert proxsuite_build.build() == "proxsuite_pywrap"
    there = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True
    ).stdout
    assert bytes.fromhex(there) == b"".join(repeats[3 * k] for k in range(n))
