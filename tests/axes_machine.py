"""An OPC UA machine with three compensation axes (X, Y, Z) for ``arfem compensate
--live`` with a version-2 model (issue 32 item 5), written apart from ``arfem twin``
and in the manner of tests/live_fault_machine.py.

Nodes (namespace ``urn:arfem:axes``, ids ``ns=2;s=M.<name>``): the model's inputs and
``time_s`` (the machine's clock) are read by the compensator; ``offset_<A>_um``
(Double) and ``alarm_<A>`` (String) for A in X, Y, Z are written by it.

Lockstep: the clock advances one Δτ per write request that names an offset or an alarm
node (a request may carry an axis's alarm without its offset: the compensator does not
write an axis whose controller holds a value beyond the clamp), so a test sees every
interval exactly once whatever the load. ``alarms`` keeps each request's alarm text per
axis; ``set_held`` changes an axis's offset behind the compensator's back. The inputs of interval n are
taken from ``rows`` (the record the model was made from); ``on_advance(machine, n)``
injects a fault after write n (e.g. an axis's offset node made read-only).
"""
from __future__ import annotations

import logging
import math
from dataclasses import dataclass

NAMESPACE = "urn:arfem:axes"
NODE = "ns=2;s=M.{}"
AXES = ("X", "Y", "Z")


@dataclass(frozen=True)
class AxisWrite:
    """One axis's part of a write request, as the machine saw it."""

    n: int                    # the request's number, 1, 2, ...
    axis: str
    value: float              # the offset requested [µm]
    accepted: bool
    held_before_um: float     # what that axis held when the request came
    alarm: str | None         # that axis's alarm text written in the same request


class AxesMachine:
    """The server; ``await start()``, ``await stop()``; ``writes`` is the record."""

    def __init__(self, port: int, rows: list, *, dtau_s: float = 60.0, held=None,
                 on_advance=None):
        self.port, self.rows, self.dtau_s = port, rows, dtau_s
        self.k = 1                                   # the row whose interval is served
        self.time_s = float(rows[1]["time_s"])
        self.held = dict(held or {ax: 0.0 for ax in AXES})
        self.on_advance = on_advance
        self.writes: list[AxisWrite] = []
        self.alarms: list[dict] = []               # per request: axis -> alarm text
        self.requests = 0
        self.server = None
        self.nodes = {}

    @property
    def endpoint(self) -> str:
        return f"opc.tcp://127.0.0.1:{self.port}/arfem/axes"

    @property
    def inputs(self) -> list:
        return [k for k in self.rows[0] if k != "time_s"]

    async def start(self) -> None:
        from asyncua import Server, ua
        from asyncua.common.callback import CallbackType
        logging.getLogger("asyncua").setLevel(logging.CRITICAL)
        s = Server()
        await s.init()
        s.set_endpoint(self.endpoint)
        s.set_security_policy([ua.SecurityPolicyType.NoSecurity])
        idx = await s.register_namespace(NAMESPACE)
        obj = await s.nodes.objects.add_object(ua.NodeId("M", idx), "M")
        self.server = s
        row = self.rows[self.k]
        for name in self.inputs + ["time_s"]:
            v = self.time_s if name == "time_s" else row[name]
            self.nodes[name] = await obj.add_variable(
                ua.NodeId(f"M.{name}", idx), name, float(v), varianttype=ua.VariantType.Double)
        for ax in AXES:
            self.nodes[f"offset_{ax}_um"] = await obj.add_variable(
                ua.NodeId(f"M.offset_{ax}_um", idx), f"offset_{ax}_um", float(self.held[ax]),
                varianttype=ua.VariantType.Double)
            await self.nodes[f"offset_{ax}_um"].set_writable()
            self.nodes[f"alarm_{ax}"] = await obj.add_variable(
                ua.NodeId(f"M.alarm_{ax}", idx), f"alarm_{ax}", "",
                varianttype=ua.VariantType.String)
            await self.nodes[f"alarm_{ax}"].set_writable()
        s.subscribe_server_callback(CallbackType.PostWrite, self._on_write)
        await s.start()

    async def set_held(self, axis: str, value: float) -> None:
        """An axis's offset changes behind the compensator's back (by hand)."""
        from asyncua import ua
        self.held[axis] = float(value)
        await self.server.write_attribute_value(
            self.nodes[f"offset_{axis}_um"].nodeid,
            ua.DataValue(ua.Variant(float(value), ua.VariantType.Double)))

    async def set_writable(self, axis: str, writable: bool) -> None:
        await self.nodes[f"offset_{axis}_um"].set_writable(writable)

    async def stop(self) -> None:
        if self.server is not None:
            await self.server.stop()
            self.server = None

    async def publish(self) -> None:
        from asyncua import ua
        row = self.rows[min(self.k, len(self.rows) - 1)]
        for name in self.inputs + ["time_s"]:
            v = self.time_s if name == "time_s" else row[name]
            await self.server.write_attribute_value(
                self.nodes[name].nodeid, ua.DataValue(ua.Variant(float(v),
                                                                 ua.VariantType.Double)))

    async def _on_write(self, event, dispatcher) -> None:
        from asyncua import ua
        req = event.request_params.NodesToWrite
        res = event.response_params
        ids = {self.nodes[f"offset_{ax}_um"].nodeid: ax for ax in AXES}
        alarms = {self.nodes[f"alarm_{ax}"].nodeid: ax for ax in AXES}
        got = [(ids[w.NodeId], w, r) for w, r in zip(req, res)
               if w.NodeId in ids and w.AttributeId == ua.AttributeIds.Value]
        text = {alarms[w.NodeId]: w.Value.Value.Value for w in req if w.NodeId in alarms}
        if not got and not text:
            return
        self.requests += 1
        self.alarms.append(text)
        for ax, w, r in got:
            v = w.Value.Value.Value
            self.writes.append(AxisWrite(self.requests, ax,
                                         float(v) if v is not None else math.nan,
                                         r.is_good(), self.held[ax], text.get(ax)))
            if r.is_good():
                self.held[ax] = float(v)
        self.k += 1                                  # lockstep: the interval ends
        self.time_s += self.dtau_s
        if self.on_advance is not None:
            await self.on_advance(self, self.requests)
        await self.publish()


def box_run(d, run_dir=None) -> tuple:
    """(run folder, version-2 model, rows) for the machine to serve: the folder ``arfem
    run`` writes for the small box of tests/test_model_v2_export.py (run here, into
    ``d/run``), or ``run_dir`` written before (e.g. for the shipped spindle unit); rows
    are the record's, ``time_s`` and each input the model reads, from row 0."""
    from arfem.scenarios.records.dataset import load_dataset
    from arfem.scenarios.compensation.model_file import read_model
    from arfem.scenarios.compensation.replay import record_columns
    if run_dir is None:
        from test_model_v2_export import box_scenario

        from arfem.scenarios.cli import main
        assert main(["run", str(box_scenario(d, 0.0)), "--out", str(d / "run")]) == 0
        run_dir = d / "run"
    model = read_model(run_dir / "model.json")
    ds = load_dataset(run_dir / "record.toml")
    inputs, _ = record_columns(model, ds, "record")
    rows = [{"time_s": float(ds.time_s[k]), **{nm: float(v[k]) for nm, v in inputs.items()}}
            for k in range(ds.time_s.size)]
    return run_dir, model, rows


def write_config(d, endpoint: str, inputs, *, log="live.log", name="live.toml",
                 limits=None, cycles=0) -> object:
    """The live config: per-axis limits (``limits``: axis → (clamp, step)), one offset
    and one alarm node per axis, the machine's clock."""
    text = ('[live]\ntransport = "opcua"\nmax_offset_um = 50.0\nmax_step_um = 1.0\n'
            'period_s = 0.05\nstale_after_s = 1000\nmax_clock_jump_s = 3600\n'
            f'status_every = 0\ncycles = {cycles}\nlog = "{log}"\n')
    for ax, (clamp, step) in (limits or {}).items():
        text += f'[live.axes.{ax}]\nmax_offset_um = {clamp}\nmax_step_um = {step}\n'
    text += (f'[opcua]\nendpoint = "{endpoint}"\ntime_node = "{NODE.format("time_s")}"\n'
             'timeout_s = 2.0\nreconnect_initial_s = 0.1\nreconnect_max_s = 0.4\n'
             '[opcua.inputs]\n' + "".join(f'{nm} = "{NODE.format(nm)}"\n' for nm in inputs))
    for ax in AXES:
        text += (f'[opcua.axes.{ax}]\noffset_node = "{NODE.format(f"offset_{ax}_um")}"\n'
                 f'alarm_node = "{NODE.format(f"alarm_{ax}")}"\n')
    (d / name).write_text(text)
    return d / name
