"""``python -m repro`` is the ``repro`` command."""

import sys

from repro.cli import main

if __name__ == "__main__":  # not when a ``--jobs`` worker process imports it (multiprocessing's spawn)
    sys.exit(main())
