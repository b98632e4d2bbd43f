"""Write the corpus of corrupted scenarios that tests/test_bad_scenarios.py validates.

Each file is a shipped scenario with one defect that must be rejected, and ``index.json`` maps
the file to the key path its error must name ("" for a file that cannot be read at all).
Deterministic: ``python tests/data/make_bad_scenarios.py`` rewrites the same corpus.
"""

from __future__ import annotations

import copy
import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[2]
OUT = Path(__file__).resolve().parent / "bad_scenarios"
BASES = (
    "tocabi_stand_sway",
    "comanplus_stand_sway",
    "ahn_double_support",
    "lee2021iros_table1",
    "lee2021access_s1_accuracy",
    "rqr_reach",
)
NAN, INF = float("nan"), float("inf")

Mutation = Callable[[dict[str, Any]], str | None]


def setter(path: tuple[Any, ...], value: Any, key: str) -> Mutation:
    """Set ``raw[path] = value``; the error must name ``key``. None when the path is absent."""

    def mutate(raw: dict[str, Any]) -> str | None:
        node: Any = raw
        for part in path[:-1]:
            if isinstance(node, dict):
                node = node.setdefault(part, {})
            elif isinstance(node, list) and isinstance(part, int) and part < len(node):
                node = node[part]
            else:
                return None
        if isinstance(node, list) and not (isinstance(path[-1], int) and path[-1] < len(node)):
            return None
        node[path[-1]] = value
        return key

    return mutate


def deleter(path: tuple[Any, ...], key: str) -> Mutation:
    def mutate(raw: dict[str, Any]) -> str | None:
        node: Any = raw
        for part in path[:-1]:
            try:
                node = node[part]
            except (KeyError, IndexError, TypeError):
                return None
        if not isinstance(node, dict) or path[-1] not in node:
            return None
        del node[path[-1]]
        return key

    return mutate


def first_task(raw: dict[str, Any], types: tuple[str, ...]) -> int | None:
    for i, t in enumerate(raw.get("tasks", [])):
        if t.get("type") in types:
            return i
    return None


def task_mutations(raw: dict[str, Any]) -> list[tuple[str, Mutation]]:
    out: list[tuple[str, Mutation]] = []
    i = first_task(raw, ("com", "frame_position", "frame_pose", "frame_orientation"))
    if i is not None:
        k = f"tasks[{i}]"
        out += [
            ("kp_nan", setter(("tasks", i, "kp"), NAN, f"{k}.kp")),
            ("kp_negative", setter(("tasks", i, "kp"), -5.0, f"{k}.kp")),
            ("kp_huge", setter(("tasks", i, "kp"), 1e300, f"{k}.kp")),
            ("kv_inf", setter(("tasks", i, "kv"), INF, f"{k}.kv")),
            ("kp_text", setter(("tasks", i, "kp"), "stiff", f"{k}.kp")),
            (
                "kp_wrong_length",
                setter(("tasks", i, "kp"), [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0], f"{k}.kp"),
            ),
            ("kv_negative_vector", setter(("tasks", i, "kv"), [-1.0], f"{k}.kv")),
            ("priority_zero", setter(("tasks", i, "priority"), 0, f"{k}.priority")),
            ("priority_fraction", setter(("tasks", i, "priority"), 1.5, f"{k}.priority")),
            ("weight_negative", setter(("tasks", i, "weight"), -1.0, f"{k}.weight")),
            ("weight_nan", setter(("tasks", i, "weight"), NAN, f"{k}.weight")),
            ("axes_unknown", setter(("tasks", i, "axes"), ["w"], f"{k}")),
            ("task_type_typo", setter(("tasks", i, "type"), "comm", f"{k}.type")),
            ("task_unknown_key", setter(("tasks", i, "kpp"), 1.0, f"{k}.kpp")),
            ("task_no_name", deleter(("tasks", i, "name"), f"{k}.name")),
            ("task_no_type", deleter(("tasks", i, "type"), f"{k}.type")),
            ("task_level_typo", setter(("tasks", i, "level"), "torque", f"{k}.level")),
        ]
    m = first_task(raw, ("joint_posture", "joint_damping"))
    if m is not None:
        out.append(
            ("joint_kp_wrong_length", setter(("tasks", m, "kp"), [1.0, 2.0], f"tasks[{m}].kp"))
        )
    j = first_task(raw, ("frame_position", "frame_pose", "frame_orientation"))
    if j is not None:
        out.append(
            (
                "task_frame_unknown",
                setter(("tasks", j, "frame"), "no_such_frame", f"tasks[{j}].frame"),
            )
        )
    return out


def contact_mutations(raw: dict[str, Any]) -> list[tuple[str, Mutation]]:
    if not raw.get("contacts"):
        return []
    k = "contacts[0]"
    return [
        ("fmin_nan", setter(("contacts", 0, "fmin"), NAN, f"{k}.fmin")),
        ("fmin_inf", setter(("contacts", 0, "fmin"), INF, f"{k}.fmin")),
        ("fmin_negative", setter(("contacts", 0, "fmin"), -1.0, f"{k}.fmin")),
        ("fmin_huge", setter(("contacts", 0, "fmin"), 1e300, f"{k}.fmin")),
        ("fmax_huge", setter(("contacts", 0, "fmax"), 1e300, f"{k}.fmax")),
        ("mu_huge", setter(("contacts", 0, "mu"), 1e3, f"{k}.mu")),
        ("fmax_below_fmin", setter(("contacts", 0, "fmax"), 1.0, f"{k}.fmax")),
        ("facets_huge", setter(("contacts", 0, "facets"), 100000, f"{k}.facets")),
        ("facets_two", setter(("contacts", 0, "facets"), 2, f"{k}.facets")),
        ("mu_zero", setter(("contacts", 0, "mu"), 0.0, f"{k}.mu")),
        ("mu_inf", setter(("contacts", 0, "mu"), INF, f"{k}.mu")),
        ("contact_unknown_key", setter(("contacts", 0, "muu"), 0.5, f"{k}.muu")),
        ("contact_no_frame", deleter(("contacts", 0, "frame"), f"{k}.frame")),
        ("contact_frame_unknown", setter(("contacts", 0, "frame"), "no_such_sole", f"{k}.frame")),
        (
            "cop_reversed",
            setter(("contacts", 0, "cop"), {"x": [0.1, -0.1], "y": [-0.05, 0.05]}, f"{k}.cop.x"),
        ),
        (
            "contact_geometry_unknown",
            setter(("contacts", 0, "contact_geometry"), "mesh", f"{k}.contact_geometry"),
        ),
        (
            "contact_geometry_not_a_name",
            setter(("contacts", 0, "contact_geometry"), {"box": True}, f"{k}.contact_geometry"),
        ),
        (
            "duplicate_contact",
            lambda r: (
                r["contacts"].append(copy.deepcopy(r["contacts"][0]))
                or f"contacts[{len(r['contacts']) - 1}].frame"
            ),
        ),
    ]


def controller_mutations(raw: dict[str, Any]) -> list[tuple[str, Mutation]]:
    """Settings of the controllers: non-finite and out-of-range numbers, names that do not
    exist in the scenario or on the robot."""
    q, kin = "controllers.qp_wbc", "controllers.kin_hqp"
    return [
        ("qp_wbc_weights_empty", setter(("controllers", "qp_wbc", "weights"), [], f"{q}.weights")),
        ("qp_wbc_weights_nan", setter(("controllers", "qp_wbc", "weights"), [NAN], f"{q}.weights")),
        (
            "qp_wbc_weights_negative",
            setter(("controllers", "qp_wbc", "weights"), [1.0, -1.0], f"{q}.weights"),
        ),
        (
            "qp_wbc_wrench_weight_inf",
            setter(("controllers", "qp_wbc", "wrench_weight"), INF, f"{q}.wrench_weight"),
        ),
        (
            "kin_hqp_com_gain_inf",
            setter(("controllers", "kin_hqp", "com_gain"), INF, f"{kin}.com_gain"),
        ),
        (
            "kin_hqp_speed_limit_unknown_task",
            setter(
                ("controllers", "kin_hqp", "speed_limits"),
                {"no_such_task": 0.25},
                f"{kin}.speed_limits.no_such_task",
            ),
        ),
        (
            "kin_hqp_self_collision_unknown_body",
            setter(
                ("controllers", "kin_hqp", "self_collision"),
                [["no_such_body", "no_such_other"]],
                f"{kin}.self_collision[0][0]",
            ),
        ),
        (
            "kin_hqp_obstacle_body_unknown",
            setter(
                ("controllers", "kin_hqp", "obstacle_bodies"),
                ["no_such_body"],
                f"{kin}.obstacle_bodies[0]",
            ),
        ),
    ]


def top_mutations(raw: dict[str, Any]) -> list[tuple[str, Mutation]]:
    dynamic = raw.get("kind", "dynamic") == "dynamic"
    out: list[tuple[str, Mutation]] = [
        ("unknown_top_key", setter(("durations",), 1.0, "durations")),
        ("no_robot", deleter(("robot",), "robot")),
        ("no_duration", deleter(("duration",), "duration")),
        ("no_version", deleter(("version",), "version")),
        ("version_two", setter(("version",), 2, "version")),
        ("robot_typo", setter(("robot",), "tocabi_lik", "robot")),
        (
            "self_collision_exclude_unknown_body",
            setter(
                ("sim", "self_collision"),
                {"exclude": [["no_such_body", "no_such_body_either"]]},
                "sim.self_collision.exclude[0][0]",
            ),
        ),
        (
            "self_collision_exclude_not_a_pair",
            setter(
                ("sim", "self_collision"),
                {"exclude": [["a", "b", "c"]]},
                "sim.self_collision.exclude",
            ),
        ),
        ("duration_nan", setter(("duration",), NAN, "duration")),
        ("duration_inf", setter(("duration",), INF, "duration")),
        ("duration_negative", setter(("duration",), -1.0, "duration")),
        ("duration_zero", setter(("duration",), 0.0, "duration")),
        ("duration_huge", setter(("duration",), 1e9, "duration")),
        ("duration_text", setter(("duration",), "ten seconds", "duration")),
        ("duration_no_tick", setter(("duration",), 1e-4, "duration")),
        ("control_rate_nan", setter(("control_rate",), NAN, "control_rate")),
        ("control_rate_zero", setter(("control_rate",), 0.0, "control_rate")),
        ("control_rate_huge", setter(("control_rate",), 1e9, "control_rate")),
        ("control_rate_tiny", setter(("control_rate",), 1e-6, "control_rate")),
        ("kind_typo", setter(("kind",), "dynamical", "kind")),
        ("no_tasks", setter(("tasks",), [], "tasks")),
        ("tasks_not_a_list", setter(("tasks",), {"a": 1}, "tasks")),
        (
            "duplicate_task",
            lambda r: (
                r["tasks"].append(copy.deepcopy(r["tasks"][0]))
                or f"tasks[{len(r['tasks']) - 1}].name"
            ),
        ),
        ("window_reversed", setter(("metrics", "window"), [5.0, 1.0], "metrics.window")),
        ("window_past_duration", setter(("metrics", "window"), [0.0, 1e4], "metrics.window")),
        ("window_nan", setter(("metrics", "window"), [NAN, 1.0], "metrics.window")),
        ("warmup_negative", setter(("metrics", "timing_warmup"), -3, "metrics.timing_warmup")),
        ("metrics_unknown_key", setter(("metrics", "windows"), [0, 1], "metrics.windows")),
        ("keyframe_unknown", setter(("initial", "keyframe"), "no_such_pose", "initial.keyframe")),
        (
            "controller_unknown",
            setter(("controllers", "no_such_controller"), {}, "controllers.no_such_controller"),
        ),
        ("torque_scale_zero", setter(("limits", "torque_scale"), 0.0, "limits.torque_scale")),
        ("torque_scale_nan", setter(("limits", "torque_scale"), NAN, "limits.torque_scale")),
        (
            "torque_joint_unknown",
            setter(("limits", "torque"), {"no_such_joint": 10.0}, "limits.torque.no_such_joint"),
        ),
        ("torque_limit_inf", setter(("limits", "torque"), {"*": INF}, "limits.torque")),
    ]
    if dynamic:
        out += [
            ("rate_not_a_multiple", setter(("control_rate",), 3000.0, "control_rate")),
            ("rate_faster_than_physics", setter(("control_rate",), 5000.0, "control_rate")),
            ("timestep_tiny", setter(("sim", "timestep"), 1e-12, "sim.timestep")),
            ("timestep_negative", setter(("sim", "timestep"), -0.001, "sim.timestep")),
            ("timestep_large", setter(("sim", "timestep"), 0.1, "sim.timestep")),
            ("timestep_nan", setter(("sim", "timestep"), NAN, "sim.timestep")),
            ("sim_unknown_key", setter(("sim", "timestap"), 0.001, "sim.timestap")),
            (
                "failures_zero",
                setter(("sim", "max_consecutive_failures"), 0, "sim.max_consecutive_failures"),
            ),
        ]
        p = "perturbations"
        push = {"body": "pelvis", "start": 0.5, "duration": 0.1, "force": [100.0, 0.0, 0.0]}
        out += [
            ("delay_negative", setter((p, "sensing", "delay"), -1, f"{p}.sensing.delay")),
            ("delay_fraction", setter((p, "sensing", "delay"), 1.5, f"{p}.sensing.delay")),
            ("q_noise_nan", setter((p, "sensing", "q_noise"), NAN, f"{p}.sensing.q_noise")),
            ("v_noise_negative", setter((p, "sensing", "v_noise"), -0.1, f"{p}.sensing.v_noise")),
            ("mass_scale_zero", setter((p, "model", "mass_scale"), 0.0, f"{p}.model.mass_scale")),
            (
                "mass_scale_negative",
                setter((p, "model", "mass_scale"), -1.1, f"{p}.model.mass_scale"),
            ),
            (
                "inertia_scale_nan",
                setter((p, "model", "inertia_scale"), NAN, f"{p}.model.inertia_scale"),
            ),
            ("lag_negative", setter((p, "actuation", "lag"), -0.01, f"{p}.actuation.lag")),
            ("quantum_inf", setter((p, "actuation", "quantum"), INF, f"{p}.actuation.quantum")),
            (
                "push_body_unknown",
                setter((p, "pushes"), [{**push, "body": "no_such_body"}], f"{p}.pushes[0].body"),
            ),
            (
                "push_duration_zero",
                setter((p, "pushes"), [{**push, "duration": 0.0}], f"{p}.pushes[0].duration"),
            ),
            (
                "push_frame_typo",
                setter((p, "pushes"), [{**push, "frame": "local"}], f"{p}.pushes[0].frame"),
            ),
            (
                "push_force_nan",
                setter((p, "pushes"), [{**push, "force": [NAN, 0, 0]}], f"{p}.pushes[0].force"),
            ),
            (
                "payload_body_unknown",
                setter(
                    (p, "model", "payload"),
                    {"body": "no_such_hand", "mass": 1.0},
                    f"{p}.model.payload.body",
                ),
            ),
            ("perturbations_unknown_key", setter((p, "noise"), 0.1, f"{p}.noise")),
        ]
    return out


def raw_files() -> dict[str, bytes | None]:
    """Files no YAML parser should get past (None: make a folder)."""
    deep = "a: " + "[" * 5000 + "]" * 5000 + "\n"
    utf8 = (ROOT / "scenarios" / "tocabi_stand_sway.yaml").read_text(encoding="utf-8")
    accented = "# déjà vu\n" + utf8
    return {
        "file_utf16.yaml": accented.encode("utf-16"),
        "file_latin1.yaml": accented.encode("latin-1", errors="replace"),
        "file_binary.yaml": bytes(range(256)) * 4,
        "file_nul_bytes.yaml": utf8.encode() + b"\x00\x00",
        "file_deep_nesting.yaml": deep.encode(),
        "file_deep_mapping.yaml": (
            "a:\n" + "".join(f"{' ' * i}b{i}:\n" for i in range(1, 1200))
        ).encode(),
        "file_empty.yaml": b"",
        "file_top_level_list.yaml": b"- version: 1\n- robot: tocabi_like\n",
        "file_not_yaml.yaml": b"version: 1\nrobot: [unclosed\n",
        "file_tabs.yaml": b"version: 1\n\trobot: tocabi_like\n",
        "file_a_folder.yaml": None,
    }


def main() -> None:
    if OUT.exists():
        shutil.rmtree(OUT)
    OUT.mkdir(parents=True)
    index: dict[str, str] = {}
    for base in BASES:
        text = (ROOT / "scenarios" / f"{base}.yaml").read_text(encoding="utf-8")
        original = yaml.safe_load(text)
        families = top_mutations(original) + task_mutations(original)
        families += contact_mutations(original) + controller_mutations(original)
        for label, mutate in families:
            raw = copy.deepcopy(original)
            key = mutate(raw)
            if key is None:
                continue
            name = f"{base}__{label}.yaml"
            (OUT / name).write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
            index[name] = key
    for name, data in raw_files().items():
        if data is None:
            (OUT / name).mkdir()  # git keeps no empty folder
            (OUT / name / "README").write_text("a folder where a scenario file is expected\n")
        else:
            (OUT / name).write_bytes(data)
        index[name] = ""
    (OUT / "index.json").write_text(json.dumps(index, indent=1, sort_keys=True) + "\n")
    print(f"{len(index)} corrupted scenarios in {OUT}")


if __name__ == "__main__":
    main()
