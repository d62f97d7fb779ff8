"""rclpy front end: the ``evaluator`` and ``summarizer`` nodes (thin adapters over ``stream/``).

Nothing here is imported by ``import dispeval_ros``: rclpy is only needed to run the nodes.
"""
