"""The request/response contract of pipeflow (pydantic), one definition of each model.

- :mod:`pipeflow.schema.simulation`: simulation and comparison requests (and the strict
  base model every request shares);
- :mod:`pipeflow.schema.stability`: stability analysis and sweep requests;
- :mod:`pipeflow.schema.study`: design-study requests (a base request and its cases);
- :mod:`pipeflow.schema.results`: every result document;
- :mod:`pipeflow.schema.keys`: the cache key of a request (RFC 8785 + version salt);
- :mod:`pipeflow.schema.registry`: :data:`~pipeflow.schema.registry.COMPUTATIONS`, the
  table of computations the service's routes, job kinds and OpenAPI document are built from,
  and where library parameter names are mapped onto request fields.

The numerical modules take plain arguments and import nothing of this package but the
response models, on first use, to write their ``to_dict`` forms
(:func:`pipeflow.schema.results.document`).
"""
