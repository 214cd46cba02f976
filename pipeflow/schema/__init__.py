"""The request/response contract of pipeflow (pydantic), one definition of each model.

- :mod:`pipeflow.schema.simulation`: simulation and comparison requests (and the strict
  base model every request shares);
- :mod:`pipeflow.schema.stability`: stability analysis and sweep requests;
- :mod:`pipeflow.schema.study`: design-study requests (a base request and its cases);
- :mod:`pipeflow.schema.results`: every result document;
- :mod:`pipeflow.schema.keys`: the cache key of a request (RFC 8785 + version salt);

The numerical modules take plain arguments, return dataclasses and import nothing of this
package: the arrows point down (service -> computations -> schema -> library).  What runs a
request (the registry, the documents written from the library's results, the study runner)
is :mod:`pipeflow.computations`, one floor up; this package holds the models only.
"""
