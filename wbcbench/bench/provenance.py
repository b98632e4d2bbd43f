"""Where and with what a result was measured: machine, versions, code, date."""

from __future__ import annotations

import datetime as _dt
import functools
import hashlib
import os
import platform
import re
import subprocess
import time
from importlib import metadata
from pathlib import Path
from typing import Any

from wbcbench.qp import proxsuite_build

REPO = Path(__file__).resolve().parents[2]

#: the tested dependency set: every distribution, direct and transitive, at an exact version
LOCK = REPO / "requirements" / "lock.txt"

#: installed but never part of the lock: the project itself and the installer
#: the installed package's folder (its source is hashed into every row's code version)
PACKAGE_DIR = Path(__file__).resolve().parents[1]
_NOT_LOCKED = frozenset({"wbcbench", "pip"})

#: distributions whose versions every results file records
PACKAGES = (
    "numpy",
    "scipy",
    "mujoco",
    "pin",
    "pandas",
    "pydantic",
    "qpsolvers",
    "proxsuite",
    "osqp",
    "clarabel",
    "piqp",
    "daqp",
    "quadprog",
    "highspy",
    "casadi",
    "pyqpmad",
    "eiquadprog",
)


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


#: other work per core above which a timing is flagged: the machine was busy
BUSY_LOAD_PER_CORE = 0.5


class CpuWatch:
    """The CPU time the rest of the machine used while this process timed something.

    Started before a timing and read after it: the machine's busy CPU time (all but idle and
    I/O wait, steal included), less this process's own, per core and per second of wall time.
    Unlike the load average, which trails by a minute, it sees only the interval itself, so a
    timing made just after a parallel phase of the same sweep is not called busy for it.
    """

    def __init__(self) -> None:
        import psutil

        self._process = psutil.Process()
        self._start = self._sample()

    def _sample(self) -> tuple[float, float, float]:
        import psutil

        system = psutil.cpu_times()
        busy = sum(system) - system.idle - getattr(system, "iowait", 0.0)
        own = self._process.cpu_times()
        return time.perf_counter(), busy, own.user + own.system

    def other_per_core(self) -> float:
        """The rest of the machine's CPU use since the start, in cores per core (0 … 1)."""
        wall0, busy0, own0 = self._start
        wall1, busy1, own1 = self._sample()
        cores = os.cpu_count() or 1
        elapsed = max(wall1 - wall0, 1e-9)
        return min(1.0, max(0.0, ((busy1 - busy0) - (own1 - own0)) / (elapsed * cores)))


def cpu_mhz() -> float | None:
    """The cores' current clock [MHz] (mean over /proc/cpuinfo), None where it is not known."""
    try:
        mhz = [
            float(line.split(":", 1)[1])
            for line in Path("/proc/cpuinfo").read_text().splitlines()
            if line.startswith("cpu MHz")
        ]
    except (OSError, ValueError):
        return None
    return round(sum(mhz) / len(mhz), 1) if mhz else None


#: the fixed workload of :func:`speed_probe`: LU solves of a seeded 120 × 120 system
_PROBE_SIZE, _PROBE_SOLVES = 120, 20


def speed_probe() -> float:
    """The time [ms] of a fixed dense workload (:data:`_PROBE_SOLVES` LU solves of a seeded
    :data:`_PROBE_SIZE`-square system, one BLAS thread where the caller limits it): how fast
    the machine runs right now. A virtual machine's speed can move by half within seconds while
    neither its load nor its CPU accounting shows it (the host's other guests); timings taken
    on either side of such a move are not comparable, which these probes around each timing
    reveal."""
    import numpy as np

    a = np.random.default_rng(0).standard_normal((_PROBE_SIZE, _PROBE_SIZE))
    a += _PROBE_SIZE * np.eye(_PROBE_SIZE)
    t0 = time.perf_counter()
    for _ in range(_PROBE_SOLVES):
        np.linalg.solve(a, a)
    return round(1e3 * (time.perf_counter() - t0), 3)


def machine_conditions(watch: CpuWatch | None = None) -> dict[str, Any]:
    """What the machine was doing when a timing was taken: the load average (1 min) in all and
    per core, the CPU model and clock, the BLAS threads, and whether the machine was ``busy``.

    With a started ``watch``, busy means the rest of the machine used more than
    :data:`BUSY_LOAD_PER_CORE` of each core over the watched interval (``other_cpu_per_core``,
    ``busy_basis: cpu``). Without one, it falls back to the load average less the one core the
    timing process keeps busy (``other_load_per_core``, ``busy_basis: load``)."""
    from threadpoolctl import threadpool_info

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    cores = os.cpu_count() or 1
    blas = [i.get("num_threads", 0) for i in threadpool_info() if i.get("user_api") == "blas"]
    # the verdict is taken on the recorded (rounded) figure, so a reader can check it
    other_load = round(max(0.0, load - 1.0) / cores, 2)
    out: dict[str, Any] = {
        "load_1min": round(load, 2),
        "load_per_core": round(load / cores, 2),
        "other_load_per_core": other_load,
        "busy": bool(other_load > BUSY_LOAD_PER_CORE),
        "busy_basis": "load",
        "cpu": cpu_model(),
        "cpu_mhz": cpu_mhz(),
        "blas_threads": max(blas, default=0),
    }
    if watch is not None:
        other_cpu = round(watch.other_per_core(), 2)
        out.update(
            other_cpu_per_core=other_cpu,
            busy=bool(other_cpu > BUSY_LOAD_PER_CORE),
            busy_basis="cpu",
        )
    return out


def other_work_per_core(conditions: dict[str, Any]) -> float:
    """The other work a timing's ``conditions`` measured per core: its CPU, else its load."""
    key = "other_cpu_per_core" if conditions.get("busy_basis") == "cpu" else "other_load_per_core"
    return float(conditions.get(key, 0.0))


def other_work(conditions: dict[str, Any]) -> str:
    """The other work a timing's ``conditions`` record, in words: ``other work 0.75 per core
    (CPU, measured over the timing)`` or ``… (load average)``."""
    if conditions.get("busy_basis") == "cpu":
        return f"other work {conditions.get('other_cpu_per_core', float('nan')):g} per core (CPU)"
    return f"other work {conditions.get('other_load_per_core', float('nan')):g} per core (load)"


def git_commit() -> str:
    """The commit of the working tree, with ``+dirty`` when it has uncommitted changes."""
    try:
        commit = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"],
            cwd=REPO,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=REPO,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        return commit + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


#: the files of the package whose content can change a result (code, models, native sources)
_SOURCE_SUFFIXES = (".py", ".xml", ".cpp", ".hpp", ".so")


def tree_hash(root: Path, digest: Any = None) -> Any:
    """Feed the code files under ``root`` (name and content, in a fixed order) to a sha256."""
    digest = hashlib.sha256() if digest is None else digest
    for path in sorted(root.rglob("*")):
        if path.suffix in _SOURCE_SUFFIXES and "__pycache__" not in path.parts and path.is_file():
            digest.update(str(path.relative_to(root)).encode())
            digest.update(path.read_bytes())
    return digest


@functools.cache
def source_hash() -> str:
    """12 hex digits of the content of the package's code: every ``.py``, model and C++ file
    and the built native module, uncommitted edits included, so a result is tied to the code
    that produced it (docs, tests and results do not count)."""
    digest = tree_hash(PACKAGE_DIR)
    try:  # an editable install keeps the compiled module outside the source folder
        from wbcbench._native import _core

        if _core is not None and getattr(_core, "__file__", None):
            digest.update(Path(_core.__file__).read_bytes())
    except ImportError:
        pass
    return digest.hexdigest()[:12]


def package_versions() -> dict[str, str]:
    out = {}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "not installed"
    return out


def _normalise(name: str) -> str:
    """A distribution name in its canonical form (PEP 503): ``Jinja2`` → ``jinja2``."""
    return re.sub(r"[-_.]+", "-", name).lower()


def read_lock(path: Path = LOCK) -> dict[str, str]:
    """The ``name==version`` pins of a pip-compile lock file, by canonical name."""
    pins = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        match = re.match(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;#]+)", line)
        if match:
            pins[_normalise(match.group(1))] = match.group(2)
    return pins


def installed_versions() -> dict[str, str]:
    """Every installed distribution of this interpreter, by canonical name."""
    return {_normalise(d.metadata["Name"]): d.version for d in metadata.distributions()}


def lock_status(path: Path = LOCK) -> dict[str, Any]:
    """Whether the environment is the locked one.

    Returns:
        ``{"lock": path, "matches": bool, "differs": {name: {"locked": v, "installed": v}}}``,
        where a side that has no such package says ``"-"``; ``matches`` is ``None`` (and
        ``differs`` empty) when there is no lock file, e.g. in an installed wheel.
    """
    if not path.is_file():
        return {"lock": str(path), "matches": None, "differs": {}}
    locked = read_lock(path)
    installed = {k: v for k, v in installed_versions().items() if k not in _NOT_LOCKED}
    differs = {
        name: {"locked": locked.get(name, "-"), "installed": installed.get(name, "-")}
        for name in sorted(set(locked) | set(installed))
        if locked.get(name) != installed.get(name)
    }
    return {"lock": str(path), "matches": not differs, "differs": differs}


def describe_lock_status(status: dict[str, Any]) -> list[str]:
    """The lock comparison as lines for a terminal (one per differing package)."""
    if status["matches"] is None:
        return [f"no lock file at {status['lock']}: versions unchecked"]
    if status["matches"]:
        return [f"matches {status['lock']}"]
    lines = [f"DIFFERS from {status['lock']} ({len(status['differs'])} packages):"]
    for name, d in status["differs"].items():
        lines.append(f"  {name:<28} locked {d['locked']:<14} installed {d['installed']}")
    return lines


def provenance() -> dict[str, Any]:
    return {
        "wbcbench": metadata.version("wbcbench"),
        "git_commit": git_commit(),
        "source_hash": source_hash(),
        "date": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "machine": platform.machine(),
        "os": platform.platform(),
        "python": platform.python_version(),
        "packages": package_versions(),
        "environment": lock_status(),
        # which of proxsuite's builds ProxQP runs (wbcbench.qp.proxsuite_build)
        "proxsuite_build": os.environ.get(proxsuite_build.ENV, "generic"),
    }
