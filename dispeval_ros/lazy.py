"""Lazy package exports (PEP 562): a package's names load their module on first use.

``import dispeval_ros`` or ``dispeval_ros.errors`` then loads no numba or OpenCV; the heavy
modules load when a name that needs them (``Evaluator``) is first read. Each package lists
once which module holds each exported name; a type checker reads the same imports under
``TYPE_CHECKING``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, MutableMapping, Sequence
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(
    namespace: MutableMapping[str, Any], modules: Mapping[str, Sequence[str]]
) -> tuple[Callable[[str], object], Callable[[], list[str]]]:
    """``__getattr__`` and ``__dir__`` for the package of ``namespace`` (its ``globals()``).

    ``modules`` maps a module to the names the package exports from it.

    A name is imported from its module when first read and then kept in the package's
    namespace, so later reads cost nothing. Any other name is an ``AttributeError`` as usual.
    """
    package = namespace["__name__"]
    where = {name: module for module, names in modules.items() for name in names}

    def attribute(name: str) -> object:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    def names() -> list[str]:
        return sorted({*namespace, *where})

    return attribute, names
