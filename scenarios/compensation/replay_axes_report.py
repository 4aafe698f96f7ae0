"""The files of a several-axes replay (``arfem compensate`` on a version-2 model):
``compensated.csv``, ``summary.json``, ``summary.md``, ``figure.png`` (the command adds
``report.html`` from them)."""
from __future__ import annotations

from arfem.io import atomic_write_text, write_csv, write_json
from arfem.scenarios.compensation.replay_axes import AxesReplay

__all__ = ["write_axes_replay", "axes_figure", "axes_markdown", "terminal_line",
           "own_output", "reproduced_to_roundoff", "file_link", "OWN_OUTPUT_REL",
           "observer_paragraph"]


def axes_figure(res: AxesReplay, path) -> None:
    """One panel per axis (the record's displacement and what is left with compensation),
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
                label=f"without compensation\n(the record's {a.output})")
        ax.plot(th, s.residual_um[:, j], color="#D55E00", lw=1.2,
                label="with compensation\n(record + offset)")
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_ylabel(f"{a.axis} [µm]")
        ax.set_title(f"axis {a.axis} ({a.output}): RMS {a.rms_before_um:.3g} → "
                     f"{a.rms_after_um:.3g} µm", fontsize=9)
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    _input_panels(axs[p], axs[p + 1], th, s.inputs)
    axs[-1].set_xlabel("time [h]")
    own = " (the record is the model's own output)" if own_output(res) else ""
    fig.suptitle(f"{m.dataset}: {m.model_kind}, replayed causally per axis{own}",
                 fontsize=10)
    fig.savefig(path)


def _input_panels(ax_drive, ax_temp, th, inputs: dict) -> None:
    """The powers (or fluxes) on the left axis, the speed [rpm] on its own right-hand
    axis (thousands of rpm beside tens of W hid the powers), the temperatures below."""
    drives = [k for k in inputs if not k.endswith("_C") and k != "speed_rpm"]
    temps = [k for k in inputs if k.endswith("_C")]
    lines = [ax_drive.plot(th, inputs[nm], lw=1.0, label=nm)[0] for nm in drives]
    ax_drive.set_ylabel("input [W or W/m²]")
    if "speed_rpm" in inputs:
        ax_speed = ax_drive.twinx()
        lines += ax_speed.plot(th, inputs["speed_rpm"], lw=1.0, color="0.35", ls="--",
                               label="speed_rpm (right)")
        ax_speed.set_ylabel("speed [rpm]")
    for nm in temps:
        ax_temp.plot(th, inputs[nm], lw=1.0, label=nm)
    ax_temp.set_ylabel("[°C]")
    for ax, hs in ((ax_drive, lines), (ax_temp, ax_temp.get_lines())):
        if hs:
            ax.legend(handles=list(hs), loc="upper left", bbox_to_anchor=(1.12, 1.0),
                      fontsize=7, frameon=False)


#: A replay whose residual is below this fraction of the uncompensated RMS on every axis
#: reproduces the record to round-off: the record is the model's own output (a run's
#: record.toml replayed with that run's model.json), not a measurement.
OWN_OUTPUT_REL = 1e-6


def reproduced_to_roundoff(rms_pairs_um) -> bool:
    """True when every ``(RMS without, RMS with compensation)`` pair [µm] with a nonzero
    error left at most :data:`OWN_OUTPUT_REL` of it: the model reproduces the record to
    round-off, i.e. the record is the model's own output, and a "100 %" measures the
    arithmetic, not a machine.

    >>> reproduced_to_roundoff([(14.3, 2e-9), (0.08, 1e-11)]), reproduced_to_roundoff([(14.3, 0.2)])
    (True, False)
    """
    pairs = [(b, a) for b, a in rms_pairs_um if b > 0]
    return bool(pairs) and all(a <= OWN_OUTPUT_REL * b for b, a in pairs)


def own_output(res: AxesReplay) -> bool:
    """:func:`reproduced_to_roundoff` on every axis of a several-axes replay."""
    return reproduced_to_roundoff((a.rms_before_um, a.rms_after_um) for a in res.summary.axes)


def _g(x: float) -> str:
    """A µm figure for a reader: 3 significant digits, round-off shown as "< 1e-6"."""
    return "< 1e-6" if abs(x) < 1e-6 else f"{x:.3g}"


def file_link(path, name: str) -> str:
    """The file ``path`` as the user gave it, linked by its absolute path (report.html
    makes the link relative to itself); ``name`` when no path is known."""
    if not path:
        return f"`{name}`"
    from pathlib import Path
    from urllib.parse import quote
    return f"[`{path}`]({quote(Path(path).resolve().as_posix())})"


def _verdict(res: AxesReplay, model_path, record_path) -> str:
    m = res.summary
    rates = [a.compensation_rate_rms_pct for a in m.axes]
    if own_output(res):
        worst = max(a.rms_after_um for a in m.axes)
        return (f"**The record is the model's own output.** The model reproduces "
                f"{file_link(record_path, m.dataset)} to round-off on every axis (residual "
                f"{worst:.1g} µm RMS at most), as when a run's `record.toml` is replayed "
                "with the same run's `model.json`. The 100 % below says that the replay "
                "is exact, not how well the model compensates a machine: replay a "
                "record measured on the machine to judge that.")
    good = [a.axis for a, r in zip(m.axes, rates) if r is not None and r > 0]
    return (f"Compensating with `{m.model_kind}` reduces the thermal error on "
            f"{', '.join(good) or 'no axis'} of {len(m.axes)} "
            f"({_window(m)}); per axis below.")


def _window(m) -> str:
    span = f"{m.score_from_s / 3600:.2f}–{m.score_to_s / 3600:.2f} h"
    return {"after_fit_window": f"scored on {span}, the part the model was not fitted on",
            "no_fit_window": f"scored on every row, {span}: the model names no fit window",
            "given": f"scored on {span}, from --score-from"}.get(m.score_basis,
                                                                   f"scored on {span}")


def axes_markdown(res: AxesReplay, model_path=None, record_path=None) -> str:
    """``summary.md``: the verdict first (saying when the record is the model's own
    output), a table per axis narrow enough for a laptop, then the model and the record
    by name, the limits and what was held."""
    m = res.summary
    n = len(m.axes)
    L = [f"# Compensation replay: `{m.dataset}` ({n} ax{'is' if n == 1 else 'es'})", "",
         "## Verdict", "", _verdict(res, model_path, record_path), "",
         "| axis | RMS without → with [µm] | rate [%] | peak to peak without → with [µm] |",
         "|---|---|---|---|"]
    for a in m.axes:
        rate = "—" if a.compensation_rate_rms_pct is None else \
            f"{a.compensation_rate_rms_pct:.1f}"
        L.append(f"| {a.axis} | {_g(a.rms_before_um)} → {_g(a.rms_after_um)} | {rate} | "
                 f"{_g(a.peak_to_peak_before_um)} → {_g(a.peak_to_peak_after_um)} |")
    L += ["", "![each axis with and without compensation, inputs below](figure.png)", "",
          "## The replay", "",
          f"Model {file_link(model_path, 'model.json')}: `{m.model_kind}`, "
          f"{m.model_description or 'no description'}.", "",
          f"Record {file_link(record_path, m.dataset)} (`{m.dataset}`): {m.n_cycles} cycles "
          f"at Δτ = {m.dtau_s:g} s, replayed strictly causally, one offset per axis; "
          f"{_window(m)}."
          + (f" The offsets were held in {m.cycles_held} cycles (an input was not usable)."
             if m.cycles_held else "")
          + (f" In {m.cycles_outside_schedule} cycles the speed lay beyond the model's "
             "speed schedule (its end's matrices were used)." if m.cycles_outside_schedule
             else ""), "",
          "| axis | record column | largest step [µm] | limits [µm] | clamped / "
          "rate-limited cycles |", "|---|---|---|---|---|"]
    for a in m.axes:
        L.append(f"| {a.axis} | `{a.output}` | {_g(a.largest_offset_step_um)} | "
                 f"±{a.max_offset_um or '∞'}, ±{a.max_step_um or '∞'} per cycle | "
                 f"{a.cycles_clamped} / {a.cycles_rate_limited} |")
    L += observer_paragraph(m.observer)
    L += ["", "Files: `compensated.csv` (every cycle, every axis), `summary.json`, "
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


def write_axes_replay(res: AxesReplay, stage, model_path=None, record_path=None) -> None:
    """Write the replay's files into ``stage`` (a staging directory), but report.html;
    ``model_path``, ``record_path``: the files replayed, named in summary.md."""
    write_csv(stage / "compensated.csv", res.series.columns())
    write_json(stage / "summary.json", res.summary.to_dict())
    atomic_write_text(stage / "summary.md", axes_markdown(res, model_path, record_path))
    axes_figure(res, stage / "figure.png")


def terminal_line(res: AxesReplay, out) -> str:
    m = res.summary
    parts = [f"{a.axis} RMS {a.rms_before_um:.3g} -> {a.rms_after_um:.3g} µm"
             for a in m.axes]
    own = " (the record is the model's own output)" if own_output(res) else ""
    ob = "" if m.observer is None else (", observer on" if m.observer.on else
                                          f", observer off ({m.observer.why})")
    return f"{m.dataset}: {m.model_kind}{ob}, " + ", ".join(parts) + f"{own}; wrote {out}"
