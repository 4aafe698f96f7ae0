"""Figures of a sweep, each a function of the rows returning a matplotlib ``Figure``
(nothing is drawn on a global pyplot state; :func:`write_figures` saves them).

Choices made from the data, and stated on the figure and in the README:

- a family of curves that coincide (the error hardly depends on Δτ) is drawn once, with
  its spread written on the axes, instead of many lines on top of each other; when the
  members differ they are drawn as small multiples, one panel each;
- one heat-map row per q level only if the error depends on q (it does not when the
  FEM and both ARs are linear in q, as for the paper's rod);
- a swept variable other than Δτ, h and q is held at its first value, and the figure
  says which value.

Colour maps are viridis/cividis (readable in grey and by colour-blind readers); the
colour of a heat-map label is chosen from the luminance of its cell.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from arfem.scenarios.sweep.points import Sweep
from arfem.scenarios.sweep.spec import CORE_INPUTS

__all__ = ["fig_error_vs_biot", "fig_c1_vs_dtau", "fig_error_heatmap", "write_figures",
           "spread_over", "q_dependence", "fixed_others", "LEVELS_PCT"]

#: Error levels drawn as labelled thresholds [% of the FEM peak].
LEVELS_PCT = (3.0, 5.0)
#: Curves whose spread is below this fraction of their largest value are drawn as one.
COINCIDE_REL = 0.01
#: % errors that differ by less than this between q levels count as the same [% points].
Q_SAME_PP = 1e-6

_PAPER = {"color": "#0072B2", "marker": "o", "ls": "-"}       # Okabe-Ito blue
_CORR = {"color": "#D55E00", "marker": "s", "ls": "--"}       # Okabe-Ito vermillion
_ERR = (("", "paper AR(1) (eq. 13)", _PAPER),
        ("corrected_", "corrected AR(1)", _CORR))


def _figure(w: float, h: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(w, h), dpi=150, layout="constrained")
    FigureCanvasAgg(fig)                  # headless: no pyplot, no global state
    return fig


def _g(v) -> str:
    return f"{v:g}" if isinstance(v, (int, float)) else str(v)


def fixed_others(sweep: Sweep) -> dict:
    """Swept variables other than Δτ, h and q, held at their first value in the figures."""
    return {c: v[0] for c, v in sweep.grid.items() if c not in CORE_INPUTS}


def _others_note(sweep: Sweep) -> str:
    f = fixed_others(sweep)
    return "; ".join(f"{c} = {_g(v)} (first of {len(sweep.grid[c])} values)"
                     for c, v in f.items())


def q_dependence(sweep: Sweep, rows: list[dict]) -> float:
    """Largest difference of a % error between q levels at equal other inputs [% points]
    (0 when q is not swept; nan when no group has two q levels)."""
    if len(sweep.grid.get("q_W_m2", [])) < 2:
        return 0.0
    groups: dict = {}
    for r in rows:
        key = tuple(repr(r.get(c)) for c in sweep.grid if c != "q_W_m2")
        groups.setdefault(key, []).append(r)
    d = [max(r[c] for r in g) - min(r[c] for r in g) for g in groups.values() if len(g) > 1
         for c in ("max_abs_diff_pct_of_peak", "corrected_max_abs_diff_pct_of_peak")]
    return max(d) if d else float("nan")


def _base_rows(sweep: Sweep, rows: list[dict], q=None) -> list[dict]:
    """Rows with every non-core swept variable at its first value, and at ``q``."""
    f = fixed_others(sweep)
    return [r for r in rows if all(r.get(c) == v for c, v in f.items())
            and (q is None or r.get("q_W_m2") == q)]


def _q_levels(sweep: Sweep, rows: list[dict]) -> tuple[list, str]:
    """q levels to draw, and a sentence saying why."""
    qs = sorted({r["q_W_m2"] for r in rows})
    if len(qs) < 2:
        return qs, (f"q = {qs[0]:g} W/m²" if qs else "")
    d = q_dependence(sweep, rows)
    if math.isfinite(d) and d < Q_SAME_PP:
        return [max(qs)], (f"identical for q = {', '.join(f'{q:g}' for q in qs)} W/m² "
                           f"(differences ≤ {d:.0e} % points)")
    return qs, ""


def spread_over(rows: list[dict], by: str, x: str, y: str) -> tuple[float, float]:
    """Largest spread of ``y`` over the values of ``by`` at equal ``x``, and its largest value."""
    groups: dict = {}
    for r in rows:
        groups.setdefault(r[x], []).append(r[y])
    sp = max((max(v) - min(v) for v in groups.values()), default=0.0)
    top = max((abs(a) for v in groups.values() for a in v), default=0.0)
    return sp, top


def _title(fig, head: str, notes: list[str]) -> None:
    """Figure title with the data-driven notes (what was drawn once, what is held fixed)
    on the lines below it, wrapped to the figure's width; nothing written over the data."""
    import textwrap
    width = int(fig.get_figwidth() * 13)
    fig.suptitle("\n".join(textwrap.wrap(head, width) +
                           textwrap.wrap("; ".join(notes), width)), fontsize=10)


def _plain_log_ticks(axis, decades: float = 0.0) -> None:
    """Log axis labelled 0.01, 0.02, 0.05, 0.1 ... (no crowded 2×10⁻¹ minor labels); over
    more than 3 decades, powers of ten only."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    axis.set_major_locator(LogLocator(base=10, subs=(1.0,) if decades > 3 else (1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(NullFormatter())


def _threshold_lines(ax) -> None:
    """Horizontal lines at the error levels, labelled at the left end (the lower level
    below its line, the higher above, so the two labels never collide)."""
    for i, lv in enumerate(LEVELS_PCT):
        ax.axhline(lv, color="0.35", lw=0.9, ls=":", zorder=1)
        ax.annotate(f"{lv:g} % of peak", xy=(0.01, lv), xycoords=("axes fraction", "data"),
                    xytext=(0, -2 if i == 0 else 2), textcoords="offset points",
                    ha="left", va="top" if i == 0 else "bottom", fontsize=8, color="0.25")


def fig_error_vs_biot(sweep: Sweep, rows: list[dict]):
    """Max |AR − FEM| [% of peak] against the Biot number, paper and corrected AR.

    Curves for the Δτ values are drawn once if they coincide (spread < 1 % of the
    largest error), else one panel per Δτ (small multiples, shared axes).
    """
    qs, qnote = _q_levels(sweep, rows)
    sel = _base_rows(sweep, rows, qs[-1] if qs else None)
    dtaus = sorted({r["dtau_s"] for r in sel})
    spreads = [spread_over(sel, "dtau_s", "biot", pre + "max_abs_diff_pct_of_peak")
               for pre, _, _ in _ERR]
    same = all(sp <= COINCIDE_REL * top for sp, top in spreads)
    panels = [None] if same or len(dtaus) == 1 else dtaus
    ncol = min(3, len(panels))
    nrow = math.ceil(len(panels) / ncol)
    fig = _figure(4.2 * ncol + 1.2 if ncol > 1 else 6.4, 3.4 * nrow + 0.8 if nrow > 1 else 4.6)
    axs = np.atleast_1d(fig.subplots(nrow, ncol, sharex=True, sharey=True, squeeze=False)).ravel()
    for ax, dt in zip(axs, panels):
        rs = sel if dt is None else [r for r in sel if r["dtau_s"] == dt]
        if dt is None:                            # one curve: the largest over Δτ at each Bi
            bs = sorted({r["biot"] for r in rs})
            for pre, lab, st in _ERR:
                e = [max(max(r[pre + "max_abs_diff_pct_of_peak"] for r in rs
                             if r["biot"] == b), 1e-9) for b in bs]
                ax.plot(bs, e, label=lab, ms=4, lw=1.4, **st)
        else:
            rs = sorted(rs, key=lambda r: r["biot"])
            for pre, lab, st in _ERR:
                ax.plot([r["biot"] for r in rs],
                        [max(r[pre + "max_abs_diff_pct_of_peak"], 1e-9) for r in rs],
                        label=lab, ms=4, lw=1.4, **st)
            ax.set_title(f"Δτ = {dt:g} s", fontsize=10)
        ax.set_xscale("log")
        ax.set_yscale("log")
        _plain_log_ticks(ax.xaxis)
        _threshold_lines(ax)
        ax.grid(True, which="major", alpha=0.3)
    for ax in axs[len(panels):]:
        ax.set_visible(False)
    for ax in axs[:len(panels)]:
        ax.set_xlabel("Biot number hR/λ [-]")
        ax.set_ylabel("max |AR − FEM| [% of FEM peak]")
    axs[0].legend(loc="best", fontsize=8, framealpha=0.9)
    notes = []
    if panels == [None] and len(dtaus) > 1:
        sp = max(s for s, _ in spreads)
        notes.append(f"the {len(dtaus)} values Δτ = {dtaus[0]:g}–{dtaus[-1]:g} s coincide "
                     f"(spread ≤ {sp:.1g} % points); drawn once")
    elif len(dtaus) == 1:
        notes.append(f"Δτ = {dtaus[0]:g} s")
    if qnote:
        notes.append(qnote)
    on = _others_note(sweep)
    if on:
        notes.append(on)
    _title(fig, "When does the AR(1) stop tracking the FEM? Error against Biot number", notes)
    return fig


def fig_c1_vs_dtau(sweep: Sweep, rows: list[dict]):
    """(a) 1 − C1 against Δτ for every h (colour = h, colour bar, no per-line legend);
    (b) the FEM's fitted per-step decay over the paper's, against the Biot number."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import LogNorm, Normalize
    from matplotlib.lines import Line2D
    qs, qnote = _q_levels(sweep, rows)
    sel = _base_rows(sweep, rows, qs[-1] if qs else None)
    hs = sorted({r["h_W_m2K"] for r in sel})
    dtaus = sorted({r["dtau_s"] for r in sel})
    fig = _figure(11.5, 4.6)
    a1, a2 = fig.subplots(1, 2)
    norm = (LogNorm(min(hs), max(hs)) if len(hs) > 1 and min(hs) > 0
            else Normalize(min(hs) - 1, max(hs) + 1))
    cmap = "viridis"
    sm = ScalarMappable(norm=norm, cmap=cmap)
    for h in hs:
        rs = sorted((r for r in sel if r["h_W_m2K"] == h), key=lambda r: r["dtau_s"])
        col = sm.to_rgba(h)
        d = [r["dtau_s"] for r in rs]
        a1.plot(d, [1 - r["C1"] for r in rs], "-", color=col, lw=1.3)
        a1.plot(d, [1 - r["C1_fitted"] for r in rs], "o", color=col, mfc="none", ms=5)
        a1.plot(d, [1 - r["corrected_C1"] for r in rs], ":", color=col, lw=1.0)
    a1.set_xscale("log")
    _plain_log_ticks(a1.xaxis)
    a1.set_yscale("log")
    a1.set_xlabel("AR step Δτ [s]")
    a1.set_ylabel("per-step decay 1 − C1 [-]")
    a1.set_title("(a) 1 − C1 against Δτ, one colour per h", fontsize=10)
    a1.grid(True, which="major", alpha=0.3)
    a1.legend(handles=[Line2D([], [], color="0.2", ls="-", label="paper eq. 13 (closed form)"),
                       Line2D([], [], color="0.2", ls="none", marker="o", mfc="none",
                              label="fitted to the FEM"),
                       Line2D([], [], color="0.2", ls=":", label="corrected AR")],
              loc="upper left", fontsize=8, framealpha=0.9)
    cb = fig.colorbar(sm, ax=a1, pad=0.01)
    cb.set_label("h [W/(m²·K)]")
    # (b) ratio against Biot; one curve if the Δτ values coincide
    ratio = [dict(r, _ratio=(1 - r["C1_fitted"]) / (1 - r["C1"])) for r in sel
             if 1 - r["C1"] > 0]
    sp, top = spread_over(ratio, "dtau_s", "biot", "_ratio")
    dsel = [dtaus[0]] if sp <= 1e-3 * top else dtaus
    dnorm = LogNorm(min(dtaus), max(dtaus)) if len(dtaus) > 1 else Normalize(0, 2 * dtaus[0])
    dsm = ScalarMappable(norm=dnorm, cmap="cividis")
    for dt in dsel:
        rs = sorted((r for r in ratio if r["dtau_s"] == dt), key=lambda r: r["biot"])
        a2.plot([r["biot"] for r in rs], [r["_ratio"] for r in rs], "o-", ms=4, lw=1.3,
                color="#0072B2" if len(dsel) == 1 else dsm.to_rgba(dt))
    a2.axhline(1.0, color="0.35", lw=0.9, ls=":")
    a2.annotate("1 = paper's decay", xy=(0.99, 1.0), xycoords=("axes fraction", "data"),
                ha="right", va="top", fontsize=8, color="0.25")
    a2.set_xscale("log")
    _plain_log_ticks(a2.xaxis)
    a2.set_xlabel("Biot number hR/λ [-]")
    a2.set_ylabel("(1 − C1 fitted) / (1 − C1 paper) [-]")
    a2.set_title("(b) FEM's fitted decay over the paper's", fontsize=10)
    a2.grid(True, which="major", alpha=0.3)
    if len(dsel) > 1:
        cb2 = fig.colorbar(dsm, ax=a2, pad=0.01)
        cb2.set_label("Δτ [s]")
    notes = []
    if len(dsel) == 1 and len(dtaus) > 1:
        notes.append(f"the same for all {len(dtaus)} Δτ values {dtaus[0]:g}–{dtaus[-1]:g} s "
                     f"(spread ≤ {sp:.1g})")
    if qnote:
        notes.append(qnote)
    on = _others_note(sweep)
    if on:
        notes.append(on)
    _title(fig, "AR(1) coefficient C1: closed form (paper eq. 13) against the FEM", notes)
    return fig


_LEVEL_STYLES = ({"color": "#E69F00", "lw": 1.8, "ls": (0, (3, 1.5))},
                 {"color": "#E69F00", "lw": 2.6, "ls": "-"})


def _level_boundary(ax, mask, **style) -> None:
    """Outline the cells where ``mask`` holds by the cell edges it shares with the others
    (a stepped contour on a grid whose axes are categories, not a false interpolation)."""
    from matplotlib.collections import LineCollection
    ni, nj = mask.shape
    seg = []
    for i in range(ni):
        for j in range(nj):
            if not mask[i, j]:
                continue
            if j == 0 or not mask[i, j - 1]:
                seg.append([(j - 0.5, i - 0.5), (j - 0.5, i + 0.5)]) if j > 0 else None
            if j < nj - 1 and not mask[i, j + 1]:
                seg.append([(j + 0.5, i - 0.5), (j + 0.5, i + 0.5)])
            if i > 0 and not mask[i - 1, j]:
                seg.append([(j - 0.5, i - 0.5), (j + 0.5, i - 0.5)])
            if i < ni - 1 and not mask[i + 1, j]:
                seg.append([(j - 0.5, i + 0.5), (j + 0.5, i + 0.5)])
    ax.add_collection(LineCollection(seg, colors=style["color"], linewidths=style["lw"],
                                     linestyles=[style["ls"]], zorder=3, capstyle="butt"))


def _luminance(rgba) -> float:
    """WCAG relative luminance of an sRGB colour (0 black .. 1 white)."""
    c = np.asarray(rgba[:3], float)
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return float(lin @ [0.2126, 0.7152, 0.0722])


def _short(z: float) -> str:
    """Compact cell label: 3 significant digits from 1 up (4.98 is not shown as 5), 2 below, 1 for tiny numbers, no padded exponent."""
    if z >= 0.995:
        return f"{z:.3g}"
    if z >= 0.095:
        return f"{z:.2g}"
    m, e = f"{z:.0e}".split("e")
    return f"{m}e{int(e)}"


def fig_error_heatmap(sweep: Sweep, rows: list[dict]):
    """Max |AR − FEM| [% of peak] over (h, Δτ): paper AR and corrected AR, one row of panels
    per q level that gives different errors (one row when the error does not depend on q),
    contours at the error levels, labels coloured by cell luminance."""
    from matplotlib.colors import LogNorm
    qs, qnote = _q_levels(sweep, rows)
    base = _base_rows(sweep, rows)
    dtaus = sorted({r["dtau_s"] for r in base})
    hs = sorted({r["h_W_m2K"] for r in base})
    bi = {r["h_W_m2K"]: r["biot"] for r in base}
    nq = len(qs)
    fig = _figure(max(7.0, 0.62 * len(hs) + 2.5), 0.5 + nq * 2 * max(2.4, 0.42 * len(dtaus) + 1.2))
    axs = fig.subplots(2 * nq, 1, squeeze=False).ravel()
    cmap = "cividis"
    k = 0
    for q in qs:
        rs = [r for r in base if r.get("q_W_m2") == q]
        for pre, lab, _ in _ERR:
            ax = axs[k]
            k += 1
            Z = np.full((len(dtaus), len(hs)), np.nan)
            for r in rs:
                Z[dtaus.index(r["dtau_s"]), hs.index(r["h_W_m2K"])] = \
                    r[pre + "max_abs_diff_pct_of_peak"]
            # one colour scale per AR over every q level, so the rows can be compared
            allz = np.array([r[pre + "max_abs_diff_pct_of_peak"] for r in base
                             if r.get("q_W_m2") in qs], float)
            pos = allz[np.isfinite(allz) & (allz > 0)]
            norm = LogNorm(pos.min(), pos.max()) if pos.size and pos.max() > pos.min() else None
            im = ax.imshow(np.where(Z > 0, Z, np.nan), origin="lower", aspect="auto",
                           cmap=cmap, norm=norm, interpolation="nearest")
            ax.set_xticks(range(len(hs)), [f"{h:g}" for h in hs], fontsize=8)
            ax.set_yticks(range(len(dtaus)), [f"{d:g}" for d in dtaus], fontsize=8)
            ax.set_xlabel("convection coefficient h [W/(m²·K)]")
            ax.set_ylabel("AR step Δτ [s]")
            top = ax.secondary_xaxis("top")
            top.set_xticks(range(len(hs)), [f"{bi[h]:.2g}" for h in hs], fontsize=7)
            top.set_xlabel("Biot number hR/λ [-]", fontsize=8)
            for (i, j), z in np.ndenumerate(Z):
                if np.isfinite(z):
                    rgba = im.cmap(im.norm(z)) if z > 0 else (1, 1, 1, 1)
                    ax.text(j, i, _short(z), ha="center", va="center", fontsize=7,
                            color="black" if _luminance(rgba) > 0.179 else "white")
            cb = fig.colorbar(im, ax=ax, pad=0.01)
            cb.set_label("% of FEM peak", fontsize=8)
            if norm is not None:
                _plain_log_ticks(cb.ax.yaxis, math.log10(norm.vmax / norm.vmin))
                cb.ax.tick_params(labelsize=7)
            for lv, st in zip(LEVELS_PCT, _LEVEL_STYLES):
                if np.nanmax(Z) >= lv > np.nanmin(Z):
                    _level_boundary(ax, Z >= lv, **st)
                if norm is not None and norm.vmin <= lv <= norm.vmax:   # keyed on the bar
                    cb.ax.axhline(lv, **st)
                    cb.ax.annotate(f"{lv:g} %", xy=(0.0, lv), xycoords=("axes fraction", "data"),
                                   xytext=(-2, 0), textcoords="offset points", ha="right",
                                   va="center", fontsize=7, color="black",
                                   bbox={"fc": "white", "ec": "none", "pad": 0.5})
            never = [lv for lv in LEVELS_PCT if np.nanmax(Z) < lv]
            extra = f"; below {never[0]:g} % everywhere" if never else ""
            qtxt = f", q = {q:g} W/m²" if (nq > 1) else ""
            ax.set_title(f"{lab}: max |AR − FEM| [% of FEM peak]{qtxt}{extra}", fontsize=9.5)
    notes = [n for n in (qnote, _others_note(sweep)) if n]
    head = ("AR(1) error over Δτ and h. Orange: edge of the cells at or above "
            + " (dashed) and ".join(f"{v:g} %" for v in LEVELS_PCT) + " (solid), keyed on the "
            "colour bars")
    _title(fig, head, notes)
    return fig


def write_figures(sweep: Sweep, rows: list[dict], folder: Path) -> list[str]:
    """Save every figure of the sweep as PNG in ``folder``; return the file names."""
    out = []
    for name, make in (("error_vs_biot.png", fig_error_vs_biot),
                       ("c1_vs_dtau.png", fig_c1_vs_dtau),
                       ("error_heatmap.png", fig_error_heatmap)):
        fig = make(sweep, rows)
        fig.savefig(Path(folder) / name)
        out.append(name)
    return out
