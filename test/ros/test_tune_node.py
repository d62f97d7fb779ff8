"""``dispeval tune --node``: a sweep of a running test-bed disparity node over real rclpy.

The node runs as its own process (``python -m dispeval_ros.ros.testbed_disparity``, or
``tune_target.py`` when it must refuse a value or die), in the ``ros`` harness's domain so the
harness can read its parameters before and after. A sweep of 6 SGBM configurations on two
MiddEval3 Q scenes must store, frame for frame, the very rows the offline ``tune`` of the same
space stores (issue 25's must-hold), with no frame dropped, and leave the node's parameters as
it found them. A refused value and a node that dies are one line with exit 2 and a database
that ``--resume`` completes; so is Ctrl-C (exit 130), the node's parameters restored; a node that
is not there, or one without the disparity node's parameters, is one line and nothing written.

The space starts the search at ``min_disparity: 1``: the offline sweep scores a map as a file
(valid means > 0) and the node's maps as the message defines them (valid inside
``[min_disparity, max_disparity]``, so a match at 0 is valid); from 1 the two agree.
"""

from __future__ import annotations

import itertools
import os
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from ros_nodes_support import DOMAIN_ID
from ros_support import Ros, ros_import

from dispeval_ros.cli.main import main
from dispeval_ros.io.store import RESULTS_FILE, ResultsStore
from dispeval_ros.testbed.disparity_node import node_defaults

parameter_client = ros_import("dispeval_ros.ros.parameter_client")
ros_import("dispeval_ros.ros.tune_node")

pytestmark = [pytest.mark.data, pytest.mark.slow]

SCENES = ("ArtL", "Teddy")
SPACE = """
family: sgbm
parameters:
  correlation_window_size: [5, 9]
  uniqueness_ratio: [5, 10, 15]
  min_disparity: 1
  disparity_range: 64
  P1: 200
  P2: 800
  speckle_size: 50
  speckle_range: 2
"""
CONFIGURATIONS = [f"sgbm_w{w}_u{u}" for w, u in itertools.product((5, 9), (5, 10, 15))]
HERE = Path(__file__).resolve().parent
_names = itertools.count()


@pytest.fixture
def domain(monkeypatch: pytest.MonkeyPatch) -> None:
    """The command's rclpy context in the harness's domain (the node's too)."""
    monkeypatch.setenv("ROS_DOMAIN_ID", str(DOMAIN_ID))


@pytest.fixture
def space(tmp_path: Path) -> Path:
    path = tmp_path / "space.yaml"
    path.write_text(SPACE)
    return path


@pytest.fixture(scope="module")
def offline(shared_data: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The offline sweep of the same space on the same scenes."""
    root = tmp_path_factory.mktemp("offline")
    (root / "space.yaml").write_text(SPACE)
    out = root / "out"
    argv = ["tune", "--space", str(root / "space.yaml"), *scene_args(shared_data)]
    assert main([*argv, "--out", str(out), "--quiet", "--json"]) == 0
    return out


def scene_args(shared_data: Path) -> list[str]:
    folder = shared_data / "middeval3-training-Q"
    return [a for name in SCENES for a in ("--scene", str(folder / name))]


class NodeProcess:
    """A disparity node in a namespace of its own, as a process."""

    def __init__(self, *extra: str, namespace: str | None = None) -> None:
        self.namespace = namespace or f"/tune_{os.getpid()}_{next(_names)}"
        self.name = f"{self.namespace}/disparity_node"
        env = {**os.environ, "ROS_DOMAIN_ID": str(DOMAIN_ID)}
        paths = [str(HERE.parents[1]), env.get("PYTHONPATH", "")]
        env["PYTHONPATH"] = os.pathsep.join(p for p in paths if p)
        if extra:
            command = [sys.executable, str(HERE / "tune_target.py"), self.namespace, *extra]
        else:
            command = [sys.executable, "-m", "dispeval_ros.ros.testbed_disparity", "--ros-args"]
            command += ["-r", f"__ns:={self.namespace}"]
        self.process = subprocess.Popen(
            command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
        )

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


@pytest.fixture
def nodes() -> Iterator[list[NodeProcess]]:
    started: list[NodeProcess] = []
    yield started
    for node in started:
        node.stop()


def remote(ros: Ros, node: NodeProcess) -> Any:
    client = parameter_client.RemoteParameters(ros.helper, node.name, ros.executor, timeout=20.0)
    client.wait()
    return client


def frame_rows(folder: Path) -> list[tuple[object, ...]]:
    """Every frame row but its unit (offline units hold 8 configurations, the node's one)."""
    db = sqlite3.connect(folder / RESULTS_FILE)
    try:
        columns = [row[1] for row in db.execute("PRAGMA table_info(frames)") if row[1] != "unit"]
        listed = ", ".join(f'"{c}"' for c in columns)
        return db.execute(
            f"SELECT {listed} FROM frames ORDER BY sequence, stamp, method, criterion"
        ).fetchall()
    finally:
        db.close()


def dropped(folder: Path) -> int:
    db = sqlite3.connect(folder / RESULTS_FILE)
    try:
        return int(db.execute("SELECT SUM(dropped) FROM match_counts").fetchone()[0])
    finally:
        db.close()


def tune_node(
    capsys: pytest.CaptureFixture[str], space: Path, shared: Path, node: str, out: Path, *more: str
) -> tuple[int, str]:
    argv = ["tune", "--node", node, "--space", str(space), *scene_args(shared), "--out", str(out)]
    code = main([*argv, "--quiet", *more])
    return code, capsys.readouterr().err


def test_a_live_sweep_stores_the_offline_scores_and_restores_the_node(
    ros: Ros,
    domain: None,
    nodes: list[NodeProcess],
    space: Path,
    offline: Path,
    shared_data: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    node = NodeProcess()
    nodes.append(node)
    parameters = remote(ros, node)
    found = {"uniqueness_ratio": 12.0, "speckle_size": 77}  # not the defaults: what it had
    parameters.set(found)
    names = list(node_defaults())
    before = parameters.get(names)
    assert {k: before[k] for k in found} == found

    started = time.monotonic()
    code, err = tune_node(capsys, space, shared_data, node.name, tmp_path / "live")
    seconds = time.monotonic() - started
    assert code == 0, err
    rows = frame_rows(tmp_path / "live")
    assert len(rows) == len(CONFIGURATIONS) * len(SCENES) * 7  # the default partition's criteria
    assert rows == frame_rows(offline)
    assert dropped(tmp_path / "live") == 0
    with ResultsStore.open(tmp_path / "live") as store:
        assert sorted(store.methods()) == sorted(CONFIGURATIONS)
        assert store.config()["node"] == node.name
    assert parameters.get(names) == before
    print(
        f"live sweep of {len(CONFIGURATIONS)} configurations x {len(SCENES)} frames: {seconds:.1f} s"
    )


def test_a_refused_value_is_one_line_and_resume_completes_the_database(
    ros: Ros,
    domain: None,
    nodes: list[NodeProcess],
    space: Path,
    offline: Path,
    shared_data: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    refusing = NodeProcess("--refuse", "correlation_window_size=9")
    nodes.append(refusing)
    before = remote(ros, refusing).get(list(node_defaults()))
    out = tmp_path / "live"
    code, err = tune_node(capsys, space, shared_data, refusing.name, out)
    assert code == 2
    (line,) = err.strip().splitlines()
    assert f"node {refusing.name} refused " in line
    assert "correlation_window_size = 9" in line
    assert "the 3 configuration unit(s) written are kept, continue with --resume" in line
    assert remote(ros, refusing).get(list(node_defaults())) == before
    with ResultsStore.open(out) as store:
        assert sorted(store.methods()) == sorted(CONFIGURATIONS[:3])
    refusing.stop()  # the same node, now willing: the run continues where it stopped
    willing = NodeProcess(namespace=refusing.namespace)
    nodes.append(willing)
    remote(ros, willing)
    code, err = tune_node(capsys, space, shared_data, willing.name, out, "--resume")
    assert code == 0, err
    assert frame_rows(out) == frame_rows(offline)


def test_a_first_configuration_refused_is_one_line_and_writes_nothing(
    ros: Ros,
    domain: None,
    nodes: list[NodeProcess],
    space: Path,
    shared_data: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    refusing = NodeProcess("--refuse", "correlation_window_size=5")
    nodes.append(refusing)
    before = remote(ros, refusing).get(list(node_defaults()))
    out = tmp_path / "live"
    code, err = tune_node(capsys, space, shared_data, refusing.name, out)
    assert code == 2
    (line,) = err.strip().splitlines()
    assert f"node {refusing.name} refused " in line
    assert "correlation_window_size 5 not here" in line
    assert not out.exists()
    assert remote(ros, refusing).get(list(node_defaults())) == before


def test_a_node_that_dies_mid_run_is_one_line_and_keeps_what_was_done(
    ros: Ros,
    domain: None,
    nodes: list[NodeProcess],
    space: Path,
    shared_data: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    dying = NodeProcess("--die-after", "3")  # the check frame, then two units (one frame each)
    nodes.append(dying)
    remote(ros, dying)
    out = tmp_path / "live"
    code, err = tune_node(capsys, space, shared_data, dying.name, out, "--timeout", "1")
    assert code == 2
    (line,) = err.strip().splitlines()
    assert f"node {dying.name} stopped answering during configuration {CONFIGURATIONS[2]}" in line
    assert "2 configuration unit(s) written are kept" in line
    with ResultsStore.open(out) as store:
        assert sorted(store.methods()) == sorted(CONFIGURATIONS[:2])


def test_ctrl_c_restores_the_node_and_resume_completes_the_database(
    ros: Ros,
    domain: None,
    nodes: list[NodeProcess],
    space: Path,
    offline: Path,
    shared_data: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    slow = NodeProcess("--delay", "0.3")
    nodes.append(slow)
    parameters = remote(ros, slow)
    before = parameters.get(list(node_defaults()))
    out = tmp_path / "live"
    argv = ["tune", "--node", slow.name, "--space", str(space), *scene_args(shared_data)]
    command = [sys.executable, "-m", "dispeval_ros", *argv, "--out", str(out), "--quiet"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(HERE.parents[1]), *sys.path])}
    run = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        while units_done(out) < 2 and run.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        run.send_signal(signal.SIGINT)
        _, err = run.communicate(timeout=60)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
    assert run.returncode == 130, err
    assert len(err.decode().strip().splitlines()) == 1, err  # "interrupted", no traceback
    assert 2 <= units_done(out) < len(CONFIGURATIONS) * len(SCENES)
    assert parameters.get(list(node_defaults())) == before
    code, err = tune_node(capsys, space, shared_data, slow.name, out, "--resume")
    assert code == 0, err
    assert frame_rows(out) == frame_rows(offline)


def units_done(folder: Path) -> int:
    """Units written so far (read while the run writes)."""
    if not (folder / RESULTS_FILE).is_file():
        return 0
    db = sqlite3.connect(folder / RESULTS_FILE, timeout=5)
    try:
        return int(db.execute("SELECT COUNT(*) FROM units").fetchone()[0])
    except sqlite3.OperationalError:  # tables not made yet
        return 0
    finally:
        db.close()


def test_a_node_that_does_not_exist_is_one_line_and_writes_nothing(
    domain: None, space: Path, shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "live"
    code, err = tune_node(capsys, space, shared_data, "/no_such_disparity_node", out)
    assert code == 2
    (line,) = err.strip().splitlines()
    assert "no node /no_such_disparity_node" in line
    assert not out.exists()


def test_a_node_without_the_parameters_is_one_line_and_writes_nothing(
    ros: Ros,
    domain: None,
    space: Path,
    shared_data: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    stop = threading.Event()

    def spin() -> None:  # the harness's helper node answers its parameter services meanwhile
        while not stop.is_set():
            ros.executor.spin_once(timeout_sec=0.05)

    thread = threading.Thread(target=spin)
    thread.start()
    out = tmp_path / "live"
    try:
        code, err = tune_node(capsys, space, shared_data, f"/{ros.helper.get_name()}", out)
    finally:
        stop.set()
        thread.join()
    assert code == 2
    (line,) = err.strip().splitlines()
    assert f"node /{ros.helper.get_name()} has no parameter 'stereo_algorithm'" in line
    assert not out.exists()
