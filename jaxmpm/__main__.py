"""``python -m jaxmpm``: the ``jaxmpm`` command."""

from .cli import console

console()
