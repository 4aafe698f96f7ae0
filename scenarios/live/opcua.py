"""The OPC UA transport of ``arfem compensate MODEL.json --live CONFIG.toml``.

An asyncua client. Every ``period_s`` (absolute deadlines, so the period does not drift)
it reads the model's input nodes in one request, runs
:meth:`arfem.models.compensator.Compensator.step` -- the call the replay makes -- and
writes the offset node and the alarm node in one request. The config::

    [live]
    transport = "opcua"
    max_offset_um = 50.0
    max_step_um = 0.5
    period_s = 60.0                         # = the model's Δτ on a machine
    stale_after_s = 180.0
    log = "compensate.log.jsonl"

    [opcua]
    endpoint = "opc.tcp://10.0.0.12:4840"
    offset_node = "ns=2;s=Z.thermal_offset_um"
    alarm_node = "ns=2;s=Z.thermal_alarm"   # optional: Boolean (held), String (names)
                                            # or an integer type (number of alarms)
    time_node = "ns=2;s=Machine.time_s"     # optional: the machine's sample time [s]
    security_mode = "SignAndEncrypt"        # None | Sign | SignAndEncrypt
    security_policy = "Basic256Sha256"      # None | Basic256Sha256 | Aes128_Sha256_RsaOaep
                                            # | Aes256_Sha256_RsaPss
    certificate_env = "ARFEM_OPCUA_CERT"    # names of environment variables holding the
    private_key_env = "ARFEM_OPCUA_KEY"     # client certificate's and key's paths,
    username_env = "ARFEM_OPCUA_USER"       # and the credentials: never in the file
    password_env = "ARFEM_OPCUA_PASSWORD"
    timeout_s = 2.0
    reconnect_initial_s = 1.0               # backoff doubles up to reconnect_max_s
    reconnect_max_s = 60.0

    [opcua.inputs]                          # one node per input the model reads
    speed_rpm = "ns=2;s=Spindle.speed_rpm"

A version-2 model (one output per axis) writes one offset node per axis instead of
``offset_node``/``alarm_node``, each checked as above, read back on start, on every
reconnect and every cycle, and written in the same request as the others::

    [opcua.axes.X]
    offset_node = "ns=2;s=X.thermal_offset_um"
    alarm_node = "ns=2;s=X.thermal_alarm"   # optional, per axis
    [opcua.axes.Z]
    offset_node = "ns=2;s=Z.thermal_offset_um"

Each axis has its own clamp and step limit (``[live.axes.<AXIS>]``); a refused write on
one axis (``write_refused@X:STATUS``) puts that axis's command back to the value it
last accepted and raises that axis's alarm until one of its writes is accepted; the
other axes go on.

Before any offset is written the endpoint is reached, every node is read and the
model's inputs are matched with ``[opcua.inputs]``: a node id that does not exist, an
offset node that this client cannot write, or one whose type is not Double or Float, is
refused in one line naming the key and node (exit 2).

Bumpless: the offset the controller holds is read on start, on every reconnect and in
every cycle (in the cycle's one read request, with the inputs), and taken by
:func:`arfem.scenarios.live.jsonl.take_held` -- the compensator's one rule
(:meth:`arfem.models.compensator.Compensator.resume_axis`): inside the axis's clamp it
is adopted and the rate limit counts from it (the next write is at most
``max_step_um`` from it; a value that differs from the last one written is
``external_change``); beyond the clamp or not a finite number the axis is held
(``held_beyond_clamp`` / ``held_nonfinite``) and its offset node is not written -- its
alarm node is -- until it holds a value inside. A read-back that fails
(``readback_failed:STATUS``) leaves that axis unwritten for the cycle. The state is
warm-started from the cycle log (:func:`arfem.scenarios.live.jsonl.warm_start`); the log's
offsets are not used over OPC UA.

Per cycle: a bad status, a non-finite value or one outside its plausible range holds
the offset (``missing:NAME`` / ``nonfinite:NAME`` / ``out_of_range:NAME``); the machine
clock (``time_node``) is handled by :func:`arfem.scenarios.live.jsonl.clocked_step` (stale,
backwards, jump, missed intervals in closed form). The cycle's log line is written and
fsync'ed before the write request leaves (write-ahead). Every write is checked: a
refused offset write (``write_refused:STATUS``, e.g. a read-only node) puts
the command back to the controller's last accepted value and raises the alarm until a
write is accepted; a failed or timed-out request drops the connection
(``connection_lost``), which is retried with backoff, and on reconnect the controller's
offset is read back. A deadline missed by whole periods without a machine clock is one
``overrun`` cycle that steps the missed intervals in closed form. SIGINT/SIGTERM end the
loop within one period in every state (a pending request is abandoned).
"""
from __future__ import annotations

import asyncio
import logging
import math
import os
import signal
import time
from dataclasses import dataclass, replace

from arfem.params import InputError, one_line
from arfem.scenarios.live.cycle import (Clock, CycleLog, Status, answer, axes_doc, axes_text,
                                        axis_names, clocked_step, faults, limits_doc,
                                        model_sha, offsets_doc, refuse_unknown_axes,
                                        take_held, um_or_none, warm_start)
from arfem.strict import check_keys, number, string

__all__ = ["OpcuaConfig", "parse_config", "run_opcua"]

_KEYS = {"endpoint", "inputs", "offset_node", "alarm_node", "time_node", "axes",
         "security_mode", "security_policy", "certificate_env", "private_key_env",
         "server_certificate_env", "username_env", "password_env", "timeout_s",
         "reconnect_initial_s", "reconnect_max_s"}
_SECRETS = {"password", "username", "user", "certificate", "private_key", "key"}
MODES = ("None", "Sign", "SignAndEncrypt")
POLICIES = ("None", "Basic256Sha256", "Aes128_Sha256_RsaOaep", "Aes256_Sha256_RsaPss")


@dataclass(frozen=True)
class OpcuaConfig:
    """The validated ``[opcua]`` table (node ids as strings; ``*_env`` are the names of
    environment variables, read when connecting)."""

    where: str
    endpoint: str
    inputs: tuple            # ((input name, node id), ...) in the model's order
    offset_node: str
    alarm_node: str | None = None
    time_node: str | None = None
    security_mode: str = "None"
    security_policy: str = "None"
    certificate_env: str | None = None
    private_key_env: str | None = None
    server_certificate_env: str | None = None
    username_env: str | None = None
    password_env: str | None = None
    timeout_s: float = 2.0
    reconnect_initial_s: float = 1.0
    reconnect_max_s: float = 60.0
    axes: tuple = ()         # version 2: ((axis, offset node id, alarm node id or None), ...)


def _ua():
    try:
        from asyncua import ua
    except ImportError:
        raise InputError("needs the asyncua package: pip install 'arfem[opcua]'",
                         "transport opcua") from None
    return ua


def parse_config(table, path: str, model=None) -> OpcuaConfig:
    """Validate the ``[opcua]`` table of ``path`` (and its inputs against ``model``)."""
    ua = _ua()
    where = f"{path}: opcua"
    if not isinstance(table, dict):
        raise InputError("transport = \"opcua\" needs an [opcua] table", path)
    for k in table:
        if k in _SECRETS:
            raise InputError("credentials are never read from the config file; name an "
                             "environment variable with username_env / password_env / "
                             "certificate_env / private_key_env", f"{where}.{k}")
    check_keys(table, _KEYS, where)

    def node(key, required):
        v = table.get(key)
        if v is None:
            if required:
                raise InputError("is required", f"{where}.{key}")
            return None
        v = string(v, f"{where}.{key}")
        try:
            ua.NodeId.from_string(v)
        except Exception:
            raise InputError(f"is not an OPC UA node id (e.g. \"ns=2;s=Z.offset\"): {v!r}",
                             f"{where}.{key}") from None
        return v

    endpoint = string(table.get("endpoint"), f"{where}.endpoint") \
        if "endpoint" in table else None
    if not endpoint or not endpoint.startswith("opc.tcp://"):
        raise InputError(f"must be an opc.tcp:// URL, got {endpoint!r}", f"{where}.endpoint")
    ins = table.get("inputs")
    if not isinstance(ins, dict) or not ins:
        raise InputError("needs an [opcua.inputs] table: input name = node id", where)
    ins = dict(ins)
    names = [i.name for i in model.inputs] if model is not None else list(ins)
    for nm in names:
        if nm not in ins:
            raise InputError(f"has no node for {nm!r}, which the model reads",
                             f"{where}.inputs")
    therm = list(getattr(getattr(model, "observer", None), "thermometers", ()))  # issue 43
    for nm in ins:
        if nm not in names and nm not in therm:
            raise InputError(f"the model does not read this input (it reads "
                             f"{', '.join(names + therm)})", f"{where}.inputs.{nm}")
    inputs = []
    for nm in names + [t for t in therm if t in ins]:
        v = ins[nm]
        if not isinstance(v, str):
            raise InputError(f"must be a node id string, got {v!r}", f"{where}.inputs.{nm}")
        try:
            ua.NodeId.from_string(v)
        except Exception:
            raise InputError(f"is not an OPC UA node id: {v!r}",
                             f"{where}.inputs.{nm}") from None
        inputs.append((nm, v))
    mode = string(table.get("security_mode", "None"), f"{where}.security_mode", MODES)
    policy = string(table.get("security_policy", "None"), f"{where}.security_policy",
                    POLICIES)
    if (mode == "None") != (policy == "None"):
        raise InputError(f"security_mode {mode!r} and security_policy {policy!r} do not go "
                         "together (both \"None\" or neither)", f"{where}.security_mode")
    envs = {}
    for key in ("certificate_env", "private_key_env", "server_certificate_env",
                "username_env", "password_env"):
        v = table.get(key)
        envs[key] = None if v is None else string(v, f"{where}.{key}")
    if mode != "None" and not (envs["certificate_env"] and envs["private_key_env"]):
        raise InputError(f"security_mode {mode!r} needs certificate_env and private_key_env",
                         where)
    if (envs["username_env"] is None) != (envs["password_env"] is None):
        raise InputError("username_env and password_env go together", where)
    nums = {k: number(table.get(k, d), f"{where}.{k}", positive=True)
            for k, d in (("timeout_s", 2.0), ("reconnect_initial_s", 1.0),
                         ("reconnect_max_s", 60.0))}
    axes = _axis_nodes(table, where, model, ua)
    return OpcuaConfig(where, endpoint, tuple(inputs),
                       None if axes else node("offset_node", True),
                       None if axes else node("alarm_node", False), node("time_node", False),
                       mode, policy, **envs, **nums, axes=axes)


def _axis_nodes(table, where: str, model, ua) -> tuple:
    """``[opcua.axes.<AXIS>]`` of a version-2 model: ((axis, offset node, alarm node or
    None), ...) in the model's order; () for a one-output model."""
    names = list(model.axes) if model is not None else list(table.get("axes") or {})
    axes = table.get("axes")
    if not names:
        if axes is not None:
            raise InputError("is for a model with several axes (model_version 2)",
                             f"{where}.axes")
        return ()
    for key in ("offset_node", "alarm_node"):
        if key in table:
            raise InputError("a model with several axes writes one node per axis: "
                             f"[opcua.axes.<AXIS>] {key}", f"{where}.{key}")
    if not isinstance(axes, dict):
        raise InputError(f"needs an [opcua.axes.<AXIS>] table per axis ({', '.join(names)})",
                         f"{where}.axes")
    refuse_unknown_axes(axes, names, f"{where}.axes")
    out = []
    for ax in names:
        key = f"{where}.axes.{ax}"
        t = axes.get(ax)
        if not isinstance(t, dict):
            raise InputError("is missing: every axis of the model needs its offset_node",
                             key)
        check_keys(t, {"offset_node", "alarm_node"}, key)
        ids = []
        for k, required in (("offset_node", True), ("alarm_node", False)):
            v = t.get(k)
            if v is None:
                if required:
                    raise InputError("is required", f"{key}.{k}")
                ids.append(None)
                continue
            v = string(v, f"{key}.{k}")
            try:
                ua.NodeId.from_string(v)
            except Exception:
                raise InputError(f"is not an OPC UA node id: {v!r}", f"{key}.{k}") from None
            ids.append(v)
        out.append((ax, ids[0], ids[1]))
    return tuple(out)


def _env(cfg: OpcuaConfig, key: str) -> str | None:
    name = getattr(cfg, key)
    if name is None:
        return None
    v = os.environ.get(name)
    if not v:
        raise InputError(f"the environment variable {name} is not set", f"{cfg.where}.{key}")
    return v


async def _client(cfg: OpcuaConfig):
    """A connected asyncua client (raises on failure)."""
    from asyncua import Client
    c = Client(cfg.endpoint, timeout=cfg.timeout_s)
    if cfg.username_env:
        c.set_user(_env(cfg, "username_env"))
        c.set_password(_env(cfg, "password_env"))
    if cfg.security_mode != "None":
        parts = [cfg.security_policy, cfg.security_mode, _env(cfg, "certificate_env"),
                 _env(cfg, "private_key_env")]
        if cfg.server_certificate_env:
            parts.append(_env(cfg, "server_certificate_env"))
        await c.set_security_string(",".join(parts))
    await asyncio.wait_for(c.connect(), cfg.timeout_s * 2)
    return c


async def _drop(c) -> None:
    """Close a client whose connection may already be dead, without waiting long."""
    try:
        await asyncio.wait_for(c.disconnect(), 1.0)
    except Exception:
        pass
    try:
        c.disconnect_socket()
    except Exception:
        pass


@dataclass(frozen=True)
class _AxisNodes:
    """One axis's resolved nodes (``axis`` None: a version-1 model's one offset): its
    offset node and variant type, its alarm node and type (None: none), and the value
    that axis of the controller held when resolved (a float, possibly not finite; None
    where it is not a number)."""

    axis: str | None
    offset: object
    offset_type: object
    alarm: object = None
    alarm_type: object = None
    held_um: float | None = None


@dataclass(frozen=True)
class _Nodes:
    """The resolved nodes: input ids (+ the time node last, if any) and one
    :class:`_AxisNodes` per offset written (one for a version-1 model)."""

    ids: list
    axes: tuple = ()


_FLOATS = ("Double", "Float")


def _outputs(cfg: OpcuaConfig) -> list:
    """(axis, (key, offset node), (key, alarm node) or None) of every offset written."""
    if not cfg.axes:
        return [(None, (f"{cfg.where}.offset_node", cfg.offset_node),
                 (f"{cfg.where}.alarm_node", cfg.alarm_node) if cfg.alarm_node else None)]
    return [(ax, (f"{cfg.where}.axes.{ax}.offset_node", off),
             (f"{cfg.where}.axes.{ax}.alarm_node", al) if al else None)
            for ax, off, al in cfg.axes]


async def _resolve(c, cfg: OpcuaConfig) -> _Nodes:
    """Check every node exists, the offset/alarm nodes can be written and every offset
    node is a Double or Float; read the offset the controller holds (per axis). One-line
    :class:`InputError` naming the key and node otherwise."""
    ua = _ua()
    keys = [(f"{cfg.where}.inputs.{nm}", nid) for nm, nid in cfg.inputs]
    if cfg.time_node:
        keys.append((f"{cfg.where}.time_node", cfg.time_node))
    plan = _outputs(cfg)
    outs = [o for _, off, al in plan for o in ((off, al) if al else (off,))]
    ids = [ua.NodeId.from_string(n) for _, n in keys + outs]
    dvs = await c.uaclient.read_attributes(ids, ua.AttributeIds.Value)
    for (key, nid), dv in zip(keys + outs, dvs):
        if dv.StatusCode.value == ua.StatusCodes.BadNodeIdUnknown:
            raise InputError(f"node {nid} does not exist on {cfg.endpoint}", key)
    n_in = len(keys)
    acc = await c.uaclient.read_attributes(ids[n_in:], ua.AttributeIds.UserAccessLevel)
    first = [n_in + i for i, o in enumerate(outs) if any(o is p[1] for p in plan)]
    dtypes = await c.uaclient.read_attributes([ids[i] for i in first], ua.AttributeIds.DataType)
    types = []
    for (key, nid), a, dv in zip(outs, acc, dvs[n_in:]):
        level = a.Value.Value if a.StatusCode.is_good() else 0
        if not level & ua.AccessLevel.CurrentWrite.mask:
            raise InputError(f"node {nid} is not writable by this client", key)
        types.append(dv.Value.VariantType if dv.Value is not None
                     and dv.Value.VariantType != ua.VariantType.Null else None)
    axes, i = [], 0
    for (ax, (okey, onid), al), dtype in zip(plan, dtypes):
        tname = _type_name(ua, dtype, types[i])
        if tname not in _FLOATS:
            raise InputError(f"node {onid} has type {tname}; the offset needs a Double or "
                             "Float node (an integer node would round or refuse every "
                             "offset)", okey)
        dv = dvs[n_in + i]
        v = dv.Value.Value if dv.Value is not None else None
        held = _number_or_none(v)
        alarm, atype = None, None
        if al is not None:
            alarm, atype = ids[n_in + i + 1], types[i + 1] or ua.VariantType.String
        axes.append(_AxisNodes(ax, ids[n_in + i], getattr(ua.VariantType, tname), alarm,
                               atype, held))
        i += 2 if al is not None else 1
    return _Nodes(ids[:n_in], tuple(axes))


def _number_or_none(v) -> float | None:
    """A node's value as a float (finite or not: :func:`take_held` judges it), None
    where it is not a number."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    try:
        return float(v)
    except OverflowError:
        return math.inf


def _type_name(ua, dtype, vtype) -> str:
    """The offset node's type: its DataType attribute where it names a built-in type,
    else the type of the value it holds."""
    if dtype.StatusCode.is_good() and dtype.Value is not None:
        nid = dtype.Value.Value
        if isinstance(nid, ua.NodeId) and nid.NamespaceIndex == 0 \
                and isinstance(nid.Identifier, int):
            try:
                return ua.VariantType(nid.Identifier).name
            except ValueError:
                pass
    return vtype.name if vtype is not None else "unknown"


def _alarm_value(ua, vtype, cyc, axis: str | None = None):
    """The alarm node's value: Boolean -- set while the offset is held or any fault
    lasts; String -- the alarm names; an integer type -- their number. With ``axis``
    (version 2): the alarms that concern that axis (the inputs' and its own)."""
    alarms = cyc.alarms if axis is None else cyc.axis_alarms(axis)
    if vtype == ua.VariantType.Boolean:
        return ua.Variant(bool(cyc.held or faults(cyc, axis)), vtype)
    if vtype == ua.VariantType.String:
        return ua.Variant(",".join(alarms), vtype)
    return ua.Variant(len(alarms), vtype)


def _err(exc) -> str:
    return one_line(f"{type(exc).__name__}: {exc}")


def _with_alarm(cyc, axis, alarm: str):
    """``cyc`` with a transport's ``alarm`` on ``axis`` (None: the one axis of a
    version-1 model, whose alarms are the cycle's)."""
    if axis is None:
        return replace(cyc, alarms=cyc.alarms + (alarm,))
    return cyc.with_axis_alarm(axis, alarm)


#: the status line of each event of :func:`arfem.scenarios.live.jsonl.take_held`
_EVENT_TEXT = {
    "held_beyond_clamp": "the controller holds an offset beyond the clamp; NOT written "
                         "until it holds one inside (set it by hand)",
    "held_nonfinite": "the controller's offset is not a finite number; NOT written until "
                      "it holds one inside the clamp (set it by hand)",
    "held_cleared": "the controller holds an offset inside the clamp again; ramping from it",
    "external_change": "the offset was changed behind the compensator's back; ramping "
                       "from the value it holds now"}


class _Loop:
    """The live cycle over OPC UA; :meth:`run` returns the exit status.

    A version-1 model is one axis (``None``), a version-2 model one per output: every
    per-axis rule below (read back, adopt, write, refuse) is the same code for both."""

    def __init__(self, model, cfg, status=None):
        self.model, self.cfg, self.o = model, cfg, cfg.opcua
        self.comp = cfg.compensator(model)
        self.names = [nm for nm, _ in self.o.inputs]     # inputs, then thermometers
        self.sha = model_sha(model)
        self.status = status or Status(cfg.status_every)
        self.client = None
        self.nodes = None
        self.clock = Clock()
        self.axes = axis_names(model)
        # per axis: what the controller holds, as last read back or accepted
        self.accepted = {ax: None for ax in self.axes}
        self.faults = {ax: None for ax in self.axes}   # a refused write, until one lands
        self.unread = {ax: None for ax in self.axes}   # this cycle's failed read-back
        self.pending = []             # event lines for the log, until it is open
        self.last_total_s = None      # the last cycle: start -> its write answered [s]
        self.backoff = self.o.reconnect_initial_s
        self.next_try = 0.0
        self.stop = None
        self.reason = None
        self.log = None

    def _log(self, obj):
        if self.log is None:
            self.pending.append(obj)
        else:
            self.log.write(obj)

    def _adopt(self, held: dict, source: str, readback: bool = False) -> None:
        """What the controller holds, per axis, through the compensator's one rule
        (:func:`arfem.scenarios.live.jsonl.take_held`); an axis that enters or leaves the hold
        or changed behind the compensator's back is an event line and a status line."""
        self.accepted.update(held)
        for e in take_held(self.comp, held, source, readback):
            self._log(e)
            ax = f"axis {e['axis']}: " if e.get("axis") else ""
            self.status.say(f"{source}: {ax}{_EVENT_TEXT[e['event']]} "
                            f"({e.get('value', e['controller_offset_um'])})")

    def _take_controller(self, source):
        """The controller's offsets, read back on start and on reconnect."""
        self._adopt({a.axis: a.held_um for a in self.nodes.axes}, source)

    async def _lose(self, exc, now):
        self._log({"event": "connection_lost", "wall_time": time.time(),
                   "error": _err(exc), "retry_in_s": self.backoff})
        if self.client is not None:
            await _drop(self.client)
        self.client = None
        self.next_try = now + self.backoff
        self.backoff = min(2 * self.backoff, self.o.reconnect_max_s)

    async def _reconnect(self, now):
        c = None
        try:
            c = await _client(self.o)
            nodes = await asyncio.wait_for(_resolve(c, self.o), self.o.timeout_s * 2)
        except Exception as exc:               # unreachable, or a node gone: wait longer
            if c is not None:
                await _drop(c)
            self._log({"event": "reconnect_failed", "wall_time": time.time(),
                       "error": _err(exc), "retry_in_s": self.backoff})
            self.next_try = now + self.backoff
            self.backoff = min(2 * self.backoff, self.o.reconnect_max_s)
            return
        self.client, self.nodes = c, nodes
        self.backoff = self.o.reconnect_initial_s
        self._take_controller("reconnect")
        self._log({"event": "reconnected", "wall_time": time.time(), **self._held_doc()})
        self.status.say(f"reconnected; the controller holds {self._held_text()}")

    def _held_doc(self) -> dict:
        """What the controller holds as last read or accepted, for a log line."""
        return axes_doc(self.model, self.accepted, "controller_offset_um",
                        "controller_offsets_um")

    def _held_text(self) -> str:
        return axes_text(self.accepted, lambda v: f"{v:+.3f}" if isinstance(v, float)
                         and math.isfinite(v) else repr(v))

    async def _read(self, ua, values, transport):
        """Read the inputs, the time and every axis's offset (the read-back) in ONE
        request; adopt the read-back (:meth:`_adopt`, external changes raised); returns
        the machine time or None."""
        n = len(self.nodes.ids)
        try:
            dvs = await asyncio.wait_for(self.client.uaclient.read_attributes(
                self.nodes.ids + [a.offset for a in self.nodes.axes],
                ua.AttributeIds.Value), self.o.timeout_s)
        except Exception as exc:
            await self._lose(exc, asyncio.get_running_loop().time())
            transport.append("connection_lost")
            return None
        for nm, dv in zip(self.names, dvs):
            if dv.StatusCode.is_good() and dv.Value is not None:
                values[nm] = dv.Value.Value
        self._readback(dvs[n:])
        if not self.o.time_node:
            return None
        dv = dvs[n - 1]
        v = dv.Value.Value if dv.StatusCode.is_good() and dv.Value is not None else None
        if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
            return float(v)
        transport.append("missing:time_s")
        return None

    def _readback(self, dvs) -> None:
        """Each axis's offset as read this cycle: adopted (a change behind the
        compensator's back is ``external_change``); a read that failed
        (``readback_failed:STATUS``) leaves that axis unwritten this cycle."""
        held = {}
        for a, dv in zip(self.nodes.axes, dvs):
            if dv.StatusCode.is_good():
                self.unread[a.axis] = None
                held[a.axis] = _number_or_none(dv.Value.Value if dv.Value is not None
                                               else None)
            else:
                self.unread[a.axis] = f"readback_failed:{dv.StatusCode.name}"
        self._adopt(held, "readback", readback=True)

    async def _send(self, ua, nodes, vals):
        """Write ``vals`` to ``nodes`` in one request: each one's status, or None when the
        request failed, the connection is then treated as lost (whether it landed is
        unknown, so it is read back on reconnect)."""
        try:
            return await asyncio.wait_for(self.client.uaclient.write_attributes(
                nodes, vals, ua.AttributeIds.Value), self.o.timeout_s)
        except Exception as exc:
            await self._lose(exc, asyncio.get_running_loop().time())
            return None

    async def _write(self, ua, k, cyc):
        """Send every axis's offset (and alarm) in one request and check each answer. An
        axis whose offset is not to be written (NaN: the controller holds a value not
        adopted; its read-back failed) sends its alarm only. A refused axis goes back to
        what it last accepted, the others go on."""
        nodes, vals, plan = [], [], []
        for j, an in enumerate(self.nodes.axes):
            off = cyc.per_axis()[j].offset_um
            i = ial = None
            if math.isfinite(off) and self.unread[an.axis] is None:
                i = len(nodes)
                nodes.append(an.offset)
                vals.append(ua.DataValue(ua.Variant(off, an.offset_type)))
            if an.alarm is not None:
                ial = len(nodes)
                nodes.append(an.alarm)
                vals.append(ua.DataValue(_alarm_value(ua, an.alarm_type, cyc, an.axis)))
            plan.append((j, an.axis, off, i, ial))
        res = await self._send(ua, nodes, vals) if nodes else []
        if res is None:
            return
        for j, ax, off, i, ial in plan:
            if i is not None and res[i].is_good():
                self.accepted[ax], self.faults[ax] = off, None
            elif i is not None:
                self.faults[ax] = f"write_refused:{res[i].name}"
                self.comp.resume_axis(j, self.accepted[ax])   # never run away from it
                self._log({"event": "write_refused", "cycle": k,
                           **({"axis": ax} if ax else {}), "status": res[i].name,
                           "offset_um": off,
                           "controller_offset_um": um_or_none(self.accepted[ax]),
                           "wall_time": time.time()})
            if ial is not None and not res[ial].is_good():
                self._log({"event": "alarm_write_refused", "cycle": k,
                           **({"axis": ax} if ax else {}), "status": res[ial].name})

    async def _cycle(self, loop, k, deadline, missed_periods=0):
        ua = _ua()
        start = loop.time()
        transport, values, t = [], {nm: None for nm in self.names}, None
        self.unread = {ax: None for ax in self.axes}
        if self.client is None and start >= self.next_try:
            await self._reconnect(start)
        if self.client is None:
            transport.append("connection_lost")
        else:
            t = await self._read(ua, values, transport)
        values = {nm: (v if isinstance(v, (int, float)) and not isinstance(v, bool) else None)
                  for nm, v in values.items()}
        if missed_periods:                     # no machine clock: the loop's periods count
            transport.append("overrun")
            self.comp.advance_idle(missed_periods)
        cyc, self.clock = clocked_step(
            self.comp, values, t, self.clock, stale_after_s=self.cfg.stale_after_s,
            max_clock_jump_s=self.cfg.max_clock_jump_s, alarms=transport,
            clock_only=bool(self.o.time_node))
        for j, ax in enumerate(self.axes):     # the inputs still feed the state (read)
            if self.unread[ax]:                # not written: it still holds what it held
                self.comp.resume_axis(j, self.accepted[ax])
            for fault in (self.unread[ax], self.faults[ax]):
                if fault:
                    cyc = _with_alarm(cyc, ax, fault)
        send = self.client is not None
        missed = self.clock.missed + missed_periods
        self._log(self._cycle_doc(cyc, k, t, values, transport, send, missed,
                                  start - deadline, loop.time() - start))
        if send:                               # the log line above is ahead of it
            await self._write(ua, k, cyc)
        self.last_total_s = loop.time() - start
        self.status.cycle(k + 1, t, cyc)

    def _cycle_doc(self, cyc, k, t, values, transport, send, missed, late, took) -> dict:
        """A cycle's log line: its offset, or one per axis (version 2)."""
        return {"cycle": k, "time_s": t, "wall_time": time.time(), "lateness_s": late,
                "cycle_s": took, "last_cycle_total_s": self.last_total_s,
                "inputs": values, "transport_alarms": transport, **answer(cyc, t),
                "sent": send, **self._held_doc(), "model": self.sha,
                "state": self.comp.state(),
                **({"missed_intervals": missed} if missed else {})}

    async def _start(self):
        """Connect and resolve (refused in one line), read the controller's offset."""
        try:
            self.client = await _client(self.o)
        except InputError:
            raise
        except Exception as exc:
            raise InputError(f"cannot connect to {self.o.endpoint}: "
                             f"{type(exc).__name__} {exc}".strip(),
                             f"{self.o.where}.endpoint") from None
        try:
            self.nodes = await _resolve(self.client, self.o)
        except BaseException:
            await _drop(self.client)
            raise
        self._take_controller("start")

    async def _guarded(self, coro):
        """Run one cycle unless a signal comes first (then the cycle is abandoned: its
        log line, if written, is ahead of any write that may have left)."""
        task = asyncio.ensure_future(coro)
        stop = asyncio.ensure_future(self.stop.wait())
        await asyncio.wait({task, stop}, return_when=asyncio.FIRST_COMPLETED)
        stop.cancel()
        if not task.done():
            task.cancel()
            try:
                await task
            except BaseException:
                pass
            return False
        task.result()
        return True

    async def run(self) -> int:
        loop = asyncio.get_running_loop()
        self.stop = asyncio.Event()

        def on_signal(sig):
            self.reason = sig.name
            self.stop.set()
        for s in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(s, on_signal, s)
        period, n = self.cfg.period_s, 0
        try:
            await self._start()                # refused before any offset is written
            ws = warm_start(self.cfg.log, self.comp, self.sha)
            self.clock = Clock(ws.time_s)
            log = CycleLog(self.cfg.log, self.cfg.fsync)
            log.write({"event": "started", "model": self.sha, "kind": self.model.kind,
                       "transport": "opcua", "endpoint": self.o.endpoint,
                       "period_s": period, "start": ws.mode, "start_reason": ws.reason,
                       **self._held_doc(), **limits_doc(self.comp),
                       "wall_time": time.time()})
            self.log, pending, self.pending = log, self.pending, []
            for e in pending:                      # the start's read-back, after "started"
                self._log(e)
            self.status.say(f"live (OPC UA {self.o.endpoint}), {ws.mode} start "
                            f"({ws.reason}); the controller holds {self._held_text()}; "
                            f"log {self.cfg.log}")
            t0, k = loop.time(), 0                 # k: deadline index; n: cycles run
            while not self.stop.is_set() and not (self.cfg.cycles and n >= self.cfg.cycles):
                deadline = t0 + k * period
                wait = deadline - loop.time()
                if wait > 0:
                    try:
                        await asyncio.wait_for(self.stop.wait(), wait)
                        break
                    except asyncio.TimeoutError:
                        pass
                behind = int((loop.time() - deadline) // period)
                if behind >= 1:                    # whole periods missed
                    k += behind
                    deadline = t0 + k * period
                missed = behind if behind >= 1 and not self.o.time_node else 0
                if not await self._guarded(self._cycle(loop, n, deadline, missed)):
                    break
                n += 1
                k += 1
            self._log({"event": "stopped", "cycles": n,
                       "reason": self.reason or "cycles done",
                       **offsets_doc(self.comp, "last_offset_um"), **self._held_doc(),
                       "wall_time": time.time()})
            self.status.say(f"stopped after {n} cycles ({self.reason or 'cycles done'}); "
                            f"the controller holds {self._held_text()}")
        finally:
            if self.log is not None:
                self.log.close()
            if self.client is not None:
                await _drop(self.client)
            for s in (signal.SIGINT, signal.SIGTERM):
                loop.remove_signal_handler(s)
        return 0


def run_opcua(model, cfg) -> int:
    """Run the OPC UA loop of ``cfg`` (a :class:`arfem.scenarios.live.jsonl.LiveConfig`)."""
    _ua()
    # asyncua reports lost connections on the logging module (with tracebacks); the
    # cycle log says what happened, in one line per event
    logging.getLogger("asyncua").setLevel(logging.CRITICAL)
    return asyncio.run(_Loop(model, cfg).run())
