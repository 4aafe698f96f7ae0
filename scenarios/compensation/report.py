"""The files of a replay (``arfem compensate MODEL.json RECORD.toml --out DIR``), one
writer for one axis and several: ``compensated.csv``, ``summary.json``, ``summary.md``
(the verdict first) and ``figure.png`` (in the manner of the seed paper's Fig. 8: per
axis the error without and with compensation, the inputs below); the command adds
``report.html`` from them."""
from __future__ import annotations

import textwrap

from arfem.io import atomic_write_text, write_csv, write_json
from arfem.scenarios.compensation.replay import Replay

__all__ = ["write_replay", "replay_figure", "replay_markdown", "replay_terminal_line",
           "own_output", "reproduced_to_roundoff", "file_link", "OWN_OUTPUT_REL",
           "observer_paragraph"]


def replay_figure(res: Replay, path) -> None:
    """One panel per axis (the record's displacement and what is left with compensation,
    a dashed line where scoring starts), the inputs below (the powers or fluxes, the
    speed, then the temperatures), every legend outside its panel."""
    from matplotlib.figure import Figure
    s, m = res.series, res.summary
    th = s.time_s / 3600.0
    p = len(s.axes)
    temps = [k for k in s.inputs if k.endswith("_C")]
    drives = [k for k in s.inputs if k not in temps]
    panels = [x for x in (drives, temps) if x]
    fig = Figure(figsize=(9.0, 2.2 * p + 1.4 * len(panels) + 1.6), dpi=130,
                 layout="constrained")
    axs = fig.subplots(p + len(panels), 1, sharex=True, squeeze=False,
                       gridspec_kw={"height_ratios": [2.2] * p + [1.4] * len(panels)})[:, 0]
    for ax, a, ser in zip(axs, m.axes, s.axes):
        ax.plot(th, ser.measured_um, color="#0072B2", lw=1.2,
                label=f"without compensation\n(the record's {a.output})")
        ax.plot(th, ser.residual_um, color="#D55E00", lw=1.2,
                label="with compensation\n(record + offset)")
        ax.axhline(0.0, color="0.5", lw=0.8)
        ax.set_ylabel(f"{a.axis} [µm]" if p > 1 else "thermal error [µm]")
        ax.set_title(f"{a.axis} ({a.output}): RMS {a.rms_before_um:.3g} → "
                     f"{a.rms_after_um:.3g} µm", fontsize=9)
    if m.score_from_s > float(s.time_s[0]):
        for a in axs:                      # where scoring starts (the fit window's end)
            a.axvline(m.score_from_s / 3600.0, color="k", ls="--", lw=0.8)
        axs[0].plot([], [], color="k", ls="--", lw=0.8, label="scored from here")
    for ax in axs[:p]:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False)
    if drives:
        _drive_panel(axs[p], th, s.inputs, drives)
    if temps:
        _temperature_panel(axs[-1], th, s.inputs, temps)
    axs[-1].set_xlabel("time [h]")
    own = " (the record is the model's own output)" if own_output(res) else ""
    fig.suptitle(f"{m.dataset}: {m.model_kind}, replayed causally"
                 f"{' per axis' if p > 1 else ''}{own}\n"
                 + textwrap.fill(m.score_window_text(), 95), fontsize=10)
    fig.savefig(path)


def _drive_panel(ax, th, inputs: dict, drives: list) -> None:
    """The powers or fluxes on the left axis and the speed [rpm] on its own right-hand
    axis (thousands of rpm beside tens of W hid the powers); the speed alone on the
    left axis."""
    heat = [k for k in drives if k != "speed_rpm"]
    lines = [ax.plot(th, inputs[nm], lw=1.0, label=nm)[0] for nm in heat]
    if heat:
        ax.set_ylabel("heat flux [W/m²]" if heat == ["q_W_m2"] else "input [W or W/m²]")
    if "speed_rpm" in inputs:
        sx = ax.twinx() if heat else ax
        lines += sx.plot(th, inputs["speed_rpm"], lw=1.0, color="0.35",
                         ls="--" if heat else "-",
                         label="speed_rpm (right)" if heat else "speed_rpm")
        sx.set_ylabel("speed [rpm]")
    ax.legend(handles=lines, loc="upper left", bbox_to_anchor=(1.12 if heat and len(lines)
              > len(heat) else 1.01, 1.0), fontsize=7, frameon=False)


def _temperature_panel(ax, th, inputs: dict, temps: list) -> None:
    """The temperatures [°C] (16 thermometers: no colour used twice)."""
    from matplotlib import colormaps
    if len(temps) > 10:
        ax.set_prop_cycle(color=colormaps["tab20"].colors)
    for nm in temps:
        ax.plot(th, inputs[nm], lw=1.0, label=nm)
    ax.set_ylabel("temperature [°C]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, frameon=False,
              ncol=1 + len(temps) // 9)


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


def own_output(res: Replay) -> bool:
    """:func:`reproduced_to_roundoff` on every axis of a replay."""
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


def _verdict(res: Replay, record_path) -> str:
    m = res.summary
    if own_output(res):
        worst = max(a.rms_after_um for a in m.axes)
        every = " on every axis" if len(m.axes) > 1 else ""
        return (f"**The record is the model's own output.** `{m.model_kind}` reproduces "
                f"{file_link(record_path, m.dataset)} to round-off{every} (residual "
                f"{worst:.1g} µm RMS{' at most' if every else ''}), as when a run's "
                "`record.toml` is replayed with the same run's `model.json`. The figures "
                "below say that the replay is exact, not how well the model compensates a "
                "machine: replay a record measured on the machine to judge that.")
    if len(m.axes) == 1:
        a = m.axes[0]
        rate = a.compensation_rate_rms_pct
        return (f"Compensating with `{m.model_kind}` "
                f"{'reduces' if rate and rate > 0 else 'does not reduce'} the thermal "
                f"error of `{m.dataset}` ({m.score_window_text()}): RMS "
                f"{a.rms_before_um:.3g} → {a.rms_after_um:.3g} µm"
                + (f" ({rate:.0f} %)" if rate is not None else "")
                + f", peak to peak {a.peak_to_peak_before_um:.3g} → "
                f"{a.peak_to_peak_after_um:.3g} µm, replayed strictly causally.")
    good = [a.axis for a in m.axes if (a.compensation_rate_rms_pct or 0) > 0]
    return (f"Compensating with `{m.model_kind}` reduces the thermal error on "
            f"{', '.join(good) or 'no axis'} of {len(m.axes)} ({m.score_window_text()}); "
            "per axis below.")


def _record_notes(m) -> list:
    """What the reader must know of the record to read the figures: how the held and
    out-of-schedule cycles, the displacement's zero and the channels not compensated."""
    notes = []
    if m.cycles_held:
        notes.append(f"The offsets were held in {m.cycles_held} cycles (an input was not "
                     "usable).")
    if m.cycles_outside_schedule:
        notes.append(f"In {m.cycles_outside_schedule} cycles the speed lay beyond the "
                     "model's speed schedule (its end's matrices were used).")
    if m.displacement_zero == "first_row":
        notes.append("The record's probes were zeroed at its first row (`[dataset] "
                     "displacement_zero = \"first_row\"`): each residual is the record + "
                     "the offset minus the offset of the first row, i.e. counted from the "
                     "first row as the record is.")
    if m.not_compensated:
        notes.append("Not compensated (no axis of the model writes them): "
                     + ", ".join(f"`{c}`" for c in m.not_compensated)
                     + (" (a tilt is not an offset of an axis)" if any(
                         c.startswith("tilt_") for c in m.not_compensated) else "") + ".")
    return notes


def replay_markdown(res: Replay, model_path=None, record_path=None) -> str:
    """``summary.md``: the verdict first (saying when the record is the model's own
    output), a table per axis narrow enough for a laptop, then the model and the record
    by name, what the record's zero and its other channels mean, the limits, what was
    held, the probes and the observer."""
    m = res.summary
    n = len(m.axes)
    L = [f"# Compensation replay: `{m.dataset}`" + (f" ({n} axes)" if n > 1 else ""), "",
         "## Verdict", "", _verdict(res, record_path), "",
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
          " ".join([f"Record {file_link(record_path, m.dataset)} (`{m.dataset}`): "
                    f"{m.n_cycles} cycles at Δτ = {m.dtau_s:g} s, replayed strictly "
                    f"causally, one offset per axis; {m.score_window_text()}."]
                   + _record_notes(m)), "",
          "| axis | record column | largest step [µm] | limits [µm] | clamped / "
          "rate-limited cycles |", "|---|---|---|---|---|"]
    for a in m.axes:
        L.append(f"| {a.axis} | `{a.output}` | {_g(a.largest_offset_step_um)} | "
                 f"±{a.max_offset_um or '∞'}, ±{a.max_step_um or '∞'} per cycle | "
                 f"{a.cycles_clamped} / {a.cycles_rate_limited} |")
    if m.probe_every_s is not None or m.model_version == 1:
        L += ["", f"Probes every {m.probe_every_s:g} s: {m.n_probes} Kalman updates, mean "
              f"gain {m.probe_gain_mean:.3g}." if m.n_probes else "No probe updates."]
    L += observer_paragraph(m.observer)
    L += ["", "Files: `compensated.csv` (every cycle, every axis), `summary.json`, "
          "`figure.png`, `report.html`."]
    return "\n".join(L) + "\n"


def observer_paragraph(ob) -> list:
    """summary.md's lines on the thermometers' observer: what it corrected (each
    disturbance's estimate, W or K), or why it did not run; [] without one."""
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


def write_replay(res: Replay, stage, model_path=None, record_path=None) -> None:
    """Write the replay's files into ``stage`` (a staging directory), but report.html;
    ``model_path``, ``record_path``: the files replayed, named in summary.md."""
    write_csv(stage / "compensated.csv", res.series.columns())
    write_json(stage / "summary.json", res.summary.to_dict())
    atomic_write_text(stage / "summary.md", replay_markdown(res, model_path, record_path))
    replay_figure(res, stage / "figure.png")


def replay_terminal_line(res: Replay, out) -> str:
    """``arfem compensate``'s line: the model, the observer, the rows scored and each
    axis's RMS (and a one-axis replay's peak to peak) without → with compensation."""
    m = res.summary
    if len(m.axes) == 1:
        a = m.axes[0]
        parts = [f"RMS {a.rms_before_um:.3g} -> {a.rms_after_um:.3g} µm, peak to peak "
                 f"{a.peak_to_peak_before_um:.3g} -> {a.peak_to_peak_after_um:.3g} µm"]
    else:
        parts = [f"{a.axis} RMS {a.rms_before_um:.3g} -> {a.rms_after_um:.3g} µm"
                 for a in m.axes]
    own = " (the record is the model's own output)" if own_output(res) else ""
    ob = "" if m.observer is None else (", observer on" if m.observer.on else
                                          f", observer off ({m.observer.why})")
    return (f"{m.dataset}: {m.model_kind}{ob}, {m.score_window_text()}: "
            + ", ".join(parts) + f"{own}; wrote {out}")
