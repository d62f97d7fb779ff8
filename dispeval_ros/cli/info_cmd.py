"""``dispeval info``: what a bag holds and how ``dispeval bag`` could evaluate it.

Topics, types, message counts, the log-time span and, per topic, how far the first and last
messages were logged after their header stamps (the offset ``dispeval bag`` warns about,
:func:`~dispeval_ros.offline.units.log_minus_stamp`), for every format
:class:`~dispeval_ros.io.bags.BagSource` reads. Each topic says which option of ``dispeval
bag`` could read it, and a ready command line is suggested, with the ``--tolerance`` the
stamps need where the default cannot join them. Reads the first and last message of each
topic (the last from near the end of the bag) and the first :data:`STAMP_SAMPLE` of the
ground truth and the methods, not the whole bag. ``/tf`` and ``/tf_static`` are read whole
(:mod:`~dispeval_ros.cli.info_transforms`): edges, spans and whether the camera's frame moves.
"""

from __future__ import annotations

import argparse
import bisect
import itertools
import math
import re
import shlex
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from dispeval_ros.cli.bag_cmd import add_bags_argument
from dispeval_ros.cli.info_transforms import TransformFacts, transform_facts
from dispeval_ros.cli.output import print_json, table
from dispeval_ros.errors import DispevalError, InputError
from dispeval_ros.io.bags import BagSource
from dispeval_ros.io.grey import GREY_SOURCES
from dispeval_ros.io.messages import GT_ENCODINGS, stamp_ns
from dispeval_ros.stream.config import (
    CAMERA_INFO_TYPE,
    DISPARITY_TYPE,
    IMAGE_TYPE,
    POINT_CLOUD_TYPE,
    TF_STATIC_TOPIC,
    TF_TYPE,
)

HELP = "show a bag's topics, counts, time span and stamp offsets, and a 'dispeval bag' command"
_GT_NAME = re.compile(r"ground_?truth|(^|[/_])gt($|[/_])|truth", re.IGNORECASE)
STAMP_SAMPLE = 32
"""Messages per topic whose stamps the ``--tolerance`` suggestion compares (from the start)."""
_CLOCKS = ("--gt", "--gt-cloud", "--left-image")
"""The options naming the topic the methods are joined to (the frame clock)."""
_LEAVES = ("disparity", "disparity_image", "image")
"""Topic leaves that do not name a method (``/stereo/sgbm/disparity`` is ``sgbm``)."""


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    """Register ``info``."""
    parser = subparsers.add_parser(
        "info",
        help=HELP,
        description=HELP + ". Offsets are log time minus header stamp of each topic's first "
        "and last message: 'dispeval bag' cuts its units by log time and joins frames by "
        "stamp. A bag that cannot be read is one line; the others are still shown.",
    )
    add_bags_argument(parser)
    parser.add_argument("--json", action="store_true", help="machine-readable output")
    parser.set_defaults(run=run_command)


@dataclass
class TopicFacts:
    """One topic: type and count, first/last log times and offsets, what ``bag`` reads it as."""

    name: str
    msgtype: str
    count: int
    first_log_ns: int | None = None
    last_log_ns: int | None = None
    first_offset_ns: int | None = None
    last_offset_ns: int | None = None
    encoding: str | None = None
    use: str = ""
    """The ``dispeval bag`` option that reads it ("" for none)."""

    def to_dict(self) -> dict[str, object]:
        """JSON form."""
        return {
            "name": self.name,
            "type": self.msgtype,
            "count": self.count,
            "first_log_ns": self.first_log_ns,
            "last_log_ns": self.last_log_ns,
            "stamp_offset_ns": {"first": self.first_offset_ns, "last": self.last_offset_ns},
            "encoding": self.encoding,
            "use": self.use or None,
        }


@dataclass
class BagFacts:
    """A bag: format, messages, log-time span, its topics and what reading them found."""

    path: Path
    format: str
    messages: int
    first_log_ns: int | None
    last_log_ns: int | None
    topics: list[TopicFacts]
    damage: str | None = None
    """The first reading error (a damaged recording is described up to it)."""
    options: list[str] = field(default_factory=list)
    """The suggested ``dispeval bag`` options (empty: nothing it could score)."""
    notes: list[str] = field(default_factory=list)
    transforms: TransformFacts | None = None
    """What /tf and /tf_static hold (None: the bag has neither)."""

    def to_dict(self) -> dict[str, object]:
        """JSON form."""
        span = None
        if self.first_log_ns is not None and self.last_log_ns is not None:
            span = (self.last_log_ns - self.first_log_ns) / 1e9
        return {
            "path": str(self.path),
            "format": self.format,
            "messages": self.messages,
            "log_time": {
                "first_ns": self.first_log_ns,
                "last_ns": self.last_log_ns,
                "duration_s": span,
            },
            "topics": [topic.to_dict() for topic in self.topics],
            "damage": self.damage,
            "bag_options": self.options,
            "command": command_line([self.path], self.options) if self.options else None,
            "notes": self.notes,
            "transforms": self.transforms.to_dict() if self.transforms else None,
        }


def _camera_frame(source: BagSource, facts: BagFacts) -> str | None:
    """The frame of the first CameraInfo, else of the first DisparityImage: the camera's."""
    for use in ("--camera-info", "--method"):
        for topic in (t for t in facts.topics if t.use == use and t.count):
            first = _first(source.messages([topic.name], on_error=_skip))
            frame = getattr(getattr(first[2], "header", None), "frame_id", "") if first else ""
            if frame:
                return str(frame)
    return None


def bag_facts(path: Path) -> BagFacts:
    """Open the bag and gather its facts (InputError, one line, when it cannot be opened)."""
    with BagSource(path) as source:
        empty = source.message_count == 0
        facts = BagFacts(
            path,
            source.format,
            source.message_count,
            None if empty else source.start_ns,
            None if empty else source.end_ns - 1,  # end_ns is one past the last log time
            [],
        )
        for topic, info in source.topics.items():
            item = TopicFacts(topic, info.msgtype, info.count)
            if info.count:
                facts.damage = _read_ends(source, item) or facts.damage
            item.use = _use(item)
            facts.topics.append(item)
        facts.options, facts.notes = suggestion(facts)
        _tolerance(source, facts)
        tf_topics = {t.name: t.count for t in facts.topics if t.msgtype == TF_TYPE}
        if tf_topics:
            facts.transforms = transform_facts(source, tf_topics, _camera_frame(source, facts))
    return facts


def _tolerance(source: BagSource, facts: BagFacts) -> None:
    """Add ``--tolerance`` to the suggestion where the default cannot join the stamps."""
    from dispeval_ros.stream.config import core_default

    joined = [facts.options[i + 1] for i, option in enumerate(facts.options) if option in _CLOCKS]
    methods = [
        facts.options[i + 1].partition("=")[2]
        for i, option in enumerate(facts.options)
        if option == "--method"
    ]
    if not joined or not methods:
        return
    gap = stamp_gap_ns(source, joined[0], methods)
    default = int(core_default("tolerance_ns"))
    if gap is None or gap <= default:
        return
    chosen = math.ceil(gap / 1e6)
    facts.options += ["--tolerance", str(chosen)]
    facts.notes.append(
        f"method stamps are up to {gap / 1e6:.2f} ms from the nearest {joined[0]} stamp (first "
        f"{STAMP_SAMPLE} messages), beyond the default --tolerance {default / 1e6:g} ms: the "
        f"command gives --tolerance {chosen}"
    )


def stamp_gap_ns(source: BagSource, clock: str, methods: Sequence[str]) -> int | None:
    """The largest stamp gap from a method's message to the nearest ``clock`` (GT) message.

    Over the first :data:`STAMP_SAMPLE` messages of each topic; a gap of half the shortest GT
    period or more is to another frame (a frame missing), not a tolerance. None: no GT stamp.
    """
    stamps: dict[str, list[int]] = {topic: [] for topic in (clock, *methods)}
    messages = source.messages(list(stamps), on_error=_skip)
    try:
        for topic, _, msg in messages:
            if hasattr(msg, "header") and len(stamps[topic]) < STAMP_SAMPLE:
                stamps[topic].append(stamp_ns(msg.header))
            if all(len(found) >= STAMP_SAMPLE for found in stamps.values()):
                break
    except DispevalError:  # damage: the stamps before it
        pass
    finally:
        close = getattr(messages, "close", None)
        if close is not None:
            close()
    truth = sorted(set(stamps[clock]))
    if not truth:
        return None
    periods = [b - a for a, b in itertools.pairwise(truth)]
    half = min(periods) // 2 if periods else None
    worst = 0
    for topic in methods:
        for stamp in stamps[topic]:
            at = bisect.bisect_left(truth, stamp)
            gap = min(abs(stamp - truth[i]) for i in (at - 1, at) if 0 <= i < len(truth))
            if half is None or gap < half:
                worst = max(worst, gap)
    return worst


def _read_ends(source: BagSource, item: TopicFacts) -> str | None:
    """Read the topic's first and last message into ``item``; the damage met, if any.

    A damaged bag is described up to the damage: its last message is the last one before it.
    """
    from dispeval_ros.offline.units import log_minus_stamp

    try:
        first = _first(source.messages([item.name], on_error=_skip))
    except DispevalError as error:
        return str(error)
    if first is None:
        return None
    item.first_log_ns, item.first_offset_ns = first[1], log_minus_stamp(first[1], first[2])
    encoding = getattr(first[2], "encoding", None)
    item.encoding = encoding if isinstance(encoding, str) else None
    last, damage = _last(source, item.name, item.count)
    if last is not None:
        item.last_log_ns, item.last_offset_ns = last[1], log_minus_stamp(last[1], last[2])
    return damage


def _skip(error: InputError) -> None:
    """A message that cannot be decoded is not a topic's first or last one."""


def _first(messages: Iterator[tuple[str, int, Any]]) -> tuple[str, int, Any] | None:
    try:
        return next(messages, None)
    finally:
        close = getattr(messages, "close", None)
        if close is not None:
            close()


def _last(
    source: BagSource, topic: str, count: int
) -> tuple[tuple[str, int, Any] | None, str | None]:
    """The topic's last message (before any damage, then named), read from near the end.

    Stretches before the bag's end are read, each four times longer than the one before;
    the first holds about four of the topic's messages if they are spread evenly. So a topic
    logged only at the start costs a few reads of that topic, never a pass decoding the others.
    """
    span = max(1, source.end_ns - source.start_ns)
    stretch = max(1, 4 * span // max(1, count))
    while True:
        start = max(source.start_ns, source.end_ns - stretch)
        last = None
        try:
            for message in source.messages([topic], start_ns=start, on_error=_skip):
                last = message
        except DispevalError as error:
            if last is not None or start <= source.start_ns:
                return last, str(error)
        if last is not None or start <= source.start_ns:
            return last, None
        stretch *= 4


def _use(topic: TopicFacts) -> str:
    """Which ``dispeval bag`` option reads the topic."""
    if topic.msgtype == DISPARITY_TYPE:
        return "--method"
    if topic.msgtype == CAMERA_INFO_TYPE:
        return "--camera-info"
    if topic.msgtype == POINT_CLOUD_TYPE:
        return "--gt-cloud"
    if topic.msgtype == TF_TYPE and topic.name == TF_STATIC_TOPIC:
        return "(the --gt-cloud extrinsic)"
    if topic.msgtype == TF_TYPE:
        return "(ego-motion)"
    if topic.msgtype == IMAGE_TYPE:
        if topic.encoding in GT_ENCODINGS:
            return "--gt --gt-kind depth" if "depth" in topic.name.lower() else "--gt"
        if topic.encoding in GREY_SOURCES:
            return "--left-image/--right-image"
        if topic.encoding is None:  # not read: the GT by its name, else an image
            return "--gt" if _GT_NAME.search(topic.name) else "--left-image/--right-image"
    return ""


def method_names(topics: Sequence[str]) -> list[str]:
    """A short, unique method name per DisparityImage topic (``/stereo/sgbm/disparity``: sgbm)."""
    parts = [[part for part in topic.split("/") if part] for topic in topics]
    names = []
    for words in parts:
        kept = words[:-1] if len(words) > 1 and words[-1] in _LEAVES else words
        names.append(kept[-1] if kept else "method")
    if len(set(names)) < len(names):  # the whole path where the short names clash
        names = ["_".join(words) or "method" for words in parts]
    return names


def _pair(topics: Sequence[str]) -> tuple[str, str] | None:
    """The left and right topics among ``topics``, told apart by their names."""
    left = [t for t in topics if "left" in t.lower()]
    right = [t for t in topics if "right" in t.lower()]
    if len(left) == 1 and len(right) == 1 and left != right:
        return left[0], right[0]
    return None


def suggestion(facts: BagFacts) -> tuple[list[str], list[str]]:
    """The ``dispeval bag`` options for the bag (empty when nothing can be scored) and notes."""
    by_use: dict[str, list[str]] = {}
    for topic in facts.topics:
        by_use.setdefault(topic.use.split(" ")[0], []).append(topic.name)
    notes: list[str] = []
    methods = by_use.get("--method", [])
    if not methods:
        return [], ["no stereo_msgs/DisparityImage topic: nothing for 'dispeval bag' to score"]
    infos = _pair(by_use.get("--camera-info", []))
    images = _pair(by_use.get("--left-image/--right-image", []))
    truths = by_use.get("--gt", [])
    options: list[str] = []
    if truths:
        chosen = next((t for t in truths if _GT_NAME.search(t)), truths[0])
        options += ["--gt", chosen]
        if any(t.name == chosen and "depth" in t.use for t in facts.topics):
            options += ["--gt-kind", "depth"]
        if len(truths) > 1:
            notes.append(f"ground truth: {chosen} of {', '.join(truths)}")
    elif by_use.get("--gt-cloud") and infos:
        options += ["--gt-cloud", by_use["--gt-cloud"][0]]
    elif images:
        options += ["--left-image", images[0], "--right-image", images[1]]
        notes.append("no ground truth: the ground-truth-free measures (vpe, lrc) only")
    else:
        return [], ["no ground truth (Image, or PointCloud2 with a CameraInfo pair) nor image pair"]
    for name, method in zip(method_names(methods), methods, strict=True):
        options += ["--method", f"{name}={method}"]
    if infos:
        options += ["--camera-info", *infos]
    return options, notes


def command_line(bags: Sequence[Path], options: Sequence[str]) -> str:
    """``dispeval bag BAG... OPTIONS`` as a shell would take it."""
    return shlex.join(["dispeval", "bag", *map(str, bags), *options])


def _offset_s(value: int | None) -> float:
    return math.nan if value is None else value / 1e9  # "-", in a numeric column


def _utc(ns: int) -> str:
    moment = datetime.fromtimestamp(ns // 1_000_000_000, tz=timezone.utc)
    return moment.strftime("%Y-%m-%d %H:%M:%S") + f".{ns % 1_000_000_000:09d} UTC"


def facts_text(facts: BagFacts) -> str:
    """The human report of one bag."""
    from dispeval_ros.offline.units import DEFAULT_SLICE_NS, stamp_offset_warning

    lines = [f"{facts.path}: {facts.format}, {facts.messages} messages, {len(facts.topics)} topics"]
    if facts.first_log_ns is None or facts.last_log_ns is None:
        lines.append("log time: no messages")
    else:
        span = (facts.last_log_ns - facts.first_log_ns) / 1e9
        lines.append(
            f"log time: {_utc(facts.first_log_ns)} to {_utc(facts.last_log_ns)} ({span:.9g} s)"
        )
    rows = [
        [
            t.name,
            t.msgtype + (f" ({t.encoding})" if t.encoding else ""),
            t.count,
            _offset_s(t.first_offset_ns),
            _offset_s(t.last_offset_ns),
            t.use or "-",
        ]
        for t in facts.topics
    ]
    header = ["topic", "type", "messages", "log − stamp first [s]", "last [s]", "dispeval bag"]
    lines.append(table(header, rows))
    if facts.damage:
        lines.append(f"damaged: {facts.damage}")
    gt = facts.options[facts.options.index("--gt") + 1] if "--gt" in facts.options else None
    offset = next((t.first_offset_ns for t in facts.topics if t.name == gt), None)
    warning = stamp_offset_warning(facts.path, offset, DEFAULT_SLICE_NS)
    if warning:
        lines.append(f"note: {warning}")
    lines += [f"note: {note}" for note in facts.notes]
    if facts.transforms is not None:
        lines += facts.transforms.lines()
    return "\n".join(lines)


def run_command(args: argparse.Namespace) -> int:
    """Describe every bag; one line per bag that cannot be read (exit 2 if any)."""
    found: list[BagFacts] = []
    failed: list[tuple[Path, str]] = []
    for path in args.bags:
        try:
            found.append(bag_facts(path))
        except DispevalError as error:
            failed.append((path, str(error)))
            print(f"dispeval info: error: {error}", file=sys.stderr)
    options = {tuple(facts.options) for facts in found}
    together = None
    if len(found) > 1 and len(options) == 1 and found[0].options:
        together = command_line([facts.path for facts in found], found[0].options)
    if args.json:
        print_json(
            {
                "bags": [facts.to_dict() for facts in found],
                "errors": [{"path": str(path), "error": text} for path, text in failed],
                "command": together,
            }
        )
        return 2 if failed else 0
    for facts in found:
        print(facts_text(facts))
        if facts.options and together is None:
            print(f"suggested: {command_line([facts.path], facts.options)}")
        print()
    if together is not None:
        print(f"suggested (every bag): {together}")
    return 2 if failed else 0
