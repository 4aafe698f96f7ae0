"""Small inputs shared by several test files (``from scenario_texts import ...``: the
``pythonpath`` setting of ``[tool.pytest.ini_options]`` puts ``tests/`` on the path)."""
from __future__ import annotations


def small_scenario(name: str = "small", fields: bool = False, picture: bool = False,
                   field_interval_s: float | None = None) -> str:
    """A 2 h scenario (1 h at 2000 W/m², 1 h off) on a 2 x 8 mesh: seconds to run.

    The lines are the ones tests edit by ``str.replace`` (``dtau_s = 60.0``,
    ``nr = 2``, ``nz = 8``, ``[scenario]``, ...)."""
    text = f"""
[scenario]
name = "{name}"
[cycle]
phases = [ {{ duration_h = 1.0, q_W_m2 = 2000.0 }}, {{ duration_h = 1.0, q_W_m2 = 0.0 }} ]
[ar]
dtau_s = 60.0
[fem]
[fem.mesh]
nr = 2
nz = 8
[outputs]
fields = {str(fields).lower()}
picture = {str(picture).lower()}
"""
    if field_interval_s is not None:
        text += f"field_interval_s = {field_interval_s!r}\n"
    return text
