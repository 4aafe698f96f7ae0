"""The live compensator's configuration (``arfem compensate MODEL.json --live
CONFIG.toml``): its ``[live]`` table, the transport's (``[opcua]``,
:func:`arfem.scenarios.live.opcua.parse_config`) and what the command line may tighten.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from arfem.io import read_toml
from arfem.models.compensator import Compensator, plausible_ranges
from arfem.params import InputError
from arfem.scenarios.live.cycle import axis_names, reading_names, refuse_unknown_axes
from arfem.scenarios.live.opcua import OpcuaConfig, parse_config
from arfem.strict import boolean, check_keys, number

__all__ = ["LiveConfig", "load_config", "with_command_line"]


_KEYS = {"transport", "max_offset_um", "max_step_um", "stale_after_s", "log", "period_s",
         "cycles", "max_clock_jump_s", "fsync", "status_every", "ranges", "axes"}


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
        opc = parse_config(doc.get("opcua"), str(path), model)
    elif "opcua" in doc:
        raise InputError("is for transport = \"opcua\"", f"{path}: opcua")
    return LiveConfig(transport, vals["max_offset_um"], vals["max_step_um"],
                      vals["stale_after_s"], str(Path(path).parent / log),
                      vals["period_s"], ints["cycles"], opc, vals["max_clock_jump_s"],
                      fsync, ints["status_every"], ranges, axes)


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
