"""``model.json``: the state-space model a compensator runs (``docs/model-json.md``), its
format read and written here and nowhere else.

Reading (:func:`read_model`, :func:`model_from_doc`) refuses, in one line naming the
file and the key, a file that is not JSON (the non-standard tokens ``NaN`` and
``Infinity`` included), of another ``model_version``, with a key of the wrong type,
matrices of the wrong shape or not finite, a negative variance, or a model that would
not settle; ``docs/model.schema.json`` states the same as a JSON Schema. It is built on
the one strict reader (:mod:`arfem.strict`: JSON numbers, objects, strings, number
arrays of a shape). Writing (:func:`write_model`, :func:`model_to_doc`) gives the
document back exactly: a model read and written again is the same file.

The model itself (:class:`arfem.models.compensator.StateSpaceModel`, its observer
:class:`arfem.models.observer.Observer`) is pure: arrays and dataclasses, no format.
"""
from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from arfem.io import read_text_utf8, write_json
from arfem.models.compensator import InputSpec, OutputSpec, SpeedSchedule, StateSpaceModel
from arfem.models.observer import (STABLE_RADIUS, Disturbance, Observer,
                                   noise_from_table)
from arfem.params import InputError
from arfem.strict import (json_number, json_object, json_string, number_array, shaped,
                          short_repr)

__all__ = ["read_model", "write_model", "model_from_doc", "model_to_doc", "MODEL_VERSION",
           "MODEL_VERSIONS", "MAX_ABS_NUMBER", "MODEL_REQUIRED", "MODEL_OPTIONAL",
           "MODEL_REQUIRED_V2", "MODEL_OPTIONAL_V2", "OBSERVER_REQUIRED",
           "OBSERVER_OPTIONAL"]

#: version of the ``model.json`` layout of a one-output model (the rod's growth)
MODEL_VERSION = 1
#: the versions this module reads: 1 (one output, ``growth_um``) and 2 (several outputs,
#: one per axis)
MODEL_VERSIONS = (1, 2)

#: Largest magnitude of any number in a ``model.json`` (matrix entries, d0_um, variances,
#: map points, offsets, the fit window, Δτ). Far beyond any physical model (growth in µm,
#: inputs in W/m², 1/min, °C, s) and far enough from the float range that a stable model
#: run on any accepted record stays finite; ``docs/model.schema.json`` states the same.
MAX_ABS_NUMBER = 1e12

#: The keys of ``model.json`` (``docs/model.schema.json``), required ones first.
MODEL_REQUIRED = ("model_version", "kind", "dtau_s", "inputs", "output", "A", "B", "C",
                  "D", "d0_um", "x0")
MODEL_OPTIONAL = ("noise", "input_maps", "input_offsets", "fit_window_s", "description",
                  "arfem_version")
#: version 2 may also hold ``speed_schedule`` (:class:`SpeedSchedule`)
MODEL_OPTIONAL_V2 = MODEL_OPTIONAL + ("speed_schedule", "observer")
#: version 2: ``outputs`` (several, each with its axis) in place of ``output``
MODEL_REQUIRED_V2 = tuple("outputs" if k == "output" else k for k in MODEL_REQUIRED)
#: input names of the measured-data contract (the schema's ``pattern``)
INPUT_NAME_PATTERN = r"^(q_W_m2|speed_rpm|ambient_C|T_[A-Za-z0-9_]+_C)$"
#: version 2 also reads each heat source's power ``P_<source>_W`` [W] or flux
#: ``q_<source>_W_m2`` [W/m²] (the sources of a ``[geometry]`` scenario)
INPUT_NAME_PATTERN_V2 = (r"^(q_W_m2|speed_rpm|ambient_C|T_[A-Za-z0-9_]+_C|P_[A-Za-z0-9_]+_W"
                         r"|q_[A-Za-z0-9_]+_W_m2)$")
#: version 2's output names: a displacement sensor's column, and axis names
OUTPUT_NAME_PATTERN = r"^d_[A-Za-z0-9_]+_um$"
AXIS_PATTERN = r"^[A-Za-z][A-Za-z0-9_]{0,31}$"


def read_model(path, limits=None) -> StateSpaceModel:
    """Read and validate ``model.json`` (:func:`model_from_doc`).

    Raises
    ------
    InputError
        ``<file>: <key>: <what is wrong>``.
    """
    text = read_text_utf8(path, limits=limits)

    def constant(token):
        raise InputError(f"holds {token}, which is not a JSON number (every number of a "
                         "model must be finite)", str(path))
    try:
        doc = json.loads(text, parse_constant=constant)
    except InputError:
        raise
    except json.JSONDecodeError as exc:
        raise InputError(f"is not JSON ({exc.msg} at line {exc.lineno})", str(path)) from None
    except (ValueError, RecursionError) as exc:     # an integer of > 4300 digits, nesting
        raise InputError(f"is not JSON arfem can read ({' '.join(str(exc).split())[:80]})",
                         str(path)) from None
    return model_from_doc(doc, str(path))


def write_model(path, model: StateSpaceModel) -> None:
    """Write ``model.json`` atomically (:func:`model_to_doc`)."""
    write_json(Path(path), model_to_doc(model))


def _number(v, key: str, what: str = "a finite number", low: float | None = None,
            low_open: bool = False) -> float:
    """:func:`arfem.strict.json_number` within :data:`MAX_ABS_NUMBER`."""
    return json_number(v, key, what, bound=MAX_ABS_NUMBER, low=low, low_open=low_open)


def _numbers(v, key: str, ndim: int, min_len: int = 0) -> np.ndarray:
    """:func:`arfem.strict.number_array` within :data:`MAX_ABS_NUMBER`."""
    return number_array(v, key, ndim, min_len, bound=MAX_ABS_NUMBER)


def model_from_doc(d, where: str = "model") -> StateSpaceModel:
    """The one strict reading of a ``model.json`` document (parsed JSON); every refusal
    is one :class:`InputError` ``<where>: <key>: <what is wrong>``.

    It checks what ``docs/model.schema.json`` states (every key's type, strings where
    strings go, numbers that are JSON numbers -- not booleans -- finite and within
    :data:`MAX_ABS_NUMBER`, variances >= 0) and what a schema cannot (shapes that
    agree, an A that settles, maps that increase). Version 1 has one output (``output``,
    ``growth_um``); version 2 several (``outputs``, each with its axis).

    Examples
    --------
    >>> from arfem.models.compensator import ar1_model
    >>> m = ar1_model(0.99, 1e-4, dtau_s=30.0)
    >>> model_from_doc(model_to_doc(m)).A.tolist()
    [[0.99]]
    >>> model_from_doc({**model_to_doc(m), "model_version": 7})
    Traceback (most recent call last):
    ...
    arfem.params.InputError: model: model_version: is 7; this arfem reads versions 1 and 2
    >>> model_from_doc({**model_to_doc(m), "d0_um": float("nan")})
    Traceback (most recent call last):
    ...
    arfem.params.InputError: model: d0_um: must be a finite number of µm, got nan
    """
    if not isinstance(d, dict):
        raise InputError("must be a JSON object", where)
    k = lambda name: f"{where}: {name}"              # noqa: E731 - the key's label
    version = _read_layout(d, where, k)
    kind = json_string(d["kind"], k("kind"))
    dtau = _number(d["dtau_s"], k("dtau_s"), "a positive number of seconds", 0.0, True)
    names = _read_inputs(d["inputs"], k, INPUT_NAME_PATTERN if version == 1
                         else INPUT_NAME_PATTERN_V2)
    if version == 1:
        out = json_object(d["output"], k("output"), ("name", "unit"), ("name", "unit"))
        if out["name"] != "growth_um" or out["unit"] != "µm":
            raise InputError(f"must be {{\"name\": \"growth_um\", \"unit\": \"µm\"}}, got "
                             f"{short_repr(out)}", k("output"))
        outputs = ()
    else:
        outputs = _read_outputs(d["outputs"], k)
    A, B, C, D, x0 = _read_matrices(d, k, len(names), max(len(outputs), 1))
    if version == 1:
        d0 = _number(d["d0_um"], k("d0_um"), "a finite number of µm")
    else:
        d0 = tuple(float(v) for v in shaped(_numbers(d["d0_um"], k("d0_um"), 1),
                                             (len(outputs),), k("d0_um")))
    noise = json_object(d.get("noise", {}), k("noise"), ("Q_um2", "R_um2"))
    Q, R = (_number(noise.get(q, 0.0), k(f"noise.{q}"), "a finite variance >= 0 [µm²]", 0.0)
            for q in ("Q_um2", "R_um2"))
    maps, offsets = _read_maps(d, k, names), _read_offsets(d, k, names)
    fw = _read_window(d, k)
    description = json_string(d.get("description", ""), k("description"))
    arfem_version = json_string(d.get("arfem_version", ""), k("arfem_version"))
    schedule = (_read_schedule(d["speed_schedule"], k, names, A.shape, B.shape, D.shape,
                               maps) if "speed_schedule" in d else None)
    model = StateSpaceModel(kind=kind, dtau_s=dtau, A=A, B=B, C=C, D=D,
                inputs=tuple(InputSpec(s["name"], s["unit"]) for s in d["inputs"]), x0=x0,
                d0_um=d0, Q=Q, R=R, description=description, arfem_version=arfem_version,
                input_maps=maps, input_offsets=offsets, fit_window_s=fw, outputs=outputs,
                schedule=schedule)
    if "observer" in d:                             # version 2's thermometers (issue 43)
        model = replace(model, observer=_read_observer(d["observer"], k("observer"), model))
    return model


def _read_layout(d: dict, where: str, k) -> int:
    """The document's ``model_version`` (1 or 2), once its keys are those of that
    version's layout: every required one, no unknown one, ``output`` (version 1) or
    ``outputs`` (version 2)."""
    version = d.get("model_version")
    if version not in MODEL_VERSIONS or isinstance(version, bool):
        extra = sorted(set(d) - set(MODEL_REQUIRED) - set(MODEL_OPTIONAL_V2)
                       - {"outputs"}, key=str)
        if extra:
            raise InputError(f"unknown key {extra[0]!r}", where)
        raise InputError(f"is {short_repr(version)}; this arfem reads versions 1 and 2",
                         k("model_version"))
    required = MODEL_REQUIRED if version == 1 else MODEL_REQUIRED_V2
    other = "outputs" if version == 1 else "output"
    if other in d and other not in required and (version == 1) != ("output" in d):
        raise InputError(f"is {version}, whose layout has {'output' if version == 1 else 'outputs'}"
                         f", not {other} (version 1: one output, growth_um; version 2: one "
                         "output per axis)", k("model_version"))
    optional = MODEL_OPTIONAL if version == 1 else MODEL_OPTIONAL_V2
    extra = sorted(set(d) - set(required) - set(optional), key=str)
    if extra:
        raise InputError(f"unknown key {extra[0]!r}" + (
            " (a speed schedule is read in version 2 only)" if extra[0] == "speed_schedule"
            else ""), where)
    for name in required:
        if name not in d:
            raise InputError("missing", k(name))
    return version


def _read_inputs(ins, k, pattern: str) -> list:
    """The input names of ``inputs``: ``{name, unit}`` each, names matching ``pattern``
    (the measured-data contract's), each once."""
    if not isinstance(ins, list):
        raise InputError(f"must be a list of {{name, unit}}, got {short_repr(ins)}",
                         k("inputs"))
    names = []
    for i, spec in enumerate(ins):
        key = k(f"inputs[{i}]")
        json_object(spec, key, ("name", "unit"), ("name", "unit"))
        name = json_string(spec["name"], f"{key}.name")
        json_string(spec["unit"], f"{key}.unit")
        if not re.match(pattern, name):
            raise InputError(f"{name!r} is not an input of the measured-data contract "
                             "(q_W_m2, speed_rpm, ambient_C, T_<name>_C"
                             + (", P_<source>_W, q_<source>_W_m2)" if pattern
                                != INPUT_NAME_PATTERN else ")"), f"{key}.name")
        if name in names:
            raise InputError(f"{name!r} is read twice", f"{key}.name")
        names.append(name)
    return names


def _read_outputs(outs, k) -> tuple:
    """Version 2's ``outputs``: at least one ``{name, unit, axis}``, names
    ``d_<sensor>_um`` in µm, names and axes each once."""
    if not isinstance(outs, list) or not outs:
        raise InputError(f"must be a list of at least one {{name, unit, axis}}, got "
                         f"{short_repr(outs)}", k("outputs"))
    specs = []
    for i, spec in enumerate(outs):
        key = k(f"outputs[{i}]")
        json_object(spec, key, ("name", "unit", "axis"), ("name", "unit", "axis"))
        name = json_string(spec["name"], f"{key}.name")
        axis = json_string(spec["axis"], f"{key}.axis")
        if json_string(spec["unit"], f"{key}.unit") != "µm":
            raise InputError(f"must be \"µm\", got {spec['unit']!r}", f"{key}.unit")
        if not re.match(OUTPUT_NAME_PATTERN, name):
            raise InputError(f"{name!r} is not a displacement column d_<sensor>_um",
                             f"{key}.name")
        if not re.match(AXIS_PATTERN, axis):
            raise InputError(f"{axis!r} is not an axis name (a letter, then letters, "
                             "digits or _; e.g. X)", f"{key}.axis")
        if any(o.name == name for o in specs) or any(o.axis == axis for o in specs):
            raise InputError("names an output or an axis twice", key)
        specs.append(OutputSpec(name, "µm", axis))
    return tuple(specs)


def _read_matrices(d, k, m: int, p: int) -> tuple:
    """A (n × n, stable), B (n × m), C (p × n), D (p × m) and x0 (n)."""
    A = _numbers(d["A"], k("A"), 2)
    if A.shape[0] != (A.shape[1] if A.ndim == 2 else 0):
        raise InputError(f"must be square, got shape {A.shape}", k("A"))
    n = A.shape[0]
    B = shaped(_numbers(d["B"], k("B"), 2), (n, m), k("B"))
    rows = "one row" if p == 1 else f"{p} rows, one per output"
    C = _numbers(d["C"], k("C"), 2)
    if C.shape[0] != p:
        raise InputError(f"must be {rows}, got {C.shape[0]}", k("C"))
    C = shaped(C, (p, n), k("C"))
    D = _numbers(d["D"], k("D"), 2)
    if D.shape[0] != p:
        raise InputError(f"must be {rows}, got {D.shape[0]}", k("D"))
    D = shaped(D, (p, m), k("D"))
    x0 = shaped(_numbers(d["x0"], k("x0"), 1), (n,), k("x0"))
    if n and np.max(np.abs(np.linalg.eigvals(A))) >= 1.0:
        raise InputError("has an eigenvalue on or outside the unit circle: the model "
                         "would not settle", k("A"))
    return A, B, C, D, x0


def _read_schedule(v, k, names, a_shape, b_shape, d_shape, maps) -> SpeedSchedule:
    """``speed_schedule`` (version 2): ``input`` an input the model reads (unmapped),
    ``speeds_rpm`` strictly increasing (at least two, >= 0), and per speed an A, B, D of
    the model's shapes, finite, each A settling."""
    key = k("speed_schedule")
    json_object(v, key, ("input", "speeds_rpm", "A", "B", "D"),
            ("input", "speeds_rpm", "A", "B", "D"))
    name = json_string(v["input"], f"{key}.input")
    if name not in names:
        raise InputError(f"{name!r} is not an input the model reads", f"{key}.input")
    if name in maps:
        raise InputError(f"{name!r} has an input map; a schedule reads the raw speed",
                         f"{key}.input")
    x = _numbers(v["speeds_rpm"], f"{key}.speeds_rpm", 1, 2)
    if np.any(np.diff(x) <= 0) or x[0] < 0:
        raise InputError("must be speeds >= 0 [1/min], strictly increasing, got "
                         + short_repr(x.tolist()), f"{key}.speeds_rpm")
    mats = []
    for nm, shape in (("A", a_shape), ("B", b_shape), ("D", d_shape)):
        at = f"{key}.{nm}"
        lst = v[nm]
        if not isinstance(lst, list) or len(lst) != x.size:
            raise InputError(f"must be a list of {x.size} matrices, one per speed, got "
                             + short_repr(lst), at)
        mats.append(np.array([shaped(_numbers(m, f"{at}[{i}]", 2), shape, f"{at}[{i}]")
                              for i, m in enumerate(lst)]).reshape((x.size,) + shape))
    for i, Ai in enumerate(mats[0]):
        if Ai.size and np.max(np.abs(np.linalg.eigvals(Ai))) >= 1.0:
            raise InputError("has an eigenvalue on or outside the unit circle: the model "
                             "would not settle", f"{key}.A[{i}]")
    return SpeedSchedule(name, x, *mats)


def _read_maps(d, k, names) -> dict:
    """``input_maps``: name → (x, y), x strictly increasing, as many x as y."""
    maps = {}
    for name, mp in json_object(d.get("input_maps", {}), k("input_maps")).items():
        key = k(f"input_maps.{name}")
        json_object(mp, key, ("x", "y"), ("x", "y"))
        x = _numbers(mp["x"], f"{key}.x", 1, 1)
        y = _numbers(mp["y"], f"{key}.y", 1, 1)
        if name not in names:
            raise InputError("maps an input the model does not read", key)
        if x.shape != y.shape or np.any(np.diff(x) <= 0):
            raise InputError("x must increase strictly and match y, all finite", key)
        maps[name] = (x, y)
    return maps


def _read_offsets(d, k, names) -> dict:
    """``input_offsets``: name → the reference subtracted from the reading."""
    offsets = {}
    for name, v in json_object(d.get("input_offsets", {}), k("input_offsets")).items():
        key = k(f"input_offsets.{name}")
        offsets[name] = _number(v, key)
        if name not in names:
            raise InputError("offsets an input the model does not read", key)
    return offsets


def _read_window(d, k):
    """``fit_window_s``: (first, last) in order, or None where the key is absent."""
    if "fit_window_s" not in d:                      # null is not a window: refused
        return None
    fw = d["fit_window_s"]
    bad = InputError(f"must be [first, last] sample times in seconds, got "
                     f"{short_repr(fw)}", k("fit_window_s"))
    if not (isinstance(fw, list) and len(fw) == 2):
        raise bad
    fw = tuple(_number(v, k("fit_window_s")) for v in fw)
    if fw[0] > fw[1]:
        raise bad
    return fw


#: keys of ``model.json``'s ``observer`` block, required ones first
OBSERVER_REQUIRED = ("thermometers", "C", "D", "z0_C", "disturbances", "uniform", "noise",
                     "gain")
OBSERVER_OPTIONAL = ("speeds_rpm",)


def _read_observer(v, key: str, model) -> Observer:
    """The strict reading of ``model.json``'s ``observer`` block against ``model``
    (the StateSpaceModel read so far); one :class:`InputError` naming the key.

    Checked: the keys; thermometer names ``T_<sensor>_C`` in °C, each once; C (q × n),
    D (q × m), z0_C (q), uniform (n) of the model's shapes; each disturbance an input
    the model reads (a source's or ``ambient_C``; not the speed), once, with a strength
    >= 0; the noise levels (:func:`noise_from_table`); one gain (n + n_d) × q per
    tabulated speed of the model's schedule (one without), ``speeds_rpm`` equal to the
    schedule's; and that the observer settles at every tabulated speed (the spectral
    radius of (I − K H) F below 1).
    """
    json_object(v, key, OBSERVER_REQUIRED + OBSERVER_OPTIONAL, OBSERVER_REQUIRED)
    n, m = model.n_states, len(model.inputs)
    ts = v["thermometers"]
    if not isinstance(ts, list) or not ts:
        raise InputError("must be a list of at least one {name, unit}", f"{key}.thermometers")
    names = []
    for i, t in enumerate(ts):
        at = f"{key}.thermometers[{i}]"
        json_object(t, at, ("name", "unit"), ("name", "unit"))
        nm = json_string(t["name"], f"{at}.name")
        if not re.match(r"^T_[A-Za-z0-9_]+_C$", nm) or nm in names:
            raise InputError(f"{nm!r} is not a thermometer column T_<sensor>_C named once",
                             f"{at}.name")
        if json_string(t["unit"], f"{at}.unit") != "°C":
            raise InputError(f"must be \"°C\", got {t['unit']!r}", f"{at}.unit")
        names.append(nm)
    q = len(names)
    C_T = shaped(_numbers(v["C"], f"{key}.C", 2), (q, n), f"{key}.C")
    D_T = shaped(_numbers(v["D"], f"{key}.D", 2), (q, m), f"{key}.D")
    z0 = shaped(_numbers(v["z0_C"], f"{key}.z0_C", 1), (q,), f"{key}.z0_C")
    uniform = shaped(_numbers(v["uniform"], f"{key}.uniform", 1), (n,), f"{key}.uniform")
    noise = noise_from_table(json_object(v["noise"], f"{key}.noise"), f"{key}.noise")
    dist, cols = _read_disturbances(v["disturbances"], f"{key}.disturbances", model)
    sched = model.schedule
    S = 1 if sched is None else sched.speeds_rpm.size
    g = v["gain"]
    if not isinstance(g, list) or len(g) != S:
        raise InputError(f"must be a list of {S} gain matrices (one per tabulated speed)",
                         f"{key}.gain")
    gains = np.array([shaped(_numbers(gk, f"{key}.gain[{i}]", 2), (n + len(dist), q),
                              f"{key}.gain[{i}]") for i, gk in enumerate(g)])
    speeds = None
    if sched is not None or "speeds_rpm" in v:
        speeds = _numbers(v.get("speeds_rpm"), f"{key}.speeds_rpm", 1) \
            if "speeds_rpm" in v else None
        if sched is None or speeds is None or not np.array_equal(speeds, sched.speeds_rpm):
            raise InputError("must equal the speed schedule's speeds_rpm (and is only for "
                             "a model with one)", f"{key}.speeds_rpm")
    ob = Observer(tuple(names), C_T, D_T, z0, dist, cols, uniform, noise,
                  float(model.dtau_s), gains, speeds)
    pairs = [(model.A, model.B)] if sched is None else list(zip(sched.A, sched.B))
    for i, (A, B) in enumerate(pairs):
        if not ob.closed_loop_radius(A, B, i) < STABLE_RADIUS:
            raise InputError("the observer with this gain would not settle (an eigenvalue "
                             "of (I - K H) F on or outside the unit circle)",
                             f"{key}.gain[{i}]")
    return ob


def _read_disturbances(ds, key: str, model) -> tuple:
    """``disturbances``: [{input, unit, sigma_per_sqrt_h}] → (Disturbance tuple, columns)."""
    if not isinstance(ds, list):
        raise InputError("must be a list of {input, unit, sigma_per_sqrt_h}", key)
    names = [i.name for i in model.inputs]
    out, cols = [], []
    for i, d in enumerate(ds):
        at = f"{key}[{i}]"
        json_object(d, at, ("input", "unit", "sigma_per_sqrt_h"),
                ("input", "unit", "sigma_per_sqrt_h"))
        nm = json_string(d["input"], f"{at}.input")
        if nm not in names or not (nm == "ambient_C" or nm.startswith(("P_", "q_"))):
            raise InputError(f"{nm!r} is not a source's input or ambient_C the model reads",
                             f"{at}.input")
        if nm in [x.input for x in out]:
            raise InputError(f"{nm!r} has two disturbances", f"{at}.input")
        unit = json_string(d["unit"], f"{at}.unit")
        want = "K" if nm == "ambient_C" else model.inputs[names.index(nm)].unit
        if unit != want:
            raise InputError(f"must be {want!r} (the unit of {nm}'s estimate), got {unit!r}",
                             f"{at}.unit")
        s = _number(d["sigma_per_sqrt_h"], f"{at}.sigma_per_sqrt_h",
                    "a finite strength >= 0", 0.0)
        out.append(Disturbance(nm, unit, s))
        cols.append(names.index(nm))
    return tuple(out), tuple(cols)


def model_to_doc(m: StateSpaceModel) -> dict:
    """The ``model.json`` document of ``m`` (``docs/model-json.md``): version 1 for a
    model without named outputs (``output``, ``d0_um`` a number), else version 2
    (``outputs``, ``d0_um`` a list, its speed schedule and observer where it has them).

    >>> from arfem.models.compensator import ar1_model
    >>> list(model_to_doc(ar1_model(0.99, 1e-4, dtau_s=30.0)))[:6]
    ['model_version', 'kind', 'dtau_s', 'inputs', 'output', 'A']
    """
    v2 = bool(m.outputs)
    return {"model_version": 2 if v2 else MODEL_VERSION, "kind": m.kind, "dtau_s": m.dtau_s,
            "inputs": [{"name": i.name, "unit": i.unit} for i in m.inputs],
            **({"outputs": [{"name": o.name, "unit": o.unit, "axis": o.axis}
                            for o in m.outputs]} if v2 else
               {"output": {"name": "growth_um", "unit": "µm"}}),
            "A": m.A.tolist(), "B": m.B.tolist(), "C": m.C.tolist(), "D": m.D.tolist(),
            "d0_um": [float(v) for v in m.d0_vector()] if v2 else m.d0_um,
            "x0": m.x0.tolist(), "noise": {"Q_um2": m.Q, "R_um2": m.R},
            "input_maps": {k: {"x": x.tolist(), "y": y.tolist()}
                           for k, (x, y) in m.input_maps.items()},
            "description": m.description, "arfem_version": m.arfem_version,
            **({"input_offsets": dict(m.input_offsets)} if m.input_offsets else {}),
            **({"fit_window_s": [float(v) for v in m.fit_window_s]}
               if m.fit_window_s is not None else {}),
            **({"speed_schedule": _schedule_doc(m.schedule)}
               if m.schedule is not None else {}),
            **({"observer": _observer_doc(m.observer)} if m.observer is not None else {})}


def _schedule_doc(s: SpeedSchedule) -> dict:
    """The ``speed_schedule`` object of ``model.json``."""
    return {"input": s.input, "speeds_rpm": [float(v) for v in s.speeds_rpm],
            "A": s.A.tolist(), "B": s.B.tolist(), "D": s.D.tolist()}


def _observer_doc(ob: Observer) -> dict:
    """The ``observer`` block of ``model.json`` (``docs/model-json.md``)."""
    n = ob.noise
    return {"thermometers": [{"name": t, "unit": "°C"} for t in ob.thermometers],
            "C": ob.C_T.tolist(), "D": ob.D_T.tolist(),
            "z0_C": [float(v) for v in ob.z0_C],
            "disturbances": [{"input": d.input, "unit": d.unit,
                              "sigma_per_sqrt_h": d.sigma_per_sqrt_h}
                             for d in ob.disturbances],
            "uniform": ob.uniform.tolist(),
            "noise": {"thermometer_K": n.thermometer_K,
                      "heat_per_sqrt_h": n.heat_per_sqrt_h,
                      "ambient_K_per_sqrt_h": n.ambient_K_per_sqrt_h,
                      "uniform_K_per_sqrt_h": n.uniform_K_per_sqrt_h,
                      "time_constant_h": n.time_constant_h},
            "gain": ob.gains.tolist(),
            **({"speeds_rpm": [float(v) for v in ob.speeds_rpm]}
               if ob.speeds_rpm is not None else {})}
