"""Natural convection applied point by point on the rod's lateral surface.

The law h = h_ref (|θ_s − θ_amb| / ΔT_ref)^n holds *locally*: the heated end of a rod is
tens of kelvin above the air while its far end is near it, so the heat lost,
∫ h(ΔT) ΔT dS ∝ ∫ |ΔT|^{1+n} dS, is not a function of the mean surface temperature
(by Jensen's inequality it exceeds the mean-temperature law by a factor that changes
with the axial profile, i.e. with time). A model that takes h from the mean surface
temperature (as the diagnosis did until issue 13) fits a biased exponent: +0.02 to
+0.08 on generated records, outside its 95 % interval in 5 of 6.

:class:`LocalConvectionRod` works in *all* modes of the FEM rod at the nominal h0
(the M-orthonormal modes of M θ' = −(K + h0 B) θ + q f_q, :func:`arfem.fem.heat.modes`;
the fast ones carry the surface's sharp profile near the heated face, and keeping only
the growth modes and the 20 slowest biased the exponent by −0.001 to −0.002), and
integrates

    c' = −Λ c + q Φᵀf_q − Φᵀ B_l [(h(ΔT) − h0) ΔT],   ΔT = Φ_l c − θ_amb   (nodal, lateral)

by splitting: the linear part (h0) exactly per sample interval, the nonlinear surface
flux (interpolated from nodal values, "group finite elements", as the generator of
:mod:`arfem.models.diagnosis.synth` does) held over blocks of <= ``BLOCK_S`` and
evaluated at each block's middle sample (the linear part exact there, the nonlinear
part extrapolated from the last two blocks), an exponential integrator of second order
in the block length; a change of the heat input starts a new block. On generated
records its growth is within ~0.02 µm RMS of the generator's 15 s θ-method FEM (the
mean-temperature model is 2.3 µm off), and only the growth modes are assembled at the
samples.

References
----------
Hochbruck M., Ostermann A., "Exponential integrators", Acta Numerica 19 (2010) 209-286
(exponential Euler / explicit splitting); Christie I., Griffiths D. F., Mitchell A. R.,
Sanz-Serna J. M., "Product approximation for non-linear problems in the finite element
method", IMA J. Numer. Anal. 1 (1981) 253-266 (group finite elements).
"""
from __future__ import annotations

import numpy as np

from arfem.fem.heat import HeatFEM, modes
from arfem.models.diagnosis.forward import linear_recursion, intervals

__all__ = ["LocalConvectionRod", "BLOCK_S", "H_FLOOR", "H_CAP"]

#: longest stretch [s] over which the nonlinear surface flux is held (0.03 µm at 300 s)
BLOCK_S = 300.0
#: the local h is kept within [H_FLOOR, H_CAP] x h0 (ΔT -> 0 would give h -> 0; the cap
#: keeps the explicit surface flux stable: blocks are at most ρcR / (2 (H_CAP − 1) h0)
#: long, the time in which the capped extra convection would cool a lumped rod by 1/e)
H_FLOOR, H_CAP = 0.05, float(np.exp(2.5))


class LocalConvectionRod:
    """The FEM rod with pointwise natural convection on its lateral surface.

    Parameters
    ----------
    fem : HeatFEM
        The rod's axisymmetric heat FEM (M [J/K], K [W/K], B [m²], loads, growth [m/K]).
    all_modes : optional
        ``arfem.fem.heat.modes(fem, h0)`` if already computed (saves the eigensolve).

    Examples
    --------
    >>> from arfem.params import Rod
    >>> from arfem.fem.heat import build_axisymmetric
    >>> m = LocalConvectionRod(build_axisymmetric(Rod(), order=2, nr=4, nz=24))
    >>> t = np.arange(1, 1441) * 60.0
    >>> g0 = m.simulate(t, np.full(t.size, 2000.0), 0.0, 55.0, 10.0)
    >>> from arfem.models.diagnosis.forward import RodModel
    >>> bool(abs(g0[-1] - RodModel(Rod()).simulate(t, np.full(t.size, 2000.0))[-1]) < 0.01)
    True
    """

    def __init__(self, fem: HeatFEM, all_modes=None):
        rod = fem.rod
        self.h0 = float(rod.convection_W_m2K)
        md = modes(fem, self.h0) if all_modes is None else all_modes
        B = fem.B.tocsr()
        # the lateral surface's nodes: the facet assembly leaves rows of 1e-21..1e-17
        # (rounding, 1e-14 of the true entries) at the 84 interior nodes of the outer
        # element column (Q2, nr = 4, nz = 24); they carried nothing but rounding and
        # made the block loop's two mat-vecs 2.7x as long (133 nodes for 49)
        weight = np.asarray(abs(B).sum(axis=1)).ravel()
        lateral = np.flatnonzero(weight > 1e-12 * weight.max())
        # every mode is kept: truncating the fast ones (which carry the surface's sharp
        # profile near the heated face) biased the fitted exponent by -0.001 to -0.002
        self.lam, self.fq, self.fb = md.mu, md.fq, md.fb
        self.L = md.phi[lateral]                               # lateral nodal θ per mode
        self.W = np.asarray((B[:, lateral].T @ md.phi).T)      # Φᵀ B_l
        self.grow = np.flatnonzero(np.abs(md.g) > 1e-9 * np.max(np.abs(md.g)))
        self.g = md.g[self.grow] * 1e6                         # growth [µm] per growth mode
        rhocR = rod.density_kg_m3 * rod.specific_heat_J_kgK * rod.radius_m
        self.block_s = min(BLOCK_S, rhocR / (2.0 * (H_CAP - 1.0) * self.h0))
        self._lin: dict = {}

    def _linear(self, t, q, amb, block_s):
        """The h0 response (modal states, lateral ΔT) and the blocks, cached per record."""
        key = (t.tobytes(), q.tobytes(), amb.tobytes(), block_s)
        v = self._lin.get(key)
        if v is not None:
            return v
        # intervals longer than half a block (gaps in the record) get interior points,
        # the input held, so that no stretch of held surface flux exceeds a block
        k = np.maximum(1, np.ceil(intervals(t) / (0.5 * block_s) - 1e-9).astype(int))
        real = np.cumsum(k) - 1                                   # rows of the samples
        if real[-1] + 1 > t.size:
            tp = np.concatenate([[0.0], t[:-1]])
            j = np.arange(real[-1] + 1) - np.repeat(real - k + 1, k) + 1
            t_in = t
            t = np.repeat(tp, k) + j * np.repeat((t - tp) / k, k)
            t[real] = t_in
            q, amb = np.repeat(q, k), np.repeat(amb, k)
        lam = self.lam
        d = intervals(t)
        a = np.exp(-np.outer(d, lam))
        forcing = (np.outer(q, self.fq) + np.outer(self.h0 * amb, self.fb)) / lam
        Z = linear_recursion(a, (1.0 - a) * forcing, np.zeros(lam.size))
        starts, t0 = [0], 0.0
        for i in range(1, t.size):
            if t[i] - t0 > block_s or q[i] != q[i - 1]:
                starts.append(i)
                t0 = t[i - 1]
        starts = np.array(starts)
        ends = np.append(starts[1:], t.size)
        tprev = np.concatenate([[0.0], t])[starts]               # each block's start time
        mid = (starts + ends - 1) // 2
        blk = np.repeat(np.arange(starts.size), ends - starts)
        # decay of each growth mode since its block's start
        P = np.exp(-(t - tprev[blk])[:, None] * lam[self.grow])
        v = {"growth": Z[:, self.grow] @ self.g, "dT_mid": Z[mid] @ self.L.T - amb[mid][:, None],
             "tprev": tprev, "t_mid": t[mid] - tprev,
             "Pend": np.exp(-np.outer(t[ends - 1] - tprev, lam)), "blk": blk, "P": P,
             "real": real}
        v["Qend"] = (1.0 - v["Pend"]) / lam
        # the extrapolation's factor t_mid / (the previous block's length); NaN where
        # there is none (the first block, a repeated time)
        span = np.diff(np.concatenate([[0.0], tprev]))
        with np.errstate(divide="ignore", invalid="ignore"):
            v["ratio"] = np.where(span > 0.0, v["t_mid"] / span, np.nan)
        v["ratio"][0] = np.nan
        # each block's rows and extrapolation factor, for the loop of :meth:`_run`
        v["rows"] = list(zip(v["dT_mid"], v["Pend"], v["Qend"], v["ratio"].tolist()))
        if len(self._lin) > 8:
            self._lin.clear()
        self._lin[key] = v
        return v

    def simulate(self, time_s, q_W_m2, exponent: float, h_ref_W_m2K: float,
                 dT_ref_K: float, ambient_K=None):
        """Growth [µm] with h = h_ref (|ΔT|/ΔT_ref)^n at every lateral surface node.

        h is kept within [``H_FLOOR``, ``H_CAP``] x h0 (as the former mean-temperature
        model did).

        Parameters
        ----------
        time_s : array_like
            Sample times [s] (the first interval starts at t = 0), increasing.
        q_W_m2 : array_like
            Heat flux into the heated end on the interval ending at each sample [W/m²].
        exponent : float
            n in h ∝ ΔT^n [-] (1/4 laminar, 1/3 turbulent natural convection).
        h_ref_W_m2K : float
            h where the surface is ``dT_ref_K`` above the air [W/(m²·K)].
        dT_ref_K : float
            Surface-to-air difference at which h = ``h_ref_W_m2K`` [K].
        ambient_K : array_like, optional
            Ambient minus the nominal ambient on each interval [K]; default 0.

        Returns
        -------
        ndarray
            Axial growth at each sample [µm], from equilibrium at t = 0.
        """
        t = np.asarray(time_s, float)
        q = np.asarray(q_W_m2, float)
        amb = np.zeros(t.size) if ambient_K is None else np.asarray(ambient_K, float)
        # the explicit surface flux is stable for plausible h; far outside (an h near the
        # cap on a thick rod) the blocks are halved until the run stays bounded
        for j in range(6):
            v = self._linear(t, q, amb, self.block_s / 2 ** j)
            with np.errstate(over="ignore", invalid="ignore"):
                g = self._run(v, exponent, h_ref_W_m2K, dT_ref_K)
            bound = 100.0 * (np.max(np.abs(v["growth"])) + 1.0)
            if np.all(np.isfinite(g)) and np.max(np.abs(g)) < bound:
                return g
        return np.full(t.size, bound)

    def _run(self, v, exponent, h_ref_W_m2K, dT_ref_K):
        """Growth [µm] at the samples for one exponent and h_ref: the blocks in turn
        (module docstring), their per-block factors precomputed once per record.

        The loop is most of a natural convection's fit (a screen's polish runs it ~75
        times per record): each step writes into buffers and the modal states' rows
        (``out=``) instead of allocating, with the same operations in the same order,
        so the same bits."""
        L, W, h0 = self.L, self.W, self.h0
        n = float(exponent)
        c = float(h_ref_W_m2K) / float(dT_ref_K) ** n
        nb, m = v["Pend"].shape
        S = np.empty((nb, m))
        Z = np.empty((nb + 1, m))                    # Z[b]: the modes at block b's start
        Z[0] = 0.0
        zs, tmp = np.empty(m), np.empty(m)
        dT, h = np.empty(L.shape[0]), np.empty(L.shape[0])
        lo, hi = H_FLOOR * h0, H_CAP * h0
        power, absolute, lower, upper = np.power, np.abs, np.maximum, np.minimum
        add, sub, mul, dot = np.add, np.subtract, np.multiply, np.dot
        for b, (dT_mid, Pend, Qend, r) in enumerate(v["rows"]):
            zn = Z[b]
            if b and r == r:
                # the state extrapolated to the block's middle: zn + r (zn − zp)
                sub(zn, Z[b - 1], out=zs)
                mul(r, zs, out=zs)
                add(zn, zs, out=zs)
                add(dT_mid, L.dot(zs), out=dT)
            else:
                add(dT_mid, L.dot(zn), out=dT)
            # h = clip(c (|ΔT| + 1e-12)^n), as maximum then minimum (np.clip's own
            # overhead was a tenth of a run); the flux (h − h0) ΔT
            add(absolute(dT, out=h), 1e-12, out=h)
            mul(c, power(h, n, out=h), out=h)
            upper(lower(h, lo, out=h), hi, out=h)
            mul(sub(h, h0, out=h), dT, out=h)
            dot(W, h, out=S[b])
            sub(mul(Pend, zn, out=Z[b + 1]), mul(Qend, S[b], out=tmp), out=Z[b + 1])
        blk, P = v["blk"], v["P"]
        gi, lg = self.grow, self.lam[self.grow]
        Zn = P * Z[:-1, gi][blk] - (1.0 - P) / lg * S[:, gi][blk]
        return (v["growth"] + Zn @ self.g)[v["real"]]
