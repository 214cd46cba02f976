"""Alembic migrations of the store, run at start by :func:`service.store.schema.upgrade`."""
