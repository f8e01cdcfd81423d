"""``python -m pmsmjax``: the same as the ``pmsmjax`` command."""

import sys

from pmsmjax.cli import main

sys.exit(main())
