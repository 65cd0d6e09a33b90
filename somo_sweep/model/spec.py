"""The base of every description (unknown keys, NaN and booleans for numbers refused; frozen),
and the validated types the descriptions share: names, vectors, bounded lists."""

from __future__ import annotations

import re
from types import UnionType
from typing import Annotated, Any, ClassVar, Union, get_args, get_origin

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, ValidationInfo, field_validator

from somo_sweep.model.bounds import MAX_NAME_CHARS, NAME_PATTERN

__all__ = ["Name", "Spec", "Vec3", "at_most", "check_name"]

Vec3 = tuple[float, float, float]


def check_name(value: str) -> str:
    """``value`` if it is a name safe in URDF and in file names (see :data:`NAME_PATTERN`)."""
    if len(value) > MAX_NAME_CHARS:
        raise ValueError(f"a name may be at most {MAX_NAME_CHARS} characters long, got {len(value)}")
    if not re.fullmatch(NAME_PATTERN, value):
        raise ValueError(f"a name may hold only letters, digits, '_', '.' and '-' (pattern {NAME_PATTERN})")
    return value


#: A name that is safe in URDF and in file names.
Name = Annotated[str, AfterValidator(check_name)]


def at_most(limit: int, what: str) -> BeforeValidator:
    """Refuse a list longer than ``limit`` before validating its items (bounded time)."""

    def check(value: Any) -> Any:
        if isinstance(value, list | tuple) and len(value) > limit:
            raise ValueError(f"{len(value)} {what}; allowed: at most {limit}")
        return value

    return BeforeValidator(check)


class Spec(BaseModel):
    """Base of every description: unknown keys fail, NaN and infinity fail, instances are immutable.

    A description with ``text_numbers = False`` also refuses text where a number belongs
    (``noslip_iterations: "5"``: quoting keeps a value text), naming the range allowed.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)
    #: Whether text that spells a number is taken for one in a number field.
    text_numbers: ClassVar[bool] = True

    @field_validator("*", mode="before")
    @classmethod
    def _no_boolean_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        """``n_segments: true`` is not 1: a boolean where a number belongs is refused."""
        text = isinstance(value, str) and not cls.text_numbers
        if (isinstance(value, bool) or text) and info.field_name is not None:
            field = cls.model_fields[info.field_name]
            kinds = _kinds(field.annotation)
            if bool not in kinds and str not in kinds and kinds & {int, float}:
                if not text:
                    raise ValueError("expected a number, not a boolean")
                kind = "an integer" if float not in kinds else "a number"
                hint = " (unquote it)" if _spells_number(value) else ""
                raise ValueError(f"expected {kind}{_range(field.metadata)}, not text{hint}")
        return value


def _range(metadata: list[Any]) -> str:
    """`` from 0 to 1000``, `` > 0``...: the bounds of a field, as a message says them."""
    bounds = {k: getattr(m, k.lower()) for m in metadata if (k := type(m).__name__) in _BOUNDS}
    low = f"{bounds['Ge']:g}" if "Ge" in bounds else None
    high = f"{bounds['Le']:g}" if "Le" in bounds else None
    if low is not None and high is not None:
        return f" from {low} to {high}"
    parts = [f"{_BOUNDS[k]} {v:g}" for k, v in bounds.items()]
    return f" {' and '.join(parts)}" if parts else ""


_BOUNDS = {"Ge": ">=", "Gt": ">", "Le": "<=", "Lt": "<"}


def _spells_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _kinds(annotation: Any) -> set[Any]:
    """The plain types an annotation admits (through unions, Annotated and Optional)."""
    args = get_args(annotation)
    if not args:
        return {annotation}
    if get_origin(annotation) is Annotated:
        return _kinds(args[0])
    if get_origin(annotation) in (Union, UnionType):
        return set().union(*(_kinds(a) for a in args))
    return {get_origin(annotation)}
