"""``eval --scene FRAMES --flicker [N]``: each method's flicker over a scene's frames.

The frames of a scene folder taken by a static camera (a sequence of one view) are handed, in
the scene's order, to the same :class:`~dispeval_ros.stream.flicker.FlickerStage` as
``dispeval bag --flicker``: tumbling windows of N frames per method, each scored on the
``gtfree:`` criteria of its first frame's images (with ``--gt-free``; else ``all``). A scene's
frames have no stamps: the stage's stamps are the frames' positions (0, 1, …; the JSON lists
the frames by name) and no gap ends a window. Nothing checks that the camera stood still.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import reduce
from operator import add
from typing import TYPE_CHECKING, Any

from dispeval_ros.errors import ConfigurationError

if TYPE_CHECKING:
    from dispeval_ros.core.egomotion import TemporalSums

OPTION = "--flicker"
NO_GAP_NS = 2**62
"""A scene's frames are numbered, not stamped: no gap between them ends a window."""


def add_options(parser: argparse.ArgumentParser) -> None:
    """``--flicker [N]`` (off by default: nothing changes without it)."""
    from dispeval_ros.stream.flicker import DEFAULT_FLICKER_WINDOW, FLICKER_RULE

    parser.add_argument(
        OPTION,
        type=int,
        nargs="?",
        const=DEFAULT_FLICKER_WINDOW,
        default=0,
        metavar="N",
        help=f"with --scene of frames taken by a static camera: {FLICKER_RULE} (the frames in "
        f"the scene's order; N default {DEFAULT_FLICKER_WINDOW}; docs/method.md)",
    )


def check_options(args: argparse.Namespace) -> None:
    """Refuse ``--flicker`` where there is no sequence of frames, or a window of one (one line)."""
    from dispeval_ros.stream.flicker import FlickerStage

    if not args.flicker:
        return
    try:
        FlickerStage(args.flicker)
    except ConfigurationError as error:
        raise ConfigurationError(f"{OPTION}: {error}") from None
    if args.protocol is not None:
        raise ConfigurationError(
            f"{OPTION} does not apply with --protocol: a benchmark's protocol scores frames one "
            "by one (drop one of them)"
        )
    if args.scene is None:
        raise ConfigurationError(
            f"{OPTION} scores the consecutive frames of a scene: give --scene DIR"
        )


def configuration(args: argparse.Namespace) -> dict[str, object]:
    """The provenance's entry (nothing without ``--flicker``)."""
    return {"flicker": {"window": args.flicker}} if args.flicker else {}


@dataclass
class FlickerResult:
    """Every method's flicker over the scene: for the text, the JSON and ``--out``."""

    size: int
    frames: list[str]
    methods: dict[str, tuple[int, int, TemporalSums]]
    problems: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, object]:
        """The JSON ``flicker`` entry (also stored with ``--out``)."""
        from dispeval_ros.summary import flicker_entry

        entry = flicker_entry(self.methods)
        return {"measure": "flicker", "window": self.size, "frames": self.frames, **entry,
                "problems": self.problems}  # fmt: skip

    def text(self) -> str:
        """The flicker table, then each problem on a line."""
        from dispeval_ros.cli.summary import flicker_text

        return "\n".join([flicker_text(self.methods).lstrip("\n"), *self.problems])


def score(args: argparse.Namespace, scored: Sequence[Any]) -> FlickerResult | None:
    """Score every method's windows over ``scored`` (eval's scored frames, in the scene's order).

    None without ``--flicker``. Each frame's images and criteria are the ones its scores used.
    """
    from dispeval_ros.io import read_disparity
    from dispeval_ros.stream.flicker import FlickerInput, FlickerScore, FlickerStage

    if not args.flicker:
        return None
    stage = FlickerStage(args.flicker, NO_GAP_NS)
    windows: list[FlickerScore] = []
    problems: list[str] = []
    names = [str(s.frame.frame) for s in scored]
    for number, one in enumerate(scored):
        image = None if one.pair is None else one.pair.left
        frames = {
            name: stage.prepare(read_disparity(path, scale=args.est_scale), None, 0.0, image)
            for name, path in one.frame.estimates
        }
        partition = None if one.pair is None else one.pair.partition
        outcome = stage.add(FlickerInput(number, frames, partition, one.frame.camera))
        windows += outcome.windows
        problems += [text for _, text in outcome.problems]
    tail = stage.finish()
    windows += tail.windows
    problems += [text for _, text in tail.problems]
    methods: dict[str, tuple[int, int, TemporalSums]] = {}
    for method in dict.fromkeys(w.method for w in windows):
        own = [w for w in windows if w.method == method]
        methods[method] = (len(own), sum(w.frames for w in own), reduce(add, [w.sums for w in own]))
    return FlickerResult(args.flicker, names, methods, problems)
