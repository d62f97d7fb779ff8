"""A refused ``--scheduler`` is one line and leaves no results folder (executor before store)."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest
from bag_support import bag_args
from refusal_support import assert_refused, snapshot

from dispeval_ros.cli.main import main
from dispeval_ros.offline import dask_executor
from dispeval_ros.offline.make_bag import synthetic_frames, write_bag


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("bag") / "drive"
    write_bag(path, synthetic_frames(2, 64, 32, 10.0, seed=5))
    return path


def closed_port() -> int:
    """A local port nothing listens on (bound, then released)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


@pytest.mark.parametrize(
    ("scheduler", "needle"),
    [
        ("local:0", "N ≥ 1"),
        ("127.0.0.1:8786", "tcp://HOST:PORT"),
        ("tcp://", "tcp://HOST:PORT"),
        ("tls://127.0.0.1:8786", "security configuration"),
        ("wss://127.0.0.1:8786", "security configuration"),
        ("ucx://127.0.0.1:8786", "distributed-ucxx"),
        ("inproc://x", "supported: tcp://"),
        ("nothing-listening", "cannot reach the Dask scheduler"),
    ],
)
def test_a_refused_scheduler_leaves_nothing(
    bag: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    scheduler: str,
    needle: str,
) -> None:
    pytest.importorskip("distributed")
    if scheduler == "nothing-listening":
        monkeypatch.setattr(dask_executor, "CONNECT_TIMEOUT_S", 1)
        scheduler = f"tcp://127.0.0.1:{closed_port()}"
    before = snapshot(tmp_path)
    capsys.readouterr()
    code = main(bag_args(bag, tmp_path / "out", "--scheduler", scheduler))
    assert_refused(code, capsys.readouterr().err, needle)
    assert snapshot(tmp_path) == before  # no results folder, no empty database
