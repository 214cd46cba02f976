"""Python client of the pipeflow HTTP service (httpx).

A separate top-level package, not ``pipeflow.client``: the project's rule is that
``pipeflow/`` imports no web library, so the numerical library stays usable (and
importable) without any HTTP stack, and a grep for ``httpx`` under ``pipeflow/`` stays
empty.  The client depends on ``pipeflow`` for its exception base class, the request models
and the response models (:mod:`pipeflow.schema.results`), with which it validates every
result it receives (:func:`parse`): the client and the service share one definition.

Example::

    from pipeflow.schema.simulation import PAPER_EXAMPLE
    from pipeflow_client import Client

    # api_key="pf_..." (or PIPEFLOW_API_KEY in the environment) for a server requiring keys
    with Client("http://localhost:8000") as c:
        r = c.simulate(PAPER_EXAMPLE)          # numpy arrays, SI units
        print(r.key, r.tip_displacement[:3])   # u(L, t) [m]
        png = c.plot(r.key, "frequency")       # PNG bytes
        r.to_dataframe()                       # pandas, units in attrs (pipeflow[notebook])

    async with AsyncClient("http://localhost:8000") as c:   # the same methods, awaited
        r = await c.simulate(PAPER_EXAMPLE)

Both retry ``503`` answers (all computation slots busy), waiting what ``Retry-After`` says
(:class:`RetryPolicy`).
"""

from pipeflow.optional import require

# its own extra: `pip install -e '.[service]'` alone has neither (an ImportError saying so)
for _module in ("httpx", "tenacity"):
    require(_module, "client", "pipeflow_client (and `pipeflow ... --server URL`)")

from pipeflow_client.client import (  # noqa: E402
    API_KEY_ENV,
    AsyncClient,
    Client,
    JobFailed,
    RetryPolicy,
    ServiceError,
    SimulationResult,
    parse,
)

__all__ = [
    "API_KEY_ENV",
    "AsyncClient",
    "Client",
    "JobFailed",
    "RetryPolicy",
    "ServiceError",
    "SimulationResult",
    "parse",
]
