"""Who is asking: the client identity the job queue's fairness and the quotas count by.

:func:`principal` is ``request.state.principal`` when the optional API-key authentication
set it (the key's id), else :data:`ANONYMOUS`.  Not the client's address: behind the
compose file's proxy or a NAT every client has the same one, and one client may come from
many; an address is not an identity anyone proved.  So with authentication off, every
client is the one ``anonymous`` principal: quotas then bound the anonymous traffic as a
whole, and fairness has one client to be fair to.
"""

from __future__ import annotations

from fastapi import Request

#: the principal of a request without an authenticated identity
ANONYMOUS = "anonymous"


async def principal(request: Request) -> str:
    """The client identity of ``request`` (a FastAPI dependency; ``async`` so that FastAPI
    runs it on the event loop: a plain ``def`` dependency is sent to its thread pool, a
    thread hop per request for an attribute read)."""
    who = getattr(request.state, "principal", None)
    return str(who) if who else ANONYMOUS
