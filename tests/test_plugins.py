"""Controllers, solvers and robots from outside the package: the example plugin distribution
(``examples/plugin``) put on the path with its metadata, a broken one beside it, and
registrations made by a script. Each reaches ``wbcbench list``, ``validate``, ``run`` (its runs
in the guard's child process), a Dask sweep and the tables."""

from __future__ import annotations

import importlib
import shutil
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest

import wbcbench
from wbcbench import plugins
from wbcbench.cli import main
from wbcbench.controllers.qp_wbc import QpWbc
from wbcbench.controllers.registry import available_controllers, controller_class
from wbcbench.qp.backends.quadprog import QuadprogSolver
from wbcbench.qp.registry import available_solvers, make_solver
from wbcbench.robots.loader import load_robot, plugin_robots
from wbcbench.robots.spec import RobotFile

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "plugin"
SCENARIO = EXAMPLE / "src" / "wbcbench_example_plugin" / "scenarios" / "example_biped_sway.yaml"
SHORT = ["--set", "duration=0.05", "--set", "metrics.window=[0, 0.05]"]


def install(site: Path, project: Path) -> None:
    """A distribution's package and its ``.dist-info`` (METADATA, entry_points.txt from its
    pyproject.toml) in ``site``: installed as far as importlib.metadata can tell."""
    meta = tomllib.loads((project / "pyproject.toml").read_text())["project"]
    for package in (project / "src").iterdir():
        shutil.copytree(package, site / package.name)
    info = site / f"{meta['name'].replace('-', '_')}-{meta['version']}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {meta['name']}\nVersion: {meta['version']}\n"
    )
    lines = []
    for group, entries in meta.get("entry-points", {}).items():
        lines.append(f"[{group}]")
        lines += [f"{name} = {target}" for name, target in entries.items()]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The example plugin, and a broken one (an entry point to a missing module), on the path
    of this process and of every process it starts (PYTHONPATH: the Dask workers)."""
    folder = tmp_path_factory.mktemp("site")
    install(folder, EXAMPLE)
    broken = tmp_path_factory.mktemp("broken_project")
    (broken / "src" / "wbcbench_broken_plugin").mkdir(parents=True)
    (broken / "src" / "wbcbench_broken_plugin" / "__init__.py").write_text("")
    (broken / "pyproject.toml").write_text(
        '[project]\nname = "wbcbench-broken-plugin"\nversion = "0.0.1"\n'
        '[project.entry-points."wbcbench.controllers"]\n'
        'broken_wbc = "wbcbench_broken_plugin.missing:Controller"\n'
        '[project.entry-points."wbcbench.solvers"]\n'
        'broken_qp = "wbcbench_broken_plugin:NoSuchSolver"\n'
    )
    install(folder, broken)
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(folder))
        mp.setenv("PYTHONPATH", str(folder))
        importlib.invalidate_caches()
        yield folder
    importlib.invalidate_caches()


def test_the_example_plugin_is_listed_with_where_it_comes_from(
    site: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    origin = "plugin wbcbench-example-plugin 0.1.0"
    lines = {line.split()[0]: line for line in out.splitlines() if line.strip()}
    assert origin in lines["example_qp_wbc"] and "QP-WBC" in lines["example_qp_wbc"]
    assert origin in lines["example_daqp"] and "available" in lines["example_daqp"]
    assert origin in lines["example_biped"]
    assert "built-in" not in lines["qp_wbc"] and "plugin" not in lines["qp_wbc"]
    # the broken distribution is named, and hides nothing
    assert "BROKEN" in lines["broken_wbc"] and "wbcbench-broken-plugin 0.0.1" in out
    assert "ModuleNotFoundError" in lines["broken_wbc"]
    assert {"qp_wbc", "hqp", "example_qp_wbc"} <= set(available_controllers())
    assert {"proxqp", "example_daqp"} <= set(available_solvers())


def test_a_broken_entry_point_is_an_error_naming_its_distribution(site: Path) -> None:
    with pytest.raises(plugins.PluginError) as err:
        controller_class("broken_wbc")
    assert str(err.value).startswith(
        "cannot load entry point broken_wbc = 'wbcbench_broken_plugin.missing:Controller' of "
        "distribution wbcbench-broken-plugin 0.0.1 (group wbcbench.controllers): "
        "ModuleNotFoundError"
    )
    with pytest.raises(plugins.PluginError, match="broken_qp = 'wbcbench_broken_plugin:No"):
        make_solver("broken_qp")
    assert controller_class("qp_wbc") is QpWbc  # the built-ins are untouched


def test_plugin_entries_are_what_their_groups_take(site: Path) -> None:
    cls = controller_class("example_qp_wbc")
    assert issubclass(cls, QpWbc) and cls.Config().variables == "eliminated"
    assert make_solver("example_daqp").tier_settings("default")["eps_prox"] == 1e-6
    robot = load_robot("example_biped")
    assert (
        robot.k == 20
        and robot.info is not None
        and robot.info.contact_frames
        == (
            "l_sole",
            "r_sole",
        )
    )
    assert "example_biped" in plugin_robots()[0]


def test_validate_run_sweep_and_tables_with_the_plugin(
    site: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["validate", str(SCENARIO)]) == 0
    assert "example_biped, 4 tasks" in capsys.readouterr().out
    out = tmp_path / "run"
    args = ["run", str(SCENARIO), "--controller", "example_qp_wbc", "--controller", "qp_wbc"]
    args += ["--solver", "example_daqp", *SHORT, "--out", str(out), "--no-progress"]
    assert main(args) == 0  # in the guard's child: the plugin found there from its metadata
    runs = pd.read_csv(out / "runs.csv")
    assert set(runs["controller"]) == {"example_qp_wbc", "qp_wbc"}
    assert set(runs["solver"]) == {"example_daqp"} and set(runs["status"]) == {"ok"}

    sweep = tmp_path / "plugin.yaml"
    sweep.write_text(
        "version: 1\ntracking:\n"
        f"  - scenarios: [{SCENARIO}]\n"
        "    controllers: [example_qp_wbc]\n"
        "    solvers: [example_daqp, daqp]\n"
        '    set: ["duration=0.05", "metrics.window=[0, 0.05]"]\n'
    )
    folder = tmp_path / "sweep"
    args = ["sweep", str(sweep), "--executor", "dask", "--out", str(folder), "--no-progress"]
    assert main(args) == 0  # on Dask workers: the plugin found there too
    runs = pd.read_csv(folder / "runs.csv")
    assert sorted(runs["solver"]) == ["daqp", "example_daqp"]
    assert set(runs["status"]) == {"ok"}, runs["message"].tolist()
    assert main(["tables", str(folder)]) == 0
    assert (folder / "tables" / "papers.md").exists()


class RegisteredQuadprog(QuadprogSolver):
    """quadprog under another name, registered by a script."""

    name = "registered_quadprog"
    summary = "quadprog, registered in the test"


class RegisteredQpWbc(QpWbc):
    """QP-WBC under another name, registered by a script."""

    name = "registered_qp_wbc"
    summary = "QP-WBC, registered in the test"


@pytest.fixture
def registrations(site: Path) -> Iterator[None]:
    robot = RobotFile(
        path=site / "wbcbench_example_plugin" / "models" / "example_biped.xml",
        info=load_robot("example_biped").info,  # type: ignore[arg-type]
        summary="the example biped, registered in the test",
    )
    wbcbench.register_controller(RegisteredQpWbc)
    wbcbench.register_solver(RegisteredQuadprog)
    wbcbench.register_robot("registered_biped", robot)
    yield
    for group, name in (
        ("wbcbench.controllers", "registered_qp_wbc"),
        ("wbcbench.solvers", "registered_quadprog"),
        ("wbcbench.robots", "registered_biped"),
    ):
        plugins.unregister(group, name)


@pytest.mark.usefixtures("registrations")
def test_registrations_of_a_script_reach_its_guarded_runs(tmp_path: Path) -> None:
    res = wbcbench.run(
        SCENARIO,
        "registered_qp_wbc",
        "registered_quadprog",
        overrides=["robot=registered_biped", "duration=0.05", "metrics.window=[0, 0.05]"],
        out=tmp_path,
    )
    assert len(res.runs) == 1, res.runs
    row = res.runs.iloc[0]
    assert (row["robot"], row["controller"], row["solver"]) == (
        "registered_biped",
        "registered_qp_wbc",
        "registered_quadprog",
    )
    assert row["status"] == "ok", row["message"]
    assert set(res.metrics["run_id"]) == {row["run_id"]} and "unit" in res.metrics


def test_what_cannot_reach_another_process_is_refused() -> None:
    class Local(QpWbc):
        name = "local_qp_wbc"

    with pytest.raises(plugins.PluginError, match="not importable by module and name"):
        wbcbench.register_controller(Local)
    with pytest.raises(plugins.PluginError, match="built-in controller"):
        wbcbench.register_controller(QpWbc)
    with pytest.raises(plugins.PluginError, match=r"not a subclass of wbcbench\.QPSolver"):
        wbcbench.register_solver(QpWbc)  # type: ignore[arg-type]
    with pytest.raises(plugins.PluginError, match=r"not a wbcbench\.robots\.spec\.RobotFile"):
        wbcbench.register_robot("x", "model.xml")  # type: ignore[arg-type]
    assert "local_qp_wbc" not in available_controllers()
