"""The examples of README.md and of the manual in docs/ run as written, the figures they
quote are current, and the manual builds into a site with no broken link.

Every fenced ``bash`` and ``python`` block of README.md and of every page under ``docs/``
is run, page by page (README first, then the pages in ``mkdocs.yml``'s nav order, then any
page the nav misses: a new page is picked up by itself), each page in a temporary working
directory of its own, its blocks in order (as a reader pasting them one after another
would: a later block may use a file an earlier one of the same page wrote), against a live
``uvicorn service.main:app`` started by the fixture on a free port; ``localhost:8000`` in a
block is rewritten to that server.  Bash blocks run under ``bash -euo pipefail`` with
``curl`` failing on HTTP errors (as if every call had ``--fail-with-body``), so an example
answered 4xx/5xx fails here.

A block is skipped only when the line before it is the marker
``<!-- readme-test: skip (reason) -->`` with a reason (installs, a second server in the
foreground, a Docker engine, runs of minutes); the marker convention is stated in the
README's Development section and in docs/development.md.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.live import ROOT

README = ROOT / "README.md"
DOCS = ROOT / "docs"
SKIP = re.compile(r"<!--\s*readme-test:\s*skip\s*\((?P<reason>[^)]+)\)\s*-->")
FENCE = re.compile(r"^```(?P<lang>[a-z]*)\s*$")
#: per block [s]: the slowest (the stability examples) take a few seconds on a free core
TIMEOUT_S = 600


@dataclass(frozen=True)
class Block:
    lang: str
    line: int  # 1-based line of the opening fence
    text: str
    skip: str | None  # the marker's reason, or None
    page: str = "README.md"  # the file, relative to the repository's root


def nav_pages() -> list[str]:
    """The pages of ``mkdocs.yml``'s nav, in its order (paths relative to ``docs/``)."""
    import yaml

    found: list[str] = []

    def walk(node: object) -> None:
        if isinstance(node, str):
            found.append(node)
        elif isinstance(node, list):
            for item in node:
                walk(item)
        elif isinstance(node, dict):
            for item in node.values():
                walk(item)

    walk(yaml.safe_load((ROOT / "mkdocs.yml").read_text(encoding="utf-8")).get("nav", []))
    return [page for page in found if page.endswith(".md")]


def pages() -> list[Path]:
    """README.md, then every Markdown page under docs/: the nav's first, in its order."""
    everything = sorted(DOCS.rglob("*.md"))
    ordered = [DOCS / page for page in nav_pages() if (DOCS / page).is_file()]
    return [README, *ordered, *(p for p in everything if p not in ordered)]


def blocks(text: str, page: str = "README.md") -> list[Block]:
    """The fenced blocks of ``text`` with their language and skip marker."""
    out = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        start = i
        i += 1
        body = []
        while i < len(lines) and not lines[i].startswith("```"):
            body.append(lines[i])
            i += 1
        i += 1
        before = next((ln for ln in reversed(lines[:start]) if ln.strip()), "")
        marker = SKIP.search(before)
        if "readme-test" in before and marker is None:
            raise AssertionError(f"{page}:{start}: malformed marker {before!r}")
        reason = marker and marker["reason"]
        out.append(Block(m["lang"], start + 1, "\n".join(body) + "\n", reason, page))
    return out


PAGES = pages()
RUNNABLE = [
    b
    for page in PAGES
    for b in blocks(page.read_text(encoding="utf-8"), str(page.relative_to(ROOT)))
    if b.lang in ("bash", "python")
]

#: makes an HTTP error answer of any curl call fail the block (BASH_ENV of the shells)
#: curl fails on HTTP errors unless the block already says how (-f: curl refuses both)
CURL_FAILS = (
    'curl() { local a; for a in "$@"; do case "$a" in --fail|--fail-with-body) '
    'command curl "$@"; return;; --*) ;; -*f*) command curl "$@"; return;; esac; done; '
    'command curl --fail-with-body "$@"; }\n'
)


def test_the_readme_has_runnable_examples_and_marks_every_skip() -> None:
    """Guards the extraction itself: blocks are found, and every skip states a reason."""
    assert len([b for b in RUNNABLE if b.skip is None and b.page == "README.md"]) >= 6
    assert len([b for b in RUNNABLE if b.skip is None and b.page != "README.md"]) >= 20
    for b in RUNNABLE:
        assert b.skip is None or len(b.skip.strip()) > 5, b


def test_every_docs_page_is_read_and_in_the_nav() -> None:
    """A page added under docs/ is run by these tests whether or not it is in the nav, and
    the nav names every page (so the site shows it); the nav's order is the run order."""
    names = {str(p.relative_to(ROOT)) for p in PAGES}
    assert {"docs/index.md", "docs/http-api.md", "docs/model.md", "docs/caches.md"} <= names
    on_disk = {str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md")}
    assert on_disk <= set(nav_pages()), (
        f"pages missing from mkdocs.yml's nav: {on_disk - set(nav_pages())}"
    )
    assert PAGES[0] == README and PAGES[1] == DOCS / "index.md"


def test_the_readme_is_the_front_door() -> None:
    """Issue 33: the README is short (what it is, a picture, the set-up, one example per
    job, links) and its first screen links the start-here notebook (issue 34, item 11)."""
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 250
    assert "![" in text  # a picture
    first_screen = "\n".join(text.splitlines()[:40])
    assert "examples/start_here.ipynb" in first_screen
    assert (ROOT / "examples" / "start_here.ipynb").is_file()
    for link, anchor in re.findall(r"\]\((docs/[^)#]+)(?:#([^)]+))?\)", text):
        assert (ROOT / link).is_file(), link
        if anchor:  # MkDocs checks the pages' own links; the README is not one of them
            headings = re.findall(r"^#+ (.+)$", (ROOT / link).read_text(encoding="utf-8"), re.M)
            slugs = {re.sub(r"[^\w\- ]", "", h).strip().lower().replace(" ", "-") for h in headings}
            assert anchor in slugs, (link, anchor, slugs)


def test_the_report_of_a_spec_shows_its_inputs_in_the_docs() -> None:
    """Issue 34, item 11: `pipeflow report spec.json` is shown in a page the README links,
    in a block that runs, and the block checks the report lists the inputs."""
    shown = [b for b in RUNNABLE if b.skip is None and "pipeflow report spec.json" in b.text]
    assert shown and any("Inputs" in b.text for b in shown), shown
    assert "pipeflow report spec.json" in README.read_text(encoding="utf-8")


def test_the_docs_site_builds_without_a_broken_link(tmp_path: Path) -> None:
    """`mkdocs build --strict` (the command of README's Development section): a link to a
    missing page or anchor, or a page missing from the nav, is a warning and so a failure."""
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "site" / "http-api" / "index.html").is_file()


def test_the_parser_reads_markers() -> None:
    text = (
        "x\n<!-- readme-test: skip (needs Docker) -->\n```bash\ndocker ps\n```\n```python\n1\n```\n"
    )
    found = blocks(text)
    assert [(b.lang, b.line, b.skip) for b in found] == [
        ("bash", 3, "needs Docker"),
        ("python", 6, None),
    ]
    with pytest.raises(AssertionError, match="malformed marker"):
        blocks("<!-- readme-test: skip -->\n```bash\nls\n```\n")


def _setup_commands() -> list[str]:
    """The commands of the README's "Set-up: two commands" section, split at ``&&``."""
    text = README.read_text(encoding="utf-8")
    section = text[text.index("## Set-up: two commands") :]
    section = section[: section.index("\n## ", 1)]
    found = [b for b in blocks(section) if b.lang == "bash"][:2]
    return [part.strip() for b in found for part in b.text.strip().split("&&")]


def test_ci_runs_the_readme_set_up_commands_in_a_fresh_venv() -> None:
    """.ci/run installs exactly as the README says (the lock, the extras) inside a venv it
    made itself, and runs the README's test command: a missing install step or an unlocked
    package fails CI, not a user's first run."""
    commands = _setup_commands()
    assert commands[0].startswith("pip install -c constraints-dev.txt -e '.[service]'")
    assert commands[-1] == "python -m pytest -q", commands
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    lines = [" ".join(t for t in ln.split() if t != "-q") for ln in ci.splitlines()]
    venv_at = next(i for i, ln in enumerate(lines) if re.search(r" -m venv ", ln))
    assert any(ln.startswith(". ") and "/bin/activate" in ln for ln in lines[venv_at:])
    for command in commands:
        if command.startswith("uvicorn "):  # CI serves on a port of its own, then stops
            command = command.rpartition("--port")[0] + "--port"
        plain = " ".join(t for t in command.split() if t != "-q")
        at = [i for i, ln in enumerate(lines) if ln.startswith(plain)]
        assert at and min(at) > venv_at, f".ci/run does not run {command!r} in its venv"


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("readme-work")


@dataclass
class Reader:
    """A reader pasting each page's blocks in order into a shell directory of that page's
    own: each block runs once, after every block above it on its page (whatever order
    pytest asks for them in: the suite passes with ``-p randomly``), and its exit code is
    kept for the block's test."""

    server: str
    workdir: Path
    done: dict[tuple[str, int], subprocess.CompletedProcess[str]]

    def run_through(self, block: Block) -> subprocess.CompletedProcess[str]:
        for earlier in RUNNABLE:
            if earlier.page != block.page:
                continue
            if earlier.line > block.line:
                break
            if earlier.skip is None and (earlier.page, earlier.line) not in self.done:
                self.done[earlier.page, earlier.line] = self._run(earlier)
        return self.done[block.page, block.line]

    def page_dir(self, page: str) -> Path:
        d = self.workdir / page.replace("/", "_").removesuffix(".md")
        if not d.is_dir():
            d.mkdir(parents=True)
            (d / ".curl-fails.sh").write_text(CURL_FAILS)
        return d

    def _run(self, block: Block) -> subprocess.CompletedProcess[str]:
        host = self.server.removeprefix("http://")
        code = block.text.replace("localhost:8000", host)
        workdir = self.page_dir(block.page)
        env = dict(os.environ, BASH_ENV=str(workdir / ".curl-fails.sh"), MPLBACKEND="Agg")
        # the blocks import this tree's packages, as after the README's `pip install -e .`
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
        if block.lang == "bash":
            cmd = ["bash", "-euo", "pipefail", "-c", code]
        else:
            script = workdir / f"block_line{block.line}.py"
            script.write_text(code)
            cmd = [sys.executable, str(script)]
        return subprocess.run(
            cmd, cwd=workdir, env=env, capture_output=True, text=True, timeout=TIMEOUT_S
        )


@pytest.fixture(scope="module")
def reader(server: str, workdir: Path) -> Reader:
    return Reader(server, workdir, {})


@pytest.mark.parametrize(
    "block", RUNNABLE, ids=[f"{b.page}-{b.lang}-line{b.line}" for b in RUNNABLE]
)
def test_readme_block_runs(block: Block, reader: Reader) -> None:
    if block.skip:
        pytest.skip(f"{block.page} marker: {block.skip}")
    done = reader.run_through(block)
    failed_before = [
        line
        for (page, line), run in reader.done.items()
        if page == block.page and line < block.line and run.returncode
    ]
    assert done.returncode == 0, (
        f"{block.page}:{block.line} ({block.lang}) failed with {done.returncode}"
        f" (blocks above it that failed: {failed_before or 'none'}):\n"
        f"{block.text}\n--- stdout\n{done.stdout[-4000:]}\n--- stderr\n{done.stderr[-4000:]}"
    )


def _manual() -> str:
    """README.md and every docs/ page, one text."""
    return "\n".join(p.read_text(encoding="utf-8") for p in PAGES)


def _quoted(pattern: str) -> list[re.Match[str]]:
    found = list(re.finditer(pattern, _manual()))
    assert found, f"README.md and docs/ no longer quote {pattern!r}: update this test"
    return found


def test_the_sobol_figures_the_studies_page_quotes_reproduce(tmp_path: Path) -> None:
    """Issue 34, item 9: the Sobol' indices and their bootstrap intervals quoted under the
    uncertainty example are what running it prints (the design and the bootstrap are both
    seeded, so the same versions give the same digits); every ``# `` line after the
    block's last statement must be a line of its output."""
    [block] = [b for b in RUNNABLE if b.page == "docs/studies.md" and "saltelli" in b.text]
    lines = block.text.rstrip().splitlines()
    quoted = []
    while lines and lines[-1].startswith("# "):
        quoted.insert(0, lines.pop()[2:].strip())
    assert any("S1 = " in q for q in quoted), quoted
    (tmp_path / "block.py").write_text(block.text)
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    done = subprocess.run(
        [sys.executable, "block.py"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
    )
    assert done.returncode == 0, done.stderr
    printed = [ln.strip() for ln in done.stdout.splitlines()]
    assert quoted == printed, (quoted, printed)


def test_the_figures_the_readme_quotes_are_current() -> None:
    """The numbers the README's prose quotes are what the code computes now, to the digits
    quoted (issue 13: the tip-error figure had gone stale).  This checks the README against
    the library, not the physics: the values themselves are tested against the paper and
    analytic references in tests/pipeflow/."""
    from pipeflow.basis import paper_scale, tip_values
    from pipeflow.computations import documents
    from pipeflow.paper import PAPER_PIPE
    from pipeflow.schema.simulation import PAPER_EXAMPLE, SimulationSpec
    from pipeflow.simulation import simulate
    from pipeflow.stability import critical_velocities

    def same(quoted: str, value: float) -> None:
        digits = len(quoted.replace(".", "").split("e")[0].lstrip("0"))
        assert float(quoted) == float(f"{value:.{digits}g}"), (quoted, value)

    # error estimates of the paper's example with cma (v = 0.4 t, w0 = 100 rad/s; the
    # default method "auto" would pick magnus there)
    spec = SimulationSpec.model_validate(dict(PAPER_EXAMPLE, method="cma"))
    d = documents.simulation(simulate(spec.to_simulation()))
    (m,) = _quoted(
        r"e\.g\. (?P<tip>[0-9.e-]+) against (?P<state>[0-9.e-]+) for `cma` at v = 0\.4 t"
    )
    same(m["tip"], d["diagnostics"]["estimated_tip_relative_error"])
    same(m["state"], d["diagnostics"]["estimated_relative_error"])

    # the critical flow velocity of the paper's pipe at w0 = 100 rad/s, 10 modes, 0..60 m/s
    res = critical_velocities(PAPER_PIPE, omega0=100.0, velocity_range=(0.0, 60.0), modes=10)
    assert res.critical_velocity is not None
    for m in _quoted(r"# (?P<v>[0-9.]+) m/s, u_cr = (?P<u>[0-9.]+)"):
        same(m["v"], res.critical_velocity)
        same(m["u"], res.u_cr)
    for m in _quoted(r'"critical_velocity": (?P<v>[0-9.]+) \[m/s\]'):
        same(m["v"], res.critical_velocity)
    for m in _quoted(r'"u_cr": (?P<u>[0-9.]+), "beta", "gamma"'):  # the paper's pipe's
        same(m["u"], res.u_cr)

    # the same pipe at 1000 rad/s, unstable at rest (issue 34): where it is stable, and the
    # spin past which it diverges at v = 20 m/s (the Campbell sweep's boundary)
    fast = critical_velocities(PAPER_PIPE, omega0=1000.0, velocity_range=(0.0, 60.0), modes=10)
    [(a, b)] = fast.stable_intervals
    for m in _quoted(r"stable from (?P<a>[0-9.]+) to (?P<b>[0-9.]+) m/s only"):
        same(m["a"], a)
        same(m["b"], b)
    from pipeflow.stability import sweep

    campbell = sweep(PAPER_PIPE, "spin", (0.0, 1500.0), fixed=20.0, modes=10, tracked=4)
    [edge] = campbell.boundary
    for m in _quoted(r"the pipe diverges past (?P<w>[0-9.]+) rad/s"):
        same(m["w"], edge.value)

    # the tip value of the paper's first mode shape phi_1 (eq. (3)), and the initial tip of
    # the example (u0 = 1 mm times it)
    paper_tip = float(paper_scale(1)[0] * tip_values(1)[0])
    for m in _quoted(r"whose tip\s+value is (?P<tip>[0-9.]+)"):
        same(m["tip"], paper_tip)
    for m in _quoted(r"starts the tip at (?P<mm>[0-9.]+) mm"):
        same(m["mm"], 1e3 * d["initial_tip_displacement"])
