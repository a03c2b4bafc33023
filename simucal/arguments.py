"""The public functions' arguments checked at the door: a wrong type, an unknown keyword or a missing argument is
refused in one line (ArgumentError, an InputError and a TypeError) naming the function, the argument, what was
given and what is expected, before it reaches code that would fail on it further in (a bare TypeError from a
comparison, a KeyError) or misread it (one path as a str taken for a list of paths, a character at a time).

`@checked` reads what each argument accepts off the function's own annotations (resolved in its module), so an
argument or a function added later is checked as well:
- a number (int or float, never a bool), a whole number, True or False, a string (a pathlib.Path given for one
  is passed on as its str: many take a built-in name or a file), a path (str or os.PathLike), a list of any of them (a
  list, a tuple, a 1-d array; an iterator or a set is taken as a list, so that reading it here leaves the function its
  items), a mapping, an instance of a class, or a union of these; a Literal's type; Any, and what cannot be resolved,
  accepts anything;
- None where the annotation admits it or the argument is optional (None: not given, as the command line
  passes an option left out);
- only the keywords the function takes, the nearest one named."""
from __future__ import annotations

import collections.abc as abc
import difflib
import functools
import inspect
import numbers
import os
import re
import types
import typing
from typing import Any, Callable, NamedTuple, ParamSpec, Protocol, TypeVar, runtime_checkable

from simucal.errors import ArgumentError

P = ParamSpec("P")
R = TypeVar("R")


class Accepts(NamedTuple):
    """What an annotation accepts: the test of a value, its words ("a number"), and whether it takes a list
    (where an iterator or a set is taken as one) and what of (an item refused is named by its index)."""
    test: Callable[[Any], bool]
    words: str
    listed: bool = False
    item: Accepts | None = None
    fspath: bool = False  # a string: a pathlib.Path given for it is passed on as its str (os.fspath)


def _number(v: Any) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)  # True is an int to Python, not a quantity


SCALARS = {float: Accepts(_number, "a number"),
           int: Accepts(lambda v: isinstance(v, numbers.Integral) and not isinstance(v, bool), "a whole number"),
           bool: Accepts(lambda v: isinstance(v, bool) or type(v).__name__ == "bool_", "True or False"),  # numpy's
           str: Accepts(lambda v: isinstance(v, str), "a string", fspath=True),
           os.PathLike: Accepts(lambda v: isinstance(v, (str, os.PathLike)), "a path")}
SEQUENCES = (abc.Sequence, abc.Iterable, abc.Collection, list, tuple)
MAPPINGS = (abc.Mapping, dict)


def _plural(words: str) -> str:
    return " or ".join(re.sub(r"^an? ", "", w) + "s" for w in words.split(" or "))


def _list_like(v: Any) -> bool:
    """A list, tuple or other sequence, or a 1-d array (not a str, nor a table whose iteration is its columns)."""
    return not isinstance(v, (str, bytes, abc.Mapping)) and (isinstance(v, abc.Sequence) or getattr(v, "ndim", 0) == 1)


def _to_list(v: Any) -> bool:
    """Whether v is items to take as a list: an iterator (read once) or a set."""
    return not isinstance(v, (str, bytes)) and isinstance(v, (abc.Iterator, abc.Set, abc.ValuesView))


def _is_path(t: Any) -> bool:
    return (typing.get_origin(t) or t) is os.PathLike  # os.PathLike[str] as the bare class


def _union(args: tuple[Any, ...]) -> Accepts | None:
    if str in args and any(_is_path(a) for a in args):  # a path's words cover the str
        args = tuple(a for a in args if a is not str)
    members = [accepts(a) for a in args if a is not type(None)]  # None: the door's
    if any(m is None for m in members):
        return None
    known = [m for m in members if m is not None]
    none = type(None) in args  # an item's None (a mapping's value): at the top, the door's nullable already took it
    return Accepts(lambda v: (none and v is None) or any(m.test(v) for m in known),
                   " or ".join(dict.fromkeys(m.words for m in known)),
                   any(m.listed for m in known), next((m.item for m in known if m.item), None),
                   any(m.fspath for m in known))


def _collection(origin: Any, args: tuple[Any, ...]) -> Accepts:
    """A sequence's or a mapping's Accepts, its items checked where their type is given."""
    if origin in MAPPINGS or (isinstance(origin, type) and typing.is_typeddict(origin)):
        key, value = (accepts(a) for a in args) if len(args) == 2 else (None, None)
        return Accepts(lambda v: isinstance(v, abc.Mapping) and all((key is None or key.test(k)) and
                                                                    (value is None or value.test(x))
                                                                    for k, x in v.items()),
                       "a mapping" + (f" of {_plural(key.words)} to {_plural(value.words)}" if key and value else ""))
    item = accepts(args[0]) if args else None
    return Accepts(lambda v: _list_like(v) and (item is None or all(item.test(x) for x in v)),
                   "a list" + (f" of {_plural(item.words)}" if item else ""), True, item)


def accepts(t: Any) -> Accepts | None:
    """What a resolved annotation accepts; None: anything."""
    if _is_path(t):
        t = os.PathLike
    origin, args = typing.get_origin(t), typing.get_args(t)
    if t is Any or t is object:
        return None
    if t is type(None):
        return Accepts(lambda v: v is None, "None")
    if origin in (typing.Union, types.UnionType):
        return _union(args)
    if origin is typing.Literal:
        kinds = tuple({type(a) for a in args})
        return Accepts(lambda v: isinstance(v, kinds), "one of " + ", ".join(map(repr, args)))
    if t in SCALARS:
        return SCALARS[t]
    if (origin or t) in SEQUENCES + MAPPINGS or (isinstance(t, type) and typing.is_typeddict(t)):
        return _collection(origin or t, args)
    if origin is abc.Callable or t is abc.Callable:
        return Accepts(callable, "a function")
    if isinstance(t, type):
        try:
            isinstance(None, t)
        except TypeError:  # a protocol or a generic that isinstance cannot test
            return None
        return Accepts(lambda v: isinstance(v, t), f"a {t.__name__}")
    return None


def _resolved(annotation: Any, namespace: dict[str, Any]) -> Any:
    """An annotation as a type: a string (PEP 563) evaluated in the function's module; Any where it cannot be."""
    if annotation is inspect.Parameter.empty:
        return Any
    if not isinstance(annotation, str):
        return annotation
    try:
        return eval(annotation, namespace)  # noqa: S307 (the annotations of simucal's own functions)
    except Exception:  # a name imported for type checkers only
        return Any


def shown(v: Any) -> str:
    """A value as a refusal shows it: its repr, cut at 60 characters; a table's or an array's type alone."""
    r = repr(v)
    return f"<{type(v).__name__}>" if "\n" in r else r if len(r) <= 60 else r[:57] + "..."


def refusal(where: str, name: str, value: Any, expected: str) -> ArgumentError:
    """The one line of a wrong argument, with the fix where it is known."""
    kind = type(value).__name__
    hint = ""
    if expected.startswith("a list") and isinstance(value, (str, os.PathLike)):
        hint = f" ([{shown(value)}] for one)"
    elif "MeasurementSet" in expected and kind in ("DataFrame", "ndarray"):
        how = "from_dataframe(df, ...)" if kind == "DataFrame" else "from_arrays(...)"
        hint = f"; make one with simucal.MeasurementSet.{how}"
    article = "an" if kind[:1].lower() in "aeiou" else "a"
    return ArgumentError(f"{where}: {name}={shown(value)} is {article} {kind}, {expected} is expected{hint}")


def _refused(where: str, name: str, value: Any, ok: Accepts) -> ArgumentError:
    """The refusal of value, or of its first wrong item where it is a list of wrong items."""
    if ok.item is not None and _list_like(value):
        i, x = next(((i, x) for i, x in enumerate(value) if not ok.item.test(x)), (None, None))
        if i is not None:
            return refusal(where, f"{name}[{i}]", x, ok.item.words)
    return refusal(where, name, value, ok.words)


class Door(NamedTuple):
    """What a function's door checks: each argument's Accepts, those that may be None and the keywords it takes
    (None: any, where it has **kwargs)."""
    expects: dict[str, Accepts | None]
    nullable: set[str]
    keywords: list[str] | None


def door_of(f: Callable[..., Any]) -> Door:
    """The checks of f's arguments, from its signature."""
    params = inspect.signature(f).parameters
    named = {n: p for n, p in params.items() if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)
             and n not in ("self", "cls")}  # a method's own, never a keyword
    types_of = {n: _resolved(p.annotation, f.__globals__) for n, p in named.items()}
    nullable = {n for n, p in named.items() if p.default is not p.empty
                or types_of[n] is type(None) or type(None) in typing.get_args(types_of[n])}
    open_ended = any(p.kind is p.VAR_KEYWORD for p in params.values())
    return Door({n: accepts(t) for n, t in types_of.items()}, nullable, None if open_ended else list(named))


def _unknown(where: str, keywords: list[str], kwargs: dict[str, Any]) -> None:
    for k, v in kwargs.items():
        if k not in keywords:
            near = difflib.get_close_matches(k, keywords, 1)
            raise ArgumentError(f"{where}: {k}={shown(v)} is not an argument of {where}"
                                + (f"; did you mean {near[0]}=?" if near else "")
                                + f" (it takes {', '.join(keywords)})")


def checked(f: Callable[P, R]) -> Callable[P, R]:
    """f with its arguments checked before it runs (module doc)."""
    signature, where, door = inspect.signature(f), f.__qualname__, door_of(f)

    @functools.wraps(f)
    def checked_door(*args: P.args, **kwargs: P.kwargs) -> R:
        if door.keywords is not None:
            _unknown(where, door.keywords, kwargs)
        try:
            bound = signature.bind(*args, **kwargs)
        except TypeError as e:  # missing, too many or repeated arguments
            raise ArgumentError(f"{where}: {e} (it takes {', '.join(door.keywords or signature.parameters)})") from None
        for name, value in list(bound.arguments.items()):
            ok = door.expects.get(name)
            if ok is None or (value is None and name in door.nullable):
                continue
            given = value
            if ok.listed and _to_list(value):
                value = list(value)
            if ok.fspath and isinstance(value, os.PathLike):
                value = os.fspath(value)
            elif ok.item is not None and ok.item.fspath and _list_like(value):
                value = [os.fspath(x) if isinstance(x, os.PathLike) else x for x in value]
            if value is not given:
                bound.arguments[name] = value
            if value is None or not ok.test(value):
                raise _refused(where, name, value, ok)
        return f(*bound.args, **bound.kwargs)
    return checked_door


@runtime_checkable
class DataFrame(Protocol):
    """A table by column: pandas' DataFrame, or anything with its columns and to_dict (io/arrays reads it so), for
    the annotation of an argument that takes one (pandas is an extra: the door cannot name its class)."""
    columns: Any

    def to_dict(self, orient: str = "dict") -> Any: ...
