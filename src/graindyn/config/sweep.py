"""The sweep file: a base config and the parameters to vary around it, one at a time.

```toml
base = "oedometer.toml"          # the reference run config, relative to this file
seeds = [1, 2, 3]                # random seeds per point (default: the base run.seed)
[overrides]                      # optional: base fields every point changes (dotted paths)
"output.vtk_every" = 10.0
[[vary]]
parameter = "materials.sand.youngs_modulus"   # dotted path into the config
values = [1.12e7, 1.125e8, 1.125e9, 1.8e10]
label = "V [GPa]"                             # optional display name
display = [0.0112, 0.1125, 1.125, 18.0]       # optional display values
```

This module checks the file's own shape (unknown keys, lengths, duplicates); what the
values mean is checked by building each point's ``Config`` (``graindyn.sweep``).
"""
import pathlib
import re
import warnings
from typing import Any

from pydantic import Field, ValidationError, field_validator, model_validator

from .load import ConfigError, read_toml
from .models import Float, Int, Section, moved

# config fields a sweep sets itself: varying them would be silently overridden
RESERVED = {"run.seed": "the sweep sets it per point: list the seeds in 'seeds'",
            "run.threads": "the sweep sets it to --threads-per-worker"}
# a dotted path into the config: materials.sand.youngs_modulus
PATH = re.compile(r"^[A-Za-z0-9_]+(\.[A-Za-z0-9_]+)*$")


class VarySection(Section):
    """One parameter varied around the base config, the others kept at their base values."""

    parameter: str = Field(..., min_length=1, pattern=PATH.pattern,
                           description="dotted path into the config, materials (and "
                           "other named list items) by name: materials.sand.youngs_modulus")
    values: list[Any] = Field(..., min_length=1, description="values the parameter takes, "
                              "in the units of the config field (SI)")
    label: str | None = Field(None, min_length=1, description="display name of the "
                              "parameter in tables and figures, e.g. 'V [GPa]'")
    display: list[Int | Float | str] | None = Field(
        None, description="display values in tables and figures, one per value")

    @field_validator("parameter")
    @classmethod
    def _present_path(cls, parameter):
        """A path of an older config (integrator.dt) names the field where it is now."""
        now = moved(parameter)
        if now is not None:
            warnings.warn(f"vary parameter {parameter!r} is now {now!r}", DeprecationWarning,
                          stacklevel=2)
            return now
        return parameter

    @field_validator("values")
    @classmethod
    def _unique(cls, values):
        seen = []
        for v in values:
            key = (isinstance(v, bool), v)     # True is not the value 1 (the field says so)
            if key in seen:
                raise ValueError(f"value {v!r} is listed twice")
            seen.append(key)
        return values

    @model_validator(mode="after")
    def _lengths(self):
        if self.parameter in RESERVED:
            raise ValueError(f"parameter = {self.parameter!r} cannot be varied: "
                             f"{RESERVED[self.parameter]}")
        if self.display is not None and len(self.display) != len(self.values):
            raise ValueError(f"display has {len(self.display)} entries but values has "
                             f"{len(self.values)}: give one display value per value")
        return self


class SweepFile(Section):
    """A whole sweep: the base config, the seeds and the parameters varied."""

    base: str = Field(..., min_length=1, description="path of the base (reference) run "
                      "config, relative to the sweep file")
    seeds: list[Int] | None = Field(None, min_length=1, description="random seeds [-] of "
                                    "every point (each >= 0); default: the base run.seed")
    overrides: dict[str, Any] = Field({}, description="fields of the base config "
                                      "changed for every point, the reference included: "
                                      "dotted path -> value (a shorter run, no VTK...)")
    vary: list[VarySection] = Field([], description="parameters varied one at a time")

    @field_validator("seeds")
    @classmethod
    def _seeds(cls, seeds):
        if seeds is not None:
            if any(s < 0 for s in seeds):
                raise ValueError(f"seeds = {seeds}: each seed must be >= 0")
            if len(set(seeds)) != len(seeds):
                raise ValueError(f"seeds = {seeds}: a seed is listed twice")
        return seeds

    @field_validator("overrides")
    @classmethod
    def _overridable(cls, overrides):
        """Paths as vary's (older paths renamed), none the sweep sets itself."""
        out = {}
        for path, value in overrides.items():
            if not PATH.fullmatch(path):
                raise ValueError(f"{path!r} is not a dotted path into the config")
            path = VarySection._present_path(path)
            if path in RESERVED:
                raise ValueError(f"{path!r} cannot be overridden: {RESERVED[path]}")
            out[path] = value
        return out

    @model_validator(mode="after")
    def _distinct_parameters(self):
        seen = {}
        for k, vary in enumerate(self.vary):
            if vary.parameter in seen:
                raise ValueError(f"vary.{k}.parameter = {vary.parameter!r} is already "
                                 f"varied in vary.{seen[vary.parameter]}: merge the values")
            seen[vary.parameter] = k
            if vary.parameter in self.overrides:
                raise ValueError(f"vary.{k}.parameter = {vary.parameter!r} is also in "
                                 "overrides: give its base value there or vary it, not both")
        return self


def _format(error: ValidationError, source):
    lines = [f"{source}: {error.error_count()} problem(s)"]
    for e in error.errors():
        path = ".".join(str(p) for p in e["loc"])
        msg = e["msg"].removeprefix("Value error, ")
        if e["type"] == "missing":
            text = f"{path}: missing"
        elif e["type"] == "extra_forbidden":
            text = f"{path}: unknown key"
        elif e["type"].startswith("value_error"):
            text = f"{path}: {msg}" if path else msg
        else:
            text = f"{path} = {e['input']!r}: {msg}"
        lines.append(f"  {text}")
    return "\n".join(lines)


def load_sweep_file(path) -> SweepFile:
    """Read and check a sweep file; ConfigError naming every problem otherwise."""
    path = pathlib.Path(path)
    data = read_toml(path, "sweep")
    if "base" not in data and "grains" in data:
        raise ConfigError(f"{path}: a run config, not a sweep file (a sweep file names its "
                          f"base config: base = ...): run it with `graindyn run {path}`")
    try:
        return SweepFile.model_validate(data)
    except ValidationError as err:
        raise ConfigError(_format(err, str(path))) from None
