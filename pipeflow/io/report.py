"""A report of one result for a design review: HTML (figures embedded) or PDF.

:func:`report` gathers what an engineer attaches to a review from a result's JSON form
(:mod:`pipeflow.computations.documents`, what the service stores) and, when known, its request:
the inputs, the key numbers (status, critical velocity, peaks and damping ratios, growth
rates, divergence, error estimate; a study's statistics with their standard errors and its
Sobol' indices with their intervals, :mod:`pipeflow.io.study_report`), the figures
(:mod:`pipeflow.io.plots`, matplotlib), the method and its diagnostics, the warnings and
the version.  :func:`to_html` writes one self-contained page (PNG figures as data URIs, no
script, no external asset); :func:`to_pdf` writes the same content with matplotlib's
``PdfPages`` (a text page, then one page per figure; no other dependency).  Both are
deterministic for a given result (no timestamps), so equal results give equal bytes.
"""

from __future__ import annotations

import base64
import html
import io
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from pipeflow import __version__
from pipeflow.io import study_report

#: most figures in one report (the first of the result's available plots)
MAX_FIGURES = 6

MEDIA_TYPES = {"html": "text/html; charset=utf-8", "pdf": "application/pdf"}


@dataclass
class Report:
    """The content of a report: ``sections`` of (label, value) rows, ``figures`` as
    (title, plot name) and ``warnings``; SI units stated in every label."""

    title: str
    sections: list[tuple[str, list[tuple[str, str]]]] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)


def _g(x: Any, digits: int = 6) -> str:
    """A number as text (null: '-'), lists and strings as they are."""
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, float):
        return f"{x:.{digits}g}" if math.isfinite(x) else str(x)
    if isinstance(x, list | dict):
        return json.dumps(x)
    return str(x)


def _flat(prefix: str, value: Any, out: list[tuple[str, str]]) -> None:
    if isinstance(value, Mapping):
        for k, v in value.items():
            _flat(f"{prefix}.{k}" if prefix else str(k), v, out)
    else:
        out.append((prefix, _g(value)))


def _simulation_numbers(r: dict[str, Any]) -> list[tuple[str, str]]:
    tip = [abs(v) for v in r.get("tip_displacement", [])]
    modes = r["eigenvalues"]["modes"]
    first = modes[0]
    s, w = first["sigma"][-1], first["omega"][-1]
    # the traces end with the history: t_end, or the divergence time of a stopped run
    end = f"t = {_g(r['eigenvalues']['t'][-1])} s"
    rows = [
        ("status", r["status"]),
        ("output times", f"{len(r['t'])} from 0 to {_g(r['t'][-1])} s"),
        ("initial tip displacement u(L, 0) [m]", _g(r.get("initial_tip_displacement"))),
        ("peak tip displacement max |u(L, t)| [m]", _g(max(tip) if tip else None)),
        ("divergence bound (linear range) [m]", _g(r.get("divergence_bound"))),
        ("divergence time [s]", _g(r.get("divergence_time"))),
        ("growth rate at divergence [1/s]", _g(r.get("divergence_growth_rate"))),
        ("first unstable time [s]", _g(r.get("first_unstable_time"))),
        ("largest growth rate max sigma [1/s]", _g(r["diagnostics"].get("max_growth_rate"))),
        (f"mode {first['mode']} at {end}: sigma [1/s], omega [rad/s]", f"{_g(s)}, {_g(w)}"),
        (
            f"mode {first['mode']} damping ratio -sigma/|xi| at {end} [-]",
            _g(-s / math.hypot(s, w) if (s or w) else None),
        ),
    ]
    least = next((m for m in modes if m.get("least_stable")), None)
    if least is not None and least is not first:
        rows.append(
            (
                f"least stable branch: mode {least['mode']}, max sigma [1/s]",
                _g(max(least["sigma"])),
            )
        )
    d = r["diagnostics"]
    rows.append(("estimated relative error [-]", _g(d.get("estimated_relative_error"))))
    if d.get("error_estimate_method"):
        rows.append(("error estimate method", str(d["error_estimate_method"])))
    return rows


#: the results' field of how the pipe is unstable at the start of a range
START = "instability_at_start"


def _interval(i: list[float]) -> str:
    return f"[{_g(i[0], 5)}, {_g(i[1], 5)}]"


def _intervals(intervals: list[list[float]], unit: str) -> str:
    return ", ".join(map(_interval, intervals)) + unit if intervals else "none"


def _start(stable: Any, how: list[str] | None) -> str:
    """'yes' or 'no: divergence' (how it is unstable there)."""
    if stable is None:
        return "-"
    return "yes" if stable else "no: " + (" and ".join(how) if how else "mechanism not recorded")


def _changes(changes: list[tuple[float, str, str]], unit: str) -> str:
    """Every change of stability: 'regains at 17.51 m/s (divergence); loses at ...'."""
    words = {"loss": "loses", "gain": "regains"}
    return (
        "; ".join(f"{words[d]} at {_g(x, 5)}{unit} ({kind})" for x, d, kind in changes)
        if changes
        else "none"
    )


def _first_loss(stable: Any, changes: list[tuple[float, str, str]], where: str) -> str:
    """The critical value: the first loss from a stable start (else why there is none)."""
    if not stable:
        return f"none: already unstable at {where}"
    loss = next((x for x, d, _ in changes if d == "loss"), None)
    return _g(loss) if loss is not None else "none in the range"


def _stability_numbers(r: dict[str, Any]) -> list[tuple[str, str]]:
    lo = max(float((r.get("velocity_range") or [0.0])[0]), 0.0)
    where = f"v = {_g(lo, 5)} m/s"
    stable = r.get("stable_at_start")
    changes = [
        (c["velocity"], c["direction"], f"{c['kind']}, mode {c['mode']}")
        for c in r.get("crossings") or []
        if c.get("boundary")
    ]
    rows = [
        (f"stable at the start of the range, {where}", _start(stable, r.get(START))),
        (
            f"critical velocity v_cr [m/s]: the first loss of stability from {where}",
            _first_loss(stable, changes, where) if stable is not None else "-",
        ),
        ("stable intervals [m/s]", _intervals(r.get("stable_intervals") or [], " m/s")),
        ("changes of stability", _changes(changes, " m/s")),
        ("stable throughout", _g(r.get("stable_throughout"))),
        ("spin w0 [rad/s]", _g(r.get("omega0"))),
        ("velocity range [m/s]", _g(r.get("velocity_range"))),
    ]
    for i, c in enumerate(r.get("crossings") or []):
        rows.append(
            (
                f"crossing {i + 1}: v [m/s], frequency [rad/s], mode, kind",
                f"{_g(c['velocity'])}, {_g(c['frequency'])}, {c['mode']}, {c['kind']} "
                f"({c['direction']})",
            )
        )
    return rows


def _map_numbers(r: dict[str, Any]) -> list[tuple[str, str]]:
    """A spin map (per spin, in v [m/s]) or a beta map (per beta, in u [-]): each line's
    stability at its start, its critical value (first loss from a stable start), its
    stable intervals and its changes of stability."""
    spin = r["kind"] == "spin_map"
    lines = r["spins"] if spin else r["betas"]
    lo = max(float(r["velocities"][0]), 0.0) if spin else float(r["u_range"][0])
    where = f"v = {_g(lo, 5)} m/s" if spin else f"u = {_g(lo, 5)}"
    unit = " m/s" if spin else ""
    how = r.get(START) or [None] * len(lines)
    intervals = r.get("stable_intervals") or [[] for _ in lines]
    value = "velocity" if spin else "u"
    rows = [
        (
            "columns",
            f"stable at {where}; first loss from there (v_cr [m/s])"
            if spin
            else f"stable at {where}; first loss from there (u_cr [-])",
        )
    ]
    for i, x in enumerate(lines):
        changes = [(c[value], c["direction"], c["kind"]) for c in r["crossings"][i]]
        ok = r["stable_at_start"][i]
        name = f"w0 = {_g(x, 5)} rad/s" if spin else f"beta = {_g(x, 4)}"
        rows.append(
            (
                name,
                f"{_start(ok, how[i])}; {_first_loss(ok, changes, where)}; stable on "
                f"{_intervals(intervals[i], unit)}; {_changes(changes, unit)}",
            )
        )
    return rows


def _sweep_picture(r: dict[str, Any]) -> list[tuple[str, str]]:
    """An Argand or Campbell sweep: the pipe's stability along it (every eigenvalue)."""
    if "stable_at_start" not in r:
        return []
    par = r["parameter"]
    unit = f" {par['unit']}"
    name = "w0" if par["name"] == "spin" else "v"
    where = f"{name} = {_g(par['values'][0], 5)}{unit}"
    stable = r["stable_at_start"]
    changes = [(c["value"], c["direction"], c["kind"]) for c in r.get("boundary") or []]
    critical = "critical velocity v_cr" if par["name"] == "velocity" else "critical spin"
    return [
        (f"pipe stable at the start of the sweep, {where}", _start(stable, r.get(START))),
        (
            f"{critical} [{par['unit']}]: the first loss of stability from {where}",
            _first_loss(stable, changes, where),
        ),
        (f"stable intervals [{par['unit']}]", _intervals(r.get("stable_intervals") or [], unit)),
        ("changes of stability (every eigenvalue)", _changes(changes, unit)),
    ]


def _frf_numbers(r: dict[str, Any]) -> list[tuple[str, str]]:
    rows = [("quantity", f"{r['quantity']} [{r['unit']}] per unit load")]
    for i, p in enumerate(r["operating_points"]):
        where = f"point {i + 1} (v = {_g(p['velocity'])} m/s, w0 = {_g(p['omega0'])} rad/s)"
        rows.append((f"{where}: stable, max growth rate [1/s]",
                     f"{_g(p['stable'])}, {_g(p['max_growth_rate'])}"))  # fmt: skip
        for k in p.get("peaks") or []:
            rows.append(
                (
                    f"{where}: peak of mode {k['mode']}: frequency [rad/s], damping ratio [-]",
                    f"{_g(k['frequency'])}, {_g(k['damping_ratio'])}",
                )
            )
    return rows


def _sweep_numbers(r: dict[str, Any]) -> list[tuple[str, str]]:
    if r.get("kind") in ("spin_map", "beta_map") and r.get("crossings") is not None:
        return _map_numbers(r)
    par = r.get("parameter") or {}
    rows = [("swept", f"{par.get('name')} [{par.get('unit')}]")] if par else []
    if par:
        rows += _sweep_picture(r)
    for c in r.get("zero_crossings") or []:
        rows.append(
            (
                f"sigma = 0 crossing of tracked mode {c['mode']} ({c['direction']})",
                f"at {_g(c['value'])} {par.get('unit', '')}, frequency {_g(c['frequency'])} rad/s",
            )
        )
    for key in ("critical_velocity", "verdict", "growth_rate", "max_multiplier", "period"):
        if key in r and not isinstance(r[key], list):
            rows.append((key, _g(r[key])))
    return rows


def report(
    result: Mapping[str, Any], inputs: Mapping[str, Any] | None = None, key: str | None = None
) -> Report:
    """The content of the report of ``result`` (its JSON form), with its request
    ``inputs`` when known and its ``key``."""
    from pipeflow.io.plots import available_plots

    r = dict(result)
    kind = r.get("kind") or "simulation"
    if kind == "simulation" and "tip_displacement" in r:
        numbers = _simulation_numbers(r)
    elif kind == "stability":
        numbers = _stability_numbers(r)
    elif kind == "frequency_response":
        numbers = _frf_numbers(r)
    elif kind == "study":
        numbers = study_report.numbers(r)
    else:
        numbers = _sweep_numbers(r)
    out = Report(title=f"pipeflow report: {kind}")
    about = [("pipeflow version", __version__), ("result kind", kind)]
    if key or r.get("key"):
        about.append(("key (parameter hash)", str(key or r.get("key"))))
    out.sections.append(("Result", about))
    out.sections.append(("Key numbers (SI units)", numbers))
    indices = study_report.sensitivity(r) if kind == "study" else None
    if indices:
        out.sections.append(("Sensitivity: Sobol' indices and their intervals", indices))
    method: list[tuple[str, str]] = study_report.method(r, inputs) if kind == "study" else []
    if r.get("method_used"):
        from pipeflow.solvers import SOLVERS

        solver = SOLVERS.get(r["method_used"])
        method.append(("method", f"{r.get('method')} -> {r['method_used']}"))
        if r.get("method_reason"):
            method.append(("why", r["method_reason"]))
        if solver is not None:
            method.append(("what it is", solver.description))
    diagnostics: list[tuple[str, str]] = []
    _flat("", r.get("diagnostics") or {}, diagnostics)
    out.sections.append(("Method and diagnostics", method + diagnostics))
    inputs = inputs or r.get("request")  # a study echoes its request
    if inputs:
        rows: list[tuple[str, str]] = []
        _flat("", dict(inputs), rows)
        out.sections.append(("Inputs (SI units, as requested)", rows))
    else:
        out.sections.append(("Inputs", [("request", "not stored with this result")]))
    out.figures = available_plots(r)[:MAX_FIGURES]
    out.warnings = list(r.get("warnings") or [])
    return out


def _png(result: dict[str, Any], name: str) -> bytes:
    from pipeflow.io.plots import figure, to_bytes

    return to_bytes(figure(name, [(None, result)]), "png", dpi=90)


def to_html(
    result: Mapping[str, Any], inputs: Mapping[str, Any] | None = None, key: str | None = None
) -> str:
    """The report as one self-contained HTML page (figures as PNG data URIs)."""
    rep = report(result, inputs, key)
    e = html.escape
    parts = [
        "<!doctype html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{e(rep.title)}</title>",
        "<style>body{font-family:sans-serif;max-width:60em;margin:2em auto;padding:0 1em}"
        "table{border-collapse:collapse;width:100%;margin-bottom:1.5em}"
        "td{border-bottom:1px solid #ddd;padding:.25em .5em;vertical-align:top}"
        "td:first-child{width:45%;color:#333}.warn{color:#8a4b00}"
        "figure{margin:1em 0}img{max-width:100%}</style>",
        "</head><body>",
        f"<h1>{e(rep.title)}</h1>",
    ]
    for title, rows in rep.sections:
        parts.append(f"<h2>{e(title)}</h2><table>")
        parts += [f"<tr><td>{e(k)}</td><td>{e(v)}</td></tr>" for k, v in rows]
        parts.append("</table>")
    if rep.warnings:
        parts.append("<h2>Warnings</h2><ul>")
        parts += [f'<li class="warn">{e(w)}</li>' for w in rep.warnings]
        parts.append("</ul>")
    if rep.figures:
        parts.append("<h2>Figures</h2>")
        for name in rep.figures:
            data = base64.b64encode(_png(dict(result), name)).decode()
            parts.append(
                f'<figure id="figure-{e(name)}"><img alt="{e(name)}" '
                f'src="data:image/png;base64,{data}"><figcaption>{e(name)}</figcaption></figure>'
            )
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


def _text_lines(rep: Report) -> list[tuple[str, str, str]]:
    """The report's lines as (style, left, right)."""
    lines: list[tuple[str, str, str]] = [("title", rep.title, "")]
    for title, rows in rep.sections:
        lines.append(("heading", title, ""))
        lines += [("row", k, v) for k, v in rows]
    if rep.warnings:
        lines.append(("heading", "Warnings", ""))
        lines += [("warn", w, "") for w in rep.warnings]
    return lines


def _wrap(text: str, width: int) -> str:
    import textwrap

    # a key (64 hex digits) or a number stays whole on its line
    return "\n".join(textwrap.wrap(text, width, break_long_words=False)) or text


def to_pdf(
    result: Mapping[str, Any], inputs: Mapping[str, Any] | None = None, key: str | None = None
) -> bytes:
    """The report as PDF bytes (A4 pages: the text, then one figure a page), written by
    matplotlib's ``PdfPages`` with no creation date (equal results, equal bytes)."""
    from matplotlib.backends.backend_pdf import PdfPages
    from matplotlib.figure import Figure

    from pipeflow.io.plots import figure

    rep = report(result, inputs, key)
    buf = io.BytesIO()
    a4 = (8.27, 11.69)
    with PdfPages(buf, metadata={"Title": rep.title, "CreationDate": None}) as pdf:
        fig, y = Figure(figsize=a4), 0.96
        for style, left, right in _text_lines(rep):
            texts: list[tuple[float, str, dict[str, Any]]]
            if style == "warn":
                texts = [(0.07, _wrap(left, 110), {"color": "#8a4b00", "fontsize": 7.5})]
            elif style == "row":
                texts = [
                    (0.07, _wrap(left, 48), {"fontsize": 8}),
                    (0.45, _wrap(right, 66), {"fontsize": 7.5, "family": "monospace"}),
                ]
            else:
                size = 15 if style == "title" else 11.5
                texts = [(0.06, left, {"fontsize": size, "weight": "bold"})]
            height = 0.0145 * max(t.count("\n") + 1 for _, t, _ in texts) + (
                0.02 if style != "row" and style != "warn" else 0.002
            )
            if y - height < 0.04:  # the next page
                pdf.savefig(fig)
                fig, y = Figure(figsize=a4), 0.96
            for x, text, kw in texts:
                fig.text(x, y, text, va="top", **kw)
            y -= height
        pdf.savefig(fig)
        for name in rep.figures:
            fig = figure(name, [(None, dict(result))], size=(7.5, 5.0))
            pdf.savefig(fig)
    return buf.getvalue()
