"""Models, one module per family; :mod:`wearnav.models.registry` maps names to constructors."""

from wearnav.models.base import OdometryModel
from wearnav.models.registry import ModelSpec, available, build, get, register

__all__ = ["ModelSpec", "OdometryModel", "available", "build", "get", "register"]
