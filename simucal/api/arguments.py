"""The public functions' arguments checked by type at the door: a wrong type is refused in one line
(InputError) naming the function, the argument, what was given and what is expected, before it reaches
code that would fail on it further in (a bare TypeError from a comparison) or misread it (one path as a
str taken for a list of paths, a character at a time). `@checked` reads what each argument expects off
the function's own annotations, so an argument added later is checked as well."""
from __future__ import annotations

import functools
import inspect
import numbers
import os
from typing import Any, Callable, ParamSpec, TypeVar

from simucal.api.options import CalibrateOptions
from simucal.errors import InputError

P = ParamSpec("P")
R = TypeVar("R")


def _number(v: Any) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)  # True is an int to Python, not a quantity


def _paths(v: Any) -> bool:
    return isinstance(v, (list, tuple)) and all(isinstance(p, (str, os.PathLike)) for p in v)


# what each expected kind accepts (None, every optional argument's default, is accepted by all)
KINDS: dict[str, Callable[[Any], bool]] = {
    "a number": _number,
    "a whole number": lambda v: isinstance(v, numbers.Integral) and not isinstance(v, bool),
    "a list of paths": _paths,
    "a list of numbers": lambda v: not isinstance(v, (str, bytes)) and hasattr(v, "__iter__")
    and all(_number(x) for x in v),
}
# the annotations (as the API writes them, without "| None") whose arguments are checked, and their kind
ANNOTATED = {"float": "a number", "int": "a whole number", "Sequence[float]": "a list of numbers",
             "Sequence[Path_]": "a list of paths", "Sequence[str | os.PathLike]": "a list of paths"}


def _kind(annotation: Any) -> str | None:
    text = str(getattr(annotation, "__forward_arg__", annotation))  # a TypedDict's are ForwardRefs
    return ANNOTATED.get(text.removesuffix(" | None"))


def refuse_unless(where: str, name: str, value: Any, expected: str) -> None:
    """Refuse `value` unless it is None or of the `expected` kind (KINDS)."""
    if value is None or KINDS[expected](value):
        return
    shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
    hint = f" ([{shown}] for one)" if expected == "a list of paths" and isinstance(value, (str, os.PathLike)) else ""
    raise InputError(f"{where}: {name}={shown} is a {type(value).__name__}, {expected} is expected{hint}")


def checked(f: Callable[P, R]) -> Callable[P, R]:
    """f with each argument whose annotation ANNOTATED names checked before f runs; the keyword options typed
    by CalibrateOptions (calibrate's **options) too."""
    signature = inspect.signature(f)
    expects = {name: kind for name, p in signature.parameters.items() if (kind := _kind(p.annotation))}
    options = next((p.name for p in signature.parameters.values() if p.kind is p.VAR_KEYWORD), "")
    if "CalibrateOptions" in str(signature.parameters[options].annotation if options else ""):
        expects.update({k: kind for k, a in CalibrateOptions.__annotations__.items() if (kind := _kind(a))})

    @functools.wraps(f)
    def door(*args: P.args, **kwargs: P.kwargs) -> R:
        given = signature.bind_partial(*args, **kwargs).arguments
        given.update(given.pop(options, {}))  # **options' names beside the others
        for name, kind in expects.items():
            refuse_unless(f.__name__, name, given.get(name), kind)
        return f(*args, **kwargs)
    return door
