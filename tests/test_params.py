"""`metrics.params`: the one parameter check of methods and hole generators (scikit-learn style)."""

from __future__ import annotations

import pytest

from dpcbench.holes.base import HoleGenerator
from dpcbench.methods.base import InpaintingMethod
from dpcbench.metrics.errors import UserError
from dpcbench.metrics.params import Parameterized, check_param_types, signature_params


class _Toy(Parameterized):
    name = "toy"
    _kind = "thing"
    _param_hooks = ("_first", "_second")

    def __init__(self, size: float = 1.0, *, mode: str = "a", flag=False, extra=None):
        self.size = size
        self.mode = mode
        self.flag = flag
        self.extra = extra

    def _second(self) -> None:  # never reached while _first exists
        raise AssertionError("only the first hook defined runs")

    def _first(self) -> None:
        if self.size <= 0:
            raise ValueError(f"toy: size must be > 0, got {self.size}")


def test_methods_and_hole_generators_share_one_implementation():
    for base in (InpaintingMethod, HoleGenerator):
        assert issubclass(base, Parameterized)
        assert base.validate_params is Parameterized.validate_params
        assert base.get_params is Parameterized.get_params


def test_get_and_set_params_follow_the_signature():
    toy = _Toy(size=2.5, mode="b")
    assert list(signature_params(_Toy)) == ["size", "mode", "flag", "extra"]
    assert toy.get_params() == {"size": 2.5, "mode": "b", "flag": False, "extra": None}
    assert toy.set_params(size=3.0) is toy and toy.size == 3.0
    with pytest.raises(UserError, match=r"toy: unknown parameter 'sizes'; valid parameters: \['extra', 'flag'"):
        toy.set_params(sizes=1)


def test_types_are_checked_from_annotations_then_defaults():
    check_param_types(_Toy, {"size": 2, "mode": "x", "flag": True, "extra": [1, 2]}, "toy")  # all fine
    with pytest.raises(UserError, match="toy: parameter size must be a number, got 'big'"):
        check_param_types(_Toy, {"size": "big"}, "toy")
    with pytest.raises(UserError, match="toy: parameter size must be a number, got True"):
        check_param_types(_Toy, {"size": True}, "toy")  # a bool is not a number here
    with pytest.raises(UserError, match="toy: parameter flag must be true or false, got 1"):
        check_param_types(_Toy, {"flag": 1}, "toy")  # no annotation: the default's type decides
    with pytest.raises(UserError, match="toy: unknown parameter.s. colour; valid parameters: size, mode, flag, extra"):
        check_param_types(_Toy, {"colour": 1}, "toy")


def test_validate_params_runs_the_first_hook_and_keeps_its_message():
    assert _Toy().validate_params().size == 1.0
    with pytest.raises(UserError, match="thing toy: parameter mode must be text, got 3"):
        _Toy(mode=3).validate_params()
    with pytest.raises(UserError, match=r"^toy: size must be > 0, got -1$") as info:
        _Toy(size=-1).validate_params()
    assert type(info.value) is UserError  # the hook's plain ValueError becomes the one error class
