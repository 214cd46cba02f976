"""The ``pipeflow`` command line: run a simulation, export CSV, draw the paper's figures.

Installed as the ``pipeflow`` console script.  Every subcommand reads and writes the same
JSON as the HTTP service (a request of :mod:`pipeflow.schema` in, the result dictionary
out), and local runs go through the same registry of computations.  The command line never
imports the service: ``serve`` runs ``python -m service`` in a child process, and the HTTP
client is imported only inside the subcommands that talk HTTP (``--server``), so the
command works with the library alone (``pip install -e .``) for local runs.

Exit status: 0 success, 2 invalid input (the message names the field), 1 other failures.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

from pipeflow.errors import PipeflowError

#: the environment variable of the API key (``pipeflow_client.API_KEY_ENV``; spelled here
#: too because the command line imports the client only with ``--server``)
API_KEY_ENV = "PIPEFLOW_API_KEY"

EXAMPLE_HELP = """\
the paper's example (Wang & Zhong 2018, section 5: v = 0.4 t m/s, w0 = 100 rad/s):

  pipeflow example > spec.json                  # write the example spec
  pipeflow run spec.json -o result.json         # run it locally (about a second)
  pipeflow run spec.json --format csv -o tip.csv                 # t [s], u(L,t) [m]
  pipeflow run spec.json --format csv --table eigenvalues        # sigma [1/s], omega [rad/s]
  pipeflow run spec.json --format parquet -o history.parquet     # units in column metadata
  pipeflow plot result.json --name tip_displacement --out tip.png
  pipeflow plot spec.json --name frequency --out freq.svg        # runs the spec, then plots
  pipeflow stability stab.json                  # critical flow velocity, sweeps, maps
  pipeflow frequency-response frf.json -o frf_result.json        # H(W), peaks, stable
  pipeflow serve --port 8000                    # the HTTP service and viewer at / (it
                                                # runs: python -m service --port 8000)
  pipeflow run spec.json --server http://localhost:8000          # run on a server
  export PIPEFLOW_API_KEY=pf_...                # its key, if it requires keys (or --api-key)
"""


STABILITY_HELP = """\
examples (the paper's pipe, 10 modes):

  echo '{"pipe": {"E": 7.8e9, "I": 1.21e-17, "L": 0.025, "M1": 1.884e-5, "M2": 1.6485e-5},
         "rotation": {"omega0": {"kind": "constant", "value": 100}},
         "velocity_range": [0, 60]}' | pipeflow stability -       # critical velocity [m/s]
  # argand.json: {"kind": "argand", "pipe": {...}, "velocity_range": [0, 60]}
  pipeflow stability argand.json -o argand_result.json
  pipeflow plot argand_result.json --name argand --out argand.png
"""


FREQUENCY_HELP = """\
example: a hammer test at the tip of the paper's pipe at w0 = 100 rad/s, v = 5 m/s

  echo '{"pipe": {"E": 7.8e9, "I": 1.21e-17, "L": 0.025, "M1": 1.884e-5, "M2": 1.6485e-5},
         "flow": {"velocity": {"kind": "constant", "value": 5}},
         "rotation": {"omega0": {"kind": "constant", "value": 100}},
         "load": {"kind": "point_force", "position": 0.025},
         "response": {"positions": [0.025]},
         "frequencies": {"min": 10, "max": 8000, "count": 2000, "spacing": "log"}}' > frf.json
  pipeflow frequency-response frf.json -o frf_result.json   # peaks on stderr
  pipeflow frequency-response frf.json --format csv --table peaks
  pipeflow plot frf_result.json --name bode --out bode.png  # also nyquist, waterfall,
                                                            # deflection_shape
"""


class ProgressBar:
    """A one-line progress bar on a text stream (stderr), drawn at most every 0.1 s.

    ``enabled=None`` draws only when the stream is a terminal.
    """

    def __init__(self, label: str, stream: IO[str] | None = None, enabled: bool | None = None):
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            enabled = bool(getattr(self.stream, "isatty", lambda: False)())
        self.enabled = enabled
        self.label = label
        self._last = -1.0
        self._fraction = -1.0
        self._shown = False
        self._start = time.monotonic()

    def __call__(self, fraction: float) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if (fraction < 1.0 and now - self._last < 0.1) or fraction == self._fraction:
            return
        self._last = now
        self._fraction = fraction
        width = 30
        filled = round(width * min(max(fraction, 0.0), 1.0))
        bar = "#" * filled + "-" * (width - filled)
        self.stream.write(
            f"\r{self.label} [{bar}] {100 * fraction:5.1f}% {now - self._start:6.1f} s"
        )
        self.stream.flush()
        self._shown = True

    def close(self) -> None:
        if self._shown:
            self.stream.write("\n")
            self.stream.flush()
            self._shown = False


def _read_json(path: str) -> Any:
    text = sys.stdin.read() if path == "-" else Path(path).read_text(encoding="utf-8")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise PipeflowError(f"{path} is not valid JSON: {exc}", parameter="input") from exc


def _unwrap(data: Any) -> Any:
    """The result inside a service envelope (``{"key": ..., "result": {...}}``), or ``data``."""
    if isinstance(data, dict) and isinstance(data.get("result"), dict):
        return data["result"]
    return data


def _sweep_kinds() -> tuple[str, ...]:
    from pipeflow.computations.registry import SWEEP_KINDS

    return SWEEP_KINDS


def _is_result(data: Any) -> bool:
    if not isinstance(data, dict):
        return False
    if "t" in data and "tip_displacement" in data:
        return True
    if data.get("kind") == "frequency_response":  # a result has its unit; a request has not
        return "unit" in data and "operating_points" in data
    # stability results echo their kind and carry no request-only fields
    return data.get("kind") in (*_sweep_kinds(), "stability") and "diagnostics" in data


def _kinds() -> tuple[str, ...]:
    from pipeflow.computations.registry import COMPUTATIONS

    return tuple(COMPUTATIONS)


def _tagged_kinds() -> tuple[str, ...]:
    """The computations whose request model carries its name as ``kind``."""
    from pipeflow.computations.registry import COMPUTATIONS

    return tuple(n for n, c in COMPUTATIONS.items() if "kind" in c.request.model_fields)


def _kind(args: argparse.Namespace, data: Any, default: str, allowed: Sequence[str]) -> str:
    """The computation to run: ``--kind``, else the spec's own ``kind`` where its request
    model has one, else ``default``; refused (naming the allowed names) unless in
    ``allowed``.  Never guessed from the spec's other fields."""
    given = data.get("kind") if isinstance(data, dict) else None
    if given is not None and given not in _tagged_kinds():
        raise PipeflowError(
            f"the spec's kind {given!r} names no computation; its kind is one of: "
            f"{', '.join(_tagged_kinds())} (or give no kind and --kind NAME)",
            parameter="kind",
        )
    kind = getattr(args, "kind", None) or given or default
    if kind not in allowed:
        raise PipeflowError(
            f"unknown kind {kind!r}; choose one of: {', '.join(allowed)}", parameter="--kind"
        )
    if given is not None and given != kind:
        raise PipeflowError(f"--kind {kind} but the spec's kind is {given!r}", parameter="--kind")
    return kind


def _progress(args: argparse.Namespace, label: str) -> ProgressBar:
    return ProgressBar(label, enabled=True if args.progress else (False if args.quiet else None))


def _run_local(kind: str, spec_data: Any, bar: ProgressBar) -> dict[str, Any]:
    """Validate ``spec_data`` as a request of the registry's computation ``kind``; run it."""
    from pydantic import ValidationError

    from pipeflow.computations import registry

    try:
        request = registry.parse(kind, spec_data)
    except ValidationError as exc:
        print(
            f"error: not a valid {kind!r} request (choose the computation with --kind: "
            f"{', '.join(_kinds())})",
            file=sys.stderr,
        )
        exc.__notes__ = [_REQUEST_TYPE_NOTE + kind]
        raise
    try:
        return registry.computation_for(request).execute(request, bar)
    finally:
        bar.close()


def _run_remote(
    kind: str, spec_data: Any, server: str, bar: ProgressBar, api_key: str | None = None
) -> dict[str, Any]:
    """Run on ``server``; ``api_key`` (None: ``PIPEFLOW_API_KEY``, read by the client)."""
    from pipeflow_client import Client  # imported here: the library has no web imports

    with Client(server, api_key=api_key) as client:
        try:
            return dict(client.compute(kind, spec_data, progress=bar))
        finally:
            bar.close()


def _result_for(
    args: argparse.Namespace, data: Any, default: str = "simulation", allowed: Sequence[str] = ()
) -> dict[str, Any]:
    """``data`` itself when it is a result, else the result of running it as the
    computation :func:`_kind` names."""
    data = _unwrap(data)
    if _is_result(data):
        return data
    kind = _kind(args, data, default, allowed or _kinds())
    bar = _progress(
        args,
        {"simulation": "simulating", "compare": "comparing", "study": "studying"}.get(
            kind, "analysing"
        ),
    )
    if getattr(args, "server", None):
        return _run_remote(kind, data, args.server, bar, getattr(args, "api_key", None))
    return _run_local(kind, data, bar)


def _write(out: str | None, payload: str | bytes) -> None:
    if out in (None, "-"):
        if isinstance(payload, bytes):
            sys.stdout.buffer.write(payload)
        else:
            sys.stdout.write(payload)
        return
    path = Path(out)
    if isinstance(payload, bytes):
        path.write_bytes(payload)
    else:
        path.write_text(payload, encoding="utf-8", newline="")


def _write_json(args: argparse.Namespace, result: dict[str, Any]) -> None:
    """``result`` as JSON to ``--output`` (stdout by default), one line with ``--compact``."""
    _write(args.output, json.dumps(result, indent=None if args.compact else 1) + "\n")


def _print_warnings(result: dict[str, Any]) -> None:
    for w in result.get("warnings", []):
        print(f"warning: {w}", file=sys.stderr)


def cmd_example(args: argparse.Namespace) -> int:
    from pipeflow.schema.simulation import PAPER_EXAMPLE

    _write(args.output, json.dumps(PAPER_EXAMPLE, indent=2) + "\n")
    return 0


def _write_file_format(args: argparse.Namespace, result: dict[str, Any]) -> bool:
    """Write ``result`` as UFF, netCDF or MATLAB (a state-space result) when ``--format``
    asks for it (True if so)."""
    from pipeflow.io.formats import to_mat, to_netcdf, to_uff

    writers = {"uff": to_uff, "netcdf": to_netcdf, "mat": to_mat}
    if args.format not in writers:
        return False
    _write(args.output, writers[args.format](result))
    return True


def cmd_run(args: argparse.Namespace) -> int:
    result = _result_for(args, _read_json(args.spec))
    if _write_file_format(args, result):
        pass
    elif args.format in ("csv", "parquet"):
        from pipeflow.io.export import to_csv, to_parquet

        export = to_csv if args.format == "csv" else to_parquet
        _write(args.output, export(result, args.table))
    else:
        _write_json(args, result)
    _print_warnings(result)
    return 0


def _spec_pipe(data: Any) -> Any:
    """The library pipe of a spec's ``pipe`` (its supports are drawn on the plots along x),
    or None for a result (which does not carry its request's pipe)."""
    data = _unwrap(data)
    if _is_result(data):
        return None
    from pipeflow.schema.simulation import pipe_of_request

    return pipe_of_request(data)


def cmd_plot(args: argparse.Namespace) -> int:
    from pipeflow.io.plots import PlotError, render

    fmt = args.format or Path(args.out).suffix.lstrip(".").lower()
    if fmt not in ("png", "svg"):
        raise PlotError("give --out a .png or .svg file name, or --format", field="--out")
    from pipeflow.io.plots import available_plots

    data = _read_json(args.input)
    result = _result_for(args, data)
    names = available_plots(result)
    name = args.name or (names[0] if names else "tip_displacement")
    if name not in names:
        raise PlotError(
            f"this result has no {name!r} plot; it has: {', '.join(names) or 'none'}",
            field="--name",
        )
    units = {"spin": args.spin_unit, "frequency": args.frequency_unit}
    pipe = _spec_pipe(data)
    _write(args.out, render(result, name, fmt, title=args.title, units=units, pipe=pipe))
    if args.out not in (None, "-"):
        print(f"wrote {args.out}", file=sys.stderr)
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from pipeflow.io import report

    fmt = args.format or Path(args.out).suffix.lstrip(".").lower()
    if fmt not in report.MEDIA_TYPES:
        raise ValueError("give --out a .html or .pdf file name, or --format")
    data = _unwrap(_read_json(args.input))
    # a spec is run first and is then the report's inputs; a result has none to show
    inputs = None if _is_result(data) else data
    result = _result_for(args, data)
    if fmt == "pdf":
        _write(args.out, report.to_pdf(result, inputs))
    else:
        _write(args.out, report.to_html(result, inputs))
    if args.out not in (None, "-"):
        print(f"wrote {args.out}", file=sys.stderr)
    return 0


def cmd_stability(args: argparse.Namespace) -> int:
    data = _unwrap(_read_json(args.spec))
    result = _result_for(args, data, "stability", ("stability", *_sweep_kinds()))
    _write_json(args, result)
    if result.get("kind") == "stability":
        print(f"critical flow velocity: {_critical(result)}", file=sys.stderr)
    _print_warnings(result)
    return 0


def _critical(result: dict[str, Any]) -> str:
    """The critical velocity of a stability result: the first loss of stability from a
    stable start of the range; a pipe already unstable there has none (its
    ``critical_velocity`` is then a loss after a regain), and where it is stable is said."""
    v = result.get("critical_velocity")
    if result.get("stable_at_start") is False:
        lo = max(float(result["velocity_range"][0]), 0.0)
        how = " and ".join(result.get("instability_at_start") or []) or "unstable"
        stable = ", ".join(f"[{a:.5g}, {b:.5g}]" for a, b in result.get("stable_intervals") or [])
        return f"none: already unstable at v = {lo:.6g} m/s ({how}); stable on " + (
            f"{stable} m/s" if stable else "no part of the range"
        )
    return "none in the range" if v is None else f"{v:.6g} m/s"


def _g(value: Any) -> str:
    return "-" if value is None else f"{value:.6g}"


def study_report(result: dict[str, Any]) -> list[str]:
    """A study's statistics (and Sobol' indices) as lines of text, units from its columns."""
    st = result["statistics"]
    lines = [f"{result['counts']['total']} cases: {st['ok']} ok, {st['failed']} failed"]
    for name, c in st["columns"].items():
        q = c["quantiles"]
        lines.append(
            f"{name} [{c['unit']}]: mean {_g(c['mean'])}, std {_g(c['std'])}, "
            f"min {_g(c['min'])}, max {_g(c['max'])}, 5/50/95% {_g(q['0.05'])} / "
            f"{_g(q['0.5'])} / {_g(q['0.95'])} (n = {c['count']})"
        )
    inst = st.get("instability")
    if inst is not None and inst["probability"] is not None:
        lines.append(
            f"P(unstable) = {inst['probability']:.4g} +- {inst['standard_error']:.2g} "
            f"({inst['unstable']} of {inst['decided']}: {inst['criterion']})"
        )
    sens = result.get("sensitivity")
    for name, c in (sens or {}).get("columns", {}).items():
        if not c["available"]:
            continue
        for path, ix in c["parameters"].items():
            lines.append(
                f"Sobol {name} / {path}: S1 {ix['S1']:.3f} +- {ix['S1_conf']:.3f}, "
                f"ST {ix['ST']:.3f} +- {ix['ST_conf']:.3f}"
            )
    return lines


def cmd_study(args: argparse.Namespace) -> int:
    data = _unwrap(_read_json(args.spec))
    result = _result_for(args, data, "study", ("study",))
    if _write_file_format(args, result):
        pass
    elif args.format in ("csv", "parquet"):
        from pipeflow.io.export import to_csv, to_parquet

        export = to_csv if args.format == "csv" else to_parquet
        _write(args.output, export(result, "study"))
    else:
        _write_json(args, result)
    for line in study_report(result):
        print(line, file=sys.stderr)
    _print_warnings(result)
    return 0


def cmd_frequency_response(args: argparse.Namespace) -> int:
    data = _unwrap(_read_json(args.spec))
    result = _result_for(args, data, "frequency_response", ("frequency_response",))
    if _write_file_format(args, result):
        pass
    elif args.format in ("csv", "parquet"):
        from pipeflow.io.export import to_csv, to_parquet

        export = to_csv if args.format == "csv" else to_parquet
        _write(args.output, export(result, args.table))
    else:
        _write_json(args, result)
    for point in result["operating_points"]:
        where = f"v = {point['velocity']:g} m/s, w0 = {point['omega0']:g} rad/s"
        peaks = ", ".join(
            f"mode {p['mode']} at {p['frequency']:.6g} rad/s (zeta {p['damping_ratio']:.4g})"
            for p in point["peaks"]
        )
        print(f"{where}: {peaks or 'no peak in the range'}", file=sys.stderr)
    _print_warnings(result)
    return 0


def cmd_serve(args: argparse.Namespace) -> int:
    """Run ``python -m service`` with the same flags in a child process and return its exit
    status: the service (an extra, ``pip install 'pipeflow[service]'``) is not imported by
    the command line.  Ctrl-C reaches the child through the terminal's process group."""
    import importlib.util
    import subprocess

    for module in ("service", "uvicorn"):
        if importlib.util.find_spec(module) is None:
            raise PipeflowError(
                f"the service is not installed (no module {module!r}); pip install -e '.[service]'",
                parameter="serve",
            )
    argv = [sys.executable, "-m", "service", "--host", args.host, "--port", str(args.port)]
    if args.workers is not None:
        argv += ["--workers", str(args.workers)]
    if args.data_dir is not None:
        argv += ["--data-dir", str(args.data_dir)]
    child = subprocess.Popen(argv)
    try:
        return child.wait()
    except KeyboardInterrupt:  # the child got the same interrupt: let it shut down
        return child.wait()


def build_parser() -> argparse.ArgumentParser:
    from pipeflow import __version__
    from pipeflow.io.export import TABLES
    from pipeflow.io.plots import DISPLAY_UNITS, PLOTS

    p = argparse.ArgumentParser(
        prog="pipeflow",
        description=(
            "Vibration of a rotating cantilevered pipe conveying fluid with time-varying "
            "flow v(t) [m/s] and spin w0(t) [rad/s] (complex modal analysis, RK4, reference)."
        ),
        epilog=EXAMPLE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"pipeflow {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def progress_flags(sp: argparse.ArgumentParser) -> None:
        g = sp.add_mutually_exclusive_group()
        g.add_argument(
            "--progress", action="store_true", help="always draw the progress bar on stderr"
        )
        g.add_argument("--quiet", action="store_true", help="never draw the progress bar")

    def api_key_flag(sp: argparse.ArgumentParser) -> None:
        sp.add_argument(
            "--api-key",
            metavar="KEY",
            help=f"API key of a --server that requires keys, sent as 'Authorization: Bearer "
            f"KEY' (default: ${API_KEY_ENV}; the variable keeps the key out of the process "
            "list, where other users can read a command line)",
        )

    def json_output_flags(sp: argparse.ArgumentParser) -> None:
        """-o, --server, --api-key, --compact and the progress flags of the JSON-writing
        commands."""
        sp.add_argument("-o", "--output", help="write to this file instead of stdout")
        sp.add_argument("--server", metavar="URL", help="run on this pipeflow server instead")
        api_key_flag(sp)
        sp.add_argument("--compact", action="store_true", help="JSON on one line")
        progress_flags(sp)

    def units_flags(sp: argparse.ArgumentParser) -> None:
        """Display units of the figures' spin and frequency axes (the data stay SI)."""
        for quantity in DISPLAY_UNITS:
            sp.add_argument(
                f"--{quantity}-unit",
                choices=tuple(DISPLAY_UNITS[quantity]),
                default="rad/s",
                help=f"unit of the {quantity} axes of the figures (default rad/s)",
            )

    def kind_flag(sp: argparse.ArgumentParser, default: str, names: Sequence[str] = ()) -> None:
        sp.add_argument(
            "--kind",
            metavar="NAME",
            help=f"the computation to run a spec as: {', '.join(names or _kinds())} "
            f"(default: the spec's own 'kind' where it has one, else {default})",
        )

    sp = sub.add_parser(
        "example",
        help="print the paper's example spec (JSON)",
        description="Print the paper's section-5 example as a simulation spec (JSON, SI units).",
    )
    sp.add_argument("-o", "--output", help="write to this file instead of stdout")
    sp.set_defaults(func=cmd_example)

    sp = sub.add_parser(
        "run",
        help="run a simulation spec, print the result as JSON or CSV",
        description=(
            "Run the simulation described by SPEC (JSON; '-' reads stdin) locally, or on a "
            "pipeflow server with --server, and write the result."
        ),
        epilog=EXAMPLE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sp.add_argument("spec", help="simulation spec JSON file ('-': stdin); see 'pipeflow example'")
    kind_flag(sp, "simulation")
    sp.add_argument(
        "--format",
        choices=("json", "csv", "parquet", "uff", "netcdf", "mat"),
        default="json",
        help="output format (parquet: units in the column metadata, needs pipeflow[parquet]; "
        "uff: dataset 58 per FRF curve, 55 per mode shape; netcdf: the xarray layout; both "
        "need pipeflow[formats]; mat: a state_space result as a MATLAB file)",
    )
    sp.add_argument(
        "--table",
        choices=tuple(TABLES),
        default="history",
        help="CSV/Parquet table: " + "; ".join(f"{k}: {v}" for k, v in TABLES.items()),
    )
    json_output_flags(sp)
    sp.set_defaults(func=cmd_run)

    sp = sub.add_parser(
        "plot",
        help="draw a figure (PNG or SVG) of a result, or of a spec after running it",
        description=(
            "Draw one figure of INPUT, a result JSON (from 'pipeflow run' or the service) or "
            "a spec JSON (run first, locally or with --server). Plots: "
            + "; ".join(f"{k}: {v.title}" for k, v in PLOTS.items())
        ),
        epilog=EXAMPLE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sp.add_argument("input", help="result or spec JSON file ('-': stdin)")
    sp.add_argument(
        "--name", choices=tuple(PLOTS), help="which plot (default: the first the result has)"
    )
    sp.add_argument("--out", required=True, help="output file, .png or .svg ('-': stdout)")
    sp.add_argument("--format", choices=("png", "svg"), help="image format (default: from --out)")
    sp.add_argument("--title", help="figure title (default: the plot's name)")
    units_flags(sp)
    sp.add_argument("--server", metavar="URL", help="run a spec on this pipeflow server")
    api_key_flag(sp)
    kind_flag(sp, "simulation")
    progress_flags(sp)
    sp.set_defaults(func=cmd_plot)

    sp = sub.add_parser(
        "report",
        help="write a report (HTML or PDF) of a result, or of a spec after running it",
        description=(
            "Write the report of INPUT, a result JSON or a spec JSON (run first, locally or "
            "with --server; its inputs are then in the report): the inputs, key numbers, "
            "figures, method and diagnostics, warnings and the version."
        ),
    )
    sp.add_argument("input", help="result or spec JSON file ('-': stdin)")
    sp.add_argument("--out", required=True, help="output file, .html or .pdf ('-': stdout)")
    sp.add_argument("--format", choices=("html", "pdf"), help="format (default: from --out)")
    sp.add_argument("--server", metavar="URL", help="run a spec on this pipeflow server")
    api_key_flag(sp)
    kind_flag(sp, "simulation")
    progress_flags(sp)
    sp.set_defaults(func=cmd_report)

    sp = sub.add_parser(
        "stability",
        help="critical flow velocity, Argand/Campbell sweeps and stability maps (JSON)",
        description=(
            "Run a stability analysis locally (or with --server) and write its JSON. SPEC is "
            "a /v1/stability body (pipe, rotation, modes, velocity_range [m/s]: critical "
            "velocities) or a /v1/sweeps body with a 'kind': " + ", ".join(_sweep_kinds()) + ". "
            "Draw it with 'pipeflow plot RESULT --name argand|sweep_frequency|sweep_damping|"
            "spin_map|beta_map'."
        ),
        epilog=STABILITY_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sp.add_argument("spec", help="stability or sweep spec JSON file ('-': stdin)")
    kind_flag(sp, "stability", ("stability", *_sweep_kinds()))
    json_output_flags(sp)
    sp.set_defaults(func=cmd_stability)

    sp = sub.add_parser(
        "study",
        help="a design study (cases, grid or sampled parameters): table and statistics",
        description=(
            "Run the design study SPEC (a /v1/studies body: base, and cases, grid or samples "
            "with distributions per field for uncertainty quantification) locally (or with "
            "--server) and write its JSON (or its table with --format csv); the statistics "
            "of the summary columns, the probability of instability and, for saltelli "
            "samples, the Sobol' indices are printed on stderr."
        ),
    )
    sp.add_argument("spec", help="study spec JSON file ('-': stdin)")
    sp.add_argument(
        "--format",
        choices=("json", "csv", "parquet", "netcdf"),
        default="json",
        help="output format: the result JSON, the study table (one row per case), or netCDF",
    )
    json_output_flags(sp)
    sp.set_defaults(func=cmd_study)

    sp = sub.add_parser(
        "frequency-response",
        help="frequency response functions (Bode data, peaks) at frozen operating points",
        description=(
            "Compute the frequency response H(W) of SPEC (a /v1/frequency-responses body: "
            "pipe, constant flow.velocity [m/s] and rotation.omega0 [rad/s] or "
            "operating_points, load, response positions [m] and quantity, frequencies "
            "[rad/s]) locally (or with --server) and write its JSON (or a table); the peaks "
            "(frequency [rad/s], damping ratio [-]) are printed on stderr.  Draw it with "
            "'pipeflow plot RESULT --name bode|nyquist|waterfall|deflection_shape'."
        ),
        epilog=FREQUENCY_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sp.add_argument("spec", help="frequency-response spec JSON file ('-': stdin)")
    sp.add_argument(
        "--format",
        choices=("json", "csv", "parquet", "uff", "netcdf"),
        default="json",
        help="output format (parquet: units in the column metadata, needs pipeflow[parquet]; "
        "uff: dataset 58 per FRF curve, 55 per mode shape; netcdf: the xarray layout; both "
        "need pipeflow[formats])",
    )
    sp.add_argument(
        "--table",
        choices=("frequency_response", "peaks"),
        default="frequency_response",
        help="CSV/Parquet table: frequency_response (H per point and position) or peaks",
    )
    json_output_flags(sp)
    sp.set_defaults(func=cmd_frequency_response)

    sp = sub.add_parser(
        "serve",
        help="run the HTTP service (API and viewer)",
        description="Run the pipeflow HTTP service with uvicorn, as 'python -m service' with "
        "the same flags (in a child process; or 'uvicorn service.main:app --http "
        "service.http.deadline:HTTPProtocol', configured by the environment); the viewer is "
        "at /.  One server process per data directory: its "
        "worker pool (PIPEFLOW_WORKERS) gives the parallelism.",
    )
    sp.add_argument("--host", default="127.0.0.1", help="interface to bind (default 127.0.0.1)")
    sp.add_argument("--port", type=int, default=8000, help="TCP port (default 8000)")
    sp.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="compute worker processes (as PIPEFLOW_WORKERS; default min(2, CPUs)); the "
        "server itself is one process",
    )
    sp.add_argument(
        "--data-dir",
        type=Path,
        metavar="DIR",
        help="directory of the results and jobs store (as PIPEFLOW_DATA_DIR; default the "
        "per-user data directory, ~/.local/share/pipeflow on Linux)",
    )
    sp.set_defaults(func=cmd_serve)
    return p


#: the note a request's ValidationError carries: the computation it was validated as
_REQUEST_TYPE_NOTE = "pipeflow request kind: "


def _describe_validation(exc: Exception, tp: Any = None) -> list[str]:
    """One line per error: the field and :func:`pipeflow.schema.messages.message` (``tp``,
    the request type, gives an unknown field its "did you mean")."""
    from pipeflow.schema import messages

    errors = getattr(exc, "errors", None)
    if not callable(errors):
        return [str(exc)]
    lines = []
    for e in errors():
        loc = ".".join(str(x) for x in e.get("loc", ()))
        lines.append(f"{loc or 'spec'}: {messages.message(e, tp)}")
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``pipeflow`` console script; returns the exit status."""
    from pydantic import ValidationError

    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "api_key", None) is not None and not getattr(args, "server", None):
        parser.error("--api-key is the key of a --server; give --server URL too")
    try:
        return int(args.func(args))
    except ValidationError as exc:
        tp = None
        for note in getattr(exc, "__notes__", ()):
            if note.startswith(_REQUEST_TYPE_NOTE):
                from pipeflow.computations import registry

                tp = registry.request_type(note.removeprefix(_REQUEST_TYPE_NOTE))
        for line in _describe_validation(exc, tp):
            print(f"error: {line}", file=sys.stderr)
        return 2
    except PipeflowError as exc:
        name = exc.field if exc.field is not None else exc.parameter
        where = f"{name}: " if name else ""
        print(f"error: {where}{exc.message}", file=sys.stderr)
        if getattr(exc, "status", None) == 401:  # the server's answer (pipeflow_client)
            print(
                f"hint: this server requires an API key: give it with --api-key KEY or the "
                f"environment variable {API_KEY_ENV}",
                file=sys.stderr,
            )
        return 2
    except (ValueError, KeyError, ImportError) as exc:
        # plot/export errors carry a field too; a missing optional extra says what to install
        field = getattr(exc, "field", None)
        print(f"error: {field + ': ' if field else ''}{exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
