"""The HTTP layer: problem+json for every error (:mod:`~service.http.problems`), content
negotiation (:mod:`~service.http.negotiation`), the answers of the computing endpoints
(:mod:`~service.http.responses`) and the ASGI middleware (:mod:`~service.http.middleware`).

Only this layer (and the routes) speaks HTTP: the engine (:mod:`service.engine`) returns
plain outcomes and neutral error records (:class:`pipeflow.errors.ErrorRecord`), which
:func:`service.http.problems.record_problem` maps to problem documents in one table.
"""
