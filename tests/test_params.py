"""The parameter server: inline, periodic:N and async (a worker process with shared memory on
the Python path, a worker thread on the native one)."""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from wbcbench import _native
from wbcbench.controllers.params import ParameterServer, ParamsMode, parse_params_mode
from wbcbench.controllers.registry import make_controller
from wbcbench.dynamics.state import RobotState
from wbcbench.errors import ControllerError
from wbcbench.robots.loader import Robot
from wbcbench.runs import plan_run, scenario_context
from wbcbench.scenarios.load import build_tasks, load_scenario
from wbcbench.sim.closed_loop import run_closed_loop
from wbcbench.tasks.osf import OsfModel, OsfParams, group_levels

from .conftest import random_standing_state

threadpool_limits(1)

FRAMES = ["l_sole", "r_sole"]


def model(robot: Robot) -> OsfModel:
    loaded = load_scenario("tocabi_stand_sway")
    tasks = build_tasks(loaded.spec, robot)
    return OsfModel(group_levels(tasks), FRAMES, affine=True)


def same(a: OsfParams, b: OsfParams, tol: float = 1e-10) -> bool:
    return all(
        x.shape == y.shape and np.abs(x - y).max(initial=0.0) <= tol * max(1.0, np.abs(y).max())
        for x, y in zip(a.arrays(), b.arrays(), strict=True)
    )


def test_parse_modes() -> None:
    assert parse_params_mode("inline") == ParamsMode("inline")
    assert parse_params_mode("periodic:5") == ParamsMode("periodic", 5)
    assert str(parse_params_mode("periodic:5")) == "periodic:5"
    assert parse_params_mode("async").kind == "async"
    for bad in ("periodic", "periodic:0", "periodic:x", "sometimes"):
        with pytest.raises(ControllerError, match=r"valid choices: inline, periodic:N, async"):
            parse_params_mode(bad)


def test_inline_and_periodic(tocabi: Robot) -> None:
    m = model(tocabi)
    rng = np.random.default_rng(0)
    states = [random_standing_state(tocabi, rng) for _ in range(7)]
    with ParameterServer(m, "periodic:3", tocabi) as periodic:
        inline = ParameterServer(m, "inline", tocabi)
        for tick, (q, v) in enumerate(states):
            rp = periodic.get(RobotState(tocabi, q, v), tick)
            ri = inline.get(RobotState(tocabi, q, v), tick)
            assert ri.staleness == 0 and ri.params.tick == tick
            assert rp.staleness == tick % 3
            q0, v0 = states[tick - tick % 3]
            assert same(rp.params, m.params(RobotState(tocabi, q0, v0)))
            assert rp.loop_time >= 0.0 and rp.compute_time > 0.0


def test_async_worker_serves_consistent_sets_and_stops(tocabi: Robot) -> None:
    """Every set the loop reads is exactly the parameters of the state of its tick (no torn
    reads), staleness is reported, and close() ends the worker and frees the shared memory."""
    m = model(tocabi)
    rng = np.random.default_rng(1)
    states = [random_standing_state(tocabi, rng) for _ in range(40)]
    server = ParameterServer(m, "async", tocabi)
    seen = []
    try:
        for tick, (q, v) in enumerate(states):
            read = server.get(RobotState(tocabi, q, v), tick)
            assert read.staleness == tick - read.params.tick >= 0
            seen.append(read)
            time.sleep(2e-3)  # a slow control loop: the worker keeps up
        assert server.worker_alive
        proc, shm_name = server._proc, server._shm.name  # type: ignore[union-attr]
    finally:
        server.close()
    fresh = [r for r in seen if r.params.tick > 0]
    assert len(fresh) >= 10, "the worker never delivered"
    assert min(r.staleness for r in seen[5:]) <= 2
    for r in fresh:
        q, v = states[r.params.tick]
        assert same(r.params, m.params(RobotState(tocabi, q, v)))
    assert not proc.is_alive()
    from multiprocessing.shared_memory import SharedMemory

    with pytest.raises(FileNotFoundError):
        SharedMemory(name=shm_name)
    server.close()  # idempotent


def test_closed_loop_with_async_params_cleans_up(tocabi: Robot) -> None:
    """The runner closes the controller however the run ends: no worker survives it."""
    import multiprocessing as mp

    loaded = load_scenario("tocabi_stand_sway", ["duration=0.2"])
    before = set(mp.active_children())
    result = run_closed_loop(
        plan_run(
            loaded,
            controller="osf_hqp",
            solver="daqp",
            config={"params": "async", "impl": "python"},
        ),
    )
    assert result.status == "ok", result.message
    stale = result.log.arrays()["diag.params_staleness"]
    assert np.all(stale >= 0) and stale.max() >= 1
    assert "time.params" in result.log.columns
    time.sleep(0.1)
    assert set(mp.active_children()) <= before


def test_controller_close_stops_the_worker(tocabi: Robot) -> None:
    loaded = load_scenario("tocabi_stand_sway")
    ctx = scenario_context(loaded, tocabi, solver="daqp")
    ctrl = make_controller("to_osf", ctx, {"params": "async", "impl": "python"})
    q, v = tocabi.keyframe("stand")
    ctrl.start(RobotState(tocabi, q, v))
    for tick in range(5):
        out = ctrl.step(RobotState(tocabi, q, v), 1e-3 * tick)
        assert out.ok, out.message
        assert "params" in out.timings and out.diagnostics["params_staleness"] >= 0
    server = ctrl.server  # type: ignore[attr-defined]
    proc = server._proc
    assert proc is not None and proc.is_alive()
    ctrl.close()
    assert not proc.is_alive()


# -- the native worker thread --------------------------------------------------------------------

native_only = pytest.mark.skipif(not _native.BUILT, reason=f"the native module is {_native.REASON}")


def os_threads() -> int:
    return len(os.listdir("/proc/self/task"))


@native_only
@pytest.mark.parametrize("name", ["to_osf", "osf_hqp"])
def test_native_async_uses_the_set_of_a_published_state(tocabi: Robot, name: str) -> None:
    """Every tick's torque realises what the parameters of the state published ``staleness``
    ticks earlier predict, and the worker's newer sets do reach the loop."""
    loaded = load_scenario("tocabi_stand_sway")
    ctx = scenario_context(loaded, tocabi, solver="daqp")
    ctrl = make_controller(name, ctx, {"params": "async", "impl": "native"})
    rng = np.random.default_rng(5)
    states = [random_standing_state(tocabi, rng, 0.02, 0.1) for _ in range(12)]
    ctrl.start(RobotState(tocabi, *tocabi.keyframe("stand")))
    threads = os_threads()
    used = []
    for n, (q, v) in enumerate(states):
        out = ctrl.step(RobotState(tocabi, q, v), 1.0 + 1e-3 * n)
        assert out.ok, out.message
        stale = int(out.diagnostics["params_staleness"])
        assert 0 <= stale <= n
        used.append(n - stale)
        p = ctrl.model.params(RobotState(tocabi, *states[n - stale]))  # type: ignore[attr-defined]
        scale = max(1.0, float(np.abs(out.qdd).max()))
        assert np.abs(p.qdd(out.tau) - out.qdd).max() <= 1e-8 * scale
        assert np.abs(p.wrench(out.tau) - out.wrench).max() <= 1e-8 * max(
            1.0, float(np.abs(out.wrench).max())
        )
        time.sleep(0.01)  # let the worker catch up with the newest state
    assert used[0] == 0 and len(set(used)) > len(used) // 2, used
    assert ctrl.native_tick.worker_sets >= len(set(used)) - 1  # type: ignore[attr-defined]
    ctrl.close()
    assert os_threads() < threads  # the worker thread is joined


@native_only
def test_native_async_closed_loop(tocabi: Robot) -> None:
    loaded = load_scenario("tocabi_stand_sway", ["duration=0.2"])
    assert plan_run(loaded, "to_osf", config={"params": "async"}).impl == "native"
    threads = os_threads()
    result = run_closed_loop(
        plan_run(loaded, controller="to_osf", solver="daqp", config={"params": "async"}),
    )
    assert result.status == "ok", result.message
    stale = result.log.arrays()["diag.params_staleness"]
    assert np.all(stale >= 0) and stale.max() >= 1
    assert os_threads() <= threads


@native_only
@pytest.mark.parametrize("name", ["to_osf", "osf_hqp"])
def test_native_async_never_uses_a_set_from_before_a_change_of_contacts(
    tocabi: Robot, name: str
) -> None:
    """A native tick with ``params: async`` that changes its contact set (one foot lifted, then
    both again: a workspace and worker per set, the second change to a set held before) computes
    the new set's parameters at the change and from then on takes only its worker's sets of
    states published since: never one of the other contact set, nor one its own worker computed
    before the tick last switched to it."""
    loaded = load_scenario("tocabi_stand_sway")
    ctx = scenario_context(loaded, tocabi, solver="daqp")
    ctrl: Any = make_controller(name, ctx, {"params": "async", "impl": "native"})
    rng = np.random.default_rng(7)
    states = [random_standing_state(tocabi, rng, 0.02, 0.1) for _ in range(24)]
    ctrl.start(RobotState(tocabi, *tocabi.keyframe("stand")))
    tick = ctrl.native_tick

    def hold(active: tuple[int, ...]) -> None:
        """The controller's settings and QPs for the set, as a change of contacts makes them
        (without the Python parameter server, which the native tick does not use)."""
        ctrl.hold_contacts(active)
        ctrl.group_tasks(ctrl.active_tasks)
        ctrl.model = ctrl.osf_model()
        ctrl.wrench_weighting()
        ctrl._per_set[active] = {a: getattr(ctrl, a) for a in ctrl.set_attrs}
        if tick.select_contacts(list(active)) and tick.contact_set not in seen:
            ctrl.configure_tick(tick)
            seen.add(tick.contact_set)
            ctrl.workspaces[active] = (tick.contact_set, ctrl.qp_calls(tick))
        ctrl.native_calls = ctrl.workspaces[active][1]
        tick.set_wrench_bounds(ctrl.lw, ctrl.uw)

    seen = {tick.contact_set}
    ctrl.workspaces[(0, 1)] = (tick.contact_set, ctrl.native_calls)
    since = 0  # the first state of the set held
    for n, (q, v) in enumerate(states):
        if n in (8, 16):
            hold((1,) if n == 8 else (0, 1))
            since = n
        out = ctrl.step(RobotState(tocabi, q, v), 1.0 + 1e-3 * n)
        assert out.ok, (n, out.message)
        assert out.wrench.shape == (6 * len(ctrl.active_contacts),)
        stale = int(out.diagnostics["params_staleness"])
        assert n - stale >= since, (n, stale, since)  # a state of this set, since the change
        p = ctrl.model.params(RobotState(tocabi, *states[n - stale]))
        scale = max(1.0, float(np.abs(out.qdd).max()))
        assert np.abs(p.qdd(out.tau) - out.qdd).max() <= 1e-8 * scale, n
        time.sleep(0.01)  # let the worker catch up with the newest state
    ctrl.close()
