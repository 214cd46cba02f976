"""``python -m service [--host H] [--port P] [--workers N] [--data-dir DIR]``: run the
service with uvicorn.

The app object is built here by :func:`service.main.create_app` and handed to uvicorn, not
imported by a string name; ``pipeflow serve`` runs this module in a child process.  One
server process (the store allows one per data directory): ``workers`` is the compute pool
(PIPEFLOW_WORKERS), never uvicorn's server processes.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any


def serve(
    host: str = "127.0.0.1",
    port: int = 8000,
    *,
    workers: int | None = None,
    data_dir: Path | None = None,
) -> None:
    """Serve the API and viewer on ``host:port`` until interrupted; ``workers`` and
    ``data_dir`` override PIPEFLOW_WORKERS and PIPEFLOW_DATA_DIR, the rest comes from the
    environment."""
    import uvicorn

    from service.http.deadline import deadline_protocol
    from service.main import create_app
    from service.settings import Settings

    overrides: dict[str, Any] = {"workers": workers, "data_dir": data_dir}
    settings = Settings(**{k: v for k, v in overrides.items() if v is not None})
    print(f"pipeflow: data in {settings.data_dir}, {settings.workers} worker(s)", file=sys.stderr)
    # the request deadline (service.http.deadline): a half-sent request is answered 408
    http = deadline_protocol(settings.read_timeout_s)
    uvicorn.run(create_app(settings), host=host, port=port, http=http)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m service", description=__doc__)
    parser.add_argument("--host", default="127.0.0.1", help="interface (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8000, help="TCP port (default 8000)")
    parser.add_argument("--workers", type=int, help="compute worker processes")
    parser.add_argument("--data-dir", type=Path, help="directory of the store")
    args = parser.parse_args(argv)
    from pydantic import ValidationError

    try:
        serve(args.host, args.port, workers=args.workers, data_dir=args.data_dir)
    except ValidationError as exc:  # a flag or variable out of range: name it, exit 2
        for e in exc.errors():
            print(f"error: {'.'.join(map(str, e['loc']))}: {e['msg']}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
