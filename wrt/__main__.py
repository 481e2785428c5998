"""``python -m wrt``: the ``wrt`` command (``wrt.console``)."""

import sys

from wrt.console import main

sys.exit(main())
