"""``arfem compensate MODEL.json --live CONFIG.toml``: the compensator on a live stream.

Transport ``jsonl`` (built): one JSON object per line on standard input is one cycle,

    {"time_s": 1830.0, "speed_rpm": 3000, "T_t1_C": 24.1}

and one JSON object per line on standard output is its answer, flushed at once,

    {"time_s": 1830.0, "offset_um": -4.213, "predicted_growth_um": 4.213,
     "alarms": [], "held": false}

for any bridge that speaks lines (an MTConnect agent adapter, a PLC gateway). Each
cycle runs :meth:`arfem.models.compensator.Compensator.step`, the call ``arfem
compensate``'s replay makes, so replaying the logged inputs gives the same offsets.

Safety, per cycle:

* the offset is clamped to ``max_offset_um`` and its change limited to ``max_step_um``;
* a line that is not JSON, an input missing or not finite, a line whose ``time_s`` is
  not newer than the last one (stale), or one more than ``stale_after_s`` after it (a
  gap: the inputs in between were not seen) holds the last offset and raises an alarm
  (in the answer and in the log);
* every cycle is appended to the log file (time, inputs, offset, alarms) and flushed,
  so the log survives ``kill -9``;
* SIGINT / SIGTERM end the loop after the current cycle with a final log line; so does
  the end of the input.

Transport ``opcua`` (:mod:`arfem.scenarios.opcua_live`, an asyncua client): every
``period_s`` the loop reads the input nodes, runs the same step and writes the offset
(and the alarm) node; a lost connection is retried with backoff while the controller
keeps the last offset. The ``[opcua]`` table of the config names the endpoint and nodes.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
import signal
import sys
import time

from arfem.io import read_toml
from arfem.models.compensator import Compensator
from arfem.params import InputError
from arfem.strict import check_keys

__all__ = ["LiveConfig", "load_config", "run_jsonl", "run_live"]

_KEYS = {"transport", "max_offset_um", "max_step_um", "stale_after_s", "log", "period_s",
         "cycles"}


@dataclass(frozen=True)
class LiveConfig:
    """The validated config of live mode (units in the names; ``log`` is the cycle log's
    path, ``cycles`` = 0 runs until a signal; ``opcua`` the ``[opcua]`` table, for that
    transport)."""

    transport: str
    max_offset_um: float
    max_step_um: float
    stale_after_s: float
    log: str
    period_s: float = 1.0
    cycles: int = 0
    opcua: object = None


def load_config(path, model=None) -> LiveConfig:
    """Read ``CONFIG.toml``; one-line :class:`InputError` naming the file and key.

    Keys of ``[live]``: ``transport`` (``"jsonl"`` or ``"opcua"``), ``max_offset_um`` [µm]
    and ``max_step_um`` [µm] (required: a controller must never be sent an unbounded
    offset), ``stale_after_s`` [s] (default 60), ``log`` (the cycle log's path, relative
    to the config file; default ``compensate.log.jsonl``), ``period_s`` [s] (the OPC UA
    loop's cycle, default 1), ``cycles`` (stop after this many cycles; default 0 = run
    until SIGINT/SIGTERM). The ``opcua`` transport also needs an ``[opcua]`` table
    (:func:`arfem.scenarios.opcua_live.parse_config`), checked against ``model``'s inputs.
    """
    from pathlib import Path
    doc = read_toml(path)
    check_keys(doc, {"live", "opcua"}, str(path))
    live = doc.get("live")
    if not isinstance(live, dict):
        raise InputError("needs a [live] table", str(path))
    check_keys(live, _KEYS, f"{path}: live")
    transport = live.get("transport", "jsonl")
    if transport not in ("jsonl", "opcua"):
        raise InputError(f"must be \"jsonl\" or \"opcua\", got {transport!r}",
                         f"{path}: live.transport")
    vals = {}
    for key, default in (("max_offset_um", None), ("max_step_um", None),
                         ("stale_after_s", 60.0), ("period_s", 1.0)):
        v = live.get(key, default)
        if v is None:
            raise InputError("is required (the bound on what is sent to the controller)",
                             f"{path}: live.{key}")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or v <= 0:
            raise InputError(f"must be a positive number, got {v!r}", f"{path}: live.{key}")
        vals[key] = float(v)
    cycles = live.get("cycles", 0)
    if isinstance(cycles, bool) or not isinstance(cycles, int) or cycles < 0:
        raise InputError(f"must be a whole number >= 0, got {cycles!r}", f"{path}: live.cycles")
    log = live.get("log", "compensate.log.jsonl")
    if not isinstance(log, str) or not log:
        raise InputError(f"must be a file name, got {log!r}", f"{path}: live.log")
    opc = None
    if transport == "opcua":
        from arfem.scenarios.opcua_live import parse_config
        opc = parse_config(doc.get("opcua"), str(path), model)
    elif "opcua" in doc:
        raise InputError("is for transport = \"opcua\"", f"{path}: opcua")
    return LiveConfig(transport, vals["max_offset_um"], vals["max_step_um"],
                      vals["stale_after_s"], str(Path(path).parent / log),
                      vals["period_s"], cycles, opc)


def run_jsonl(model, cfg: LiveConfig, stdin=None, stdout=None) -> int:
    """The JSON-lines loop; returns 0 when the input ends or a signal stops it."""
    stdin = sys.stdin if stdin is None else stdin
    stdout = sys.stdout if stdout is None else stdout
    comp = Compensator(model, max_offset_um=cfg.max_offset_um, max_step_um=cfg.max_step_um)
    stop = {"signal": None, "busy": False}

    def on_signal(signum, frame):
        stop["signal"] = signal.Signals(signum).name
        if not stop["busy"]:                  # waiting for a line: end the wait now
            raise _Stop                       # (inside a cycle: after it, below)

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    names = [i.name for i in model.inputs]
    state = {"last_t": -math.inf}
    n = 0
    try:
        with open(cfg.log, "a", encoding="utf-8", buffering=1) as log:
            log.write(json.dumps({"event": "started", "model": model.kind,
                                  "wall_time": time.time()}) + "\n")
            log.flush()
            try:
                for line in stdin:
                    stop["busy"] = True
                    n += _cycle(line, comp, names, cfg, state, stdout, log)
                    stop["busy"] = False
                    if stop["signal"] or (cfg.cycles and n >= cfg.cycles):
                        break
            except _Stop:
                pass
            log.write(json.dumps({"event": "stopped", "cycles": n,
                                  "reason": stop["signal"] or (
                                      "cycles done" if cfg.cycles and n >= cfg.cycles
                                      else "end of input"),
                                  "last_offset_um": comp.offset_um}) + "\n")
    finally:
        for s_, h in old.items():
            signal.signal(s_, h)
    return 0


class _Stop(Exception):
    """Raised by the SIGINT/SIGTERM handler to leave the loop after a cycle or a wait."""


def _cycle(line, comp, names, cfg, state, stdout, log) -> int:
    """One input line → one answer line and one log line; returns 1."""
    alarms, t, values = [], None, {}
    try:
        doc = json.loads(line)
        if not isinstance(doc, dict):
            raise ValueError
    except ValueError:
        doc = {}
        alarms.append("malformed_line")
    t = doc.get("time_s")
    if not isinstance(t, (int, float)) or isinstance(t, bool) \
            or not math.isfinite(t):
        alarms.append("missing:time_s")
        t = None
    for nm in names:
        v = doc.get(nm)
        values[nm] = v if isinstance(v, (int, float)) and not isinstance(v, bool) \
            else None
    cyc = clocked_step(comp, values, t, state, cfg.stale_after_s, alarms)
    out = {"time_s": t, "offset_um": cyc.offset_um,
           "predicted_growth_um": None if math.isnan(cyc.predicted_growth_um)
           else cyc.predicted_growth_um,
           "alarms": list(cyc.alarms), "held": cyc.held}
    stdout.write(json.dumps(out) + "\n")
    stdout.flush()
    log.write(json.dumps({"time_s": t, "inputs": values, **out}) + "\n")
    log.flush()
    return 1


def clocked_step(comp, values: dict, t, state: dict, stale_after_s: float, alarms: list,
                 clock_only: bool = False):
    """One cycle with the machine's sample time ``t`` [s] (None: not known; one interval
    is assumed, or, with ``clock_only`` -- the machine has a clock and it could not be
    read -- none: the model waits for the clock to say how many passed). A time not newer than the last (``state["last_t"]``) is stale: the
    offset is held and the model does not advance (no interval passed). A time more
    than one Δτ after the last means intervals this loop did not see: the model advances
    through them first (held, with the last inputs), so that it stays on time; more than
    ``stale_after_s`` after it also raises ``gap:time_s``. Used by every transport."""
    last = state.get("last_t", -math.inf)
    names = list(values)
    state["missed"] = 0
    if t is None and clock_only:
        return comp.step(values, alarms, advance=False)
    if t is not None and t <= last:                  # a repeated or out-of-order sample
        return comp.step(values, alarms + [f"stale:{nm}" for nm in names], advance=False)
    if t is not None and last > -math.inf:
        if t - last > stale_after_s:
            alarms = alarms + ["gap:time_s"]         # the inputs in between were not seen
        missed = max(int(round((t - last) / comp.model.dtau_s)) - 1, 0)
        state["missed"] = missed
        for _ in range(missed):
            comp.step({nm: None for nm in names}, alarms=["missed_interval"])
    if t is not None:
        state["last_t"] = t
    return comp.step(values, alarms)


def run_live(args) -> int:
    """``arfem compensate MODEL --live CONFIG``: refuse bad input before any offset."""
    from arfem.scenarios.model_file import read_model
    model = read_model(args.model)
    cfg = load_config(args.live, model)
    if cfg.transport == "opcua":
        from arfem.scenarios.opcua_live import run_opcua
        return run_opcua(model, cfg)
    return run_jsonl(model, cfg)
