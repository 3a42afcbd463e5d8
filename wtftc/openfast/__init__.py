"""OpenFAST as wtftc's second engine (issue 32): getting the programs (``install``)."""
