"""The documentation site: every public name has a reference page that resolves to it."""
from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

import ltd_brake_ros

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "docs" / "reference"


@pytest.mark.parametrize("name", sorted(set(ltd_brake_ros.__all__) - {"__version__"}))
def test_every_public_name_has_a_reference_page_that_resolves_to_it(name):
    page = REFERENCE / f"{name}.md"
    assert page.is_file(), f"docs/reference/{name}.md is missing"
    target = re.match(r"::: ([\w.]+)", page.read_text()).group(1)
    module, _, attr = target.rpartition(".")
    assert getattr(importlib.import_module(module), attr) is getattr(ltd_brake_ros, name)
    assert f"({name}.md)" in (REFERENCE / "index.md").read_text()


def test_every_page_of_the_navigation_exists():
    nav = re.findall(r":\s+([\w\-/]+\.md)\s*$", (ROOT / "mkdocs.yml").read_text(), re.M)
    assert "index.md" in nav and "reference/index.md" in nav
    for page in nav:
        assert (ROOT / "docs" / page).is_file(), page
