"""The package's import structure: short loops only, a light top level, complete exports.

The layer order itself is import-linter's ``layers`` contract in ``pyproject.toml``, run by
``lint-imports`` in CI; these tests guard what a layers contract cannot say.
"""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path

import grimp
import pytest

import dispeval_ros.errors

REPOSITORY = Path(__file__).resolve().parents[1]
LAZY_PACKAGES = ("dispeval_ros", "dispeval_ros.core", "dispeval_ros.io")
HEAVY = ("numba", "cv2")


def strongly_connected(edges: dict[str, set[str]]) -> list[set[str]]:
    """Tarjan's strongly connected components of a directed graph (iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[set[str]] = []
    for root, first in edges.items():
        if root in index:
            continue
        work = [(root, iter(sorted(first)))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, successors = work[-1]
            for successor in successors:
                if successor not in index:
                    index[successor] = low[successor] = len(index)
                    stack.append(successor)
                    on_stack.add(successor)
                    work.append((successor, iter(sorted(edges[successor]))))
                    break
                if successor in on_stack:
                    low[node] = min(low[node], index[successor])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    component = set()
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.add(member)
                        if member == node:
                            break
                    components.append(component)
    return components


def test_strongly_connected_finds_loops() -> None:
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}}
    assert sorted(map(sorted, strongly_connected(edges))) == [["a", "b", "c"], ["d"], ["e"]]


def test_no_import_loop_longer_than_two_modules() -> None:
    """A loop of three or more modules means a layer imports upwards somewhere (issue 22)."""
    graph = grimp.build_graph("dispeval_ros", include_external_packages=False)
    edges = {name: set(graph.find_modules_directly_imported_by(name)) for name in graph.modules}
    loops = [sorted(c) for c in strongly_connected(edges) if len(c) > 2]
    assert not loops, f"import loops of more than two modules: {loops}"


@pytest.mark.parametrize("module", ["dispeval_ros", "dispeval_ros.errors"])
def test_importing_the_package_loads_no_numba_or_opencv(module: str) -> None:
    """``from dispeval_ros.errors import InputError`` must stay cheap (lazy exports)."""
    code = f"import sys, {module}; print(' '.join(m for m in {HEAVY!r} if m in sys.modules))"
    loaded = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPOSITORY
    ).stdout.split()
    assert loaded == []


@pytest.mark.parametrize("package", LAZY_PACKAGES)
def test_every_exported_name_resolves_and_is_listed(package: str) -> None:
    """``__all__`` and the lazy table agree: each name loads, none is exported unlisted."""
    module = importlib.import_module(package)
    for name in module.__all__:
        assert getattr(module, name) is not None, name
    assert set(module.__all__) <= set(dir(module))
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        module.no_such_name  # noqa: B018


def test_every_error_class_is_exported() -> None:
    """Every exception the errors module defines is in its ``__all__``."""
    defined = {
        name
        for name, value in vars(dispeval_ros.errors).items()
        if isinstance(value, type)
        and issubclass(value, Exception)
        and value.__module__ == "dispeval_ros.errors"
    }
    assert defined == set(dispeval_ros.errors.__all__)
