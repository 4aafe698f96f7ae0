"""``arfem twin``: a simulated spindle behind an OPC UA server, to try a compensator on.

The machine is :class:`arfem.models.twin.SpindleTwin` (the FEM rod under a speed
program, with a daily ambient swing the paper's AR(1) does not model), or with
``--scenario TOML`` a ``[geometry]`` scenario such as the shipped spindle unit
(:class:`arfem.models.twin.AxesTwin`: its FEM, with the speed-dependent convection,
served interval by interval), which has one compensation axis per displacement sensor:
its nodes are the scenario's inputs (``P_<source>_W``, ``speed_rpm``, ``ambient_C``),
thermometers (``T_<name>_C``), displacement sensors (``d_<sensor>_um``, true + noise),
``growth_um`` (the Z axis's), and per axis ``offset_<AXIS>_um`` (writable),
``alarm_<AXIS>`` (writable, String), ``true_<AXIS>_um`` and ``error_<AXIS>_um`` (true +
the offset in force). It stops at the end of the scenario's cycle. The server
listens on 127.0.0.1 only and exposes, under the object ``Spindle`` of namespace
``urn:arfem:twin`` (node ids ``ns=2;s=Spindle.<name>``):

    time_s, speed_rpm, q_W_m2, ambient_C, T_face_C, T_mid_C   the machine's readings
    growth_um          what the displacement sensor reads (true growth + noise) [µm]
    true_growth_um     the true growth [µm]
    error_um           true growth + the offset in force: what a part would show [µm]
    offset_um          writable: the compensation offset [µm]
    alarm              writable: the compensator's alarm (String)

Time runs accelerated: one interval Δτ (``--dtau-s``) every ``--period-s`` of wall
time; with ``--lockstep`` the machine instead advances one Δτ each time the offset is
written (each compensator cycle), so that a test sees every interval exactly once.
``--record DIR`` writes the history as a measured-data record (``twin.toml`` and
``twin.csv``, with the extra columns ``true_growth_um``, ``offset_um``, ``error_um`` and
``alarm_set``: the offset, and whether the alarm node was set, when the interval ended) when the twin stops: after ``--steps``
intervals, or at SIGINT/SIGTERM. The first line on standard output is
``arfem twin: listening on <endpoint>``.
"""
from __future__ import annotations

import asyncio
import logging
import math
import signal
import sys
from pathlib import Path

from arfem.params import InputError
from arfem.scenarios.live.twin_record import AxesTwinCycle, TwinCycle, free_port, write_record

__all__ = ["NAMESPACE", "READINGS", "serve", "add_parser", "main"]

NAMESPACE = "urn:arfem:twin"
READINGS = ("time_s", "speed_rpm", "q_W_m2", "ambient_C", "T_face_C", "T_mid_C",
            "growth_um", "true_growth_um", "error_um")


def _user_manager(name: str, secret: str):
    """An asyncua user manager that admits one user, by name and password."""
    from asyncua.crypto.permission_rules import User, UserRole
    from asyncua.server.user_managers import UserManager

    class _One(UserManager):
        def get_user(self, iserver, username=None, password=None, certificate=None):
            if username == name and password == secret:
                return User(role=UserRole.User)
            return None
    return _One()


async def _server(port: int, secure_dir, credentials):
    """An initialised asyncua server on 127.0.0.1:``port`` and its endpoint: no security,
    or (``secure_dir``) Basic256Sha256 SignAndEncrypt only with a self-signed
    certificate kept there; ``credentials`` (user, password): the only identity admitted."""
    from asyncua import Server, ua
    server = Server(user_manager=None if credentials is None else _user_manager(*credentials))
    await server.init()
    endpoint = f"opc.tcp://127.0.0.1:{port}/arfem/twin"
    server.set_endpoint(endpoint)
    server.set_server_name("arfem twin")
    if secure_dir is None:
        server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
    else:
        from pathlib import Path

        from asyncua.crypto.cert_gen import setup_self_signed_certificate
        from cryptography.x509.oid import ExtendedKeyUsageOID
        d = Path(secure_dir)
        d.mkdir(parents=True, exist_ok=True)
        await setup_self_signed_certificate(
            d / "twin_key.pem", d / "twin_cert.der", "urn:arfem:twin", "localhost",
            [ExtendedKeyUsageOID.SERVER_AUTH], {"commonName": "arfem twin"})
        server.set_security_policy([ua.SecurityPolicyType.Basic256Sha256_SignAndEncrypt])
        await server.load_certificate(str(d / "twin_cert.der"))
        await server.load_private_key(str(d / "twin_key.pem"))
    if credentials is not None:
        server.set_security_IDs(["Username"])
    return server, endpoint


def _layout(twin) -> tuple:
    """(readings, axes): the names the twin publishes and its compensation axes, each
    axis a tuple (axis, offset node name, alarm node name, error reading, true reading).
    The rod: :data:`READINGS` and one axis ``None`` on ``offset_um``/``alarm``."""
    axes = tuple(getattr(twin, "axes", ()) or ())
    if not axes:
        return READINGS, ((None, "offset_um", "alarm", "error_um", "true_growth_um"),)
    names = ["time_s"] + list(twin.names)
    names += [f"true_{ax}_um" for ax in axes] + [f"error_{ax}_um" for ax in axes]
    return tuple(dict.fromkeys(names)), tuple(
        (ax, f"offset_{ax}_um", f"alarm_{ax}", f"error_{ax}_um", f"true_{ax}_um")
        for ax in axes)


class _Served:
    """The twin behind a server: its nodes, the offsets written, the interval in force
    and the history (one :class:`TwinCycle` or :class:`AxesTwinCycle` per interval)."""

    def __init__(self, server, twin, lockstep: bool, steps: int):
        self.server, self.twin, self.lockstep = server, twin, lockstep
        n = getattr(twin, "n_steps", None)
        self.steps = steps if n is None else (min(steps, n) if steps else n)
        self.readings, self.axes = _layout(twin)
        self.nodes, self.history, self.now = {}, [], None
        self.offset = {a[0]: 0.0 for a in self.axes}
        self.alarm = {a[0]: "" for a in self.axes}
        self.done = asyncio.Event()

    async def add_nodes(self) -> None:
        from asyncua import ua
        idx = await self.server.register_namespace(NAMESPACE)
        obj = await self.server.nodes.objects.add_object(ua.NodeId("Spindle", idx), "Spindle")
        for name in self.readings + tuple(a[1] for a in self.axes):
            self.nodes[name] = await obj.add_variable(
                ua.NodeId(f"Spindle.{name}", idx), name, 0.0, varianttype=ua.VariantType.Double)
        for a in self.axes:
            self.nodes[a[2]] = await obj.add_variable(
                ua.NodeId(f"Spindle.{a[2]}", idx), a[2], "", varianttype=ua.VariantType.String)
            await self.nodes[a[1]].set_writable()
            await self.nodes[a[2]].set_writable()

    def errors(self, r) -> dict:
        """Each axis's error: true displacement + the offset in force [µm]."""
        if self.axes[0][0] is None:
            return {"error_um": r.true_growth_um + self.offset[None]}
        return {a[3]: r.true_um[a[0]] + self.offset[a[0]] for a in self.axes}

    async def publish(self, values: dict) -> None:
        from asyncua import ua
        for name in self.readings:
            if name in values:
                await self.server.write_attribute_value(
                    self.nodes[name].nodeid,
                    ua.DataValue(ua.Variant(values[name], ua.VariantType.Double)))

    def close(self) -> None:
        """The interval in force ends: its offsets, alarms and errors go to the history."""
        r, self.now = self.now, None
        if r is None:
            return
        if self.axes[0][0] is None:
            self.history.append(TwinCycle(r, offset_um=self.offset[None],
                                          alarm_set=1.0 if self.alarm[None] else 0.0,
                                          error_um=r.true_growth_um + self.offset[None]))
        else:
            self.history.append(AxesTwinCycle(r, dict(self.offset),
                                              {k: 1.0 if v else 0.0
                                               for k, v in self.alarm.items()},
                                              self.errors(r)))

    async def advance(self) -> None:
        """Close the interval in force and start the next (unless ``steps`` are done)."""
        self.close()
        if self.steps and len(self.history) >= self.steps:
            self.done.set()
            return
        r = self.twin.advance()
        self.now = r
        await self.publish({**r.as_dict(), **self.errors(r)})

    async def on_write(self, event, dispatcher) -> None:
        ids = [w.NodeId for w in event.request_params.NodesToWrite]
        wrote = False
        for ax, off, alarm, _, _ in self.axes:
            if self.nodes[alarm].nodeid in ids:
                v = self.server.read_attribute_value(self.nodes[alarm].nodeid).Value.Value
                self.alarm[ax] = str(v or "")
            if self.nodes[off].nodeid in ids:
                v = self.server.read_attribute_value(self.nodes[off].nodeid).Value.Value
                self.offset[ax] = float(v)
                wrote = True
        if wrote and self.lockstep:
            await self.advance()


async def serve(twin, port: int, period_s: float, lockstep: bool, steps: int,
                ready=None, secure_dir=None, credentials=None) -> list:
    """Run the server until ``steps`` intervals are done (0 = until cancelled or a
    signal, or a run's end for a twin with several axes); returns the history (one
    :class:`TwinCycle`, or :class:`AxesTwinCycle`, per interval).

    ``secure_dir``: serve Basic256Sha256 SignAndEncrypt only, with a self-signed server
    certificate kept there (made on first use); ``credentials``: (user, password), the
    only identity admitted (anonymous refused)."""
    from asyncua.common.callback import CallbackType

    logging.getLogger("asyncua").setLevel(logging.CRITICAL)
    server, endpoint = await _server(port, secure_dir, credentials)
    sv = _Served(server, twin, lockstep, steps)
    await sv.add_nodes()
    server.subscribe_server_callback(CallbackType.PostWrite, sv.on_write)
    loop = asyncio.get_running_loop()
    for s in (signal.SIGINT, signal.SIGTERM):
        try:
            loop.add_signal_handler(s, sv.done.set)
        except (RuntimeError, ValueError):      # not the main thread: cancel instead
            pass
    async with server:
        await sv.advance()
        if ready is not None:
            ready(endpoint)
        if lockstep:
            await sv.done.wait()
        else:
            t0, k = loop.time(), 1
            while not sv.done.is_set():
                try:
                    await asyncio.wait_for(sv.done.wait(),
                                           max(0.0, t0 + k * period_s - loop.time()))
                except asyncio.TimeoutError:
                    await sv.advance()
                    k += 1
    sv.close()                               # stopped early: the interval in force ends
    return sv.history


def add_parser(sub) -> None:
    p = sub.add_parser(
        "twin", help="serve a simulated spindle over OPC UA (127.0.0.1), to try "
                     "arfem compensate --live on",
        description="A FEM spindle rod with a hidden daily ambient swing, run in "
                    "accelerated time behind an OPC UA server on 127.0.0.1.")
    p.add_argument("--scenario", metavar="TOML",
                   help="serve a [geometry] scenario (e.g. scenarios/data/spindle_unit.toml) "
                        "instead of the rod: its FEM solved once, then served interval by "
                        "interval with one offset node per axis (offset_<AXIS>_um, "
                        "alarm_<AXIS>, error_<AXIS>_um); Δτ is its output_interval_s")
    p.add_argument("--port", type=int, default=4840, help="TCP port; 0 = a free one "
                   "(default 4840)")
    p.add_argument("--dtau-s", type=float, default=60.0, help="simulated interval Δτ [s]")
    p.add_argument("--period-s", type=float, default=1.0,
                   help="wall time per interval [s] (default 1: 60x real time at Δτ 60 s)")
    p.add_argument("--lockstep", action="store_true",
                   help="advance one interval per write of offset_um instead of per period")
    p.add_argument("--steps", type=int, default=0, help="stop after this many intervals "
                   "(default 0: until SIGINT/SIGTERM)")
    p.add_argument("--ambient-amplitude-K", type=float, default=2.0,
                   help="amplitude of the hidden daily ambient swing [K] (default 2)")
    p.add_argument("--noise-um", type=float, default=0.05,
                   help="white noise σ of the growth sensor [µm] (default 0.05)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sensor noise")
    p.add_argument("--start-h", type=float, default=0.0,
                   help="run the machine this many hours before serving (default 0)")
    p.add_argument("--nan-at-step", type=int, default=-1, metavar="N",
                   help="the q_W_m2 reading of interval N is NaN (a sensor fault)")
    p.add_argument("--record", metavar="DIR", help="write the history as a measured-data "
                   "record (twin.toml, twin.csv) into DIR when the twin stops")
    p.add_argument("--secure", metavar="DIR", help="serve Basic256Sha256 SignAndEncrypt "
                   "only, with a self-signed certificate kept in DIR (made on first use)")
    p.add_argument("--user-env", metavar="NAME", help="admit only the user whose name is "
                   "in this environment variable (with --password-env); anonymous refused")
    p.add_argument("--password-env", metavar="NAME",
                   help="environment variable holding that user's password")
    p.set_defaults(func=main)


#: Bounds of the twin's flags [unit]: (flag, attribute, low, high, what). A physical
#: spindle: Δτ 10 ms to a day, an ambient swing of at most 50 K, a sensor noise of at most
#: 1 mm, a warm-up of at most 30 days; a wall-clock period of 1 ms to an hour.
FLAG_BOUNDS = (("--dtau-s", "dtau_s", 0.01, 86400.0, "seconds"),
               ("--period-s", "period_s", 0.001, 3600.0, "seconds"),
               ("--ambient-amplitude-K", "ambient_amplitude_K", 0.0, 50.0, "K"),
               ("--noise-um", "noise_um", 0.0, 1000.0, "µm"),
               ("--start-h", "start_h", 0.0, 720.0, "hours"))
#: Most intervals ``--start-h`` may run before serving (at Δτ = 60 s, 30 days are 43200).
MAX_START_STEPS = 100_000


def check_flags(args) -> None:
    """Every flag of ``arfem twin`` bounded (issue 29): one :class:`InputError` naming
    the flag, before anything is built or served."""
    for flag, name, lo, hi, unit in FLAG_BOUNDS:
        v = getattr(args, name)
        if not (math.isfinite(v) and lo <= v <= hi) or (name in ("dtau_s", "period_s")
                                                        and v <= 0):
            raise InputError(f"must be a number of {unit} from {lo:g} to {hi:g}, got {v!r}",
                             flag)
    if not 0 <= args.port < 65536:
        raise InputError(f"must be a TCP port (0-65535), got {args.port}", "--port")
    if not 0 <= args.steps <= 10**9:
        raise InputError(f"must be from 0 to 1e9, got {args.steps}", "--steps")
    if not 0 <= args.seed < 2**63:
        raise InputError(f"must be a whole number from 0 to 2^63 - 1, got {args.seed}",
                         "--seed")
    if not -1 <= args.nan_at_step <= 10**9:
        raise InputError(f"must be -1 (never) or a step from 0 to 1e9, got "
                         f"{args.nan_at_step}", "--nan-at-step")
    n = args.start_h * 3600.0 / args.dtau_s
    if n > MAX_START_STEPS:
        raise InputError(f"asks for {n:.0f} intervals of Δτ = {args.dtau_s:g} s before "
                         f"serving; at most {MAX_START_STEPS} (a longer --dtau-s or a "
                         "shorter --start-h)", "--start-h")


#: the rod's flags and their defaults: a geometry scenario brings its own program
_ROD_ONLY = (("--dtau-s", "dtau_s", 60.0), ("--ambient-amplitude-K", "ambient_amplitude_K", 2.0),
             ("--start-h", "start_h", 0.0), ("--nan-at-step", "nan_at_step", -1))


def _scenario_twin(args):
    """The twin of ``--scenario`` (:func:`arfem.scenarios.geometry.twin.axes_twin`)."""
    from arfem.scenarios.geometry.twin import axes_twin
    from arfem.scenarios.geometry.scenario import is_geometry_scenario
    for flag, name, default in _ROD_ONLY:
        if getattr(args, name) != default:
            raise InputError("is for the rod; a --scenario brings its own program and "
                             "interval", flag)
    if not Path(args.scenario).is_file():     # a typo is not "not a [geometry] scenario"
        raise InputError(f"{args.scenario}: file not found", "--scenario")
    if not is_geometry_scenario(args.scenario):
        raise InputError("must be a scenario TOML with a [geometry] table", "--scenario")
    import contextlib
    with contextlib.redirect_stdout(sys.stderr):   # (the mesh reader prints): the first
        twin, _ = axes_twin(args.scenario, args.noise_um, args.seed)   # line stays ours
    return twin


def main(args) -> int:
    from pathlib import Path

    from arfem.models.twin import SpindleTwin, TwinProgram
    try:
        import asyncua  # noqa: F401
    except ImportError:
        raise InputError("needs the asyncua package: pip install 'arfem[opcua]'",
                         "arfem twin") from None
    check_flags(args)
    if args.record is not None:
        for name in ("twin.csv", "twin.toml"):      # never over a file already there
            if (Path(args.record) / name).exists() or (Path(args.record) / name).is_symlink():
                raise InputError(f"already holds a {name}; choose another directory",
                                 "--record")
        if Path(args.record).exists() and not Path(args.record).is_dir():
            raise InputError("exists and is not a directory", "--record")
    if getattr(args, "scenario", None) is not None:
        twin = _scenario_twin(args)
    else:
        twin = SpindleTwin(TwinProgram(dtau_s=args.dtau_s,
                                       ambient_amplitude_K=args.ambient_amplitude_K,
                                       growth_noise_um=args.noise_um, seed=args.seed,
                                       nan_at_step=args.nan_at_step))
        for _ in range(int(round(args.start_h * 3600.0 / args.dtau_s))):
            twin.advance()
    port = free_port() if args.port == 0 else args.port
    credentials = None
    if (args.user_env is None) != (args.password_env is None):
        raise InputError("go together", "--user-env/--password-env")
    if args.user_env is not None:
        import os
        vals = [os.environ.get(n) for n in (args.user_env, args.password_env)]
        for flag, n, v in zip(("--user-env", "--password-env"),
                              (args.user_env, args.password_env), vals):
            if not v:
                raise InputError(f"the environment variable {n} is not set", flag)
        credentials = tuple(vals)

    def ready(endpoint):
        print(f"arfem twin: listening on {endpoint}", flush=True)

    try:
        history = asyncio.run(serve(twin, port, args.period_s, args.lockstep, args.steps,
                                    ready, args.secure, credentials))
    except OSError as exc:
        raise InputError(f"cannot listen on 127.0.0.1:{port}: {exc.strerror or exc}",
                         "--port") from None
    if args.record is not None:
        write_record(args.record, history, scenario=getattr(args, "scenario", None))
    print(f"arfem twin: stopped after {len(history)} intervals", file=sys.stderr)
    return 0
