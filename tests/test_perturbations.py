"""Perturbations of a closed-loop run: pushes, sensing noise and delay, actuator lag and
quantisation, model error; their validation, their records and their repeatability."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from wbcbench.bench.runner import base_row, run_id
from wbcbench.errors import ScenarioError
from wbcbench.metrics.oracle import forward_dynamics
from wbcbench.robots.loader import load_robot, simulation_model
from wbcbench.robots.model_error import with_model_error
from wbcbench.runs import check_scenario, plan_run
from wbcbench.scenarios.load import SCENARIO_DIR, load_scenario
from wbcbench.scenarios.schema import PerturbationsSpec, PushSpec
from wbcbench.sim.closed_loop import run_closed_loop
from wbcbench.sim.perturbations import Pushes, Sensing, push_impulse, push_scale

BASE = SCENARIO_DIR / "tocabi_stand_sway.yaml"
SHORT = ("duration=0.06", "metrics.window=[0.0, 0.06]")


def error_of(overrides: tuple[str, ...]) -> str:
    with pytest.raises(ScenarioError) as exc:
        loaded = load_scenario(BASE, overrides)
        check_scenario(loaded, load_robot(loaded.spec.robot))
    return str(exc.value)


def test_bad_perturbations_are_clear_errors_at_their_key() -> None:
    assert error_of(("perturbations.sensing.delay=-1",)) == (
        f"{BASE}: perturbations.sensing.delay: Input should be greater than or equal to 0"
    )
    assert error_of(("perturbations.sensing.q_noise=.nan",)) == (
        f"{BASE}: perturbations.sensing.q_noise: Input should be a finite number"
    )
    assert error_of(("perturbations.model.mass_scale=0",)) == (
        f"{BASE}: perturbations.model.mass_scale: Input should be greater than 0"
    )
    message = error_of(
        ("perturbations.pushes=[{body: pelvs, start: 1, duration: 0.1, force: [50, 0, 0]}]",)
    )
    assert message.startswith(
        f"{BASE}: perturbations.pushes[0].body: unknown body 'pelvs'; valid choices: "
    )
    assert "pelvis" in message
    local = "perturbations.pushes=[{body: pelvis, start: 1, duration: 0.1, frame: local}]"
    assert error_of((local,)) == (
        f"{BASE}: perturbations.pushes[0].frame: invalid value 'local'; valid choices: "
        "'world' or 'body'"
    )
    late = (
        "perturbations.pushes=[{body: pelvis, start: 1, duration: 0.1, "
        "profile: [[0, 1], [0.2, 0]]}]"
    )
    assert error_of((late,)) == (
        f"{BASE}: perturbations.pushes[0]: profile times must lie in [0, duration = 0.1], "
        "got [0.0, 0.2]"
    )
    kinematic = SCENARIO_DIR / "rqr_reach.yaml"
    with pytest.raises(ScenarioError) as exc:
        load_scenario(kinematic, ("perturbations.sensing.delay=2",))
    assert str(exc.value) == (
        f"{kinematic}: perturbations: a kinematic scenario has no physics to perturb; "
        "perturbations apply to dynamic scenarios (kind: dynamic)"
    )


def test_off_by_default_and_the_hash_unchanged() -> None:
    plain = load_scenario(BASE)
    assert not plain.spec.perturbations.active
    explicit = load_scenario(BASE, ("perturbations={seed: 0}",))
    assert explicit.hash == plain.hash
    seeded_only = load_scenario(BASE, ("perturbations.seed=3",))
    assert not seeded_only.spec.perturbations.active  # a seed without noise changes nothing
    pushed = load_scenario(
        BASE, ("perturbations.pushes=[{body: pelvis, start: 1, duration: 0.1}]",)
    )
    assert pushed.spec.perturbations.active and pushed.hash != plain.hash


def test_push_profiles_and_impulses() -> None:
    pulse = PushSpec(body="b", start=1.0, duration=0.2, force=(50.0, 0.0, 0.0))
    assert push_scale(pulse, -1e-9) == 0.0 and push_scale(pulse, 0.2) == 0.0
    assert push_scale(pulse, 0.1) == 1.0
    np.testing.assert_allclose(push_impulse(pulse), [10.0, 0.0, 0.0])
    sine = pulse.model_copy(update={"shape": "half_sine"})
    assert push_scale(sine, 0.1) == pytest.approx(1.0)
    np.testing.assert_allclose(push_impulse(sine), [10.0 * 2 / np.pi, 0.0, 0.0])
    ramp = pulse.model_copy(update={"profile": [(0.0, 0.0), (0.1, 1.0), (0.2, 0.0)]})
    assert push_scale(ramp, 0.05) == pytest.approx(0.5)
    np.testing.assert_allclose(push_impulse(ramp), [5.0, 0.0, 0.0])


@pytest.mark.parametrize("frame", ["world", "body"])
def test_a_push_changes_the_free_robots_momentum_by_its_impulse(frame: str) -> None:
    """Without gravity or contact, a push's impulse is the robot's change of linear momentum
    (its force applied at the body's centre of mass, in the axes the push names)."""
    robot = load_robot("tocabi_like")
    model = robot.fresh_mj_model()
    model.opt.gravity[:] = 0.0
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    data = mujoco.MjData(model)
    data.qpos[:] = model.key_qpos[0]
    data.qpos[3:7] = [np.cos(0.3), 0.0, 0.0, np.sin(0.3)]  # yawed: body axes ≠ world axes
    mujoco.mj_forward(model, data)
    push = PushSpec(
        body="pelvis", start=0.0, duration=0.01, force=(200.0, -50.0, 30.0), frame=frame
    )
    pushes = Pushes(model, [push])
    h = model.opt.timestep
    R0 = data.xmat[pushes.bodies[0]].reshape(3, 3).copy()
    for i in range(round(0.02 / h)):
        pushes.apply(data, i * h)
        mujoco.mj_step(model, data)
    mujoco.mj_subtreeVel(model, data)
    momentum = model.body_subtreemass[1] * data.subtree_linvel[1]
    expected = push_impulse(push)
    if frame == "body":  # the body barely turns in 10 ms: its axes then are R0's
        expected = R0 @ expected
    np.testing.assert_allclose(momentum, expected, rtol=2e-2, atol=0.02)
    assert not data.xfrc_applied.any()  # cleared once the push is over


def test_sensing_noise_is_seeded_and_the_delay_holds_k_ticks() -> None:
    spec = PerturbationsSpec.model_validate(
        {"seed": 7, "sensing": {"q_noise": 1e-3, "v_noise": 0.1, "delay": 2}}
    )
    q, v = np.zeros(7 + 3), np.zeros(6 + 3)
    a, b = Sensing(spec, 3), Sensing(spec, 3)
    qa, va = a.measure(q, v)
    qb, vb = b.measure(q, v)
    np.testing.assert_array_equal(qa, qb)
    np.testing.assert_array_equal(va, vb)
    assert not qa[:7].any() and not va[:6].any()  # the base's state stays exact
    assert np.all(qa[7:] != 0) and np.all(va[6:] != 0)
    taus = [np.full(3, float(i)) for i in range(5)]
    sent = [a.command(t)[0] for t in taus]
    assert sent == [0.0, 0.0, 0.0, 1.0, 2.0]  # the first until two were computed, then 2 late
    quantised = Sensing(PerturbationsSpec.model_validate({"actuation": {"quantum": 0.5}}), 3)
    np.testing.assert_array_equal(quantised.command(np.array([0.2, 0.3, -1.26])), [0, 0.5, -1.5])


def test_model_error_changes_the_controllers_model_only() -> None:
    robot = load_robot("tocabi_like")
    wrong = with_model_error(robot, 1.1, com_offset=(0.01, 0.0, 0.0))
    assert wrong.mj_model is robot.mj_model
    total = pin.computeTotalMass(robot.pin_model)
    assert pin.computeTotalMass(wrong.pin_model) == pytest.approx(1.1 * total)
    i = robot.pin_model.getJointId(robot.joint_names[0])
    a, b = robot.pin_model.inertias[i], wrong.pin_model.inertias[i]
    np.testing.assert_allclose(b.lever - a.lever, [0.01, 0.0, 0.0])
    np.testing.assert_allclose(b.inertia, 1.1 * a.inertia)
    assert with_model_error(robot) is robot
    sim = simulation_model(robot, {}, payloads=[("l_hand", 2.0, (0.0, 0.0, 0.05))])
    assert sim.body_subtreemass[1] == pytest.approx(robot.mj_model.body_subtreemass[1] + 2.0)


def test_the_oracle_holds_on_the_controllers_own_model() -> None:
    """With a 15 % mass error and a payload the controller does not know, each step still
    realises its prediction on the controller's own model (the rigid-contact oracle)."""
    run = plan_run(
        BASE,
        "qp_wbc",
        "daqp",
        tier="high",
        overrides=(
            *SHORT,
            "perturbations.model={mass_scale: 1.15, payload: {body: r_hand, mass: 1.5}}",
        ),
    )
    frames = [c.frame for c in run.scenario.spec.contacts]
    masses, worst = [], 0.0

    def on_step(state, out) -> None:
        nonlocal worst
        masses.append(pin.computeTotalMass(state.robot.pin_model))
        oracle = forward_dynamics(state, out.tau, frames)
        worst = max(worst, float(np.abs(oracle.qdd - out.qdd).max()))

    result = run_closed_loop(run, on_step=on_step)
    assert result.status == "ok", result.message
    assert masses and masses[0] == pytest.approx(1.15 * pin.computeTotalMass(run.robot.pin_model))
    assert worst <= 1e-6


PERTURBED = (
    *SHORT,
    "perturbations={seed: 11, sensing: {q_noise: 2e-4, v_noise: 0.02, delay: 2}, "
    "actuation: {lag: 0.004, quantum: 0.01}, model: {mass_scale: 1.1}, "
    "pushes: [{body: torso, start: 0.01, duration: 0.03, force: [0, 60, 0], shape: half_sine}]}",
)


def logs_of(overrides: tuple[str, ...]) -> dict[str, np.ndarray]:
    return run_closed_loop(plan_run(BASE, "qp_wbc", "daqp", overrides=overrides)).log.arrays()


def test_the_same_seed_gives_the_same_log_and_another_seed_another() -> None:
    a, b = logs_of(PERTURBED), logs_of(PERTURBED)
    assert a.keys() == b.keys()
    timed = {k for k in a if k.startswith("time.")}
    for key in a.keys() - timed:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    other = logs_of(tuple(s.replace("seed: 11", "seed: 12") for s in PERTURBED))
    assert not np.array_equal(a["tau.L_HipYaw"], other["tau.L_HipYaw"])
    # the robot's own errors are logged beside the controller's view of them
    assert "true_err.com.pos" in a and not np.array_equal(a["true_err.com.pos"], a["err.com.pos"])


def test_a_perturbed_run_states_it_in_its_row_and_id() -> None:
    plain = plan_run(BASE, "qp_wbc", "daqp", overrides=SHORT)
    run = plan_run(BASE, "qp_wbc", "daqp", overrides=PERTURBED)
    assert run_id(run, "v") != run_id(plain, "v")
    row = base_row(run, "x", "v")
    assert row["seed"] == 11
    settings = json.loads(row["settings"])
    assert settings["perturbations"]["sensing"] == {"q_noise": 2e-4, "v_noise": 0.02, "delay": 2}
    assert settings["perturbations"]["model"] == {"mass_scale": 1.1}
    assert settings["controller_model"] == "the robot's file with masses x1.1, inertias x1.1"
    assert settings["simulated_model"] == ("the robot's file, motors with a 4 ms first-order lag")
    assert "perturbations" not in json.loads(base_row(plain, "x", "v")["settings"])


def test_serial_and_dask_give_the_same_perturbed_run(tmp_path: Path) -> None:
    import pandas as pd

    from wbcbench.bench.sweep import load_sweep_file, plan_sweep, run_sweep

    sets = ", ".join(f'"{s}"' for s in PERTURBED)
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(
        "version: 1\ntracking:\n  - scenarios: [tocabi_stand_sway]\n"
        f"    controllers: [qp_wbc]\n    solvers: [daqp]\n    set: [{sets}]\n"
    )
    for executor in ("serial", "dask"):
        run_sweep(
            plan_sweep(*load_sweep_file(str(sweep))),
            tmp_path / executor,
            executor=executor,
            show_progress=False,
        )
    logs = [
        pd.read_parquet(next((tmp_path / e / "logs").glob("*.parquet"))) for e in ("serial", "dask")
    ]
    timed = [c for c in logs[0].columns if c.startswith("time.")]
    pd.testing.assert_frame_equal(logs[0].drop(columns=timed), logs[1].drop(columns=timed))
    assert "true_err.com.pos" in logs[0]


# -- the push-recovery study and the degradation table


def test_the_push_study_brackets_the_largest_survived_push(tmp_path: Path) -> None:
    from wbcbench.bench.push_recovery import PushStudy, push_table, run_push_study

    study = PushStudy(
        start=0.05, duration=0.05, recover_time=0.3, max_impulse=120.0, resolution=70.0
    )
    rows = run_push_study(
        [("tocabi_stand_sway", "qp_wbc", "daqp", "pelvis")], ["+x"], study, tmp_path, "v@c"
    )
    (row,) = rows.to_dict("records")
    trials = json.loads(row["trials"])
    assert [t["impulse"] for t in trials] == [0.0, 120.0, 60.0]
    assert trials[0]["survived"] and not trials[1]["survived"]
    assert row["failed_Ns"] - row["survived_Ns"] <= study.resolution
    assert row["failure"] == next(t["why"] for t in trials if t["impulse"] == row["failed_Ns"])
    assert row["failure"].startswith(("fell: ", "failed: ", "CoM "))
    # a rerun of the same code keeps the stored bracket
    again = run_push_study(
        [("tocabi_stand_sway", "qp_wbc", "daqp", "pelvis")], ["+x"], study, tmp_path, "v@d"
    )
    assert len(again) == 1
    table = push_table(again)
    assert table.loc[0, "+x"] == (
        f"{row['survived_Ns']:g} [{row['survived_Ns']:g}, {row['failed_Ns']:g})"
    )
    assert (tmp_path / "tables" / "push_recovery.md").exists()


def test_a_push_study_names_its_bad_body_and_scenario(tmp_path: Path) -> None:
    from wbcbench.bench.sweep import load_sweep_file, plan_sweep

    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(
        "version: 1\npush_recovery:\n  scenarios: [tocabi_stand_sway]\n"
        "  controllers: [qp_wbc]\n  body: pelvs\n"
    )
    with pytest.raises(ScenarioError) as exc:
        plan_sweep(*load_sweep_file(str(sweep)))
    assert str(exc.value).startswith(
        f"{sweep}: push_recovery.body: scenario 'tocabi_stand_sway': {BASE}: "
        "perturbations.pushes[0].body: unknown body 'pelvs'; valid choices: "
    )
    sweep.write_text("version: 1\npush_recovery:\n  max_impulse: 10\n  resolution: 10\n")
    with pytest.raises(ScenarioError) as exc:
        load_sweep_file(str(sweep))
    assert str(exc.value) == (
        f"{sweep}: push_recovery: resolution (10 N·s) must be below max_impulse (10 N·s)"
    )


def test_each_perturbed_run_is_placed_on_one_degradation_axis() -> None:
    from wbcbench.report.robustness import ENCODER_Q_STD, ENCODER_V_STD, perturbation_axis

    def settings(pert: dict) -> str:
        return json.dumps({"duration_s": 3.0, **({"perturbations": pert} if pert else {})})

    assert perturbation_axis(settings({})) == ("", 0.0)
    assert perturbation_axis(settings({"model": {"mass_scale": 1.15}})) == ("mass", 15.0)
    assert perturbation_axis(settings({"sensing": {"delay": 3}})) == ("delay", 3.0)
    noise = {"q_noise": 2 * ENCODER_Q_STD, "v_noise": 2 * ENCODER_V_STD}
    assert perturbation_axis(settings({"seed": 0, "sensing": noise})) == ("noise", 2.0)
    # two axes at once, or an inertia error apart from the mass: on no axis
    assert perturbation_axis(settings({"sensing": {**noise, "delay": 1}})) is None
    assert perturbation_axis(settings({"model": {"mass_scale": 1.1, "inertia_scale": 1}})) is None


def test_the_controller_that_falls_first_is_named_with_its_runs_message() -> None:
    import pandas as pd

    from wbcbench.bench.push_recovery import falls_first, push_table

    def bracket(controller: str, d: str, lo: float, hi: float, why: str) -> dict:
        return {"scenario": "s", "controller": controller, "solver": "daqp", "impl": "native",
                "direction": d, "survived_Ns": lo, "failed_Ns": hi, "failure": why}  # fmt: skip

    rows = pd.DataFrame(
        [
            bracket("a", "+y", 20.0, 25.0, "fell: contact 'l_sole' moved 21 mm"),
            bracket("b", "+y", 10.0, 15.0, "failed: 20 failed ticks in a row"),
            bracket("a", "+x", 10.0, 15.0, "fell: base at 0.4 m"),
            bracket("b", "+x", 10.0, 15.0, "CoM 30.0 mm from its reference"),
            bracket("a", "-x", 80.0, float("nan"), ""),
            bracket("b", "-x", float("nan"), 0.0, "fell: unpushed"),
            bracket("a", "-y", 80.0, float("nan"), ""),
        ]
    )
    first = falls_first(rows).set_index("direction")
    assert first.loc["+y", "falls first"] == "b"
    assert first.loc["+y", "at [N·s]"] == "15"
    assert first.loc["+y", "why (the run's message)"] == "failed: 20 failed ticks in a row"
    # a tie names both, each with its own message
    assert first.loc["+x", "falls first"] == "a, b"
    assert first.loc["+x", "why (the run's message)"] == (
        "a: fell: base at 0.4 m; b: CoM 30.0 mm from its reference"
    )
    # a controller that falls unpushed falls first; no one fails in -y: no row
    assert first.loc["-x", "falls first"] == "b" and first.loc["-x", "at [N·s]"] == "0"
    assert "-y" not in first.index
    # the table's directions in the study's order, each cell `J [survived, failed)`
    table = push_table(rows)
    assert list(table.columns[4:]) == ["+x", "-x", "+y", "-y"]
    assert table.set_index("controller").loc["b", "-x"] == "falls unpushed"
    assert table.set_index("controller").loc["a", "-x"] == "≥ 80"
    assert table.set_index("controller").loc["b", "-y"] == "not run"


def test_degradation_names_who_falls_first_or_who_degrades_most() -> None:
    import pandas as pd

    from wbcbench.report.robustness import degradation_falls_first, degradation_grid

    def run(controller: str, axis: str, value: float, err: float, status: str = "ok") -> dict:
        message = "" if status == "ok" else f"{controller} fell at {value:g}"
        return {"scenario": "s", "controller": controller, "solver": "daqp", "duration_s": 3.0,
                "axis": axis, "value": value, "err_mean": err, "status": status,
                "message": message}  # fmt: skip

    table = pd.DataFrame(
        [
            run("a", "delay", 0, 1e-4),
            run("a", "delay", 2, 2e-4),
            run("a", "delay", 5, 1e-3, "fell"),
            run("b", "delay", 0, 1e-4),
            run("b", "delay", 2, 5e-4, "failed"),
            run("b", "delay", 5, 2e-3, "fell"),
            run("a", "mass", 0, 1e-4),
            run("a", "mass", 20, 4e-4),
            run("b", "mass", 0, 2e-4),
            run("b", "mass", 20, 1.2e-3),
        ]
    )
    first = degradation_falls_first(table).set_index("falls first")
    assert first.loc["b", "at"] == "2"
    assert first.loc["b", "why (the run's message)"] == "failed: b fell at 2"
    # nobody falls under a mass error: the one whose error grows most [mm] is named
    assert first.loc["none", "at"] == "none up to 20"
    assert first.loc["none", "why (the run's message)"] == (
        "every run ok; degrades most: b (from 0.2 to 1.2 mm at 20)"
    )
    grid = degradation_grid(table, "delay").set_index("controller")
    assert list(grid.columns[2:]) == ["0", "2", "5"]
    assert grid.loc["a", "2"] == "0.2" and grid.loc["b", "2"] == "failed"
