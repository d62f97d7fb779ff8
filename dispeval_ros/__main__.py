"""``python -m dispeval_ros`` is the ``dispeval`` command."""

import sys

from dispeval_ros.cli.main import main

if __name__ == "__main__":  # worker processes that are spawned import this module
    sys.exit(main())
