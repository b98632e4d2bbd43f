"""The small Python API: make_controller / step / close, and load_results."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import wbcbench
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import WbcBenchError
from wbcbench.metrics.oracle import forward_dynamics

REFERENCE = Path(__file__).resolve().parents[1] / "results" / "reference"


@pytest.mark.parametrize("impl", ["native", "python"])
def test_a_scenario_controller_steps_and_its_answer_is_realised(impl: str) -> None:
    if impl == "native" and not wbcbench._native.BUILT:
        pytest.skip(f"the native module is {wbcbench._native.REASON}")
    with wbcbench.make_controller("tocabi_stand_sway", "osf_hqp", solver="daqp", impl=impl) as c:
        assert c.controller.impl == impl
        assert c.contact_frames == ["l_sole", "r_sole"]
        q, v = c.initial_state()
        out = c.step(q, v, t=2.5)
        assert out.ok, out.message
        assert out.tau.shape == (c.robot.k,)
        assert out.qdd.shape == (c.robot.nv,)
        assert out.wrench.shape == (12,)
        oracle = forward_dynamics(RobotState(c.robot, q, v), out.tau, c.contact_frames)
        np.testing.assert_allclose(oracle.qdd, out.qdd, atol=1e-6)
        with pytest.raises(ValueError, match=r"q must have shape"):
            c.step(q[:-1], v, 0.0)


def test_settings_and_names_are_checked() -> None:
    with pytest.raises(WbcBenchError, match="valid choices"):
        wbcbench.make_controller("tocabi_stand_sway", "no_such_controller")
    with pytest.raises(WbcBenchError, match="unknown scenario"):
        wbcbench.make_controller("no_such_scenario", "qp_wbc")
    c = wbcbench.make_controller("tocabi_stand_sway", "qp_wbc", overrides=["duration=2"])
    assert c.scenario.spec.duration == 2.0
    with pytest.raises(Exception, match="variables"):
        wbcbench.make_controller("tocabi_stand_sway", "qp_wbc", variables="none")


def test_load_results_reads_a_results_folder() -> None:
    res = wbcbench.load_results(REFERENCE)
    assert not res.runs.empty and not res.metrics.empty
    assert {"controller", "solver", "status"} <= set(res.runs.columns)


def test_the_readme_example_runs_as_written(monkeypatch: pytest.MonkeyPatch) -> None:
    readme = (REFERENCE.parents[1] / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", readme, flags=re.S)
    assert blocks, "the README has no Python example"
    monkeypatch.chdir(REFERENCE.parents[1])
    for code in blocks:
        exec(compile(code, "README.md", "exec"), {})
