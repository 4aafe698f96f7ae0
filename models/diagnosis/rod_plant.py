"""The seed paper's rod as a :class:`~arfem.models.plant.Plant` (issue 41, build item 1):
the reduced FEM rod (:class:`arfem.models.diagnosis.forward.RodModel`, exact in its
growth modes at any h) bound to a measured ``q_W_m2`` record, so that the one diagnosis
pipeline (:func:`arfem.models.geodiagnosis.engine.diagnose_plant`) diagnoses a rod
record as it diagnoses a mesh.

Channel: the axial growth ``growth_um`` [µm] (a displacement; Hampel outliers of the
record are left out as missing readings). Inputs per row: the end flux q [W/m²] and
the recorded ambient [°C] (zero-order hold over the interval ending at the row, paper
§2), both inputs of the nominal model: the growth is the FEM's response to q through
the end face and to h (T_amb − T_ref) on the lateral surface, h the rod's nominal
(paper: 55 W/(m²K)).

Causes (the one vocabulary, :func:`arfem.models.plant.cause`):

* ``convection_scale:lateral_surface``: h = h_scale × h_nominal [-] (nonlinear; the
  rod engine's ``convection_mismatch`` with h_W_m2K = h_scale × h_nominal);
* ``source_scale:end_flux``: the flux that enters is scale × the recorded q [-] (the
  rod engine's ``heat_input_scale``, or a heat-input efficiency);
* ``sensor_drift:growth_um``: an offset [µm] and a drift [µm/h] of the sensor;
* ``warm_start``: the rod starts uniformly initial_offset_K [K] above the reference
  (the free response of a uniform 1 K start is αL·10⁶ minus the growth response to a
  1 K ambient step: linearity, a uniform 1 K with a 1 K ambient being equilibrium).
  A record that says ``initial = "unknown"`` (contract) declares it: there the
  uniform start's free response is a nuisance column of the nominal model
  (:attr:`arfem.models.plant.Design.nuisance`), not a cause, as the rod engine's own
  nuisance columns are.

Its reduction is exact at every h (:mod:`.forward`), so it never regrows. Named
properties where the rod differs from the mesh: one channel and no modelled
thermometer, so its data baseline is the MLR of eq. 18 on the ambient alone; and no
``ambient_lag`` cause. The rod records' ambient is one thermometer with white noise
(0.05 K in the synth) on an ambient that is often constant: a lag of the recorded
ambient then smooths the sensor's own noise out of the nominal input, and it was
established beside a true flux scale (lag 1.6 h [0.61, 2.63], synth seed 22, flux ×
1.3), a cause of the measurement rather than of the rod. (The setting keeps the lag,
for a plant that offers it.)
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from arfem.models.diagnosis.forward import RodModel
from arfem.models.geodiagnosis.problem import Channel, ambient_lagged
from arfem.models.plant import Design, cause

__all__ = ["RodPlant", "RodSetting", "rod_plant", "GROWTH_COLUMN"]

#: The rod's one channel.
GROWTH_COLUMN = "growth_um"


@dataclass(frozen=True)
class RodSetting:
    """The rod's nonlinear parameters (1 and no lag: nominal).

    Attributes
    ----------
    h_scale : float, factor on the nominal lateral h [-]
    lag_s : float, first-order lag of the ambient reaching the rod [s] (0: none)
    """

    h_scale: float = 1.0
    lag_s: float = 0.0


@dataclass(frozen=True)
class RodPlant:
    """The reduced FEM rod bound to a ``q_W_m2`` record (module docstring).

    Attributes
    ----------
    model : RodModel, the rod (its ``rod`` holds h_nominal [W/(m²K)] and the
        reference = initial = nominal ambient [°C])
    name : str, the record's name
    time_s : ndarray (N,), sample times [s] from 0
    data : ndarray (N, 1), measured growth [µm], NaN where left out
    q_W_m2 : ndarray (N,), recorded end flux [W/m²]
    ambient_C : ndarray (N,) or None, recorded ambient [°C]
    load_shape : ndarray (N,), q / max q [-]
    initial_known : bool, False: the record declares an unknown (warm) start
    cache : dict, growth responses per (h_scale, lag_s)
    """

    model: RodModel
    name: str
    time_s: np.ndarray
    data: np.ndarray
    q_W_m2: np.ndarray
    ambient_C: np.ndarray | None
    load_shape: np.ndarray
    initial_known: bool = True
    cache: dict = field(default_factory=dict, repr=False)
    kind: str = "rod"
    channels: tuple = (Channel(GROWTH_COLUMN, "growth", "displacement", 0, 1.0, "um"),)
    not_searched: tuple = ()
    regrows: bool = False
    nominal_parameters: tuple = ()

    def candidate_causes(self) -> tuple:
        """Every single cause the rod and this record can tell (module docstring)."""
        out = (cause("convection_scale", "lateral_surface"), cause("source_scale", "end_flux"),
               cause("sensor_drift", GROWTH_COLUMN, "um"))
        return out + ((cause("warm_start"),) if self.initial_known else ())

    def setting(self, causes, values: dict) -> RodSetting:
        """The :class:`RodSetting` of ``causes`` at ``values`` {cause name: value}."""
        hs, lag = 1.0, 0.0
        for c in causes:
            if c.kind == "convection_scale":
                hs = float(values.get(c.name))
            elif c.kind == "ambient_lag":
                lag = float(values.get(c.name)) * 3600.0
        return RodSetting(hs, lag)

    def _responses(self, s: RodSetting):
        """(growth per recorded q, growth per recorded ambient, growth of a uniform
        1 K start) [µm] at setting ``s``, each (N,)."""
        key = (round(s.h_scale, 10), round(s.lag_s, 6))
        if key not in self.cache:
            if len(self.cache) > 400:
                self.cache.clear()
            m, t = self.model, self.time_s
            h = s.h_scale * m.h0
            zero = np.zeros_like(t)
            if self.ambient_C is None:
                amb = zero
            else:
                amb = ambient_lagged(t, self.ambient_C, s.lag_s) - m.rod.ambient_C
            rod = m.rod
            uniform_um = rod.expansion_1_K * rod.length_m * 1e6
            self.cache[key] = (m.simulate(t, self.q_W_m2, h_W_m2K=h),
                               m.simulate(t, zero, ambient_K=amb, h_W_m2K=h),
                               uniform_um - m.simulate(t, zero, ambient_K=np.ones_like(t),
                                                       h_W_m2K=h))
        return self.cache[key]

    def design(self, causes, setting: RodSetting) -> Design:
        """The nominal growth and the linear columns of ``causes`` at ``setting``, (N, 1)."""
        gq, ga, gw = self._responses(setting)
        th = self.time_s / 3600.0
        cols = []
        for c in causes:
            if c.kind == "source_scale":
                cols.append(gq[:, None])
            elif c.kind == "warm_start":
                cols.append(gw[:, None])
            elif c.kind == "sensor_drift":
                cols += [np.ones((th.size, 1)), th[:, None].copy()]
        return Design((gq + ga)[:, None], tuple(cols), setting,
                      () if self.initial_known else (gw[:, None],))

    def regrown(self, setting: RodSetting) -> "RodPlant":
        """The rod itself: its reduction is exact at every h (never called)."""
        return self


def rod_plant(ds, model: RodModel | None = None) -> RodPlant:
    """The :class:`RodPlant` of a validated ``q_W_m2`` record
    (:class:`arfem.models.diagnosis.dataset.Dataset`): growth with its flagged outliers
    left out, the flux and the ambient as inputs; ``model`` the reduced rod of
    ``ds.rod`` (built when not given)."""
    if ds.q_W_m2 is None:
        raise ValueError(f"{ds.name}: the rod plant needs a q_W_m2 record")
    y = np.array(ds.growth_um, float)
    y[np.asarray(ds.outliers, bool)] = np.nan
    q = np.asarray(ds.q_W_m2, float)
    shape = q / float(np.max(q)) if np.max(q) > 0 else np.zeros_like(q)
    return RodPlant(model or RodModel(ds.rod), ds.name, np.asarray(ds.time_s, float),
                    y[:, None], q, None if ds.ambient_C is None else np.asarray(ds.ambient_C),
                    shape, bool(ds.initial_known))
