"""Plain config trees (YAML / OmegaConf) -> frozen, typed dataclasses, converted once at the
stage boundary. The library never sees a DictConfig.

``to_typed(cls, tree, where, strict=True)`` rejects unknown keys, wrong types and (with
``strict``) missing keys, naming the full key path, so every value a stage uses is visible in
``params.yaml`` and a typo fails loudly instead of falling back to a default.
"""

import dataclasses
import types
import typing
from typing import Any, TypeVar, Union

from drawer_lib.errors import ConfigError

T = TypeVar("T")


def _plain(tree: Any) -> Any:
    try:
        from omegaconf import DictConfig, ListConfig, OmegaConf
    except ImportError:  # pragma: no cover
        return tree
    if isinstance(tree, (DictConfig, ListConfig)):
        return OmegaConf.to_container(tree, resolve=True)
    return tree


def _convert(tp: Any, v: Any, where: str, strict: bool) -> Any:
    origin = typing.get_origin(tp)
    if origin in (Union, types.UnionType):
        args = typing.get_args(tp)
        if v is None:
            if type(None) in args:
                return None
            raise ConfigError(f"{where}: must not be null")
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _convert(a, v, where, strict)
            except ConfigError as e:
                errors.append(str(e))
        raise ConfigError(errors[0] if len(errors) == 1 else f"{where}: {v!r} matches none of {args}")
    if dataclasses.is_dataclass(tp):
        return to_typed(tp, v, where, strict)
    if origin is list:
        if not isinstance(v, (list, tuple)):
            raise ConfigError(f"{where}: expected a list, got {v!r}")
        (item,) = typing.get_args(tp) or (Any,)
        return [_convert(item, x, f"{where}[{i}]", strict) for i, x in enumerate(v)]
    if origin is tuple:
        if not isinstance(v, (list, tuple)):
            raise ConfigError(f"{where}: expected a list, got {v!r}")
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], x, f"{where}[{i}]", strict) for i, x in enumerate(v))
        if len(args) != len(v):
            raise ConfigError(f"{where}: expected {len(args)} values, got {v!r}")
        return tuple(_convert(a, x, f"{where}[{i}]", strict) for i, (a, x) in enumerate(zip(args, v)))
    if origin is dict:
        if not isinstance(v, dict):
            raise ConfigError(f"{where}: expected a mapping, got {v!r}")
        kt, vt = typing.get_args(tp) or (Any, Any)
        return {_convert(kt, k, f"{where} key", strict): _convert(vt, x, f"{where}.{k}", strict) for k, x in v.items()}
    if tp is Any:
        return v
    if tp is bool:
        if not isinstance(v, bool):
            raise ConfigError(f"{where}: expected true or false, got {v!r}")
        return v
    if tp is int:
        if isinstance(v, bool) or not isinstance(v, int):
            raise ConfigError(f"{where}: expected an integer, got {v!r}")
        return v
    if tp is float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ConfigError(f"{where}: expected a number, got {v!r}")
        return float(v)
    if tp is str:
        if not isinstance(v, str):
            raise ConfigError(f"{where}: expected a string, got {v!r}")
        return v
    raise TypeError(f"to_typed: unsupported field type {tp!r} at {where}")


def to_typed(cls: type[T], tree: Any, where: str, strict: bool = True) -> T:
    """Build dataclass ``cls`` from a mapping; errors name the key path ``where.<key>``
    (``where`` ending in ':' names a file: ``file.yaml:<key>``)."""
    tree = _plain(tree)
    if not isinstance(tree, dict):
        raise ConfigError(f"{where.rstrip(':')}: expected a mapping, got {tree!r}")
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls) if f.init]
    unknown = sorted(set(tree) - set(names))
    if unknown:
        raise ConfigError(f"{where.rstrip(':')}: unknown key(s) {unknown} (known: {names})")
    missing = [n for n in names if n not in tree]
    if strict and missing:
        raise ConfigError(f"{where.rstrip(':')}: missing key(s) {missing}")
    sep = "" if where.endswith(":") else "."
    kwargs = {n: _convert(hints[n], tree[n], f"{where}{sep}{n}", strict) for n in names if n in tree}
    try:
        return cls(**kwargs)
    except ConfigError as e:
        raise ConfigError(f"{where.rstrip(':')}: {e}") from None
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{where.rstrip(':')}: {e}") from e


def to_tree(obj: Any) -> Any:
    """Inverse of :func:`to_typed`: dataclasses -> plain dicts/lists (for writing YAML)."""
    if dataclasses.is_dataclass(obj):
        return {f.name: to_tree(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, (list, tuple)):
        return [to_tree(x) for x in obj]
    if isinstance(obj, dict):
        return {k: to_tree(v) for k, v in obj.items()}
    return obj
