"""``python -m jaxmpm.cli``: the ``jaxmpm`` command."""

from . import console

console()
