"""The ``pipeflow`` command line: a front end over the library and, with ``--server``, over
the HTTP client.

A top-level package of its own, beside ``pipeflow_client``: it uses both the numerical
library (runs and plots on this machine) and the client (``--server``), so keeping it inside
``pipeflow/`` would make the library import the client.  The arrows: ``pipeflow_cli ->
pipeflow_client -> pipeflow``; nothing imports ``pipeflow_cli``.
"""

from pipeflow_cli.cli import main

__all__ = ["main"]
