"""``jaxmpm scenes``: the scenes, their parameters and defaults."""

import math

import jaxmpm as jm

from ._common import print_json


def add_parser(subparsers) -> None:
    """Add the ``scenes`` subcommand.

    Args:
        subparsers: the ``jaxmpm`` parser's subparsers.
    """
    p = subparsers.add_parser("scenes", help="list scenes with their parameters and defaults")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=command)


def command(args) -> int:
    """List every scene: a table, or with ``--json`` one object ``{name: {description, parameters}}``.

    A default of NaN (``null`` in JSON) is a parameter that, when not given, the scene derives from
    its others (the Gurney scenes' ``sqrt_2E`` from ``explosive``); the table says so.

    Args:
        args: the parsed command line.

    Returns:
        The exit status, 0.
    """
    if args.json:
        print_json(
            {
                name: dict(description=cls.description, parameters=cls.parameters())
                for name, cls in jm.SCENES.items()
            }
        )
        return 0
    for name, cls in jm.SCENES.items():
        print(f"{name}: {cls.description}")
        for key, value in cls.parameters().items():
            kind = type(value).__name__
            if isinstance(value, float) and math.isnan(value):
                kind += "; not given: derived from the others, see the scene's docstring"
            print(f"    {key:<8} = {value!r:<10} ({kind})")
    return 0
