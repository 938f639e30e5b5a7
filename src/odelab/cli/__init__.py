"""The ``odelab`` command line (Typer) and every terminal view: the only package that prints or exits.

:mod:`odelab.cli.app` holds the commands, the other modules draw what the core returns (the run's
tables, a fit, the grades, a network's derivation).
"""

from odelab.cli.app import app, main

__all__ = ["app", "main"]
