"""The heat problem one θ-method step at a time, for a process that learns its inputs as
it goes (the OPC UA twin of ``arfem twin``): the same matrices as
:func:`arfem.fem.heat.solve_theta`, one factorisation per convection value.
"""
from __future__ import annotations

import numpy as np

from arfem.fem.heat import HeatFEM
from arfem.fem.linsolve import factorize_spd
from arfem.params import InputError

__all__ = ["HeatStepper"]


class HeatStepper:
    """Advance θ by one step of Δt under inputs held over the step.

    Parameters
    ----------
    model : HeatFEM
        Assembled heat problem (axisymmetric or 3D).
    dt_s : float
        Step Δt [s].
    theta : float
        0.5 = Crank–Nicolson, 1 = backward Euler.

    Examples
    --------
    >>> from arfem.fem.heat import build_axisymmetric
    >>> from arfem.params import Rod
    >>> s = HeatStepper(build_axisymmetric(Rod(), nr=2, nz=8), dt_s=60.0)
    >>> g = [s.step(2000.0, 55.0, 0.0) for _ in range(3)]
    >>> 0 < g[0] < g[1] < g[2]
    True
    """

    def __init__(self, model: HeatFEM, dt_s: float, theta: float = 0.5):
        if not (np.isfinite(dt_s) and dt_s > 0):
            raise InputError(f"must be > 0, got {dt_s!r}", "dt_s")
        if not 0.5 <= theta <= 1.0:
            raise InputError(f"must lie in [0.5, 1], got {theta!r}", "theta")
        self.model, self.dt_s, self.theta = model, float(dt_s), float(theta)
        self.x = np.zeros(model.ndofs)
        self._cache: dict[float, tuple] = {}

    def _matrices(self, h: float):
        m = self._cache.get(h)
        if m is None:
            A = self.model.operator(h)
            m = (factorize_spd(self.model.M + self.theta * self.dt_s * A),
                 (self.model.M - (1.0 - self.theta) * self.dt_s * A).tocsr())
            self._cache[h] = m
        return m

    def step(self, q_W_m2: float, h_W_m2K: float, theta_amb_K: float) -> float:
        """One step; returns the axial growth at its end [µm].

        Parameters
        ----------
        q_W_m2 : float
            Heat flux into the heated end over the step [W/m²].
        h_W_m2K : float
            Lateral convection coefficient over the step [W/(m²·K)].
        theta_amb_K : float
            Ambient minus the rod's nominal ambient over the step [K].
        """
        lhs, rhs = self._matrices(float(h_W_m2K))
        f = self.dt_s * self.model.load(q_W_m2, h_W_m2K, theta_amb_K)
        self.x = lhs.solve(rhs @ self.x + f)
        return self.growth_um

    @property
    def growth_um(self) -> float:
        """Axial growth of the current state [µm]."""
        return float(self.model.growth @ self.x) * 1e6

    def temperature_C(self, point) -> float:
        """Temperature [°C] at the degree of freedom nearest ``point`` ((r, z) or (x, y, z)
        [m])."""
        locs = self.model.basis.doflocs
        i = int(np.argmin(np.sum((locs.T - np.asarray(point, float)) ** 2, axis=1)))
        return float(self.model.rod.ambient_C + self.x[i])
