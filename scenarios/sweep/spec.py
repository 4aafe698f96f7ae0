"""The sweep file: a base scenario and the grid of values to vary, every point resolved
to a full scenario dict, validated and keyed before anything is computed."""
from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from arfem.io import read_toml
from arfem.limits import Limits
from arfem.params import InputError
from arfem.scenarios.rod.scenario import ALIASES, apply_override, scenario_from_dict
from arfem.scenarios.shipped import builtin_scenario_path
from arfem.scenarios.sweep.geometry import geometry_sweep_from_dict
from arfem.scenarios.sweep.points import (MAX_POINTS, STORE_VERSION, Point, Sweep,
                                          distinct_values, flatten_keys, point_key)
from arfem.strict import check_keys

__all__ = ["Sweep", "Point", "load_sweep", "sweep_from_dict", "point_key", "resolved_inputs",
           "STORE_VERSION", "METRIC_COLUMNS", "CORE_INPUTS", "TIMING_COLUMNS",
           "MAX_POINTS", "check_size"]

#: Column name of a grid key (the three usual inputs keep their short names).
_COLUMN = {"ar.dtau_s": "dtau_s", "rod.convection_W_m2K": "h_W_m2K", "cycle.q_W_m2": "q_W_m2"}
#: Input columns always present in ``results.csv`` (taken from the point's metrics if not swept).
CORE_INPUTS = ("dtau_s", "h_W_m2K", "q_W_m2")

#: Output columns of ``results.csv``, in order (units in the names; pct = % of FEM peak).
METRIC_COLUMNS = (
    "biot", "C1", "C2_um", "C1_fitted", "C2_fitted_um", "corrected_C1", "corrected_C2_um",
    "fem_peak_um", "fem_peak_time_h", "ar_peak_um",
    "max_abs_diff_um", "max_abs_diff_pct_of_peak", "rmse_um", "rmse_pct_of_peak",
    "corrected_max_abs_diff_um", "corrected_max_abs_diff_pct_of_peak",
    "corrected_rmse_um", "corrected_rmse_pct_of_peak",
    "fem_dofs", "n_samples", "run_time_s",
)
#: Columns that depend on the machine, not on the inputs (left out of reproducibility checks).
TIMING_COLUMNS = ("run_time_s",)

_SWEEP_KEYS = {"name", "base", "description", "grid"}


def resolved_inputs(scenario) -> dict:
    """Everything a point's results depend on, with defaults filled in.

    The validated rod (every field), the cycle as segments (durations, q, ambient,
    h), Δτ and the FEM settings. Names, descriptions and output options are left
    out: they do not change a number in ``results.csv``.

    Examples
    --------
    >>> from arfem.scenarios.rod.scenario import scenario_from_dict
    >>> cyc = {"phases": [{"duration_h": 1.0, "q_W_m2": 2000.0}]}
    >>> a = scenario_from_dict({"cycle": cyc, "scenario": {"name": "a"}})
    >>> b = scenario_from_dict({"cycle": cyc, "rod": {"radius_m": 0.1}, "ar": {"dtau_s": 30}})
    >>> point_key(resolved_inputs(a)) == point_key(resolved_inputs(b))
    True
    """
    from dataclasses import asdict, fields as dc_fields
    sch = scenario.schedule
    arr = lambda a: None if a is None else [float(x) for x in np.asarray(a)]
    return {
        "rod": {f.name: getattr(scenario.rod, f.name) for f in dc_fields(scenario.rod)},
        "schedule": {"durations_s": arr(sch.durations_s), "q_W_m2": arr(sch.q_W_m2),
                     "ambient_C": arr(sch.ambient_C), "h_W_m2K": arr(sch.h_W_m2K)},
        "dtau_s": scenario.dtau_s,
        "fem": asdict(scenario.fem),
    }


def _resolve_base(base: str, sweep_path: Path) -> tuple[Path, str]:
    """A path relative to the sweep file, or a built-in scenario name."""
    p = Path(base)
    cand = p if p.is_absolute() else sweep_path.parent / p
    if cand.is_file():
        return cand, str(cand)
    if p.suffix in ("", ".toml") and len(p.parts) == 1:
        try:
            b = builtin_scenario_path(p.name)
            return b, p.stem
        except InputError:
            pass
    raise InputError(f"no scenario file {str(cand)!r} and no built-in scenario {base!r}",
                     "sweep.base")


def load_sweep(path, max_points: int | None = None, limits: Limits | None = None) -> Sweep:
    """Read and validate a sweep file; every point is resolved and checked up front.

    Errors are one line naming the file, the key (``sweep.grid.dtau_s[2]``) and what
    is wrong, e.g. a Δτ that does not divide the phases. A grid of more than
    ``max_points`` points (default :data:`MAX_POINTS`) is refused before any point is
    resolved (:func:`check_size`). ``limits`` (:class:`arfem.limits.Limits`): what the
    user allows past each point's size limits.
    """
    p = Path(path)
    data = read_toml(p, limits)
    return sweep_from_dict(data, str(p), max_points=max_points, limits=limits)


def sweep_from_dict(data: dict, source: str = "<sweep>", base_data: dict | None = None,
                    max_points: int | None = None, limits: Limits | None = None) -> Sweep:
    """Validate a sweep given as a dict (as read from TOML).

    ``base_data`` may be given to use a scenario dict instead of reading
    ``sweep.base`` (tests, programmatic sweeps).
    """
    try:
        return _sweep_from_dict(data, source, base_data, max_points, limits)
    except InputError as exc:
        if exc.where and exc.where.startswith(source):
            raise
        raise exc.at(source) from None


def _sweep_from_dict(data: dict, source: str, base_data: dict | None,
                     max_points: int | None, limits: Limits | None) -> Sweep:
    if not isinstance(data, dict) or set(data) != {"sweep"}:
        extra = sorted(set(data) - {"sweep"}) if isinstance(data, dict) else []
        raise InputError(f"unknown top-level key {extra[0]!r}; a sweep file holds one [sweep] "
                         "table" if extra else "needs a [sweep] table", extra[0] if extra else None)
    sw = data["sweep"]
    if not isinstance(sw, dict):
        raise InputError("must be a table", "sweep")
    check_keys(sw, _SWEEP_KEYS, "sweep")
    name = sw.get("name", Path(source).stem)
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"must be a non-empty string, got {name!r}", "sweep.name")
    description = sw.get("description", "")
    if not isinstance(description, str):
        raise InputError(f"must be a string, got {description!r}", "sweep.description")
    if base_data is None:
        if "base" not in sw:
            raise InputError("missing: name the base scenario (a built-in such as "
                             "'paper_fig2', or a .toml path relative to the sweep file)",
                             "sweep.base")
        if not isinstance(sw["base"], str):
            raise InputError(f"must be a string, got {sw['base']!r}", "sweep.base")
        base_path, base_name = _resolve_base(sw["base"], Path(source))
        base_data = read_toml(base_path, limits)
        base_source = str(base_path)
    else:
        base_name, base_source = str(sw.get("base", "<base>")), "<base>"
    if isinstance(base_data, dict) and "geometry" in base_data:    # a mesh scenario (issue 32)
        return _mesh_sweep(sw, name, description, source, base_data, base_source, max_points)
    base_sc = scenario_from_dict(base_data, base_source, limits)   # the base must be valid

    grid_d = sw.get("grid")
    if not isinstance(grid_d, dict) or not grid_d:
        raise InputError("must be a non-empty table of key = [values, ...]", "sweep.grid")
    check_size(flatten_keys(grid_d), base_sc, max_points)
    grid, paths = {}, {}
    for key, values in flatten_keys(grid_d).items():
        where = f"sweep.grid.{key}"
        if not isinstance(values, list):
            raise InputError(f"must be a list of values, got {type(values).__name__} "
                             f"{values!r}", where)
        if not values:
            raise InputError("is empty; give at least one value", where)
        path = ALIASES.get(key, key)
        col = _COLUMN.get(path, key)
        if col in grid:
            raise InputError(f"sets the same input as sweep.grid.{paths[col]}", where)
        distinct_values(values, where)
        try:
            apply_override(base_data, key, values[0])
        except InputError as exc:            # unknown key
            raise InputError(exc.message, where) from None
        for i, v in enumerate(values):        # each value alone on the base: names the culprit
            try:
                scenario_from_dict(apply_override(base_data, key, v), base_source, limits)
            except InputError as exc:
                raise InputError(f"{v!r} is refused: {exc}", f"{where}[{i}]") from None
        grid[col], paths[col] = list(values), key

    points = []
    cols = list(grid)
    for i, combo in enumerate(itertools.product(*(grid[c] for c in cols))):
        d = base_data
        for c, v in zip(cols, combo):
            d = apply_override(d, paths[c], v)
        inputs = dict(zip(cols, combo))
        try:
            sc = scenario_from_dict(d, base_source, limits)
        except InputError as exc:
            raise InputError(f"point {inputs} is refused: {exc}", "sweep.grid") from None
        points.append(Point(i, inputs, d, point_key(resolved_inputs(sc))))
    return Sweep(name=name, description=description, source=source, base=base_name,
                 grid=grid, paths=paths, points=tuple(points))


def _mesh_sweep(sw, name, description, source, base_data, base_source, max_points):
    """The sweep of a mesh scenario (``[geometry]``): :mod:`arfem.scenarios.sweep.geometry`."""
    return geometry_sweep_from_dict(sw, name, description, source, base_data,
                                    None if base_source == "<base>" else Path(base_source),
                                    str(sw.get("base", "<base>")), max_points)


def check_size(grid: dict, base, max_points: int | None = None) -> tuple[int, float]:
    """Points and AR/FEM time steps of a grid, from the list lengths alone; refuse (one
    line) a grid of more than ``max_points`` points before anything is resolved.

    Parameters
    ----------
    grid : dict
        Flattened ``sweep.grid`` (dotted key -> list of values).
    base : Scenario
        The validated base scenario (its cycle length and Δτ give the steps per point).
    max_points : int, optional
        Limit (default :data:`MAX_POINTS`; ``--max-points`` lifts it).

    Returns
    -------
    (int, float)
        Number of points, estimated number of time steps over all points.
    """
    limit = MAX_POINTS if max_points is None else int(max_points)
    n = 1
    sizes = []
    for v in grid.values():
        sizes.append(len(v) if isinstance(v, list) else 1)
        n *= sizes[-1]
    cycle_s = float(sum(base.schedule.durations_s))
    dtaus = next((v for k, v in grid.items() if ALIASES.get(k, k) == "ar.dtau_s"
                  and isinstance(v, list)), None)
    try:
        per = (sum(cycle_s / float(d) for d in dtaus) / len(dtaus) if dtaus
               else cycle_s / float(base.dtau_s))
    except (TypeError, ValueError, ZeroDivisionError):
        per = cycle_s / float(base.dtau_s)
    steps = n * per
    if n > limit:
        shape = " × ".join(str(k) for k in sizes)
        raise InputError(f"{n} points ({shape}), about {steps:.2g} AR/FEM time steps, is "
                         f"more than the limit of {limit} points; split the grid, or pass "
                         f"--max-points {n} to run it anyway", "sweep.grid")
    return n, steps
