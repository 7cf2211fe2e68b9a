"""Parameters: the one ``--param KEY=VALUE`` parser of every command, and the type check of a
method's or generator's parameters against its ``__init__`` signature.

VALUE is read the same way everywhere (``damage``, ``inpaint``, ``detect-holes``, ``generate``,
``info``, ``render``, ``--dataset-param``):

- ``true``/``false`` (also ``yes``/``no``, any case) -> bool; ``none``/``null`` -> None;
- an integer (``20``) -> int; a decimal number (``0.5``, ``1e-3``, ``inf``) -> float;
- text starting with ``[``, ``{`` or ``"`` -> JSON (a list ``[1, 2]``, a quoted string ``"20"``);
- anything else -> the text itself (``preset=large``).

A parameter given twice is refused (the second would silently win).
"""

from __future__ import annotations

import inspect
import json
import math

from bench.errors import UserError

_TRUE = ("true", "yes")
_FALSE = ("false", "no")
_NONE = ("none", "null")


def parse_param_value(text: str, option: str = "--param", key: str = ""):
    """One VALUE of ``--param KEY=VALUE`` (rules in the module docstring)."""
    value = text.strip()
    low = value.lower()
    if low in _TRUE:
        return True
    if low in _FALSE:
        return False
    if low in _NONE:
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


# -- type checks against a signature ----------------------------------------------------------
def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _annotation_kinds(annotation) -> set[str] | None:
    """The simple kinds an annotation (a string under ``from __future__ import annotations``) allows,
    or None when it says nothing usable."""
    if annotation is inspect.Parameter.empty:
        return None
    text = annotation if isinstance(annotation, str) else getattr(annotation, "__name__", str(annotation))
    kinds = set()
    for part in str(text).replace(" ", "").split("|"):
        if part in ("int", "float"):
            kinds.add("number")
        elif part == "bool":
            kinds.add("bool")
        elif part == "str":
            kinds.add("str")
        elif part == "None":
            kinds.add("none")
        else:
            return None  # a type this check does not know: leave it to the class's own validation
    return kinds or None


def _kind_ok(value, kinds: set[str]) -> bool:
    return (("number" in kinds and _is_number(value)) or ("bool" in kinds and isinstance(value, bool))
            or ("str" in kinds and isinstance(value, str)) or ("none" in kinds and value is None))


def _describe(kinds: set[str]) -> str:
    words = {"number": "a number", "bool": "true or false", "str": "text", "none": "none"}
    return " or ".join(words[k] for k in ("number", "bool", "str", "none") if k in kinds)


def signature_params(func) -> dict[str, inspect.Parameter]:
    """Keyword parameters of a function or of a class's ``__init__`` (``self`` left out)."""
    sig = inspect.signature(func.__init__ if isinstance(func, type) else func)
    kinds = (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    return {n: p for n, p in sig.parameters.items() if n != "self" and p.kind in kinds}


def check_param_types(func, params: dict, who: str) -> None:
    """UserError for an unknown parameter name, or a value whose type the signature rules out.

    The allowed kinds come from the annotation when it is made of int/float/bool/str/None, else
    from the default: a numeric default requires a number, a boolean default true/false. Ranges
    and the allowed texts are the class's own validation (``validate_params``).
    """
    known = signature_params(func)
    unknown = [key for key in params if key not in known]
    if unknown:
        raise UserError(f"{who}: unknown parameter(s) {', '.join(unknown)}; valid parameters: "
                        f"{', '.join(known) or '(none)'}")
    for key, value in params.items():
        param = known[key]
        kinds = _annotation_kinds(param.annotation)
        if kinds is None:
            default = param.default
            if isinstance(default, bool):
                kinds = {"bool"}
            elif _is_number(default):
                kinds = {"number"}
            else:
                continue
        if not _kind_ok(value, kinds):
            raise UserError(f"{who}: parameter {key} must be {_describe(kinds)}, got {value!r}")
