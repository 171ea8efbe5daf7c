"""Packaging basics: one version everywhere, a licence, a changelog."""
from __future__ import annotations

import re
from pathlib import Path

import ltd_brake_ros

ROOT = Path(__file__).resolve().parents[1]


def test_one_version_everywhere(capsys):
    from ltd_brake_ros.cli.main import main

    xml = (ROOT / "package.xml").read_text()
    assert re.search(r"<version>([^<]+)</version>", xml).group(1) == ltd_brake_ros.__version__
    try:
        main(["--version"])
    except SystemExit as exc:
        assert exc.code == 0
    assert capsys.readouterr().out.strip() == f"ltd-brake {ltd_brake_ros.__version__}"


def test_licence_and_changelog_ship():
    text = (ROOT / "LICENSE").read_text()
    assert "Apache License" in text and "Version 2.0, January 2004" in text
    assert "Apache-2.0" in (ROOT / "package.xml").read_text()
    assert "## Unreleased" in (ROOT / "CHANGELOG.md").read_text()
