"""What every transport of the live compensator shares, cycle by cycle: the machine's
clock (a reading is new, stale or a jump), the cycle log and its warm start, what the
controller holds (taken only inside each axis's clamp), the answer and the status line.
JSON lines (:mod:`arfem.scenarios.live.jsonl`) and OPC UA (:mod:`arfem.scenarios.live.opcua`)
both run on it.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import time
from dataclasses import dataclass, field, replace
from typing import Mapping

from arfem.models.compensator import INFORMATIVE, Compensator, alarm_kind
from arfem.params import InputError
from arfem.strict import is_json_number

__all__ = ["refuse_unknown_axes", "Clock", "clocked_step", "model_sha", "CycleLog",
           "WarmStart", "warm_start", "um_or_none", "axis_names", "take_held", "faults",
           "line_offsets", "axes_doc", "axes_text", "offsets_text", "held_offsets",
           "offsets_doc", "limits_doc", "answer", "observer_doc", "reading_names",
           "Status", "held_text", "finite_number"]


#: how much of the log's end a warm start reads [bytes]
_TAIL = 1 << 20


def refuse_unknown_axes(table: dict, names: list, where: str) -> None:
    """One line for a per-axis table ``[<where>.<AXIS>]`` naming an axis the model lacks
    (shared by ``[live.axes]`` and ``[opcua.axes]``)."""
    for ax in table:
        if ax not in names:
            raise InputError(f"the model has no axis {ax!r} (it has {', '.join(names)})",
                             f"{where}.{ax}")


@dataclass(frozen=True)
class Clock:
    """What the loop knows of the machine's clock.

    Attributes
    ----------
    last_t : float or None
        Machine time [s] of the last reading the state was synchronised to (None:
        none yet).
    missed : int
        Intervals the last cycle advanced through unseen (closed form).
    """

    last_t: float | None = None
    missed: int = 0


def clocked_step(comp: Compensator, values: Mapping, t: float | None, clock: Clock, *,
                 stale_after_s: float, max_clock_jump_s: float = math.inf,
                 alarms=(), clock_only: bool = False):
    """One cycle at the machine's sample time ``t`` [s]; returns ``(Cycle, Clock)``.

    Used by every transport. ``t`` None: not known -- one interval is assumed, or, with
    ``clock_only`` (the machine has a clock and it could not be read), none: the state
    waits for the clock. Otherwise, against the last time:

    * equal: stale (``stale:NAME``), held, no interval passed;
    * earlier (a controller reboot, a clock set back): ``clock_backwards``, held, and
      the clock re-synchronised on ``t`` (the state is kept);
    * later by more than ``max_clock_jump_s``: ``clock_jump``, held, the state
      re-initialised (what happened meanwhile is unknown) and the clock re-synchronised;
    * later by k > 1 intervals: the k − 1 unseen ones are stepped with the last inputs
      in closed form (:meth:`Compensator.advance_idle`, O(log k)); more than
      ``stale_after_s`` also raises ``gap:time_s``.
    """
    alarms = list(alarms)
    if t is None:
        return comp.step(values, alarms, advance=not clock_only), replace(clock, missed=0)
    last = clock.last_t
    if last is None:
        return comp.step(values, alarms), Clock(t, 0)
    dt = t - last
    if dt == 0:                                     # a repeated sample
        return comp.step(values, alarms + [f"stale:{nm}" for nm in values],
                         advance=False), Clock(last, 0)
    if dt < 0:
        return comp.step(values, alarms + ["clock_backwards"], advance=False), Clock(t, 0)
    if dt > max_clock_jump_s:
        comp.reinitialise()
        return comp.step(values, alarms + ["clock_jump"], advance=False), Clock(t, 0)
    if dt > stale_after_s:
        alarms.append("gap:time_s")                 # the inputs in between were not seen
    missed = max(int(round(dt / comp.model.dtau_s)) - 1, 0)
    comp.advance_idle(missed)
    return comp.step(values, alarms), Clock(t, missed)


# ------------------------------------------------------------------- the cycle log

def model_sha(model) -> str:
    """12 hex digits naming the model's numbers (a warm start needs the same model)."""
    from arfem.scenarios.compensation.model_file import model_to_doc
    d = model_to_doc(model)
    d.pop("arfem_version", None)
    d.pop("description", None)
    return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]


class CycleLog:
    """The append-only cycle log: one JSON object a line, flushed (and fsync'ed) per
    line, so that it is ahead of anything the process sends. A torn last line (kill -9
    in the middle of a write) is closed by a newline before anything is appended."""

    def __init__(self, path: str, fsync: bool = True):
        self.path, self.fsync = path, fsync
        try:
            self.f = open(path, "a+b")
        except OSError as exc:
            raise InputError(f"cannot write the cycle log: {exc.strerror or exc}",
                             str(path)) from None
        self.f.seek(0, os.SEEK_END)
        if self.f.tell() > 0:
            self.f.seek(-1, os.SEEK_END)
            if self.f.read(1) != b"\n":
                self.f.write(b"\n")

    def write(self, obj: dict) -> None:
        self.f.write((json.dumps(obj) + "\n").encode())
        self.f.flush()
        if self.fsync:
            os.fsync(self.f.fileno())

    def close(self) -> None:
        self.f.close()


@dataclass(frozen=True)
class WarmStart:
    """What the log gave a starting loop: ``mode`` "warm" or "cold", ``reason``,
    and from the last good line its machine time [s] and what each axis was sent
    (``offsets_um``: axis → offset [µm], the key None for a version-1 model's one axis,
    as :func:`take_held` takes it; {} if none)."""

    mode: str
    reason: str
    time_s: float | None = None
    offsets_um: dict = field(default_factory=dict)


def warm_start(path: str, comp: Compensator, sha: str) -> WarmStart:
    """Restore ``comp``'s state from the last line of the log at ``path`` that holds one
    for this model (:func:`model_sha`); torn or unreadable lines are skipped. Reads at
    most the last MiB."""
    try:
        with open(path, "rb") as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            f.seek(max(0, size - _TAIL))
            tail = f.read()
    except FileNotFoundError:
        return WarmStart("cold", "no log yet")
    except OSError as exc:
        return WarmStart("cold", f"log unreadable: {exc.strerror or exc}")
    other = False
    for raw in reversed(tail.split(b"\n")):
        try:
            doc = json.loads(raw)
        except Exception:                           # torn, or cut by the tail window
            continue
        if not isinstance(doc, dict) or not isinstance(doc.get("state"), dict):
            continue
        if doc.get("model") != sha:
            other = True
            break
        try:
            comp.restore(doc["state"])
        except (KeyError, TypeError, ValueError):
            continue
        t = doc.get("time_s")
        t = float(t) if finite_number(t) else None
        # an offset the line names but that is not a finite number (null: that axis was
        # not written) is kept as NaN, so that resume_axis holds that axis
        offs = {ax: _held_value(v) for ax, v in line_offsets(comp.model, doc).items()}
        return WarmStart("warm", f"state of the log's line at time_s = {t}", t, offs)
    return WarmStart("cold", "the log's last state is of another model" if other
                     else "no state in the log")


def finite_number(v) -> bool:
    """A finite JSON number (int or float, not a bool): a reading or an offset a line
    may carry."""
    return is_json_number(v) and math.isfinite(v)


def _held_value(v) -> float:
    """An offset read from a log or a line: the number, or NaN where it is not one."""
    return float(v) if finite_number(v) else math.nan


def um_or_none(v):
    """A value [µm] for a JSON line: the float, or None where it is not a finite number
    (an axis not written; a controller holding NaN or ±inf)."""
    return float(v) if finite_number(v) else None


def axis_names(model) -> tuple:
    """The axes a compensator writes: a version-2 model's, or ``(None,)`` for the one
    axis of a version-1 model."""
    return model.axes or (None,)


def take_held(comp: Compensator, held: Mapping, source: str,
              readback: bool = False) -> list:
    """Give ``comp`` what the controller holds, per axis (``held``: axis → value, the
    key None for a version-1 model; axes it lacks are left as they are), through the one
    rule :meth:`Compensator.resume_axis` (adopted inside the clamp; beyond it or not a
    finite number the axis is held, ``held_beyond_clamp`` / ``held_nonfinite``; with
    ``readback``, a value that differs from what was last set is ``external_change``).
    Used by every transport. Returns the log's event lines: an axis entering or leaving
    the hold, and an external change, each with ``source`` (``start``, ``reconnect``,
    ``readback``, ``line``, ``log``) and the value."""
    events = []
    for j, ax in enumerate(axis_names(comp.model)):
        if ax not in held:
            continue
        v, before = held[ax], comp.held_reason(j)
        kind = comp.resume_axis(j, v, readback=readback)
        if kind == before:
            continue
        kind = kind or "held_cleared"
        doc = {"event": kind, **({"axis": ax} if ax else {}), "source": source,
               "controller_offset_um": um_or_none(v), "wall_time": time.time()}
        if um_or_none(v) is None:
            doc["value"] = repr(v)[:40]
        events.append(doc)
    return events


def faults(cyc, axis: str | None = None) -> list:
    """The alarms of a cycle that are faults (not the informative ``clamped``,
    ``rate_limited``, ``extrapolated``, also when tagged with an axis: ``clamped@X``);
    with ``axis``, those that concern that axis (:meth:`Cycle.axis_alarms`)."""
    alarms = cyc.alarms if axis is None else cyc.axis_alarms(axis)
    return sorted({a for a in alarms if alarm_kind(a) not in INFORMATIVE})


def line_offsets(model, doc: Mapping, one: str = "offset_um", key: str | None = "offset_um",
                 several: str = "axes") -> dict:
    """What a line (a log line, an input line) says of each axis's offset, as
    :func:`take_held` takes it: axis → raw value, the key None for a version-1 model's
    one axis (its key ``one``); per axis of a version-2 model ``doc[several]``, a mapping
    axis → {``key``: value} (``key`` None: axis → value). Axes the line lacks, or the
    model does not have, are left out (left as they are).

    >>> from types import SimpleNamespace as N
    >>> line_offsets(N(axes=()), {"controller_offset_um": 2.0}, "controller_offset_um")
    {None: 2.0}
    >>> line_offsets(N(axes=("X",)), {"axes": {"X": {"offset_um": 1.5}, "W": {}}})
    {'X': 1.5}
    """
    if not model.axes:
        return {None: doc[one]} if one in doc else {}
    per = doc.get(several)
    if not isinstance(per, Mapping):
        return {}
    return {ax: (v if key is None else v.get(key)) for ax, v in per.items()
            if ax in model.axes and (key is None or isinstance(v, Mapping))}


def axes_doc(model, values: Mapping, one: str, several: str) -> dict:
    """Per-axis values [µm] (axis → value, the key None for a version-1 model's one axis)
    for a line: ``{one: value}`` for a version-1 model, ``{several: {axis: value}}`` for
    a version-2 one; null where a value is not a finite number. The inverse of
    :func:`line_offsets`."""
    if not model.axes:
        return {one: um_or_none(values[None])}
    return {several: {ax: um_or_none(v) for ax, v in values.items()}}


def axes_text(values: Mapping, um, one: str = "", several: str = "") -> str:
    """Per-axis values (as :func:`axes_doc` takes them) for a status line, each through
    ``um``; ``one`` / ``several`` open the text of one axis / of several."""
    if None in values:
        return f"{one}{um(values[None])} um"
    return several + ", ".join(f"{ax} {um(v)}" for ax, v in values.items()) + " um"


def _um_or_not_written(v) -> str:
    return f"{v:+.3f}" if math.isfinite(v) else "not written"


def offsets_text(cyc) -> str:
    """The offset(s) of a cycle for a status line."""
    return axes_text({a.axis if cyc.axes else None: a.offset_um for a in cyc.per_axis()},
                     _um_or_not_written, "offset ", "offsets ")


def held_offsets(comp: Compensator) -> dict:
    """What each axis holds as far as ``comp`` knows (axis → offset [µm], the key None
    for a version-1 model's one axis)."""
    return dict(zip(axis_names(comp.model), (float(v) for v in comp.offsets_um)))


def offsets_doc(comp: Compensator, key: str = "offset_um") -> dict:
    """What each axis holds as far as ``comp`` knows, for a ``started`` or ``stopped``
    line: ``{key: value}`` for a version-1 model, ``{"offsets_um": {axis: value}}`` per
    axis for a version-2 one (null for an axis held beyond its clamp)."""
    return axes_doc(comp.model, held_offsets(comp), key, "offsets_um")


def limits_doc(comp: Compensator) -> dict:
    """The limits each axis runs with, for the ``started`` line."""
    return {"limits_um": {ax or "offset": {"max_offset_um": lim, "max_step_um": step}
                          for j, ax in enumerate(axis_names(comp.model))
                          for lim, step in [comp.limits(j)]}}


def answer(cyc, t) -> dict:
    """A cycle's answer line (and the log's copy): one offset, or one per axis; an
    offset not to be written (the controller holds a value beyond the clamp or not a
    number) is null, with ``held`` true."""
    if not cyc.axes:
        return {"time_s": t, "offset_um": um_or_none(cyc.offset_um),
                "predicted_growth_um": um_or_none(cyc.predicted_growth_um),
                "alarms": list(cyc.alarms), "held": cyc.held}
    return {"time_s": t,
            "axes": {a.axis: {"offset_um": um_or_none(a.offset_um),
                              "predicted_um": um_or_none(a.predicted_um),
                              "alarms": list(a.alarms), "held": a.held}
                     for a in cyc.axes},
            "alarms": list(cyc.alarms), "held": cyc.held,
            **({"observer": observer_doc(cyc.observer)} if cyc.observer is not None
               else {})}


def observer_doc(corr) -> dict:
    """What the thermometers' observer corrected in a cycle (issue 43), for the answer
    and the log: each disturbance's estimate ``{input: value}`` in its unit (W for a
    source's power, K for the ambient), the units, each thermometer's innovation
    (measured − predicted [K], None where held) and the thermometers held."""
    return {"disturbances": corr.estimates(),
            "units": {name: unit for name, unit, _ in corr.disturbances},
            "innovations_K": {t: None if math.isnan(v) else v
                              for t, v in corr.innovations_K},
            "held": list(corr.held)}


def reading_names(model) -> list:
    """What a transport reads each cycle: the model's inputs, then its observer's
    thermometers (issue 43) where it has one."""
    return [i.name for i in model.inputs] + list(
        model.observer.thermometers if model.observer is not None else ())


class Status:
    """The terminal status of a live loop (standard error): a line every ``every``
    cycles, and whenever the set of faults changes (raised or cleared)."""

    def __init__(self, every: int, stream=None):
        self.every, self.stream, self.last = every, stream, None

    def say(self, text: str) -> None:
        print(f"arfem compensate: {text}", file=self.stream or sys.stderr, flush=True)

    def cycle(self, n: int, t, cyc) -> None:
        f = faults(cyc)
        if f != self.last or (self.every and n % self.every == 0):
            when = f"t = {t:g} s, " if isinstance(t, (int, float)) else ""
            self.say(f"cycle {n}, {when}{offsets_text(cyc)}, "
                     + (f"ALARM {', '.join(f)}" if f else "no alarm"))
        self.last = f


# ------------------------------------------------------------------ JSON lines

def held_text(comp: Compensator) -> str:
    """What each axis holds as far as ``comp`` knows, for a status line."""
    return axes_text(held_offsets(comp), lambda v: f"{v:+.3f}" if math.isfinite(v)
                     else "held (not adopted)", "offset ")
