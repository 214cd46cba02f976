"""What runs a request: one floor above the contract (:mod:`pipeflow.schema`, the models).

- :mod:`pipeflow.computations.registry`: :data:`~pipeflow.computations.registry.COMPUTATIONS`,
  the table of computations the service's routes, job kinds and OpenAPI document are built
  from (request model, run function, response model, cost, summaries), and where library
  parameter names are mapped onto request fields;
- :mod:`pipeflow.computations.simulation`, :mod:`pipeflow.computations.stability` and
  :mod:`pipeflow.computations.frequency` (frequency responses, state-space models): how each
  kind of request runs (validated request in, plain library call, response document out);
- :mod:`pipeflow.computations.documents`: the response documents written from the library's
  results (one function per result type, every object through
  :func:`pipeflow.schema.results.document`);
- :mod:`pipeflow.computations.study_runner`: a design study's cases, pieces, memo and table.

The arrows point down: service -> computations -> schema -> library, never back.
"""
