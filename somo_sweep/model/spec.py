"""The base of every description (unknown keys, NaN and booleans for numbers refused; frozen),
and the validated types the descriptions share: names, vectors, bounded lists."""

from __future__ import annotations

import re
from types import UnionType
from typing import Annotated, Any, Union, get_args, get_origin

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
    """Base of every description: unknown keys fail, NaN and infinity fail, instances are immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _no_boolean_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        """``n_segments: true`` is not 1: a boolean where a number belongs is refused."""
        if isinstance(value, bool) and info.field_name is not None:
            kinds = _kinds(cls.model_fields[info.field_name].annotation)
            if bool not in kinds and kinds & {int, float}:
                raise ValueError("expected a number, not a boolean")
        return value


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
