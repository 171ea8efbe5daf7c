"""``ltd-brake campaign report DIR --html FILE``: one self-contained HTML file (inline style,
embedded PNG figures, no external resource) with the summary, the quantiles, the exceedance
curves, the relative approach, the sensitivity bars and the worst runs with their rerun
commands; an existing file is replaced only with --force."""
from __future__ import annotations

import base64
import re

import pytest
from campaign_helpers import write_campaign

from ltd_brake_ros.cli.main import main
from ltd_brake_ros.inputs.campaign import load_campaign
from ltd_brake_ros.studies.campaign_exec import run_campaign

#: A campaign name that HTML must escape.
NAME = "small <b>&amp;"
#: A manoeuvre name with markup for HTML and for matplotlib's mathtext (an unbalanced formula).
MANOEUVRE = "stop <i>$x^$</i> & 'co'"


def _named(text: str) -> str:
    """The campaign text with its manoeuvre named :data:`MANOEUVRE`."""
    quoted = MANOEUVRE.replace("'", "''")
    return text.replace("  - {kind: emergency,", f"  - {{name: '{quoted}', kind: emergency,")


def _run(folder, name, edit=None, runs=20, sampling="monte_carlo"):
    path = write_campaign(folder, name=name, runs=runs, batch=10, sampling=sampling)
    text = _named(path.read_text())
    path.write_text(edit(text) if edit else text)
    run_campaign(load_campaign(path), folder / name)
    return folder / name


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A family (k0 lowered: more brake force), its reference, and a Sobol' campaign."""
    folder = tmp_path_factory.mktemp("html")
    return {
        "reference": _run(folder, "reference"),
        "family": _run(folder, "family", lambda t: t.replace("name: family", f"name: '{NAME}'")
                       .replace("mean: 2.7", "mean: 2.55")),
        "sobol": _run(folder, "sobol", runs=8, sampling="{design: sobol, inputs: [k0, wagons]}"),
    }


def _images(text: str) -> list[bytes]:
    return [base64.b64decode(m) for m in re.findall(r'src="data:image/png;base64,([^"]+)"',
                                                    text)]


def _assert_self_contained(text: str) -> None:
    """No reference that a browser would load: every src is an embedded image; no link,
    script, style import or url()."""
    assert text.startswith("<!DOCTYPE html>") and text.rstrip().endswith("</html>")
    assert not re.search(r"""(?:src|href)\s*=\s*["']?\s*(?:[a-z]+:)?//""", text, re.I)
    assert all(v.startswith("data:image/png;base64,")
               for v in re.findall(r'src="([^"]*)"', text))
    for banned in ("<script", "<link", "@import", "url(", "<iframe", "<object"):
        assert banned not in text.lower()


def test_html_report_is_self_contained(folders, tmp_path, capsys):
    out = tmp_path / "report.html"
    status = main(["campaign", "report", str(folders["family"]), "--against",
                   str(folders["reference"]), "--quantile", "0.9", "--threshold",
                   "peak_draft_kN=80", "--html", str(out)])
    assert status in (0, 1, 4)
    assert f"html: {out}" in capsys.readouterr().out
    text = out.read_text(encoding="utf-8")
    _assert_self_contained(text)
    # the embedded figures are PNG images: the exceedance curves of the one manoeuvre
    images = _images(text)
    assert len(images) == 1 and all(i.startswith(b"\x89PNG\r\n\x1a\n") for i in images)
    # the tables: summary, quantiles with intervals, exceedance, relative approach, worst runs
    assert text.count("<table>") >= 5
    for words in ("<h2>Summary</h2>", "<th>q0.5</th>", "<th>q0.99</th>", "Wilson interval",
                  "Exceedance curves", "Relative approach against reference",
                  "runs paired", "<th>worsening</th>", "peak_buff_kN",
                  "stopping_distance_m"):
        assert words in text, words
    assert re.search(r"exit status [014]\)", text)
    # the worst runs and the command that reruns each
    import html
    import shlex

    cmd = re.search(r"ltd-brake campaign rerun \S+ --runs (\d+) --manoeuvre "
                    + re.escape(html.escape(shlex.quote(MANOEUVRE))) + r" --out \S+_reruns", text)
    assert cmd and f"<td class=\"l\">{cmd.group(1)}</td>" in text
    # text is escaped: the campaign's name appears only escaped
    assert "small &lt;b&gt;&amp;amp;" in text and "<b>&amp;" not in text.replace(
        "<b>peak", "")
    # so is the manoeuvre's name, and its dollar signs are no formula in the figures
    assert f"<h2>Manoeuvre {html.escape(MANOEUVRE)} (20 runs)</h2>" in text
    assert "<i>" not in text


def test_an_existing_file_is_replaced_only_with_force(folders, tmp_path, capsys):
    out = tmp_path / "report.html"
    out.write_text("keep me")
    argv = ["campaign", "report", str(folders["reference"]), "--html", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"--html: {out} exists; give a new file, or --force to replace it" in err
    assert out.read_text() == "keep me"
    assert main([*argv, "--force"]) == 0
    _assert_self_contained(out.read_text())
    assert main(["campaign", "report", str(folders["reference"]), "--force"]) == 2
    assert "--force: applies to --html FILE" in capsys.readouterr().err
    assert main(["campaign", "report", str(folders["reference"]), "--html",
                 str(tmp_path / "no" / "such" / "dir.html")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_json_names_the_html_file(folders, tmp_path, capsys):
    import json

    out = tmp_path / "r.html"
    assert main(["campaign", "report", str(folders["reference"]), "--html", str(out),
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["html"] == str(out) and out.is_file()


def test_sensitivity_bars_of_a_sobol_campaign(folders, tmp_path):
    out = tmp_path / "sobol.html"
    assert main(["campaign", "report", str(folders["sobol"]), "--html", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    _assert_self_contained(text)
    assert "<h2>Design and sensitivity</h2>" in text and "Saltelli&#x27;s design" in text
    assert "<th>ST interval</th>" in text and '<td class="l">wagons</td>' in text
    images = _images(text)
    assert len(images) == 2 and all(i.startswith(b"\x89PNG") for i in images)


def test_sensitivity_indices_in_python_are_the_reports(folders, capsys):
    import json

    from ltd_brake_ros import read_campaign

    res = read_campaign(folders["sobol"])
    table = res.sensitivity()
    assert set(table.input) == {"k0", "wagons"} and {"S1", "ST_low", "ST_high"} <= set(table)
    assert main(["campaign", "report", str(folders["sobol"]), "--json"]) == 0
    sens = json.loads(capsys.readouterr().out)["sensitivity"]["manoeuvres"][MANOEUVRE]
    row = table[(table.kpi == "peak_draft_kN") & (table.input == "k0")].iloc[0]
    assert row.S1 == pytest.approx(sens["peak_draft_kN"]["indices"]["k0"]["S1"])
    assert [row.ST_low, row.ST_high] == pytest.approx(
        sens["peak_draft_kN"]["indices"]["k0"]["ST_interval"])
