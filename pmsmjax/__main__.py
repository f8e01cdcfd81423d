"""``python -m pmsmjax``: the same as the ``pmsmjax`` command."""

import sys

from .cli import main

sys.exit(main())
