"""The request/response contract of pipeflow (pydantic), one definition of each model.

- :mod:`pipeflow.schema.simulation`: simulation and comparison requests (and the strict
  base model every request shares);
- :mod:`pipeflow.schema.stability`: stability analysis and sweep requests;
- :mod:`pipeflow.schema.study`: design-study requests (a base request and its cases);
- :mod:`pipeflow.schema.results`: every result document;
- :mod:`pipeflow.schema.documents`: those documents built from the library's results (one
  function per result type);
- :mod:`pipeflow.schema.keys`: the cache key of a request (RFC 8785 + version salt);
- :mod:`pipeflow.schema.registry`: :data:`~pipeflow.schema.registry.COMPUTATIONS`, the
  table of computations the service's routes, job kinds and OpenAPI document are built from,
  and where library parameter names are mapped onto request fields.

The numerical modules take plain arguments, return dataclasses and import nothing of this
package: the arrows point down (service -> schema -> library).  This package writes their
documents (:mod:`pipeflow.schema.documents`, every object through
:func:`pipeflow.schema.results.document`).
"""
