"""Reading a TOML config into a validated ``Config``, with errors a person can read, and
writing the resolved config back (every default filled in)."""
import pathlib
import tomllib
import typing

import tomli_w
from pydantic import BaseModel, ValidationError

from .. import engines, protocols
from .models import Config


class ConfigError(ValueError):
    """A config that cannot run: the message names each field path, value and range."""


# the sections whose class the registries choose by kind (schema.by_kind)
KINDS = {"engine": engines.settings_classes, "protocol": protocols.base.settings_classes}


def _models_in(annotation):
    """The pydantic model classes inside an annotation (X, list[X], X | Y | None)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models_in(arg)]


def _locate(loc):
    """(dotted path, description with unit and range, or '') of the field at ``loc`` in
    Config.  The tag pydantic puts in the location of a discriminated union (the kind:
    box, oedometer) picks the section and is left out of the path."""
    models, info, path = [Config], None, []
    for part in loc:
        owner = next((m for m in models if part in m.model_fields), None)
        if owner is not None:
            info = owner.model_fields[part]
            models = _models_in(info.annotation)
        elif len(path) == 1 and path[0] in KINDS and part in KINDS[path[0]]():
            models = [KINDS[path[0]]()[part]]
            continue
        elif info is not None and info.discriminator is not None:
            tagged = [m for m in models
                      if m.model_fields[info.discriminator].default == part]
            if tagged:
                models = tagged
                continue
        path.append(str(part))
    return ".".join(path), info.description if info is not None and info.description else ""


def format_errors(error: ValidationError, source="config"):
    """One line per problem: field path = value: what is wrong (unit and allowed range)."""
    lines = [f"{source}: {error.error_count()} problem(s)"]
    for e in error.errors():
        path, doc = _locate(e["loc"])
        msg = e["msg"].removeprefix("Value error, ")
        if e["type"] == "missing":
            text = f"{path}: missing"
        elif e["type"] == "extra_forbidden":
            text = f"{path}: unknown key"
        elif e["type"].startswith("value_error") or e["type"] == "assertion_error":
            text = f"{path}: {msg}" if path else msg
        else:
            text = f"{path} = {e['input']!r}: {msg}"
        lines.append(f"  {text}" + (f"  ({doc})" if doc and e["type"] != "value_error"
                                    else ""))
    return "\n".join(lines)


def validate(data: dict, source="config") -> Config:
    """A Config from a dict; ConfigError with every problem listed otherwise."""
    try:
        return Config.model_validate(data)
    except ValidationError as err:
        raise ConfigError(format_errors(err, source)) from None


def read_toml(path, what="config"):
    """The dict of a TOML file; ConfigError when it is missing or not TOML."""
    try:
        return tomllib.loads(pathlib.Path(path).read_text())
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such {what} file") from None
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{path}: not valid TOML: {err}") from None


def load(path) -> Config:
    """Read and validate a TOML config file (ConfigError for a sweep file, which names a
    base config instead of being one)."""
    data = read_toml(path)
    if "base" in data and "grains" not in data:
        raise ConfigError(f"{path}: a sweep file (it names a base config), not a run "
                          f"config: run it with `graindyn sweep {path}`")
    return validate(data, str(path))


def dumps(config: Config) -> str:
    """The config as TOML, every default written out (fields left None are omitted)."""
    return tomli_w.dumps(config.model_dump(mode="json", exclude_none=True))
