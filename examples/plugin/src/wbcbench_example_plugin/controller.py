"""A controller from outside wbcbench: the weighted QP-WBC in its torque-eliminated form, with
a task weight per priority three decades apart (1e6, 1e3, 1) instead of wbcbench's defaults.

A plugin controller is a :class:`wbcbench.Controller` subclass whose ``name`` is its entry
point's name; its ``Config`` is a pydantic model of its settings (a scenario's
``controllers.example_qp_wbc`` section and a sweep's ``configs`` are validated against it).
"""

from __future__ import annotations

from typing import Annotated, ClassVar, Literal

from pydantic import Field

from wbcbench.controllers.qp_wbc import QpWbc, QpWbcConfig


class ExampleQpWbcConfig(QpWbcConfig):
    """QP-WBC's settings with this controller's defaults."""

    variables: Literal["full", "eliminated"] = Field(
        "eliminated", description="(q̈, Γ, f) or torque-eliminated (q̈, f)"
    )
    weights: list[Annotated[float, Field(gt=0)]] = Field(
        [1e6, 1e3, 1.0],
        min_length=1,
        description="task weight per priority (1 first); the last one repeats for lower ones",
    )


class ExampleQpWbc(QpWbc):
    """Weighted QP-WBC, torque eliminated, weights 1e6 / 1e3 / 1 per priority."""

    name: ClassVar[str] = "example_qp_wbc"
    summary: ClassVar[str] = "example plugin: QP-WBC, torque eliminated, weights 1e6/1e3/1"
    Config = ExampleQpWbcConfig
