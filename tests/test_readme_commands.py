"""Every command the README shows runs as written, in a short form.

The ``sh`` blocks are run command by command, each shortened so that the whole file takes well
under a minute: ``run`` simulates 50 ms; ``sweep`` and ``bench`` validate their whole plan
(``--dry-run``: every scenario against its robot, every name); the report commands read a copy of
the curated reference; ``make`` targets are checked with ``make -n``; benchmark scripts must
offer every option the command passes. Commands quoted inline in the text must parse.
"""

from __future__ import annotations

import glob
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from wbcbench.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
REFERENCE = ROOT / "results" / "reference"
SHORT_RUN = ["--set", "duration=0.05", "--set", "metrics.window=[0.0, 0.05]", "--no-progress"]


def shell_commands() -> list[str]:
    """The commands of the README's ``sh`` blocks: continuations joined, ``&&`` chains split."""
    commands = []
    for block in re.findall(r"```sh\n(.*?)```", README, flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            commands += [part.strip() for part in line.split("&&") if part.strip()]
    return commands


def inline_cli_commands() -> list[str]:
    """``wbcbench <subcommand> ARG…`` quoted inline in the text (not a subcommand's bare name)."""
    return sorted(set(re.findall(r"`(wbcbench [a-z]+ [^`]+)`", README)))


COMMANDS = shell_commands()
IDS = [" ".join(shlex.split(c, comments=True)) for c in COMMANDS]


def test_the_readme_shows_the_main_commands() -> None:
    firsts = {" ".join(shlex.split(c, comments=True)[:2]) for c in COMMANDS}
    main_commands = {"make test", "make bench", "wbcbench run", "wbcbench sweep", "wbcbench tables"}
    assert main_commands <= firsts


def reference_copy(tmp_path: Path, name: str) -> str:
    """A copy of the curated results (the report commands write into their folder)."""
    target = tmp_path / name
    if not target.exists():
        shutil.copytree(REFERENCE, target)
    return str(target)


def tiny_dump(tmp_path: Path) -> Path:
    """A results folder holding three dumped QPs of one sequence (as a sweep dumps them)."""
    from wbcbench.qp.examples import random_qp

    folder = tmp_path / "dumped"
    target = folder / "problems" / "tocabi_stand_sway-000000000000" / "qp_wbc"
    target.mkdir(parents=True, exist_ok=True)
    for tick in (1, 2, 3):
        problem = random_qp(tick, n=12, n_eq=4, n_in=6)
        problem.name = "qp_wbc"
        problem.meta = {
            "scenario": "tocabi_stand_sway",
            "controller": "qp_wbc",
            "robot": "tocabi_like",
            "dt": 1e-3,
            "tick": tick,
            "index": 0,
        }
        problem.save(target / f"t{tick:05d}-00.npz")
    return folder


def tiny_export(tmp_path: Path) -> Path:
    from wbcbench.bench.qp_export import export_qps

    out = tmp_path / "exported"
    if not out.exists():
        export_qps(tiny_dump(tmp_path), out, show_progress=False)
    return out


def short_form(argv: list[str], tmp_path: Path) -> list[str]:
    """The command's arguments, shortened and pointed at ``tmp_path``."""
    sub, rest = argv[1], argv[2:]
    out: list[str] = []
    if sub == "export-qps":  # a results folder with dumped QPs, exported into tmp_path
        return [sub, str(tiny_dump(tmp_path)), "--out", str(tmp_path / "exported")]
    if sub == "solvers" and "--sequences" in rest:  # an export, solved by two backends
        return [
            sub,
            "--sequences",
            str(tiny_export(tmp_path)),
            "--solver",
            "daqp",
            "--solver",
            "quadprog",
            "--no-progress",
        ]
    for arg in rest:
        if "<" in arg and arg.endswith(".npz"):  # a placeholder for a dumped QP
            from wbcbench.qp.examples import random_qp

            path = tmp_path / "problem.npz"
            random_qp(1, n=12, n_eq=4, n_in=6).save(path)
            out.append(str(path))
        elif any(ch in arg for ch in "*?[") and arg.endswith(".yaml"):  # the shell's glob
            out += sorted(glob.glob(str(ROOT / arg)))
        elif sub in ("tables", "solvers", "plots", "compare") and not arg.startswith("-"):
            out.append(reference_copy(tmp_path, arg.replace("/", "_")))
        elif arg.startswith("results"):
            out.append(str(tmp_path / arg))
        else:
            out.append(arg)
    if sub == "run":
        out += SHORT_RUN
        if "--out" not in out:
            out += ["--out", str(tmp_path / "run")]
    if sub in ("sweep", "bench"):
        out.append("--dry-run")
    return [sub, *out]


@pytest.mark.parametrize("command", COMMANDS, ids=IDS)
def test_each_readme_command_runs(
    command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(ROOT)
    argv = shlex.split(command, comments=True)
    if argv[0] == "make":
        done = subprocess.run(["make", "-n", *argv[1:]], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
    elif argv[0] == "python":
        script, options = argv[1], [a for a in argv[2:] if a.startswith("--")]
        done = subprocess.run(
            [sys.executable, script, "--help"], capture_output=True, text=True, cwd=ROOT
        )
        assert done.returncode == 0, done.stderr
        for option in options:
            assert option in done.stdout, f"{script} has no option {option}"
    else:
        assert argv[0] == "wbcbench", command
        assert main(short_form(argv, tmp_path)) == 0, command


@pytest.mark.parametrize("command", inline_cli_commands())
def test_each_inline_command_parses(command: str) -> None:
    """Placeholders (DIR, FILE) parse as the strings they stand for."""
    argv = shlex.split(command)[1:]
    if argv[0] == "sweep" and argv[1:] == ["FILE"]:
        argv = ["sweep", "sweeps/smoke.yaml"]
    build_parser().parse_args(argv)
