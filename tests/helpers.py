"""Shared test helpers: the one list of every interpolator and transfer that parametrised checks
run over, so a new interpolator or transfer inherits every check; and the check of a usage error."""

import jaxmpm as jm
from jaxmpm.cli import main

INTERPOLATORS = {name: make() for name, make in jm.INTERPOLATORS.items()}
TRANSFERS = {name: make() for name, make in jm.TRANSFERS.items()}


def usage(capsys, argv, match):
    """Run ``jaxmpm argv``: exit status 2, nothing on stdout, one line on stderr with ``match``."""
    rc = main(argv)
    captured = capsys.readouterr()
    assert rc == 2, (argv, captured.err)
    assert "Traceback" not in captured.err and captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, (argv, captured.err)
    assert lines[0].startswith("jaxmpm: error:") and match in lines[0], lines[0]
    return lines[0]
