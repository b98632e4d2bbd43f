"""An example wbcbench plugin: a controller, a QP backend and a robot, declared as entry points
in this distribution's ``pyproject.toml``."""
