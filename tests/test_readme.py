"""The README's examples run as written, and the figures it quotes are current.

Every fenced ``bash`` and ``python`` block of README.md is run, in README order, in one
temporary working directory (as a reader pasting them one after another would: a later
block may use a file an earlier one wrote), against a live ``uvicorn service.main:app``
started by the fixture on a free port; ``localhost:8000`` in a block is rewritten to that
server.  Bash blocks run under ``bash -euo pipefail`` with ``curl`` failing on HTTP errors
(as if every call had ``--fail-with-body``), so an example answered 4xx/5xx fails here.

A block is skipped only when the line before it is the marker
``<!-- readme-test: skip (reason) -->`` with a reason (installs, a second server in the
foreground, a Docker engine, runs of minutes); the marker convention is stated in the
README's Development section.
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


def blocks(text: str) -> list[Block]:
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
            raise AssertionError(f"README.md:{start}: malformed marker {before!r}")
        out.append(Block(m["lang"], start + 1, "\n".join(body) + "\n", marker and marker["reason"]))
    return out


RUNNABLE = [b for b in blocks(README.read_text(encoding="utf-8")) if b.lang in ("bash", "python")]

#: makes an HTTP error answer of any curl call fail the block (BASH_ENV of the shells)
#: curl fails on HTTP errors unless the block already says how (-f: curl refuses both)
CURL_FAILS = (
    'curl() { local a; for a in "$@"; do case "$a" in --fail|--fail-with-body) '
    'command curl "$@"; return;; --*) ;; -*f*) command curl "$@"; return;; esac; done; '
    'command curl --fail-with-body "$@"; }\n'
)


def test_the_readme_has_runnable_examples_and_marks_every_skip() -> None:
    """Guards the extraction itself: blocks are found, and every skip states a reason."""
    assert len([b for b in RUNNABLE if b.skip is None]) >= 6
    for b in RUNNABLE:
        assert b.skip is None or len(b.skip.strip()) > 5, b


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
    d = tmp_path_factory.mktemp("readme-work")
    (d / ".curl-fails.sh").write_text(CURL_FAILS)
    return d


@dataclass
class Reader:
    """A reader pasting the README's blocks in order into one shell directory: each block
    runs once, after every block above it (whatever order pytest asks for them in: the
    suite passes with ``-p randomly``), and its exit code is kept for the block's test."""

    server: str
    workdir: Path
    done: dict[int, subprocess.CompletedProcess[str]]

    def run_through(self, block: Block) -> subprocess.CompletedProcess[str]:
        for earlier in RUNNABLE:
            if earlier.line > block.line:
                break
            if earlier.skip is None and earlier.line not in self.done:
                self.done[earlier.line] = self._run(earlier)
        return self.done[block.line]

    def _run(self, block: Block) -> subprocess.CompletedProcess[str]:
        host = self.server.removeprefix("http://")
        code = block.text.replace("localhost:8000", host)
        env = dict(os.environ, BASH_ENV=str(self.workdir / ".curl-fails.sh"), MPLBACKEND="Agg")
        # the blocks import this tree's packages, as after the README's `pip install -e .`
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
        if block.lang == "bash":
            cmd = ["bash", "-euo", "pipefail", "-c", code]
        else:
            script = self.workdir / f"readme_line{block.line}.py"
            script.write_text(code)
            cmd = [sys.executable, str(script)]
        return subprocess.run(
            cmd, cwd=self.workdir, env=env, capture_output=True, text=True, timeout=TIMEOUT_S
        )


@pytest.fixture(scope="module")
def reader(server: str, workdir: Path) -> Reader:
    return Reader(server, workdir, {})


@pytest.mark.parametrize("block", RUNNABLE, ids=[f"{b.lang}-line{b.line}" for b in RUNNABLE])
def test_readme_block_runs(block: Block, reader: Reader) -> None:
    if block.skip:
        pytest.skip(f"README marker: {block.skip}")
    done = reader.run_through(block)
    failed_before = [
        line for line, run in reader.done.items() if line < block.line and run.returncode
    ]
    assert done.returncode == 0, (
        f"README.md:{block.line} ({block.lang}) failed with {done.returncode}"
        f" (blocks above it that failed: {failed_before or 'none'}):\n"
        f"{block.text}\n--- stdout\n{done.stdout[-4000:]}\n--- stderr\n{done.stderr[-4000:]}"
    )


def _quoted(pattern: str) -> list[re.Match[str]]:
    found = list(re.finditer(pattern, README.read_text(encoding="utf-8")))
    assert found, f"README.md no longer quotes {pattern!r}: update this test"
    return found


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
