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

import json
import signal
import sys
import time
from dataclasses import dataclass, replace

from arfem.models.compensator import Compensator
from arfem.scenarios.live.config import LiveConfig, load_config, with_command_line
from arfem.scenarios.live.cycle import (Clock, CycleLog, Status, answer, clocked_step,
                                        finite_number, held_text, limits_doc, line_offsets,
                                        model_sha, offsets_doc, reading_names, take_held,
                                        warm_start)
from arfem.scenarios.live.opcua import run_opcua

__all__ = ["run_jsonl", "run_live", "MAX_LINE", "Clock", "Status", "clocked_step", "load_config",
           "LiveConfig"]


#: a JSON line longer than this [characters] is not a reading (held, skipped to its end)
MAX_LINE = 65536



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
            if not finite_number(t):
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
        return run_opcua(model, cfg)
    return run_jsonl(model, cfg, stdin, stdout, status)
