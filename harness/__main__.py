"""``python -m wrt_harness VERB``: the harness's own command (``wrt-harness``)."""

import sys

from .cli import main

sys.exit(main())
