"""Property-based scenario validation: any value at any key of a shipped scenario, and any
bytes as a file, end either in a valid scenario or in a ScenarioError that names the file (and,
where the file could be read, a key path); never in another exception.

Complements the fixed corpus (tests/test_bad_scenarios.py) with generated defects; the examples
are derandomised, so a failure reproduces.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wbcbench.errors import ScenarioError
from wbcbench.runs import check_scenario
from wbcbench.scenarios.load import load_scenario, load_scenario_robot

ROOT = Path(__file__).resolve().parents[1]
BASES = ("tocabi_stand_sway", "ahn_single_support", "lee2021iros_table1", "rqr_reach")
RAW = {b: yaml.safe_load((ROOT / "scenarios" / f"{b}.yaml").read_text()) for b in BASES}

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(10**12), max_value=10**12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1e-300, 1e300, 1e-12, 0.5, 3, 1000]),
    st.text(max_size=12),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=3)
    ),
    max_leaves=8,
)


def key_paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every key path of a parsed YAML tree (mapping keys and list indices)."""
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += key_paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += key_paths(v, (*prefix, i))
    return out


PATHS = [(b, p) for b in BASES for p in key_paths(RAW[b])]


def validate(path: Path) -> None:
    """Load and check against the robot; a ScenarioError must name the file."""
    try:
        loaded = load_scenario(path)
        check_scenario(loaded, load_scenario_robot(loaded))
    except ScenarioError as exc:
        assert str(exc).startswith(f"{path}: "), str(exc)


@settings(
    max_examples=150,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(where=st.sampled_from(PATHS), value=values, extra=st.booleans())
def test_any_value_at_any_key_is_accepted_or_a_clean_error(
    tmp_path: Path, where: tuple[str, tuple[Any, ...]], value: Any, extra: bool
) -> None:
    base, keys = where
    raw = copy.deepcopy(RAW[base])
    node = raw
    for k in keys[:-1]:
        node = node[k]
    if extra and isinstance(node, dict):
        node["unexpected_key"] = value  # an unknown key next to a known one
    else:
        node[keys[-1]] = value
    path = tmp_path / f"{base}.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False, allow_unicode=True))
    validate(path)


@settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(data=st.binary(max_size=300))
def test_any_bytes_as_a_file_are_a_clean_error(tmp_path: Path, data: bytes) -> None:
    path = tmp_path / "noise.yaml"
    path.write_bytes(data)
    try:
        load_scenario(path)
    except ScenarioError as exc:
        assert str(exc).startswith(f"{path}: "), str(exc)
    else:
        raise AssertionError("random bytes were accepted as a scenario")
