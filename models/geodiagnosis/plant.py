"""The user's mesh as a :class:`~arfem.models.plant.Plant`: the parametric reduced model
of a scenario (:class:`.problem.GeoModel`, :mod:`.rom`) bound to a measured record
(:class:`.problem.GeoRecord`).

Its causes are every kind of the one vocabulary (:func:`arfem.models.plant.cause`):
each convection group's h, each recorded source's scale, a missing source on each
candidate surface group, each interface group's conductivity, the ambient's lag, each
channel's drift and a warm start.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from arfem.models.geodiagnosis.problem import GeoModel, GeoRecord, Setting, responses
from arfem.models.plant import BOUNDS, PLAUSIBLE, Design, SelectionRules
from arfem.models.plant import cause as Cause  # noqa: N812 (the mesh's name since issue 33)

__all__ = ["MeshPlant", "Cause", "BOUNDS", "PLAUSIBLE", "mesh_plant"]


def _load_shape(rec: GeoRecord) -> np.ndarray:
    """The missing source's schedule: n / n_max where the record has a speed, else the
    sum of the recorded source inputs, 1 at its largest."""
    if np.any(rec.speed_rpm > 0):
        return rec.speed_rpm / float(np.max(rec.speed_rpm))
    tot = rec.power_W.sum(axis=1)
    return tot / float(np.max(tot)) if np.max(tot) > 0 else np.zeros_like(tot)


@dataclass(frozen=True)
class MeshPlant:
    """A mesh scenario's reduced model bound to a record (:class:`~arfem.models.plant.Plant`).

    Attributes
    ----------
    model : GeoModel
    rec : GeoRecord
    load_shape : ndarray (N,), the missing source's schedule [-]
    cache : dict, responses per setting (at most 400 kept)
    """

    model: GeoModel
    rec: GeoRecord
    load_shape: np.ndarray
    cache: dict = field(default_factory=dict, repr=False)
    kind: str = "mesh"

    name = property(lambda self: self.rec.name)
    time_s = property(lambda self: self.rec.time_s)
    data = property(lambda self: self.rec.data)
    channels = property(lambda self: self.rec.channels)
    ambient_C = property(lambda self: self.rec.ambient_C)
    not_searched = property(lambda self: tuple(self.model.unsearched))
    regrows = property(lambda self: self.model.regrow is not None)
    nominal_parameters = ()
    rules = SelectionRules()

    def candidate_causes(self) -> tuple:
        """Every single cause the record and the model can tell (module table)."""
        m, rec = self.model, self.rec
        out = [Cause("convection_scale", g) for g in m.convections]
        out += [Cause("source_scale", s) for j, s in enumerate(m.sources)
                if np.any(rec.power_W[:, j] != 0)]
        if np.any(self.load_shape > 0):
            out += [Cause("missing_source", g) for g in m.candidates]
        out += [Cause("contact_conductance", g) for g in m.interfaces]
        if rec.ambient_C is not None and np.ptp(rec.ambient_C) > 0:
            out.append(Cause("ambient_lag"))
        out += [Cause("sensor_drift", c.column, c.unit) for c in rec.channels]
        out.append(Cause("warm_start"))
        return tuple(out)

    def setting(self, causes, values: dict) -> Setting:
        """The reduced model's :class:`.problem.Setting` for ``causes`` at ``values``."""
        m = self.model
        hs = np.ones(len(m.convections))
        kap = np.ones(len(m.interfaces))
        lag = 0.0
        for c in causes:
            v = values.get(c.name)
            if c.kind == "convection_scale":
                hs[m.convections.index(c.target)] = v
            elif c.kind == "contact_conductance":
                kap[m.interfaces.index(c.target)] = v
            elif c.kind == "ambient_lag":
                lag = v * 3600.0
        return Setting(hs, kap, lag)

    def _responses(self, s: Setting, warm: bool):
        key = (tuple(np.round(s.h_scale, 10)), tuple(np.round(s.kappa, 10)),
               round(s.lag_s, 6), warm)
        if key not in self.cache:
            if len(self.cache) > 400:
                self.cache.clear()
            self.cache[key] = responses(self.model, self.rec, s, self.load_shape, warm)
        return self.cache[key]

    def design(self, causes, setting: Setting) -> Design:
        """The nominal prediction and the linear columns of ``causes`` at ``setting``."""
        m, rec = self.model, self.rec
        R, Rw = self._responses(setting, any(c.kind == "warm_start" for c in causes))
        S, G = len(m.sources), len(m.convections)
        cols = []
        th = rec.time_s / 3600.0
        for c in causes:
            if c.kind == "source_scale":
                cols.append(R[:, :, m.sources.index(c.target)])
            elif c.kind == "missing_source":
                cols.append(R[:, :, S + G + m.candidates.index(c.target)])
            elif c.kind == "warm_start":
                cols.append(Rw)
            elif c.kind == "sensor_drift":
                on = np.zeros((th.size, len(rec.channels)))
                on[:, [ch.column for ch in rec.channels].index(c.target)] = 1.0
                cols.append(on)
                cols.append(on * th[:, None])
        return Design(R[:, :, :S + G].sum(axis=2), tuple(cols), setting)

    def regrown(self, setting: Setting) -> "MeshPlant":
        """The plant on the reduced model regrown at ``setting`` (``model.regrow``)."""
        model = GeoModel(**{**vars(self.model),
                            "rb": self.model.regrow(setting.h_scale, setting.kappa)})
        return MeshPlant(model, self.rec, self.load_shape)

    def reference_models(self, rows) -> tuple:
        """None beside the MLR of eq. 18: the simulation is the model judged."""
        return ()


def mesh_plant(model: GeoModel, rec: GeoRecord) -> MeshPlant:
    """The :class:`MeshPlant` of ``model`` on ``rec``."""
    return MeshPlant(model, rec, _load_shape(rec))
