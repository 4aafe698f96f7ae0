"""arfem's public Python API: what each ``arfem`` command does, as functions.

Everything listed in ``__all__`` here is promised: documented, with units in its
parameter names, an example that runs, and a result object with ``to_dataframe()``
and ``to_json()`` where that helps. It is re-exported lazily by ``import arfem``
(``arfem.solve_fem`` …), so importing arfem stays fast and the FEM, the diagnosis
engine and matplotlib load only when used. Everything else stays importable from its
module but is not promised.

The paper's rod and a user's mesh are two kinds of one scenario: :func:`load_scenario`
reads either, and :func:`solve`, :func:`run`, :func:`compare`, :func:`check` and
:func:`sweep` take either and give one result type each (:class:`FemResult`,
:class:`Comparison`, :class:`CheckResult`, :class:`SweepResult`).

This module sits above every layer (ground → fem → models → scenarios → api): it
composes them, nothing imports it.

Quick start (the FEM and the paper's AR(1) on your own rod in a few lines):

>>> import arfem
>>> rod = arfem.Rod(radius_m=0.05, length_m=0.5)
>>> cycle = arfem.paper_cycle(2000.0)
>>> fem = arfem.solve_fem(rod, cycle, dtau_s=60.0)
>>> ar = arfem.ar1(rod, cycle, dtau_s=60.0)
>>> round(float(fem.growth_um.max()), 2), round(float(ar.growth_um.max()), 2)
(11.06, 10.91)
"""
from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from arfem import __version__
from arfem.io import json_text
from arfem.models.compensator import Compensator, StateSpaceModel, ar1_model
from arfem.models.diagnosis.result import Holdout, NamedCause
from arfem.params import InputError, Rod, Schedule, paper_cycle

if TYPE_CHECKING:                     # names in annotations only; not loaded at import
    import pandas
    from numpy.typing import ArrayLike

    from arfem.models.diagnosis.dataset import Dataset
    from arfem.models.diagnosis.result import Diagnosis
    from arfem.scenarios.gate import Criterion
    from arfem.scenarios.rod.scenario import Scenario
    from arfem.scenarios.geometry.check import GeometryCheckCase
    from arfem.scenarios.geometry.scenario import GeometryScenario

__all__ = ["Rod", "Schedule", "paper_cycle", "load_scenario", "shipped_scenario", "solve",
           "run", "solve_fem", "FemResult", "ar1", "AR1Result", "compare", "Comparison",
           "check", "CheckResult", "sweep", "SweepResult",
           "diagnose", "diagnose_mesh", "DiagnosisResult", "NamedCause", "Holdout",
           "Compensator", "StateSpaceModel", "ar1_model",
           "read_model", "read_record", "Record", "InputError", "__version__"]


def _frame(columns: dict) -> pandas.DataFrame:
    import pandas as pd
    return pd.DataFrame(columns)


# -- scenarios: the rod's and a mesh's --------------------------------------------------------

def shipped_scenario(name: str) -> Path:
    """The file of a scenario shipped with arfem, by its name.

    Parameters
    ----------
    name : str
        ``"paper_fig2"``, ``"paper_fig3"`` (the paper's rod at q = 2000 and 3000 W/m²),
        ``"spindle_unit"`` (a spindle unit on a Gmsh mesh, its ``.msh`` beside it), or
        a shipped sweep (``"sweep_dtau_h"``, ``"sweep_spindle_unit"``); ``.toml`` may
        be given or left out.

    Returns
    -------
    pathlib.Path
        The installed file (read it, or copy it to edit it).

    Raises
    ------
    InputError
        No shipped file of that name; the message lists the names there are.

    Examples
    --------
    >>> p = shipped_scenario("spindle_unit")
    >>> p.name, p.with_suffix(".msh").is_file()
    ('spindle_unit.toml', True)
    """
    from arfem.scenarios.shipped import builtin_scenario_path
    return builtin_scenario_path(str(name))


def _file_or_shipped(path: str | Path) -> Path:
    """``path`` itself, or the shipped file of a bare name that is no file here (the
    CLI's rule, :func:`arfem.scenarios.rod.scenario.scenario_file`)."""
    from arfem.scenarios.shipped import scenario_file
    return scenario_file(path)


def load_scenario(path: str | Path, *, order: int | None = None) -> Scenario | GeometryCheckCase:
    """Read and validate a scenario TOML: the paper's rod, or a mesh (``[geometry]``).

    Parameters
    ----------
    path : str or path-like
        A scenario file (the documentation's "Scenario files" and "Your own geometry"
        pages) or the name of a shipped one (:func:`shipped_scenario`):
        ``"paper_fig2"``, ``"paper_fig3"``, ``"spindle_unit"``.
    order : {1, 2}, optional
        Element order instead of the file's (``[fem] order`` of a rod, ``[geometry]
        order`` of a mesh): 1 for a quick look (seconds on the shipped unit, where 2
        takes about a minute). Validated as the file's value would be.

    Returns
    -------
    Scenario or GeometryCheckCase
        ``kind == "rod"``: :class:`arfem.scenarios.rod.scenario.Scenario` (``rod``,
        ``schedule``, ``dtau_s`` [s], ``fem``, ``check``). ``kind == "mesh"``:
        :class:`arfem.scenarios.geometry.check.GeometryCheckCase`: ``scenario`` (the
        validated mesh scenario: ``mesh_path``, ``materials``, ``cycle``, ``sources``,
        ``sensors``, …) and its ``[check]`` values. Both have ``name`` and ``source``.

    Raises
    ------
    InputError
        Malformed file, unknown key or impossible value; the message is the one line
        ``arfem`` prints: the file, the key and what is wrong.

    Examples
    --------
    >>> sc = load_scenario("paper_fig2")
    >>> sc.kind, sc.dtau_s, sc.schedule.total_s / 3600
    ('rod', 30.0, 24.0)
    >>> unit = load_scenario("spindle_unit", order=1)
    >>> unit.kind, unit.scenario.order, [s.name for s in unit.scenario.sensors][:3]
    ('mesh', 1, ['tcp_x', 'tcp_y', 'tcp_z'])
    """
    from arfem.io import read_toml
    from arfem.scenarios.rod.scenario import scenario_from_dict
    from arfem.scenarios.geometry.check import geometry_case_from_dict
    p = _file_or_shipped(path)
    data = read_toml(p)
    mesh = isinstance(data, dict) and "geometry" in data       # as arfem check tells them
    if order is not None:
        key = "geometry" if mesh else "fem"
        if isinstance(data.get(key, {}), dict):   # else the reader names the bad table
            data = {**data, key: {**data.get(key, {}), "order": order}}
    if mesh:
        return geometry_case_from_dict(data, str(p), p.parent)
    return scenario_from_dict(data, str(p))


def _loaded(scenario) -> Scenario | GeometryCheckCase:
    """A scenario argument as :func:`load_scenario` gives it (a path or a name is read)."""
    from arfem.scenarios.rod.scenario import Scenario
    from arfem.scenarios.geometry.check import GeometryCheckCase
    from arfem.scenarios.geometry.scenario import GeometryScenario
    if isinstance(scenario, (Scenario, GeometryCheckCase)):
        return scenario
    if isinstance(scenario, GeometryScenario):
        return GeometryCheckCase(scenario)
    if isinstance(scenario, (str, Path)):
        return load_scenario(scenario)
    raise InputError("must be a scenario from arfem.load_scenario, a scenario file or a "
                     f"shipped scenario's name, got {type(scenario).__name__}", "scenario")


def _progress_hook(progress: bool | Callable[[str], None], steps: int, desc: str):
    """A context giving the step hook of ``progress``: the callable itself, or a
    :class:`~arfem.scenarios.progress.Progress` shown on stderr (asked for: shown even
    where stderr is no terminal, a notebook's) or silent."""
    if callable(progress):
        return contextlib.nullcontext(progress)
    from arfem.scenarios.progress import Progress
    return Progress(steps, desc, enabled=bool(progress), tty=True)


# -- the FEM -------------------------------------------------------------------------------

class Channel(NamedTuple):
    """One output of a FEM solve: a sensor of a mesh scenario, or the rod's growth.

    Attributes
    ----------
    name : str
        The sensor's name (``"tcp_z"``); the rod's one channel is ``"growth"``.
    quantity : str
        ``"displacement"`` [µm], ``"tilt"`` [µrad] or ``"temperature"`` [°C].
    column : str
        Its column in the files arfem writes and in :meth:`FemResult.to_dataframe`:
        ``d_<name>_um``, ``tilt_<name>_urad``, ``T_<name>_C`` (``sensors.csv`` of a
        mesh run, contract v3); the rod's ``growth_um`` (contract v1).
    unit : str
        ``"µm"``, ``"µrad"`` or ``"°C"``.
    """

    name: str
    quantity: str
    column: str
    unit: str


#: The rod's one output: the axial growth α∫θ dV / A of the free rod [µm].
_ROD_GROWTH = Channel("growth", "displacement", "growth_um", "µm")


@dataclass(frozen=True)
class FemResult:
    """A FEM solve of the rod or of a mesh: every output channel at the output times.

    Attributes
    ----------
    times_s : ndarray
        Output times [s]: 0, Δτ, 2Δτ, … (the rod), every ``output_interval_s`` (a mesh).
    displacement_um : dict of str to ndarray
        Each displacement channel [µm] by name: the rod's ``"growth"`` (α∫θ dV / A, the
        far-face growth of a free rod), a mesh's sensors along their directions.
    tilt_urad : dict of str to ndarray
        Each tilt sensor [µrad] (a mesh's; empty for the rod).
    temperature_C : dict of str to ndarray
        Each thermometer [°C] (a mesh's; empty for the rod).
    channels : tuple of Channel
        Every channel in the scenario's order: name, quantity, file column, unit.
    kind : str
        ``"rod"`` or ``"mesh"``.
    scenario : str
        The scenario's name (empty for :func:`solve_fem` on a bare rod).
    model : str
        The rod's ``"axisymmetric"`` or ``"3d"``; ``"mesh"``.
    solver : str
        The rod's ``"modal"``, ``"crank-nicolson"`` or ``"backward-euler"``; a mesh's
        ``"reduced"``, ``"crank-nicolson"`` or ``"backward-euler"``.
    ndofs : int
        Temperature unknowns.
    heat_J : ndarray or None
        Heat stored in the rod relative to the ambient state [J] (the rod, by
        :func:`solve` and :func:`solve_fem`; else None).
    error_estimate_um : ndarray or None
        The rod's reduced-modal solve's stated error [µm] (3D modal only).
    """

    times_s: np.ndarray
    displacement_um: dict
    tilt_urad: dict
    temperature_C: dict
    channels: tuple
    kind: str
    scenario: str
    model: str
    solver: str
    ndofs: int
    heat_J: np.ndarray | None = None
    error_estimate_um: np.ndarray | None = None

    @property
    def growth_um(self) -> np.ndarray:
        """The rod's axial growth [µm] (``displacement_um["growth"]``); a mesh has one
        displacement per sensor instead (AttributeError)."""
        if self.kind != "rod":
            raise AttributeError("a mesh has no one growth: read displacement_um[<sensor>] "
                                 f"(sensors {sorted(self.displacement_um)})")
        return self.displacement_um["growth"]

    def _values(self, c: Channel) -> np.ndarray:
        by = {"displacement": self.displacement_um, "tilt": self.tilt_urad,
              "temperature": self.temperature_C}
        return by[c.quantity][c.name]

    def to_dataframe(self) -> pandas.DataFrame:
        """``time_s``, then each channel under its file column (``d_tcp_z_um``,
        ``T_housing_C``, …; the rod's ``growth_um``), and the rod's ``heat_J``."""
        cols = {"time_s": self.times_s}
        cols.update({c.column: self._values(c) for c in self.channels})
        if self.heat_J is not None:
            cols["heat_J"] = self.heat_J
        return _frame(cols)

    def to_json(self) -> str:
        """The result as a JSON document: its attributes, each channel with its name,
        quantity, column, unit and values."""
        return json_text({
            "kind": self.kind, "scenario": self.scenario, "model": self.model,
            "solver": self.solver, "ndofs": self.ndofs, "time_s": self.times_s,
            "channels": [{**c._asdict(), "values": self._values(c)} for c in self.channels],
            "heat_J": self.heat_J, "error_estimate_um": self.error_estimate_um})


def _rod_result(times_s, growth_um, *, scenario: str, model: str, solver: str, ndofs: int,
                heat_J=None, error_estimate_um=None) -> FemResult:
    return FemResult(times_s, {"growth": growth_um}, {}, {}, (_ROD_GROWTH,), "rod", scenario,
                     model, solver, ndofs, heat_J, error_estimate_um)


def _mesh_result(run) -> FemResult:
    """The :class:`FemResult` of a solved mesh scenario
    (:class:`~arfem.scenarios.geometry.scenario.GeometryRun`), in the units and columns
    of its ``sensors.csv``."""
    sc = run.model.scenario
    series = run.sensor_series()
    channels = tuple(Channel(s.name, s.quantity, s.column, s.unit) for s in sc.sensors)
    by = {q: {c.name: series[c.column] for c in channels if c.quantity == q}
          for q in ("displacement", "tilt", "temperature")}
    return FemResult(run.result.times_s, by["displacement"], by["tilt"], by["temperature"],
                     channels, "mesh", sc.name, "mesh", sc.solver, run.model.thermal.ndofs)


def solve_fem(rod: Rod, schedule: Schedule, *, dtau_s: float = 30.0,
              model: str = "axisymmetric", order: int = 2, solver: str = "modal",
              dt_s: float | None = None, mesh: dict | None = None) -> FemResult:
    """Run the transient heat FEM of the rod over a duty cycle; growth every Δτ.

    Parameters
    ----------
    rod : Rod
        Geometry [m], material and nominal convection h [W/(m²·K)] and ambient [°C].
    schedule : Schedule
        Piecewise-constant heat flux q [W/m²] (and optionally ambient [°C], h) per
        segment; every segment must be a multiple of ``dtau_s``.
    dtau_s : float
        Output interval Δτ [s].
    model : {"axisymmetric", "3d"}
        Axisymmetric Q1/Q2 quadrilaterals, or 3D bricks (order 2 = the paper's 20-node).
    order : {1, 2}
        Element order.
    solver : {"modal", "crank-nicolson", "backward-euler"}
        ``"modal"``: exact in time (reduced-modal with a stated error on 3D).
    dt_s : float, optional
        θ-method step [s]; must divide ``dtau_s`` (default ``dtau_s``).
    mesh : dict, optional
        Mesh counts (axisymmetric ``nr``, ``nz``; 3D ``n_core``, ``n_ring``, ``nz``).

    Returns
    -------
    FemResult
        ``kind == "rod"``; ``growth_um`` (= ``displacement_um["growth"]``) and
        ``heat_J``.

    Examples
    --------
    >>> r = solve_fem(Rod(), paper_cycle(2000.0))
    >>> r.ndofs, round(float(r.growth_um.max()), 3)
    (441, 22.167)
    """
    from arfem.fem.heat import build_3d, build_axisymmetric, solve_modal, solve_theta
    thetas = {"modal": None, "crank-nicolson": 0.5, "backward-euler": 1.0}
    if solver not in thetas:
        raise InputError(f"must be one of {sorted(thetas)}, got {solver!r}", "solver")
    if model not in ("axisymmetric", "3d"):
        raise InputError(f"must be 'axisymmetric' or '3d', got {model!r}", "model")
    build = build_axisymmetric if model == "axisymmetric" else build_3d
    fem = build(rod, order=order, **(mesh or {}))
    fine = schedule.subdivided(dtau_s)
    about = dict(scenario="", model=model, solver=solver, ndofs=fem.ndofs)
    if thetas[solver] is None:
        res = solve_modal(fem, fine)
        est = getattr(res, "error_estimate_m", None)
        return _rod_result(res.times_s, res.growth_um, heat_J=res.heat_J,
                           error_estimate_um=None if est is None else est * 1e6, **about)
    dt = dtau_s if dt_s is None else float(dt_s)
    k = dtau_s / dt
    if abs(k - round(k)) > 1e-9:
        raise InputError(f"must divide dtau_s = {dtau_s:g} s, got {dt:g}", "dt_s")
    res = solve_theta(fem, fine.subdivided(dt), dt, theta=thetas[solver])
    pick = slice(None, None, int(round(k)))
    return _rod_result(res.times_s[pick], res.growth_um[pick], heat_J=res.heat_J[pick],
                       **about)


def solve(scenario: Scenario | GeometryCheckCase | str | Path, *,
          progress: bool | Callable[[str], None] = False) -> FemResult:
    """Run a scenario's FEM, the rod's or a mesh's, without writing a file.

    The rod: :func:`solve_fem` with the scenario's rod, cycle, Δτ and ``[fem]``
    settings. A mesh: heat and thermo-elasticity of
    :mod:`arfem.scenarios.geometry.scenario`, every sensor every
    ``output_interval_s`` (the numbers ``arfem run`` writes to ``sensors.csv``; the
    fields, which only files hold, are left out: :func:`run` writes them).

    Parameters
    ----------
    scenario : Scenario, GeometryCheckCase, str or path-like
        From :func:`load_scenario`, or a file or a shipped scenario's name (read here).
    progress : bool or callable
        True: show the step under way on stderr (a mesh at P2 takes a minute); a
        callable is called with each step's name instead.

    Returns
    -------
    FemResult
        ``displacement_um``, ``tilt_urad`` and ``temperature_C`` by sensor.

    Raises
    ------
    InputError
        A scenario file that is malformed (see :func:`load_scenario`), a mesh that
        cannot be read or is too large, a sensor outside the mesh.

    Examples
    --------
    >>> r = solve(load_scenario("spindle_unit", order=1))     # P1: seconds
    >>> r.kind, [c.column for c in r.channels][:4]
    ('mesh', ['d_tcp_x_um', 'd_tcp_y_um', 'd_tcp_z_um', 'T_front_bearing_C'])
    >>> round(float(r.displacement_um["tcp_z"].min()), 1), float(r.times_s[-1]) / 3600
    (-28.1, 24.0)
    >>> round(float(solve("paper_fig2").growth_um.max()), 2)
    22.17
    """
    case = _loaded(scenario)
    if case.kind == "rod":
        f = case.fem
        r = solve_fem(case.rod, case.schedule, dtau_s=case.dtau_s, model=f.model,
                      order=f.order, solver=f.solver, dt_s=f.dt_s, mesh=f.mesh)
        return dataclasses.replace(r, scenario=case.name)
    from arfem.scenarios.geometry.scenario import build_geometry_model, solve_geometry
    sc = dataclasses.replace(case.scenario, fields=False)   # fields: files, arfem.run's
    with _progress_hook(progress, 3, "arfem.solve") as hook:
        return _mesh_result(solve_geometry(build_geometry_model(sc, hook), hook))


def run(scenario: str | Path, out: str | Path, *, force: bool = False,
        progress: bool | Callable[[str], None] = False) -> FemResult:
    """Run a scenario file and write every file ``arfem run`` writes into ``out``.

    The rod: ``timeseries.csv``, ``summary.json``, ``figure.png``, ``model.json``, the
    fields where asked, ``report.html``. A mesh: ``sensors.csv``, ``summary.json``,
    ``geometry.png``, ``sensors.png``, ``model.json``, ``record.toml``, the fields
    where asked (``fields/fields.xdmf3``), ``report.html``. The files are written
    atomically; a file in ``out`` that arfem did not write is never replaced.

    Parameters
    ----------
    scenario : str or path-like
        The scenario file, or a shipped scenario's name; a file, not a loaded scenario,
        since the run copies it beside its results (so that they can be run again).
    out : str or path-like
        The output folder (``--out``).
    force : bool
        Allow a non-empty ``out`` that holds something else (``--force``).
    progress : bool or callable
        True: show the step under way on stderr; a callable is called with each
        step's name instead.

    Returns
    -------
    FemResult
        What the files hold: the FEM's channels at the output times (the rod's
        ``growth_um`` as ``timeseries.csv``'s ``fem_growth_um``, without ``heat_J``).

    Raises
    ------
    InputError
        A malformed scenario (see :func:`load_scenario`) or an ``out`` that cannot be
        written; nothing is written then.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "fig2"
    >>> r = run("paper_fig2", out)
    >>> (out / "timeseries.csv").is_file(), round(float(r.growth_um.max()), 2)
    (True, 22.17)
    """
    from arfem.scenarios.geometry.scenario import is_geometry_scenario, run_geometry
    from arfem.scenarios.rod.outputs import run_scenario
    if not isinstance(scenario, (str, Path)):
        raise InputError("give the scenario's file or shipped name: arfem.run copies it "
                         "beside its results (arfem.solve takes a loaded scenario)",
                         "scenario")
    p = _file_or_shipped(scenario)
    with _progress_hook(progress, 8, "arfem.run") as hook:
        if is_geometry_scenario(p):
            return _mesh_result(run_geometry(p, out, force, hook))
        ev = run_scenario(p, out, force, progress=hook)
    sc = ev.scenario
    return _rod_result(ev.times_s, ev.fem_growth_um, scenario=sc.name, model=sc.fem.model,
                       solver=sc.fem.solver, ndofs=ev.model.ndofs)


# -- the AR(1) ------------------------------------------------------------------------------

@dataclass(frozen=True)
class AR1Result:
    r"""The paper's AR(1) growth on a duty cycle, with its two coefficients.

    The growth follows :math:`\Delta L_n = C_1 \Delta L_{n-1} + C_2(q_n)` (paper
    equation 12).

    Attributes
    ----------
    times_s : ndarray
        0, Δτ, 2Δτ, … [s].
    growth_um : ndarray
        ΔL [µm].
    C1 : float
        :math:`e^{-b\Delta\tau}` (paper eq. 13), or the corrected model's value from the
        slowest radial mode.
    C2_um_per_W_m2 : float
        C2 per unit heat flux [µm per W/m²] (paper eq. 14 is linear in q).
    corrected : bool
        True for the radial-mode corrected AR(1).
    """

    times_s: np.ndarray
    growth_um: np.ndarray
    C1: float
    C2_um_per_W_m2: float
    corrected: bool

    def to_dataframe(self) -> pandas.DataFrame:
        """``time_s``, ``growth_um`` as a pandas DataFrame."""
        return _frame({"time_s": self.times_s, "growth_um": self.growth_um})

    def to_json(self) -> str:
        """The result as a JSON document (arrays as lists)."""
        return json_text(self.__dict__)


def ar1(rod: Rod, schedule: Schedule, *, dtau_s: float = 30.0,
        corrected: bool = False) -> AR1Result:
    """Run the paper's closed-form AR(1) thermal-growth model on a duty cycle.

    The model is equations 12–14 of Du et al. (2021); ``corrected=True`` runs arfem's
    radial-mode corrected coefficients instead.

    Parameters
    ----------
    rod : Rod
        Supplies a = λ/(ρc), b = 2h/(ρcR) and α (the thermal expansion coefficient).
    schedule : Schedule
        Heat flux q [W/m²] per segment; every segment a multiple of ``dtau_s``.
    dtau_s : float
        AR step Δτ [s].
    corrected : bool
        Use arfem's radial-mode corrected C1, C2 (derived from the 3D rod's slowest
        axially uniform mode; reduces to eqs. 13–14 as the Biot number → 0).

    Returns
    -------
    AR1Result

    Examples
    --------
    >>> r = ar1(Rod(), paper_cycle(2000.0))
    >>> round(r.C1, 4), round(r.C2_um_per_W_m2 * 2000, 4)
    (0.9909, 0.1985)
    """
    from arfem.models.ar1 import ar1_on_schedule, c1_paper, c2_paper, corrected_coefficients
    t, g = ar1_on_schedule(rod, schedule, dtau_s, corrected=corrected)
    if corrected:
        c1, c2 = corrected_coefficients(rod, dtau_s, 1.0)
    else:
        c1, c2 = c1_paper(rod, dtau_s), c2_paper(rod, dtau_s, 1.0)
    return AR1Result(t, g * 1e6, float(c1), float(c2) * 1e6, corrected)


# -- FEM against AR(1), and the gate ----------------------------------------------------------

@dataclass(frozen=True)
class Comparison:
    """The FEM and both AR(1) models on one scenario, the rod's or a mesh's, per
    displacement channel (what ``arfem run`` compares on the rod, ``arfem check`` on a
    mesh).

    Attributes
    ----------
    kind : str
        ``"rod"`` or ``"mesh"``.
    scenario : str
        The scenario's name.
    times_s : ndarray
        Sample times 0, Δτ, 2Δτ, … [s] (a mesh: its ``[check] dtau_s``, else its
        ``output_interval_s``).
    fem_um : dict of str to ndarray
        The FEM's displacement per channel [µm]: the rod's ``"growth"``, a mesh's
        displacement sensors by name (tilts and temperatures: :func:`solve`).
    ar_um : dict of str to ndarray
        The paper's AR(1) [µm]: eqs. 12–14 on the rod; on a mesh their lumped
        generalisation (b = Σh·A / Σρc·V), superposed over every input.
    ar_corrected_um : dict of str to ndarray
        The corrected AR(1) [µm]: the rod's radial-mode one; on a mesh the
        slowest-mode one (C1 from the reduced model's slowest eigenvalue, the FEM's
        static gain per input).
    metrics : dict
        The rod: every figure of ``summary.json`` (C1, C2, max|AR − FEM| in µm and in %
        of the peak, the fitted C1, …). A mesh: ``dtau_s``, the ``inputs``
        superposed, the C1 range of each AR(1) (``C1``, ``corrected_C1``: [low,
        high]), ``fem_peak_um`` (the largest drift) and per sensor ``fem_peak_um``,
        ``max_abs_diff_um`` and ``max_abs_diff_pct_of_peak`` of each AR (% of the
        largest drift: ``arfem check``'s measure). Units in the keys.
    """

    kind: str
    scenario: str
    times_s: np.ndarray
    fem_um: dict
    ar_um: dict
    ar_corrected_um: dict
    metrics: dict = field(repr=False)

    def to_dataframe(self) -> pandas.DataFrame:
        """``time_s``, then per channel ``fem_<name>_um``, ``ar_<name>_um`` and
        ``ar_corrected_<name>_um`` (the rod's are ``timeseries.csv``'s
        ``fem_growth_um``, ``ar_growth_um``, ``ar_corrected_growth_um``)."""
        cols = {"time_s": self.times_s}
        for name in self.fem_um:
            cols.update({f"fem_{name}_um": self.fem_um[name], f"ar_{name}_um": self.ar_um[name],
                         f"ar_corrected_{name}_um": self.ar_corrected_um[name]})
        return _frame(cols)

    def to_json(self) -> str:
        """The metrics as a JSON document (the series are in :meth:`to_dataframe`)."""
        return json_text({"kind": self.kind, "scenario": self.scenario, **self.metrics})


def _mesh_comparison(case) -> Comparison:
    """:func:`compare` on a mesh: :func:`arfem.scenarios.geometry.check.compare_geometry_ar1`
    at the check's Δτ, its errors as ``arfem check`` measures them."""
    from arfem.scenarios.geometry.check import ar_errors, compare_geometry_ar1
    from arfem.scenarios.geometry.scenario import build_geometry_model
    sc = dataclasses.replace(case.scenario, fields=False)
    cmp = compare_geometry_ar1(build_geometry_model(sc), case.check_dtau_s)
    scale = {s.name: s.record_scale for s in sc.sensors}          # m -> µm
    disp = [(i, cmp.sensors[i]) for i in np.flatnonzero(cmp.displacement)]

    def per_sensor(y):
        return {n: y[:, i] * scale[n] for i, n in disp}
    sensors: dict = {n: {} for _, n in disp}
    peak = 0.0
    for pre, model in (("", "lumped"), ("corrected_", "slowest-mode")):
        rows, peak = ar_errors(cmp, model)
        for n, err, own in rows:
            sensors[n].update({"fem_peak_um": own * scale[n],
                               f"{pre}max_abs_diff_um": err * scale[n],
                               f"{pre}max_abs_diff_pct_of_peak":
                                   100.0 * err / peak if peak > 0 else float("nan")})
    metrics = {"dtau_s": case.check_dtau_s, "inputs": list(cmp.inputs),
               "C1": [float(cmp.lumped.c1.min()), float(cmp.lumped.c1.max())],
               "corrected_C1": [float(cmp.slowest_mode.c1.min()),
                                float(cmp.slowest_mode.c1.max())],
               "fem_peak_um": peak * 1e6, "sensors": sensors}
    return Comparison("mesh", sc.name, cmp.times_s, per_sensor(cmp.fem),
                      per_sensor(cmp.prediction("lumped")),
                      per_sensor(cmp.prediction("slowest-mode")), metrics)


def compare(scenario: Scenario | GeometryCheckCase | str | Path) -> Comparison:
    """Run the FEM and both AR(1) models on a scenario and compare them, the rod's or a
    mesh's, without writing files.

    Parameters
    ----------
    scenario : Scenario, GeometryCheckCase, str or path-like
        From :func:`load_scenario`, or a file or a shipped scenario's name (read here).

    Returns
    -------
    Comparison

    Raises
    ------
    InputError
        As :func:`load_scenario` and :func:`solve`.

    Examples
    --------
    >>> c = compare("paper_fig2")
    >>> round(c.metrics["max_abs_diff_pct_of_peak"], 2), list(c.fem_um)
    (2.57, ['growth'])
    >>> m = compare(load_scenario("spindle_unit", order=1))
    >>> list(m.fem_um), round(m.metrics["sensors"]["tcp_z"]["corrected_max_abs_diff_um"], 1)
    (['tcp_x', 'tcp_y', 'tcp_z'], 3.4)
    """
    case = _loaded(scenario)
    if case.kind == "mesh":
        return _mesh_comparison(case)
    from arfem.scenarios.rod.evaluation import evaluate
    ev = evaluate(case)
    return Comparison("rod", case.name, ev.times_s, {"growth": ev.fem_growth_um},
                      {"growth": ev.ar_growth_um}, {"growth": ev.ar_corrected_growth_um},
                      dict(ev.metrics))


@dataclass(frozen=True)
class CheckResult:
    """``arfem check`` on one scenario, the rod's or a mesh's: each criterion with its
    value and limit.

    Attributes
    ----------
    scenario : str
        The scenario's name.
    passed : bool
        Every criterion holds.
    criteria : tuple of arfem.scenarios.gate.Criterion
        Each criterion (frozen): ``name``, ``value`` against ``limit`` (in ``unit``),
        ``passed``, and the ``message`` ``arfem check`` prints. The rod: max|AR − FEM|
        [% of the FEM peak] and the C1 difference (fitted to the FEM, of the AR) [-]; a
        mesh: max|AR − FEM| per displacement sensor [% of the largest FEM drift].
    kind : str
        ``"rod"`` or ``"mesh"``.
    file : str
        The scenario's file.
    model : str
        The AR(1) held to the limits: the rod's ``"paper"`` or ``"corrected"``; a
        mesh's ``"lumped"`` or ``"slowest-mode"``.
    notes : tuple of str
        Reported, not gated (a mesh: the other AR's errors, the C1 range, tilts).
    biot : float
        hR/λ of the rod (NaN for a mesh).
    """

    scenario: str
    passed: bool
    criteria: tuple[Criterion, ...]
    kind: str = "rod"
    file: str = ""
    model: str = ""
    notes: tuple[str, ...] = ()
    biot: float = float("nan")

    def to_dataframe(self) -> pandas.DataFrame:
        """One row per criterion: ``name``, ``value``, ``limit``, ``unit``, ``passed``,
        ``message``."""
        import pandas as pd
        return pd.DataFrame([dataclasses.asdict(c) for c in self.criteria],
                            columns=["name", "value", "limit", "unit", "passed", "message"])

    def to_json(self) -> str:
        """The scenario's entry of ``arfem check --json``: ``scenario``, ``file``,
        ``model``, ``biot``, ``passed``, ``notes`` and each criterion's fields."""
        from arfem.scenarios.gate import ScenarioResult, json_report
        r = ScenarioResult(self.scenario, self.file, self.model, list(self.criteria),
                           biot=self.biot, notes=self.notes)
        return json_text(json_report([r], [])["scenarios"][0])


def check(scenario: Scenario | GeometryCheckCase | str | Path, *,
          max_abs_pct: float | None = None, max_c1_diff: float | None = None,
          model: str | None = None) -> CheckResult:
    """Does the AR(1) track the FEM on this scenario? (``arfem check``, one scenario.)

    Parameters
    ----------
    scenario : Scenario, GeometryCheckCase, str or path-like
        From :func:`load_scenario`, or a file or a shipped scenario's name (read here).
    max_abs_pct : float, optional
        Limit on max|AR − FEM| [% of the FEM peak; on a mesh, of the largest FEM
        drift]; default the scenario's ``[check]`` value, else 3 % (a mesh: 15 %).
    max_c1_diff : float, optional
        Limit on the absolute difference of C1 fitted to the FEM and the AR's C1 [-];
        default 5e-4. The rod's only (a mesh's result notes that it does not apply).
    model : {"paper", "corrected"}, optional
        Which AR(1) is held to the limits; default the scenario's ``[check]``, else the
        paper's. On a mesh "corrected" (its default) is the slowest-mode AR(1), "paper"
        the lumped one, held per displacement sensor
        (:mod:`arfem.scenarios.geometry.check`).

    Returns
    -------
    CheckResult

    Raises
    ------
    InputError
        A malformed scenario or limit; the message names the file or the parameter.

    Examples
    --------
    >>> r = check("paper_fig2")
    >>> r.passed, [c.name for c in r.criteria]
    (True, ['max_abs_diff_pct_of_peak', 'C1_abs_diff'])
    >>> m = check(load_scenario("spindle_unit", order=1))
    >>> m.kind, m.model, m.passed, [c.name for c in m.criteria][-1]
    ('mesh', 'slowest-mode', True, 'max_abs_diff_pct_of_peak[tcp_z]')
    """
    from arfem.scenarios.rod.checking import check_case
    from arfem.scenarios.rod.scenario import CHECK_MODELS, check_limit
    from arfem.strict import string
    if max_abs_pct is not None:
        max_abs_pct = check_limit("max_abs_diff_pct_of_peak", max_abs_pct, "max_abs_pct")
    if max_c1_diff is not None:
        max_c1_diff = check_limit("max_C1_abs_diff", max_c1_diff, "max_c1_diff")
    if model is not None:
        model = string(model, "model", CHECK_MODELS)
    case = _loaded(scenario)
    r = check_case(case, max_abs_pct, max_c1_diff, model)
    return CheckResult(r.scenario, r.passed, tuple(r.criteria), case.kind, r.file, r.model,
                       tuple(r.notes), r.biot)


# -- sweeps ------------------------------------------------------------------------------------

class SweepFailure(NamedTuple):
    """A point of a sweep that failed: its ``inputs`` (swept key → value) and the
    ``error`` (one line). The same command computes it again."""

    inputs: dict
    error: str


@dataclass(frozen=True)
class SweepResult:
    """What :func:`sweep` did, and the table it wrote (``results.csv``).

    Attributes
    ----------
    name : str
        ``[sweep] name``.
    kind : str
        ``"rod"`` or ``"mesh"``: the base scenario's.
    out : pathlib.Path
        The output folder (``results.csv``, ``summary.json``, figures, ``report.html``,
        the point store).
    n_points, n_stored_before, n_computed, n_failed : int
        The grid's points; those already stored by an earlier run; computed now; failed.
    wall_s : float
        This run's wall time [s].
    executor : str
        Where the points ran.
    failures : tuple of SweepFailure
        The points that failed.
    rows : tuple of dict
        ``results.csv``: one row per stored point, the swept keys and then the metrics,
        units in the names (the rod: C1, C2, FEM peak, max|AR − FEM| …; a mesh: per
        sensor its ``*_peak_*``, ``*_peak_time_h`` and ``*_final_*``).
    """

    name: str
    kind: str
    out: Path
    n_points: int
    n_stored_before: int
    n_computed: int
    n_failed: int
    wall_s: float
    executor: str
    failures: tuple[SweepFailure, ...]
    rows: tuple = field(repr=False)

    def to_dataframe(self) -> pandas.DataFrame:
        """:attr:`rows` as a DataFrame, the columns of ``results.csv``."""
        return _frame(list(self.rows))

    def to_json(self) -> str:
        """The report and the rows as a JSON document."""
        return json_text({**{f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                             if f.name not in ("out", "failures", "rows")},
                          "out": str(self.out),
                          "failures": [f._asdict() for f in self.failures],
                          "rows": list(self.rows)})


def _sweep_rows(sw, out: Path) -> tuple:
    """The rows ``results.csv`` holds, from the sweep's store in ``out``."""
    if getattr(sw, "kind", None) == "geometry":           # a mesh sweep (run_sweep's rule)
        from arfem.scenarios.sweep.geometry_run import GeometryPointStore, geometry_rows
        return tuple(geometry_rows(sw, GeometryPointStore(out, sw.sensors)))
    from arfem.scenarios.sweep import PointStore, results_rows
    return tuple(results_rows(sw, PointStore(out)))


def sweep(sweep_toml: str | Path, out: str | Path, *, workers: int | None = None,
          force: bool = False, progress: bool = False) -> SweepResult:
    """Run a parameter sweep file into ``out`` (``arfem sweep``; resumable), on the rod
    or on a mesh.

    Parameters
    ----------
    sweep_toml : str or path-like
        A sweep file (``[sweep]`` with ``base``, a rod or a mesh scenario, and a
        ``[sweep.grid]`` of scenario keys), or a shipped one's name
        (``"sweep_dtau_h"``, ``"sweep_spindle_unit"``).
    out : str or path-like
        Output folder (``results.csv``, figures, ``report.html``); the ``--out`` rules
        apply: arfem never replaces a file it did not write. A folder holding the same
        sweep is resumed: only the missing points are computed.
    workers : int, optional
        Local processes (default: the cores, 1 = in-process).
    force : bool
        Allow a non-empty ``out`` that holds something else.
    progress : bool
        Show a progress bar.

    Returns
    -------
    SweepResult

    Raises
    ------
    InputError
        A malformed sweep file or base scenario, a key the base lacks, a point that
        would be refused; nothing is computed or written then.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "s.toml").write_text(
    ...     '[sweep]\\nname = "demo"\\nbase = "paper_fig2"\\n'
    ...     '[sweep.grid]\\nh_W_m2K = [35, 55]\\n')
    >>> rep = sweep(d / "s.toml", d / "out", workers=1)
    >>> rep.kind, rep.n_points, rep.n_failed, list(rep.to_dataframe()["h_W_m2K"])
    ('rod', 2, 0, [35, 55])
    """
    from arfem.scenarios.sweep import load_sweep, run_sweep
    sw = load_sweep(_file_or_shipped(sweep_toml))
    rep = run_sweep(sw, out, workers=workers, force=force, progress=progress)
    return SweepResult(sw.name, "mesh" if getattr(sw, "kind", None) == "geometry" else "rod",
                       Path(out), rep.n_points, rep.n_stored_before, rep.n_computed,
                       rep.n_failed, rep.wall_s, rep.executor,
                       tuple(SweepFailure(f["inputs"], f["error"]) for f in rep.failures),
                       _sweep_rows(sw, Path(out)))


# -- diagnosis of measured data ---------------------------------------------------------------

class DiagnosisSeries(NamedTuple):
    """The arrays behind a diagnosis's figures, each of shape (N,).

    Attributes
    ----------
    time_s : ndarray
        Sample times [s].
    growth_um : ndarray
        Measured growth [µm] (NaN where not observed).
    baseline_um, extended_um : ndarray
        The baseline's and the extended model's growth [µm].
    outlier : ndarray
        1.0 on rows left out of the fit and the scores (outliers, unobserved), else 0.0.
    mlr_um : ndarray or None
        Paper eq. 18 on the recorded temperatures [µm] (None without thermometers).
    """

    time_s: np.ndarray
    growth_um: np.ndarray
    baseline_um: np.ndarray
    extended_um: np.ndarray
    outlier: np.ndarray
    mlr_um: np.ndarray | None


@dataclass(frozen=True)
class DiagnosisResult:
    """What ``arfem diagnose`` finds in a record, on the rod or on a mesh: the one typed
    result of both engines (:class:`~arfem.models.diagnosis.result.Diagnosis`) and the
    ``diagnosis.json`` document written from it.

    Attributes
    ----------
    diagnosis : Diagnosis
        The typed result: ``verdict``, ``text``, ``causes`` (every cause the selection
        rules named, established or not, each a ``NamedCause`` with its parameters, 95 %
        intervals and no-effect values), ``holdout`` (a ``Holdout``: start, how chosen,
        gains, the scores per channel), ``alternatives``, ``not_searched``, ``channels``
        (the evidence per channel), ``warnings``, ``series``.
    summary : dict
        The ``diagnosis.json`` document of ``docs/measured-data.md`` (contract v2 for the
        rod, v3 for a mesh record; the mesh's reduced-model statement and compensators
        are the command's, not computed here).
    """

    diagnosis: Diagnosis = field(repr=False)
    summary: dict = field(repr=False)

    @property
    def cause(self) -> str:
        """The (first) established cause, ``"none"`` where none is."""
        return self.diagnosis.cause

    @property
    def verdict(self) -> str:
        """``established``, ``unconfirmed``, ``explained`` or ``not_explained``."""
        return self.diagnosis.verdict

    @property
    def text(self) -> str:
        """The verdict in words."""
        return self.diagnosis.text

    @property
    def causes(self) -> tuple[NamedCause, ...]:
        """The established causes, with their parameters and 95 % intervals (empty if
        none; a best candidate that is not established is in ``diagnosis.causes``)."""
        return self.diagnosis.established

    @property
    def established(self) -> tuple[NamedCause, ...]:
        """The same as :attr:`causes`."""
        return self.diagnosis.established

    @property
    def holdout(self) -> Holdout:
        """The hold-out: its start and how it was chosen, the gain, per channel the
        baseline's, the extended model's and the MLR's error."""
        return self.diagnosis.holdout

    @property
    def warnings(self) -> tuple[str, ...]:
        """What a reader of the result must not miss."""
        return self.diagnosis.warnings

    @property
    def series(self) -> dict:
        """The arrays behind the figures (rod: ``time_s``, ``growth_um``, ``baseline_um``,
        ``extended_um``, ``outlier``, the recorded signals; mesh: ``time_s`` and the
        (N, C) ``measured``, ``baseline``, ``extended``)."""
        return dict(self.diagnosis.series)

    @property
    def arrays(self) -> DiagnosisSeries | None:
        """A rod record's growths typed (None for a mesh record: see :meth:`to_dataframe`)."""
        s = self.diagnosis.series
        if self.diagnosis.plant == "mesh":
            return None
        return DiagnosisSeries(*(np.asarray(s[k]) for k in (
            "time_s", "growth_um", "baseline_um", "extended_um", "outlier")),
            None if s.get("mlr_um") is None else np.asarray(s["mlr_um"]))

    def to_dataframe(self) -> pandas.DataFrame:
        """The series as a pandas DataFrame (a mesh record: ``<column>``,
        ``<column>_nominal`` and ``<column>_extended`` per channel)."""
        s = self.diagnosis.series
        if self.diagnosis.plant == "mesh":
            cols = {"time_s": np.asarray(s["time_s"])}
            for j, c in enumerate(self.diagnosis.holdout.channels):
                cols[c.column] = s["measured"][:, j]
                cols[f"{c.column}_nominal"] = s["baseline"][:, j]
                cols[f"{c.column}_extended"] = s["extended"][:, j]
            return _frame(cols)
        n = len(s.get("time_s", ()))
        return _frame({k: np.asarray(v) for k, v in s.items()
                       if np.ndim(v) == 1 and len(v) == n})

    def to_json(self) -> str:
        """``diagnosis.json`` as a string."""
        return json_text(self.summary)


#: The unit of each contract column (``T_<name>_C`` columns are °C).
_UNITS = {"time_s": "s", "growth_um": "µm", "q_W_m2": "W/m²", "speed_rpm": "1/min",
          "ambient_C": "°C"}


@dataclass(frozen=True)
class Record:
    """A measured record read by :func:`read_record`: its samples and what its TOML says.

    Attributes
    ----------
    data : pandas.DataFrame
        One row per kept sample, columns under the contract's names: ``time_s`` [s],
        ``growth_um`` [µm], ``q_W_m2`` [W/m²] and/or ``speed_rpm`` [1/min], and where
        recorded ``ambient_C`` [°C] and ``T_<name>_C`` [°C] (NaN where a cell was empty).
    name : str
        ``[dataset] name``.
    initial : str
        ``"equilibrium"`` or ``"unknown"`` (``[dataset] initial``): did the record start
        at equilibrium with the ambient? :func:`diagnose` uses it.
    units : dict of str to str
        The unit of each column of ``data``.
    rod : Rod
        The rod the simulation assumes (``[rod]``, the seed paper's where not given).
    source : pathlib.Path
        The TOML file.
    csv_path : pathlib.Path
        The CSV file it names.
    columns : dict of str to str
        Contract name to the CSV's own column name (``[columns]``; the identity where the
        CSV already uses the contract's name).
    sensors : dict of str to str
        ``[sensors.<column>] description``.
    notes : tuple of str
        What the reader did (rows dropped, gaps filled, outliers flagged) and noticed.
    """

    data: pandas.DataFrame = field(repr=False)
    name: str
    initial: str
    units: dict
    rod: Rod = field(repr=False)
    source: Path
    csv_path: Path
    columns: dict = field(repr=False)
    sensors: dict = field(repr=False)
    notes: tuple = field(repr=False)
    _dataset: Dataset = field(repr=False, compare=False)

    def to_dataframe(self) -> pandas.DataFrame:
        """The samples (:attr:`data`, a copy) as a pandas DataFrame."""
        return self.data.copy()


def _record_frame(ds):
    """A loaded :class:`~arfem.models.diagnosis.dataset.Dataset` as a DataFrame."""
    cols = {"time_s": ds.time_s, "growth_um": ds.growth_um}
    for key in ("q_W_m2", "speed_rpm", "ambient_C"):
        if getattr(ds, key) is not None:
            cols[key] = getattr(ds, key)
    cols.update(ds.temperatures)
    return _frame({k: np.array(v, dtype=float) for k, v in cols.items()})


def read_record(path: str | Path) -> Record:
    """Read a measured record (a contract TOML and the CSV it names) into a DataFrame.

    The CSV's own column names are mapped onto the contract's by the TOML's
    ``[columns]`` table, and every check of ``docs/measured-data.md`` is applied (the
    same reading as ``arfem diagnose``).

    Parameters
    ----------
    path : str or path-like
        The record's TOML file (``[dataset]``, ``[rod]``, ``[columns]``, ``[sensors.*]``).

    Returns
    -------
    Record
        ``data`` (the samples under the contract's names) and the metadata: ``initial``,
        ``units``, ``rod``, ``source``, ``csv_path``, ``columns``, ``sensors``, ``notes``.

    Raises
    ------
    InputError
        A malformed TOML or CSV; the message names the file, the key or line, and what
        is wrong.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "r.csv").write_text("t,g,q\\n0,0,0\\n30,0.2,2000\\n60,0.4,2000\\n")
    >>> _ = (d / "r.toml").write_text('[dataset]\\ninitial = "unknown"\\n'
    ...                               '[columns]\\ntime_s = "t"\\ngrowth_um = "g"\\nq_W_m2 = "q"\\n')
    >>> rec = read_record(d / "r.toml")
    >>> rec.initial, list(rec.data.columns), rec.units["q_W_m2"]
    ('unknown', ['time_s', 'growth_um', 'q_W_m2'], 'W/m²')
    """
    from arfem.scenarios.records.dataset import load_dataset, read_record_doc
    from arfem.scenarios.records.georecord import refuse_mesh_channels, refuse_mesh_record
    doc = read_record_doc(path)          # the TOML, read once
    refuse_mesh_record(doc)              # contract v3: the mesh's diagnosis, not this
    ds = load_dataset(doc)
    refuse_mesh_channels(ds)
    frame = _record_frame(ds)
    mapping = doc.mapping
    columns = {c: mapping.get(c, c) for c in frame.columns}
    units = {c: _UNITS.get(c, "°C") for c in frame.columns}
    return Record(frame, ds.name, "equilibrium" if ds.initial_known else "unknown", units,
                  ds.rod, Path(path), ds.csv_path, columns, dict(ds.sensors),
                  tuple(ds.notes), ds)


def _initial_of(given: str | None, recorded: str, where: str) -> str:
    """The record's ``initial``; an explicit value must not contradict it."""
    if given is not None and given != recorded:
        raise InputError(f"initial={given!r} contradicts the record's initial = "
                         f"{recorded!r}; change [dataset] initial in the TOML instead",
                         where)
    return recorded


def diagnose(data: Record | str | Path | pandas.DataFrame | Mapping[str, ArrayLike], *,
             rod: Rod | None = None, holdout_start_s: float | None = None,
             initial: str | None = None, name: str = "dataframe",
             frame_search: str = "narrow", speed_engine: str = "branch",
             progress: bool | Callable[[str], None] = False) -> DiagnosisResult:
    """What does the simulation get wrong on a measured record, and why?

    Parameters
    ----------
    data : Record, path-like, pandas.DataFrame or dict of columns
        A :class:`Record` from :func:`read_record`; the path of a contract TOML file (as
        ``arfem diagnose`` takes: a rod record, or a contract-v3 record whose ``[model]``
        names a mesh scenario, diagnosed on that mesh as :func:`diagnose_mesh` does); or
        the samples, with the columns of
        ``docs/measured-data.md``: ``time_s`` [s], ``growth_um`` [µm], and ``q_W_m2``
        [W/m²] or ``speed_rpm`` [1/min]; optional ``ambient_C`` [°C] and ``T_<name>_C``
        [°C] (NaN = an empty cell). Samples are validated in memory, no file is written.
    rod : Rod, optional
        The rod the simulation assumes (default: the seed paper's); only with samples
        (a TOML's rod is its ``[rod]`` table; a mesh record's model is its scenario).
    holdout_start_s : float, optional
        Start of the hold-out [s] (default: the rule of
        :func:`arfem.models.diagnosis.holdout.default_holdout`, for every plant).
    initial : {"equilibrium", "unknown"}, optional
        Did the record start at equilibrium with the ambient? A TOML or a
        :class:`Record` states it (``[dataset] initial``), and a value given here must
        agree with it. For samples the default is ``"equilibrium"``, and the result's
        warnings say it was assumed.
    name : str
        The record's name in the result (samples only).
    frame_search : {"narrow", "wide", "average"}
        Speed-only records: frame structures compared (see ``arfem diagnose --help``).
    speed_engine : {"branch", "pipeline"}
        ``speed_rpm`` records (``arfem diagnose --speed-engine``): the rod engine's speed
        branch (the default, published) or the one pipeline on the speed plant (a
        prototype; ``frame_search`` must then stay ``"narrow"``, else ValueError). Which
        one ran: ``summary["selection"]["speed_engine"]``.
    progress : bool or callable
        True: show the step under way and the elapsed time on stderr (a real record
        takes seconds to a minute); a callable is called with each step's name instead.

    Returns
    -------
    DiagnosisResult
        The one result type of the rod's and the mesh's diagnosis: ``verdict``,
        ``causes`` (each a ``NamedCause``: ``cause``, ``parameters``, ``ci95``,
        ``no_effect``), ``holdout`` (a ``Holdout``: ``start_s``, ``how_chosen``,
        ``gain_pct``, ``channels``), ``warnings``, ``summary`` (diagnosis.json).

    Raises
    ------
    InputError
        A missing column, a unit that cannot be right, NaNs in time or input; for
        samples the message names ``<DataFrame>``, the row (from 0) and the column;
        ``rod`` or ``initial`` given with a mesh record.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> cycle = Schedule([4 * 3600.0] * 6, [2000.0, 0.0] * 3)      # 24 h, on/off
    >>> truth = solve_fem(Rod(convection_W_m2K=80.0), cycle, dtau_s=300.0)
    >>> noise = np.random.default_rng(1).normal(0.0, 0.02, truth.times_s.size)
    >>> df = pd.DataFrame({"time_s": truth.times_s,
    ...                    "q_W_m2": np.r_[0.0, cycle.subdivided(300.0).q_W_m2],
    ...                    "growth_um": truth.growth_um + noise})
    >>> d = diagnose(df, initial="equilibrium")   # the simulation assumes h = 55 W/(m²K)
    >>> d.cause, round(d.summary["causes"][0]["parameters"]["h_W_m2K"])
    ('convection_mismatch', 80)
    """
    if not callable(progress):
        from arfem.scenarios.progress import Progress
        # asked for: shown even where stderr is no terminal (a notebook's)
        with Progress(12, "arfem.diagnose", enabled=bool(progress), tty=True) as bar:
            return diagnose(data, rod=rod, holdout_start_s=holdout_start_s, initial=initial,
                            name=name, frame_search=frame_search,
                            speed_engine=speed_engine, progress=bar)
    return _route(data, rod, holdout_start_s, initial, name, frame_search, speed_engine,
                  progress)


def _route(data, rod, holdout_start_s, initial, name, frame_search, speed_engine,
           progress) -> DiagnosisResult:
    """:func:`diagnose` with ``progress`` a callable: a path's TOML read once, and a mesh
    record diagnosed on its mesh, every other record on the rod."""
    progress("reading the dataset")
    if isinstance(data, (str, Path)):
        data = _record_doc(data, rod=rod, initial=initial)     # the TOML, read once
        if data.is_mesh:
            return _diagnose_mesh(data, holdout_start_s, progress)
    return _diagnose_rod(data, rod, holdout_start_s, initial, name, frame_search, progress,
                         speed_engine)


def _record_doc(path, **rod_only):
    """A record's TOML, read once; ``rod_only`` (the rod's own options) refused, each
    by its key, where the record names a mesh scenario."""
    from arfem.scenarios.records.dataset import read_record_doc
    doc = read_record_doc(path)
    if doc.is_mesh:
        for key, v in rod_only.items():
            if v is not None:
                raise InputError(f"applies to the rod's records; {path} names a mesh "
                                 "scenario ([model]), whose model is that scenario", key)
    return doc


def _diagnose_rod(data, rod, holdout_start_s, initial, name, frame_search,
                  progress, speed_engine="branch") -> DiagnosisResult:
    """:func:`diagnose` of a rod record (``data`` a :class:`Record`, the TOML as read, or
    samples) on ``speed_engine`` where it is a speed record; the warnings of what was
    assumed join the result's."""
    import dataclasses

    from arfem.models.diagnosis.engine import diagnose as _diagnose
    from arfem.models.diagnosis.result import frozen_mapping
    from arfem.scenarios.diagnosis.document import document
    ds, assumed = _dataset_of(data, rod, initial, name)
    d = _diagnose(ds, holdout_start_s, frame_search, progress, speed_engine=speed_engine)
    summary = document(d)
    if assumed:
        summary["warnings"] = [*summary.get("warnings", []), *assumed]
        d = dataclasses.replace(d, warnings=tuple(summary["warnings"]), evidence=(
            dataclasses.replace(d.evidence, document=frozen_mapping(summary))))
    return DiagnosisResult(d, summary)


def _diagnose_mesh(record, holdout_start_s, progress) -> DiagnosisResult:
    """:func:`diagnose` of a contract-v3 record (its path, or its TOML as read) on the
    mesh scenario it names."""
    from arfem.models.geodiagnosis.engine import diagnose_geometry
    from arfem.scenarios.diagnosis.document import document
    from arfem.scenarios.diagnosis.mesh import load_mesh_record
    from arfem.scenarios.records.georecord import read_mesh_record
    mr = read_mesh_record(record.path, None, record) if hasattr(record, "is_mesh") else record
    rec, model, _plant, _sc, _tm = load_mesh_record(mr, progress)
    if holdout_start_s is not None and not rec.time_s[0] < holdout_start_s < rec.time_s[-1]:
        raise InputError(f"{holdout_start_s:g} s is outside the record "
                         f"({rec.time_s[0]:g}-{rec.time_s[-1]:g} s)", "holdout_start_s")
    d = diagnose_geometry(model, rec, holdout_start_s, progress)
    return DiagnosisResult(d, document(d))


def diagnose_mesh(record: str | Path, *, holdout_start_s: float | None = None,
                  progress: bool | Callable[[str], None] = False) -> DiagnosisResult:
    """Which part of a mesh model is wrong, from a contract-v3 record: the same as
    :func:`diagnose` of that record's path.

    The record's TOML names the mesh scenario it is checked against (``[model] scenario
    = "spindle_unit.toml"``, ``docs/measured-data.md``, version 3); its displacement
    channels ``d_<sensor>_um`` and thermometers ``T_<sensor>_C`` are fitted together on a
    parametric reduced model of that scenario, and up to two causes on the scenario's
    own groups are named when established on the hold-out (``arfem diagnose`` on such a
    record, without its files; see ``docs/geometry.md``).

    Parameters
    ----------
    record : str or path-like
        The record's TOML file (``[model]``, ``[dataset]``, ``[columns]``) or its CSV.
    holdout_start_s : float, optional
        Start of the hold-out [s] (default: the rod's rule,
        :func:`arfem.models.diagnosis.holdout.default_holdout`).
    progress : bool or callable
        True: show the step under way on stderr; a callable is called with each step's
        name instead.

    Returns
    -------
    DiagnosisResult
        ``verdict``, ``established`` (the causes, each with its parameters and 95 %
        interval), ``holdout`` (the scores per channel [µm, K]), ``text`` (the verdict
        in words).

    Raises
    ------
    InputError
        The record or its scenario is malformed, names a sensor or group the scenario
        lacks, is not a mesh record, or its hold-out start lies outside it; the message
        names the file and key.

    Examples
    --------
    Not run as a doctest (the shipped unit's run and diagnosis take about a minute of
    CPU); ``tests/test_mesh_run_folder.py`` runs the same on a coarse unit.

    >>> import subprocess
    >>> _ = subprocess.run(["arfem", "run", "scenarios/data/spindle_unit.toml",
    ...                     "--out", "run"])                     # doctest: +SKIP
    >>> d = diagnose_mesh("run/record.toml")                     # doctest: +SKIP
    >>> d.established                  # the FEM's own record  # doctest: +SKIP
    ()
    """
    if not callable(progress):
        from arfem.scenarios.progress import Progress
        with Progress(8, "arfem.diagnose_mesh", enabled=bool(progress), tty=True) as bar:
            return diagnose_mesh(record, holdout_start_s=holdout_start_s, progress=bar)
    from arfem.scenarios.records.georecord import read_mesh_record
    return _diagnose_mesh(read_mesh_record(record), holdout_start_s, progress)


def _dataset_of(data, rod: Rod | None, initial: str | None, name: str) -> tuple:
    """The loaded dataset of :func:`diagnose`'s ``data`` and the warnings of what was
    assumed: a :class:`Record` or a TOML as read keeps its own ``initial`` (a contradicting
    ``initial`` is refused); samples are read in memory, ``"equilibrium"`` assumed and
    said where ``initial`` is not given."""
    from arfem.scenarios.records.dataset import RecordDoc, dataset_from_columns, load_dataset
    if isinstance(data, (RecordDoc, Record)):
        if rod is not None:
            raise InputError("give the rod in the dataset TOML's [rod] table, not here", "rod")
        if isinstance(data, Record):
            ds = data._dataset
        else:                                          # the TOML as read (a RecordDoc)
            from arfem.scenarios.records.georecord import refuse_mesh_channels
            ds = load_dataset(data)
            refuse_mesh_channels(ds)
        recorded = "equilibrium" if ds.initial_known else "unknown"
        _initial_of(initial, recorded, str(ds.source))
        return ds, []
    assumed = []
    if initial is None:
        initial = "equilibrium"
        assumed.append('initial = "equilibrium" was assumed (the record starts at '
                       'equilibrium with the ambient); pass initial="unknown" if it did not')
    return dataset_from_columns(data, name=name, rod=rod, initial=initial), assumed


def read_model(path: str | Path) -> StateSpaceModel:
    """Read and validate a compensator's model file (``model.json`` and its kin).

    ``arfem run`` writes ``model.json`` (the paper's AR(1) of the scenario);
    ``arfem diagnose`` writes ``model.json`` (the baseline), ``model_extended.json`` (the
    baseline extended by the named cause) and ``model_mlr.json`` (the thermometer
    regression) where they apply. ``arfem compensate`` replays any of them.

    Parameters
    ----------
    path : str or path-like
        The file (layout: the documentation's "model.json" page).

    Returns
    -------
    StateSpaceModel

    Raises
    ------
    InputError
        Not JSON, another ``model_version``, a wrong shape, a model that would not settle.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from arfem.scenarios.compensation.model_file import write_model
    >>> p = pathlib.Path(tempfile.mkdtemp()) / "model.json"
    >>> write_model(p, ar1_model(0.99, 1e-4, dtau_s=30.0))
    >>> read_model(p).dtau_s, read_model(p).inputs[0].name
    (30.0, 'q_W_m2')
    """
    from arfem.scenarios.compensation.model_file import read_model as _read
    return _read(path)
