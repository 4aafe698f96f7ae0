"""A measured record on a mesh scenario (contract v3) and the model it is checked
against, as arrays: channels mapped onto the scenario's sensors, inputs per row, and
the responses of the parametric reduced model (:mod:`.rom`) to each load column.

Each row's inputs hold over the interval that ends at the row (zero-order hold, as in
contract v2); at t = 0 the structure is at the reference temperature unless a warm
start is the cause.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from arfem.models.geodiagnosis.rom import ReducedBody, Trial, simulate

__all__ = ["Channel", "GeoRecord", "GeoModel", "Setting", "responses", "ambient_lagged", "make_record",
           "SPEED_KEY_LEVELS"]

#: Distinct speeds at most given their own operator per trial; a record with more
#: distinct speeds is rounded onto this many levels for h(n) (documented approximation).
SPEED_KEY_LEVELS = 40


@dataclass(frozen=True)
class Channel:
    """One measured column mapped onto a scenario sensor.

    Attributes
    ----------
    column : str, e.g. ``d_tcp_z_um`` or ``T_housing_C``
    sensor : str, the scenario's sensor name
    kind : str, ``"displacement"``, ``"temperature"`` or ``"tilt"``
    output : int, the sensor's column in the model's outputs
    scale : float, model unit → record unit (1e6 m → µm, rad → µrad; 1 K → K)
    unit : str, ``"um"``, ``"urad"`` or ``"K"``
    """

    column: str
    sensor: str
    kind: str
    output: int
    scale: float
    unit: str


@dataclass(frozen=True)
class GeoRecord:
    """A record's samples (rows in time order).

    Attributes
    ----------
    name : str
    time_s : ndarray (N,)
    data : ndarray (N, C), each channel's reading (µm; °C for thermometers), NaN missing
    channels : tuple of Channel
    power_W : ndarray (N, S), each source's input (its power [W] or flux [W/m²])
    speed_rpm : ndarray (N,), zeros where the record has none
    ambient_C : ndarray (N,) or None
    displacement_zero : str
        ``"reference"``: the displacement (and tilt) channels read from the stress-free
        reference state; ``"first_row"``: the probes were zeroed at the first row (ISO
        230-3): those channels are held as deviations from their mean over the record,
        and every prediction is compared the same way (:func:`_zeroed`).
    """

    name: str
    time_s: np.ndarray
    data: np.ndarray
    channels: tuple
    power_W: np.ndarray
    speed_rpm: np.ndarray
    ambient_C: np.ndarray | None
    displacement_zero: str = "reference"


@dataclass(frozen=True)
class GeoModel:
    """The scenario's model, reduced (what a trial varies, by name).

    Attributes
    ----------
    rb : ReducedBody
        Load columns: the sources, then the convection groups, then the candidates.
    sources : tuple of str, heat-source names
    convections : tuple of str, convection-group names (their surface groups in
        ``convection_groups``)
    convection_groups : tuple of str
    h_law : ndarray (G, 3), (a, b, m): h = a + b·n^m [W/(m²K)], n in rpm
    convection_ambient_C : ndarray (G,), a group's own fixed ambient, NaN: the record's
    reference_C : float, start and stress-free temperature [°C]
    candidates : tuple of str, candidate surface groups for a missing source
    interfaces : tuple of str, volume groups whose conductivity may be scaled
    regrow : callable or None
        ``regrow(h_scale, kappa) -> ReducedBody``: the same reduced model with its basis
        grown at another setting (one new factorisation), used once to refit a named
        nonlinear cause where the basis was grown (its bias there is then gone).
    unsearched : tuple of str
        Causes left out of the search because the scenario's ``[diagnosis]`` table
        narrowed it (``missing_source:<group>``, ``contact_conductance:<group>``); the
        verdict says so.
    """

    rb: ReducedBody
    sources: tuple
    convections: tuple
    convection_groups: tuple
    h_law: np.ndarray
    convection_ambient_C: np.ndarray
    reference_C: float
    candidates: tuple
    interfaces: tuple
    regrow: object = None
    unsearched: tuple = ()


@dataclass(frozen=True)
class Setting:
    """The nonlinear parameters of one trial (1 everywhere and no lag: nominal).

    Attributes
    ----------
    h_scale : ndarray (G,), factor on each convection group's h [-]
    kappa : ndarray (V,), factor on each interface group's conductivity [-]
    lag_s : float, first-order lag of the ambient reaching the structure [s] (0: none)
    """

    h_scale: np.ndarray
    kappa: np.ndarray
    lag_s: float = 0.0


def ambient_lagged(time_s: np.ndarray, ambient_C: np.ndarray, lag_s: float) -> np.ndarray:
    """The ambient through a first-order lag of time constant ``lag_s`` [s], exact for a
    piecewise-constant (zero-order hold) ambient, starting at its first value.

    >>> a = ambient_lagged(np.array([0., 3600., 7200.]), np.array([20., 21., 21.]), 3600.)
    >>> [round(float(v), 3) for v in a]
    [20.0, 20.632, 20.865]
    """
    if lag_s <= 0:
        return ambient_C.copy()
    out = np.empty_like(ambient_C)
    out[0] = ambient_C[0]
    e = np.exp(-np.diff(time_s) / lag_s)
    for i in range(1, ambient_C.size):
        out[i] = ambient_C[i] + e[i - 1] * (out[i - 1] - ambient_C[i])
    return out


def _segments(rec: GeoRecord):
    """Segment lengths and the record row each segment ends at; a first row after t = 0
    gets a segment from 0 with its own inputs."""
    t = rec.time_s
    if t[0] > 0:
        return np.diff(np.concatenate([[0.0], t])), np.arange(t.size), 1
    return np.diff(t), np.arange(1, t.size), 0


def _speed_keys(speed: np.ndarray) -> np.ndarray:
    u = np.unique(speed)
    if u.size <= SPEED_KEY_LEVELS:
        return speed
    levels = np.linspace(speed.min(), speed.max(), SPEED_KEY_LEVELS)
    return levels[np.argmin(np.abs(speed[:, None] - levels[None, :]), axis=1)]


def trial_for(model: GeoModel, rec: GeoRecord, s: Setting, shape: np.ndarray) -> Trial:
    """The :class:`Trial` of setting ``s`` on ``rec``; ``shape`` (N,) is the missing
    source's schedule (1 at the record's largest input)."""
    d, rows, _ = _segments(rec)
    n = _speed_keys(np.maximum(rec.speed_rpm, 0.0))[rows]
    a, b, m = model.h_law.T
    h = (a[None, :] + b[None, :] * np.power(n[:, None], m[None, :])) * s.h_scale[None, :]
    if rec.ambient_C is not None:
        amb = ambient_lagged(rec.time_s, rec.ambient_C, s.lag_s)[rows]
    else:
        amb = np.full(rows.size, model.reference_C)
    own = model.convection_ambient_C
    th_amb = np.where(np.isnan(own)[None, :], amb[:, None], own[None, :]) - model.reference_C
    nc = len(model.candidates)
    U = np.column_stack([rec.power_W[rows], h * th_amb,
                         np.repeat(shape[rows][:, None], nc, axis=1)])
    return Trial(d, h, s.kappa, U)


def responses(model: GeoModel, rec: GeoRecord, s: Setting, shape: np.ndarray,
              warm: bool = False):
    """Each load column's response on the record's rows, in record units, and (if
    ``warm``) the free response of a uniform 1 K start.

    Returns
    -------
    R : ndarray (N, C, q), per channel (µm or K) and load column
    Rw : ndarray (N, C) or None
    """
    tr = trial_for(model, rec, s, shape)
    off = _segments(rec)[2]
    out = simulate(model.rb, tr)[off:]
    idx = [c.output for c in rec.channels]
    sc = np.array([c.scale for c in rec.channels])
    R = out[:, idx, :] * sc[None, :, None]
    Rw = None
    if warm:
        w = simulate(model.rb, tr, z0=model.rb.ones)[off:]
        Rw = w[:, idx] * sc[None, :]
    if rec.displacement_zero == "first_row":        # like with like: zeroed probes
        for j in _zeroed(rec):
            ok = np.isfinite(rec.data[:, j])
            R[:, j, :] -= R[ok, j, :].mean(axis=0)
            if Rw is not None:
                Rw[:, j] -= Rw[ok, j].mean()
    return R, Rw


def _zeroed(rec: GeoRecord) -> list:
    """The channels a ``first_row`` record zeroed at its start (displacements, tilts).

    Zeroed probes read y_t = m_t − m_0 + e_t − e_0: the zeroing reading's own noise e_0
    sits on every row. Data and model are therefore both compared as deviations from
    their mean over the record's readings (:func:`make_record` centres the data,
    :func:`responses` the model): the same as zeroing the model at its first row, with
    e_0 gone (a free constant per channel, projected out), one datum per channel spent.
    """
    return [j for j, c in enumerate(rec.channels) if c.kind != "temperature"]


def make_record(name: str, time_s, readings, columns, sensor_names, sensor_kinds,
                power_W, speed_rpm=None, ambient_C=None, reference_C: float = 20.0,
                displacement_zero: str = "reference") -> GeoRecord:
    """A :class:`GeoRecord` from readings in record units (µm; °C), columns named
    ``d_<sensor>_um`` / ``T_<sensor>_C``; thermometers are kept as θ = T − reference [K],
    the model's own variable.

    Parameters
    ----------
    readings : ndarray (N, C)
    columns : sequence of str, one per column of ``readings``
    sensor_names, sensor_kinds : the scenario's sensors in output order
    power_W : ndarray (N, S)
    displacement_zero : ``"reference"`` | ``"first_row"`` (:class:`GeoRecord`)
    """
    chans = []
    data = np.array(readings, float, copy=True)
    for j, col in enumerate(columns):
        if col.startswith("d_") and col.endswith("_um"):
            s, kind, scale, unit = col[2:-3], "displacement", 1e6, "um"
        elif col.startswith("tilt_") and col.endswith("_urad"):     # evidence, in µrad
            s, kind, scale, unit = col[5:-5], "tilt", 1e6, "urad"
        else:
            s, kind, scale, unit = col[2:-2], "temperature", 1.0, "K"
            data[:, j] -= reference_C
        k = list(sensor_names).index(s)
        if sensor_kinds[k] != kind:
            raise ValueError(f"{col}: sensor {s!r} is a {sensor_kinds[k]} sensor")
        chans.append(Channel(col, s, kind, k, scale, unit))
    t = np.asarray(time_s, float)
    speed = np.zeros_like(t) if speed_rpm is None else np.asarray(speed_rpm, float)
    rec = GeoRecord(name, t, data, tuple(chans), np.asarray(power_W, float).reshape(t.size, -1),
                    speed, None if ambient_C is None else np.asarray(ambient_C, float),
                    displacement_zero)
    if displacement_zero == "first_row":
        for j in _zeroed(rec):
            data[:, j] -= np.nanmean(data[:, j])
    return rec
