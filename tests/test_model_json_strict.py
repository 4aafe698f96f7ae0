"""``model.json`` is read through one strict schema (issue 29).

Properties verified:

* every malformed field the reliability test of issue 29 found (wrong types that gave
  tracebacks, NaN/inf/negative values that gave exit 0 with NaN results, ``kind: [1]``)
  is one :class:`InputError` naming the key;
* ``arfem compensate`` refuses ANY generated malformed model (hypothesis) with exit 2 and
  exactly one ``arfem: error:`` line, and writes nothing;
* the JSON Schema ``docs/model.schema.json`` and the reader agree on the same generated
  documents: whatever the reader accepts is schema-valid; for every change the schema can
  express (types, signs, bounds, keys), the reader accepts exactly what the schema accepts
  (changes only the reader can check -- shapes that must agree, a stable A, increasing map
  points -- are refused by the reader and may pass the schema).
"""
from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from arfem.models.compensator import ar1_model, fit_speed_ar1_model
from arfem.params import InputError
from arfem.scenarios.compensation.model_file import MAX_ABS_NUMBER, model_from_doc, model_to_doc

REPO = Path(__file__).resolve().parents[1]
SCHEMA = json.loads((REPO / "docs" / "model.schema.json").read_text("utf-8"))

AR1 = model_to_doc(ar1_model(0.99, 1e-3, dtau_s=60.0, Q_um2=0.01, R_um2=1e-4))


def _speed_model() -> dict:
    import numpy as np

    from arfem.models.ar1 import ar1_simulate
    sp = np.repeat([0.0, 3000.0, 0.0, 6000.0, 0.0], 200)
    g = ar1_simulate(0.99, np.where(sp == 3000, 0.1, np.where(sp == 6000, 0.25, 0.0)))
    d = model_to_doc(fit_speed_ar1_model(g, sp, dtau_s=60.0))
    d["input_offsets"] = {"speed_rpm": 0.0}
    d["fit_window_s"] = [0.0, 3600.0]
    return json.loads(json.dumps(d))


SPEED = _speed_model()


def _axes_model() -> dict:
    """A version-2 model (issue 32): two sources' powers in, two axes out."""
    import numpy as np

    from arfem.models.modal_export import modal_state_space
    m = modal_state_space([1e-3, 4e-3], [[1e-3, 5e-4], [2e-3, 0.0]],
                          [[2e-6, 1e-6], [-1e-6, 3e-6]], [[0.0, 0.0], [1e-9, 0.0]],
                          dtau_s=60.0, input_map=np.eye(2),
                          inputs=[("P_front_W", "W"), ("P_rear_W", "W")],
                          outputs=[("d_tcp_x_um", "X"), ("d_tcp_z_um", "Z")])
    return json.loads(json.dumps(model_to_doc(m)))


AXES = _axes_model()


def _scheduled_model() -> dict:
    """A version-2 model scheduled over the speed (issue 32): two states in one basis,
    A, B, D at 0 and 6000 rpm, inputs a power, the ambient and the speed."""
    import numpy as np

    from arfem.models.modal_export import speed_scheduled_state_space
    T = [[1.0, 0.0, 0.0], [0.0, 5.0, 0.0]]
    Y = np.array([[0.8, -0.6], [0.6, 0.8]])
    m = speed_scheduled_state_space(
        [0.0, 6000.0], [([1e-3, 4e-3], None, [[0.0, 0.0]] * 2, T),
                        ([2e-3, 6e-3], Y, [[0.0, 0.0]] * 2, T)],
        ([1.5e-3, 5e-3], Y.T, [[0.0, 0.0]] * 2, T), [[1e-3, 5e-4], [2e-3, 1e-4]],
        [[2e-6, 1e-6], [-1e-6, 3e-6]], dtau_s=60.0,
        inputs=[("P_front_W", "W"), ("ambient_C", "°C"), ("speed_rpm", "1/min")],
        outputs=[("d_tcp_y_um", "Y"), ("d_tcp_z_um", "Z")],
        input_offsets={"ambient_C": 20.0})
    return json.loads(json.dumps(model_to_doc(m)))


SCHED = _scheduled_model()
SEEDS = [AR1, SPEED, AXES, SCHED]


# -- the cases of the issue ----------------------------------------------------------------

ISSUE_CASES = [
    ("d0_um", [1.0]), ("d0_um", None), ("d0_um", "abc"), ("d0_um", math.nan),
    ("d0_um", math.inf), ("d0_um", True), ("input_maps", 2), ("input_maps", [1]),
    ("input_offsets", [1]), ("noise", math.nan), ("noise", [1]),
    ("noise", {"Q_um2": "x"}), ("noise", {"Q_um2": -1.0}), ("noise", {"R_um2": math.nan}),
    ("noise", {"Q_um2": math.inf}), ("noise", {"Q_um2": 0.1, "S": 1}), ("kind", [1]),
    ("kind", 3), ("description", 5), ("arfem_version", None), ("fit_window_s", None),
    ("dtau_s", True), ("A", [[True]]), ("B", [["1e-3"]]), ("x0", [None]),
    ("model_version", True), ("output", {"name": "growth_um", "unit": "µm", "x": 1}),
    ("inputs", [{"name": "q_W_m2", "unit": "W/m²", "gain": 2}]),
    ("inputs", [{"name": "heat", "unit": "W/m²"}]), ("A", [[1e300]]), ("B", [[1e13]]),
]


@pytest.mark.parametrize("key,value", ISSUE_CASES, ids=[f"{k}={v!r}" for k, v in ISSUE_CASES])
def test_each_malformed_field_is_one_error_naming_its_key(key, value):
    """Each of these gave a traceback or exit 0 with NaN before issue 29; now the reader
    refuses it in one InputError whose text names the key."""
    doc = {**copy.deepcopy(AR1), key: value}
    with pytest.raises(InputError) as e:
        model_from_doc(doc, "m.json")
    msg = str(e.value)
    assert "\n" not in msg and key in msg, msg


def test_nan_and_infinity_tokens_of_the_file_are_refused(tmp_path):
    """Python's json reads the non-standard NaN/Infinity; read_model refuses them (the
    schema validates JSON, which has no such numbers), and 1e400 (inf) by its key."""
    from arfem.scenarios.compensation.model_file import read_model
    for text, where in (('"d0_um": NaN', "NaN"), ('"d0_um": -Infinity', "Infinity"),
                        ('"d0_um": 1e400', "d0_um")):
        body = json.dumps(AR1).replace('"d0_um": 0.0', text)
        assert text in body
        (tmp_path / "m.json").write_text(body, "utf-8")
        with pytest.raises(InputError, match=where):
            read_model(tmp_path / "m.json")


def test_every_model_arfem_writes_still_reads_back():
    """The strict reading accepts what arfem writes (a round trip is exact)."""
    for doc in SEEDS:
        m = model_from_doc(doc)
        assert json.loads(json.dumps(model_to_doc(m))) == doc


# -- generated malformed models --------------------------------------------------------

#: values of the wrong type or out of range for any key
BAD_VALUES = st.sampled_from([None, True, False, "x", "", [], [1], [[]], {}, {"a": 1}, -1,
                              -1e-300, math.nan, math.inf, -math.inf, 1e13, -1e300,
                              10 ** 30, [[math.nan]], [["1"]], [[None]], 0])


def _paths(doc, prefix=()):
    yield prefix
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from _paths(v, prefix + (i,))


def _set(doc, path, value):
    doc = copy.deepcopy(doc)
    parent = doc
    for p in path[:-1]:
        parent = parent[p]
    parent[path[-1]] = value
    return doc


def _delete(doc, path):
    doc = copy.deepcopy(doc)
    parent = doc
    for p in path[:-1]:
        parent = parent[p]
    del parent[path[-1]]
    return doc


@st.composite
def mutated(draw, malformed_only: bool = True):
    """(document, tag): a seed model with one change. Tag ``layout``: a change the schema
    can state (a type, a sign, a bound, a key); ``relational``: a change that breaks only
    what the schema cannot state (shapes that must agree, stability, increasing map
    points, unique inputs, the window's order); ``maybe``: a value that may or may not
    break such a relation (a number in A, in a map, in the window; a whole matrix)."""
    seed = draw(st.sampled_from(SEEDS))
    paths = [p for p in _paths(seed) if p]
    kind = draw(st.sampled_from(["value", "value", "value", "delete", "extra", "relational"]))
    if kind == "value":
        path = draw(st.sampled_from(paths))
        value = draw(BAD_VALUES)
        doc = _set(seed, path, value)
        # a number where a number goes may still break what only the reader checks: A's
        # stability, the order of map points and of the fit window, a whole matrix or
        # input list replaced (its shape against the others)
        maybe = (path[0] in ("A", "input_maps", "fit_window_s")
                 # a schedule: its speeds' order, its matrices' shapes and stability, the
                 # input it names are the reader's
                 or (path[0] == "speed_schedule" and len(path) > 1)
                 or (path[0] in ("B", "C", "D", "inputs", "outputs") and len(path) < 3)
                 or (path[0] == "x0" and len(path) < 2)
                 or (path[0] == "d0_um" and len(path) < 2 and isinstance(seed["d0_um"], list)))
        return doc, "maybe" if maybe else "layout"
    if kind == "delete":
        required = [p for p in paths if len(p) == 1 and p[0] in SCHEMA["required"]] + \
            [p for p in paths if len(p) == 2 and p[0] == "output"] + \
            [p for p in paths if len(p) == 3 and p[0] == "inputs"] + \
            [p for p in paths if len(p) == 2 and p[0] == "speed_schedule"]
        return _delete(seed, draw(st.sampled_from(required))), "layout"
    if kind == "extra":
        where = draw(st.sampled_from([(), ("noise",), ("output",)]))
        doc = copy.deepcopy(seed)
        target = doc
        for p in where:
            target = target.setdefault(p, {})
        target[draw(st.sampled_from(["gain", "Q", "colour", "R"]))] = 1
        return doc, "layout"
    change = draw(st.sampled_from(["B_shape", "C_shape", "x0_shape", "unstable", "map_order",
                                   "map_len", "offset_name", "window_order", "dup_input"]))
    doc = copy.deepcopy(seed)
    if change == "B_shape":
        doc["B"] = [row + [0.0] for row in doc["B"]]
    elif change == "C_shape":
        doc["C"] = [doc["C"][0] + [1.0]]
    elif change == "x0_shape":
        doc["x0"] = doc["x0"] + [0.0]
    elif change == "unstable":
        doc["A"] = [[1.5]]
    elif change == "map_order" and doc.get("input_maps"):
        m = next(iter(doc["input_maps"].values()))
        m["x"] = list(reversed(m["x"]))
    elif change == "map_len" and doc.get("input_maps"):
        m = next(iter(doc["input_maps"].values()))
        m["y"] = m["y"] + [1.0]
    elif change == "offset_name":
        doc["input_offsets"] = {"ambient_C": 20.0}
    elif change == "window_order":
        doc["fit_window_s"] = [10.0, 0.0]
    else:
        doc["inputs"] = doc["inputs"] + doc["inputs"]
        doc["B"] = [row * 2 for row in doc["B"]]
        doc["D"] = [row * 2 for row in doc["D"]]
    return doc, "relational"


def _reader_accepts(doc) -> bool:
    try:
        model_from_doc(doc)
    except InputError:
        return False
    return True


def _schema_accepts(doc) -> bool:
    import jsonschema
    try:
        jsonschema.validate(doc, SCHEMA)
    except jsonschema.ValidationError:
        return False
    return True


def _finite(doc) -> bool:
    """JSON has no NaN/inf: the schema is about documents without them (read_model
    refuses the tokens before either is asked)."""
    try:
        json.dumps(doc, allow_nan=False)
    except ValueError:
        return False
    return True


CI = settings(max_examples=200, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.too_slow,
                                     HealthCheck.function_scoped_fixture])


@CI
@given(case=mutated())
def test_schema_and_reader_agree_on_generated_documents(case):
    """Same generated document to both: the reader never accepts what the schema refuses;
    for a change the schema can express, they accept exactly the same documents."""
    doc, tag = case
    reader = _reader_accepts(doc)
    if not _finite(doc):
        assert not reader                    # and read_model refuses NaN/Infinity tokens
        return
    schema = _schema_accepts(doc)
    if reader:
        assert schema, doc
    if tag == "layout":
        assert reader == schema, (doc, reader, schema)
    elif tag == "relational":
        assert not reader or doc in SEEDS    # refused, unless the change was a no-op


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    """A small q_W_m2 record at Δτ = 60 s (the models' interval)."""
    from arfem.models.diagnosis.synth import generate
    from arfem.scenarios.records.synth_files import write_case
    d = tmp_path_factory.mktemp("rec")
    case = generate("none", 3, duration_h=3.0, interval_s=60, jitter_s=0.0, n_gaps=0,
                    empty_fraction=0.0, n_outliers=0)
    return write_case(case, d)


@CI
@given(case=mutated())
def test_compensate_refuses_any_malformed_model_in_one_line(case, record, tmp_path_factory,
                                                             capsys):
    """``arfem compensate`` on a generated malformed model (and the record it would
    replay): exit 2, exactly one ``arfem: error:`` line naming the file, no --out made."""
    from arfem.scenarios.cli import main
    doc, _ = case
    if _reader_accepts(doc):                 # a change that left the model valid
        return
    d = tmp_path_factory.mktemp("m")
    (d / "model.json").write_text(json.dumps(doc), "utf-8")
    capsys.readouterr()
    rc = main(["compensate", str(d / "model.json"), str(record), "--out", str(d / "o")])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2
    assert len(err) == 1 and err[0].startswith("arfem: error:") and "model.json" in err[0], err
    assert not (d / "o").exists()


V2_CASES = [
    ("outputs", []), ("outputs", [{"name": "d_tcp_x_um", "unit": "µm"}]),
    ("outputs", [{"name": "tcp_x", "unit": "µm", "axis": "X"}] * 2),
    ("outputs", [{"name": "d_a_um", "unit": "mm", "axis": "X"},
                 {"name": "d_b_um", "unit": "µm", "axis": "Z"}]),
    ("outputs", [{"name": "d_a_um", "unit": "µm", "axis": "X"},
                 {"name": "d_b_um", "unit": "µm", "axis": "X"}]),
    ("d0_um", 0.0), ("d0_um", [0.0]), ("C", [[1.0, 0.0]]), ("D", [[0.0, 0.0]] * 3),
    ("output", {"name": "growth_um", "unit": "µm"}),
    ("inputs", [{"name": "P_front", "unit": "W"}, {"name": "P_rear_W", "unit": "W"}]),
]


def _sched(**change) -> dict:
    doc = copy.deepcopy(SCHED)
    doc["speed_schedule"].update(change)
    return doc


_S = SCHED["speed_schedule"]
SCHEDULE_CASES = [
    ("not increasing", _sched(speeds_rpm=[6000.0, 0.0]), "speeds_rpm"),
    ("equal speeds", _sched(speeds_rpm=[0.0, 0.0]), "speeds_rpm"),
    ("negative speed", _sched(speeds_rpm=[-1.0, 6000.0]), "speeds_rpm"),
    ("one speed", _sched(speeds_rpm=[0.0], A=_S["A"][:1], B=_S["B"][:1], D=_S["D"][:1]),
     "speeds_rpm"),
    ("A per speed missing", _sched(A=_S["A"][:1]), "speed_schedule.A"),
    ("B of another shape", _sched(B=[[r + [0.0] for r in b] for b in _S["B"]]),
     "speed_schedule.B[0]"),
    ("D of another shape", _sched(D=[d[:1] for d in _S["D"]]), "speed_schedule.D[0]"),
    ("A not finite (beyond the bound)", _sched(A=[_S["A"][0], [[1e300, 0.0], [0.0, 0.5]]]),
     "speed_schedule.A[1][0][0]"),
    ("A that would not settle", _sched(A=[_S["A"][0], [[1.2, 0.0], [0.0, 0.5]]]),
     "speed_schedule.A[1]"),
    ("an input the model does not read", _sched(input="feed_rpm"), "speed_schedule.input"),
    ("a key missing", {**SCHED, "speed_schedule": {k: v for k, v in _S.items()
                                                   if k != "D"}}, "speed_schedule.D"),
    ("an unknown key", _sched(h=1), "speed_schedule"),
    ("in version 1", {**copy.deepcopy(AR1), "speed_schedule": _S}, "speed_schedule"),
]


@pytest.mark.parametrize("what,doc,key", SCHEDULE_CASES, ids=[c[0] for c in SCHEDULE_CASES])
def test_bad_speed_schedules_are_one_error_naming_the_key(what, doc, key, tmp_path, capsys):
    """A speed schedule whose speeds do not increase strictly (or are fewer than two, or
    negative), whose matrices are not one per speed in the model's shapes, finite and
    settling, that names no input of the model, lacks a key or has an unknown one, or
    sits in a version-1 model: one InputError naming the key, and ``arfem compensate``
    exits 2 with one line, writing nothing."""
    from arfem.scenarios.cli import main
    with pytest.raises(InputError) as e:
        model_from_doc(doc, "m.json")
    msg = str(e.value)
    assert "\n" not in msg and key in msg, msg
    (tmp_path / "model.json").write_text(json.dumps(doc), "utf-8")
    rec = tmp_path / "r.csv"
    rec.write_text("time_s,P_front_W,ambient_C,speed_rpm,d_tcp_y_um,d_tcp_z_um\n"
                   + "".join(f"{60 * i},1.0,20.0,0.0,0.0,0.0\n" for i in range(5)))
    (tmp_path / "r.toml").write_text('[dataset]\nname = "r"\ncsv = "r.csv"\n')
    capsys.readouterr()
    rc = main(["compensate", str(tmp_path / "model.json"), str(tmp_path / "r.toml"),
               "--out", str(tmp_path / "o")])
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2 and len(err) == 1 and "speed_schedule" in err[0], err
    assert not (tmp_path / "o").exists()


def test_a_scheduled_model_reads_back_and_the_schema_takes_it():
    """The speed schedule round-trips exactly and is schema-valid; a model without one
    writes no ``speed_schedule`` key (version 2 as before)."""
    m = model_from_doc(SCHED)
    assert m.schedule is not None and m.schedule.speeds_rpm.tolist() == [0.0, 6000.0]
    assert json.loads(json.dumps(model_to_doc(m))) == SCHED and _schema_accepts(SCHED)
    assert "speed_schedule" not in AXES and model_from_doc(AXES).schedule is None


@pytest.mark.parametrize("key,value", V2_CASES, ids=[f"{k}={v!r}" for k, v in V2_CASES])
def test_version_2_refusals_name_their_key(key, value):
    """A version-2 model with a wrong ``outputs`` (none, a key missing, a name that is
    not a displacement column, a unit not µm, an axis twice), a ``d0_um`` not one per
    output, C/D with other than one row per output, a version-1 ``output``, an input
    name outside the contract: one InputError naming the key (``output`` is named
    through model_version, whose layout it is not)."""
    doc = {**copy.deepcopy(AXES), key: value}
    with pytest.raises(InputError) as e:
        model_from_doc(doc, "m.json")
    msg = str(e.value)
    assert "\n" not in msg and (key in msg or "model_version" in msg), msg
    assert not _schema_accepts(doc) or key in ("outputs", "d0_um", "C", "D"), doc


def test_version_1_documents_are_written_as_before():
    """A one-output model's document has no key of version 2 (byte-identical files)."""
    assert AR1["model_version"] == 1 and "outputs" not in AR1 and AR1["output"] == {
        "name": "growth_um", "unit": "µm"}
    assert AXES["model_version"] == 2 and "output" not in AXES
    assert [o["axis"] for o in AXES["outputs"]] == ["X", "Z"]
    assert _schema_accepts(AR1) and _schema_accepts(AXES)


def test_bound_is_stated_in_the_schema():
    """The magnitude bound of the reader is the schema's (one number, not two)."""
    assert SCHEMA["$defs"]["number"]["maximum"] == MAX_ABS_NUMBER
    assert SCHEMA["$defs"]["number"]["minimum"] == -MAX_ABS_NUMBER
    assert SCHEMA["$defs"]["variance"]["minimum"] == 0
