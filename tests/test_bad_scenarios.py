"""The corpus of corrupted scenarios: each one is a clean error naming the file and the key.

The corpus (tests/data/bad_scenarios/, written by tests/data/make_bad_scenarios.py) holds the
shipped scenarios with one defect each: missing, mistyped and unknown keys at every depth;
NaN, infinite, huge, negative and zero numbers; unknown names; contradictory limits; wrong
lengths; other encodings, binary data, folders and absurd nesting. None may be accepted, none
may end in another exception than a ScenarioError, and each message names the file and, where
the file could be read, the key path that holds the defect.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from wbcbench.cli import main
from wbcbench.errors import ScenarioError
from wbcbench.runs import check_scenario
from wbcbench.scenarios.load import load_scenario, load_scenario_robot

CORPUS = Path(__file__).resolve().parent / "data" / "bad_scenarios"
INDEX: dict[str, str] = json.loads((CORPUS / "index.json").read_text())


def test_the_corpus_is_large_and_current() -> None:
    assert len(INDEX) >= 200
    on_disk = {p.name for p in CORPUS.iterdir() if p.name != "index.json"}
    assert on_disk == set(INDEX)


@pytest.mark.parametrize("name", sorted(INDEX))
def test_a_corrupted_scenario_is_a_clean_error_naming_file_and_key(name: str) -> None:
    path = CORPUS / name
    with pytest.raises(ScenarioError) as exc:
        loaded = load_scenario(path)
        check_scenario(loaded, load_scenario_robot(loaded))
    message = str(exc.value)
    key = INDEX[name]
    prefix = f"{path}: {key}" if key else f"{path}: "
    assert message.startswith(prefix), (message, key)
    assert "Traceback" not in message


@pytest.mark.parametrize("name", sorted(INDEX)[::25])
def test_the_cli_says_it_in_one_line(name: str, capsys) -> None:
    assert main(["validate", str(CORPUS / name)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: {CORPUS / name}: ") and err.count("\n") == 1, err
