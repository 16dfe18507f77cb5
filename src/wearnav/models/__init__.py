"""Models, one module per family; :mod:`wearnav.models.registry` maps names to constructors.

The names below are imported on first use (PEP 562), so that :mod:`wearnav.models.catalogue`
(the registry's table, read without torch) does not load torch with its package."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from wearnav.models.base import OdometryModel
    from wearnav.models.registry import ModelSpec, available, build, get, register

__all__ = ["ModelSpec", "OdometryModel", "available", "build", "get", "register"]
_WHERE = {"OdometryModel": "wearnav.models.base"} | {
    n: "wearnav.models.registry" for n in ("ModelSpec", "available", "build", "get", "register")
}


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
