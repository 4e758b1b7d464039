"""Typed plugin options: a plugin's ``Options`` is a frozen dataclass with defaults.

:func:`parse_options` turns a mapping (from the CLI, a TOML spec or code) into an
instance, checking names and types so a typo fails at once with the list of valid names.
Range checks live in the dataclass's ``__post_init__`` and raise :class:`ConfigError`.
"""

from __future__ import annotations

import contextlib
import dataclasses
import difflib
import functools
import numbers
import types
import typing
from collections.abc import Mapping
from typing import Any, Literal, Union

from workbench.errors import ConfigError


@dataclasses.dataclass(frozen=True)
class NoOptions:
    """For plugins without options."""


UNIT = "unit"  # the metadata key of an option field's unit


def with_unit(default: Any, unit: str) -> Any:
    """An option field whose value is in ``unit`` (``"rad"``, ``"m/s"``): ``describe``
    prints the unit beside it, so a number is never shown without one."""
    return dataclasses.field(default=default, metadata={UNIT: unit})


def option_units(options_class: type) -> dict[str, str]:
    """The unit of every option declared :func:`with_unit` ("" for the others)."""
    if not dataclasses.is_dataclass(options_class):
        return {}
    return {f.name: f.metadata.get(UNIT, "") for f in dataclasses.fields(options_class)}


def option_fields(options_class: type) -> list[tuple[str, Any, Any]]:
    """(name, type, default) of every option, in declaration order (default None if required)."""
    if not dataclasses.is_dataclass(options_class):
        raise ConfigError(f"options class {options_class!r} is not a dataclass")
    hints = _type_hints(options_class)
    rows = []
    for f in dataclasses.fields(options_class):
        default = f.default if f.default is not dataclasses.MISSING else None
        if f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
            default = f.default_factory()  # type: ignore[misc]
        rows.append((f.name, hints.get(f.name, Any), default))
    return rows


def unknown_option(option: str, classes: Mapping[str, type]) -> str:
    """Why ``option`` (given without its plugin's kind) is refused: no plugin of ``classes``
    (kind -> plugin class) declares it, with the close names that some do declare."""
    names = [
        name
        for plugin in classes.values()
        if getattr(plugin, "Options", None) is not None
        for name, _, _ in option_fields(plugin.Options)
    ]
    close = difflib.get_close_matches(option, list(dict.fromkeys(names)), n=3)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    return f"no option of that name in the problem, formalism or integrator{hint}"


@functools.cache
def _type_hints(options_class: type) -> dict[str, Any]:
    """``typing.get_type_hints`` of an options class, once: it evaluates the string
    annotations (``from __future__ import annotations``) anew at every call, about
    0.2 ms, and every ``Integrator.solve`` parses its options."""
    return typing.get_type_hints(options_class)


def _is_union(annotation: Any) -> bool:
    return typing.get_origin(annotation) in (Union, types.UnionType)


def type_name(annotation: Any) -> str:
    if typing.get_origin(annotation) is Literal:
        return " | ".join(repr(a) for a in typing.get_args(annotation))
    if _is_union(annotation):
        return " | ".join(type_name(a) for a in typing.get_args(annotation))
    if annotation is type(None):
        return "None"
    if typing.get_origin(annotation) is not None:
        return str(annotation).replace("typing.", "")
    return getattr(annotation, "__name__", str(annotation))


def _coerce(owner: str, name: str, annotation: Any, value: Any) -> Any:
    origin = typing.get_origin(annotation)
    if origin is Literal:
        allowed = typing.get_args(annotation)
        for choice in allowed:
            # True == 1, so compare the kind of value as well
            same_kind = isinstance(value, bool) == isinstance(choice, bool) and isinstance(
                value, str
            ) == isinstance(choice, str)
            if same_kind and value == choice:
                return choice
        raise ConfigError(
            f"{owner}: option {name!r} must be one of {', '.join(map(repr, allowed))}, "
            f"not {value!r}"
        )
    if _is_union(annotation):
        members = typing.get_args(annotation)
        if value is None and type(None) in members:
            return None
        for member in members:
            if member is type(None):
                continue
            try:
                return _coerce(owner, name, member, value)
            except ConfigError:
                continue
    elif annotation is bool:
        if isinstance(value, bool):
            return value
    elif annotation is int:
        if isinstance(value, numbers.Integral) and not isinstance(value, bool):
            return int(value)
    elif annotation is float:
        if isinstance(value, numbers.Real) and not isinstance(value, bool):
            return float(value)
    elif annotation is str:
        if isinstance(value, str):
            return value
    elif (origin or annotation) in (tuple, list, dict):
        with contextlib.suppress(ConfigError):  # an item of the wrong type: said below
            return _coerce_container(owner, name, annotation, value)
    else:
        return value
    hint = ""
    if annotation is str and isinstance(value, int | float):  # -o mode=3 reads a number
        hint = f" (text in quotes: -o '{name}=\"{value}\"', in TOML {name} = \"{value}\")"
    raise ConfigError(
        f"{owner}: option {name!r} must be of type {type_name(annotation)}, "
        f"not {type(value).__name__} {value!r}{hint}"
    )


def _coerce_container(owner: str, name: str, annotation: Any, value: Any) -> Any:
    """``value`` as the tuple, list or dict ``annotation`` names, each item coerced to its
    type (TOML and ``-o name=[1, 2]`` give lists); ConfigError if it is not one."""
    kind, args = typing.get_origin(annotation) or annotation, typing.get_args(annotation)
    if kind is dict:
        if not isinstance(value, Mapping):
            raise ConfigError(name)
        key_type, value_type = args or (Any, Any)
        return {_coerce(owner, name, key_type, k): _coerce(owner, name, value_type, v)
                for k, v in value.items()}  # fmt: skip
    if not isinstance(value, (list, tuple)):
        raise ConfigError(name)
    if kind is tuple and args and args[-1] is not Ellipsis:  # tuple[float, float]: fixed
        if len(value) != len(args):
            raise ConfigError(name)
        return tuple(_coerce(owner, name, a, v) for a, v in zip(args, value, strict=True))
    items = [_coerce(owner, name, args[0] if args else Any, v) for v in value]
    return tuple(items) if kind is tuple else items


def parse_options(options_class: type, values: Mapping[str, Any] | None, owner: str) -> Any:
    """Build ``options_class`` from ``values``; unknown names and wrong types raise ConfigError."""
    if values is None:
        values = {}
    if dataclasses.is_dataclass(values) and isinstance(values, options_class):
        return values
    if not isinstance(values, Mapping):
        raise ConfigError(f"{owner}: options must be a table of name = value, not {values!r}")
    fields = {name: annotation for name, annotation, _ in option_fields(options_class)}
    if any(not isinstance(key, str) for key in values):
        raise ConfigError(f"{owner}: option names must be strings, got {list(values)!r}")
    kwargs = {}
    for key, value in values.items():
        if key not in fields:
            close = difflib.get_close_matches(str(key), list(fields), n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            valid = ", ".join(fields) or "none"
            raise ConfigError(f"{owner}: unknown option {key!r}{hint} (valid options: {valid})")
        kwargs[key] = _coerce(owner, key, fields[key], value)
    try:
        return options_class(**kwargs)
    except ConfigError as error:
        raise ConfigError(f"{owner}: {error}") from None
    except (TypeError, ValueError) as error:
        raise ConfigError(f"{owner}: invalid options: {error}") from None


def options_dict(options: Any) -> dict[str, Any]:
    """An options instance as a plain dict (for hashing, storing and printing)."""
    return dataclasses.asdict(options) if dataclasses.is_dataclass(options) else {}
