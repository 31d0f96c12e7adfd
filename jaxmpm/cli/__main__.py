"""``python -m jaxmpm.cli``: the ``jaxmpm`` command."""

import sys

from . import main

sys.exit(main())
