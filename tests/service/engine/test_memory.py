"""The API process bounds glibc's malloc arenas (issue 34, item 12: idle memory).

glibc gives every new thread that allocates an arena of its own, up to 8 per core, and an
arena keeps the pages it touched; the API process runs many threads (event loop, thread
pools, the fast lane, Dask's client and nannies).  :func:`service.main.create_app` bounds
them to :data:`service.engine.preload.API_ARENAS` (one: 16 MB less idle RSS of the
server, ``benchmarks/RESULTS.md``).  Checked in a fresh interpreter, counting the arenas glibc
reports (``malloc_info``) after 8 threads each allocated: with the app, at most the bound;
without it (the control), more; an operator's ``MALLOC_ARENA_MAX`` stands.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from service.engine.preload import API_ARENAS
from service.launch import child_environment

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="glibc's allocator (Linux)"
)

#: in the child: maybe build the app, then 8 threads, alive at once, each allocate from
#: malloc (64 KiB: below the mmap threshold); then malloc_info's report into a file
PROGRAM = """
import ctypes, ctypes.util, sys, threading
if sys.argv[1] == "app":
    from service.main import create_app
    from service.settings import Settings
    create_app(Settings(workers=1, data_dir=sys.argv[2]))
held = []
together = threading.Barrier(8)  # all alive at once: none hands its arena to the next
def allocate():
    held.append(bytearray(65536))
    together.wait()
threads = [threading.Thread(target=allocate) for _ in range(8)]
for t in threads:
    t.start()
for t in threads:
    t.join()
libc = ctypes.CDLL(ctypes.util.find_library("c"))
libc.fopen.restype = ctypes.c_void_p
libc.fopen.argtypes = [ctypes.c_char_p, ctypes.c_char_p]
libc.malloc_info.argtypes = [ctypes.c_int, ctypes.c_void_p]
libc.fclose.argtypes = [ctypes.c_void_p]
stream = libc.fopen(sys.argv[3].encode(), b"w")
libc.malloc_info(0, stream)
libc.fclose(stream)
"""


def _arenas(tmp_path: Path, mode: str, **env: str) -> int:
    report = tmp_path / f"malloc-{mode}-{len(env)}.xml"
    environment = child_environment(**env)
    if "MALLOC_ARENA_MAX" not in env:
        environment.pop("MALLOC_ARENA_MAX", None)
    done = subprocess.run(
        [sys.executable, "-c", PROGRAM, mode, str(tmp_path), str(report)],
        env=environment,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return len(re.findall(r'<heap nr="\d+">', report.read_text()))


def test_the_api_process_bounds_its_malloc_arenas(tmp_path: Path) -> None:
    assert (os.cpu_count() or 1) * 8 > API_ARENAS  # glibc's own bound is larger
    assert _arenas(tmp_path, "plain") > API_ARENAS  # the control: one arena per thread
    assert 1 <= _arenas(tmp_path, "app") <= API_ARENAS


def test_an_operators_arena_setting_stands(tmp_path: Path) -> None:
    assert _arenas(tmp_path, "app", MALLOC_ARENA_MAX="4") == 4
