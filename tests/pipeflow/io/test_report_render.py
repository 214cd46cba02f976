"""The report's PDF rendered page by page (issue 24: "test the PDF by rendering its pages").

pypdfium2 (PDFium, the PDF engine of Chromium: independent of matplotlib, which writes the
file) rasterises every page at 50 dpi.  A page is "inked" where its pixels are darker than
light grey (mean RGB < 200 of 255): every page must be neither blank nor a filled block
(ink between 0.05 % and 50 % of its area).  A figure page must have an axes frame (its
spines: inked rows and columns running over half the page), coloured curves (pixels whose
channels differ by over 60: matplotlib's tab: colours; frame, ticks and text are black or
grey) all inside that frame, and ink outside it (tick labels, axis labels, title).  The
page count and sizes are checked against pypdf's reading of the same bytes, and the
figure pages are those of :func:`pipeflow.io.report.report`.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np
import pytest

from pipeflow.computations import documents
from pipeflow.io.report import report, to_pdf
from pipeflow.paper import PAPER_PIPE
from pipeflow.profiles import Constant, polynomial
from pipeflow.simulation import Simulation, simulate

pytest.importorskip("matplotlib")
pdfium = pytest.importorskip("pypdfium2")
pypdf = pytest.importorskip("pypdf")

#: ~2-3 s for the PDF (matplotlib draws 4 figures and the text pages): CI's slow step
pytestmark = pytest.mark.slow

DPI = 50
#: darker than this mean RGB (of 255) is ink
INK_LEVEL = 200
#: channels differing by more than this: a coloured (curve) pixel
COLOUR_SPREAD = 60
A4 = (595.44, 841.68)  # [pt], matplotlib's 8.27 x 11.69 in


def _pages(data: bytes) -> list[tuple[tuple[float, float], np.ndarray]]:
    pdf = pdfium.PdfDocument(data)
    try:
        out = []
        for i in range(len(pdf)):
            page = pdf[i]
            image = page.render(scale=DPI / 72).to_numpy()[..., :3].astype(int)
            out.append((page.get_size(), image))
        return out
    finally:
        pdf.close()


def _ink(image: np.ndarray) -> np.ndarray:
    return np.asarray(image.mean(axis=2) < INK_LEVEL)


def _coloured(image: np.ndarray) -> np.ndarray:
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    spread = np.maximum(np.maximum(abs(r - g), abs(g - b)), abs(r - b))
    return np.asarray(spread > COLOUR_SPREAD)


@pytest.fixture(scope="module")
def result() -> dict[str, Any]:
    sim = Simulation(
        PAPER_PIPE, polynomial(0, 0.4), Constant(100.0), modes=4, t_end=0.2, samples=201,
        eigen_samples=51,
    )  # fmt: skip
    return documents.simulation(simulate(sim))


def test_every_page_of_the_pdf_renders_with_ink_and_its_figures_draw_curves(
    result: dict[str, Any],
) -> None:
    data = to_pdf(result, None, key="k")
    pages = _pages(data)
    reader = pypdf.PdfReader(io.BytesIO(data))
    assert len(pages) == len(reader.pages)
    for (w, h), rp in zip((size for size, _ in pages), reader.pages, strict=True):
        assert (w, h) == pytest.approx((float(rp.mediabox.width), float(rp.mediabox.height)))

    figures = report(result).figures
    assert len(figures) >= 3  # tip displacement, damping, frequency at least
    text_pages = len(pages) - len(figures)
    assert text_pages >= 1
    for i, ((w, h), image) in enumerate(pages):
        assert image.shape[:2] == pytest.approx((h * DPI / 72, w * DPI / 72), abs=1), i
        ink = _ink(image)
        assert 5e-4 < ink.mean() < 0.5, (i, ink.mean())
        if i < text_pages:
            assert (w, h) == pytest.approx(A4, abs=0.5)
            assert ink[: image.shape[0] // 10].any(), i  # the first line of text on top
            continue
        # a figure page: its axes' frame (the inked rows and columns running over half the
        # page), coloured curves, all of them inside that frame
        name = figures[i - text_pages]
        top, bottom, left, right = _frame(ink)
        assert bottom - top > 0.3 * ink.shape[0] and right - left > 0.3 * ink.shape[1], name
        colour = _coloured(image)
        assert colour.mean() > 1e-3, (name, colour.mean())
        inside = colour[top : bottom + 1, left : right + 1].sum()
        assert inside >= 0.95 * colour.sum(), (name, inside, colour.sum())
        # and ink besides the curves and the frame: tick labels, axis labels, title
        outside = ink.copy()
        outside[top : bottom + 1, left : right + 1] = False
        assert outside.mean() > 1e-3, name


def _frame(ink: np.ndarray) -> tuple[int, int, int, int]:
    """The first and last row and column inked over more than half the page's height or
    width: the axes' spines (grid lines are lighter than the ink level)."""
    rows = np.flatnonzero(ink.sum(axis=1) > 0.5 * ink.shape[1])
    cols = np.flatnonzero(ink.sum(axis=0) > 0.5 * ink.shape[0])
    assert rows.size >= 2 and cols.size >= 2, "no axes frame"
    return int(rows[0]), int(rows[-1]), int(cols[0]), int(cols[-1])


def test_a_blank_page_would_fail_the_checks() -> None:
    """The checks above can fail: a PDF page with nothing drawn has no ink, a page of
    black text no coloured pixels and no axes frame (matplotlib writes both here)."""
    from matplotlib.backends.backend_pdf import PdfPages
    from matplotlib.figure import Figure

    buf = io.BytesIO()
    with PdfPages(buf) as pdf:
        pdf.savefig(Figure(figsize=(4, 3)))
        fig = Figure(figsize=(4, 3))
        fig.text(0.1, 0.5, "only black text", fontsize=20)
        pdf.savefig(fig)
    (_, blank), (_, text) = _pages(buf.getvalue())
    assert _ink(blank).mean() == 0.0
    assert _ink(text).mean() > 5e-4 and _coloured(text).mean() == 0.0
    with pytest.raises(AssertionError, match="no axes frame"):
        _frame(_ink(text))
