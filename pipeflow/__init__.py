"""pipeflow: vibration of a rotating cantilevered pipe conveying fluid.

Library entry points (SI units throughout):

- :class:`pipeflow.model.Pipe`; the paper's cases in :mod:`pipeflow.paper` (``PAPER_PIPE``, ...)
- profiles: :mod:`pipeflow.profiles` (constant, polynomial, harmonic, table)
- :class:`pipeflow.simulation.Simulation` and :func:`pipeflow.simulation.simulate`
- :mod:`pipeflow.schema`: the request and result models shared with the service and CLI,
  and the registry of computations
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("pipeflow")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+source"

__all__ = ["__version__"]
