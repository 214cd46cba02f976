"""Presentation of results: JSON, tables, figures and notebook views.

The numerical library (:mod:`pipeflow.simulation`, :mod:`pipeflow.stability`, ...) returns
plain results; this layer turns their JSON form into other shapes:

- :mod:`pipeflow.io.json`: the one non-finite rule of every JSON document (:func:`json_safe`);
- :mod:`pipeflow.io.export`: CSV and Parquet tables;
- :mod:`pipeflow.io.plots`: matplotlib figures (the ``plots`` extra);
- :mod:`pipeflow.io.notebook`: xarray, pandas and figure views (the ``notebook`` extra).

Nothing is imported here: each module loads its optional dependency on first use.
"""
