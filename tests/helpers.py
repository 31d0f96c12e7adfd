"""Shared test helpers: the one list of every interpolator and transfer that parametrised checks
run over, so a new interpolator or transfer inherits every check."""

import jaxmpm as jm

INTERPOLATORS = {name: make() for name, make in jm.INTERPOLATORS.items()}
TRANSFERS = {name: make() for name, make in jm.TRANSFERS.items()}
