"""PEP 517 build backend: setuptools, with the runtime requirements in a wheel's build environment.

``setup.py`` compiles the numba kernels into the wheel (:mod:`dispeval_ros.jitcache`), so a
fresh ``pip install .`` does not compile them on its first run. That needs numba and the
package's other requirements where the wheel is built: pip's isolated build environment gets
them from here. Everything else is setuptools' own backend.
"""

from __future__ import annotations

from typing import Any

from setuptools import build_meta as _setuptools
from setuptools.build_meta import (  # noqa: F401  (the hooks this backend leaves as they are)
    build_editable,
    build_sdist,
    build_wheel,
    get_requires_for_build_editable,
    get_requires_for_build_sdist,
    prepare_metadata_for_build_editable,
    prepare_metadata_for_build_wheel,
)

from buildtools.requirements import requirements


def get_requires_for_build_wheel(config_settings: dict[str, Any] | None = None) -> list[str]:
    """The build requirements of setuptools and the runtime ones (to compile the kernels)."""
    return [*_setuptools.get_requires_for_build_wheel(config_settings), *requirements()]
