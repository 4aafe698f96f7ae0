"""The seed paper's rod as a :class:`~arfem.models.plant.Plant` (issue 41, build item 1):
the reduced FEM rod (:class:`arfem.models.diagnosis.forward.RodModel`, exact in its
growth modes at any h) bound to a measured ``q_W_m2`` record, so that the one diagnosis
pipeline (:func:`arfem.models.geodiagnosis.engine.diagnose_plant`) diagnoses a rod
record as it diagnoses a mesh.

Channel: the axial growth ``growth_um`` [µm] (a displacement; Hampel outliers of the
record are left out as missing readings). Input per row: the end flux q [W/m²] (zero-
order hold over the interval ending at the row, paper §2). The nominal model is the
paper's: the FEM's growth under q with the rod's nominal h (paper: 55 W/(m²K)) and a
**constant ambient** at the reference; a recorded ambient is not an input of it but the
``ambient_drift`` cause (the paper names a varying ambient as its open limit; the
measured-data contract names it a cause). This is the rod plant's one named difference
from the mesh, whose nominal model takes the recorded ambient.

Causes (the one vocabulary, :func:`arfem.models.plant.cause`), each with the contract
cause it is (:func:`contract_causes`):

=================================================== ================================
plant cause                                         contract (docs/measured-data.md)
=================================================== ================================
``convection_scale:lateral_surface`` (h_scale)      ``convection_mismatch``
``convection_scale:lateral_surface_running``        ``speed_dependent_convection``
(h × h_scale while q > 0)                           (with or without the first)
``natural_convection:lateral_surface``              ``nonlinear_convection``
(h = h_scale h0 (ΔT/10 K)^exponent point by point)
``source_scale:end_flux`` (scale)                   ``heat_input_scale``
``ambient_drift`` (ambient_gain_um_per_K)           ``ambient_drift``
``frame_lag`` (frame_time_constant_h, frame_gain)   ``frame_expansion``
``sensor_drift:growth_um``                          ``sensor_drift``
``warm_start`` (initial_offset_K)                   (outside the contract)
=================================================== ================================

* the ambient column is the FEM's growth under h (T_amb − T_ref) on the lateral surface
  per µm/K of its steady gain αL, so its coefficient is the growth per kelvin of
  ambient at steady state (αL·10⁶ = 9.6 µm/K for a free rod);
* the frame is a slower body heated by the same source: a first-order lag of the rod's
  steady growth target (q times the rod's steady gain), its gain the frame's steady
  growth per unit of rod growth (as :mod:`arfem.models.diagnosis.candidates`);
* the warm start: the rod starts uniformly initial_offset_K [K] above the reference
  (the free response of a uniform 1 K start is αL·10⁶ minus the growth response to a
  1 K ambient step: linearity, a uniform 1 K with a 1 K ambient being equilibrium).
  A record that says ``initial = "unknown"`` (contract) declares it: there the
  uniform start's free response is a nuisance column of the nominal model
  (:attr:`arfem.models.plant.Design.nuisance`), not a cause, as the rod engine's own
  nuisance columns are.

Its reduction is exact at every h (:mod:`.forward`), so it never regrows; natural
convection runs the pointwise rod of :mod:`.local_convection`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

# DT_REF_K: the surface-to-air difference at which a natural-convection h is h_ref [K],
# the rod engine's
from arfem.models.diagnosis.candidates import DT_REF_K
from arfem.models.diagnosis.forward import RodModel, first_order_lag
from arfem.models.diagnosis.synth import ambient_gain_um_per_K
from arfem.models.geodiagnosis.problem import Channel
from arfem.models.plant import Design, cause

__all__ = ["RodPlant", "RodSetting", "rod_plant", "contract_causes", "GROWTH_COLUMN",
           "DT_REF_K"]

#: The rod's one channel.
GROWTH_COLUMN = "growth_um"


@dataclass(frozen=True)
class RodSetting:
    """The rod's nonlinear parameters (the defaults: nominal).

    Attributes
    ----------
    h_scale : float, factor on the nominal lateral h [-]
    h_running_scale : float, a further factor on h while q > 0 [-]
    exponent : float, natural-convection exponent, h = h_ref (ΔT/10 K)^exponent
        with h_ref = h_scale × h_nominal [-] (0: a constant h)
    frame_time_constant_h : float, the frame's time constant [h]
    """

    h_scale: float = 1.0
    h_running_scale: float = 1.0
    exponent: float = 0.0
    frame_time_constant_h: float = 4.0


_SETTING_OF = {"convection_scale:lateral_surface": "h_scale",
               "convection_scale:lateral_surface_running": "h_running_scale",
               "natural_convection:lateral_surface": "h_scale",
               "natural_convection:lateral_surface/exponent": "exponent",
               "frame_lag": "frame_time_constant_h"}


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
    cache : dict, growth responses per setting
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
        """Every single cause the rod and this record can tell (module docstring): a
        running-only h where the flux is both on and off, an ambient drift where the
        ambient is recorded and varies, a warm start where the start is known."""
        running = self.q_W_m2 > 0
        out = [cause("convection_scale", "lateral_surface")]
        if running.any() and not running.all():
            out.append(cause("convection_scale", "lateral_surface_running"))
        out += [cause("natural_convection", "lateral_surface"),
                cause("source_scale", "end_flux")]
        amb = self.ambient_C
        if amb is not None and np.ptp(amb[np.isfinite(amb)]) > 0:
            out.append(cause("ambient_drift"))
        out += [cause("frame_lag"), cause("sensor_drift", GROWTH_COLUMN, "um")]
        return tuple(out) + ((cause("warm_start"),) if self.initial_known else ())

    def setting(self, causes, values: dict) -> RodSetting:
        """The :class:`RodSetting` of ``causes`` at ``values`` {parameter key: value}
        (:meth:`arfem.models.plant.CandidateCause.key`)."""
        kw = {_SETTING_OF[k]: float(values[k]) for c in causes
              for k in (c.key(p) for p in c.nonlinear_parameters) if k in _SETTING_OF}
        return RodSetting(**kw)

    def _local(self):
        """The rod with pointwise convection (built on first use)."""
        if "local" not in self.cache:
            from arfem.models.diagnosis.local_convection import LocalConvectionRod
            self.cache["local"] = LocalConvectionRod(self.model.fem,
                                                     all_modes=self.model.all_modes)
        return self.cache["local"]

    def _h(self, s: RodSetting) -> np.ndarray:
        """The lateral h on each interval at setting ``s`` [W/(m²K)]."""
        return s.h_scale * self.model.h0 * np.where(self.q_W_m2 > 0, s.h_running_scale, 1.0)

    def _cached(self, what: str, s: RodSetting, make):
        key = (what, round(s.h_scale, 10), round(s.h_running_scale, 10), round(s.exponent, 10))
        if key not in self.cache:
            if len(self.cache) > 600:
                local = self.cache.get("local")
                self.cache.clear()
                if local is not None:
                    self.cache["local"] = local
            self.cache[key] = make()
        return self.cache[key]

    def _growth_q(self, s: RodSetting) -> np.ndarray:
        """The growth under the recorded q at setting ``s`` [µm] (N,)."""
        def make():
            m, t = self.model, self.time_s
            if s.exponent != 0.0:
                return self._local().simulate(t, self.q_W_m2, s.exponent, s.h_scale * m.h0,
                                              DT_REF_K)
            return m.simulate(t, self.q_W_m2, h_W_m2K=self._h(s))
        return self._cached("q", s, make)

    def _growth_ambient(self, s: RodSetting) -> np.ndarray:
        """The growth under the recorded ambient per µm/K of steady gain at ``s`` (N,)."""
        def make():
            m, t = self.model, self.time_s
            amb = np.nan_to_num(np.asarray(self.ambient_C, float) - m.rod.ambient_C)
            return m.simulate(t, np.zeros_like(t), ambient_K=amb,
                              h_W_m2K=self._h(s)) / ambient_gain_um_per_K(self.model.rod)
        return self._cached("ambient", s, make)

    def _growth_warm(self, s: RodSetting) -> np.ndarray:
        """The free growth of a uniform 1 K start at ``s`` [µm] (N,)."""
        def make():
            m, t = self.model, self.time_s
            return ambient_gain_um_per_K(self.model.rod) - m.simulate(t, np.zeros_like(t),
                                                   ambient_K=np.ones_like(t),
                                                   h_W_m2K=self._h(s))
        return self._cached("warm", s, make)

    def _frame(self, tau_h: float) -> np.ndarray:
        key = ("frame", round(tau_h, 10))
        if key not in self.cache:
            target = self.q_W_m2 * self.model.steady_growth_um(1.0)
            self.cache[key] = first_order_lag(self.time_s, target, tau_h * 3600.0)
        return self.cache[key]

    def design(self, causes, setting: RodSetting) -> Design:
        """The nominal growth and the linear columns of ``causes`` at ``setting``, (N, 1)."""
        gq = self._growth_q(setting)
        th = self.time_s / 3600.0
        cols = []
        for c in causes:
            if c.kind == "source_scale":
                cols.append(gq[:, None])
            elif c.kind == "warm_start":
                cols.append(self._growth_warm(setting)[:, None])
            elif c.kind == "ambient_drift":
                cols.append(self._growth_ambient(setting)[:, None])
            elif c.kind == "frame_lag":
                cols.append(self._frame(setting.frame_time_constant_h)[:, None])
            elif c.kind == "sensor_drift":
                cols += [np.ones((th.size, 1)), th[:, None].copy()]
        return Design(gq[:, None], tuple(cols), setting,
                      () if self.initial_known else (self._growth_warm(setting)[:, None],))

    def regrown(self, setting: RodSetting) -> "RodPlant":
        """The rod itself: its reduction is exact at every h (never called)."""
        return self


def contract_causes(causes, h_nominal_W_m2K: float) -> tuple:
    """The named causes of a rod diagnosis (:class:`~arfem.models.diagnosis.result.NamedCause`)
    as the measured-data contract names them: ((contract cause, {parameter: value}),
    ...), strongest first (module table); a warm start keeps its plant name, outside
    the contract's vocabulary.

    >>> from arfem.models.diagnosis.result import NamedCause
    >>> c = NamedCause("convection_scale", "convection_scale:lateral_surface",
    ...                "lateral_surface", {"h_scale": 1.5}, {}, {"h_scale": 1.0})
    >>> contract_causes((c,), 55.0)
    (('convection_mismatch', {'h_W_m2K': 82.5}),)
    """
    by = {c.name: c.parameters for c in causes}
    hs = by.get("convection_scale:lateral_surface", {}).get("h_scale", 1.0)
    out, done = [], set()
    for c in causes:
        if c.name in done:
            continue
        p = c.parameters
        if c.name == "convection_scale:lateral_surface_running" or (
                c.name == "convection_scale:lateral_surface"
                and "convection_scale:lateral_surface_running" in by):
            hr = by["convection_scale:lateral_surface_running"]["h_scale"]
            out.append(("speed_dependent_convection",
                        {"h_running_W_m2K": hs * hr * h_nominal_W_m2K,
                         "h_stopped_W_m2K": hs * h_nominal_W_m2K}))
            done |= {"convection_scale:lateral_surface",
                     "convection_scale:lateral_surface_running"}
        elif c.name == "natural_convection:lateral_surface":
            out.append(("nonlinear_convection", {"exponent": p["exponent"],
                                                 "h_at_10K_W_m2K": p["h_scale"] * h_nominal_W_m2K}))
        elif c.name == "convection_scale:lateral_surface":
            out.append(("convection_mismatch", {"h_W_m2K": p["h_scale"] * h_nominal_W_m2K}))
        elif c.cause == "source_scale":
            out.append(("heat_input_scale", {"scale": p["scale"]}))
        elif c.cause == "ambient_drift":
            out.append(("ambient_drift", dict(p)))
        elif c.cause == "frame_lag":
            out.append(("frame_expansion", dict(p)))
        elif c.cause == "sensor_drift":
            out.append(("sensor_drift", {"drift_um_per_h": p["drift_um_per_h"]}))
        else:
            out.append((c.name, dict(p)))
        done.add(c.name)
    return tuple(out)


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
