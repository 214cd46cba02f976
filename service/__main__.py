"""``python -m service [--host H] [--port P]``: run the service with uvicorn.

The app object is built here by :func:`service.main.create_app` (from the environment's
settings) and handed to uvicorn, not imported by a string name.  ``pipeflow serve`` calls
:func:`serve`.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence


def serve(host: str = "127.0.0.1", port: int = 8000) -> None:
    """Serve the API and viewer on ``host:port`` until interrupted."""
    import uvicorn

    from service.main import create_app

    uvicorn.run(create_app(), host=host, port=port)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m service", description=__doc__)
    parser.add_argument("--host", default="127.0.0.1", help="interface (default 127.0.0.1)")
    parser.add_argument("--port", type=int, default=8000, help="TCP port (default 8000)")
    args = parser.parse_args(argv)
    serve(args.host, args.port)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
