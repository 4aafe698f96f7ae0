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

Before any offset is written the endpoint is reached, every node is read (a node id
that does not exist, or an offset node that cannot be written, is refused in one line
naming the key and node) and the model's inputs are matched with ``[opcua.inputs]``.

Per cycle: a bad status or a non-finite value holds the offset (``missing:NAME`` /
``nonfinite:NAME``); with ``time_node``, a time that does not advance holds it
(``stale:NAME``) and one more than ``stale_after_s`` after the last one raises
``gap:time_s``; a failed request drops the connection (``connection_lost``, offset
held by the controller), which is retried with backoff; a deadline missed by a whole
period counts a cycle of its own (``overrun``: the model's state advances with the
last inputs, so that it stays on time) -- unless ``time_node`` is given: then the
machine's clock counts the intervals, a late cycle simply runs late, and intervals the
loop did not see (the time advanced by more than one Δτ) advance the state, held
(``missed_intervals`` in the log); while it cannot be read (a lost connection) the
state waits for it. Every cycle is one flushed line of the log.
"""
from __future__ import annotations

import asyncio
import json
import logging
import math
import os
import signal
import time
from dataclasses import dataclass

from arfem.models.compensator import Compensator
from arfem.params import InputError, one_line
from arfem.scenarios.live import clocked_step
from arfem.strict import check_keys, number, string

__all__ = ["OpcuaConfig", "parse_config", "run_opcua"]

_KEYS = {"endpoint", "inputs", "offset_node", "alarm_node", "time_node", "security_mode",
         "security_policy", "certificate_env", "private_key_env", "server_certificate_env",
         "username_env", "password_env", "timeout_s", "reconnect_initial_s",
         "reconnect_max_s"}
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
    for nm in ins:
        if nm not in names:
            raise InputError(f"the model does not read this input (it reads "
                             f"{', '.join(names)})", f"{where}.inputs.{nm}")
    inputs = []
    for nm in names:
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
    return OpcuaConfig(where, endpoint, tuple(inputs), node("offset_node", True),
                       node("alarm_node", False), node("time_node", False), mode, policy,
                       **envs, **nums)


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


@dataclass
class _Nodes:
    ids: list            # input node ids (+ the time node last, if any)
    offset: object
    offset_type: object
    alarm: object = None
    alarm_type: object = None


async def _resolve(c, cfg: OpcuaConfig) -> _Nodes:
    """Check every node exists (and the offset/alarm nodes can be written); one-line
    :class:`InputError` naming the key and node otherwise."""
    ua = _ua()
    keys = [(f"{cfg.where}.inputs.{nm}", nid) for nm, nid in cfg.inputs]
    if cfg.time_node:
        keys.append((f"{cfg.where}.time_node", cfg.time_node))
    outs = [(f"{cfg.where}.offset_node", cfg.offset_node)]
    if cfg.alarm_node:
        outs.append((f"{cfg.where}.alarm_node", cfg.alarm_node))
    ids = [ua.NodeId.from_string(n) for _, n in keys + outs]
    dvs = await c.uaclient.read_attributes(ids, ua.AttributeIds.Value)
    for (key, nid), dv in zip(keys + outs, dvs):
        if dv.StatusCode.value == ua.StatusCodes.BadNodeIdUnknown:
            raise InputError(f"node {nid} does not exist on {cfg.endpoint}", key)
    acc = await c.uaclient.read_attributes(ids[len(keys):], ua.AttributeIds.UserAccessLevel)
    types = []
    for (key, nid), a, dv in zip(outs, acc, dvs[len(keys):]):
        level = a.Value.Value if a.StatusCode.is_good() else 0
        if not level & ua.AccessLevel.CurrentWrite.mask:
            raise InputError(f"node {nid} is not writable by this client", key)
        types.append(dv.Value.VariantType if dv.Value is not None else ua.VariantType.Double)
    n = _Nodes(ids[:len(keys)], ids[len(keys)], types[0])
    if cfg.alarm_node:
        n.alarm, n.alarm_type = ids[len(keys) + 1], types[1]
    return n


def _alarm_value(ua, vtype, cyc):
    if vtype == ua.VariantType.Boolean:
        return ua.Variant(bool(cyc.held), vtype)
    if vtype == ua.VariantType.String:
        return ua.Variant(",".join(cyc.alarms), vtype)
    return ua.Variant(len(cyc.alarms), vtype)


class _Loop:
    """The live cycle over OPC UA; :meth:`run` returns the exit status."""

    def __init__(self, model, cfg):
        self.model, self.cfg, self.o = model, cfg, cfg.opcua
        self.comp = Compensator(model, max_offset_um=cfg.max_offset_um,
                                max_step_um=cfg.max_step_um)
        self.names = [i.name for i in model.inputs]
        self.client = None
        self.nodes = None
        self.last_t = -math.inf
        self.backoff = self.o.reconnect_initial_s
        self.next_try = 0.0
        self.stop = None
        self.reason = None

    def _log(self, obj):
        self.log.write(json.dumps(obj) + "\n")
        self.log.flush()

    async def _lose(self, exc, now):
        self._log({"event": "connection_lost", "wall_time": time.time(),
                   "error": one_line(f"{type(exc).__name__}: {exc}"),
                   "retry_in_s": self.backoff})
        if self.client is not None:
            await _drop(self.client)
        self.client = None
        self.next_try = now + self.backoff
        self.backoff = min(2 * self.backoff, self.o.reconnect_max_s)

    async def _reconnect(self, now):
        try:
            c = await _client(self.o)
            self.nodes = await _resolve(c, self.o)
        except InputError:
            raise
        except Exception as exc:               # still unreachable: wait longer
            self._log({"event": "reconnect_failed", "wall_time": time.time(),
                       "error": one_line(f"{type(exc).__name__}: {exc}"),
                       "retry_in_s": self.backoff})
            self.next_try = now + self.backoff
            self.backoff = min(2 * self.backoff, self.o.reconnect_max_s)
            return
        self.client = c
        self.backoff = self.o.reconnect_initial_s
        self._log({"event": "reconnected", "wall_time": time.time()})

    async def _cycle(self, loop, k, deadline, overrun=False):
        ua = _ua()
        start = loop.time()
        transport, values, t = [], {nm: None for nm in self.names}, None
        if overrun:
            transport.append("overrun")
        else:
            if self.client is None and start >= self.next_try:
                await self._reconnect(start)
            if self.client is None:
                transport.append("connection_lost")
            else:
                try:
                    dvs = await asyncio.wait_for(self.client.uaclient.read_attributes(
                        self.nodes.ids, ua.AttributeIds.Value), self.o.timeout_s)
                except Exception as exc:
                    await self._lose(exc, loop.time())
                    transport.append("connection_lost")
                else:
                    for nm, dv in zip(self.names, dvs):
                        if dv.StatusCode.is_good() and dv.Value is not None:
                            values[nm] = dv.Value.Value
                    if self.o.time_node:
                        dv = dvs[-1]
                        if dv.StatusCode.is_good() and isinstance(
                                dv.Value.Value, (int, float)) and math.isfinite(dv.Value.Value):
                            t = float(dv.Value.Value)
                        else:
                            transport.append("missing:time_s")
        values = {nm: (v if isinstance(v, (int, float)) and not isinstance(v, bool) else None)
                  for nm, v in values.items()}
        clock = {"last_t": self.last_t}
        cyc = clocked_step(self.comp, values, t, clock, self.cfg.stale_after_s, transport,
                           clock_only=bool(self.o.time_node))
        self.last_t = clock["last_t"]
        missed = clock["missed"]
        written = False
        if self.client is not None and not overrun:
            nodes = [self.nodes.offset]
            vals = [ua.DataValue(ua.Variant(cyc.offset_um, self.nodes.offset_type))]
            if self.nodes.alarm is not None:
                nodes.append(self.nodes.alarm)
                vals.append(ua.DataValue(_alarm_value(ua, self.nodes.alarm_type, cyc)))
            try:
                res = await asyncio.wait_for(self.client.uaclient.write_attributes(
                    nodes, vals, ua.AttributeIds.Value), self.o.timeout_s)
                written = all(r.is_good() for r in res)
            except Exception as exc:
                await self._lose(exc, loop.time())
        end = loop.time()
        g = cyc.predicted_growth_um
        self._log({"cycle": k, "time_s": t, "wall_time": time.time(),
                   "lateness_s": start - deadline, "cycle_s": end - start,
                   "inputs": values, "transport_alarms": transport,
                   "offset_um": cyc.offset_um,
                   "predicted_growth_um": None if math.isnan(g) else g,
                   "alarms": list(cyc.alarms), "held": cyc.held, "written": written,
                   **({"missed_intervals": missed} if missed else {})})

    async def run(self) -> int:
        loop = asyncio.get_running_loop()
        self.stop = asyncio.Event()

        def on_signal(sig):
            self.reason = sig.name
            self.stop.set()
        for s in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(s, on_signal, s)
        # refuse an unreachable endpoint or a bad node before any offset is written
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
        period, n = self.cfg.period_s, 0
        try:
            with open(self.cfg.log, "a", encoding="utf-8", buffering=1) as self.log:
                self._log({"event": "started", "model": self.model.kind, "transport": "opcua",
                           "endpoint": self.o.endpoint, "period_s": period,
                           "wall_time": time.time()})
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
                        if not self.o.time_node:       # no machine clock: count them
                            for j in range(behind):
                                await self._cycle(loop, n, deadline + j * period, overrun=True)
                                n += 1
                        k += behind                    # (with one, its time tells)
                        deadline = t0 + k * period
                    await self._cycle(loop, n, deadline)
                    n += 1
                    k += 1
                self._log({"event": "stopped", "cycles": n,
                           "reason": self.reason or "cycles done",
                           "last_offset_um": self.comp.offset_um, "wall_time": time.time()})
        finally:
            if self.client is not None:
                await _drop(self.client)
            for s in (signal.SIGINT, signal.SIGTERM):
                loop.remove_signal_handler(s)
        return 0


def run_opcua(model, cfg) -> int:
    """Run the OPC UA loop of ``cfg`` (a :class:`arfem.scenarios.live.LiveConfig`)."""
    _ua()
    # asyncua reports lost connections on the logging module (with tracebacks); the
    # cycle log says what happened, in one line per event
    logging.getLogger("asyncua").setLevel(logging.CRITICAL)
    return asyncio.run(_Loop(model, cfg).run())
