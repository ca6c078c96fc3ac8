"""The building blocks of config sections, shared by every layer that declares one
(the config itself, each engine's settings, each protocol's parameters).

A ``Section`` refuses unknown keys, validates assignments and means every number to be
finite; a ``Float`` or ``Int`` field refuses booleans and strings, which pydantic would
otherwise read as numbers (true as 1, "2650" as 2650.0).  ``described`` writes a
field's unit and range into its description, where ``graindyn`` users read them.
"""
from typing import Annotated

import numpy as np
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field
from pydantic_core import PydanticCustomError


def _number(value):
    """``value`` unchanged unless it is a boolean or a string."""
    if isinstance(value, (bool, np.bool_, str)):
        raise PydanticCustomError("number_type", "Input should be a number, not {kind}",
                                  {"kind": "a string" if isinstance(value, str)
                                   else "a boolean"})
    return value


# the numbers of every section, also inside tuples, lists and dicts; finite by
# Section's allow_inf_nan=False
Float = Annotated[float, BeforeValidator(_number)]
Int = Annotated[int, BeforeValidator(_number)]


class Section(BaseModel):
    """A config section: unknown keys are errors, assignments are validated, and numbers
    are finite: no field means inf or nan (a field that may be absent is None)."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False)


def described(default=..., doc="", **bounds):
    """A field with its unit and range written into its description."""
    return Field(default, description=doc, **bounds)


def by_kind(classes, what, default):
    """A ``field_validator(mode="wrap")`` body for a section whose class is chosen by its
    ``kind`` key: ``classes()`` gives kind -> Section class (a registry, read at each
    validation so that every registered kind is known), ``what`` names the section in
    messages, ``default`` is the kind of a section that gives none.  The errors of the
    chosen class keep their own locations under the section's, after the kind (as
    pydantic tags the members of a discriminated union)."""
    from pydantic import ValidationError
    from pydantic_core import InitErrorDetails

    def validate(cls, value, handler):
        if not isinstance(value, dict):
            return handler(value)
        known = classes()
        kind = value.get("kind", default)
        if kind not in known:
            article = "an" if what[0] in "aeiou" else "a"
            raise ValueError(f"{what}.kind = {kind!r} is not {article} {what} of this "
                             f"version; {what}s: " + ", ".join(known))
        try:
            return known[kind].model_validate({**value, "kind": kind})
        except ValidationError as err:
            raise ValidationError.from_exception_data(what, [
                InitErrorDetails(type=PydanticCustomError(e["type"], e["msg"]),
                                 loc=(kind, *e["loc"]), input=e["input"])
                for e in err.errors()]) from None

    return validate
