"""Keyword parameters of the numpy API's estimators (methods, hole generators): read them back from
the ``__init__`` signature, check their types against it, and run the class's own range checks.

scikit-learn convention: ``__init__`` only stores its keyword parameters under the same names;
`Parameterized` gives every such class ``get_params``, ``set_params`` and ``validate_params``.
Shared by ``holes`` (hole generators) and ``methods`` (inpainting methods) and by the harness's
config checks, so it lives in ``metrics``, the lowest layer (metrics < holes < methods < bench).
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from typing import Any, ClassVar, TypeVar, cast

from dpcbench.metrics.errors import UserError

_Self = TypeVar("_Self", bound="Parameterized")


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _annotation_kinds(annotation: object) -> set[str] | None:
    """The simple kinds an annotation (a string under ``from __future__ import annotations``) allows,
    or None when it says nothing usable."""
    if annotation is inspect.Parameter.empty:
        return None
    text = annotation if isinstance(annotation, str) else getattr(annotation, "__name__", str(annotation))
    kinds = set()
    parts = str(text).replace(" ", "").split("|")
    for part in parts:
        if part == "int" and "float" not in parts:
            kinds.add("int")  # a whole number: 2.5 or inf would be truncated or overflow where it is used
        elif part in ("int", "float"):
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


def _is_whole(value: object) -> bool:
    """An int, or a float with an integer value (finite: not inf, not NaN)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    return isinstance(value, int) or (math.isfinite(value) and value.is_integer())


def _kind_ok(value: object, kinds: set[str]) -> bool:
    return (("number" in kinds and _is_number(value)) or ("int" in kinds and _is_whole(value)) or ("bool" in kinds and isinstance(value, bool))
            or ("str" in kinds and isinstance(value, str)) or ("none" in kinds and value is None))


def _describe(kinds: set[str]) -> str:
    words = {"number": "a number", "int": "a whole number", "bool": "true or false", "str": "text", "none": "none"}
    return " or ".join(words[k] for k in ("number", "int", "bool", "str", "none") if k in kinds)


def signature_params(func: Callable[..., Any]) -> dict[str, inspect.Parameter]:
    """Keyword parameters of a function or of a class's ``__init__`` (``self`` left out)."""
    sig = inspect.signature(cast(Any, func).__init__ if isinstance(func, type) else func)
    kinds = (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    return {n: p for n, p in sig.parameters.items() if n != "self" and p.kind in kinds}


#: the texts a config writes for None (TOML has no null)
NONE_TEXTS = ("none", "null")


def none_from_text(func: Callable[..., Any], params: dict[str, Any]) -> dict[str, Any]:
    """``params`` with each text "none" or "null" (any case; in a grid list too) replaced by None where ``func``'s
    parameter admits None and no text (annotated ``int | None``, not ``str | None``): TOML, the configs' format, has
    no null, so ``bit_depth = "none"`` is how a config asks for ``bit_depth=None``. Other values, and parameters
    this signature does not name, are left as they are."""
    known = signature_params(func)

    def converted(key: str, value: Any) -> Any:
        kinds = _annotation_kinds(known[key].annotation) if key in known else None
        if kinds and "none" in kinds and "str" not in kinds and isinstance(value, str) and value.lower() in NONE_TEXTS:
            return None
        return value

    return {key: [converted(key, v) for v in value] if isinstance(value, list) else converted(key, value)
            for key, value in params.items()}


def check_param_types(func: Callable[..., Any], params: dict[str, Any], who: str) -> None:
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


class Parameterized:
    """``get_params`` / ``set_params`` / ``validate_params`` from the ``__init__`` signature.

    Subclasses set ``_kind`` (the word that names them in messages: "method", "hole generator") and
    ``_param_hooks``, the names of their own parameter-only range checks, the first one defined runs.
    """

    name: ClassVar[str] = ""
    _kind: ClassVar[str] = "estimator"
    _param_hooks: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def _param_names(cls) -> list[str]:
        return list(signature_params(cls))

    def get_params(self) -> dict[str, Any]:
        """The constructor parameters and their current values."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self: _Self, **params: Any) -> _Self:
        """Set constructor parameters by name (UserError naming the valid ones for an unknown name)."""
        valid = set(self._param_names())
        for key, value in params.items():
            if key not in valid:
                raise UserError(f"{self.name}: unknown parameter {key!r}; valid parameters: {sorted(valid)}")
            setattr(self, key, value)
        return self

    def validate_params(self: _Self) -> _Self:
        """Check the parameters without any data (scikit-learn style: ``__init__`` does not call it).

        First the types against the ``__init__`` signature (`check_param_types`), then the class's
        own range checks (the first of ``_param_hooks`` it defines). Raises `UserError` (a
        ValueError) naming the parameter, the value and what is allowed.
        """
        check_param_types(type(self), self.get_params(), f"{self._kind} {self.name or type(self).__name__}")
        hook = next((getattr(self, h) for h in self._param_hooks if getattr(self, h, None) is not None), None)
        if hook is not None:
            try:
                hook()
            except UserError:
                raise
            except ValueError as err:  # the hook's own refusal (it only checks parameters)
                raise UserError(str(err)) from None
        return self
