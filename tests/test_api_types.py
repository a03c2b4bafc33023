"""Every public function of the Python API checks its arguments at the door (arguments.checked): a wrong type,
an unknown keyword or a missing argument is one line, a simucal refusal naming the argument, never a bare
TypeError, KeyError, IndexError or AttributeError from deep inside. The functions are found by walking the API
(simucal.__all__ and the public methods of its classes), and the wrong values chosen from each parameter's
annotation as written, so that a function or an argument added later is held to it too."""
import inspect
import re
import sys
import typing

import pytest

import simucal
from simucal.errors import SimucalError


# The set's own accessors, which every method calls per segment (the door costs about 8 us a call): the API's
# functions take their arguments from the user, these from simucal's own code.
ACCESSORS = {"MeasurementSet": {"copy", "raw", "acc_g", "gyro_dph", "in_units", "rows", "sample_digests"},
             "Calibration": {"blocks", "drop_sensor", "to_json", "from_json"}}


def _public_callables():
    """(name, function to call, the function itself) of every public function and public method of the API (its
    classes: the API's own and the two it shares with io/, the set and the calibration)."""
    found = []
    for name in simucal.__all__:
        obj = getattr(simucal, name)
        if inspect.isfunction(obj):
            found.append((name, obj, obj))
        elif inspect.isclass(obj) and obj.__module__.startswith(("simucal.api", "simucal.io")):
            blank = obj.__new__(obj) if not issubclass(obj, tuple) else None  # never read: the door refuses first
            for attr, member in vars(obj).items():
                f = member.__func__ if isinstance(member, (classmethod, staticmethod)) else member
                if attr.startswith("_") or not inspect.isfunction(f) or attr in ACCESSORS.get(name, ()):
                    continue
                bound = getattr(obj, attr) if isinstance(member, (classmethod, staticmethod)) else \
                    getattr(blank, attr) if blank is not None else None
                if bound is not None:
                    found.append((f"{name}.{attr}", bound, f))
    return found


CALLABLES = _public_callables()


def _members(annotation: str) -> list[str]:
    """An annotation's members at the top level of its union ('Sequence[float] | None' -> [Sequence[float], None])."""
    out, depth, start = [], 0, 0
    for i, c in enumerate(annotation):
        depth += c in "[(" and 1 or c in "])" and -1 or 0
        if c == "|" and depth == 0:
            out.append(annotation[start:i].strip())
            start = i + 1
    return out + [annotation[start:].strip()]


def _takes_text(members, namespace) -> bool:
    """Whether a member takes a str: str, a path, a Literal, or an alias of the module's that holds one of them (Data,
    Path_, Method)."""
    def text(m):
        if m in ("str", "os.PathLike") or m.startswith("Literal["):
            return True
        try:
            alias = eval(m, namespace)
        except Exception:
            return False
        return typing.get_origin(alias) is typing.Literal or str in typing.get_args(alias)
    return any(text(m) for m in members)


def _wrong_values(annotation: str, namespace: dict) -> list:
    """Values of a wrong type for a parameter so annotated, chosen from the text alone: an object of no API type
    (wrong for all but Any); a str where none of the members is text (a str for a number, a list, a mapping); an int
    where no member is a number (an int for a path or a name); a bool where a number is; a fraction where a whole
    number is."""
    members = _members(annotation)
    if "Any" in members or annotation in ("", "Any"):
        return []
    numeric = {m for m in members if m in ("int", "float")}
    wrong: list = [object()]
    if not _takes_text(members, namespace):
        wrong.append("ten")
    if not numeric and "bool" not in members:
        wrong.append(7)
    if numeric and "bool" not in members:
        wrong.append(True)
    if numeric == {"int"}:
        wrong.append(2.5)
    return wrong


def _placeholder(annotation: str, namespace: dict):
    """A value of the right type for a required parameter beside the one tested (never read: the door refuses the
    tested one before any work)."""
    members = _members(annotation)
    if any(m.startswith(("Sequence[", "list[")) for m in members) and not _takes_text(members, namespace):
        return []
    if _takes_text(members, namespace):
        return "set"
    if {"int", "float"} & set(members):
        return 1
    if any(m.startswith(("Mapping[", "dict[")) for m in members):
        return {}
    if "Any" in members or not annotation:
        return None
    cls = eval(members[0], namespace)  # a class of the API (save's result): an instance never initialised
    return cls.__new__(cls)


def _parameters(f):
    """{name: (annotation text, required, the namespace it is written in)} of f, calibrate's **options
    (CalibrateOptions) among them."""
    out = {}
    for p in inspect.signature(f).parameters.values():
        if p.name in ("self", "cls") or p.kind is p.VAR_POSITIONAL:
            continue
        if p.kind is p.VAR_KEYWORD:
            assert "CalibrateOptions" in str(p.annotation), (f, p)  # untyped **kwargs would take any keyword
            options = sys.modules[simucal.CalibrateOptions.__module__].__dict__
            out.update({k: (str(getattr(a, "__forward_arg__", a)), False, options)
                        for k, a in simucal.CalibrateOptions.__annotations__.items()})
            continue
        text = "" if p.annotation is p.empty else str(p.annotation)
        out[p.name] = (text, p.default is p.empty, inspect.unwrap(f).__globals__)
    return out


def _refusal(call, **given) -> str:
    with pytest.raises(SimucalError) as refused:
        call(**given)
    text = str(refused.value)
    assert "\n" not in text, text
    return text


def _required(f, params, but=None) -> dict:
    return {k: _placeholder(a, ns) for k, (a, required, ns) in params.items() if required and k != but}


@pytest.mark.parametrize("name, call, f", CALLABLES, ids=[c[0] for c in CALLABLES])
def test_every_argument_of_a_wrong_type_is_refused_naming_it(name, call, f):
    params = _parameters(f)
    tried = 0
    for arg, (annotation, _, namespace) in params.items():
        for wrong in _wrong_values(annotation, namespace):
            text = _refusal(call, **_required(f, params, but=arg), **{arg: wrong})
            assert re.search(rf"\b{re.escape(arg)}(\[\d+\])?=", text) and "expected" in text, (arg, wrong, text)
            tried += 1
    untyped = [a for a, (annotation, _, ns) in params.items() if not _wrong_values(annotation, ns)]
    assert tried or not params or untyped == list(params), name  # each typed parameter tried at least once


@pytest.mark.parametrize("name, call, f", CALLABLES, ids=[c[0] for c in CALLABLES])
def test_an_unknown_keyword_is_refused_with_the_nearest(name, call, f):
    params = _parameters(f)
    text = _refusal(call, **_required(f, params), no_such_argument=1)
    assert "no_such_argument=1 is not an argument of" in text, text
    if params:
        arg = max(params, key=len)
        typo = arg + "s"
        assert f"did you mean {arg}=?" in _refusal(call, **_required(f, params), **{typo: None}), typo


@pytest.mark.parametrize("name, call, f", CALLABLES, ids=[c[0] for c in CALLABLES])
def test_a_missing_argument_is_refused(name, call, f):
    required = [k for k, (_, req, _) in _parameters(f).items() if req]
    if required:
        text = _refusal(call)
        assert f"missing a required argument: '{required[0]}'" in text, text


def test_the_walk_finds_the_api():
    """The walk covers the functions, the classes' methods and calibrate's options (not a vacuous loop)."""
    names = {n for n, _, _ in CALLABLES}
    assert {"calibrate", "read_set", "save", "plan", "MeasurementSet.from_arrays", "MeasurementSet.write",
            "apply", "apply_set", "parameters", "Calibration.sensor", "Calibration.autopilot_files"} <= names
    assert all(hasattr(getattr(simucal, c), m) for c, ms in ACCESSORS.items() for m in ms)  # none stale
    assert "acc_noise_g" in _parameters(simucal.calibrate)


def test_a_list_refused_names_its_item_and_a_frame_names_its_constructor():
    import pandas as pd
    text = _refusal(simucal.calibrate, data=["set", 3])
    assert text.startswith("calibrate: data[1]=3 is an int, a path or a MeasurementSet is expected"), text
    frame = pd.DataFrame({"ax": [0.0, 0.1]})
    text = _refusal(simucal.noise, data=frame)
    assert "data=<DataFrame> is a DataFrame" in text and "simucal.MeasurementSet.from_dataframe" in text, text
    with pytest.raises(TypeError):  # a refusal, and still the TypeError callers caught before
        simucal.diagnose(frame)


def test_any_iterable_of_items_is_taken_as_a_list():
    """A generator or a set where a list is expected is read once at the door and handed on as a list: the same
    result as the list (a str is refused, not taken a character at a time)."""
    as_list = simucal.plan("table1", add=["acc.quadratic.z"])
    as_generator = simucal.plan("table1", add=(e for e in ["acc.quadratic.z"]))
    as_set = simucal.plan("table1", add={"acc.quadratic.z"})
    assert as_list["crlb"] == as_generator["crlb"] == as_set["crlb"] and "acc.quadratic.z" in as_list["crlb"]
    assert "(['acc.quadratic.z'] for one)" in _refusal(simucal.plan, score="table1", add="acc.quadratic.z")



def test_a_path_object_is_taken_where_a_name_or_a_file_is(tmp_path):
    """A pathlib.Path given for a str argument (a built-in name or a file) is passed on as its str: the same result
    as the str; a number for it is still refused."""
    from simucal.turntable.plans import TABLE1
    plan = tmp_path / "plan.csv"
    plan.write_text("outer_deg,middle_deg,inner_deg\n" + "".join(",".join(map(str, p)) + "\n" for p in TABLE1))
    assert simucal.plan(plan)["crlb"] == simucal.plan(str(plan))["crlb"]
    assert "score=3 is an int" in _refusal(simucal.plan, score=3)
