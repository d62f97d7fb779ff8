"""Protocol presets for recorded streams (bags), scored with the project's exact sums."""

from __future__ import annotations

from dataclasses import dataclass

from dispeval_ros.core.protocols.registry import get_protocol


@dataclass(frozen=True)
class StreamPreset:
    """A protocol's measures for recorded streams, where frames are scored by summable sums.

    Bags carry no official region masks and the stream pipeline keeps exact arithmetic, so
    this is the benchmark's measures, thresholds and invalid-estimate handling over ``all``;
    ``differs`` says what is not the official tool's.
    """

    criteria: tuple[str, ...]
    measures: tuple[str, ...]
    missing: str
    differs: str

    def record(self) -> dict[str, object]:
        """Plain values for the run's configuration."""
        return {
            "criteria": list(self.criteria),
            "measures": list(self.measures),
            "missing": self.missing,
            "differs": self.differs,
        }


_EXACT = "exact arithmetic instead of the tool's float32 steps; no official region masks"
STREAM_PRESETS: dict[str, StreamPreset] = {
    "middeval3": StreamPreset(
        ("all",),
        ("bad_0.5", "bad_1", "bad_2", "bad_4", "mae", "rmse", "density"),
        "ignore",
        _EXACT + "; bad X over valid estimates (the SDK's 'bad'; its totals add 1 − density)",
    ),
    "kitti2015": StreamPreset(
        ("all",), ("d1", "density"), "interpolate", _EXACT + "; rows without estimate count 0"
    ),
    "kitti2012": StreamPreset(
        ("all",),
        ("bad_2", "bad_3", "bad_4", "bad_5", "mae", "density"),
        "interpolate",
        _EXACT + "; Out-k = bad_k, Avg = mae",
    ),
    "eth3d": StreamPreset(
        ("all",),
        ("bad_0.5", "bad_1", "bad_2", "bad_4", "mae", "rmse", "density"),
        "ignore",
        _EXACT + "; avgerr = mae, coverage = density",
    ),
}


def stream_preset(name: str) -> StreamPreset:
    """The stream preset of protocol ``name`` (a one-line error for unknown names)."""
    get_protocol(name)
    return STREAM_PRESETS[name]
