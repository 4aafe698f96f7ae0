"""The files of a several-axes replay (``arfem compensate`` on a version-2 model):
``compensated.csv``, ``summary.json``, ``summary.md``, ``figure.png`` (the command adds
``report.html`` from them)."""
from __future__ import annotations

from arfem.io import atomic_write_text, write_csv, write_json
from arfem.scenarios.replay_axes import AxesReplay

__all__ = ["write_axes_replay", "axes_figure", "axes_markdown", "terminal_line",
           "observer_paragraph"]


def axes_figure(res: AxesReplay, path) -> None:
    """One panel per axis (measured displacement and what is left with compensation),
    the inputs below (the powers, then the ambient), legends outside the panels."""
    from matplotlib.figure import Figure
    s, m = res.series, res.summary
    th = s.time_s / 3600.0
    p = len(s.axes)
    fig = Figure(figsize=(9.0, 2.2 * p + 3.0), dpi=130, layout="constrained")
    axs = fig.subplots(p + 2, 1, sharex=True, squeeze=False,
                       gridspec_kw={"height_ratios": [2.0] * p + [1.3, 1.0]})[:, 0]
    for j, (ax, a) in enumerate(zip(axs, m.axes)):
        ax.plot(th, s.measured_um[:, j], color="#0072B2", lw=1.2,
                label="without compensation\n(measured)")
        ax.plot(th, s.residual_um[:, j], color="#D55E00", lw=1.2,
                label="with compensation\n(measured + offset)")
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_ylabel(f"{a.axis} [µm]")
        ax.set_title(f"axis {a.axis} ({a.output}): RMS {a.rms_before_um:.3g} → "
                     f"{a.rms_after_um:.3g} µm", fontsize=9)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    _input_panels(axs[p], axs[p + 1], th, s.inputs)
    axs[-1].set_xlabel("time [h]")
    fig.suptitle(f"{m.dataset}: {m.model_kind}, replayed causally per axis", fontsize=10)
    fig.savefig(path)


def _input_panels(ax_drive, ax_temp, th, inputs: dict) -> None:
    """The powers (or fluxes) on the left axis, the speed [1/min] on its own right-hand
    axis (thousands of rpm beside tens of W hid the powers), the temperatures below."""
    drives = [k for k in inputs if not k.endswith("_C") and k != "speed_rpm"]
    temps = [k for k in inputs if k.endswith("_C")]
    lines = [ax_drive.plot(th, inputs[nm], lw=1.0, label=nm)[0] for nm in drives]
    ax_drive.set_ylabel("input [W or W/m²]")
    if "speed_rpm" in inputs:
        ax_speed = ax_drive.twinx()
        lines += ax_speed.plot(th, inputs["speed_rpm"], lw=1.0, color="0.35", ls="--",
                               label="speed_rpm (right)")
        ax_speed.set_ylabel("speed [1/min]")
    for nm in temps:
        ax_temp.plot(th, inputs[nm], lw=1.0, label=nm)
    ax_temp.set_ylabel("[°C]")
    for ax, hs in ((ax_drive, lines), (ax_temp, ax_temp.get_lines())):
        if hs:
            ax.legend(handles=list(hs), loc="upper left", bbox_to_anchor=(1.12, 1.0),
                      fontsize=7, frameon=False)


def axes_markdown(res: AxesReplay) -> str:
    m = res.summary
    L = [f"# Compensation replay: `{m.dataset}` ({len(m.axes)} axes)", "",
         f"Model `{m.model_kind}` replayed strictly causally, one offset per axis, "
         f"{m.n_cycles} cycles at Δτ = {m.dtau_s:g} s; scored on "
         f"{m.score_from_s / 3600:.2f}–{m.score_to_s / 3600:.2f} h ({m.score_basis}). "
         + (f"The offsets were held in {m.cycles_held} cycles (an input was not usable)."
            if m.cycles_held else "")
         + (f" In {m.cycles_outside_schedule} cycles the speed lay beyond the model's "
            "speed schedule (its end's matrices were used)." if m.cycles_outside_schedule
            else ""), "",
         "![each axis with and without compensation, inputs below](figure.png)", "",
         "| axis | output | RMS without [µm] | RMS with [µm] | rate [%] | peak to peak "
         "without → with [µm] | largest step [µm] | limits [µm] | clamped | rate-limited |",
         "|---|---|---|---|---|---|---|---|---|---|"]
    for a in m.axes:
        rate = "—" if a.compensation_rate_rms_pct is None else \
            f"{a.compensation_rate_rms_pct:.1f}"
        L.append(f"| {a.axis} | `{a.output}` | {a.rms_before_um:.4g} | {a.rms_after_um:.4g} "
                 f"| {rate} | {a.peak_to_peak_before_um:.4g} → {a.peak_to_peak_after_um:.4g} "
                 f"| {a.largest_offset_step_um:.4g} | ±{a.max_offset_um or '∞'}, "
                 f"±{a.max_step_um or '∞'}/cycle | {a.cycles_clamped} | "
                 f"{a.cycles_rate_limited} |")
    L += observer_paragraph(m.observer)
    L += ["", f"Model: {m.model_description or m.model_kind}.", "",
          "Files: `compensated.csv` (every cycle, every axis), `summary.json`, "
          "`figure.png`, `report.html`."]
    return "\n".join(L) + "\n"


def observer_paragraph(ob) -> list:
    """summary.md's lines on the thermometers' observer (issue 43): what it corrected
    (each disturbance's estimate, W or K), or why it did not run; [] without one."""
    if ob is None:
        return []
    if not ob.on:
        return ["", f"Observer: not run ({ob.why}); the model ran open loop."]
    est = "; ".join(f"`{d['input']}` {d['final']:+.3g} {d['unit']} at the end (mean "
                    f"{d['mean_scored']:+.3g}, range {d['min_scored']:+.3g} to "
                    f"{d['max_scored']:+.3g} over the scored rows)" for d in ob.disturbances)
    held = (f" A thermometer was held (not used) in {ob.cycles_thermometer_held} cycles."
            if ob.cycles_thermometer_held else "")
    return ["", f"Observer: the thermometers {', '.join(f'`{t}`' for t in ob.thermometers)} "
            f"corrected the model's state every cycle. What it corrected, as disturbances "
            f"added to the model's inputs: {est}.{held} Per cycle: the `estimate_*` and "
            "`innovation_*` columns of `compensated.csv`; `--no-observer` runs open loop."]


def write_axes_replay(res: AxesReplay, stage) -> None:
    """Write the replay's files into ``stage`` (a staging directory), but report.html."""
    write_csv(stage / "compensated.csv", res.series.columns())
    write_json(stage / "summary.json", res.summary.to_dict())
    atomic_write_text(stage / "summary.md", axes_markdown(res))
    axes_figure(res, stage / "figure.png")


def terminal_line(res: AxesReplay, out) -> str:
    m = res.summary
    parts = [f"{a.axis} RMS {a.rms_before_um:.3g} -> {a.rms_after_um:.3g} µm"
             for a in m.axes]
    ob = "" if m.observer is None else (", observer on" if m.observer.on else
                                          f", observer off ({m.observer.why})")
    return f"{m.dataset}: {m.model_kind}{ob}, " + ", ".join(parts) + f"; wrote {out}"
