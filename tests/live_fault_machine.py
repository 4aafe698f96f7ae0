"""An OPC UA machine for fault tests of ``arfem compensate --live``, written apart from
``arfem twin`` (issue 28): an asyncua server on 127.0.0.1 that records every write to
its offset node and injects faults on request.

Nodes (namespace ``urn:arfem:faults``, ids ``ns=2;s=M.<name>``): ``q_W_m2`` and
``time_s`` (the machine's clock) are read by the compensator; ``offset_um`` (Double, or
another type for the start-up test) and ``alarm`` (String) are written by it.

Lockstep: the machine's clock advances one Δτ per write request that names the offset
node or the alarm node, accepted or refused (a request with the alarm only: the
compensator did not write the offset, e.g. while the controller holds a value beyond
the clamp), so a test sees every interval exactly once and nothing depends on timing.
``on_advance(machine, n)`` is called after the n-th request (n from 1) to change the
next interval's inputs or to inject a fault. ``writes`` records every request that
wrote the offset, ``requests`` every request. Used by ``tests/test_live_faults.py`` and
``benchmarks/soak_live.py``.
"""
from __future__ import annotations

import asyncio
import json
import logging
import math
import socket
import sys
from dataclasses import dataclass
from pathlib import Path

NAMESPACE = "urn:arfem:faults"
NODE = "ns=2;s=M.{}"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass(frozen=True)
class Write:
    """One write request that named the offset node, as the machine saw it."""

    n: int                    # the request's number, 1, 2, ... in the order received
    value: float              # the offset requested [µm]
    accepted: bool            # whether the machine took it
    held_before_um: float     # what the machine held when it came
    alarm: str | None         # the alarm text written in the same request (None: none)
    time_s: float             # the machine's clock the compensator had read


class FaultMachine:
    """The server; ``await start()``, ``await stop()``; ``writes`` is the record."""

    def __init__(self, port: int, *, dtau_s: float = 60.0, q_W_m2: float = 2000.0,
                 held_um: float = 0.0, offset_type: str = "Double", on_advance=None):
        self.port, self.dtau_s, self.q, self.held = port, dtau_s, q_W_m2, held_um
        self.time_s = 0.0
        self.offset_type = offset_type
        self.on_advance = on_advance
        self.writes: list[Write] = []
        self.requests: list[tuple] = []     # per request: (offset value or None, alarm)
        self.reads = 0
        self.read_delay_s = 0.0              # slow server: each read waits this long
        self.stalled = asyncio.Event()       # set: reads hang until cleared
        self.release = asyncio.Event()
        self.server = None
        self.nodes = {}

    @property
    def endpoint(self) -> str:
        return f"opc.tcp://127.0.0.1:{self.port}/arfem/faults"

    async def start(self) -> None:
        from asyncua import Server, ua
        from asyncua.common.callback import CallbackType
        logging.getLogger("asyncua").setLevel(logging.CRITICAL)
        self.release = asyncio.Event()       # (stop() released the reads of the last run)
        s = Server()
        await s.init()
        s.set_endpoint(self.endpoint)
        s.set_security_policy([ua.SecurityPolicyType.NoSecurity])
        self.idx = await s.register_namespace(NAMESPACE)
        self.obj = await s.nodes.objects.add_object(ua.NodeId("M", self.idx), "M")
        self.server = s
        for name, v in (("q_W_m2", self.q), ("time_s", self.time_s)):
            self.nodes[name] = await self.obj.add_variable(
                ua.NodeId(f"M.{name}", self.idx), name, float(v),
                varianttype=ua.VariantType.Double)
        await self.add_offset_node()
        self.nodes["alarm"] = await self.obj.add_variable(
            ua.NodeId("M.alarm", self.idx), "alarm", "", varianttype=ua.VariantType.String)
        await self.nodes["alarm"].set_writable()
        s.subscribe_server_callback(CallbackType.PostWrite, self._on_write)
        s.subscribe_server_callback(CallbackType.PreRead, self._on_read)
        await s.start()

    async def add_offset_node(self) -> None:
        from asyncua import ua
        vt = getattr(ua.VariantType, self.offset_type)
        v = int(self.held) if self.offset_type.startswith(("Int", "UInt")) else self.held
        self.nodes["offset_um"] = await self.obj.add_variable(
            ua.NodeId("M.offset_um", self.idx), "offset_um", v, varianttype=vt)
        await self.nodes["offset_um"].set_writable()

    async def delete_offset_node(self) -> None:
        await self.server.delete_nodes([self.nodes["offset_um"]])

    async def set_offset_writable(self, writable: bool) -> None:
        await self.nodes["offset_um"].set_writable(writable)

    async def set_held(self, value: float) -> None:
        """The controller's own offset changes (e.g. set by hand while nobody writes)."""
        from asyncua import ua
        self.held = float(value)
        await self.server.write_attribute_value(
            self.nodes["offset_um"].nodeid, ua.DataValue(ua.Variant(self.held,
                                                                    ua.VariantType.Double)))

    async def stop(self) -> None:
        if self.server is not None:
            self.release.set()
            await self.server.stop()
            self.server = None

    async def publish(self) -> None:
        from asyncua import ua
        for name, v in (("q_W_m2", self.q), ("time_s", self.time_s)):
            await self.server.write_attribute_value(
                self.nodes[name].nodeid, ua.DataValue(ua.Variant(float(v),
                                                                 ua.VariantType.Double)))

    async def _on_read(self, event, dispatcher) -> None:
        ids = [r.NodeId for r in event.request_params.NodesToRead]
        if self.nodes["time_s"].nodeid not in ids:
            return
        self.reads += 1
        if self.read_delay_s:
            await asyncio.sleep(self.read_delay_s)
        if self.stalled.is_set():
            await self.release.wait()

    async def _on_write(self, event, dispatcher) -> None:
        from asyncua import ua
        req = event.request_params.NodesToWrite
        res = event.response_params
        oid, aid = self.nodes["offset_um"].nodeid, self.nodes["alarm"].nodeid
        off = [(w, r) for w, r in zip(req, res)
               if w.NodeId == oid and w.AttributeId == ua.AttributeIds.Value]
        alarm = [x.Value.Value.Value for x in req if x.NodeId == aid]
        if not off and not alarm:
            return
        value = None
        if off:
            w, r = off[0]
            before = self.held
            if r.is_good():
                self.held = float(w.Value.Value.Value)
            v = w.Value.Value.Value
            value = float(v) if v is not None else math.nan
            self.writes.append(Write(len(self.requests) + 1, value, r.is_good(), before,
                                     alarm[0] if alarm else None, self.time_s))
        self.requests.append((value, alarm[0] if alarm else None))
        self.time_s += self.dtau_s               # lockstep: the interval ends
        if self.on_advance is not None:
            await self.on_advance(self, len(self.requests))
        await self.publish()


# ------------------------------------------------ the compensator's side, for the tests

CLAMP, STEP = 20.0, 0.5
WAIT_S = 120.0                       # how long to wait for the compensator at most


def paper_model(d: Path) -> Path:
    """The paper's AR(1) at Δτ = 60 s (eqs. 13-14 from the rod), as ``d/model.json``."""
    from arfem.models.ar1 import c1_paper, c2_paper
    from arfem.models.compensator import ar1_model
    from arfem.params import Rod
    from arfem.scenarios.compensation.model_file import write_model
    rod = Rod()
    m = ar1_model(c1_paper(rod, 60.0), c2_paper(rod, 60.0, 1.0) * 1e6, dtau_s=60.0)
    write_model(d / "model.json", m)
    return d / "model.json"


def write_config(d: Path, endpoint: str, *, log="live.log", timeout_s=2.0, name="live.toml",
                 cycles=0):
    (d / name).write_text(
        f'[live]\ntransport = "opcua"\nmax_offset_um = {CLAMP}\nmax_step_um = {STEP}\n'
        f'period_s = 0.05\nstale_after_s = 1000\nmax_clock_jump_s = 3600\n'
        f'status_every = 0\ncycles = {cycles}\nlog = "{log}"\n'
        f'[opcua]\nendpoint = "{endpoint}"\noffset_node = "{NODE.format("offset_um")}"\n'
        f'alarm_node = "{NODE.format("alarm")}"\ntime_node = "{NODE.format("time_s")}"\n'
        f'timeout_s = {timeout_s}\nreconnect_initial_s = 0.1\nreconnect_max_s = 0.4\n'
        f'[opcua.inputs]\nq_W_m2 = "{NODE.format("q_W_m2")}"\n')
    return d / name


async def start_compensator(d: Path, cfg: Path, tag: str, extra=(), model=None):
    """``arfem compensate MODEL --live CFG [extra...]`` as a process (MODEL: d/model.json
    unless given)."""
    out = open(d / f"{tag}.stdout", "w")
    err = open(d / f"{tag}.stderr", "w")
    p = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "arfem", "compensate", str(model or d / "model.json"),
        "--live", str(cfg), *extra, stdout=out, stderr=err)
    out.close()
    err.close()
    return p


def log_lines(path: Path) -> list:
    if not path.exists():
        return []
    out = []
    for x in path.read_text().splitlines():
        try:
            out.append(json.loads(x))
        except ValueError:
            pass                                   # a line torn by kill -9
    return out


async def until(pred, what: str, proc=None, timeout=WAIT_S):
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while loop.time() < end:
        if pred():
            return
        if proc is not None and proc.returncode is not None:
            raise AssertionError(f"compensator exited ({proc.returncode}) waiting for {what}")
        await asyncio.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


