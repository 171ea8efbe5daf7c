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


def _sections(obj) -> dict:
    """The numpydoc sections of an object's docstring, parsed as the reference renders them."""
    import inspect

    griffe = pytest.importorskip("griffe")
    doc = inspect.getdoc(obj) or ""
    out: dict = {}
    for section in griffe.Docstring(doc, parser="numpy").parse():
        out.setdefault(section.kind.value, []).append(section)
    return out


def _names(sections: dict, kind: str) -> dict:
    """Documented name -> description (``a, b : float`` documents both)."""
    out = {}
    for section in sections.get(kind, []):
        for item in section.value:
            for name in item.name.split(","):
                out[name.strip().lstrip("*")] = item.description or ""
    return out


#: A unit in a description ([m], [kN], [-], [km/h], ...) or in the name (speed_kmh, time_s).
_UNIT = re.compile(r"\[[^\]]+\]|_(?:s|m|kmh|kn|n|k|mm|t|percent|m_s|ns|kg)$", re.I)


@pytest.mark.parametrize("name", sorted(set(ltd_brake_ros.__all__) - {"__version__"}))
def test_every_public_name_documents_its_fields_parameters_units_returns_and_examples(name):
    """A public class documents every field (those added later too); a public function every
    parameter, a float's unit, its return value; both show an example."""
    import dataclasses
    import inspect

    obj = getattr(ltd_brake_ros, name)
    sec = _sections(obj)
    assert "examples" in sec, f"{name}: no Examples section"
    if inspect.isclass(obj):
        if dataclasses.is_dataclass(obj):
            documented = {**_names(sec, "attributes"), **_names(sec, "parameters")}
            missing = [f.name for f in dataclasses.fields(obj) if f.name not in documented]
            assert not missing, f"{name}: fields without a description: {missing}"
            assert all(documented[f.name].strip() or f.type in ("str", "bool") for f in
                       dataclasses.fields(obj)), f"{name}: an empty field description"
        return
    params = _names(sec, "parameters")
    signature = inspect.signature(obj).parameters
    missing = [p for p in signature if p.lstrip("*") not in params]
    assert not missing, f"{name}: parameters without a description: {missing}"
    for p, spec in signature.items():
        if "float" in str(spec.annotation) and "float" in str(spec.annotation).split("|")[0]:
            assert _UNIT.search(params[p]) or _UNIT.search(p), f"{name}({p}): no unit"
    assert "returns" in sec, f"{name}: no Returns section"


def test_every_sphinx_role_of_the_docstrings_renders_as_code():
    """The docstrings' roles are those the docs hook turns into code and links (mkdocstrings
    would show ':class:' as text), and the hook turns them."""
    import sys

    sys.path.insert(0, str(ROOT))
    try:
        import docs_hooks
    finally:
        sys.path.remove(str(ROOT))
    used = set()
    for path in (ROOT / "ltd_brake_ros").rglob("*.py"):
        used |= set(re.findall(r":(?:py:)?([a-z]+):`", path.read_text()))
    assert used <= set(docs_hooks.ROLES), used - set(docs_hooks.ROLES)
    html = (":class:<code>~ltd_brake_ros.api.TimeSeries</code> and "
            ":meth:<code>TimeSeries.to_xarray</code> of :mod:<code>ltd_brake_ros.api</code>, "
            ":attr:<code>Consist.n &lt;ltd_brake_ros.inputs.Consist&gt;</code>")
    out = docs_hooks.plain_roles(html, "../")
    assert not re.search(r":[a-z]+:<code>", out), out
    assert '<a href="../TimeSeries/"><code>TimeSeries</code></a>' in out
    assert "<code>ltd_brake_ros.api</code>" in out
    assert "docs_hooks.py" in (ROOT / "mkdocs.yml").read_text()
