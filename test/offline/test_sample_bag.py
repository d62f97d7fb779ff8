"""The bundled sample bag is what its generator writes (``demo`` falls back to the generator)."""

from __future__ import annotations

import hashlib
from pathlib import Path

from dispeval_ros.io.bags import BagSource
from dispeval_ros.offline.sample import find_sample_bag, make_sample_bag


def _digests(bag: Path) -> dict[str, tuple[int, str]]:
    """Per topic: message count and a digest of (log time, serialized bytes) in order."""
    with BagSource(bag) as source:
        stream = source.serialized_messages(list(source.topics))
        assert stream is not None, "the sample bag is indexed MCAP storage"
        hashes: dict[str, hashlib._Hash] = {}
        counts: dict[str, int] = {}
        for topic, log_time, data in stream:
            digest = hashes.setdefault(topic, hashlib.sha256())
            digest.update(log_time.to_bytes(8, "little"))
            digest.update(bytes(data))
            counts[topic] = counts.get(topic, 0) + 1
    return {topic: (counts[topic], hashes[topic].hexdigest()) for topic in sorted(hashes)}


def test_bundled_sample_bag_equals_the_generator(tmp_path: Path) -> None:
    bundled = find_sample_bag()
    assert bundled is not None, "bags/sample_drive is part of the repository"
    made = make_sample_bag(tmp_path / "sample_drive")
    assert _digests(made) == _digests(bundled), (
        "bags/sample_drive differs from make_sample_bag(): regenerate it with "
        "python -c 'from pathlib import Path; from dispeval_ros.offline.sample import "
        'make_sample_bag; make_sample_bag(Path("bags/sample_drive"))\' (after removing it)'
    )
