"""``python -m dispeval_ros`` is the ``dispeval`` command."""

import sys

from dispeval_ros.cli.main import main

sys.exit(main())
