"""Parameters: the one ``--param KEY=VALUE`` parser of every command, and the type check of a
method's or generator's parameters against its ``__init__`` signature.

VALUE is read the same way everywhere (``damage``, ``inpaint``, ``detect-holes``, ``generate``,
``info``, ``render``, ``--dataset-param``):

- ``true``/``false`` (also ``yes``/``no``, any case) -> bool; ``none``/``null`` -> None;
- an integer (``20``) -> int; a decimal number (``0.5``, ``1e-3``, ``inf``) -> float;
- text starting with ``[``, ``{`` or ``"`` -> JSON (a list ``[1, 2]``, a quoted string ``"20"``);
- anything else -> the text itself (``preset=large``).

A parameter given twice is refused (the second would silently win).

The type check of parameters against a signature (`check_param_types`) lives in `metrics.params`,
beside the `get_params` / `validate_params` of methods and hole generators, and is re-exported here.
"""

from __future__ import annotations

import json
import math

from dpcbench.bench.core.errors import UserError
from dpcbench.metrics.params import NONE_TEXTS, check_param_types, signature_params

__all__ = ["check_param_types", "parse_param_value", "parse_params", "signature_params"]

_TRUE = ("true", "yes")
_FALSE = ("false", "no")


def parse_param_value(text: str, option: str = "--param", key: str = ""):
    """One VALUE of ``--param KEY=VALUE`` (rules in the module docstring)."""
    value = text.strip()
    low = value.lower()
    if low in _TRUE:
        return True
    if low in _FALSE:
        return False
    if low in NONE_TEXTS:
        return None
    if value[:1] in ("[", "{", '"'):
        try:
            return json.loads(value)
        except json.JSONDecodeError as err:
            raise UserError(f"{option} {key}={text}: not valid JSON ({err.msg} at character {err.pos}); "
                            "write a list as [1, 2] and a quoted string as \"text\"") from None
    try:
        return int(value)
    except ValueError:
        pass
    try:
        number = float(value)
    except ValueError:
        return value
    if math.isnan(number):
        raise UserError(f"{option} {key}={text}: NaN is not a parameter value; give a number")
    return number


def parse_params(items: list[str] | None, option: str = "--param") -> dict:
    """``["KEY=VALUE", ...]`` -> {KEY: parsed VALUE}."""
    params: dict = {}
    for item in items or []:
        key, sep, value = str(item).partition("=")
        key = key.strip()
        if not sep or not key:
            raise UserError(f"{option} {item!r}: expected KEY=VALUE, e.g. {option} size=tiny")
        if key in params:
            raise UserError(f"{option} {key}: given twice ({params[key]!r} and {value!r}); give it once")
        params[key] = parse_param_value(value, option, key)
    return params
