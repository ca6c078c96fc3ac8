"""Reading a TOML config into a validated ``Config``, with errors a person can read, and
writing the resolved config back (every default filled in)."""
import pathlib
import tomllib
import typing

import tomli_w
from pydantic import BaseModel, ValidationError

from .models import Config


class ConfigError(ValueError):
    """A config that cannot run: the message names each field path, value and range."""


def _model_in(annotation):
    """The pydantic model class inside an annotation (X, list[X], X | None), if any."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _model_in(arg)
        if found is not None:
            return found
    return None


def _describe(loc):
    """Description (unit and range) of the field at ``loc`` in Config, or ''."""
    cls, info = Config, None
    for part in loc:
        if isinstance(part, int) or cls is None or part not in cls.model_fields:
            continue
        info = cls.model_fields[part]
        cls = _model_in(info.annotation)
    return info.description if info is not None and info.description else ""


def format_errors(error: ValidationError, source="config"):
    """One line per problem: field path = value: what is wrong (unit and allowed range)."""
    lines = [f"{source}: {error.error_count()} problem(s)"]
    for e in error.errors():
        path = ".".join(str(p) for p in e["loc"] if p not in ("box", "cylinder"))
        msg = e["msg"].removeprefix("Value error, ")
        if e["type"] == "missing":
            text = f"{path}: missing"
        elif e["type"] == "extra_forbidden":
            text = f"{path}: unknown key"
        elif e["type"].startswith("value_error") or e["type"] == "assertion_error":
            text = f"{path}: {msg}" if path else msg
        else:
            text = f"{path} = {e['input']!r}: {msg}"
        doc = _describe(e["loc"])
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
    """Read and validate a TOML config file."""
    return validate(read_toml(path), str(path))


def dumps(config: Config) -> str:
    """The config as TOML, every default written out (fields left None are omitted)."""
    return tomli_w.dumps(config.model_dump(mode="json", exclude_none=True))
