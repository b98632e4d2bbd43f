"""Which of proxsuite's builds ProxQP runs: the generic one, for the same bits in every run.

proxsuite's wheel ships three builds of its Python module (generic, AVX2, AVX-512) and loads the
widest the CPU runs. The vectorised builds do not give the same bits for the same QP: measured on
10 dumped WBC QPs (hqp and qp_wbc on ``tocabi_stand_sway``, tier ``mid``), 2-3 of them changed
between repeated solves in one process as the heap moved, and two processes gave different
answers; the generic build gave the same bits every time, in every process, at about 1.5-1.9 ×
the solve time. In closed loop such last-bit differences grow (two identical sweeps' tracking
errors differed by up to 0.6 %), so wbcbench loads the generic build unless
``WBCBENCH_PROXSUITE=vectorized`` asks for proxsuite's own choice.

Importing this module calls :func:`choose`; ``wbcbench.qp`` imports it before anything imports
proxsuite. :func:`build` says what was loaded.
"""

from __future__ import annotations

import os
import sys
import types

#: ``generic`` (the default: reproducible) or ``vectorized`` (proxsuite's choice for the CPU)
ENV = "WBCBENCH_PROXSUITE"
CHOICES = ("generic", "vectorized")


def choose() -> None:
    """Have the next ``import proxsuite`` load the build :data:`ENV` asks for (a no-op once
    proxsuite is imported: :func:`build` then says which one it is)."""
    if "proxsuite" in sys.modules or os.environ.get(ENV, "generic") != "generic":
        return
    # proxsuite's __init__ asks its `instructionset` module which build the CPU runs
    stub = types.ModuleType("proxsuite.instructionset")
    stub.has_AVX512F = lambda: False  # type: ignore[attr-defined]
    stub.has_AVX2 = lambda: False  # type: ignore[attr-defined]
    sys.modules["proxsuite.instructionset"] = stub


def build() -> str:
    """The proxsuite build in use (``proxsuite_pywrap``, ``…_avx2``, ``…_avx512``), or "" when
    proxsuite is not imported."""
    module = sys.modules.get("proxsuite")
    loaded = getattr(module, "_submodule", None) if module is not None else None
    return str(getattr(loaded, "__name__", "")).rsplit(".", 1)[-1]


choose()
