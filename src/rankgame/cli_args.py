"""Command-line options generated from typed, documented config dataclasses.

Each dataclass field becomes ``--field-name`` (nested dataclasses become ``--prefix.field-name``),
its type decides parsing, its default comes from the dataclass instance given (so presets show
their own defaults in ``--help``), and the string literal written under the field is its help text.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import textwrap
import types
import typing
from functools import cache
from pathlib import Path
from typing import Any, Literal, Union, get_args, get_origin


@cache
def field_docs(cls: type) -> dict[str, str]:
    """The string literal that follows each field in the class body (its attribute docstring)."""
    try:
        source = textwrap.dedent(inspect.getsource(cls))
    except (OSError, TypeError):
        return {}
    body = ast.parse(source).body[0]
    docs: dict[str, str] = {}
    assert isinstance(body, ast.ClassDef)
    for node, following in zip(body.body, body.body[1:], strict=False):
        if (
            isinstance(node, ast.AnnAssign)
            and isinstance(node.target, ast.Name)
            and isinstance(following, ast.Expr)
            and isinstance(following.value, ast.Constant)
            and isinstance(following.value.value, str)
        ):
            docs[node.target.id] = " ".join(following.value.value.split())
    return docs


def _option(prefix: str, name: str) -> str:
    return "--" + prefix + name.replace("_", "-")


def _parser_for(annotation: Any) -> tuple[Any, dict[str, Any]]:
    """argparse ``type``/``choices``/``nargs`` for a field annotation."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin in (Union, types.UnionType):
        inner = [a for a in args if a is not type(None)]
        if len(inner) == 1:
            base, extra = _parser_for(inner[0])

            def optional(text: str) -> Any:
                return None if text.lower() == "none" else base(text)

            optional.__name__ = getattr(base, "__name__", "value")  # argparse names it in "invalid int value"
            return optional, extra
    if origin is Literal:
        return str, {"choices": list(args)}
    if origin is tuple:
        return args[0], {"nargs": "+"}
    if annotation in (int, float, str, Path):
        return annotation, {}
    raise TypeError(f"unsupported option type {annotation!r}")


def add_dataclass_options(parser: argparse.ArgumentParser, default: Any, prefix: str = "") -> None:
    """Add one option per field of the dataclass instance ``default`` (recursing into nested ones)."""
    cls = type(default)
    hints = typing.get_type_hints(cls)
    docs = field_docs(cls)
    summary = (cls.__doc__ or "").strip().split("\n\n")[0]
    group = parser.add_argument_group(prefix.rstrip("."), " ".join(summary.split())) if prefix else parser
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        value = getattr(default, f.name)
        if dataclasses.is_dataclass(value):
            add_dataclass_options(parser, value, prefix + f.name + ".")
            continue
        dest = prefix + f.name
        help_text = docs.get(f.name, "")
        if hints[f.name] is bool:
            group.add_argument(
                _option(prefix, f.name),
                dest=dest,
                default=value,
                action=argparse.BooleanOptionalAction,
                help=f"{help_text} (default: {'yes' if value else 'no'})",
            )
            continue
        kind, extra = _parser_for(hints[f.name])
        shown = " ".join(map(str, value)) if isinstance(value, tuple) else value
        if value is not None:  # a field defaulting to None says in its docstring what None means
            help_text = f"{help_text} (default: {shown})"
        group.add_argument(_option(prefix, f.name), dest=dest, type=kind, default=value, help=help_text, **extra)


def dataclass_from_args(namespace: argparse.Namespace, default: Any, prefix: str = "") -> Any:
    """Rebuild the dataclass from parsed options, starting from ``default``."""
    changes = {}
    for f in dataclasses.fields(default):
        if not f.init:
            continue
        value = getattr(default, f.name)
        if dataclasses.is_dataclass(value):
            changes[f.name] = dataclass_from_args(namespace, value, prefix + f.name + ".")
        else:
            parsed = getattr(namespace, prefix + f.name)
            changes[f.name] = tuple(parsed) if isinstance(value, tuple) and parsed is not None else parsed
    return dataclasses.replace(default, **changes)


def explicit_dests(parser: argparse.ArgumentParser, argv: list[str] | tuple[str, ...]) -> set[str]:
    """The destinations (dotted option names) of the options given explicitly in ``argv``."""
    defaults = {action: action.default for action in parser._actions}
    try:
        for action in defaults:
            action.default = argparse.SUPPRESS
        return set(vars(parser.parse_args(argv)))
    finally:
        for action, default in defaults.items():
            action.default = default
