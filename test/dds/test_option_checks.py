"""``live`` and ``play`` refuse every bad option before anything needs the DDS transport.

The transport's import is made to fail (as on a machine without Cyclone DDS): an option that
can never work must be its own one-line error, never the install hint.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from bag_support import bag_args
from refusal_support import assert_refused, snapshot

from dispeval_ros.cli import streams
from dispeval_ros.cli.live_cmd import live_record
from dispeval_ros.cli.main import build_parser, main
from dispeval_ros.dds import environment
from dispeval_ros.errors import ConfigurationError
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.make_bag import GT_TOPIC, synthetic_frames, write_bag

NO_TRANSPORT = "the DDS transport needs the Cyclone DDS Python binding (test)"


@pytest.fixture(autouse=True)
def no_transport(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse() -> None:
        raise ConfigurationError(NO_TRANSPORT)

    monkeypatch.setattr(environment, "require_cyclonedds", refuse)
    monkeypatch.delenv("CYCLONEDDS_URI", raising=False)
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)


def live(tmp_path: Path, *extra: str) -> list[str]:
    return ["live", "--gt", GT_TOPIC, "--method", "a=/a/disparity", "--out", str(tmp_path), *extra]


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (("--warn", "all/bpm=20"), "unknown measure 'bpm'"),
        (("--error", "all/bmp=nan"), "finite number"),
        (("--warn", "all/bmp=inf"), "finite number"),
        (("--warn", "everything/bmp=20"), "no criterion 'everything'"),
        (("--warn", "all/bad_3.0=5"), "not among the measures scored"),
        (("--warn", "gtfree:all/vpe=5"), "not among the measures scored"),
        (("--warn", "all/bmp"), "CRITERION/MEASURE=NUMBER"),
        (("--duration", "nan"), "--duration"),
        (("--queue-size", "0"), "--queue-size"),
        (("--domain-id", "300"), "out of range"),
        (("--egomotion",), "--egomotion moves each estimate by the camera's motion: give"),
        (("--odometry", "/odom"), "--odometry moves the camera for --egomotion: give it too"),
        (
            ("--egomotion", "--camera-info", "/l", "/r", "--camera-mount", "mount.txt"),
            "--camera-mount mounts the camera on the odometry's child frame: give --odometry",
        ),
        (
            (
                "--egomotion",
                "--camera-info",
                "/l",
                "/r",
                "--odometry",
                "/odom",
                "--camera-mount",
                "no-such-mount.txt",
            ),
            "no-such-mount.txt",
        ),
    ],
)
def test_live_refuses_a_bad_option_before_the_transport(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: tuple[str, ...], needle: str
) -> None:
    code = main(live(tmp_path / "out", *extra))
    err = capsys.readouterr().err
    assert_refused(code, err, needle)
    assert NO_TRANSPORT not in err
    assert not (tmp_path / "out").exists()


def test_good_options_reach_the_transport(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The control: with every option valid, the (failing) transport is what stops the run."""
    bag = tmp_path / "drive"
    write_bag(bag, synthetic_frames(2, 64, 32, 10.0, seed=6))
    extra = ("--warn", "all/bmp=20", "near/bad_2=30", "--error", "all/density=0.5")
    assert_refused(main(live(tmp_path / "out", *extra)), capsys.readouterr().err, NO_TRANSPORT)
    assert_refused(main(["play", str(bag)]), capsys.readouterr().err, NO_TRANSPORT)
    mount = tmp_path / "mount.txt"
    mount.write_text("0.3 0.3 1.65 0.5 -0.5 0.5 -0.5  # x y z qx qy qz qw\n")
    ego = ("--camera-info", "/l", "/r", "--egomotion", "--odometry", "/odom")
    assert_refused(
        main(live(tmp_path / "out", *ego, "--camera-mount", str(mount))),
        capsys.readouterr().err,
        NO_TRANSPORT,
    )


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (("--wait-matched", "nan"), "--wait-matched"),
        (("--wait-matched", "inf"), "--wait-matched"),
        (("--wait-matched", "-1"), "--wait-matched"),
        (("--rate", "nan"), "--rate"),
        (("--rate", "0"), "--rate"),
        (("--rate", "inf"), "--fast plays as fast as possible"),
        (("--rate=-1",), "--rate"),
        (("--rate", "1e400"), "--rate"),
        (("--domain-id", "-1"), "out of range"),
    ],
)
def test_play_refuses_a_bad_option_before_the_transport(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: tuple[str, ...], needle: str
) -> None:
    bag = tmp_path / "drive"
    write_bag(bag, synthetic_frames(2, 64, 32, 10.0, seed=6))
    err_code = main(["play", str(bag), *extra])
    err = capsys.readouterr().err
    assert_refused(err_code, err, needle)
    assert NO_TRANSPORT not in err


def test_play_refuses_a_missing_bag_before_the_transport(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["play", str(tmp_path / "nobag")])
    err = capsys.readouterr().err
    assert_refused(code, err, "nobag")
    assert NO_TRANSPORT not in err


def test_live_refuses_an_unusable_out_before_the_transport(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A file as --out, or results there without --resume, can never take this run's results."""
    (tmp_path / "afile").write_text("x")
    held = tmp_path / "held"
    bag = tmp_path / "drive"
    write_bag(bag, synthetic_frames(2, 64, 32, 10.0, seed=6))
    assert main(bag_args(bag, held, "--slice", "0.2")) == 0
    capsys.readouterr()
    for out, needle in ((tmp_path / "afile", "is a file"), (held, "already holds results")):
        code = main(live(out))
        err = capsys.readouterr().err
        assert_refused(code, err, needle)
        assert NO_TRANSPORT not in err


def live_results(out: Path, *extra: str) -> None:
    """Results of a ``live`` run with these options (one unit stored), as if it had run."""
    args = build_parser().parse_args(live(out, *extra))
    with ResultsStore.create(out, live_record(streams.core_config(args, "live streams"))) as store:
        store.add_unit("live-0", "0", [])


def kept(out: Path) -> dict[str, bytes]:
    """The files of a results folder, but SQLite's -wal/-shm (reading WAL results makes them)."""
    return {name: data for name, data in snapshot(out).items() if name[-4:] not in ("-wal", "-shm")}


def test_live_resume_refuses_another_configuration_before_the_transport(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--resume onto another run's results is refused up front; onto this run's, it goes on."""
    bag = tmp_path / "drive"
    write_bag(bag, synthetic_frames(2, 64, 32, 10.0, seed=6))
    assert main(bag_args(bag, tmp_path / "bag_results", "--slice", "0.2")) == 0
    live_results(tmp_path / "live_results")
    capsys.readouterr()
    for out, extra in (
        (tmp_path / "bag_results", ()),
        (tmp_path / "live_results", ("--delta", "2")),
    ):
        before = kept(out)
        code = main(live(out, "--resume", *extra))
        err = capsys.readouterr().err
        assert_refused(code, err, f"{out} holds results of another configuration")
        assert NO_TRANSPORT not in err
        assert kept(out) == before
    code = main(live(tmp_path / "live_results", "--resume"))
    assert_refused(code, capsys.readouterr().err, NO_TRANSPORT)  # the same run: the transport


def test_play_names_every_topic_the_bag_lacks_before_the_transport(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = tmp_path / "drive"
    write_bag(bag, synthetic_frames(2, 64, 32, 10.0, seed=6))
    code = main(["play", str(bag), "--topics", "/nope", GT_TOPIC, "/nada"])
    err = capsys.readouterr().err
    assert_refused(code, err, "has no topic /nope, /nada;", GT_TOPIC)
    assert NO_TRANSPORT not in err
    assert_refused(
        main(["play", str(bag), "--topics", GT_TOPIC]), capsys.readouterr().err, NO_TRANSPORT
    )
