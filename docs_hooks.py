"""mkdocs hook: the Sphinx roles of the numpydoc docstrings as code, linked where the name has a
reference page.

mkdocstrings renders a docstring's Markdown, in which ``:class:`~pkg.mod.Name``` is the text
":class:" before the code ``~pkg.mod.Name``. This hook, run on every page's HTML, turns it
into the code ``Name`` (the last part after ``~``, the whole name otherwise, as Sphinx shows
it), a link to the API reference page of ``Name`` where there is one.
"""
from __future__ import annotations

import re
from pathlib import Path

#: The roles the docstrings use (a test checks that no other appears).
ROLES = ("class", "func", "meth", "attr", "mod", "data", "exc", "obj", "const")
_ROLE = re.compile(r":(?:py:)?(" + "|".join(ROLES) + r"):<code>(~?)([\w.]+)</code>")
#: A role with its own title: ``:attr:`Title <target>```.
_TITLED = re.compile(r":(?:py:)?(" + "|".join(ROLES) + r"):<code>([^<&]+?) &lt;~?([\w.]+)&gt;"
                     r"</code>")
_REFERENCE = Path(__file__).resolve().parent / "docs" / "reference"


def plain_roles(html: str, base: str = "") -> str:
    """``:role:<code>~a.b.Name</code>`` -> ``<code>Name</code>``, linked to
    ``{base}Name/`` when ``docs/reference/Name.md`` exists (``base`` ''  for no links).

    Examples
    --------
    >>> plain_roles(":class:<code>~ltd_brake_ros.api.TimeSeries</code>")
    '<code>TimeSeries</code>'
    >>> plain_roles(":func:<code>load_consist</code>", "../")
    '<a href="../load_consist/"><code>load_consist</code></a>'
    >>> plain_roles(":attr:<code>Consist.n &lt;ltd_brake_ros.inputs.Consist&gt;</code>")
    '<code>Consist.n</code>'
    """
    pages = {p.stem for p in _REFERENCE.glob("*.md")} if base else set()

    def one(m: re.Match) -> str:
        name = m.group(3)
        shown = name.rsplit(".", 1)[-1] if m.group(2) else name
        target = name.rsplit(".", 1)[-1]
        code = f"<code>{shown}</code>"
        return f'<a href="{base}{target}/">{code}</a>' if target in pages else code

    def titled(m: re.Match) -> str:
        target = m.group(3).rsplit(".", 1)[-1]
        code = f"<code>{m.group(2)}</code>"
        return f'<a href="{base}{target}/">{code}</a>' if target in pages else code

    return _ROLE.sub(one, _TITLED.sub(titled, html))


def on_page_content(html: str, page, config, files) -> str:
    """mkdocs' hook on every page's HTML."""
    uri = page.file.src_uri
    base = "./" if uri == "reference/index.md" else "../" if uri.startswith("reference/") \
        else ""
    return plain_roles(html, base)
