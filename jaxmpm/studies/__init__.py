"""Studies: each writes its figures and tables to a directory (``jaxmpm study NAME --out DIR``)."""
