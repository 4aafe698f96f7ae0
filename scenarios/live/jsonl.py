"""``arfem compensate MODEL.json --live CONFIG.toml``: the compensator on a live stream.

Transport ``jsonl`` (built): one JSON object per line on standard input is one cycle,

    {"time_s": 1830.0, "speed_rpm": 3000, "T_t1_C": 24.1}

and one JSON object per line on standard output is its answer, flushed at once,

    {"time_s": 1830.0, "offset_um": -4.213, "predicted_growth_um": 4.213,
     "alarms": [], "held": false}

for any bridge that speaks lines (an MTConnect agent adapter, a PLC gateway). A line may
also carry ``controller_offset_um``, the offset the controller holds (read back by the
gateway), taken by the compensator's one rule (:func:`take_held`): inside the clamp the
rate limit counts from it (a value that differs from the last answer is
``external_change``); beyond the clamp or not a finite number the offset is answered
``null`` (not to be written) with ``held_beyond_clamp`` / ``held_nonfinite`` until a
line reports a value inside. The limits are the config's, tightened by the command line
(:func:`with_command_line`). Each cycle runs
:meth:`arfem.models.compensator.Compensator.step`, the call ``arfem compensate``'s replay
makes, so replaying the logged inputs gives the same offsets.

Safety, per cycle (``docs/safety.md`` lists every fault):

* the offset is clamped to ``max_offset_um`` and its change limited to ``max_step_um``,
  counted from what the controller holds;
* **write-ahead log**: a cycle's line (time, inputs, offset, alarms, the model's state)
  is written, flushed and fsync'ed before its offset leaves the process, so the log holds
  every offset the machine may have received;
* **warm start**: the state is restored from the log's last good line (a torn last
  line is ignored; a log of another model is not used), and its offsets are taken by the
  same rule as a line's (a value beyond the clamp there holds that axis); the
  ``started`` line says ``"start": "warm"`` or ``"cold"`` and the limits in use;
* a line that is not a reading (not JSON, nested too deeply, longer than 64 KiB, blank,
  not an object) is held and logged without advancing the model; an input missing, not
  finite or outside its plausible range (:func:`arfem.models.compensator.plausible_ranges`,
  ``[live.ranges]``) holds the offset and is never fed to the state;
* the machine's clock (``time_s``): a repeated time is stale (held, no interval passed);
  intervals not seen are stepped in closed form; a clock that goes backwards
  (``clock_backwards``) or jumps beyond ``max_clock_jump_s`` (``clock_jump``: the state
  is re-initialised) raises an alarm, holds, and re-synchronises on the new time;
* SIGINT / SIGTERM end the loop after the current cycle with a final log line; so does
  the end of the input. A status line goes to standard error every ``status_every``
  cycles and whenever the set of alarms changes.

A version-2 model (several axes, e.g. the X, Y, Z drift of a spindle unit's tool centre
point) answers per axis,

    {"time_s": 1830.0, "axes": {"X": {"offset_um": -1.2, "predicted_um": 1.2,
     "alarms": []}, "Z": {...}}, "alarms": [], "held": false}

each axis with its own clamp and step limit (``[live.axes.<AXIS>]``), counted from what
that axis holds (``controller_offsets_um``: ``{"X": ..., "Z": ...}`` on an input line);
an input fault holds every axis, a clamp or rate limit is that axis's alarm.

Transport ``opcua`` (:mod:`arfem.scenarios.live.opcua`, an asyncua client): every
``period_s`` the loop reads the input nodes, runs the same step and writes the offset
(and the alarm) node; it reads the controller's offset back on start and on every
reconnect, and checks every write.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import signal
import sys
import time
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Mapping

from arfem.io import read_toml
from arfem.models.compensator import INFORMATIVE, Compensator, alarm_kind, plausible_ranges
from arfem.params import InputError
from arfem.strict import boolean, check_keys, number

if TYPE_CHECKING:                                  # (opcua_live imports this module)
    from arfem.scenarios.live.opcua import OpcuaConfig

__all__ = ["LiveConfig", "Clock", "CycleLog", "Status", "load_config", "clocked_step",
           "model_sha", "warm_start", "faults", "line_offsets", "take_held", "offsets_text",
           "offsets_doc", "axes_doc", "axes_text", "limits_doc", "held_text", "answer",
           "with_command_line",
           "run_jsonl", "run_live", "observer_doc", "reading_names"]

_KEYS = {"transport", "max_offset_um", "max_step_um", "stale_after_s", "log", "period_s",
         "cycles", "max_clock_jump_s", "fsync", "status_every", "ranges", "axes"}

#: a JSON line longer than this [characters] is not a reading (held, skipped to its end)
MAX_LINE = 65536

#: how much of the log's end a warm start reads [bytes]
_TAIL = 1 << 20


@dataclass(frozen=True)
class LiveConfig:
    """The validated config of live mode.

    Attributes
    ----------
    transport : str
        ``"jsonl"`` or ``"opcua"``.
    max_offset_um, max_step_um : float
        Clamp on the offset and on its change per cycle [µm].
    stale_after_s : float
        A machine time step longer than this raises ``gap:time_s`` [s].
    log : str
        The cycle log's path.
    period_s : float
        The OPC UA loop's cycle [s].
    cycles : int
        Stop after this many cycles; 0 runs until a signal.
    max_clock_jump_s : float
        A machine clock that jumps forward by more than this is a fault
        (``clock_jump``): hold, alarm, re-initialise the state, re-synchronise [s].
    fsync : bool
        fsync the log after each line (before the offset leaves the process).
    status_every : int
        A status line on standard error every this many cycles (0: only when the
        alarms change).
    ranges : tuple
        ((input name, lo, hi), ...): the plausible range of each input's reading.
    opcua : OpcuaConfig or None
        The ``[opcua]`` table, for that transport.
    axes : tuple
        ((axis, max_offset_um, max_step_um), ...): a version-2 model's limits per axis,
        in the model's order ([live.axes.<AXIS>] over the common ones); () otherwise.
    """

    transport: str
    max_offset_um: float
    max_step_um: float
    stale_after_s: float
    log: str
    period_s: float = 1.0
    cycles: int = 0
    opcua: OpcuaConfig | None = None
    max_clock_jump_s: float = 86400.0
    fsync: bool = True
    status_every: int = 100
    ranges: tuple = ()
    axes: tuple = ()

    def ranges_dict(self) -> dict:
        return {nm: (lo, hi) for nm, lo, hi in self.ranges}

    def compensator(self, model) -> Compensator:
        """The compensator this config runs ``model`` with: its limits (per axis for a
        version-2 model) and plausible ranges."""
        if self.axes:
            return Compensator(model, max_offset_um=tuple(a[1] for a in self.axes),
                               max_step_um=tuple(a[2] for a in self.axes),
                               ranges=self.ranges_dict())
        return Compensator(model, max_offset_um=self.max_offset_um,
                           max_step_um=self.max_step_um, ranges=self.ranges_dict())


def load_config(path, model=None) -> LiveConfig:
    """Read ``CONFIG.toml``; one-line :class:`InputError` naming the file and key.

    Keys of ``[live]``: ``transport`` (``"jsonl"`` or ``"opcua"``), ``max_offset_um`` [µm]
    and ``max_step_um`` [µm] (required: a controller must never be sent an unbounded
    offset), ``stale_after_s`` [s] (default 60), ``log`` (the cycle log's path, relative
    to the config file; default ``compensate.log.jsonl``), ``period_s`` [s] (the OPC UA
    loop's cycle, default 1), ``cycles`` (stop after this many cycles; default 0 = run
    until SIGINT/SIGTERM), ``max_clock_jump_s`` [s] (default 86400), ``fsync`` (default
    true), ``status_every`` (default 100), and a table ``[live.ranges]`` of
    ``input = [lo, hi]`` (plausible ranges; defaults from the model,
    :func:`arfem.models.compensator.plausible_ranges`). The ``opcua`` transport also
    needs an ``[opcua]`` table (:func:`arfem.scenarios.live.opcua.parse_config`),
    checked against ``model``'s inputs. A version-2 model's axes take the common limits
    or their own, ``[live.axes.X] max_offset_um = 20.0, max_step_um = 0.5``.
    """
    from pathlib import Path
    doc = read_toml(path)
    check_keys(doc, {"live", "opcua"}, str(path))
    live = doc.get("live")
    if not isinstance(live, dict):
        raise InputError("needs a [live] table", str(path))
    where = f"{path}: live"
    check_keys(live, _KEYS, where)
    transport = live.get("transport", "jsonl")
    if transport not in ("jsonl", "opcua"):
        raise InputError(f"must be \"jsonl\" or \"opcua\", got {transport!r}",
                         f"{where}.transport")
    vals = {}
    for key, default in (("max_offset_um", None), ("max_step_um", None),
                         ("stale_after_s", 60.0), ("period_s", 1.0),
                         ("max_clock_jump_s", 86400.0)):
        v = live.get(key, default)
        if v is None:
            raise InputError("is required (the bound on what is sent to the controller)",
                             f"{where}.{key}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or v <= 0:
            raise InputError(f"must be a positive number, got {v!r}", f"{where}.{key}")
        vals[key] = float(v)
    ints = {}
    for key, default in (("cycles", 0), ("status_every", 100)):
        v = live.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int) or v < 0:
            raise InputError(f"must be a whole number >= 0, got {v!r}", f"{where}.{key}")
        ints[key] = v
    fsync = boolean(live.get("fsync", True), f"{where}.fsync")
    log = live.get("log", "compensate.log.jsonl")
    if not isinstance(log, str) or not log:
        raise InputError(f"must be a file name, got {log!r}", f"{where}.log")
    ranges = _ranges(live.get("ranges", {}), f"{where}.ranges", model)
    axes = _axes(live.get("axes", {}), f"{where}.axes", model, vals["max_offset_um"],
                 vals["max_step_um"])
    opc = None
    if transport == "opcua":
        from arfem.scenarios.live.opcua import parse_config
        opc = parse_config(doc.get("opcua"), str(path), model)
    elif "opcua" in doc:
        raise InputError("is for transport = \"opcua\"", f"{path}: opcua")
    return LiveConfig(transport, vals["max_offset_um"], vals["max_step_um"],
                      vals["stale_after_s"], str(Path(path).parent / log),
                      vals["period_s"], ints["cycles"], opc, vals["max_clock_jump_s"],
                      fsync, ints["status_every"], ranges, axes)


def refuse_unknown_axes(table: dict, names: list, where: str) -> None:
    """One line for a per-axis table ``[<where>.<AXIS>]`` naming an axis the model lacks
    (shared by ``[live.axes]`` and ``[opcua.axes]``)."""
    for ax in table:
        if ax not in names:
            raise InputError(f"the model has no axis {ax!r} (it has {', '.join(names)})",
                             f"{where}.{ax}")


def _axes(table, where: str, model, max_offset_um: float, max_step_um: float) -> tuple:
    """``[live.axes]``: per axis of a version-2 model its ``max_offset_um`` and
    ``max_step_um`` [µm] (default the common ones): ((axis, offset, step), ...)."""
    if not isinstance(table, dict):
        raise InputError("must be a table of [live.axes.<AXIS>] tables", where)
    names = list(model.axes) if model is not None else list(table)
    if table and not names:
        raise InputError("is for a model with several axes (model_version 2)", where)
    refuse_unknown_axes(table, names, where)
    out = []
    for ax in names:
        t = table.get(ax, {})
        if not isinstance(t, dict):
            raise InputError("must be a table with max_offset_um, max_step_um", f"{where}.{ax}")
        check_keys(t, {"max_offset_um", "max_step_um"}, f"{where}.{ax}")
        vals = []
        for key, default in (("max_offset_um", max_offset_um), ("max_step_um", max_step_um)):
            v = t.get(key, default)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or \
                    not math.isfinite(v) or v <= 0:
                raise InputError(f"must be a positive number, got {v!r}",
                                 f"{where}.{ax}.{key}")
            vals.append(float(v))
        out.append((ax, vals[0], vals[1]))
    return tuple(out)


def _ranges(table, where: str, model) -> tuple:
    """``[live.ranges]`` merged over the model's defaults: ((name, lo, hi), ...)."""
    if not isinstance(table, dict):
        raise InputError("must be a table of input = [lo, hi]", where)
    names = reading_names(model) if model is not None else list(table)
    over = {}
    for nm, v in table.items():
        if nm not in names:
            raise InputError(f"the model does not read this input (it reads "
                             f"{', '.join(names)})", f"{where}.{nm}")
        if not (isinstance(v, list) and len(v) == 2):
            raise InputError(f"must be [lo, hi], got {v!r}", f"{where}.{nm}")
        lo, hi = (number(x, f"{where}.{nm}") for x in v)
        if not lo < hi:
            raise InputError(f"needs lo < hi, got {v!r}", f"{where}.{nm}")
        over[nm] = (lo, hi)
    if model is None:
        return tuple((nm, lo, hi) for nm, (lo, hi) in over.items())
    return tuple((nm, lo, hi) for nm, (lo, hi) in plausible_ranges(model, over).items())


# ---------------------------------------------------------------- the machine's clock

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
        t = float(t) if _num(t) else None
        # an offset the line names but that is not a finite number (null: that axis was
        # not written) is kept as NaN, so that resume_axis holds that axis
        offs = {ax: _held_value(v) for ax, v in line_offsets(comp.model, doc).items()}
        return WarmStart("warm", f"state of the log's line at time_s = {t}", t, offs)
    return WarmStart("cold", "the log's last state is of another model" if other
                     else "no state in the log")


def _num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _held_value(v) -> float:
    """An offset read from a log or a line: the number, or NaN where it is not one."""
    return float(v) if _num(v) else math.nan


def um_or_none(v):
    """A value [µm] for a JSON line: the float, or None where it is not a finite number
    (an axis not written; a controller holding NaN or ±inf)."""
    return float(v) if _num(v) else None


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

def run_jsonl(model, cfg: LiveConfig, stdin=None, stdout=None, status=None) -> int:
    """The JSON-lines loop; returns 0 when the input ends or a signal stops it. No line
    of input ends it otherwise."""
    stdin = sys.stdin if stdin is None else stdin
    stdout = sys.stdout if stdout is None else stdout
    status = status or Status(cfg.status_every)
    comp = cfg.compensator(model)
    stop = {"signal": None, "busy": False}

    def on_signal(signum, frame):
        stop["signal"] = signal.Signals(signum).name
        if not stop["busy"]:                  # waiting for a line: end the wait now
            raise _Stop                       # (inside a cycle: after it, below)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    sha = model_sha(model)
    ws = warm_start(cfg.log, comp, sha)
    # what the gateway may have been sent last: adopted inside the clamp only
    from_log = take_held(comp, ws.offsets_um, "log")
    run = _JsonRun(comp, reading_names(model), cfg, sha, Clock(ws.time_s), stdout, status)
    n = 0
    try:
        run.log = CycleLog(cfg.log, cfg.fsync)
        try:
            run.log.write({"event": "started", "model": sha, "kind": model.kind,
                           "transport": "jsonl", "start": ws.mode, "start_reason": ws.reason,
                           **offsets_doc(comp), **limits_doc(comp),
                           "wall_time": time.time()})
            for e in from_log:
                run.log.write(e)
            status.say(f"live (JSON lines), {ws.mode} start ({ws.reason}); log {cfg.log}")
            try:
                while True:
                    line, oversized = _read_line(stdin)
                    if line == "" and not oversized:
                        break
                    stop["busy"] = True
                    n += run.cycle(line, oversized, n)
                    stop["busy"] = False
                    if stop["signal"] or (cfg.cycles and n >= cfg.cycles):
                        break
            except _Stop:
                pass
            reason = stop["signal"] or ("cycles done" if cfg.cycles and n >= cfg.cycles
                                        else "end of input")
            run.log.write({"event": "stopped", "cycles": n, "reason": reason,
                           **offsets_doc(comp, "last_offset_um"), "wall_time": time.time()})
            status.say(f"stopped after {n} cycles ({reason}); last " + held_text(comp))
        finally:
            run.log.close()
    finally:
        for s_, h in old.items():
            signal.signal(s_, h)
    return 0


def held_text(comp: Compensator) -> str:
    """What each axis holds as far as ``comp`` knows, for a status line."""
    return axes_text(held_offsets(comp), lambda v: f"{v:+.3f}" if math.isfinite(v)
                     else "held (not adopted)", "offset ")


class _Stop(Exception):
    """Raised by the SIGINT/SIGTERM handler to leave the loop after a cycle or a wait."""


def _read_line(stdin) -> tuple[str, bool]:
    """The next line (at most :data:`MAX_LINE` characters kept) and whether it was
    longer (the rest is read and dropped, so memory stays bounded)."""
    line = stdin.readline(MAX_LINE + 1)
    if len(line) <= MAX_LINE or line.endswith("\n"):
        return line, False
    while True:
        rest = stdin.readline(MAX_LINE)
        if rest == "" or rest.endswith("\n"):
            return line[:80], True


def _parse(line: str, oversized: bool) -> tuple[dict | None, str | None]:
    """A line as a reading (a JSON object), or None and why not."""
    if oversized:
        return None, "oversized_line"
    if not line.strip():
        return None, "blank_line"
    try:
        doc = json.loads(line)
    except RecursionError:
        return None, "nested_line"
    except Exception:                               # ValueError, and anything else
        return None, "malformed_line"
    if not isinstance(doc, dict):
        return None, "malformed_line"
    return doc, None


@dataclass
class _JsonRun:
    comp: Compensator
    names: list
    cfg: LiveConfig
    sha: str
    clock: Clock
    stdout: object
    status: Status
    log: CycleLog | None = None

    def cycle(self, line: str, oversized: bool, n: int) -> int:
        """One input line → one log line, then one answer line; returns 1. The log line
        is written (and fsync'ed) first: it is ahead of the offset it names."""
        doc, bad = _parse(line, oversized)
        values = {nm: None for nm in self.names}
        t = None
        if bad is not None:                  # not a reading: hold, do not advance
            cyc = self.comp.step(values, [bad], advance=False)
            cyc = replace(cyc, alarms=(bad,))  # (not also missing:NAME for each input)
        else:
            alarms = []
            t = doc.get("time_s")
            if not _num(t):
                alarms.append("missing:time_s")
                t = None
            for nm in self.names:
                v = doc.get(nm)
                values[nm] = v if isinstance(v, (int, float)) and not isinstance(v, bool) \
                    else None
            # what the controller holds, read back by the gateway: one rule for all
            events = take_held(self.comp, line_offsets(
                self.comp.model, doc, "controller_offset_um", None, "controller_offsets_um"),
                "line", readback=True)
            for e in events:
                self.log.write(e)
            cyc, self.clock = clocked_step(
                self.comp, values, t, self.clock, stale_after_s=self.cfg.stale_after_s,
                max_clock_jump_s=self.cfg.max_clock_jump_s, alarms=alarms)
        out = answer(cyc, t)
        entry = {"time_s": t, "inputs": values, **out, "model": self.sha,
                 "state": self.comp.state()}
        if bad is not None:
            entry["line"] = line[:80]
        if self.clock.missed:
            entry["missed_intervals"] = self.clock.missed
        self.log.write(entry)                # write-ahead: the log first
        self.stdout.write(json.dumps(out) + "\n")
        self.stdout.flush()
        self.status.cycle(n + 1, t, cyc)
        return 1


def with_command_line(cfg: LiveConfig, model, args) -> LiveConfig:
    """``cfg`` with the limits typed on the command line (``--max-offset-um``,
    ``--max-step-um``, ``--axis-limits``, parsed as for a replay) where they are given.

    Precedence: the command line can only TIGHTEN the config. Per axis and per limit a
    value typed is used where it is at most the config's; one larger than the config's
    is refused in one line (exit 2), so that a live run never runs looser than either.
    Axes not named by ``--axis-limits`` take ``--max-offset-um`` / ``--max-step-um``
    where given, else the config's (``[live.axes.<AXIS>]``, else ``[live]``)."""
    from arfem.scenarios.compensation.replay import axis_limits
    items = getattr(args, "axis_limits", None) or []
    off, step = axis_limits(model, items, args.max_offset_um, args.max_step_um)
    cli = list(zip(off, step)) if model.axes else [(off, step)]   # one axis: the common
    lims = list(cfg.axes) or [(ax, cfg.max_offset_um, cfg.max_step_um)
                              for ax in axis_names(model)]
    named = {it.split("=", 1)[0].strip() for it in items}
    out = []
    for (ax, c_off, c_step), typed in zip(lims, cli):
        vals = []
        for key, c, v in (("max_offset_um", c_off, typed[0]),
                          ("max_step_um", c_step, typed[1])):
            if math.isinf(v):                          # not given
                vals.append(c)
                continue
            if v > c:
                opt = "--axis-limits" if ax in named else "--" + key.replace("_", "-")
                raise InputError(
                    f"{v:g} um{f' for axis {ax}' if ax else ''} is looser than the "
                    f"config's {key} = {c:g} ({args.live}); with --live the command line "
                    "can only tighten the config's limits", opt)
            vals.append(v)
        out.append((ax, *vals))
    if not model.axes:
        return replace(cfg, max_offset_um=out[0][1], max_step_um=out[0][2])
    return replace(cfg, axes=tuple(out))


def run_live(args, stdin=None, stdout=None, status=None) -> int:
    """``arfem compensate MODEL --live CONFIG``: refuse bad input before any offset. The
    limits are the config's, tightened by the command line's
    (:func:`with_command_line`)."""
    from arfem.scenarios.compensation.model_file import read_model
    model = read_model(args.model, getattr(args, "limits", None))
    if model.observer is not None and getattr(args, "no_observer", False):
        model = replace(model, observer=None)      # open loop, exactly as without one
    cfg = with_command_line(load_config(args.live, model), model, args)
    if cfg.transport == "opcua":
        lack = [] if model.observer is None else [
            t for t in model.observer.thermometers if t not in dict(cfg.opcua.inputs)]
        if lack:                                # no node for a thermometer: open loop,
            model = replace(model, observer=None)      # exactly as without an observer
            Status(0).say(f"observer off: [opcua.inputs] has no node for {', '.join(lack)}")
        from arfem.scenarios.live.opcua import run_opcua
        return run_opcua(model, cfg)
    return run_jsonl(model, cfg, stdin, stdout, status)
