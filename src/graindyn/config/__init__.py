"""Run configuration: pydantic models of the TOML sections, loading and resolving."""
from .load import ConfigError, dumps, load, validate
from .models import Config

__all__ = ["Config", "ConfigError", "dumps", "load", "validate"]
