"""The two locks are in step with pyproject.toml and with each other.

``constraints-dev.txt`` pins every package the README's commands install (the ``dev`` extra,
which holds every other extra); ``constraints.txt`` pins the Docker image's (``service``,
``parquet``, ``client``, ``formats``).  ``bash .ci/lock`` writes both with pip-compile.
These tests check that every requirement of every extra is pinned, at a version its
specifier admits (a new dependency without a lock entry fails here), and that the image pins
the same versions as the README; completeness of the transitive set is checked by
``pip check`` after the
installs in clean virtualenvs (``.ci/run``: the README's venv and the image's).
"""

from __future__ import annotations

import tomllib
from importlib.metadata import requires
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]

#: the lock of each set of extras: the README's (every extra) and the image's
LOCKS = {
    "constraints-dev.txt": tuple(PROJECT["optional-dependencies"]),
    "constraints.txt": ("service", "parquet", "client", "formats"),
}


def _pins(lock: str) -> dict[str, str]:
    pins = {}
    for line in (ROOT / lock).read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, _, version = line.partition("==")
            assert version, f"{lock}: {line!r} is not pinned with == (regenerate: bash .ci/lock)"
            pins[canonicalize_name(name)] = version.split(";")[0].strip()
    return pins


def _extra_requirements(extras: tuple[str, ...]) -> list[Requirement]:
    """The requirements of ``extras``, self-references (``pipeflow[plots]``) expanded."""
    out: list[Requirement] = []
    for extra in extras:
        for spec in PROJECT["optional-dependencies"][extra]:
            req = Requirement(spec)
            if canonicalize_name(req.name) == canonicalize_name(PROJECT["name"]):
                out += _extra_requirements(tuple(sorted(req.extras)))
            else:
                out.append(req)
    return out


def _requirements(extras: tuple[str, ...]) -> list[Requirement]:
    return [Requirement(s) for s in PROJECT["dependencies"]] + _extra_requirements(extras)


@pytest.mark.parametrize("lock", LOCKS)
def test_every_requirement_is_pinned_within_its_range(lock: str) -> None:
    pins = _pins(lock)
    for req in _requirements(LOCKS[lock]):
        name = canonicalize_name(req.name)
        assert name in pins, f"{req.name} is not in {lock}: regenerate it (bash .ci/lock)"
        assert req.specifier.contains(pins[name], prereleases=True), (
            f"{lock} pins {req.name}=={pins[name]}, outside {req.specifier}"
        )
    # the package itself is installed from the source tree, never from the pins (nor as a
    # path of the machine that wrote the lock: "pipeflow @ file:///...")
    assert canonicalize_name(PROJECT["name"]) not in pins
    assert "file://" not in (ROOT / lock).read_text()


def _named_extras(extra: str) -> set[str]:
    """``extra`` and every extra it names through ``pipeflow[...]``, recursively."""
    out = {extra}
    for spec in PROJECT["optional-dependencies"][extra]:
        req = Requirement(spec)
        if canonicalize_name(req.name) == canonicalize_name(PROJECT["name"]):
            for named in req.extras:
                out |= _named_extras(named)
    return out


def test_the_readme_lock_covers_every_extra() -> None:
    """The README installs the dev extra: it must name every other extra, else the packages
    of a new extra would be in no lock the README uses."""
    assert _named_extras("dev") == set(PROJECT["optional-dependencies"])


def test_the_image_pins_the_versions_the_readme_pins() -> None:
    """One set of versions: the image's lock is compiled under the README's."""
    dev, image = _pins("constraints-dev.txt"), _pins("constraints.txt")
    assert set(image) <= set(dev), set(image) - set(dev)
    assert {n: v for n, v in image.items() if dev[n] != v} == {}


@pytest.mark.parametrize("lock", LOCKS)
def test_extras_of_dependencies_are_pinned(lock: str) -> None:
    """A dependency asked for with an extra (``psycopg[binary]``: libpq inside the wheel,
    which the slim image lacks) has that extra's own requirements pinned as well, read
    from the installed distribution's metadata (``Requires-Dist: ...; extra == "binary"``)."""
    pins = _pins(lock)
    checked = 0
    for req in _requirements(LOCKS[lock]):
        for extra in sorted(req.extras):
            for dep in map(Requirement, requires(req.name) or []):
                if dep.marker is None or not dep.marker.evaluate({"extra": extra}):
                    continue
                if dep.marker.evaluate({"extra": ""}):
                    continue  # not specific to the extra
                checked += 1
                assert canonicalize_name(dep.name) in pins, (
                    f"{req.name}[{extra}] needs {dep.name}, not in {lock}"
                )
    assert checked  # psycopg[binary] at least: the check ran
