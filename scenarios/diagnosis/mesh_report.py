"""The human side of a mesh diagnosis (issue 33): ``report.md`` / ``report.html``
opening with the verdict, the geometry with the named group highlighted, each channel
measured against the nominal and the extended model, ``series.csv``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from arfem.io import atomic_write_text, write_csv
from arfem.models.geodiagnosis.engine import NAMED_BY_SCREEN
from arfem.scenarios.html_report import write_html_report

__all__ = ["write_report", "highlighted_picture", "named_groups"]


def named_groups(d, model) -> tuple[list, list]:
    """(surface groups, volume groups) the named causes sit on."""
    surf, vol = [], []
    for c in d.causes:
        if c.cause == "convection_scale":
            surf.append(model.convection_groups[model.convections.index(c.target)])
        elif c.cause == "missing_source":
            surf.append(c.target)
        elif c.cause == "contact_conductance":
            vol.append(c.target)
    return surf, vol


def _source_groups(sc, names) -> list:
    return [s.spec.group for s in sc.sources if s.spec.name in names]


def highlighted_picture(gm, path: Path, surfaces=(), volumes=(), sensors=(),
                        title: str = "") -> None:
    """Off-screen PNG of the mesh: every surface translucent grey, the ``surfaces``
    groups and the boundary of the ``volumes`` groups opaque red, the sensors marked."""
    import pyvista as pv
    from vtkmodules.vtkCommonCore import vtkLogger
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    mesh = gm.mesh
    nv = int(mesh.t.max()) + 1
    P = mesh.p[:, :nv].T
    pl = pv.Plotter(off_screen=True, window_size=(1100, 850))

    def poly(fac):
        f = mesh.facets[:, np.asarray(fac, int)].T
        return pv.PolyData(P, np.column_stack([np.full(len(f), f.shape[1]), f]).ravel())
    bnd = mesh.boundary_facets()
    pl.add_mesh(poly(bnd), color="lightgrey", opacity=0.25)
    for g in surfaces:
        pl.add_mesh(poly(gm.surfaces[g]), color="red", label=f"{g} (surface)")
    for g in volumes:
        el = gm.volumes[g]
        f = mesh.t2f[:, el].ravel()
        u, n = np.unique(f, return_counts=True)
        pl.add_mesh(poly(u[n == 1]), color="red", label=f"{g} (volume)")
    for s in sensors:
        if s.point is not None:
            pl.add_mesh(pv.Sphere(radius=0.01 * float(np.ptp(P, axis=0).max()), center=s.point),
                        color="black")
            pl.add_point_labels(np.array([s.point]), [s.name], font_size=12, point_size=1,
                                shape_opacity=0.6, always_visible=True)
    if surfaces or volumes:
        pl.add_legend(bcolor="white", face="rectangle", loc="lower right")   # clear of the title
    pl.add_axes()
    if title:                      # wrapped: a long verdict ran off both sides
        import textwrap
        pl.add_title(textwrap.fill(title, 64), font_size=10)
    c = 0.5 * (P.min(axis=0) + P.max(axis=0))
    r = float(np.linalg.norm(np.ptp(P, axis=0)))
    pl.camera_position = [tuple(c + r * np.array([1.2, -2.0, -0.6])), tuple(c), (0, 0, 1)]
    pl.screenshot(str(path))
    pl.close()


def _channels_figure(rec, d, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = len(rec.channels)
    fig, axes = plt.subplots(n, 1, figsize=(9, 1.9 * n + 0.6), sharex=True, squeeze=False)
    th = rec.time_s / 3600.0
    ext = d.series["extended"] if d.causes else None
    for j, (ax, c) in enumerate(zip(axes[:, 0], rec.channels)):
        ax.plot(th, rec.data[:, j], ".", ms=1.5, color="0.5", label="measured")
        ax.plot(th, d.series["baseline"][:, j], color="C0", lw=1.0, label="nominal model")
        if ext is not None:
            ax.plot(th, ext[:, j], color="C3", lw=1.0,
                    label="extended" if d.verdict == "established" else
                    "best candidate (not established)")
        ax.axvline(d.holdout.start_s / 3600.0, color="k", ls=":", lw=0.8)
        ax.set_ylabel(f"{c.column}\n[{'µm' if c.unit == 'um' else 'K above ref.'}]",
                      fontsize=8)
    axes[0, 0].legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("time [h]  (dotted: hold-out starts; fits use the data before it)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _compensator_lines(em: dict | None) -> list:
    """The compensators' section: what was written, how each cause enters, and each
    model's replay residual per axis on the hold-out (arfem compensate's replay)."""
    if not em:
        return []
    lines = ["", "## The extended model as a compensator", ""]
    if em["written"]:
        lines.append(f"`{em['file']}` (model_version 2, kind `{em['kind']}`) is the reduced "
                     "model with the established cause(s) built in; `model_nominal.json` is "
                     "the same reduced model without them. Replay either with `arfem "
                     "compensate MODEL.json RECORD.toml --out DIR`.")
        lines += ["", "| cause | enters the model as |", "|---|---|"]
        lines += [f"| {c['cause']} | {c['enters_as']} |" for c in em["causes"]]
    else:
        lines.append(f"No `model_extended.json`: {em['why_not']}.")
    rep = em.get("replay") or {}
    if "not_replayed" in rep:
        lines += ["", f"Not replayed: {rep['not_replayed']}."]
    elif rep:
        lines += ["", "Replayed causally on this record, scored on the hold-out (RMS [µm] "
                  "of what is left on each axis after the offset):", "",
                  "| axis | output | uncompensated | nominal model | extended model |",
                  "|---|---|---|---|---|"]
        for ax, r in rep.items():
            e = r["extended_rms_after_um"]
            lines.append(f"| {ax} | {r['output']} | {r['rms_before_um']:.3g} | "
                         f"{r['nominal_rms_after_um']:.3g} | "
                         f"{'-' if e is None else f'{e:.3g}'} |")
    return lines


def _compensator_gist(em: dict | None) -> list:
    """One sentence for the verdict: the extended model's replay residual against the
    nominal's on the hold-out, per axis, or why there is no extended model."""
    if not em:
        return []
    rep = em.get("replay") or {}
    if em["written"] and rep and "not_replayed" not in rep:
        per = "; ".join(f"{ax} {r['nominal_rms_after_um']:.3g} → "
                        f"{r['extended_rms_after_um']:.3g} µm" for ax, r in rep.items())
        return [f"As a compensator (`{em['file']}`, replayed causally on the hold-out), "
                f"the RMS left after the offset, nominal → extended model: {per}.", ""]
    if not em["written"]:
        return [f"No extended model is written: {em['why_not']}.", ""]
    return []


def _markdown(s: dict, d, sc) -> str:
    # "## Verdict": the HTML page shows this section first, its picture embedded
    lines = [f"# Diagnosis of {s['dataset']} on {Path(sc.source).name}", "", "## Verdict", "",
             f"**Verdict: {s['verdict']}.** {s['verdict_text']}", "",
             ("![the geometry, the named group in red](geometry_named.png)"
              if s["verdict"] == "established" else
              "![the geometry: no cause established, no group highlighted]"
              "(geometry_named.png)"), ""]
    if d.causes:
        lines += ["| cause | parameter | value | 95 % interval |", "|---|---|---|---|"]
        for c in d.causes:
            for k, v in c.parameters.items():
                lo, hi = c.ci95.get(k, (float("nan"), float("nan")))
                lines.append(f"| {c.name} | {k} | {v:.4g} | [{lo:.4g}, {hi:.4g}] |")
        lines.append("")
    lines += _compensator_gist(s.get("extended_model"))
    lines += ["## Hold-out", "",
              f"Hold-out from {d.holdout.start_s / 3600:.2f} h (the fits saw only the data "
              f"before it); weighted gain {d.holdout.gain_pct:.1f} %; on the whitened "
              f"hold-out (each channel's one-step errors under its fitted noise, the gain the "
              f"verdict requires) {d.holdout.gain_whitened_pct:.1f} %.", "",
              "| channel | nominal RMSE | extended RMSE | MLR (eq. 18) RMSE |",
              "|---|---|---|---|"]
    for h in d.holdout.channels:
        ms = "-" if h.mlr_rmse is None else f"{h.mlr_rmse:.3g}"
        lines.append(f"| {h.column} | {h.baseline_rmse:.3g} | {h.extended_rmse:.3g} | {ms} |")
    lines += _compensator_lines(s.get("extended_model"))
    rm = s["reduced_model"]
    lines += ["", "![channels](channels.png)", "",
              f"Reduced model: {rm['basis_vectors']} basis vectors ({rm['krylov_blocks']} Krylov "
              "blocks) from one factorisation; its largest error against the full solve on "
              "this record's nominal inputs: " + ", ".join(
                  f"{n} {v:.2g}" for n, v in rm["max_abs_error"].items())
              + " (µm / K).", "", "## Candidates (best BIC first)", "",
              "| cause | BIC | F-test p | whitened hold-out RMS [-] | alone, not named because |",
              "|---|---|---|---|---|"]
    shown = s["ranking"][:12]
    for r in shown:
        lines.append(f"| {r['cause']} | {r['bic']:.1f} | {r['f_test_p']:.2g} | "
                     f"{r['holdout_whitened_rms']:.3g} | "
                     f"{r.get('not_named_alone_because') or NAMED_BY_SCREEN} |")
    if len(s["ranking"]) > len(shown):
        lines += ["", f"The {len(shown)} best of {len(s['ranking'])} single causes; every one "
                      "is in diagnosis.json (`ranking`)."]
    lines += ["", "Rules: a single cause passes when its F test on the fit window gives "
              "p < 0.01/candidates, its fit is physical and its effect is above the "
              "sensors' practical floor; among the passing causes within ΔBIC 10 of the "
              "best (at most three) the lowest whitened hold-out RMS (each channel's "
              "one-step errors under its fitted noise, 1 for a perfect model) is named. A "
              "second cause is added by the same tests, the pair revisited from both sides "
              "and each of its causes tested against the other alone. A cause is "
              "established when its 95 % interval excludes no effect, reaches no end of "
              "the fitted range and the gain on the whitened hold-out is positive "
              "(arfem.models.geodiagnosis.engine).", ""]
    return "\n".join(lines)


def _cause_words(c) -> str:
    """A named cause (:class:`arfem.models.diagnosis.result.NamedCause`) with its first
    parameter and 95 % interval, for the picture's title (in words: VTK's font draws
    square brackets like parentheses).

    >>> from types import SimpleNamespace as N
    >>> _cause_words(N(name="source_scale:motor", parameters={"scale": 1.5},
    ...                ci95={"scale": (1.4, 1.6)}))
    'source_scale:motor, scale = 1.5 (95 % interval 1.4 to 1.6)'
    """
    if not c.parameters:
        return c.name
    k, v = next(iter(c.parameters.items()))
    lo, hi = c.ci95.get(k, (float("nan"), float("nan")))
    return f"{c.name}, {k} = {v:.4g} (95 % interval {lo:.4g} to {hi:.4g})"


def write_report(stage: Path, s: dict, d, rec, model, plant, sc) -> None:
    """report.md, report.html, geometry_named.png, channels.png and series.csv."""
    # red only for an established cause: a best candidate that failed a check of
    # "established" is not painted as if it were named (the verdict never claims more)
    est = bool(d.established)
    surf, vol = named_groups(d, model) if est else ([], [])
    if est:
        surf += _source_groups(sc, [c.target for c in d.causes if c.cause == "source_scale"])
    title = f"{s['verdict']}: " + (
        " + ".join(_cause_words(c) for c in d.causes) if est
        else "no cause named" + (f" (best candidate {' + '.join(c.name for c in d.causes)}"
                                 ", not established: not highlighted)"
                                 if d.causes else ""))
    highlighted_picture(plant.body.gmesh, stage / "geometry_named.png", surf, vol,
                        [x for x in sc.sensors if x.point is not None], title)
    _channels_figure(rec, d, stage / "channels.png")
    cols = {"time_s": rec.time_s}
    for j, c in enumerate(rec.channels):
        off = sc.reference_C if c.kind == "temperature" else 0.0      # θ back to °C
        cols[f"{c.column}"] = rec.data[:, j] + off
        cols[f"{c.column}_nominal"] = d.series["baseline"][:, j] + off
        if d.causes:
            cols[f"{c.column}_extended"] = d.series["extended"][:, j] + off
    write_csv(stage / "series.csv", cols)
    atomic_write_text(stage / "report.md", _markdown(s, d, sc))
    write_html_report(stage, title=f"Diagnosis of {s['dataset']}")
