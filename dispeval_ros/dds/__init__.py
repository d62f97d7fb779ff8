"""ROS 2 topics over Cyclone DDS without ROS: evaluate, summarise and play bags on a DDS domain.

ROS 2 topics are DDS topics (``/a/b`` travels as ``rt/a/b`` with type ``pkg::msg::dds_::T_``
and XCDR1 payloads), so the transport-free evaluation core runs over Cyclone DDS directly and
talks to ROS 2 nodes that use ``rmw_cyclonedds_cpp``. Payloads are serialised by rosbags and
exchanged as raw CDR bytes: large images are never packed element by element in Python.

Modules (each one job):

- :mod:`~dispeval_ros.dds.wire`: the ROS 2 wire conventions (names, type hash, QoS profiles);
  pure Python, usable without Cyclone DDS;
- :mod:`~dispeval_ros.dds.environment`: importing Cyclone DDS, the domain id, the configuration;
- :mod:`~dispeval_ros.dds.idl`: DDS type descriptions of ROS 2 messages from a rosbags typestore;
- :mod:`~dispeval_ros.dds.transport`: participant, raw-CDR writers and readers, reader threads;
- :mod:`~dispeval_ros.dds.evaluator`: the live evaluator on DDS (scores and vectors out);
- :mod:`~dispeval_ros.dds.summarizer`: the summarizer on DDS (results database, groups out);
- :mod:`~dispeval_ros.dds.player`: publish a bag's topics at the recorded rate.

Importing ``dispeval_ros`` never imports ``cyclonedds``; only the transport does, and a missing
binding is a one-line :class:`~dispeval_ros.errors.ConfigurationError`.
"""
