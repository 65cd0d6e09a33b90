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
        """``n_segments: true`` is not 1, nor ``actuated: 1`` true: a boolean where a number belongs
        is refused, and a number or text where a boolean belongs, in lists and tuples too."""
        if info.field_name is not None:
            field = cls.model_fields[info.field_name]
            why = _mistyped(value, field.annotation, field.metadata, cls.text_numbers)
            if why is not None:
                raise ValueError(why)
        return value


def _mistyped(value: Any, annotation: Any, metadata: list[Any], text_numbers: bool) -> str | None:
    """Why ``value`` is not of ``annotation``'s plain kind (number or boolean), or None."""
    kinds = _kinds(annotation)
    if isinstance(value, bool):
        if bool not in kinds and str not in kinds and kinds & {int, float}:
            return "expected a number, not a boolean"
        return None
    if isinstance(value, int | float | str) and bool in kinds and not kinds - {bool, type(None)}:
        what = "text" if isinstance(value, str) else "a number"
        return f"expected true or false, not {what} ({value!r})"
    if isinstance(value, str) and not text_numbers:
        if bool not in kinds and str not in kinds and kinds & {int, float}:
            kind = "an integer" if float not in kinds else "a number"
            hint = " (unquote it)" if _spells_number(value) else ""
            return f"expected {kind}{_range(metadata)}, not text{hint}"
        return None
    if isinstance(value, list | tuple):
        for i, (item, inner) in enumerate(zip(value, _items(annotation, len(value)), strict=False)):
            why = _mistyped(item, inner, [], text_numbers)
            if why is not None:  # item [0][1]: ... for an item of an item
                return (
                    f"item [{i}]{why.removeprefix('item ')}"
                    if why.startswith("item [")
                    else f"item [{i}]: {why}"
                )
    return None


def _items(annotation: Any, n: int) -> list[Any]:
    """The annotation of each of ``n`` items of a list or tuple ``annotation`` (through Optional)."""
    for arg in (annotation, *get_args(annotation)):
        origin = get_origin(arg)
        args = get_args(arg)
        if origin is Annotated:
            return _items(args[0], n)
        if origin in (list, tuple) and args:
            if origin is list or (len(args) == 2 and args[1] is Ellipsis):
                return [args[0]] * n
            return list(args)
    return []


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
