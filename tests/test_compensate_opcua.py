"""``arfem compensate --live`` over OPC UA against ``arfem twin`` (issue 21, items 3-4).

Each test starts the twin (a FEM spindle behind an asyncua server on 127.0.0.1, a free
port) and the compensator as separate processes, as a user would. The twin runs in
lockstep (one interval per offset written), so the comparisons do not depend on timing.

What is verified and why:
* live equals replay: the offsets the live loop wrote, as the twin recorded them, are
  exactly (==) those of ``arfem compensate``'s replay of the twin's record, and the
  twin's compensated error equals its true growth plus the replayed offset to round-off
  (1e-12 µm: the same floats added) -- one code path for both modes;
* the clamp and the rate limit hold on the wire (they bind in this run: asserted);
* a NaN reading holds the offset and raises the alarm node for that interval only;
* a killed server: every cycle after the loss holds the last offset with
  ``connection_lost``, reconnection is retried with growing backoff, a server back on
  the same port is reconnected and compensation resumes; SIGTERM ends the loop with
  exit 0 and a final log line;
* bad input -- an unreachable endpoint, a node id the server lacks, a key that is
  unknown, a password in the file, an unset credential variable -- is one line with
  exit status 2 and no offset written;
* security: against a twin that serves only Basic256Sha256 SignAndEncrypt and admits
  one user, the compensator connects with a client certificate and credentials taken
  from the environment variables its config names, and runs; a wrong password is one
  line, exit 2, no offset written;
* nothing is left running: every process started here has exited when its test ends.
"""
import json
import os
import select
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("asyncua")

from arfem.models.ar1 import c1_paper, c2_paper  # noqa: E402
from arfem.models.compensator import ar1_model  # noqa: E402
from arfem.params import Rod  # noqa: E402
from arfem.scenarios.compensation.model_file import write_model  # noqa: E402

# serves OPC UA on a TCP port: one xdist worker runs all such tests (see conftest.py)
pytestmark = pytest.mark.xdist_group("tcp_ports")

ARFEM = [sys.executable, "-m", "arfem"]
NODE = "ns=2;s=Spindle.{}"


class Procs:
    """Processes started by a test; all are ended (and checked ended) at teardown."""

    def __init__(self):
        self.all = []

    def start(self, args, **kw):
        p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             **kw)
        self.all.append(p)
        return p

    def twin(self, d, *extra, port=0, env=None):
        p = self.start(ARFEM + ["twin", "--port", str(port), "--lockstep",
                                "--record", str(d), *extra], env=env)
        ready, _, _ = select.select([p.stdout], [], [], 60)
        line = p.stdout.readline() if ready else ""
        assert "listening on" in line, (line, p.poll(), p.stderr.read() if p.poll() else "")
        return p, line.split("listening on ")[1].strip()

    def end(self):
        for p in self.all:
            if p.poll() is None:
                p.kill()
            p.wait(timeout=30)
            for f in (p.stdout, p.stderr):
                f.close()
        assert all(p.returncode is not None for p in self.all)


@pytest.fixture
def procs():
    ps = Procs()
    yield ps
    ps.end()


@pytest.fixture
def model_file(tmp_path):
    rod = Rod()
    m = ar1_model(c1_paper(rod, 60.0), c2_paper(rod, 60.0, 1.0) * 1e6, dtau_s=60.0)
    write_model(tmp_path / "model.json", m)
    return tmp_path / "model.json", m


def config(d, endpoint, *, cycles, max_offset=1e3, max_step=1e3, period=0.01, extra="",
           inputs=None, opc_extra=""):
    inputs = inputs or {"q_W_m2": NODE.format("q_W_m2")}
    text = (f'[live]\ntransport = "opcua"\nmax_offset_um = {max_offset}\n'
            f'max_step_um = {max_step}\nperiod_s = {period}\ncycles = {cycles}\n'
            f'stale_after_s = 600\nlog = "live.log"\n{extra}'
            f'[opcua]\nendpoint = "{endpoint}"\noffset_node = "{NODE.format("offset_um")}"\n'
            f'alarm_node = "{NODE.format("alarm")}"\ntime_node = "{NODE.format("time_s")}"\n'
            f'timeout_s = 1.0\nreconnect_initial_s = 0.1\nreconnect_max_s = 0.4\n'
            f'{opc_extra}[opcua.inputs]\n'
            + "".join(f'{k} = "{v}"\n' for k, v in inputs.items()))
    (d / "live.toml").write_text(text)
    return d / "live.toml"


def compensate(model, cfg, **kw):
    return subprocess.run(ARFEM + ["compensate", str(model), "--live", str(cfg)],
                          capture_output=True, text=True, timeout=120, **kw)


def log_lines(d):
    """The complete lines of the cycle log. The compensator may be writing while this
    reads, and a read can see a write in progress (a fresh-clone CI run read
    '{"cycle": 40, ..., "cycle_s": 5.77759' and failed on it), so a last line without its
    newline is left for the next read; every complete line must parse."""
    *complete, _in_progress = (d / "live.log").read_text().split("\n")
    return [json.loads(x) for x in complete]


def read_csv(path):
    import csv
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) if r[k] else np.nan for r in rows]) for k in rows[0]}


def test_live_equals_replay_and_limits_hold(tmp_path, procs, model_file):
    from arfem.scenarios.compensation.replay import replay
    from arfem.scenarios.records.dataset import load_dataset
    mpath, model = model_file
    n = 240                                         # 4 h at Δτ = 60 s: heating and a stop
    twin, url = procs.twin(tmp_path, "--steps", str(n))
    cfg = config(tmp_path, url, cycles=n, max_offset=12.0, max_step=0.3)
    r = compensate(mpath, cfg)
    assert r.returncode == 0, r.stderr
    assert twin.wait(timeout=30) == 0              # the twin ended after its n intervals
    cyc = [c for c in log_lines(tmp_path) if "cycle" in c]
    assert len(cyc) == n and not any(c["held"] for c in cyc) and all(c["sent"] for c in cyc)
    assert not any(e.get("event") == "write_refused" for e in log_lines(tmp_path))
    rec = read_csv(tmp_path / "twin.csv")
    live_off = rec["offset_um"]
    assert np.array_equal(live_off, [c["offset_um"] for c in cyc])
    # the limits bind in this run, and hold on the wire
    assert any("rate_limited" in c["alarms"] for c in cyc)
    assert any("clamped" in c["alarms"] for c in cyc)
    assert np.max(np.abs(live_off)) <= 12.0 + 1e-12
    assert np.max(np.abs(np.diff(np.concatenate([[0.0], live_off])))) <= 0.3 + 1e-12
    # replay of the twin's record (its inputs as it served them) through the same step
    res = replay(model, load_dataset(tmp_path / "twin.toml"), max_offset_um=12.0,
                 max_step_um=0.3)
    assert np.array_equal(res.series.offset_um, live_off)
    err = rec["true_growth_um"] + res.series.offset_um
    assert np.max(np.abs(err - rec["error_um"])) <= 1e-12


def test_nan_reading_holds_the_offset_and_raises_the_alarm(tmp_path, procs, model_file):
    mpath, _ = model_file
    twin, url = procs.twin(tmp_path, "--steps", "40", "--nan-at-step", "20")
    r = compensate(mpath, config(tmp_path, url, cycles=40))
    assert r.returncode == 0, r.stderr
    assert twin.wait(timeout=30) == 0
    cyc = [c for c in log_lines(tmp_path) if "cycle" in c]
    bad = cyc[19]                                   # the 20th interval
    assert bad["held"] and "nonfinite:q_W_m2" in bad["alarms"]
    assert bad["offset_um"] == cyc[18]["offset_um"]
    assert [c["held"] for c in cyc].count(True) == 1
    rec = read_csv(tmp_path / "twin.csv")
    assert np.flatnonzero(rec["alarm_set"]).tolist() == [19]   # the alarm node, as served
    assert rec["offset_um"][19] == rec["offset_um"][18]


def test_killed_server_holds_retries_and_recovers(tmp_path, procs, model_file):
    mpath, _ = model_file
    (tmp_path / "a").mkdir()
    twin, url = procs.twin(tmp_path / "a")
    port = int(url.split(":")[2].split("/")[0])
    cfg = config(tmp_path, url, cycles=0, period=0.02)
    comp = procs.start(ARFEM + ["compensate", str(mpath), "--live", str(cfg)])

    def wait_for(pred, timeout=60):
        t_end = time.monotonic() + timeout
        while time.monotonic() < t_end:
            if (tmp_path / "live.log").exists() and pred(log_lines(tmp_path)):
                return log_lines(tmp_path)
            assert comp.poll() is None, comp.stderr.read()
            time.sleep(0.05)
        raise AssertionError(f"timed out; log ends {log_lines(tmp_path)[-3:]}")

    wait_for(lambda L: sum("cycle" in c for c in L) >= 30)
    twin.send_signal(signal.SIGKILL)
    twin.wait(timeout=30)
    log = wait_for(lambda L: sum(e.get("event") == "reconnect_failed" for e in L) >= 3)
    lost = next(i for i, e in enumerate(log) if e.get("event") == "connection_lost")
    before = [c for c in log[:lost] if "cycle" in c][-1]["offset_um"]
    after = [c for c in log[lost:] if "cycle" in c]
    assert after and all(c["held"] and c["offset_um"] == before for c in after)
    assert all("connection_lost" in c["alarms"] for c in after)
    waits = [e["retry_in_s"] for e in log if e.get("event") == "reconnect_failed"]
    assert waits[:3] == sorted(waits[:3]) and waits[2] > waits[0]     # backoff grows
    # the machine comes back on the same port (later in its day): compensation resumes
    (tmp_path / "b").mkdir()
    procs.twin(tmp_path / "b", "--start-h", "5", port=port)
    log = wait_for(lambda L: any(e.get("event") == "reconnected" for e in L)
                   and not L[-1].get("held", True))
    comp.send_signal(signal.SIGTERM)
    assert comp.wait(timeout=30) == 0
    last = log_lines(tmp_path)[-1]
    assert last["event"] == "stopped" and last["reason"] == "SIGTERM"


@pytest.mark.parametrize("case, msg", [
    ("unreachable", "opcua.endpoint: cannot connect"),
    ("no_node", "opcua.inputs.q_W_m2: node ns=2;s=Spindle.nothing does not exist"),
    ("unknown_key", "opcua.endpont: unknown key (did you mean 'endpoint'?)"),
    ("password", "opcua.password: credentials are never read from the config file"),
    ("env_unset", "opcua.username_env: the environment variable ARFEM_TEST_UNSET_USER"),
    ("input_unread", "opcua.inputs.speed_rpm: the model does not read this input"),
])
def test_bad_live_input_is_one_line_exit_2_before_any_offset(tmp_path, procs, model_file,
                                                              case, msg):
    from arfem.scenarios.live.twin_record import free_port
    mpath, _ = model_file
    twin = None
    if case == "unreachable":
        url = f"opc.tcp://127.0.0.1:{free_port()}/arfem/twin"
    else:
        twin, url = procs.twin(tmp_path)
    kw = {}
    if case == "no_node":
        kw["inputs"] = {"q_W_m2": NODE.format("nothing")}
    elif case == "unknown_key":
        kw["opc_extra"] = "endpont = \"x\"\n"
    elif case == "password":
        kw["opc_extra"] = "password = \"hunter2\"\n"
    elif case == "env_unset":
        kw["opc_extra"] = ("username_env = \"ARFEM_TEST_UNSET_USER\"\n"
                           "password_env = \"ARFEM_TEST_UNSET_PASSWORD\"\n")
    elif case == "input_unread":
        kw["inputs"] = {"q_W_m2": NODE.format("q_W_m2"), "speed_rpm": NODE.format("speed_rpm")}
    env = {k: v for k, v in os.environ.items() if not k.startswith("ARFEM_TEST_UNSET")}
    r = compensate(mpath, config(tmp_path, url, cycles=5, **kw), env=env)
    assert r.returncode == 2, r.stderr
    assert msg in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "Traceback" not in r.stderr
    assert not (tmp_path / "live.log").exists()    # no cycle ran, nothing was written
    if twin is not None:
        twin.send_signal(signal.SIGTERM)
        assert twin.wait(timeout=30) == 0
        rec = read_csv(tmp_path / "twin.csv")
        assert np.all(rec["offset_um"] == 0.0)    # the machine never received an offset


def test_signed_and_encrypted_with_credentials_from_the_environment(tmp_path, procs,
                                                                    model_file):
    import asyncio

    from asyncua.crypto.cert_gen import setup_self_signed_certificate
    from cryptography.x509.oid import ExtendedKeyUsageOID
    mpath, _ = model_file
    asyncio.run(setup_self_signed_certificate(
        tmp_path / "client_key.pem", tmp_path / "client_cert.der", "urn:freeopcua:client",
        "localhost", [ExtendedKeyUsageOID.CLIENT_AUTH], {"commonName": "arfem test"}))
    env = {**os.environ, "TWIN_USER": "operator", "TWIN_PASSWORD": "s3cret",
           "ARFEM_OPCUA_CERT": str(tmp_path / "client_cert.der"),
           "ARFEM_OPCUA_KEY": str(tmp_path / "client_key.pem"),
           "ARFEM_OPCUA_USER": "operator", "ARFEM_OPCUA_PASSWORD": "s3cret"}
    twin, url = procs.twin(tmp_path, "--steps", "20", "--secure", str(tmp_path / "pki"),
                           "--user-env", "TWIN_USER", "--password-env", "TWIN_PASSWORD",
                           env=env)
    sec = ('security_mode = "SignAndEncrypt"\nsecurity_policy = "Basic256Sha256"\n'
           'certificate_env = "ARFEM_OPCUA_CERT"\nprivate_key_env = "ARFEM_OPCUA_KEY"\n'
           'username_env = "ARFEM_OPCUA_USER"\npassword_env = "ARFEM_OPCUA_PASSWORD"\n')
    cfg = config(tmp_path, url, cycles=20, opc_extra=sec)
    assert "s3cret" not in cfg.read_text()          # the secret lives in the environment
    bad = compensate(mpath, cfg, env={**env, "ARFEM_OPCUA_PASSWORD": "wrong"})
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1, bad.stderr
    assert "opcua.endpoint: cannot connect" in bad.stderr
    assert not (tmp_path / "live.log").exists()
    r = compensate(mpath, cfg, env=env)
    assert r.returncode == 0, r.stderr
    assert twin.wait(timeout=60) == 0
    cyc = [c for c in log_lines(tmp_path) if "cycle" in c]
    assert len(cyc) == 20 and all(c["sent"] and not c["held"] for c in cyc)
    rec = read_csv(tmp_path / "twin.csv")
    assert np.array_equal(rec["offset_um"], [c["offset_um"] for c in cyc])
