# syntax=docker/dockerfile:1
# pipeflow REST service: docker build -t pipeflow . && docker run -p 8000:8000 -v pipeflow-data:/data pipeflow
# A bind mount instead of the named volume must be writable by the container's user, uid
# 10001 (chown 10001 DIR), or run as its owner: docker run --user "$(id -u):$(id -g)" ...

# --- build: install the dependencies, then the package, into a virtualenv -----------------
FROM python:3.11-slim AS build
ENV PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PIP_NO_CACHE_DIR=1
RUN python -m venv /opt/venv
WORKDIR /src
# dependencies (with the parquet and formats extras: UFF and netCDF exports) in their own layer, pinned by constraints.txt (from
# pyproject.toml by the command in its header): a source change does not reinstall them;
# psycopg-binary carries its own libpq (this slim image has none)
COPY constraints.txt ./
RUN /opt/venv/bin/pip install --no-cache-dir -r constraints.txt
COPY pyproject.toml README.md ./
COPY pipeflow ./pipeflow
COPY service ./service
COPY pipeflow_client ./pipeflow_client
COPY pipeflow_cli ./pipeflow_cli
# the package alone; pip check fails the build if constraints.txt misses a dependency
RUN /opt/venv/bin/pip install --no-cache-dir --no-deps . && /opt/venv/bin/pip check

# --- runtime: the virtualenv only, as a non-root user ------------------------------------
FROM python:3.11-slim AS runtime
ENV PATH=/opt/venv/bin:$PATH \
    PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    OMP_NUM_THREADS=1 \
    OPENBLAS_NUM_THREADS=1 \
    MKL_NUM_THREADS=1 \
    MPLCONFIGDIR=/tmp/matplotlib \
    PIPEFLOW_DATA_DIR=/data
COPY --from=build /opt/venv /opt/venv
# /tls: the Dask TLS files of docker-compose.yml (python -m service.tls /tls), a named volume
# that Docker initialises from this directory, so owned by the service's user
RUN mkdir -p /data /tls && chown 10001:10001 /data /tls
VOLUME ["/data"]
WORKDIR /tmp
USER 10001:10001
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD ["python", "-c", "import sys, urllib.request; sys.exit(urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=4).status != 200)"]
CMD ["uvicorn", "service.main:app", "--http", "service.http.deadline:HTTPProtocol", "--host", "0.0.0.0", "--port", "8000"]
