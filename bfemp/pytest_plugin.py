"""A pytest plugin for users' own regression references (:mod:`bfemp.regress`).

Enable it in your ``conftest.py`` and call the fixture with a reference's scene file::

    pytest_plugins = ["bfemp.pytest_plugin"]

    def test_my_scene(bfemp_reference):
        bfemp_reference("references/my_scene.toml")   # fails with the drift table

``pytest --bfemp-update-references`` rewrites the stored trajectories instead of comparing
(and logs what changed). The plugin is not registered automatically, so bfemp adds nothing to
pytest runs that do not ask for it.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import pytest

from bfemp.testing import assert_reference

log = logging.getLogger(__name__)


def pytest_addoption(parser: pytest.Parser) -> None:
    """``--bfemp-update-references``: rewrite references instead of comparing."""
    parser.addoption(
        "--bfemp-update-references",
        action="store_true",
        default=False,
        help="bfemp: rewrite the regression references the tests check, and log what changed",
    )


@pytest.fixture
def bfemp_reference(request: pytest.FixtureRequest) -> Callable[[str], object]:
    """A function ``(path) -> Report`` that reruns the reference and fails the test on drift."""
    update = request.config.getoption("--bfemp-update-references")

    def check(path: str) -> object:
        result = assert_reference(path, update=update)
        if update:
            log.warning("bfemp reference %s rewritten: %s", path, result or "no change")
        return result

    return check
