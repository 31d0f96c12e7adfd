"""Studies: each writes its figures and tables to a directory (``jaxmpm study NAME --out DIR``)."""

from ._runtime import machine as machine
