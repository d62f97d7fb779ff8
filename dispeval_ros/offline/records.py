"""The provenance record of a stream run: version, configuration and its hash, stream digests."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from dispeval_ros.core.provenance import provenance_record
from dispeval_ros.io.provenance import stream_digests
from dispeval_ros.io.store import ResultsStore
from dispeval_ros.offline.bag_eval import sequence_names
from dispeval_ros.stream.core import CoreConfig


def stream_topics(config: CoreConfig) -> list[str]:
    """Every topic the evaluation reads: ground truth, methods, camera infos."""
    topics = [config.gt_topic, *config.methods.values()]
    topics += [t for t in (config.left_info_topic, config.right_info_topic) if t]
    return list(dict.fromkeys(topics))


def record_bag_provenance(
    store: ResultsStore,
    bags: Sequence[Path],
    configuration: Mapping[str, object],
    config: CoreConfig,
) -> dict[str, object]:
    """Hash each bag's scored streams, store the record in ``store`` and return it.

    ``inputs.streams`` maps each sequence to its bag and, per topic, the sha256 and the
    number of its serialized messages (see :func:`dispeval_ros.io.provenance.stream_digests`).
    """
    topics = stream_topics(config)
    streams = {
        sequence: {"bag": str(path), "topics": stream_digests(path, topics)}
        for path, sequence in zip(bags, sequence_names(bags), strict=True)
    }
    record = provenance_record(configuration, {"streams": streams})
    store.set_provenance(record)
    return record
