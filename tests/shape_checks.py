"""Run-time checks of the public API's jaxtyping annotations (installed by ``conftest.py``).

Each public function whose annotations name array shapes is replaced, in the
``jaxbill`` namespace, by a wrapper that calls it and then checks, in one
jaxtyping scope (so a dimension named twice must agree), every annotated
argument, the result, and the annotated fields of a result that is a dataclass
or an ``equinox.Module`` (``Orbit``, ``Run``, ``LyapunovSpectrum``...).

The call comes first on purpose: a bad input must still raise the library's own
``ValueError`` with its message (``tests/test_bad_input.py``); the check then
finds an annotation that does not describe what the function accepted or
returned, and raises ``jaxtyping.TypeCheckError``.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import types
import typing

import jaxtyping
import numpy as np
from beartype.door import is_bearable

CHECKED = "__jaxbill_shapes_checked__"


def _names_shapes(hint) -> bool:
    return "jaxtyping" in repr(hint)


def _field_hints(value) -> dict:
    if not dataclasses.is_dataclass(value) or isinstance(value, type):
        return {}
    hints = typing.get_type_hints(type(value), include_extras=True)
    return {f.name: hints[f.name] for f in dataclasses.fields(value) if _names_shapes(hints.get(f.name))}


def shape_hints(function) -> dict:
    """The annotations of ``function`` that involve jaxtyping, resolved (NameError if they do not resolve)."""
    hints = typing.get_type_hints(function, include_extras=True)
    return {name: hint for name, hint in hints.items() if _names_shapes(hint)}


def _is_plain_protocol(hint) -> bool:
    return (
        isinstance(hint, type)
        and getattr(hint, "_is_protocol", False)
        and not getattr(hint, "_is_runtime_protocol", False)
    )


def _bearable(value, hint) -> bool:
    """``is_bearable``, except that a protocol isinstance cannot test (``Scene``) stands for "not an array"."""
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        return any(_bearable(value, member) for member in typing.get_args(hint))
    if _is_plain_protocol(hint):
        return not hasattr(value, "shape")
    return is_bearable(value, hint)


def _fail(function, what: str, value, hint):
    shape = getattr(value, "shape", None)
    dtype = getattr(value, "dtype", None)
    raise jaxtyping.TypeCheckError(
        f"{function.__module__}.{function.__qualname__}: {what} (shape {shape}, dtype {dtype}) is not {hint}"
    )


def check_shapes(function):
    """``function`` wrapped so that each call checks its arguments and result against the annotations."""
    signature = inspect.signature(function)
    hints = shape_hints(function)
    result_hint = typing.get_type_hints(function, include_extras=True).get("return")

    @jaxtyping.jaxtyped(typechecker=None)
    def check(bound: inspect.BoundArguments, result):
        for name, value in bound.arguments.items():
            if name not in hints:
                continue
            if isinstance(value, list | tuple):  # nested numbers: checked as the array jnp.asarray makes
                value = np.asarray(value)
            if not _bearable(value, hints[name]):
                _fail(function, f"argument {name!r}", value, hints[name])
        if "return" in hints and not _bearable(result, hints["return"]):
            _fail(function, "the result", result, hints["return"])
        if result_hint is not None and isinstance(result_hint, type) and isinstance(result, result_hint):
            for name, hint in _field_hints(result).items():
                field = getattr(result, name)
                if not _bearable(field, hint):
                    _fail(function, f"the result's field {name!r}", field, hint)

    @functools.wraps(function)
    def checked(*args, **kwargs):
        result = function(*args, **kwargs)
        check(signature.bind(*args, **kwargs), result)
        return result

    setattr(checked, CHECKED, True)
    return checked


def _shaped_result(function) -> bool:
    result = typing.get_type_hints(function, include_extras=True).get("return")
    if not (isinstance(result, type) and dataclasses.is_dataclass(result)):
        return False
    hints = typing.get_type_hints(result, include_extras=True)
    return any(_names_shapes(hints.get(f.name)) for f in dataclasses.fields(result))


def install(module) -> dict[str, str]:
    """Wrap every public function of ``module`` (its ``__all__``) that names shapes.

    Returns the functions whose annotations could not be resolved, with the reason,
    for a test to report (the rest of the suite still runs).
    """
    unresolved = {}
    for name in module.__all__:
        function = getattr(module, name)
        if not inspect.isfunction(function) or getattr(function, CHECKED, False):
            continue
        try:
            names_shapes = bool(shape_hints(function)) or _shaped_result(function)
        except Exception as error:  # an annotation naming something undefined
            unresolved[name] = f"{type(error).__name__}: {error}"
            continue
        if names_shapes:
            setattr(module, name, check_shapes(function))
    return unresolved
