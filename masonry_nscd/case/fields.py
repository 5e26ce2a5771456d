"""The field types of the case schema and the base of its sections.

``Real`` and ``Whole`` are lax numbers (numeric text is converted) that refuse ``true`` and
``false``; ``Section`` forbids unknown keys, validates assignments and refuses inf and NaN.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field
from pydantic_core import PydanticCustomError


def _reject_bool(value: Any) -> Any:
    """Refuse ``true``/``false`` where a number is expected (pydantic would read them as 1/0)."""
    if isinstance(value, bool):
        raise PydanticCustomError("number_type", "a number is expected, not true/false")
    return value


#: A real number (lax: ints and numeric text are converted; booleans are refused).
Real = Annotated[float, BeforeValidator(_reject_bool)]
#: A whole number (lax: 3.0 and "3" are converted; 3.5 and booleans are refused).
Whole = Annotated[int, BeforeValidator(_reject_bool)]
#: Number of hexahedra of one unit along one direction.
ElementCount = Annotated[int, BeforeValidator(_reject_bool), Field(ge=1, le=16)]

SQRT3 = math.sqrt(3.0)


class Section(BaseModel):
    """Common configuration: unknown keys are errors, assignments are validated, no inf/nan.

    An assignment that breaks a field's own bounds is refused (pydantic ``ValidationError``) and
    leaves the model unchanged; one that breaks a cross-field check of the section (e.g. the
    running-bond identity) raises too, but pydantic has already stored the value. To change
    several related values, build a new case: ``case_from_dict(case.model_dump() | {...})``.
    """

    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False)


Vector3 = tuple[Real, Real, Real]


def _unit(value: tuple[float, float, float]) -> tuple[float, float, float]:
    """A direction (3 components, not all zero) made a unit vector."""
    norm = math.sqrt(sum(v * v for v in value))
    if not norm > 0.0:
        raise PydanticCustomError("direction_zero", "a direction needs a non-zero component")
    return tuple(v / norm for v in value)  # type: ignore[return-value]


Direction = Annotated[Vector3, AfterValidator(_unit)]


def given(model: BaseModel, path: str) -> bool:
    """Whether the dotted ``path`` was given in the case (not a default)."""
    *parents, last = path.split(".")
    for part in parents:
        if part not in model.model_fields_set:
            return False
        model = getattr(model, part)
    return last in model.model_fields_set and getattr(model, last) is not None

