"""What a run does with its grains: protocols made of phases (protocols.base), and the
registry PROTOCOLS of every protocol a config may name (protocol.kind)."""
from .base import PROTOCOLS, Phase, Protocol, Vessel, register
from . import cyclic, deposition, gas, oedometer, silo, vibrated  # noqa: F401,E402  (each registers its protocol)

__all__ = ["PROTOCOLS", "Phase", "Protocol", "Vessel", "register"]
